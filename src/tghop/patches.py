"""Stage 0: source patches, and the 2x2 block reshaping every hop uses.

Where the patches go: a fit (:meth:`tghop.synthesis.TGHop.fit`) takes them through the hops
(:mod:`tghop.hops`, each a :mod:`tghop.saab` transform) and the spatial reduction (:mod:`tghop.sdr`) to the core
model (:mod:`tghop.core`, ICHM), which learns their distribution. Generation goes the other way: new core vectors
back through the inverse SDR and hops to patches (:mod:`tghop.codec`, :mod:`tghop.pool`), which quilting
(:mod:`tghop.quilting`) stitches into an image; :func:`tghop.generation.synthesize` runs those steps in order.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ._arrays import check_int
from ._errors import TGHopError
from ._estimator import check_rng
from ._images import check_image
from .scale import scaled_shape

__all__ = ["extract_patches", "patch_origins", "clean_windows", "check_exclude", "enough_patches",
           "check_exemplar_size", "ExemplarTooSmallError", "TooLittleTextureError", "downsample_mask",
           "count_patches", "space_to_depth", "depth_to_space", "patch_grid", "stage_sheet"]


def _check_max_patches(max_patches):
    """``max_patches`` as an int, or None."""
    return None if max_patches is None else check_int(max_patches, "max_patches", 1)


def count_patches(shape, patch_size: int, stride: int) -> int:
    """Number of ``patch_size`` patches at ``stride`` in an image of ``shape`` (H, W, ...).

    Parameters
    ----------
    shape : tuple
        (H, W, ...) of the image.
    patch_size : int
        Side of the square patches, at least 1.
    stride : int
        Step between patch origins, at least 1.

    Returns
    -------
    int
        0 when the image is smaller than a patch on either side.
    """
    patch_size = check_int(patch_size, "patch_size", 1)
    stride = check_int(stride, "stride", 1)
    h, w = shape[:2]
    if h < patch_size or w < patch_size:
        return 0
    return ((h - patch_size) // stride + 1) * ((w - patch_size) // stride + 1)


def extract_patches(image, patch_size: int = 32, *, stride: int = 2, max_patches=None, rng=None) -> np.ndarray:
    """All ``patch_size`` x ``patch_size`` patches of an image at a given stride.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
        Float in [0, 1], ``H, W >= patch_size``.
    patch_size : int
        Side of the square patches, at least 2 (paper: 32).
    stride : int
        Step between patch origins, at least 1 (paper: 2, giving 113 x 113 = 12,769 patches
        of a 256 x 256 exemplar).
    max_patches : int, optional
        At least 1. If there are more patches than this, a random subset of this size is
        returned (in raster order), drawn with ``rng``. Bounds memory for large exemplars.
    rng : int or numpy.random.Generator, optional

    Returns
    -------
    ndarray, shape (n, patch_size, patch_size, C), float64
        Raster order of the patch origins.
    """
    patch_size = check_int(patch_size, "patch_size", 2)
    stride = check_int(stride, "stride", 1)
    img = check_image(image, min_size=patch_size)
    origins = patch_origins(img.shape, patch_size, stride=stride, max_patches=max_patches, rng=rng)
    windows = sliding_window_view(img, (patch_size, patch_size), axis=(0, 1))
    # windows: (H-P+1, W-P+1, C, P, P) -> (n, P, P, C)
    return np.ascontiguousarray(windows[origins[:, 0], origins[:, 1]].transpose(0, 2, 3, 1))


def patch_origins(shape, patch_size: int, *, stride: int = 2, max_patches=None, rng=None,
                  exclude=None) -> np.ndarray:
    """Top-left corners of the patches :func:`extract_patches` takes, in raster order.

    Parameters
    ----------
    shape : tuple
        (H, W, ...) of the image.
    patch_size, stride, max_patches, rng
        As :func:`extract_patches` (``patch_size`` at least 1 here). An image smaller than
        a patch has no patch origins.
    exclude : ndarray of bool, shape (H, W), optional
        Pixels no patch may touch (a sample mask: a logo, a label, a hole to inpaint):
        patches that overlap them are dropped before the ``max_patches`` subset is drawn.
        None: every patch (the same origins and the same draws as without the argument).

    Returns
    -------
    ndarray of int, shape (n, 2)
        (row, column) of each patch origin.
    """
    patch_size = check_int(patch_size, "patch_size", 1)
    stride = check_int(stride, "stride", 1)
    max_patches = _check_max_patches(max_patches)
    h, w = shape[:2]
    ys = np.arange(0, h - patch_size + 1, stride)
    xs = np.arange(0, w - patch_size + 1, stride)
    if exclude is None:
        allowed = np.arange(ys.size * xs.size)
    else:
        clean = clean_windows(exclude, patch_size)  # (H - P + 1, W - P + 1)
        allowed = np.flatnonzero(clean[ys[:, None], xs[None, :]].ravel())
    total = allowed.size
    if max_patches is not None and total > max_patches:
        index = allowed[np.sort(check_rng(rng).choice(total, size=max_patches, replace=False))]
    else:
        index = allowed
    rows, cols = np.divmod(index, xs.size)
    return np.column_stack([ys[rows], xs[cols]])


def clean_windows(exclude, size: int) -> np.ndarray:
    """Which ``size`` x ``size`` windows of a mask hold no excluded pixel.

    Parameters
    ----------
    exclude : array_like of bool, shape (H, W)
    size : int

    Returns
    -------
    ndarray of bool, shape (H - size + 1, W - size + 1)
        True at the top-left corner of every window without a True pixel of ``exclude``
        (from a summed-area table: linear time).
    """
    mask = np.asarray(exclude, dtype=bool)
    table = np.zeros((mask.shape[0] + 1, mask.shape[1] + 1), dtype=np.int64)
    np.cumsum(np.cumsum(mask, axis=0, dtype=np.int64), axis=1, out=table[1:, 1:])
    sums = table[size:, size:] - table[:-size, size:] - table[size:, :-size] + table[:-size, :-size]
    return sums == 0


def check_exclude(exclude, shape, *, name="exclude"):
    """A sample mask as an (H, W) bool array for an image of ``shape``, or None.

    None or a mask without a True pixel give None (nothing excluded: the same model as
    without a mask). An integer mask excludes its pixels above 0 (0/1, 0/255), a float one
    those above 0.5, as :func:`tghop.inpaint.inpaint`'s hole (a float mask of a grey or JPEG
    picture excluded its every faintly grey pixel). Raises :class:`TGHopError` for a mask of
    another size or not 2-d.

    Parameters
    ----------
    exclude : array_like, shape (H, W) or (H, W, 1), or None
        bool (True: excluded), integer or float; another dtype, NaN or infinite values raise
        :class:`TGHopError`.
    shape : tuple of int
        The image's shape, (H, W) or (H, W, C); only H and W are read.
    name : str
        The mask's name in the error messages.

    Returns
    -------
    ndarray of bool, shape (H, W), or None
        True where excluded; None when nothing is.
    """
    if exclude is None:
        return None
    mask = np.asarray(exclude)
    if mask.ndim == 3 and mask.shape[2] == 1:
        mask = mask[..., 0]
    if mask.ndim != 2 or mask.shape != tuple(shape[:2]):
        raise TGHopError(f"{name} must be a boolean (H, W) mask of the image's size {shape[0]}x{shape[1]}, "
                         f"got shape {mask.shape}; resize the mask to the image")
    if mask.dtype != bool:
        if mask.dtype.kind not in "biuf" or not np.isfinite(mask).all():
            raise TGHopError(f"{name} must be a boolean mask (True: excluded), got dtype {mask.dtype}")
        mask = mask > (0.5 if mask.dtype.kind == "f" else 0)
    return mask if mask.any() else None


class TooLittleTextureError(TGHopError):
    """A sample mask leaves too few training patches (:func:`enough_patches`). Its
    ``n_patches``, ``need`` and ``patch_size`` say how many, so that a caller can name its own
    fix (``tghop inpaint``: ``--source``)."""


class ExemplarTooSmallError(TGHopError):
    """An exemplar too small for its model's settings (:func:`check_exemplar_size`). Its
    ``least_side`` is the side of the smallest square exemplar that works (as given, before
    a working scale), so that a caller whose user gave no exemplar can word its own fix
    (``tghop extend``: IMAGE)."""


def enough_patches(n_patches, need, patch_size, per_cluster=None):
    """Raise a one-line :class:`TooLittleTextureError` when a mask leaves fewer than ``need``
    training patches; with ``per_cluster`` (ICHM's least cluster size) it names the N that fits.

    Parameters
    ----------
    n_patches : int
        Training patches the mask leaves.
    need : int
        The fewest the model needs.
    patch_size : int
        Their side, for the message (and the error's ``patch_size``).
    per_cluster : int, optional
        Least patches a cluster needs.
    """
    if n_patches < need:
        fewer = (f", or N of at most {n_patches // per_cluster} (n_clusters, --clusters)"
                 if per_cluster and n_patches >= per_cluster else "")
        exc = TooLittleTextureError(
            f"too little texture outside the mask: {n_patches} training patch{'es' if n_patches != 1 else ''} of "
            f"{patch_size}x{patch_size} avoid{'s' if n_patches == 1 else ''} it, at least {need} are needed; use a "
            f"smaller mask or a larger image{fewer}")
        exc.n_patches, exc.need, exc.patch_size = n_patches, need, patch_size
        raise exc


def _n_patches(shape, patch_size, stride, max_patches):
    """Training patches of an exemplar of ``shape`` (none when a side is below ``patch_size``:
    :func:`count_patches`' 0)."""
    n = count_patches(shape, patch_size, stride)
    return n if max_patches is None else min(n, int(max_patches))


def check_exemplar_size(shape, ichm, *, patch_size, stride, max_patches, scale=1.0):
    """Raise a one-line :class:`ExemplarTooSmallError` when an exemplar of ``shape`` gives too few
    training patches for ``ichm``, naming the smallest square exemplar that works (and a
    smaller stride, N or a larger scale where one would do).

    Parameters
    ----------
    shape : tuple
        (H, W, ...) of the exemplar.
    ichm : tghop.core.ICHM
        The core model of the settings (its ``n_clusters``, ``min_cluster_size`` and
        ``clusters_for``).
    patch_size, stride, max_patches
        The training patches' settings.
    scale : float
        The working scale (:mod:`tghop.scale`): the patches are those of the exemplar resampled
        by it; the message speaks of the exemplar as given.

    Notes
    -----
    A ``max_patches`` too small for any exemplar is left to :meth:`tghop.core.ICHM._check_params`.
    """
    def enough(shape, stride):
        n = _n_patches(shape, patch_size, stride, max_patches)
        return n >= ichm.clusters_for(n) * ichm.min_cluster_size

    given, shape = shape, scaled_shape(shape, scale)
    if enough(shape, stride):
        return
    n = _n_patches(shape, patch_size, stride, max_patches)
    most = ichm.clusters_for(2**62) * ichm.min_cluster_size  # no larger exemplar needs more

    def square(k):  # the smallest square exemplar with k patch positions a row
        return (patch_size + (k - 1) * stride,) * 2

    # The fewest positions a row that are enough, by bisection (one pixel at a time took
    # hours at a stride of 10^9).
    low, top = 1, math.isqrt(most - 1) + 1  # top * top >= most
    if not enough(square(top), stride):
        return  # max_patches caps the patches below the need: ICHM's message
    while low < top:
        mid = (low + top) // 2
        low, top = (low, mid) if enough(square(mid), stride) else (mid + 1, top)
    clusters = ichm.clusters_for(n)
    least = square(low)[0]
    side = math.ceil(least / scale)  # enough; a side resampled to round(side * scale) may be one less
    while side > 1 and scaled_shape((side - 1, side - 1), scale)[0] >= least:
        side -= 1
    fixes = [f"use an exemplar of at least {side}x{side} pixels"]
    # A stride beyond the exemplar's side gives one position a row, as that side does.
    smaller = next((s for s in range(min(stride - 1, max(shape[:2])), 0, -1) if enough(shape, s)), None)
    if smaller:
        fixes.append(f"a stride of {smaller} (stride, --stride)")
    if n >= ichm.min_cluster_size:
        fixes.append(f"N of at most {n // ichm.min_cluster_size} (n_clusters, --clusters)")
    if scale < 1:  # the least scale, in hundredths, at which the exemplar as given is enough
        larger = next((k / 100 for k in range(math.floor(scale * 100) + 1, 101)
                       if enough(scaled_shape(given, k / 100), stride)), None)
        if larger:
            fixes.append(f"a scale of at least {larger:g} (scale, --scale)")
    h, w = shape[:2]
    at = "" if scale == 1 else f" at scale {scale:g} (given {given[0]}x{given[1]})"
    auto = " (auto)" if ichm.n_clusters is None else ""
    exc = ExemplarTooSmallError(
        f"exemplar is {h}x{w} pixels{at}, {n} training patch{'es' if n != 1 else ''} of {patch_size}x{patch_size} "
        f"at stride {stride}, but N={clusters}{auto} cluster{'s' if clusters != 1 else ''} of at least "
        f"{ichm.min_cluster_size} need {clusters * ichm.min_cluster_size}; " + ", or ".join(fixes))
    exc.least_side = side
    raise exc


def downsample_mask(mask, factor):
    """(H // factor, W // factor) bool: True where any pixel of the box is.

    Parameters
    ----------
    mask : ndarray of bool, shape (H, W)
    factor : int
        Side of the boxes, at least 1.

    Returns
    -------
    ndarray of bool, shape (H // factor, W // factor)
    """
    factor = check_int(factor, "factor", 1)
    h, w = mask.shape[0] // factor, mask.shape[1] // factor
    return mask[: h * factor, : w * factor].reshape(h, factor, w, factor).any(axis=(1, 3))


def space_to_depth(x: np.ndarray, block: int = 2) -> np.ndarray:
    """Split each image into non-overlapping ``block`` x ``block`` blocks, flattened into channels.

    Parameters
    ----------
    x : ndarray, shape (n, H, W, C)
        ``H`` and ``W`` divisible by ``block``.
    block : int, default=2
        Side of the blocks.

    Returns
    -------
    ndarray, shape (n, H // block, W // block, block * block * C)
        The last axis is ordered (row in block, column in block, channel).
    """
    n, h, w, c = x.shape
    if h % block or w % block:
        raise TGHopError(f"spatial size {h}x{w} is not divisible by the block size {block}")
    y = x.reshape(n, h // block, block, w // block, block, c).transpose(0, 1, 3, 2, 4, 5)
    return y.reshape(n, h // block, w // block, block * block * c)


def depth_to_space(y: np.ndarray, block: int = 2) -> np.ndarray:
    """Inverse of :func:`space_to_depth`: ``(n, h, w, b*b*C)`` -> ``(n, h*b, w*b, C)``.

    Parameters
    ----------
    y : ndarray, shape (n, h, w, b*b*C)
        The last axis ordered (row in block, column in block, channel); any dtype.
    block : int
        The block side ``b``.

    Returns
    -------
    ndarray, shape (n, h*b, w*b, C)
        ``y``'s dtype (a copy, or a view where NumPy can make one).
    """
    n, h, w, d = y.shape
    c = d // (block * block)
    x = y.reshape(n, h, w, block, block, c).transpose(0, 1, 3, 2, 4, 5)
    return x.reshape(n, h * block, w * block, c)


def patch_grid(patches, *, n_cols=None, gap: int = 2, background: float = 1.0) -> np.ndarray:
    """Lay patches out in a grid image (for looking at generated samples).

    Parameters
    ----------
    patches : ndarray, shape (n, P, P, C) or (n, P, P)
        At least one patch.
    n_cols : int, optional
        Columns of the grid (at least 1); default about sqrt(n).
    gap : int
        Pixels between patches (at least 0).
    background : float
        Grey level of the gaps.

    Returns
    -------
    ndarray, shape (rows*(P+gap)-gap, n_cols*(P+gap)-gap, C)
    """
    p = np.asarray(patches, dtype=np.float64)
    if p.ndim == 3:
        p = p[..., None]
    if p.ndim != 4 or p.shape[0] == 0:
        raise TGHopError(f"patches must be a non-empty (n, P, P) or (n, P, P, C) array, got shape {p.shape}")
    n, ph, pw, c = p.shape
    gap = check_int(gap, "gap", 0)
    n_cols = max(1, int(np.ceil(np.sqrt(n)))) if n_cols is None else check_int(n_cols, "n_cols", 1)
    n_rows = int(np.ceil(n / n_cols))
    out = np.full((n_rows * (ph + gap) - gap, n_cols * (pw + gap) - gap, c), background)
    for i in range(n):  # one copy per patch, for display only
        r, q = divmod(i, n_cols)
        out[r * (ph + gap): r * (ph + gap) + ph, q * (pw + gap): q * (pw + gap) + pw] = p[i]
    return out


def stage_sheet(views, patch_size):
    """The paper's Fig. 6 as one image: a row per sample, each DC map (grey, enlarged to
    the patch size) then the patch.

    Parameters
    ----------
    views : dict of ndarray
        :meth:`tghop.TGHop.stage_views`: DC maps (n, h, w) by name, then ``"S0"``, the
        patches (n, P, P, C); a ``"cluster"`` entry (:meth:`tghop.TGHop.sample_patches`) is left out.
    patch_size : int

    Returns
    -------
    ndarray, shape (H, W, C)
        The sheet (:func:`patch_grid` of the rows).
    """
    columns = []
    for name, maps in views.items():
        if name == "cluster":  # labels, not an image
            continue
        if name == "S0":
            columns.append(maps)
            continue
        scale = patch_size // maps.shape[1]
        big = np.repeat(np.repeat(maps, scale, axis=1), scale, axis=2)
        grey = np.clip(big, 0.0, 1.0)[..., None]
        columns.append(np.repeat(grey, views["S0"].shape[3], axis=3))
    rows = np.stack(columns, axis=1).reshape((-1,) + views["S0"].shape[1:])
    return patch_grid(rows, n_cols=len(columns))
