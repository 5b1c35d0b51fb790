"""Whole materials (issue #27, item 5): an albedo and its maps synthesised together, aligned."""

import json
import re
import warnings

import numpy as np
import pytest
from click.testing import CliRunner

from tghop import ModelFileError, TGHop, TGHopError, data
from tghop.cli import main
from tghop.imageio import load_image, save_image
from tghop.material import Material, MapNameClashError, check_map_names, example_maps, renormalise
from tghop.modelfile import load_model, save_model

from conftest import save_texture

SIZE = (96, 96)
#: A small, fast joint model (a few seconds on 2 cores).
FAST = dict(max_patches=1500, n_clusters=10, layout_factor=None)
FAST_CLI = ["--max-patches", "1500", "--clusters", "10", "--layout", "none"]
#: A small pool: quick syntheses.
POOL = dict(n_patches=1000)
#: A faster fit (conftest's small models' settings), for the tests of how maps are named and matched, which never
#: judge the model.
NAMES = dict(max_patches=1500, n_clusters=6, n_codewords=30, stride=4, layout_factor=None)


@pytest.fixture(scope="module")
def exemplar():
    return data.bricks()[:128, :128]


@pytest.fixture(scope="module")
def maps(exemplar):
    return example_maps(exemplar)


@pytest.fixture(scope="module")
def material(exemplar, maps):
    return Material(model=TGHop(**FAST), rng=0).fit(exemplar, maps)


@pytest.fixture(scope="module")
def old_material(exemplar, maps):
    """:func:`material` without the albedo's patch statistics (``patch_levels=0``), as 0.58 fitted every one."""
    return Material(model=TGHop(**FAST, patch_levels=0), rng=0).fit(exemplar, maps)


def _corr(a, b):
    return float(np.corrcoef(np.ravel(a), np.ravel(b))[0, 1])


def test_maps_come_out_aligned_and_normal_maps_unit(material, exemplar, maps):
    out = material.synthesize(SIZE, rng=3, **POOL)
    assert list(out) == ["albedo", "normal", "roughness", "height"]
    assert out["albedo"].shape == SIZE + (3,) and out["normal"].shape == SIZE + (3,)
    assert out["roughness"].shape == SIZE + (1,) and out["height"].shape == SIZE + (1,)
    # roughness = 1 - blurred luminance and height = blurred luminance: functions of the
    # albedo that stay (about) those functions of the output's albedo
    lum = out["albedo"].mean(axis=2)
    for name in ("roughness", "height"):
        want = _corr(exemplar.mean(axis=2), maps[name])
        got = _corr(lum, out[name])
        assert abs(got - want) < 0.1, (name, want, got)
    lengths = np.linalg.norm(out["normal"] * 2 - 1, axis=2)
    np.testing.assert_allclose(lengths, 1.0, atol=1e-6)
    # the normal map follows the height's slope
    gy, gx = np.gradient(out["height"][..., 0])
    assert _corr(gx, out["normal"][..., 0]) < -0.6 and _corr(gy, out["normal"][..., 1]) < -0.6


def test_a_material_at_a_working_scale_learns_every_map_there(exemplar, maps, monkeypatch):
    from tghop.refine import BandStatistics
    from tghop.scale import rescale

    events, fit = [], BandStatistics.fit  # each map's band statistics came after the joint model's last stage, unsaid

    def marked(*args, **kwargs):
        events.append("bands")
        return fit(*args, **kwargs)

    monkeypatch.setattr(BandStatistics, "fit", marked)
    material = Material(model=TGHop(scale=0.75, **FAST), rng=0).fit(
        exemplar, maps, progress=lambda *call: events.append(call))
    monkeypatch.undo()
    assert events[-9:] == [("maps", 0, 4), "bands", ("maps", 1, 4), "bands", ("maps", 2, 4), "bands", ("maps", 3, 4),
                           "bands", ("maps", 4, 4)], events[-12:]
    assert material.model_.exemplar_shape_[:2] == (96, 96)
    height = BandStatistics(n_levels=material.model_.band_levels,
                            n_orientations=material.model_.band_orientations).fit(rescale(maps["height"], 0.75))
    np.testing.assert_array_equal(material.bands_[3].band_quantiles_, height.band_quantiles_)
    out = material.synthesize(SIZE, rng=3, **POOL)
    lengths = np.linalg.norm(out["normal"] * 2 - 1, axis=2)
    np.testing.assert_allclose(lengths, 1.0, atol=1e-6)


def test_channel_counts_not_given_are_the_stacked_channels_defaults(exemplar, maps, material):
    # 3 + 3 + 1 + 1 stacked channels: K2 by default 22 * 8 / 3 -> 59, with K1 given (tghop fit --k1 alone)
    k1 = Material(model=TGHop(n_channels=(20, None), **FAST), rng=0).fit(exemplar, maps)
    assert k1.model_.channels_ == [20, 59]
    assert material.model_.channels_ == [24, 59]  # the module's, of FAST


@pytest.mark.parametrize("path, name", [("Rock Normal.png", "Rock_Normal"), ("a/b/rock_n.png", "rock_n"),
                                        ("..hidden.png", "hidden"), ("\u00fc.png", "map"), ("a.b.tif", "a.b"),
                                        ("x" * 80 + ".png", "x" * 64)])
def test_a_maps_name_from_its_file_is_one_that_can_name_a_file(path, name):
    from tghop.material import map_name

    assert map_name(path) == name


def test_same_seed_same_maps(material):
    a, b = material.synthesize(SIZE, rng=5, **POOL), material.synthesize(SIZE, rng=5, **POOL)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    c = material.synthesize(SIZE, rng=6, **POOL)
    assert not np.array_equal(a["albedo"], c["albedo"])


def test_progress_goes_on_through_the_maps_and_stops_them(material):
    """The maps' refinement reports progress too: a server's Stop (a progress callback that
    raises) stopped only the joint model's quilting, the maps' refinement ran on to its end."""
    stages = []
    material.synthesize((40, 40), rng=1, refine=2, progress=lambda stage, done, total: stages.append(stage))
    last_quilt = max(i for i, s in enumerate(stages) if s != "refine" and s != "maps")
    assert "refine" in stages[last_quilt:] and stages[-1] == "maps"
    assert stages.count("maps") == len(material.names_)

    class Stop(Exception):
        pass

    def stop_in_refine(stage, done, total):
        if stage in ("refine", "maps"):
            raise Stop

    with pytest.raises(Stop):
        material.synthesize((40, 40), rng=1, refine=2, progress=stop_in_refine)


