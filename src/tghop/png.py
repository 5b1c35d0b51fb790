"""PNG files tghop reads and writes itself: 16-bit ones, which Pillow reduces to 8 bits, and
every PNG it writes, compressed on several cores (:func:`tghop.imageio.save_image` calls
:func:`write_png`; :func:`tghop.imageio.load_image` calls :func:`decode_png16`)."""

from __future__ import annotations

import struct
import zlib

import numpy as np

from ._errors import InvalidImageError, TGHopError
from ._progress import ProgressCounter, report
from ._resources import usable_cores

__all__ = ["decode_png16", "write_png", "WRITING"]

#: The stage name of an image's write in ``progress(stage, done, total)`` (:func:`write_png`,
#: :func:`tghop.imageio.save_image`).
WRITING = "writing"


#: The seven passes of an Adam7-interlaced PNG: (first column, first row, column step, row step).
_ADAM7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2))


def decode_png16(data):
    """A 16-bit PNG file's samples: (uint16 array (H, W, S), colour type).

    Pillow reduces 16-bit colour PNG files to 8 bits; this reads every type of them
    (grey, grey+alpha, RGB, RGBA), interlaced (Adam7: each pass a small image of its own) or not.
    Rows filtered with None, Sub or Up only (tghop's and
    Pillow's writers) are unfiltered a row at a time; others (Average, Paeth) along
    anti-diagonals, every pixel of one at once (a pixel depends on its left, upper and
    upper-left neighbours only). A grey or RGB file's transparent colour (a tRNS chunk: every
    pixel of that level is transparent) comes back as an alpha channel, its colour type 4 or 6,
    as Pillow reads an 8-bit one's."""
    pos, idat, header, key = 8, [], None, None
    while pos + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[pos: pos + 8])
        body = data[pos + 8: pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"tRNS":
            key = body
        elif kind == b"IEND":
            break
        pos += 12 + length
    if header is None:
        raise ValueError("no PNG header")
    w, h, bits, ctype = header[:4]
    samples = {0: 1, 2: 3, 4: 2, 6: 4}.get(ctype)
    if bits != 16 or samples is None:
        raise ValueError(f"PNG colour type {ctype} at {bits} bits")
    if header[6] not in (0, 1):
        raise ValueError(f"PNG interlace method {header[6]}")
    bpp = 2 * samples
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), dtype=np.uint8)
    out, pos = np.empty((h, w, bpp), dtype=np.uint8), 0
    for x0, y0, dx, dy in _ADAM7 if header[6] else ((0, 0, 1, 1),):
        ph, pw = len(range(y0, h, dy)), len(range(x0, w, dx))
        if not ph or not pw:  # an empty pass (a small image) has no rows at all
            continue
        size = ph * (1 + pw * bpp)
        if raw.size < pos + size:
            raise ValueError("truncated PNG data")
        out[y0::dy, x0::dx] = _unfilter(raw[pos: pos + size].reshape(ph, 1 + pw * bpp), bpp)
        pos += size
    levels = out.reshape(h, w * bpp).view(">u2").reshape(h, w, samples).astype(np.uint16)
    if key is not None and ctype in (0, 2) and len(key) == 2 * samples:
        opaque = ~np.all(levels == np.frombuffer(key, dtype=">u2").astype(np.uint16), axis=2)
        return np.concatenate([levels, (opaque * np.uint16(65535))[:, :, None]], axis=2), ctype + 4
    return levels, ctype


def _unfilter(raw, bpp):
    """The bytes (h, w, bpp) of a PNG image's (or an interlaced pass's) rows ``raw`` (h, 1 + w bpp):
    each row's first byte its filter type."""
    h, w = raw.shape[0], (raw.shape[1] - 1) // bpp
    kinds = raw[:, 0]
    if kinds.max(initial=0) > 4:
        raise ValueError(f"PNG filter type {kinds.max()}")
    rows = raw[:, 1:].reshape(h, w, bpp)
    if np.all(kinds <= 2):
        out = np.empty((h, w, bpp), dtype=np.uint8)
        prev = np.zeros((w, bpp), dtype=np.uint8)
        for y in range(h):
            if kinds[y] == 1:
                out[y] = np.cumsum(rows[y], axis=0, dtype=np.uint8)  # modulo 256
            elif kinds[y] == 2:
                np.add(rows[y], prev, out=out[y])
            else:
                out[y] = rows[y]
            prev = out[y]
        return out
    pad = np.zeros((h + 1, w + 1, bpp), dtype=np.int32)  # a zero row above and column to the left
    rows = rows.astype(np.int32)
    for t in range(h + w - 1):
        ys = np.arange(max(0, t - w + 1), min(h, t + 1))
        xs = t - ys
        a, b, c = pad[ys + 1, xs], pad[ys, xs + 1], pad[ys, xs]
        pa, pb, pc = np.abs(b - c), np.abs(a - c), np.abs(a + b - 2 * c)
        paeth = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))
        f = kinds[ys][:, None]
        pred = np.select([f == 0, f == 1, f == 2, f == 3], [0, a, b, (a + b) >> 1], paeth)
        pad[ys + 1, xs + 1] = (rows[ys, xs] + pred) & 255
    return pad[1:, 1:].astype(np.uint8)


