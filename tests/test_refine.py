"""The refinement after stitching (tghop.refine): pyramid, statistics, matching, wiring."""

import sys

import numpy as np
import pytest
from scipy import ndimage

from tghop import _fft as F
from tghop import data
from tghop._errors import TGHopError
from tghop.pyramid import laplacian_pyramid, reconstruct
from tghop.refine import TAIL_LEVELS, BandStatistics, oriented_parts, refine, tail_quantiles


@pytest.fixture(scope="module")
def cells():
    return data.cells(96, rng=3)


def _blurred(img, sigma=1.2):
    return np.stack([ndimage.gaussian_filter(img[..., k], sigma) for k in range(img.shape[2])], axis=2)


@pytest.mark.parametrize("mode", ["reflect", "wrap"])
@pytest.mark.parametrize("shape", [(37, 50, 3), (64, 64, 1), (5, 9, 3)])
def test_pyramid_is_exact(shape, mode, rng):
    img = rng.random(shape).astype(np.float32)
    bands = laplacian_pyramid(img, 4, mode=mode)
    assert bands[0].shape == shape and all(b.dtype == np.float32 for b in bands)
    assert np.abs(reconstruct(bands, mode=mode) - img).max() < 1e-5


@pytest.mark.parametrize("n", [0, 1, 2, 4])
def test_oriented_parts_sum_to_band(n, rng):
    band = rng.standard_normal((20, 33, 3)).astype(np.float32)
    parts = oriented_parts(band, n)
    assert len(parts) == max(n, 1)
    assert np.abs(np.sum(parts, axis=0) - band).max() < 1e-4


@pytest.mark.parametrize("n", [2, 3, 4, 6])
@pytest.mark.parametrize("shape, axes", [((24, 31), (0, 1)), ((20, 33, 3), (0, 1)), ((2, 20, 33), (1, 2))])
def test_oriented_parts_are_the_angular_windows(n, shape, axes, rng):
    """Part k is the band filtered by cos^2(theta - k pi / n) * 2 / n in the Fourier domain."""
    band = rng.standard_normal(shape)
    h, w = shape[axes[0]], shape[axes[1]]
    theta = np.arctan2(np.fft.fftfreq(h)[:, None], np.fft.rfftfreq(w)[None, :])
    spectrum = np.fft.rfft2(band, axes=axes)
    for k, part in enumerate(oriented_parts(band.astype(np.float32), n, axes=axes)):
        window = np.cos(theta - k * np.pi / n) ** 2 * 2.0 / n
        if len(shape) == 3:
            window = window[..., None] if axes == (0, 1) else window[None]
        expect = np.fft.irfft2(spectrum * window, s=(h, w), axes=axes)
        assert part.dtype == np.float32 and np.abs(part - expect).max() < 1e-5


def test_oriented_parts_separate_directions():
    y, x = np.mgrid[:64, :64]
    vertical_stripes = np.sin(2 * np.pi * x / 8.0)[..., None]
    energy = [float(np.sum(p ** 2)) for p in oriented_parts(vertical_stripes, 4)]
    assert np.argmax(energy) == 0 and energy[2] < 1e-6 * energy[0]


@pytest.mark.parametrize("n_orientations", [0, 4])
def test_band_statistics_shapes(cells, n_orientations):
    st = BandStatistics(n_levels=3, n_orientations=n_orientations, n_quantiles=65).fit(cells)
    assert st.band_quantiles_.shape == (3, max(n_orientations, 1), 3, 65) and st.pixel_quantiles_.shape == (3, 65)
    assert np.allclose(st.colour_basis_ @ st.colour_basis_.T, np.eye(3))
    assert np.all(np.diff(st.band_quantiles_, axis=-1) >= 0)
    assert np.allclose(st.from_decorrelated(st.to_decorrelated(cells)), cells)


@pytest.mark.parametrize("n_orientations", [0, 4])
def test_refine_restores_fine_detail(cells, n_orientations):
    """A blurred copy regains the exemplar's fine-band contrast and pixel distribution."""
    st = BandStatistics(n_orientations=n_orientations).fit(cells)
    soft = _blurred(cells)
    out = refine(soft, st, n_iter=3)
    assert out.shape == soft.shape and out.dtype == np.float64 and 0 <= out.min() and out.max() <= 1

    def fine_energy(img):
        return [float(np.std(b)) for b in laplacian_pyramid(img.astype(np.float32), 2)[:2]]

    ref, before, after = fine_energy(cells), fine_energy(soft), fine_energy(out)
    for r, b, a in zip(ref, before, after):
        assert abs(a - r) < 0.5 * abs(b - r)
    # Layout kept: the refined image is still the blurred one, sharpened (not a new picture).
    assert np.corrcoef(out[..., 0].ravel(), soft[..., 0].ravel())[0, 1] > 0.9