def test_model_file_round_trip(material, tmp_path):
    save_model(material, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz", material=True)
    assert loaded.names_ == material.names_ and loaded.normal_ == material.normal_
    a, b = material.synthesize(SIZE, rng=1, **POOL), loaded.synthesize(SIZE, rng=1, **POOL)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    with pytest.raises(ModelFileError, match="is a material"):  # where a plain model is expected
        load_model(tmp_path / "m.npz")


def test_settings_changed_after_fit_are_refused_as_a_tghops_are(material, tmp_path):
    # A TGHop whose settings change after fit is refused until it is fitted again; a Material synthesised on with
    # the old joint model, its get_params saying another (set_params(model__gamma=...), normal=...).
    import copy

    from tghop import NotFittedError

    mat = copy.deepcopy(material)
    gamma = mat.model.gamma
    mat.set_params(model__gamma=0.5)
    with pytest.raises(NotFittedError, match=rf"^this Material's settings changed after it was fitted "
                                             rf"\(model__gamma {gamma} -> 0.5\); fit it again"):
        mat.synthesize(SIZE, rng=1, **POOL)
    mat.set_params(model__gamma=gamma)
    assert set(mat.synthesize(SIZE, rng=1, **POOL)) == set(material.names_)
    for change in (dict(normal="none"), dict(model=TGHop(**FAST))):
        with pytest.raises(NotFittedError, match="settings changed after it was fitted"):
            copy.deepcopy(material).set_params(**change).map_slices()
    copy.deepcopy(material).set_params(rng=5, model__rng=3).map_slices()  # the fit's seed: nothing learned changes
    save_model(material, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz", material=True)
    loaded.map_slices()
    with pytest.raises(NotFittedError, match=r"\(model__n_clusters 10 -> 9\)"):
        loaded.set_params(model__n_clusters=9).map_slices()


def test_maps_of_another_size_are_refused(exemplar, maps):
    with pytest.raises(TGHopError, match="albedo's size") as err:
        Material(model=TGHop(**FAST)).fit(exemplar, {"height": maps["height"][:100]})
    assert "\n" not in str(err.value)


def test_a_normal_map_that_is_not_one_is_refused(exemplar, maps):
    with pytest.raises(TGHopError, match="not unit vectors"):
        Material(model=TGHop(**FAST)).fit(exemplar, {"normal": exemplar})  # colours, not unit vectors
    with pytest.raises(TGHopError, match="not 3"):
        Material(model=TGHop(**FAST)).fit(exemplar, {"my_normal": maps["roughness"]})


def test_renormalise_makes_unit_vectors():
    v = np.random.default_rng(0).random((5, 6, 3))
    n = renormalise(v) * 2 - 1
    np.testing.assert_allclose(np.linalg.norm(n, axis=2), 1.0, atol=1e-12)
    flat = renormalise(np.full((2, 2, 3), 0.5))  # a zero vector points straight up
    np.testing.assert_allclose(flat, np.tile([0.5, 0.5, 1.0], (2, 2, 1)))


def _write_material(folder, exemplar, maps):
    save_image(exemplar, folder / "albedo.png")
    save_image(maps["normal"], folder / "normal.png")
    save_image(maps["roughness"], folder / "roughness.png")
    save_image(maps["height"], folder / "height.png", depth=16)


def test_cli_fit_and_synth_write_every_map(tmp_path, exemplar, maps):
    _write_material(tmp_path, exemplar, maps)
    runner = CliRunner()
    files = [str(tmp_path / f) for f in ("albedo.png", "normal.png", "roughness.png", "height.png")]
    res = runner.invoke(main, ["fit", files[0], "--maps", *files[1:], "-o", str(tmp_path / "mat.npz"), "-q",
                               *FAST_CLI])
    assert res.exit_code == 0, res.output
    out = tmp_path / "out.png"
    res = runner.invoke(main, ["synth", str(tmp_path / "mat.npz"), "-o", str(out), "--size", "64", "--seed", "2",
                               "-q", "--pool", "1000"])
    assert res.exit_code == 0, res.output
    for name, depth, channels in (("out", 8, 3), ("out_normal", 8, 3), ("out_roughness", 8, 1),
                                  ("out_height", 16, 1)):
        image, got = load_image(tmp_path / f"{name}.png", with_depth=True)
        assert (got, image.shape) == (depth, (64, 64, channels)), name
    info = runner.invoke(main, ["info", str(tmp_path / "mat.npz")])
    assert info.exit_code == 0 and "height (1 channel, 16-bit)" in info.output


def test_cli_synth_warns_once_of_the_maps_a_format_writes_with_fewer_bits(tmp_path, exemplar, maps):
    # synth mat.npz -o out.jpg wrote a 16-bit and a float map as 8-bit JPEG without a word, where a
    # 16-bit exemplar written with 8 bits is warned of: one warning naming those maps and the fix.
    material = Material(model=TGHop(**FAST), rng=0).fit(
        exemplar, {"height": maps["height"], "roughness": maps["roughness"], "normal": maps["normal"]},
        depths={"albedo": 8, "height": 16, "roughness": 32, "normal": 8})
    save_model(material, tmp_path / "mat.npz")

    def synth(name, *more):
        res = CliRunner().invoke(main, ["synth", str(tmp_path / "mat.npz"), "-o", str(tmp_path / name), "--size",
                                        "64", "--seed", "2", "-q", "--pool", "1000", *more])
        assert res.exit_code == 0, res.output
        return [line for line in res.output.splitlines() if line.startswith("Warning")]

    warned = synth("out.jpg")
    assert warned == ["Warning: maps height (16-bit) and roughness (float) have more bits a channel than JPEG "
                      "holds, but are written with 8; name the output .tif or .tiff to keep them"]
    assert load_image(tmp_path / "out_height.jpg", with_depth=True)[1] == 8
    warned = synth("out.png")
    assert warned == ["Warning: map roughness (float) has more bits a channel than PNG holds, but is written with "
                      "16; name the output .tif or .tiff to keep them"]
    assert load_image(tmp_path / "out_height.png", with_depth=True)[1] == 16
    assert synth("out.tif") == []  # every depth held
    assert synth("chosen.jpg", "--depth", "8") == []  # asked for


def test_cli_fit_names_a_map_file_with_spaces_as_the_page_does(tmp_path, exemplar, maps):
    save_image(exemplar, tmp_path / "albedo.png")
    save_image(maps["height"], tmp_path / "Rock Height.png")
    res = CliRunner().invoke(main, ["fit", str(tmp_path / "albedo.png"), "--maps", str(tmp_path / "Rock Height.png"),
                                    "-o", str(tmp_path / "mat.npz"), "-q", *FAST_CLI])
    assert res.exit_code == 0, res.output
    assert load_model(tmp_path / "mat.npz", material=True).names_ == ["albedo", "Rock_Height"]



def test_one_check_refuses_two_maps_of_one_name_or_a_map_named_as_the_albedo(exemplar, maps):
    # The command line, a batch manifest, the web server and Material.fit each had their own loop for it.
    check_map_names(["normal", "height", "Rock_Height"])  # distinct: nothing raised
    check_map_names([])
    for names, index, albedo in ((["normal", "height", "Normal"], 2, False), (["h", "ALBEDO", "h"], 1, True),
                                 (["a", "b", "a", "b"], 2, False)):
        with pytest.raises(MapNameClashError) as err:
            check_map_names(names)
        exc = err.value
        assert isinstance(exc, TGHopError) and (exc.name, exc.index, exc.albedo) == (names[index], index, albedo)
        assert repr(names[index]) in str(exc) and "\n" not in str(exc)
        assert ("the albedo's name" in str(exc)) == albedo
    # Material.fit says the clash as it is (0.60: "two maps are named 'Height'" of height and Height, and of a
    # map named Albedo, without a word of case or of the albedo)
    for named, said in (({"height": maps["height"], "Height": maps["height"]},
                         "two maps are named 'height' and 'Height', which differ only in case (one file name where "
                         "case is ignored); give each map its own name, not only in case"),
                        ({"Albedo": maps["height"]},
                         "a map is named 'Albedo', the albedo's name in another case; give each map its own name")):
        with pytest.raises(TGHopError, match=f"^{re.escape(said)}$"):
            Material(model=TGHop(**FAST), rng=0).fit(exemplar, named)

def test_cli_failures_are_one_line_and_write_nothing(tmp_path, exemplar, maps):
    _write_material(tmp_path, exemplar, maps)
    runner = CliRunner()
    save_image(maps["height"][:100], tmp_path / "small_height.png")
    for args, words in (
            (["fit", "albedo.png", "--maps", "small_height.png", "-o", "m.npz"], "albedo's size"),
            (["fit", "albedo.png", "height.png", "-o", "m.npz"], "--maps"),
            # "two maps are named 'albedo'" with one map given
            (["fit", "height.png", "--maps", "albedo.png", "-o", "m.npz"],
             "albedo.png is named 'albedo', the name of EXEMPLAR itself")):
        res = runner.invoke(main, [str(tmp_path / a) if a.endswith(".png") else a for a in args])
        assert res.exit_code != 0 and "Traceback" not in res.output
        assert words in res.output
    assert not list(tmp_path.glob("*.npz"))
    material = Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"height": maps["height"]})
    save_model(material, tmp_path / "mat.npz")
    (tmp_path / "o_height.png").mkdir()  # the second map's output cannot be written
    res = runner.invoke(main, ["synth", str(tmp_path / "mat.npz"), "-o", str(tmp_path / "o.png"), "--size", "64",
                               "-q", "--pool", "1000"])
    assert res.exit_code != 0 and res.output.strip().count("\n") == 0 and "folder" in res.output
    assert not (tmp_path / "o.png").exists()
    res = runner.invoke(main, ["synth", str(tmp_path / "mat.npz"), "-o", "-", "--size", "64", "-q"])
    assert res.exit_code != 0 and "file per map" in res.output


