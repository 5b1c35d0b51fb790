"""Tests of tghop.baselines on tiny textures made in code."""

from __future__ import annotations

import math
import sys
import types

import numpy as np
import pytest

from tghop import baselines, data
from tghop._errors import InvalidImageError, TGHopError
from tghop._images import MAX_PIXELS
from tghop.baselines import BASELINES, MissingExtraError

NUMPY_BASELINES = ["crop", "blurred-crop", "colour-noise"]



pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def exemplar():
    return data.bricks(48)


@pytest.mark.parametrize("name", NUMPY_BASELINES)
@pytest.mark.parametrize("size, shape", [(None, (48, 48)), (32, (32, 32)), ((20, 40), (20, 40))])
def test_reference_points_size_range_and_seed(name, size, shape, exemplar):
    fn = BASELINES[name]
    out = fn(exemplar, size, rng=3)
    assert out.shape == shape + (3,)
    assert out.dtype == np.float64 and out.min() >= 0 and out.max() <= 1
    np.testing.assert_array_equal(out, fn(exemplar, size, rng=3))


def test_crop_is_a_piece_of_the_exemplar(exemplar):
    out = baselines.crop(exemplar, 16, rng=0)
    windows = np.lib.stride_tricks.sliding_window_view(exemplar, (16, 16), axis=(0, 1))
    found = (windows.transpose(0, 1, 3, 4, 2) == out).all(axis=(2, 3, 4))
    assert found.any()
    assert not np.array_equal(out, baselines.crop(exemplar, 16, rng=1))
    np.testing.assert_array_equal(baselines.crop(exemplar, rng=0), exemplar)


def test_crops_larger_than_the_exemplar_are_refused(exemplar):
    with pytest.raises(TGHopError, match="does not fit"):
        baselines.crop(exemplar, 64)
    with pytest.raises(TGHopError):
        baselines.blurred_crop(exemplar, (10, 49))
    with pytest.raises(TGHopError):
        baselines.crop(exemplar, 0)
    with pytest.raises(TGHopError):
        baselines.blurred_crop(exemplar, 16, sigma=0)


@pytest.mark.parametrize("name", ["crop", "blurred-crop", "colour-noise", "quilting", "ustyuzhaninov", "gpdm"])
def test_sizes_above_the_pixel_limit_are_refused_before_any_work(name, exemplar, monkeypatch):
    if name in ("ustyuzhaninov", "gpdm"):
        pytest.importorskip("torch")

    def no_quilt(*args, **kwargs):
        raise AssertionError("quilting started")

    monkeypatch.setitem(sys.modules, "tghop.quilting", types.SimpleNamespace(quilt=no_quilt))
    side = math.isqrt(MAX_PIXELS) + 1
    with pytest.raises(TGHopError, match="above the limit"):
        BASELINES[name](exemplar, side, rng=0)
    with pytest.raises(TGHopError, match="above the limit"):
        BASELINES[name](exemplar, (2, MAX_PIXELS), rng=0)


def test_blurred_crop_is_smoother(exemplar):
    sharp = baselines.crop(exemplar, rng=0)
    soft = baselines.blurred_crop(exemplar, rng=0, sigma=1.5)
    assert np.abs(np.diff(soft, axis=1)).mean() < 0.7 * np.abs(np.diff(sharp, axis=1)).mean()


def test_colour_noise_matches_colour_statistics(exemplar):
    soft = 0.25 + 0.5 * exemplar  # no clipping of the noise at 0 and 1
    noise = baselines.colour_noise(soft, 256, rng=0)
    px, pn = soft.reshape(-1, 3), noise.reshape(-1, 3)
    np.testing.assert_allclose(pn.mean(axis=0), px.mean(axis=0), atol=0.01)
    np.testing.assert_allclose(np.cov(pn, rowvar=False), np.cov(px, rowvar=False), atol=0.003)
    # Greyscale (and grey stored as RGB: a singular covariance) work too.
    grey = exemplar.mean(axis=2)
    assert baselines.colour_noise(grey, 16, rng=0).shape == (16, 16, 1)
    grey_rgb = np.repeat(grey[..., None], 3, axis=2)
    out = baselines.colour_noise(grey_rgb, 16, rng=0)
    np.testing.assert_allclose(out[..., 0], out[..., 2], atol=1e-6)


def test_greyscale_reference_points(exemplar):
    grey = exemplar.mean(axis=2)
    for name in NUMPY_BASELINES:
        assert BASELINES[name](grey, 16, rng=0).shape == (16, 16, 1)


