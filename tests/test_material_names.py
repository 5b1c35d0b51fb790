"""A material's maps named as the common libraries name them (ambientCG, Poly Haven, Unreal,
Substance): each read as its kind, a normal map as one, and a set that does not fit together told in
one line."""

import warnings

import numpy as np
import pytest

from tghop import TGHop, TGHopError, data
from tghop.map_names import name_kind
from tghop.material import Material, example_maps, is_normal_name, map_kind, normal_convention

#: A small, fast joint model (as tests/test_material.py's).
#: A fast fit (conftest's small models' settings): these tests check names, warnings and channels, not the model.
FAST = dict(max_patches=1500, n_clusters=6, n_codewords=30, stride=4, layout_factor=None)


@pytest.fixture(scope="module")
def exemplar():
    return data.bricks()[:96, :96]


@pytest.fixture(scope="module")
def maps(exemplar):
    return example_maps(exemplar)


@pytest.mark.parametrize("name, kind", [
    ("Rock023_2K_Color.jpg", "albedo"), ("Rock023_2K_NormalGL.png", "normal"), ("Rock023_2K_NormalDX.png", "normal"),
    ("Rock023_2K_Displacement.png", "height"), ("Rock023_2K_AmbientOcclusion.jpg", "ao"),
    ("Rock023_2K_Metalness.jpg", "metallic"), ("Rock023_2K_Opacity.jpg", "opacity"),
    ("rock_wall_diff_2k.jpg", "albedo"), ("rock_wall_nor_gl_2k.png", "normal"), ("rock_wall_nor_dx_4k.exr", "normal"),
    ("rock_wall_rough_2k.jpg", "roughness"), ("rock_wall_arm_2k.jpg", "packed"),
    ("rock-wall-nor-gl-1024.png", "normal"),
    ("T_Rock_BC.png", "albedo"), ("T_Rock_N.png", "normal"), ("T_Rock_ORM.png", "packed"),
    ("Rock_BaseColor.png", "albedo"), ("ROCK_NORMAL_OPENGL.PNG", "normal"), ("bricks.jpg", None), ("gl.png", None)])
def test_the_libraries_map_names_are_read_as_their_kind(name, kind):
    # Poly Haven's rock_wall_nor_gl_2k and Unreal's T_Rock_N were no kind: a remix of them was not warned of.
    assert map_kind(name) == kind
    stem = name.rsplit(".", 1)[0]
    assert name_kind(stem) == kind
    assert is_normal_name(stem) == (kind == "normal")


def test_a_maps_name_is_read_whole_as_its_kind_a_dot_no_extension():
    # tghop.material_files read a map's name (which may hold a '.') as map_kind(name + ".png"): a name is no file's.
    assert name_kind("Rock.Normal") == "normal" and map_kind("Rock.Normal") is None  # '.Normal': the extension
    assert name_kind("rock.wall.nor.gl.2k") == "normal" and name_kind("Rock_2K.v2") is None
    assert name_kind("Rock_ORM") == "packed" and name_kind("bricks") is None and name_kind("gl") is None


def test_a_normal_maps_convention_is_read_from_its_name():
    for name, convention in (("Rock023_2K_NormalGL", "OpenGL"), ("Rock023_2K_NormalDX", "DirectX"),
                             ("rock_wall_nor_gl_2k", "OpenGL"), ("rock_wall_nor_dx_2k", "DirectX"),
                             ("Rock_Normal_DirectX", "DirectX"), ("T_Rock_N", None), ("Rock_Normal", None)):
        assert normal_convention(name) == convention, name


def test_a_poly_haven_normal_map_is_a_normal_map_and_comes_out_unit(exemplar, maps):
    # rock_wall_nor_gl_2k was fitted as a colour map: not checked, and not renormalised after synthesis.
    gl = example_maps(exemplar, convention="OpenGL")["normal"]
    mat = Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"rock_wall_nor_gl_2k": gl,
                                                              "T_Rock_N": maps["normal"][:, ::-1]})
    assert mat.normal_ == [False, True, True]
    out = mat.synthesize((64, 64), rng=1, n_patches=800, refine=1)
    for name in ("rock_wall_nor_gl_2k", "T_Rock_N"):
        np.testing.assert_allclose(np.linalg.norm(out[name] * 2 - 1, axis=2), 1.0, atol=1e-6)