def test_impossible_depths_are_refused_at_fit(exemplar, maps):
    """Review 58, item 2: depths the model file refuses (7, 12, a name no map has) are refused by fit."""
    for depths, words in (({"height": 12}, "depths['height'] must be 8, 16 or 32"),
                          ({"albedo": 7}, "depths['albedo'] must be 8, 16 or 32"),
                          ({"height": True}, "must be 8, 16 or 32"),
                          ({"foo": 16}, "depths names 'foo', which is not a map's name"),
                          ([16], "depths must be a dict")):
        with pytest.raises(TGHopError, match=re.escape(words)) as err:
            Material(model=TGHop(**FAST)).fit(exemplar, {"height": maps["height"]}, depths=depths)
        assert "\n" not in str(err.value)


def test_wrong_kinds_of_argument_name_the_argument(exemplar, maps):
    """Review 58, item 13: a wrong model, maps or normal gives a TGHopError naming it and the type expected."""
    for material, given, words in (
            (Material(model="x"), {"height": maps["height"]}, "model must be a TGHop (the joint model's settings) "
                                                               "or None, got str"),
            (Material(model=TGHop(**FAST)), [maps["height"]], "maps must be a dict of map name -> array, got list"),
            (Material(model=TGHop(**FAST), normal=5), maps, "normal must be 'auto', a map's name or a list"),
            (Material(model=TGHop(**FAST), normal=["normal", 1]), maps, "normal must be 'auto'"),
            (Material(model=TGHop(**FAST), normal="bump"), maps, "normal names 'bump', which is not a map's name")):
        with pytest.raises(TGHopError, match=re.escape(words)):
            material.fit(exemplar, given)


def test_normal_as_one_string_and_depths_reach_the_model_file(exemplar, maps, tmp_path):
    """normal="bump" names one map (not the letters b, u, m, p); a normal map whose three channels are equal
    (unit vectors pointing along the diagonal) stays three channels; the depths given are written and read back."""
    diagonal = np.full(exemplar.shape[:2] + (3,), (1 + 1 / np.sqrt(3)) / 2)
    material = Material(model=TGHop(**FAST), normal="bump", rng=0).fit(
        exemplar, {"bump": diagonal, "height": maps["height"]}, depths={"height": 16, "albedo": 8})
    assert material.normal_ == [False, True, False] and material.map_channels_ == [3, 3, 1]
    assert material.depths_ == [8, 32, 16]
    save_model(material, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz", material=True)
    assert loaded.map_info() == material.map_info()


def test_a_normal_map_of_equal_channels_is_refused_for_its_vectors(exemplar):
    """Review 58, item 15: a 3-channel normal map is checked before grey maps become one channel."""
    with pytest.raises(TGHopError, match="not unit vectors"):
        Material(model=TGHop(**FAST)).fit(exemplar, {"normal": np.full(exemplar.shape[:2] + (3,), 0.5)})


def test_synthesize_checks_its_settings_as_tghop_does(material):
    """Review 58, item 14: the checks of TGHop.synthesize, and refine_maps as a boolean."""
    for kwargs, words in (({"refine": 100}, "refine must be an integer >= 0 and <= 20, got 100"),
                          ({"refine": 2.0}, "refine must be an integer >= 0 and <= 20, got 2.0; write 2"),
                          ({"match_colours": "no"}, "match_colours must be True or False, got 'no'"),
                          ({"tile": "no"}, "tile must be True or False, got 'no'"),
                          ({"refine_maps": "no"}, "refine_maps must be True or False, got 'no'"),
                          ({"n_patches": 0}, "n_patches must be"),
                          ({"no_such_setting": 1}, "unknown setting 'no_such_setting'"),
                          ({"patch_refine": -1}, "patch_refine must be")):
        with pytest.raises(TGHopError, match=re.escape(words)):
            material.synthesize(SIZE, rng=1, **kwargs)


def test_the_albedo_is_patch_refined_the_maps_kept_and_a_material_without_statistics_refuses_it(material,
                                                                                                   old_material,
                                                                                                   tmp_path):
    """0.59: a material's albedo is patch-refined with its own statistics (0.58 refused patch_refine for a
    material, and its albedo came out blockier than the texture's); the other maps are 0.58's, the model file
    keeps the statistics; a material fitted with patch_levels 0 (as every material of 0.58) refuses it."""
    assert material.albedo_patches() is not None and material.albedo_patches().directions_.shape[-1] == 5 * 5 * 3
    auto, off = material.synthesize(SIZE, rng=1, **POOL), material.synthesize(SIZE, rng=1, patch_refine=0, **POOL)
    assert np.abs(auto["albedo"] - off["albedo"]).mean() > 1e-3
    assert all(np.array_equal(auto[k], off[k]) for k in auto if k != "albedo")
    more = material.synthesize(SIZE, rng=1, patch_refine=4, patch_stride=1, **POOL)
    assert not np.array_equal(more["albedo"], auto["albedo"]) and np.array_equal(more["height"], auto["height"])
    save_model(material, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz", material=True)
    again = loaded.synthesize(SIZE, rng=1, **POOL)
    assert all(np.array_equal(auto[k], again[k]) for k in auto)
    import json

    with np.load(tmp_path / "m.npz") as f:  # the file's statistics checked as a texture model's are
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays["__meta__"]))
    assert meta["material"]["patch_levels"] == 4 and "material_patch.patch.directions" in arrays
    for change, words in (({"patch_levels": 1.5}, "patch_levels is not a whole number"),
                          ({"patch_levels": 1}, "material_patch.patch.directions has 4 entries along axis 0")):
        with open(tmp_path / "bad.npz", "wb") as fh:
            np.savez(fh, **{**arrays, "__meta__": np.array(json.dumps({**meta, "material": {**meta["material"],
                                                                                             **change}}))})
        with pytest.raises(ModelFileError, match=words):
            load_model(tmp_path / "bad.npz", material=True)
    old = old_material
    assert old.albedo_patches() is None
    plain = old.synthesize(SIZE, rng=1, **POOL)
    assert all(np.array_equal(plain[k], off[k]) for k in plain)  # the same joint model; the albedo as 0.58's
    with pytest.raises(TGHopError, match="patch_refine=2 needs the albedo's patch statistics"):
        old.synthesize(SIZE, rng=1, patch_refine=2, **POOL)


