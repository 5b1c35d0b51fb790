"""Bit depths and pixel levels: float images in [0, 1] to 8- and 16-bit levels
(:func:`to_uint8`, :func:`to_uint16`), the output format an extension names (:func:`output_format`),
the depths it holds (:func:`check_depth`, :func:`deepest`), the dtype to generate in for a depth
(:func:`generation_dtype`) and the depth of an exemplar a model records (:func:`exemplar_depth`)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ._errors import InvalidImageError, TGHopError
from ._formats import DEPTHS, FORMATS, check_tifffile, extensions

__all__ = ["RANGE_TOLERANCE", "output_format", "to_uint8", "to_uint16", "generation_dtype", "check_depth", "deepest",
           "exemplar_depth"]


#: How far outside [0, 1] a float image to save may stray (float rounding after clipping; less than
#: half an 8-bit level, so at 8 bits clipping it changes no pixel); further is refused, not clipped.
RANGE_TOLERANCE = 1e-3


def output_format(path) -> str:
    """Pillow format name for an output path (``-`` means PNG on stdout); a path that is not
    a str or os.PathLike is refused with a one-line :class:`TGHopError`."""
    if not isinstance(path, (str, os.PathLike)):
        raise TGHopError(f"the output path must be a str or os.PathLike, got {type(path).__name__}")
    if str(path) == "-":
        return "PNG"
    if not os.fsdecode(path).strip():
        raise InvalidImageError("the image's file name is empty; give one")
    ext = Path(path).suffix.lower()
    if ext not in FORMATS:
        if os.path.isdir(path):  # -o outputs/: 0.55 spoke of its extension
            raise InvalidImageError(f"{path} is a folder; give a file name for the image in it "
                                    f"(e.g. {os.path.join(path, 'texture.png')})")
        raise InvalidImageError(f"{path}: unknown image extension {ext or '(none)'}; use {extensions()}")
    return FORMATS[ext]


def to_uint8(image) -> np.ndarray:
    """Convert a float image in [0, 1] to ``uint8`` (rounding), dropping a singleton channel.
    A uint8 image is taken as it is (e.g. from ``TGHop.synthesize(..., dtype=numpy.uint8)``).

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C), float in [0, 1] (clipped; NaN: InvalidImageError) or uint8

    Returns
    -------
    ndarray of uint8, shape (H, W) or (H, W, C) with C > 1
        Levels ``round(255 x)``; a uint8 input itself (a view without its singleton channel).
    """
    arr = np.asarray(image)
    if arr.dtype == np.uint8:
        return arr[:, :, 0] if arr.ndim == 3 and arr.shape[2] == 1 else arr
    arr = np.asarray(arr, dtype=np.float64)
    _refuse_nan(arr)
    out = np.empty(arr.shape, dtype=np.uint8)
    # A few rows at a time: the temporaries of a large image stay small (an 8192x8192
    # RGB image is 1.6 GB in float64; whole-image steps made two more of those).
    step = max(1, (1 << 20) // max(1, arr[:1].size))
    for a in range(0, arr.shape[0], step):
        tmp = np.clip(arr[a : a + step], 0.0, 1.0)
        tmp *= 255.0
        out[a : a + step] = np.round(tmp, out=tmp)
    if out.ndim == 3 and out.shape[2] == 1:
        out = out[:, :, 0]
    return out


def _refuse_nan(arr) -> None:
    """One :class:`InvalidImageError` line for NaN values (they have no level to round to)."""
    if np.isnan(arr).any():
        raise InvalidImageError("an image to convert has NaN values, which have no colour; replace them first "
                                "(e.g. numpy.nan_to_num)")


def to_uint16(image) -> np.ndarray:
    """Convert a float image in [0, 1] to ``uint16`` levels 0-65535 (rounding), dropping a
    singleton channel (uint8 levels ``v`` become ``257 v``: the same value).

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C), float in [0, 1] (clipped; NaN: InvalidImageError) or uint8

    Returns
    -------
    ndarray of uint16, shape (H, W) or (H, W, C) with C > 1
    """
    arr = np.asarray(image)
    if arr.dtype == np.uint8:
        out = arr.astype(np.uint16) * np.uint16(257)
    else:
        arr = np.asarray(arr, dtype=np.float64)
        _refuse_nan(arr)
        out = np.round(np.clip(arr, 0.0, 1.0) * 65535.0).astype(np.uint16)
    return out[:, :, 0] if out.ndim == 3 and out.shape[2] == 1 else out


def generation_dtype(depth):
    """The dtype to generate an image in that is written with ``depth`` bits a channel (None: 8):
    uint8 for 8 bits (straight from the generation, no float image), float32 for more.

    Parameters
    ----------
    depth : int or None, bits per channel of the output file (8, 16 or 32)

    Returns
    -------
    type : ``numpy.uint8`` or ``numpy.float32``
    """
    return np.float32 if (depth or 8) > 8 else np.uint8


def check_depth(path, depth, *, channels=None) -> int:
    """Refuse a bit depth the output's format cannot hold (one line naming the fix);
    returns the depth (8, 16 or 32).

    Parameters
    ----------
    path : str or os.PathLike, the output file; its extension names the format (PNG: 8 or 16, JPEG: 8, TIFF: any)
    depth : int, bits per channel (a float such as 16.0, or a bool, is refused)
    channels : int, optional, the image's, where known before the work: a colour TIFF of 16 or 32
        bits without tifffile is then refused here (:func:`tghop._formats.check_tifffile`)

    Returns
    -------
    int : an :class:`InvalidImageError` for another depth, one the format cannot hold or an unknown extension
    """
    fmt = output_format(path)
    if isinstance(depth, (bool, np.bool_)) or not isinstance(depth, (int, np.integer)) or depth not in (8, 16, 32):
        whole = isinstance(depth, (float, np.floating)) and float(depth) in (8.0, 16.0, 32.0)
        raise InvalidImageError(f"depth {depth!r} is not 8, 16 or 32 bits per channel"
                                + (f"; write {int(depth)} (an integer)" if whole else ""))
    if depth not in DEPTHS[fmt]:
        fix = f"name the output {extensions([f for f, held in DEPTHS.items() if depth in held])}" + (
            " (float TIFF)" if depth == 32 else "")
        raise InvalidImageError(f"{path}: {fmt} cannot hold {depth}-bit {'float ' if depth == 32 else ''}values "
                                f"(it takes {' or '.join(map(str, DEPTHS[fmt]))} bits); {fix}, or pick another depth")
    if fmt == "TIFF" and channels is not None and channels > 1 and depth > 8:
        check_tifffile(path, depth)
    return depth


def deepest(path, depth: int) -> int:
    """The largest depth, at most ``depth``, that ``path``'s format holds (a 16-bit image
    written as JPEG: 8; a float one as PNG: 16).

    Parameters
    ----------
    path : str or os.PathLike, the output file (an unknown extension: :class:`InvalidImageError`)
    depth : int, bits per channel wanted (below 8 counts as 8)

    Returns
    -------
    int : 8, 16 or 32
    """
    return max(d for d in DEPTHS[output_format(path)] if d <= max(depth, 8))


def exemplar_depth(depth, image=None, *, what: str = "depth"):
    """The bits per channel of an exemplar's file that a model records
    (:attr:`tghop.TGHop.exemplar_depth_`): ``depth`` checked, or without it ``image``'s dtype's.

    Parameters
    ----------
    depth : {8, 16, 32} or None, as given (``fit``'s ``depth``, a model file's metadata)
    image : array_like, optional, the exemplar: uint8 is 8 bits, uint16 16; any other dtype (floats,
        which hold any file's levels) leaves the depth unknown
    what : str, the name of ``depth`` in the error (``the metadata's exemplar_depth``)

    Returns
    -------
    int or None : 8, 16 or 32, or None when not known; another ``depth`` is a one-line :class:`TGHopError`
    """
    if depth is None:
        dtype = getattr(image, "dtype", None)
        return 8 if dtype == np.uint8 else 16 if dtype == np.uint16 else None
    if isinstance(depth, (bool, np.bool_)) or not isinstance(depth, (int, np.integer)) or depth not in (8, 16, 32):
        raise TGHopError(f"{what} must be 8, 16 or 32 (bits per channel of the exemplar's file; 32: float) "
                         f"or None, got {depth!r}")
    return int(depth)
