"""Image quilting (Efros & Freeman 2001) of a pool of patches into an image of any size, each block
pasted along a minimum-error cut through its overlap (:func:`min_error_boundary_cut`; a wavefront's cuts
at once in ``quilt_prepared``); the steps in tone left across the cuts are removed by :mod:`tghop.seams`.

TGHop generates a *pool* of texture patches; :func:`quilt` stitches them into the output
image. It does not care where the patches come from: any ``(n, P, P, C)`` array works.
:func:`quilt` is :func:`prepare_pool` (what quilting needs from the pool alone) followed
by :func:`quilt_prepared` (placing the blocks), for callers that prepare the pool while
something else is being computed.

How it works
------------
Blocks of ``P x P`` pixels are laid on a grid with step ``P - overlap``. Each block takes
the pool patch whose *overlap* with the pixels already placed (a left strip, a top strip,
an L shape, and for tileable output also right/bottom strips) has a small squared error,
and is pasted along a minimum-error boundary cut through each overlap strip.

Speed: the overlap error of every pool patch at once is
``||o||^2 - 2 p.o + ||p||^2``; the pool's squared norms are precomputed for each of the
few possible overlap shapes, so a block costs one matrix product. Blocks are placed in
*wavefronts* ``2 * row + col``: a block only overlaps its 8 neighbours, and those that come
before it in raster order are all on earlier wavefronts, so every block of a wavefront is
matched at once with one matrix-matrix product (GEMM) and the result is the same as
placing them one by one in raster order.

Most of the pool is ruled out cheaply: a lower bound of each patch's error from sums over
2 x 2 boxes of the overlap (a tenth of its values) leaves, typically, a dozen of 5,000
patches whose full error could be within the tolerance of the best, and only theirs are
computed (:class:`_Boxes`; the same candidates, up to float32 round-off).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from ._arrays import LEVELS, check_dtype, check_int, check_number, from_levels
from ._errors import TGHopError
from ._estimator import check_rng
from ._images import MAX_PIXELS, check_size
from ._progress import ProgressCallback, report
from .seams import SeamSteps

__all__ = [
    "FLAT_PENALTY",
    "GUIDE_SCALE",
    "MAX_BLOCKS",
    "MAX_PIXELS",
    "POOL_CHUNK",
    "PreparedPool",
    "QuiltingPlan",
    "block_count",
    "block_labels",
    "boundary_cut_mask",
    "default_overlap",
    "flat_factors",
    "gradient_energy",
    "min_error_boundary_cut",
    "prepare_pool",
    "quilt",
    "quilt_prepared",
    "quilting_plan",
]

#: Largest number of blocks in one quilt (e.g. 2048 x 2048 pixels of 4 x 4 patches); the
#: plan keeps a few integers per block and quilting runs one step per wavefront.
MAX_BLOCKS = 2**22

# The 8 neighbours of a block, in a fixed order (the bits of a mask signature).
_OFFSETS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))
#: Default box size of the low pass that guided quilting compares with the guide.
GUIDE_SCALE = 4
#: Factor of the errors of the pool's flattest patches (``flat_share``): they win only
#: where they match this many times better than any other patch (docs/choices.md, Quilting).
FLAT_PENALTY = 2.0

# Pool patches are converted to float32 in chunks of this many patches (small enough for
# the chunk to stay in cache between the steps that read it, large enough that the
# per-chunk overhead stays small; any chunk size gives the same numbers).
POOL_CHUNK = 128


def default_overlap(patch_size: int) -> int:
    """The default overlap for ``patch_size``: ``round(P / 6)``, at least 1.

    Parameters
    ----------
    patch_size : int
        The patch side P (not checked).

    Returns
    -------
    int
        Pixels of overlap between neighbouring blocks.
    """
    return max(1, int(round(patch_size / 6)))


# ----------------------------------------------------------------------------- validation


def _check_patch_overlap(patch_size, overlap) -> Tuple[int, int]:
    p = check_int(patch_size, "patch size", 2)
    if overlap is None:
        return p, default_overlap(p)
    if isinstance(overlap, (bool, np.bool_)) or not isinstance(overlap, (numbers.Integral, np.integer)):
        raise TGHopError(f"overlap must be an integer number of pixels, got {overlap!r}")
    o = int(overlap)
    if not 1 <= o <= p // 2:
        fix = "1 or more" if o < 1 else f"{p // 2} or less, or fit with larger patches (patch_size, --patch-size)"
        raise TGHopError(f"the overlap (overlap, --overlap) must be between 1 and {p // 2} (half the patch size {p}), "
                         f"got {o}; give {fix}")
    return p, o


def _check_canvas(h: int, w: int, p: int) -> None:
    """Refuse an output whose quilting canvas (each side at least a patch) is above
    :data:`MAX_PIXELS`: a strip thinner than a patch is quilted (and refined) at the patch's
    height, so 1x67108864 would cost 32 times an 8192x8192 image."""
    ch, cw = max(h, p), max(w, p)
    if ch * cw > MAX_PIXELS:
        side = math.isqrt(MAX_PIXELS)
        raise TGHopError(
            f"size {h}x{w} is quilted on a canvas of {ch}x{cw} pixels (each side at least the patch size {p}), "
            f"{ch * cw:,} pixels, above the limit of {MAX_PIXELS:,} ({side}x{side}); "
            f"ask for a smaller image, or for one at least {p} pixels a side")


def _check_values(values: np.ndarray) -> None:
    """Raise unless ``values`` are finite and in [0, 1]."""
    if values.size == 0:
        return
    lo, hi = float(values.min()), float(values.max())
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise TGHopError("pool contains NaN or infinite values; clean it first")
    if lo < -1e-6 or hi > 1 + 1e-6:
        fix = "divide by 255 for 8-bit data" if lo >= 0 and hi <= 255 else "rescale them into [0, 1]"
        raise TGHopError(f"pool values must lie in [0, 1], got [{lo:.3g}, {hi:.3g}]; {fix}")


def _read_on_demand(pool) -> bool:
    """Whether ``pool`` is a pool object read on demand (shape, a NumPy dtype, indexing)
    rather than something to turn into an array."""
    if (isinstance(pool, (np.ndarray, list, tuple))
            or not all(hasattr(pool, a) for a in ("shape", "dtype", "__getitem__"))):
        return False
    try:
        np.dtype(pool.dtype)
    except TypeError:  # e.g. a PyTorch tensor: read as an array
        return False
    return True


def _check_pool(pool) -> np.ndarray:
    """Return the pool as a float32/float64 ``(n, P, P, C)`` array (no copy if possible),
    or a pool object read on demand as it is.

    Values are checked where they are read (:func:`_check_values`), which saves a pass
    over a large pool.
    """
    if _read_on_demand(pool):
        # A pool read as it is used (e.g. generated on demand): ``pool[a:b]`` in order while
        # preparing (the array may be reused by the next read) and ``pool[indices]``.
        shape = tuple(pool.shape)
        if (len(shape) != 4 or shape[1] != shape[2] or shape[3] < 1 or shape[0] < 1 or shape[1] < 2
                or np.dtype(pool.dtype) not in (np.float32, np.float64)):
            raise TGHopError(f"a pool read on demand must have shape (n, P, P, C) (n >= 1, P >= 2, C >= 1) "
                             f"and dtype float32 or float64, got {shape} {pool.dtype}")
        return pool
    arr = np.asarray(pool)
    if arr.ndim == 3:
        arr = arr[..., None]
    if arr.ndim != 4 or arr.shape[1] != arr.shape[2] or arr.shape[3] < 1:
        raise TGHopError(
            f"pool must have shape (n, P, P, C) with square P x P patches and C >= 1 channels, got {arr.shape}"
        )
    n, p = arr.shape[0], arr.shape[1]
    if n < 1:
        raise TGHopError("pool is empty; give at least one patch")
    if p < 2:
        raise TGHopError(f"pool patches are {p}x{p} pixels; they must be at least 2x2")
    if arr.dtype in LEVELS:
        arr = from_levels(arr, np.float32)
    elif arr.dtype not in (np.float32, np.float64):
        if arr.dtype.kind not in "biuf":
            raise TGHopError(f"pool has unsupported dtype {arr.dtype}; pass a float array in [0, 1]")
        arr = arr.astype(np.float64)
    return arr


# ----------------------------------------------------------------------------- boundary cut


def _dp_cut(error: np.ndarray) -> np.ndarray:
    """Minimum-cost top-to-bottom paths through ``error`` of shape ``(b, h, w)``.

    A path takes one column per row and moves at most one column between rows. Returns
    the ``(b, h)`` column indices. ``+inf`` entries are never used unless a row has no
    finite entry. Ties prefer going straight, then left.
    """
    b, h, w = error.shape
    n = b * (w + 2)
    # Each row of all strips laid out flat, every strip between two +inf columns, so that
    # a row's three neighbours above are shifts of one contiguous array (a strip never
    # reaches into the next; the same sums and minima as strip by strip, in fewer, larger
    # NumPy calls).
    cost = np.full((h, b, w + 2), np.inf)
    cost[:, :, 1:-1] = error.transpose(1, 0, 2)
    cost = cost.reshape(h, n)
    cum = np.full((h, n), np.inf)
    cum[0] = cost[0]
    best = np.empty(n - 2)
    for r in range(1, h):
        prev = cum[r - 1]
        np.minimum(prev[:-2], prev[1:-1], out=best)
        np.minimum(best, prev[2:], out=best)
        np.add(cost[r, 1:-1], best, out=cum[r, 1:-1])
    # The way back, as flat positions: straight, left or right, in the order ties are broken.
    start = np.arange(b) * (w + 2) + 1
    pos = start + np.argmin(cum[-1].reshape(b, w + 2)[:, 1:-1], axis=1)
    path = np.empty((h, b), dtype=np.intp)
    path[-1] = pos
    step = np.array([0, -1, 1])
    for r in range(h - 2, -1, -1):
        pos = pos + step[cum[r][pos[:, None] + step].argmin(axis=1)]
        path[r] = pos
    path -= start
    return path.T


def min_error_boundary_cut(error) -> np.ndarray:
    """Minimum-error boundary cut through a vertical overlap strip (dynamic programming).

    Parameters
    ----------
    error : array_like, shape (h, w) or (b, h, w)
        Per-pixel error (e.g. the squared difference summed over channels) between the
        old and the new patch over a vertical overlap strip ``h`` pixels high and ``w``
        wide. ``+inf`` marks pixels the cut must avoid. A batch of strips may be given.

    Returns
    -------
    ndarray of int, shape (h,) or (b, h)
        The column of the cut in each row: a connected path (consecutive rows differ by at
        most one column) with the smallest total error. Pixels left of the cut belong to
        the old patch (on the left), the cut pixel and those right of it to the new one.
        For a horizontal strip pass ``error.T``; for a strip whose old patch lies on the
        right pass ``error[:, ::-1]`` and mirror the result (``w - 1 - cut``).
    """
    arr = np.asarray(error, dtype=np.float64)
    if arr.ndim not in (2, 3) or arr.shape[-1] < 1 or arr.shape[-2] < 1:
        raise TGHopError(f"error must be a non-empty (h, w) or (b, h, w) array, got shape {arr.shape}")
    if np.isnan(arr).any():
        raise TGHopError("error contains NaN; compute it from finite images")
    path = _dp_cut(arr if arr.ndim == 3 else arr[None])
    return path if arr.ndim == 3 else path[0]


def _orient(x: np.ndarray, side: int) -> np.ndarray:
    """View ``(b, P, P)`` blocks so that overlap strip ``side`` (0 left, 1 top, 2 right,
    3 bottom) becomes a left strip: rows along axis 1, the old pixels towards column 0.
    The map is its own inverse."""
    if side == 1:
        return x.transpose(0, 2, 1)
    if side == 2:
        return x[:, :, ::-1]
    if side == 3:
        return x.transpose(0, 2, 1)[:, :, ::-1]
    return x


def _unorient(x: np.ndarray, side: int) -> np.ndarray:
    """Inverse of :func:`_orient`."""
    if side == 3:
        return x[:, :, ::-1].transpose(0, 2, 1)
    return _orient(x, side)


def _cut_masks(err: np.ndarray, strips: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Where each new block is pasted: ``(b, P, P)`` bool from pixel errors ``(b, P, P)``.

    ``strips`` ``(b, 4)`` are the (left, top, right, bottom) overlap widths (0 = none);
    ``keep`` ``(b, P, P)`` marks old pixels outside every strip, which stay as they are.
    All strips of all blocks go through one batched dynamic programme.
    """
    new = ~keep
    block, side = np.nonzero(strips > 0)
    if block.size == 0:
        return new
    p = err.shape[1]
    widths = strips[block, side]
    wmax = int(widths.max())
    batch = np.empty((block.size, p, wmax))
    for s in range(4):
        sel = np.flatnonzero(side == s)
        if sel.size:
            batch[sel] = _orient(err[block[sel]], s)[:, :, :wmax]
    batch[np.broadcast_to(np.arange(wmax) >= widths[:, None, None], batch.shape)] = np.inf
    cut = _dp_cut(batch)  # (k, p)
    keep_new = np.arange(p)[None, None, :] >= cut[:, :, None]  # (k, p, p), left-strip orientation
    for s in range(4):
        sel = np.flatnonzero(side == s)
        if sel.size:
            # A block has at most one strip per side, so block[sel] has no repeats.
            new[block[sel]] &= _unorient(keep_new[sel], s)
    return new


