"""A two-level exemplar (a 1-bit scan, line art, a stencil) gives a two-level texture (0.57): the model
keeps its levels (``TGHop.exemplar_levels_``, in its file) and ``synthesize`` snaps each pixel to the nearer."""

import json

import numpy as np
from PIL import Image

from conftest import SMALL, cli
from tghop import data
from tghop.modelfile import load_model, save_model
from tghop.synthesis import TGHop

GREY = {**SMALL, "n_channels": None}  # hop 1 of one channel has 4


def black_and_white(size=96, rng=4):
    return (data.bricks(size, rng=rng).mean(axis=2, keepdims=True) > 0.45).astype(np.float64)


def test_a_black_and_white_exemplar_gives_black_and_white(tmp_path):
    # 0.56 blended its seams and refinements into greys: 6 in 10 pixels of a 128x128 image were neither
    model = TGHop(**GREY).fit(black_and_white())
    np.testing.assert_array_equal(model.exemplar_levels_, [[0.0], [1.0]])
    image = model.synthesize((64, 80), rng=1)
    assert set(np.unique(image)) == {0.0, 1.0}
    eight = model.synthesize((64, 80), rng=1, dtype=np.uint8)
    np.testing.assert_array_equal(eight, (image * 255).astype(np.uint8))
    save_model(model, tmp_path / "bw.npz")  # kept in the file
    np.testing.assert_array_equal(load_model(tmp_path / "bw.npz").synthesize((64, 80), rng=1), image)
    two = np.where(black_and_white(), [0.9, 0.2, 0.1], [0.1, 0.3, 0.8])  # two colours: the same
    assert len(np.unique(TGHop(**SMALL).fit(two).synthesize((48, 48), rng=2).reshape(-1, 3), axis=0)) == 2


