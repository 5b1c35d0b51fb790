"""Command-line options made from the settings table (:data:`tghop.settings.SETTINGS`)
and the parameter types of the ``tghop`` command line (sizes, channel rules, float
ranges that refuse NaN).

Each value is checked by the library's own check (:func:`tghop._images.check_size`,
:func:`tghop.settings.check_channel_rule`, :meth:`tghop.settings.Setting.check`), so
the command line and the library refuse the same values with the same words.
"""

from __future__ import annotations

import math
import os
import re

import click

from .._errors import TGHopError
from ..fit_options import OFF, setting_value

__all__ = ["MAX_COUNT", "DOWNSCALE_HELP", "EXCLUDE_HELP", "QUIET_OPTION", "depth_option", "ChannelRule", "Size",
           "FloatRange", "SettingType", "model_options", "generation_options", "FIT_OPTION_PARAMS", "generation_params",
           "given_options", "refuse_split_size"]

#: Largest accepted --count.
MAX_COUNT = 1000

EXCLUDE_HELP = ("A mask image of the exemplar's size: its white parts (a logo, a label, a stain) are not learnt "
                "(training patches touching them are dropped; colour and band statistics leave them out).")

DOWNSCALE_HELP = ("Exemplars over 64 Mpx (8192x8192) are refused; with --downscale they are reduced to "
                  "64 Mpx instead (with a warning).")

#: ``-q/--quiet`` of every command that writes files: no progress bars. Those that draw none
#: (patches, cooc morph, cooc edit) take it too, so that a script can pass it to any of them.
QUIET_OPTION = click.option("-q", "--quiet", is_flag=True, help="No progress bars.")


def depth_option(default: str):
    """``--depth 8|16|32``: bits per channel of the images written (32: float TIFF);
    ``default`` says what is written without it."""
    return click.option("--depth", type=click.Choice(["8", "16", "32"]), default=None,
                        callback=lambda ctx, param, value: None if value is None else int(value),
                        help="Bits per channel of the images written: 8, 16 (PNG, TIFF) or 32 (float TIFF). "
                             f"[default: {default}]")


def scale_option(help: str):
    """``--scale S`` outside ``fit`` and ``synth`` (whose ``--scale`` is the setting's own): the
    working scale (:mod:`tghop.scale`), in the settings table's range, default 1."""
    from ..settings import BY_NAME

    setting = BY_NAME["scale"]
    return click.option("--scale", type=SettingType(setting), default=setting.default, show_default=True, help=help)


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


class FloatRange(click.FloatRange):
    """:class:`click.FloatRange` that also refuses NaN (which fails no comparison, so click's
    range lets it through): "nan is not a number; give one in the range"."""

    def convert(self, value, param, ctx):
        rv = super().convert(value, param, ctx)
        if math.isnan(rv):
            self.fail(f"{value!r} is not a number; give a number in the option's range", param, ctx)
        return rv


class Size(click.ParamType):
    """``HxW`` or a single number for a square, at most :data:`tghop._images.MAX_PIXELS`
    pixels (:func:`tghop._images.check_size`)."""

    name = "HxW"

    def convert(self, value, param, ctx):
        from .._images import check_size
        from ..manifest import split_size

        if isinstance(value, tuple):
            return value
        pair = split_size(value, signed=True)  # a negative one is told the range
        if pair is None:
            self.fail(f"{value!r} is not a size; write HEIGHTxWIDTH, e.g. 512x512", param, ctx)
        h, w = pair
        try:
            return check_size((h, w), name="the size")  # click names the option before it
        except TGHopError as exc:
            self.fail(str(exc), param, ctx)