def test_refine_moves_patch_statistics_towards_exemplar(cells):
    from tghop.metrics import sliced_wasserstein

    st = BandStatistics().fit(cells)
    soft = _blurred(cells, 1.5)
    out = refine(soft, st, n_iter=3)
    assert sliced_wasserstein(cells, out) < 0.7 * sliced_wasserstein(cells, soft)


def test_refine_deterministic_grey_and_tiled(rng):
    grey = data.bricks(64, rng=2)[..., :1]
    st = BandStatistics().fit(grey)
    img = _blurred(grey) * 0.8 + 0.1
    a, b = refine(img, st), refine(img, st)
    assert np.array_equal(a, b) and a.shape == (64, 64, 1)
    tiled = refine(img, st, tile=True)
    assert tiled.shape == img.shape and not np.array_equal(tiled, a)
    assert np.array_equal(refine(img, st, n_iter=0), np.clip(img, 0, 1))


def test_threaded_refine_equals_one_thread(cells, monkeypatch):
    """Large images are refined one thread per channel: the same numbers as one by one."""
    from tghop import refine as refine_module

    st = BandStatistics().fit(cells)
    img = _blurred(cells) * 0.8 + 0.1
    monkeypatch.setattr(refine_module, "_THREADED_PIXELS", 1)
    monkeypatch.setattr(refine_module, "usable_cores", lambda: 2)
    threaded = refine(img, st)
    monkeypatch.setattr(refine_module, "_THREADED_PIXELS", 1 << 62)
    assert np.array_equal(threaded, refine(img, st))


def test_refine_threads_are_limited_by_memory(cells, monkeypatch):
    """Channels refined at once: as many as their working memory allows (at least one),
    with the same numbers whatever the number."""
    import concurrent.futures

    from tghop import refine as refine_module

    st = BandStatistics().fit(cells)
    img = _blurred(cells) * 0.8 + 0.1
    one_channel = refine_module._CHANNEL_ARRAYS * 4 * img.shape[0] * img.shape[1]
    monkeypatch.setattr(refine_module, "_THREADED_PIXELS", 1)
    monkeypatch.setattr(refine_module, "usable_cores", lambda: 2)
    started = []
    real = concurrent.futures.ThreadPoolExecutor

    def spy(max_workers):
        started.append(max_workers)
        return real(max_workers=max_workers)

    monkeypatch.setattr(concurrent.futures, "ThreadPoolExecutor", spy)
    results = {}
    for budget, threads in ((10 * one_channel, 3), (2 * one_channel, 2), (one_channel, None), (1, None)):
        monkeypatch.setattr(refine_module, "_REFINE_MEMORY", budget)
        started.clear()
        results[budget] = refine(img, st)
        assert started == ([threads] if threads else []), (budget, started)
    first = next(iter(results.values()))
    assert all(np.array_equal(first, r) for r in results.values())


def test_refine_errors(cells):
    st = BandStatistics().fit(cells)
    with pytest.raises(TGHopError, match="n_iter"):
        refine(cells, st, n_iter=-1)
    with pytest.raises(TGHopError, match="channels"):
        refine(cells[..., :1], st)
    with pytest.raises(TGHopError, match="n_orientations"):
        BandStatistics(n_orientations=-1).fit(cells)


def test_synthesize_refine_switch(small_model, bricks96):
    plain = small_model.synthesize((64, 64), rng=1, n_patches=300, refine=0)
    refined = small_model.synthesize((64, 64), rng=1, n_patches=300)
    assert refined.shape == plain.shape and not np.allclose(plain, refined)
    assert np.array_equal(refined, small_model.synthesize((64, 64), rng=1, n_patches=300))
    with pytest.raises(TGHopError, match="refine"):
        small_model.synthesize((64, 64), rng=1, n_patches=300, refine=-2)


def test_refine_survives_save_and_load(small_model, tmp_path):
    from tghop.modelfile import load_model, save_model

    path = tmp_path / "m.npz"
    save_model(small_model, path)
    loaded = load_model(path)
    assert np.array_equal(loaded.synthesize((48, 48), rng=4, n_patches=200),
                          small_model.synthesize((48, 48), rng=4, n_patches=200))
    assert small_model.n_parameters()["refinement (ours)"]["stored"] == (4 * 4 + 1) * 3 * 257 + 3 + 9 + 4 * 3 * 257


def test_large_exemplar_is_measured_on_crops_with_the_same_statistics(monkeypatch):
    from tghop import data, refine as refine_module

    tile = data.bricks(128, rng=1)
    small = BandStatistics().fit(tile)
    seen = []
    crops = refine_module._crops
    monkeypatch.setattr(refine_module, "_crops", lambda h, w, side: seen.append(crops(h, w, side)) or seen[-1])
    big = BandStatistics().fit((np.tile(tile, (12, 12, 1)) * 255 + 0.5).astype(np.uint8))  # 1536 x 1536, uint8
    assert [c[2:] for c in seen[0]] == [(1024, 1024)] * 4  # four crops, never the whole image
    # A periodic texture has the same band statistics over any large region.
    assert np.median(np.abs(big.band_quantiles_ - small.band_quantiles_)) < 0.005
    assert np.median(np.abs(big.pixel_quantiles_ - small.pixel_quantiles_)) < 0.02


