"""Images kept at a few pixel values, each pixel moved to the nearest: a material's mask maps and a
two-level exemplar's images (:meth:`TGHop.synthesize <tghop.synthesis.TGHop.synthesize>`). Not a hole's
mask (:func:`tghop.inpaint.check_hole`) nor the pixels left out with ``exclude`` (:func:`tghop.patches.check_exclude`).

A material's mask map stays a mask: a map whose exemplar holds only a few distinct values (a
metalness or opacity map of 0 and 1, a cut-out's 0, 0.5 and 1) comes out holding only those values.

The joint model's patches, the map's refinement and its histogram matching all make values between
a mask's levels at the edges of its elements (docs/choices.md, "Material sets, a second audit"),
where an engine expects metalness 0 or 1 and an alpha-tested opacity cuts at its own threshold.
:class:`tghop.material.Material` reads each map's levels at fit (:func:`mask_levels`, at most
:data:`MASK_LEVELS` distinct pixel values) and moves each pixel of its output to the nearest of them
(:func:`snap_to_levels`): values move, pixels do not, so the map stays aligned with the others. A
map of more values (a normal, height or roughness map, a photographed one) is left as it is, but
for its channels of at most :data:`MASK_LEVELS` values (:func:`channel_levels`: a packed ORM's
metalness in its blue, a mask map's binary channel), each snapped on its own (:func:`snap_channels`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MASK_LEVELS", "mask_levels", "snap_to_levels", "channel_levels", "snap_channels", "snap_map"]

#: A map whose exemplar holds at most this many distinct pixel values is a mask, snapped to them.
MASK_LEVELS = 4


def mask_levels(image, exclude=None, most: int = MASK_LEVELS):
    """The distinct pixel values of a map that holds at most ``most`` of them, or None.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Floats in [0, 1] (a map as :meth:`tghop.material.Material.fit` takes it).
    exclude : array_like of bool, shape (H, W), optional
        Pixels not read (those the model does not learn).
    most : int

    Returns
    -------
    ndarray, shape (k, C), k <= most, or None
        The values, sorted (each a pixel's C channels); None where the map holds more.
    """
    arr = np.asarray(image)
    pixels = arr.reshape(-1, arr.shape[-1]) if exclude is None else arr[~np.asarray(exclude, dtype=bool)]
    if len(pixels) == 0:
        return None
    sample = np.unique(pixels[:: max(1, len(pixels) // 65536)], axis=0)  # more than `most` here: no mask, early
    if len(sample) > most:
        return None
    found = np.zeros(len(pixels), dtype=bool)
    for level in sample:
        found |= (pixels == level).all(axis=1)
    return sample.astype(np.float64) if found.all() else None


def snap_to_levels(image, levels, *, out=None):
    """Each pixel of ``image`` moved to the nearest of ``levels`` (Euclidean over its channels; a
    tie to the first): the values change, not where they are.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
    levels : array_like, shape (k, C)
    out : ndarray, shape (H, W, C), optional
        Where to write (may be ``image``).

    Returns
    -------
    ndarray, shape (H, W, C), of ``image``'s dtype
    """
    levels = np.asarray(levels, dtype=np.float64)
    best = np.full(image.shape[:2], np.inf)
    pick = np.zeros(image.shape[:2], dtype=np.intp)
    for i, level in enumerate(levels):
        d = ((image - level.astype(image.dtype)) ** 2).sum(axis=2)
        closer = d < best
        best[closer], pick[closer] = d[closer], i
    if out is None:
        out = np.empty_like(image)
    out[...] = levels.astype(image.dtype)[pick]
    return out


def channel_levels(image, exclude=None, most: int = MASK_LEVELS):
    """Each channel's distinct values where it holds at most ``most`` of them (:func:`mask_levels`
    of the channel alone), or None where no channel does: the levels of a packed map's binary
    channel (an ORM's metalness), whose map holds many values (its occlusion and roughness).

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Floats in [0, 1].
    exclude : array_like of bool, shape (H, W), optional
        Pixels not read.
    most : int

    Returns
    -------
    list or None
        C entries, each an ndarray of shape (k,), k <= most, sorted (that channel's levels), or None
        (a channel of more values); None where every entry would be None.
    """
    arr = np.asarray(image)
    out = []
    for c in range(arr.shape[-1]):
        found = mask_levels(arr[..., c:c + 1], exclude, most)
        out.append(None if found is None else found[:, 0])
    return out if any(lv is not None for lv in out) else None


def snap_channels(image, levels, *, out=None):
    """Each channel of ``image`` that has levels moved to its nearest level (:func:`snap_to_levels`
    channel by channel); the channels without are copied as they are.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
    levels : sequence of array_like or None
        C entries: a channel's levels, shape (k,), or None (the channel is left as it is).
    out : ndarray, shape (H, W, C), optional
        Where to write (may be ``image``).

    Returns
    -------
    ndarray, shape (H, W, C), of ``image``'s dtype
    """
    if out is None:
        out = np.empty_like(image)
    if out is not image:
        out[...] = image
    for c, lv in enumerate(levels):
        if lv is not None:
            out[..., c:c + 1] = snap_to_levels(image[..., c:c + 1], np.asarray(lv, dtype=np.float64)[:, None])
    return out


def snap_map(image, levels, channel_levels):
    """A material's map kept at its levels: the whole map's (:func:`snap_to_levels`) where it has them,
    else its mask channels' (:func:`snap_channels`), else ``image`` as it is.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
    levels : array_like, shape (k, C), or None
        The map's levels (:attr:`tghop.material.Material.levels_`).
    channel_levels : sequence of array_like or None, or None
        Its channels' (:attr:`tghop.material.Material.channel_levels_`).

    Returns
    -------
    ndarray, shape (H, W, C), of ``image``'s dtype
    """
    if levels is not None:
        return snap_to_levels(image, levels)
    if channel_levels is not None:
        return snap_channels(image, channel_levels)
    return image
