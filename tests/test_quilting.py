"""Tests of tghop.quilting: image quilting of a pool of patches."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from scipy import ndimage

from tghop import TGHopError, quilting
from tghop.data import bricks
from tghop.quilting import (
    MAX_PIXELS,
    _cut_masks,
    boundary_cut_mask,
    default_overlap,
    min_error_boundary_cut,
    quilt,
    quilting_plan,
)


def crops(texture, n, patch, seed=0):
    """``n`` random ``patch x patch`` crops of ``texture`` (H, W, C)."""
    rng = np.random.default_rng(seed)
    ys = rng.integers(0, texture.shape[0] - patch + 1, n)
    xs = rng.integers(0, texture.shape[1] - patch + 1, n)
    return np.stack([texture[y : y + patch, x : x + patch] for y, x in zip(ys, xs)])


def periodic_pool(period=16, patch=8, channels=1, seed=0):
    """A random periodic texture and the pool of all its (wrapping) patches."""
    tex = np.random.default_rng(seed).random((period, period, channels))
    big = np.tile(tex, (2, 2, 1))
    pool = np.stack([big[y : y + patch, x : x + patch] for y in range(period) for x in range(period)])
    return tex, pool


def shift_of(out, tex):
    """(dy, dx) such that ``out`` is ``tex`` repeated and shifted by it, or None."""
    period = tex.shape[0]
    reps = (out.shape[0] // period + 2, out.shape[1] // period + 2, 1)
    big = np.tile(tex, reps)
    for dy, dx in itertools.product(range(period), range(period)):
        if np.allclose(out, big[dy : dy + out.shape[0], dx : dx + out.shape[1]], atol=1e-6):
            return dy, dx
    return None


@pytest.fixture(scope="module")
def brick_pool():
    return crops(bricks(128), 300, 32)


@pytest.fixture(scope="module")
def noise_texture():
    rng = np.random.default_rng(3)
    field = ndimage.gaussian_filter(rng.standard_normal((128, 128, 3)), (3, 3, 0), mode="wrap")
    return (field - field.min()) / (field.max() - field.min())


# ----------------------------------------------------------------------------- shapes


@pytest.mark.parametrize("size", [(5, 7), (1, 1), (33, 71), (32, 32), (59, 60), (100, 3), (27, 200)])
@pytest.mark.parametrize("channels", [1, 3])
def test_output_shape_any_size(brick_pool, size, channels):
    pool = brick_pool[..., :channels] if channels == 3 else brick_pool.mean(axis=3, keepdims=True)
    out = quilt(pool, size, rng=0)
    assert out.shape == (*size, channels)
    assert out.dtype == np.float64
    assert np.isfinite(out).all() and out.min() >= 0 and out.max() <= 1


@pytest.mark.parametrize("size", [(32, 32), (33, 71), (70, 45), (64, 64)])
def test_tiled_output_shape(brick_pool, size):
    out = quilt(brick_pool, size, tile=True, rng=0)
    assert out.shape == (*size, 3)


def test_greyscale_3d_pool_and_int_size(brick_pool):
    out = quilt(brick_pool.mean(axis=3), 40, rng=0)  # (n, P, P) pool, square int size
    assert out.shape == (40, 40, 1)


def test_uint8_pool_is_rescaled(brick_pool):
    pool8 = np.round(brick_pool * 255).astype(np.uint8)
    out = quilt(pool8, (40, 50), rng=0)
    assert out.max() <= 1.0 and out.max() > 0.5


def test_output_pixels_come_from_pool():
    # Constant patches with distinct values: every output pixel must be one of them.
    values = np.linspace(0.1, 0.9, 9)
    pool = np.broadcast_to(values[:, None, None, None], (9, 12, 12, 1)).copy()
    out = quilt(pool, (37, 50), rng=1)
    assert np.isin(np.round(out, 6), np.round(values, 6)).all()


# ----------------------------------------------------------------------------- plan


@pytest.mark.parametrize(
    "size, patch, overlap, tile",
    [
        ((100, 90), 16, None, False),
        ((5, 7), 32, None, False),
        ((64, 64), 16, 4, True),
        ((33, 71), 32, None, True),
        ((16, 16), 8, None, True),  # two blocks per axis: a block's neighbour on both sides
        ((16, 80), 8, 2, True),  # ny = 2, nx = 13: some blocks of a wavefront would collide
        ((48, 84), 8, 1, True),  # nx = 2 * ny - 1: same-wavefront wrap neighbours
        ((9, 13), 9, 4, True),  # odd patch as wide as the output: overlaps of 5 and 4
    ],
)
def test_plan_levels_and_masks_match_a_sequential_simulation(size, patch, overlap, tile):
    plan = quilting_plan(size, patch, overlap=overlap, tile=tile)
    hc, wc = plan.canvas_shape
    assert hc >= size[0] and wc >= size[1]
    filled = np.zeros((hc, wc), dtype=bool)
    nx = plan.xs.size
    offs = np.arange(patch)
    for level in range(plan.n_levels):
        blocks = np.flatnonzero(plan.level.ravel() == level)
        count = np.zeros((hc, wc), dtype=int)
        for b in blocks:
            i, j = divmod(int(b), nx)
            rows, cols = plan.ys[i] + offs, plan.xs[j] + offs
            if tile:
                rows, cols = rows % hc, cols % wc
            window = np.ix_(rows, cols)
            # The overlap shape the plan predicts is exactly what is already covered.
            np.testing.assert_array_equal(filled[window], plan.masks[plan.mask_id[i, j]])
            np.add.at(count, window, 1)
        assert count.max() <= 1, "blocks of one wavefront overlap"
        filled |= count > 0
    assert filled[: size[0], : size[1]].all(), "output not covered"
    # Every overlap is inside the frame the pool is compared on.
    assert not (plan.masks & ~plan.region).any()


@pytest.mark.parametrize("tile", [False, True])
def test_wavefronts_give_the_same_image_as_one_block_at_a_time(monkeypatch, tile):
    pool = np.random.default_rng(0).random((300, 16, 16, 3))
    batched = quilt(pool, (70, 90), tile=tile, tolerance=0, rng=3)
    original = quilting.quilting_plan

    def sequential(*args, **kwargs):
        plan = original(*args, **kwargs)
        ny, nx = plan.level.shape
        ii, jj = np.mgrid[0:ny, 0:nx]
        order = np.lexsort((jj.ravel(), ii.ravel(), plan.level.ravel()))
        level = np.empty(ny * nx, dtype=np.int32)
        level[order] = np.arange(ny * nx)
        return dataclasses.replace(plan, level=level.reshape(ny, nx), n_levels=ny * nx)

    monkeypatch.setattr(quilting, "quilting_plan", sequential)
    calls = []
    one_by_one = quilt(pool, (70, 90), tile=tile, tolerance=0, rng=3, progress=lambda *a: calls.append(a))
    assert len(calls) == original((70, 90), 16, tile=tile).n_blocks  # really one block per step
    np.testing.assert_array_equal(batched, one_by_one)


def test_plan_uses_wavefronts_for_speed():
    plan = quilting_plan((2048, 2048), 32)
    assert plan.n_blocks == 76 * 76
    assert plan.n_levels < 3 * 76  # not one block at a time
    assert plan.masks.shape[0] <= 8


def test_default_overlap():
    assert default_overlap(32) == 5
    assert default_overlap(2) == 1
    assert default_overlap(64) == 11


# ----------------------------------------------------------------------------- randomness


def test_same_seed_same_image_different_seed_different_image(brick_pool):
    a = quilt(brick_pool, (70, 90), rng=5)
    b = quilt(brick_pool, (70, 90), rng=5)
    c = quilt(brick_pool, (70, 90), rng=6)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).mean() > 0.01


def test_generator_rng_advances(brick_pool):
    gen = np.random.default_rng(0)
    a = quilt(brick_pool, (40, 40), rng=gen)
    b = quilt(brick_pool, (40, 40), rng=gen)
    assert not np.array_equal(a, b)


# ----------------------------------------------------------------------------- boundary cut


def test_boundary_cut_follows_zero_cost_zigzag_channel():
    rng = np.random.default_rng(1)
    h, w = 40, 9
    path = [4]
    for _ in range(h - 1):
        path.append(int(np.clip(path[-1] + rng.choice([-1, 0, 1]), 0, w - 1)))
    path = np.array(path)
    error = np.full((h, w), 10.0) + rng.random((h, w))
    error[np.arange(h), path] = 0.0
    np.testing.assert_array_equal(min_error_boundary_cut(error), path)
    # Batched and transposed-strip use.
    np.testing.assert_array_equal(min_error_boundary_cut(np.stack([error, error])), np.stack([path, path]))


def test_boundary_cut_is_optimal_against_brute_force():
    rng = np.random.default_rng(2)
    h, w = 6, 4
    for _ in range(20):
        error = rng.random((h, w))
        best = min(
            (error[np.arange(h), list(p)].sum(), p)
            for p in itertools.product(range(w), repeat=h)
            if all(abs(a - b) <= 1 for a, b in zip(p, p[1:]))
        )
        cut = min_error_boundary_cut(error)
        assert np.all(np.abs(np.diff(cut)) <= 1)
        assert error[np.arange(h), cut].sum() == pytest.approx(best[0])


def test_batched_boundary_cuts_do_not_see_each_other():
    # The batch is worked on side by side: each strip's cut must be its own alone, with
    # neighbours of zero cost, +inf columns, rows of ties and strips one column wide.
    rng = np.random.default_rng(5)
    for w in (1, 2, 5):
        error = rng.integers(0, 3, size=(7, 9, w)).astype(float)
        error[rng.random(error.shape) < 0.15] = np.inf
        error[1::2, :, 0] = 0.0  # a free column at the left edge of every other strip
        error[2] = np.inf  # a strip with no finite entry
        alone = np.stack([min_error_boundary_cut(e) for e in error])
        np.testing.assert_array_equal(min_error_boundary_cut(error), alone)
        assert ((alone >= 0) & (alone < w)).all()


def test_boundary_cut_avoids_infinite_cost():
    error = np.zeros((5, 4))
    error[:, 0] = np.inf
    assert (min_error_boundary_cut(error) > 0).all()
    with pytest.raises(TGHopError, match="NaN"):
        min_error_boundary_cut(np.full((3, 3), np.nan))
    with pytest.raises(TGHopError, match="shape"):
        min_error_boundary_cut(np.zeros(5))


def test_l_shaped_cut_mask():
    p, o = 12, 4
    rng = np.random.default_rng(0)
    error = rng.random((p, p))
    mask = boundary_cut_mask(error, left=o, top=o)
    assert mask[o:, o:].all()  # outside the overlap: new block
    assert not mask[0, 0]  # corner pixel: cut-away old (costs cannot put the cut at column -1)
    left_cut = min_error_boundary_cut(error[:, :o])
    top_cut = min_error_boundary_cut(error[:o, :].T)
    expected = (np.arange(p)[None, :] >= left_cut[:, None]) & (np.arange(p)[:, None] >= top_cut[None, :])
    np.testing.assert_array_equal(mask, expected)


def test_batched_cut_masks_agree_with_the_public_function():
    rng = np.random.default_rng(4)
    p = 10
    errors = rng.random((6, p, p))
    strips = np.array([[3, 0, 0, 0], [0, 2, 0, 0], [3, 3, 0, 0], [2, 3, 4, 0], [1, 2, 3, 4], [0, 0, 0, 5]])
    got = _cut_masks(errors, strips, np.zeros((6, p, p), dtype=bool))
    for k in range(6):
        left, top, right, bottom = strips[k].tolist()
        want = boundary_cut_mask(errors[k], left=left, top=top, right=right, bottom=bottom)
        np.testing.assert_array_equal(got[k], want)


# ----------------------------------------------------------------------------- matching


@pytest.mark.parametrize("size, tile", [((40, 50), False), ((48, 48), True), ((32, 64), True)])
def test_pool_of_a_periodic_texture_is_reassembled_exactly(size, tile):
    tex, pool = periodic_pool(period=16, patch=8)
    out = quilt(pool, size, tolerance=0, tile=tile, rng=1)
    assert shift_of(out, tex) is not None


def _second_block_errors(pool, out, p, o):
    """For a 1x2-block quilt: overlap error of every pool patch against the first block,
    and the index of the patch pasted second."""
    s = p - o
    first = int(np.argmin(((pool[:, :, :s] - out[None, :, :s]) ** 2).sum(axis=(1, 2, 3))))
    np.testing.assert_allclose(pool[first][:, :s], out[:, :s], atol=1e-6)
    errors = ((pool[:, :, :o] - pool[first][None, :, s:]) ** 2).sum(axis=(1, 2, 3))
    second = int(np.argmin(((pool[:, :, o:] - out[None, :, p:]) ** 2).sum(axis=(1, 2, 3))))
    np.testing.assert_allclose(out[:, p:], pool[second][:, o:], atol=1e-6)
    return errors, second


def test_tolerance_zero_takes_the_best_match():
    # Two blocks side by side: the second must be the pool patch whose left strip best
    # matches the first block's right strip (checked by brute force).
    rng = np.random.default_rng(7)
    p, o = 8, 2
    pool = rng.random((300, p, p, 3))
    for seed in range(4):
        out = quilt(pool, (p, 2 * p - o), overlap=o, tolerance=0, rng=seed)
        errors, second = _second_block_errors(pool, out, p, o)
        ranked = np.sort(errors)
        assert ranked[1] - ranked[0] > 1e-2  # the best match is unique
        assert second == int(np.argmin(errors))


def test_tolerance_bounds_the_error_and_allows_variety():
    rng = np.random.default_rng(8)
    p, o = 8, 2
    pool = rng.random((300, p, p, 3))
    picked_best = []
    for seed in range(8):
        out = quilt(pool, (p, 2 * p - o), overlap=o, tolerance=0.5, rng=seed)
        errors, second = _second_block_errors(pool, out, p, o)
        assert errors[second] <= 1.5 * errors.min() + 1e-6
        picked_best.append(second == int(np.argmin(errors)))
    assert not all(picked_best)


def test_large_tolerance_breaks_exact_reassembly():
    # The same periodic pool with a loose tolerance: blocks no longer continue exactly,
    # which shows the exact-reassembly test above can fail.
    tex, pool = periodic_pool(period=16, patch=8)
    assert shift_of(quilt(pool, (40, 50), tolerance=1e6, rng=1), tex) is None


# ----------------------------------------------------------------------------- tiling


def seam_errors(out):
    """Squared difference between adjacent pixels, averaged along each line of pixel pairs.

    Returns (across the wrap-around edges, over all interior pairs, worst line on the
    torus), the last being the largest mean over one column pair or row pair, edges
    included: an unmatched seam anywhere shows up there.
    """
    cols = np.mean((np.roll(out, -1, axis=1) - out) ** 2, axis=(0, 2))  # [-1]: last vs first column
    rows = np.mean((np.roll(out, -1, axis=0) - out) ** 2, axis=(1, 2))
    wrap = 0.5 * (cols[-1] + rows[-1])
    inner = 0.5 * (np.mean(np.diff(out, axis=1) ** 2) + np.mean(np.diff(out, axis=0) ** 2))
    return wrap, inner, max(cols.max(), rows.max())


@pytest.mark.parametrize("size", [(64, 64), (70, 90)])
def test_tiled_output_wraps_around_seamlessly(noise_texture, size):
    pool = crops(noise_texture, 800, 16, seed=1)
    wrap_t, inner_t, worst_t = np.mean([seam_errors(quilt(pool, size, tile=True, rng=s)) for s in range(3)], axis=0)
    wrap_p, inner_p, _ = np.mean([seam_errors(quilt(pool, size, rng=s)) for s in range(3)], axis=0)
    # Across the wrap seam no worse than across an average pair of interior pixels ...
    assert wrap_t <= inner_t
    # ... which a plain quilt is far from (its opposite edges do not match at all) ...
    assert wrap_p > 4 * inner_p
    # ... and the wrap seam was matched and cut, not just moved inside the image.
    assert worst_t < 0.5 * wrap_p


def test_tiled_output_repeats_without_seams_on_exact_pool():
    tex, pool = periodic_pool(period=16, patch=8, channels=3)
    out = quilt(pool, (48, 64), tolerance=0, tile=True, rng=3)
    tiled = np.tile(out, (2, 2, 1))
    assert shift_of(tiled, tex) is not None


# ----------------------------------------------------------------------------- progress


def test_progress_reports_per_wavefront(brick_pool):
    calls = []
    quilt(brick_pool, (100, 120), rng=0, progress=lambda *a: calls.append(a))
    plan = quilting_plan((100, 120), 32)
    assert {c[0] for c in calls} == {"quilting"}
    done = [c[1] for c in calls]
    assert done == sorted(done) and len(calls) == plan.n_levels
    assert calls[-1][1] == calls[-1][2] == plan.n_blocks


# ----------------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    "size, match",
    [
        ((0, 10), "positive"),
        ((-5, 10), "positive"),
        (0, "positive"),
        ((10.5, 10), "integers"),
        ((10, 10, 3), "integers"),
        ("big", "integers"),
        ((MAX_PIXELS, 2), "limit"),
        ((100_000, 100_000), "limit"),
    ],
)
def test_bad_size(brick_pool, size, match):
    with pytest.raises(TGHopError, match=match):
        quilt(brick_pool, size)


@pytest.mark.parametrize(
    "shape, match",
    [
        ((10, 8, 9, 3), "square"),
        ((10, 8, 8, 0), "C >= 1"),  # any other count: the stacked maps of a material (tghop.material)
        ((0, 8, 8, 3), "empty"),
        ((10, 1, 1, 3), "at least 2x2"),
        ((8, 8), "shape"),
        ((2, 2, 8, 8, 3), "shape"),
    ],
)
def test_bad_pool_shape(shape, match):
    with pytest.raises(TGHopError, match=match):
        quilt(np.zeros(shape), (20, 20))


def test_bad_pool_values():
    pool = np.zeros((4, 8, 8, 3))
    pool[0, 0, 0, 0] = 2.0
    with pytest.raises(TGHopError, match=r"\[0, 1\]"):
        quilt(pool, (20, 20))
    pool[0, 0, 0, 0] = np.nan
    with pytest.raises(TGHopError, match="NaN"):
        quilt(pool, (20, 20))


@pytest.mark.parametrize("overlap", [0, -1, 17, 2.5, True])
def test_bad_overlap(brick_pool, overlap):
    with pytest.raises(TGHopError, match="overlap"):
        quilt(brick_pool, (40, 40), overlap=overlap)


@pytest.mark.parametrize("patch_size", [1, 2.5, "8"])
def test_bad_patch_size(patch_size):
    with pytest.raises(TGHopError, match=rf"^patch size must be an integer >= 2, got {patch_size!r}$"):
        quilting_plan((40, 40), patch_size)


@pytest.mark.parametrize("left", [-1, 9, 2.0, True])
def test_bad_cut_overlap(left):
    with pytest.raises(TGHopError, match=rf"^left overlap must be an integer from 0 to 8, got {left!r}$"):
        boundary_cut_mask(np.zeros((8, 8)), left=left)


@pytest.mark.parametrize("tolerance", [-0.1, float("nan"), float("inf"), "0.1"])
def test_bad_tolerance(brick_pool, tolerance):
    with pytest.raises(TGHopError, match="tolerance"):
        quilt(brick_pool, (40, 40), tolerance=tolerance)


def test_too_many_blocks():
    with pytest.raises(TGHopError, match="larger patches"):
        quilting_plan((8192, 8192), 2)


def test_a_strip_thinner_than_a_patch_is_refused_where_its_canvas_is_above_the_limit(small_model):
    # 1x67108864 is within the pixel limit, but quilting lays it on a 32-pixel-high canvas, 32 times the
    # limit (about 100 GB and half an hour): it was accepted and run.
    from tghop._images import MAX_PIXELS

    for size in ((1, MAX_PIXELS), (MAX_PIXELS // 2, 2), (16, MAX_PIXELS // 16)):
        for check in (quilting_plan, quilting.block_count):
            with pytest.raises(TGHopError, match=r"is quilted on a canvas of .* above the limit of 67,108,864"):
                check(size, 32)

    def no_work(stage, done, total):
        raise AssertionError(f"{stage} began")

    with pytest.raises(TGHopError, match=r"^size 1x67108864 is quilted on a canvas of 32x67108864 pixels"):
        small_model.synthesize((1, MAX_PIXELS), progress=no_work)
    # The largest outputs are not: no side under the patch, or the canvas at the limit.
    assert quilting.block_count((8192, 8192), 32) and quilting.block_count((32, MAX_PIXELS // 32), 32)
    assert quilting.block_count((1, MAX_PIXELS // 32), 32) and quilting.block_count((4096, 16384), 32)


def test_tile_needs_a_patch_sized_output(brick_pool):
    with pytest.raises(TGHopError, match=r"a tileable output \(tile, --tile\) needs a height of at least the patch "
                                         r"size 32, got 20; ask for a larger image, or fit with smaller patches"):
        quilt(brick_pool, (20, 64), tile=True)


def test_error_messages_are_one_line(brick_pool):
    for kwargs in ({"size": (0, 1)}, {"size": (10, 10), "overlap": 99}, {"size": (10, 10), "rng": "x"}):
        with pytest.raises(TGHopError) as info:
            quilt(brick_pool, **kwargs)
        assert "\n" not in str(info.value)


@pytest.mark.parametrize("s", [1, 2, 4, 8])
def test_box_means_are_the_means_of_the_boxes(s):
    from tghop.quilting import _box_means

    x = np.random.default_rng(s).random((5, 16, 16, 3)).astype(np.float32)
    ref = x.reshape(5, 16 // s, s, 16 // s, s, 3).astype(np.float64).mean(axis=(2, 4)).reshape(5, -1)
    out = _box_means(x, s)
    assert out.dtype == np.float32 and out.shape == ref.shape
    np.testing.assert_allclose(out, ref, atol=1e-6)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_gradient_energy_is_the_mean_squared_neighbour_difference(dtype):
    from tghop.quilting import POOL_CHUNK, gradient_energy

    x = np.random.default_rng(3).random((POOL_CHUNK + 7, 8, 6, 3)).astype(dtype)  # not square
    x[:, :, :, 1] **= 3
    ref = (np.square(np.diff(x.astype(np.float64), axis=1)).mean(axis=(1, 2, 3))
           + np.square(np.diff(x.astype(np.float64), axis=2)).mean(axis=(1, 2, 3)))
    out = gradient_energy(x)
    assert out.dtype == np.float32 and out.shape == (len(x),)
    np.testing.assert_allclose(out, ref, rtol=1e-5)


def test_gradient_energy_works_through_the_pool_in_chunks():
    """0.62: POOL_CHUNK patches at a time, the same bits as each patch alone; 0.61 made two differences of the
    whole pool (twice its memory, fresh each call: a fill's pool step waited on it)."""
    import tracemalloc

    from tghop.quilting import POOL_CHUNK, gradient_energy

    pool = np.random.default_rng(4).random((8 * POOL_CHUNK + 3, 32, 32, 3), dtype=np.float32)
    tracemalloc.start()
    try:
        whole = gradient_energy(pool)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < pool.nbytes / 2, (peak, pool.nbytes)
    alone = np.concatenate([gradient_energy(pool[i : i + 1]) for i in range(0, len(pool), 97)])
    assert np.array_equal(whole[::97], alone)


def test_quilt_prepared_in_float32_is_the_same_canvas(brick_pool):
    from tghop.quilting import prepare_pool, quilt_prepared

    prepared = prepare_pool(brick_pool.astype(np.float32), (50, 70))
    wide = quilt_prepared(prepared, rng=3)
    narrow = quilt_prepared(prepared, rng=3, dtype=np.float32)
    assert wide.dtype == np.float64 and narrow.dtype == np.float32
    assert np.array_equal(wide, narrow.astype(np.float64))
    for dtype in (np.int32, "junk", [np.float32]):  # "junk" was NumPy's TypeError
        with pytest.raises(TGHopError, match=r"^dtype must be float32 or float64 .*got"):
            quilt_prepared(prepared, rng=3, dtype=dtype)


class _ReadOnDemand:
    """A pool read as quilting reads one generated on demand: ranges into a reused buffer
    (scribbled over after use), chosen patches as new arrays; the reads are recorded."""

    def __init__(self, arr):
        self._arr, self.shape, self.dtype, self.reads = arr, arr.shape, arr.dtype, []
        self._buffer = np.empty_like(arr)

    def __getitem__(self, index):
        self.reads.append(index)
        self._buffer[...] = -7.0  # a range read earlier must not be used any more
        if isinstance(index, slice):
            out = self._buffer[index]
            out[...] = self._arr[index]
            return out
        return self._arr[np.asarray(index)].copy()


@pytest.mark.parametrize("guided", [False, True])
@pytest.mark.parametrize("tile", [False, True])
def test_a_pool_read_on_demand_quilts_as_its_array(brick_pool, guided, tile):
    from tghop.quilting import prepare_pool, quilt_prepared

    arr = brick_pool.astype(np.float32)
    size = (48, 64)
    guide = np.random.default_rng(2).random((*size, 3)) if guided else None
    kwargs = dict(detail=0.5, tile=tile, guide_scale=4 if guided else None)
    expected = quilt_prepared(prepare_pool(arr, size, **kwargs), rng=5, guide=guide)
    pool = _ReadOnDemand(arr)
    prepared = prepare_pool(pool, size, **kwargs)
    ranges = [r for r in pool.reads if isinstance(r, slice)]
    assert [(r.start, r.stop) for r in ranges] == [(a, min(a + 128, len(arr))) for a in range(0, len(arr), 128)]
    assert np.array_equal(quilt_prepared(prepared, rng=5, guide=guide), expected)
    assert not any(isinstance(r, slice) for r in pool.reads[len(ranges):])  # quilting reads chosen patches only


def test_a_pool_read_on_demand_is_checked():
    from tghop.quilting import prepare_pool

    class Pool:
        def __init__(self, shape, dtype=np.float32):
            self.shape, self.dtype = shape, np.dtype(dtype)

        def __getitem__(self, index):
            return np.full((5,) + self.shape[1:], np.nan, dtype=self.dtype)[: self.shape[0]]

    for bad in (Pool((5, 8, 6, 3)), Pool((5, 8, 8, 0)), Pool((0, 8, 8, 3)), Pool((5, 8, 8, 3), np.uint8)):
        with pytest.raises(TGHopError, match="read on demand"):
            prepare_pool(bad, (20, 20))
    with pytest.raises(TGHopError, match="NaN"):  # values are checked where they are read
        prepare_pool(Pool((5, 8, 8, 3)), (20, 20))


# ----------------------------------------------------------------------------- error bound


@pytest.mark.parametrize("tile", [False, True])
def test_box_sums_bound_the_overlap_error_from_below(brick_pool, tile):
    # The lower bound that prunes the pool: for every overlap shape, the squared box sums
    # of a masked difference never exceed its squared norm, and equal it for a difference
    # that is constant over each box.
    prepared = quilting.prepare_pool(brick_pool, (120, 120), tile=tile)
    boxes, masks = prepared._boxes, prepared._masks_fc
    rng = np.random.default_rng(0)
    for j in range(masks.shape[0]):
        d = rng.standard_normal((50, masks.shape[1])).astype(np.float32) * masks[j]
        bound = np.square(quilting._box_sums(d, boxes)).sum(axis=1)
        assert np.all(bound <= np.square(d).sum(axis=1) * (1 + 1e-5))
        values = rng.standard_normal(boxes.scale.size).astype(np.float32) * boxes.in_mask[j]
        d = np.full((1, masks.shape[1]), np.nan, dtype=np.float32)
        start = 0
        for members in boxes.members:  # constant over each box
            d[0, members] = values[start : start + len(members), None]
            start += len(members)
        assert not np.isnan(d).any()  # the boxes cover the frame
        assert np.allclose(np.square(quilting._box_sums(d, boxes)).sum(), np.square(d).sum(), rtol=1e-5)


@pytest.mark.parametrize("tile", [False, True])
def test_pruned_candidates_give_the_same_quilt_as_full_errors(monkeypatch, brick_pool, tile):
    # Full errors are computed only for the patches the bound cannot rule out; the quilt is
    # the one every patch's full error gives (with a guide, and with detail selection).
    guide = ndimage.uniform_filter(crops(bricks(256), 1, 96, seed=5)[0], (9, 9, 1))
    kwargs = dict(tile=tile, detail=0.5, guide=guide, guide_weight=3.0, rng=4)
    pruned = quilt(brick_pool, (96, 96), **kwargs)
    monkeypatch.setattr(quilting, "_bounded_candidates", lambda *args: None)
    np.testing.assert_array_equal(pruned, quilt(brick_pool, (96, 96), **kwargs))


def test_boundary_cut_breaks_ties_straight_then_left():
    # Equal costs: the path goes straight; left and right equal (straight dearer): left.
    assert min_error_boundary_cut(np.zeros((4, 3))).tolist() == [0, 0, 0, 0]
    assert min_error_boundary_cut(np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 1.0]])).tolist() == [0, 1]
    assert min_error_boundary_cut(np.array([[1.0, 0.0, 1.0],
                                            [0.0, 0.0, 0.0]])).tolist() == [1, 0]  # first column, then right


