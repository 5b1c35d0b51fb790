"""Decoding image files into arrays, for :func:`tghop.imageio.load_image`: Pillow's path
(:func:`decode_pillow`: any format, downscaled on request, colour profiles and EXIF orientation applied)
and tghop's own for what Pillow would not read whole (:func:`read_deep`: 16-bit PNG, TIFF files
through :mod:`tifffile`: 16-bit and float, alpha, min-is-white, premultiplied, and 32-bit BMP: :mod:`tghop.bmp`)."""

from __future__ import annotations

import io
import os
import struct
import threading
import warnings

import numpy as np

from ._errors import ImageTooLargeError, InvalidImageError, warn
from ._formats import TIFF_HINT, read_as_it_stands, warn_frames
from .depths import RANGE_TOLERANCE
from .bmp import read_bmp
from .png import decode_png16
from .profiles import gamma_to_srgb, png_gamma, tiff_profile, to_srgb
from .tiff_tags import FIELD_BYTES, quiet_copy

__all__ = ["open_image", "exif_damage", "read_deep", "decode_pillow", "file_header", "upright", "has_alpha",
           "transparent_share", "transparency_note", "share_text", "metadata_too_large"]


#: Pillow's modes with an alpha channel ("P+transparency": a palette with a transparent entry, as
#: :func:`decode_pillow` names it).
ALPHA_MODES = ("RGBA", "LA", "PA", "RGBa", "La", "P+transparency")


def has_alpha(mode: str) -> bool:
    """Whether an image of ``mode`` (as :func:`decode_pillow` or :func:`read_deep` return it) has alpha."""
    return mode in ALPHA_MODES


def transparent_share(alpha) -> float:
    """The share of an alpha channel's pixels (an array: uint8 or float in [0, 1]) that are more
    transparent than opaque: those whose colours an exemplar read without its alpha shows anyway."""
    alpha = np.asarray(alpha)
    return float(np.mean(alpha < (128 if alpha.dtype == np.uint8 else 0.5))) if alpha.size else 0.0


def share_text(share) -> str:
    """A transparent share (:func:`transparent_share`) as the warnings and notes say it: "under 1%" or "37%"."""
    return "under 1%" if share < 0.005 else f"{share:.0%}"


def transparency_note(share, *, exclude="an exclude mask (--exclude MASK, white where it is transparent)") -> str:
    """What follows "alpha channel dropped" in :func:`tghop.imageio.load_image`'s warning: nothing
    for an opaque image (or ``share`` None: not known), else how much was transparent and what to do,
    since the colours under transparent pixels (black, white, whatever the editor left) are then
    taken as they are, learnt as part of the texture; ``exclude``: how the caller's user leaves that
    part out (the command line's option; :func:`tghop.exemplar.drop_alpha`'s, an ``exclude`` array), None:
    cropping is the one fix (a metric's image, a guide: 0.59)."""
    if not share:
        return ""
    other = "" if exclude is None else f", or leave that part out with {exclude}"
    return (f", though {share_text(share)} of its pixels are transparent: the colours under them are taken as "
            f"texture; crop it to its opaque part{other}")


def open_image(path, *, say=True):
    """``PIL.Image.open(path)`` (the header read, no pixels decoded; the caller closes it, e.g.
    ``with``), less Pillow's DecompressionBombWarning on the main thread, and a JPEG's damaged EXIF
    block said in tghop's words in every thread (``say``: said at all).

    Pillow warns of a header over its ``Image.MAX_IMAGE_PIXELS`` as it opens one; tghop's own limit
    applies instead (:func:`decode_pillow` refuses or downscales before decoding). Hiding the warning
    takes ``warnings.catch_warnings``, which is process-wide (not thread-safe) before Python 3.14: it is
    used on the main thread alone (the command line's reads). On other threads (the server's uploads,
    a batch worker's tasks) Pillow's warning of such a header goes to the console as Pillow says it; the
    image is then refused or downscaled in tghop's words all the same (on the server, a 413: tghop's
    64 Mpx limit is below Pillow's 89 Mpx warning threshold). On the main thread Pillow's other warnings
    are passed on.

    A JPEG whose EXIF block Pillow would warn of ("Corrupt EXIF data", as it parses it on opening) is
    found first (:func:`exif_damage`) and opened from a copy in memory whose block Pillow does not
    take for EXIF: tghop's warning alone, in every thread, with no filter or handler of the process
    changed (0.58: tghop's words on the main thread, Pillow's on the others). A TIFF whose tag directories
    Pillow would warn of is opened alike from a copy it reads without a word (:func:`tghop.tiff_tags.quiet_copy`,
    0.60; 0.59: Pillow's words on threads other than the main one); one whose first directory is cut short
    is refused in one line.
    """
    from PIL import Image

    source = quiet_copy(path) or _hide_damaged_exif(path, say)
    if threading.current_thread() is not threading.main_thread():
        return Image.open(source)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        im = Image.open(source)
    for w in caught:  # the others passed on; a damaged EXIF block :func:`exif_damage` missed in tghop's words
        text = " ".join(str(w.message).split())
        if issubclass(w.category, Image.DecompressionBombWarning):
            continue
        if text.startswith("Corrupt EXIF data"):
            if say:
                _warn_exif(getattr(path, "name", path), text[18:])
        else:
            warn(w.message, w.category)
    return im


