"""Conventions shared by every stage: randomness, progress, image arrays, sizes and the
small estimator base class; also the errors, which live in :mod:`tghop._errors` and are
re-exported here. The checks of array and number arguments (``check_array``, ``check_int``,
``check_mask``) are :mod:`tghop._arrays`'s.

Nothing here knows about TGHop itself; each pipeline module imports from here. Nothing
here imports scikit-learn or SciPy: generating from a saved model, ``tghop info`` and
``--help`` must not pay for their (long) import time.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import inspect
import math
import numbers
import os
import threading
from typing import Callable, Optional, Union

import numpy as np

__all__ = [
    "TGHopError",
    "InvalidImageError",
    "MissingExtraError",
    "ModelFileError",
    "NotFittedError",
    "BaseEstimator",
    "TransformerMixin",
    "FourDInputMixin",
    "check_is_fitted",
    "ProgressCallback",
    "check_rng",
    "fit_part",
    "check_image",
    "checked_image",
    "check_texture",
    "grey_as_rgb",
    "report",
    "in_thread",
    "usable_cores",
    "limit_cores",
    "MAX_PIXELS",
    "check_size",
    "available_memory",
    "check_memory",
    "INSTALL_HINT",
    "import_torch",
]


from ._arrays import LEVELS, check_not_path, from_levels
from ._errors import (InvalidImageError, MissingExtraError, ModelFileError, NotFittedError, TGHopError,  # noqa: F401
                      check_progress)


# ------------------------------------------------------------------ estimators
class BaseEstimator:
    """The part of scikit-learn's ``BaseEstimator`` tghop uses: ``get_params``,
    ``set_params`` and a repr of the changed parameters.

    tghop's own so that generating from a saved model never imports scikit-learn;
    ``sklearn.base.clone`` and grid searches still work (they need only these methods).
    The constructor stores its arguments and does nothing else.
    """

    @classmethod
    @functools.cache  # per class: its constructor's signature does not change (check_is_fitted reads it often)
    def _get_param_names(cls):
        if cls.__init__ is object.__init__:
            return ()
        params = inspect.signature(cls.__init__).parameters.values()
        return tuple(sorted(p.name for p in params if p.name != "self"
                            and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)))

    def get_params(self, deep=True):
        """Parameters of this estimator (and, with ``deep``, of nested estimators as ``name__param``).

        Parameters
        ----------
        deep : bool, default=True
            Also the parameters of parameters that are estimators (a :class:`~tghop.material.Material`'s
            ``model``), as ``model__rng`` etc.

        Returns
        -------
        dict of str to object
            The constructor's arguments by name, as stored.
        """
        out = {}
        for name in self._get_param_names():
            value = getattr(self, name)
            if deep and hasattr(value, "get_params") and not isinstance(value, type):
                out.update((f"{name}__{k}", v) for k, v in value.get_params().items())
            out[name] = value
        return out

    def set_params(self, **params):
        """Set parameters (``name`` or nested ``name__param``); returns self.

        Parameters
        ----------
        **params
            New values by name, as :meth:`get_params` names them. A fitted
            :class:`~tghop.synthesis.TGHop` whose settings change is no longer fitted
            (:class:`~tghop.NotFittedError` until it is fitted again).

        Returns
        -------
        self
        """
        valid = self._get_param_names()
        nested = {}
        for key, value in params.items():
            name, _, sub = key.partition("__")
            if name not in valid:
                raise TGHopError(f"invalid parameter {name!r} for {type(self).__name__}; valid: {', '.join(valid)}")
            if sub:
                nested.setdefault(name, {})[sub] = value
            else:
                setattr(self, name, value)
        for name, sub_params in nested.items():
            part = getattr(self, name)
            if not callable(getattr(part, "set_params", None)) or isinstance(part, type):
                key = f"{name}__{next(iter(sub_params))}"
                raise TGHopError(f"invalid parameter {key!r} for {type(self).__name__}: its {name} is {part!r:.60}, "
                                 f"not an estimator; set {name} first")
            part.set_params(**sub_params)
        return self

    def __sklearn_tags__(self):
        """scikit-learn's default tags (its ``check_is_fitted``, ``is_regressor`` and HTML repr
        ask for them; scikit-learn is imported only then)."""
        from sklearn.base import BaseEstimator as SklearnBase

        return SklearnBase.__sklearn_tags__(self)

    def __sklearn_is_fitted__(self):
        """Whether scikit-learn's ``check_is_fitted`` takes this estimator as fitted: as tghop's own
        check does, learned state (an attribute ending in ``_``) and the settings it was fitted
        with (``set_params`` after ``fit`` unfits a :class:`~tghop.synthesis.TGHop`; scikit-learn's
        own test, learned state alone, took it as fitted still)."""
        if not any(k.endswith("_") and not k.startswith("__") for k in vars(self)):
            return False
        try:
            check_is_fitted(self, ())
        except NotFittedError:
            return False
        return True

    def __repr__(self):
        defaults = {p.name: p.default for p in inspect.signature(type(self).__init__).parameters.values()}
        changed = []
        for name in self._get_param_names():
            value = getattr(self, name, None)
            default = defaults.get(name, inspect.Parameter.empty)
            try:
                same = value is default or bool(value == default)
            except (ValueError, TypeError):  # arrays
                same = False
            if not same:
                text = generator_text(value) if isinstance(value, np.random.Generator) else repr(value)
                changed.append(f"{name}={text}")
        return f"{type(self).__name__}({', '.join(changed)})"


def generator_text(rng: np.random.Generator) -> str:
    """A Generator as an estimator's repr shows it, the same in every run and process (NumPy's repr
    names its address): ``Generator(PCG64, seed=0)`` as ``default_rng(0)`` makes it, ``..., advanced)``
    once drawn from (a fitted part's copy of the fit's generator), ``Generator(PCG64)`` without a seed
    that says how it was made (spawned; unseeded, from 128 bits of the system's entropy)."""
    bits = rng.bit_generator
    seeds = getattr(bits, "seed_seq", None)
    entropy = getattr(seeds, "entropy", None)
    if not isinstance(entropy, int) or not 0 <= entropy < 2**64 or tuple(getattr(seeds, "spawn_key", ())):
        return f"Generator({type(bits).__name__})"
    try:
        fresh = type(bits)(entropy).state == bits.state
    except (TypeError, ValueError):  # a bit generator of another constructor
        fresh = False
    return f"Generator({type(bits).__name__}, seed={entropy}{'' if fresh else ', advanced'})"


class TransformerMixin:
    """``fit_transform`` as ``fit(X).transform(X)`` (as scikit-learn's mixin)."""

    def fit_transform(self, X, y=None, **fit_params):
        """Fit to ``X``, then transform it.

        Parameters
        ----------
        X : array_like
            As ``fit`` takes it.
        y : None
            Ignored (scikit-learn's signature).
        **fit_params
            Passed to ``fit``.

        Returns
        -------
        ndarray
            ``self.fit(X, y, **fit_params).transform(X)``.
        """
        return self.fit(X, y, **fit_params).transform(X)

    def __sklearn_tags__(self):
        from sklearn.utils import TransformerTags

        tags = super().__sklearn_tags__()
        tags.transformer_tags = TransformerTags()
        return tags


class FourDInputMixin:
    """Mixin, before :class:`TransformerMixin`: the input is a 4-D array ((n, H, W, C) images or
    responses), which scikit-learn's tags say (``input_tags.two_d_array`` False), so that its
    ``check_estimator``, whose checks feed 2-D arrays, skips the estimator instead of failing."""

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False
        return tags


class StoredArrays:
    """Mixin: fitted float arrays to and from a model file, as ``_ARRAYS`` lists them
    ((file name, attribute), ...); read back as float64."""

    _ARRAYS: tuple = ()

    def _to_arrays(self) -> dict:
        return {name: getattr(self, attr) for name, attr in self._ARRAYS}

    def _from_arrays(self, arrays):
        """Restore the fitted state from :meth:`_to_arrays` output; returns self."""
        for name, attr in self._ARRAYS:
            setattr(self, attr, arrays[name].astype(np.float64, copy=False))
        return self


def check_is_fitted(estimator, attributes) -> None:
    """Raise :class:`NotFittedError` unless ``estimator`` has every attribute in ``attributes``, or when
    its settings differ from those it was fitted with (``set_params`` after ``fit``: its learned state,
    and a model file's metadata, would not match them; an AttributeError, so ``hasattr`` of a fitted
    property is False then, as before ``fit``)."""
    names = [attributes] if isinstance(attributes, str) else list(attributes)
    if not hasattr(estimator, "__dict__"):  # a path or a number where a model belongs
        raise TGHopError(f"expected a fitted model, got {type(estimator).__name__} {str(estimator)[:60]!r} "
                         "(a model file is read by tghop.modelfile.load_model)")
    if not all(name in vars(estimator) for name in names):
        raise NotFittedError(
            f"this {type(estimator).__name__} is not fitted yet; call 'fit' with an exemplar first "
            "(or load a fitted model with tghop.modelfile.load_model)"
        )
    fitted = vars(estimator).get("_fitted_params")  # kept by TGHop.fit and load: the settings of its state
    if fitted is not None:
        now = fitted_settings(estimator)
        changed = [k for k in now if k in fitted and k.replace("__", ".").split(".")[-1] != "rng"
                   and not _same_setting(now[k], fitted[k])]
        if changed:
            what = ", ".join(f"{k} {fitted[k]!r} -> {now[k]!r}" for k in changed)
            raise NotFittedError(f"this {type(estimator).__name__}'s settings changed after it was fitted ({what}); "
                                 "fit it again, or set them back with set_params")


def fitted_settings(estimator) -> dict:
    """What :func:`check_is_fitted` holds a fitted estimator's settings to: its own (``get_params``, with
    those of a parameter that is an estimator as ``model__name``: a Material's ``model``) and
    those of its fitted parts (attributes ending in ``_`` that have ``get_params``, as ``part_.name``),
    lists and arrays copied, so that a list the caller changes later counts as a change. ``rng`` (the
    fit's seed) is kept but not compared: changing it after fit changes nothing learned. A part set to
    None or removed since is not compared either (a model file without it loads so)."""
    def copied(value):
        return [copied(v) for v in value] if isinstance(value, (list, tuple, np.ndarray)) else value

    out = {k: copied(v) for k, v in estimator.get_params(deep=True).items()}
    for name, part in vars(estimator).items():
        if name.endswith("_") and not name.startswith("_") and callable(getattr(part, "get_params", None)):
            out.update({f"{name}.{k}": copied(v) for k, v in part.get_params(deep=False).items()})
    return out


def _same_setting(a, b) -> bool:
    """Whether two values of a setting are the same: sequences (lists, tuples, arrays) element by element,
    an integer never the same as a float (``patch_size`` 32.0 is refused where 32 is taken)."""
    if a is b:
        return True
    sequences = (list, tuple, np.ndarray)
    if isinstance(a, sequences) or isinstance(b, sequences):
        return (isinstance(a, sequences) and isinstance(b, sequences) and len(a) == len(b)
                and all(_same_setting(x, y) for x, y in zip(a, b)))
    if isinstance(a, numbers.Integral) != isinstance(b, numbers.Integral) or isinstance(a, bool) != isinstance(b, bool):
        return False
    try:
        return bool(a == b)
    except (TypeError, ValueError):  # values that cannot be compared
        return False


#: ``progress(stage, done, total)``: called by long-running steps. ``stage`` is a short
#: human-readable name ("hop 1", "clusters", "quilting"), ``done`` counts finished units
#: out of ``total``. A stage always ends with ``done == total``.
ProgressCallback = Callable[[str, int, int], None]

RngLike = Union[None, int, np.integer, np.random.Generator]


def report(progress: Optional[ProgressCallback], stage: str, done: int, total: int) -> None:
    """Call ``progress`` if one was given."""
    if progress is not None:
        if not callable(progress):
            raise TGHopError(f"progress must be a function progress(stage, done, total) or None, "
                             f"got {type(progress).__name__}")
        progress(stage, int(done), int(total))


class ProgressCounter:
    """``progress(stage, done, total)`` of steps done in several threads: ``counter(n)`` adds ``n`` steps and
    reports the sum (under a lock, so that the counts reported only grow, from whichever thread did the step).

    Parameters
    ----------
    progress : callable or None
        The callback (None: the steps are only counted).
    stage : str
    total : int
        The steps of the whole stage.
    """

    def __init__(self, progress, stage, total):
        self.progress, self.stage, self.total = progress, stage, total
        self.done = 0
        self._lock = threading.Lock()

    def __call__(self, n):
        with self._lock:
            self.done += n
            report(self.progress, self.stage, self.done, self.total)

    def relay(self):
        """A ``progress(stage, done, total)`` callback for a part of the work: each of its reports adds the
        steps its ``done`` gained since its last one (its own stage and total are not used)."""
        last = [0]

        def told(stage, done, total):
            if done > last[0]:
                self(done - last[0])
                last[0] = done

        return told


def check_keywords(options, function, *, where: str, exclude=()) -> None:
    """Refuse a keyword of ``options`` that ``function`` does not take, in one line naming the
    keywords it does take (all but ``exclude``), instead of Python's TypeError naming an inner
    function."""
    known = [p for p in inspect.signature(function).parameters if p not in exclude]
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise TGHopError(f"{where}: unknown keyword {unknown[0]!r}; the keywords are {', '.join(known)}")


def check_rng(rng: RngLike) -> np.random.Generator:
    """Turn ``rng`` (None, an int seed, not a bool, or a Generator) into a ``numpy.random.Generator``.

    A Generator is returned as is (so consecutive calls advance it); an int gives the same
    stream every time; None gives fresh OS entropy.
    """
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or isinstance(rng, (numbers.Integral, np.integer)) and not isinstance(rng, (bool, np.bool_)):
        if rng is not None and int(rng) < 0:
            raise TGHopError(f"seed must be a non-negative integer, got {rng}")
        return np.random.default_rng(None if rng is None else int(rng))
    raise TGHopError(f"rng must be None, an int seed or numpy.random.Generator, got {type(rng).__name__}")


def fit_part(part, rng: np.random.Generator, *args, **kwargs):
    """``part.fit(*args, **kwargs)`` drawing from ``rng`` as if ``rng`` were its own, leaving ``part.rng``
    a copy of ``rng`` as it was before: what reproduces it (``sklearn.base.clone(part).fit(*args)``).

    The fit draws from that copy; ``rng`` is then moved on to where the fit left it (also when the fit
    fails), so the caller's later draws are those a fit from ``rng`` itself leaves, bit for bit, and no
    fitted part holds the caller's generator, used up. Returns ``part``.
    """
    own = copy.deepcopy(rng)
    start = own.bit_generator.state
    part.rng = own
    try:
        return part.fit(*args, **kwargs)
    finally:
        rng.bit_generator.state = own.bit_generator.state
        own.bit_generator.state = start


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
    as one, and :func:`tghop.metrics.common.pair` compares as one."""
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


# ------------------------------------------------------------------ sizes
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


# ------------------------------------------------------------------ memory
def available_memory() -> Optional[int]:
    """Bytes of memory available to a new allocation now, or None where unknown.

    Linux's ``MemAvailable`` (``/proc/meminfo``: free memory plus the page cache and
    buffers that can be reclaimed), else ``os.sysconf('SC_PAGE_SIZE') *
    os.sysconf('SC_AVPHYS_PAGES')`` (free pages only: an underestimate). Containers'
    cgroup limits are not read.
    """
    import os

    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_AVPHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def _format_bytes(n: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n / 1e6:.2g} MB"


def check_memory(estimate: Callable[[int, int], float], size, *, what: str, name: str = "size") -> None:
    """Refuse, before any work, a ``size`` whose memory ``estimate(h, w)`` (bytes) exceeds
    :func:`available_memory`; the one-line :class:`TGHopError` names the largest size of
    the same aspect ratio that fits. Nothing is checked where the available memory is unknown.

    Parameters
    ----------
    estimate : callable
        ``estimate(h, w)``: bytes the work needs for an ``h x w`` result, non-decreasing in both.
    size : (int, int)
    what : str
        The work, for the message (``"ustyuzhaninov"``).
    name : str
        How the size is called (``"size"``; ``"--size"`` on the command line).
    """
    avail = available_memory()
    if avail is None:
        return
    h, w = (int(v) for v in size)
    need = float(estimate(h, w))
    if need <= avail:
        return
    lo, hi = 0.0, 1.0  # largest scale f with estimate(f h, f w) <= avail, by bisection
    for _ in range(40):
        mid = (lo + hi) / 2
        if estimate(max(1, int(mid * h)), max(1, int(mid * w))) <= avail:
            lo = mid
        else:
            hi = mid
    fh, fw = int(lo * h), int(lo * w)
    if fh < 1 or fw < 1 or estimate(max(1, fh), max(1, fw)) > avail:
        raise TGHopError(f"{what} needs about {_format_bytes(need)} of memory for {h}x{w} and still "
                         f"{_format_bytes(estimate(1, 1))} for the smallest result, but only "
                         f"{_format_bytes(avail)} is available; use a smaller exemplar or free some memory")
    raise TGHopError(f"{what} at {name} {h}x{w} needs about {_format_bytes(need)} of memory but only "
                     f"{_format_bytes(avail)} is available; the largest {name} that fits is about {fh}x{fw}")


# ------------------------------------------------------------------ optional extras
#: How to install what the neural baselines, the cGAN and the network metrics need.
INSTALL_HINT = "pip install 'tghop[metrics]'"


def import_torch(what: str):
    """``torch``, or a one-line :class:`MissingExtraError` saying that ``what`` needs it
    and how to install it."""
    try:
        import torch
    except ImportError:
        raise MissingExtraError(f"{what} needs PyTorch; install it with: {INSTALL_HINT} (where pip would fetch a "
                                "CUDA build of several GB, install PyTorch's CPU build of torch 2.13.0 first: "
                                "README)") from None
    return torch


# ------------------------------------------------------------------ threads
#: The process-wide limit of :func:`limit_cores` (None: no limit).
_core_limit = None


def usable_cores() -> int:
    """Cores this process may run on: its affinity mask (``os.sched_getaffinity``, else
    ``os.cpu_count()``), at most the limit of :func:`limit_cores`, at least 1.

    :meth:`tghop.core.ICHM.fit` runs its clusters in this many Python threads, each with
    one BLAS thread: threads that block do not spin, so beside other work they share the
    cores fairly and a fit is no slower than on one thread, while on an idle machine it
    uses every core (OpenBLAS's own threads spin between calls, and on a loaded machine a
    fit with them took several times as long as with one; docs/choices.md). The steps of
    generation that split a large image over threads (refinement, colour matching, the
    coarse layout's guide, PNG compression) use this too.
    """
    import os

    try:
        n = max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    return n if _core_limit is None else max(1, min(n, _core_limit))


class limit_cores:
    """Context manager: :func:`usable_cores` says at most ``n`` (None: no limit) while it
    is active, in every thread of the process (like ``threadpoolctl.threadpool_limits``,
    whose BLAS limit it complements: tghop's own threads).

    A batch worker process runs one exemplar at a time on one core
    (:func:`tghop.batch.process_exemplar` with ``threads=1``): its fit and generation
    then start no threads of their own to compete with the other workers.
    """

    def __init__(self, n: Optional[int]):
        self.n = None if n is None else max(1, int(n))

    def __enter__(self):
        global _core_limit
        self._previous = _core_limit
        if self.n is not None:
            _core_limit = self.n if _core_limit is None else min(_core_limit, self.n)
        return self

    def __exit__(self, *exc):
        global _core_limit
        _core_limit = self._previous
        return False


#: The process's holds of one BLAS thread (:func:`one_blas_thread`): how many are active, in any thread,
#: and the limiter the first set, which the last to leave restores.
_BLAS_HOLD = {"count": 0, "limiter": None}
_BLAS_LOCK = threading.Lock()
_BLAS_OWN = threading.local()  # this thread's holds: the ones a child of os.fork keeps


def _blas_holds_after_fork():
    """In a child of ``os.fork`` only the forking thread's holds go on (0.57; 0.56's child stayed on one BLAS
    thread)."""
    global _BLAS_LOCK
    _BLAS_LOCK, own = threading.Lock(), getattr(_BLAS_OWN, "count", 0)  # the lock: another thread's at the fork
    if _BLAS_HOLD["count"] > own:
        _BLAS_HOLD["count"] = own
        import threadpoolctl  # imported by the hold

        controller = threadpoolctl.OpenBLASController
        if hasattr(controller, "clear_controlling_thread"):  # threadpoolctl >= 3.8: the holder is not in the child
            controller.clear_controlling_thread(force=True)
        if not own:
            _BLAS_HOLD.pop("limiter").restore_original_limits()
            _BLAS_HOLD["limiter"] = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_blas_holds_after_fork)


@contextlib.contextmanager
def one_blas_thread():
    """Context manager (and decorator): one BLAS thread while inside, in every thread of the process.

    OpenBLAS's products round differently on more threads, so generating inside it gives the
    same image on a machine of any number of cores (a batch worker's one thread, ``tghop
    synth``'s all). Its limit is the process's, so the holds are counted process-wide (0.57): the
    first sets it (``threadpoolctl.threadpool_limits(limits=1, user_api="blas")``), the last to
    leave, in whichever thread, puts back what the first found. Until 0.56 each hold set and
    restored its own, so two threads' calls at once left the later one on the process's threads
    (other bytes: a fit in two threads gave another model) and the process on one BLAS thread after
    both. A thread that leaves while another holds on gives up threadpoolctl's control of OpenBLAS's
    limit (since threadpoolctl 3.8, only the thread that set it first may change it), unless a
    ``threadpool_limits`` of its own is active.
    """
    import threadpoolctl

    with _BLAS_LOCK:
        if not _BLAS_HOLD["count"]:
            _BLAS_HOLD["limiter"] = threadpoolctl.threadpool_limits(limits=1, user_api="blas")
        _BLAS_HOLD["count"] += 1
        _BLAS_OWN.count = getattr(_BLAS_OWN, "count", 0) + 1
    try:
        yield
    finally:
        with _BLAS_LOCK:
            _BLAS_HOLD["count"] -= 1
            _BLAS_OWN.count -= 1
            if not _BLAS_HOLD["count"]:
                _BLAS_HOLD.pop("limiter").restore_original_limits()
                _BLAS_HOLD["limiter"] = None
            own = getattr(threadpoolctl, "CONTROLLING_THREAD_OWNERSHIP", None)  # threadpoolctl >= 3.8
            if own is not None and not own.count:
                threadpoolctl.OpenBLASController.clear_controlling_thread()


def in_thread(fn, *args, **kwargs) -> Callable:
    """Start ``fn(*args, **kwargs)`` in a thread of its own; return a function that waits
    for it and returns its result (or raises its exception).

    The thread is a daemon: an interrupted caller does not wait for it. (``threading``
    alone: ``concurrent.futures`` imports ``logging``, a noticeable part of a small
    ``tghop synth``.) With one usable core (:func:`usable_cores`, e.g. a batch worker's
    task) no thread is started: ``fn`` runs in the caller's thread when its result is asked for.
    The thread runs in a copy of the caller's context (as ``asyncio.to_thread``): its warnings
    go where the caller's would (:func:`tghop._errors.collect_warnings`).
    """
    if usable_cores() == 1:
        return lambda: fn(*args, **kwargs)
    import contextvars

    outcome = {}

    def run():
        try:
            outcome["result"] = fn(*args, **kwargs)
        except BaseException as exc:  # handed to the caller, who raises it
            outcome["error"] = exc

    thread = threading.Thread(target=contextvars.copy_context().run, args=(run,), daemon=True)
    thread.start()

    def result():
        thread.join()
        if "error" in outcome:
            raise outcome.pop("error")
        return outcome["result"]

    return result