def test_a_map_that_looks_like_a_normal_map_but_is_not_named_so_is_warned_of(exemplar, maps):
    # Rock_bump_nm.png (a normal map by its content, by no known name) was modelled as colours without a word.
    with pytest.warns(UserWarning, match=r"map 'rock_bump_nm' looks like a normal map but its name does not say so"):
        mat = Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"rock_bump_nm": maps["normal"]})
    assert mat.normal_ == [False, False]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # named as one, or given in normal: no warning
        Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"rock_nor_dx": maps["normal"]})  # DirectX's, as named
        Material(model=TGHop(**FAST), normal=["rock_bump_nm"], rng=0).fit(exemplar, {"rock_bump_nm": maps["normal"]})


def test_a_materials_fit_warns_through_the_threads_collector(exemplar, maps):
    # Material.fit's warnings went to warnings.warn, past collect_warnings: on a web server's fit thread they
    # reached the console, not the fit's answer, as every other library warning does since 0.55.
    from tghop._errors import collect_warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # none issued: each kept by the collector
        with collect_warnings() as said:
            Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"rock_bump_nm": maps["normal"]})
    assert [str(w) for w in said if "looks like a normal map" in str(w)], said


def _cli(args, folder):
    from click.testing import CliRunner

    from tghop.cli import main

    return CliRunner().invoke(main, [str(folder / a) if a.endswith((".png", ".jpg", ".npz")) else a for a in args])


FAST_CLI = ["--max-patches", "1500", "--clusters", "6", "--codewords", "30", "--stride", "4", "--layout", "none", "-q"]


def test_a_colour_map_given_after_maps_or_left_out_is_refused_in_one_line(exemplar, maps, tmp_path):
    # The normal map given first was fitted as the albedo (its vectors modelled as colours, written to OUT).
    from tghop.imageio import save_image

    save_image(exemplar, tmp_path / "Rock023_2K_Color.jpg")
    save_image(maps["normal"], tmp_path / "Rock023_2K_NormalGL.png")
    save_image(maps["roughness"], tmp_path / "Rock023_2K_Roughness.jpg")
    for args, words in (
            (["fit", "Rock023_2K_NormalGL.png", "--maps", "Rock023_2K_Roughness.jpg", "Rock023_2K_Color.jpg"],
             "is named as a normal map and --maps {0}/Rock023_2K_Color.jpg as the colour map; the albedo comes first: "
             "tghop fit {0}/Rock023_2K_Color.jpg --maps {0}/Rock023_2K_NormalGL.png {0}/Rock023_2K_Roughness.jpg"),
            (["fit", "Rock023_2K_Roughness.jpg", "--maps", "Rock023_2K_Color.jpg"],
             "is named as a roughness map and --maps {0}/Rock023_2K_Color.jpg as the colour map"),
            (["fit", "Rock023_2K_NormalGL.png", "--maps", "Rock023_2K_Roughness.jpg"],
             "is named as a normal map and no --maps as the colour map (a normal map fitted as the albedo is modelled "
             "as colours, not unit vectors); give the material's colour map first (tghop fit Rock_Color.png --maps "
             "{0}/Rock023_2K_NormalGL.png ...)")):
        res = _cli([*args, "-o", "m.npz"], tmp_path)
        assert res.exit_code == 1 and "Traceback" not in res.output, res.output
        assert res.output.count("\n") == 1 and words.format(tmp_path) in res.output, res.output
    assert not (tmp_path / "m.npz").exists()


