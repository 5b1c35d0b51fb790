"""Reading and writing images: files <-> float ``(H, W, C)`` arrays in [0, 1]."""

from __future__ import annotations

import functools
import io
import os
import struct
import sys
import tempfile
import warnings
import zlib
from pathlib import Path

import numpy as np

from ._common import InvalidImageError, TGHopError, check_image
from ._errors import ImageTooLargeError
from ._formats import DEPTHS, FORMATS, TIFF_HINT, check_tifffile, extensions, warn_frames, why_unreadable
from .png import decode_png16, write_png
from .profiles import deep_to_srgb, tiff_profile, to_srgb

__all__ = ["load_image", "is_image", "save_image", "to_uint8", "to_uint16", "write_atomic", "write_png",
           "check_output_path", "written_file", "check_depth", "deepest", "generation_dtype", "save_images", "DEPTHS"]

#: Largest image :func:`load_image` reads (pixels), checked from the file's header before
#: decoding: 64 Mpx (8192x8192, the largest output tghop writes). A larger file is refused
#: (``max_pixels`` or ``downscale`` change that).
MAX_IMAGE_PIXELS = 8192 * 8192


def load_image(path, *, max_pixels=MAX_IMAGE_PIXELS, downscale=False, dtype=np.float64,
               too_large_hint: str = "pass downscale=True to reduce it (or downscale it yourself)",
               with_depth: bool = False, keep_alpha: bool = False) -> np.ndarray:
    """Read an image file as a float array.

    Parameters
    ----------
    path : str or os.PathLike
        Any format Pillow reads, turned or flipped as its EXIF orientation says (as photos
        are shown), in sRGB (:mod:`tghop.profiles`). Palette, CMYK, YCbCr and LAB images (TIFF
        files too) are converted to RGB, bilevel ones to grey; an alpha channel (in TIFF, an
        extra sample its ExtraSamples tag calls alpha) is dropped with a warning. 16-bit PNG
        and TIFF files and float TIFF files are read without loss (16-bit levels ``v`` become
        ``v / 65535``; float values in [0, 1] are kept, others taken as 8-bit or 16-bit levels);
        colour ones in TIFF need :mod:`tifffile` (``pip install 'tghop[tiff]'``) and must be
        grey or RGB (a 16-bit CMYK TIFF is refused); tghop decodes 16-bit colour PNG itself.
    max_pixels : int
        Images with more pixels (read from the header, before decoding) are refused
        with :class:`InvalidImageError`, or, with ``downscale``, reduced to at most this
        many pixels (aspect ratio kept) with a warning.
    downscale : bool
    dtype : {numpy.float64, numpy.float32, None}
        None keeps 8-bit images as uint8 (0-255, an eighth of the memory; what
        :meth:`TGHop.fit` takes for large exemplars) and gives float64 for deeper ones.
        Any other is a :class:`TGHopError`.
    too_large_hint : str
        The advice that ends the error for an image over ``max_pixels`` (the command line
        says "pass --downscale" only in the commands that have that option).
    with_depth : bool
        Also return the file's bits per channel: 8, 16 or 32 (float).
    keep_alpha : bool
        Keep an alpha channel (no warning) as the last channel, at the colours' depth: ``C``
        is then 2 (grey and alpha) or 4 (RGBA); a palette image with transparency is read
        as RGBA (``tghop inpaint`` writes it back).

    Returns
    -------
    ndarray, shape (H, W, C), in [0, 1] (0-255 for uint8)
        ``C`` is 1 for greyscale images and 3 for colour ones (2 and 4 with ``keep_alpha``).
    depth : int, only with ``with_depth``
    """
    from PIL import Image, UnidentifiedImageError  # imported on first use: not needed by `tghop info`

    try:
        wanted = None if dtype is None else np.dtype(dtype)
    except TypeError:
        wanted = False
    if wanted is not None and wanted not in (np.float64, np.float32):
        raise TGHopError(f"dtype must be numpy.float64, numpy.float32 or None (uint8 for 8-bit images), "
                         f"not {wanted.name if wanted is not False else repr(dtype)}")
    if not os.fsdecode(path).strip():  # Path("") is the current folder
        raise InvalidImageError("the image's file name is empty; give one")
    path = Path(path)
    if not path.exists():
        if path.is_symlink():  # it said "no such file" of a link that is there
            raise InvalidImageError(f"{path}: a symbolic link to no file (missing target, or a loop); fix or remove it")
        raise InvalidImageError(f"{path}: no such file; check the path")
    if path.is_dir():
        raise InvalidImageError(f"{path} is a folder, not an image; give an image file")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # our own limit applies
            deep = _read_deep(path, max_pixels, keep_alpha)
            if deep is not None:
                (arr, mode, depth), (orientation, profile) = deep, _file_header(path)
                arr = deep_to_srgb(_upright(arr, orientation), profile, path.name)  # a colour profile: sRGB
            else:
                with Image.open(path) as im:
                    arr, mode = _decode(im, path, max_pixels, downscale, too_large_hint, keep_alpha)
                    depth = 32 if im.mode == "F" else 16 if arr.dtype != np.uint8 else 8
    except TGHopError:  # ours: already one line (a missing extra too)
        raise
    except Image.DecompressionBombError:
        raise InvalidImageError(f"{path}: the image header declares too many pixels to decode safely; "
                                f"tghop reads at most {max_pixels:,} pixels") from None
    except MemoryError:
        raise InvalidImageError(f"{path}: not enough memory to decode this image; downscale it first") from None
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError, EOFError, IndexError, TypeError,
            struct.error, ZeroDivisionError, zlib.error) as exc:
        raise InvalidImageError(f"{path}: not a readable image ({why_unreadable(path, exc)}); "
                                "give a PNG, JPEG or other common image file") from None
    if not keep_alpha and (mode in ("RGBA", "LA", "PA", "RGBa", "La") or mode == "P+transparency"):
        warnings.warn(f"{path.name}: alpha channel dropped", UserWarning, stacklevel=2)
    if dtype is None and arr.dtype == np.uint8:
        out = arr[:, :, None] if arr.ndim == 2 else arr
    else:
        out = check_image(arr, name=str(path), dtype=np.float64 if dtype is None else dtype,
                          channels=(1, 2, 3, 4) if keep_alpha else (1, 3))
    return (out, depth) if with_depth else out


