"""Distribution metrics in NumPy: sliced Wasserstein distance between multi-scale patch
sets, and the soft colour co-occurrence distance (Darzi et al.)."""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from .._errors import InvalidImageError, TGHopError
from .._images import check_texture
from . import common
from .._arrays import check_int, check_number
from .common import pair, counter, check_patch_size, check_seed, exemplar_statistics, sample_patches

__all__ = ["sliced_wasserstein", "cooccurrence_distance", "MAX_PROJECTIONS"]

#: Most random directions of :func:`sliced_wasserstein`: 16 times its default 256 (each is a
#: column of the patches' projections; 10**9 ended in a MemoryError).
MAX_PROJECTIONS = 4096

# ---------------------------------------------------------------------------------------
# Sliced Wasserstein distance between patch sets
# ---------------------------------------------------------------------------------------


def _downsample(img: np.ndarray, factor: int) -> np.ndarray:
    """Gaussian-blur (sigma = factor / 2) and keep every ``factor``-th pixel."""
    if factor == 1:
        return img
    blurred = ndimage.gaussian_filter(img, sigma=(factor / 2.0, factor / 2.0, 0), mode="reflect")
    return blurred[::factor, ::factor]


def sliced_wasserstein(
    exemplar,
    result,
    *,
    patch_size: int = 7,
    scales=(1, 2, 4),
    n_projections: int = 256,
    max_patches: int = 4096,
    seed: int = 0,
    progress=None,
) -> float:
    """Sliced Wasserstein distance between the small-patch distributions, lower is better.

    At each scale ``s`` both images are blurred (Gaussian, sigma = s/2) and subsampled
    by ``s``; up to ``max_patches`` random ``patch_size`` x ``patch_size`` patches of each
    (stride 1) are projected on ``n_projections`` random unit directions, and the 1-D
    Wasserstein-1 distance between the sorted projections is averaged over directions.
    The result is the mean over scales, in intensity units (0 to 1 per pixel value).

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], or uint8 / uint16 (scored as x / 255, x / 65535), at least ``patch_size * max(scales)`` on each
        side.
    patch_size : int
        Side of the patches (default 7).
    scales : sequence of int
        Downsampling factors (default ``(1, 2, 4)``: fine grain, mid-size and large
        structure).
    n_projections : int
        Random directions per scale (default 256), at most :data:`MAX_PROJECTIONS` = 4,096.
    max_patches : int
        Patches sampled per image and scale (default 4,096); both images use the same
        number, so sets of different sizes are comparable. Patches and projections whose
        memory exceeds the memory available are refused before any work.
    seed : int
        Seed of the directions and of the patch sampling.
    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"swd"``, one unit per scale.

    Returns
    -------
    float
        0 for identical images.

    Notes
    -----
    Memory: already bounded by sampling (``max_patches`` patches per image and scale);
    beyond that, one blurred copy of each image at a time.
    """
    patch_size, seed = check_patch_size(patch_size), check_seed(seed)
    try:
        scales = tuple(scales)
    except TypeError:
        raise TGHopError(f"scales must be a sequence of positive downsampling factors, got {scales!r}") from None
    if not scales:
        raise TGHopError("scales must be positive downsampling factors, got ()")
    scales = tuple(check_int(s, "each of scales") for s in scales)  # 2.5 is refused, not truncated to 2
    n_projections = check_int(n_projections, "n_projections", 1, MAX_PROJECTIONS)
    max_patches = check_int(max_patches, "max_patches")  # as the nearest-patch metrics: 2.5 is not rounded down
    ex, res = pair(exemplar, result, min_size=patch_size * max(scales))
    dim = patch_size * patch_size * ex.shape[2]
    _check_swd_memory(ex, res, patch_size, dim, n_projections, max_patches)
    directions = np.random.default_rng((int(seed), 0)).standard_normal((dim, int(n_projections)))
    directions /= np.linalg.norm(directions, axis=0, keepdims=True)
    per_scale = []
    tick = counter(progress, "swd", len(scales))
    for level, s in enumerate(scales):
        a, b = _downsample(ex, s), _downsample(res, s)
        if min(a.shape[:2] + b.shape[:2]) < patch_size:
            raise InvalidImageError(f"images are too small for {patch_size}px patches at scale {s}; use smaller scales")
        count = (a.shape[0] - patch_size + 1) * (a.shape[1] - patch_size + 1)
        count = min(count, (b.shape[0] - patch_size + 1) * (b.shape[1] - patch_size + 1), int(max_patches))
        # The same seed for both images: identical images give identical samples.
        pa = sample_patches(a, patch_size, count, np.random.default_rng((int(seed), 1, level)))
        pb = sample_patches(b, patch_size, count, np.random.default_rng((int(seed), 1, level)))
        proj_a = np.sort(pa @ directions, axis=0)
        proj_b = np.sort(pb @ directions, axis=0)
        per_scale.append(np.abs(proj_a - proj_b).mean())
        tick()
    return float(np.mean(per_scale))


