"""A whole material's hole filled, or its picture grown, in every map alike
(:func:`tghop.inpaint.inpaint_material`, ``tghop inpaint/extend IMAGE ... --maps``): known
pixels kept exactly, the maps' fills aligned as the material's own images are, normal maps
unit vectors, and each bad input one line with no file written."""

import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from tghop import TGHop, TGHopError, data
from tghop.cli import main
from tghop.imageio import load_image, save_image, to_uint8, to_uint16
from tghop.inpaint import inpaint_material
from tghop.material import Material, example_maps
from tghop.modelfile import save_model

FAST = dict(max_patches=1500, n_clusters=10, layout_factor=None)
SIZE = 128


@pytest.fixture(scope="module")
def picture():
    """An albedo (uint8) and its maps (floats), with a hole."""
    albedo = data.bricks(SIZE, rng=5)
    maps = example_maps(albedo)
    hole = np.zeros((SIZE, SIZE), dtype=bool)
    hole[44:84, 40:96] = True
    return {"albedo": to_uint8(albedo), **maps}, hole


@pytest.fixture(scope="module")
def material(picture):
    images, hole = picture
    maps = {k: v for k, v in images.items() if k != "albedo"}
    return Material(model=TGHop(**FAST), rng=0).fit(images["albedo"], maps, exclude=hole)


@pytest.fixture(scope="module")
def filled(material, picture):
    """The picture's hole filled by :func:`material` (seed 1), patch-refined and not: read by several tests, made
    once (the tests only read them)."""
    images, hole = picture
    return {refine: inpaint_material(material, images, hole, rng=1, n_patches=1500, **refine_arg)
            for refine, refine_arg in ((True, {}), (False, {"patch_refine": 0}))}


def _corr(a, b):
    return float(np.corrcoef(np.ravel(a), np.ravel(b))[0, 1])


def test_every_map_is_filled_alike_and_the_rest_kept(material, picture, filled):
    images, hole = picture
    out = filled[True]
    assert list(out) == ["albedo", "normal", "roughness", "height"]
    assert out["albedo"].dtype == np.uint8 and out["height"].dtype == np.float64
    for name, image in images.items():
        assert out[name].shape == image.shape
        np.testing.assert_array_equal(out[name][~hole], image[~hole])  # bit for bit
        assert not np.array_equal(out[name][hole], image[hole])
    n = out["normal"][hole] * 2 - 1
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    # The fill's height goes with its albedo's brightness as the picture's does (the maps are aligned);
    # a height filled on its own would not
    lum = out["albedo"][hole].mean(axis=1)
    inside, outside = _corr(lum, out["height"][hole]), _corr(images["albedo"][~hole].mean(axis=1),
                                                              images["height"][~hole])
    assert inside > 0.6 and outside > 0.6, (inside, outside)
    again = inpaint_material(material, images, hole, rng=1, n_patches=1500)
    for name in out:
        np.testing.assert_array_equal(again[name], out[name])


def test_return_stages_gives_every_maps_steps_and_the_last_is_the_result(material, picture, filled):
    # 0.60: inpaint(return_stages=True) showed a picture's fill step by step; inpaint_material had no such keyword.
    images, hole = picture
    out, stages = inpaint_material(material, images, hole, rng=1, n_patches=1500, return_stages=True)
    for name in out:  # the same fill with and without the steps
        np.testing.assert_array_equal(out[name], filled[True][name])
    assert [k for k in stages if k != "pool"] == ["quilt", "seams", "refine", "patch refine", "maps"]
    for step in ("quilt", "seams", "refine", "patch refine", "maps"):
        assert list(stages[step]) == list(out), step
        for name, image in images.items():
            pic = stages[step][name]
            assert pic.dtype == np.float32 and pic.shape == image.shape, (step, name)
            top = np.float32(255 if image.dtype == np.uint8 else 1)
            assert np.array_equal(pic[~hole], (image[~hole] / top).astype(np.float32)), (step, name)  # kept
    for name in out:  # the last step is the result
        top = np.float32(255 if out[name].dtype == np.uint8 else 1)
        assert np.array_equal(stages["maps"][name], (out[name] / top).astype(np.float32)), name
    assert not np.array_equal(stages["quilt"]["albedo"], stages["seams"]["albedo"])
    assert not np.array_equal(stages["seams"]["height"], stages["refine"]["height"])
    assert np.array_equal(stages["patch refine"]["height"], stages["refine"]["height"])  # the albedo's step alone
    assert not np.array_equal(stages["patch refine"]["albedo"], stages["refine"]["albedo"])
    assert stages["pool"].shape[1:] == (material.model_.patch_size,) * 2 + (sum(material.map_channels_),)
    with pytest.warns(UserWarning, match="the mask has no hole"):  # 0.62: said, as inpaint says it
        assert inpaint_material(material, images, np.zeros_like(hole), rng=1, return_stages=True)[1] == {}


