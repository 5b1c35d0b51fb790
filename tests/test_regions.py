"""Tests of tghop.regions: refinement and colour matching region by region, cross-faded."""

from __future__ import annotations

import numpy as np
import pytest

from tghop import TGHopError
from tghop.colour import channel_quantiles, match_histograms
from tghop.regions import OVERLAP, match_regions, n_regions, region_spans


@pytest.mark.parametrize("periodic", [False, True])
@pytest.mark.parametrize("n, count", [(520, 2), (2048, 2), (1000, 3), (4096, 4), (300, 1)])
def test_region_weights_sum_to_one_everywhere(n, count, periodic):
    total = np.zeros(n)
    covered = np.zeros(n, dtype=int)
    spans = region_spans(n, count, periodic=periodic)
    assert len(spans) == count
    for start, weights in spans:
        index = np.arange(start, start + len(weights))
        if not periodic or count == 1:
            assert 0 <= index[0] and index[-1] < n
        assert len(np.unique(index % n)) == len(index)  # no pixel twice in one span
        np.add.at(total, index % n, weights)
        np.add.at(covered, index % n, 1)
        assert weights.min() > 0 and weights.max() == 1
    np.testing.assert_allclose(total, 1.0, atol=1e-6)
    assert covered.max() == (1 if count == 1 else 2)  # only neighbours overlap


def test_region_spans_refuse_regions_narrower_than_their_overlap():
    with pytest.raises(TGHopError, match="narrower than their overlap"):
        region_spans(100, 2, overlap=64)


def test_n_regions():
    assert n_regions((256, 256), 1024) == (1, 1)
    assert n_regions((1500, 1600), 1024) == (1, 2)  # 1.46 and 1.56 regions
    assert n_regions((2048, 4096), 1024) == (2, 4)
    assert n_regions((2048, 2048), None) == (1, 1)
    # Tileable: every axis needs two regions at least (one would wrap onto itself).
    assert n_regions((2048, 4096), 1024, tile=True) == (2, 4)
    assert n_regions((512, 4096), 1024, tile=True) == (1, 1)