def test_uint8_exemplar_gives_the_statistics_of_its_float_version():
    # tghop 0.2 measured a uint8 exemplar (what `tghop fit` loads) on the 0-255 scale, and
    # its refinement turned every image flat grey.
    from tghop import TGHop

    tile = data.bricks(96, rng=2)
    as_uint8 = (tile * 255 + 0.5).astype(np.uint8)
    a, b = BandStatistics().fit(as_uint8 / 255.0), BandStatistics().fit(as_uint8)
    np.testing.assert_allclose(b.band_quantiles_, a.band_quantiles_, atol=1e-5)
    np.testing.assert_allclose(b.colour_mean_, a.colour_mean_, atol=1e-6)
    model = TGHop(n_clusters=4, n_codewords=20, max_patches=400, layout_factor=None).fit(as_uint8)
    out = model.synthesize(64, rng=0, n_patches=200)
    assert out.std() > 0.5 * tile.std()


def test_matching_in_chunks_is_pointwise_and_handles_strided_outputs(monkeypatch):
    # The table lookup runs a chunk of values at a time; the result must not depend on
    # the chunk size, and an ``out`` that is a strided view (or the input itself) must
    # receive the values.
    from tghop import quantiles as Q, refine as R

    rng = np.random.default_rng(3)
    values = (rng.standard_normal((61, 53)) ** 3).astype(np.float32)
    levels = np.linspace(0.0, 1.0, 33)
    target = np.sort(rng.standard_normal(33))
    whole = R.match_quantiles(values, target, levels)
    monkeypatch.setattr(Q, "_MATCH_CHUNK", 7)
    np.testing.assert_array_equal(R.match_quantiles(values, target, levels), whole)
    big = np.zeros((61, 106), dtype=np.float32)
    big[:, ::2] = values
    strided = big[:, ::2]
    assert R.match_quantiles(strided, target, levels, out=strided) is strided
    np.testing.assert_array_equal(big[:, ::2], whole)
    assert not big[:, 1::2].any()
    # The map is monotone and reaches the target's range.
    order = np.argsort(values, axis=None)
    assert np.all(np.diff(whole.ravel()[order]) >= 0)
    assert whole.min() >= target[0] - 1e-6 and whole.max() <= target[-1] + 1e-6


def test_matching_maps_values_beyond_the_sampled_range_to_the_ends_of_the_target():
    # The ranks come from a strided subset, so values outside its range (here far
    # outliers the subset misses) occur; with the largest table (65,536 entries) they take
    # the first and last entries, and the rest take the target's distribution.
    from tghop import refine as R

    rng = np.random.default_rng(5)
    values = rng.standard_normal(1 << 18).astype(np.float32)
    values[1::1024] = 1e6
    values[3::1024] = -1e6
    levels = np.linspace(0.0, 1.0, 65)
    target = np.sort(rng.uniform(-2.0, 3.0, 65))
    out = R.match_quantiles(values, target, levels)
    assert np.all(out[1::1024] == np.float32(target[-1])) and np.all(out[3::1024] == np.float32(target[0]))
    inside = np.abs(values) < 1e6
    # Ranks of a quarter of the values: the quantiles of all of them within sampling error
    # (measured: 0.03 at most, at the last level, where the target's tail is steep).
    assert np.abs(np.quantile(out[inside], levels) - target).max() < 0.05


@pytest.mark.parametrize("n_values, dist", [(1 << 16, "normal"), (5000, "cubed"), (1000, "two-valued")])
def test_matching_gives_the_values_the_target_distribution(n_values, dist):
    # Histogram matching by ranks: with every value ranked, the matched values' quantiles
    # are the target's (up to a table step), the smallest value takes target[0] and the
    # largest target[-1], and the order of the values is kept (ties stay tied).
    from tghop import refine as R

    rng = np.random.default_rng(n_values)
    values = {"normal": rng.standard_normal(n_values), "cubed": rng.standard_normal(n_values) ** 3,
              "two-valued": rng.integers(0, 2, n_values) * 0.7}[dist].astype(np.float32)
    levels = np.linspace(0.0, 1.0, 257)
    target = np.sort(rng.gamma(2.0, 1.0, 257))
    out = R.match_quantiles(values, target, levels)
    assert out.dtype == np.float32
    order = np.argsort(values, kind="stable")
    assert np.all(np.diff(out[order]) >= 0)
    if dist == "two-valued":  # two ties: each takes the target at its mid-rank
        zeros = values == 0
        rank = lambda lo, n: np.interp((lo + (n - 1) / 2) / (n_values - 1), levels, target)  # noqa: E731
        np.testing.assert_allclose(out[zeros], rank(0, zeros.sum()), rtol=1e-6)
        np.testing.assert_allclose(out[~zeros], rank(zeros.sum(), (~zeros).sum()), rtol=1e-6)
        return
    assert out.min() == np.float32(target[0]) and out.max() == np.float32(target[-1])
    # Values that share a table entry share an output: a heavy tail (cubed) leaves few
    # entries to the bulk of the values, hence tolerances relative to the target's span.
    span = target[-1] - target[0]
    step = np.abs(np.quantile(out, levels) - target)
    assert np.median(step) < 1e-3 * span and step.max() < 0.05 * span


