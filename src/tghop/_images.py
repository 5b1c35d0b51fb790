"""The checks of image arrays and output sizes every stage shares: ``check_image`` (to float
``(H, W, C)`` in [0, 1]), ``checked_image`` (cheap, not converted), ``check_texture`` (no flat
exemplar), ``grey_as_rgb`` and ``check_size`` (``MAX_PIXELS``). The checks of other array and
number arguments are :mod:`tghop._arrays`'s.
"""

from __future__ import annotations

import math
import numbers
from typing import Optional

import numpy as np

from ._arrays import LEVELS, check_not_path, from_levels
from ._errors import InvalidImageError, TGHopError

__all__ = [
    "check_image",
    "checked_image",
    "FLAT_SPREAD",
    "grey_as_rgb",
    "check_texture",
    "MAX_PIXELS",
    "check_size",
]


def check_image(image, *, min_size: int = 1, name: str = "image", dtype=np.float64, channels=(1, 3)) -> np.ndarray:
    """Validate an image array and return it as float64 ``(H, W, C)`` in [0, 1].

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C)
        Float images must lie in [0, 1]; integer (uint8/uint16) images are rescaled.
    min_size : int
        Smallest allowed height and width.
    name : str
        How the image is called in error messages.
    dtype : {numpy.float64, numpy.float32}
        Of the result (float32 halves the memory of large exemplars).
    channels : tuple of int or None
        Channel counts accepted; None: any (the stacked maps of a material).

    Returns
    -------
    ndarray, shape (H, W, C), ``dtype``
        ``C`` is 1 for greyscale or 3 for colour (a fourth, alpha channel is not accepted
        here; :func:`tghop.imageio.load_image` drops it with a warning).
    """
    check_not_path(image, name)
    arr = np.asarray(image)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or (arr.shape[2] not in channels if channels is not None else arr.shape[2] < 1):
        if channels is None:
            raise InvalidImageError(f"{name} must have shape (H, W) or (H, W, C), got {arr.shape}; "
                                    "give it as an image array (rows, columns and optionally channels)")
        shapes = ["(H, W)"] + [f"(H, W, {c})" for c in channels]
        raise InvalidImageError(f"{name} must have shape {', '.join(shapes[:-1])} or {shapes[-1]}, got {arr.shape}; "
                                "convert it to greyscale or RGB first")
    dtype = np.dtype(dtype)
    if arr.dtype in LEVELS:
        arr = from_levels(arr, dtype)
    elif arr.dtype.kind in "fbiu":
        arr = arr.astype(dtype)
    else:
        raise InvalidImageError(f"{name} has unsupported dtype {arr.dtype}; pass a float array in [0, 1]")
    if not np.all(np.isfinite(arr)):
        raise InvalidImageError(f"{name} contains NaN or infinite values; clean it first")
    if arr.size and (arr.min() < -1e-6 or arr.max() > 1 + 1e-6):
        lo, hi = arr.min(), arr.max()
        fix = "divide by 255 for 8-bit data" if lo >= 0 and hi <= 255 else "rescale them into [0, 1]"
        raise InvalidImageError(f"{name} values must lie in [0, 1], got [{lo:.3g}, {hi:.3g}]; {fix}")
    h, w = arr.shape[:2]
    if h < min_size or w < min_size:
        raise InvalidImageError(
            f"{name} is {h}x{w} pixels but at least {min_size}x{min_size} is needed; "
            "give a larger image"
        )
    return np.clip(arr, 0.0, 1.0, out=arr if arr is not image else None)


def checked_image(image, where, name="image", channels=None, *, integers=None, empty=True):
    """``image`` as an (H, W, C) array, not converted, or a one-line :class:`InvalidImageError`
    naming ``where`` and ``name``.

    The check of the generation steps' images (:func:`tghop.colour.match_histograms`,
    :func:`tghop.refine.refine`, ...), of :meth:`tghop.hops.HopStack.fit_image`'s and of
    :func:`tghop.inpaint.inpaint`'s, cheap enough for every image they are given: float
    images must be finite and in [0, 1] (within :func:`check_image`'s tolerance; one min and
    one max, which a NaN fails), unsigned integer ones pass as they are.

    Parameters
    ----------
    image : array_like, shape (H, W, C)
    where : str
        The function checking, put before the message (``"where: name must ..."``).
    name : str
        How the image is called in the message.
    channels : int or None
        The channel count the caller's statistics have; None: any.
    integers : tuple of dtypes, optional
        The unsigned integer dtypes accepted, e.g. ``(numpy.uint8,)`` for callers that read
        8-bit levels (None: any).
    empty : bool
        Accept an image of no pixels.

    Returns
    -------
    ndarray, shape (H, W, C)
        ``np.asarray(image)``.
    """
    arr = np.asarray(image)
    if (arr.ndim != 3 or arr.shape[2] < 1 or arr.dtype.kind not in "fu"
            or (integers is not None and arr.dtype.kind == "u" and arr.dtype not in integers)):
        ints = "".join(f" or {np.dtype(d).name}" for d in integers or ())
        raise InvalidImageError(f"{where}: {name} must be an (H, W, C) float array in [0, 1]{ints}, "
                                f"got {arr.dtype} of shape {arr.shape}")
    if channels is not None and arr.shape[2] != channels:
        raise InvalidImageError(f"{where}: {name} has {arr.shape[2]} channel{'s' if arr.shape[2] != 1 else ''} where "
                                f"{channels} {'is' if channels == 1 else 'are'} expected (as many as the statistics "
                                "have)")
    if not empty and arr.size == 0:
        raise InvalidImageError(f"{where}: the {name} is empty (shape {arr.shape}); "
                                "give an image of at least one pixel")
    if arr.dtype.kind == "f" and arr.size and not (arr.min() >= -1e-6 and arr.max() <= 1 + 1e-6):
        check_image(arr, name=f"{where}: {name}", channels=None)  # its message: NaN, or the range
        raise InvalidImageError(f"{where}: {name} values must lie in [0, 1]")
    return arr