def test_the_albedos_fill_is_patch_refined_the_maps_kept(material, picture, filled):
    """0.59: the albedo's hole is patch-refined with the material's albedo statistics, as inpaint refines a
    texture's (0.58 refused patch_refine for a material); the other maps' fills are as without it, the known
    pixels kept; a material fitted without the statistics (as 0.58 fitted every one) refuses it."""
    images, hole = picture
    auto, off = filled[True], filled[False]
    assert np.abs(auto["albedo"][hole].astype(float) - off["albedo"][hole]).mean() > 0.3  # 8-bit levels
    np.testing.assert_array_equal(auto["albedo"][~hole], images["albedo"][~hole])
    assert all(np.array_equal(auto[k], off[k]) for k in auto if k != "albedo")
    maps = {k: v for k, v in images.items() if k != "albedo"}
    old = Material(model=TGHop(**FAST, patch_levels=0), rng=0).fit(images["albedo"], maps, exclude=hole)
    with pytest.raises(TGHopError, match="patch_refine=4 needs the albedo's patch statistics"):
        inpaint_material(old, images, hole, patch_refine=4)


def test_16_bit_maps_are_filled_and_kept_at_16_bits(material, picture, filled):
    # As Material.fit takes them (and inpaint a 16-bit picture): levels / 65535, the result uint16
    images, hole = picture
    deep = {**images, "albedo": images["albedo"].astype(np.uint16) * np.uint16(257),
            "normal": to_uint16(images["normal"]), "height": to_uint16(images["height"])}
    out = inpaint_material(material, deep, hole, rng=1, n_patches=1500)
    assert [out[k].dtype for k in out] == [np.uint16, np.uint16, np.float64, np.uint16]
    for name in ("albedo", "normal", "height"):
        np.testing.assert_array_equal(out[name][~hole], deep[name][~hole])  # the same levels
        assert not np.array_equal(out[name][hole], deep[name][hole])
    n = out["normal"][hole] / 65535.0 * 2 - 1
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-4)
    # The fill of the 8-bit albedo and float maps, but for the maps' 16-bit rounding (levels / 65535, not 255);
    # without the albedo's patch refinement (0.59), whose steps of a fixed size follow such differences' signs
    deep0, eight = inpaint_material(material, deep, hole, rng=1, n_patches=1500, patch_refine=0), filled[False]
    assert np.abs(deep0["albedo"][hole] / 257.0 - eight["albedo"][hole]).mean() < 0.5


@pytest.mark.parametrize("change, words", [
    (lambda im: {k: v for k, v in im.items() if k != "height"}, "dict of the material's maps, albedo, normal"),
    (lambda im: {**im, "height": im["height"][:100]}, "map height is 100x128 but the albedo is 128x128"),
    (lambda im: {**im, "roughness": np.repeat(im["roughness"], 3, axis=2) * [1, 0.5, 0.2]},
     "map roughness: the material's map is greyscale but the image given for it has colour; give that map's own "
     r"image \(two maps swapped\?\)"),
    # 0.59: "the model is in colour but the image is greyscale; fit the model on a greyscale exemplar"
    (lambda im: {**im, "normal": im["height"]}, "map normal: the material's map is in colour but the image given for "
                                                "it is greyscale; give that map's own image"),
])
def test_bad_maps_are_refused_naming_them(material, picture, change, words):
    images, hole = picture
    with pytest.raises(TGHopError, match=words):
        inpaint_material(material, change(images), hole, rng=1)
    with pytest.raises(TGHopError, match="a texture model fills with inpaint"):
        inpaint_material(material.model_, images, hole)


