"""Repetition: copied_textured and self_repetition (tghop.metrics), quilting's reuse penalty."""

import numpy as np
import pytest
from scipy import ndimage

from tghop import metrics
from tghop._errors import TGHopError
from tghop.quilting import quilt


def _texture(shape, seed=0, sigma=1.0):
    rng = np.random.default_rng(seed)
    img = ndimage.gaussian_filter(rng.random(shape), (sigma, sigma, 0))
    img -= img.min()
    return img / img.max()


@pytest.fixture(scope="module")
def exemplar():
    return _texture((96, 96, 3))


def test_copied_textured_crop_noise_and_flat(exemplar):
    crop = exemplar[10:74, 20:84]
    assert metrics.copied_textured(exemplar, crop) == 1.0
    noise = np.random.default_rng(5).random((64, 64, 3))
    assert metrics.copied_textured(exemplar, noise) == 0.0
    # A flat result has no textured window: 0, though every window nearly equals a flat one.
    flat_ex = exemplar.copy()
    flat_ex[:40, :40] = 0.5
    flat = np.full((48, 48, 3), 0.5)
    assert metrics.copied(flat_ex, flat) == 1.0
    assert metrics.copied_textured(flat_ex, flat) == 0.0
    # Flat windows are left out: a result half flat (no copy of the exemplar) and half
    # a crop counts only the crop's windows and those that straddle the two.
    half = np.concatenate([np.full((64, 32, 3), 0.5), crop[:, :32]], axis=1)
    assert metrics.copied_textured(exemplar, half) > metrics.copied(exemplar, half) + 0.1
    assert metrics.copied_textured(flat_ex, flat_ex[8:72, 8:72]) == 1.0


def test_flat_coloured_windows_are_not_textured(exemplar):
    # A flat orange window has no texture, though its three channels differ by far more
    # than TEXTURED_STD: the window's deviation is each channel's own, not across channels.
    orange = np.array([0.8, 0.5, 0.2])
    flat = np.broadcast_to(orange, (64, 64, 3)).copy()
    ex = exemplar.copy()
    ex[:40, :40] = orange
    assert metrics.copied(ex, flat) == 1.0
    assert metrics.copied_textured(ex, flat) == 0.0
    assert metrics.self_repetition(flat) == 0.0
    # Smooth colour, no structure: an orange with a gentle ramp (a few grey levels per
    # 16 px) matches itself everywhere within RMS 0.03 but is not a repeated pattern.
    ramp = orange + np.linspace(0.0, 0.05, 160)[:, None, None] + np.zeros((160, 160, 3))
    assert metrics.self_repetition(ramp) == 0.0
    # Texture on a colour still counts, channel by channel.
    textured = 0.3 * orange + 0.7 * exemplar  # windows of deviation 0.08 or so
    assert metrics.copied_textured(textured, textured[8:72, 8:72]) == 1.0


def test_self_repetition_tiled_noise_and_determinism(exemplar):
    tiled = np.tile(exemplar[:40, :40], (4, 4, 1))  # 160 x 160
    assert metrics.self_repetition(tiled) >= 0.95
    noise = np.random.default_rng(1).random((160, 160, 3))
    assert metrics.self_repetition(noise) <= 0.01
    smooth = _texture((160, 160, 3), seed=2, sigma=1.5)
    a = metrics.self_repetition(smooth, max_windows=200, seed=3)
    assert a == metrics.self_repetition(smooth, max_windows=200, seed=3)
    assert 0.0 <= a <= 0.05
    assert metrics.self_repetition(np.full((64, 64), 0.3)) == 0.0  # nothing textured
    # Grey images, a region and search area smaller than the image.
    grey = np.tile(exemplar[:40, :40].mean(axis=2), (5, 5))
    assert metrics.self_repetition(grey, region=64, search=128) >= 0.95


def test_self_repetition_does_not_count_overlapping_shifts():
    # A smooth texture matches its own 1-pixel shifts, which overlap it: not repetition.
    img = _texture((128, 128, 3), seed=4, sigma=6.0)
    shift = np.sqrt(np.mean((img[20:36, 20:36] - img[21:37, 20:36]) ** 2))
    assert shift < 0.03
    assert metrics.self_repetition(img) <= 0.05


