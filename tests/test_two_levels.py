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
