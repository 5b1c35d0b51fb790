"""Whole materials in ``tghop batch`` (issue #29's material library): a manifest row's ``maps``
make it a material (:class:`tghop.material.Material`) whose albedo is its ``path``; each image
is then the albedo and a file per map at the map's depth, the library's maps bit for bit; a
rerun skips it until a map changes; bad maps are refused (the manifest's) or recorded (the
task's); and the same on a real local Dask cluster.

Exemplars and maps are made in code (no ../shared); fits use tiny settings.
"""

import json

import numpy as np
import pytest

from tghop import batch, data
from tghop._errors import TGHopError
from tghop.imageio import load_image, save_image, to_uint8
from tghop.manifest import MAX_MAPS, parse_maps
from tghop.material import example_maps
from tghop.modelfile import load_model

from test_cli_failures import assert_one_line, invoke

FIT = dict(n_clusters=6, n_codewords=30, stride=4)
GEN = dict(n_patches=300)
SIZE = (40, 48)


def make_material(d, stem="rock", size=64, rng=3):
    """An albedo and its normal (16-bit) and height (8-bit) maps in ``d``."""
    d.mkdir(parents=True, exist_ok=True)
    albedo = data.bricks(size, rng=rng)
    maps = example_maps(albedo)
    save_image(albedo, d / f"{stem}.png")
    save_image(maps["normal"], d / f"{stem}_n.png", depth=16)
    save_image(maps["height"], d / f"{stem}_h.png")
    return d


def ledger(out):
    return [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]


def pixels(path):
    image, depth = load_image(path, dtype=None, with_depth=True)
    return image, depth


@pytest.mark.parametrize("value, want", [
    ("normal=rock_n.png; rock_h.png", [("normal", "rock_n.png"), ("rock_h", "rock_h.png")]),
    ({"normal": "rock_n.png", "height": "sub/h.png"}, [("normal", "rock_n.png"), ("height", "sub/h.png")]),
    (["rock_n.png", "/abs/h.png"], [("rock_n", "rock_n.png"), ("h", "/abs/h.png")]),
])
def test_a_rows_maps_are_named_and_found_beside_the_manifest(tmp_path, value, want):
    got = parse_maps(value, "m.csv line 2", tmp_path)
    assert got == [(n, tmp_path / f) for n, f in want]  # an absolute path stays itself


@pytest.mark.parametrize("value, words", [
    ("my map=a.png", ["the map name 'my map' cannot name a file"]),
    ("albedo=a.png", ["a map is named 'albedo', the albedo's name; give each map its own name, e.g. normal="]),
    # 0.60: "two maps are named 'N' (or a map is named albedo, ...)", not a word of case
    ("n=a.png;N=b.png", ["two maps are named 'n' and 'N', which differ only in case", "not only in case"]),
    # two files' stems alike in their first 64 characters (the names cut from them): 0.60 "two maps are named 'rrr...'"
    (f"{'r' * 70}_a.png;{'r' * 70}_b.png", [f"the maps' files {'r' * 70}_a.png and {'r' * 70}_b.png give one name, "
                                            f"'{'r' * 64}' (a map's name is its file stem's first 64 characters); "
                                            "name each map, e.g. normal=rock_n.png, or give files whose stems differ"]),
    (f"a={'r' * 70}_a.png;b={'r' * 70}_b.png", None),  # named: no clash
    ("normal=", ["the map 'normal' has no path"]),
    (3, ["maps 3 must be paths separated by"]),
    ({"normal": 5}, ["the file of the map 'normal' must be a path (a string), not a number"]),
    (";".join(f"m{i}.png" for i in range(MAX_MAPS + 1)), [f"a material takes at most {MAX_MAPS}"]),
    (" ; ;", ["maps ' ; ;' lists no file"]),
])
def test_bad_maps_in_a_manifest_are_refused_naming_the_line(tmp_path, value, words):
    if words is None:
        assert [name for name, _ in parse_maps(value, "m.csv line 2", tmp_path)] == ["a", "b"]
        return
    with pytest.raises(TGHopError) as info:
        parse_maps(value, "m.csv line 2", tmp_path)
    message = str(info.value)
    assert message.startswith("m.csv line 2: ") and "\n" not in message
    for word in words:
        assert word in message, message


