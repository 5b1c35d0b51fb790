"""The working scale (tghop.scale, ``TGHop(scale=...)``, ``--scale``), on textures made in code."""

import json

import numpy as np
import pytest

from tghop import TGHopError, data
from tghop.imageio import load_image, save_image, to_uint8
from tghop.modelfile import load_model, save_model
from tghop.scale import rescale, rescale_mask, scaled_shape
from tghop.synthesis import TGHop

from conftest import assert_user_error, cli

#: A small model, fast to fit.
FAST = dict(n_clusters=10, n_codewords=40, max_patches=1200, layout_factor=None, patch_levels=0)


def _dots(size, period, radius=None):
    """(size, size, 3) float: dark discs on a light ground, one every ``period`` pixels each way."""
    radius = period / 4 if radius is None else radius
    y, x = np.mgrid[:size, :size] % period - (period - 1) / 2
    disc = (np.hypot(y, x) <= radius).astype(float)
    return np.repeat((0.85 - 0.6 * disc)[..., None], 3, axis=2)


def _period(image):
    """The dominant spatial period (pixels) of an image's grey values along its rows and columns."""
    grey = np.asarray(image, dtype=float).mean(axis=2)
    grey = grey - grey.mean()
    power = np.abs(np.fft.rfft2(grey)) ** 2
    n = grey.shape[0]
    along = power[1: n // 2, 0] + power[0, 1: n // 2]  # pure vertical and horizontal frequencies
    return n / (1 + int(np.argmax(along)))


def test_scaled_shape_rounds_each_side_and_keeps_the_rest():
    assert scaled_shape((1200, 1600, 3), 1 / 3) == (400, 533, 3)
    assert scaled_shape((10, 3), 0.1) == (1, 1)
    assert scaled_shape((7, 9, 2), 1.0) == (7, 9, 2)
    assert scaled_shape((50, 40), 2.5) == (125, 100)


def test_rescale_filters_before_it_drops_pixels():
    checker = np.indices((96, 96)).sum(axis=0) % 2  # the finest pattern there is: its mean, once halved
    image = np.repeat(checker[..., None], 3, axis=2).astype(float)
    half = rescale(image, 0.5)
    assert half.shape == (48, 48, 3) and half.dtype == np.float64
    assert np.abs(half[4:-4, 4:-4] - 0.5).max() < 0.02  # decimation would give all 0 or all 1
    third = rescale(to_uint8(image), 1 / 3)  # the 8-bit path, one call for three channels
    assert third.shape == (32, 32, 3) and third.dtype == np.uint8
    assert np.abs(third[4:-4, 4:-4].astype(int) - 128).max() <= 6
    flat = np.full((40, 30, 5), 0.25)  # a material's stack: channel by channel
    assert np.allclose(rescale(flat, 0.7), 0.25, atol=1e-6) and rescale(flat, 0.7).shape == (28, 21, 5)
    assert rescale(image, 1.0) is image
    edge = np.zeros((64, 64, 1))
    edge[:, 32:] = 1.0  # Lanczos overshoots beside an edge: clipped
    assert 0.0 <= rescale(edge, 0.6).min() and rescale(edge, 0.6).max() <= 1.0


def test_rescale_mask_marks_every_pixel_an_excluded_one_reaches():
    mask = np.zeros((100, 100), dtype=bool)
    mask[41, 60] = True
    small = rescale_mask(mask, 0.25)
    assert small.shape == (25, 25) and small.dtype == bool
    assert small[10, 15] and small.sum() <= 4  # the box that holds it, no more than its neighbours
    assert rescale_mask(None, 0.5) is None
    assert rescale_mask(mask, 1.0) is mask


def test_a_scaled_model_is_the_model_of_the_resampled_exemplar():
    image = data.cells(128, rng=2)
    model = TGHop(scale=0.75, rng=0, **FAST).fit(image)
    direct = TGHop(rng=0, **FAST).fit(rescale(image, 0.75))
    assert model.exemplar_shape_ == (96, 96, 3) == direct.exemplar_shape_
    assert np.array_equal(model.synthesize((64, 64), rng=1, n_patches=300),
                          direct.synthesize((64, 64), rng=1, n_patches=300))
    assert not np.array_equal(model.synthesize((64, 64), rng=1, n_patches=300),
                              TGHop(rng=0, **FAST).fit(image).synthesize((64, 64), rng=1, n_patches=300))


def test_elements_come_out_scaled():
    image = _dots(192, 24)
    assert _period(image) == 24
    full = TGHop(rng=0, **FAST).fit(image).synthesize((192, 192), rng=0, n_patches=600)
    half = TGHop(scale=0.5, rng=0, **FAST).fit(image).synthesize((192, 192), rng=0, n_patches=600)
    assert _period(full) == 24
    assert _period(half) == 12


def test_the_sample_mask_is_resampled_with_the_exemplar():
    image = data.cells(160, rng=1)
    image[40:90, 50:100] = (1.0, 0.0, 0.0)
    label = np.zeros((160, 160), dtype=bool)
    label[40:90, 50:100] = True
    model = TGHop(scale=0.6, rng=0, **FAST).fit(image, exclude=label)
    red = model.sample_patches(300, rng=1)
    assert model.exemplar_shape_ == (96, 96, 3)
    assert not np.any((red[..., 0] > 0.8) & (red[..., 1] < 0.2))  # the label's red is not learnt
    assert model.colour_quantiles_[0, -1] < 0.9  # nor counted in the colour statistics, even at its blurred rim


def test_too_small_at_the_scale_names_the_scale_that_works():
    with pytest.raises(TGHopError, match=r"exemplar is 26x26 pixels at scale 0\.1 \(given 256x256\), .*"
                                         r"use an exemplar of at least \d+x\d+ pixels.*a scale of at least 0\.\d+"):
        TGHop(scale=0.1).fit(data.bricks())
    with pytest.raises(TGHopError, match=r"scale must be a finite number > 0 and <= 4, got 0\.0"):
        TGHop(scale=0).fit(data.bricks())
    model = TGHop(scale=0.1)
    with pytest.raises(TGHopError, match="at scale 0.1"):  # the check the CLI, batch and server make first
        model.check_exemplar_size((256, 256, 3))
    model.set_params(scale=0.5).check_exemplar_size((256, 256, 3))


def test_the_least_exemplar_named_at_a_scale_is_the_least_that_fits():
    # At scale 0.5 it said "at least 152x152 pixels", but 151 pixels resample to round(75.5) = 76, as 152 do
    # (0.57's least, 76x76; from 0.58 44x44: 87 pixels resample to round(43.5) = 44).
    model = TGHop(scale=0.5)
    with pytest.raises(TGHopError, match="at least 87x87 pixels") as info:
        model.check_exemplar_size((60, 60, 3))
    side = info.value.least_side
    model.check_exemplar_size((side, side, 3))  # the side named is enough
    with pytest.raises(TGHopError):
        model.check_exemplar_size((side - 1, side - 1, 3))  # and one pixel less is not
    for scale in (0.3, 0.7, 1.7, 2.5):
        model.set_params(scale=scale)
        with pytest.raises(TGHopError) as info:
            model.check_exemplar_size((16, 16, 3))
        side = info.value.least_side
        model.check_exemplar_size((side, side, 3))
        with pytest.raises(TGHopError):
            model.check_exemplar_size((side - 1, side - 1, 3))


def test_model_files_keep_the_scale(tmp_path):
    model = TGHop(scale=0.75, rng=0, **FAST).fit(data.cells(128, rng=2))
    save_model(model, tmp_path / "m.npz")
    back = load_model(tmp_path / "m.npz")
    assert back.scale == 0.75 and back.exemplar_shape_ == (96, 96, 3)
    assert np.array_equal(back.synthesize((64, 64), rng=1, n_patches=300),
                          model.synthesize((64, 64), rng=1, n_patches=300))


def test_command_line_scale(tmp_path):
    save_image(data.cells(128, rng=2), tmp_path / "ex.png")
    done = cli("fit", tmp_path / "ex.png", "-o", tmp_path / "m.npz", "--scale", "0.75", "--clusters", "10",
               "--codewords", "40", "--max-patches", "1200", "-q")
    assert done.returncode == 0, done.stderr.decode()
    info = cli("info", tmp_path / "m.npz")
    assert "exemplar: 96x96 (resampled by --scale 0.75), 3 channels" in info.stdout.decode()
    done = cli("synth", tmp_path / "ex.png", "-o", tmp_path / "out.png", "--scale", "0.75", "--size", "64x64",
               "--clusters", "10", "--codewords", "40", "--max-patches", "1200", "--pool", "300", "-q")
    assert done.returncode == 0, done.stderr.decode()
    assert load_image(tmp_path / "out.png").shape == (64, 64, 3)
    done = cli("clusters", tmp_path / "m.npz", tmp_path / "ex.png", "-o", tmp_path / "map.png", "-q")
    assert done.returncode == 0, done.stderr.decode()
    assert load_image(tmp_path / "map.png").shape == (96, 192, 3)  # the exemplar as the model saw it, and its map
    scores = [cli("evaluate", tmp_path / "ex.png", tmp_path / "out.png", "--metrics", "swd", "--json", *extra)
              for extra in ((), ("--scale", "0.75"))]
    assert all(r.returncode == 0 for r in scores)
    plain, scaled = (json.loads(r.stdout)["swd"] for r in scores)
    assert scaled != plain  # scored against the exemplar resampled as the model saw it
    r = cli("evaluate", tmp_path / "ex.png", tmp_path / "out.png", "--scale", "0.1", "--metrics", "swd")
    assert_user_error(r, "ex.png at --scale 0.1 is 13x13 pixels but swd needs at least")  # not "ex.png is 13x13"
    for bad in ("0", "nan"):  # NaN passed click's FloatRange and reached the resampling (a traceback)
        for command in (("evaluate", tmp_path / "ex.png", tmp_path / "out.png"),
                        ("extend", tmp_path / "ex.png", "-o", tmp_path / "bad.png")):
            assert_user_error(cli(*command, "--scale", bad), f"'--scale': '{bad}' must be a finite number > 0")
    for bad, why in (("0", "'--scale': '0' must be a finite number > 0"), ("x", "'x' is not a number"),
                     ("0.05", "at scale 0.05 (given 128x128)")):
        assert_user_error(cli("synth", tmp_path / "ex.png", "-o", tmp_path / "bad.png", "--scale", bad), why)
        assert not (tmp_path / "bad.png").exists()


def test_inpaint_fits_a_source_exemplar_at_a_working_scale(tmp_path):
    picture = to_uint8(data.cells(96, rng=3))
    hole = np.zeros((96, 96), dtype=bool)
    hole[30:62, 34:66] = True
    save_image(picture, tmp_path / "photo.png")
    save_image(hole.astype(float), tmp_path / "hole.png")
    save_image(data.cells(192, rng=5), tmp_path / "closeup.png")
    done = cli("inpaint", tmp_path / "photo.png", tmp_path / "hole.png", "-o", tmp_path / "out.png", "--source",
               tmp_path / "closeup.png", "--scale", "0.5", "--seed", "1", "-q")
    assert done.returncode == 0, done.stderr.decode()
    out = load_image(tmp_path / "out.png", dtype=None)
    assert np.array_equal(out[~hole], picture[~hole]) and not np.array_equal(out[hole], picture[hole])
    save_model(TGHop(rng=0, **FAST).fit(data.cells(128)), tmp_path / "m.npz")
    for source, why in (((), "IMAGE's own texture is at IMAGE's scale already"),
                        (("--source", tmp_path / "m.npz"), "a saved model keeps the scale it was fitted at")):
        r = cli("inpaint", tmp_path / "photo.png", tmp_path / "hole.png", "-o", tmp_path / "bad.png", *source,
                "--scale", "0.5")
        assert_user_error(r, "--scale applies to an exemplar given as --source", why, status=2)  # a usage error
        assert not (tmp_path / "bad.png").exists()
