"""The finishing of a fill inside its hole (:func:`tghop.inpaint.inpaint`'s steps 3 and 4): the steps in
tone across the fill's seams taken out in the gradient domain (:func:`stitch_hole`), and the refinement by the
model's band statistics restricted to the hole (:func:`refine_hole`). Both keep every pixel outside the hole:
the known pixels are the context (the fixed boundary of the seam removal, what each refinement round is put
back to), not part of what changes.

Example
-------
>>> import numpy as np
>>> from tghop.hole_refine import stitch_hole
>>> canvas = np.full((32, 32, 1), 0.5, np.float32); canvas[8:24, 8:16] = 0.6; canvas[8:24, 16:24] = 0.4
>>> hole = np.zeros((32, 32), bool); hole[8:24, 8:24] = True
>>> owner = np.where(hole, 1, -1); owner[8:24, 16:24] = 2
>>> out = stitch_hole(canvas, hole, owner)
>>> bool(np.array_equal(out[~hole], canvas[~hole]))
True
"""

from __future__ import annotations

import numpy as np

from ._arrays import check_int
from ._progress import report
from .oriented import windows_held
from .pyramid import laplacian_pyramid, reconstruct
from .refine import match_quantiles, oriented_parts, tailed_band_quantiles
from .seams import SCREENING, SeamSteps, local_means

__all__ = ["stitch_hole", "refine_hole", "STITCH_LU", "STITCH_STEP", "STITCH_RIM_STEP", "STITCH_RIM_WEIGHT"]

#: Unknowns up to which :func:`stitch_hole` solves by a sparse LU factorisation; conjugate gradients above.
STITCH_LU = 400_000
#: A seam edge's change (the norm over the channels) counts ``1 / (1 + (change / STITCH_STEP)**4)``
#: of itself in :func:`stitch_hole`: tone steps whole, content edges (a change of several times this) not.
STITCH_STEP = 0.3
#: The same for the detail of the hole's rim (a known pixel beside a filled one: each edge's change less the rim's
#: mean around it, taken pixel by pixel), whose edges count ``STITCH_RIM_WEIGHT`` times in the misfit: the fill's
#: first pixels continue the known ones beside them (docs/choices.md, Inpainting "the hole's rim").
STITCH_RIM_STEP = 0.6
STITCH_RIM_WEIGHT = 4.0


