"""Fit options -> a :class:`~tghop.TGHop`: what the command line (``fit``, ``synth``,
``batch``), the web server (``POST /api/models``) and :mod:`tghop.batch` share.

Options are a dict by setting name (:data:`tghop.settings.SETTINGS`), as typed: a value
not given is absent or None and takes the table's default (or its paper value with
``paper``); :data:`OFF` is an explicit "none" for a setting that allows None. Channel
counts are ``k1``, ``k2``, ``k3`` (a count, a fraction or ``"knee"``); those not given
take :func:`tghop.synthesis.default_channels` for the exemplar's colours, filled in by
:func:`model_for` once the exemplar is known.

Only :mod:`tghop._errors` is imported at the top (no NumPy: the command line builds its options
from this module); the settings table when options are read, the estimator when a model is made.
"""

from __future__ import annotations

from ._errors import TGHopError

__all__ = ["OFF", "setting_value", "fit_params", "model_for", "material_model", "build_model"]


class _Off:
    """An explicit "none" / "off" for a setting that allows None (``--layout none``), told
    apart from an option not given (None), whose value is the table's default."""

    def __repr__(self):
        return "OFF"


#: An explicit "none" / "off" (``--layout none``): the setting is None, not its default.
OFF = _Off()


def setting_value(s, options: dict, paper: bool):
    """The value of setting ``s`` from ``options``: the one given (:data:`OFF`: None), else
    the table's default, or its paper value with ``paper``.

    Parameters
    ----------
    s : tghop.settings.Setting
        The setting.
    options : dict
        Fit options by setting name (not checked here).
    paper : bool
        A setting not given takes its paper value, where it has one.

    Returns
    -------
    object
        The value given, None for :data:`OFF`, or the default (paper) value.
    """
    value = options.get(s.name)
    if value is OFF:
        return None
    if value is not None:
        return value
    return s.paper if paper and s.has_paper else s.default


def _called(name: str, api: bool) -> str:
    """How a message names fit option ``name``: the web API's field (``patch_size``, ``k1``)
    or the command line's option (``--patch-size``, ``--k1``; from the settings table)."""
    if api:
        return name
    from .settings import BY_NAME

    s = BY_NAME.get(name)
    return s.option_names[0] if s is not None and s.option_names else "--" + name.replace("_", "-")


def fit_params(options: dict, *, api: bool = False) -> dict:
    """TGHop's parameters from the fit options (``paper``, ``k1``/``k2``/``k3``, ``rng``
    and the fit settings by name). ``api``: messages name the web API's fields
    (``patch_size``), not the command line's options (``--patch-size``).

    Channel counts not given stay None in ``n_channels`` (the default for the exemplar's
    colours: :func:`model_for` fills them in when the exemplar is known; ``tghop batch``
    fits many exemplars).

    Parameters
    ----------
    options : dict
        Fit options: ``paper`` (bool), ``k1``, ``k2``, ``k3`` (channel rules or None),
        ``rng`` and fit settings by name; absent or None: not given.
    api : bool
        Name the web API's fields in messages.

    Returns
    -------
    dict
        Keyword arguments of :class:`~tghop.TGHop`: every fit setting, ``n_channels``
        (a tuple, entries not given None, or None when none is given) and ``rng`` (0 when
        not given). Values are not checked here (``TGHop.fit`` checks them).

    Raises
    ------
    TGHopError
        A patch size without default channel counts and none given, or ``k3`` for
        32x32 patches.
    """
    from .settings import fit_settings

    paper = options.get("paper", False)
    params = {s.name: setting_value(s, options, paper) for s in fit_settings() if s.name not in ("n_channels", "rng")}
    patch_size = int(params["patch_size"])
    size, k1, k2, k3 = (_called(name, api) for name in ("patch_size", "k1", "k2", "k3"))
    if patch_size not in (32, 64) and any(options.get(k) is None for k in ("k1", "k2")):
        raise TGHopError(f"{size} {patch_size} needs {k1} and {k2} (defaults exist for 32 and 64)")
    if patch_size == 32 and options.get("k3") is not None:
        raise TGHopError(f"{k3} applies to {size} 64 only (three hops)")
    given = [options.get(k) for k in ("k1", "k2", "k3")][: 3 if patch_size == 64 else 2]
    params["n_channels"] = None if all(g is None for g in given) else tuple(given)
    rng = options.get("rng")
    params["rng"] = 0 if rng is None else rng
    return params


def model_for(params: dict, n_colours: int = 3):
    """A TGHop from its parameters (:func:`fit_params`) for an exemplar of ``n_colours``
    channels: channel counts that are None (all of ``n_channels``, or some entries) take
    :func:`tghop.synthesis.default_channels`; ``rng`` None is 0.

    Parameters
    ----------
    params : dict
        Keyword arguments of :class:`~tghop.TGHop` (:func:`fit_params`); not changed.
    n_colours : int
        The exemplar's channels (C of its (H, W, C) array): 1 for grey, 3 for colour.

    Returns
    -------
    TGHop
        Unfitted. Channel defaults are filled in for 32x32 and 64x64 patches only.
    """
    from .synthesis import TGHop, default_channels

    params = dict(params)
    patch_size = int(params.get("patch_size", 32))
    if patch_size in (32, 64):
        defaults = default_channels(patch_size, n_colours)
        given = params.get("n_channels") or (None,) * len(defaults)
        params["n_channels"] = tuple(d if g is None else g for g, d in zip(given, defaults))
    if params.get("rng") is None:
        params["rng"] = 0
    return TGHop(**params)


def material_model(params: dict):
    """The joint model of a whole material (:class:`tghop.material.Material`'s ``model``) from
    TGHop's parameters (:func:`fit_params`): channel counts not given stay None, which the
    material's fit takes as the defaults for the stacked channels of the albedo and its maps
    (as ``tghop fit --maps``); ``rng`` None is 0.

    Parameters
    ----------
    params : dict
        Keyword arguments of :class:`~tghop.TGHop` (:func:`fit_params`); not changed.

    Returns
    -------
    TGHop
        Unfitted.
    """
    from .synthesis import TGHop

    params = dict(params)
    if params.get("rng") is None:
        params["rng"] = 0
    return TGHop(**params)


def build_model(options: dict, n_colours: int = 3, *, api: bool = False):
    """A TGHop from the fit options for an exemplar of ``n_colours`` channels:
    ``model_for(fit_params(options, api=api), n_colours)``.

    Parameters
    ----------
    options : dict
        Fit options (:func:`fit_params`).
    n_colours : int
        The exemplar's channels: 1 for grey, 3 for colour.
    api : bool
        Name the web API's fields in messages.

    Returns
    -------
    TGHop
        Unfitted.

    Raises
    ------
    TGHopError
        As :func:`fit_params`.
    """
    return model_for(fit_params(options, api=api), n_colours)