def boundary_cut_mask(error, *, left: int = 0, top: int = 0, right: int = 0, bottom: int = 0) -> np.ndarray:
    """Where a new block replaces the old pixels, given overlaps on up to four sides.

    Cuts each overlap strip along its minimum-error boundary
    (:func:`min_error_boundary_cut`) and combines them: ``left=o, top=o`` is the classic
    L-shaped overlap of image quilting.

    Parameters
    ----------
    error : array_like, shape (h, w)
        Per-pixel error between the old and new block; only the overlap strips are read.
    left, top, right, bottom : int
        Width in pixels of the overlap with already placed pixels on each side (0: none).

    Returns
    -------
    ndarray of bool, shape (h, w)
        True where the new block is kept, False where the old pixels stay.
    """
    arr = np.asarray(error, dtype=np.float64)
    if arr.ndim != 2 or arr.size == 0:
        raise TGHopError(f"error must be a non-empty (h, w) array, got shape {arr.shape}")
    if np.isnan(arr).any():
        raise TGHopError("error contains NaN; compute it from finite images")
    h, w = arr.shape
    mask = np.ones((h, w), dtype=bool)
    rows, cols = np.arange(h)[:, None], np.arange(w)[None, :]
    for name, value, limit in (("left", left, w), ("top", top, h), ("right", right, w), ("bottom", bottom, h)):
        check_int(value, f"{name} overlap", 0, limit)
    if left:
        cut = _dp_cut(arr[None, :, :left])[0]
        mask &= cols >= cut[:, None]
    if top:
        cut = _dp_cut(arr[None, :top, :].transpose(0, 2, 1))[0]
        mask &= rows >= cut[None, :]
    if right:
        cut = _dp_cut(arr[None, :, ::-1][:, :, :right])[0]
        mask &= cols <= (w - 1 - cut)[:, None]
    if bottom:
        cut = _dp_cut(arr[None, ::-1, :][:, :bottom, :].transpose(0, 2, 1))[0]
        mask &= rows <= (h - 1 - cut)[None, :]
    return mask


# ----------------------------------------------------------------------------- plan


@dataclass(frozen=True, eq=False)
class QuiltingPlan:
    """Where the blocks of a quilt go, in which order, and what each one overlaps.

    Blocks form a ``ny x nx`` grid; block ``(i, j)`` covers rows ``ys[i] : ys[i] + P`` and
    columns ``xs[j] : xs[j] + P`` of the canvas (modulo the canvas size when ``tile``).

    Attributes
    ----------
    size : (int, int)
        Output height and width.
    patch_size, overlap : int
        ``P`` and the requested overlap (with ``tile``, actual overlaps may be a pixel or
        so larger so that the blocks fit the period exactly).
    tile : bool
        Whether the output wraps around (the canvas is a torus of exactly ``size``).
    canvas_shape : (int, int)
        Working canvas; the output is its top-left ``size`` corner.
    ys, xs : ndarray of int, shapes (ny,), (nx,)
        Block positions.
    level : ndarray of int, shape (ny, nx)
        Wavefront of each block: blocks of one level do not overlap and only overlap
        blocks of earlier levels that come before them in raster order.
    n_levels : int
    mask_id : ndarray of int, shape (ny, nx)
        Index into ``masks`` of each block's overlap shape.
    masks : ndarray of bool, shape (m, P, P)
        Pixels of a block already covered when it is placed (its overlap).
    strips : ndarray of int, shape (m, 4)
        Widths of the (left, top, right, bottom) overlap strips cut by dynamic programming.
    keep : ndarray of bool, shape (m, P, P)
        Covered pixels in no strip (corners of diagonal neighbours only); they stay old.
    frame : (int, int, int, int)
        (left, top, right, bottom) widths of the frame of the block that holds every
        overlap; only these pixels of the pool patches are compared.
    """

    size: Tuple[int, int]
    patch_size: int
    overlap: int
    tile: bool
    canvas_shape: Tuple[int, int]
    ys: np.ndarray
    xs: np.ndarray
    level: np.ndarray
    n_levels: int
    mask_id: np.ndarray
    masks: np.ndarray
    strips: np.ndarray
    keep: np.ndarray
    frame: Tuple[int, int, int, int]

    @property
    def n_blocks(self) -> int:
        return int(self.level.size)

    @property
    def region(self) -> np.ndarray:
        """``(P, P)`` bool: the pixels of :attr:`frame`, which contain every overlap."""
        out = np.zeros((self.patch_size, self.patch_size), dtype=bool)
        for rows, cols in _frame_slices(self.patch_size, self.frame):
            out[rows, cols] = True
        return out