def test_matching_flat_values_gives_the_target_median():
    from tghop import refine as R

    levels = np.linspace(0.0, 1.0, 5)
    target = np.array([0.0, 1.0, 2.0, 3.0, 10.0])
    assert np.all(R.match_quantiles(np.full(100, 0.25, dtype=np.float32), target, levels) == 2.0)


def test_tail_quantiles_follow_an_exponential_tail_up_to_the_extremes():
    # A Laplacian band with one far outlier at each end: the stored extremes are the
    # outliers. Linear interpolation over the end steps would put a quarter of their 1/256
    # beyond half the outlier; the added levels follow the Laplacian's own quantiles.
    rng = np.random.default_rng(2)
    values = np.concatenate([rng.laplace(0.0, 0.01, 1 << 16), [-0.5, 0.4]])
    levels = np.linspace(0.0, 1.0, 257)
    q = np.quantile(values, levels)
    new_levels, new_q = tail_quantiles(levels, np.stack([q, 2 * q]))
    assert new_levels.shape == (257 + 2 * TAIL_LEVELS,) and new_q.shape == (2, 257 + 2 * TAIL_LEVELS)
    assert np.all(np.diff(new_levels) > 0) and np.all(np.diff(new_q, axis=1) >= 0)
    kept = np.isin(new_levels, levels)
    np.testing.assert_array_equal(new_levels[kept], levels)  # the stored quantiles stay, extremes included
    np.testing.assert_array_equal(new_q[:, kept], np.stack([q, 2 * q]))
    added = ~kept
    truth = np.quantile(values, new_levels[added])
    assert np.abs(new_q[0, added] - truth).max() < 0.2 * np.abs(truth).max()
    linear = np.interp(new_levels[added], levels, q)
    assert np.abs(linear - truth).max() > 2 * np.abs(truth).max()
    same_levels, same_q = tail_quantiles(levels, q, n_tail=0)
    assert same_levels.shape == levels.shape and np.array_equal(same_q, q)


def test_refine_makes_no_speckles_of_an_exemplars_lone_extremes():
    # A smooth exemplar with three bright dots: its finest band's extreme quantiles are the
    # dots. Matched linearly through the end steps, a smooth image's largest band values
    # took dot-sized values and came out as bright and dark specks (16 here; blue_bubbles).
    def smooth(seed):
        x = ndimage.gaussian_filter(np.random.default_rng(seed).random((128, 128, 3)), (4, 4, 0))
        return 0.2 + 0.6 * (x - x.min()) / (x.max() - x.min())

    def specks(img):
        grey = img.mean(axis=2)
        return int((np.abs(grey - ndimage.median_filter(grey, 3)) > 0.15).sum())

    exemplar = smooth(0)
    exemplar[[20, 70, 100], [90, 15, 60]] = 1.0
    assert specks(exemplar) == 3
    assert specks(refine(smooth(1), BandStatistics().fit(exemplar))) <= 3


@pytest.mark.parametrize("n", [0, 1, 2, 3, 4, 5])
def test_oriented_parts_matched_in_chunks_equal_matching_each_part(n, monkeypatch):
    # _match_oriented makes, matches and sums the parts a chunk at a time; it must give
    # exactly what matching each whole part (iter_oriented_parts) and summing gives.
    from tghop import oriented as O, refine as R

    rng = np.random.default_rng(n)
    band = rng.standard_normal((2, 45, 38)).astype(np.float32)
    q = np.sort(rng.standard_normal((max(n, 1), 2, 33)), axis=-1)
    levels = np.linspace(0.0, 1.0, 33)
    total = None
    for j, part in enumerate(R.iter_oriented_parts(band.copy(), n, axes=(1, 2))):
        for k in range(2):
            R.match_quantiles(part[k], q[j, k], levels, out=part[k])
        total = part if total is None else total + part
    np.testing.assert_array_equal(O.match_oriented(band.copy(), q, levels), total)  # one chunk: part by part
    monkeypatch.setattr(O, "_PARTS_CHUNK", 256)  # several chunks and a short last one
    got = band.copy()
    assert O._match_oriented(got, q, levels) is got
    np.testing.assert_array_equal(got, total)
    np.testing.assert_array_equal(O.match_oriented(band.copy(), q, levels), total)
    # The refinement takes that path for bands above one chunk: the same image either way.
    img = np.clip(rng.random((50, 60, 3)) * 0.5 + 0.2, 0, 1)
    st = BandStatistics(n_orientations=n).fit(np.clip(rng.random((64, 64, 3)), 0, 1))
    chunked = refine(img, st, n_iter=2)
    monkeypatch.setattr(O, "_PARTS_CHUNK", 1 << 30)
    np.testing.assert_array_equal(refine(img, st, n_iter=2), chunked)


