"""Patch-distribution refinement, the last step: sliced Wasserstein matching of small patches (ours).

The band refinement (:mod:`tghop.refine`) gives every band the exemplar's marginal
distribution, but says nothing about how values go together inside a small window: edges
stay soft, grain is mushy. GPDM (Elnekave & Weiss 2022) and Heitz et al.'s sliced
Wasserstein loss (2021) match the distribution of an image's small patches to the
exemplar's along random directions, by gradient descent on the pixels.

This step does the same from statistics stored in the model, coarse to fine, started from
tghop's finished image (which already has the layout, so few steps suffice):

- Fit (:class:`PatchStatistics`): for each of a few levels of the exemplar's binomial
  pyramid (full, 1/2, 1/4, 1/8 resolution), ``SETS`` fixed sets of ``DIRECTIONS`` random
  unit directions in the space of ``PATCH x PATCH x C`` patches (5 x 5; GPDM's are 7 x 7),
  and ``QUANTILES`` quantiles of the exemplar's patch projections on each, at levels
  crowded towards both ends (:func:`quantile_levels`): a projection's tails are the patches
  with the strongest edges. Nothing else of the exemplar is kept, so no exemplar patch can
  be pasted. With ``whitening`` w > 0 the directions are drawn in partly whitened patch
  space (``C^-w u`` for the level's patch covariance C): uniform directions mostly see a
  patch's mean and smooth ramps, which carry most of its variance; these see its edges and
  grain as well.
- Generation (:func:`patch_refine`): from the coarsest level, ``n_steps`` Adam steps on the
  level's pixels; step t projects every ``stride``-th patch each way (more on large levels,
  every patch on small ones; the grid shifted each step, so that every pixel takes its turn in
  every place of a patch) on set ``t mod SETS``, gives each projection the stored quantile at
  its rank (1-D optimal transport, ranks from a histogram), and moves the pixels along the
  gradient of the L1 distance between the two (as GPDM). A level's change is upsampled into
  the next finer one.
  At stride 2 the full level's change loses the 2-pixel checker such steps leave
  (:func:`_without_checker`); at strides 3 and 4 (images of about 724x724 pixels and more)
  the pattern of that period (:func:`_without_grid`).
"""

from __future__ import annotations

import numbers
import warnings

import numpy as np

from ._arrays import check_int, check_mask, check_number
from ._errors import InvalidImageError, TGHopError
from ._estimator import BaseEstimator, ImageInputMixin, check_is_fitted, check_rng
from ._images import check_image, checked_image
from ._progress import report
from ._resources import one_blas_thread
from .patches import clean_windows
from .pyramid import downsample, upsample

__all__ = ["PatchStatistics", "patch_refine", "fit_patch_statistics", "refine_image", "steps_for"]

#: Patch side (pixels of each level) of the statistics fitted now (GPDM: 7; docs/choices.md,
#: Patch refinement "0.25").
PATCH = 5
#: The side in model files of format 5 (tghop 0.15 to 0.24), which have no ``patch.levels``.
_FORMAT5_PATCH = 7
#: Direction sets stored per level (step t of a level uses set t mod SETS).
SETS = 32
#: Random unit directions per set (GPDM draws 64 per step; 32 here: docs/choices.md).
DIRECTIONS = 32
#: Quantiles stored per direction (at :func:`quantile_levels`).
QUANTILES = 129
#: ``PatchStatistics.fit``'s deprecated ``rng`` keyword, not given.
_NOT_GIVEN = object()
#: Patches measured per level at fit (a strided subset beyond this): enough for the tails.
_FIT_PATCHES = 1 << 15
#: The fit measures the exemplar in parts of at most _FIT_SIDE pixels a side, one at a time (its
#: memory stays bounded): the whole exemplar up to _FIT_GRID parts a side, else _FIT_GRID x
#: _FIT_GRID parts spread evenly over it (:func:`_parts`).
_FIT_SIDE = 1024
_FIT_GRID = 3
#: Evenly spaced levels the stored quantiles are read at during generation (:func:`_on_ranks`):
#: as good as 4,097 and cheaper (docs/choices.md, Patch refinement "0.25").
_RANKS = 1025
#: Adam's step at full resolution, in pixel values of [0, 1] (GPDM: 0.01 in [-1, 1] from
#: noise; from a finished image smaller steps: docs/choices.md).
LEARNING_RATE = 0.002
#: Adam's step at the coarser levels, at most COARSE_TRAVEL / steps: their changes, upsampled,
#: smear the full level when they travel further in all (docs/choices.md, "0.22").
COARSE_RATE = 0.0015
COARSE_TRAVEL = 0.045
#: Table entries of the rank matching per direction: one per _PER_BIN ranked patches, at least
#: _MIN_BINS and at most _BINS (:func:`_n_bins`).
_BINS = 4096
_MIN_BINS = 256
_PER_BIN = 3
#: Patches whose projections give the rank tables of a step (a strided subset beyond this).
_RANK_PATCHES = 1 << 16
#: Patches cut out at once: their copies stay in the cache, and the memory of large images
#: stays bounded (docs/choices.md, Patch refinement).
_CHUNK = 1 << 14
#: Pixels of a level moved through every patch; larger levels use a stride (:func:`_stride`).
_STRIDE_PIXELS = 1 << 17
#: Levels of at most this many pixels take every patch, whatever the stride.
_DENSE_PIXELS = 1 << 13
_MAX_STRIDE = 4
#: Eigenvalues of the patch covariance below this share of the largest count as this much
#: when directions are whitened (flat or noiseless exemplars: no direction of pure noise).
_EIGEN_FLOOR = 1e-3
#: The default (``patch_refine`` None): AUTO_STEPS per level on images of at most AUTO_PIXELS
#: pixels, AUTO_LARGE_STEPS on images of at most AUTO_LARGE_PIXELS, then fewer in proportion to
#: the pixels up to AUTO_LARGEST_PIXELS (15 at 1280x1280), none on larger ones: a step's cost
#: grows with the image (docs/choices.md, Patch refinement "0.31" and "0.43").
AUTO_STEPS = 52
AUTO_PIXELS = 512 * 512
AUTO_LARGE_STEPS = 24
AUTO_LARGE_PIXELS = 1024 * 1024
AUTO_LARGEST_PIXELS = 1280 * 1280
#: Scale (pixels of one phase's grid) at which :func:`_without_grid` compares a phase of the change
#: with the whole change (docs/choices.md, Patch refinement "0.43").
_GRID_SIGMA = 1.5
#: Pixels added around a change before its checker is measured (:func:`_without_checker`).
_CHECKER_MARGIN = 8
#: Smallest side of a level, in patch sides (coarser levels are not made).
_MIN_SIDE = 3