@pytest.mark.parametrize("size, tile", [((100, 130), False), ((96, 120), True), ((70, 70), False)])
def test_guide_targets_of_all_blocks_equal_the_box_means_of_their_windows(size, tile):
    # The guide's low pass is taken once for every block (row sums, then column sums);
    # it must be exactly the box means of each block's window of the canvas (wrapped for
    # tileable output, edge-extended where the canvas is larger than the output).
    rng = np.random.default_rng(2)
    guide = rng.random((*size, 3)).astype(np.float32)
    plan = quilting_plan(size, 16, overlap=3, tile=tile)
    hc, wc = plan.canvas_shape
    canvas = guide if tile else np.pad(guide, ((0, hc - size[0]), (0, wc - size[1]), (0, 0)), mode="edge")
    got = quilting._all_targets(guide, plan, 4)
    assert got.shape == (plan.ys.size, plan.xs.size, 4 * 4 * 3)
    for i, y in enumerate(plan.ys.tolist()):
        for j, x in enumerate(plan.xs.tolist()):
            window = canvas[quilting._window(y, x, 16, hc, wc)]
            np.testing.assert_array_equal(got[i, j], quilting._box_means(window[None], 4)[0])


@pytest.mark.parametrize("size,tile", [((256, 256), False), ((50, 70), False), ((10, 10), False), ((96, 160), True),
                                       ((33, 200), True)])