def test_a_rows_map_that_is_its_albedo_is_refused_and_no_maps_is_a_texture(tmp_path):
    src = make_material(tmp_path / "src")
    (src / "list.csv").write_text("path,maps\nrock.png,normal=./rock.png\n")
    with pytest.raises(TGHopError, match="line 2: the map normal is the row's path itself, the albedo"):
        batch.find_work(src / "list.csv")
    (src / "list.jsonl").write_text('{"path": "rock.png", "maps": []}\n{"path": "rock.png", "maps": {}}\n')
    with pytest.warns(UserWarning, match="line 2 lists rock.png as line 1 does, with the same settings"):
        assert [it["maps"] for it in batch.find_work(src / "list.jsonl")] == [[], []]


def test_a_material_row_writes_every_map_as_the_library_makes_them(tmp_path):
    src = make_material(tmp_path / "src")
    save_image(data.cells(64, rng=4), src / "cells.png")
    (src / "list.csv").write_text("path,maps,count\nrock.png,normal=rock_n.png;rock_h.png,2\ncells.png,,1\n")
    out = tmp_path / "out"
    results = batch.run(src / "list.csv", out, size=SIZE, seed=5, fit=FIT, generate=GEN, workers=1)
    assert [r["status"] for r in results] == ["ok", "ok"], results
    rock = results[0]
    assert rock["settings"]["maps"] == ["normal", "rock_h"] and "maps" not in results[1]["settings"]
    assert rock["outputs"] == ["rock/rock_1.png", "rock/rock_1_normal.png", "rock/rock_1_rock_h.png",
                               "rock/rock_2.png", "rock/rock_2_normal.png", "rock/rock_2_rock_h.png"]
    assert results[1]["outputs"] == ["cells/cells.png"]
    material = load_model(out / rock["model"], material=True)
    assert material.names_ == ["albedo", "normal", "rock_h"] and material.depths_ == [8, 16, 8]
    rng = np.random.default_rng(5)  # the task's images, one generator after another
    for i in (1, 2):
        want = material.synthesize(SIZE, rng=rng, dtype=np.float32, tile=False, **GEN)
        for name, suffix, depth in (("albedo", "", 8), ("normal", "_normal", 16), ("rock_h", "_rock_h", 8)):
            image, got_depth = pixels(out / "rock" / f"rock_{i}{suffix}.png")
            assert got_depth == depth
            if depth == 8:
                np.testing.assert_array_equal(to_uint8(image).ravel(), to_uint8(want[name]).ravel())
            else:
                np.testing.assert_allclose(image, want[name], atol=1 / 65535)
    # A rerun skips it; a changed map redoes it alone; a map dropped removes its files
    again = batch.run(src / "list.csv", out, size=SIZE, seed=5, fit=FIT, generate=GEN, workers=1)
    assert [r["skipped"] for r in again] == [True, True]
    save_image(example_maps(data.bricks(64, rng=3))["height"] * 0.5, src / "rock_h.png")
    again = batch.run(src / "list.csv", out, size=SIZE, seed=5, fit=FIT, generate=GEN, workers=1)
    assert [r["skipped"] for r in again] == [False, True]
    (src / "list.csv").write_text("path,maps,count\nrock.png,normal=rock_n.png,2\ncells.png,,1\n")
    again = batch.run(src / "list.csv", out, size=SIZE, seed=5, fit=FIT, generate=GEN, workers=1)
    assert [r["skipped"] for r in again] == [False, True]
    assert sorted(p.name for p in (out / "rock").iterdir()) == [
        "exemplar.png", "rock.npz", "rock_1.png", "rock_1_normal.png", "rock_2.png", "rock_2_normal.png"]
    names = [rec["name"] for rec in ledger(out)]
    assert names.count("rock") == 3 and names.count("cells") == 1