def _warn_exif(path, why):
    """Say that the EXIF block of the image at ``path`` is damaged (``why``, Pillow's words for it)."""
    warn(f"{os.path.basename(os.fsdecode(path))}: its EXIF data is damaged ({why.strip().rstrip('.')}); its "
         "orientation is not read: the pixels are taken as stored")


def exif_damage(exif):
    """Why Pillow cannot read the EXIF block ``exif`` (bytes, "Exif\\0\\0" first or not) whole, in its
    words ("Expecting to read 12 bytes but only got 4": its first directory runs past the block's end,
    where Pillow stops and warns "Corrupt EXIF data"), or None where it can (or refuses it without a
    word: a block that is no TIFF header)."""
    if exif[:6] == b"Exif\x00\x00":
        exif = exif[6:]
    if len(exif) < 8 or exif[:4] not in (b"II*\x00", b"MM\x00*"):
        return None
    order = "<" if exif[:2] == b"II" else ">"
    offset = struct.unpack(order + "I", exif[4:8])[0]
    left = max(0, len(exif) - offset)
    if left < 2:
        return f"Expecting to read 2 bytes but only got {left}"
    count = struct.unpack(order + "H", exif[offset:offset + 2])[0]
    left -= 2
    if left < 12 * count:
        return f"Expecting to read 12 bytes but only got {left % 12}"
    if left - 12 * count < 4:
        return f"Expecting to read 4 bytes but only got {left - 12 * count}"
    return None


def _values_past_end(tiff):
    """Where (offsets in ``tiff``, an EXIF block less "Exif\\0\\0", whose first directory
    :func:`exif_damage` found whole) the directory's entries are whose values lie past the block's end, or
    whose values' sizes add up to more than it holds: Pillow skips each with a warning ("Tag data larger than
    file", "Truncated File Read", the latter ending the directory there), on any thread. None is the
    orientation, whose value is in its entry."""
    order = "<" if tiff[:2] == b"II" else ">"
    start = struct.unpack(order + "I", tiff[4:8])[0]
    count = struct.unpack(order + "H", tiff[start:start + 2])[0]
    total, found = 0, []
    for entry in range(start + 2, start + 2 + 12 * count, 12):
        _, kind, values, at = struct.unpack(order + "HHII", tiff[entry:entry + 12])
        size = values * FIELD_BYTES.get(kind, 0)  # Pillow's types alone: it passes over 17 and 18 without a word
        if size > 4:
            total += size
            if total > len(tiff) or at + size > len(tiff):
                found.append(entry)
    return found


def _orientation_entry(tiff):
    """The orientation (tag 274) an EXIF block's first directory (whole: :func:`exif_damage`) holds, or 1."""
    order = "<" if tiff[:2] == b"II" else ">"
    start = struct.unpack(order + "I", tiff[4:8])[0]
    for entry in range(start + 2, start + 2 + 12 * struct.unpack(order + "H", tiff[start:start + 2])[0], 12):
        tag, kind = struct.unpack(order + "HH", tiff[entry:entry + 4])
        if tag == 274 and kind == 3:
            return struct.unpack(order + "H", tiff[entry + 8:entry + 10])[0]
    return 1


def _hide_damaged_exif(path, say):
    """``path`` itself, or, for a JPEG file (a path, or a binary file object from where it stands) whose EXIF
    block (APP1) :func:`exif_damage` finds damaged, the file's bytes in memory with that block renamed so
    that Pillow leaves it unparsed (said, with ``say``)."""
    try:
        return read_as_it_stands(path, lambda fh, name: _without_damaged_exif(fh, name, say)) or path
    except (OSError, ValueError):  # Pillow's own error follows
        return path


