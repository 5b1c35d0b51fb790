"""Colour matching after quilting (our addition to TGHop, on by default).

Generated textures lose contrast and colour saturation: cluster models pull samples
towards their means, and quilting prefers smooth patches because they match any overlap
best. Matching each channel's histogram of the result to the exemplar's (Heeger & Bergen
1995) restores them. On six textures of ``../shared/textures`` it halved the median SIFID,
Gram, SWD and co-occurrence distances while raising novelty (see docs/choices.md).
Switch it off (``match_colours=False``, CLI ``--no-match-colours``) to reproduce the
paper exactly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["channel_quantiles", "match_histograms", "N_QUANTILES"]

#: Quantile levels stored per channel (0, 1/256, ..., 1).
N_QUANTILES = 257


def channel_quantiles(image, n: int = N_QUANTILES) -> np.ndarray:
    """Quantiles of each channel of an image.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
    n : int
        Number of equally spaced probability levels from 0 to 1.

    Returns
    -------
    ndarray, shape (C, n)
    """
    image = np.asarray(image, dtype=np.float64)
    flat = image.reshape(-1, image.shape[2])
    return np.quantile(flat, np.linspace(0.0, 1.0, n), axis=0).T


def match_histograms(image, quantiles) -> np.ndarray:
    """Give each channel of ``image`` the distribution described by ``quantiles``.

    Every pixel keeps its rank within its channel (ties broken by position), and the
    rank is mapped through the target quantile function with linear interpolation, so
    the map is monotone and deterministic.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
    quantiles : ndarray, shape (C, n)
        From :func:`channel_quantiles` of the reference.

    Returns
    -------
    ndarray, shape (H, W, C), float64 in [0, 1]
    """
    image = np.asarray(image)
    h, w, c = image.shape
    out = np.empty((h, w, c))
    levels = np.linspace(0.0, 1.0, quantiles.shape[1])
    ranks = np.linspace(0.0, 1.0, h * w)
    for k in range(c):
        order = np.argsort(image[..., k].ravel(), kind="stable")
        channel = np.empty(h * w)
        channel[order] = np.interp(ranks, levels, quantiles[k])
        out[..., k] = channel.reshape(h, w)
    return np.clip(out, 0.0, 1.0)