def is_image(path) -> bool:
    """Whether Pillow recognises ``path`` (a path or a binary file object) as an image,
    without decoding it: a decompression bomb counts.

    Parameters
    ----------
    path : str, os.PathLike or binary file object

    Returns
    -------
    bool : False for any failure to open it (a missing file, another format, a truncated header)
    """
    from PIL import Image

    try:
        with Image.open(path):
            return True
    except Image.DecompressionBombError:
        return True
    except Exception:  # noqa: BLE001 (any failure: not an image Pillow can open)
        return False


def _read_deep(path, max_pixels, keep_alpha=False):
    """16-bit PNG and TIFF files and float TIFF files that Pillow would not read whole:
    ``(array, mode, depth)`` with the array float64 in [0, 1] (uint8 for an 8-bit TIFF read
    by tifffile), or None for every other file (Pillow reads it: TIFF files too, but grey and RGB
    ones tifffile decodes, :func:`_tiff_layout`). ``mode`` is "RGBA" or "LA" when the file has
    an alpha channel: dropped, or, with ``keep_alpha``, kept last."""
    with open(path, "rb") as fh:
        head = fh.read(33)
    if head[:8] == b"\x89PNG\r\n\x1a\n" and len(head) >= 33 and head[24] == 16:
        width, height = struct.unpack(">II", head[16:24])
        if width * height > max_pixels or head[28] != 0:  # too large, or interlaced: Pillow's path (its errors)
            return None
        levels, ctype = decode_png16(path.read_bytes())
        arr, mode = _drop_alpha(levels, {4: "LA", 6: "RGBA"}.get(ctype, ""), keep_alpha)
        return arr / 65535.0, mode, 16
    if head[:4] not in (b"II*\x00", b"MM\x00*"):
        return None
    try:
        import tifffile
    except ImportError:
        from PIL import Image

        with Image.open(path) as im:  # grey 16-bit and float TIFF: Pillow; deeper colour ones: refused
            tags = im.tag_v2 if hasattr(im, "tag_v2") else {}
            bits, photometric = max(tags.get(258, (8,))), tags.get(262, 1)
            if bits > 8 and photometric not in (0, 1, 2, 3):
                _refuse_deep_tiff(path, photometric, bits)
            if bits > 8 and (photometric == 0 or im.mode in ("RGB", "RGBA")):  # Pillow: 8 bits, or not inverted
                from ._errors import MissingExtraError

                kind = "colour" if photometric == 2 else _PHOTOMETRIC_NAMES.get(photometric, "colour")
                raise MissingExtraError(f"{path}: a {bits}-bit {kind} TIFF; reading it without loss needs "
                                        f"tifffile: {TIFF_HINT}")
        return None
    try:
        tif = tifffile.TiffFile(path)
    except MemoryError:
        raise
    except Exception:  # noqa: BLE001 - a TIFF tifffile cannot parse: Pillow's path (its error if any)
        return None
    with tif:
        page, _ = tif.pages[0], warn_frames(path, len(tif.pages))
        layout = _tiff_layout(page, path)
        if layout is None:
            return None
        shape = page.shape
        if int(np.prod(shape[:2] if page.axes.startswith("YX") else shape[-2:])) > max_pixels:
            return None  # Pillow's path: its size error (or downscaling)
        try:
            arr = page.asarray()
        except MemoryError:
            raise
        except Exception as exc:  # noqa: BLE001 - e.g. LZW or JPEG compression without imagecodecs
            if page.dtype != np.uint8 and (layout[0] == 3 or layout[2]):  # Pillow: 8 bits, or not inverted
                reason = (str(exc).splitlines() or [exc.__class__.__name__])[0][:120]
                raise InvalidImageError(
                    f"{path}: tifffile cannot decode this {page.bitspersample}-bit "
                    f"{'min-is-white' if layout[2] else 'colour'} TIFF ({reason}); "
                    "pip install imagecodecs, or save it uncompressed or zlib-compressed") from None
            return None  # Pillow's path: it decodes 8-bit and grey 16-bit and float TIFF files whole
    colours, alpha, inverted, premultiplied = layout
    if page.axes.startswith("S"):  # planar: (S, H, W)
        arr = np.moveaxis(arr, 0, -1)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[2] < colours + alpha:
        return None  # an arrangement of samples tghop does not know: Pillow's path
    arr = arr[:, :, : colours + alpha]  # extra samples that are not alpha are dropped, as Pillow drops them
    if inverted:  # min-is-white integer levels
        arr = arr.copy()
        arr[:, :, 0] = np.iinfo(arr.dtype).max - arr[:, :, 0]
    if premultiplied:
        arr = _unpremultiply(arr, colours)
    arr, mode = _drop_alpha(arr, ("LA" if colours == 1 else "RGBA") if alpha else "", keep_alpha)
    if arr.dtype == np.uint8:
        return arr, mode, 8
    if arr.dtype == np.uint16:
        return arr / 65535.0, mode, 16
    return _float_pixels(arr.astype(np.float64), path), mode, 32


