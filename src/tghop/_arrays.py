"""Input checks of the scikit-learn-style components (:mod:`tghop.saab`, :mod:`tghop.hops`,
:mod:`tghop.sdr`, :mod:`tghop.core`): arrays of numbers of a given rank, sample counts, and
forgetting a fitted state; :func:`check_int`, the library's integer-parameter check; and
:func:`from_levels`, how every entry point reads 8-bit and 16-bit images. The checks of images and
output sizes are :mod:`tghop._images`', ``rng``'s :mod:`tghop._estimator`'s; the errors, :mod:`tghop._errors`'s.

Each check is O(1) or one pass over its input; the fits call them with ``finite=True``,
the transforms check shapes only.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from ._errors import NonNumericError, TGHopError

__all__ = ["check_array", "check_count", "check_dtype", "check_int", "check_mask", "check_not_path", "check_width",
           "forget_fit", "from_levels"]

#: Full scale of the integer types read as image levels: ``x / 255`` and ``x / 65535`` lie in [0, 1].
LEVELS = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}


def check_array(X, name: str, shape: str, *, ndim: int, min_rows: int = 1, finite: bool = True,
                samples: bool = True) -> np.ndarray:
    """``X`` as a float64 array (no copy where it is one already), or a one-line :class:`TGHopError`.

    Parameters
    ----------
    X : array_like
    name : str
        The argument, for messages (``"X"``, ``"Y"``, ``"Z"``).
    shape : str
        The expected shape, for messages (``"(n_samples, d)"``).
    ndim : int
        Required number of dimensions.
    min_rows : int
        Fewest rows (first axis) allowed.
    finite : bool
        Refuse NaN and infinite values (one pass over ``X``).
    samples : bool
        The rows are samples: a 1-D ``X`` where a 2-D one belongs is told how to reshape it.

    Returns
    -------
    ndarray of float64

    Raises
    ------
    TGHopError
        One line; it also holds scikit-learn's wording where its estimator checks look for
        one ("Complex data not supported", "Reshape your data").
    NonNumericError
        ``X`` holds something NumPy cannot read as a number (also a TypeError, as NumPy's).
    """
    if hasattr(X, "toarray") and hasattr(X, "nnz"):  # SciPy's sparse matrices and arrays
        raise TGHopError(f"{name} is a sparse {type(X).__name__}; give a dense array of shape {shape} "
                         f"({name}.toarray())")
    if getattr(X, "dtype", None) is not None and np.dtype(X.dtype).kind == "c" or (
            isinstance(X, (list, tuple)) and np.iscomplexobj(X)):  # NumPy would drop the imaginary parts
        raise TGHopError(f"{name} holds complex numbers; give real ones, of shape {shape} (Complex data not supported)")
    try:
        arr = np.asarray(X, dtype=np.float64)
    except (TypeError, ValueError) as exc:  # NumPy's reason names the culprit ("... not 'dict'", "... 'abc'")
        what = f"{type(X).__name__} of dtype {X.dtype}" if isinstance(X, np.ndarray) else type(X).__name__
        reason = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise (NonNumericError if isinstance(exc, TypeError) else TGHopError)(
            f"{name} must be an array of numbers of shape {shape}, got {what} ({reason})") from None
    if arr.ndim != ndim:
        hint = ""
        if samples and ndim == 2 and arr.ndim == 1:
            hint = (f". Reshape your data: {name}.reshape(1, -1) if it is one sample, "
                    f"{name}.reshape(-1, 1) if one feature")
        raise TGHopError(f"{name} must have shape {shape}, got {arr.shape}{hint}")
    if arr.shape[0] < min_rows:
        raise TGHopError(f"{name} must have at least {min_rows} row{'s' if min_rows != 1 else ''} "
                         f"(samples), got shape {arr.shape}")
    if finite and not np.isfinite(arr).all():
        raise TGHopError(f"{name} contains NaN or infinite values; clean it first")
    return arr


def from_levels(arr: np.ndarray, dtype=np.float64) -> np.ndarray:
    """uint8 or uint16 levels as floats of ``dtype`` in [0, 1] (``x / 255``, ``x / 65535``,
    divided in ``dtype``); any other array is returned as it is, for the caller's own checks.

    Parameters
    ----------
    arr : ndarray, any shape
    dtype : {numpy.float64, numpy.float32}

    Returns
    -------
    ndarray, the shape of ``arr``
    """
    full = LEVELS.get(arr.dtype)
    if full is None:
        return arr
    dtype = np.dtype(dtype)
    return np.divide(arr, dtype.type(full), dtype=dtype)


def check_not_path(value, name: str) -> None:
    """Refuse a file name (str, bytes or os.PathLike) given where an image array belongs: a one-line
    :class:`~tghop.InvalidImageError` naming :func:`tghop.imageio.load_image`. NumPy reads a name as a
    0-d array of text, which was told as a shape ``()`` or a dtype ``<U9`` (0.56).

    Parameters
    ----------
    value : object
        What was given.
    name : str
        How it is called in the message ("exemplar", "the mask").
    """
    import os

    if isinstance(value, (str, bytes, os.PathLike)):
        from ._errors import InvalidImageError

        raise InvalidImageError(f"{name} is a file name ({os.fsdecode(value)!r}), not an image array; read it first: "
                                "tghop.imageio.load_image(path)")


def check_width(arr, name: str, shape: str, expected: tuple, *, who: str | None = None) -> None:
    """Refuse ``arr`` unless its shape after the first axis is ``expected`` (shape checks only:
    the transforms' check, for arrays already made by :func:`numpy.asarray`). With ``who`` (the
    estimator's class name), a 2-D ``arr`` of another width is also told so in scikit-learn's
    words (``X has 1 features, but Saab is expecting 4 features as input``)."""
    if arr.ndim != len(expected) + 1 or tuple(arr.shape[1:]) != tuple(expected):
        features = ""
        if who is not None and arr.ndim == 2 and len(expected) == 1:
            features = f"; {name} has {arr.shape[1]} features, but {who} is expecting {expected[0]} features as input"
        raise TGHopError(f"{name} must have shape {shape} for this fitted model, got {arr.shape}{features}")


def check_count(n, name: str = "n") -> int:
    """A non-negative integer count (a Python or NumPy integer, not a bool): :func:`check_int`
    with ``low=0`` (``name must be an integer >= 0, got n``)."""
    return check_int(n, name, 0)


def check_dtype(dtype, allowed, names: str) -> np.dtype:
    """The output ``dtype`` as a :class:`numpy.dtype`, one of ``allowed``; anything else
    (``"junk"``, ``int``, a list) is one :class:`TGHopError` line naming ``names``."""
    try:
        wanted = np.dtype(dtype)
    except (TypeError, ValueError):
        wanted = None
    if wanted is None or wanted not in allowed:
        raise TGHopError(f"dtype must be {names} (e.g. numpy.float32), got {dtype!r}")
    return wanted


def check_int(value, name: str, low: int = 1, high: int | None = None, *, where: str | None = None) -> int:
    """``value`` as an int of at least ``low`` (and at most ``high``, where given), or a
    one-line :class:`TGHopError`.

    The library's one integer-parameter check: the patch helpers, the metrics' counts, the
    guide helpers, the coarse layout, the co-occurrence model, the colour classes, the band
    and patch statistics and their refinements, inpainting, coupling, seam smoothing and
    quilting's overlap cut call it.

    Parameters
    ----------
    value : object
        A Python or NumPy integer (not a bool: ``True`` is refused, and so is a whole float
        such as ``2.0``).
    name : str
        The parameter, for the message.
    low : int
        Smallest value allowed.
    high : int or None
        Largest value allowed; None: no upper bound.
    where : str or None
        The function or class checking, put before the message (``"where: name must be ..."``).

    Returns
    -------
    int

    Raises
    ------
    TGHopError
        ``name must be an integer >= low, got value`` (with ``high``: ``an integer from low
        to high``), after ``where: `` where given.
    """
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Integral, np.integer)) or value < low
            or (high is not None and value > high)):
        wanted = f">= {low}" if high is None else f"from {low:,} to {high:,}"
        raise TGHopError(("" if where is None else f"{where}: ") + f"{name} must be an integer {wanted}, got {value!r}")
    return int(value)


def check_number(value, name: str, *, positive: bool = False, where: str | None = None,
                 unit: str | None = None) -> float:
    """``value`` as a float, finite and at least 0 (above 0 with ``positive``), or a one-line
    :class:`TGHopError`: the real-number twin of :func:`check_int`.

    Parameters
    ----------
    value : object
        A Python or NumPy real number (not a bool).
    name : str
        The parameter, for the message.
    positive : bool
        Refuse 0 as well.
    where : str or None
        The function checking, put before the message (``"where: name must be ..."``).
    unit : str or None
        Put in brackets after the bound (``"(pixels)"``).

    Returns
    -------
    float

    Raises
    ------
    TGHopError
        ``name must be a finite number >= 0, got value`` (``> 0`` with ``positive``).
    """
    if (isinstance(value, bool) or not isinstance(value, numbers.Real)
            or not ((0 < value) if positive else (0 <= value)) or not value < math.inf):
        wanted = "> 0" if positive else ">= 0"
        raise TGHopError(("" if where is None else f"{where}: ") + f"{name} must be a finite number {wanted}"
                         + ("" if unit is None else f" ({unit})") + f", got {value!r}")
    return float(value)


def check_mask(mask, shape, where: str, name: str = "exclude"):
    """``mask`` as an (H, W) bool array of the image's ``shape[:2]`` (None stays None), or a
    one-line :class:`TGHopError` naming ``where`` (the function) and ``name``: the sample
    mask check of :meth:`~tghop.patch_refine.PatchStatistics.fit`,
    :meth:`~tghop.refine.BandStatistics.fit` and :meth:`~tghop.colour.ColourClasses.fit`."""
    if mask is None:
        return None
    h, w = shape[:2]
    if np.shape(mask) != (h, w):
        raise TGHopError(f"{where}: {name} must be an (H, W) mask of the image's {h}x{w} pixels, "
                         f"got shape {np.shape(mask)}")
    return np.asarray(mask, dtype=bool)


def forget_fit(estimator, private=()) -> None:
    """Remove ``estimator``'s fitted state: every attribute whose name ends with ``_`` (the
    learned attributes; parameters never do) and the ``private`` caches. A fit that fails
    calls this, so that the estimator does not look fitted (or fitted on other data)."""
    for name in list(vars(estimator)):
        if (name.endswith("_") and not name.startswith("__")) or name in private:
            del estimator.__dict__[name]