def _check_swd_memory(ex, res, patch_size, dim, n_projections, max_patches):
    """Refuse, before any work, patches and projections of :func:`sliced_wasserstein` (at its
    finest scale, the most patches) whose float64 arrays exceed the memory available."""
    from .._resources import available_memory

    count = min(int(max_patches), *((img.shape[0] - patch_size + 1) * (img.shape[1] - patch_size + 1)
                                    for img in (ex, res)))
    need = 8.0 * (dim * n_projections + count * (2 * dim + 4 * n_projections))  # 2 patch sets, 2 sorted projections
    avail = available_memory()
    if avail is not None and need > avail:
        raise TGHopError(f"sliced_wasserstein: {count:,} patches on {n_projections:,} projections need about "
                         f"{need / 1e9:.3g} GB of memory but {avail / 1e9:.3g} GB is available; lower max_patches "
                         "or n_projections")

# ---------------------------------------------------------------------------------------
# Co-occurrence distance (Darzi et al.)
# ---------------------------------------------------------------------------------------


def cooccurrence_distance(
    exemplar,
    result,
    *,
    n_clusters: int = 8,
    sigma: float = math.sqrt(51.0),
    window: int = 51,
    max_fit_pixels: int = 20_000,
    seed: int = 0,
    progress=None,
) -> float:
    """L1 distance between soft colour co-occurrence matrices (Darzi et al.), lower is better.

    After Darzi et al., "Co-occurrence based texture synthesis", Eq. 1-2: the exemplar's
    colours are clustered by k-means into ``n_clusters`` centres ``tau_l``, each with
    per-channel standard deviations ``sigma_l`` (of the pixels assigned to it, floored at
    0.01). Every pixel of both images is softly assigned to every cluster,
    ``K(I_p, tau_l) = exp(-sum_i (I_p^i - tau_l^i)^2 / (sigma_l^i)^2)``, and the
    co-occurrence matrix sums ``exp(-d(p, q)^2 / (2 sigma^2)) K(I_p, tau_a) K(I_q, tau_b)``
    over pixel pairs ``q`` in a ``window`` x ``window`` neighbourhood of ``p``, normalised
    to sum to 1. The distance is the L1 norm of the difference of the two matrices.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], or uint8 / uint16 (scored as x / 255, x / 65535), any sizes. The
        clusters come from the exemplar only.
    n_clusters : int
        k (paper: 2, 4 or 8 depending on the texture; default 8), at most
        :data:`tghop.cooccurrence.MAX_CLUSTERS` = 32 (memory grows as k**2). Fewer if the
        exemplar has fewer distinct colours.
    sigma : float
        Spatial scale in pixels (paper: sigma^2 = 51, the default).
    window : int
        Side of the neighbourhood (paper: 51).
    max_fit_pixels : int
        Exemplar pixels sampled to fit k-means, at least 1 (default 20,000).
    seed : int
        Seed of the pixel sample and of k-means.
    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"cooccurrence"``, one unit per strip.

    Returns
    -------
    float
        In [0, 2]; 0 for identical images.

    Notes
    -----
    Memory: an image of up to :data:`common.PLAIN_MAX_PIXELS` (512 x 512) pixels is done in one
    piece, as it always was (about 1 KB per pixel: the soft assignments and the
    ``k x k`` pair maps). A larger one in full-width row strips of about that many pixels,
    each read with ``window // 2`` rows of context above and below, so that every pixel
    sees its whole neighbourhood; the matrix is the sum over strips, the same up to float
    rounding, in memory that does not grow with the image.
    """
    from ..cooccurrence import MAX_CLUSTERS, cooccurrence_matrix, fit_colour_clusters  # Eq. 1-2, shared with the cGAN

    sigma = check_number(sigma, "sigma", positive=True)
    window, n_clusters = check_int(window, "window"), check_int(n_clusters, "n_clusters", 1, MAX_CLUSTERS)
    max_fit_pixels, seed = check_int(max_fit_pixels, "max_fit_pixels"), check_seed(seed)
    ex, res = pair(exemplar, result)
    check_texture(ex)  # one colour cluster: its 1x1 matrix matched any result (a distance of 0)
    tick = counter(progress, "cooccurrence", len(_cooc_strips(ex, int(window))) + len(_cooc_strips(res, int(window))))

    def matrix(img, centres, spreads):
        if img.shape[0] * img.shape[1] <= common.PLAIN_MAX_PIXELS:  # one piece, exactly as before
            # A tiny floor keeps the matrix defined for a result far from every exemplar colour.
            out = cooccurrence_matrix(img.transpose(2, 0, 1)[None], centres, spreads, sigma=float(sigma),
                                      window=int(window), floor=1e-12)[0]
            tick()
            return out
        return _cooccurrence_strips(img, centres, spreads, float(sigma), int(window), tick)

    def exemplar():
        centres, spreads = fit_colour_clusters(ex, n_clusters=int(n_clusters), max_fit_pixels=max_fit_pixels,
                                               seed=int(seed))
        return centres, spreads, matrix(ex, centres, spreads)

    # The exemplar's clusters and matrix, reused for the next result scored against it.
    options = (n_clusters, sigma, window, max_fit_pixels, seed, common.PLAIN_MAX_PIXELS)
    centres, spreads, m_ex = exemplar_statistics("cooccurrence", ex, options, exemplar,
                                                 len(_cooc_strips(ex, int(window))), tick)
    return float(np.abs(m_ex - matrix(res, centres, spreads)).sum())


