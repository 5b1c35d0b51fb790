"""Tests of coarse-to-fine layout: tghop.layout and guided quilting (tghop.quilting)."""

from __future__ import annotations

import numpy as np
import pytest

from tghop.synthesis import PAPER_TABLE4

from tghop import TGHop, TGHopError, data, settings
from tghop.layout import (GUIDE_PIXELS, GUIDE_RATE, GUIDE_STEPS, PATCH_LEVELS, coarse_guide, downsample, fits_excluding,
                          follows_guide, guide_fits, guide_steps, upsample, usable_factor)
from tghop.parameter_count import PAPER_MODULES
from tghop.synthesis import CoarseLayout
from tghop.modelfile import load_model, save_model
from tghop.quilting import prepare_pool, quilt, quilt_prepared

from conftest import SMALL


def two_tone_pool(n=200, p=16, seed=0):
    """Half dark, half bright flat patches with a little noise."""
    rng = np.random.default_rng(seed)
    levels = np.where(np.arange(n) % 2 == 0, 0.2, 0.8)[:, None, None, None]
    return np.clip(levels + 0.02 * rng.standard_normal((n, p, p, 1)), 0, 1)


def half_guide(size=(64, 96)):
    """Dark on the left half, bright on the right."""
    g = np.full((*size, 1), 0.2)
    g[:, size[1] // 2:] = 0.8
    return g


# ----------------------------------------------------------------------------- guided quilting


def test_guided_quilting_follows_the_guide():
    pool, guide = two_tone_pool(), half_guide()
    out = quilt(pool, guide.shape[:2], guide=guide, guide_weight=1.0, rng=0)
    # Blocks away from the middle column take the guide's tone.
    assert np.abs(out[:, :32] - 0.2).mean() < 0.05
    assert np.abs(out[:, 64:] - 0.8).mean() < 0.05
    free = quilt(pool, guide.shape[:2], rng=0)  # unguided: the first block's tone everywhere
    assert abs(free[:, :32].mean() - free[:, 64:].mean()) < 0.1


def test_zero_weight_is_unguided_and_seeded():
    pool, guide = two_tone_pool(), half_guide()
    free = quilt(pool, guide.shape[:2], rng=5)
    assert np.array_equal(quilt(pool, guide.shape[:2], guide=guide, guide_weight=0.0, rng=5), free)
    a = quilt(pool, guide.shape[:2], guide=guide, rng=5)
    assert np.array_equal(a, quilt(pool, guide.shape[:2], guide=guide, rng=5))


def test_guided_tileable_and_grey_2d_guide():
    pool, guide = two_tone_pool(), half_guide((48, 48))
    out = quilt(pool, (48, 48), guide=guide[..., 0], tile=True, guide_scale=2, rng=0)
    assert out.shape == (48, 48, 1) and 0 <= out.min() and out.max() <= 1


@pytest.mark.parametrize("kw, match", [
    (dict(guide=np.zeros((10, 10, 1))), "shape"),
    (dict(guide=np.zeros((64, 96, 1)), guide_weight=-1), "guide_weight"),
    (dict(guide=np.zeros((64, 96, 1)), guide_scale=3), "guide_scale"),
])
def test_bad_guide(kw, match):
    with pytest.raises(TGHopError, match=match):
        quilt(two_tone_pool(), (64, 96), **kw)


def test_prepared_pool_is_reusable_and_equals_quilt():
    # synthesize prepares the pool while the guide is being made; quilting must not
    # change the prepared pool, so the same preparation gives the same image again.
    pool, guide = two_tone_pool(), half_guide()
    prepared = prepare_pool(pool, guide.shape[:2], detail=0.5, guide_scale=4)
    a = quilt_prepared(prepared, guide=guide, rng=3)
    other = quilt_prepared(prepared, guide=guide, rng=4)
    assert np.array_equal(quilt_prepared(prepared, guide=guide, rng=3), a)
    assert not np.array_equal(a, other)
    assert np.array_equal(a, quilt(pool, guide.shape[:2], detail=0.5, guide=guide, rng=3))


def test_prepared_pool_errors():
    pool, guide = two_tone_pool(), half_guide()
    with pytest.raises(TGHopError, match="prepared without a guide_scale"):
        quilt_prepared(prepare_pool(pool, guide.shape[:2]), guide=guide, rng=0)
    with pytest.raises(TGHopError, match="result of prepare_pool"):
        quilt_prepared(pool, rng=0)
    with pytest.raises(TGHopError, match="guide_scale"):
        prepare_pool(pool, guide.shape[:2], guide_scale=5)


# ----------------------------------------------------------------------------- resampling


def test_downsample_upsample():
    img = np.random.default_rng(0).random((9, 8, 3))
    small = downsample(img, 2)
    assert small.shape == (4, 4, 3)
    assert np.allclose(small[0, 0], img[:2, :2].reshape(-1, 3).mean(axis=0))
    flat = np.full((4, 4, 1), 0.3)
    assert np.allclose(upsample(flat, 4, (15, 16)), 0.3) and upsample(flat, 4, (15, 16)).shape == (15, 16, 1)
    # The same bilinear, pixel-centre-aligned interpolation as SciPy's (generation does not import SciPy).
    from scipy import ndimage

    for wrap in (False, True):
        ref = ndimage.zoom(img, (2, 2, 1), order=1, mode="grid-wrap" if wrap else "nearest", grid_mode=True)
        assert np.allclose(upsample(img, 2, (17, 15), wrap=wrap), np.clip(ref[:17, :15], 0, 1), atol=1e-12)
    # A large guide (rows split between two threads): still SciPy's interpolation.
    big = np.random.default_rng(1).random((513, 520, 1))
    for wrap in (False, True):
        ref = ndimage.zoom(big, (2, 2, 1), order=1, mode="grid-wrap" if wrap else "nearest", grid_mode=True)
        assert np.allclose(upsample(big, 2, (1025, 1040), wrap=wrap), np.clip(ref[:1025, :1040], 0, 1), atol=1e-12)
    # float32 in, float32 out (the guide of a large image), the same numbers to float32 precision.
    up32 = upsample(img.astype(np.float32), 2, (17, 15))
    assert up32.dtype == np.float32 and upsample(img, 2, (17, 15)).dtype == np.float64
    assert np.allclose(up32, upsample(img, 2, (17, 15)), atol=1e-6)


# ----------------------------------------------------------------------------- CoarseLayout


@pytest.fixture(scope="module")
def layout():
    return CoarseLayout(factor=2, n_clusters=6, rng=0).fit(data.bricks(128, rng=1))


def test_layout_guide_shape_range_determinism(layout):
    assert layout.model_.exemplar_shape_[:2] == (64, 64)
    assert layout.model_.layout_factor is None  # no recursion
    g = layout.guide((70, 90), rng=3, n_patches=300)
    assert g.shape == (70, 90, 3) and g.dtype == np.float32 and 0 <= g.min() and g.max() <= 1
    assert np.array_equal(g, layout.guide((70, 90), rng=3, n_patches=300))
    assert not np.array_equal(g, layout.guide((70, 90), rng=4, n_patches=300))
    assert layout.guide(64, rng=0, n_patches=300, tile=True).shape == (64, 64, 3)


def test_layout_guide_refine_rounds(layout):
    """The guide is the coarse model's synthesis upsampled, quilted with GUIDE_DETAIL whatever
    the fine level's detail; its ``refine`` rounds leave the finest band at factor 2 (the fine
    level compares 4x4 box means, which hardly see it). Its patch refinement (after the colours)
    is off by default in ``guide`` (``TGHop.synthesize`` asks for it)."""
    from tghop.colour import match_histograms
    from tghop.layout import GUIDE_DETAIL, upsample
    from tghop.refine import refine

    model = layout.model_
    assert GUIDE_DETAIL != settings.BY_NAME["detail"].default  # else this test could not tell them apart
    plain = model.synthesize((35, 45), rng=3, n_patches=300, refine=0, detail=GUIDE_DETAIL, patch_refine=0)
    assert np.array_equal(layout.guide((70, 90), rng=3, n_patches=300, refine=0),
                          upsample(plain.astype(np.float32), 2, (70, 90)))
    quilt = model.synthesize((35, 45), rng=3, n_patches=300, refine=0, match_colours=False, detail=GUIDE_DETAIL,
                             patch_refine=0)
    coarse = match_histograms(refine(quilt, model.bands_, n_iter=2, first_level=1), model.colour_quantiles_)
    guide = layout.guide((70, 90), rng=3, n_patches=300, refine=2)
    np.testing.assert_array_equal(guide, upsample(coarse.astype(np.float32), 2, (70, 90)))
    every_band = model.synthesize((35, 45), rng=3, n_patches=300, refine=2, detail=GUIDE_DETAIL, patch_refine=0)
    assert not np.array_equal(guide, upsample(every_band.astype(np.float32), 2, (70, 90)))
    assert not np.array_equal(guide, layout.guide((70, 90), rng=3, n_patches=300, refine=0))


def test_layout_errors(layout):
    with pytest.raises(TGHopError, match="at least 192x192"):
        CoarseLayout(factor=4).fit(data.bricks(96, rng=1))
    assert not CoarseLayout(factor=2).fits((95, 200)) and CoarseLayout(factor=2).fits((96, 96, 3))
    with pytest.raises(TGHopError, match="factor"):
        CoarseLayout(factor=1).fit(data.bricks(96, rng=1))
    with pytest.raises(TGHopError, match="at least 63 pixels a side"):  # 31 coarse pixels < one patch
        layout.guide((61, 64), tile=True)
    assert guide_fits((61, 64), 2, 32) and not guide_fits((61, 64), 2, 32, tile=True)
    assert guide_fits((63, 64), 2, 32, tile=True)
    assert follows_guide(layout, (61, 64)) and not follows_guide(layout, (61, 64), tile=True)
    assert not follows_guide(None, (256, 256))  # a model without a layout
    with pytest.raises(TGHopError, match=r"^guide: unknown keyword 'seed'; the keywords are rng, n_patches, tile, "):
        layout.guide((64, 64), seed=1)  # was Python's TypeError naming coarse_guide


def neighbour_steps(image, axis):
    """Mean squared step from each row (axis 0) or column (axis 1) of an (H, W, C) image to
    the next; the last entry is the step across the wrap-around edge."""
    return np.mean((np.roll(image, -1, axis=axis) - image) ** 2, axis=tuple({0, 1, 2} - {axis}))


def test_a_tileable_guide_of_any_size_wraps_around(layout):
    """A size that is not a multiple of the factor: the coarse image is stretched so that
    its period is the output's (before 0.19: refused)."""
    g = layout.guide((65, 71), rng=2, n_patches=300, tile=True)
    assert g.shape == (65, 71, 3)
    for axis in (0, 1):  # the wrap-around edge is a seam like those inside, far below a plain guide's
        steps = neighbour_steps(g, axis)  # (the quilt's seams inside make steps of up to ~20 times the median)
        assert steps[-1] <= steps[:-1].max()
    plain = layout.guide((65, 71), rng=2, n_patches=300)
    assert neighbour_steps(plain, 0)[-1] > 3 * neighbour_steps(g, 0)[-1]


def test_periodic_upsampling_by_any_ratio_is_periodic_linear_interpolation():
    rng = np.random.default_rng(0)
    small = rng.random((11, 9, 2))
    out = upsample(small, None, (32, 29), wrap=True)
    assert out.shape == (32, 29, 2)
    for axis, n in ((0, 32), (1, 29)):  # one axis at a time, against NumPy's periodic interp
        m = small.shape[axis]
        x = (np.arange(n) + 0.5) * m / n - 0.5
        line = small[:, 4, 1] if axis == 0 else small[5, :, 1]
        got = upsample(line[:, None, None] if axis == 0 else line[None, :, None], None,
                       (n, 1) if axis == 0 else (1, n), wrap=True).ravel()
        np.testing.assert_allclose(got, np.interp(x, np.arange(m), line, period=m), atol=1e-12)
    # Whole multiples: the same as the integer factor.
    np.testing.assert_allclose(upsample(small, None, (33, 27), wrap=True), upsample(small, 3, (33, 27), wrap=True),
                               atol=1e-12)


# ----------------------------------------------------------------------------- in TGHop


@pytest.fixture(scope="module")
def layout_model():
    return TGHop(**SMALL, layout_factor=2).fit(data.bricks(128, rng=1))


def test_tghop_with_layout_follows_its_guide(layout_model, monkeypatch):
    """The output's low pass is closer to the guide it was given than an unguided output's is."""
    size = (96, 96)
    made = []
    guide_of = layout_model.layout_.guide
    monkeypatch.setattr(layout_model.layout_, "guide", lambda *a, **k: made.append(guide_of(*a, **k)) or made[-1])
    on = layout_model.synthesize(size, rng=7, n_patches=800, layout_weight=3.0, match_colours=False)
    (guide,) = made
    off = layout_model.synthesize(size, rng=7, n_patches=800, layout_weight=0.0, match_colours=False)

    def dist(img):
        return np.abs(downsample(img, 8) - downsample(guide, 8)).mean()

    assert dist(on) < 0.8 * dist(off)


def test_tghop_tileable_at_any_size_and_without_a_guide_when_too_small(layout_model, monkeypatch):
    sizes = []
    guide_of = layout_model.layout_.guide
    monkeypatch.setattr(layout_model.layout_, "guide", lambda size, **k: sizes.append(size) or guide_of(size, **k))
    # Wraps around: the step across the edge is a seam like the quilt's seams inside, where the
    # edges of an image made without `tile` do not meet. Three images: in one, the roughest
    # seam may be the one on the edge.
    edge_ratios = []
    for seed in (1, 2, 3):
        out = layout_model.synthesize((67, 75), rng=seed, n_patches=400, tile=True)  # not a multiple of 2
        assert out.shape == (67, 75, 3) and sizes[-1] == (67, 75)
        for axis in (0, 1):
            steps = neighbour_steps(out, axis)
            assert steps[-1] <= 2 * steps[:-1].max()
        plain = layout_model.synthesize((67, 75), rng=seed, n_patches=400)
        edge_ratios.append(sum(neighbour_steps(plain, a)[-1] for a in (0, 1))
                           / sum(neighbour_steps(out, a)[-1] for a in (0, 1)))
    assert np.median(edge_ratios) > 2, edge_ratios
    assert sizes == [(67, 75)] * 6  # each image's guide, tileable or not
    small = layout_model.synthesize((48, 48), rng=1, n_patches=400, tile=True)  # 24 coarse pixels: no guide
    assert small.shape == (48, 48, 3) and len(sizes) == 6
    assert np.array_equal(small, layout_model.synthesize((48, 48), rng=1, n_patches=400, tile=True, layout_weight=0))


def test_a_tileable_remix_too_small_for_the_guides_goes_without_them(layout_model):
    from tghop import synthesize_guided

    kw = dict(size=(48, 48), rng=3, n_patches=300, tile=True)  # 24 coarse pixels at factor 2
    out = synthesize_guided([layout_model, layout_model], **kw)
    assert out.shape == (48, 48, 3)
    assert np.array_equal(out, synthesize_guided([layout_model, layout_model], layout_weight=0, **kw))
    assert synthesize_guided([layout_model, layout_model], **{**kw, "size": (67, 75)}).shape == (67, 75, 3)


def test_tghop_layout_refine_reaches_the_guide(layout_model, monkeypatch):
    seen = []
    guide_of = layout_model.layout_.guide
    monkeypatch.setattr(layout_model.layout_, "guide", lambda *a, **k: seen.append(k["refine"]) or guide_of(*a, **k))
    for rounds in (0, 2):
        layout_model.synthesize((64, 64), rng=2, n_patches=300, layout_refine=rounds)
    assert seen == [0, 2]
    with pytest.raises(TGHopError, match="layout_refine"):
        layout_model.synthesize((64, 64), rng=2, n_patches=300, layout_refine=-1)


def test_the_guide_is_patch_refined_with_the_coarse_models_statistics(layout_model, monkeypatch):
    """The coarse model keeps patch statistics (at most PATCH_LEVELS levels); the guide's patch
    refinement moves the coarse image's patches towards them; synthesize's layout_patch_refine
    reaches it; a model fitted without patch statistics has none in its layout either."""
    from test_patch_refine import _patch_swd

    coarse = layout_model.layout_.model_
    assert layout_model.layout_.patch_levels == coarse.patch_levels == min(layout_model.patch_levels, PATCH_LEVELS)
    kw = dict(rng=3, n_patches=300)
    plain = coarse_guide(coarse, 1, (64, 64), patch_refine=0, **kw)
    refined = coarse_guide(coarse, 1, (64, 64), patch_refine=20, **kw)
    assert _patch_swd(refined, coarse.patches_).mean() < 0.8 * _patch_swd(plain, coarse.patches_).mean()
    assert 0 < np.abs(refined - plain).mean() < 0.1  # it refines the guide, it does not replace it
    # Its steps are GUIDE_RATE times the fine level's (0.49): further in the same 20 steps.
    from tghop.patch_refine import refine_image

    assert np.array_equal(refined, refine_image(plain, coarse.patches_, n_steps=20, rate=GUIDE_RATE))
    slow = refine_image(plain, coarse.patches_, n_steps=20)
    assert _patch_swd(refined, coarse.patches_).mean() < 0.9 * _patch_swd(slow, coarse.patches_).mean()
    for rate in (0, -1.0, float("nan"), True):
        with pytest.raises(TGHopError, match="rate must be a finite number > 0"):
            refine_image(plain, coarse.patches_, n_steps=1, rate=rate)
    seen = []
    guide_of = layout_model.layout_.guide
    monkeypatch.setattr(layout_model.layout_, "guide",
                        lambda *a, **k: seen.append(k["patch_refine"]) or guide_of(*a, **k))
    for steps in (0, 7, None):
        layout_model.synthesize((64, 64), rng=2, n_patches=300,
                                **({} if steps is None else {"layout_patch_refine": steps}))
    assert seen == [0, 7, settings.BY_NAME["layout_patch_refine"].default]
    from tghop import morph, synthesize_guided

    import copy

    # two models (one given twice would be one synthesis), sharing the coarse layout watched above
    synthesize_guided([layout_model, copy.copy(layout_model)], size=(64, 64), rng=3, n_patches=300,
                      layout_patch_refine=5)
    morph(layout_model, copy.copy(layout_model), (64, 128), rng=3, n_patches=300, layout_patch_refine=6)
    assert seen[3:] == [5, 5, 6, 6]  # each model's guide
    # By default (None) only images of up to GUIDE_PIXELS are patch-refined; a number is taken as given.
    side = GUIDE_PIXELS // 512
    assert guide_steps(None, (side, 512)) == GUIDE_STEPS > 0 and guide_steps(None, (side + 1, 512)) == 0
    assert guide_steps(5, (4096, 4096)) == 5 and guide_steps(0, (64, 64)) == 0
    with pytest.raises(TGHopError, match="layout_patch_refine must be an integer >= 0"):
        layout_model.synthesize((64, 64), rng=2, n_patches=300, layout_patch_refine=-1)
    bare = TGHop(**SMALL, layout_factor=2, patch_levels=0).fit(data.bricks(128, rng=1))
    assert bare.layout_.patch_levels == 0 and bare.layout_.model_.patches_ is None
    assert np.array_equal(bare.layout_.guide((64, 64), patch_refine=20, **kw),
                          bare.layout_.guide((64, 64), patch_refine=0, **kw))


def test_an_error_in_the_guides_thread_reaches_the_caller(layout_model, monkeypatch):
    # The guide is made in a thread of its own while the pool is made: its error is
    # raised by synthesize, as the guide's own exception.
    def broken(*args, **kwargs):
        raise TGHopError("the guide broke")

    monkeypatch.setattr(layout_model.layout_, "guide", broken)
    with pytest.raises(TGHopError, match="the guide broke"):
        layout_model.synthesize((64, 64), rng=2, n_patches=300)


def test_in_thread_returns_the_result_or_raises_the_error():
    import threading

    from tghop._resources import in_thread, limit_cores, usable_cores

    main = threading.get_ident()
    if usable_cores() > 1:
        assert in_thread(lambda a, b=0: (a + b, threading.get_ident() != main), 2, b=3)() == (5, True)
    wait = in_thread(lambda: {}["missing"])
    with pytest.raises(KeyError, match="missing"):
        wait()
    # One core (a batch worker's task): no second thread, the work runs when it is asked for.
    ran = []
    with limit_cores(1):
        wait = in_thread(lambda a: ran.append(threading.get_ident()) or a * 2, 4)
        assert ran == []
        assert wait() == 8 and ran == [main]
        with pytest.raises(KeyError, match="missing"):
            in_thread(lambda: {}["missing"])()


def test_one_core_makes_the_same_image_without_the_guides_thread(layout_model, monkeypatch):
    import threading

    from tghop._resources import limit_cores, usable_cores

    guide, ran_in = layout_model.layout_.guide, []

    def recorded(*args, **kwargs):  # the real guide, noting the thread it ran in
        ran_in.append(threading.get_ident())
        return guide(*args, **kwargs)

    monkeypatch.setattr(layout_model.layout_, "guide", recorded)
    a = layout_model.synthesize((64, 64), rng=2, n_patches=300)
    with limit_cores(1):
        b = layout_model.synthesize((64, 64), rng=2, n_patches=300)
    assert np.array_equal(a, b)
    main = threading.get_ident()
    assert ran_in[1] == main and (usable_cores() == 1 or ran_in[0] != main)


def test_tghop_layout_save_load_identical(layout_model, tmp_path):
    a = layout_model.synthesize((64, 64), rng=2, n_patches=400)
    save_model(layout_model, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz")
    assert loaded.layout_ is not None and loaded.layout_.factor == 2
    assert np.array_equal(a, loaded.synthesize((64, 64), rng=2, n_patches=400))
    rows = layout_model.n_parameters()
    assert rows["coarse layout (ours)"]["stored"] > 0
    assert rows["total"]["stored"] == sum(v["stored"] for k, v in rows.items() if k not in ("total", PAPER_MODULES))


def test_tghop_layout_on_by_default_off_in_paper_small_exemplar_and_errors(small_model):
    # 96 px: under 48 * 3 for the default factor 3, so the largest that fits, 2 (48 * 2)
    assert small_model.layout_factor == 3 and small_model.layout_ is not None and small_model.layout_.factor == 2
    assert PAPER_TABLE4["layout_factor"] is None
    off = TGHop(**SMALL, layout_factor=None).fit(data.bricks(96, rng=1))
    assert off.layout_ is None and off.n_parameters()["coarse layout (ours)"]["stored"] == 0
    m = TGHop(**SMALL, layout_factor=4).fit(data.bricks(96, rng=1))  # smaller than 4 * 48: 2 as well
    assert m.layout_.factor == 2 and m.layout_.model_.exemplar_shape_[:2] == (48, 48)
    tiny = TGHop(**SMALL).fit(data.bricks(90, rng=1))  # under 48 * 2: no factor fits
    assert tiny.layout_ is None
    with pytest.raises(TGHopError, match="layout_factor"):
        TGHop(**SMALL, layout_factor=1).fit(data.bricks(96, rng=1))


def test_usable_factor_is_the_largest_the_exemplar_allows_up_to_the_setting():
    assert usable_factor((144, 300), 3) == 3  # 48 * 3
    assert usable_factor((143, 300), 3) == 2
    assert usable_factor((300, 95), 3) is None  # under 48 * 2
    assert usable_factor((1000, 1000), 2) == 2  # never above the setting
    assert usable_factor((1000, 1000), 5) == 5
    mask = np.zeros((200, 200), dtype=bool)
    mask[:, :110] = True  # at 1/3 too few clean coarse patches are left, at 1/2 enough
    assert fits_excluding(mask, 2) and not fits_excluding(mask, 3)
    assert usable_factor((200, 200), 3, exclude=mask) == 2
    assert usable_factor((200, 200), 3) == 3
    with pytest.raises(TGHopError, match="factor"):
        usable_factor((200, 200), 1)


def test_downsample_uint8_in_row_bands_gives_the_rounded_box_mean():
    rng = np.random.default_rng(3)
    u = rng.integers(0, 256, (301, 257, 3), dtype=np.uint8)
    ref = u[:300, :256].reshape(150, 2, 128, 2, 3).mean(axis=(1, 3))
    small = downsample(u, 2)
    assert small.dtype == np.uint8
    np.testing.assert_array_equal(small, np.round(ref))


# ------------------------------------------------------------------ input checks
@pytest.mark.parametrize("factor", [0, -1, 2.5, "2", True, 200])
def test_downsample_checks_its_factor(factor):
    with pytest.raises(TGHopError, match="downsample: factor"):
        downsample(data.bricks(96), factor)


@pytest.mark.parametrize("factor,size,message", [(0, (100, 100), "upsample: factor"),
                                                 (2.5, (100, 100), "upsample: factor"),
                                                 (2, (1000, 1000), "larger than the 96x96 image"),
                                                 (2, (0, 10), "upsample: size must be positive"),
                                                 (2, "a", "upsample: size must be")])
def test_upsample_checks_its_factor_and_size(factor, size, message):
    with pytest.raises(TGHopError, match=message):
        upsample(data.bricks(96), factor, size)


def test_downsample_and_upsample_check_their_images():
    from tghop._errors import InvalidImageError

    img = data.bricks(32)
    nan = img.copy()
    nan[0, 0, 0] = np.nan
    for bad in (img * 255, nan, img[..., 0]):
        with pytest.raises(InvalidImageError, match="^downsample: image"):
            downsample(bad, 2)
        with pytest.raises(InvalidImageError, match="^upsample: image"):
            upsample(bad, 2, (64, 64))
    assert upsample(img, 2, 64).shape == (64, 64, 3)  # size as in check_size
    assert downsample(np.round(img * 255).astype(np.uint8), 2).dtype == np.uint8


def test_coarse_guide_names_its_refine():
    model = TGHop(**SMALL, layout_factor=2).fit(data.bricks(96))
    with pytest.raises(TGHopError, match="^refine must be an integer >= 0, got -1"):
        model.layout_.guide((64, 64), refine=-1)


def test_the_layout_guide_reports_its_progress(layout_model):
    # The coarse guide ran silent: between "layout" 0/1 and 1/1 (the guide of a 4096x4096 image: many
    # seconds) tghop serve's bar stood at its start.
    calls = []
    kw = dict(rng=7, n_patches=800, layout_patch_refine=2)
    image = layout_model.synthesize((96, 96), progress=lambda *call: calls.append(call), **kw)
    np.testing.assert_array_equal(image, layout_model.synthesize((96, 96), **kw))  # the same image
    layout = [(done, total) for stage, done, total in calls[:calls.index(("patch pool", 1, 1))] if stage == "layout"]
    # One unit throughout (the CLI's bar is made at the first report: 0 of 1, then 250 of 1000, read 100 %)
    assert layout[0] == (0, 1000) and layout[-1] == (1000, 1000) and {total for _, total in layout} == {1000}
    inner = [done for done, total in layout[1:-1]]
    assert len(inner) == len(layout) - 2 > 10 and inner == sorted(inner)  # its steps, going forward
    assert inner[0] < 250 and inner[-1] == 1000  # quilting first ... the patch refinement's end last
    assert {500, 750} <= set(inner)  # the refinement's and the patch refinement's starts


def _layout_reports(calls, after):
    """The "layout" reports before the first report of stage ``after``; checked as one stage of 1000 units that
    goes forward from 0 to 1000, not interleaved with another stage."""
    head = calls[:[stage for stage, _, _ in calls].index(after)]
    first = head.index(("layout", 0, 1000))
    layout = head[first:]
    assert {stage for stage, _, _ in layout} == {"layout"} and {total for _, _, total in layout} == {1000}
    done = [d for _, d, _ in layout]
    assert done[0] == 0 and done[-1] == 1000 and done == sorted(done)
    return done


def test_inpaintings_coarse_fill_reports_its_progress(layout_model):
    # The coarse fill (an inpainting of the downsampled image) ran silent between "layout" 0/1 and 1/1.
    from tghop.inpaint import inpaint

    image = data.bricks(96, rng=2)
    hole = np.zeros((96, 96), dtype=bool)
    hole[24:72, 30:70] = True
    calls = []
    kw = dict(rng=4, n_patches=600, refine=1, patch_refine=0)
    out = inpaint(layout_model, image, hole, progress=lambda *call: calls.append(call), **kw)
    np.testing.assert_array_equal(out, inpaint(layout_model, image, hole, **kw))  # the same image
    assert ("layout", 0, 1000) in calls  # there is a coarse fill
    done = _layout_reports(calls, "inpainting")
    assert len(set(done)) > 5  # its steps