def test_a_material_with_albedo_patches_is_format_version_11_and_others_keep_theirs(exemplar, material,
                                                                                    old_material, tmp_path):
    """0.59: a material's albedo patch statistics (material_patch.*) make its file format version 11, so that tghop
    0.58 (which reads 2 to 10) refuses it by its version, "by tghop ..., a newer tghop ...", rather than as "an
    edited file or another program's" by the unknown array; a material without them stays 10 (0.58 reads it); a
    version above this tghop's says to upgrade."""
    import json

    from tghop.modelfile import FORMAT_VERSION, READABLE_VERSIONS, WITHOUT_MATERIAL_PATCHES

    def version(model, name):
        save_model(model, tmp_path / name)
        with np.load(tmp_path / name) as f:
            return json.loads(str(f["__meta__"]))["format_version"], {k: f[k] for k in f.files}

    got, arrays = version(material, "m.npz")
    assert got == FORMAT_VERSION == 11 and WITHOUT_MATERIAL_PATCHES == 10
    assert version(old_material, "old.npz")[0] == 10
    assert version(TGHop(**FAST).fit(exemplar), "plain.npz")[0] == 10 and READABLE_VERSIONS[-1] == 11
    meta = json.loads(str(arrays["__meta__"]))
    with open(tmp_path / "newer.npz", "wb") as fh:
        np.savez(fh, **{**arrays, "__meta__": np.array(json.dumps({**meta, "format_version": 12}))})
    with pytest.raises(ModelFileError, match=r"version 12 \(by tghop .*, a newer tghop\).*upgrade tghop to read it, "
                                             "or refit the model"):
        load_model(tmp_path / "newer.npz", material=True)