def _without_damaged_exif(fh, name, say):
    """:func:`_hide_damaged_exif`'s copy of the file open as ``fh``, or None where it needs none."""
    head = fh.read(3)
    if head != b"\xff\xd8\xff":  # not a JPEG
        return None
    head += fh.read(1 << 20)  # the APP segments come first, each at most 64 KiB
    at = 2
    while at + 4 <= len(head) and head[at] == 0xFF and head[at + 1] not in (0xD9, 0xDA):
        length = int.from_bytes(head[at + 2:at + 4], "big")
        block = head[at + 4:at + 2 + length]
        if head[at + 1] == 0xE1 and block[:6] == b"Exif\x00\x00" and at + 2 + length <= len(head):
            why = exif_damage(block)
            past = [] if why or block[6:10] not in (b"II*\x00", b"MM\x00*") else _values_past_end(block[6:])
            if why is None and not past:
                return None
            if why and say:
                _warn_exif(name, why)
            data = bytearray(head + fh.read())
            if why:
                data[at + 4:at + 8] = b"Exi_"  # no longer "Exif": Pillow keeps the segment as an unknown one
            for entry in past:  # a value past the block's end (no word: the orientation is read all the same)
                kind = at + 4 + 6 + entry + 2
                data[kind:kind + 2] = b"\x00\x00"  # a field type Pillow passes over without a word
            return io.BytesIO(bytes(data))
        at += 2 + length
    return None


def read_deep(path, max_pixels, keep_alpha=False):
    """16-bit PNG and TIFF files and float TIFF files that Pillow would not read whole, and 32-bit BMP
    files (:mod:`tghop.bmp`: their 4th byte alpha only where the header's mask says so):
    ``(array, mode, depth)`` with the array float64 in [0, 1] (uint8 for an 8-bit TIFF read
    by tifffile), or None for every other file (Pillow reads it: TIFF files too, but grey and RGB
    ones tifffile decodes, :func:`_tiff_layout`). ``mode`` is "RGBA" or "LA" when the file has
    an alpha channel: dropped, or, with ``keep_alpha``, kept last.

    Parameters
    ----------
    path : pathlib.Path, the image file
    max_pixels : int, a larger image is left to Pillow's path (its size error, or downscaling)
    keep_alpha : bool, keep an alpha channel last

    Returns
    -------
    tuple (ndarray of shape (H, W) or (H, W, C), str, int) or None
        The pixels, the mode ("", "LA" or "RGBA") and the bits per channel (8, 16 or 32).
    """
    with open(path, "rb") as fh:
        head = fh.read(33)
    if head[:2] == b"BM":  # 32-bit (and masked 16-bit) BMP: its 4th byte as the header says (0.59)
        found = read_bmp(path, max_pixels)
        if found is None:
            return None
        arr, mode = _drop_alpha(*found, keep_alpha)
        return arr, mode, 8 if arr.dtype == np.uint8 else 16
    if head[:8] == b"\x89PNG\r\n\x1a\n" and len(head) >= 33 and head[24] == 16:
        width, height = struct.unpack(">II", head[16:24])
        if width * height > max_pixels:  # too large: Pillow's path (its errors)
            return None
        levels, ctype = decode_png16(path.read_bytes())
        arr, mode = _drop_alpha(levels, {4: "LA", 6: "RGBA"}.get(ctype, ""), keep_alpha)
        return arr / 65535.0, mode, 16
    if head[:4] not in (b"II*\x00", b"MM\x00*"):
        return None
    try:
        import tifffile
    except ImportError:
        with open_image(path) as im:  # grey 16-bit and float TIFF: Pillow; deeper colour ones: refused
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
        if int(page.subfiletype or 0) & 1:
            _refuse_preview(path)
        layout = _tiff_layout(page, path)
        if layout is None:
            _check_wide_integers(page, path, max_pixels)
            return None
        shape = page.shape
        if not all(isinstance(n, (int, np.integer)) for n in shape):  # a size tag of several values (0.59: NumPy's
            return None  # words, "setting an array element with a sequence"): Pillow's path takes the first
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
    if premultiplied == "unmarked":  # RGB's one 4th sample that ExtraSamples does not call alpha
        premultiplied = False
        alpha = _unmarked_alpha(arr[:, :, 3], path, page.extrasamples)
    dropped = arr.shape[2] - colours - alpha
    # Extra samples that are not alpha (a multispectral file): dropped as Pillow drops them, and said (0.57).
    if dropped and not (colours == 3 and not alpha and dropped == 1):
        kept = f"{'its grey channel' if colours == 1 else 'its RGB channels'}{' and alpha' if alpha else ''}"
        warn(f"{path.name}: {dropped} extra channel{'s' if dropped > 1 else ''} that {'are' if dropped > 1 else 'is'} "
             f"not alpha dropped; tghop reads {kept} only")
    arr = arr[:, :, : colours + alpha]
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