def test_bands_finer_than_first_level_keep_their_values(cells):
    # first_level=1 leaves the finest band as it is: only the coarser bands move, so the
    # result differs from matching every band, and skipping every band leaves only the
    # pixel matching (what statistics without bands do).
    st = BandStatistics().fit(cells)
    img = _blurred(cells) * 0.8 + 0.1
    every = refine(img, st, n_iter=1)
    coarse_only = refine(img, st, n_iter=1, first_level=1)
    assert not np.allclose(every, coarse_only, atol=1e-3)
    fine = lambda x: x - _blurred(x, 1.0)  # noqa: E731 (high-pass: the finest detail)
    assert np.abs(fine(coarse_only) - fine(img)).mean() < np.abs(fine(every) - fine(img)).mean()
    pixels_only = BandStatistics(n_levels=0).fit(cells)
    np.testing.assert_allclose(refine(img, st, n_iter=2, first_level=4), refine(img, pixels_only, n_iter=2), atol=1e-5)
    for bad in (-1, 1.5, True):
        with pytest.raises(TGHopError, match="first_level"):
            refine(img, st, first_level=bad)


def test_refine_takes_float32_without_changing_the_result(cells):
    st = BandStatistics().fit(cells)
    img = (_blurred(cells) * 0.8 + 0.1).astype(np.float32)
    out = refine(img, st)
    assert out.dtype == np.float64
    assert np.array_equal(out, refine(img.astype(np.float64), st))
    assert refine(img, st, n_iter=0).dtype == np.float64
    # A float32 result: the same numbers (they are computed in float32).
    narrow = refine(img, st, dtype=np.float32)
    assert narrow.dtype == np.float32
    assert np.array_equal(narrow, out)
    assert refine(img, st, n_iter=0, dtype=np.float32).dtype == np.float32
    with pytest.raises(TGHopError, match="dtype"):
        refine(img, st, dtype=np.uint8)


@pytest.mark.parametrize("path", ["stacked", "threads", "one by one"])
def test_refine_reports_progress_per_round_or_channel(cells, monkeypatch, path):
    # Small images: all channels at once, after each round; large ones: a thread per
    # channel, after each round of each channel (from the channels' threads); too large for
    # several at once: after each round of each channel. The same numbers on every path.
    from tghop import refine as refine_module

    st = BandStatistics().fit(cells)
    img = _blurred(cells) * 0.8 + 0.1
    monkeypatch.setattr(refine_module, "_THREADED_PIXELS", 1 << 62 if path == "stacked" else 1)
    if path == "one by one":
        monkeypatch.setattr(refine_module, "_REFINE_MEMORY", 1)
    monkeypatch.setattr(refine_module, "usable_cores", lambda: 2)
    calls = []
    out = refine(img, st, n_iter=2, progress=lambda *a: calls.append(a))
    assert {c[0] for c in calls} == {"refine"} and {c[2] for c in calls} == {6}  # 3 channels x 2 rounds
    done = [c[1] for c in calls]
    assert done[0] == 0 and done[-1] == 6 and done == sorted(done)
    assert len(done) == {"stacked": 3, "threads": 7, "one by one": 7}[path]  # start, then each step
    monkeypatch.undo()
    assert np.array_equal(out, refine(img, st, n_iter=2))


@pytest.mark.parametrize("mode", ["wrap", "reflect"])
def test_pad_is_numpys_wrap_or_symmetric_padding(mode):
    from tghop.pyramid import _pad

    rng = np.random.default_rng(0)
    for shape in [(1, 5), (2, 3), (3, 7), (4, 4, 3), (7, 2)]:  # also widths beyond the axis
        x = rng.random(shape).astype(np.float32)
        for axis in range(x.ndim):
            for width in (1, 2, 3):
                pad = [(0, 0)] * x.ndim
                pad[axis] = (width, width)
                expected = np.pad(x, pad, mode="wrap" if mode == "wrap" else "symmetric")
                out = _pad(x, axis, width, mode)
                assert out.dtype == x.dtype and np.array_equal(out, expected), (shape, axis, width)