def test_a_bad_map_is_recorded_and_the_rest_finish(tmp_path):
    src = make_material(tmp_path / "src")
    save_image(np.zeros((32, 32, 3)) + np.linspace(0, 1, 32)[:, None, None], src / "small.png")
    (src / "notimage.png").write_bytes(b"not an image")
    (src / "list.jsonl").write_text(
        '{"path": "rock.png", "name": "wrong_size", "maps": {"height": "small.png"}}\n'
        '{"path": "rock.png", "name": "not_image", "maps": ["notimage.png"]}\n'
        '{"path": "rock.png", "name": "missing", "maps": ["nowhere.png"]}\n'
        '{"path": "rock.png", "name": "good", "maps": {"normal": "rock_n.png"}}\n')
    results = batch.run(src / "list.jsonl", tmp_path / "out", size=SIZE, seed=1, fit=FIT, generate=GEN, workers=1)
    status = {r["name"]: (r["status"], r["error"]) for r in results}
    assert status["good"] == ("ok", None)
    assert "'height' is 32x32 but the albedo is 64x64" in status["wrong_size"][1]
    assert "notimage.png" in status["not_image"][1]
    assert "nowhere.png" in status["missing"][1]
    for name in ("wrong_size", "not_image", "missing"):
        assert status[name][0] == "failed" and "\n" not in status[name][1]
        assert not (tmp_path / "out" / name).exists()


def test_quality_best_patch_refines_a_materials_albedo_and_leaves_its_maps(tmp_path):
    # 0.58 refused it ("a material (maps) has no patch statistics"); 0.59 fits the albedo's (Material.patches_)
    src = make_material(tmp_path / "src")
    (src / "list.csv").write_text("path,maps\nrock.png,rock_n.png;rock_h.png\n")
    made = {}
    for steps in (0, 8):
        out = tmp_path / f"out{steps}"
        results = batch.run(src / "list.csv", out, size=SIZE, seed=1, fit=FIT, generate={**GEN, "patch_refine": steps},
                            workers=1)
        assert [r["status"] for r in results] == ["ok"]
        made[steps] = {f: pixels(out / "rock" / f"rock{f}.png")[0] for f in ("", "_n", "_h")}
    assert not np.array_equal(made[0][""], made[8][""])  # the albedo refined
    for f in ("_n", "_h"):  # the other maps as without it, bit for bit
        assert np.array_equal(made[0][f], made[8][f])
    code, _, err, exc = invoke("batch", "src/list.csv", "-o", "out", "--quality", "best", "--workers", "1", "-q",
                               "--clusters", "6", "--codewords", "30", "--stride", "4",
                               "--size", "40x48", cwd=tmp_path)
    assert code == 0, err
    assert [r["status"] for r in ledger(tmp_path / "out")] == ["ok"]


def test_quality_best_without_patch_statistics_is_refused_before_any_work(tmp_path):
    src = make_material(tmp_path / "src")
    (src / "list.csv").write_text("path,maps\nrock.png,rock_n.png\n")
    code, _, err, exc = invoke("batch", "src/list.csv", "-o", "out", "--quality", "best", "--patch-levels", "0",
                               "--workers", "1", "-q", cwd=tmp_path)
    assert_one_line(code, err, "need the patch statistics that patch_levels 0 leaves out", exception=exc)
    assert not (tmp_path / "out").exists()


def test_materials_on_a_local_dask_cluster(tmp_path):
    pytest.importorskip("distributed", reason="the batch extra is not installed: pip install -e '.[batch]'")
    src = make_material(tmp_path / "src")
    make_material(tmp_path / "src", stem="wall", rng=7)
    (src / "list.csv").write_text("path,maps\nrock.png,normal=rock_n.png;height=rock_h.png\n"
                                  "wall.png,normal=wall_n.png\n")
    results = batch.run(src / "list.csv", tmp_path / "out", size=SIZE, seed=2, fit=FIT, generate=GEN, workers=2)
    assert [r["status"] for r in results] == ["ok", "ok"], results
    assert results[0]["outputs"] == ["rock/rock.png", "rock/rock_normal.png", "rock/rock_height.png"]
    assert results[1]["outputs"] == ["wall/wall.png", "wall/wall_normal.png"]
    assert all(r["threads"] == 1 for r in results)  # a cluster's task: one thread
    # In process at the machine's BLAS threads (0.59 compared at one: its albedo's patch statistics, fitted outside
    # the fit's one BLAS thread, were 8e-7 apart on two, which the patch refinement carried into the albedo)
    one = batch.run(src / "list.csv", tmp_path / "one", size=SIZE, seed=2, fit=FIT, generate=GEN, workers=1)
    for a, b in zip(results, one):  # a worker's maps are the same bytes as in process
        for f, g in zip(a["outputs"], b["outputs"]):
            assert (tmp_path / "out" / f).read_bytes() == (tmp_path / "one" / g).read_bytes(), f


