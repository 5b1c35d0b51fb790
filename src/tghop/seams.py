"""Seam removal after quilting: gradient-domain stitching of the quilted blocks (ours).

Minimum-error boundary cuts choose *where* two blocks meet, but the two patches still
differ there: a step in tone or colour across the cut, repeated on the block grid, is what
makes a quilted image look tiled (smooth textures show it most: bubbles, skies, plaster).
As in gradient-domain image stitching (Pérez et al. 2003; Agarwala et al. 2004), the fix
works on the differences between neighbouring pixels. Quilting knows, for every seam edge
it leaves (two neighbours pasted from two different blocks), what both patches have at
both pixels: the difference across the edge should be the mean of the two patches' own
differences there, and it is the step between them instead. :class:`SeamSteps` holds the
change that turns one into the other at every seam edge
(:func:`tghop.quilting.quilt_prepared` with ``return_seams=True``); :func:`remove_seams`
finds the image whose differences come closest to the changed ones, in least squares: the
quilted image plus a correction that solves a (screened) Poisson equation whose right-hand
side lives on the seams only, one transform and its inverse per channel. The screening
lets each correction fade within about a block (:data:`SCREENING`), so that steps that
lean one way on average cannot add up to a drift of colour across a large image.

The change can be averaged over the seam edges nearby (``window``): the tone step between
two blocks is about the same along their seam, while their detail differs from pixel to
pixel. Away from the seams the image keeps its differences, so detail is untouched; the
steps are spread out as a smooth field over the blocks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple

import numpy as np

from ._arrays import check_int
from ._errors import TGHopError
from ._progress import report
from ._fft import fft_for

__all__ = ["SCREENING", "SeamSteps", "local_means", "remove_seams"]


@dataclass(frozen=True)
class SeamSteps:
    """The steps across the seams of a quilted image.

    Attributes
    ----------
    shape : (int, int)
        The image's (H, W).
    tile : bool
        The image wraps around (seam edges may join its last and first columns or rows).
    index : (ndarray, ndarray) of int, shapes (n_x,), (n_y,)
        Flat indices into the (H, W) image of the first pixel of every seam edge: along x
        (pixel ``(y, x)`` and ``(y, x + 1)``, modulo W) and along y (``(y, x)`` and
        ``(y + 1, x)``, modulo H). Each index appears at most once per axis.
    change : (ndarray, ndarray), shapes (n_x, C), (n_y, C)
        At each seam edge, the mean of the two patches' own differences across it minus
        the difference the quilted image has there (minus the step).
    """

    shape: Tuple[int, int]
    tile: bool
    index: Tuple[np.ndarray, np.ndarray]
    change: Tuple[np.ndarray, np.ndarray]

    def second(self, axis: int) -> np.ndarray:
        """Flat indices of the second pixel of the seam edges along ``axis`` (1: x, 0: y).

        Parameters
        ----------
        axis : int
            1: the edges along x (the pixel to the right), 0: along y (the pixel below).

        Returns
        -------
        ndarray of int, shape (n_x,) or (n_y,)
            Flat indices into the (H, W) image, in the order of :attr:`index`, wrapping around
            the image's last column or row.
        """
        h, w = self.shape
        rows, cols = np.divmod(self.index[0 if axis == 1 else 1], w)
        if axis == 1:
            return rows * w + (cols + 1) % w
        return ((rows + 1) % h) * w + cols


#: Length in pixels over which a correction fades away from its seam (the screened Poisson
#: equation's ``laplacian(u) - u / SCREENING**2 = div(d)``). Without it, steps that lean one
#: way on average add up over many blocks into a drift of colour across a large image
#: (2048x2048 crops' SIFID 2.64 -> 4.45 on brick_wall); about a block keeps the steps'
#: removal and stops the drift (docs/choices.md).
SCREENING = 32.0


def _filter(h, w, tile, half):
    """1 / (the screened discrete Laplacian's eigenvalues) at the frequencies of the
    transform used: periodic (``tile``; ``half``: the last axis of a real FFT) or the DCT's;
    0 at the mean."""
    if tile:
        fy = 2.0 * np.pi * np.minimum(np.arange(h), h - np.arange(h)) / h
        fx = 2.0 * np.pi * np.arange(w // 2 + 1 if half else w) / w
    else:
        fy, fx = np.pi * np.arange(h) / h, np.pi * np.arange(w) / w
    eigen = (2.0 * np.cos(fy) - 2.0)[:, None] + (2.0 * np.cos(fx) - 2.0)[None, :]
    eigen -= 1.0 / SCREENING**2
    eigen[0, 0] = 1.0
    out = 1.0 / eigen
    out[0, 0] = 0.0  # the mean: left as it is
    return out


def _poisson_solver(h, w, tile, dtype):
    """A function ``rhs (H, W) -> u`` with ``laplacian(u) - u / SCREENING**2 = rhs``: periodic
    (``tile``) or with free edges.

    Free edges (Neumann: no difference across the image's border) through the orthonormal
    DCT where SciPy's transforms serve this size (:func:`tghop._fft.fft_for`); through
    ``numpy.fft`` on the right-hand side mirrored to twice the size each way (the DCT's
    even extension) for small images, where that costs a few milliseconds.
    """
    fft = fft_for(h * w)
    if not tile and hasattr(fft, "dctn"):
        inverse = _filter(h, w, False, False).astype(dtype)

        def solve(rhs):
            spectrum = fft.dctn(rhs, type=2, axes=(0, 1), norm="ortho")
            spectrum *= inverse
            return fft.dctn(spectrum, type=3, axes=(0, 1), norm="ortho")

        return solve
    if not tile:
        periodic = _poisson_solver(2 * h, 2 * w, True, dtype)

        def solve(rhs):
            mirrored = np.empty((2 * h, 2 * w), dtype=rhs.dtype)
            mirrored[:h, :w] = rhs
            mirrored[:h, w:] = rhs[:, ::-1]
            mirrored[h:] = mirrored[h - 1::-1]
            return periodic(mirrored)[:h, :w]

        return solve
    inverse = _filter(h, w, True, True)

    def solve(rhs):
        spectrum = fft.rfft2(rhs, axes=(0, 1))
        spectrum *= inverse
        return fft.irfft(fft.ifft(spectrum, axis=0), n=w, axis=1).astype(rhs.dtype, copy=False)

    return solve


def _run_sums(a, m, axis):
    """Sums of ``m`` consecutive elements along ``axis``: ``out[j] = a[j] + ... + a[j + m - 1]``
    (length ``n - m + 1``), from sums over runs of 1, 2, 4, ... elements (``log2(m)`` passes)."""
    def part(x, start, length):
        index = [slice(None)] * x.ndim
        index[axis] = slice(start, start + length)
        return x[tuple(index)]

    length = a.shape[axis] - m + 1
    out, offset, runs, span = None, 0, a, 1  # runs[j]: the sum of span elements from j
    while span <= m:
        if m & span:
            piece = part(runs, offset, length)
            out = piece.copy() if out is None else np.add(out, piece, out=out)
            offset += span
        if 2 * span <= m:
            n = runs.shape[axis] - span
            runs = part(runs, 0, n) + part(runs, span, n)
        span *= 2
    return out


def _box_sums(a, size, wrap):
    """Sums of ``a`` (H, W) over the ``size x size`` squares (side ``2 * (size // 2) + 1``)
    centred on each element, wrapping around or with zeros beyond the edges."""
    r = size // 2
    for axis in (0, 1):
        widths = [(0, 0), (0, 0)]
        widths[axis] = (r, r)
        a = _run_sums(np.pad(a, widths, mode="wrap" if wrap else "constant"), 2 * r + 1, axis)
    return a


def local_means(steps, axis, window):
    """The change at each seam edge along ``axis`` (1: x, 0: y) averaged over the seam edges along
    the same axis within the ``window x window`` square around it, (n, C) float32 in the order of
    ``steps.index`` (:func:`remove_seams`' ``window``; :func:`tghop.hole_refine.stitch_hole`'s too).

    Parameters
    ----------
    steps : SeamSteps
    axis : int
        1: the seam edges along x, 0: along y.
    window : int
        Side of the square, ``2 * (window // 2) + 1`` pixels (wrapping around for a tileable image).

    Returns
    -------
    ndarray of float32, shape (n, C)
        ``n`` the number of seam edges along ``axis``.
    """
    h, w = steps.shape
    index, change = steps.index[0 if axis == 1 else 1], steps.change[0 if axis == 1 else 1]
    dense = np.zeros(h * w, dtype=np.float32)
    dense[index] = 1.0
    near = _box_sums(dense.reshape(h, w), window, steps.tile).ravel()[index]
    out = np.empty(change.shape, dtype=np.float32)
    for k in range(change.shape[1]):
        dense[index] = change[:, k]
        out[:, k] = _box_sums(dense.reshape(h, w), window, steps.tile).ravel()[index] / near
    return out


def remove_seams(image, steps: SeamSteps, *, window: int = 1, out=None, progress=None) -> np.ndarray:
    """Remove the steps across quilting seams by gradient-domain stitching.

    Parameters
    ----------
    image : ndarray, shape (H, W, C), float32 or float64 in [0, 1]
        A quilted image.
    steps : SeamSteps
        Its seams (:func:`tghop.quilting.quilt_prepared` with ``return_seams=True``).
    window : int
        1: each seam edge's change as it is (the steps are removed exactly). Larger: the
        mean of the changes at the seam edges along the same axis within a ``window x
        window`` square (side ``2 * (window // 2) + 1``): the step between two blocks'
        tones is about the same along their seam, while their detail differs from pixel
        to pixel and averages out, so the seam keeps some of its detail mismatch.
    out : ndarray, optional
        Where to write the result (may be ``image``); a new array of ``image``'s dtype
        otherwise.
    progress : callable, optional
        ``progress("seams", done, total)``: 0 first, then after each seam axis's local means
        (with ``window`` over 1) and after each channel's correction.

    Returns
    -------
    ndarray, shape (H, W, C), ``image``'s dtype, clipped to [0, 1]
        ``image`` plus, per channel, the smooth correction ``u`` that solves the screened
        Poisson equation ``laplacian(u) - u / SCREENING**2 = div(d)`` (periodic with
        ``steps.tile``; no difference across the border otherwise), where ``d`` is the
        change at the seam edges. Without seams the image is returned unchanged.
    """
    image = np.asarray(image)
    if image.ndim != 3 or image.dtype not in (np.float32, np.float64):
        raise TGHopError(f"image must be an (H, W, C) float32 or float64 array, got {image.dtype} {image.shape}")
    if not isinstance(steps, SeamSteps):
        raise TGHopError(f"steps must be the SeamSteps of quilting, got {type(steps).__name__}")
    h, w, c = image.shape
    if tuple(steps.shape) != (h, w) or any(ch.shape[1:] != (c,) for ch in steps.change):
        raise TGHopError(f"the seam steps are of a {steps.shape[0]}x{steps.shape[1]} image with "
                         f"{steps.change[0].shape[1]} channels, not of this {h}x{w} one with {c}")
    window = check_int(window, "window")
    if out is None:
        out = image.copy()
    elif out is not image:
        np.copyto(out, image)
    total = c + (2 if window > 1 else 0)
    report(progress, "seams", 0, total)
    if not any(index.size for index in steps.index):
        report(progress, "seams", total, total)
        return out
    # The least-squares condition: laplacian(u)[i] = d(edge leaving i forwards) - d(edge
    # arriving at i from behind): each seam edge adds +d at its first pixel and -d at its
    # second; all of them in one weighted count per channel.
    where = np.concatenate([index for n, axis in enumerate((1, 0)) for index in (steps.index[n], steps.second(axis))])
    changes = list(steps.change)
    if window > 1:
        for n, axis in enumerate((1, 0)):
            changes[n] = local_means(steps, axis, window)
            report(progress, "seams", n + 1, total)
    solve = _poisson_solver(h, w, steps.tile, out.dtype)
    for k in range(c):
        weights = np.concatenate([part for change in changes for part in (change[:, k], -change[:, k])])
        div = np.bincount(where, weights=weights, minlength=h * w)
        out[..., k] += solve(div.reshape(h, w).astype(out.dtype))
        report(progress, "seams", total - c + k + 1, total)
    return np.clip(out, 0.0, 1.0, out=out)