def test_progress_is_reported(exemplar):
    calls = []
    baselines.crop(exemplar, 8, rng=0, progress=lambda *a: calls.append(a))
    assert calls[-1][1] == calls[-1][2]


def test_quilting_builds_the_pool_from_all_exemplar_patches(exemplar, monkeypatch):
    seen = {}

    def fake_quilt(pool, size, *, overlap=None, tolerance=0.1, tile=False, rng=None, progress=None):
        seen.update(pool=pool, size=size, overlap=overlap, tolerance=tolerance, tile=tile)
        return np.zeros(tuple(size) + (pool.shape[3],))

    monkeypatch.setitem(sys.modules, "tghop.quilting", types.SimpleNamespace(quilt=fake_quilt))
    out = baselines.quilting(exemplar, (40, 30), patch_size=16, max_patches=None, tolerance=0.2, rng=0)
    assert out.shape == (40, 30, 3)
    assert seen["pool"].shape == (33 * 33, 16, 16, 3) and seen["pool"].dtype == np.float32
    np.testing.assert_allclose(seen["pool"][0], exemplar[:16, :16], atol=1e-6)
    np.testing.assert_allclose(seen["pool"][-1], exemplar[-16:, -16:], atol=1e-6)
    assert seen["tolerance"] == 0.2
    baselines.quilting(exemplar, 40, patch_size=16, max_patches=100, rng=0)
    assert seen["pool"].shape == (100, 16, 16, 3)
    with pytest.raises(InvalidImageError):
        baselines.quilting(exemplar, 40, patch_size=64)


def test_quilting_runs(exemplar):
    pytest.importorskip("tghop.quilting")
    out = baselines.quilting(exemplar, 40, patch_size=16, rng=0)
    assert out.shape == (40, 40, 3) and 0 <= out.min() and out.max() <= 1
    np.testing.assert_array_equal(out, baselines.quilting(exemplar, 40, patch_size=16, rng=0))


def test_ustyuzhaninov_reduces_its_gram_loss(exemplar):
    pytest.importorskip("torch")
    small = exemplar[:32, :32]
    calls = []
    out, info = baselines.ustyuzhaninov(
        small, 24, n_iter=8, scales=(3, 7, 15), n_maps=16, rng=0, return_info=True,
        progress=lambda *a: calls.append(a),
    )
    assert out.shape == (24, 24, 3) and out.dtype == np.float64
    assert 0 <= out.min() and out.max() <= 1
    assert info["n_iter"] == 8 and info["n_evals"] >= 8 and info["n_features"] == 3 * 16
    assert info["loss"] < 0.5 * info["initial_loss"]
    assert calls[0] == ("ustyuzhaninov", 0, 8) and calls[-1] == ("ustyuzhaninov", 8, 8)
    again = baselines.ustyuzhaninov(small, 24, n_iter=8, scales=(3, 7, 15), n_maps=16, rng=0)
    np.testing.assert_allclose(again, out, atol=1e-3)


def test_ustyuzhaninov_greyscale_and_zero_iterations(exemplar):
    pytest.importorskip("torch")
    grey = exemplar[:32, :32].mean(axis=2)
    out, info = baselines.ustyuzhaninov(grey, n_iter=0, scales=(3, 5), n_maps=4, rng=0, return_info=True)
    assert out.shape == (32, 32, 1) and info["n_iter"] == 0 and info["n_evals"] == 0
    with pytest.raises(TGHopError):
        baselines.ustyuzhaninov(grey, n_iter=1, scales=(4,))


@pytest.mark.parametrize("options, message", [
    ({"n_iter": 2.5}, r"^n_iter must be an integer from 0 to 20,000, got 2.5$"),  # was run as 2 iterations
    ({"n_maps": 1.5}, r"^n_maps must be an integer >= 1, got 1.5$"),  # was run with 1 map
    ({"scales": (3, 4.9)}, r"^scales must be odd positive filter sizes, got \(3, 4.9\)$"),  # was a filter of 4
])
def test_ustyuzhaninov_refuses_fractional_counts_instead_of_truncating(options, message, exemplar):
    pytest.importorskip("torch")
    with pytest.raises(TGHopError, match=message):
        baselines.ustyuzhaninov(exemplar, 16, rng=0, **options)