def _unmarked_alpha(sample, path, extras):
    """Whether an RGB TIFF's one 4th sample that no ExtraSamples tag calls alpha (the tag missing, or
    "unspecified") is read as alpha: 1, said; 0 (dropped, said) where it is 0 everywhere, which as
    alpha would hide every pixel: padding (RGBX).

    0.57 dropped it without a word. Such a sample is nearly always an alpha channel whose writer left
    the tag out or wrote "unspecified": GIMP reads it as straight alpha (it asks, straight by default),
    libtiff's RGBA reader and ImageMagick as alpha, Pillow as alpha where the tag is missing (it drops
    an "unspecified" one). Straight, not premultiplied: colours are read as stored."""
    how = "no ExtraSamples tag" if not extras else "ExtraSamples unspecified"
    if not np.any(sample):
        warn(f"{path.name}: its 4th sample, not marked as alpha ({how}), is 0 everywhere: taken as padding and "
             "dropped; tghop reads its RGB channels only")
        return 0
    warn(f"{path.name}: its 4th sample, not marked as alpha ({how}), is read as straight alpha, as GIMP and "
         "libtiff read it; save the file with its alpha marked (or without it) to be sure")
    return 1


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


def _refuse_preview(path):
    """The error for a TIFF whose first image is a reduced-resolution one (NewSubfileType bit 0): a
    camera raw file's (DNG, NEF, ...) preview, whose full image tghop cannot read (0.55 learnt the
    preview, a few hundred pixels wide, without a word)."""
    raise InvalidImageError(f"{path}: its first image is a reduced-resolution preview (a camera raw file, such as "
                            "DNG?); tghop does not develop raw images: export it as TIFF, PNG or JPEG first")


def _integer_levels(arr, path):
    """An integer image's pixels (float64, as Pillow gives a 16- or 32-bit one) in [0, 1]: levels
    of an 8-bit range, else a 16-bit one, or a one-line :class:`InvalidImageError` for values
    outside 0-65535 (a signed or 32-bit TIFF: 0.55 clipped them to black and white without a word)."""
    lo, hi = (arr.min(), arr.max()) if arr.size else (0.0, 0.0)
    if lo < 0 or hi > 65535:
        _refuse_levels(path, lo, hi)
    return arr / (65535.0 if hi > 255 else 255.0)


def _refuse_levels(path, lo, hi):
    raise InvalidImageError(f"{path}: integer pixel values from {lo:.0f} to {hi:.0f}; tghop reads integer images as "
                            "levels from 0 to 65535; rescale it to that range (a 16-bit image) or to floats in [0, 1] "
                            "first")


def _check_wide_integers(page, path, max_pixels):
    """Refuse a TIFF page of signed or 32-bit integer samples (Pillow's path, which wraps 32-bit
    unsigned values to negative ones) whose values are outside 0-65535 (:func:`_integer_levels`),
    naming the values as stored."""
    dtype = page.dtype
    if dtype is None or dtype.kind not in "iu" or dtype in (np.uint8, np.uint16) or page.size > 4 * max_pixels:
        return
    try:
        arr = page.asarray()
    except MemoryError:
        raise
    except Exception:  # noqa: BLE001 - e.g. a compression tifffile cannot decode: Pillow's path
        return
    if arr.size and (arr.min() < 0 or arr.max() > 65535):
        _refuse_levels(path, arr.min(), arr.max())


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
    colour samples; whether the next sample is alpha, as its ExtraSamples tag says, or RGB's one 4th
    sample the tag leaves unmarked; min-is-white levels to invert; whether that alpha is associated,
    the colours multiplied by it, or "unmarked": :func:`_unmarked_alpha` decides), or None for
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
    if colours == 3 and page.samplesperpixel == 4 and extras in ((), (0,)):
        return 3, 1, inverted, "unmarked"  # straight alpha its writer did not mark (read_deep says so)
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