def test_a_material_whose_exemplar_is_named_as_another_kind_and_no_colour_map_is_warned_of(exemplar, maps, tmp_path):
    # tghop fit Rock_Roughness.png --maps Rock_NormalGL.png fitted the roughness as the colour map without a word.
    from tghop.imageio import save_image

    save_image(maps["roughness"], tmp_path / "Rock023_2K_Roughness.png")
    save_image(example_maps(exemplar, convention="OpenGL")["normal"], tmp_path / "Rock023_2K_NormalGL.png")
    save_image(exemplar, tmp_path / "Rock023_2K_Color.png")
    res = _cli(["fit", "Rock023_2K_Roughness.png", "--maps", "Rock023_2K_NormalGL.png", "-o", "m.npz", *FAST_CLI],
               tmp_path)
    assert res.exit_code == 0 and (tmp_path / "m.npz").exists(), res.output  # fitted as asked (it may have none)
    said = [line for line in res.output.splitlines() if "as the colour map" in line]
    assert len(said) == 1, res.output
    assert ("is named as a roughness map and no --maps as the colour map; it is fitted as the colour map (written to "
            "OUT); tghop expects the colour map first (named *_Color, *_BaseColor, *_Albedo, *_diff, ...): tghop fit "
            "Rock_Color.png --maps {0}/Rock023_2K_Roughness.png {0}/Rock023_2K_NormalGL.png, or rename".format(tmp_path)
            ) in said[0], said
    res = _cli(["fit", "Rock023_2K_Color.png", "--maps", "Rock023_2K_NormalGL.png", "Rock023_2K_Roughness.png",
                "-o", "m2.npz", *FAST_CLI], tmp_path)
    assert res.exit_code == 0 and "colour map" not in res.output, res.output


def test_fit_says_the_convention_that_comes_out_where_the_name_says_the_other(exemplar, maps, tmp_path):
    """0.59 warned that a map named OpenGL's has DirectX's content and comes out DirectX's, then summed the material
    up as "normal map, OpenGL convention kept": the name's, not what the file records and synth writes."""
    from tghop.imageio import save_image
    from tghop.modelfile import load_model

    save_image(exemplar, tmp_path / "Stone_Color.png")
    save_image(maps["normal"], tmp_path / "Stone_NormalGL.png")  # example_maps' normal map is DirectX's
    res = _cli(["fit", "Stone_Color.png", "--maps", "Stone_NormalGL.png", "-o", "m.npz", *FAST_CLI], tmp_path)
    assert res.exit_code == 0, res.output
    assert "Stone_NormalGL (3 channels, 8-bit, normal map, DirectX by its content (its name says OpenGL), kept)" \
        in res.output, res.output
    assert load_model(tmp_path / "m.npz", material=True).conventions_[1] == "DirectX"


def test_fit_says_which_maps_are_normal_maps_and_that_their_convention_is_kept(exemplar, maps, tmp_path):
    from tghop.imageio import save_image

    dx = maps["normal"]  # example_maps' normal map is DirectX's: green down
    save_image(exemplar, tmp_path / "rock_wall_diff_2k.jpg")
    save_image(dx, tmp_path / "rock_wall_nor_dx_2k.png")
    res = _cli(["fit", "rock_wall_diff_2k.jpg", "--maps", "rock_wall_nor_dx_2k.png", "-o", "m.npz", *FAST_CLI],
               tmp_path)
    assert res.exit_code == 0, res.output
    assert "rock_wall_nor_dx_2k (3 channels, 8-bit, normal map, DirectX convention kept)" in res.output
    res = _cli(["synth", "m.npz", "-o", "out.png", "--size", "64", "--seed", "1", "-q", "--pool", "800"], tmp_path)
    assert res.exit_code == 0, res.output
    from tghop.imageio import load_image

    out = load_image(tmp_path / "out_nor_dx.png")  # rock_wall_nor_dx_2k: its name and resolution dropped
    assert np.abs(np.linalg.norm(out * 2 - 1, axis=2) - 1).max() < 0.02  # unit vectors, to 8 bits
    # kept DirectX (green down): its green falls where the brightness rises down the rows, as the input's does
    slope = np.gradient(load_image(tmp_path / "out.png").mean(axis=2), axis=0)
    assert np.corrcoef(slope.ravel(), out[..., 1].ravel())[0, 1] < -0.5
    assert np.corrcoef(np.gradient(exemplar.mean(axis=2), axis=0).ravel(), dx[..., 1].ravel())[0, 1] < -0.5


