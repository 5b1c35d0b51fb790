"""The exemplar's working scale: resampled before anything is learned (``TGHop(scale=...)``).

A model sees its exemplar through 32x32 patches and, with the coarse layout, 96x96 ones
(``layout_factor`` 3). Elements much larger than that, as in a photograph of a few large
stones or bubbles taken close up, come out merged into blobs: nothing in the model holds
their outlines. ``scale`` resamples the exemplar first (0.5: half its width and height), so the
same patches hold elements twice as large, relative to them, and every output is a texture at
that scale: its elements are ``scale`` times the exemplar's size in pixels. Above 1 the exemplar
is enlarged (a small exemplar whose elements should come out larger; enlarging adds no detail).

Downsampling is Lanczos filtering with the filter widened by the factor (Pillow's ``resize``),
so fine detail is averaged away instead of aliased; each channel is resampled on its own in
float32, or as 8 bits for a uint8 exemplar of one or three channels. A sample mask
(``exclude``) marks every resampled pixel that any excluded pixel reaches.

Example
-------
>>> from tghop import TGHop, data
>>> model = TGHop(scale=0.5, rng=0).fit(data.bricks())                 # doctest: +SKIP
>>> model.exemplar_shape_                                               # doctest: +SKIP
(128, 128, 3)
"""

from __future__ import annotations

import numpy as np

__all__ = ["scaled_shape", "rescale", "rescale_mask"]


def scaled_shape(shape, scale: float) -> tuple:
    """(H, W, ...) of an exemplar of ``shape`` resampled by ``scale``: each side rounded to
    the nearest pixel, at least 1; the other dimensions as they are.

    Parameters
    ----------
    shape : tuple of int
        (H, W, ...).
    scale : float
        Greater than 0 (not checked here); 1 gives ``shape`` as a tuple.

    Returns
    -------
    tuple of int
        (H', W', ...).
    """
    if scale == 1:
        return tuple(shape)
    return tuple(max(1, round(side * scale)) for side in shape[:2]) + tuple(shape[2:])


def _resample(plane, size, mode, resample):
    from PIL import Image

    return np.asarray(Image.fromarray(plane, mode=mode).resize(size, resample=resample))


def rescale(image, scale: float) -> np.ndarray:
    """An exemplar resampled by ``scale`` (antialiased Lanczos).

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Float in [0, 1], or uint8 (0-255).
    scale : float
        Greater than 0; 1 returns ``image`` itself.

    Returns
    -------
    ndarray, shape :func:`scaled_shape` (H', W', C)
        uint8 for a uint8 image, else float64, clipped to [0, 1] (Lanczos overshoots at edges).
    """
    if scale == 1:
        return image
    from PIL import Image

    h, w, c = image.shape
    hs, ws = scaled_shape((h, w), scale)
    size, lanczos = (ws, hs), Image.Resampling.LANCZOS
    if image.dtype == np.uint8:
        if c in (1, 3):  # Pillow's 8-bit modes: one call, one byte per value
            out = _resample(np.ascontiguousarray(image if c == 3 else image[..., 0]), size, "RGB" if c == 3 else "L",
                            lanczos)
            return out.reshape(hs, ws, c)
        planes = [_resample(np.ascontiguousarray(image[..., k]), size, "L", lanczos) for k in range(c)]
        return np.stack(planes, axis=-1)
    planes = [_resample(np.ascontiguousarray(image[..., k], dtype=np.float32), size, "F", lanczos) for k in range(c)]
    return np.clip(np.stack(planes, axis=-1).astype(np.float64), 0.0, 1.0)


def rescale_mask(mask, scale: float):
    """A sample mask (H, W) bool resampled by ``scale``: True wherever an excluded pixel reaches
    (its box-filtered share above zero); None stays None.

    Parameters
    ----------
    mask : ndarray of bool, shape (H, W), or None
    scale : float
        Greater than 0; 1 returns ``mask`` itself.

    Returns
    -------
    ndarray of bool, shape (H', W') (:func:`scaled_shape`), or None
    """
    if mask is None or scale == 1:
        return mask
    from PIL import Image

    h, w = mask.shape
    hs, ws = scaled_shape((h, w), scale)
    share = _resample(np.ascontiguousarray(mask, dtype=np.float32), (ws, hs), "F", Image.Resampling.BOX)
    return share > 1e-6
