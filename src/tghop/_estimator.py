"""The small estimator base of every learned part (scikit-learn's conventions without importing it:
``get_params``, ``set_params``, a stable repr, ``check_is_fitted``), and how randomness enters
(``check_rng``; ``fit_part``, which leaves each fitted part a copy of the generator it drew from).

Nothing here imports scikit-learn or SciPy: generating from a saved model, ``tghop info`` and
``--help`` must not pay for their (long) import time.
"""

from __future__ import annotations

import copy
import functools
import inspect
import numbers
from typing import Union

import numpy as np

from ._errors import NotFittedError, TGHopError

__all__ = [
    "BaseEstimator",
    "generator_text",
    "TransformerMixin",
    "FourDInputMixin",
    "ImageInputMixin",
    "StoredArrays",
    "check_is_fitted",
    "fitted_settings",
    "check_keywords",
    "named_keywords",
    "check_rng",
    "fit_part",
]


#: What :func:`check_is_fitted` says to do about a component fitted on arrays (a Saab, an ICHM), whose ``fit`` takes
#: no exemplar and no model file holds alone (0.63; 0.62 said "call 'fit' with an exemplar first (or load a fitted
#: model with tghop.modelfile.load_model)" to every estimator).
NOT_FITTED_HINT = ("call its 'fit' first, or take the fitted part of a fitted TGHop (model.hops_, model.sdr_, "
                   "model.ichm_, ...)")
#: ... and about one whose ``fit`` takes an image (:class:`ImageInputMixin`).
NOT_FITTED_IMAGE_HINT = "call 'fit' with an exemplar first"
#: ... and about a model that a model file holds (:class:`~tghop.synthesis.TGHop`, :class:`~tghop.material.Material`).
NOT_FITTED_MODEL_HINT = ("call 'fit' with an exemplar first (or load a fitted model with "
                         "tghop.modelfile.load_model)")


class BaseEstimator:
    """The part of scikit-learn's ``BaseEstimator`` tghop uses: ``get_params``,
    ``set_params`` and a repr of the changed parameters.

    tghop's own so that generating from a saved model never imports scikit-learn;
    ``sklearn.base.clone`` and grid searches still work (they need only these methods).
    The constructor stores its arguments and does nothing else.
    """

    def __new__(cls, *args, **kwargs):
        """Refuse, before the constructor runs, a keyword it does not take, with the words of :meth:`set_params`
        (a TypeError, as Python's own; 0.64: 0.63 let Python's "unexpected keyword argument 'k1'" out, which names
        neither the Python name of the command line's --k1 nor the valid ones). The constructor itself still only
        stores its arguments; a copy or an unpickled estimator, made without arguments, is not checked."""
        self = super().__new__(cls)
        if kwargs and not cls._takes_any_keyword():
            valid = cls._get_param_names()
            unknown = next((name for name in kwargs if name not in valid), None)
            if unknown is not None:
                raise TypeError(f"{cls.__name__}() got an unexpected keyword argument {unknown!r}"
                                f"{self._unknown_param_hint(unknown)}; valid: {', '.join(valid)}")
        return self

    @classmethod
    @functools.cache
    def _takes_any_keyword(cls):
        """Whether the constructor takes ``**kwargs`` (then every keyword is its own to refuse)."""
        return cls.__init__ is not object.__init__ and any(
            p.kind is p.VAR_KEYWORD for p in inspect.signature(cls.__init__).parameters.values())

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
                hint = self._unknown_param_hint(name)
                raise TGHopError(f"invalid parameter {name!r} for {type(self).__name__}{hint}; valid: "
                                 f"{', '.join(valid)}")
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

    def _unknown_param_hint(self, name):
        """What :meth:`set_params` adds for an unknown parameter ``name`` before the valid ones (a subclass names
        its command line's words for its parameters: :class:`tghop.synthesis.TGHop`)."""
        if name == "random_state" and "rng" in self._get_param_names():
            return "; scikit-learn's random_state is tghop's rng"  # 0.59
        return ""

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


class ImageInputMixin:
    """Mixin, before :class:`BaseEstimator`: ``fit`` takes one (H, W, C) image (a :class:`~tghop.synthesis.TGHop`, its
    steps' statistics, a :class:`~tghop.material.Material`, the cGAN), which scikit-learn's tags say
    (``input_tags.two_d_array`` False, ``three_d_array`` True), so that its ``check_estimator`` skips the estimator
    (0.60; 0.59's tags said 2-D arrays, and 28 or 29 of its 41 checks failed on each)."""

    _not_fitted_hint = NOT_FITTED_IMAGE_HINT

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False
        tags.input_tags.three_d_array = True
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
        raise NotFittedError(f"this {type(estimator).__name__} is not fitted yet; "
                             f"{getattr(estimator, '_not_fitted_hint', NOT_FITTED_HINT)}")
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


RngLike = Union[None, int, np.integer, np.random.Generator]


def named_keywords(method):
    """A method that refuses a keyword it does not take with the estimator's hint for that name
    (``_unknown_keyword_hint``, else :meth:`BaseEstimator._unknown_param_hint`: a command line's name, a setting
    of another call), in Python's
    words (a TypeError, 0.64: ``model.synthesize(size, pool=30)`` was Python's bare "unexpected keyword
    argument 'pool'"). Its signature is the method's own (``inspect.signature`` follows ``__wrapped__``)."""
    takes = set(inspect.signature(method).parameters)

    @functools.wraps(method)
    def checked(self, *args, **kwargs):
        unknown = next((name for name in kwargs if name not in takes), None)
        if unknown is not None:
            raise TypeError(f"{type(self).__name__}.{method.__name__}() got an unexpected keyword argument "
                            f"{unknown!r}{getattr(self, '_unknown_keyword_hint', self._unknown_param_hint)(unknown)}")
        return method(self, *args, **kwargs)

    return checked


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
    fix = ""  # 0.59: the fix for what scikit-learn's users hold (random_state=RandomState(0)), which default_rng takes
    if isinstance(rng, (np.random.RandomState, np.random.SeedSequence, np.random.BitGenerator)):
        fix = "; give numpy.random.default_rng(rng) of it, or an int seed"
    raise TGHopError(f"rng must be None, an int seed or numpy.random.Generator, got {type(rng).__name__}{fix}")


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