def _float_pixels(arr, path):
    """A float image's pixels (float64) in [0, 1], or a one-line :class:`InvalidImageError`.

    Values within :data:`RANGE_TOLERANCE` of [0, 1] are clipped (float rounding, as
    :func:`save_image` allows); whole numbers up to 65535 are integer levels in a float file
    (an 8-bit range, else 16-bit, as Pillow's path reads integer images). Anything else (NaN,
    infinity, heights in metres, HDR) is refused: divided as levels it became a nearly black
    image without a word (tghop 0.49.0)."""
    if not np.all(np.isfinite(arr)):
        raise InvalidImageError(f"{path}: NaN or infinite pixel values; tghop reads float images with values in "
                                "[0, 1]; replace them first")
    lo, hi = (arr.min(), arr.max()) if arr.size else (0.0, 1.0)
    if lo >= -RANGE_TOLERANCE and hi <= 1.0 + RANGE_TOLERANCE:
        return np.clip(arr, 0.0, 1.0)
    if lo >= 0 and hi <= 65535 and np.array_equal(arr, np.round(arr)):
        return arr / (65535.0 if hi > 255 else 255.0)
    raise InvalidImageError(f"{path}: float pixel values from {lo:.6g} to {hi:.6g}; tghop reads float images with "
                            "values in [0, 1]; rescale it to [0, 1] first (or save it with 8 or 16 bits)")


