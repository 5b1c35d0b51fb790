"""Reading and writing images: files <-> float ``(H, W, C)`` arrays in [0, 1]."""

from __future__ import annotations

import io
import os
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from ._common import InvalidImageError, check_image

__all__ = ["load_image", "save_image", "to_uint8", "write_atomic", "check_output_path"]

#: Output formats chosen by file extension.
FORMATS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG"}


def load_image(path) -> np.ndarray:
    """Read an image file as a float array.

    Parameters
    ----------
    path : str or os.PathLike
        Any format Pillow reads. Palette and 16-bit images are converted; an alpha
        channel is dropped with a warning.

    Returns
    -------
    ndarray, shape (H, W, C), float64 in [0, 1]
        ``C`` is 1 for greyscale images and 3 for colour ones.
    """
    path = Path(path)
    if not path.exists():
        raise InvalidImageError(f"{path}: no such file; check the path")
    if path.is_dir():
        raise InvalidImageError(f"{path} is a folder, not an image; give an image file")
    try:
        with Image.open(path) as im:
            im.load()
            mode = im.mode
            if mode in ("RGBA", "LA", "PA") or (mode == "P" and "transparency" in im.info):
                warnings.warn(f"{path.name}: alpha channel dropped", UserWarning, stacklevel=2)
            if mode in ("L", "LA", "1"):
                arr = np.asarray(im.convert("L"))
            elif mode in ("I;16", "I;16B", "I;16L", "I"):
                arr = np.asarray(im, dtype=np.float64)
                arr = arr / (65535.0 if arr.max() > 255 else 255.0)
            else:
                arr = np.asarray(im.convert("RGB"))
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as exc:
        raise InvalidImageError(
            f"{path}: not a readable image ({exc.__class__.__name__}); give a PNG, JPEG or other common image file"
        ) from None
    return check_image(arr, name=str(path))


def to_uint8(image) -> np.ndarray:
    """Convert a float image in [0, 1] to ``uint8`` (rounding), dropping a singleton channel."""
    arr = np.asarray(image, dtype=np.float64)
    out = np.round(np.clip(arr, 0.0, 1.0) * 255.0).astype(np.uint8)
    if out.ndim == 3 and out.shape[2] == 1:
        out = out[:, :, 0]
    return out


def check_output_path(path, *, what: str = "image", error=InvalidImageError) -> Path:
    """Refuse an output path that is a folder or whose folder does not exist.

    Returns the folder the file will be written to; ``error`` is the exception class raised.
    """
    path = Path(path)
    if path.is_dir():
        raise error(f"{path} is a folder; give a file name for the {what}")
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise error(f"{directory}: output folder does not exist; create it first")
    return directory


def write_atomic(path, write) -> None:
    """Call ``write(fileobj)`` on a temporary file next to ``path``, then move it into place.

    If ``write`` raises, no file (and no partial file) is left at ``path``.
    """
    path = Path(path)
    directory = check_output_path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the usual permissions
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def output_format(path) -> str:
    """Pillow format name for an output path (``-`` means PNG on stdout)."""
    if str(path) == "-":
        return "PNG"
    ext = Path(path).suffix.lower()
    if ext not in FORMATS:
        raise InvalidImageError(f"{path}: unknown image extension {ext or '(none)'}; use .png, .jpg or .jpeg")
    return FORMATS[ext]


def save_image(image, path) -> None:
    """Write a float image in [0, 1] to ``path`` (PNG or JPEG by extension; ``-`` is PNG on stdout).

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
    path : str or os.PathLike
        The file appears complete or not at all.
    """
    fmt = output_format(path)
    pil = Image.fromarray(to_uint8(image))
    options = {"quality": 95} if fmt == "JPEG" else {}
    if str(path) == "-":
        buf = io.BytesIO()
        pil.save(buf, format=fmt)
        sys.stdout.buffer.write(buf.getvalue())
        sys.stdout.buffer.flush()
        return
    write_atomic(path, lambda fh: pil.save(fh, format=fmt, **options))