def test_prepare_tabulates_what_refine_needs(cells):
    # synthesize prepares the refinement while the coarse guide is made: afterwards the
    # refinement finds every table it needs, and a bad size is refused before any work.
    from tghop import oriented, refine as refine_module

    st = BandStatistics().fit(cells)
    img = _blurred(cells)[:70, :90] * 0.8 + 0.1
    oriented.double_angle.cache_clear()
    refine_module.prepare(img.shape[:2], st)
    made = oriented.double_angle.cache_info().misses
    assert made == st.band_quantiles_.shape[0]  # one per band size
    refine(img, st, n_iter=1)
    assert oriented.double_angle.cache_info().misses == made
    with pytest.raises(TGHopError, match="size must be positive"):
        refine_module.prepare((0, 5), st)


def test_the_oriented_windows_kept_are_bounded_in_bytes():
    # 0.58 kept the last 16 band shapes whatever their size (an lru_cache of 16): 16 first bands of the largest
    # images a server makes (a tileable strip of 67 Mpx refined whole, 268 MB each) would have held 4.3 GB for
    # good. Now the tables kept take at most MAX_WINDOW_BYTES, the least recently used dropped first.
    import gc
    import weakref

    from tghop import oriented

    oriented.double_angle.cache_clear()
    f32 = np.dtype(np.float32)
    made = []
    try:
        for extra in range(6):  # six bands of 2048 x (2048 + 2 * extra): about 16.8 MB each, 100 MB in all
            made += [weakref.ref(m) for m in oriented.double_angle(2048, 2048 + 2 * extra, f32)]
        gc.collect()
        alive = sum(ref().nbytes for ref in made if ref() is not None)
        assert 3 * 16 * 1024**2 < alive <= 64 * 1024**2  # 0.58: all six, 100 MB
        assert oriented.MAX_WINDOW_BYTES == 64 * 1024**2
        assert oriented.double_angle.cache_info().nbytes == alive
        # The most recently used stay: the last band's tables are found again, the first's made again.
        last = oriented.double_angle(2048, 2058, f32)
        assert oriented.double_angle(2048, 2058, f32) is last
        misses = oriented.double_angle.cache_info().misses
        first = oriented.double_angle(2048, 2048, f32)
        assert oriented.double_angle.cache_info().misses == misses + 1
        assert np.array_equal(first[0], oriented._double_angle(2048, 2048, f32)[0])
    finally:
        oriented.double_angle.cache_clear()


def test_oriented_windows_over_the_bound_are_made_for_their_call_alone(monkeypatch):
    # A band whose tables alone take more than the bound is refined as before, its tables made at each call
    # outside a refinement's rounds (windows_held: below).
    from tghop import oriented

    oriented.double_angle.cache_clear()
    monkeypatch.setattr(oriented, "MAX_WINDOW_BYTES", 100_000)
    band = np.random.default_rng(0).random((3, 256, 256)).astype(np.float32)
    parts = oriented.oriented_parts(band, 4, axes=(1, 2))
    small = oriented.double_angle(64, 64, np.dtype(np.float32))
    again = oriented.oriented_parts(band, 4, axes=(1, 2))
    info = oriented.double_angle.cache_info()
    assert (info.kept, info.nbytes) == (1, small[0].nbytes * 2) and info.misses == 3
    assert all(np.array_equal(a, b) for a, b in zip(parts, again))
    oriented.double_angle.cache_clear()


@pytest.mark.parametrize("where", ["refine", "refine_hole", "refine channel by channel", "refine in threads"])
def test_a_refinement_makes_each_bands_oriented_windows_once_whatever_their_size(cells, monkeypatch, where):
    # A band's tables over the bound (a large picture's fill, a tileable strip refined whole) are not kept between
    # calls, but a refinement's rounds (and its channels) use them again: each band's are made once per refinement,
    # not once a round, and they are gone when it ends. The images are the same as with every table kept.
    from tghop import oriented
    from tghop.hole_refine import refine_hole

    st = BandStatistics().fit(cells)
    img = _blurred(cells)[:70, :90] * 0.8 + 0.1
    if where.startswith("refine "):
        img = np.tile(img, (8, 6, 1))[:520, :520]  # large enough for its channels one at a time, or on threads
    hole = np.zeros(img.shape[:2], bool)
    hole[20:50, 30:60] = True

    def run():
        oriented.double_angle.cache_clear()
        if where == "refine_hole":
            out = refine_hole(img, hole, st, n_iter=3)
        else:
            out = refine(img, st, n_iter=3, threads={"refine": None, "refine channel by channel": 1}.get(where, 2))
        return out, oriented.double_angle.cache_info()

    kept, kept_info = run()
    monkeypatch.setattr(oriented, "MAX_WINDOW_BYTES", 100)  # every band's tables over it
    made, info = run()
    bands = st.band_quantiles_.shape[0]
    if where == "refine in threads":  # two channels' threads may both make a band's tables first (as 0.58 did)
        assert bands <= info.misses <= 2 * bands and bands <= kept_info.misses <= 2 * bands
    else:  # without windows_held: one a band, round and channel
        assert info.misses == kept_info.misses == bands
    assert (info.kept, info.nbytes) == (0, 0) and np.array_equal(made, kept)
    oriented.double_angle.cache_clear()