#: Names of the TIFF photometric interpretations (tag 262) tghop does not read as grey or RGB itself.
_PHOTOMETRIC_NAMES = {0: "min-is-white", 3: "palette", 4: "mask", 5: "CMYK", 6: "YCbCr", 8: "CIELAB",
                      9: "ICCLAB", 10: "ITULAB", 32803: "CFA", 32844: "LogL", 32845: "LogLuv", 34892: "LinearRaw"}


def _refuse_deep_tiff(path, photometric, bits):
    """The error for a 16-bit or float TIFF whose colours tghop cannot convert without loss."""
    name = _PHOTOMETRIC_NAMES.get(photometric, f"photometric {photometric}")
    raise InvalidImageError(f"{path}: a {bits}-bit {name} TIFF; tghop reads 16-bit and float TIFF files as grey "
                            "or RGB only; convert it to RGB (or grey) first, or save it with 8 bits")


def _tiff_layout(page, path):
    """How tghop reads a TIFF page itself: ``(colours, alpha, inverted, premultiplied)`` (1 or 3
    colour samples; whether the next sample is alpha, as its ExtraSamples tag says; min-is-white
    levels to invert; whether that alpha is associated, the colours multiplied by it), or None for
    Pillow's path: 8-bit and bilevel TIFF files of other colour kinds (palette, CMYK, YCbCr, LAB,
    min-is-white), which Pillow converts to RGB or grey, and samples
    tifffile gives in no type tghop reads. Refused: a 16-bit or float one of those colour kinds
    (Pillow would reduce it to 8 bits or read it wrong)."""
    photometric, dtype = page.photometric, page.dtype
    if photometric is None or dtype is None or not (dtype in (np.uint8, np.uint16) or dtype.kind == "f"):
        return None  # bilevel (bool), signed or 32-bit integers: Pillow's path
    photometric = int(photometric)
    colours = {0: 1, 1: 1, 2: 3}.get(photometric)
    inverted = photometric == 0
    if colours is None or (inverted and dtype == np.uint8):
        if dtype == np.uint8 or photometric == 3:
            return None
        _refuse_deep_tiff(path, photometric, page.bitspersample)
    if inverted and dtype.kind == "f":
        _refuse_deep_tiff(path, photometric, page.bitspersample)
    extras = tuple(int(e) for e in (page.extrasamples or ()))
    if page.samplesperpixel > colours and extras[:1] == (1,) and dtype == np.uint8:
        return None  # premultiplied alpha: Pillow's path, which divides it out
    alpha = page.samplesperpixel > colours and extras[:1] in ((1,), (2,))  # associated, unassociated
    return colours, int(alpha), inverted, alpha and extras[0] == 1


def _unpremultiply(arr, colours):
    """An (H, W, colours + 1) array of uint16 or float samples whose colours are multiplied by its
    last (alpha) sample, with the colours divided by it (0 where alpha is 0), in its own dtype, as
    Pillow does for 8-bit files (0.36 read them as plain colours: semi-transparent ones darker)."""
    values = arr.astype(np.float64)
    alpha = values[..., colours:]
    colour = np.divide(values[..., :colours], alpha, out=np.zeros_like(values[..., :colours]), where=alpha > 0)
    if arr.dtype == np.uint16:
        colour = np.clip(np.round(colour * 65535.0), 0, 65535)
    elif alpha.max() <= 1:  # a colour a rounding above its alpha stays in [0, 1] (else read as levels below)
        colour = np.clip(colour, 0.0, 1.0)
    values[..., :colours] = colour
    return values.astype(arr.dtype)


def _drop_alpha(arr, mode, keep_alpha=False):
    """The colour channels of an (H, W, C) array whose last channel is alpha when ``mode`` says
    so (all of them with ``keep_alpha``)."""
    if mode and not keep_alpha:
        arr = arr[..., :-1]
    return (arr[..., 0] if arr.ndim == 3 and arr.shape[2] == 1 else arr), mode