def testblock_count_is_the_plans(size, tile):
    from tghop.quilting import block_count, quilting_plan

    for overlap in (None, 3, 8):
        assert block_count(size, 32 if not tile else 16, overlap=overlap, tile=tile) == quilting_plan(
            size, 32 if not tile else 16, overlap=overlap, tile=tile).n_blocks


def test_real_number_settings_are_checked_by_one_helper_with_the_same_words():
    """check_number: finite, >= 0 (> 0 with positive), not a bool; its message at every caller."""
    from tghop._arrays import check_number
    from tghop.guided import random_labels, region_weights

    assert check_number(0, "x") == 0.0 and isinstance(check_number(np.float32(2.5), "x", positive=True), float)
    for value in (-1, float("nan"), float("inf"), True, "1", None):
        with pytest.raises(TGHopError, match=r"^x must be a finite number >= 0, got "):
            check_number(value, "x")
    with pytest.raises(TGHopError, match=r"^w: x must be a finite number > 0 \(pixels\), got 0$"):
        check_number(0, "x", positive=True, where="w", unit="pixels")
    pool = np.random.default_rng(0).random((20, 8, 8, 3))
    for kw, words in ((dict(tolerance=-1), "tolerance must be a finite number >= 0, got -1"),
                      (dict(reuse=float("nan")), "reuse must be a finite number >= 0, got nan"),
                      (dict(guide=np.zeros((16, 16, 3)), guide_weight=-0.5),
                       "guide_weight must be a finite number >= 0, got -0.5")):
        with pytest.raises(TGHopError, match=f"^{words}$"):
            quilt(pool, (16, 16), rng=0, **kw)
    with pytest.raises(TGHopError, match=r"^transition must be a finite number >= 0 \(pixels\), got -4$"):
        region_weights(np.array([[0, 1], [1, 0]]), 2, -4)
    with pytest.raises(TGHopError, match=r"^scale must be a finite number > 0 \(pixels\), got 0$"):
        random_labels((64, 64), 3, scale=0, rng=1)