def _write(folder, picture):
    images, hole = picture
    save_image(images["albedo"], folder / "wall.png")
    save_image(images["normal"], folder / "wall_normal.png", depth=16)
    save_image(images["height"], folder / "h.png")
    save_image(hole.astype(float), folder / "mask.png")


def run(*args):
    result = CliRunner().invoke(main, [*args, "-q"], catch_exceptions=False)
    return result.exit_code, result.output


@pytest.fixture(scope="module")
def saved_material(picture, tmp_path_factory):
    """The picture's material of two maps (wall_normal, h), fitted around the hole, saved once: a model file."""
    images, hole = picture
    mat = Material(model=TGHop(**FAST), rng=0).fit(
        images["albedo"], {"wall_normal": images["normal"], "h": images["height"]}, exclude=hole)
    path = tmp_path_factory.mktemp("saved") / "mat.npz"
    save_model(mat, path)
    return path


@pytest.fixture
def in_saved(tmp_path, picture, saved_material, monkeypatch):
    """The picture's files in tmp_path (the working folder) and a copy of :func:`saved_material` there, as mat.npz."""
    monkeypatch.chdir(tmp_path)
    _write(tmp_path, picture)
    shutil.copyfile(saved_material, tmp_path / "mat.npz")
    return picture


@pytest.fixture(scope="module")
def plain_fills(picture, saved_material, tmp_path_factory):
    """The plain fills that several CLI tests check or compare theirs with, made once (the tests only read them):
    ``tghop inpaint`` of the picture's hole and ``tghop extend`` to 128x192 (anchor left) with its two maps and
    :func:`saved_material`, seed 3, in a folder of their own. Returns (the folder, each command's output)."""
    d = tmp_path_factory.mktemp("plain")
    _write(d, picture)
    shutil.copyfile(saved_material, d / "mat.npz")
    maps = ["--maps", str(d / "wall_normal.png"), str(d / "h.png"), "--source", str(d / "mat.npz"), "--seed", "3"]
    said = {}
    for command, args in (("inpaint", [str(d / "wall.png"), str(d / "mask.png"), *maps, "-o", str(d / "out.png")]),
                          ("extend", [str(d / "wall.png"), *maps, "-o", str(d / "big.png"), "--size", "128x192",
                                      "--anchor", "left"])):
        code, said[command] = run(command, *args)
        assert code == 0, said[command]
    return d, said


def test_cli_inpaint_and_extend_with_maps(picture, plain_fills):
    # `tghop inpaint IMAGE MASK --maps ... -o out.png --seed 3` and `tghop extend IMAGE --maps ... -o big.png
    # --size 128x192 --anchor left --seed 3`, run by the fixture
    images, hole = picture
    d, _ = plain_fills
    albedo = load_image(d / "out.png", dtype=None)
    np.testing.assert_array_equal(albedo[~hole], images["albedo"][~hole])
    normal, depth = load_image(d / "out_wall_normal.png", dtype=None, with_depth=True)
    assert depth == 16 and normal.shape == (SIZE, SIZE, 3)
    height, depth = load_image(d / "out_h.png", dtype=None, with_depth=True)
    assert depth == 8 and height.shape == (SIZE, SIZE, 1)
    big = load_image(d / "big.png", dtype=None)
    assert big.shape == (SIZE, 192, 3)
    np.testing.assert_array_equal(big[:, :SIZE], images["albedo"])
    assert load_image(d / "big_h.png").shape == (SIZE, 192, 1)