def _decode(im, path, max_pixels, downscale, too_large_hint, keep_alpha=False):
    """Decode an open Pillow image into uint8 (or float for 16-bit) array; return (array, mode).
    With ``keep_alpha`` an image with alpha (or a palette with transparency) is LA or RGBA."""
    width, height = im.size
    if width < 1 or height < 1:
        raise ValueError("empty image")
    if width * height > max_pixels:
        if not downscale:
            raise ImageTooLargeError(
                f"{path}: the image is {width}x{height} pixels, more than the {max_pixels:,} tghop reads; "
                f"{too_large_hint}")
        factor = (width * height / max_pixels) ** 0.5
        size = (max(1, int(width / factor)), max(1, int(height / factor)))
        im.draft(im.mode, size)  # JPEG: decode at reduced size directly
        warnings.warn(f"{path.name}: {width}x{height} pixels downscaled to {size[0]}x{size[1]} "
                      f"(at most {max_pixels:,} pixels)", UserWarning, stacklevel=3)
        if im.size != size:
            small = im.resize(size, resample=1, reducing_gap=2.0)  # 1 = LANCZOS
            im.close()  # frees the full-size pixels before the copies below
            im = small
    else:
        im.load()
    warn_frames(path, getattr(im, "n_frames", 1))
    orientation = _exif_orientation(im)  # after loading: Pillow's TIFF reader applies (and drops) its own
    im = to_srgb(im, path.name)  # an ICC profile other than sRGB: its colours converted (tghop.profiles)
    mode = im.mode
    if mode == "P" and "transparency" in im.info:
        mode = "P+transparency"
    if keep_alpha and (mode in ("RGBA", "LA", "PA", "RGBa", "La") or mode == "P+transparency"):
        arr = np.asarray(im if im.mode in ("RGBA", "LA") else im.convert("LA" if im.mode == "La" else "RGBA"))
    elif im.mode in ("L", "RGB"):
        arr = np.asarray(im)  # no converted copy of a large image
    elif im.mode in ("LA", "1"):
        arr = np.asarray(im.convert("L"))
    elif im.mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        arr = np.asarray(im, dtype=np.float64)
        if im.mode == "F":  # a float image (TIFF, PFM)
            arr = _float_pixels(arr, path)
        else:  # integer levels: 8-bit range, else 16-bit
            arr = np.clip(arr / (65535.0 if arr.max() > 255 else 255.0), 0.0, 1.0)
    else:
        arr = np.asarray(im.convert("RGB"))
    return _upright(arr, orientation), mode


def _exif_orientation(im) -> int:
    """An open Pillow image's EXIF orientation (tag 0x0112): 1 (as stored) when it has none or
    a damaged EXIF block."""
    try:
        return int(im.getexif().get(0x0112, 1))
    except Exception:  # noqa: BLE001 - a damaged EXIF block: the pixels as stored
        return 1


def _file_header(path):
    """(EXIF orientation, ICC profile bytes or None) of a file tghop decodes itself (16-bit PNG,
    TIFF by tifffile), from its header (no pixels decoded); orientation 1 where Pillow cannot open it."""
    from PIL import Image

    try:
        with Image.open(path) as im:
            return _exif_orientation(im), im.info.get("icc_profile")
    except Exception:  # noqa: BLE001 - not Pillow's (a float colour TIFF): the pixels as stored
        return 1, tiff_profile(path)


def _upright(arr, orientation):
    """An (H, W[, C]) array as it is displayed: turned or flipped as its EXIF ``orientation``
    says (cameras and phones store JPEG pixels sideways and record how to show them); the
    array itself for orientation 1 or an unknown one."""
    if orientation not in range(2, 9):
        return arr
    if orientation >= 5:  # the four that swap height and width: a transposition, then as 1-4
        arr = np.swapaxes(arr, 0, 1)
        orientation -= 4
    if orientation in (2, 3):
        arr = arr[:, ::-1]
    if orientation in (3, 4):
        arr = arr[::-1]
    return np.ascontiguousarray(arr)


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


def written_file(path, *, what: str = "image", error=InvalidImageError) -> Path:
    """The file that writing ``path`` replaces: ``path`` itself, or, where ``path`` is a
    symbolic link, the file the link (through a chain of links) points to, so that the link
    stays and its target gets the new content, as ``cp`` and a shell's ``>`` do. A dangling
    link gives the file it names (written if that file's folder exists,
    :func:`check_output_path`); a loop of links is an ``error``.

    Parameters
    ----------
    path : str or os.PathLike
    what : str, what is written, in the error message ("image", "model", ...)
    error : type, the exception class raised

    Returns
    -------
    pathlib.Path : ``path``, or the link's resolved target (nothing is created)
    """
    path = Path(path)
    if not path.is_symlink():
        return path
    target = Path(os.path.realpath(path))
    if target.is_symlink():  # realpath stops at a loop of links
        raise error(f"{path} is a loop of symbolic links; point the link at a file, or give the {what} another name")
    return target