class SettingType(click.ParamType):
    """A command-line value of one setting of :data:`tghop.settings.SETTINGS`."""

    def __init__(self, setting):
        import dataclasses

        # Checked against the command line's own bound where it has one (its message then
        # states the range the option takes, not the library's wider one).
        self.setting = setting if setting.cli_high is None else dataclasses.replace(setting, high=setting.cli_high)
        self.name = setting.kind.upper()

    def get_metavar(self, param, ctx=None):
        """A choice's values, as click.Choice shows them (``[absolute|relative]``); else the kind."""
        return "[" + "|".join(self.setting.choices) + "]" if self.setting.kind == "choice" else None

    def convert(self, value, param, ctx):
        if not isinstance(value, str):
            return value
        s = self.setting
        try:
            out = s.check(s.parse(value), label=repr(value), cli=True)
        except TGHopError as exc:
            self.fail(str(exc), param, ctx)
        return OFF if out is None else out


def _plain(text: str) -> str:
    """The table's help text without its reStructuredText roles and literals (for ``--help``)."""
    return re.sub(r"``([^`]+)``", r"\1", re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text))


def _shown(s, value):
    """``value`` of setting ``s`` as the command line writes it: on / off, auto / none, else the value."""
    # By kind, not by value: 1.0 == True and 0.0 == False as dictionary keys.
    if isinstance(value, bool):
        return {True: "on", False: "off"}[value]
    return ("auto" if s.auto else "none") if value is None else value


def _setting_option(s):
    """A click option for setting ``s``, its help and default taken from the table."""
    names = list(s.option_names)
    help_text = _plain(s.help).replace("None: ", f"{_shown(s, None)}: ")  # the word the option takes for None
    extra = f"default: {_shown(s, s.default)}"
    if s.kind == "rng":
        return click.option(*names, "rng", type=click.IntRange(min=0), default=None,
                            help="Seed of fitting (K-means, FastICA). [default: 0]")
    if s.has_paper and s.paper != s.default:
        extra += f"; --paper: {_shown(s, s.paper)}"
    if s.kind == "float" and s.low is not None and s.high is not None and s.high <= 1:  # a fraction: its range
        extra += f"; {s.low:g}{'<' if s.low_open else '<='}x{'<' if s.high_open else '<='}{s.high:g}"
    if s.kind == "bool":
        flag = names[0]
        return click.option(f"{flag}/--no-{flag[2:]}", s.name, default=None, help=f"{help_text} [{extra}]")
    return click.option(*names, s.name, type=SettingType(s), default=None, help=f"{help_text} [{extra}]")


def _channel_options():
    return [
        click.option("--k1", type=ChannelRule(), default=None,
                     help="Hop-1 channels (paper: 9): count, energy fraction or 'knee'. " + _channels_default(0)),
        click.option("--k2", type=ChannelRule(), default=None,
                     help="Hop-2 channels in total (paper: 22). " + _channels_default(1)),
        click.option("--k3", type=ChannelRule(), default=None,
                     help="Hop-3 channels (64x64 patches only; paper: 63). " + _channels_default(2)),
    ]


def _channels_default(hop):
    """The default of ``--k<hop + 1>`` in words: tghop.synthesis.default_channels's counts (not imported here,
    which would load the library for ``--help``; a test holds the two alike)."""
    colour, grey = (9, 22, 63)[hop], (4, 10, 28)[hop]
    return f"[default: {colour}; grey exemplars {grey}; a material of C channels {colour} x C / 3, rounded up]"


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
                                     "colour matching; options given as well override it. With a saved model: "
                                     "the paper's generation settings. Its sampling step (iv), a rejection "
                                     "threshold it does not give, stays off: --reject-threshold T sets one."))
    return options


#: Options of ``fit`` that only matter when fitting (refused by ``synth`` with a saved model;
#: not ``--paper``, which also sets the paper's generation settings).
FIT_OPTION_PARAMS = ("k1", "k2", "k3", "exclude")


def model_options(func):
    """The fitting options shared by ``fit`` and ``synth``, from the settings table."""
    for option in reversed(_fit_options()):
        func = option(func)
    return func