def test_cli_stages_with_maps_writes_each_steps_maps_the_last_the_output(tmp_path, in_saved, plain_fills):
    # 0.60 refused it ("--stages applies to a picture's fill, not a material's maps; drop it").
    images, hole = in_saved
    maps = ("--maps", "wall_normal.png", "h.png", "--source", "mat.npz", "--seed", "3")
    plain, _ = plain_fills  # the same commands without --stages: out.png, big.png
    for command, args, without in (("inpaint", ("mask.png",), "out"),
                                   ("extend", ("--size", "128x192", "--anchor", "left"), "big")):
        code, out = run(command, "wall.png", *args, *maps, "-o", f"{command}.png", "--stages")
        assert code == 0, out
        steps = ["quilt", "seams", "refine", "patch-refine", "maps"]
        assert (f"steps written beside it, each with its maps: {', '.join(f'{command}_{s}.png' for s in steps)}"
                in out)
        for step in steps:
            for m in ("", "_wall_normal", "_h"):
                assert (tmp_path / f"{command}_{step}{m}.png").exists(), (step, m)
        for m in ("", "_wall_normal", "_h"):  # the last step's maps are those written
            assert np.array_equal(load_image(f"{command}_maps{m}.png", dtype=None),
                                  load_image(f"{command}{m}.png", dtype=None)), m
        assert not np.array_equal(load_image(f"{command}_quilt.png"), load_image(f"{command}.png"))
        for m in ("", "_wall_normal", "_h"):  # the same without it
            assert np.array_equal(load_image(plain / f"{without}{m}.png", dtype=None),
                                  load_image(f"{command}{m}.png", dtype=None)), m
    # IMAGE's alpha channel: in the albedo's steps as in the albedo written (0.62; 0.61 wrote the steps without it)
    albedo = load_image("wall.png")
    alpha = (np.arange(albedo.shape[0] * albedo.shape[1]) % 251).reshape(*albedo.shape[:2], 1) / 255.0
    save_image(np.concatenate([albedo, alpha], axis=2), "walla.png")
    code, out = run("inpaint", "walla.png", "mask.png", *maps, "-o", "a.png", "--stages")
    assert code == 0, out
    written = load_image("a.png", dtype=None, keep_alpha=True)
    for step in ("quilt", "patch-refine", "maps"):
        staged = load_image(f"a_{step}.png", dtype=None, keep_alpha=True)
        assert staged.shape == written.shape and np.array_equal(staged[..., 3], written[..., 3]), step


def test_cli_inpaint_with_maps_warns_once_of_the_maps_a_format_writes_with_fewer_bits(tmp_path, in_saved,
                                                                                         plain_fills):
    # A 16-bit map written as JPEG lost its depth without a word: one warning names it (as synth's).
    images, hole = in_saved
    args = ["inpaint", "wall.png", "mask.png", "--maps", "wall_normal.png", "h.png", "--source", "mat.npz", "--seed",
            "3"]
    code, out = run(*args, "-o", "out.jpg")
    assert code == 0, out
    assert [line for line in out.splitlines() if line.startswith("Warning")] == [
        "Warning: map wall_normal (16-bit) has more bits a channel than JPEG holds, but is written with 8; name "
        "the output .png, .tif or .tiff to keep them"]
    code, out = run(*args, "-o", "out.tif")  # every depth held
    assert code == 0 and "Warning" not in out, out
    assert "Warning" not in plain_fills[1]["inpaint"]  # the same command's -o out.png


def test_cli_inpaint_with_maps_fits_a_material_on_the_picture(tmp_path):
    albedo = data.bricks(128, rng=2)  # 0.60: 192x192; the same hole, and nothing checked depends on the size
    maps = example_maps(albedo)
    save_image(albedo, tmp_path / "a.png")
    save_image(maps["height"], tmp_path / "a_height.png")
    hole = np.zeros((128, 128))
    hole[40:80, 30:100] = 1
    save_image(hole, tmp_path / "m.png")
    result = CliRunner().invoke(main, ["inpaint", str(tmp_path / "a.png"), str(tmp_path / "m.png"), "--maps",
                                       str(tmp_path / "a_height.png"), "-o", str(tmp_path / "o.png"), "--seed", "1"])
    assert result.exit_code == 0, result.output
    assert "2,800 pixels filled in 2 maps, written to" in result.output
    assert load_image(tmp_path / "o_height.png").shape == (128, 128, 1)  # a_height: the word before its kind dropped