def _cooc_strips(img: np.ndarray, window: int):
    """Row strips ``(lo, a, b, hi)`` for :func:`cooccurrence_distance`: rows ``a:b`` are scored,
    read with their context ``lo:hi``. One strip for images up to :data:`common.PLAIN_MAX_PIXELS`."""
    h, w = img.shape[:2]
    if h * w <= common.PLAIN_MAX_PIXELS:
        return [(0, 0, h, h)]
    radius = window // 2
    rows = max(1, common.PLAIN_MAX_PIXELS // w)
    return [(max(0, a - radius), a, min(h, a + rows), min(h, a + rows + radius)) for a in range(0, h, rows)]


def _cooccurrence_strips(img, centres, spreads, sigma: float, window: int, tick):
    """The co-occurrence matrix of Eq. 1, summed over row strips (bounded memory)."""
    from ..cooccurrence import soft_assign, spread_pairs, symmetric_normalised

    k = centres.shape[0]
    total = np.zeros((k, k))
    for lo, a, b, hi in _cooc_strips(img, window):
        assign = soft_assign(img[lo:hi].transpose(2, 0, 1)[None], centres, spreads)[0] + 1e-12  # (k, rows, W)
        spread = spread_pairs(assign, sigma, window // 2)
        total += assign[:, a - lo : b - lo].reshape(k, -1) @ spread[:, a - lo : b - lo].reshape(k, -1).T
        tick()
    return symmetric_normalised(total)