def test_step_counts_without_end_are_refused_before_any_work(exemplar, monkeypatch):
    # n_iter = 10**11 ran for days; the bounds are ten times the papers' counts.
    pytest.importorskip("torch")
    from tghop import gpdm

    def work(*args, **kwargs):
        pytest.fail("the work started: the count was not refused first")

    monkeypatch.setattr(baselines, "RandomCNN", work)
    monkeypatch.setattr(gpdm, "_run", work)
    with pytest.raises(TGHopError, match=r"^n_iter must be an integer from 0 to 20,000, got 20001$"):
        baselines.ustyuzhaninov(exemplar, 16, n_iter=20_001)
    with pytest.raises(TGHopError, match=r"^gpdm: n_steps must be an integer from 0 to 3,000, got 3001$"):
        baselines.gpdm(exemplar, 16, n_steps=3_001)


def test_ustyuzhaninov_without_torch_raises_install_hint(exemplar, monkeypatch, without_torch):
    with pytest.raises(MissingExtraError, match=r"needs PyTorch; install it with: pip install 'tghop\[metrics\]' "
                                                r"\(where pip would fetch a CUDA build .* CPU build of torch 2\.13\.0"):
        baselines.ustyuzhaninov(exemplar, n_iter=1)


def test_ustyuzhaninov_default_model_runs(exemplar):
    pytest.importorskip("torch")
    out = baselines.ustyuzhaninov(exemplar[:24, :24], n_iter=1, rng=0)  # 8 scales x 128 maps
    assert out.shape == (24, 24, 3)


def test_registry_has_a_uniform_signature(exemplar):
    assert set(BASELINES) == {"crop", "blurred-crop", "colour-noise", "quilting", "ustyuzhaninov", "cooc", "gpdm"}
    for fn in BASELINES.values():
        assert callable(fn) and fn.__doc__


@pytest.mark.parametrize("mode", ["same", "valid"])
def test_random_cnn_fft_and_direct_convolution_agree(mode, exemplar, monkeypatch):
    torch = pytest.importorskip("torch")
    from tghop import _random_cnn

    filters = _random_cnn.random_filters((3, 15), 4, 3, np.random.default_rng(0))
    x = _random_cnn.to_tensor(torch, exemplar[:40, :36], exemplar.reshape(-1, 3).mean(axis=0))
    fft = _random_cnn.RandomCNN(torch, filters).features(x, mode)  # 15 > DIRECT_MAX: by FFT
    monkeypatch.setattr(_random_cnn, "DIRECT_MAX", 15)
    direct = _random_cnn.RandomCNN(torch, filters).features(x, mode)
    assert fft.shape == direct.shape == (8, 40 * 36 if mode == "same" else 26 * 22)
    np.testing.assert_allclose(fft.numpy(), direct.numpy(), atol=1e-5)
    with pytest.raises(TGHopError, match="odd"):
        _random_cnn.check_scales((3, 4))


# ------------------------------------------------------------------ memory
def _largest(message):
    import re

    m = re.search(r"largest size that fits is about (\d+)x(\d+)", message)
    assert m, message
    return int(m.group(1)), int(m.group(2))


@pytest.mark.parametrize("name, asked", [("crop", (40, 40)), ("blurred-crop", (40, 40)), ("colour-noise", (600, 300)),
                                         ("quilting", (600, 300)), ("ustyuzhaninov", (800, 400))])
def test_sizes_beyond_the_available_memory_are_refused_naming_one_that_fits(name, asked, exemplar, monkeypatch):
    from tghop import _random_cnn, _resources

    estimate = baselines.memory_estimate(name, exemplar.shape)
    base = estimate(1, 1)  # the fixed costs (blurred-crop: the blurred exemplar; quilting: the pool)
    avail = base + (estimate(*asked) - base) / 3
    monkeypatch.setattr(_resources, "available_memory", lambda: avail)
    if name == "ustyuzhaninov":
        pytest.importorskip("torch")
        monkeypatch.setattr(_random_cnn.RandomCNN, "__init__", lambda *a, **k: pytest.fail("work started"))
    monkeypatch.setattr("tghop.quilting.quilt", lambda *a, **k: pytest.fail("work started"))
    with pytest.raises(TGHopError, match="of memory but only") as info:
        BASELINES[name](exemplar, asked, rng=0)
    h, w = _largest(str(info.value))
    assert 0 < h < asked[0] and 0 < w < asked[1]
    assert abs(h / w - asked[0] / asked[1]) < 0.05  # the asked aspect ratio
    assert estimate(h, w) <= avail < estimate(h + 2, w + 2)  # the largest, give or take a pixel of rounding
    monkeypatch.undo()
    if name in NUMPY_BASELINES:  # the size named runs
        monkeypatch.setattr(_resources, "available_memory", lambda: avail)
        assert BASELINES[name](exemplar, (h, w), rng=0).shape[:2] == (h, w)