def test_self_repetition_errors():
    img = np.zeros((32, 32, 3))
    with pytest.raises(TGHopError):
        metrics.self_repetition(img, patch_size=10)
    with pytest.raises(TGHopError):
        metrics.self_repetition(img, threshold=0)


def _flat_and_noisy_pool(seed=0):
    rng = np.random.default_rng(seed)
    pool = np.clip(0.5 + 0.15 * rng.standard_normal((40, 12, 12, 1)), 0, 1)
    pool[0] = 0.5  # a flat patch: the overlap error prefers it everywhere
    return pool


def test_reuse_penalty_spreads_the_choice():
    pool = _flat_and_noisy_pool()
    plain = quilt(pool, (120, 120), rng=0, tolerance=0.0)
    assert np.array_equal(plain, quilt(pool, (120, 120), rng=0, tolerance=0.0, reuse=0.0))
    spread = quilt(pool, (120, 120), rng=0, tolerance=0.0, reuse=1.0)
    flat_plain = np.mean(plain == 0.5)
    flat_spread = np.mean(spread == 0.5)
    assert flat_plain > 0.5 and flat_spread < flat_plain / 2, (flat_plain, flat_spread)
    assert np.array_equal(spread, quilt(pool, (120, 120), rng=0, tolerance=0.0, reuse=1.0))
    with pytest.raises(TGHopError):
        quilt(pool, (60, 60), reuse=-1.0)


def test_reuse_penalty_without_the_bound_agrees():
    """The bounded candidate search and the full errors pick the same with a penalty."""
    from tghop import quilting

    pool = _flat_and_noisy_pool(1)
    a = quilt(pool, (90, 90), rng=2, reuse=0.5)
    old = quilting._bounded_candidates
    try:
        quilting._bounded_candidates = lambda *args, **kw: None  # every error in full
        b = quilt(pool, (90, 90), rng=2, reuse=0.5)
    finally:
        quilting._bounded_candidates = old
    assert np.allclose(a, b)


def _brute_self_repetition(img, p, threshold, min_std):
    """Every textured p x p window of ``img``: does a non-overlapping one lie within RMS ``threshold``?"""
    from numpy.lib.stride_tricks import sliding_window_view

    win = sliding_window_view(img, (p, p), axis=(0, 1))  # (nh, nw, C, p, p)
    nh, nw = win.shape[:2]
    flat = win.reshape(nh * nw, -1)
    std = np.sqrt(win.reshape(nh * nw, img.shape[2], -1).var(axis=2).mean(axis=1))  # TEXTURED_STD's measure
    ys, xs = np.divmod(np.arange(nh * nw), nw)
    found = []
    for i in np.flatnonzero(std >= min_std):
        far = (np.abs(ys - ys[i]) >= p) | (np.abs(xs - xs[i]) >= p)
        found.append(bool((np.sqrt(((flat[far] - flat[i]) ** 2).mean(axis=1)) < threshold).any()))
    return float(np.mean(found))


@pytest.mark.parametrize("kind, amount", [("noise", 0.022), ("noise", 0.025), ("offset", 0.029), ("offset", 0.031)])
def test_self_repetition_matches_a_brute_force_search(kind, amount):
    # Tiles of one 12 x 12 texture, each repeat differing from the next by noise (which the box
    # means' bound averages away) or by a constant just within or just beyond the threshold (for
    # which the bound is tight): a bound that skipped a pair within 0.03 would lower the score.
    rng = np.random.default_rng(0)
    tile = _texture((12, 12, 3))
    if kind == "noise":
        img = np.clip(np.tile(tile, (4, 4, 1)) + rng.normal(0, amount, (48, 48, 3)), 0, 1)
    else:
        steps = np.arange(4)[:, None] * amount + np.arange(4)[None, :] * 0.07
        img = np.tile(0.1 + 0.5 * tile, (4, 4, 1)) + np.kron(steps, np.ones((12, 12)))[..., None]
    expected = _brute_self_repetition(img, 8, 0.03, metrics.TEXTURED_STD)
    assert 0.0 < expected  # the cases are near the threshold, not trivially 0 ...
    assert expected < 1.0 or amount < 0.03  # ... nor 1 beyond it
    assert metrics.self_repetition(img, patch_size=8, max_windows=10**6) == expected