def quantile_levels(n=QUANTILES):
    """The ``n`` probability levels of the stored quantiles: ``(1 - cos(pi u)) / 2`` for ``u``
    evenly spaced in [0, 1], crowded towards 0 and 1 (the outermost steps about ``2.5 / n^2``
    instead of ``1 / n``): the tails of a patch projection, where edges and grain sit, get
    their own quantiles (docs/choices.md, Patch refinement "0.25")."""
    return 0.5 - 0.5 * np.cos(np.pi * np.linspace(0.0, 1.0, n))


def _on_ranks(quantiles, levels, n=_RANKS):
    """``quantiles`` (..., Q) at probability ``levels`` (Q,), read at ``n`` evenly spaced
    levels by linear interpolation between them: (..., n) float32, what the rank tables of
    :func:`_table` take. By ``take``, whose result is C-contiguous: indexing the last axis
    (``quantiles[..., j]``) gives another layout, five times slower to make and copied again
    by each step's table."""
    pos = np.interp(np.linspace(0.0, 1.0, n), levels, np.arange(len(levels), dtype=np.float64))
    j = np.minimum(pos.astype(np.int64), len(levels) - 2)
    frac = (pos - j).astype(np.float32)
    low = quantiles.take(j, axis=-1)
    out = quantiles.take(j + 1, axis=-1)
    out -= low
    out *= frac
    out += low  # low + (high - low) * frac
    return out


def _projection_quantiles(dirs, x, qlev):
    """Quantiles at ``qlev`` (Q,) of the patches ``x`` (n, D) projected on ``dirs`` (S, K, D):
    (S, K, Q) float32.

    By linear interpolation between the order statistics (np.quantile's rule, from one sort;
    np.quantile takes about twice as long here: docs/choices.md). One set of directions at a
    time: its projections (K x n) stay in the cache while they are sorted, and the fit's
    memory does not hold all S sets' at once.
    """
    n_x = len(x)
    pos = qlev * (n_x - 1)
    lo = np.minimum(pos.astype(np.int64), n_x - 2) if n_x > 1 else np.zeros_like(pos, np.int64)
    frac = (pos - lo).astype(np.float32)
    hi = np.minimum(lo + 1, n_x - 1)
    out = np.empty(dirs.shape[:2] + (len(qlev),), dtype=np.float32)
    for s, d in enumerate(dirs):
        proj = d @ x.T  # (K, n)
        proj.sort(axis=1)  # along rows: a contiguous sort per direction
        low = proj[:, lo]
        q = low + (proj[:, hi] - low) * frac  # tied values stay exact
        # Levels crowded into one interval must not step back by a rounding (a file checks that).
        out[s] = np.maximum.accumulate(q, axis=1)
    return out


def _levels_of(img, n_levels, mode, p):
    """Gaussian pyramid [img, down(img), ...] of an (H, W, C) image, stopping before a
    side gets below _MIN_SIDE patch sides ``p``."""
    out = [img]
    while len(out) < n_levels and min(out[-1].shape[:2]) >= 2 * _MIN_SIDE * p:
        out.append(downsample(out[-1], mode))
    return out


def _columns(img, p, stride=1):
    """The p x p windows at ``stride`` of a channel-first (C, H, W) image, as columns
    (C * p * p, n) (channel, row, column; windows row-major), a contiguous copy.

    Where windows overlap by at least half (``2 * stride <= p``, stride above 1), from each
    phase of the grid (its pixels at offsets ``(py, px)`` modulo ``stride``) copied into a plane
    of its own first: the window offsets of that phase then read contiguous runs of that plane
    (rather than every stride-th pixel of the image). At larger strides the planes would copy
    about as much as the windows themselves.
    """
    window = np.lib.stride_tricks.sliding_window_view
    if stride == 1 or 2 * stride > p:
        v = window(img, (p, p), axis=(1, 2))[:, ::stride, ::stride]
        return np.ascontiguousarray(v.transpose(0, 3, 4, 1, 2)).reshape(img.shape[0] * p * p, -1)
    c, h, w = img.shape
    hh, ww = (h - p) // stride + 1, (w - p) // stride + 1
    out = np.empty((c, p, p, hh, ww), dtype=img.dtype)
    for py in range(min(stride, p)):
        for px in range(min(stride, p)):
            plane = np.ascontiguousarray(img[:, py::stride, px::stride])
            v = window(plane, (len(range(py, p, stride)), len(range(px, p, stride))), axis=(1, 2))
            out[:, py::stride, px::stride] = v[:, :hh, :ww].transpose(0, 3, 4, 1, 2)
    return out.reshape(c * p * p, -1)