@pytest.fixture(scope="module")
def folder(tmp_path_factory, picture, saved_material):
    """The picture's files, saved materials of two maps (:func:`saved_material`) and of one, and a texture model."""
    d = tmp_path_factory.mktemp("fill")
    _write(d, picture)
    (d / "sub").mkdir()
    save_image(picture[0]["height"], d / "sub" / "h.png")
    save_image(picture[0]["height"], d / "sub" / "H.png")
    for end in "ab":  # two stems alike in their first 64 characters
        save_image(picture[0]["height"], d / "sub" / f"{'h' * 70}{end}.png")
    save_image(picture[0]["height"], d / "sub" / "albedo.png")
    save_image(picture[0]["height"][:64], d / "small.png")
    shutil.copyfile(saved_material, d / "mat.npz")
    save_model(Material(model=TGHop(**FAST), rng=0).fit(picture[0]["albedo"], {"h": picture[0]["height"]}),
               d / "one.npz")
    save_model(TGHop(**FAST).fit(picture[0]["albedo"]), d / "tex.npz")
    return d


@pytest.mark.parametrize("args, words", [
    (["inpaint", "wall.png", "mask.png", "h.png", "-o", "o.png"], "an argument too many after MASK (h.png)"),
    (["inpaint", "wall.png", "mask.png", "--maps", "-o", "o.png"], "--maps without maps"),
    (["inpaint", "wall.png", "mask.png", "--maps", "h.png", "-o", "-"], "a file per map"),
    (["inpaint", "wall.png", "mask.png", "--maps", "h.png", "--source", "wall.png", "-o", "o.png"],
     "--source wall.png is an exemplar"),
    (["inpaint", "wall.png", "mask.png", "--maps", "h.png", "--source", "mat.npz", "-o", "o.png"],
     "a material of 2 maps (wall_normal, h) but 1 was given;"),
    (["inpaint", "wall.png", "mask.png", "--maps", "h.png", "wall_normal.png", "--source", "one.npz", "-o", "o.png"],
     "a material of 1 map (h) but 2 were given;"),
    (["inpaint", "wall.png", "mask.png", "--maps", "small.png", "-o", "o.png"], "MAP small.png is 64x128"),
    (["inpaint", "wall.png", "mask.png", "--maps", "h.png", "sub/h.png", "-o", "o.png"], "two maps are named 'h':"),
    (["inpaint", "wall.png", "mask.png", "--maps", "h.png", "sub/H.png", "-o", "o.png"],
     "two maps are named 'h' and 'H', which differ only in case (one file name where case is ignored): the file "),
    (["inpaint", "wall.png", "mask.png", "--maps", f"sub/{'h' * 70}a.png", f"sub/{'h' * 70}b.png", "-o", "o.png"],
     f"the maps' files sub/{'h' * 70}a.png and sub/{'h' * 70}b.png give one name, '{'h' * 64}' (a map's name is its "
     "file stem's first 64 characters); give files whose stems differ in their first 64 characters"),
    (["inpaint", "wall.png", "mask.png", "--maps", "h.png", "--source", "tex.npz", "-o", "o.png"],
     "--source tex.npz is a texture model"),
    (["extend", "wall.png", "h.png", "--size", "200x200", "-o", "o.png"], "an argument too many after IMAGE"),
    # a saved material without --maps said "a material is generated alone and whole (one SOURCE of 'tghop synth'
    # without --guide ...); for this, fit a plain model from its albedo": --maps was the fix
    (["inpaint", "wall.png", "mask.png", "--source", "mat.npz", "-o", "o.png"],
     "--source mat.npz is a material (wall_normal, h); give --maps and its maps after MASK"),
    (["extend", "wall.png", "--source", "mat.npz", "--size", "200x200", "-o", "o.png"],
     "--source mat.npz is a material (wall_normal, h); give --maps and its maps after IMAGE"),
    # a map file named albedo said "two maps are named 'albedo'" with one map given
    (["inpaint", "wall.png", "mask.png", "--maps", "sub/albedo.png", "-o", "o.png"],
     "MAP sub/albedo.png is named 'albedo', the name of IMAGE itself"),
    (["inpaint", "wall.png", "mask.png", "--maps", "mat.npz", "h.png", "--source", "mat.npz", "-o", "o.png"],
     "MAP mat.npz is a model file"),
])
def test_cli_bad_input_with_maps_is_one_line_and_writes_nothing(folder, monkeypatch, args, words):
    monkeypatch.chdir(folder)
    before = sorted(p.name for p in folder.rglob("*"))
    result = CliRunner().invoke(main, args)
    # usage errors, 2 (they exited 1; a material given with a texture's arguments since 0.62)
    usage = ("an argument too many", "--maps without maps", "a file per map", "--source tex.npz is a texture model",
             "--source mat.npz is a material (", "--source wall.png is an exemplar", "a material of")
    assert result.exit_code == (2 if words.startswith(usage) else 1), result.output
    text = result.output.strip()
    assert "\n" not in text and "Traceback" not in text and words in text, text
    assert sorted(p.name for p in folder.rglob("*")) == before


