"""The patch refinement (tghop.patch_refine): statistics, sliced transport, wiring, model files."""

import json

import numpy as np
import pytest

from tghop import data, settings
from tghop._errors import TGHopError
from tghop import patch_refine as pr
from tghop.modelfile import WITHOUT_MATERIAL_PATCHES, ModelFileError, load_model, save_model
from tghop.synthesis import TGHop

from conftest import SMALL


@pytest.fixture(scope="module")
def patch_model():
    return TGHop(**SMALL, patch_levels=3).fit(data.cells(96, rng=3))


@pytest.fixture(scope="module")
def plain_model():
    """:func:`patch_model` fitted without patch statistics (``patch_levels=0``), once for the tests that read it."""
    return TGHop(**SMALL, patch_levels=0).fit(data.cells(96, rng=3))


def _rows(img):
    """Every 7x7 patch of an (H, W, C) image as rows (n, C * 49)."""
    return pr._columns(img.transpose(2, 0, 1), pr.PATCH).T


def _patch_swd(img, stats):
    """Mean distance of the image's projection quantiles to the stored ones (full resolution,
    every patch), per direction set."""
    x = _rows(np.asarray(img, np.float32))
    out = []
    for j in range(pr.SETS):
        proj = x @ stats.directions_[0, j].T
        q = np.quantile(proj, stats.levels_.astype(np.float64), axis=0).T
        out.append(np.abs(q - stats.quantiles_[0, j]).mean())
    return np.array(out)


def test_statistics_shapes_and_directions(patch_model, plain_model):
    st = patch_model.patches_
    d = pr.PATCH * pr.PATCH * 3
    assert st.directions_.shape == (3, pr.SETS, pr.DIRECTIONS, d)
    assert st.quantiles_.shape == (3, pr.SETS, pr.DIRECTIONS, pr.QUANTILES)
    assert np.allclose(np.linalg.norm(st.directions_, axis=-1), 1, atol=1e-5)
    assert (np.diff(st.quantiles_, axis=-1) >= 0).all()
    # The quantiles are the exemplar's: a direction's quantiles against np.quantile of the projections.
    ex = data.cells(96, rng=3).astype(np.float32)
    x = _rows(ex)
    proj = x @ st.directions_[0, 1, 5]
    assert np.allclose(st.quantiles_[0, 1, 5], np.quantile(proj, pr.quantile_levels()), atol=1e-5)
    assert np.array_equal(st.levels_, pr.quantile_levels().astype(np.float32))
    # Stored unless switched off: then no arrays, no parameters.
    plain = plain_model
    assert plain.patches_ is None and not any(k.startswith("patch.") for k in plain._to_arrays())
    assert plain.n_parameters()["patch refinement (ours)"]["stored"] == 0
    assert (patch_model.n_parameters()["patch refinement (ours)"]["stored"]
            == 3 * pr.SETS * pr.DIRECTIONS * (d + pr.QUANTILES) + pr.QUANTILES)