@pytest.mark.parametrize("keep_levels", [True, False])
def test_a_material_whose_albedo_patches_say_format_version_10_is_refused(material, tmp_path, keep_levels):
    """material_patch.* came with format version 11 (0.59), and a version holds a fixed set of arrays: 0.60 read a file
    saying 10 that held them (and material.patch_levels) as if it were 11. Refused, naming both versions."""
    import json

    save_model(material, tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz") as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays["__meta__"]))
    meta["format_version"] = 10
    if not keep_levels:  # the arrays alone: 0.60 named the first as unknown, without the version it belongs to
        del meta["material"]["patch_levels"]
    with open(tmp_path / "v10.npz", "wb") as fh:
        np.savez(fh, **{**arrays, "__meta__": np.array(json.dumps(meta))})
    with pytest.raises(ModelFileError, match=r"v10.npz: this model file was edited, damaged or written by another "
                                             r"program, so tghop cannot use it; fit the material again from its maps: "
                                             r"tghop fit ALBEDO --maps MAP \.\.\. -o \S+v10.npz \(what is wrong: the "
                                             r"albedo's patch statistics \(material_patch.\*\) in format version 10; "
                                             r"they are version 11's\)$"):
        load_model(tmp_path / "v10.npz", material=True)


@pytest.mark.parametrize("new, said", [
    ("h" * 70, "the material metadata has a bad map name 'hhhhhhhhhhhhhhhhhhhhhhhhhhhhhhhhhhhhhhhh...' (letters, "
               "digits, '.', '_' or '-', at most 64)"),
    ("Normal", "the material metadata's map names clash: two maps are named 'normal' and 'Normal', which differ only "
               "in case (one file name where case is ignored)"),
    ("Albedo", "the material metadata's map names clash: a map is named 'Albedo', the albedo's name in another case"),
])
def test_a_material_file_whose_map_names_were_edited_says_what_is_wrong(material, tmp_path, new, said):
    """0.60 read a map name of 70 characters (a file of tghop cuts them to 64, as they name files) and said "a bad or
    repeated map name 'Normal'" of two names alike but for case, or of a map named as the albedo."""
    import json

    save_model(material, tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz") as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays["__meta__"]))
    old = meta["material"]["maps"][-1]["name"]  # the last map, renamed, its statistics with it
    meta["material"]["maps"][-1]["name"] = new
    for part in ("levels", "channel_levels", "conventions"):
        if old in meta["material"].get(part, {}):
            meta["material"][part][new] = meta["material"][part].pop(old)
    arrays = {k.replace(f"material.{old}.", f"material.{new}."): v for k, v in arrays.items()}
    with open(tmp_path / "edited.npz", "wb") as fh:
        np.savez(fh, **{**arrays, "__meta__": np.array(json.dumps(meta))})
    with pytest.raises(ModelFileError, match=re.escape(f"edited.npz (what is wrong: {said})")):
        load_model(tmp_path / "edited.npz", material=True)


def test_cli_refuses_patch_refinement_of_a_material_without_statistics_by_its_options(old_material, tmp_path):
    """Review 58, item 8: the options typed are named, not the library's patch_refine (0.59: a material fitted
    without patch statistics, as 0.58 fitted every material)."""
    save_model(old_material, tmp_path / "mat.npz")
    runner = CliRunner()
    for args, words in ((["--quality", "best"], "Error: --quality best does not apply to this material"),
                        (["--patch-refine", "5"], "Error: --patch-refine does not apply to this material"),
                        (["--quality", "best", "--patch-refine", "5"], "--quality best and --patch-refine do not"),
                        # --patch-stride was silently ignored (a material has no patch refinement)
                        (["--patch-stride", "3"], "Error: --patch-stride does not apply to this material (it has no "
                                                  "patch statistics: fitted by tghop 0.58 or older, or with "
                                                  "--patch-levels 0); fit it again, or drop it"),
                        (["--patch-refine", "5", "--patch-stride", "3"], "--patch-refine and --patch-stride do not"),
                        (["-o", "-"], "Error: a material writes a file per map; give -o a file name")):
        res = runner.invoke(main, ["synth", str(tmp_path / "mat.npz"), "-o", str(tmp_path / "o.png"), "--size", "64",
                                   "-q", *args])
        assert res.exit_code == 2 and "Traceback" not in res.output, res.output  # usage errors (they exited 1)
        assert words in res.output and "patch_refine" not in res.output, res.output
        assert res.output.strip().count("\n") == 0
    assert not list(tmp_path.glob("*.png"))



def test_cli_stages_of_a_material_writes_each_steps_maps_the_last_its_output(material, tmp_path):
    # 0.60 refused synth MAT --stages ("applies to a texture model, not a material").
    save_model(material, tmp_path / "mat.npz")
    res = CliRunner().invoke(main, ["synth", str(tmp_path / "mat.npz"), "-o", str(tmp_path / "o.png"), "--size",
                                    "64", "--seed", "1", "-q", "--stages", "--pool", "1000"])
    assert res.exit_code == 0, res.output
    assert ("steps written beside it, each with its maps: o_quilt.png, o_seams.png, o_refine.png, o_patch-refine.png, "
            "o_colour.png, o_maps.png") in res.output
    maps = [""] + [f"_{name}" for name in material.names_[1:]]  # o.png, o_normal.png, ...
    steps = ["", "_quilt", "_seams", "_refine", "_patch-refine", "_colour", "_maps"]
    assert sorted(p.name for p in tmp_path.glob("o*.png")) == sorted(f"o{s}{m}.png" for s in steps for m in maps)
    for m in maps:  # the last step's maps are those written
        assert np.array_equal(load_image(tmp_path / f"o_maps{m}.png"), load_image(tmp_path / f"o{m}.png")), m
    assert not np.array_equal(load_image(tmp_path / "o_quilt.png"), load_image(tmp_path / "o.png"))
    plain = tmp_path / "plain"
    plain.mkdir()
    res = CliRunner().invoke(main, ["synth", str(tmp_path / "mat.npz"), "-o", str(plain / "o.png"), "--size", "64",
                                    "--seed", "1", "-q", "--pool", "1000"])
    assert res.exit_code == 0 and np.array_equal(load_image(plain / "o.png"), load_image(tmp_path / "o.png"))


def test_synth_help_names_every_step_a_material_writes():
    # It named OUTPUT_quilt first and _maps last: a material with a layout writes OUTPUT_guide first, and each
    # material writes OUTPUT_colour (after _patch-refine), which it did not name.
    text = " ".join(CliRunner().invoke(main, ["synth", "--help-all"]).output.split())
    said = text[text.index("A material's (0.61)"):text.index("Several SOURCEs or --guide (0.61)")]
    assert "OUTPUT_guide, OUTPUT_guide_<map>, where it has a layout" in said and "_colour after _patch-refine" in said


def test_cli_stages_of_a_material_with_a_map_named_as_a_step_say_so(material, tmp_path):
    # A map named 'quilt' is written as o_quilt.png, the albedo's quilt step's name: it was refused as "-o and
    # --stages: one would be written over the other; give each its own name", which no -o can do.
    import copy

    named = copy.deepcopy(material)
    named.names_ = [("quilt" if name == "roughness" else name) for name in named.names_]
    save_model(named, tmp_path / "mat.npz")
    res = CliRunner().invoke(main, ["synth", str(tmp_path / "mat.npz"), "-o", str(tmp_path / "o.png"), "--size",
                                    "64", "--seed", "1", "-q", "--stages"])
    assert res.exit_code == 1 and "Traceback" not in res.output and res.output.strip().count("\n") == 0, res.output
    assert (f"Error: map quilt is written as {tmp_path / 'o_quilt.png'}, the name --stages gives the quilt step's "
            "albedo; drop --stages, or give that map's file another name") in res.output, res.output
    assert not list(tmp_path.glob("*.png"))  # nothing made


def test_cli_patch_refines_a_materials_albedo(material, tmp_path):
    """0.59: synth MAT --patch-refine N (and --quality best) refine the albedo; 0.58 refused them for a material."""
    save_model(material, tmp_path / "mat.npz")
    out = {}
    for steps in ("0", "3"):
        res = CliRunner().invoke(main, ["synth", str(tmp_path / "mat.npz"), "-o", str(tmp_path / f"o{steps}.png"),
                                        "--size", "64", "--seed", "1", "-q", "--patch-refine", steps, "--pool",
                                        "1000"])
        assert res.exit_code == 0, res.output
        out[steps] = {p.name[2:]: load_image(p) for p in tmp_path.glob(f"o{steps}*.png")}
    assert set(out["3"]) == {".png", "_normal.png", "_roughness.png", "_height.png"}
    assert not np.array_equal(out["0"][".png"], out["3"][".png"])
    assert all(np.array_equal(out["0"][k], out["3"][k]) for k in out["3"] if k != ".png")


@pytest.fixture(scope="module")
def second():
    cells = data.cells(64, rng=3)
    return Material(model=TGHop(**FAST), rng=0).fit(cells, example_maps(cells))


def test_painted_materials_share_one_join_in_every_map(material, second):
    from tghop import synthesize_guided

    guide = np.zeros((64, 96), np.uint8)
    guide[:, 48:] = 255
    out = synthesize_guided([material, second], guide, rng=2, transition=16, **POOL)
    assert list(out) == material.names_ and [v.shape for v in out.values()] == [(64, 96, 3)] * 2 + [(64, 96, 1)] * 2
    np.testing.assert_allclose(np.linalg.norm(out["normal"] * 2 - 1, axis=2), 1.0, atol=1e-6)
    # Away from the band (8 px each side of column 48) every map is its material's own synthesis with the
    # layer's stream: the regions are whole materials, aligned, and the join is one for all maps.
    rng = np.random.default_rng(2)
    seeds = [np.random.default_rng(rng.integers(0, 2**63 - 1)) for _ in range(2)]
    a = material.synthesize((64, 57), rng=seeds[0], **POOL)  # the boxes: each half, 8 + 1 px more
    b = second.synthesize((64, 57), rng=seeds[1], **POOL)
    for name in out:
        np.testing.assert_allclose(out[name][:, :38], a[name][:, :38], atol=1e-12)
        np.testing.assert_allclose(out[name][:, 58:], b[name][:, 19:], atol=1e-12)
    eight = synthesize_guided([material, second], guide, rng=2, transition=16, dtype=np.uint8, **POOL)
    assert all(v.dtype == np.uint8 for v in eight.values())
    with pytest.raises(TGHopError, match="input 2 is not a material but input 1 is; give all materials"):
        synthesize_guided([material, material.model_], guide, **POOL)


def test_painted_materials_patch_refine_each_albedo_by_its_own_statistics(material, second):
    """0.60: patch_refine (quality best) of painted or remixed materials refines each layer's albedo with its own
    material's patch statistics (0.59 refused it above 0); away from the join the other maps are those without
    it, bit for bit."""
    import copy

    from tghop import synthesize_guided

    guide = np.zeros((64, 96), np.uint8)
    guide[:, 48:] = 255
    best = dict(patch_refine=3, patch_stride=1, **POOL)
    out = synthesize_guided([material, second], guide, rng=2, transition=16, **best)
    off = synthesize_guided([material, second], guide, rng=2, transition=16, patch_refine=0, **POOL)
    rng = np.random.default_rng(2)
    seeds = [np.random.default_rng(rng.integers(0, 2**63 - 1)) for _ in range(2)]
    a = material.synthesize((64, 57), rng=seeds[0], **best)  # each half's box, refined by its own material
    b = second.synthesize((64, 57), rng=seeds[1], **best)
    for name in out:  # away from the band every map is its material's own
        np.testing.assert_allclose(out[name][:, :38], a[name][:, :38], atol=1e-12)
        np.testing.assert_allclose(out[name][:, 58:], b[name][:, 19:], atol=1e-12)
    for half in (np.s_[:, :38], np.s_[:, 58:]):  # the other maps as without it (in the band the one join follows
        assert np.abs(out["albedo"][half] - off["albedo"][half]).max() > 0.01  # the refined albedo too)
        assert all(np.array_equal(out[name][half], off[name][half]) for name in out if name != "albedo")
    np.testing.assert_allclose(np.linalg.norm(out["normal"] * 2 - 1, axis=2), 1.0, atol=1e-6)
    old = copy.copy(second)  # tghop 0.58's material, or one fitted with patch_levels 0
    old.patches_ = None
    with pytest.raises(TGHopError, match="patch_refine=2 needs the albedo's patch statistics input 2 lacks"):
        synthesize_guided([material, old], guide, patch_refine=2, **POOL)
    remix = synthesize_guided([material, old], None, size=(48, 48), rng=1, **POOL)  # auto: refined where it can be
    assert list(remix) == material.names_


def test_a_material_where_a_plain_model_is_needed_says_what_takes_it(material, second, tmp_path):
    # Review 58, item 7: `tghop synth MAT OTHER` said "only 'tghop synth' and 'tghop info' take it".
    save_model(material, tmp_path / "mat.npz")
    save_model(second, tmp_path / "cells.npz")
    save_model(material.model_, tmp_path / "plain.npz")

    def run(*args):
        return CliRunner().invoke(main, [str(tmp_path / a) if a.endswith(("npz", "g.png")) else a for a in args])

    res = run("patches", "mat.npz", "-o", "o.png")
    assert res.exit_code == 1 and "Traceback" not in res.output, res.output
    assert "is a material (" in res.output and "only 'tghop synth'" not in res.output, res.output
    with pytest.raises(ModelFileError, match=r"load_model\(path, material=True\)"):
        load_model(tmp_path / "mat.npz")
    # Painted (since 0.50) and remixed materials: every map, one join
    save_image(np.repeat([[0.0, 1.0]], 48, axis=0).repeat(32, axis=1), tmp_path / "g.png")  # 48x64, two levels
    res = run("synth", "mat.npz", "cells.npz", "--guide", "g.png", "-o", str(tmp_path / "p.png"), "--seed", "1",
              "--pool", "1000", "-q")
    assert res.exit_code == 0, res.output
    for name in ("p", "p_normal", "p_roughness", "p_height"):
        assert load_image(tmp_path / f"{name}.png").shape[:2] == (48, 64)
    res = run("synth", "mat.npz", "plain.npz", "-o", str(tmp_path / "o.png"), "--size", "48x64", "-q")
    assert res.exit_code == 2 and "Traceback" not in res.output, res.output  # a usage error (0.62; 0.61: 1)
    assert "SOURCE 2 (" + str(tmp_path / "plain.npz") + ") is a texture model but SOURCE 1" in res.output, res.output
    res = run("morph", "mat.npz", "plain.npz", "-o", str(tmp_path / "o.png"), "-q")  # two materials: since 0.59
    assert res.exit_code == 2 and "is a material but B" in res.output, res.output
    with pytest.raises(ModelFileError, match=r"load_model\(path, material=True\)"):
        load_model(tmp_path / "mat.npz")
    assert not (tmp_path / "o.png").exists()


def test_cli_patch_refines_painted_materials_albedos(material, second, tmp_path, monkeypatch):
    """0.60: synth A.npz B.npz --guide (or a remix) with --patch-refine N or --quality best refines each region's
    albedo by its own material (0.59 refused them as a usage error); a material without the statistics is named."""
    import copy

    old = copy.copy(second)
    old.patches_ = None
    for name, m in (("mat", material), ("cells", second), ("old", old)):
        save_model(m, tmp_path / f"{name}.npz")
    save_image(np.repeat([[0.0, 1.0]], 48, axis=0).repeat(32, axis=1), tmp_path / "g.png")
    monkeypatch.chdir(tmp_path)
    out = {}
    for steps in ("0", "3"):
        res = CliRunner().invoke(main, ["synth", "mat.npz", "cells.npz", "--guide", "g.png", "-o", f"p{steps}.png",
                                        "--seed", "1", "--pool", "1000", "-q", "--patch-refine", steps])
        assert res.exit_code == 0, res.output
        out[steps] = {p.name[2:]: load_image(p) for p in tmp_path.glob(f"p{steps}*.png")}
    assert set(out["3"]) == {".png", "_normal.png", "_roughness.png", "_height.png"}
    for half in (np.s_[:, :15], np.s_[:, 49:]):  # away from the join (32 px wide) the other maps as without it
        assert not np.array_equal(out["0"][".png"][half], out["3"][".png"][half])
        assert all(np.array_equal(out["0"][k][half], out["3"][k][half]) for k in out["3"] if k != ".png")
    res = CliRunner().invoke(main, ["synth", "mat.npz", "old.npz", "-o", "r.png", "--size", "48x64", "-q",
                                    "--quality", "best"])
    assert res.exit_code == 2 and "Traceback" not in res.output, res.output  # a usage error, as synth's (0.61: 1)
    assert "--quality best does not apply to SOURCE 2 (old.npz) (it has no patch statistics: fitted by tghop 0.58 " \
           "or older, or with --patch-levels 0); fit it again, or drop it" in res.output, res.output
    assert not list(tmp_path.glob("r*.png"))


def test_painted_materials_of_the_same_maps_in_another_order_are_told_so(material, tmp_path, monkeypatch):
    # They were refused as "input 2's maps are albedo, height, normal, roughness but input 1's are albedo,
    # normal, roughness, height (or their channels differ); give materials with the same maps": the same maps.
    cells = data.cells(64, rng=3)
    maps = example_maps(cells)
    reordered = Material(model=TGHop(**FAST), rng=0).fit(cells, {k: maps[k] for k in ("height", "normal",
                                                                                       "roughness")})
    fewer = Material(model=TGHop(**FAST), rng=0).fit(cells, {"height": maps["height"]})
    for name, m in (("mat", material), ("re", reordered), ("few", fewer)):
        save_model(m, tmp_path / f"{name}.npz")
    monkeypatch.chdir(tmp_path)
    for second, words in (("re.npz", "SOURCE 2 (re.npz) has its maps in another order (height, normal, roughness) "
                                     "than SOURCE 1 (mat.npz) (normal, roughness, height); fit it again with its "
                                     "maps after --maps in that order: normal, roughness, height"),  # 0.60: "in "
                          # "SOURCE 1 (mat.npz)'s order"
                          ("few.npz", "SOURCE 2 (few.npz) has the maps height but SOURCE 1 (mat.npz) has normal, "
                                      "roughness, height; give materials with the same maps")):
        res = CliRunner().invoke(main, ["synth", "mat.npz", second, "-o", "o.png", "--size", "48x64", "-q"])
        assert res.exit_code == 1 and "Traceback" not in res.output, res.output
        assert res.output.count("Error:") == 1 and words in res.output, res.output
    assert not list(tmp_path.glob("o*.png"))


def test_materials_of_one_library_naming_paint_together(exemplar, maps, tmp_path, monkeypatch):
    # 0.58 matched painted materials' maps by their whole names, which hold each material's own name, so
    # two sets of one naming (Stone_NormalGL, Stone_Height beside Gravel_NormalGL, Gravel_Height) were
    # refused as "other maps" by synth, synthesize_guided and the page. They are matched by the suffixes
    # their output files take (tghop.material_files.map_keys), the first material's names kept.
    from tghop import synthesize_guided
    from tghop.server.materials import same_kind

    cells = data.cells(64, rng=3)
    cell_maps = example_maps(cells)
    stone = Material(model=TGHop(**NAMES), rng=0).fit(exemplar, {"Stone_Normal": maps["normal"],
                                                                "Stone_Height": maps["height"]})
    gravel = Material(model=TGHop(**NAMES), rng=0).fit(cells, {"Gravel_normal": cell_maps["normal"],
                                                              "Gravel_Height": cell_maps["height"]})
    guide = np.repeat([[0.0, 1.0]], 48, axis=0).repeat(32, axis=1)
    out = synthesize_guided([stone, gravel], guide, rng=1, **POOL)
    assert list(out) == stone.names_
    same_kind([stone, gravel], ["a" * 16, "b" * 16])  # the page's paint: no 422
    save_model(stone, tmp_path / "stone.npz")
    save_model(gravel, tmp_path / "gravel.npz")
    save_image(guide, tmp_path / "g.png")
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(main, ["synth", "stone.npz", "gravel.npz", "--guide", "g.png", "-o", "wall.png",
                                    "--seed", "1", "--pool", "1000", "-q"])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in tmp_path.glob("wall*.png")) == ["wall.png", "wall_Height.png", "wall_Normal.png"]
    # Other maps are still refused, saying how maps are matched
    rough = Material(model=TGHop(**NAMES), rng=0).fit(cells, {"Gravel_Normal": cell_maps["normal"],
                                                             "Gravel_Roughness": cell_maps["roughness"]})
    save_model(rough, tmp_path / "rough.npz")
    res = CliRunner().invoke(main, ["synth", "stone.npz", "rough.npz", "-o", "o.png", "--size", "48x64", "-q"])
    assert res.exit_code == 1 and res.output.count("Error:") == 1, res.output
    assert "matched by their kinds (NormalGL and nor_gl are both a normal map)" in res.output, res.output
    with pytest.raises(TGHopError, match="give materials with the same maps"):
        synthesize_guided([stone, rough], guide, rng=1, **POOL)


def test_materials_of_two_libraries_namings_paint_together_by_kind(exemplar, maps, tmp_path, monkeypatch):
    # 0.59 before this matched maps by their files' suffixes: ambientCG's Stone_NormalGL beside Poly Haven's
    # gravel_nor_gl_2k was refused as other maps. Each map's kind is matched where the material has one of it.
    from tghop import synthesize_guided
    from tghop.server.materials import same_kind

    cells = data.cells(64, rng=3)
    cell_maps = example_maps(cells, convention="OpenGL")
    gl = example_maps(exemplar, convention="OpenGL")
    stone = Material(model=TGHop(**NAMES), rng=0).fit(exemplar, {"Stone_NormalGL": gl["normal"],
                                                                "Stone_Roughness": gl["roughness"]})
    gravel = Material(model=TGHop(**NAMES), rng=0).fit(cells, {"gravel_nor_gl_2k": cell_maps["normal"],
                                                              "gravel_rough_2k": cell_maps["roughness"]})
    guide = np.repeat([[0.0, 1.0]], 48, axis=0).repeat(32, axis=1)
    assert list(synthesize_guided([stone, gravel], guide, rng=1, **POOL)) == stone.names_
    same_kind([stone, gravel], ["a" * 16, "b" * 16])  # the page's paint: no 422
    save_model(stone, tmp_path / "stone.npz")
    save_model(gravel, tmp_path / "gravel.npz")
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(main, ["synth", "stone.npz", "gravel.npz", "-o", "wall.png", "--size", "48x64",
                                    "--seed", "1", "--pool", "1000", "-q"])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in tmp_path.glob("wall*.png")) == ["wall.png", "wall_NormalGL.png",
                                                                   "wall_Roughness.png"]