def decode_pillow(im, path, max_pixels, downscale, too_large_hint, keep_alpha=False, *, as_data=False):
    """Decode an open Pillow image into uint8 (or float for 16-bit) array; return (array, mode).
    With ``keep_alpha`` an image with alpha (or a palette or a transparent colour) is LA or RGBA.

    Parameters
    ----------
    im : PIL.Image.Image, open (and closed by the caller; replaced by a smaller copy when downscaled)
    path : pathlib.Path, the file's path, in messages
    max_pixels : int, the most pixels read
    downscale : bool, reduce a larger image to ``max_pixels`` (a warning) instead of refusing it
    too_large_hint : str, the advice that ends the error for a larger image
    keep_alpha : bool, keep an alpha channel last
    as_data : bool, the values as stored: no ICC profile or PNG gamma applied (a material's data map;
        a CMYK image is converted all the same)

    Returns
    -------
    ndarray, shape (H, W) or (H, W, C), uint8 or float64 in [0, 1], upright (EXIF orientation applied)
    mode : str, the image's Pillow mode ("P+transparency" for a palette with transparency; "LA" and "RGBA"
        for a grey or RGB image with a transparent colour)
    """
    width, height = im.size
    if width < 1 or height < 1:
        raise ValueError("empty image")
    if width * height > max_pixels:
        if not downscale:
            raise ImageTooLargeError(
                f"{path}: the image is {height}x{width} pixels, more than the {max_pixels:,} tghop reads; "
                f"{too_large_hint}")
        factor = (width * height / max_pixels) ** 0.5
        size = (max(1, int(width / factor)), max(1, int(height / factor)))
        im.draft(im.mode, size)  # JPEG: decode at reduced size directly
        warn(f"{path.name}: {height}x{width} pixels downscaled to {size[1]}x{size[0]} "
             f"(at most {max_pixels:,} pixels)", UserWarning, stacklevel=3)
        if im.size != size:
            small = im.resize(size, resample=1, reducing_gap=2.0)  # 1 = LANCZOS
            im.close()  # frees the full-size pixels before the copies below
            im = small
    else:
        im.load()
    warn_frames(path, getattr(im, "n_frames", 1))
    if int(getattr(im, "tag_v2", {}).get(254, 0) or 0) & 1:  # a TIFF's NewSubfileType: reduced resolution
        _refuse_preview(path)
    tags = getattr(im, "tag_v2", {})
    if im.mode == "RGB" and tags.get(277) == 4 and tuple(tags.get(338, ())) == (0,):  # Pillow's RGBX
        warn(f"{path.name}: its 4th sample, not marked as alpha (ExtraSamples unspecified), dropped; tghop reads "
             f"it as alpha with tifffile ({TIFF_HINT})", UserWarning, stacklevel=3)
    orientation = _exif_orientation(im)  # after loading: Pillow's TIFF reader applies (and drops) its own
    if im.mode in ("L", "RGB") and "transparency" in im.info:  # a PNG's transparent colour: an alpha channel
        im = im.convert("LA" if im.mode == "L" else "RGBA")  # (0.55 kept its pixels without a word)
    gamma = None if as_data else png_gamma(im.info)  # a PNG's gamma (gAMA) alone, not sRGB's: converted below
    if not as_data or im.mode == "CMYK":  # an ICC profile other than sRGB: its colours converted (tghop.profiles)
        im = to_srgb(im, path.name)
    if im.mode == "CMYK":  # no usable profile: Pillow's formula below, R = (255 - C)(255 - K) / 255, no ink's colour
        warn(f"{path.name}: a CMYK image without a usable colour profile; its colours are converted to RGB by a "
             "simple formula and are only approximate; export it as RGB (sRGB) for exact colours", UserWarning,
             stacklevel=3)
    mode = im.mode
    if mode == "P" and "transparency" in im.info:
        mode = "P+transparency"
    if keep_alpha and has_alpha(mode):
        arr = np.asarray(im if im.mode in ("RGBA", "LA") else im.convert("LA" if im.mode == "La" else "RGBA"))
    elif im.mode in ("L", "RGB"):
        arr = np.asarray(im)  # no converted copy of a large image
    elif im.mode in ("LA", "1"):
        arr = np.asarray(im.convert("L"))
    elif mode == "P+transparency":  # its colours through RGBA: the same, without Pillow's warning of bytes of it
        arr = np.ascontiguousarray(np.asarray(im.convert("RGBA"))[..., :3])
    elif im.mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        arr = np.asarray(im, dtype=np.float64)
        if im.mode == "F":  # a float image (TIFF, PFM)
            arr = _float_pixels(arr, path)
        else:  # integer levels: 8-bit range, else 16-bit
            arr = _integer_levels(arr, path)
    else:
        arr = np.asarray(im.convert("RGB"))
    arr = gamma_to_srgb(arr, gamma, path.name, alpha=arr.ndim == 3 and keep_alpha and has_alpha(mode))
    return upright(arr, orientation), mode


