"""Reading and writing images: files <-> float ``(H, W, C)`` arrays in [0, 1].

The entry points live here (:func:`load_image`, :func:`save_image`, :func:`save_images`,
:func:`is_image`); their parts are modules of their own, whose public names this module
re-exports: decoding files (:mod:`tghop.image_decode`: Pillow's path, 16-bit PNG, TIFF through
tifffile), bit depths and levels (:mod:`tghop.depths`: ``to_uint8``, ``check_depth``, ...),
safe output files (:mod:`tghop.output_files`: ``write_atomic``, ``check_output_path``, ...)
and the PNG writer (:mod:`tghop.png`).
"""

from __future__ import annotations

import functools
import io
import os
import struct
import sys
import zlib
from pathlib import Path

import numpy as np

from ._errors import InvalidImageError, MissingExtraError, OpaqueAlphaWarning, TGHopError, TransparencyWarning, warn
from ._images import check_image
from ._progress import report
from ._formats import DEPTHS, check_tifffile, checkpoint_note, extensions, missing_decoder, unread_format, unreadable
from .depths import RANGE_TOLERANCE, check_depth, deepest, generation_dtype, output_format, to_uint8, to_uint16
from .image_decode import (decode_pillow, file_header, has_alpha, metadata_too_large, open_image, read_deep,
                           transparency_note, transparent_share, upright)
from .output_files import check_output_path, temporary_prefix, write_atomic, write_fix, written_file
from .png import WRITING, write_png
from .profiles import deep_to_srgb, gamma_to_srgb

__all__ = ["load_image", "is_image", "save_image", "to_uint8", "to_uint16", "write_atomic", "write_png",
           "check_output_path", "written_file", "check_depth", "deepest", "generation_dtype", "save_images", "DEPTHS"]

#: Largest image :func:`load_image` reads (pixels), checked from the file's header before
#: decoding: 64 Mpx (8192x8192, the largest output tghop writes). A larger file is refused
#: (``max_pixels`` or ``downscale`` change that).
MAX_IMAGE_PIXELS = 8192 * 8192