def test_example_maps_says_its_normal_maps_convention_and_makes_opengls_too(exemplar, maps):
    # example_maps' normal map was DirectX's (green down) without a word: an artist's demo set was lit upside down
    # in Blender. Its default is kept (the tests' and benchmarks' figures); OpenGL's is its green flipped.
    gl = example_maps(exemplar, convention="OpenGL")
    np.testing.assert_allclose(gl["normal"][..., 1], 1 - maps["normal"][..., 1], atol=1e-12)
    np.testing.assert_array_equal(gl["normal"][..., [0, 2]], maps["normal"][..., [0, 2]])
    bump = np.zeros((33, 33))
    bump[12:21, 12:21] = 1.0  # a raised square: its upper edge faces up the image, green up in OpenGL
    top = example_maps(bump, convention="OpenGL")["normal"][9:12, 14:19, 1]
    assert top.mean() > 0.55 and example_maps(bump)["normal"][9:12, 14:19, 1].mean() < 0.45
    with pytest.raises(TGHopError, match="convention must be 'DirectX' or 'OpenGL'"):
        example_maps(exemplar, convention="GL")


def test_a_batch_folder_of_material_sets_is_warned_of_with_the_manifest_line(tmp_path):
    # tghop batch of a folder of ambientCG / Unreal sets made every map a texture of its own without a word.
    from tghop.batch_plan import find_work

    for rel in ("Rock023/Rock023_2K_Color.jpg", "Rock023/Rock023_2K_NormalGL.png", "Rock023/Rock023_2K_Roughness.jpg",
                "T_Rock/T_Rock_BC.png", "T_Rock/T_Rock_N.png", "bricks/bricks.png", "bricks/cells.png"):
        (tmp_path / rel).parent.mkdir(exist_ok=True)
        (tmp_path / rel).write_bytes(b"")  # only the names are read
    with pytest.warns(UserWarning) as record:
        assert len(find_work(tmp_path, tmp_path / "out")) == 7  # still every image, as before
    messages = [str(w.message) for w in record]
    assert len(messages) == 1 and "Rock023 and 1 other folder hold a material's maps by their names" in messages[0]
    assert messages[0].endswith("e.g. the line Rock023/Rock023_2K_Color.jpg,Rock023/Rock023_2K_NormalGL.png;"
                                "Rock023/Rock023_2K_Roughness.jpg")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # textures only: no warning
        find_work(tmp_path / "bricks", tmp_path / "out")