def check_output_path(path, *, what: str = "image", error=InvalidImageError) -> Path:
    """Refuse an output path that is a folder, whose folder does not exist, or where no
    file can be created (read-only or unwritable folder, name too long): checked by
    creating and removing a probe file, before any long work. A symbolic link is checked
    as the file it points to (:func:`written_file`).

    Parameters
    ----------
    path : str or os.PathLike
    what : str, what is written, in the error messages ("image", "model", ...)
    error : type, the exception class raised

    Returns
    -------
    pathlib.Path : the folder the file will be written to (the link's target's, for a link)
    """
    text = os.fsdecode(path)
    if not text.strip():
        raise error(f"the {what}'s file name is empty; give one")
    if text.endswith(("/", os.sep)):  # Path() would drop the slash and write a file of that name
        raise error(f"{text} ends with a slash, as a folder does; give a file name for the {what}")
    path = Path(path)
    try:
        is_dir = path.is_dir()
        target = written_file(path, what=what, error=error)
    except OSError as exc:  # e.g. a name too long
        raise error(f"{str(path)[:80]}: cannot write the {what} there ({exc.strerror}); choose another name") from None
    if is_dir:
        raise error(f"{path} is a folder; give a file name for the {what}")
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        if target != path:
            fix = "point the link elsewhere" if directory.exists() else "create that folder or point the link elsewhere"
            raise error(f"{path} is a symbolic link to {target}, whose folder {directory} "
                        f"{'is a file' if directory.exists() else 'does not exist'}; {fix}")
        if directory.exists():
            raise error(f"{directory} is a file, not a folder; give the {what} a path in a folder")
        raise error(f"{directory}: output folder does not exist; create it first")
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".probe", dir=directory)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise error(f"{path}: cannot write the {what} there ({exc.strerror or exc.__class__.__name__}); "
                    "choose another folder or name") from None
    return directory


def write_atomic(path, write, *, what: str = "image", error=InvalidImageError) -> None:
    """Call ``write(fileobj)`` on a temporary file next to ``path``, then move it into place.

    If ``write`` raises, no file (and no partial file) is left at ``path``; an operating
    system error (disk full, ...) becomes one ``error`` line. Where ``path`` is a symbolic
    link, its target is written (:func:`written_file`; the temporary file beside the
    target, so that the move stays atomic) and the link stays.

    Parameters
    ----------
    path : str or os.PathLike, the file to write (checked first by :func:`check_output_path`)
    write : callable, ``write(fileobj)`` writes the content to a binary file object
    what : str, what is written, in the error messages
    error : type, the exception class raised for a bad path or an operating system error
    """
    path = Path(path)
    directory = check_output_path(path, what=what, error=error)
    target = written_file(path, what=what, error=error)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=directory)
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the usual permissions
        os.replace(tmp, target)
    except BaseException as exc:  # Ctrl-C and the command's SIGTERM/SIGHUP (tghop.cli.common.Terminated) too
        if tmp is None:  # mkstemp failed: nothing to remove
            if isinstance(exc, OSError):
                raise error(f"{path}: cannot write the {what} ({exc.strerror or exc.__class__.__name__})") from None
            raise
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError):
            raise error(f"{path}: writing the {what} failed ({exc.strerror or exc.__class__.__name__}); "
                        "nothing was written") from None
        raise


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
        raise InvalidImageError(f"{path}: unknown image extension {ext or '(none)'}; use {extensions()}")
    return FORMATS[ext]


#: How far outside [0, 1] a float image to save may stray (float rounding after clipping; less than
#: half an 8-bit level, so at 8 bits clipping it changes no pixel); further is refused, not clipped.
RANGE_TOLERANCE = 1e-3