def test_memory_is_not_checked_where_unknown(exemplar, monkeypatch):
    from tghop import _resources

    monkeypatch.setattr(_resources, "available_memory", lambda: None)
    assert baselines.colour_noise(exemplar, 64, rng=0).shape == (64, 64, 3)


def test_available_memory_reads_the_machine():
    from tghop._resources import available_memory

    avail = available_memory()
    assert avail is None or avail > 0


def test_ustyuzhaninov_estimate_grows_with_the_size_and_the_maps(exemplar):
    small = baselines.memory_estimate("ustyuzhaninov", exemplar.shape)
    fewer = baselines.memory_estimate("ustyuzhaninov", exemplar.shape, n_maps=8, scales=(3, 5))
    assert small(8192, 8192) > 1e12 > small(256, 256) > small(128, 128)  # 8192: the 114 GB allocation and more
    assert fewer(256, 256) < small(256, 256) / 10


def test_cli_refuses_a_size_beyond_the_memory_in_one_line(tmp_path, monkeypatch):
    pytest.importorskip("torch")
    from click.testing import CliRunner

    from tghop import _resources
    from tghop.cli import main

    monkeypatch.setattr(_resources, "available_memory", lambda: 2e9)
    out = tmp_path / "u.png"
    result = CliRunner().invoke(main, ["baseline", "ustyuzhaninov", "builtin:bricks", "--size", "8192", "-o", str(out)])
    assert result.exit_code != 0 and not out.exists()
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("Error: the ustyuzhaninov baseline at size 8192x8192"), result.output
    assert "largest size that fits" in lines[0] and "Traceback" not in result.output


def test_cli_keeps_a_16bit_exemplar_with_depth_and_warns_without(tmp_path):
    # It wrote 8 bits without a word; as synth: a warning naming --depth 16, which keeps every level.
    from click.testing import CliRunner

    from tghop.cli import main
    from tghop.imageio import load_image, save_image

    levels = np.random.default_rng(0).integers(0, 65536, (40, 40, 3)).astype(np.uint16)
    save_image(levels / 65535.0, tmp_path / "deep.png", depth=16)

    def run(source, name, *more):
        result = CliRunner().invoke(main, ["baseline", "crop", source, "-o", str(tmp_path / name), *more])
        assert result.exit_code == 0, result.output
        return [line for line in result.output.splitlines() if line.startswith("Warning")]

    assert run(str(tmp_path / "deep.png"), "a.png") == [
        f"Warning: EXEMPLAR {tmp_path / 'deep.png'} has more than 8 bits a channel, but the image is written with 8; "
        "pass --depth 16 to keep them"]
    assert load_image(tmp_path / "a.png", with_depth=True)[1] == 8
    assert run(str(tmp_path / "deep.png"), "b.png", "--depth", "16") == []
    image, depth = load_image(tmp_path / "b.png", with_depth=True)
    assert depth == 16 and np.array_equal(np.round(image * 65535).astype(np.uint16), levels)  # the crop: all of it
    assert run("builtin:bricks", "c.png", "--size", "32") == []  # the built-ins are 8-bit
    bad = CliRunner().invoke(main, ["baseline", "crop", str(tmp_path / "deep.png"), "-o", str(tmp_path / "d.jpg"),
                                    "--depth", "16"])
    assert bad.exit_code != 0 and bad.output.count("\n") == 1 and "JPEG cannot hold 16-bit" in bad.output
    assert not (tmp_path / "d.jpg").exists()
    # To JPEG, which --depth 16 alone cannot give, the fix names the formats that hold 16 bits first.
    assert run(str(tmp_path / "deep.png"), "e.jpg") == [
        f"Warning: EXEMPLAR {tmp_path / 'deep.png'} has more than 8 bits a channel, but the image is written with 8; "
        "name the output .png, .tif or .tiff and pass --depth 16 to keep them"]


# ---------------------------------------------------------------------------------------
# GPDM
# ---------------------------------------------------------------------------------------


