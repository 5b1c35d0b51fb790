"""The picture inpainting fills and its hole, as :mod:`tghop.inpaint` and the front ends that read them
(``tghop inpaint``, the web page) take them: a mask read as the hole (:func:`check_hole`; refused
empty by :func:`require_hole`; :func:`grey_share`: a picture given as a mask), an alpha channel set
apart and given back opaque in the hole (:func:`split_alpha`, :func:`with_alpha`), a model's
channels against the picture's (:func:`channel_mismatch`), and the integer depths kept
(:data:`LEVELS`).

Up to 0.63 these were part of :mod:`tghop.inpaint`, which still re-exports them.
"""

from __future__ import annotations

import numpy as np

from ._arrays import check_not_path
from ._errors import TGHopError

__all__ = ["LEVELS", "check_hole", "require_hole", "grey_share", "MASK_BLACK_WHITE", "MASK_PICTURE_SHARE",
           "split_alpha", "with_alpha", "channel_mismatch"]

#: The integer images filled, each kept at its depth: its levels' top (``v / top`` is the value in [0, 1],
#: as :func:`tghop.imageio.load_image` reads 16-bit files); a mask's hole is above half of it.
LEVELS = {np.dtype(np.uint8): 255, np.dtype(np.uint16): 65535}


def check_hole(mask, shape) -> np.ndarray:
    """The hole of an image of ``shape`` as an (H, W) bool array.

    Raises :class:`TGHopError` for a mask of another size, or with NaN or infinite values.

    Parameters
    ----------
    mask : array_like, shape (H, W) or (H, W, C)
        bool (True: hole), or numbers (> 0.5: hole; uint8 and uint16 levels: above half their
        top; an (H, W, C) mask counts a pixel as hole when its channels' mean is).
    shape : tuple of int, the image's shape (H, W) or (H, W, C); only H and W are read

    Returns
    -------
    ndarray of bool, shape (H, W): True in the hole (it may be empty: :func:`require_hole` refuses that)
    """
    check_not_path(mask, "the mask")
    arr = original = np.asarray(mask)
    if arr.dtype.kind not in "biuf":
        raise TGHopError(f"the mask must be numbers or booleans, got dtype {arr.dtype}")
    if arr.dtype.kind == "f" and not np.isfinite(arr).all():
        raise TGHopError("the mask has NaN or infinite values; give True (or 1) in the hole and False (0) elsewhere")
    if arr.ndim == 3 and arr.shape[2]:  # no channels: refused as of another shape below (a mean of none was NaN)
        arr = arr.mean(axis=2)
    if arr.dtype != bool:
        arr = arr > (LEVELS[original.dtype] / 2 if original.dtype in LEVELS else 0.5)
    if arr.ndim != 2 or arr.shape != tuple(shape[:2]):
        raise TGHopError(f"the mask is {'x'.join(map(str, arr.shape))} but the image is {shape[0]}x{shape[1]}; "
                         "give an (H, W) or (H, W, C) mask of the image's size")
    return arr


#: A mask's pixels within this of black or white (their channels' mean, and their channels within this of
#: each other) are black and white (:func:`grey_share`); ``tghop inpaint`` and the web server warn where more than
#: MASK_PICTURE_SHARE are not (a feathered brush's edges: 5 % for a circle of radius 60 blurred by sigma 4, 19 % by
#: sigma 16; a photograph: 24-100 % of the 44 exemplars).
MASK_BLACK_WHITE = 0.15
MASK_PICTURE_SHARE = 0.2


def grey_share(mask) -> float:
    """The share of a mask's pixels that are neither black nor white (:data:`MASK_BLACK_WHITE`), of every other
    pixel in each direction: more than :data:`MASK_PICTURE_SHARE` is a picture given as a mask (or a picture and
    its mask swapped), whose light pixels are taken as the hole.

    Parameters
    ----------
    mask : ndarray, shape (H, W, C)
        Floats in [0, 1], its alpha channel left out.

    Returns
    -------
    float in [0, 1]
    """
    sample = np.asarray(mask)[::2, ::2]  # every other pixel: a share, at a quarter of the memory of a large mask's
    black_white = ((np.abs(sample.mean(axis=2) - 0.5) > 0.5 - MASK_BLACK_WHITE)
                   & (np.ptp(sample, axis=2) <= MASK_BLACK_WHITE))
    return 1 - float(black_white.mean())


def require_hole(hole, mask_name: str) -> None:
    """Refuse a hole (from :func:`check_hole`) with no pixel in it: nothing would be filled.

    Parameters
    ----------
    hole : array_like of bool, shape (H, W)
    mask_name : str, the mask in the message, e.g. ``"MASK m.png"``
    """
    if not np.any(hole):
        raise TGHopError(f"{mask_name} has no white pixel, so there is nothing to fill; paint the hole white "
                         "(a pixel whose channels' mean is above mid-grey)")


def split_alpha(picture):
    """A grey+alpha or RGBA picture (H, W, 2 or 4) as its colours and its alpha channel
    (H, W, 1), of the picture's dtype; other pictures as they are and None.

    Parameters
    ----------
    picture : array_like, shape (H, W) or (H, W, C), any dtype (nothing is checked or converted)

    Returns
    -------
    colours : ndarray, shape (H, W, C - 1) (a copy) for C in {2, 4}, else ``picture`` as an array
    alpha : ndarray, shape (H, W, 1) (a view), or None
    """
    arr = np.asarray(picture)
    if arr.ndim == 3 and arr.shape[2] in (2, 4):
        return np.ascontiguousarray(arr[..., :-1]), arr[..., -1:]
    return arr, None


def with_alpha(filled, alpha, hole):
    """The filled picture (H, W, C) with the alpha channel :func:`split_alpha` took (or None: ``filled`` as
    it is) back as its last channel: as it was outside the hole, opaque in it (8-bit 255, 16-bit 65535, else 1.0).

    Parameters
    ----------
    filled : ndarray, shape (H, W, C), of the alpha's depth (its levels are cast, not rescaled)
    alpha : ndarray, shape (H, W, 1), or None
    hole : ndarray of bool, shape (H, W)

    Returns
    -------
    ndarray, shape (H, W, C + 1), ``filled``'s dtype; ``filled`` itself when ``alpha`` is None
    """
    if alpha is None:
        return filled
    alpha = np.where(hole[..., None], LEVELS.get(alpha.dtype, 1.0), alpha).astype(filled.dtype)
    return np.concatenate([filled, alpha], axis=2)


def channel_mismatch(image, n_channels):
    """Why a model of ``n_channels`` channels cannot fill ``image`` ((H, W) or (H, W, C)), as
    ``(what the model is, what the image is)`` ("greyscale", "has colour"), or None when it can: the same
    channels, or a greyscale model and an RGB image whose three channels are equal. What :func:`tghop.inpaint.inpaint`
    refuses, for a check before a model is fitted.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C)
    n_channels : int, the model's channels

    Returns
    -------
    tuple of (str, str), or None: ``("in colour", "is greyscale")`` for any other mismatch than the one above
    """
    arr = np.asarray(image)
    c = 1 if arr.ndim == 2 else arr.shape[2]
    if c == n_channels or (n_channels == 1 and c == 3
                           and np.array_equal(arr[..., 1:], np.repeat(arr[..., :1], 2, axis=2))):
        return None
    if n_channels == 1 and c == 3:
        return "greyscale", "has colour"
    return "in colour", "is greyscale"