def test_normal_maps_of_two_conventions_are_painted_in_the_first_ones(exemplar, tmp_path):
    # 0.58 did not record a normal map's convention: two maps named only "normal", one OpenGL's and one
    # DirectX's, were painted together silently, one region's slopes upside down. The convention (the content's,
    # else the name's) is recorded and kept in the model file; where two meet, the later material's map is
    # flipped to the first's, with a warning saying which and how to paint in the other.
    from tghop import synthesize_guided
    from tghop.normals import convention_of

    cells = data.cells(64, rng=3)
    gl = Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"normal": example_maps(exemplar, convention="OpenGL")[
        "normal"]})
    dx = Material(model=TGHop(**FAST), rng=0).fit(cells, {"normal": example_maps(cells)["normal"]})
    assert (gl.conventions_, dx.conventions_) == ([None, "OpenGL"], [None, "DirectX"])
    save_model(dx, tmp_path / "dx.npz")
    assert load_model(tmp_path / "dx.npz", material=True).conventions_ == [None, "DirectX"]
    res = CliRunner().invoke(main, ["info", str(tmp_path / "dx.npz")])  # 0.58 said nothing of a map named "normal"
    assert res.exit_code == 0 and "normal map, DirectX by its content, kept)" in res.output, res.output
    with np.load(tmp_path / "dx.npz") as f:
        arrays = dict(f)
    meta = json.loads(str(arrays["__meta__"]))
    meta["material"]["conventions"] = {"normal": "up"}
    np.savez(tmp_path / "bad.npz", **{**arrays, "__meta__": np.array(json.dumps(meta))})
    with pytest.raises(ModelFileError, match="conventions are not a dict of its normal maps' names"):
        load_model(tmp_path / "bad.npz", material=True)
    del meta["material"]["conventions"]  # a file of 0.58: the name's convention (none said by "normal")
    np.savez(tmp_path / "old.npz", **{**arrays, "__meta__": np.array(json.dumps(meta))})
    assert load_model(tmp_path / "old.npz", material=True).conventions_ == [None, None]
    guide = np.repeat([[0.0, 1.0]], 128, axis=0).repeat(128, axis=1)
    for first, second, want, other in ((gl, dx, "OpenGL", "DirectX"), (dx, gl, "DirectX", "OpenGL")):
        said = f"input 2's normal map 'normal' ({other}) is in the other convention than input 1's ({want}); its green"
        with pytest.warns(UserWarning, match=re.escape(said)):
            out = synthesize_guided([first, second], guide, rng=1, **POOL)["normal"]
        assert convention_of(out[:, :112]) == want and convention_of(out[:, 144:]) == want
        n = out * 2 - 1
        np.testing.assert_allclose(np.linalg.norm(n, axis=2), 1.0, atol=1e-5)
    # a map of no convention known (a model file of 0.58 named only "normal") is painted as it is, without a word
    dx.conventions_ = [None, None]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = synthesize_guided([gl, dx], guide, rng=1, **POOL)["normal"]
    assert convention_of(out[:, 144:]) == "DirectX"


