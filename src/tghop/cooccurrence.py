"""Soft colour co-occurrence statistics (Darzi et al., Eq. 1-2) on NumPy arrays or torch tensors (the
cGAN conditioned on them is :mod:`tghop.cooc`).

After A. Darzi, I. Lang, A. Taklikar, H. Averbuch-Elor, S. Avidan, "Co-occurrence based
texture synthesis" (``../shared/papers/003_db2109f0a38f9c15.txt``). Two users share these
functions: :func:`tghop.metrics.cooccurrence_distance` (a metric, on NumPy arrays) and the
co-occurrence cGAN of :mod:`tghop.cooc` (its condition and its consistency loss, on torch
tensors). This module knows nothing of the cGAN; it needs PyTorch only for tensors.

* :func:`fit_colour_clusters` -- k-means colour centres ``tau_l`` and per-cluster,
  per-channel spreads ``sigma_l`` (Eq. 2);
* :func:`soft_assign` -- ``K(I_p, tau_l)`` for every pixel and cluster (Eq. 2);
* :func:`cooccurrence_matrix` -- one ``k x k`` matrix of a whole image (Eq. 1);
* :func:`cooccurrence_tensor` -- a matrix per pixel over a patch around it, row-stacked
  to ``k*k`` channels and average-pooled by ``s`` (Sec. 3): ``(k*k, H/s, W/s)``.

All are vectorised (separable convolutions and integral images) and, on tensors,
differentiable -- the cGAN's generator is trained through them.
"""

from __future__ import annotations

import math

import numpy as np

from ._arrays import check_int
from ._errors import TGHopError
from ._images import check_image
from ._resources import import_torch

__all__ = ["MAX_CLUSTERS", "fit_colour_clusters", "soft_assign", "spread_pairs", "symmetric_normalised",
           "cooccurrence_matrix", "cooccurrence_tensor"]


def _torch():
    """``torch``, for the tensor paths (a one-line hint if it is missing)."""
    return import_torch("co-occurrence on tensors")


#: Most colour clusters :func:`fit_colour_clusters` fits: four times the paper's largest k = 8
#: (the k x k pair maps of :func:`cooccurrence_matrix` grow as k**2: about 2.4 GB for a
#: 512 x 512 image at k = 32; k = 10**9 ended in a MemoryError).
MAX_CLUSTERS = 32


def fit_colour_clusters(image, *, n_clusters: int = 8, max_fit_pixels: int = 20_000, seed: int = 0):
    """K-means colour clusters of an image with per-cluster, per-channel spreads (Eq. 2).

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1].
    n_clusters : int
        k (the paper uses 2, 4 or 8), at most :data:`MAX_CLUSTERS` = 32. Fewer if the image
        has fewer distinct colours.
    max_fit_pixels : int
        Pixels sampled for k-means (default 20,000).
    seed : int
        Seed of the pixel sample and of k-means.

    Returns
    -------
    centres : ndarray, shape (k, C), float64
        ``tau_l``.
    spreads : ndarray, shape (k, C), float64
        ``sigma_l``: standard deviation of each channel among the pixels of cluster l,
        floored at 0.01.
    """
    from sklearn.cluster import KMeans
    from threadpoolctl import threadpool_limits

    n_clusters = check_int(n_clusters, "n_clusters", 1, MAX_CLUSTERS)
    max_fit_pixels = check_int(max_fit_pixels, "max_fit_pixels")  # 0 failed inside scikit-learn
    img = check_image(image)
    pixels = img.reshape(-1, img.shape[2])
    rng = np.random.default_rng(int(seed))
    if pixels.shape[0] > int(max_fit_pixels):
        pixels = pixels[rng.choice(pixels.shape[0], size=int(max_fit_pixels), replace=False)]
    k = int(min(n_clusters, np.unique(np.round(pixels, 6), axis=0).shape[0]))
    # A few thousand 3-vectors: one thread is fast, and OpenMP threads busy-waiting on a
    # loaded machine made this many times slower.
    with threadpool_limits(1, user_api="openmp"):
        kmeans = KMeans(n_clusters=k, n_init=3, random_state=int(seed)).fit(pixels)
    centres = kmeans.cluster_centers_
    spreads = np.full_like(centres, 0.01)
    for label in range(k):
        members = pixels[kmeans.labels_ == label]
        if len(members) > 1:
            spreads[label] = np.maximum(members.std(axis=0), 0.01)
    return centres, spreads