@pytest.mark.parametrize("shape, axes", [((64, 70), (0, 1)), ((3, 33, 40), (1, 2)), ((2, 17, 5), (1, 2))])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_pocketfft_without_scipy_fft_gives_scipy_fft_numbers(shape, axes, dtype, rng):
    # Large bands are transformed by SciPy's compiled pocketfft module loaded alone (no
    # 0.2-0.3 s import of scipy.fft): bit for bit what scipy.fft gives.
    import scipy.fft

    fft = F.PocketFFT(F.load_pocketfft())
    x = rng.standard_normal(shape).astype(dtype)
    spectrum = fft.rfft2(x, axes=axes, workers=2)
    np.testing.assert_array_equal(spectrum, scipy.fft.rfft2(x, axes=axes))
    half = fft.ifft(spectrum.copy(), axis=axes[0], overwrite_x=True)
    np.testing.assert_array_equal(half, scipy.fft.ifft(spectrum, axis=axes[0]))
    back = fft.irfft(half.copy(), n=shape[axes[1]], axis=axes[1])
    np.testing.assert_array_equal(back, scipy.fft.irfft(half, n=shape[axes[1]], axis=axes[1]))
    assert back.dtype == dtype and np.abs(back - x).max() < 1e-4


def test_large_images_are_refined_without_importing_scipy_fft():
    # In a new process: the refinement of a 512x512 image loads the compiled module only,
    # and a later `import scipy.fft` takes that very module.
    import subprocess

    code = (
        "import sys, numpy as np\n"
        "from tghop.refine import BandStatistics, refine\n"
        "st = BandStatistics().fit(np.random.default_rng(1).random((96, 96, 3)))\n"
        "out = refine(np.random.default_rng(0).random((512, 512, 3)) * 0.5 + 0.2, st, n_iter=1)\n"
        "print('SCIPY_FFT', 'scipy.fft' in sys.modules, 'scipy' in sys.modules)\n"
        "import scipy.fft\n"
        "print('SAME', scipy.fft._pocketfft.basic.pfft is sys.modules['scipy.fft._pocketfft.pypocketfft'])\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "SCIPY_FFT False False" in p.stdout and "SAME True" in p.stdout, p.stdout


def test_refinement_falls_back_to_scipy_fft(cells, monkeypatch):
    # If SciPy's files are laid out otherwise, scipy.fft itself is used: the same image as
    # through the compiled module alone.
    import scipy.fft

    from tghop import refine as R

    st = BandStatistics().fit(cells)
    img = _blurred(cells) * 0.8 + 0.1
    monkeypatch.setattr(F, "SCIPY_FFT_PIXELS", 1)
    real_load = F.load_pocketfft

    def missing():
        raise StopIteration("no such file")

    try:
        monkeypatch.delitem(sys.modules, "scipy.fft")  # as if not imported yet (put back after the test)
        monkeypatch.setattr(F, "load_pocketfft", missing)
        F.scipy_fft.cache_clear()
        fallback = F.scipy_fft()
        assert fallback is sys.modules["scipy.fft"] and fallback.rfft2 is scipy.fft.rfft2  # imported (again)
        through_scipy = R.refine(img, st, n_iter=2)
        monkeypatch.setattr(F, "load_pocketfft", real_load)
        monkeypatch.delitem(sys.modules, "scipy.fft")
        F.scipy_fft.cache_clear()
        assert isinstance(F.scipy_fft(), F.PocketFFT)
        np.testing.assert_array_equal(R.refine(img, st, n_iter=2), through_scipy)
    finally:
        F.scipy_fft.cache_clear()


def test_refine_threads_do_not_change_the_numbers(small_model):
    img = np.random.default_rng(7).random((520, 530, 3)).astype(np.float32)  # channels in threads
    np.testing.assert_array_equal(refine(img, small_model.bands_, n_iter=2, dtype=np.float32),
                                  refine(img, small_model.bands_, n_iter=2, dtype=np.float32, threads=1))


def test_over_relaxed_rounds_move_twice_as_far_and_the_last_round_is_plain(cells):
    from tghop import refine as R

    st = BandStatistics().fit(cells)
    x = st.to_decorrelated(_blurred(cells) * 0.8 + 0.1)[..., 0].astype(np.float32)
    bq, pq = st.band_quantiles_[:, :, 0], st.pixel_quantiles_[0]

    def rounds(start, n, relaxation=1.0):
        return R._refine_channel(start.copy(), bq, pq, n_iter=n, mode="reflect", relaxation=relaxation)

    one = rounds(x, 1)
    np.testing.assert_array_equal(rounds(x, 1, relaxation=2.0), one)  # a single round is the last: plain
    moved = x + 2.0 * (one - x)  # round 1 over-relaxed, then a plain last round
    np.testing.assert_allclose(rounds(x, 2, relaxation=2.0), rounds(moved, 1), atol=1e-5)
    assert not np.allclose(rounds(x, 2, relaxation=2.0), rounds(x, 2), atol=1e-3)
    img = _blurred(cells) * 0.8 + 0.1
    assert not np.allclose(refine(img, st, n_iter=3), refine(img, st, n_iter=3, relaxation=1.0), atol=1e-3)
    for bad in (0, -1, 2.5, "2", None, True):
        with pytest.raises(TGHopError, match="relaxation"):
            refine(img, st, relaxation=bad)


# ------------------------------------------------------------------ estimator conventions and input checks
def test_band_statistics_is_a_scikit_learn_estimator(cells):
    from sklearn.base import clone

    from tghop._errors import NotFittedError

    st = BandStatistics(n_levels=2, n_quantiles=33)
    assert st.get_params() == {"n_levels": 2, "n_orientations": 4, "n_quantiles": 33}
    assert repr(st) == "BandStatistics(n_levels=2, n_quantiles=33)"
    copy = clone(st.set_params(n_orientations=0))
    assert copy is not st and copy.get_params() == st.get_params()
    for call in (lambda: st.to_decorrelated(cells), lambda: st.from_decorrelated(cells),
                 lambda: refine(cells, st, n_iter=1)):
        with pytest.raises(NotFittedError):
            call()


@pytest.mark.parametrize("n_quantiles", [0, 1, 2.5, "9", True])
def test_band_statistics_refuses_a_bad_n_quantiles_at_fit(cells, n_quantiles):
    with pytest.raises(TGHopError, match="n_quantiles must be an integer >= 2"):
        BandStatistics(n_quantiles=n_quantiles).fit(cells)


def _bad_images(img):
    nan = img.copy()
    nan[3, 4, 1] = np.nan
    inf = img.copy()
    inf[0, 0, 0] = np.inf
    return [(img * 255, r"values must lie in \[0, 1\]"), (nan, "NaN"), (inf, "NaN or infinite"),
            (img[..., 0], r"\(H, W, C\)"), (img[None], r"\(H, W, C\)"), (img.astype(object), r"\(H, W, C\)")]


def test_refine_and_band_statistics_check_their_images(cells):
    from tghop._errors import InvalidImageError

    st = BandStatistics(n_levels=2, n_quantiles=33).fit(cells)
    for bad, message in _bad_images(cells):
        with pytest.raises(InvalidImageError, match="^refine: image.*" + message):
            refine(bad, st, n_iter=1)
        with pytest.raises(InvalidImageError, match="^BandStatistics.fit: exemplar.*" + message):
            BandStatistics(n_levels=2).fit(bad)
    with pytest.raises(InvalidImageError, match="BandStatistics.fit: exemplar is empty"):
        BandStatistics().fit(np.zeros((0, 0, 3)))
    with pytest.raises(TGHopError, match="refine: image of shape .* 3 channels"):
        refine(cells[..., :1], st, n_iter=1)
    # Values past the range's ends within check_image's tolerance are accepted; uint8 is scaled.
    edge = cells.copy()
    edge[0, 0, 0] = 1 + 1e-7
    assert refine(edge, st, n_iter=1).shape == cells.shape
    u8 = np.round(cells * 255).astype(np.uint8)
    assert np.array_equal(refine(u8, st, n_iter=1), refine(u8 / 255.0, st, n_iter=1))


def test_the_first_level_docstring_names_an_existing_api():
    import tghop.synthesis

    assert "tghop.synthesis.CoarseLayout.guide" in refine.__doc__
    assert hasattr(tghop.synthesis.CoarseLayout, "guide")


def test_too_small_or_empty_inputs_are_one_line_errors():
    # A 1x1 exemplar reached NumPy's LinAlgError (a covariance of one pixel), an empty image an
    # IndexError, and NaN quantiles made a NaN image without a word.
    from tghop.colour import channel_quantiles, match_histograms

    with pytest.raises(TGHopError, match=r"^BandStatistics.fit: the exemplar has 1 pixel; give at least 2$"):
        BandStatistics().fit(np.full((1, 1, 3), 0.5))
    BandStatistics().fit(np.random.default_rng(0).random((2, 2, 3)))
    with pytest.raises(TGHopError, match=r"^channel_quantiles: the image is empty \(shape \(0, 0, 3\)\)"):
        channel_quantiles(np.zeros((0, 0, 3)))
    quantiles = np.full((3, 257), np.nan)
    with pytest.raises(TGHopError, match=r"^match_histograms: quantiles must be finite numbers"):
        match_histograms(np.full((4, 4, 3), 0.5), quantiles)