def test_two_materials_morph_every_map_alike(exemplar, maps, tmp_path, monkeypatch):
    # 0.58 refused a morph of materials ("a morph takes texture models or exemplars"): a game artist's strip from
    # one ground to another came without its maps. Two materials with the same maps morph as they paint.
    from tghop import morph

    cells = data.cells(64, rng=3)
    cell_maps = example_maps(cells)
    stone = Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"Stone_Normal": maps["normal"],
                                                                "Stone_Height": maps["height"]})
    gravel = Material(model=TGHop(**FAST), rng=0).fit(cells, {"gravel_nor": cell_maps["normal"],
                                                              "gravel_disp": cell_maps["height"]})
    strip = morph(stone, gravel, (48, 160), rng=1, **POOL)
    assert list(strip) == stone.names_ and strip["Stone_Height"].shape == (48, 160, 1)
    np.testing.assert_allclose(np.linalg.norm(strip["Stone_Normal"] * 2 - 1, axis=2), 1.0, atol=1e-5)
    save_model(stone, tmp_path / "stone.npz")
    save_model(gravel, tmp_path / "gravel.npz")
    save_texture(tmp_path / "tex.npz")  # a texture model: refused before any work
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(main, ["morph", "stone.npz", "gravel.npz", "-o", "strip.png", "--size", "48x160",
                                    "--grid", "2", "--seed", "1", "-q"])
    assert res.exit_code == 0, res.output
    assert "1 material of 96x160 written to strip.png, strip_Normal.png, strip_Height.png" in res.output
    assert load_image("strip_Height.png").shape == (96, 160, 1)
    res = CliRunner().invoke(main, ["morph", "stone.npz", "tex.npz", "-o", "mixed.png", "--size", "48x160", "-q"])
    assert res.exit_code == 2 and "A stone.npz is a material but B tex.npz is not; morph two materials" in \
        res.output, res.output
    assert not list(tmp_path.glob("mixed*"))


def test_a_failed_refit_leaves_the_earlier_material_whole(exemplar, maps):
    # A second fit on other maps that fails (too little texture outside the mask) used to leave the new
    # maps' names and channels beside the earlier joint model: synthesize then broke on a shape mismatch.
    mat = Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"height": maps["height"]})
    before = mat.synthesize(SIZE, rng=1, **POOL)
    exclude = np.zeros(exemplar.shape[:2], dtype=bool)
    exclude[:, :100] = True
    with pytest.raises(TGHopError, match="too little texture"):
        mat.fit(exemplar, maps, exclude=exclude)
    assert mat.names_ == ["albedo", "height"] and mat.map_channels_ == [3, 1]
    after = mat.synthesize(SIZE, rng=1, **POOL)
    assert all(np.array_equal(before[k], after[k]) for k in before)


def test_material_synthesize_refuses_a_bad_dtype_in_one_line(material):
    told = r"^dtype must be float64, float32 or uint8 \(e\.g\. numpy\.float32\), got 'junk'$"
    with pytest.raises(TGHopError, match=told):
        material.synthesize(SIZE, rng=1, dtype="junk")