def test_cli_fill_count_writes_a_set_of_maps_per_fill(tmp_path, in_saved, plain_fills):
    # --count on inpaint/extend --maps (0.59): one fit, a set per fill, numbered as synth's (out_2_h.png)
    maps = ["--maps", "wall_normal.png", "h.png", "--source", "mat.npz", "--seed", "3"]
    plain, _ = plain_fills  # the same commands without --count: out.png, big.png
    for args, one in ((["inpaint", "wall.png", "mask.png", *maps], "out"),
                      (["extend", "wall.png", *maps, "--size", "128x192", "--anchor", "left"], "big")):
        code, out = run(*args, "-o", "two.png", "--count", "2")
        assert code == 0 and "(and 1 more set)" in out, out
        for name in ("", "_wall_normal", "_h"):
            assert (plain / f"{one}{name}.png").read_bytes() == (tmp_path / f"two_1{name}.png").read_bytes()
            assert (tmp_path / f"two_1{name}.png").read_bytes() != (tmp_path / f"two_2{name}.png").read_bytes()


@pytest.fixture(scope="module")
def rough_then_height(picture, tmp_path_factory):
    """The picture's material of its roughness then its height map, fitted around the hole, saved once."""
    images, hole = picture
    mat = Material(model=TGHop(**FAST), rng=0).fit(
        images["albedo"], {"wall_roughness": images["roughness"], "wall_height": images["height"]}, exclude=hole)
    path = tmp_path_factory.mktemp("rough") / "mat.npz"
    save_model(mat, path)
    return path


@pytest.mark.parametrize("command", ["inpaint", "extend"])
def test_cli_fill_refuses_a_saved_material_s_maps_given_in_another_order_by_their_names(tmp_path, picture,
                                                                                        monkeypatch, command,
                                                                                        rough_then_height):
    # A saved material takes its maps in its order, whatever their names: 0.59 filled its roughness map from the
    # height map given in its place (both grey) without a word, and failed on a grey map where its normal map goes
    # with "the model is in colour but the image is greyscale; fit the model on a greyscale exemplar".
    monkeypatch.chdir(tmp_path)
    images, hole = picture
    save_image(images["albedo"], tmp_path / "wall.png")
    save_image(hole.astype(float), tmp_path / "mask.png")
    save_image(images["roughness"], tmp_path / "wall_roughness.png")
    save_image(images["height"], tmp_path / "wall_height.png")
    shutil.copyfile(rough_then_height, tmp_path / "mat.npz")
    where = ["mask.png"] if command == "inpaint" else []
    grow = [] if command == "inpaint" else ["--size", "160x160"]
    before = sorted(p.name for p in tmp_path.iterdir())
    result = CliRunner().invoke(main, [command, "wall.png", *where, "--maps", "wall_height.png", "wall_roughness.png",
                                       "--source", "mat.npz", "-o", "o.png", *grow, "-q"])
    assert result.exit_code == 1 and result.output.strip() == (
        "Error: MAP wall_height.png is named as a height map, but --source mat.npz's map 'wall_roughness', a "
        "roughness map, goes there: the maps are taken in the material's order; give them as wall_roughness, "
        "wall_height"), result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    result = CliRunner().invoke(main, [command, "wall.png", *where, "--maps", "wall_roughness.png", "wall_height.png",
                                       "--source", "mat.npz", "-o", "o.png", *grow, "-q", "--seed", "1"])
    assert result.exit_code == 0 and (tmp_path / "o_height.png").exists(), result.output
