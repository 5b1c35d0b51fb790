"""Tests of tghop.seams (gradient-domain seam removal) and the seam steps quilting records."""

from __future__ import annotations

import numpy as np
import pytest

from tghop import TGHopError
from tghop.quilting import GUIDE_SCALE, block_labels, prepare_pool, quilt_prepared, quilting_plan
from tghop.seams import SeamSteps, remove_seams


def smooth_image(h, w, c=3):
    """A smooth test image in [0.2, 0.8]."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    base = np.sin(y / 9.0) + x / w - 0.5 * y / h
    return np.stack([0.5 + 0.1 * base * (k + 1) / c for k in range(c)], axis=-1).astype(np.float32)


def steps_between(image, target, labels, tile=False):
    """The SeamSteps that turn ``image``'s differences across label changes into ``target``'s."""
    h, w, c = image.shape
    index, change = [], []
    for axis in (1, 0):
        nxt = lambda a: np.roll(a, -1, axis=axis)  # noqa: E731
        across = labels != nxt(labels)
        if not tile:
            if axis == 1:
                across[:, -1] = False
            else:
                across[-1] = False
        flat = np.flatnonzero(across)
        index.append(flat)
        change.append(((nxt(target) - target) - (nxt(image) - image)).reshape(-1, c)[flat])
    return SeamSteps(shape=(h, w), tile=tile, index=tuple(index), change=tuple(change))


def blocky(img, step, seed=0):
    """``img`` with a random tone offset added per ``step x step`` block, and block labels."""
    h, w = img.shape[:2]
    rng = np.random.default_rng(seed)
    offsets = rng.uniform(-0.1, 0.1, (-(-h // step), -(-w // step), img.shape[2])).astype(np.float32)
    rows, cols = np.arange(h) // step, np.arange(w) // step
    labels = rows[:, None] * 1000 + cols[None, :]
    return img + offsets[rows][:, cols], labels


@pytest.mark.parametrize("size", [(64, 80), (520, 530)])  # numpy.fft's mirrored solve; the DCT
def test_remove_seams_undoes_block_offsets(size):
    # The exact steps given: across every seam the smooth image's differences again (the
    # steps of up to 0.2 fall a hundredfold).
    img = smooth_image(*size)
    shifted, labels = blocky(img, 27)
    steps = steps_between(shifted, img, labels)
    out = remove_seams(shifted, steps)
    for k, axis in enumerate((1, 0)):
        first, second = steps.index[k], steps.second(axis)

        def across(a):
            flat = a.reshape(-1, 3)
            return flat[second] - flat[first] - (img.reshape(-1, 3)[second] - img.reshape(-1, 3)[first])

        assert np.abs(across(shifted)).max() > 0.15 and np.abs(across(out)).max() < 0.003
    assert out.dtype == np.float32 and out.shape == img.shape


def test_remove_seams_screening_stops_a_drift():
    # Thirty seams that all ask for a step up of 0.01: the corrections fade within about
    # a block (SCREENING) instead of adding up to a ramp of 0.3 across the image.
    from tghop import seams

    h, w = 40, 600
    flat = np.full((h, w, 1), 0.5, dtype=np.float32)
    labels = np.broadcast_to(np.arange(w) // 20, (h, w))
    steps = steps_between(flat, flat, labels)
    steps = SeamSteps(steps.shape, False, steps.index, (np.full_like(steps.change[0], 0.01), steps.change[1]))
    out = remove_seams(flat, steps)
    assert 0.005 < out.max() - out.min() < 0.05
    assert seams.SCREENING < w / 10


def test_remove_seams_tile_removes_the_step_across_the_wrap():
    # A ramp in x jumps from its last column back to its first: a seam where the image wraps
    # around. With tile the jump is removed (the result wraps around smoothly).
    h, w = 40, 60
    ramp = np.broadcast_to((0.3 + 0.4 * np.arange(w) / w)[None, :, None], (h, w, 3)).astype(np.float32)
    labels = np.zeros((h, w), int)
    labels[:, w // 2:] = 1
    smooth = np.broadcast_to((0.3 + 0.4 * np.abs(np.arange(w) - w / 2) / w)[None, :, None], (h, w, 3))
    steps = steps_between(ramp, smooth.astype(np.float32), labels, tile=True)
    assert steps.index[0].size == 2 * h and steps.index[1].size == 0  # the middle and the wrap
    wrapped = remove_seams(ramp, steps)
    inner = np.abs(np.diff(wrapped, axis=1)).max()
    assert np.abs(wrapped[:, 0] - wrapped[:, -1]).max() <= inner + 1e-6
    assert np.abs(ramp[:, 0] - ramp[:, -1]).max() > 0.35


def test_remove_seams_window_keeps_the_step_and_leaves_the_detail():
    # Two halves of one noise texture, the right one brighter by 0.1, and steps that would
    # also flatten the noise across the seam: averaged over a window only the mean step is
    # removed, and the noise's own differences across the seam are kept.
    rng = np.random.default_rng(0)
    h, w = 64, 64
    noise = (0.4 + 0.1 * rng.random((h, w, 1))).astype(np.float32)
    labels = np.zeros((h, w), int)
    labels[:, 32:] = 1
    shifted = noise.copy()
    shifted[:, 32:] += 0.1
    flat = np.full_like(noise, 0.45)
    steps = steps_between(shifted, flat, labels)
    original = noise[:, 32, 0] - noise[:, 31, 0]
    moved = {}
    for window in (31, 1):
        out = remove_seams(shifted, steps, window=window)
        step = out[:, 32, 0] - out[:, 31, 0]
        assert abs(step.mean() - original.mean()) < 0.005, window  # the 0.1 step is gone
        moved[window] = np.std(step - original) / np.std(original)
    assert moved[31] < 0.1 and moved[1] > 0.4, moved


def test_remove_seams_without_seams_changes_nothing_and_out_in_place():
    img = smooth_image(40, 50)
    none = SeamSteps((40, 50), False, (np.zeros(0, int),) * 2, (np.zeros((0, 3)),) * 2)
    assert np.array_equal(remove_seams(img, none), img)
    shifted, labels = blocky(img.astype(np.float64), 16)
    steps = steps_between(shifted, img.astype(np.float64), labels)
    expected = remove_seams(shifted, steps, window=5)
    assert expected.dtype == np.float64 and expected.min() >= 0.0 and expected.max() <= 1.0
    same = shifted.copy()
    assert remove_seams(same, steps, window=5, out=same) is same
    np.testing.assert_array_equal(same, expected)


def test_remove_seams_bad_input():
    img = smooth_image(20, 20)
    steps = steps_between(img, img, np.zeros((20, 20), int))
    with pytest.raises(TGHopError, match="not of this 20x21"):
        remove_seams(smooth_image(20, 21), steps)
    with pytest.raises(TGHopError, match=r"\(H, W, C\) float32 or float64"):
        remove_seams(img[..., 0], steps)
    with pytest.raises(TGHopError, match=r"\(H, W, C\) float32 or float64"):
        remove_seams((img * 255).astype(np.uint8), steps)
    with pytest.raises(TGHopError, match="SeamSteps"):
        remove_seams(img, np.zeros((20, 20), int))
    with pytest.raises(TGHopError, match="window must be an integer >= 1"):
        remove_seams(img, steps, window=0)


@pytest.mark.parametrize("tile", [False, True])
def test_block_labels_differ_between_overlapping_blocks(tile):
    for size in [(32, 32), (100, 127), (162, 190), (300, 54)]:
        plan = quilting_plan(size, 32, tile=tile)
        codes = block_labels(plan)
        assert codes.shape == (plan.ys.size, plan.xs.size) and codes.max() < 25
        ny, nx = codes.shape
        for i in range(ny):
            for j in range(nx):
                for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
                    a, b = i + di, j + dj
                    if tile:
                        a, b = a % ny, b % nx
                    if 0 <= a < ny and 0 <= b < nx and (a, b) != (i, j):
                        assert codes[i, j] != codes[a, b], (size, i, j, a, b)


@pytest.mark.parametrize("tile,size", [(False, (70, 75)), (True, (60, 60))])
def test_quilt_seam_steps_flatten_a_quilt_of_flat_patches(tile, size):
    # Flat patches, each its own value, quilted after a ramp: every difference in the image
    # is a step between two patches, and quilting knows each one. Removed, the steps across
    # the seams fall to a tenth or less (a few 3-block corners keep theirs).
    n, p = 400, 12
    pool = np.repeat(np.linspace(0.0, 1.0, n, dtype=np.float32), p * p).reshape(n, p, p, 1)
    x = np.arange(size[1]) / size[1]
    ramp = (0.1 + 0.8 * (1.0 - np.abs(2.0 * x - 1.0))).astype(np.float32)  # up and back down: periodic
    guide = np.broadcast_to(ramp[None, :, None], size + (1,))
    prepared = prepare_pool(pool, size, tile=tile, guide_scale=GUIDE_SCALE)
    kw = dict(rng=3, dtype=np.float32, guide=guide, guide_weight=100.0)
    image, steps = quilt_prepared(prepared, return_seams=True, **kw)
    np.testing.assert_array_equal(image, quilt_prepared(prepared, **kw))
    assert steps.shape == size and steps.tile == tile
    values = image[..., 0].ravel()
    for k, axis in enumerate((1, 0)):
        index = steps.index[k]
        assert np.unique(index).size == index.size
        # the steps are exactly the differences (flat patches have none of their own) ...
        np.testing.assert_allclose(steps.change[k][:, 0], values[index] - values[steps.second(axis)], atol=1e-6)
    # ... and every difference between neighbours inside the image is one of them
    across = image[:, 1:, 0] != image[:, :-1, 0]
    recorded = np.zeros(size, dtype=bool).ravel()
    recorded[steps.index[0]] = True
    assert across.any() and (across & ~recorded.reshape(size)[:, :-1]).sum() <= (across.sum() // 10 if tile else 0)
    smooth = remove_seams(image, steps)
    for k, axis in enumerate((1, 0)):
        step = np.abs(values[steps.second(axis)] - values[steps.index[k]])
        after = smooth[..., 0].ravel()
        assert np.abs(after[steps.second(axis)] - after[steps.index[k]]).mean() < 0.15 * step.mean()


def test_synthesize_seam_window(small_model):
    # The same quilt (no layout guide) with and without the seam removal: smaller steps
    # across the grid's overlap bands; the same seed gives the same image.
    kw = dict(rng=4, n_patches=300, refine=0, match_colours=False, layout_weight=0.0)
    plain = small_model.synthesize((80, 96), seam_window=0, **kw)
    smooth = small_model.synthesize((80, 96), **kw)
    exact = small_model.synthesize((80, 96), seam_window=1, **kw)
    np.testing.assert_array_equal(smooth, small_model.synthesize((80, 96), **kw))
    plan = quilting_plan((80, 96), small_model.patch_size)
    bands = np.zeros(96 - 1, dtype=bool)
    for x in plan.xs[1:]:
        bands[x - 1 : x + plan.overlap - 1] = True  # where the cuts run

    def step(img):
        d = np.abs(np.diff(img, axis=1)).mean(axis=(0, 2))
        return d[bands].mean() / d[~bands].mean()

    assert step(exact) < step(smooth) < step(plain)
    from tghop.settings import PAPER

    assert PAPER["seam_window"] == 0
    with pytest.raises(TGHopError, match="seam_window must be"):
        small_model.synthesize((80, 96), seam_window=-1)


@pytest.mark.parametrize("window", [9, 1])
def test_synthesize_tile_stays_tileable(small_model, window):
    # The periodic solve keeps a tileable image tileable: across its wrap-around edges the
    # differences are like those inside. Where the wrap-around line ranks among the inside
    # lines varies from image to image (one at the 92nd percentile in ten), so four images
    # are taken: on average it ranks mid-field (about 0.4), as an inside line would; across
    # the edges of an image made without tile it ranks at 0.95.
    ranks = []
    for seed in range(4):
        img = small_model.synthesize((64, 80), rng=seed, n_patches=300, tile=True, seam_window=window)
        for axis in (0, 1):
            inside = np.abs(np.diff(img, axis=axis)).mean(axis=(1 - axis, 2))  # one value per edge line
            first, last = np.take(img, 0, axis=axis), np.take(img, -1, axis=axis)
            ranks.append(float((inside < np.abs(first - last).mean()).mean()))
    assert np.mean(ranks) <= 0.7 and max(ranks) < 1, (ranks, window)


def test_the_seam_removal_reports_its_progress(small_model):
    # Nothing was reported between the last quilting block and the refinement: the seam removal (the local
    # means of each axis, a screened Poisson solve per channel) ran silent, and at 4096x4096 the progress
    # bar of tghop serve stood still for seconds.
    calls = []
    kw = dict(rng=4, n_patches=300, layout_weight=0.0)
    image = small_model.synthesize((80, 96), progress=lambda *call: calls.append(call), **kw)
    np.testing.assert_array_equal(image, small_model.synthesize((80, 96), **kw))  # the same image
    stages = [stage for stage, _, _ in calls]
    last_quilt, first_refine = len(stages) - stages[::-1].index("quilting"), stages.index("refine")
    between = calls[last_quilt:first_refine]
    # the steps gathered (quilting), the two axes' local means, then 3 channels' solves
    assert between == [("seams", 0, 1)] + [("seams", done, 5) for done in range(6)]
    calls.clear()
    small_model.synthesize((80, 96), progress=lambda *call: calls.append(call), seam_window=1, **kw)
    assert [c for c in calls if c[0] == "seams"] == [("seams", 0, 1)] + [("seams", done, 3) for done in range(4)]
    calls.clear()
    small_model.synthesize((80, 96), progress=lambda *call: calls.append(call), seam_window=0, **kw)
    assert "seams" not in [c[0] for c in calls]
    image = smooth_image(24, 32)
    labels = np.zeros((24, 32), dtype=int)
    calls.clear()
    remove_seams(image, steps_between(image, image, labels), window=3, progress=lambda *call: calls.append(call))
    assert calls == [("seams", 0, 5), ("seams", 5, 5)]  # no seam edges: done at once
