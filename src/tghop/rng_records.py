"""What a model file records of the random generators a fit drew from, and how a loaded model gets
them back: an int seed as it is (:func:`recorded_seed`, :func:`fit_seed`), a NumPy Generator as its
bit generator's name, seed and state (:func:`generator_record`, :func:`generator_from_record`), and
the Generators an estimator was given as its ``rng`` settings (:func:`generators_given`,
:func:`generator_records`, :func:`set_generators`; 0.58).

:mod:`tghop.settings` re-exports these names and reads a model file's seed with
:func:`recorded_seed`. NumPy is imported inside the functions that need it: the command line reads
the settings table without it.
"""

from __future__ import annotations

import numbers

from ._errors import TGHopError

__all__ = ["recorded_seed", "fit_seed", "BIT_GENERATORS", "generator_record", "generator_from_record",
           "generators_given", "generator_records", "set_generators"]


def recorded_seed(rng):
    """What a model file records of the fit's ``rng``: an int seed as it is, anything else
    (a Generator, None: no seed to give again) as None.

    Parameters
    ----------
    rng : int, numpy.random.Generator or None
        A ``rng`` argument as given to ``TGHop``.

    Returns
    -------
    int or None
        ``rng`` as an int where it is an integer >= 0 (a NumPy integer too), else None.
    """
    if isinstance(rng, numbers.Integral) and not isinstance(rng, bool) and rng >= 0:
        return int(rng)
    return None


def fit_seed(model):
    """:func:`recorded_seed` of the ``rng`` a fitted model was fitted with (its ``rng`` now may
    have been changed by ``set_params`` since, which changes nothing learned).

    Parameters
    ----------
    model : TGHop
        A fitted (or loaded) model.

    Returns
    -------
    int or None
        The seed the model was fitted with, or None (fitted from a Generator or None).
    """
    return recorded_seed(vars(model).get("_fitted_params", {}).get("rng", model.rng))


#: The bit generators whose state a model file may record (:func:`generator_record`): NumPy's own.
BIT_GENERATORS = ("PCG64", "PCG64DXSM", "MT19937", "Philox", "SFC64")


def generator_record(rng):
    """A fitted part's ``rng`` as a model file records it (JSON data): a Generator as its bit
    generator's name, its seed where :func:`tghop._estimator.generator_text` shows one, and its state;
    anything else (an int seed, None) as None (an int seed is in the settings already).

    Parameters
    ----------
    rng : numpy.random.Generator, int or None
        A fitted part's copy of the fit's generator, as it was before the part's fit.

    Returns
    -------
    dict or None
        ``{"bit_generator": name, "seed": int or None, "state": ...}`` (arrays in the state as
        ``{"dtype": ..., "values": [...]}``), or None.
    """
    import numpy as np  # here: the command line reads this table without NumPy

    if not isinstance(rng, np.random.Generator) or type(rng.bit_generator).__name__ not in BIT_GENERATORS:
        return None
    bits = rng.bit_generator
    seeds = getattr(bits, "seed_seq", None)
    entropy = getattr(seeds, "entropy", None)
    seed = entropy if isinstance(entropy, int) and 0 <= entropy < 2**64 and not tuple(
        getattr(seeds, "spawn_key", ())) else None

    def data(value):
        if isinstance(value, dict):
            return {k: data(v) for k, v in value.items()}
        if isinstance(value, np.ndarray):
            return {"dtype": value.dtype.str, "values": value.tolist()}
        return value.item() if isinstance(value, np.generic) else value

    return {"bit_generator": type(bits).__name__, "seed": seed, "state": data(bits.state)}