def test_a_materials_files_drop_the_prefix_its_maps_share_and_an_earlier_runs_names_are_still_found(tmp_path):
    # rock_n.png and rock_h.png were written rock/rock_rock_n.png and rock/rock_rock_h.png, as tghop synth now
    # does not: the maps' shared "rock_" is dropped (tghop.material_files.map_files)
    src = make_material(tmp_path / "src")
    (src / "list.csv").write_text("path,maps\nrock.png,rock_n.png;rock_h.png\n")
    out = tmp_path / "out"
    first = batch.run(src / "list.csv", out, size=SIZE, seed=5, fit=FIT, generate=GEN, workers=1)
    assert first[0]["outputs"] == ["rock/rock.png", "rock/rock_n.png", "rock/rock_h.png"], first
    # An earlier version's run: its files and ledger line named by the maps' whole names
    old = ["rock/rock.png", "rock/rock_rock_n.png", "rock/rock_rock_h.png"]
    for new, was in zip(first[0]["outputs"][1:], old[1:]):
        (out / new).rename(out / was)
    lines = (out / "batch.jsonl").read_text().replace('"rock/rock_n.png", "rock/rock_h.png"',
                                                       '"rock/rock_rock_n.png", "rock/rock_rock_h.png"')
    (out / "batch.jsonl").write_text(lines)
    # A rerun finds them done (the ledger lists the files it made) and keeps them as they are
    again = batch.run(src / "list.csv", out, size=SIZE, seed=5, fit=FIT, generate=GEN, workers=1)
    assert again[0]["skipped"] is True
    assert all((out / f).is_file() for f in old)
    # Redone (a map changed): the files get the new names, and the old ones go
    save_image(example_maps(data.bricks(64, rng=3))["height"] * 0.5, src / "rock_h.png")
    again = batch.run(src / "list.csv", out, size=SIZE, seed=5, fit=FIT, generate=GEN, workers=1)
    assert again[0]["skipped"] is False and again[0]["outputs"] == first[0]["outputs"]
    assert sorted(p.name for p in (out / "rock").iterdir()) == [
        "exemplar.png", "rock.npz", "rock.png", "rock_h.png", "rock_n.png"]