def _check_pixels(image):
    """What :func:`save_image` refuses: an array that is not (H, W) or (H, W, C) with C in 1-4,
    no pixels, integers other than uint8 (0-255 as floats would clip to white, 0-65535 too),
    booleans, NaN or infinite floats, and floats outside [0, 1] by more than
    :data:`RANGE_TOLERANCE` (they would be clipped)."""
    arr = np.asarray(image)
    if arr.dtype != np.uint8 and arr.dtype.kind != "f":
        raise InvalidImageError(f"an image to save must be floats in [0, 1] or uint8, not {arr.dtype} "
                                f"(e.g. image / 255 for 8-bit levels)")
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] not in (1, 2, 3, 4)):
        raise InvalidImageError(f"an image to save must be an (H, W) or (H, W, C) array with C 1 to 4 (grey, grey "
                                f"and alpha, RGB, RGBA), not of shape {arr.shape}; pass those channels only")
    if arr.size == 0:
        raise InvalidImageError(f"an image to save has no pixels (shape {arr.shape}); give at least 1x1 pixels")
    if arr.dtype.kind == "f":
        lo, hi = float(arr.min()), float(arr.max())
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise InvalidImageError("an image to save has NaN or infinite values, which have no colour; replace them "
                                    "(e.g. numpy.nan_to_num) and scale the image to [0, 1]")
        if lo < -RANGE_TOLERANCE or hi > 1.0 + RANGE_TOLERANCE:
            raise InvalidImageError(f"an image to save must be floats in [0, 1], but its values run from {lo:.4g} "
                                    f"to {hi:.4g}; scale it to [0, 1] first (e.g. image / 255 for 8-bit levels, "
                                    "(image + 1) / 2 for [-1, 1]), or numpy.clip it")


def save_image(image, path, *, depth: int = 8) -> None:
    """Write a float image in [0, 1] to ``path`` (PNG, JPEG or TIFF by extension; ``-`` is PNG on stdout).

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
        Floats in [0, 1], or uint8 (written as they are). ``C`` is 1 or 3, or 2 or 4 with
        an alpha channel last (PNG and TIFF; JPEG holds none and is refused).
    path : str or os.PathLike
        The file appears complete or not at all.
    depth : {8, 16, 32}
        Bits per channel: 8 (any format), 16 (PNG, TIFF) or 32 (float32 TIFF, values
        not rounded to levels). A format that cannot hold it is an :class:`InvalidImageError`
        (:func:`check_depth`). Colour TIFF files of 16 or 32 bits need :mod:`tifffile`.
        So are an empty image, a channel count other than 1-4, pixels neither uint8 nor
        floats, and NaN, infinite or out-of-range floats (outside [0, 1] by more than
        :data:`RANGE_TOLERANCE`; less is clipped).
    """
    fmt = output_format(path)
    check_depth(path, depth)
    _check_pixels(image)
    if fmt == "JPEG" and np.ndim(image) == 3 and np.shape(image)[2] in (2, 4):
        raise InvalidImageError(f"{path}: JPEG holds no alpha channel; name the output "
                                f"{extensions([f for f in DEPTHS if f != 'JPEG'])}, or drop the alpha channel")
    if str(path) == "-" and sys.stdout is None:
        raise InvalidImageError("-o -: the standard output is closed; give a file name instead")
    if fmt == "TIFF":
        write = _tiff_writer(image, depth, path)
    elif fmt == "PNG":
        write = functools.partial(write_png, pixels=to_uint16(image) if depth == 16 else to_uint8(image))
    else:
        from PIL import Image

        pil = Image.fromarray(to_uint8(image))
        write = functools.partial(pil.save, format=fmt, quality=95)
    if str(path) == "-":
        buf = io.BytesIO()
        write(buf)
        sys.stdout.buffer.write(buf.getvalue())
        sys.stdout.buffer.flush()
        return
    write_atomic(path, write)


def save_images(items) -> None:
    """Write several images as one: every file appears, or none (a material's maps).

    Parameters
    ----------
    items : sequence of (image, path, depth)
        As :func:`save_image` takes them (no ``-``; each path once). Every path is checked
        first (:func:`check_output_path`); each image is then written to a temporary name
        beside its path, and once all are written they are moved into place. If a move
        fails, the files already moved are taken back (a file they replaced is restored).
        A path that is a symbolic link has its target written, as :func:`write_atomic` does.

    Raises
    ------
    InvalidImageError
        One line naming the path given (never the temporary file); no file is left.
    TGHopError
        ``items`` is not a sequence of (image, path, depth) triples.
    """
    import uuid

    checked = _check_items(items)
    done = []  # (temporary, path) written
    moved = []  # (path, backup or None) in place
    try:
        for image, path, target, depth in checked:
            tmp = target.with_name(f".{target.stem}.{uuid.uuid4().hex[:8]}.part{path.suffix}")
            try:
                save_image(image, tmp, depth=depth)
            except TGHopError as exc:
                raise type(exc)(str(exc).replace(str(tmp), str(path))) from None
            done.append((tmp, path, target))
        for tmp, path, target in done:
            backup = None
            try:
                if os.path.lexists(target):
                    backup = target.with_name(f".{target.name}.{uuid.uuid4().hex[:8]}.old")
                    os.replace(target, backup)
                os.replace(tmp, target)
            except OSError as exc:
                if backup is not None and not os.path.lexists(target):
                    os.replace(backup, target)
                raise InvalidImageError(f"{path}: writing the image failed ({exc.strerror or exc.__class__.__name__}); "
                                        "none of the images was written") from None
            moved.append((target, backup))
    except BaseException:
        for target, backup in reversed(moved):
            _undo_move(target, backup)
        for tmp, _, _ in done:
            _unlink_quietly(tmp)
        raise
    for _, backup in moved:
        if backup is not None:
            _unlink_quietly(backup)