def _patch_swd(a, b, patch_size=7, n_projections=256):
    """Sliced Wasserstein distance of two images' patches, fixed projections (numpy)."""
    def patches(img):
        w = np.lib.stride_tricks.sliding_window_view(img, (patch_size, patch_size), axis=(0, 1))
        return w.reshape(-1, w.shape[2] * patch_size * patch_size)

    pa, pb = patches(a), patches(b)
    d = np.random.default_rng(0).standard_normal((pa.shape[1], n_projections))
    d /= np.linalg.norm(d, axis=0)
    qa, qb = np.sort(pa @ d, axis=0), np.sort(pb @ d, axis=0)
    q = (np.arange(len(qa)) + 0.5) / len(qa)
    qb = np.stack([np.quantile(qb[:, j], q) for j in range(n_projections)], axis=1)
    return float(np.abs(qa - qb).mean())


def test_gpdm_levels_and_memory():
    from tghop.gpdm import gpdm_levels, gpdm_memory

    levels = gpdm_levels((256, 256, 3), (128, 128))
    assert levels[0][0] == (21, 21) and levels[-1] == ((128, 128), (256, 256)) and len(levels) == 12
    assert all(a[0][0] < b[0][0] for a, b in zip(levels, levels[1:]))
    assert gpdm_levels((20, 20, 3), (16, 16)) == [((16, 16), (20, 20))]
    assert gpdm_levels((24, 24, 3), (24, 24), coarsest=20) == [((20, 20), (20, 20)), ((24, 24), (24, 24))]
    assert gpdm_memory((256, 256, 3), (512, 512)) > 4 * gpdm_memory((256, 256, 3), (128, 128)) / 2


def test_gpdm_shapes_range_seed_and_progress(exemplar):
    pytest.importorskip("torch")
    calls = []
    out, info = baselines.gpdm(exemplar[:24, :24], (24, 20), n_steps=3, coarsest=16, rng=0, n_threads=1,
                               progress=lambda *a: calls.append(a), return_info=True)
    assert out.shape == (24, 20, 3) and out.dtype == np.float64 and 0 <= out.min() and out.max() <= 1
    assert len(info["levels"]) == 2 and info["levels"][-1] == ((24, 20), (24, 24))
    assert calls[0] == ("gpdm level 1/2", 0, 3) and calls[-1] == ("gpdm level 2/2", 3, 3)
    again = baselines.gpdm(exemplar[:24, :24], (24, 20), n_steps=3, coarsest=16, rng=0, n_threads=1)
    np.testing.assert_array_equal(again, out)
    other = baselines.gpdm(exemplar[:24, :24], (24, 20), n_steps=3, coarsest=16, rng=1, n_threads=1)
    assert not np.array_equal(other, out)
    grey = baselines.gpdm(exemplar[:16, :16].mean(axis=2), 12, n_steps=1, rng=0, n_threads=1)
    assert grey.shape == (12, 12, 1)


def test_gpdm_reduces_the_patch_swd(exemplar):
    pytest.importorskip("torch")
    small = exemplar[:24, :24]
    kwargs = dict(coarsest=20, rng=0, n_threads=1, lr=0.05)
    start = baselines.gpdm(small, 24, n_steps=0, **kwargs)  # the initial noise, upsampled
    out, info = baselines.gpdm(small, 24, n_steps=5, return_info=True, **kwargs)
    assert len(info["levels"]) == 2
    assert _patch_swd(out, small) < 0.8 * _patch_swd(start, small)
    assert all(last < first for first, last in info["losses"])


def test_gpdm_restores_the_thread_count(exemplar):
    torch = pytest.importorskip("torch")
    before = torch.get_num_threads()
    baselines.gpdm(exemplar[:12, :12], 12, n_steps=1, rng=0, n_threads=2)
    assert torch.get_num_threads() == before