def test_other_exemplars_keep_their_greys_and_their_files(tmp_path, small_model):
    assert small_model.exemplar_levels_ is None
    assert len(np.unique(small_model.synthesize((48, 48), rng=1))) > 2
    save_model(small_model, tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz") as arrays:
        meta = json.loads(str(arrays["__meta__"]))
    assert "exemplar_shape" in meta and "exemplar_levels" not in meta  # the file as before
    assert load_model(tmp_path / "m.npz").exemplar_levels_ is None


def test_a_1_bit_file_gives_a_black_and_white_image(tmp_path):
    Image.fromarray(black_and_white(128)[..., 0] > 0.5).convert("1").save(tmp_path / "bw.png")
    r = cli("synth", tmp_path / "bw.png", "-o", tmp_path / "out.png", "--size", "64", "--seed", "0", "-q",
            "--clusters", "8", "--codewords", "40", "--stride", "4")
    assert r.returncode == 0, r.stderr.decode()
    assert set(np.unique(np.asarray(Image.open(tmp_path / "out.png")))) == {0, 255}


def test_info_shows_a_two_level_exemplars_levels(tmp_path, small_model):
    # 0.57: tghop info said nothing of them, though its images are snapped to them
    two = np.where(black_and_white(), [0.9, 0.2, 0.1], [0.1, 0.3, 0.8])
    save_model(TGHop(**SMALL).fit(two), tmp_path / "two.npz")
    save_model(TGHop(**GREY).fit(black_and_white()), tmp_path / "bw.npz")
    save_model(small_model, tmp_path / "m.npz")
    said = {name: cli("info", tmp_path / name).stdout.decode() for name in ("two.npz", "bw.npz", "m.npz")}
    assert "exemplar levels: two only, (0.1, 0.3, 0.8) and (0.9, 0.2, 0.1) (its images are snapped to them)" \
        in said["two.npz"]
    assert "exemplar levels: two only, 0 and 1 " in said["bw.npz"]
    assert "exemplar levels" not in said["m.npz"]
    as_json = {name: json.loads(cli("info", "--json", tmp_path / name).stdout) for name in ("bw.npz", "m.npz")}
    assert as_json["bw.npz"]["exemplar_levels"] == [[0.0], [1.0]] and as_json["m.npz"]["exemplar_levels"] is None


def _off_levels(image, levels, where=None):
    """The share of ``image``'s pixels (of ``where``) at neither of ``levels``."""
    image = np.asarray(image, dtype=np.float64)
    on = np.zeros(image.shape[:2], dtype=bool)
    for level in np.asarray(levels, dtype=np.float64):
        on |= np.all(image == level, axis=2)
    return float((~on if where is None else ~on[where]).mean())


def test_inpaint_and_extend_fill_a_two_level_image_with_its_two_levels():
    # 0.57's first two-level models snapped synthesize's images but not inpaint's or extend's fills: 56 % of a
    # hole's pixels (45 % in a uint8 picture) and 53 % of an extension's were greys
    from tghop.inpaint import extend, inpaint

    image = black_and_white()
    model = TGHop(**GREY).fit(image)
    hole = np.zeros(image.shape[:2], dtype=bool)
    hole[30:70, 25:75] = True
    filled = inpaint(model, image, hole, rng=1)
    assert _off_levels(filled, model.exemplar_levels_, hole) == 0
    np.testing.assert_array_equal(filled[~hole], image[~hole])  # the known pixels as they were
    eight = (image * 255).astype(np.uint8)
    filled = inpaint(model, eight, hole, rng=1)
    assert set(np.unique(filled[hole])) == {0, 255}
    np.testing.assert_array_equal(filled[~hole], eight[~hole])
    wider = extend(model, image, (96, 160), rng=1)
    assert _off_levels(wider, model.exemplar_levels_) == 0
    np.testing.assert_array_equal(wider[:, 32:128], image)
    other = TGHop(**SMALL).fit(data.bricks(96, rng=3))  # any other model's fill keeps its greys
    assert len(np.unique(inpaint(other, data.bricks(96, rng=3), hole, rng=1)[hole])) > 2


def test_inpaint_of_a_1_bit_file_gives_black_and_white(tmp_path):
    picture = black_and_white(128)[..., 0] > 0.5
    Image.fromarray(picture).convert("1").save(tmp_path / "bw.png")
    mask = np.zeros(picture.shape, dtype=np.uint8)
    mask[40:80, 40:90] = 255
    Image.fromarray(mask).save(tmp_path / "mask.png")
    save_model(TGHop(**GREY).fit(picture[..., None] * 1.0, exclude=mask > 0), tmp_path / "bw.npz")
    r = cli("inpaint", tmp_path / "bw.png", tmp_path / "mask.png", "-o", tmp_path / "out.png", "--seed", "0", "-q",
            "--source", tmp_path / "bw.npz")
    assert r.returncode == 0, r.stderr.decode()
    out = np.asarray(Image.open(tmp_path / "out.png").convert("L"))
    assert set(np.unique(out)) == {0, 255}
    np.testing.assert_array_equal(out[mask == 0], np.where(picture, 255, 0)[mask == 0])


def test_painted_images_of_two_level_models_keep_their_levels_where_all_share_them():
    # the join between two black-and-white layers blended them into greys (0.3 % of a two-region image, 1.7 % of
    # a morph); models of other levels are joined as before (each layer at its own levels, the join's means kept)
    from tghop.guided import morph, synthesize_guided

    a, b = TGHop(**GREY).fit(black_and_white(rng=4)), TGHop(**GREY).fit(black_and_white(rng=9))
    guide = np.zeros((96, 128), dtype=np.int64)
    guide[:, 64:] = 1
    assert _off_levels(synthesize_guided([a, b], guide, rng=1), a.exemplar_levels_) == 0
    assert set(np.unique(synthesize_guided([a, b], guide, rng=1, dtype=np.uint8))) == {0, 255}
    assert _off_levels(morph(a, b, (64, 192), rng=1), a.exemplar_levels_) == 0
    grey_white = TGHop(**GREY).fit(0.5 + 0.5 * black_and_white(rng=9))
    image = synthesize_guided([a, grey_white], guide, rng=1)
    assert _off_levels(image, [[0.0], [0.5], [1.0]]) > 0  # the join's means, not snapped to any of the levels
    assert _off_levels(image[:, :48], a.exemplar_levels_) == 0 and _off_levels(image[:, 80:], [[0.5], [1.0]]) == 0


def test_the_snap_to_two_levels_is_the_last_step_return_stages_gives(tmp_path):
    # 0.59's stages ended with the patch refinement's (or colour matching's) image, in greys, where the image returned
    # (and synth --stages' OUTPUT) was snapped to the exemplar's two levels: no step showed that snap.
    model = TGHop(**GREY).fit(black_and_white())
    for dtype in (np.float64, np.uint8):
        image, steps = model.synthesize((64, 80), rng=1, return_stages=True, dtype=dtype)
        assert list(steps)[-1] == "levels"
        assert steps["levels"].dtype == np.float32
        np.testing.assert_array_equal(steps["levels"], image / 255 if dtype == np.uint8 else image)
        before = steps[list(steps)[-2]]
        assert len(np.unique(before)) > 2 and set(np.unique(steps["levels"])) == {0.0, 1.0}
    assert "levels" not in TGHop(**SMALL).fit(data.bricks(96)).synthesize((48, 48), rng=1, return_stages=True)[1]
    save_model(model, tmp_path / "bw.npz")
    r = cli("synth", tmp_path / "bw.npz", "-o", tmp_path / "out.png", "--size", "64", "--seed", "0", "--stages")
    assert r.returncode == 0, r.stderr.decode()
    assert "out_levels.png" in r.stderr.decode()
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "out_levels.png")),
                                  np.asarray(Image.open(tmp_path / "out.png")))