def test_a_rows_path_named_as_another_kind_of_map_fails_or_is_warned_of_as_fit_refuses_or_warns(tmp_path):
    # tghop fit Rock_Roughness.png --maps Rock_NormalGL.png warns that a roughness is fitted as the colour map, and
    # refuses the colour map given after the maps, or a normal map as EXEMPLAR with no colour map; a manifest row
    # of either was fitted anyway (a wrong material), with a warning. Now it fails as an input failure: the rest
    # run, a rerun skips it until the row changes.
    src = tmp_path / "src"
    src.mkdir()
    albedo = data.bricks(64, rng=3)
    maps = example_maps(albedo, convention="OpenGL")
    save_image(albedo, src / "Rock_Color.png")
    save_image(maps["roughness"], src / "Rock_Roughness.png")
    save_image(maps["normal"], src / "Rock_NormalGL.png")
    save_image(albedo, src / "Wall_Normal.png")  # a colour map misnamed: renamed, the same bytes, it is made
    rows = ["path,name,maps",
            "Rock_Roughness.png,no_colour,Rock_NormalGL.png",
            "Rock_Roughness.png,swapped,Rock_Color.png;Rock_NormalGL.png",
            "Rock_NormalGL.png,normal_first,Rock_Roughness.png",
            "Rock_Color.png,right,Rock_Roughness.png;Rock_NormalGL.png",
            "Wall_Normal.png,misnamed,Rock_Roughness.png"]
    (src / "list.csv").write_text("\n".join(rows) + "\n")
    args = ("batch", "src/list.csv", "-o", "out", "--workers", "1", "--size", "40x48", "--seed", "1", "-N", "6",
            "-W", "30", "--stride", "4", "--pool", "300")
    code, _, err, exc = invoke(*args, cwd=tmp_path)
    assert code == 1 and isinstance(exc, SystemExit) and "Traceback" not in err, (err, exc)
    lines = {r["name"]: r for r in ledger(tmp_path / "out")}
    assert {n: (r["status"], r["cause"]) for n, r in lines.items()} == {
        "no_colour": ("ok", None), "swapped": ("failed", "input"), "normal_first": ("failed", "input"),
        "right": ("ok", None), "misnamed": ("failed", "input")}, lines
    assert ("failed: swapped: the row's path Rock_Roughness.png is named as a roughness map and its map Rock_Color.png "
            "as the colour map; the albedo comes first: swap them, Rock_Color.png as the row's path") in err
    assert "failed: normal_first: the row's path Rock_NormalGL.png is named as a normal map and none of its maps" in err
    assert "Error: 3 of 5 exemplars failed: swapped, normal_first, misnamed" in err
    assert not (tmp_path / "out" / "swapped").exists() and not (tmp_path / "out" / "normal_first").exists()
    said = [w for w in lines["no_colour"]["warnings"] if "it is fitted as the colour map" in w]
    assert len(said) == 1 and said[0].startswith(
        "the row's path Rock_Roughness.png is named as a roughness map and none of its maps as the colour map; it is "
        "fitted as the colour map (its images' albedo, NAME.png); tghop expects the colour map as the row's path"), said
    assert f"Warning: no_colour: {said[0]}" in err
    assert lines["right"]["warnings"] == []
    # A rerun skips them as failed before; the row swapped the right way round is tried again and made, and so is
    # the one whose path was renamed (its bytes, and so the ledger's hash, the same)
    code, _, err, _ = invoke(*args, cwd=tmp_path)
    assert code == 1 and "3 skipped as failed before" in err and "failed: swapped" not in err, err
    rows[2] = "Rock_Color.png,swapped,Rock_Roughness.png;Rock_NormalGL.png"
    (src / "Wall_Normal.png").rename(src / "Wall_Color.png")
    rows[5] = "Wall_Color.png,misnamed,Rock_Roughness.png"
    (src / "list.csv").write_text("\n".join(rows) + "\n")
    code, _, err, _ = invoke(*args, cwd=tmp_path)
    assert code == 1 and "1 skipped as failed before, their input and settings unchanged (normal_first" in err, err
    again = {r["name"]: r for r in ledger(tmp_path / "out")[5:]}
    assert {n: r["status"] for n, r in again.items()} == {"swapped": "ok", "misnamed": "ok"}, again


def test_a_rows_map_named_as_the_colour_map_by_its_given_name_is_the_colour_map_out_of_place():
    # maps: color=Rock_C.png names the colour map by its name, not its file's: the check read the files only, so
    # the row (path Rock_Roughness.png) was fitted with a warning that no map is the colour map; a name of no kind
    # leaves it to the file's name
    from tghop.batch_task import _check_colour_map

    for maps, shown in (([("color", "src/Rock_C.png"), ("Rock_NormalGL", "src/Rock_NormalGL.png")], "Rock_C.png"),
                        ([("layer", "src/Rock_Color.png")], "Rock_Color.png")):
        with pytest.raises(TGHopError, match=rf"^the row's path Rock_Roughness.png is named as a roughness map and its "
                                             rf"map {shown} as the colour map; the albedo comes first: swap them"):
            _check_colour_map("src/Rock_Roughness.png", maps)
    # a name of another kind: not the colour map, whatever its file says
    with pytest.warns(UserWarning, match="none of its maps as the colour map"):
        _check_colour_map("src/Rock_Roughness.png", [("height", "src/Rock_Color.png")])


def test_a_rows_map_is_read_as_every_reader_reads_a_map(tmp_path):
    # One reader (tghop.material_files.read_map): a row's missing map named *.npz was "a model file, not an image"
    # (its extension taken for its content); a model file is still refused by its content, whatever its name.
    import zipfile

    from tghop.batch_task import _read_maps

    with pytest.raises(TGHopError, match=r"x\.npz: no such file"):
        _read_maps([("x", tmp_path / "x.npz")])
    with zipfile.ZipFile(tmp_path / "Rock_Height.png", "w") as archive:  # a zip archive, as np.savez writes
        archive.writestr("meta.npy", b"")
    with pytest.raises(TGHopError, match=r"^the map height \(.*Rock_Height.png\) is a model file, not an image"):
        _read_maps([("height", tmp_path / "Rock_Height.png")])