def test_the_manifest_line_a_batch_folder_is_warned_with_is_one_the_manifest_takes(tmp_path):
    # A folder of an ambientCG set of 10 maps was warned of with a line of 10 maps, which the manifest refused
    # (at most MAX_MAPS); a name with a comma broke the CSV line.
    from tghop.batch_plan import find_work
    from tghop.manifest import MAX_MAPS

    kinds = ("NormalGL", "NormalDX", "Roughness", "Displacement", "AmbientOcclusion", "Metalness", "Opacity",
             "Emission", "Specular", "ORM")
    assert len(kinds) > MAX_MAPS
    for rel in ["Rock,023_2K_Color.jpg"] + [f"Rock,023_2K_{k}.png" for k in kinds]:
        (tmp_path / rel).write_bytes(b"")  # only the names are read
    with pytest.warns(UserWarning) as record:
        find_work(tmp_path, tmp_path / "out")
    message = str(record[0].message)
    assert f"(a material takes at most {MAX_MAPS} maps: Rock,023_2K_NormalGL.png, Rock,023_2K_ORM.png left out)" \
        in message, message
    line = message.split("e.g. the line ")[1].split(" (a material")[0]
    (tmp_path / "list.csv").write_text("path,maps\n" + line + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        items = find_work(tmp_path / "list.csv", tmp_path / "out")
    assert len(items) == 1 and len(items[0]["maps"]) == MAX_MAPS, items
    assert str(items[0]["path"]).endswith("Rock,023_2K_Color.jpg")


def test_a_materials_progress_in_a_log_says_each_map_done_not_stopped(capsys, monkeypatch):
    # A log of `tghop synth MAT.npz -o out.png 2>log` read "maps: stopped at 14 %", "... 28 %", ... at each map.
    import re
    import sys

    import tghop.cli.common as common

    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    progress = common.Progress(True)
    progress("quilting", 1, 1)
    for i in range(3):
        for done in range(5):
            progress("refine", done, 4)
        progress("maps", i + 1, 3)
    progress("writing", 1, 1)
    progress("layout", 1, 4)  # a stage that stops, and two after it: said in its order
    progress("pool", 1, 1)
    progress("quilting", 1, 1)
    progress.close()
    lines = [re.sub(r"^\[\d\d:\d\d:\d\d\] ", "", line).split(" in ")[0].split(" after")[0]
             for line in capsys.readouterr().err.splitlines()]
    assert lines == ["quilting: done"] + ["refine: done"] * 3 + [
        "maps: done", "writing: done", "layout: stopped at 25 %", "pool: done", "quilting: done"], lines


def test_inpaint_and_extend_refuse_the_colour_map_after_maps_as_fit_does(exemplar, maps, tmp_path):
    from tghop.imageio import save_image

    save_image(exemplar, tmp_path / "wall_diff_2k.png")
    save_image(maps["normal"], tmp_path / "wall_nor_gl_2k.png")
    mask = np.zeros(exemplar.shape[:2])
    mask[30:50, 30:50] = 1
    save_image(mask, tmp_path / "hole.png")
    for args, words in (
            (["inpaint", "wall_nor_gl_2k.png", "hole.png", "--maps", "wall_diff_2k.png"],
             "the albedo comes first: tghop inpaint {0}/wall_diff_2k.png MASK --maps {0}/wall_nor_gl_2k.png ..."),
            (["extend", "wall_nor_gl_2k.png", "--maps", "wall_diff_2k.png", "--size", "128x128"],
             "the albedo comes first: tghop extend {0}/wall_diff_2k.png --maps {0}/wall_nor_gl_2k.png ...")):
        res = _cli([*args, "-o", "o.png"], tmp_path)
        assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
        assert "IMAGE " in res.output and words.format(tmp_path) in res.output, res.output
    assert not list(tmp_path.glob("o*.png"))


def test_a_maps_alpha_that_holds_data_is_refused_and_an_opaque_one_dropped(exemplar, maps, tmp_path):
    # Unity's mask map (metal, occlusion, detail, smoothness in A) lost its smoothness with a warning about
    # transparency ("crop it to its opaque part"), and the material came out without it. 0.57-0.58 refused it;
    # since 0.59 a map named as a packing with a map in A keeps it (the next test); any other map's is refused.
    from tghop.batch_task import _read_maps
    from tghop.imageio import save_image

    save_image(exemplar, tmp_path / "Rock_BaseColor.png")
    packed = np.concatenate([maps["roughness"], maps["height"], maps["roughness"]], axis=2)
    save_image(np.concatenate([packed, 1 - maps["roughness"]], axis=2), tmp_path / "Rock_Roughness.png")
    save_image(np.concatenate([packed, np.ones_like(packed[..., :1])], axis=2), tmp_path / "Rock_ORM.png")
    mask = np.zeros(exemplar.shape[:2])
    mask[30:50, 30:50] = 1
    save_image(mask, tmp_path / "hole.png")
    words = "has an alpha channel that holds data (100% of its pixels not opaque: a smoothness, an opacity?)"
    for args in (["fit", "Rock_BaseColor.png", "--maps", "Rock_Roughness.png", "-o", "m.npz", *FAST_CLI],
                 ["inpaint", "Rock_BaseColor.png", "hole.png", "--maps", "Rock_Roughness.png", "-o", "o.png"]):
        res = _cli(args, tmp_path)
        assert res.exit_code == 1 and res.output.count("\n") == 1 and words in res.output, res.output
        assert "Rock_Roughness.png" in res.output and "save the alpha as a map of its own" in res.output
    with pytest.raises(TGHopError, match=r"the map mask \(.*Rock_Roughness.png\) has an alpha channel"):
        _read_maps([("mask", str(tmp_path / "Rock_Roughness.png"))])
    res = _cli(["fit", "Rock_BaseColor.png", "--maps", "Rock_ORM.png", "-o", "m.npz", *FAST_CLI], tmp_path)
    assert res.exit_code == 0 and "Warning" not in res.output, res.output  # an opaque alpha: dropped, no word
    assert "Rock_ORM (3 channels, 8-bit)" in _cli(["info", "m.npz"], tmp_path).output


@pytest.mark.parametrize("name, unused", [("Rock_MaskMap", None), ("Rock_Metallic", 0.0),
                                          ("Rock_MetallicSmoothness", "copy"), ("T_Rock_Metal", "grey")])
def test_a_packing_with_a_map_in_its_alpha_keeps_it_as_its_fourth_channel(name, unused, exemplar, maps, tmp_path):
    # HDRP's mask map (R metallic, G occlusion, B detail mask, A smoothness) and Unity's metallic-smoothness
    # (metalness in R, smoothness in A, G and B unused: zero or copies of R) were refused (0.57-0.58: "save the
    # alpha as a map of its own"), or, given without their alpha, warned of as colours under a metalness's name.
    # Since 0.59 the alpha is a 4th channel, modelled with the others and written back as the file's alpha.
    from tghop.imageio import load_image, save_image

    metal = (maps["height"] > np.quantile(maps["height"], 0.6)).astype(np.float64)
    smooth = 1 - maps["roughness"]
    if unused is None:
        packed = np.concatenate([metal, maps["height"], maps["roughness"], smooth], axis=2)
    elif unused == "grey":  # saved as grey and alpha (LA): metalness and smoothness
        packed = np.concatenate([metal, smooth], axis=2)
    else:
        rest = metal if unused == "copy" else np.full_like(metal, unused)
        packed = np.concatenate([metal, rest, rest, smooth], axis=2)
    save_image(exemplar, tmp_path / "Rock_BaseColor.png")
    save_image(packed, tmp_path / f"{name}.png")
    res = _cli(["fit", "Rock_BaseColor.png", "--maps", f"{name}.png", "-o", "m.npz", *FAST_CLI], tmp_path)
    assert res.exit_code == 0 and "Warning" not in res.output, res.output
    channels = 2 if unused == "grey" else 4
    assert f"{name} ({channels} channels, 8-bit)" in _cli(["info", "m.npz"], tmp_path).output
    res = _cli(["synth", "m.npz", "-o", "out.png", "--size", "64x64", "--seed", "1", "-q", "--pool", "800"], tmp_path)
    assert res.exit_code == 0, res.output
    (written,) = [p for p in tmp_path.glob("out_*.png")]
    made = load_image(written, keep_alpha=True)
    assert made.shape == (64, 64, channels) and made[..., -1].std() > 0.02  # the smoothness, not an opaque alpha
    assert set(np.unique(made[..., 0])) <= {0.0, 1.0}  # the metalness a mask channel, snapped to 0 and 1
    if unused == 0.0:
        assert (made[..., 1:3] == 0).all()  # the unused channels as given
    with warnings.catch_warnings(record=True) as caught:  # without its alpha: no colour warning (G, B unused)
        warnings.simplefilter("always")
        Material(model=TGHop(**FAST)).fit(exemplar, {name: packed[..., :-1] if unused == "grey" else packed[..., :3]})
    assert not [str(w.message) for w in caught if "one value a pixel" in str(w.message)]


def test_a_normal_maps_convention_is_read_from_its_content():
    from tghop.normals import convention_of

    for name in ("bricks", "cells"):
        exemplar = getattr(data, name)()
        assert convention_of(example_maps(exemplar)["normal"]) == "DirectX"
        gl = example_maps(exemplar, convention="OpenGL")["normal"]
        assert convention_of(gl) == "OpenGL" and convention_of((gl * 65535).round().astype(np.uint16)) == "OpenGL"
    v = np.random.default_rng(0).normal(size=(64, 64, 3)) * 0.2
    v[..., 2] = 1
    assert convention_of((v / np.linalg.norm(v, axis=2, keepdims=True) + 1) / 2) is None  # noise: not clear
    assert convention_of(np.tile([0.5, 0.5, 1.0], (8, 8, 1))) is None  # flat


def test_a_mirrored_normal_map_is_told_apart_by_the_height_map_and_has_no_convention(exemplar, maps):
    """0.60: a normal map mirrored left to right (its pixels, red not negated) read as the other convention with
    full confidence (the mixed slopes cannot tell it from that convention's map of the surface inside out), and a
    paint beside a material of its own convention flipped its green. The material's height map is a second cue:
    where the normal map's slopes run against it, its content says no convention, and nothing is flipped; without
    one, the ambient occlusion (an ORM's red) is the cue."""
    from tghop import synthesize_guided
    from tghop.normals import convention_of, surface_map

    normal, height = maps["normal"], maps["height"]
    assert convention_of(normal[:, ::-1]) == "OpenGL"  # alone: indistinguishable
    gl = example_maps(exemplar, convention="OpenGL")
    assert convention_of(normal, height) == "DirectX" and convention_of(gl["normal"], gl["height"][..., 0]) == "OpenGL"
    assert convention_of(normal, (height * 65535).round().astype(np.uint16)) == "DirectX"
    assert convention_of(normal[::-1], height[::-1]) == "OpenGL"  # upside down: an OpenGL map of that surface
    for mirrored, h in ((normal[:, ::-1], height[:, ::-1]), (normal[::-1, ::-1], height[::-1, ::-1]), (normal,
                                                                                                       1 - height)):
        assert convention_of(mirrored, h) is None  # mirrored, turned a half, the height inverted: unsure
    occlusion = np.clip(1 + 4 * (height[..., 0] - np.mean(height)), 0, 1)  # dark in the creases
    assert convention_of(normal[:, ::-1], occlusion[:, ::-1]) is None
    orm = np.concatenate([height, maps["roughness"], height > 0.5], axis=2)
    r = maps["roughness"]
    for given, want in (([("T_Rock_ORM", orm)], orm[..., 0]), ([("Rock_MaskMap", orm[..., ::-1])], orm[..., 1]),
                        ([("r", r), ("Rock_AO", r), ("Rock_Height", height)], height[..., 0]),
                        ([("Rock_AO", r), ("T_Rock_ORM", orm)], r[..., 0])):
        np.testing.assert_array_equal(surface_map(given), want)
    assert surface_map([("Rock_Roughness", r), ("Rock_Height", orm)]) is None  # a height of 3 channels: none
    noise = np.random.default_rng(0).random(height.shape)
    assert convention_of(normal, noise) == "DirectX"  # a height it does not follow says nothing
    with pytest.raises(TGHopError, match="height must be the normal map's 96x96 pixels of one channel"):
        convention_of(normal, height[:48])
    mirrored = Material(model=TGHop(**FAST), rng=0).fit(exemplar[:, ::-1], {k: v[:, ::-1] for k, v in maps.items()})
    assert mirrored.conventions_ == [None, None, None, None]
    own = Material(model=TGHop(**FAST), rng=0).fit(exemplar, maps)
    assert own.conventions_ == [None, "DirectX", None, None]
    guide = np.zeros((48, 64), np.uint8)
    guide[:, 32:] = 255
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # 0.59: "input 2's normal map 'normal' (OpenGL) is in the other convention"
        synthesize_guided([own, mirrored], guide, rng=1, n_patches=800, patch_refine=0)


def test_a_normal_map_named_as_one_convention_but_holding_the_other_is_warned_of(exemplar, maps, tmp_path):
    # A map named NormalGL that holds DirectX's green (a mislabelled export) came out lit upside down, unsaid.
    gl = example_maps(exemplar, convention="OpenGL")["normal"]
    with pytest.warns(UserWarning, match=r"map 'Rock_NormalGL' is named as OpenGL's but its content is DirectX's "
                                         r"\(green down\); it comes out as it is"):
        Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"Rock_NormalGL": maps["normal"]})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"Rock_NormalGL": gl, "Rock_NormalDX": maps["normal"]})
    from tghop.imageio import save_image

    save_image(exemplar, tmp_path / "Rock_BaseColor.png")
    save_image(maps["normal"], tmp_path / "Rock_Normal.png", depth=16)
    res = _cli(["fit", "Rock_BaseColor.png", "--maps", "Rock_Normal.png", "-o", "m.npz", *FAST_CLI], tmp_path)
    assert res.exit_code == 0 and "Rock_Normal (3 channels, 16-bit, normal map, DirectX by its content, kept)" \
        in res.output, res.output


