"""Command-line options made from the settings table (:data:`tghop.settings.SETTINGS`)
and the parameter types of the ``tghop`` command line (sizes, channel rules).

Each value is checked by the library's own check (:func:`tghop._common.check_size`,
:func:`tghop.settings.check_channel_rule`, :meth:`tghop.settings.Setting.check`), so
the command line and the library refuse the same values with the same words.
"""

from __future__ import annotations

import re

import click

from .._errors import TGHopError

__all__ = ["OFF", "MAX_COUNT", "DOWNSCALE_HELP", "EXCLUDE_HELP", "ChannelRule", "Size", "SettingType", "model_options",
           "generation_options", "FIT_OPTION_PARAMS", "build_model", "fit_params", "generation_params", "given_options"]

#: Largest accepted --count.
MAX_COUNT = 1000

EXCLUDE_HELP = ("A mask image of the exemplar's size: its white parts (a logo, a label, a stain) are not learnt "
                "(training patches touching them are dropped; colour and band statistics leave them out).")

DOWNSCALE_HELP = ("Exemplars over 64 Mpx (8192x8192) are refused; with --downscale they are reduced to "
                  "64 Mpx instead (with a warning).")


class _Off:
    """An explicit "none" / "off" for a setting that allows None (``--layout none``), told
    apart from an option not given (None), whose value is the table's default."""

    def __repr__(self):
        return "OFF"


#: What :class:`SettingType` makes of "none" / "off"; :func:`build_model` and ``synth`` read it as None.
OFF = _Off()


class ChannelRule(click.ParamType):
    """An int count, a fraction in (0, 1], or 'knee' (:func:`tghop.settings.check_channel_rule`)."""

    name = "COUNT|FRACTION|knee"

    def convert(self, value, param, ctx):
        from ..settings import check_channel_rule

        if isinstance(value, (int, float)) or value is None:
            return value
        text = str(value).strip().lower()
        try:
            rule = text if text == "knee" else int(text)
        except ValueError:
            try:
                rule = float(text)
            except ValueError:
                self.fail(f"{value!r} is not a channel count, a fraction in (0, 1] or 'knee'", param, ctx)
        try:
            return check_channel_rule(rule, repr(value))
        except TGHopError as exc:
            self.fail(str(exc), param, ctx)


class Size(click.ParamType):
    """``HxW`` or a single number for a square, at most :data:`tghop._common.MAX_PIXELS`
    pixels (:func:`tghop._common.check_size`)."""

    name = "HxW"

    def convert(self, value, param, ctx):
        from .._common import check_size

        if isinstance(value, tuple):
            return value
        m = re.fullmatch(r"\s*(-?\d+)\s*(?:[xX*,]\s*(-?\d+)\s*)?", str(value))
        if not m:
            self.fail(f"{value!r} is not a size; write HEIGHTxWIDTH, e.g. 512x512", param, ctx)
        h = int(m.group(1))
        w = int(m.group(2)) if m.group(2) else h
        try:
            return check_size((h, w), name="--size")
        except TGHopError as exc:
            self.fail(str(exc), param, ctx)


class SettingType(click.ParamType):
    """A command-line value of one setting of :data:`tghop.settings.SETTINGS`."""

    def __init__(self, setting):
        self.setting = setting
        self.name = setting.kind.upper()

    def convert(self, value, param, ctx):
        if not isinstance(value, str):
            return value
        s = self.setting
        try:
            out = s.check(s.parse(value), label=repr(value))
            if s.cli_high is not None and out is not None and out > s.cli_high:
                raise TGHopError(f"{value!r} is more than the command line allows ({s.cli_high:,g})")
        except TGHopError as exc:
            self.fail(str(exc), param, ctx)
        return OFF if out is None else out


def _plain(text: str) -> str:
    """The table's help text without its reStructuredText roles and literals (for ``--help``)."""
    return re.sub(r"``([^`]+)``", r"\1", re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text))


def _setting_option(s):
    """A click option for setting ``s``, its help and default taken from the table."""
    names = list(s.option_names)
    help_text = _plain(s.help)
    default = s.default
    shown = {True: "on", False: "off", None: "none"}.get(default, default) if not isinstance(default, int) or \
        isinstance(default, bool) else default
    extra = f"default: {shown}"
    if s.kind == "rng":
        return click.option(*names, "rng", type=click.IntRange(min=0), default=None,
                            help="Seed of fitting (K-means, FastICA). [default: 0]")
    if s.has_paper and s.paper != s.default:
        extra += f"; --paper: {s.paper}"
    if s.kind == "bool":
        flag = names[0]
        return click.option(f"{flag}/--no-{flag[2:]}", s.name, default=None, help=f"{help_text} [{extra}]")
    return click.option(*names, s.name, type=SettingType(s), default=None, help=f"{help_text} [{extra}]")