def generation_options(func):
    """The generation options of ``synth``, from the settings table, and ``--quality``."""
    from ..settings import QUALITY, generate_settings

    for s in reversed(generate_settings()):
        func = _setting_option(s)(func)
    return click.option(
        "--quality", type=click.Choice(sorted(QUALITY)), default=None,
        help="Preset: 'best' refines patches harder (--patch-refine 90 --patch-stride 1, at any size: "
             "sharper grain, about 1.5 s more per 256x256 image (0.51); models fitted with --patch-levels, the "
             "default). Options given as well override it. [default: default]")(func)


def generation_params(options):
    """The keywords of ``TGHop.synthesize`` from the generation options (popped from
    ``options``; unset ones: the table's default, or its paper value with --paper)."""
    from ..settings import QUALITY, generate_settings

    preset = QUALITY[options.pop("quality", None) or "default"]
    out = {}
    for s in generate_settings():
        given = options.get(s.name) is not None
        out[s.name] = preset[s.name] if s.name in preset and not given else \
            setting_value(s, options, options.get("paper", False))
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


def refuse_split_size(ctx, values):
    """The second number of ``--size 512 512``, which click takes for one more SOURCE (or MAP), refused as the usage
    error it is, naming --size's form (exit status 2 before any work, 0.63; 0.62 said the same with status 1 when the
    number was read as a file): a number among ``values`` that is no file, with --size typed."""
    if ctx is None or not given_options(ctx, ["size"]):
        return
    for value in values:
        name = os.fspath(value)
        if re.fullmatch(r"\d+", name) and not os.path.lexists(name):
            raise click.UsageError(split_size_message(name))


def split_size_message(name):
    """What a number ``name`` taken for a file most likely is: the second of ``--size 512 512``."""
    return f"{name}: no such file; --size takes one value, HEIGHTxWIDTH (--size 512x1024: 1024 wide), or one number " \
           "for a square"


def refuse_patch_refine_without_statistics(ctx, generation, planned):
    """Refuse, before any fit, a patch refinement asked for (``--patch-refine N`` or ``--quality
    best``: ``generation["patch_refine"]``) from a fit that stores no patch statistics
    (``planned``: the unfitted model the fit options make; --paper's or --patch-levels 0), in the
    options typed (the library's error came after the fit, in its keywords)."""
    from ..settings import BY_NAME

    if not generation["patch_refine"] or planned.patch_levels:
        return
    asked = (f"--patch-refine {generation['patch_refine']}" if given_options(ctx, ["patch_refine"])
             else "--quality best")
    why = "--patch-levels 0" if given_options(ctx, ["patch_levels"]) else "--paper (its --patch-levels 0)"
    raise click.UsageError(f"{asked} needs the patch statistics that {why} leaves out of the fit; give "
                           f"--patch-levels {BY_NAME['patch_levels'].default} as well, or drop {asked}")


def refuse_patch_refine_of_saved(ctx, what: str, material: bool):
    """Refuse a patch refinement asked for (``--patch-refine``, ``--quality best``, ``--patch-stride``: the
    options typed) of a saved model without patch statistics (``what``: how it is named, "this model", "SOURCE 2
    (old.npz)"): a usage error of those options with this model, one wording and exit status 2 for a texture
    and a material alike (0.62; 0.61 exited 1 for a texture, in other words)."""
    typed = (["--quality best"] if ctx.params.get("quality") == "best" else []) + given_options(
        ctx, ["patch_refine", "patch_stride"])
    typed = typed or ["--patch-refine"]
    several = len(typed) > 1
    older = "0.58" if material else "0.14"
    raise click.UsageError(f"{' and '.join(typed)} {'do' if several else 'does'} not apply to {what} (it has no "
                           f"patch statistics: fitted by tghop {older} or older, or with --patch-levels 0); fit it "
                           f"again, or drop {'them' if several else 'it'}")
