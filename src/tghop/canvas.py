"""Growing an image beyond its edges (outpainting): the image at an anchor of a larger canvas
(:func:`expand_canvas`), the rest of the canvas the hole that :func:`tghop.inpaint.extend` fills with
a model's texture (as :func:`tghop.inpaint.inpaint` fills any hole).

Example
-------
>>> import numpy as np
>>> from tghop.canvas import expand_canvas
>>> canvas, hole, offset = expand_canvas(np.ones((2, 3)), (4, 4), anchor="top-left")
>>> canvas.shape, int(hole.sum()), offset
((4, 4), 10, (0, 0))
"""

from __future__ import annotations

import numpy as np

from ._arrays import check_not_path
from ._errors import TGHopError
from ._images import check_size

__all__ = ["expand_canvas", "ANCHORS"]

#: Where :func:`expand_canvas` (and :func:`tghop.inpaint.extend`) keeps the image on the larger canvas
#: (a canvas-size dialog's anchor).
ANCHORS = ("center", "top", "bottom", "left", "right", "top-left", "top-right", "bottom-left", "bottom-right")


def expand_canvas(image, size, *, anchor="center", patch_size=None):
    """``image`` on a larger canvas of ``size``, at ``anchor``, and the canvas's hole (the rest).

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
        Any dtype.
    size : int or (int, int)
        The canvas's (height, width), at least ``image``'s in both and larger in one.
    anchor : str
        One of :data:`ANCHORS`: where the image sits (``"top-left"``: the canvas grows
        to the right and downwards; ``"center"``: evenly all round, the odd pixel
        below and to the right).
    patch_size : int, optional
        The side of the patches that will fill the new area (the model's ``patch_size``): a
        canvas thinner than one is refused, naming the image, the size and the size that
        would do (as :func:`tghop.inpaint.extend` says it). None: not checked.

    Returns
    -------
    canvas : ndarray, shape (size[0], size[1]) + image.shape[2:]
        ``image``'s dtype: ``image`` at its place, zeros elsewhere.
    hole : ndarray of bool, shape size
        True outside the image.
    offset : (int, int)
        The canvas row and column of ``image``'s top-left pixel.
    """
    check_not_path(image, "the image")
    arr = np.asarray(image)
    if arr.ndim not in (2, 3):
        raise TGHopError(f"image must have shape (H, W) or (H, W, C), got {arr.shape}")
    if arr.size == 0:  # it was grown to a canvas all hole: a texture, with none of the image kept
        raise TGHopError(f"the image is empty (shape {arr.shape}); give an image of at least one pixel")
    if anchor not in ANCHORS:
        raise TGHopError(f"anchor must be one of {', '.join(ANCHORS)}; got {anchor!r}")
    hh, ww = check_size(size)
    h, w = arr.shape[:2]
    if hh < h or ww < w:
        raise TGHopError(f"the size {hh}x{ww} is smaller than the image ({h}x{w}) in "
                         f"{'height' if hh < h else 'width'}; give a size at least {h}x{w} (crop the image first "
                         "to make it smaller)")
    if (hh, ww) == (h, w):
        raise TGHopError(f"the size {hh}x{ww} is the image's own, so there is nothing to extend; give a larger size")
    if patch_size is not None and min(hh, ww) < patch_size:
        p = int(patch_size)
        raise TGHopError(f"the image ({h}x{w}) extended to {hh}x{ww} is thinner than the {p}x{p} patches that fill "
                         f"the new area; give a size of at least {max(hh, p)}x{max(ww, p)}, or use a model fitted "
                         "with a smaller patch_size")
    y = 0 if anchor.startswith("top") else hh - h if anchor.startswith("bottom") else (hh - h) // 2
    x = 0 if anchor.endswith("left") else ww - w if anchor.endswith("right") else (ww - w) // 2
    canvas = np.zeros((hh, ww) + arr.shape[2:], dtype=arr.dtype)
    canvas[y:y + h, x:x + w] = arr
    hole = np.ones((hh, ww), dtype=bool)
    hole[y:y + h, x:x + w] = False
    return canvas, hole, (y, x)