class PatchStatistics(ImageInputMixin, BaseEstimator):
    """The exemplar's patch projections per pyramid level, for :func:`patch_refine`.

    Parameters
    ----------
    n_levels : int
        Pyramid levels (full resolution, 1/2, ...); fewer for small exemplars.
    whitening : float in [0, 1]
        Directions ``C^-whitening u`` (normalised) for Gaussian ``u`` and the level's patch
        covariance ``C`` (its eigenvalues floored at ``_EIGEN_FLOOR`` times the largest):
        0 uniform random directions (tghop 0.15 to 0.20), 0.5 uniform in whitened space.
    rng : int or numpy.random.Generator, default=0
        The directions come from it alone (as every estimator of tghop, a constructor
        parameter; the default 0 gives the directions of every model so far, which
        :meth:`tghop.TGHop.fit` keeps whatever its own ``rng``).

    Attributes
    ----------
    directions_ : ndarray, shape (L, SETS, DIRECTIONS, D)
        Unit directions in patch space (D = C * side * side, channel-major; ``side`` is
        PATCH, or 7 in files of format 5).
    quantiles_ : ndarray, shape (L, SETS, DIRECTIONS, QUANTILES)
        The exemplar's quantiles of its patches' projections on each direction.
    levels_ : ndarray, shape (QUANTILES,)
        Their probability levels (:func:`quantile_levels`; evenly spaced in model files of
        format 5, tghop 0.15 to 0.24).
    side_ : int
        The patches' side: PATCH (7 in model files of format 5).
    """

    def __init__(self, n_levels=4, whitening=0.0, rng=0):
        self.n_levels = n_levels
        self.whitening = whitening
        self.rng = rng

    # One BLAS thread: OpenBLAS's products round by its thread count (0.59's material fitted its albedo's outside
    # TGHop.fit's hold: the quantiles 8e-7 apart on two threads and on a batch worker's one)
    @one_blas_thread()
    def fit(self, image, y=None, *, exclude=None, rng=_NOT_GIVEN):
        """Learn from the exemplar; returns self.

        Parameters
        ----------
        image : ndarray, shape (H, W) or (H, W, C)
            Float in [0, 1], or uint8 (read as ``x / 255``, as :meth:`tghop.TGHop.fit` does);
            at least PATCH pixels a side. Measured in parts of at most 1024x1024 pixels, one at
            a time (:func:`_parts`): the whole of it up to 3072 pixels a side, else 3 x 3
            parts spread over it.
        y : None
            Ignored (scikit-learn's signature: a Pipeline passes it; 0.59 took the image alone).
        exclude : ndarray, shape (H, W), bool, optional
            Patches touching these pixels (at each level: touching pixels reached by them)
            are left out.
        rng : int or numpy.random.Generator, optional
            Deprecated (a FutureWarning): give ``rng`` to the constructor, as every estimator
            of tghop takes it. Given, it is used in place of the constructor's for this fit.

        Returns
        -------
        self
        """
        n = self.n_levels
        n = check_int(n, "n_levels", where="PatchStatistics")
        w = self.whitening
        if not isinstance(w, numbers.Real) or isinstance(w, bool) or not 0 <= w <= 1:
            raise TGHopError(f"PatchStatistics: whitening must be a number in [0, 1], got {w!r}")
        if rng is _NOT_GIVEN:
            rng = self.rng
        else:
            warnings.warn("PatchStatistics.fit(rng=...) is deprecated and will be removed; give it to the "
                          "constructor: PatchStatistics(..., rng=...).fit(image)", FutureWarning, stacklevel=2)
        rng = check_rng(rng)
        arr = np.asarray(image)
        parts = _parts(arr.shape[:2]) if arr.ndim in (2, 3) else [(Ellipsis,)]  # (Ellipsis,): for the error
        rows_of, counts = [[] for _ in range(n)], []  # per level, the patches (n, D) measured in each part
        for j, part in enumerate(parts):  # one part's pixels as floats at a time
            img = check_image(arr[part], min_size=PATCH, name="PatchStatistics.fit: image", dtype=np.float32,
                              channels=None)
            if j == 0 and exclude is not None:
                exclude = check_mask(exclude, arr.shape, "PatchStatistics.fit")
            hole = None if exclude is None else exclude[part]
            levels = _levels_of(img, n, "reflect", PATCH)
            counts.append(len(levels))
            for i, level in enumerate(levels):
                rows_of[i].append(_fit_patches(level, hole, -(-_FIT_PATCHES // len(parts))))
                if hole is not None:  # the next level's mask: pixels whose 5-tap neighbourhood met a hole
                    hole = downsample(hole.astype(np.float32)[..., None])[..., 0] > 0
        n_levels = min(counts)  # as many as every part has
        d = PATCH * PATCH * img.shape[2]
        dirs = rng.standard_normal((n_levels, SETS, DIRECTIONS, d)).astype(np.float32)
        dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
        qlev = quantile_levels(QUANTILES)
        quantiles = np.empty((n_levels, SETS, DIRECTIONS, QUANTILES), dtype=np.float32)
        for i in range(n_levels):
            x = np.concatenate(rows_of[i])
            if w:
                dirs[i] = _whitened(dirs[i].reshape(-1, d), x, w).reshape(dirs[i].shape)
            quantiles[i] = _projection_quantiles(dirs[i], x, qlev)
        self.directions_, self.quantiles_, self.levels_ = dirs, quantiles, qlev.astype(np.float32)
        self.side_ = PATCH
        return self

    #: Fitted arrays in model files: (file name, attribute).
    _ARRAYS = (("patch.directions", "directions_"), ("patch.quantiles", "quantiles_"), ("patch.levels", "levels_"))

    def _to_arrays(self) -> dict:
        return {name: getattr(self, attr).astype(np.float32) for name, attr in self._ARRAYS}

    def _from_arrays(self, arrays):
        """The fitted arrays from a model file's; without ``patch.levels`` (format 5), evenly
        spaced levels."""
        for name, attr in self._ARRAYS:
            if name in arrays:
                setattr(self, attr, arrays[name].astype(np.float32, copy=False))
        self.side_ = PATCH
        if "patch.levels" not in arrays:
            self.levels_ = np.linspace(0.0, 1.0, self.quantiles_.shape[-1]).astype(np.float32)
            self.side_ = _FORMAT5_PATCH
        return self

    def _array_specs(self, c, meta=None):
        """Specs of :mod:`tghop.modelfile` for a model of ``c`` colour channels in a file
        with metadata ``meta`` (``patch.levels`` from format version 6 on)."""
        version = (meta or {}).get("format_version")
        format5 = version is not None and version < 6  # 7x7 patches, no patch.levels
        side = _FORMAT5_PATCH if format5 else PATCH
        d = side * side * c

        def unit(arr, dims):
            # The squared lengths summed in float64 as they are read: no float64 copy of the array.
            if np.abs(np.sqrt(np.einsum("...i,...i->...", arr, arr, dtype=np.float64)) - 1).max() > 1e-4:
                return "holds a direction that is not of unit length"
            return None

        says = f"the metadata says at most {self.n_levels} levels of {side}x{side}x{c} patches"
        return (
            ("patch.directions", ("Lp", SETS, DIRECTIONS, d), "f", says, (("dim", 0, 1, self.n_levels), unit)),
            ("patch.quantiles", ("Lp", SETS, DIRECTIONS, QUANTILES), "f", says, (("nondecreasing",),)),
        ) + (() if format5 else (("patch.levels", (QUANTILES,), "f", f"{QUANTILES} quantile levels",
                                  (("range", 0.0, 1.0), ("nondecreasing",))),))


def _parts(shape):
    """The parts (row slice, column slice) of an exemplar of ``shape`` (H, W) that the fit
    measures: along each side ``k = ceil(n / _FIT_SIDE)`` parts that tile it (at most
    _FIT_SIDE pixels each), or, beyond _FIT_GRID of them, _FIT_GRID parts of _FIT_SIDE pixels
    spread evenly from one end to the other."""
    def spans(n):
        k = -(-n // _FIT_SIDE)
        if k <= _FIT_GRID:
            cuts = [round(j * n / k) for j in range(k + 1)]
            return [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:])]
        return [slice(a, a + _FIT_SIDE) for a in np.linspace(0, n - _FIT_SIDE, _FIT_GRID).round().astype(int)]

    return [(ys, xs) for ys in spans(shape[0]) for xs in spans(shape[1])]


def _fit_patches(level, hole, limit):
    """At most about ``limit`` of the PATCH x PATCH windows of an (H, W, C) pyramid level, none
    touching ``hole`` (H, W) where others are left: a strided subset of them (row-major), as
    rows (n, D)."""
    v = np.lib.stride_tricks.sliding_window_view(level, (PATCH, PATCH), axis=(0, 1))
    rows = np.arange(v.shape[0] * v.shape[1])
    if hole is not None:
        keep = clean_windows(hole, PATCH).ravel()
        if keep.any():
            rows = np.flatnonzero(keep)
    if len(rows) > limit:
        rows = rows[:: -(-len(rows) // limit)]
    return v[rows // v.shape[1], rows % v.shape[1]].reshape(len(rows), -1)


def _whitened(u, x, w):
    """Unit directions ``C^-w u`` (rows) for the patches ``x`` (n, D) of covariance C."""
    xc = (x - x.mean(axis=0)).astype(np.float64)
    vals, vecs = np.linalg.eigh(xc.T @ xc / max(len(x) - 1, 1))
    vals = np.maximum(vals, _EIGEN_FLOOR * max(vals[-1], 1e-12))
    out = (u.astype(np.float64) @ vecs) * vals**-w @ vecs.T
    return (out / np.linalg.norm(out, axis=1, keepdims=True)).astype(np.float32)


def _n_bins(n):
    """Table entries per direction for ``n`` ranked patches: a coarser level's table costs
    what its patches need, not a full level's."""
    return int(min(_BINS, max(_MIN_BINS, n // _PER_BIN)))


def _grid(ys, bins):
    """Each row's table grid for the projections ``ys``, a list of (K, n_i) arrays whose
    rows go together: its minimum and the entries per unit, ``bins`` entries between the
    row's extremes."""
    lo = np.min([y.min(axis=1) for y in ys], axis=0)
    hi = np.max([y.max(axis=1) for y in ys], axis=0)
    return lo, ((bins - 1) / np.maximum(hi - lo, np.float32(1e-12))).astype(np.float32)


def _table(idxs, target, bins):
    """The stored quantile ``target`` (K, Q) at the mid-rank of each table entry, given
    the entries ``idxs`` of :func:`_bins`, a list of (K, n_i) arrays of the same rows:
    (K * bins,) float32."""
    (k, q), n = target.shape, sum(idx.shape[1] for idx in idxs)
    counts = np.bincount(idxs[0].ravel(), minlength=k * bins)
    for idx in idxs[1:]:
        counts += np.bincount(idx.ravel(), minlength=k * bins)
    counts = counts.reshape(k, bins)
    # The mid-rank cumsum - (counts + 1) / 2 scaled to the quantiles' positions, from its double
    # (2 cumsum - counts - 1, integers) times half the scale: exact until the one rounding of the
    # product, as the mid-rank times the scale. In place from here on: fewer and smaller passes
    # than new arrays for each term.
    twice = np.cumsum(counts, axis=1)
    twice *= 2
    twice -= counts
    twice -= 1
    frac = twice * (0.5 * ((q - 1) / max(n - 1, 1)))
    j = frac.astype(np.int64)
    np.clip(j, 0, q - 2, out=j)
    frac -= j
    j += np.arange(0, k * q, q)[:, None]  # flat positions: one take instead of 2-D indexing
    flat = target.ravel()
    low = 1 - frac
    low *= flat.take(j)
    frac *= flat[1:].take(j)  # the next quantile's
    low += frac  # low (1 - frac) + high frac in float64, rounded to float32 once
    return low.astype(np.float32).ravel()


def _bins(y, lo, scale, bins):
    """Each value's table entry (of ``bins`` per row), offset by its row: int32 (K, n)."""
    pos = y - lo[:, None]
    pos *= scale[:, None]
    pos += 0.5
    np.clip(pos, 0, bins - 1, out=pos)
    idx = pos.astype(np.int32)
    idx += np.arange(y.shape[0], dtype=np.int32)[:, None] * bins
    return idx


def _scatter(out, gp, stride, top):
    """Add what each patch asks of its pixels, ``gp`` (C, p, p, bh, bw) for the patches at
    rows ``top + stride * i`` and columns ``stride * j``, to ``out`` (C, H, W), in place.

    Summed per phase of the grid into contiguous planes first, then interleaved once: the
    same sums, in the same order, as adding each offset to strided slices of ``out``.
    """
    c, p, _, bh, bw = gp.shape
    a = -(-p // stride)  # grid rows a patch spans
    planes = np.zeros((c, stride, stride, bh + a - 1, bw + a - 1), dtype=np.float32)
    for dy in range(p):
        for dx in range(p):
            i, j = dy // stride, dx // stride
            planes[:, dy % stride, dx % stride, i: i + bh, j: j + bw] += gp[:, dy, dx]
    h, w = out.shape[1] - top, out.shape[2]
    for py in range(stride):
        for px in range(stride):
            rows = min(bh + a - 1, -(-(h - py) // stride))
            cols = min(bw + a - 1, -(-(w - px) // stride))
            out[:, top + py: top + py + stride * rows: stride, px: px + stride * cols: stride] += (
                planes[:, py, px, :rows, :cols])


def _gradient(x, dirs, target, stride, origin=(0, 0)):
    """The gradient of the L1 sliced distance of a channel-first (C, H, W) image's patches (every
    ``stride``-th position from ``origin``) along ``dirs`` (K, D) to ``target`` (K, Q):
    (C, H, W) float32.

    The patches are cut out and sent back to their pixels in bands of rows of about _CHUNK
    patches, so that a band's copies stay in the cache. Up to _RANK_PATCHES patches, every
    patch's projection is kept (K x 4 bytes each), band by band, and gives the ranks: each
    band's table entries and lookups are made on its own, so that their temporaries stay
    small (the same numbers as on the whole array). Above, the ranks come from the patches
    on a coarser grid, and each band is projected when it is needed.
    """
    p = _side(dirs, x.shape[0])
    grad = np.zeros(x.shape, dtype=np.float32)
    out = grad[:, origin[0]:, origin[1]:]  # the grid's part of the image
    x = x[:, origin[0]:, origin[1]:]
    c, h, w = x.shape
    if h < p or w < p:  # a grid shifted on a side of 7 or 8 pixels holds no patch
        return grad
    (hh, ww) = ((h - p) // stride + 1, (w - p) // stride + 1)
    n = hh * ww
    rows = max(1, _CHUNK // ww)
    bands = [(r0, min(hh, r0 + rows)) for r0 in range(0, hh, rows)]

    def patches(r0, r1):  # (D, patches) of the grid rows r0 to r1
        return _columns(x[:, r0 * stride: (r1 - 1) * stride + p], p, stride)

    def back(g, r0, r1):  # what the patches of those rows ask of their pixels, added to the gradient
        _scatter(out, (dirs.T @ g).reshape(c, p, p, r1 - r0, ww), stride, r0 * stride)

    if n <= _RANK_PATCHES:
        ys = [dirs @ patches(r0, r1) for r0, r1 in bands]  # (K, band's patches) each
        bins = _n_bins(n)
        lo, scale = _grid(ys, bins)
        idxs = [_bins(y, lo, scale, bins) for y in ys]
        table = _table(idxs, target, bins)
        for i, (y, (r0, r1)) in enumerate(zip(ys, bands)):
            y -= np.take(table, idxs[i], mode="clip")
            idxs[i] = None  # freed before the band goes back
            # Not in place: NumPy's in-place sign is a branching loop, slow on mixed signs
            # (docs/choices.md, Patch refinement "0.29.1").
            back(np.sign(y), r0, r1)
        return grad
    sub = int(np.ceil(np.sqrt(n / _RANK_PATCHES)))
    sample = dirs @ _columns(x, p, stride * sub)  # (K, patches of the coarser grid)
    bins = _n_bins(sample.shape[1])
    lo, scale = _grid([sample], bins)
    table = _table([_bins(sample, lo, scale, bins)], target, bins)
    del sample
    for r0, r1 in bands:
        y = dirs @ patches(r0, r1)
        y -= np.take(table, _bins(y, lo, scale, bins), mode="clip")
        back(np.sign(y), r0, r1)
    return grad


def _phases(stride):
    """The stride x stride offsets of the patch grid, in an order that moves it both ways
    at once (0, 0), (1, 1), ...: consecutive steps use different phases."""
    return [(t % stride, (t // stride + t) % stride) for t in range(stride * stride)]


def _side(dirs, c):
    """The patch side of directions ``dirs`` (K, D) for ``c`` channels: D = c * side^2."""
    return int(round(np.sqrt(dirs.shape[-1] / c)))


def _steps(x, dirs, target, n_steps, tile, stride, lr):
    """``n_steps`` Adam steps of an (H, W, C) float32 image (a new one); step t's patches on
    the grid shifted by the phase ``t mod stride^2``. The steps work on the image channel-first
    (C, H, W), so that patches are cut out of contiguous rows."""
    h, w, c = x.shape
    p = _side(dirs[0], c)
    x = np.ascontiguousarray(x.transpose(2, 0, 1))
    m = np.zeros((c, h, w), dtype=np.float32)
    v = np.zeros((c, h, w), dtype=np.float32)
    buf = np.empty((c, h, w), dtype=np.float32)  # Adam's temporaries, written in place
    b1, b2, eps = 0.9, 0.999, 1e-8
    phases = _phases(stride)
    for t in range(n_steps):
        j = t % len(dirs)
        oy, ox = phases[t % len(phases)]
        if tile:  # periodic: shift the image itself, and fold the wrapped margin back
            src = np.roll(x, (-oy, -ox), axis=(1, 2)) if oy or ox else x
            g = _gradient(np.pad(src, ((0, 0), (0, p - 1), (0, p - 1)), mode="wrap"), dirs[j], target[j], stride)
            g[:, : p - 1] += g[:, h:]
            g[:, :, : p - 1] += g[:, :, w:]
            g = np.roll(g[:, :h, :w], (oy, ox), axis=(1, 2)) if oy or ox else g[:, :h, :w]
        else:  # the grid starts at (oy, ox); the first rows and columns are reached by later phases
            g = _gradient(x, dirs[j], target[j], stride, (oy, ox))
        # m = b1 m + (1 - b1) g; v = b2 v + (1 - b2) g^2; x -= lr m^ / (sqrt(v^) + eps), with the bias
        # corrections ^; in place, into buf and g (an image-sized array each time otherwise).
        np.multiply(g, 1 - b1, out=buf)
        m *= b1
        m += buf
        g *= g
        np.multiply(g, 1 - b2, out=buf)
        v *= b2
        v += buf
        np.divide(v, 1 - b2 ** (t + 1), out=buf)
        np.sqrt(buf, out=buf)
        buf += eps
        np.multiply(m, lr / (1 - b1 ** (t + 1)), out=g)
        g /= buf
        x -= g
    return np.ascontiguousarray(x.transpose(1, 2, 0))


def _stride(pixels):
    """Step between the patches of an image of ``pixels``: 1 up to 2^17 (256x256, 362x362),
    then growing with the side, at most 4 (below the patch side: every pixel still in a patch)."""
    return int(min(_MAX_STRIDE, max(1, np.ceil(np.sqrt(pixels / _STRIDE_PIXELS)))))


def patch_refine(image, stats, *, n_steps=30, stride=1, tile=False, learning_rate=LEARNING_RATE, progress=None):
    """Move an image's patch distributions towards the exemplar's, coarse to fine.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Float in [0, 1].
    stats : PatchStatistics
    n_steps : int
        Adam steps per pyramid level (0: the image unchanged).
    stride : int
        At every level, every ``stride``-th patch each way (the grid shifted every step);
        large levels use more (:func:`_stride`), levels of at most _DENSE_PIXELS pixels every
        patch.
    tile : bool
        Periodic boundaries (the output stays tileable).
    learning_rate : float
        Adam's step in pixel values at full resolution (coarser levels: ``COARSE_RATE``, or
        ``COARSE_TRAVEL / n_steps`` where that is less).
    progress : callable, optional
        ``progress("patch refine", done_steps, total_steps)``.

    Returns
    -------
    ndarray, shape (H, W, C), float32 in [0, 1]
    """
    return _patch_refine(image, stats, n_steps=n_steps, stride=stride, tile=tile, learning_rate=learning_rate,
                         progress=progress, names=("n_steps", "stride"))


def _patch_refine(image, stats, *, n_steps, stride, tile, learning_rate, progress, names, rate=1.0):
    """:func:`patch_refine`; ``names``: what its ``n_steps`` and ``stride`` are called in
    errors (TGHop's settings for :func:`refine_image`); ``rate`` multiplies every level's step."""
    n_steps = check_int(n_steps, names[0], 0)
    check_is_fitted(stats, ("side_", "directions_", "quantiles_", "levels_"))
    p = stats.side_
    stride = check_int(stride, names[1], 1, p)  # at most the patch side
    check_number(learning_rate, "learning_rate", positive=True, where="patch_refine")
    rate = check_number(rate, "rate", positive=True, where="patch_refine")
    img = checked_image(image, "patch_refine")
    img = check_image(img, name="patch_refine: image", dtype=np.float32, channels=None) if img.dtype.kind == "u" \
        else np.asarray(img, dtype=np.float32)
    if img.shape[2] * p * p != stats.directions_.shape[-1]:
        raise InvalidImageError(f"patch_refine: image of shape {img.shape} does not fit the patch statistics "
                                f"(patches of {stats.directions_.shape[-1] // (p * p)} channels)")
    if n_steps == 0 or min(img.shape[:2]) < p:
        return img.copy()
    mode = "wrap" if tile else "reflect"
    levels = _levels_of(img, len(stats.directions_), mode, p)
    total, done = n_steps * len(levels), 0
    report(progress, "patch refine", 0, total)
    new = None
    for i in range(len(levels) - 1, -1, -1):
        cur = levels[i].copy()
        if new is not None:  # the coarser level's change, upsampled
            cur += upsample(new - levels[i + 1], cur.shape, mode)
        # Every stride-th patch each way, large levels at least _stride's (2 to 4), the grid
        # shifted every step, so that a step's cost grows more slowly than the image; small
        # levels every patch: their steps cost little (docs/choices.md, Patch refinement "0.30").
        pixels = cur.shape[0] * cur.shape[1]
        step = 1 if pixels <= _DENSE_PIXELS else max(_stride(pixels), int(stride))
        # Step t uses set t mod SETS: fewer steps than sets read only the first ones.
        target = _on_ranks(stats.quantiles_[i][: min(n_steps, len(stats.quantiles_[i]))],
                           stats.levels_.astype(np.float64))
        new = _steps(cur, stats.directions_[i], target, int(n_steps), tile, step,
                     float(learning_rate) * rate if i == 0 else min(COARSE_RATE, COARSE_TRAVEL / n_steps) * rate)
        if i == 0 and step == 2:
            new = _without_checker(new, cur, tile)
        elif i == 0 and step > 2:  # the larger images' strides, 3 and 4
            new = _without_grid(new, cur, step, tile)
        np.clip(new, 0.0, 1.0, out=new)
        done += n_steps
        report(progress, "patch refine", done, total)
    return new


def _without_checker(image, start, tile):
    """``image`` (H, W, C) less the 2-pixel checker that steps at stride 2 leave: within a
    step, a pixel takes its change from the directions' coefficients of one parity only.
    The change from ``start`` is demodulated by (-1)^row, (-1)^column and their product,
    smoothed (two pyramid levels down and up again) and taken off: what each 2x2 phase of
    the change does unlike its neighbours over a few pixels (docs/choices.md, "0.24")."""
    m = _CHECKER_MARGIN
    # Mirrored without repeating the edge (or wrapped): the margin keeps the parity of the
    # pixels it copies, so a smooth change does not look like a checker at the borders.
    change = np.pad(image - start, ((m, m), (m, m), (0, 0)), mode="wrap" if tile else "reflect")
    h, w = change.shape[:2]
    rows = np.where(np.arange(h) % 2, -1, 1).astype(np.float32)[:, None, None]
    cols = np.where(np.arange(w) % 2, -1, 1).astype(np.float32)[None, :, None]
    # A periodic image of odd side has no 2-periodic pattern along that side.
    carriers = [c for c, n in ((rows, image.shape[0]), (cols, image.shape[1])) if not tile or n % 2 == 0]
    if len(carriers) == 2:
        carriers.append(rows * cols)
    for carrier in carriers:
        shapes, low = [], change * carrier
        for _ in range(2):
            shapes.append(low.shape)
            low = downsample(low)
        for shape in reversed(shapes):
            low = upsample(low, shape)
        low *= carrier
        change -= low
    return start + change[m:-m, m:-m]


def _without_grid(image, start, step, tile):
    """``image`` (H, W, C) less the pattern of period ``step`` that steps at that stride (3 or 4)
    leave: the change from ``start`` at each of the ``step x step`` phases of the grid, smoothed
    on that phase's own pixels, less the whole change smoothed at the same scale, is taken off
    those pixels (what one phase of the change does unlike its neighbours over a few pixels).
    A periodic image whose sides are not multiples of ``step`` is returned as it is (its phases
    would not wrap)."""
    from scipy import ndimage

    h, w = image.shape[:2]
    if tile and (h % step or w % step):
        return image
    # A margin of whole periods (mirrored, or wrapped) keeps every pixel's phase, so that a smooth
    # change does not look like a pattern at the borders.
    m = 4 * step
    change = np.pad(image - start, ((m, m), (m, m), (0, 0)), mode="wrap" if tile else "reflect")
    sigma = _GRID_SIGMA
    whole = ndimage.gaussian_filter(change, (sigma * step, sigma * step, 0), mode="nearest")
    out = change.copy()
    for py in range(step):
        for px in range(step):
            low = ndimage.gaussian_filter(change[py::step, px::step], (sigma, sigma, 0), mode="nearest")
            out[py::step, px::step] -= low - whole[py::step, px::step]
    return start + out[m:-m, m:-m]


def steps_for(n_steps, size):
    """``patch_refine`` for an image of ``size`` (H, W): ``n_steps``, or for None (auto)
    AUTO_STEPS up to AUTO_PIXELS pixels, AUTO_LARGE_STEPS up to AUTO_LARGE_PIXELS, then
    ``AUTO_LARGE_STEPS * AUTO_LARGE_PIXELS / pixels`` (rounded) up to AUTO_LARGEST_PIXELS and
    0 above.

    Parameters
    ----------
    n_steps : int or None
        The setting; an int is returned as it is (unchecked).
    size : (int, int)
        The image's (H, W).

    Returns
    -------
    int
        Adam steps per pyramid level (0: no patch refinement).
    """
    if n_steps is not None:
        return n_steps
    pixels = size[0] * size[1]
    if pixels <= AUTO_PIXELS:
        return AUTO_STEPS
    if pixels <= AUTO_LARGE_PIXELS:
        return AUTO_LARGE_STEPS
    return round(AUTO_LARGE_STEPS * AUTO_LARGE_PIXELS / pixels) if pixels <= AUTO_LARGEST_PIXELS else 0


def fit_patch_statistics(levels, image, *, whitening=0.0, exclude=None):
    """:class:`PatchStatistics` of a whole exemplar (H, W, C; float in [0, 1] or uint8, read in
    parts: :func:`_parts`); None when ``levels`` is 0 (nothing stored). Until 0.43 only its centre
    crop of at most 512x512 pixels was measured, which misled the refinement wherever the centre
    differs from the rest, as in many photographs (docs/choices.md, Patch refinement "0.44").

    Parameters
    ----------
    levels : int
        Pyramid levels measured (``patch_levels``); 0 or None: nothing.
    image : array_like, shape (H, W, C)
        The exemplar, float in [0, 1] or uint8.
    whitening : float
        ``patch_whitening``, in [0, 1] (else :class:`~tghop.TGHopError`).
    exclude : ndarray of bool, shape (H, W), optional
        Pixels left out of the statistics (True: excluded).

    Returns
    -------
    PatchStatistics or None
    """
    if not levels:
        return None
    levels = check_int(levels, "patch_levels")
    if not isinstance(whitening, numbers.Real) or isinstance(whitening, bool) or not 0 <= whitening <= 1:
        raise TGHopError(f"patch_whitening must be a number in [0, 1], got {whitening!r}")
    return PatchStatistics(levels, whitening, rng=0).fit(image, exclude=exclude)  # the directions of every model


@one_blas_thread()  # the same image with any number of threads or concurrent callers
def refine_image(image, stats, *, n_steps, stride=1, tile=False, dtype=None, progress=None, rate=1.0):
    """The generation step: an (H, W, C) image in [0, 1] -> :func:`patch_refine`, as
    ``dtype`` (default the image's; uint8: the 8-bit values of :func:`tghop.imageio.to_uint8`).
    ``rate`` multiplies every level's Adam step (the coarse guide's: :data:`tghop.layout.GUIDE_RATE`).

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Float in [0, 1], or uint8 / uint16 (rescaled to [0, 1]).
    stats : PatchStatistics
        The exemplar's, fitted (:func:`fit_patch_statistics`).
    n_steps : int
        Adam steps per pyramid level (``patch_refine``; 0: the image unchanged, converted to ``dtype``).
    stride : int
        ``patch_stride``: every ``stride``-th patch each way, 1 to the patch side.
    tile : bool
        Periodic boundaries.
    dtype : numpy dtype, optional
        Of the result.
    progress : callable, optional
        ``progress("patch refine", done_steps, total_steps)``.
    rate : float
        Positive.

    Returns
    -------
    ndarray, shape (H, W, C), in [0, 1] (0-255 for uint8)
    """
    out = _patch_refine(image, stats, n_steps=n_steps, stride=stride, tile=tile, learning_rate=LEARNING_RATE,
                        progress=progress, names=("patch_refine", "patch_stride"), rate=rate)
    dtype = np.dtype(dtype or np.asarray(image).dtype)
    if dtype == np.uint8:
        from .imageio import to_uint8

        return to_uint8(out).reshape(out.shape)
    return out.astype(dtype, copy=False)