def _backend(x):
    """``numpy`` for arrays, ``torch`` for tensors."""
    if isinstance(x, np.ndarray):
        return np
    return _torch()


def soft_assign(images, centres, spreads):
    """Eq. 2: ``K(I_p, tau_l) = exp(-sum_i (I_p^i - tau_l^i)^2 / (sigma_l^i)^2)``.

    Parameters
    ----------
    images : ndarray or torch.Tensor, shape (N, C, H, W)
        Float in [0, 1] (channel-first, a batch).
    centres, spreads : same type as ``images``, shape (k, C)

    Returns
    -------
    same type, shape (N, k, H, W)
    """
    diff = (images[:, None] - centres[None, :, :, None, None]) / spreads[None, :, :, None, None]
    xp = _backend(images)
    return xp.exp(-(diff * diff).sum(2))


def _gauss_kernel(sigma: float, radius: int) -> np.ndarray:
    """``exp(-d^2 / (2 sigma^2))`` for d = -radius..radius (unnormalised, as in Eq. 1)."""
    d = np.arange(-radius, radius + 1, dtype=np.float64)
    return np.exp(-(d * d) / (2.0 * sigma * sigma))


def spread_pairs(assign, sigma: float, radius: int):
    """``S_b(p) = sum_{q in window(p), q in image} exp(-|p - q|^2 / (2 sigma^2)) K_b(q)``.

    The 2-D Gaussian over a square window is separable, so two 1-D passes give it
    exactly; pixels outside the image contribute nothing (zero padding).

    Parameters
    ----------
    assign : ndarray or torch.Tensor, shape (N, k, H, W)
        Soft assignments ``K_b`` (:func:`soft_assign`).
    sigma : float
        Spatial scale in pixels.
    radius : int
        Half the window's side: ``q`` within ``radius`` pixels of ``p`` on each axis.

    Returns
    -------
    same type, shape (N, k, H, W)
        ``S_b``; a tensor keeps its dtype and device (and its gradient).
    """
    g = _gauss_kernel(sigma, radius)
    if isinstance(assign, np.ndarray):
        from scipy import ndimage

        out = ndimage.correlate1d(assign, g, axis=-1, mode="constant", cval=0.0)
        return ndimage.correlate1d(out, g, axis=-2, mode="constant", cval=0.0)
    torch = _torch()
    n, k, h, w = assign.shape
    if max(h, w) <= 512:
        # Banded Gaussian matrices: S = Gy A Gx^T, a matrix product (much faster than a
        # long 1-D convolution, forward and backward, at these sizes).
        d_y = np.arange(h)[:, None] - np.arange(h)[None, :]
        d_x = np.arange(w)[:, None] - np.arange(w)[None, :]
        gy = np.where(np.abs(d_y) <= radius, np.exp(-(d_y * d_y) / (2.0 * sigma * sigma)), 0.0)
        gx = np.where(np.abs(d_x) <= radius, np.exp(-(d_x * d_x) / (2.0 * sigma * sigma)), 0.0)
        return _like(assign, gy) @ assign @ _like(assign, gx.T)
    f = torch.nn.functional
    kern = torch.as_tensor(g, dtype=assign.dtype, device=assign.device)
    x = assign.reshape(n * k, 1, h, w)
    x = f.conv2d(f.pad(x, (radius, radius, 0, 0)), kern.view(1, 1, 1, -1))
    x = f.conv2d(f.pad(x, (0, 0, radius, radius)), kern.view(1, 1, -1, 1))
    return x.reshape(n, k, h, w)


def _pair_maps(assign, sigma: float, radius: int):
    """``P_ab(p) = K_a(p) * S_b(p)``: the Eq. 1 summand of pixel p, summed over its window.

    Returns
    -------
    shape (N, k, k, H, W)
    """
    spread = spread_pairs(assign, sigma, radius)
    return assign[:, :, None] * spread[:, None, :]


def symmetric_normalised(m):
    """``(M + M^T) / 2`` over the last two axes, scaled to sum to 1.

    Parameters
    ----------
    m : ndarray or torch.Tensor, shape (..., k, k)
        Unnormalised co-occurrence matrices, with a positive sum each.

    Returns
    -------
    same type, shape (..., k, k)
        Symmetric, each matrix summing to 1.
    """
    m = 0.5 * (m + m.swapaxes(-1, -2))
    return m / m.sum((-2, -1))[..., None, None]


