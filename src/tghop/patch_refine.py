"""Patch-distribution refinement after stitching: sliced optimal transport of small patches (ours).

The band refinement (:mod:`tghop.refine`) gives every band the exemplar's marginal
distribution, but says nothing about how values go together inside a small window: edges
stay soft, pebbles lose their outlines. GPDM (Elnekave & Weiss 2022) and Heitz et al.'s
sliced Wasserstein loss (2021) match the distribution of an image's small patches to the
exemplar's along random directions; "optimal textures" (Risser 2020) does it without
gradients, by 1-D optimal transport along each direction of a random rotation.

This step does the same from statistics stored in the model, coarse to fine: for each of a
few pyramid levels of the exemplar (full, 1/2, 1/4 resolution; binomial pyramid, in the
decorrelated colour space of :class:`tghop.refine.BandStatistics`) the projections of its
``P x P x C`` patches on a few fixed random rotations of patch space, as quantiles
(:class:`PatchStatistics`). At generation, for each level from the coarsest, a few
rounds of: cut every patch of the image (stride 1), rotate, give each coordinate the
stored distribution (1-D optimal transport: a monotone map by ranks), rotate back; every
pixel moves by the mean of what its patches asked of it. A level's change is upsampled
into the next finer one. Nothing of the exemplar but these quantiles is kept, so no
exemplar patch can be pasted.
"""

from __future__ import annotations

import numbers

import numpy as np

from ._common import TGHopError, report
from .patches import clean_windows
from .refine import downsample, refine as refine_bands, upsample

__all__ = ["PatchStatistics", "patch_refine", "fit_patch_statistics", "refine_image"]

#: Patch side (pixels of each level).
PATCH = 5
#: Random rotations stored per level (round r of a level uses rotation r mod ROTATIONS).
ROTATIONS = 2
#: Quantiles stored per direction.
QUANTILES = 129
#: Patches measured per level at fit (a strided subset beyond this).
_FIT_PATCHES = 1 << 16
#: Table entries of the rank matching per direction.
_BINS = 4096
#: Exemplar pixels measured at fit: the centre crop of at most this side.
_FIT_SIDE = 512
#: Rounds of the band refinement after the patch refinement (docs/choices.md: quilt, bands,
#: patches, bands again; beach_gravel and brick_wall SIFID 2.06 / 1.85 -> 1.77 / 1.70, against
#: 2.06 / 1.74 with the patches last and 1.84 / 1.87 with the patches first).
BAND_ROUNDS_AFTER = 2
#: Step between the patches moved at full resolution at generation (beach_gravel, brick_wall:
#: SIFID 1.75 / 1.70 against 1.77 / 1.70 with every patch, at a quarter of the cost).
FULL_STRIDE = 2
#: Smallest side of a level (coarser levels are not made).
_MIN_SIDE = 3 * PATCH


def _levels_of(img, n_levels, mode):
    """Gaussian pyramid [img, down(img), ...] of an (H, W, C) image, stopping before a
    side gets below _MIN_SIDE."""
    out = [img]
    while len(out) < n_levels and min(out[-1].shape[:2]) >= 2 * _MIN_SIDE:
        out.append(downsample(out[-1], mode))
    return out


def _windows(img, p):
    """Every p x p window of an (H, W, C) image as rows: (n, p * p * C), a copy."""
    h, w, c = img.shape
    v = np.lib.stride_tricks.sliding_window_view(img, (p, p), axis=(0, 1))  # (h', w', C, p, p)
    return np.ascontiguousarray(v.transpose(0, 1, 3, 4, 2)).reshape(-1, p * p * c)


def _rotations(rng, n, d):
    """``n`` random orthonormal (d, d) matrices (rows: directions)."""
    out = np.empty((n, d, d))
    for i in range(n):
        q, r = np.linalg.qr(rng.standard_normal((d, d)))
        out[i] = (q * np.sign(np.diag(r))).T
    return out