def stitch_hole(canvas, hole, owner, *, tile=False, window=9):
    """Remove the steps in tone and colour across the seams of a fill, in the gradient domain,
    inside the hole only (the known pixels are the fixed boundary), as :func:`tghop.seams.remove_seams`
    does for a quilted image.

    A seam edge joins two pixels of different blocks, or a filled pixel and a known one. The
    difference across it should be like those beside it (the mean of the differences one pixel
    before and after it along the same axis, within each side's own patch), and it is a step
    instead; that change, averaged over the seam edges in a ``window x window`` square (a tone
    step is about the same along a seam, its detail is not), is what the correction ``u`` of the
    hole must make. On the hole's rim (a filled pixel beside a known one) each edge's own detail
    (its change less the rim's mean in the window, a larger step let through: ``STITCH_RIM_STEP``)
    is wanted too, ``STITCH_RIM_WEIGHT`` times as much, so that the fill's first pixels continue
    the known ones beside them (the rim's steps were the hole's outline, hard at a thin hole).
    ``u`` minimises the squared misfit over every edge that touches the hole plus
    ``u**2 / SCREENING**2`` (corrections fade within about a block), with ``u = 0`` at the
    known pixels: one sparse symmetric system per image, a solve per channel.

    Parameters
    ----------
    canvas : ndarray, shape (H, W, C), float32
        The filled image.
    hole : ndarray of bool, shape (H, W)
    owner : ndarray of int, shape (H, W)
        The block each hole pixel came from (-1 outside the hole).
    tile : bool
        The image wraps around.
    window : int
        Side of the square over which each seam edge's change is averaged (``inpaint``'s ``seam_window``).

    Returns
    -------
    ndarray, shape (H, W, C), float32, in [0, 1]
        ``canvas`` with its hole corrected; the other pixels are the same.
    """
    from scipy import sparse
    from scipy.sparse.linalg import cg, splu

    h, w, c = canvas.shape
    k = int(hole.sum())
    index = np.full((h, w), -1, dtype=np.int64)
    index[hole] = np.arange(k)

    def after(a, axis):  # each pixel's value at the next pixel along ``axis``
        return np.roll(a, -1, axis=axis)

    edges = {}  # axis -> the edges that touch the hole, the seam edges among them, their changes
    for axis in (0, 1):
        valid = np.ones((h, w), dtype=bool)  # an edge to the next pixel exists
        if not tile:
            (valid[-1] if axis == 0 else valid[:, -1])[...] = False
        touches = valid & (hole | after(hole, axis))
        seam = touches & (owner != after(owner, axis))
        diff = after(canvas, axis) - canvas  # across each edge
        # The edges before and after: their mean is what a seam edge's difference should be.
        near = [(np.roll(diff, by, axis=axis), np.roll(valid, by, axis=axis)) for by in (1, -1)]
        count = sum(ok.astype(np.float32) for _, ok in near)
        wanted = sum(d * ok[..., None] for d, ok in near) / np.maximum(count, 1)[..., None]
        change = (wanted - diff)[seam]
        # A step far larger than tone steps is an edge of the content (a stone, a label at the hole's
        # edge): left alone, or the fill takes its colour along the seam (the smear of 0.46's try).
        size = np.sqrt(np.square(change).sum(axis=-1, keepdims=True))
        # The hole's rim (an edge between a known pixel and a filled one): its detail, each edge's change less
        # the rim's mean around it, lets larger steps through (the fill's detail meets the known pixels' there).
        rim = touches & ((owner < 0) | (after(owner, axis) < 0))
        detail = (change / (1.0 + (size / STITCH_RIM_STEP) ** 4))[rim[seam]]
        change *= 1.0 / (1.0 + (size / STITCH_STEP) ** 4)
        edges[axis] = touches, seam, change, rim, np.concatenate([change[rim[seam]], detail], axis=1)
    # Each seam edge's change averaged over those nearby, as the seam removal of a quilt averages its own.
    steps = SeamSteps((h, w), bool(tile), tuple(np.flatnonzero(edges[a][1]) for a in (1, 0)),
                      tuple(edges[a][2] for a in (1, 0)))
    rims = SeamSteps((h, w), bool(tile), tuple(np.flatnonzero(edges[a][3]) for a in (1, 0)),
                     tuple(edges[a][4] for a in (1, 0)))
    rhs, degree, pairs = np.zeros((k, c)), np.zeros(k), []
    for axis in (0, 1):
        touches, seam, _, rim, detail = edges[axis]
        dense = np.zeros((h, w, c))
        dense[seam] = local_means(steps, axis, window)
        # The rim's tone step as every seam's, and its detail pixel by pixel: a content edge along the rim
        # (the same change all along it) has no detail, and the detail's corrections fade within pixels.
        means = local_means(rims, axis, window)
        dense[rim] = means[:, :c] + detail[:, c:] - means[:, c:]
        change = dense[touches]
        weight = np.where(rim, STITCH_RIM_WEIGHT, 1.0)[touches]
        first, second = index[touches], after(index, axis)[touches]
        # The misfit weight * (u[second] - u[first] - change)^2: each end in the hole adds its weight to its
        # degree, -weight * change (first) or +weight * change (second) to its right-hand side, and -1 between
        # two hole ends (a rim edge has one end known: its weight is on the diagonal only).
        for end, sign in ((first, -1.0), (second, 1.0)):
            inside = end >= 0
            degree += np.bincount(end[inside], weights=weight[inside], minlength=k)
            for ch in range(c):
                rhs[:, ch] += sign * np.bincount(end[inside], weights=weight[inside] * change[inside, ch], minlength=k)
        both = (first >= 0) & (second >= 0)
        pairs.append((first[both], second[both]))
    i = np.concatenate([a for a, _ in pairs] + [b for _, b in pairs])
    j = np.concatenate([b for _, b in pairs] + [a for a, _ in pairs])
    matrix = (sparse.diags(degree + 1.0 / SCREENING ** 2)
              + sparse.csr_matrix((np.full(i.size, -1.0), (i, j)), shape=(k, k))).tocsc()
    if k <= STITCH_LU:  # a symmetric ordering: faster than COLAMD's (docs/choices.md, Inpainting "0.49.2")
        solve = splu(matrix, permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True}).solve
    else:  # a factorisation would take tens of seconds and gigabytes
        jacobi = sparse.diags(1.0 / matrix.diagonal())
        solve = lambda b: cg(matrix, b, rtol=1e-4, maxiter=1000, M=jacobi)[0]  # noqa: E731
    out = canvas.copy()
    for ch in range(c):
        out[hole, ch] += solve(rhs[:, ch]).astype(out.dtype)
    return np.clip(out, 0.0, 1.0, out=out)