def test_statistics_describe_the_whole_exemplar_not_its_centre():
    """A photograph's centre is often unlike the rest (a light source, a vignette): the
    quantiles come from the whole exemplar. Here two thirds of it are bright, its centre 600
    columns dark; a constant patch of value a projects to a * sum(direction), so the median
    projection is the bright one's (0.1's, when only a centre crop was measured)."""
    rng = np.random.default_rng(0)
    img = np.full((40, 1800, 3), 0.9, np.float32)
    img[:, 600:1200] = 0.1
    img += rng.normal(0, 0.002, img.shape).astype(np.float32)
    for exemplar in (img, np.round(img * 255).astype(np.uint8)):
        st = pr.fit_patch_statistics(1, exemplar)
        median = st.quantiles_[0, ..., pr.QUANTILES // 2]
        bright = 0.9 * st.directions_[0].sum(axis=-1)
        assert np.abs(median - bright).max() < 0.05 * np.abs(bright).max()
    # With a mask, the statistics are those of the rest: only the dark centre left.
    hole = np.zeros(img.shape[:2], bool)
    hole[:, :600] = hole[:, 1200:] = True
    st = pr.fit_patch_statistics(1, img, exclude=hole)
    dark = 0.1 * st.directions_[0].sum(axis=-1)
    assert np.abs(st.quantiles_[0, ..., pr.QUANTILES // 2] - dark).max() < 0.05 * np.abs(dark).max()


def test_fit_measures_large_exemplars_in_parts_that_cover_them():
    """Parts of at most _FIT_SIDE a side, one at a time (bounded memory): they tile the exemplar
    up to _FIT_GRID of them a side, and beyond that spread from one end to the other."""
    def cover(shape):
        seen = np.zeros(shape, int)
        for ys, xs in pr._parts(shape):
            assert ys.stop - ys.start <= pr._FIT_SIDE and xs.stop - xs.start <= pr._FIT_SIDE
            seen[ys, xs] += 1
        return seen

    assert pr._parts((512, 700)) == [(slice(0, 512), slice(0, 700))]  # small exemplars: whole, as before
    assert (cover((1200, 1600)) == 1).all() and len(pr._parts((1200, 1600))) == 4
    assert (cover((3072, 1025)) == 1).all() and len(pr._parts((3072, 1025))) == 6
    far = pr._parts((5000, 300))
    assert [p[0].start for p in far] == [0, 1988, 3976] and far[-1][0].stop == 5000
    # The parts' patches together: a two-part exemplar's statistics are those of its whole (the
    # same patches but at the seam, a subset of them), far closer than either half's.
    rng = np.random.default_rng(1)
    img = np.concatenate([rng.random((48, 700, 3)) * 0.5, 0.5 + rng.random((48, 700, 3)) * 0.5], axis=1)
    both = pr.PatchStatistics(1).fit(img).quantiles_
    half = pr.PatchStatistics(1).fit(img[:, :700]).quantiles_
    whole = pr._projection_quantiles(pr.PatchStatistics(1).fit(img).directions_[0],
                                     pr._fit_patches(img.astype(np.float32), None, 1 << 20), pr.quantile_levels())
    assert np.abs(both[0] - whole).mean() < 0.1 * np.abs(half[0] - whole).mean()


def test_quantiles_never_decrease_on_an_exemplar_of_tied_patches(tmp_path):
    """Flat ground makes many patches project to the same value; crowded levels read
    between tied or close order statistics must not step back by a float32 rounding, or the
    saved model is refused as corrupt."""
    rng = np.random.default_rng(0)
    img = np.full((96, 96, 3), 0.3, np.float32)
    img[:, 48:] = rng.random((96, 48, 3))
    img[:, :48] += np.float32(0.37) * (rng.random((96, 48, 1)) < 0.1)
    st = pr.PatchStatistics(2).fit(img)
    assert (np.diff(st.quantiles_, axis=-1) >= 0).all()
    model = TGHop(**SMALL, patch_levels=2).fit(img)
    save_model(model, tmp_path / "flat.npz")
    assert load_model(tmp_path / "flat.npz").synthesize((48, 48), rng=1).shape == (48, 48, 3)


def test_projection_quantiles_follow_numpys_linear_rule():
    """The stored quantiles, made one direction set at a time, are np.quantile's (linear
    interpolation between order statistics) of every patch's projection on each direction."""
    rng = np.random.default_rng(3)
    x = rng.gamma(2.0, 1.0, (500, 12)).astype(np.float32)
    dirs = rng.standard_normal((3, 4, 12)).astype(np.float32)
    qlev = pr.quantile_levels(17)
    got = pr._projection_quantiles(dirs, x, qlev)
    assert got.shape == (3, 4, 17) and got.dtype == np.float32
    proj = np.einsum("skd,nd->skn", dirs.astype(np.float64), x.astype(np.float64))
    np.testing.assert_allclose(got, np.moveaxis(np.quantile(proj, qlev, axis=-1), 0, -1), atol=2e-5)


def test_quantile_levels_crowd_towards_the_tails():
    """The stored levels run from 0 to 1, symmetric, increasing, and much finer at the ends
    than in the middle: a projection's tails (its strongest edges) get quantiles of their own."""
    q = pr.quantile_levels()
    assert q.shape == (pr.QUANTILES,) and q[0] == 0 and q[-1] == 1
    assert np.allclose(q + q[::-1], 1) and (np.diff(q) > 0).all()
    step = np.diff(q)
    assert step[0] < 0.05 * step[len(step) // 2] and step[0] < 0.1 / (pr.QUANTILES - 1)


def test_quantiles_are_read_at_even_ranks_between_their_levels():
    """_on_ranks reads stored quantiles at evenly spaced levels by linear interpolation in
    the level: at a stored level it gives that quantile, between two the line through them;
    evenly spaced levels give back their own quantiles at the ranks they share."""
    rng = np.random.default_rng(1)
    levels = pr.quantile_levels(33)
    quantiles = np.sort(rng.gamma(2.0, 1.0, (2, 3, 33)), axis=-1).astype(np.float32)
    got = pr._on_ranks(quantiles, levels, n=1025)
    assert got.shape == (2, 3, 1025) and got.dtype == np.float32
    assert got.flags.c_contiguous  # each step's rank table reads it flat: no copy per step
    grid = np.linspace(0, 1, 1025)
    want = np.stack([np.interp(grid, levels, row) for row in quantiles.reshape(6, 33)]).reshape(2, 3, 1025)
    assert np.allclose(got, want, atol=1e-5)
    assert (np.diff(got, axis=-1) >= 0).all() and np.array_equal(got[..., [0, -1]], quantiles[..., [0, -1]])
    even = np.linspace(0, 1, 33)
    assert np.allclose(pr._on_ranks(quantiles, even, n=129)[..., ::4], quantiles, atol=1e-6)


def test_whitened_directions_see_detail_not_the_patch_mean():
    """With whitening the exemplar's projections depend less on a patch's mean (which
    carries most of its variance); the quantiles stay those of the projections; 0 keeps the
    directions uniform, exactly as drawn before the setting existed."""
    ex = data.cells(96, rng=3).astype(np.float32)
    x = _rows(ex)
    mean = x.mean(axis=1)
    corr = {}
    for w in (0.0, 0.25, 0.5):
        st = pr.PatchStatistics(2, w).fit(ex)
        d = st.directions_[0].reshape(-1, x.shape[1])
        assert np.allclose(np.linalg.norm(d, axis=1), 1, atol=1e-5)
        y = x @ d.T
        corr[w] = np.mean([abs(np.corrcoef(y[:, k], mean)[0, 1]) for k in range(len(d))])
        assert np.allclose(st.quantiles_[0, 2, 7], np.quantile(y[:, 2 * pr.DIRECTIONS + 7],
                                                                pr.quantile_levels()), atol=1e-5)
    assert corr[0.5] < 0.5 * corr[0.25] < 0.5 * corr[0.0]
    drawn = np.random.default_rng(0).standard_normal((2, pr.SETS, pr.DIRECTIONS, x.shape[1])).astype(np.float32)
    drawn /= np.linalg.norm(drawn, axis=-1, keepdims=True)
    assert np.array_equal(pr.PatchStatistics(2, 0.0).fit(ex).directions_, drawn)
    # A flat exemplar (every eigenvalue 0) still gets finite unit directions.
    flat = pr.PatchStatistics(1, 0.5).fit(np.full((40, 40, 3), 0.3, np.float32))
    assert np.isfinite(flat.directions_).all() and np.allclose(np.linalg.norm(flat.directions_, axis=-1), 1)
    for bad in (-0.1, 1.5, True, "x"):
        with pytest.raises(TGHopError, match="^PatchStatistics: whitening"):
            pr.PatchStatistics(1, bad).fit(ex)
    with pytest.raises(TGHopError, match="patch_whitening"):
        TGHop(**SMALL, patch_whitening=2.0).fit(ex)


def test_refinement_moves_patch_statistics_towards_the_exemplar(patch_model):
    st = patch_model.patches_
    img = patch_model.synthesize((80, 72), rng=2, patch_refine=0).astype(np.float32)
    before = _patch_swd(img, st)
    out = pr.patch_refine(img, st, n_steps=20)
    assert out.shape == img.shape and out.dtype == np.float32
    assert out.min() >= 0 and out.max() <= 1
    after = _patch_swd(out, st)
    assert after.mean() < 0.8 * before.mean()
    # Small steps: it refines the image, it does not replace it.
    assert 0 < np.abs(out - img).mean() < 0.05
    assert np.array_equal(pr.patch_refine(img, st, n_steps=0), img)
    with pytest.raises(TGHopError):
        pr.patch_refine(img[..., :1], st, n_steps=1)
    with pytest.raises(TGHopError, match="integer >= 0"):
        pr.patch_refine(img, st, n_steps=-1)


def test_rank_tables_give_each_projection_the_target_at_its_rank():
    """Through the table, each projection gets the stored quantile at its rank, for a full
    level's many patches (_BINS entries) and a coarse level's few (fewer entries: _n_bins)."""
    rng = np.random.default_rng(0)
    target = np.sort(rng.gamma(2.0, 1.0, (3, 5000)), axis=1)
    target = np.quantile(target, np.linspace(0, 1, pr.QUANTILES), axis=1).T.astype(np.float32)  # (3, Q)
    for n in (841, 3721, 15625):
        y = rng.normal(0, 1, (3, n)).astype(np.float32)
        bins = pr._n_bins(n)
        assert pr._MIN_BINS <= bins <= pr._BINS and (bins == pr._BINS) == (n >= pr._PER_BIN * pr._BINS)
        lo, scale = pr._grid([y], bins)
        idx = pr._bins(y, lo, scale, bins)
        table = pr._table([idx], target, bins)
        got = np.take(table, idx)
        # The same grid and table from the projections in pieces (a step's bands of rows).
        parts = np.array_split(y, 3, axis=1)
        lo3, scale3 = pr._grid(parts, bins)
        assert np.array_equal(lo3, lo) and np.array_equal(scale3, scale)
        assert np.array_equal(pr._table([pr._bins(q, lo, scale, bins) for q in parts], target, bins), table)
        ranks = np.argsort(np.argsort(y, axis=1), axis=1) / (n - 1)
        want = np.stack([np.interp(ranks[k], np.linspace(0, 1, pr.QUANTILES), target[k]) for k in range(3)])
        spread = target[:, -1] - target[:, 0]
        err = np.abs(got - want) / spread[:, None]
        assert np.median(err) < 0.002 and np.quantile(err, 0.99) < 0.02, (n, np.median(err), np.quantile(err, 0.99))


def test_rank_tables_are_exactly_the_plain_formula():
    """The table's entries are, bit for bit, the plain formula's: the mid-rank of each entry
    in float64, scaled to the quantiles' positions, and the line between the two quantiles
    around it in float64, rounded to float32 once (the images' bytes depend on it; the table
    is made in place, from the mid-rank's double)."""
    def plain(idxs, target, bins):
        k, n = target.shape[0], sum(idx.shape[1] for idx in idxs)
        counts = sum(np.bincount(idx.ravel(), minlength=k * bins) for idx in idxs).reshape(k, bins)
        mid = (np.cumsum(counts, axis=1) - 0.5 * (counts + 1)) * ((target.shape[1] - 1) / max(n - 1, 1))
        j = np.clip(mid.astype(np.int64), 0, target.shape[1] - 2)
        frac = mid - j
        rows = np.arange(k)[:, None]
        return (target[rows, j] * (1 - frac) + target[rows, j + 1] * frac).astype(np.float32).ravel()

    rng = np.random.default_rng(5)
    for k, n, q, parts in ((3, 1, 1025, 1), (4, 900, 129, 2), (32, 15876, 1025, 1), (7, 20000, 1025, 3)):
        y = (rng.standard_normal((k, n)) * rng.gamma(1.0, 1.0, (k, 1))).astype(np.float32)
        target = np.sort(rng.gamma(2.0, 1.0, (k, q)), axis=1).astype(np.float32)
        bins = pr._n_bins(n)
        pieces = np.array_split(y, parts, axis=1)
        lo, scale = pr._grid(pieces, bins)
        idxs = [pr._bins(p, lo, scale, bins) for p in pieces]
        got, want = pr._table(idxs, target, bins), plain(idxs, target, bins)
        assert got.dtype == np.float32 and np.array_equal(got.view(np.uint32), want.view(np.uint32)), (k, n, q)


def test_columns_at_every_stride_are_the_strided_windows():
    """_columns copies, at any stride, exactly the windows of the strided sliding view (where
    windows overlap by half or more it copies from each phase's plane): sides that leave a
    remainder, patches smaller and larger than the stride, a view that is not contiguous."""
    rng = np.random.default_rng(2)
    for c, p, stride, h, w in ((3, 5, 2, 256, 256), (3, 5, 3, 31, 44), (1, 5, 4, 9, 23), (2, 7, 5, 40, 17),
                               (3, 5, 5, 5, 5), (3, 3, 2, 3, 30), (2, 4, 3, 10, 11), (2, 7, 3, 29, 40)):
        img = rng.random((c, h + 3, w + 2)).astype(np.float32)[:, 1: h + 1, 2:]
        v = np.lib.stride_tricks.sliding_window_view(img, (p, p), axis=(1, 2))[:, ::stride, ::stride]
        want = v.transpose(0, 3, 4, 1, 2).reshape(c * p * p, -1)
        got = pr._columns(img, p, stride)
        assert got.flags.c_contiguous and np.array_equal(got, want), (c, p, stride, h, w)


def test_every_phase_of_the_shifted_grid_is_used():
    for stride in (1, 2, 3, 4):
        phases = pr._phases(stride)
        assert len(set(phases)) == stride * stride and all(0 <= a < stride and 0 <= b < stride for a, b in phases)
    # so that with stride 3, nine steps touch every pixel from every place in a patch: the
    # summed gradient magnitude of the interior is nowhere zero
    st = pr.fit_patch_statistics(1, data.cells(64, rng=1))
    img = data.cells(40, rng=2).astype(np.float32).transpose(2, 0, 1)  # channel-first
    hits = np.zeros(img.shape[1:])
    for oy, ox in pr._phases(3):
        hits += np.abs(pr._gradient(img, st.directions_[0, 0], st.quantiles_[0, 0], 3, (oy, ox))).sum(0) > 0
    assert (hits[6:-6, 6:-6] == 9).all()


def test_scatter_adds_each_patch_to_its_own_pixels():
    """The per-phase planes give the same sums as adding every patch offset to strided slices."""
    rng = np.random.default_rng(0)
    p = pr.PATCH
    for stride in range(1, p + 1):
        for h, w, top in ((30, 27, 0), (41, 33, 5), (p, p + 3, 0)):
            bh, bw = (h - top - p) // stride + 1, (w - p) // stride + 1
            gp = rng.standard_normal((2, p, p, bh, bw)).astype(np.float32)
            want = np.zeros((2, h, w), np.float32)
            for dy in range(p):
                for dx in range(p):
                    want[:, top + dy: top + dy + stride * (bh - 1) + 1: stride,
                         dx: dx + stride * (bw - 1) + 1: stride] += gp[:, dy, dx]
            got = np.zeros((2, h, w), np.float32)
            pr._scatter(got, gp, stride, top)
            assert np.array_equal(got, want), (stride, h, w, top)


def test_gradient_in_bands_matches_one_piece(monkeypatch):
    """Patches are cut out and sent back in bands of rows that share one rank table: with
    every patch in that table the result is the one-piece gradient (up to summation order);
    with the ranks of a quarter of them (large images), bands and one piece agree too."""
    st = pr.fit_patch_statistics(1, data.cells(64, rng=1))
    img = np.ascontiguousarray(data.cells(70, rng=2).astype(np.float32).transpose(2, 0, 1))
    d, t = st.directions_[0, 0], st.quantiles_[0, 0]
    whole = [pr._gradient(img, d, t, s, (1, 0)) for s in (1, 2, 3)]
    monkeypatch.setattr(pr, "_CHUNK", 200)
    for s, one in zip((1, 2, 3), whole):
        bands = pr._gradient(img, d, t, s, (1, 0))
        assert np.abs(one).max() > 1 and np.allclose(bands, one, atol=1e-4)
    monkeypatch.setattr(pr, "_RANK_PATCHES", 1000)  # 4,096 patches at stride 1: ranks from every 2nd each way
    ranked = pr._gradient(img, d, t, 1, (1, 0))
    monkeypatch.setattr(pr, "_CHUNK", 1 << 20)
    assert np.allclose(ranked, pr._gradient(img, d, t, 1, (1, 0)), atol=1e-4)
    assert not np.allclose(ranked, whole[0], atol=1e-4)  # other ranks: this path was taken


def test_steps_are_adams_textbook_update():
    """The steps update the image in place through two buffers; the same steps written out as
    Adam's formulas (Kingma & Ba 2015), with the gradients of the same shifted grids, give the
    same image."""
    st = pr.fit_patch_statistics(1, data.cells(64, rng=1))
    img = data.cells(40, rng=2).astype(np.float32)
    dirs = st.directions_[0]
    target = pr._on_ranks(st.quantiles_[0], st.levels_.astype(np.float64))
    n, stride, lr, b1, b2, eps = 6, 2, 0.01, 0.9, 0.999, 1e-8
    got = pr._steps(img, dirs, target, n, False, stride, lr)
    x = np.ascontiguousarray(img.transpose(2, 0, 1))
    m, v = np.zeros_like(x), np.zeros_like(x)
    for t in range(n):
        g = pr._gradient(x, dirs[t % len(dirs)], target[t % len(dirs)], stride, pr._phases(stride)[t % stride**2])
        m = b1 * m + (1 - b1) * g
        v = b2 * v + (1 - b2) * g * g
        x = x - lr / (1 - b1 ** (t + 1)) * m / (np.sqrt(v / (1 - b2 ** (t + 1))) + eps)
    assert np.abs(got - img).max() > 0.02  # the steps moved it
    assert np.allclose(got, x.transpose(1, 2, 0), atol=1e-5)


def test_large_images_move_through_a_shifted_strided_grid(monkeypatch):
    """Above _STRIDE_PIXELS a step takes every second patch each way, the grid shifted from
    step to step: four steps move the image as a whole, not one phase of it."""
    st = pr.fit_patch_statistics(1, data.cells(64, rng=1))
    img = data.cells(60, rng=2).astype(np.float32)
    monkeypatch.setattr(pr, "_STRIDE_PIXELS", 1000)
    assert pr._stride(60 * 60) == 2
    moved = np.abs(pr.patch_refine(img, st, n_steps=4) - img).sum(-1)
    assert (moved[2:-2, 2:-2] > 0).all()


def test_patch_stride_thins_every_level_but_small_ones(patch_model, monkeypatch):
    """patch_stride 2 takes every second patch at every level of more than _DENSE_PIXELS pixels
    (the grid shifted each step: every pixel still moves); smaller levels take every patch."""
    st = patch_model.patches_
    img = patch_model.synthesize((64, 64), rng=2, patch_refine=0).astype(np.float32)
    seen = []
    real = pr._steps

    def spy(x, dirs, target, n_steps, tile, stride, lr):
        seen.append((x.shape[0], stride))
        return real(x, dirs, target, n_steps, tile, stride, lr)
    monkeypatch.setattr(pr, "_steps", spy)
    pr.patch_refine(img, st, n_steps=1, stride=2)
    assert seen == [(16, 1), (32, 1), (64, 1)]  # coarse to fine (a 64x64 image has three levels): all small
    seen.clear()
    pr.patch_refine(np.pad(img, ((0, 72), (0, 0), (0, 0)), mode="reflect"), st, n_steps=1, stride=2)
    assert seen == [(34, 1), (68, 1), (136, 2)]  # 136x64 pixels: over _DENSE_PIXELS
    monkeypatch.setattr(pr, "_DENSE_PIXELS", 0)
    seen.clear()
    two = pr.patch_refine(img, st, n_steps=4, stride=2)
    assert seen == [(16, 2), (32, 2), (64, 2)]
    assert (np.abs(two - img).sum(-1)[3:-3, 3:-3] > 0).all()
    one = pr.patch_refine(img, st, n_steps=4, stride=1)
    assert not np.array_equal(one, two) and np.array_equal(two, pr.patch_refine(img, st, n_steps=4, stride=2))
    for bad in (0, pr.PATCH + 1, 1.5, True):
        with pytest.raises(TGHopError, match="^stride must be"):
            pr.patch_refine(img, st, n_steps=1, stride=bad)
    monkeypatch.setattr(pr, "_steps", real)
    # (_DENSE_PIXELS still 0: the setting reaches every level of a 64x64 image)
    a = patch_model.synthesize((64, 64), rng=5, patch_refine=4)  # stride 2 by default
    assert np.array_equal(a, patch_model.synthesize((64, 64), rng=5, patch_refine=4, patch_stride=2))
    assert not np.array_equal(a, patch_model.synthesize((64, 64), rng=5, patch_refine=4, patch_stride=1))
    with pytest.raises(TGHopError, match="patch_stride"):
        patch_model.synthesize((64, 64), rng=5, patch_refine=4, patch_stride=9)


def _nyquist_excess(change):
    """Power of a change's 2-pixel patterns (the spectrum's middle rows and columns) against
    that of the rows and columns next to them."""
    f = np.abs(np.fft.fft2(change - change.mean(axis=(0, 1)), axes=(0, 1))) ** 2
    h, w = change.shape[0] // 2, change.shape[1] // 2
    return (f[h].mean() + f[:, w].mean()) / (0.5 * (f[h - 1].mean() + f[h + 1].mean() + f[:, w - 1].mean()
                                                      + f[:, w + 1].mean()))


def test_checker_of_the_strided_grid_is_taken_off_the_change():
    """A 2-pixel pattern of the change whose strength varies over the image goes (each of
    the three: rows, columns, both); a smooth change and sharp edges stay."""
    rng = np.random.default_rng(0)
    start = data.cells(64, rng=1).astype(np.float32)
    yy, xx = np.mgrid[:64, :64].astype(np.float32)
    envelope = (0.05 * (1 + np.sin(xx / 9) * np.cos(yy / 7)))[..., None] * np.ones(3, np.float32)
    smooth = (0.1 * np.sin((xx + yy) / 11))[..., None] * np.ones(3, np.float32)
    for sign in ((-1) ** yy, (-1) ** xx, (-1) ** (yy + xx)):
        out = pr._without_checker(start + smooth + envelope * sign[..., None], start, False)
        assert np.abs(out - (start + smooth)).max() < 0.2 * envelope.max()
        assert np.abs(out - (start + smooth)).mean() < 0.1 * envelope.mean()
    # A smooth change stays, up to its borders; a sharp step (one edge) keeps most of itself.
    assert np.abs(pr._without_checker(start + smooth, start, False) - start - smooth).max() < 0.002
    step = np.where(xx > 31.5, 0.3, 0.0).astype(np.float32)[..., None] * np.ones(3, np.float32)
    out = pr._without_checker(start + step, start, False)
    assert np.abs(out - start - step).max() < 0.1 * 0.3 and np.abs(out - start - step).mean() < 0.005
    # Periodic images of odd width: only the rows' pattern is looked at (a column pattern
    # of odd period would not wrap), and the result still wraps.
    noise = rng.normal(0, 0.01, (64, 63, 3)).astype(np.float32)
    out = pr._without_checker(noise, np.zeros_like(noise), True)
    cols = (-1) ** np.arange(63)
    assert np.allclose((out * cols[None, :, None]).mean(), (noise * cols[None, :, None]).mean(), atol=1e-6)


def test_stride_two_leaves_no_checker(patch_model, monkeypatch):
    """Refining at stride 2 leaves a 2-pixel pattern in the change; the default takes it off.
    Stride 1 leaves none, and its result is not touched."""
    # The checker's size differs from image to image (1.11-1.75 times over seeds 2-6 of this quilt on an AMD EPYC's
    # OpenBLAS, 1.19 on an image of 0.39's quilting with the guide's detail at 0.8): three images, their geometric mean.
    st = patch_model.patches_
    ratios = []
    for seed in (2, 3, 4):
        img = patch_model.synthesize((96, 96), rng=seed, patch_refine=0, detail=0.5).astype(np.float32)
        kept = pr.patch_refine(img, st, n_steps=12, stride=2)
        with monkeypatch.context() as m:
            m.setattr(pr, "_without_checker", lambda image, start, tile: image)
            left = pr.patch_refine(img, st, n_steps=12, stride=2)
        ratios.append(_nyquist_excess(left - img) / _nyquist_excess(kept - img))
    assert np.exp(np.log(ratios).mean()) > 1.2, ratios
    every_patch = pr.patch_refine(img, st, n_steps=12, stride=1)
    monkeypatch.setattr(pr, "_without_checker", lambda image, start, tile: image)
    assert np.array_equal(pr.patch_refine(img, st, n_steps=12, stride=1), every_patch)


def _period_excess(change, period):
    """Power of an (H, W, C) change at ``period`` pixels along rows and columns over that of
    the frequencies next to it."""
    g = (change - change.mean(axis=(0, 1))).mean(axis=2)
    s = (np.abs(np.fft.rfft(g, axis=1)) ** 2).mean(0) + (np.abs(np.fft.rfft(g, axis=0)) ** 2).mean(1)
    k = g.shape[1] // period
    return s[k] / np.r_[s[k - 3:k - 1], s[k + 2:k + 4]].mean()


def test_pattern_of_a_wider_stride_is_taken_off_the_change():
    """A pattern of period 4 (or 3) whose strength varies over the image goes; a smooth change
    and a sharp edge stay; a periodic image whose side is not a multiple of the stride is left
    as it is."""
    start = data.cells(96, rng=1).astype(np.float32)
    yy, xx = np.mgrid[:96, :96].astype(np.float32)
    envelope = (0.05 * (1 + np.sin(xx / 9) * np.cos(yy / 7)))[..., None] * np.ones(3, np.float32)
    smooth = (0.1 * np.sin((xx + yy) / 13))[..., None] * np.ones(3, np.float32)
    for step in (3, 4):
        for pattern in (np.cos(2 * np.pi * yy / step), np.cos(2 * np.pi * xx / step), (xx % step == 1) - 1 / step):
            out = pr._without_grid(start + smooth + envelope * pattern[..., None], start, step, False)
            # What is left is the pattern's change in strength within the smoothing (6 px at 4).
            assert np.abs(out - (start + smooth)).mean() < 0.3 * np.abs(envelope * pattern[..., None]).mean()
    assert np.abs(pr._without_grid(start + smooth, start, 4, False) - start - smooth).max() < 0.005
    edge = np.where(xx > 47.5, 0.3, 0.0).astype(np.float32)[..., None] * np.ones(3, np.float32)
    out = pr._without_grid(start + edge, start, 4, False)
    assert np.abs(out - start - edge).max() < 0.15 * 0.3 and np.abs(out - start - edge).mean() < 0.005
    odd = start[:, :94] + 0.01
    assert pr._without_grid(odd, start[:, :94], 4, True) is odd


def test_stride_four_leaves_no_grid(patch_model, monkeypatch):
    """Refining at stride 4 leaves a pattern of period 4 in the change; the default takes it off."""
    img = patch_model.synthesize((128, 128), rng=2, patch_refine=0, detail=0.5).astype(np.float32)
    st = patch_model.patches_
    kept = pr.patch_refine(img, st, n_steps=12, stride=4)
    monkeypatch.setattr(pr, "_without_grid", lambda image, start, step, tile: image)
    left = pr.patch_refine(img, st, n_steps=12, stride=4)
    assert _period_excess(left - img, 4) > 3 * _period_excess(kept - img, 4)
    assert _period_excess(kept - img, 4) < 2


def test_coarser_levels_travel_a_bounded_distance(patch_model, monkeypatch):
    """The full level steps LEARNING_RATE; a coarser level COARSE_RATE, but at most
    COARSE_TRAVEL over all its steps (more steps take shorter ones)."""
    img = patch_model.synthesize((64, 64), rng=2, patch_refine=0).astype(np.float32)
    seen = []

    def spy(x, dirs, target, n_steps, tile, stride, lr):
        seen.append((x.shape[0], n_steps, lr))
        return x
    monkeypatch.setattr(pr, "_steps", spy)
    for n in (4, 45, 200):
        seen.clear()
        pr.patch_refine(img, patch_model.patches_, n_steps=n)
        *coarser, (full, _, lr_full) = seen  # a 64x64 image: levels 16, 32, 64
        assert len(coarser) == 2 and lr_full == pr.LEARNING_RATE
        for coarse, steps, lr_coarse in coarser:
            assert coarse < full and steps == n
            assert lr_coarse == min(pr.COARSE_RATE, pr.COARSE_TRAVEL / n) and n * lr_coarse <= pr.COARSE_TRAVEL + 1e-12
    assert pr.COARSE_TRAVEL / 200 < pr.COARSE_RATE == min(pr.COARSE_RATE, pr.COARSE_TRAVEL / 4)


def test_synthesis_is_deterministic_and_light_by_default(patch_model):
    a = patch_model.synthesize((64, 64), rng=5, patch_refine=5)
    b = patch_model.synthesize((64, 64), rng=5, patch_refine=5)
    off = patch_model.synthesize((64, 64), rng=5, patch_refine=0)
    # The default (None, "auto"): AUTO_STEPS on images of up to AUTO_PIXELS pixels, AUTO_LARGE_STEPS up
    # to AUTO_LARGE_PIXELS, then fewer in proportion to the pixels up to AUTO_LARGEST_PIXELS, none above.
    assert np.array_equal(patch_model.synthesize((64, 64), rng=5),
                          patch_model.synthesize((64, 64), rng=5, patch_refine=pr.AUTO_STEPS))
    assert pr.steps_for(None, (512, 512)) == pr.AUTO_STEPS == 52
    assert pr.steps_for(None, (512, 513)) == pr.steps_for(None, (1024, 1024)) == pr.AUTO_LARGE_STEPS == 24
    assert pr.steps_for(None, (1024, 1025)) == 24 and pr.steps_for(None, (1024, 1100)) == 22
    assert pr.steps_for(None, (1152, 1152)) == 19 and pr.steps_for(None, (800, 1920)) == 16
    assert pr.steps_for(None, (1280, 1280)) == 15 == pr.steps_for(None, (2560, 640))
    assert pr.steps_for(None, (1280, 1281)) == pr.steps_for(None, (2048, 2048)) == 0
    steps = [pr.steps_for(None, (1024, w)) for w in range(1025, 1601)]
    assert steps == sorted(steps, reverse=True) and min(steps) == 15  # never more for more pixels
    # The setting's help (settings stays free of NumPy, so it says the numbers itself).
    assert (f"auto (None in Python): {pr.AUTO_STEPS} on images of up to 512x512 pixels, {pr.AUTO_LARGE_STEPS} on "
            "images of up to 1024x1024, then fewer in proportion to the pixels "
            f"({pr.steps_for(None, (1280, 1280))} at 1280x1280), none") in settings.BY_NAME["patch_refine"].help
    assert pr.steps_for(3, (4096, 4096)) == 3 and pr.steps_for(0, (64, 64)) == 0
    assert a.shape == (64, 64, 3) and np.array_equal(a, b)
    assert not np.array_equal(a, off)
    assert (a >= 0).all() and (a <= 1).all()
    # Sides of 7 and 8 pixels: some phases of the shifted grid hold no patch.
    for size in ((7, 7), (7, 30), (8, 9)):
        small = patch_model.synthesize(size, rng=5, patch_refine=3)
        assert small.shape == size + (3,) and np.isfinite(small).all()
    u8 = patch_model.synthesize((64, 64), rng=5, patch_refine=2, dtype=np.uint8, tile=True)
    assert u8.dtype == np.uint8 and u8.shape == (64, 64, 3)
    f32 = patch_model.synthesize((64, 64), rng=5, patch_refine=5, dtype=np.float32)
    assert f32.dtype == np.float32 and np.abs(f32 - a).max() < 1e-6


def test_paper_pipeline_is_unaffected():
    assert settings.PAPER["patch_refine"] == 0 and settings.PAPER["patch_levels"] == 0
    assert settings.BY_NAME["patch_refine"].default is None and settings.BY_NAME["patch_levels"].default == 4
    assert settings.BY_NAME["patch_stride"].default == 2
    assert settings.QUALITY["best"] == {"patch_refine": 90, "patch_stride": 1}
    # On the command line the default is the word "auto"; "off" is refused (0 turns it off).
    refine = settings.BY_NAME["patch_refine"]
    assert refine.parse("auto") is None and refine.parse("0") == 0
    with pytest.raises(TGHopError, match="not an integer"):
        refine.parse("off")


def test_model_without_statistics_refuses_a_number_of_steps_and_skips_auto(plain_model):
    # A number of steps asked of a model without patch statistics did nothing, without a word
    # (tghop synth and the server refuse it).
    model = plain_model
    with pytest.raises(TGHopError, match=r"patch_refine=3 needs the patch statistics this model lacks \(fitted with "
                                         r"patch_levels=0"):
        model.synthesize((48, 48), rng=1, patch_refine=3)
    assert np.array_equal(model.synthesize((48, 48), rng=1, patch_refine=None),
                          model.synthesize((48, 48), rng=1, patch_refine=0))


def test_fit_is_unchanged_by_the_statistics(patch_model, plain_model):
    # Nor the coarse layout model's, whose own statistics only its guide's patch refinement reads.
    plain = plain_model
    assert plain.layout_.model_.patches_ is None and patch_model.layout_.model_.patches_ is not None
    assert np.array_equal(plain.synthesize((64, 64), rng=3),
                          patch_model.synthesize((64, 64), rng=3, patch_refine=0, layout_patch_refine=0))


def test_model_file_round_trip(patch_model, tmp_path):
    save_model(patch_model, tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz") as f:
        assert json.loads(str(f["__meta__"]))["format_version"] == WITHOUT_MATERIAL_PATCHES
        assert np.array_equal(f["patch.levels"], pr.quantile_levels().astype(np.float32))
    loaded = load_model(tmp_path / "m.npz")
    assert np.array_equal(loaded.synthesize((64, 64), rng=4, patch_refine=3),
                          patch_model.synthesize((64, 64), rng=4, patch_refine=3))


def _rewrite(src, dst, edit):
    with np.load(src) as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays.pop("__meta__")))
    edit(meta, arrays)
    np.savez(dst, __meta__=np.array(json.dumps(meta)), **arrays)


def test_old_files_load_and_damaged_arrays_are_refused(patch_model, tmp_path):
    save_model(TGHop(**SMALL, patch_levels=0, norm_match=0, coupling=0, colour_classes=0,
                     layout_factor=None).fit(data.cells(96, rng=3)), tmp_path / "plain.npz")
    with np.load(tmp_path / "plain.npz") as f:  # nothing new in it: still readable by older tghop
        assert json.loads(str(f["__meta__"]))["format_version"] == 3

    def old(meta, arrays):  # a file of tghop 0.13: no patch_levels setting at all
        meta["params"].pop("patch_levels")
        meta["params"].pop("patch_whitening")
    _rewrite(tmp_path / "plain.npz", tmp_path / "old.npz", old)
    loaded = load_model(tmp_path / "old.npz")
    assert loaded.patches_ is None
    assert loaded.patch_whitening == 0.0  # what files before the setting were fitted with
    assert loaded.synthesize((48, 48), rng=1).shape == (48, 48, 3)
    with pytest.raises(TGHopError, match="or by tghop 0.14 or older"):
        loaded.synthesize((48, 48), rng=1, patch_refine=2)

    save_model(patch_model, tmp_path / "p.npz")

    def skew(meta, arrays):
        arrays["patch.directions"] = arrays["patch.directions"] * 1.5
    _rewrite(tmp_path / "p.npz", tmp_path / "skew.npz", skew)
    with pytest.raises(ModelFileError, match="patch.directions.*unit length"):
        load_model(tmp_path / "skew.npz")

    def missing(meta, arrays):
        arrays.pop("patch.quantiles")
    _rewrite(tmp_path / "p.npz", tmp_path / "missing.npz", missing)
    with pytest.raises(ModelFileError, match="patch.quantiles is missing"):
        load_model(tmp_path / "missing.npz")

    def no_levels(meta, arrays):  # format 6 stores the levels
        arrays.pop("patch.levels")
    _rewrite(tmp_path / "p.npz", tmp_path / "no_levels.npz", no_levels)
    with pytest.raises(ModelFileError, match="patch.levels is missing"):
        load_model(tmp_path / "no_levels.npz")

    def bad_levels(meta, arrays):
        arrays["patch.levels"] = arrays["patch.levels"][::-1].copy()
    _rewrite(tmp_path / "p.npz", tmp_path / "bad_levels.npz", bad_levels)
    with pytest.raises(ModelFileError, match="patch.levels"):
        load_model(tmp_path / "bad_levels.npz")

    def unknown(meta, arrays):  # arrays of a model that says it has none
        meta["params"]["patch_levels"] = 0
    _rewrite(tmp_path / "p.npz", tmp_path / "unknown.npz", unknown)
    with pytest.raises(ModelFileError, match="array patch."):
        load_model(tmp_path / "unknown.npz")


def test_version_5_files_read_their_quantiles_as_evenly_spaced(patch_model, tmp_path, monkeypatch):
    """tghop 0.15 to 0.24 stored 7x7 patches' quantiles at evenly spaced levels, without
    patch.levels (format 5): such a file loads with that side and those levels."""
    save_model(patch_model, tmp_path / "p.npz")
    with monkeypatch.context() as m:  # 0.24's statistics: 7x7 patches
        m.setattr(pr, "PATCH", 7)
        old = pr.PatchStatistics(3).fit(data.cells(96, rng=3).astype(np.float32))

    def v5(meta, arrays):
        meta["format_version"] = 5
        arrays.pop("patch.levels")
        arrays["patch.directions"], arrays["patch.quantiles"] = old.directions_, old.quantiles_
    _rewrite(tmp_path / "p.npz", tmp_path / "v5.npz", v5)
    loaded = load_model(tmp_path / "v5.npz")
    assert loaded.patches_.side_ == 7 and patch_model.patches_.side_ == pr.PATCH == 5
    assert np.array_equal(loaded.patches_.levels_, np.linspace(0, 1, pr.QUANTILES).astype(np.float32))
    assert np.array_equal(loaded.patches_.quantiles_, old.quantiles_)
    img = patch_model.synthesize((48, 48), rng=2, patch_refine=0).astype(np.float32)
    a = pr.patch_refine(img, loaded.patches_, n_steps=3)
    assert a.shape == img.shape and np.abs(a - img).max() > 0
    crowded = pr.PatchStatistics(3)._from_arrays(old._to_arrays())  # the same numbers read at other levels
    crowded.side_ = 7
    assert not np.array_equal(a, pr.patch_refine(img, crowded, n_steps=3))
    # A version 5 file's 5x5 statistics are refused: format 5 holds 7x7 ones.
    _rewrite(tmp_path / "v5.npz", tmp_path / "v5bad.npz",
             lambda meta, arrays: arrays.update({"patch.directions": patch_model.patches_.directions_}))
    with pytest.raises(ModelFileError, match="7x7x3 patches"):
        load_model(tmp_path / "v5bad.npz")


def test_version_4_files_load_without_their_patch_statistics(patch_model, tmp_path):
    """tghop 0.14 stored other patch statistics (format 4): its files still load, without them."""
    save_model(patch_model, tmp_path / "p.npz")

    def v4(meta, arrays):
        meta["format_version"] = 4
        for name in ("patch.directions", "patch.quantiles", "patch.levels"):
            arrays.pop(name)
        arrays["patch.rotations"] = np.stack([np.eye(75, dtype=np.float32)] * 2)[None].repeat(3, 0)
        arrays["patch.quantiles"] = np.zeros((3, 2, 75, 129), np.float32)
    _rewrite(tmp_path / "p.npz", tmp_path / "v4.npz", v4)
    with pytest.warns(UserWarning, match="patch refinement statistics are of tghop 0.14"):
        loaded = load_model(tmp_path / "v4.npz")
    assert loaded.patches_ is None and loaded.patch_levels == 0
    assert np.array_equal(loaded.synthesize((48, 48), rng=1),
                          patch_model.synthesize((48, 48), rng=1, patch_refine=0))
    with pytest.raises(TGHopError, match="patch_refine=3 needs the patch statistics"):
        loaded.synthesize((48, 48), rng=1, patch_refine=3)


# ------------------------------------------------------------------ estimator conventions and input checks
def test_patch_statistics_is_a_scikit_learn_estimator(rng):
    from sklearn.base import clone

    from tghop._errors import NotFittedError

    st = pr.PatchStatistics(n_levels=2)
    assert st.get_params() == {"n_levels": 2, "whitening": 0.0, "rng": 0}
    assert repr(st) == "PatchStatistics(n_levels=2)"
    assert clone(st.set_params(whitening=0.5)).get_params() == {"n_levels": 2, "whitening": 0.5, "rng": 0}
    with pytest.raises(NotFittedError):
        pr.patch_refine(rng.random((16, 16, 3)), pr.PatchStatistics(), n_steps=1)


def test_patch_statistics_fit_checks_its_image_and_takes_rng():
    from tghop._errors import InvalidImageError

    img = data.bricks(40)
    u8 = np.round(img * 255).astype(np.uint8)
    base = pr.PatchStatistics(n_levels=1).fit(img)
    # uint8 is read as x / 255 (as TGHop.fit does), not 255 times too large.
    assert np.array_equal(pr.PatchStatistics(n_levels=1).fit(u8).quantiles_,
                          pr.PatchStatistics(n_levels=1).fit(u8 / 255.0).quantiles_)
    # rng: an int (the default 0: the same directions as before) or a Generator, in the constructor.
    assert np.array_equal(pr.PatchStatistics(n_levels=1, rng=0).fit(img).directions_, base.directions_)
    gen = pr.PatchStatistics(n_levels=1, rng=np.random.default_rng(0)).fit(img)
    assert np.array_equal(gen.directions_, base.directions_)
    other = pr.PatchStatistics(n_levels=1, rng=5)
    assert not np.array_equal(other.fit(img).directions_, base.directions_)
    assert np.array_equal(pr.PatchStatistics(**other.get_params()).fit(img).directions_, other.directions_)
    nan = img.copy()
    nan[2, 2, 2] = np.nan
    for bad, message in ((img * 255, r"values must lie in \[0, 1\]"), (nan, "NaN"), (img[None], "must have shape"),
                         (img[:3, :3], "at least 5x5")):
        with pytest.raises(InvalidImageError, match="PatchStatistics.fit: image.*" + message):
            pr.PatchStatistics(n_levels=1).fit(bad)
    with pytest.raises(TGHopError, match="seed must be a non-negative integer"):
        pr.PatchStatistics(n_levels=1, rng=-1).fit(img)


def test_patch_statistics_fits_old_keyword_rng_still_works_with_a_future_warning():
    # rng was fit's keyword until 0.54, where the other estimators take it in the constructor.
    img = data.bricks(40)
    with pytest.warns(FutureWarning, match=r"PatchStatistics.fit\(rng=...\) is deprecated .*"
                                           r"PatchStatistics\(..., rng=...\)"):
        old = pr.PatchStatistics(n_levels=1).fit(img, rng=5)
    assert np.array_equal(old.directions_, pr.PatchStatistics(n_levels=1, rng=5).fit(img).directions_)
    assert old.rng == 0  # fit leaves the parameters as given
    with pytest.raises(TGHopError, match="seed must be a non-negative integer"), pytest.warns(FutureWarning):
        pr.PatchStatistics(n_levels=1).fit(img, rng=-1)


def test_patch_refine_errors_name_its_own_arguments(patch_model):
    from tghop._errors import InvalidImageError

    img, p = np.full((32, 32, 3), 0.5), patch_model.patches_
    for kwargs, message in (({"n_steps": -1}, "^n_steps must be"), ({"stride": 0}, "^stride must be"),
                            ({"learning_rate": -1}, "learning_rate must be a finite number > 0"),
                            ({"learning_rate": "a"}, "learning_rate must be"),
                            ({"learning_rate": float("nan")}, "learning_rate must be")):
        with pytest.raises(TGHopError, match=message):
            pr.patch_refine(img, p, **{"n_steps": 1, **kwargs})
    for bad in (img * 255, img[..., 0]):
        with pytest.raises(InvalidImageError, match="^patch_refine: image"):
            pr.patch_refine(bad, p, n_steps=1)
    with pytest.raises(TGHopError, match=rf"^stride must be an integer from 1 to {p.side_}, got {p.side_ + 1}$"):
        pr.patch_refine(img, p, n_steps=1, stride=p.side_ + 1)
    with pytest.raises(TGHopError, match=r"^patch_levels must be an integer >= 1, got -1$"):
        pr.fit_patch_statistics(-1, img)
    with pytest.raises(TGHopError, match="^PatchStatistics: n_levels must be"):
        pr.PatchStatistics(n_levels=0).fit(img)
    with pytest.raises(TGHopError, match="^PatchStatistics: whitening must be"):
        pr.PatchStatistics(whitening=2).fit(img)
    # TGHop's own settings keep their names.
    with pytest.raises(TGHopError, match="^patch_refine must be"):
        pr.refine_image(img, p, n_steps=-1)


def test_the_same_image_with_any_number_of_blas_threads_and_in_concurrent_threads(patch_model):
    # The patch refinement and quilting ran on the process's BLAS threads (their products round
    # differently on more), so a batch worker's one thread, tghop synth's two and the server's
    # threads made different images of one seed. Generation now holds one BLAS thread.
    from concurrent.futures import ThreadPoolExecutor

    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=2, user_api="blas"):
        two = patch_model.synthesize((72, 72), rng=0)
    with threadpool_limits(limits=1, user_api="blas"):  # as tghop serve holds its process
        one = patch_model.synthesize((72, 72), rng=0)
        with ThreadPoolExecutor(max_workers=4) as pool:
            images = list(pool.map(lambda _: patch_model.synthesize((72, 72), rng=0), range(8)))
    assert np.array_equal(two, one) and all(np.array_equal(image, one) for image in images)