def _exif_orientation(im) -> int:
    """An open Pillow image's EXIF orientation (tag 0x0112): 1 (as stored) when it has none or
    a damaged EXIF block."""
    exif = im.info.get("exif")
    why = exif_damage(exif) if isinstance(exif, bytes) and im.format != "JPEG" else None
    if why:  # a PNG's or WebP's, which Pillow parses here (a JPEG's: open_image): tghop's words in every thread
        _warn_exif(getattr(im, "filename", "") or "the image", why)
        return 1
    tiff = exif[6:] if isinstance(exif, bytes) and exif[:6] == b"Exif\x00\x00" else exif
    if im.format != "JPEG" and isinstance(tiff, bytes) and tiff[:4] in (b"II*\x00", b"MM\x00*") \
            and _values_past_end(tiff):  # Pillow would warn of each; the orientation read here, without a word
        return _orientation_entry(tiff)
    try:
        return int(im.getexif().get(0x0112, 1))
    except Exception:  # noqa: BLE001 - a damaged EXIF block: the pixels as stored
        return 1


def file_header(path):
    """(EXIF orientation, ICC profile bytes or None, PNG gamma or None) of a file tghop decodes itself
    (16-bit PNG, TIFF by tifffile), from its header (no pixels decoded); orientation 1 where Pillow
    cannot open it; the gamma of a PNG's gAMA chunk where it is the only word on its colours
    (:func:`tghop.profiles.png_gamma`).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    tuple (int, bytes or None, float or None)
    """
    try:
        with open_image(path) as im:
            return _exif_orientation(im), im.info.get("icc_profile"), png_gamma(im.info)
    except ValueError as exc:
        if "MAX_TEXT_" in str(exc):  # a 16-bit PNG's: refused as an 8-bit one is (0.57 read it, its profile dropped)
            raise metadata_too_large(path) from None
        return _tiff_orientation(path), tiff_profile(path), None
    except Exception:  # noqa: BLE001 - not Pillow's (a float colour TIFF): its own tags, read by tifffile
        return _tiff_orientation(path), tiff_profile(path), None


def metadata_too_large(path):
    """The error for an image whose metadata Pillow refuses to unpack (a PNG's colour profile or compressed text
    over its ``PngImagePlugin.MAX_TEXT_CHUNK``, raised as a ValueError naming it)."""
    return InvalidImageError(f"{path}: its metadata (a colour profile, iCCP, or text, zTXt/iTXt) unpacks to more "
                             "than Pillow reads (a decompression bomb, or an outsized profile); save the image again "
                             "without its metadata")


def _tiff_orientation(path) -> int:
    """A TIFF file's first page's Orientation tag (274), read by :mod:`tifffile` (a float colour
    TIFF, which Pillow cannot open: 0.55 read it as stored, sideways where a viewer shows it upright);
    1 where it has none or cannot be read."""
    try:
        import tifffile

        with tifffile.TiffFile(path) as tif:
            tag = tif.pages[0].tags.get(274)
            return 1 if tag is None else int(tag.value)
    except Exception:  # noqa: BLE001 - not a TIFF, or no tifffile: the pixels as stored
        return 1


def upright(arr, orientation):
    """An (H, W[, C]) array as it is displayed: turned or flipped as its EXIF ``orientation``
    says (cameras and phones store JPEG pixels sideways and record how to show them); the
    array itself for orientation 1 or an unknown one.

    Parameters
    ----------
    arr : ndarray, shape (H, W) or (H, W, C)
    orientation : int, the EXIF orientation (1-8)

    Returns
    -------
    ndarray, shape (H, W[, C]) or (W, H[, C]) for orientations 5-8
    """
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