def load_image(path, *, max_pixels=MAX_IMAGE_PIXELS, downscale=False, dtype=np.float64,
               too_large_hint: str = "pass downscale=True to reduce it (or downscale it yourself)",
               with_depth: bool = False, keep_alpha: bool = False, as_data: bool = False) -> np.ndarray:
    """Read an image file as a float array.

    Parameters
    ----------
    path : str or os.PathLike
        Any format Pillow reads, turned or flipped as its EXIF orientation says (as photos
        are shown), in sRGB (:mod:`tghop.profiles`). Palette, CMYK, YCbCr and LAB images (TIFF
        files too) are converted to RGB, bilevel ones to grey; an alpha channel (in TIFF, an
        extra sample its ExtraSamples tag calls alpha, or an RGB file's one 4th sample the tag
        leaves unmarked, said; in PNG, a transparent colour too) is dropped with a warning. 16-bit PNG
        and TIFF files and float TIFF files are read without loss (16-bit levels ``v`` become
        ``v / 65535``; float values in [0, 1] are kept, others taken as 8-bit or 16-bit levels;
        signed or 32-bit integer values must be levels from 0 to 65535, as must those floats; a
        TIFF whose first image is a reduced-resolution preview, as a camera raw file's, is refused);
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
    as_data : bool
        The file holds data, not colours (a material's normal, height, roughness, metalness, AO or
        packed map): its values are read as stored, without a word; an ICC profile and a PNG's gamma
        (gAMA) are not applied (:mod:`tghop.profiles` converts a colour image's), since converting
        would corrupt them (a normal map's vectors would no longer be unit length). A CMYK image,
        whose stored values are no data, is converted to RGB as without it.

    Returns
    -------
    ndarray, shape (H, W, C), in [0, 1] (0-255 for uint8)
        ``C`` is 1 for greyscale images and 3 for colour ones (2 and 4 with ``keep_alpha``).
    depth : int, only with ``with_depth``

    Raises
    ------
    InvalidImageError
        The file is missing, not an image, truncated, too large, ...: one line naming it.
    MissingExtraError
        A file of a format the installed Pillow was built without (WebP, AVIF, JPEG 2000; 0.57:
        it was "not an image format tghop reads"), or a decoder Pillow lacks, or a colour TIFF of
        16 or 32 bits without :mod:`tifffile`: the file itself may be sound
        (:func:`tghop._formats.missing_decoder`).
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
    found = None
    try:
        deep = read_deep(path, max_pixels, keep_alpha=True)  # an alpha dropped below, its transparency told
        if deep is not None:
            (arr, mode, depth), (orientation, profile, gamma) = deep, file_header(path)
            arr = upright(arr, orientation)
            if not as_data:  # a colour image: its profile, else a PNG's gamma alone, converted to sRGB
                arr = deep_to_srgb(arr, profile, path.name)
                arr = gamma_to_srgb(arr, gamma, path.name, alpha=bool(mode))
            hidden = None
            if mode and not keep_alpha:
                hidden = transparent_share(arr[..., -1])
                arr = arr[..., :-1] if arr.shape[2] > 2 else arr[..., 0]
        else:
            with open_image(path) as im:  # our own limit applies (Pillow's warning of it hidden on the main thread)
                found = im.format  # named if it fails partway (0.58: "truncated or corrupt: OSError: ...")
                arr, mode = decode_pillow(im, path, max_pixels, downscale, too_large_hint, keep_alpha,
                                          as_data=as_data)
                depth = 32 if im.mode == "F" else 16 if arr.dtype != np.uint8 else 8
                hidden = (None if keep_alpha or not has_alpha(mode) or im.width * im.height > max_pixels
                          else transparent_share(np.asarray((im if "A" in im.getbands() else im.convert("RGBA"))
                                                            .getchannel("A"))))  # not of a downscaled one
    except TGHopError:  # ours: already one line (a missing extra too)
        raise
    except Image.DecompressionBombError:
        raise InvalidImageError(f"{path}: the image header declares too many pixels to decode safely; "
                                f"tghop reads at most {max_pixels:,} pixels: downscale it first (or, if it is "
                                f"smaller, its header is corrupt: save it again)") from None
    except MemoryError:
        raise InvalidImageError(f"{path}: not enough memory to decode this image; downscale it first") from None
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError, EOFError, IndexError, TypeError,
            struct.error, ZeroDivisionError, zlib.error) as exc:
        lacking = missing_decoder(path, exc)  # the file may be sound: said apart (a batch tries it again)
        if lacking:
            raise MissingExtraError(f"{path}: {lacking}; install a Pillow that reads it (pip install --upgrade "
                                    "pillow) or convert the file to PNG") from None
        if isinstance(exc, ValueError) and "MAX_TEXT_" in str(exc):  # 0.57: "not a readable image ... give a PNG"
            raise metadata_too_large(path) from None
        known = unread_format(path) if isinstance(exc, UnidentifiedImageError) else None
        if known:
            raise InvalidImageError(f"{path}: {known}, a format tghop does not read; convert it to PNG, TIFF "
                                    "or JPEG first") from None
        raise InvalidImageError(f"{path}: {unreadable(path, exc, found)}{checkpoint_note(path)}") from None
    if not keep_alpha and has_alpha(mode):
        said = f"{path.name}: alpha channel dropped{transparency_note(hidden)}"
        warn(TransparencyWarning(said, path.name, hidden) if hidden else UserWarning(said) if hidden is None
             else OpaqueAlphaWarning(said, path.name), stacklevel=2)
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
        with open_image(path, say=False):  # no warning of a damaged EXIF block, on any thread (0.58: Pillow's)
            return True
    except Image.DecompressionBombError:
        return True
    except Exception:  # noqa: BLE001 (any failure: not an image Pillow can open)
        return False


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


def save_image(image, path, *, depth: int = 8, progress=None) -> None:
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
    progress : callable, optional
        ``progress("writing", done, total)`` (:data:`tghop.png.WRITING`): a PNG's compressed
        parts and its write as they finish (:func:`write_png`), a JPEG or TIFF file 0 then 1
        of 1. The bytes written are the same with it or without.
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
        write = _whole_write(_tiff_writer(image, depth, path), progress)
    elif fmt == "PNG":
        write = functools.partial(write_png, pixels=to_uint16(image) if depth == 16 else to_uint8(image),
                                  progress=progress)
    else:
        from PIL import Image

        pil = Image.fromarray(to_uint8(image))
        write = _whole_write(functools.partial(pil.save, format=fmt, quality=95), progress)
    if str(path) == "-":
        buf = io.BytesIO()
        write(buf)
        sys.stdout.buffer.write(buf.getvalue())
        sys.stdout.buffer.flush()
        return
    write_atomic(path, write)


def _one_of(progress, k, n):
    """A ``progress`` for image ``k`` of ``n`` written in one stage: its ``done`` of ``total``
    as 1000 steps after the ``k`` images before it, of ``1000 n``."""
    if progress is None:
        return None
    report(progress, WRITING, 1000 * k, 1000 * n)  # a bad progress refused here, before any file
    return lambda stage, done, total: report(progress, stage, 1000 * k + 1000 * done // max(total, 1), 1000 * n)


def _whole_write(write, progress):
    """``write(fh)`` told to ``progress`` as one step of :data:`tghop.png.WRITING` (a writer
    whose parts cannot be counted: JPEG, TIFF)."""
    if progress is None:
        return write

    def told(fh):
        report(progress, WRITING, 0, 1)
        write(fh)
        report(progress, WRITING, 1, 1)

    return told


def save_images(items, *, progress=None) -> None:
    """Write several images as one: every file appears, or none (a material's maps).

    Parameters
    ----------
    items : sequence of (image, path, depth)
        As :func:`save_image` takes them (no ``-``; each path once). Every path is checked
        first (:func:`check_output_path`); each image is then written to a temporary name
        beside its path, and once all are written they are moved into place. If a move
        fails, the files already moved are taken back (a file they replaced is restored).
        A path that is a symbolic link has its target written, as :func:`write_atomic` does.
    progress : callable, optional
        ``progress("writing", done, total)`` over all the images: 1000 steps each, told as
        :func:`save_image` tells its own.

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
        for k, (image, path, target, depth) in enumerate(checked):
            # the name's start only: save_image's own temporary file adds to this name, and a long one (0.61:
            # 227 to 239 characters) passed check_output_path's probe, then failed after the work (0.62)
            tmp = target.with_name(f".{target.stem[:32]}.{uuid.uuid4().hex[:8]}.part{path.suffix}")
            try:
                save_image(image, tmp, depth=depth, progress=_one_of(progress, k, len(checked)))
            except TGHopError as exc:
                raise type(exc)(str(exc).replace(str(tmp), str(path))) from None
            done.append((tmp, path, target))
        for tmp, path, target in done:
            backup = None
            try:
                if os.path.lexists(target):
                    backup = target.with_name(f"{temporary_prefix(target)}{uuid.uuid4().hex[:8]}.old")
                    os.replace(target, backup)
                os.replace(tmp, target)
            except OSError as exc:
                if backup is not None and not os.path.lexists(target):
                    os.replace(backup, target)
                raise InvalidImageError(f"{path}: writing the image failed ({exc.strerror or exc.__class__.__name__}), "
                                        f"none of the images was written; {write_fix(exc)}") from None
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