def two_halves(h=512, w=520, seed=0):
    """Noise whose left half is dark and low in contrast, right half bright and contrasty."""
    rng = np.random.default_rng(seed)
    img = rng.random((h, w, 3)).astype(np.float32)
    img[:, : w // 2] = 0.1 + 0.2 * img[:, : w // 2]
    img[:, w // 2 :] = 0.4 + 0.6 * img[:, w // 2 :]
    return img


def test_each_region_gets_the_target_distribution():
    # Matched as a whole, the two halves keep their difference (only the mixture has the
    # target's histogram); matched region by region, each half away from the cross-fade
    # has about the target's mean and spread (its region reaches 32 px into the other half).
    img = two_halves()
    target = np.random.default_rng(1).random((200, 200, 3)) * 0.5 + 0.25  # uniform on [0.25, 0.75]
    q = channel_quantiles(target)
    whole = match_histograms(img, q)
    regional = match_regions(img, colour_quantiles=q, region=256)
    assert n_regions(img.shape[:2], 256) == (2, 2)
    core = slice(0, 260 - OVERLAP), slice(260 + OVERLAP, None)
    for half in core:
        part = regional[:, half]
        assert abs(part.mean() - 0.5) < 0.04
        assert abs(part.std() - target.std()) < 0.02
    assert abs(regional[:, core[0]].mean() - regional[:, core[1]].mean()) < 0.06
    assert abs(whole[:, core[0]].mean() - whole[:, core[1]].mean()) > 0.2
    assert regional.dtype == np.float32 and regional.shape == img.shape
    assert 0 <= regional.min() and regional.max() <= 1


def test_regions_fade_into_each_other():
    # Stationary noise: every region's map is about the same, and the cross-faded image
    # about the whole image's match: no step where the regions meet.
    img = np.random.default_rng(2).random((520, 520, 3)).astype(np.float32) ** 2
    q = channel_quantiles(np.random.default_rng(3).random((128, 128, 3)))
    whole = match_histograms(img, q)
    regional = match_regions(img, colour_quantiles=q, region=256)
    assert np.abs(regional - whole).max() < 0.03


def test_tileable_regions_wrap_around():
    # The regions at the borders wrap: with periodic spans, a rolled image gives the rolled
    # result (up to the cut positions, which roll with it when the shift is a region's).
    img = two_halves(512, 512)
    q = channel_quantiles(np.random.default_rng(1).random((64, 64, 3)))
    out = match_regions(img, colour_quantiles=q, region=256, tile=True)
    rolled = match_regions(np.roll(img, 256, axis=1), colour_quantiles=q, region=256, tile=True)
    np.testing.assert_allclose(np.roll(out, 256, axis=1), rolled, atol=1e-6)


def test_match_regions_refuses_small_regions():
    with pytest.raises(TGHopError, match="at least 256"):
        match_regions(np.zeros((64, 64, 3)), colour_quantiles=np.zeros((3, 5)), region=100)


def test_synthesize_by_regions(small_model):
    size = (520, 540)
    kw = dict(rng=3, patch_refine=0)  # the patch refinement follows the regions' matching: not what is tested
    by_regions = small_model.synthesize(size, region=256, dtype=np.float32, **kw)
    again = small_model.synthesize(size, region=256, dtype=np.float32, **kw)
    whole = small_model.synthesize(size, region=None, dtype=np.float32, **kw)
    np.testing.assert_array_equal(by_regions, again)
    assert by_regions.shape == size + (3,) and 0 <= by_regions.min() and by_regions.max() <= 1
    assert not np.array_equal(by_regions, whole)
    # The same quilt underneath: the regional result stays close to the whole one.
    assert np.abs(by_regions - whole).mean() < 0.05
    eight_bit = small_model.synthesize(size, region=256, dtype=np.uint8, **kw)
    assert eight_bit.dtype == np.uint8 and np.abs(eight_bit / 255.0 - by_regions).max() <= 0.5 / 255 + 1e-6


def test_small_images_do_not_change(small_model):
    # An image up to 1.5 regions a side is matched whole: the setting does not touch it.
    a = small_model.synthesize((128, 128), rng=4, region=256)
    b = small_model.synthesize((128, 128), rng=4, region=None)
    np.testing.assert_array_equal(a, b)


def test_region_setting_is_checked(small_model):
    with pytest.raises(TGHopError, match="region"):
        small_model.synthesize((64, 64), rng=0, region=100)


def test_regions_give_the_same_image_on_any_number_of_cores(small_model):
    # Regions run a core each and are added in a fixed order; refine(threads=1) makes the
    # same numbers as the channels in threads.
    from tghop._resources import limit_cores

    quilt = small_model.synthesize((540, 520), rng=5, refine=0, match_colours=False, seam_window=0,
                                   dtype=np.float32)
    kw = dict(bands=small_model.bands_, colour_quantiles=small_model.colour_quantiles_, region=256)
    many = match_regions(quilt, **kw)
    with limit_cores(1):
        one = match_regions(quilt, **kw)
    np.testing.assert_array_equal(many, one)


@pytest.mark.parametrize("cores", [1, 2])
def test_regions_report_each_round_of_their_refinement(small_model, cores):
    # A large region's refinement takes seconds: the bar moves after each of its rounds (told from the thread
    # that refines it), not only as each region is added; the counts only grow, the total stays, the same image.
    from tghop._resources import limit_cores

    quilt = small_model.synthesize((520, 540), rng=5, refine=0, match_colours=False, seam_window=0, patch_refine=0,
                                   dtype=np.float32)
    kw = dict(bands=small_model.bands_, colour_quantiles=small_model.colour_quantiles_, region=256, n_iter=2)
    calls = []
    with limit_cores(cores):
        out = match_regions(quilt, progress=lambda *a: calls.append(a), **kw)
    assert {c[0] for c in calls} == {"refine"}
    total = 4 * (3 * 2 + 1)  # 4 regions: 3 channels x 2 rounds each, and one step as it is added
    assert {c[2] for c in calls} == {total}
    done = [c[1] for c in calls]
    assert done[0] == 0 and done[-1] == total and done == sorted(done)
    assert len(set(done)) >= 1 + 4 * (2 + 1)  # at least each round of each region (all channels at once here)
    np.testing.assert_array_equal(out, match_regions(quilt, **kw))


def test_regions_stop_starting_once_progress_raises(small_model, monkeypatch):
    # A cancelled server job's progress raises: the regions still waiting for a core were all refined
    # before the error came out (the pool's end waited for them), seconds each at 4096x4096.
    import threading

    from tghop import regions
    from tghop._resources import limit_cores

    quilt = small_model.synthesize((1024, 1024), rng=5, refine=0, match_colours=False, seam_window=0,
                                   patch_refine=0, dtype=np.float32)
    started = []
    refine_bands = regions.refine_bands
    monkeypatch.setattr(regions, "refine_bands", lambda *a, **k: started.append(1) or refine_bands(*a, **k))

    def cancelled(stage, done, total):  # raises first where a region is added (the regions' threads' errors
        if done and threading.current_thread() is threading.main_thread():  # stopped the pool's map already)
            raise KeyboardInterrupt("stop")

    with limit_cores(2), pytest.raises(KeyboardInterrupt, match="stop"):
        match_regions(quilt, bands=small_model.bands_, region=256, n_iter=3, progress=cancelled)
    assert n_regions((1024, 1024), 256) == (4, 4)
    assert len(started) <= 8, len(started)  # the first, those running by then (a few on 2 cores); not all 16