def _match_values(values, quantiles, levels):
    """``values`` (k,) given the distribution of ``quantiles`` by their ranks
    (:func:`tghop.refine.match_quantiles`: a rank table, no sort)."""
    if values.size < 2:
        return values
    return match_quantiles(values, quantiles, levels)


def _level_mask(hole, level, shape):
    """Band ``level``'s pixels (of ``shape``) that see the hole: any hole pixel in their
    ``2**level`` box, grown by one band pixel."""
    from scipy.ndimage import binary_dilation

    step = 2 ** level
    hh, ww = shape
    padded = np.zeros((hh * step, ww * step), dtype=bool)
    padded[: hole.shape[0], : hole.shape[1]] = hole[: hh * step, : ww * step]
    small = padded.reshape(hh, step, ww, step).any(axis=(1, 3))
    return binary_dilation(small, iterations=1) if level else small


def refine_hole(image, hole, stats, *, n_iter=5, tile=False, progress=None):
    """The refinement of :func:`tghop.refine.refine` restricted to a hole.

    Each round gives the values of every band (and oriented part) of the image's
    Laplacian pyramid that lie over the hole, and then the hole's pixels, the
    distributions of ``stats`` (the model's exemplar's) by their ranks, in its
    decorrelated colour space; the pixels outside the hole are put back after each round,
    so they are the context, not part of what is matched.

    Parameters
    ----------
    image : ndarray, shape (H, W, C), float in [0, 1]
    hole : ndarray of bool, shape (H, W)
    stats : tghop.refine.BandStatistics
    n_iter : int
    tile : bool
        Periodic boundaries.
    progress : callable, optional
        ``progress("refine", done, n_iter)``.

    Returns
    -------
    ndarray, shape (H, W, C), float32 in [0, 1]
    """
    n_iter = check_int(n_iter, "n_iter", 0, where="refine_hole")
    mode = "wrap" if tile else "reflect"
    outside = np.ascontiguousarray(np.moveaxis(stats.to_decorrelated(np.asarray(image, dtype=np.float32)), 2, 0))
    dec = outside.copy()
    levels = np.linspace(0.0, 1.0, stats.pixel_quantiles_.shape[1])
    band_levels, band_q = tailed_band_quantiles(stats.band_quantiles_)
    c = dec.shape[0]
    report(progress, "refine", 0, n_iter)
    with windows_held():  # each band's oriented windows made once, not once a round, whatever their size
        for done in range(1, n_iter + 1):
            bands = laplacian_pyramid(dec, band_q.shape[0], mode=mode, axes=(1, 2))
            for i, band in enumerate(bands[:-1]):
                where = _level_mask(hole, i, band.shape[1:])
                parts = oriented_parts(band, stats.n_orientations, axes=(1, 2))
                new = band.copy()
                new[:, where] = 0.0
                for j, part in enumerate(parts):
                    for k in range(c):
                        new[k][where] += _match_values(part[k][where], band_q[i, j, k], band_levels).astype(new.dtype)
                bands[i] = new
            dec = reconstruct(bands, mode=mode, axes=(1, 2)).astype(np.float32)
            for k in range(c):
                dec[k][hole] = _match_values(dec[k][hole], stats.pixel_quantiles_[k], levels)
            dec[:, ~hole] = outside[:, ~hole]
            report(progress, "refine", done, n_iter)
    colours = stats.from_decorrelated(np.ascontiguousarray(np.moveaxis(dec, 0, 2)))
    return np.clip(colours, 0.0, 1.0).astype(np.float32)