#: Largest per-channel standard deviation (in [0, 1] units) below which an exemplar is
#: flat: a quarter of an 8-bit grey level.
FLAT_SPREAD = 1 / 1024


def grey_as_rgb(image) -> bool:
    """Whether a float (H, W, C) image in [0, 1] is a grey one stored as RGB: three channels within
    1/512 (half an 8-bit level) of each other, which :func:`tghop.synthesis.prepare_exemplar` models
    as one, and :func:`tghop.metrics.common.pair` compares as one.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Floats in [0, 1] (not checked); C other than 3 is never one.

    Returns
    -------
    bool
    """
    return image.shape[2] == 3 and bool(np.abs(image[..., 1:] - image[..., :1]).max() < 1 / 512)


def check_texture(image, *, name: str = "exemplar") -> None:
    """Refuse an exemplar with no texture (every channel's standard deviation below
    :data:`FLAT_SPREAD`, a quarter of an 8-bit grey level): a one-line :class:`TGHopError`.

    The one flat-image check of tghop: :func:`tghop.synthesis.prepare_exemplar` (``fit``)
    and :meth:`tghop.cooc.CoocGAN.fit` (``tghop cooc train``, ``tghop baseline cooc``)
    call it before any work. ``image`` is ``(H, W, C)``: float in [0, 1], or uint8
    (measured exactly from histograms, without a float copy).
    """
    img = np.asarray(image)
    if img.ndim == 2:
        img = img[:, :, None]
    if img.dtype == np.uint8:
        spread = _std_uint8(img) / 255.0
    else:
        spread = float(img.reshape(-1, img.shape[-1]).std(axis=0).max()) if img.size else 0.0
    if not spread >= FLAT_SPREAD and min(img.shape[:2]) < 2:  # 0.58 called a 1x1 image flat
        raise TGHopError(f"the {name} is {img.shape[0]}x{img.shape[1]} pixels, too small to hold a texture; give a "
                         "larger image with a visible pattern")
    if not spread >= FLAT_SPREAD:
        raise TGHopError(
            f"the {name} has no texture: its pixels are all (nearly) the same colour; "
            "give an image with a visible pattern"
        )


def _std_uint8(img) -> float:
    """Largest per-channel standard deviation of a uint8 image (exact, from histograms)."""
    levels = np.arange(256.0)
    out = 0.0
    for c in range(img.shape[2]):
        hist = np.zeros(256)
        for y in range(0, img.shape[0], 1024):
            hist += np.bincount(img[y: y + 1024, :, c].ravel(), minlength=256)
        n = hist.sum()
        if n == 0:
            return 0.0
        mean = hist @ levels / n
        out = max(out, float(np.sqrt(max(hist @ (levels - mean) ** 2 / n, 0.0))))
    return out


#: Largest image tghop makes, in pixels (8192x8192): every output size is checked
#: against it (:func:`check_size`) before any work.
MAX_PIXELS = 2**26


def _brief(value) -> str:
    """``value`` for a one-line message: an array by its shape and type (its repr is many
    lines: ``synthesize(image)`` quoted every pixel), anything else by a repr of at most 60 characters."""
    if isinstance(value, np.ndarray) and value.size > 4:
        return f"an array of shape {value.shape} ({value.dtype})"
    text = repr(value)
    return text if len(text) <= 60 and "\n" not in text else f"{type(value).__name__} {text[:60]!r}..."


def check_size(size, *, default=None, limit: Optional[int] = MAX_PIXELS, name: str = "size") -> tuple:
    """An output size as ``(height, width)``, or a one-line :class:`TGHopError`.

    The one check of an output size in tghop (the library's functions, the baselines and
    the command line all call it).

    Parameters
    ----------
    size : int, (int, int) or None
        ``n`` means ``(n, n)``; None means ``default``.
    default : (int, int), optional
        The size None stands for (a baseline's exemplar size); None refuses None.
    limit : int or None
        Most pixels allowed (:data:`MAX_PIXELS`); None: no limit.
    name : str
        How the size is called in error messages (``"--size"`` on the command line).

    Returns
    -------
    (int, int)
    """
    if size is None and default is not None:
        size = default
    if isinstance(size, (numbers.Integral, np.integer)) and not isinstance(size, (bool, np.bool_)):
        size = (size, size)
    try:
        dims = tuple(size)
    except TypeError:
        raise TGHopError(f"{name} must be (height, width) in pixels, got {size!r}") from None
    if len(dims) != 2 or not all(
        isinstance(d, (numbers.Integral, np.integer)) and not isinstance(d, (bool, np.bool_)) for d in dims
    ):
        raise TGHopError(f"{name} must be two integers (height, width), got {_brief(size)}")
    h, w = int(dims[0]), int(dims[1])
    if h < 1 or w < 1:
        raise TGHopError(f"{name} must be positive, got {h}x{w}; give a height and width of at least 1 pixel")
    if limit is not None and h * w > limit:
        side = int(math.isqrt(limit))
        raise TGHopError(
            f"{name} {h}x{w} is {h * w:,} pixels, above the limit of {limit:,} ({side}x{side}); "
            "ask for a smaller image"
        )
    return h, w