#: Raw bytes per part of a PNG compressed in parallel (smaller images: one part).
_PNG_PART = 1 << 20


def _png_chunk(fh, kind: bytes, *pieces) -> None:
    """Write one PNG chunk: length, type, data (given in ``pieces``), CRC."""
    crc = zlib.crc32(kind)
    for piece in pieces:
        crc = zlib.crc32(piece, crc)
    fh.write(struct.pack(">I", sum(len(piece) for piece in pieces)) + kind)
    for piece in pieces:
        fh.write(piece)
    fh.write(struct.pack(">I", crc))


def write_png(fh, pixels, *, level: int = 1, progress=None) -> None:
    """Write a uint8 (uint16) image as an 8-bit (16-bit) PNG, its compression spread over the
    processor's cores.

    Parameters
    ----------
    fh : binary file object
    pixels : ndarray of uint8 or uint16, shape (H, W) or (H, W, C), C in 1-4
        Grey, grey and alpha, RGB or RGBA.
    level : int
        zlib level (1: synthesised texture is noise-like, so higher levels barely shrink
        it but take noticeably longer; measured: docs/choices.md).
    progress : callable, optional
        ``progress("writing", done, total)`` (:data:`WRITING`): ``total`` is the parts
        compressed (below) and one for the file's write; ``done`` counts them as they finish
        (from the compressing threads, one at a time).

    Notes
    -----
    Every row uses PNG's "Sub" filter (the byte one pixel to the left subtracted; 16-bit
    samples are stored big-endian, two bytes each, and filtered as bytes). The rows
    are compressed in parts of about :data:`_PNG_PART` bytes, on as many threads as there
    are cores (zlib lets go of the interpreter lock), each part a separate deflate stream
    ended at a byte boundary, and the parts are joined into one zlib stream, as ``pigz``
    does: the same image as Pillow's writer (tested), in less time on several cores. The
    parts depend on the image alone: the same bytes on any number of cores.
    """
    px = np.asarray(pixels)
    if px.dtype not in (np.uint8, np.uint16) or px.ndim not in (2, 3) or (px.ndim == 3 and px.shape[2] > 4):
        raise ValueError(f"write_png takes a uint8 or uint16 (H, W) or (H, W, C) array with C up to 4, "
                         f"got {px.dtype} {px.shape}")
    if px.size == 0:
        raise InvalidImageError(f"write_png: the image has no pixels (shape {px.shape}); give at least 1x1 pixels")
    if not isinstance(level, (int, np.integer)) or isinstance(level, bool) or not 0 <= level <= 9:
        raise TGHopError(f"write_png: level must be a zlib level, an integer 0 to 9, got {level!r}")
    h, w = px.shape[:2]
    channels = 1 if px.ndim == 2 else px.shape[2]
    bits = 8 * px.dtype.itemsize
    c = channels * px.dtype.itemsize  # bytes per pixel
    rows = px.reshape(h, w * channels)
    if bits == 16:
        rows = rows.astype(">u2").view(np.uint8).reshape(h, w * c)
    raw = np.empty((h, 1 + w * c), dtype=np.uint8)
    raw[:, 0] = 1  # filter type Sub
    raw[:, 1 : 1 + c] = rows[:, :c]
    np.subtract(rows[:, c:], rows[:, :-c], out=raw[:, 1 + c :])  # modulo 256
    n_parts = max(1, min(raw.nbytes // _PNG_PART, h))  # not the cores: the same file on every machine
    bounds = [h * i // n_parts for i in range(n_parts + 1)]
    blobs = [b""] * n_parts
    report(progress, WRITING, 0, n_parts + 1)
    counter = ProgressCounter(progress, WRITING, n_parts + 1)

    def compress(i):
        stream = zlib.compressobj(level, zlib.DEFLATED, -15)  # raw deflate: the header comes once
        blobs[i] = stream.compress(raw[bounds[i] : bounds[i + 1]].data) + stream.flush(
            zlib.Z_FINISH if i == n_parts - 1 else zlib.Z_SYNC_FLUSH)
        counter(1)

    threads = min(usable_cores(), n_parts)
    if threads == 1:
        for i in range(n_parts):
            compress(i)
    else:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=threads) as pool:
            list(pool.map(compress, range(n_parts)))  # a part's error (e.g. out of memory) is raised here
    fh.write(b"\x89PNG\r\n\x1a\n")
    colour_type = {1: 0, 2: 4, 3: 2, 4: 6}[channels]  # grey, grey + alpha, RGB, RGBA
    _png_chunk(fh, b"IHDR", struct.pack(">IIBBBBB", w, h, bits, colour_type, 0, 0, 0))
    _png_chunk(fh, b"IDAT", b"\x78\x01", *blobs, struct.pack(">I", zlib.adler32(raw.data)))
    _png_chunk(fh, b"IEND")
    counter(1)