def generator_from_record(record, what: str = "rng"):
    """The Generator of :func:`generator_record`'s ``record`` (None: None), in the state it records.

    Parameters
    ----------
    record : dict or None
        As :func:`generator_record` made it (read from a model file's metadata).
    what : str
        How the record is named in the error message.

    Returns
    -------
    numpy.random.Generator or None

    Raises
    ------
    TGHopError
        A record that is not one (another bit generator, a state NumPy does not take).
    """
    import numpy as np

    if record is None:
        return None
    if not isinstance(record, dict) or set(record) != {"bit_generator", "seed", "state"} or \
            record["bit_generator"] not in BIT_GENERATORS or not isinstance(record["state"], dict):
        raise TGHopError(f"the metadata's {what} is not a generator's record (bit_generator, seed, state)")

    def value(v):
        if isinstance(v, dict) and set(v) == {"dtype", "values"}:
            return np.asarray(v["values"], dtype=np.dtype(v["dtype"]))
        return {k: value(x) for k, x in v.items()} if isinstance(v, dict) else v

    try:
        kind = getattr(np.random, record["bit_generator"])
        seed = record["seed"]
        bits = kind(np.random.SeedSequence(seed) if isinstance(seed, int) and not isinstance(seed, bool) else None)
        bits.state = value(record["state"])
    except (TypeError, ValueError, KeyError, OverflowError) as exc:
        raise TGHopError(f"the metadata's {what} holds a state NumPy does not take ({exc})") from None
    return np.random.Generator(bits)


def generators_given(estimator) -> dict:
    """Copies of the Generators among ``estimator``'s own parameters as they are now (``rng``; a
    Material's ``model__rng`` too): what a fit that starts now draws from, kept in its
    ``_fitted_params`` so that :func:`generator_records` writes them to the model file (0.58).

    Parameters
    ----------
    estimator : TGHop or Material

    Returns
    -------
    dict
        Parameter name (as ``get_params(deep=True)`` names it) -> a copy of its Generator.
    """
    import copy

    import numpy as np

    return {name: copy.deepcopy(value) for name, value in estimator.get_params(deep=True).items()
            if name.split("__")[-1] == "rng" and isinstance(value, np.random.Generator)}


def generator_records(fitted) -> dict:
    """What a model file records of the Generators a fit started from (0.58; ``fit_rngs``): each of a
    fitted estimator's own ``rng`` settings (its ``_fitted_params``: ``rng``, a Material's ``model__rng``)
    that was a Generator, as :func:`generator_record` makes it, as it was when the fit began. Its parts'
    copies (``ichm_rng``, ...) are recorded by them.

    Parameters
    ----------
    fitted : dict or None
        The estimator's ``_fitted_params``.

    Returns
    -------
    dict
        Parameter name -> record; empty where none was a Generator (an int seed: in the settings).
    """
    out = {}
    for name, value in (fitted or {}).items():
        record = generator_record(value) if "." not in name and name.split("__")[-1] == "rng" else None
        if record is not None:
            out[name] = record
    return out


def set_generators(estimator, records, what: str = "fit_rngs") -> dict:
    """Give a loaded ``estimator`` the Generators a model file records for its ``rng`` settings
    (:func:`generator_records`' ``records``; None: none recorded), each in the state its fit began in,
    so that ``clone(loaded).fit(x)`` fits it again as it was fitted.

    Parameters
    ----------
    estimator : TGHop or Material
        Loaded, not yet given its ``_fitted_params``.
    records : dict or None
    what : str
        How the records are named in an error.

    Returns
    -------
    dict
        Parameter name -> a copy of the Generator set, for the estimator's ``_fitted_params``.

    Raises
    ------
    TGHopError
        Records that are not a dict of ``rng`` settings' generator records.
    """
    import copy

    if records is None:
        return {}
    params = estimator.get_params(deep=True)
    if not isinstance(records, dict) or not all(isinstance(n, str) and n in params and n.split("__")[-1] == "rng"
                                                for n in records):
        raise TGHopError(f"the metadata's {what} is not a record of the estimator's rng settings")
    given = {name: generator_from_record(record, f"{what}[{name!r}]") for name, record in records.items()}
    estimator.set_params(**given)
    return {name: copy.deepcopy(value) for name, value in given.items()}