def test_material_synthesize_takes_uint8_as_tghop_synthesize_does(material):
    # 0.56 refused dtype=numpy.uint8 ("float32 or float64"), which synthesize_guided of materials and
    # TGHop.synthesize take: now each map's floats rounded to 0-255 by to_uint8, a mask map's levels too.
    from tghop.imageio import to_uint8

    floats = material.synthesize(SIZE, rng=1, **POOL)  # float64: a float32 copy can round a level apart
    levels = material.synthesize(SIZE, rng=1, dtype=np.uint8, **POOL)
    assert list(levels) == list(floats)
    for name, img in levels.items():
        assert img.dtype == np.uint8 and img.shape == floats[name].shape
        assert np.array_equal(img, to_uint8(floats[name]).reshape(img.shape)), name


def test_material_return_stages_gives_every_maps_steps_and_the_last_is_the_result(material):
    # 0.60: a texture's synthesize(return_stages=True) showed each step, a material's had no such keyword: the joint
    # quilt of all maps and each map's refinement and colour matching could not be looked at.
    for dtype in (np.float32, np.uint8):
        out, stages = material.synthesize(SIZE, rng=1, dtype=dtype, return_stages=True, **POOL)
        plain = material.synthesize(SIZE, rng=1, dtype=dtype, **POOL)
        assert all(np.array_equal(out[name], plain[name]) for name in plain)  # the same maps
        steps = [k for k in stages if k != "pool"]
        assert steps == ["quilt", "seams", "refine", "patch refine", "colour", "maps"]
        for step in steps:
            assert list(stages[step]) == list(out), step
            assert all(stages[step][n].dtype == np.float32 and stages[step][n].shape == out[n].shape for n in out)
        top = np.float32(255 if dtype == np.uint8 else 1)
        assert all(np.array_equal(stages["maps"][n], (out[n] / top).astype(np.float32)) for n in out)  # the result
        assert not np.array_equal(stages["quilt"]["albedo"], stages["seams"]["albedo"])
        assert np.array_equal(stages["patch refine"]["normal"], stages["refine"]["normal"])  # the albedo's step alone
        assert not np.array_equal(stages["colour"]["normal"], stages["refine"]["normal"])
        assert stages["pool"].shape[1:] == (material.model_.patch_size,) * 2 + (sum(material.map_channels_),)


def test_map_slices_before_fit_is_not_fitted():
    # It read map_channels_ unchecked: Python's AttributeError naming the attribute.
    from tghop import NotFittedError

    with pytest.raises(NotFittedError, match="this Material is not fitted yet"):
        Material().map_slices()


def test_synth_given_maps_says_to_fit_the_material_first(tmp_path):
    # 'tghop synth albedo.png --maps normal.png' said "No such option '--maps'. (Did you mean one of: '--gamma',
    # '--max-patches', '--paper'?)".
    res = CliRunner().invoke(main, ["synth", "builtin:bricks", "--maps", str(tmp_path / "normal.png"), "-o",
                                    str(tmp_path / "o.png")], prog_name="tghop")
    assert res.exit_code == 2 and "Traceback" not in res.output, res.output  # a usage error (it exited 1)
    assert res.output.strip() == ("Error: synth takes no --maps: fit the material first ('tghop fit ALBEDO --maps "
                                  "MAP... -o MAT.npz'), then 'tghop synth MAT.npz -o OUT' writes OUT and OUT_<map> "
                                  "for each map (see 'tghop synth --help')"), res.output
    assert not list(tmp_path.iterdir())


def test_a_normal_map_is_recognised_by_its_content():
    # tghop synth's remix warning read the file names alone: a normal map named rock.png went unwarned.
    from tghop import data
    from tghop.material import example_maps, looks_like_normal_map

    normal = example_maps(data.bricks(96, rng=1))["normal"]
    assert looks_like_normal_map(normal) and looks_like_normal_map(np.round(normal * 255).astype(np.uint8))
    assert looks_like_normal_map(np.round(normal * 65535).astype(np.uint16))
    flat = np.zeros((16, 16, 3))
    flat[...] = (0.5, 0.5, 1.0)  # a flat normal map: straight up everywhere
    assert looks_like_normal_map(flat)
    assert not looks_like_normal_map(data.bricks(96, rng=1)) and not looks_like_normal_map(data.cells(96, rng=1))
    assert not looks_like_normal_map(np.random.default_rng(0).random((32, 32, 3)))
    assert not looks_like_normal_map(flat[..., :1]) and not looks_like_normal_map(np.full((16, 16, 3), 0.5))
    cyan = np.zeros((16, 16, 3))
    cyan[...] = (0.0, 0.5, 0.5)  # unit vectors (-1, 0, 0) facing up, as water_caustics.jpg's: red far from 0.5
    assert not looks_like_normal_map(cyan)
    down = flat.copy()
    down[...] = (0.5, 0.5, 0.0)  # unit vectors facing down
    assert not looks_like_normal_map(down)
    mostly = normal.copy()
    mostly[: mostly.shape[0] // 4] = data.bricks(96, rng=1)[: mostly.shape[0] // 4]  # a quarter not one
    assert not looks_like_normal_map(mostly)


def test_a_loaded_materials_parameters_are_the_fitted_ones_and_its_clone_fits_the_same(exemplar, maps, material,
                                                                                         tmp_path):
    # A loaded Material's parameters were rebuilt from its joint model: model__patch_levels 0 (what fit gives the
    # joint model), rng moved onto the model, normal the list of maps found normal instead of "auto" or the name given.
    import json

    from sklearn.base import clone

    partial = TGHop(**FAST, n_channels=(20, None), rng=4)  # K2 by default at fit (--k1 alone)
    # the first: the module's, Material(model=TGHop(**FAST), rng=0)
    for mat in (material, Material(model=partial, normal="normal").fit(exemplar, maps)):
        save_model(mat, tmp_path / "m.npz")
        loaded = load_model(tmp_path / "m.npz", material=True)
        assert repr(loaded) == repr(mat)
        want, got = mat.get_params(), loaded.get_params()
        assert {k: v for k, v in got.items() if k != "model"} == {k: v for k, v in want.items() if k != "model"}
        again = clone(loaded).fit(exemplar, maps)
        a, b = mat.synthesize(SIZE, rng=1, **POOL), again.synthesize(SIZE, rng=1, **POOL)
        assert all(np.array_equal(a[k], b[k]) for k in a)
    with np.load(tmp_path / "m.npz") as f:  # a file of tghop 0.55 (no params) loads as it did; a bad one is refused
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays["__meta__"]))
    for params, problem in ((None, None), ({"model": None, "normal": 3, "rng": None}, "normal must be"),
                            ({"model": {"gamma": -1}, "normal": "auto", "rng": 0}, "gamma")):
        meta["material"].pop("params", None)
        meta["material"].update({} if params is None else {"params": params})
        with open(tmp_path / "old.npz", "wb") as fh:
            np.savez(fh, **{**arrays, "__meta__": np.array(json.dumps(meta))})
        if problem is None:
            assert load_model(tmp_path / "old.npz", material=True).get_params()["normal"] == ["normal"]
        else:
            with pytest.raises(ModelFileError, match=problem):
                load_model(tmp_path / "old.npz", material=True)


def test_a_material_whose_map_is_a_mix_of_the_albedos_channels_saves_and_loads(exemplar, tmp_path):
    # Its stacked channels are linearly dependent: a Saab channel of no energy, fitted as -1e-18 or so, which the
    # model file's check of every Saab's energies (tghop.hops.Hop._saab_energy) refused as negative.
    mat = Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"height": exemplar.mean(axis=2)})
    energies = [s.energy_ for hop in mat.model_.hops_.hops_ for s in hop.saabs_]
    assert min(e.min() for e in energies) < 0  # what the case is about
    save_model(mat, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz", material=True)
    assert all(np.array_equal(a, s.energy_) for a, s in zip(energies, [s for h in loaded.model_.hops_.hops_
                                                                        for s in h.saabs_]))