def cooccurrence_matrix(images, centres, spreads, *, sigma: float = math.sqrt(51.0), window: int = 51,
                        floor: float = 0.0):
    """Eq. 1 over a whole image: ``M(a, b) = 1/Z sum_{p, q} exp(-d(p, q)^2 / (2 sigma^2)) K_a(p) K_b(q)``.

    The sum runs over every pixel ``p`` and every ``q`` in the ``window`` x ``window``
    square around it that lies inside the image. The matrix is symmetric and sums to 1.

    Parameters
    ----------
    images : ndarray or torch.Tensor, shape (N, C, H, W)
        Float in [0, 1].
    centres, spreads : same type, shape (k, C)
        From :func:`fit_colour_clusters`.
    sigma : float
        Spatial scale in pixels (paper: sigma^2 = 51).
    window : int
        Side of the window (paper: 51; an even value acts as the next odd one down).
    floor : float
        Added to every soft assignment, so that an image far from every cluster colour
        still has a defined matrix (the metric uses 1e-12).

    Returns
    -------
    same type, shape (N, k, k)
    """
    assign = soft_assign(images, centres, spreads) + floor
    pairs = _pair_maps(assign, float(sigma), int(window) // 2)
    return symmetric_normalised(pairs.sum((-2, -1)))


def _box_sum2(x, radius: int):
    """Sum over the ``(2 radius + 1)`` square around each pixel of the last two axes (clipped
    to the image).

    Up to 512 pixels a side: products with 0/1 band matrices (sums of non-negative terms,
    exact to round-off even where values span many orders of magnitude -- a generated
    colour far from every cluster has tiny assignments next to large ones). Larger: by
    cumulative sums (cost independent of the square, but differences of large sums; the
    callers use float64 there and clip at 0).
    """
    size = 2 * radius + 1
    h, w = x.shape[-2:]
    if max(h, w) <= 512:
        band_h = (np.abs(np.arange(h)[:, None] - np.arange(h)[None, :]) <= radius).astype(np.float64)
        band_w = (np.abs(np.arange(w)[:, None] - np.arange(w)[None, :]) <= radius).astype(np.float64)
        return _like(x, band_h) @ x @ _like(x, band_w)
    for axis in (-1, -2):
        n = x.shape[axis]
        if isinstance(x, np.ndarray):
            pad = [(0, 0)] * x.ndim
            pad[axis] = (radius + 1, radius)
            c = np.pad(x, pad).cumsum(axis)
            x = np.take(c, np.arange(size, size + n), axis=axis) - np.take(c, np.arange(n), axis=axis)
        else:
            torch = _torch()
            pad = (radius + 1, radius, 0, 0) if axis == -1 else (0, 0, radius + 1, radius)
            c = torch.nn.functional.pad(x, pad).cumsum(axis)
            x = c.narrow(axis, size, n) - c.narrow(axis, 0, n)
    return x


def _like(x, arr: np.ndarray):
    """``arr`` as the type of ``x`` (same dtype and device for a tensor)."""
    if isinstance(x, np.ndarray):
        return arr.astype(x.dtype)
    torch = _torch()
    return torch.as_tensor(arr, dtype=x.dtype, device=x.device)


def _cell_bands(n: int, s: int, cells: int, radius: int) -> np.ndarray:
    """``B[i, y', y] = 1`` if pixel y is in cell i (of ``s`` pixels) and ``|y - y'| <= radius``.

    Returns
    -------
    ndarray, shape (cells, n, n)
    """
    y = np.arange(n)
    near = np.abs(y[:, None] - y[None, :]) <= radius  # (y', y)
    in_cell = (y[None, :] // s == np.arange(cells)[:, None]) & (y[None, :] < cells * s)  # (i, y)
    return (near[None] & in_cell[:, None, :]).astype(np.float64)


#: Above this many weights (images x cells x pixels), :func:`cooccurrence_tensor` normalises
#: pixel by pixel instead of through per-cell weight maps (same result, less memory).
_MAX_CELL_WEIGHTS = 2**24


def cooccurrence_tensor(images, centres, spreads, *, patch: int = 65, window: int = 51,
                        sigma: float = math.sqrt(51.0), s: int = 32, floor: float = 1e-6):
    """Co-occurrence tensor of image crops (Sec. 3 and 4.1 of Darzi et al.).

    For every pixel ``p`` a ``k x k`` matrix counts the Eq. 1 pairs ``(p', q)`` with
    ``p'`` in the ``patch`` x ``patch`` square around ``p`` and ``q`` in the ``window`` x
    ``window`` square around ``p'`` (both clipped to the image; the paper: 65 and 51,
    sigma^2 = 51). It is symmetrised (``(M + M^T) / 2``: a pair counts for ``(a, b)`` and
    ``(b, a)`` alike) and normalised to sum to 1. The ``k*k`` entries, row-stacked, form
    a volume that is average-pooled by ``s`` (every cell still sums to 1).

    Everything is computed on the crop alone, so a generated crop and a real one are
    measured identically (the paper takes the patches from the whole exemplar).

    Parameters
    ----------
    images : ndarray or torch.Tensor, shape (N, C, H, W)
        Float in [0, 1]. ``H`` and ``W`` at least ``s``; rows and columns beyond the last
        whole multiple of ``s`` are left out of the pooling.
    centres, spreads : same type, shape (k, C)
    patch, window : int
        Odd sides of the squares (an even value acts as the next odd one down).
    sigma : float
    s : int
        Downsampling factor.
    floor : float
        Added to every soft assignment (keeps the matrix defined, and its gradient finite,
        for colours far from every cluster).

    Returns
    -------
    same type, shape (N, k*k, H // s, W // s)
        Channel ``a * k + b`` is ``M(tau_a, tau_b)``.
    """
    n, _, h, w = images.shape
    s = int(s)
    if s < 1 or h < s or w < s:
        raise TGHopError(f"images of {h}x{w} pixels are smaller than the downsampling factor s={s}")
    assign = soft_assign(images, centres, spreads) + floor  # (N, k, H, W)
    spread = spread_pairs(assign, float(sigma), int(window) // 2)
    k = assign.shape[1]
    r = int(patch) // 2
    hh, ww = h // s, w // s
    pairs = (assign[:, :, None] * spread[:, None, :]).reshape(n, k * k, h, w)  # Eq. 1 summand of p'
    # The total of a pixel's matrix, sum_ab, from one channel: sum_ab K_a S_b = (sum_a K_a)(sum_b S_b).
    total = _box_sum2((assign.sum(1) * spread.sum(1))[:, None], r)[:, 0]  # (N, H, W)
    tiny = 1e-30  # never 0: 1 / total multiplies zeros of the band matrices below
    total = np.maximum(total, tiny) if isinstance(total, np.ndarray) else total.clamp(min=tiny)
    if n * hh * ww * h * w <= _MAX_CELL_WEIGHTS:
        # Cell c averages pixels p of its s x s block, each the box sum over its patch
        # divided by total(p); by linearity that is sum_p' pairs(p') V_c(p'), with weight
        # maps V_c = box sum of (1[p in c] / total(p)) = By_i (1 / total) Bx_j^T.
        inv = 1.0 / total
        by = _like(inv, _cell_bands(h, s, hh, r))  # (hh, H, H)
        bx = _like(inv, _cell_bands(w, s, ww, r))  # (ww, W, W)
        rows = by[None] @ inv[:, None]  # (N, hh, H, W)
        weights = rows[:, :, None] @ bx.swapaxes(-1, -2)[None, None]  # (N, hh, ww, H, W)
        weights = weights.reshape(n, hh * ww, h * w).swapaxes(1, 2)
        pooled = (pairs.reshape(n, k * k, h * w) @ weights).reshape(n, k, k, hh, ww) / (s * s)
    else:
        local = _box_sum2(pairs, r)
        # Differences of cumulative sums: clip the round-off below 0 of entries near 0.
        local = (np.maximum(local, 0.0) if isinstance(local, np.ndarray) else local.clamp(min=0.0)) / total[:, None]
        pooled = local[:, :, : hh * s, : ww * s].reshape(n, k, k, hh, s, ww, s).mean((4, 6))
    pooled = 0.5 * (pooled + pooled.swapaxes(1, 2))
    return pooled.reshape(n, k * k, hh, ww)