class PatchStatistics:
    """The exemplar's patch projections per pyramid level, for :func:`patch_refine`.

    Parameters
    ----------
    n_levels : int
        Pyramid levels (full resolution, 1/2, ...); fewer for small exemplars.

    Attributes
    ----------
    rotations_ : ndarray, shape (L, ROTATIONS, D, D)
        Orthonormal rotations of patch space (D = PATCH * PATCH * C), rows the directions.
    quantiles_ : ndarray, shape (L, ROTATIONS, D, QUANTILES)
        The exemplar's quantiles of its patches' projections on each direction.
    """

    def __init__(self, n_levels=3):
        self.n_levels = n_levels

    def fit(self, dec, *, exclude=None, seed=0):
        """Learn from the exemplar in decorrelated colours, (H, W, C) float; returns self.

        ``exclude`` (H, W) bool: patches touching these pixels (at each level: touching
        pixels reached by them) are left out. The rotations come from ``seed`` alone.
        """
        n = self.n_levels
        if not isinstance(n, numbers.Integral) or isinstance(n, bool) or n < 1:
            raise TGHopError(f"patch_levels must be a positive integer, got {n!r}")
        dec = np.asarray(dec, dtype=np.float32)
        rng = np.random.default_rng(seed)
        levels = _levels_of(dec, n, "reflect")
        d = PATCH * PATCH * dec.shape[2]
        self.rotations_ = _rotations(rng, len(levels) * ROTATIONS, d).reshape(len(levels), ROTATIONS, d, d)
        qlev = np.linspace(0.0, 1.0, QUANTILES)
        quantiles = np.empty((len(levels), ROTATIONS, d, QUANTILES))
        hole = None if exclude is None else np.asarray(exclude, dtype=bool)
        for i, img in enumerate(levels):
            x = _windows(img, PATCH)
            if hole is not None:
                keep = clean_windows(hole, PATCH).ravel()
                if keep.any():
                    x = x[keep]
                # The next level's mask: pixels whose 5-tap neighbourhood met a hole.
                hole = downsample(hole.astype(np.float32)[..., None])[..., 0] > 0
            if len(x) > _FIT_PATCHES:
                x = x[:: -(-len(x) // _FIT_PATCHES)]
            for r in range(ROTATIONS):
                proj = x @ self.rotations_[i, r].T.astype(np.float32)
                quantiles[i, r] = np.quantile(proj, qlev, axis=0).T
        self.quantiles_ = quantiles
        return self

    #: Fitted arrays in model files: (file name, attribute).
    _ARRAYS = (("patch.rotations", "rotations_"), ("patch.quantiles", "quantiles_"))

    def _to_arrays(self) -> dict:
        # float32 (half the file): generation computes in float32 anyway, so the same images.
        return {name: getattr(self, attr).astype(np.float32) for name, attr in self._ARRAYS}

    def _from_arrays(self, arrays):
        for name, attr in self._ARRAYS:
            setattr(self, attr, arrays[name].astype(np.float64, copy=False))
        return self

    def _array_specs(self, c):
        """Specs of :mod:`tghop.modelfile` for a model of ``c`` colour channels."""
        d = PATCH * PATCH * c

        def orthonormal(arr, dims):
            eye = np.eye(arr.shape[-1])
            if np.abs(arr @ np.swapaxes(arr, -1, -2) - eye).max() > 1e-6:
                return "holds a matrix that is not orthonormal"
            return None

        says = f"the metadata says at most {self.n_levels} levels of {PATCH}x{PATCH}x{c} patches"
        return (
            ("patch.rotations", ("Lp", ROTATIONS, d, d), "f", says, (("dim", 0, 1, self.n_levels), orthonormal)),
            ("patch.quantiles", ("Lp", ROTATIONS, d, QUANTILES), "f", says, (("nondecreasing",),)),
        )


def _match_columns(x, target):
    """Each column of ``x`` (n, D) given the distribution of the quantiles ``target`` (D, Q):
    histogram matching by ranks on a table of _BINS entries per column (as
    :func:`tghop.refine._match`, all columns at once). Returns a new (n, D) array."""
    n, d = x.shape
    lo = x.min(axis=0)
    hi = x.max(axis=0)
    span = np.maximum(hi - lo, np.float32(1e-12))
    scale = ((_BINS - 1) / span).astype(np.float32)
    pos = (x - lo) * scale
    pos += 0.5
    np.clip(pos, 0, _BINS - 1, out=pos)
    idx = pos.astype(np.int32)
    idx += (np.arange(d, dtype=np.int32) * _BINS)
    counts = np.bincount(idx.ravel(), minlength=d * _BINS).reshape(d, _BINS)
    mid = np.cumsum(counts, axis=1) - 0.5 * (counts + 1)
    mid *= (target.shape[1] - 1) / max(n - 1, 1)
    k = np.clip(mid.astype(np.int64), 0, target.shape[1] - 2)
    frac = mid - k
    rows = np.arange(d)[:, None]
    table = target[rows, k] * (1 - frac) + target[rows, k + 1] * frac
    return np.take(table.astype(x.dtype).ravel(), idx, mode="clip")


def _round(img, rot, target, tile, stride=1):
    """One round at one level: (H, W, C) image -> image with every pixel moved by the mean
    displacement its patches (every ``stride``-th position each way) get from matching
    their projections (pixels no patch covers stay)."""
    p = PATCH
    h, w, c = img.shape
    src = np.concatenate([img, img[: p - 1]], axis=0) if tile else img
    if tile:
        src = np.concatenate([src, src[:, : p - 1]], axis=1)
    win = np.lib.stride_tricks.sliding_window_view(src, (p, p), axis=(0, 1))[::stride, ::stride]
    hh, ww = win.shape[:2]
    x = np.ascontiguousarray(win.transpose(0, 1, 3, 4, 2)).reshape(-1, p * p * c)
    rot = rot.astype(np.float32)
    proj = x @ rot.T
    disp = (_match_columns(proj, target) - proj) @ rot  # (n, D): what each patch asks
    # (p, p, hh, ww, C): each offset's displacements contiguous for the sums below.
    disp = np.ascontiguousarray(disp.reshape(hh, ww, p, p, c).transpose(2, 3, 0, 1, 4))
    acc = np.zeros(src.shape, dtype=np.float32)
    count = np.zeros(src.shape[:2], dtype=np.float32)
    span_y, span_x = stride * (hh - 1) + 1, stride * (ww - 1) + 1
    for dy in range(p):
        for dx in range(p):
            acc[dy:dy + span_y:stride, dx:dx + span_x:stride] += disp[dy, dx]
            count[dy:dy + span_y:stride, dx:dx + span_x:stride] += 1.0
    if tile:  # fold the wrapped margin back
        for a in (acc, count):
            a[: p - 1] += a[h:]
            a[:, : p - 1] += a[:, w:]
        acc, count = acc[:h, :w], count[:h, :w]
    acc /= np.maximum(count, 1.0)[..., None]
    return img + acc


def patch_refine(dec, stats, *, n_iter=2, tile=False, stride=1):
    """Move an image's patch distribution towards the exemplar's, coarse to fine.

    Parameters
    ----------
    dec : ndarray, shape (H, W, C)
        The image in the decorrelated colours the statistics were fitted in (float32).
    stats : PatchStatistics
    n_iter : int
        Rounds per level (0: the image unchanged).
    tile : bool
        Periodic boundaries.
    stride : int
        Step between the patches moved at full resolution (1: every patch; 2: a quarter,
        each pixel still in about 9 of them); coarser levels move every patch.

    Returns
    -------
    ndarray, shape (H, W, C), float32
    """
    if not isinstance(n_iter, numbers.Integral) or isinstance(n_iter, bool) or n_iter < 0:
        raise TGHopError(f"patch_refine must be a non-negative integer, got {n_iter!r}")
    img = np.asarray(dec, dtype=np.float32)
    if img.ndim != 3 or img.shape[2] * PATCH * PATCH != stats.rotations_.shape[-1]:
        raise TGHopError(f"patch_refine: image of shape {img.shape} does not fit the patch statistics")
    if n_iter == 0 or min(img.shape[:2]) < PATCH:
        return img
    mode = "wrap" if tile else "reflect"
    levels = _levels_of(img, len(stats.rotations_), mode)
    target = stats.quantiles_.astype(np.float32)
    new = None
    for i in range(len(levels) - 1, -1, -1):
        cur = levels[i]
        if new is not None:  # the coarser level's change, upsampled
            cur = cur + upsample(new - levels[i + 1], cur.shape, mode)
        for r in range(n_iter):
            j = r % ROTATIONS
            cur = _round(cur, stats.rotations_[i, j], target[i, j], tile, stride if i == 0 else 1)
        new = cur
    return new


def fit_patch_statistics(levels, bands, image, *, exclude=None):
    """:class:`PatchStatistics` of an exemplar (H, W, C; float in [0, 1] or uint8): its
    centre crop of at most _FIT_SIDE squared, in the decorrelated colours of ``bands``
    (:class:`tghop.refine.BandStatistics`); None when ``levels`` is 0 (nothing stored)."""
    if not levels:
        return None
    h, w = image.shape[:2]
    y, x = max(0, (h - _FIT_SIDE) // 2), max(0, (w - _FIT_SIDE) // 2)
    crop = image[y:y + _FIT_SIDE, x:x + _FIT_SIDE].astype(np.float32)
    if image.dtype == np.uint8:
        crop *= np.float32(1.0 / 255.0)
    hole = None if exclude is None else exclude[y:y + _FIT_SIDE, x:x + _FIT_SIDE]
    return PatchStatistics(levels).fit(bands.to_decorrelated(crop), exclude=hole)


def refine_image(image, bands, stats, *, n_iter, tile=False, band_rounds=0, progress=None):
    """The generation step: an (H, W, C) image in [0, 1] -> :func:`patch_refine` in the
    decorrelated colours of ``bands``, clipped to [0, 1], then (``band_rounds`` > 0)
    min(band_rounds, BAND_ROUNDS_AFTER) rounds of the band refinement, since averaging
    overlapping patches softens detail. Same dtype as ``image``."""
    report(progress, "patch refine", 0, 1)
    dec = bands.to_decorrelated(np.asarray(image, dtype=np.float32))
    moved = bands.from_decorrelated(patch_refine(dec, stats, n_iter=n_iter, tile=tile, stride=FULL_STRIDE))
    out = np.clip(moved, 0.0, 1.0, out=moved).astype(image.dtype, copy=False)
    report(progress, "patch refine", 1, 1)
    if band_rounds:
        out = refine_bands(out, bands, n_iter=min(band_rounds, BAND_ROUNDS_AFTER), tile=tile, dtype=out.dtype)
    return out