def _channel_options():
    return [
        click.option("--k1", type=ChannelRule(), default=None, help="Hop-1 channels (paper: 9): count, energy fraction or 'knee'."),
        click.option("--k2", type=ChannelRule(), default=None, help="Hop-2 channels in total (paper: 22)."),
        click.option("--k3", type=ChannelRule(), default=None, help="Hop-3 channels (64x64 patches; default 40)."),
    ]


def _fit_options():
    from ..settings import fit_settings

    options = []
    for s in fit_settings():
        if s.name == "n_channels":
            options += _channel_options()
        elif s.option_names:
            options.append(_setting_option(s))
    options.append(click.option("--paper", is_flag=True,
                                help="The paper's pipeline exactly: Table 4 core model (F about 2,500) and no "
                                     "colour matching; options given as well override it."))
    return options


#: Options of ``fit`` that only matter when fitting (refused by ``synth`` with a saved model).
FIT_OPTION_PARAMS = ("k1", "k2", "k3", "paper", "exclude")


def model_options(func):
    """The fitting options shared by ``fit`` and ``synth``, from the settings table."""
    for option in reversed(_fit_options()):
        func = option(func)
    return func


def generation_options(func):
    """The generation options of ``synth``, from the settings table."""
    from ..settings import generate_settings

    for s in reversed(generate_settings()):
        func = _setting_option(s)(func)
    return func


def _setting_value(s, options, paper):
    """The value of setting ``s`` from the options: the one typed (``none``/``off`` is
    :data:`OFF`: None), else the table's default, or its paper value with --paper."""
    value = options.get(s.name)
    if value is OFF:
        return None
    if value is not None:
        return value
    return s.paper if paper and s.has_paper else s.default


def fit_params(options):
    """TGHop's parameters from the fit options. Channel counts not given stay None in
    ``n_channels`` (the default for the exemplar's colours: :func:`build_model` fills
    them in when the exemplar is known; ``tghop batch`` fits many exemplars)."""
    from ..settings import fit_settings

    paper = options.get("paper", False)
    params = {s.name: _setting_value(s, options, paper) for s in fit_settings() if s.name not in ("n_channels", "rng")}
    patch_size = int(params["patch_size"])
    if patch_size not in (32, 64) and any(options.get(k) is None for k in ("k1", "k2")):
        raise TGHopError(f"--patch-size {patch_size} needs --k1 and --k2 (defaults exist for 32 and 64)")
    if patch_size == 32 and options.get("k3") is not None:
        raise TGHopError("--k3 applies to --patch-size 64 only (three hops)")
    given = [options.get(k) for k in ("k1", "k2", "k3")][: 3 if patch_size == 64 else 2]
    params["n_channels"] = None if all(g is None for g in given) else tuple(given)
    rng = options.get("rng")
    params["rng"] = 0 if rng is None else rng
    return params


def build_model(options, n_colours=3):
    """A TGHop from the fit options, for an exemplar of ``n_colours`` channels (channel
    counts not given: :func:`tghop.synthesis.default_channels`)."""
    from ..synthesis import TGHop, default_channels

    params = fit_params(options)
    patch_size = int(params["patch_size"])
    defaults = default_channels(patch_size, n_colours) if patch_size in (32, 64) else (None, None)
    given = params["n_channels"] or (None,) * len(defaults)
    params["n_channels"] = tuple(d if g is None else g for g, d in zip(given, defaults))
    return TGHop(**params)


def generation_params(options):
    """The keywords of ``TGHop.synthesize`` from the generation options (popped from
    ``options``; unset ones: the table's default, or its paper value with --paper)."""
    from ..settings import generate_settings

    out = {s.name: _setting_value(s, options, options.get("paper", False)) for s in generate_settings()}
    for s in generate_settings():
        options.pop(s.name, None)
    return out


def given_options(ctx, names):
    """The option flags of ``names`` that were typed on the command line."""
    from click.core import ParameterSource

    out = []
    for param in ctx.command.params:
        if param.name in names and ctx.get_parameter_source(param.name) == ParameterSource.COMMANDLINE:
            out.append(param.opts[0] if param.opts else param.name)
    return out