def test_gpdm_refusals(exemplar, monkeypatch):
    with pytest.raises(TGHopError, match="at least 7x7"):
        baselines.gpdm(exemplar, 6)
    with pytest.raises(TGHopError, match="scale_factor"):
        baselines.gpdm(exemplar, 16, scale_factor=1.0)
    with pytest.raises(TGHopError, match="init"):
        baselines.gpdm(exemplar, 16, init="zeros")
    bad = [("n_steps", -1, "an integer from 0 to 3,000"), ("n_steps", 2.5, "an integer from 0 to 3,000"),
           ("n_projections", 0, "an integer >= 1"),
           ("patch_size", True, "an integer >= 1"), ("coarsest", "8", "an integer >= 1"),
           ("scale_factor", 0.0, "a finite number > 0"), ("scale_factor", float("nan"), "a finite number > 0"),
           ("lr", 0, "a finite number > 0"), ("lr", float("inf"), "a finite number > 0"),
           ("noise_sigma", -0.5, "a finite number >= 0"), ("noise_sigma", "0.5", "a finite number >= 0")]
    for name, value, wanted in bad:
        with pytest.raises(TGHopError, match=rf"^gpdm: {name} must be {wanted}, got "):
            baselines.gpdm(exemplar, 16, **{name: value})
    from tghop import _resources

    monkeypatch.setattr(_resources, "available_memory", lambda: 8 * 2**20)  # 8 MB available
    with pytest.raises(TGHopError, match="the gpdm baseline .*64x64 .*of memory but only .*largest size that fits"):
        baselines.gpdm(exemplar, 64)


def test_gpdm_without_torch_raises_install_hint(exemplar, monkeypatch, without_torch):
    with pytest.raises(MissingExtraError,
                       match=r"GPDM baseline needs PyTorch; install it with: pip install 'tghop\[metrics\]'"):
        baselines.gpdm(exemplar, n_steps=1)


def test_memory_estimate_covers_every_baseline_it_lists(exemplar):
    from tghop.gpdm import gpdm_memory

    for name in BASELINES:
        if name != "cooc":  # its estimate imports the cGAN's module (PyTorch)
            assert baselines.memory_estimate(name, exemplar.shape)(64, 64) > 0
    assert baselines.memory_estimate("gpdm", exemplar.shape)(64, 96) == gpdm_memory(exemplar.shape, (64, 96))
    with pytest.raises(TGHopError, match=r"^unknown baseline 'nope'; one of crop, .*gpdm$"):
        baselines.memory_estimate("nope", exemplar.shape)


@pytest.mark.parametrize("sigma", [float("inf"), float("nan"), 0, -1.0, "a", None, True])
def test_blurred_crop_refuses_a_sigma_that_is_not_finite_and_positive(sigma, exemplar):
    with pytest.raises(TGHopError, match=r"^sigma must be a finite number > 0, got"):
        baselines.blurred_crop(exemplar, 16, sigma=sigma)
    assert baselines.blurred_crop(exemplar, 16, sigma=2, rng=0).shape == (16, 16, 3)


@pytest.mark.parametrize("make", [data.bricks, data.cells])
def test_builtin_exemplar_sizes_are_checked_before_any_work(make):
    with pytest.raises(TGHopError, match=r"^size 1000000x1000000 is .* above the limit of"):
        make(10**6)
    for bad in (40.5, "a", None, True):
        with pytest.raises(TGHopError, match=r"^size must be an integer >= 32, got"):
            make(bad)
    with pytest.raises(TGHopError, match=r"^size must be an integer >= 32, got 10$"):
        make(10)
    assert make(np.int64(32)).shape == (32, 32, 3)


def test_the_cells_exemplar_needs_memory_of_its_pixels_not_of_pixels_times_seeds():
    # Every pixel against every cell seed: (size ** 2, size ** 2 / 500, 2) floats, 0.7 GB at
    # 384x384 and 33 GB at 1024x1024 (a periodic KD-tree now finds each pixel's two nearest).
    import tracemalloc

    tracemalloc.start()
    try:
        img = data.cells(384, rng=1)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert img.shape == (384, 384, 3) and peak < 100 * 2**20, peak


@pytest.mark.parametrize("name, options, message", [
    ("quilting", {"patch_size": 16.7}, r"^patch_size must be an integer >= 2, got 16.7$"),  # was quilted with 16
    ("quilting", {"patch_size": "a"}, r"^patch_size must be an integer >= 2, got 'a'$"),  # was Python's ValueError
    ("quilting", {"max_patches": 2.5}, r"^max_patches must be an integer >= 1, got 2.5$"),  # was a pool of 2
    ("gpdm", {"n_threads": 0}, r"^gpdm: n_threads must be an integer >= 1, got 0$"),  # was torch's RuntimeError
])
def test_a_baseline_refuses_a_bad_count_in_one_line(name, options, message, exemplar):
    if name == "gpdm":
        pytest.importorskip("torch")
    with pytest.raises(TGHopError, match=message):
        BASELINES[name](exemplar[:48, :48], 32, rng=0, **options)