def _check_items(items):
    """:func:`save_images`' items as a list of (image, Path, the file written, depth), every
    path checked (format, depth, folder; a symbolic link as its target) before anything is written."""
    try:
        entries = list(items)
    except TypeError:
        raise TGHopError(f"save_images takes a sequence of (image, path, depth), got {type(items).__name__}") from None
    if not entries:
        raise TGHopError("save_images takes a sequence of (image, path, depth), got none; give at least one")
    checked, seen = [], set()
    for i, entry in enumerate(entries):
        if isinstance(entry, (str, bytes)) or not hasattr(entry, "__len__") or len(entry) != 3:
            raise TGHopError(f"save_images: item {i} must be an (image, path, depth) triple, got {type(entry).__name__}"
                             f"{' of ' + str(len(entry)) if hasattr(entry, '__len__') else ''}")
        image, path, depth = entry
        if not isinstance(path, (str, os.PathLike)):
            raise TGHopError(f"save_images: item {i}'s path must be a str or path, got {type(path).__name__}")
        if str(path) == "-":
            raise InvalidImageError("save_images writes files, not the standard output (-); give a file name")
        output_format(path)
        check_depth(path, depth)
        check_output_path(path)
        path = Path(path)
        target = written_file(path)
        key = os.path.abspath(target)
        if key in seen:
            raise InvalidImageError(f"{path}: given twice to save_images; give each image its own name")
        seen.add(key)
        checked.append((image, path, target, depth))
    return checked


def _unlink_quietly(path) -> None:
    """Remove ``path`` if it is there (clean-up: an error here would hide the first one)."""
    try:
        os.unlink(path)
    except OSError:
        pass


def _undo_move(path, backup) -> None:
    """Take back a file :func:`save_images` moved to ``path``, restoring what it replaced."""
    try:
        if backup is not None:
            os.replace(backup, path)
        else:
            os.unlink(path)
    except OSError:
        pass


def _tiff_writer(image, depth, path):
    """``write(fileobj)`` for a TIFF file of ``depth`` bits: tifffile where installed (deflate
    compressed), else Pillow, which writes 8-bit ones and grey 16-bit and float ones."""
    if depth == 32:
        pixels = np.asarray(image, dtype=np.float32) / (255 if np.asarray(image).dtype == np.uint8 else 1)
        pixels = np.clip(pixels[:, :, 0] if pixels.ndim == 3 and pixels.shape[2] == 1 else pixels, 0, 1)
    else:
        pixels = to_uint16(image) if depth == 16 else to_uint8(image)
    try:
        import tifffile
    except ImportError:
        if pixels.ndim == 3 and depth > 8:
            check_tifffile(path, depth)
        from PIL import Image

        pil = Image.fromarray(pixels)  # grey uint16: mode I;16, float32: F
        return functools.partial(pil.save, format="TIFF")
    channels = 1 if pixels.ndim == 2 else pixels.shape[2]
    photometric = "rgb" if channels >= 3 else "minisblack"
    alpha = {"extrasamples": ["unassalpha"]} if channels in (2, 4) else {}  # straight alpha, as PNG's

    def write(fh):
        buf = io.BytesIO()  # tifffile wants a seekable file with a name; the temporary file's has none
        tifffile.imwrite(buf, pixels, photometric=photometric, compression="zlib", **alpha)
        fh.write(buf.getbuffer())

    return write