def _frame_slices(p: int, frame) -> list:
    """(rows, cols) slices of the 4 disjoint rectangles making up a frame (l, t, r, b).

    The top band and the left band come first: they hold every overlap except the
    wrap-around ones of tileable output (right and bottom).
    """
    left, top, right, bottom = frame
    parts = [
        (slice(0, top), slice(0, p)),
        (slice(top, p - bottom), slice(0, left)),
        (slice(p - bottom, p), slice(0, p)),
        (slice(top, p - bottom), slice(p - right, p)),
    ]
    return [(r, c) for r, c in parts if r.stop > r.start and c.stop > c.start]


def _frame_features(x: np.ndarray, slices, out: Optional[np.ndarray] = None) -> np.ndarray:
    """Flatten the frame pixels of blocks ``x`` ``(N, P, P, C)`` into ``(N, K)`` rows."""
    n = x.shape[0]
    parts = [x[:, r, c].reshape(n, -1) for r, c in slices]
    if out is None:
        return np.concatenate(parts, axis=1) if parts else np.zeros((n, 0), dtype=x.dtype)
    start = 0
    for part in parts:
        out[:, start : start + part.shape[1]] = part
        start += part.shape[1]
    return out


def _axis_positions(length: int, p: int, overlap: int, tile: bool, name: str):
    """Block starts along one axis and, per block, the overlap widths before and after it."""
    step = p - overlap
    if not tile:
        count = max(1, -(-(length - overlap) // step))
        starts = np.arange(count, dtype=np.int64) * step
        widths = np.full(count, overlap, dtype=np.int64)
        return starts, widths, widths, int((count - 1) * step + p)
    if length < p:
        raise TGHopError(
            f"a tileable output (tile, --tile) needs a {name} of at least the patch size {p}, got {length}; "
            "ask for a larger image, or fit with smaller patches (patch_size, --patch-size)"
        )
    # The blocks must fit the period exactly: spread `count` blocks evenly over `length`
    # (steps differ by at most one pixel). Use as many as needed for overlaps >= `overlap`,
    # and fewer if then a block would reach past its neighbour (two consecutive steps
    # shorter than a patch): each block must overlap only the next and previous ones.
    for count in range(-(-length // step), 1, -1):
        starts = (np.arange(count, dtype=np.int64) * length) // count
        steps = np.diff(np.append(starts, length))  # steps[k]: from block k to block k+1 (wrapping)
        if steps.max() <= p - 1 and (steps + np.roll(steps, -1)).min() >= p:
            after = p - steps
            before = np.roll(after, 1)
            return starts, before, after, length
    raise TGHopError(
        f"cannot tile an output {name} of {length} pixels with {p}-pixel patches and overlap {overlap}; "
        "change the size or the overlap"
    )


def block_count(size, patch_size: int, *, overlap: Optional[int] = None, tile: bool = False) -> int:
    """How many blocks :func:`quilting_plan` lays out (without the plan's masks).

    Parameters
    ----------
    size : (int, int) or int
        Output height and width (checked as :func:`quilt` checks them).
    patch_size : int
        The patch side P, at least 2.
    overlap : int, optional
        In ``[1, P // 2]``; default :func:`default_overlap`.
    tile : bool
        Tileable output (its last blocks overlap the first ones).

    Returns
    -------
    int
        ``ny * nx`` blocks; a bad size, patch size or overlap raises :class:`TGHopError`.
    """
    h, w = check_size(size)
    p, o = _check_patch_overlap(patch_size, overlap)
    _check_canvas(h, w, p)
    return len(_axis_positions(h, p, o, tile, "height")[0]) * len(_axis_positions(w, p, o, tile, "width")[0])


def _tile_levels(ny: int, nx: int) -> np.ndarray:
    """Wavefront levels on a torus: the longest chain of overlapping predecessors.

    Blocks are ordered by ``(2 i + j, i)`` (raster-like); each gets one more than the
    largest level of its overlapping predecessors. Runs one vectorised step per wavefront.
    """
    ii_all, jj_all = np.mgrid[0:ny, 0:nx]
    key = 2 * ii_all + jj_all
    rank = key * ny + ii_all
    level = np.full((ny, nx), -1, dtype=np.int64)
    for k in range(int(key.max()) + 1):
        ii = np.arange(max(0, -(-(k - nx + 1) // 2)), min(ny - 1, k // 2) + 1)
        if ii.size == 0:
            continue
        jj = k - 2 * ii
        lv = np.zeros(ii.size, dtype=np.int64)
        same_key = []
        for di, dj in _OFFSETS:
            ni, nj = (ii + di) % ny, (jj + dj) % nx
            earlier = rank[ni, nj] < rank[ii, jj]
            done = earlier & (key[ni, nj] < k)
            lv = np.where(done, np.maximum(lv, level[ni, nj] + 1), lv)
            same = earlier & (key[ni, nj] == k)
            if same.any():
                same_key.append((ni, nj, same))
        if same_key:  # rare (e.g. nx == 2 * ny - 1): resolve in order of increasing row
            for t in range(ii.size):
                for ni, nj, same in same_key:
                    if same[t]:
                        lv[t] = max(lv[t], level[ni[t], nj[t]] + 1)
                level[ii[t], jj[t]] = lv[t]
        else:
            level[ii, jj] = lv
    return level


def quilting_plan(size, patch_size: int, *, overlap: Optional[int] = None, tile: bool = False) -> QuiltingPlan:
    """Lay out the blocks of a quilt (no pixels involved).

    Parameters
    ----------
    size : (int, int) or int
        Output height and width.
    patch_size : int
        Side ``P`` of the square blocks.
    overlap : int, optional
        Overlap between neighbouring blocks, in ``[1, P // 2]``; default ``round(P / 6)``.
    tile : bool
        Plan a toroidal canvas so that the output wraps around seamlessly.

    Returns
    -------
    QuiltingPlan
    """
    h, w = check_size(size)
    p, o = _check_patch_overlap(patch_size, overlap)
    _check_canvas(h, w, p)
    tile = bool(tile)
    ys, up, down, hc = _axis_positions(h, p, o, tile, "height")
    xs, lw, rw, wc = _axis_positions(w, p, o, tile, "width")
    ny, nx = ys.size, xs.size
    if ny * nx > MAX_BLOCKS:
        raise TGHopError(
            f"a {h}x{w} quilt of {p}x{p} patches needs {ny * nx} blocks, above the limit of {MAX_BLOCKS}; "
            "use larger patches or a smaller size"
        )
    ii, jj = np.mgrid[0:ny, 0:nx]
    if tile:
        level = _tile_levels(ny, nx)
        rank = (2 * ii + jj) * ny + ii
    else:
        level = 2 * ii + jj
        rank = level
    # Which of the 8 neighbours are placed before each block -> bits of its overlap shape.
    bits = np.zeros((ny, nx), dtype=np.int64)
    for bit, (di, dj) in enumerate(_OFFSETS):
        ni, nj = ii + di, jj + dj
        if tile:
            earlier = rank[ni % ny, nj % nx] < rank
        else:
            inside = (ni >= 0) & (ni < ny) & (nj >= 0) & (nj < nx)
            earlier = inside & (rank[np.clip(ni, 0, ny - 1), np.clip(nj, 0, nx - 1)] < rank)
        bits |= earlier.astype(np.int64) << bit
    # Overlap shape of a block = (neighbour bits, row overlaps, column overlaps); the
    # overlaps depend only on the block's row (resp. column), so number those classes.
    row_cls, row_id = np.unique(np.stack([up, down], axis=1), axis=0, return_inverse=True)
    col_cls, col_id = np.unique(np.stack([lw, rw], axis=1), axis=0, return_inverse=True)
    n_col = col_cls.shape[0]
    code = bits + 256 * (row_id.reshape(-1)[ii] * n_col + col_id.reshape(-1)[jj])
    uniq, inverse = np.unique(code.ravel(), return_inverse=True)
    mask_id = inverse.reshape(ny, nx).astype(np.int32)

    m = uniq.size
    masks = np.zeros((m, p, p), dtype=bool)
    keep = np.zeros((m, p, p), dtype=bool)
    strips = np.zeros((m, 4), dtype=np.int64)
    frame = [0, 0, 0, 0]  # the smallest (left, top, right, bottom) frame holding every mask
    for k, c in enumerate(uniq.tolist()):
        b, rc = c % 256, c // 256
        wt, wb = (int(v) for v in row_cls[rc // n_col])
        wl, wr = (int(v) for v in col_cls[rc % n_col])
        for bit, (di, dj) in enumerate(_OFFSETS):
            if b >> bit & 1:
                # Corner rectangles lie in the full-width top and bottom bands.
                if di < 0:
                    frame[1] = max(frame[1], wt)
                elif di > 0:
                    frame[3] = max(frame[3], wb)
                elif dj < 0:
                    frame[0] = max(frame[0], wl)
                else:
                    frame[2] = max(frame[2], wr)
        row_span = {-1: slice(0, wt), 0: slice(0, p), 1: slice(p - wb, p)}
        col_span = {-1: slice(0, wl), 0: slice(0, p), 1: slice(p - wr, p)}
        for bit, (di, dj) in enumerate(_OFFSETS):
            if b >> bit & 1:
                masks[k, row_span[di], col_span[dj]] = True
        covered = np.zeros((p, p), dtype=bool)
        for side, (bit, width, span) in enumerate(
            ((3, wl, (slice(None), slice(0, wl))), (1, wt, (slice(0, wt), slice(None))),
             (4, wr, (slice(None), slice(p - wr, p))), (6, wb, (slice(p - wb, p), slice(None))))
        ):
            if b >> bit & 1:
                strips[k, side] = width
                covered[span] = True
        keep[k] = masks[k] & ~covered
    if frame[0] + frame[2] > p or frame[1] + frame[3] > p:
        # Opposite overlaps share pixels (tileable output about one patch wide): compare
        # whole patches.
        frame = [0, p, 0, 0]
    return QuiltingPlan(
        size=(h, w), patch_size=p, overlap=o, tile=tile, canvas_shape=(int(hc), int(wc)),
        ys=ys, xs=xs, level=level.astype(np.int32), n_levels=int(level.max()) + 1,
        mask_id=mask_id, masks=masks, strips=strips, keep=keep, frame=tuple(frame),
    )


# ----------------------------------------------------------------------------- guidance


def _box_means(x: np.ndarray, s: int) -> np.ndarray:
    """``(n, P, P, C)`` -> ``(n, (P/s)^2 C)`` float32 means of ``s x s`` boxes."""
    n, p, _, c = x.shape
    q = p // s
    # Sums of strided views, rows then columns: faster than ``mean`` over the two short
    # axes of a 6-d reshape (NumPy reduces short strided axes slowly), and rows first
    # (whole contiguous pixel rows added) faster than columns first.
    rows = x.reshape(n, q, s, p * c)
    acc = rows[:, :, 0].astype(np.float32)
    for k in range(1, s):
        acc += rows[:, :, k]
    cols = acc.reshape(n, q, q, s, c)
    out = cols[:, :, :, 0].copy()
    for k in range(1, s):
        out += cols[:, :, :, k]
    out *= np.float32(1.0 / (s * s))
    return out.reshape(n, -1)


def _check_guide_scale(scale, p: int) -> int:
    if isinstance(scale, bool) or not isinstance(scale, (numbers.Integral, np.integer)) or scale < 1 or p % scale:
        raise TGHopError(f"guide_scale must be a positive integer dividing the patch size {p}, got {scale!r}")
    return int(scale)


def _guide_setup(guide, weight, prepared):
    """The guide's low pass at every block and per-shape weights, for guided quilting."""
    arr, plan, scale = prepared.patches, prepared.plan, prepared.guide_scale
    p, c = arr.shape[1], arr.shape[3]
    g = np.asarray(guide, dtype=np.float32)
    if g.ndim == 2:
        g = g[..., None]
    if g.shape != (*plan.size, c):
        raise TGHopError(f"guide must have the output's shape {(*plan.size, c)}, got {g.shape}")
    check_number(weight, "guide_weight")
    if scale is None:
        raise TGHopError("this pool was prepared without a guide_scale; give prepare_pool a guide_scale to quilt "
                         "with a guide")
    # Per-pixel weights: overlap SSE + weight * (overlap pixels / low-pass values) * guide SSE.
    n_overlap = np.maximum(prepared._masks_f.sum(axis=1), p * plan.overlap)  # (m,)
    factor = (float(weight) * n_overlap / (p // scale) ** 2).astype(np.float32)
    return {"low": prepared._low, "low_norm": prepared._low_norm, "targets": _all_targets(g, plan, scale),
            "factor": factor}


def _all_targets(guide, plan, s):
    """``(ny, nx, L)``: the guide's low pass at every block (``s x s`` box means of the
    block's window, as :func:`_box_means` of the window: the same sums in the same order).

    One block row at a time: its rows of boxes summed over the whole width, then the
    boxes of every block of the row, made ahead of quilting instead of window copies and
    box means on quilting's path. Windows
    past the canvas wrap around (tileable output) or, past a larger canvas than the
    output, take the edge rows and columns (as the canvas's own edge padding would).
    """
    p = plan.patch_size
    hc, wc = plan.canvas_shape
    h, w = plan.size
    q = p // s
    c = guide.shape[2]
    offsets = np.arange(p).reshape(q, s)  # box a, row k of it
    if plan.tile:
        cols = (plan.xs[:, None, None] + offsets[None]) % wc
    else:
        cols = np.minimum(plan.xs[:, None, None] + offsets[None], w - 1)
    out = np.empty((plan.ys.size, plan.xs.size, q, q, c), dtype=np.float32)
    for i, y in enumerate(plan.ys.tolist()):
        rows = (y + offsets) % hc if plan.tile else np.minimum(y + offsets, h - 1)
        acc = guide[rows[:, 0]].astype(np.float32)  # (q, W, C): each box row's sum, in row order
        for k in range(1, s):
            acc += guide[rows[:, k]]
        boxes = acc[:, cols]  # (q, nx, q, s, C)
        total = boxes[:, :, :, 0].copy()
        for k in range(1, s):
            total += boxes[:, :, :, k]
        total *= np.float32(1.0 / (s * s))
        out[i] = total.transpose(1, 0, 2, 3)
    return out.reshape(plan.ys.size, plan.xs.size, -1)


def _guide_distances(guided, target, factor):
    """``(n, b)``: each pool patch's guide distance to ``target`` (b, L), times ``factor`` (b,)."""
    dist = guided["low"] @ (-2.0 * target).T
    dist += guided["low_norm"][:, None]
    dist += np.einsum("ij,ij->i", target, target)[None, :]
    dist *= factor[None, :]
    return dist


# ----------------------------------------------------------------------------- error bound


@dataclass(frozen=True, eq=False)
class _Boxes:
    """Small boxes of the overlap frame, for a cheap lower bound of the overlap error.

    The frame's pixels (all channels) are grouped into boxes of at most 2 x 2 pixels that
    lie wholly inside or outside each overlap shape. The box sums of a difference ``d``,
    each divided by the square root of its box's size, are its coordinates along
    orthonormal directions, so their squares add up to at most ``||d||^2`` (Cauchy-Schwarz
    per box): a lower bound of the overlap error at a tenth of the columns.

    Attributes
    ----------
    members : list of ndarray of int, shapes (g_s, s)
        The frame features of each box, for the boxes of each size ``s`` (g boxes in all,
        in this order).
    scale : ndarray of float32, shape (g,)
        ``1 / sqrt(box size)``.
    in_mask : ndarray of float32, shape (m, g)
        1 where the box lies in overlap shape ``j``.
    """

    members: list
    scale: np.ndarray
    in_mask: np.ndarray


def _overlap_boxes(masks_fc: np.ndarray, slices, p: int, c: int) -> _Boxes:
    """The boxes of the frame given by ``slices`` for overlap shapes ``masks_fc`` (m, k)."""
    rows, cols = np.mgrid[0:p, 0:p]
    y = _frame_features(np.broadcast_to(rows[None, :, :, None], (1, p, p, c)), slices)[0]
    x = _frame_features(np.broadcast_to(cols[None, :, :, None], (1, p, p, c)), slices)[0]
    covered = masks_fc > 0  # (m, k)
    # Key of a feature: the shapes its pixel belongs to (as bytes), then its 2 x 2 cell; a
    # box per distinct key. (Sorted, not np.unique, which imports numpy.ma, a slow import.)
    keys = np.vstack([np.packbits(covered, axis=0).astype(np.int64), y[None] // 2, x[None] // 2])
    order = np.lexsort(keys)  # features box by box
    ordered = keys[:, order]
    box = np.empty_like(order)
    box[order] = np.cumsum(np.concatenate(([False], (ordered[:, 1:] != ordered[:, :-1]).any(axis=0))))
    sizes = np.bincount(box)
    starts = np.cumsum(sizes) - sizes
    members, firsts = [], []
    for size in sorted(set(sizes.tolist())):  # one gather-and-sum per box size
        which = np.flatnonzero(sizes == size)
        members.append(order[starts[which, None] + np.arange(size)])
        firsts.append(members[-1][:, 0])
    first = np.concatenate(firsts) if firsts else np.zeros(0, dtype=np.intp)
    scale = (np.concatenate([np.full(len(mb), 1.0 / math.sqrt(mb.shape[1])) for mb in members]) if members
             else np.zeros(0))
    return _Boxes(members=members, scale=scale.astype(np.float32), in_mask=covered[:, first].astype(np.float32))


def _box_sums(features: np.ndarray, boxes: _Boxes) -> np.ndarray:
    """``(N, k)`` frame features -> ``(N, g)`` scaled box sums (float32)."""
    if not boxes.members:  # no frame (an output within one patch)
        return np.zeros((features.shape[0], 0), dtype=np.float32)
    out = np.concatenate([features[:, mb].sum(axis=2) for mb in boxes.members], axis=1)
    out *= boxes.scale
    return out


# ----------------------------------------------------------------------------- quilting


def _window(y: int, x: int, p: int, hc: int, wc: int):
    """Index of the ``p x p`` block at ``(y, x)`` of a canvas, wrapping around its edges."""
    rows = slice(y, y + p) if y + p <= hc else np.arange(y, y + p) % hc
    cols = slice(x, x + p) if x + p <= wc else np.arange(x, x + p) % wc
    if not isinstance(rows, slice) and not isinstance(cols, slice):
        rows = rows[:, None]  # both wrap: index the outer product
    return rows, cols


def _pool_table(arr: np.ndarray, slices, masks_fc: np.ndarray, boxes: _Boxes, *, energy: bool = False,
                guide_scale: Optional[int] = None):
    """The pool's rows for the overlap error and its lower bound, and its gradient energies
    and low-pass values: all in one pass over the pool.

    Returns ``table`` ``(n, m + k)`` float32: each patch's squared norm over each of the
    ``m`` overlap shapes, then its ``k`` frame values (channels innermost); ``bound``
    ``(n, m + g [+ l + 1])``: the same for its ``g`` scaled box sums (:class:`_Boxes`),
    then with ``guide_scale`` its ``l`` low-pass values (:func:`_box_means`) and their
    squared norm; and ``energy`` ``(n,)`` (:func:`gradient_energy`) or None.

    The pool is worked through :data:`POOL_CHUNK` patches at a time, every step of a
    chunk done while it is in cache: the pool is read from memory once, not once per step
    (and a pool generated on demand is never whole).
    """
    n, p, _, c = arr.shape
    m, k = masks_fc.shape
    g = boxes.scale.size
    n_low = 0 if guide_scale is None else (p // guide_scale) ** 2 * c
    table = np.empty((n, m + k), dtype=np.float32)
    bound = np.empty((n, m + g + (n_low + 1 if guide_scale is not None else 0)), dtype=np.float32)
    energies = np.empty(n, dtype=np.float32) if energy else None
    squares = np.empty((min(n, POOL_CHUNK), k), dtype=np.float32)
    for a in range(0, n, POOL_CHUNK):
        e = min(n, a + POOL_CHUNK)
        chunk = arr[a:e]
        rows = table[a:e, m:]
        _frame_features(chunk, slices, out=rows)
        _check_values(rows)
        sq = np.square(rows, out=squares[: e - a])
        np.matmul(sq, masks_fc.T, out=table[a:e, :m])
        sums = bound[a:e, m : m + g]
        sums[...] = _box_sums(rows, boxes)
        np.matmul(np.square(sums), boxes.in_mask.T, out=bound[a:e, :m])
        if energy:
            energies[a:e] = gradient_energy(chunk)
        if guide_scale is not None:
            low = bound[a:e, m + g : m + g + n_low]
            low[...] = _box_means(chunk, guide_scale)
            np.einsum("ij,ij->i", low, low, out=bound[a:e, -1])
    return table, bound, energies


def flat_factors(energy, share: float) -> np.ndarray:
    """The factors of a pool's errors for ``flat_share``: :data:`FLAT_PENALTY` for the
    ``round(share * n)`` patches of least gradient ``energy`` (n,) (those below the next
    one's), 1 for the rest; float32 (n,).

    Parameters
    ----------
    energy : array_like, shape (n,)
        Each patch's gradient energy (:func:`gradient_energy`).
    share : float
        ``flat_share``, in [0, 1) (not checked here); at most ``n - 1`` patches are flat.

    Returns
    -------
    ndarray of float32, shape (n,)
        :data:`FLAT_PENALTY` or 1.
    """
    energy = np.asarray(energy)
    flat = np.zeros(energy.shape, dtype=bool)
    k = min(int(round(share * energy.size)), energy.size - 1)
    if k > 0:  # np.partition, not np.quantile: that imports numpy.ma (generation keeps it out)
        flat = energy < np.partition(energy, k)[k]
    return np.where(flat, np.float32(FLAT_PENALTY), np.float32(1.0))


def gradient_energy(arr: np.ndarray) -> np.ndarray:
    """Mean squared difference of neighbouring pixels of each patch (quilting's ``detail`` and
    ``flat_share`` rank patches by it).

    Parameters
    ----------
    arr : ndarray, shape (n, P, P, C)

    Returns
    -------
    ndarray, shape (n,), float32
    """
    arr = np.asarray(arr)
    n = len(arr)
    out = np.empty(n, dtype=np.float32)
    # POOL_CHUNK patches at a time: the differences of a chunk stay in cache and their buffers are
    # reused, instead of two copies of the whole pool (fresh memory each call); each patch's value
    # is computed as it is alone, so chunks change no bit.
    for a in range(0, n, POOL_CHUNK):
        x = np.asarray(arr[a : a + POOL_CHUNK], dtype=np.float32)
        m = len(x)
        dy = (x[:, 1:] - x[:, :-1]).reshape(m, -1)  # vertical neighbours
        dx = (x[:, :, 1:] - x[:, :, :-1]).reshape(m, -1)  # horizontal
        # Means of squares as row-wise dot products: one pass each, no squared copies
        # (the same as square and mean up to float32 round-off).
        out[a : a + m] = (np.einsum("ij,ij->i", dy, dy) / np.float32(dy.shape[1])
                          + np.einsum("ij,ij->i", dx, dx) / np.float32(dx.shape[1]))
    return out


def _exact_errors(prepared, query, onorm, k1, wraps, target, factor, pool_idx, block_idx):
    """Overlap error (plus guide distance) of pool patch ``pool_idx[i]`` at block
    ``block_idx[i]``; ``wraps`` (b,): the blocks that also overlap the columns from ``k1`` on."""
    table = prepared._table
    err = np.einsum("ij,ij->i", table[pool_idx, :k1], query[block_idx, :k1])
    err += onorm[block_idx]
    w = np.flatnonzero(wraps[block_idx])
    if w.size:
        err[w] += np.einsum("ij,ij->i", table[pool_idx[w], k1:], query[block_idx[w], k1:])
    if target is not None:
        diff = prepared._low[pool_idx] - target[block_idx]
        err += factor[block_idx] * np.einsum("ij,ij->i", diff, diff)
    return err


def _full_errors(table, query, k1, wraps, guided, target, factor):
    """Every pool patch's error against every block of a wavefront, less the blocks'
    constant ``onorm`` (pool x blocks): the overlap columns, the wrapped columns of the
    blocks that wrap and the guide term; when the bound rules out too few patches."""
    err = table[:, :k1] @ query[:, :k1].T
    sel = np.flatnonzero(wraps)
    if sel.size:
        err[:, sel] += table[:, k1:] @ query[sel, k1:].T
    if target is not None:
        err += _guide_distances(guided, target, factor)
    return err


def _bounded_candidates(prepared, o, query, onorm, k1, wraps, target, factor, tolerance, slack, penalty=None):
    """The candidates of :func:`quilt_prepared`'s rule, with full errors only where needed.

    A lower bound of every pool patch's error (the box sums of :class:`_Boxes` instead of
    the overlap pixels: a tenth of the columns; the guide distance in full, to ``target``
    (b, L) times ``factor`` (b,)) is compared with the full error of the patch with the
    smallest bound, an upper bound of the best error. Only the patches whose lower bound
    is within the tolerance of it (typically a dozen of 5,000) can be candidates; their
    full errors decide, by the same rule as without the bound, so the candidates are the
    same (up to float32 round-off).

    With ``penalty`` (n,) (factors >= 1 of each patch's error, for reuse), the rule
    applies to the penalised errors: a factor >= 1 times a lower bound is a lower bound
    of the penalised error (also where the bound is negative), and the penalised full
    error of the patch with the smallest penalised bound an upper bound of the best.

    Returns
    -------
    (pool_idx, block_idx) : ndarrays of int
        The candidates, ordered by block then pool index; None when the bound leaves more
        than an eighth of all (patch, block) pairs (e.g. the first block, which overlaps
        nothing).
    """
    boxes, bound = prepared._boxes, prepared._bound
    m, g = boxes.in_mask.shape
    n, b = bound.shape[0], o.shape[0]
    sums = _box_sums(o, boxes)  # zero outside each block's own shape (o is masked)
    # One product against the pool's [norms per shape | box sums | low pass | its norm].
    lb_query = np.empty((b, bound.shape[1]), dtype=np.float32)
    lb_query[:, :m] = query[:, :m]
    np.multiply(sums, -2.0, out=lb_query[:, m : m + g])
    offset = np.einsum("ij,ij->i", sums, sums)
    if target is not None:
        np.multiply(target, (-2.0 * factor)[:, None], out=lb_query[:, m + g : -1])
        lb_query[:, -1] = factor
        offset += factor * np.einsum("ij,ij->i", target, target)
    # (b, n), as the transpose of (n, b): the pool's matrix, the large operand, on the
    # product's left, which OpenBLAS reads faster (measured: docs/choices.md).
    lower = (bound @ lb_query.T).T
    lower += offset[:, None]
    if penalty is not None:
        lower *= penalty
        slack = slack * penalty.max()
    first = lower.argmin(axis=1)
    blocks = np.arange(b)
    upper = _exact_errors(prepared, query, onorm, k1, wraps, target, factor, first, blocks)
    if penalty is not None:
        upper *= penalty[first]
    # Twice the slack: the bound's own round-off; and never below the smallest bound, so
    # that every block keeps at least that patch.
    limit = np.maximum(np.maximum(upper, 0.0) * (1.0 + tolerance) + 2.0 * slack, lower[blocks, first])
    # Flat indices, then (block, patch): np.nonzero of a 2-d array is much slower than of a
    # flat one; the same pairs in the same order.
    block_idx, pool_idx = np.divmod(np.flatnonzero(lower <= limit[:, None]), n)
    if pool_idx.size > n * b // 8:
        return None
    err = _exact_errors(prepared, query, onorm, k1, wraps, target, factor, pool_idx, block_idx)
    if penalty is not None:
        err *= penalty[pool_idx]
    best = np.full(b, np.inf, dtype=err.dtype)
    np.minimum.at(best, block_idx, err)
    keep = err <= np.maximum(best, 0.0)[block_idx] * (1.0 + tolerance) + slack[block_idx]
    return pool_idx[keep], block_idx[keep]


def quilt(
    pool,
    size,
    *,
    overlap: Optional[int] = None,
    tolerance: float = 0.1,
    tile: bool = False,
    detail: float = 0.0,
    rng=None,
    progress: Optional[ProgressCallback] = None,
    guide=None,
    guide_weight: float = 1.0,
    guide_scale: int = GUIDE_SCALE,
    reuse: float = 0.0,
    flat_share: float = 0.0,
) -> np.ndarray:
    """Stitch patches from ``pool`` into an image by image quilting (Efros & Freeman 2001).

    Parameters
    ----------
    pool : array_like, shape (n, P, P, C) or (n, P, P)
        Candidate patches, floats in [0, 1] (uint8 is rescaled), ``C`` = 1 or 3, ``P >= 2``.
        float32 pools are used without a copy.
    size : (int, int) or int
        Output height and width, any size up to :data:`MAX_PIXELS` pixels (also smaller
        than a patch). With ``tile`` both must be at least ``P``.
    overlap : int, optional
        Overlap between neighbouring blocks in pixels, in ``[1, P // 2]``; default
        ``round(P / 6)`` (at least 1).
    tolerance : float
        Each block takes a patch chosen uniformly at random among those whose overlap error
        is at most ``(1 + tolerance)`` times the best one; 0 takes the best match.
    tile : bool
        Make the output tileable: it wraps around seamlessly (the last blocks of each row
        and column also overlap, are matched with and cut into the first ones).
    detail : float in [0, 1)
        Counter the preference of the overlap error for smooth patches: among the
        candidates within the tolerance, choose only from those whose gradient energy
        (mean squared difference of neighbouring pixels over the whole patch) is at or
        above this quantile of the candidates' (0: all candidates, Efros & Freeman).
    rng : None, int or numpy.random.Generator
        Seed; the same seed gives the same image.
    progress : callable, optional
        ``progress("quilting", done, total)`` after each wavefront of blocks.
    guide : array_like, shape (H, W, C), optional
        A target layout (e.g. an upsampled coarse synthesis, :mod:`tghop.layout`): guided
        quilting as in Efros & Freeman's texture transfer. Each candidate's error also
        counts the squared distance between its low-pass version (``guide_scale`` x
        ``guide_scale`` box means) and the guide's at the block's place.
    guide_weight : float
        Weight of the guide term per pixel relative to the overlap error per pixel
        (0: the guide is ignored).
    guide_scale : int
        Box size of the low pass compared with the guide; divides ``P``.
    reuse : float
        Reuse penalty (ours; 0: none, Efros & Freeman): every error of a patch already
        placed ``u`` times is multiplied by ``1 + reuse * u`` (counted after each
        wavefront), so that a large image does not repeat the same few (mostly smooth)
        patches; the tolerance then applies to the penalised errors.
    flat_share : float in [0, 1)
        Counter the same preference in the pool (ours; 0: off, Efros & Freeman): the errors
        of this share of the pool, its patches of least gradient energy, count
        :data:`FLAT_PENALTY` times, so a flat patch is placed only where it matches that
        much better than any other (generated patches are blurrier than the exemplar's,
        the flattest most).

    Returns
    -------
    ndarray, shape (H, W, C), float64 in [0, 1]

    Raises
    ------
    TGHopError
        For a pool of the wrong shape or with values outside [0, 1] or NaN (values are
        checked where they are read: the overlap frame of every patch and each patch
        used), a size that is not positive or above :data:`MAX_PIXELS`, an overlap outside
        ``[1, P // 2]``, a negative tolerance, or ``tile`` with a size smaller than ``P``.

    Notes
    -----
    Cost: one pass over a tenth of the pool's overlap values (their box sums, float32)
    per wavefront, about ``2 * ny + nx`` of them for a ``ny x nx`` grid of blocks, and
    the full errors of the few patches that bound leaves; the products go through BLAS,
    whose threads can be limited with ``threadpoolctl``. Memory: the float32 overlap
    table of the pool (``n`` rows of about ``2 P overlap C`` values, twice that with
    ``tile``) and its box sums, ``n x`` (blocks per wavefront) bounds, a float32 canvas
    and the float64 result; per block the plan keeps only a few integers.
    """
    check_number(tolerance, "tolerance")
    prepared = prepare_pool(pool, size, overlap=overlap, tile=tile, detail=detail, flat_share=flat_share,
                            guide_scale=None if guide is None else guide_scale)
    return quilt_prepared(prepared, tolerance=tolerance, rng=rng, progress=progress, guide=guide,
                          guide_weight=guide_weight, reuse=reuse)


@dataclass(frozen=True, eq=False)
class PreparedPool:
    """A patch pool made ready for quilting one image: :func:`prepare_pool`'s result.

    What depends only on the pool and the block layout (each patch's values in the
    overlap frame and squared norms, their box sums for the error bound, gradient
    energy, low-pass values for a guide) is
    computed once here, so that it can be done while something else (e.g. the guide) is
    still being made; :func:`quilt_prepared` then places the blocks.

    Attributes
    ----------
    patches : ndarray, shape (n, P, P, C)
        The pool as given (float32 or float64; no copy), or a pool object read on demand.
    plan : QuiltingPlan
    detail : float
    guide_scale : int or None
        Box size of the low pass compared with a guide; None: quilting without a guide.
    flat_factor : ndarray, shape (n,), float32, or None
        Factor of each pool patch's errors (``flat_share``: :data:`FLAT_PENALTY` or 1);
        None: all 1.
    """

    patches: np.ndarray
    plan: QuiltingPlan
    detail: float
    guide_scale: Optional[int]
    flat_factor: Optional[np.ndarray]
    _slices: list
    _masks_f: np.ndarray
    _masks_fc: np.ndarray
    _table: np.ndarray
    _boxes: _Boxes
    _bound: np.ndarray
    _energy: Optional[np.ndarray]
    _low: Optional[np.ndarray]
    _low_norm: Optional[np.ndarray]


def prepare_pool(pool, size, *, overlap: Optional[int] = None, tile: bool = False, detail: float = 0.0,
                 guide_scale: Optional[int] = None, flat_share: float = 0.0) -> PreparedPool:
    """Precompute what quilting ``pool`` into an image of ``size`` needs from the pool alone.

    Parameters are those of :func:`quilt` (``guide_scale=None``: no guide will be used).
    ``quilt(pool, size, ...)`` is ``quilt_prepared(prepare_pool(pool, size, ...), ...)``.

    Parameters
    ----------
    pool : array_like, shape (n, P, P, C) or (n, P, P), or a pool read on demand
        Candidate patches in [0, 1] (:func:`quilt`'s ``pool``).
    size : (int, int) or int
        Output height and width.
    overlap : int, optional
    tile : bool
    detail : float in [0, 1)
    guide_scale : int, optional
        Box size of the guide's low pass, dividing P; None: no guide will be used.
    flat_share : float in [0, 1)

    Returns
    -------
    PreparedPool
        Holds the float32 overlap table of the pool (``n`` rows of about ``2 P overlap
        C`` values), its box sums (about a tenth of that) and, with ``detail > 0`` /
        ``guide_scale``, ``n`` gradient energies / ``n (P / guide_scale)^2 C`` low-pass
        values; with ``flat_share > 0`` the factors of the flattest patches' errors.
    """
    arr = _check_pool(pool)
    p, c = arr.shape[1], arr.shape[3]
    if isinstance(detail, bool) or not isinstance(detail, numbers.Real) or not 0 <= detail < 1:
        raise TGHopError(f"detail must be a number in [0, 1), got {detail!r}")
    detail = float(detail)
    if isinstance(flat_share, bool) or not isinstance(flat_share, numbers.Real) or not 0 <= flat_share < 1:
        raise TGHopError(f"flat_share must be a number in [0, 1), got {flat_share!r}")
    plan = quilting_plan(size, p, overlap=overlap, tile=tile)
    scale = None if guide_scale is None else _check_guide_scale(guide_scale, p)
    # One float32 row per pool patch: [squared norm over each of the m overlap shapes |
    # the patch's pixels in the overlap frame]. With a block's query row
    # [one-hot of its shape | -2 * its masked overlap pixels], a single matrix product gives
    # ||p||^2 - 2 p.o for every patch p; adding ||o||^2 gives the overlap error.
    slices = _frame_slices(p, plan.frame)
    masks_f = _frame_features(plan.masks[..., None], slices).astype(np.float32)  # (m, nf)
    masks_fc = np.repeat(masks_f, c, axis=1)  # (m, nf * c), matches the (pixel, channel) layout
    boxes = _overlap_boxes(masks_fc, slices, p, c)
    # The low pass and its norm (with a guide) are the bound's last columns (views into them).
    table, bound, energy = _pool_table(arr, slices, masks_fc, boxes, energy=detail > 0 or flat_share > 0,
                                       guide_scale=scale)
    flat = flat_factors(energy, flat_share) if flat_share else None
    energy = energy if detail > 0 else None  # without a detail preference the choice keeps pool order
    low = low_norm = None
    if scale is not None:  # the columns after the m overlap shapes' bounds and the g box sums
        start = len(masks_fc) + boxes.scale.size
        low, low_norm = bound[:, start:-1], bound[:, -1]
    return PreparedPool(patches=arr, plan=plan, detail=detail, guide_scale=scale, flat_factor=flat, _slices=slices,
                        _masks_f=masks_f,
                        _masks_fc=masks_fc, _table=table, _boxes=boxes, _bound=bound, _energy=energy, _low=low,
                        _low_norm=low_norm)


def quilt_prepared(
    prepared: PreparedPool,
    *,
    tolerance: float = 0.1,
    rng=None,
    progress: Optional[ProgressCallback] = None,
    guide=None,
    guide_weight: float = 1.0,
    dtype=np.float64,
    reuse: float = 0.0,
    return_seams: bool = False,
):
    """Quilt a pool made ready by :func:`prepare_pool`; parameters and result as :func:`quilt`.

    ``dtype`` float32 returns the quilting canvas's own precision at half the memory of
    float64 (the same values; :meth:`tghop.TGHop.synthesize` refines it in float32 anyway).

    ``return_seams``: also return the :class:`tghop.seams.SeamSteps` of the image: at
    every seam edge it has (two neighbours pasted from two blocks), the change that
    replaces the step between the two patches by the mean of their own differences
    (:func:`tghop.seams.remove_seams`). The image is the same either way. ``progress`` is then
    told ``("seams", 0, 1)`` once the blocks are placed, while the steps are gathered.

    Parameters
    ----------
    prepared : PreparedPool
        From :func:`prepare_pool` (anything else raises :class:`TGHopError`).
    tolerance, rng, progress, guide, guide_weight, reuse
        As :func:`quilt` takes them.
    dtype : {numpy.float64, numpy.float32}
    return_seams : bool

    Returns
    -------
    image : ndarray, shape (H, W, C), ``dtype`` in [0, 1]
    seams : tghop.seams.SeamSteps, only with ``return_seams``
    """
    if not isinstance(prepared, PreparedPool):
        raise TGHopError(f"quilt_prepared takes the result of prepare_pool, got {type(prepared).__name__}")
    dtype = check_dtype(dtype, (np.float32, np.float64), "float32 or float64")  # "junk" too: one line
    tolerance = check_number(tolerance, "tolerance")
    check_number(reuse, "reuse")
    rng = check_rng(rng)
    arr, plan, detail = prepared.patches, prepared.plan, prepared.detail
    # Uses of each pool patch and the factors (1 + reuse * uses) of its errors, times the
    # flat patches' factors; None without either (the same arithmetic as before they existed).
    uses = np.zeros(arr.shape[0], dtype=np.int64) if reuse else None
    penalty = flat = prepared.flat_factor
    p, c = arr.shape[1], arr.shape[3]
    slices, masks_fc, table, energy = prepared._slices, prepared._masks_fc, prepared._table, prepared._energy
    m, k = masks_fc.shape
    norm_max = table[:, :m].max(axis=0)  # (m,)
    one_hot = np.eye(m, dtype=np.float32)
    # Columns [0, k1) hold the norms, the top band and the left band; only wrap-around
    # blocks of tileable output overlap the others, so most blocks skip them.
    left, top, _, bottom = plan.frame
    k1 = m + (top * p + (p - top - bottom) * left) * c
    wraps = masks_fc[:, k1 - m :].any(axis=1)  # (m,)

    hc, wc = plan.canvas_shape
    canvas = np.zeros((hc, wc, c), dtype=np.float32)
    # Pasting copies whole pixels, each as one item of the C channels (a bool mask
    # broadcast over the channels takes NumPy's slow path).
    pixel = np.dtype((np.void, canvas.itemsize * c))
    guided = _guide_setup(guide, guide_weight, prepared) if guide is not None else None
    log = _SeamLog(plan, c) if return_seams else None
    order = np.argsort(plan.level.ravel(), kind="stable")
    bounds = np.cumsum(np.bincount(plan.level.ravel(), minlength=plan.n_levels))
    nx = plan.xs.size
    done, start = 0, 0
    for stop in bounds.tolist():
        blocks = order[start:stop]
        start = stop
        if blocks.size == 0:
            continue
        b = blocks.size
        bi, bj = blocks // nx, blocks % nx
        windows = [_window(y, x, p, hc, wc) for y, x in zip(plan.ys[bi].tolist(), plan.xs[bj].tolist())]
        old = np.stack([canvas[win] for win in windows])  # (b, p, p, c)
        mid = plan.mask_id[bi, bj]

        # The blocks' masked overlap pixels o and query rows [one-hot of the shape | -2 o].
        o = _frame_features(old, slices)
        o *= masks_fc[mid]
        onorm = np.einsum("ij,ij->i", o, o)
        query = np.empty((b, m + k), dtype=np.float32)
        query[:, :m] = one_hot[mid]
        np.multiply(o, -2.0, out=query[:, m:])
        target = factor = None
        if guided is not None:
            target, factor = guided["targets"][bi, bj], guided["factor"][mid]
        # Candidates: error <= (1 + tolerance) * best error, with a little slack for the
        # float32 round-off of the expansion; the best match always qualifies.
        slack = 1e-5 * (onorm + norm_max[mid])
        found = _bounded_candidates(prepared, o, query, onorm, k1, wraps[mid], target, factor, tolerance, slack,
                                    penalty)
        if found is None and penalty is not None:  # every error in full, penalised
            err = _full_errors(table, query, k1, wraps[mid], guided, target, factor)
            err += onorm
            err *= penalty[:, None]
            best = np.maximum(err.min(axis=0), 0.0)
            found = np.nonzero(err <= best * (1.0 + tolerance) + slack * penalty.max())
        if found is None:  # the bound rules out too few patches: every error in full
            err = _full_errors(table, query, k1, wraps[mid], guided, target, factor)
            best = np.maximum(err.min(axis=0) + onorm, 0.0)
            found = np.nonzero(err <= best * (1.0 + tolerance) + slack - onorm)
        pool_idx, block_idx = found  # in pool order within each block (the choice below depends on that only)
        counts = np.bincount(block_idx, minlength=b)
        first = np.concatenate(([0], np.cumsum(counts)[:-1]))
        if energy is None:
            by_block = np.argsort(block_idx, kind="stable")  # block-major, pool index ascending
            pick = rng.integers(0, counts)
        else:  # block-major, gradient energy ascending: skip the smoothest candidates
            by_block = np.lexsort((energy[pool_idx], block_idx))
            skip = np.minimum((detail * counts).astype(np.int64), counts - 1)
            pick = skip + rng.integers(0, counts - skip)
        chosen = pool_idx[by_block[first + pick]]
        if uses is not None:
            np.add.at(uses, chosen, 1)
            penalty = (1.0 + reuse * uses).astype(np.float32)
            if flat is not None:
                penalty *= flat

        new = np.ascontiguousarray(arr[chosen], dtype=np.float32)
        _check_values(new)
        diff = old - new
        # Squared differences summed over the channels, in channel order (as einsum sums
        # them, and faster than einsum for a few channels).
        diff *= diff
        pix_err = diff[..., 0].copy()
        for channel in range(1, c):
            pix_err += diff[..., channel]
        paste = _cut_masks(pix_err, plan.strips[mid], plan.keep[mid])
        if log is not None:
            log.add(blocks, windows, old, new, paste, plan.masks[mid])
        np.copyto(old.view(pixel)[..., 0], new.view(pixel)[..., 0], where=paste)
        for t, win in enumerate(windows):
            canvas[win] = old[t]
        done += b
        report(progress, "quilting", done, plan.n_blocks)

    if log is not None:
        report(progress, "seams", 0, 1)  # the seam removal's first part: its steps gathered from the log
    h, w = plan.size
    # Cropped, clipped and converted in one pass (the bounds are exact in float32).
    image = np.clip(canvas[:h, :w], 0.0, 1.0, out=np.empty((h, w, c), dtype=dtype))
    if log is not None:
        return image, log.steps()
    return image


class _SeamLog:
    """What quilting records for the seam removal (:mod:`tghop.seams`): which block each
    canvas pixel shows (by :func:`block_labels`), and for every seam edge a pasted block
    makes inside its window, the change that replaces the step between the two patches by
    the mean of their own differences, with the labels of the two sides. A record still
    holds at the end if both pixels still show those two blocks."""

    def __init__(self, plan: QuiltingPlan, c: int):
        self.plan, self.c = plan, c
        self.labels = np.full(plan.canvas_shape, 255, dtype=np.uint8)  # 255: nothing placed yet
        self.codes = block_labels(plan).ravel()
        self.records = {1: [], 0: []}  # axis (1: x, 0: y) -> [(first, second, label1, label2, change)]

    def add(self, blocks, windows, old, new, paste, covered):
        """Blocks ``blocks`` pasted: ``old`` / ``new`` (b, P, P, C) the canvas before and the
        patches, ``paste`` (b, P, P) where the patches go, ``covered`` where old is valid."""
        plan, p = self.plan, old.shape[1]
        hc, wc = plan.canvas_shape
        nx = plan.xs.size
        ys, xs = plan.ys[blocks // nx], plan.xs[blocks % nx]
        rows = (ys[:, None] + np.arange(p)) % hc  # (b, P) canvas rows
        cols = (xs[:, None] + np.arange(p)) % wc
        before = np.stack([self.labels[win] for win in windows])  # (b, P, P) labels before pasting
        after = before.copy()
        np.copyto(after, self.codes[blocks][:, None, None], where=paste)
        for t, win in enumerate(windows):
            self.labels[win] = after[t]
        step = new - old  # at a covered pixel: the new patch minus the block shown there before
        # Seam edges inside the window: a pasted pixel beside a kept one, which shows block A.
        # The step at the kept pixel is the patches' mismatch there; the step at the pasted
        # one too if it showed A before (not where a third block's corner was).
        for axis in (1, 0):
            a = (slice(None), slice(None), slice(None, -1)) if axis == 1 else (slice(None), slice(None, -1))
            z = (slice(None), slice(None), slice(1, None)) if axis == 1 else (slice(None), slice(1, None))
            t, y, x = np.nonzero((paste[a] != paste[z]) & covered[a] & covered[z])
            y2, x2 = (y, x + 1) if axis == 1 else (y + 1, x)
            first_new = paste[t, y, x]
            same = (before[t, y, x] == before[t, y2, x2])[:, None]
            kept = np.where(first_new[:, None], step[t, y2, x2], step[t, y, x])
            other = np.where(first_new[:, None], step[t, y, x], step[t, y2, x2])
            change = np.where(same, 0.5 * (kept + other), kept)
            change *= np.where(first_new, 1.0, -1.0).astype(np.float32)[:, None]
            self.records[axis].append((rows[t, y] * wc + cols[t, x], rows[t, y2] * wc + cols[t, x2],
                                       after[t, y, x], after[t, y2, x2], change))
        # Seam edges across the window's border: the pixel outside shows a block A placed
        # earlier; where the pasted pixel inside showed A before, the step there stands for
        # the edge's (the new patch's value outside is unknown).
        placed = self.labels.ravel()
        for axis, at, beyond in ((1, 0, -1), (1, p - 1, p), (0, 0, -1), (0, p - 1, p)):
            line = (slice(None), slice(None), at) if axis == 1 else (slice(None), at)
            t, u = np.nonzero(paste[line] & covered[line])
            y, x = (u, np.full_like(u, at)) if axis == 1 else (np.full_like(u, at), u)
            out_y, out_x = (rows[t, y], xs[t] + beyond) if axis == 1 else (ys[t] + beyond, cols[t, x])
            inside = (out_y >= 0) & (out_y < hc) & (out_x >= 0) & (out_x < wc)
            outside = (out_y % hc) * wc + out_x % wc
            ok = (inside | plan.tile) & (placed[outside] == before[t, y, x])
            t, y, x, outside = t[ok], y[ok], x[ok], outside[ok]
            here = rows[t, y] * wc + cols[t, x]
            if beyond < 0:  # the outside pixel comes first along the axis
                self.records[axis].append((outside, here, placed[outside], after[t, y, x], -step[t, y, x]))
            else:
                self.records[axis].append((here, outside, after[t, y, x], placed[outside], step[t, y, x]))

    def steps(self):
        """The :class:`tghop.seams.SeamSteps` of the cropped image."""
        (h, w), (_, wc) = self.plan.size, self.plan.canvas_shape
        labels = self.labels.ravel()
        index, change = [], []
        for axis in (1, 0):
            recs = self.records[axis] or [(np.zeros(0, np.int64),) * 2 + (np.zeros(0, np.uint8),) * 2
                                          + (np.zeros((0, self.c), np.float32),)]
            first, second, one, two, delta = (np.concatenate([r[i] for r in recs]) for i in range(5))
            y, x = np.divmod(first, wc)
            y2, x2 = np.divmod(second, wc)
            keep = (labels[first] == one) & (labels[second] == two) & (y < h) & (x < w) & (y2 < h) & (x2 < w)
            index.append(y[keep] * w + x[keep])
            change.append(delta[keep])
        return SeamSteps(shape=(h, w), tile=self.plan.tile, index=tuple(index), change=tuple(change))


def block_labels(plan: QuiltingPlan) -> np.ndarray:
    """A small label per block of ``plan``, different for any two blocks that overlap.

    Block ``(i, j)`` gets ``5 * r(i) + r(j)`` with ``r(i) = i % 4``, except that the last
    row and column get 4 (so that, with ``tile``, they differ from the first ones they
    wrap onto). Blocks two steps apart never overlap (the overlap is at most half a patch).

    Parameters
    ----------
    plan : QuiltingPlan
        Its ``ys`` (ny,) and ``xs`` (nx,) block positions are read.

    Returns
    -------
    ndarray, shape (ny, nx), uint8 in [0, 25)
    """
    def ranks(n):
        r = np.arange(n) % 4
        if n > 1:
            r[-1] = 4
        return r

    return (5 * ranks(plan.ys.size)[:, None] + ranks(plan.xs.size)[None, :]).astype(np.uint8)
