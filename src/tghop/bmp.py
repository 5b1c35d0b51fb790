"""BMP files whose 4th byte tghop reads itself (:func:`read_bmp`, called by
:func:`tghop.image_decode.read_deep`): 32-bit ones, whose 4th byte is alpha or padding as the header's
alpha mask says, and 16- and 32-bit ones of colour masks (BI_BITFIELDS) that Pillow does not read.

What the format says (Microsoft's BITMAPINFOHEADER and BITMAPV5HEADER): in a 32-bit BI_RGB file "the
high byte in each DWORD is not used" unless a V4 or V5 header's alpha mask (bV5AlphaMask, "the alpha
component of each pixel", not limited to BI_BITFIELDS as the colour masks are) names it; with
BI_BITFIELDS (and Windows CE's BI_ALPHABITFIELDS) the masks say where each component is. Pillow 13
reads BI_BITFIELDS files of eight mask layouts only (others: "Unsupported BMP bitfields layout") and
ignores a BI_RGB file's alpha mask. tghop reads the masks as the header gives them (0.59), and takes
an alpha that is 0 in every pixel for padding, as browsers do (a writer that fills the mask but not
the byte: as alpha it would hide the whole image)."""

from __future__ import annotations

import struct

import numpy as np

from ._errors import InvalidImageError, warn

__all__ = ["read_bmp"]

_BI_RGB, _BI_BITFIELDS, _BI_ALPHABITFIELDS = 0, 3, 6
#: The colour masks of BI_RGB (blue in the low byte) and the 16-bit ones Pillow reads (5-6-5, 5-5-5).
_DEFAULT_MASKS = (0xFF0000, 0xFF00, 0xFF)
_PILLOW_16 = ((0xF800, 0x7E0, 0x1F), (0x7C00, 0x3E0, 0x1F))


def _header(head):
    """``(width, height, bits, compression, (r, g, b, a) masks)`` of a BMP file's first bytes (at
    least 70), or None for a file tghop leaves to Pillow (an OS/2 header, another depth or compression)."""
    size = struct.unpack("<I", head[14:18])[0]
    if size < 40 or size == 64 or len(head) < 70:  # 64: OS/2's BITMAPCOREHEADER2, other fields after 40 bytes
        return None
    width, height, _, bits, compression = struct.unpack("<iiHHI", head[18:34])
    if bits not in (16, 32) or compression not in (_BI_RGB, _BI_BITFIELDS, _BI_ALPHABITFIELDS):
        return None
    # The masks: in a header of 52 bytes or more, else after a 40-byte one (four with BI_ALPHABITFIELDS).
    alpha = struct.unpack("<I", head[66:70])[0] if size >= 56 or compression == _BI_ALPHABITFIELDS else 0
    if compression == _BI_RGB:
        if bits == 16:
            return None  # 5-5-5, its top bit unused: Pillow's
        return width, height, bits, compression, (*_DEFAULT_MASKS, alpha)
    masks = struct.unpack("<III", head[54:66])
    if not any(masks) and bits == 32:  # no masks: Pillow reads B, G, R, A
        masks, alpha = _DEFAULT_MASKS, 0xFF000000
    if bits == 16 and not alpha and masks in _PILLOW_16:
        return None  # Pillow's
    return width, height, bits, compression, (*masks, alpha)


def _channel(pixels, mask):
    """The levels of one component (``mask``: contiguous bits) of packed ``pixels``, in 8 bits (as uint8)
    for a mask of up to 8 bits, else in 16 bits (as uint16)."""
    shift = (mask & -mask).bit_length() - 1
    width = (mask >> shift).bit_length()
    top = (1 << width) - 1
    values = (pixels & np.uint32(mask)) >> np.uint32(shift)
    if width == 8:
        return values.astype(np.uint8)
    out_top = 255 if width <= 8 else 65535
    scaled = (values.astype(np.uint64) * out_top + top // 2) // top
    return scaled.astype(np.uint8 if width <= 8 else np.uint16)


def read_bmp(path, max_pixels):
    """A BMP file tghop decodes itself (module docstring): ``(array, mode)``, the array (H, W, 3 or 4)
    uint8, or float64 in [0, 1] for masks of more than 8 bits, ``mode`` "RGBA" when alpha is read (kept
    last) else ""; None for every other file (Pillow's path: other BMPs, or one over ``max_pixels``).

    Raises
    ------
    InvalidImageError
        Masks that overlap or are not contiguous bits, or pixel data cut short: one line.
    """
    with open(path, "rb") as fh:
        head = fh.read(70)
        if len(head) < 34 or head[:2] != b"BM":
            return None
        found = _header(head)
        if found is None:
            return None
        width, height, bits, compression, masks = found
        if width < 1 or height == 0 or width * abs(height) > max_pixels:
            return None  # Pillow's path: its error, or its size limit and downscaling
        _check_masks(path, masks, bits)
        stride = (bits * width + 31) // 32 * 4
        need = stride * abs(height)
        fh.seek(struct.unpack("<I", head[10:14])[0])
        data = fh.read(need)
    if len(data) < need:
        raise InvalidImageError(f"{path}: a damaged BMP: its pixels are cut short ({len(data):,} of {need:,} bytes); "
                                "save or download it again")
    rows = np.frombuffer(data, dtype="<u4" if bits == 32 else "<u2", count=need // (bits // 8))
    pixels = rows.reshape(abs(height), stride // (bits // 8))[:, :width].astype(np.uint32)
    if height > 0:  # bottom-up, as most are
        pixels = pixels[::-1]
    alpha = masks[3]
    if alpha and not np.any(pixels & np.uint32(alpha)):
        kind = "its 4th byte" if bits == 32 else "its alpha bits"
        warn(f"{path.name}: {kind}, marked as alpha by the header's alpha mask, is 0 everywhere: taken as padding "
             "and ignored, as browsers read it (as alpha it would hide every pixel)")
        alpha = 0
    channels = [_channel(pixels, mask) for mask in (*masks[:3], alpha) if mask]
    if any(c.dtype != channels[0].dtype for c in channels):  # mixed widths: all as 16-bit levels
        channels = [c.astype(np.uint16) * 257 if c.dtype == np.uint8 else c for c in channels]
    arr = np.stack(channels, axis=-1)
    if arr.dtype == np.uint16:
        arr = arr / 65535.0
    return arr, "RGBA" if alpha else ""


def _check_masks(path, masks, bits):
    """Refuse colour masks that tghop cannot read as components: a zero colour mask, bits not side by side,
    masks that overlap or lie outside the pixel, or a component wider than 16 bits."""
    seen = 0
    for mask in masks:
        if not mask:
            continue
        low = mask & -mask
        if (mask + low) & mask or mask >> bits or seen & mask or (mask // low).bit_length() > 16:
            break
        seen |= mask
    else:
        if all(masks[:3]):
            return
    raise InvalidImageError(f"{path}: a BMP whose colour masks ({', '.join(f'0x{m:X}' for m in masks)}) are not "
                            "separate runs of bits; save it again as a plain 24- or 32-bit BMP, or as PNG")
