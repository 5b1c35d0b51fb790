"""The exemplar as :class:`~tghop.synthesis.TGHop` takes it, and the channels its hops keep by default.

:func:`prepare_exemplar` validates an exemplar (shape, range, not flat) and turns a grey image
stored as RGB into one channel; :func:`default_channels` gives the channels each hop keeps
when ``n_channels`` is not given, from the patch size and the exemplar's channel count. Both
are imported from :mod:`tghop.synthesis` too; the command line, ``tghop serve`` and ``tghop
batch`` prepare their exemplars with the first before fitting.
"""

from __future__ import annotations

import math

import numpy as np

from ._errors import OpaqueAlphaWarning, TGHopError, TransparencyWarning, warn
from ._images import check_image, check_texture, grey_as_rgb
from .image_decode import transparency_note, transparent_share

__all__ = ["default_channels", "prepare_exemplar", "drop_alpha"]


def default_channels(patch_size: int, n_colours: int = 3):
    """Channels kept per hop when none are given.

    Colour: the paper's K1=9, K2=22 for 32x32 patches; for 64x64 patches a third hop keeps 63 channels
    (the paper's Fig. 7: a core of 8 x 8 x 63 = 4,032; 40 until 0.49.1), so the core is 8x8 spatially in
    both cases. Grey (one channel, 4 hop-1 channels in all): K1=4, K2=10 (, K3=28), our choice in the
    same proportions. Other channel counts C (a material's stacked maps): the colour counts times C / 3.

    Parameters
    ----------
    patch_size : int
        32 (two hops) or 64 (three); others are a :class:`~tghop.TGHopError` (give ``n_channels``).
    n_colours : int
        The exemplar's channels C.

    Returns
    -------
    tuple of int
        K1, K2 (, K3): the channels hop 1, 2 (, 3) keep, in all.
    """
    if patch_size not in (32, 64):
        raise TGHopError(f"patch_size must be 32 or 64 unless n_channels is given, got {patch_size}")
    channels = (4, 10, 28) if n_colours == 1 else tuple(math.ceil(k * n_colours / 3) for k in (9, 22, 63))
    return channels[: 2 if patch_size == 32 else 3]


def prepare_exemplar(image, *, min_size: int = 1, channels=(1, 3)) -> np.ndarray:
    """A validated exemplar; a grey image stored as RGB becomes single-channel.

    Three equal channels would leave 8 of the 12 hop-1 directions empty; modelling one
    channel is the same texture at a third of the cost, and the output is grey. A flat
    exemplar (every channel's standard deviation below a quarter of an 8-bit grey level)
    has nothing to learn and is refused at once.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], uint8 or uint16 (read as x / 65535). An RGB image whose channels
        are within 1/512 of each other (uint8: equal) is grey.
    min_size : int
        Smallest height and width accepted.
    channels : tuple of int or None
        The channel counts C accepted (None: any; :class:`~tghop.synthesis.TGHop` models
        the stacked maps of a material).

    Returns
    -------
    ndarray, shape (H, W, C), C in ``channels`` (1 for a grey image stored as RGB)
        float64 in [0, 1]; a uint8 image stays uint8 (0-255), so that a large exemplar
        costs one byte per pixel and channel (:meth:`TGHop.fit <tghop.synthesis.TGHop.fit>`
        converts tile by tile).

    Raises
    ------
    tghop.InvalidImageError
        A bad shape, dtype or range, or smaller than ``min_size`` (one line).
    tghop.TGHopError
        A flat exemplar (one line).
    """
    if isinstance(image, np.ndarray) and image.dtype == np.uint8:
        img = image[:, :, None] if image.ndim == 2 else image
        if img.ndim != 3 or (channels is not None and img.shape[2] not in channels):
            check_image(img, name="exemplar", channels=channels)  # the usual shape error
        h, w = img.shape[:2]
        if h < min_size or w < min_size:
            check_image(np.zeros((h, w, 1), dtype=np.uint8), min_size=min_size, name="exemplar")
        grey = img.shape[2] == 3 and all(
            np.array_equal(img[y: y + 512, :, 1:], np.repeat(img[y: y + 512, :, :1], 2, axis=2))
            for y in range(0, h, 512))
    else:
        img = check_image(image, min_size=min_size, name="exemplar", channels=channels)
        grey = grey_as_rgb(img)
    check_texture(img)  # the one flat-image check (tghop cooc train makes it too)
    if grey:
        img = np.ascontiguousarray(img[..., :1])
    return img


def drop_alpha(image, *, stacked=False, name="exemplar", exclude="exclude=image[..., -1] < {half}",
               keep="stacked=True models every channel"):
    """The exemplar without its alpha channel, as :func:`tghop.imageio.load_image` reads an image
    file's (what ``tghop fit`` learns from a PNG with alpha): an array of 2 or 4 channels is grey or
    RGB with alpha (grey+alpha, RGBA), its last channel dropped with a warning, a
    :class:`~tghop.OpaqueAlphaWarning` where no pixel is more transparent than opaque, else a
    :class:`~tghop.TransparencyWarning` saying how much is (the colours under it are learnt as
    texture) and the ``exclude`` mask that leaves it out. 0.57 learnt the alpha as a fourth colour
    channel, without a word. The one rule of every call an image array enters where no alpha is
    kept (0.59): :meth:`TGHop.fit <tghop.synthesis.TGHop.fit>`, the albedo of
    :meth:`tghop.material.Material.fit`, a painted guide (:func:`tghop.guides.guide_labels`) and the
    metrics' images (:func:`tghop.metrics.common.pair`), each naming its image (``name``) and its fix;
    :func:`tghop.inpaint.inpaint` and :func:`~tghop.inpaint.extend` keep it (:func:`tghop.inpaint.split_alpha`).

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C)
        The exemplar as given to :meth:`TGHop.fit <tghop.synthesis.TGHop.fit>`.
    stacked : bool
        The channels are stacked maps (a material's), none of them alpha: ``image`` as given.
    name : str
        How the warning names the image (``"albedo"``, ``"result"``).
    exclude : str or None
        How the caller leaves the transparent part out (``{half}``: the alpha's mid level, 0.5, 128 or
        32768); None: cropping it is the one fix said.
    keep : str or None
        How the caller keeps every channel, said in the opaque image's warning; None: nothing.

    Returns
    -------
    array_like
        ``image`` itself, or a view of it without its last channel.
    """
    arr = image if isinstance(image, np.ndarray) else np.asarray(image)
    if stacked or arr.ndim != 3 or arr.shape[2] not in (2, 4):
        return image
    alpha = arr[..., -1]
    half = {np.dtype(np.uint8): 128, np.dtype(np.uint16): 32768}.get(alpha.dtype, 0.5)
    share = transparent_share(alpha if alpha.dtype != np.uint16 else alpha / 65535.0)
    kind = "RGBA" if arr.shape[2] == 4 else "grey+alpha"
    said = f"{name}: alpha channel dropped (an array of {arr.shape[2]} channels is read as {kind}"
    if share:
        note = transparency_note(share, exclude=None if exclude is None else exclude.format(half=half))
        warn(TransparencyWarning(f"{said}){note}", name, share))
    else:
        warn(OpaqueAlphaWarning(f"{said}{'' if keep is None else '; ' + keep})", name))
    return arr[..., :-1]