def test_maps_of_another_resolutions_download_are_told_so_in_one_line(exemplar, maps, tmp_path):
    # A 1K roughness beside a 2K colour map was "map 'Rock023_1K_Roughness' is 48x48 but the albedo is 96x96".
    from tghop.imageio import save_image

    save_image(exemplar, tmp_path / "Rock023_2K_Color.jpg")
    save_image(maps["roughness"][::2, ::2], tmp_path / "Rock023_1K_Roughness.jpg")
    save_image(maps["height"][::2, ::2], tmp_path / "height.png")
    for name, hint in (("Rock023_1K_Roughness.jpg", " (named 1K, EXEMPLAR 2K: take every map from one download)"),
                       ("height.png", "")):
        res = _cli(["fit", "Rock023_2K_Color.jpg", "--maps", name, "-o", "m.npz"], tmp_path)
        assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
        assert f"--maps {tmp_path / name} is 48x48 but EXEMPLAR {tmp_path}/Rock023_2K_Color.jpg is 96x96{hint}; give " \
               "every map at the albedo's size" in res.output, res.output


def test_a_colour_image_under_a_grey_maps_name_is_warned_of(exemplar, maps):
    # Maps are classed by name only: the colour map saved as Rock_Roughness.png was modelled as a roughness of 3
    # channels without a word. A map of a kind that holds one value a pixel whose channels differ as a colour
    # photograph's is warned of (grey maps stored as RGB: spread 0; the 38 colour photographs: 0.061 at least);
    # a packed map and a specular one (a metal's colour) are not, nor grey ones.
    from tghop.material import COLOUR_SPREAD, colour_spread

    grey = np.repeat(maps["height"], 3, axis=2)
    packed = np.concatenate([maps["roughness"], maps["height"], 1 - maps["roughness"]], axis=2)
    assert colour_spread(grey) == 0 and colour_spread(exemplar) > 2 * COLOUR_SPREAD
    given = {"Rock_Roughness": exemplar, "Rock_Height": grey, "T_Rock_ORM": packed}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Material(model=TGHop(**FAST)).fit(exemplar, given)
    said = [str(w.message) for w in caught if "one value a pixel" in str(w.message)]
    assert len(said) == 1, [str(w.message) for w in caught]
    assert said[0].startswith("map 'Rock_Roughness' is named as a roughness map, one value a pixel, but its channels "
                              "differ as a colour image's (mean spread 0."), said
    from tghop.map_names import SCALAR_KINDS

    assert name_kind("Rock_Specular") not in SCALAR_KINDS and name_kind("T_Rock_ORM") not in SCALAR_KINDS
