"""The ``tghop`` command line: synth, fit, patches, info, evaluate, baseline.

Every command reports bad input as one line on stderr and a non-zero exit status, never
a traceback, and never leaves a half-written output file. Progress bars go to stderr.
"""

from __future__ import annotations

import gc
import os
import signal
import sys


from . import _AS_COMMAND, _interrupted_while_starting  # noqa: E402  (installed by tghop/__init__ as `tghop`)

# OpenBLAS's worker threads spin for up to 2**28 cycles between calls before they sleep. When
# other programs keep the cores busy, that spinning takes the CPU from the thread with the
# work: on 2 cores with one other busy program, a 256x256 image took 1.7 s with the default
# and 1.1 s with a short spin (2**4 cycles); on a quiet machine both are the same
# (benchmarks/bench_cli.py). Only for the command, and only when NumPy is not loaded yet
# and the user has not chosen: a program that imports tghop keeps its own settings.
if "numpy" not in sys.modules:
    os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")

import json  # noqa: E402
import re  # noqa: E402
import warnings  # noqa: E402
from contextlib import contextmanager
from pathlib import Path

import click

from . import __version__
from ._errors import TGHopError

# Heavy modules (NumPy's linear algebra users, Pillow, scikit-learn, SciPy) are imported
# inside the commands that need them: --help, --version and `info` answer at once, and
# generating from a saved model never imports scikit-learn or SciPy.

#: Largest accepted --count.
MAX_COUNT = 1000

DOWNSCALE_HELP = ("Exemplars over 64 Mpx (8192x8192) are refused; with --downscale they are reduced to "
                  "64 Mpx instead (with a warning).")


# ------------------------------------------------------------------ helpers
class Progress:
    """Renders the library's ``progress(stage, done, total)`` calls as click progress bars.

    ``show_eta`` adds the remaining time; a subclass may set ``note`` (a string) to show it
    after the bar.
    """

    def __init__(self, enabled: bool, *, show_eta: bool = False):
        self.enabled = enabled
        self.show_eta = show_eta
        self.note = None
        self.bar = None
        self.stage = None
        self.done = 0

    def __call__(self, stage, done, total):
        if not self.enabled:
            return
        if stage != self.stage:
            self.close()
            self.stage, self.done = stage, 0
            self.bar = click.progressbar(length=max(total, 1), label=f"{stage:<14}", file=sys.stderr,
                                         show_eta=self.show_eta, show_percent=True,
                                         item_show_func=None if self.note is None else lambda _: self.note)
            self.bar.__enter__()
        if done > self.done:
            self.bar.update(done - self.done, current_item=self.note)
            self.done = done

    def close(self):
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None
            self.stage = None


def freeze_objects():
    """Running as the ``tghop`` command, hand every object that exists now to the garbage
    collector's permanent generation (``gc.freeze``), so that its collections no longer
    walk them: after the command's imports (the modules' functions and tables, most of the
    objects the process will have) and before the interpreter exits, whose collections
    walked them all again (a 2048x2048 ``synth`` spent about 0.1 s exiting, 0.03 s with
    this). Not when a program runs the command line in-process: its garbage then would
    never be collected."""
    if _AS_COMMAND:
        gc.freeze()


def fail(message: str, code: int = 1):
    click.echo(f"Error: {message}", err=True)
    sys.exit(code)


@contextmanager
def user_errors(progress=None):
    """Turn library errors into one line on stderr; show warnings as one line each."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield
        except TGHopError as exc:
            if progress:
                progress.close()
            fail(str(exc))
        except MemoryError:
            if progress:
                progress.close()
            fail("out of memory; use a smaller output size, pool or exemplar")
        except OSError as exc:  # a file system error the checks above did not foresee
            if progress:
                progress.close()
            where = f"{str(exc.filename)[:80]}: " if exc.filename else ""
            fail(f"{where}{exc.strerror or exc}")
        except KeyboardInterrupt:
            if progress:
                progress.close()
            fail("interrupted", 130)
        finally:
            if progress:
                progress.close()
            for w in caught:
                if issubclass(w.category, (UserWarning, RuntimeWarning)):
                    click.echo(f"Warning: {w.message}", err=True)


class ChannelRule(click.ParamType):
    """An int count, a fraction in (0, 1], or 'knee'."""

    name = "COUNT|FRACTION|knee"

    def convert(self, value, param, ctx):
        if isinstance(value, (int, float)) or value is None:
            return value
        text = str(value).strip().lower()
        if text == "knee":
            return "knee"
        try:
            number = int(text)
            if number < 1:
                self.fail(f"{value!r} must be at least 1 (or a fraction in (0, 1], or 'knee')", param, ctx)
            return number
        except ValueError:
            pass
        try:
            frac = float(text)
        except ValueError:
            self.fail(f"{value!r} is not a channel count, a fraction in (0, 1] or 'knee'", param, ctx)
        if not 0 < frac <= 1:
            self.fail(f"{value!r}: a fraction must lie in (0, 1]", param, ctx)
        return frac


class Size(click.ParamType):
    """``HxW`` or a single number for a square."""

    name = "HxW"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        m = re.fullmatch(r"\s*(-?\d+)\s*(?:[xX*,]\s*(-?\d+)\s*)?", str(value))
        if not m:
            self.fail(f"{value!r} is not a size; write HEIGHTxWIDTH, e.g. 512x512", param, ctx)
        h = int(m.group(1))
        w = int(m.group(2)) if m.group(2) else h
        if h < 1 or w < 1:
            self.fail(f"{value!r}: height and width must be positive", param, ctx)
        return (h, w)


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
        return out


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
                            help=f"Seed of fitting (K-means, FastICA). [default: 0]")
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
    from .settings import fit_settings

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
FIT_OPTION_PARAMS = ("k1", "k2", "k3", "paper")


def model_options(func):
    """The fitting options shared by ``fit`` and ``synth``, from the settings table."""
    for option in reversed(_fit_options()):
        func = option(func)
    return func


def generation_options(func):
    """The generation options of ``synth``, from the settings table."""
    from .settings import generate_settings

    for s in reversed(generate_settings()):
        func = _setting_option(s)(func)
    return func


def build_model(options, n_colours=3):
    """A TGHop from the fit options (unset ones: the table's default, or its paper value with --paper)."""
    from .settings import fit_settings
    from .synthesis import TGHop, default_channels

    paper = options.get("paper", False)
    params = {}
    for s in fit_settings():
        if s.name in ("n_channels", "rng"):
            continue
        value = options.get(s.name)
        params[s.name] = value if value is not None else (s.paper if paper and s.has_paper else s.default)
    patch_size = int(params["patch_size"])
    if patch_size not in (32, 64) and any(options.get(k) is None for k in ("k1", "k2")):
        raise TGHopError(f"--patch-size {patch_size} needs --k1 and --k2 (defaults exist for 32 and 64)")
    k1, k2, k3 = options.get("k1"), options.get("k2"), options.get("k3")
    if patch_size == 32 and k3 is not None:
        raise TGHopError("--k3 applies to --patch-size 64 only (three hops)")
    defaults = default_channels(patch_size, n_colours) if patch_size in (32, 64) else (None, None)
    given = [k1, k2, k3][: len(defaults)]
    channels = tuple(d if g is None else g for g, d in zip(given, defaults))
    rng = options.get("rng")
    return TGHop(**params, n_channels=channels, rng=0 if rng is None else rng)


def given_options(ctx, names):
    """The option flags of ``names`` that were typed on the command line."""
    from click.core import ParameterSource

    out = []
    for param in ctx.command.params:
        if param.name in names and ctx.get_parameter_source(param.name) == ParameterSource.COMMANDLINE:
            out.append(param.opts[0] if param.opts else param.name)
    return out


def load_exemplar(spec: str, *, downscale=False, dtype="float64"):
    """An image file, or ``builtin:NAME`` for a built-in exemplar."""
    from .data import builtin
    from .imageio import load_image

    if spec.startswith("builtin:"):
        return builtin(spec.split(":", 1)[1])
    if is_model_file(spec):
        raise TGHopError(f"{spec} is a model file, not an image; this command needs an image")
    return load_image(spec, downscale=downscale, dtype=dtype)


def is_model_file(path: str) -> bool:
    """True if ``path`` starts like a zip archive (an ``.npz``), which only a model can be
    here; a truncated model file still counts (and is then reported as truncated)."""
    p = Path(path)
    try:
        with open(p, "rb") as fh:
            return fh.read(4) in (b"PK\x03\x04", b"PK\x05\x06")
    except OSError:
        return False


def summary(model, params=None) -> str:
    """Dimensions, core model and parameter total of a fitted model (``params``: its
    :meth:`~tghop.TGHop.n_parameters`, when the caller already has it)."""
    d = model.dims_
    params = model.n_parameters() if params is None else params
    dims = " -> ".join(f"D{i}={d[f'D{i}']}" for i in range(len(model.channels_) + 1))
    ks = ", ".join(f"K{i + 1}={k}" for i, k in enumerate(model.channels_))
    return (
        f"dimensions: {dims}, D_r={d['D_r']}  ({ks})\n"
        f"core model: N={d['N']} clusters, F={d['F']} CDFs, W={d['W']} codewords\n"
        f"parameters: {params['total']['stored']:,} stored ({params['total']['paper']:,} by the paper's formulas)"
    )


def check_output(path: str, allow_stdout=False):
    from .imageio import check_output_path, output_format

    if path == "-" and not allow_stdout:
        raise TGHopError("this command cannot write to stdout; give a file name with -o")
    output_format(path)
    if path != "-":
        check_output_path(path)


# ------------------------------------------------------------------ commands
#: The modules each command imports when it runs (besides those of the command line).
_COMMAND_MODULES = {
    "synth": ("numpy", "threadpoolctl", "tghop.imageio", "tghop.modelfile", "tghop.synthesis"),
    "fit": ("numpy", "threadpoolctl", "tghop.imageio", "tghop.modelfile", "tghop.synthesis"),
    "patches": ("numpy", "tghop.imageio", "tghop.modelfile", "tghop.patches"),
    "info": ("numpy", "tghop.modelfile"),
}


def _import_for(args):
    """Import what the command named in ``args`` will import (nothing for ``--help``)."""
    import importlib

    words = [a for a in args if isinstance(a, str)]
    if any(a in ("-h", "--help", "--version") for a in words):
        return
    command = next((a for a in words if not a.startswith("-")), None)
    for name in _COMMAND_MODULES.get(command, ()):
        try:
            importlib.import_module(name)
        except ImportError:  # reported where the command needs it
            pass


class OneLineGroup(click.Group):
    """Every failure of the command line, click's usage errors and Ctrl-C included, is one
    line on stderr (``Error: ...``) and a non-zero exit status, never a traceback."""

    def main(self, args=None, prog_name=None, **extra):
        try:
            if signal.getsignal(signal.SIGINT) is _interrupted_while_starting:
                # Still under the start-up handler (one line, exit 130): the modules the
                # command will import. Python loses a KeyboardInterrupt that arrives at the
                # end of an import ("Exception ignored in ... _get_module_lock"), and the
                # command would then go on as if nothing had happened.
                _import_for(sys.argv[1:] if args is None else list(args))
                freeze_objects()  # what they made: the collections during the run need not walk it
                signal.signal(signal.SIGINT, signal.default_int_handler)
            rc = super().main(args=args, prog_name=prog_name, standalone_mode=False, **extra)
        except click.exceptions.Abort:  # Ctrl-C or EOF inside click
            fail("interrupted", 130)
        except click.UsageError as exc:
            command = exc.ctx.command_path if exc.ctx is not None else "tghop"
            fail(f"{exc.format_message()} (see '{command} --help')", exc.exit_code)
        except click.ClickException as exc:
            fail(exc.format_message(), exc.exit_code)
        except KeyboardInterrupt:
            fail("interrupted", 130)
        except BrokenPipeError:  # e.g. `tghop synth ... -o - | head -c 10`
            sys.exit(1)
        finally:
            freeze_objects()  # nothing left for the collections at exit to walk
        sys.exit(rc if isinstance(rc, int) else 0)


@click.group(cls=OneLineGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="tghop")
def main():
    """tghop: explainable, fast texture synthesis from one exemplar (TGHop).

    \b
    Quick start:
      tghop synth builtin:bricks -o bricks.png --size 512x512
      tghop synth my_texture.jpg -o out.png --count 4 --seed 7 --tile
    """


@main.command()
@click.argument("exemplar")
@click.option("-o", "--output", required=True, help="Model file to write (any name, e.g. model.npz).")
@model_options
@click.option("--downscale", is_flag=True, help=DOWNSCALE_HELP)
@click.option("-q", "--quiet", is_flag=True, help="No progress bars.")
def fit(exemplar, output, downscale, quiet, **options):
    """Learn a model from EXEMPLAR (an image file or builtin:NAME) and save it."""
    progress = Progress(not quiet)
    with user_errors(progress):
        from ._common import ModelFileError
        from .imageio import check_output_path
        from .modelfile import save_model
        from .synthesis import prepare_exemplar

        check_output_path(output, what="model", error=ModelFileError)  # before any work
        image = prepare_exemplar(load_exemplar(exemplar, downscale=downscale, dtype=None),
                                 min_size=options.get("patch_size") or 32)
        model = build_model(options, n_colours=image.shape[2])
        model.fit(image, progress=progress)
        progress.close()
        save_model(model, output)
    click.echo(summary(model), err=True)
    click.echo(f"model written to {output}", err=True)


@main.command()
@click.argument("model_file", metavar="MODEL")
@click.option("-n", "--count", "n", type=click.IntRange(min=1, max=10000), default=64, show_default=True,
              help="Patches to generate.")
@click.option("-o", "--output", required=True, help="Grid image to write (.png or .jpg; - for stdout).")
@click.option("--seed", type=click.IntRange(min=0), default=None, help="Seed (same seed, same patches).")
@click.option("--stages", is_flag=True,
              help="Also write OUTPUT_stages: per sample the core DC map, the S1 DC map and the patch (paper Fig. 6).")
def patches(model_file, n, output, seed, stages):
    """Generate N patches from a saved MODEL and write them as a grid image."""
    from .imageio import save_image
    from .modelfile import load_model
    from .patches import patch_grid

    with user_errors():
        check_output(output, allow_stdout=not stages)
        model = load_model(model_file)
        if stages:
            samples, views = model.sample_patches(n, rng=seed, return_stages=True)
        else:
            samples = model.sample_patches(n, rng=seed)
        save_image(patch_grid(samples), output)
        if stages:
            path = Path(output)
            stage_path = path.with_name(f"{path.stem}_stages{path.suffix}")
            save_image(stage_sheet(views, model.patch_size), stage_path)
            click.echo(f"stage views written to {stage_path}", err=True)
    if output != "-":
        click.echo(f"{n} patches written to {output}", err=True)


def stage_sheet(views, patch_size):
    """One row per sample: each DC map (grey, enlarged to the patch size) then the patch."""
    import numpy as np

    from .patches import patch_grid

    columns = []
    for name, maps in views.items():
        if name == "S0":
            columns.append(maps)
            continue
        scale = patch_size // maps.shape[1]
        big = np.repeat(np.repeat(maps, scale, axis=1), scale, axis=2)
        grey = np.clip(big, 0.0, 1.0)[..., None]
        columns.append(np.repeat(grey, views["S0"].shape[3], axis=3))
    rows = np.stack(columns, axis=1).reshape((-1,) + views["S0"].shape[1:])
    return patch_grid(rows, n_cols=len(columns))


@main.command()
@click.argument("source")
@click.option("-o", "--output", required=True,
              help="Image to write (.png/.jpg); with --count > 1 numbered name_1.png, ...; - writes PNG to stdout.")
@click.option("--size", type=Size(), default="256x256", show_default=True,
              help="Output HEIGHTxWIDTH, height first (1024x768 is 768 pixels wide), or one number for a square. "
                   "At most 8192x8192. Cost on 2 cores: about 0.5 s and 0.2 GB at 256x256, 3.5 s and 0.6 GB "
                   "at 2048x2048, 1.2 minutes and 4.0 GB at 8192x8192.")
@click.option("--count", type=click.IntRange(min=1, max=MAX_COUNT), default=1, show_default=True,
              help="Number of images.")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed of generation: the same seed gives the same image; without it every run differs.")
@click.option("--save-model", type=click.Path(dir_okay=False), default=None,
              help="When SOURCE is an image, also save the fitted model here.")
@generation_options
@model_options
@click.option("--downscale", is_flag=True, help=DOWNSCALE_HELP)
@click.option("-q", "--quiet", is_flag=True, help="No progress bars.")
@click.pass_context
def synth(ctx, source, output, size, count, seed, save_model, downscale, quiet, **options):
    """Synthesize texture images from SOURCE: an exemplar image, builtin:NAME, or a saved model."""
    from ._common import ModelFileError
    from .imageio import check_output_path, save_image
    from .modelfile import load_model, save_model as write_model
    from .quilting import MAX_PIXELS
    from .settings import BY_NAME, generate_settings
    from .synthesis import prepare_exemplar

    progress = Progress(not quiet)
    with user_errors(progress):
        check_output(output, allow_stdout=True)
        if output == "-" and count > 1:
            raise TGHopError("--count > 1 cannot write to stdout; give a file name with -o")
        if size[0] * size[1] > MAX_PIXELS:
            raise TGHopError(f"--size {size[0]}x{size[1]} exceeds the limit of {MAX_PIXELS:,} pixels; choose a smaller size")
        from_model = not source.startswith("builtin:") and is_model_file(source)
        if from_model:
            fit_only = ([s.name for s in BY_NAME.values() if s.when == "fit"] + list(FIT_OPTION_PARAMS)
                        + ["save_model", "downscale"])
            refused = given_options(ctx, fit_only)
            if refused:
                raise TGHopError(f"{', '.join(refused)}: fitting option{'s' if len(refused) > 1 else ''} but SOURCE "
                                 f"is a saved model; refit with 'tghop fit' or drop {'them' if len(refused) > 1 else 'it'}")
        generation = {}
        for s in generate_settings():
            value = options.pop(s.name)
            generation[s.name] = value if value is not None else (
                s.paper if options.get("paper") and s.has_paper else s.default)
        if save_model and not from_model:
            check_output_path(save_model, what="model", error=ModelFileError)  # before the fit
        if from_model:
            model = load_model(source)
        else:
            image = prepare_exemplar(load_exemplar(source, downscale=downscale, dtype=None),
                                     min_size=options.get("patch_size") or 32)
            model = build_model(options, n_colours=image.shape[2])
            model.fit(image, progress=progress)
            if save_model:
                write_model(model, save_model)
        import numpy as np

        rng = np.random.default_rng(seed)
        outputs = [output] if count == 1 else numbered(output, count)
        for path in outputs:
            # 8-bit straight from the colour matching: no float64 image (1.6 GB at 8192x8192).
            image = model.synthesize(size, rng=rng, progress=progress, dtype=np.uint8, **generation)
            progress.close()
            save_image(image, path)
    if output != "-":
        where = outputs[0] if count == 1 else f"{outputs[0]} ... {outputs[-1]}"
        click.echo(f"{count} image{'s' if count > 1 else ''} of {size[0]}x{size[1]} written to {where}", err=True)
        if save_model and not from_model:
            click.echo(f"model written to {save_model}", err=True)


def numbered(path: str, count: int):
    p = Path(path)
    width = len(str(count))
    return [str(p.with_name(f"{p.stem}_{i:0{width}d}{p.suffix}")) for i in range(1, count + 1)]


@main.command()
@click.argument("model_file", metavar="MODEL")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def info(model_file, as_json):
    """Describe a saved MODEL: settings, dimensions and parameter count (paper Table 4)."""
    from .modelfile import load_model

    with user_errors():
        model = load_model(model_file)
        params = model.n_parameters()
    if as_json:
        click.echo(json.dumps({"params": {k: v for k, v in model.get_params().items() if k != "rng"},
                               "dims": model.dims_, "channels": model.channels_,
                               "exemplar_shape": list(model.exemplar_shape_),
                               "n_parameters": params}, indent=2, default=str, allow_nan=False))
        return
    h, w, c = model.exemplar_shape_
    click.echo(f"tghop model {model_file}")
    click.echo(f"exemplar: {h}x{w}, {c} channel{'s' if c > 1 else ''}; {model.n_patches_:,} training patches "
               f"of {model.patch_size}x{model.patch_size} at stride {model.stride}")
    click.echo(summary(model, params))
    click.echo("\nparameters (paper Table 4):")
    rows = [("module", "formula", "paper formula", "stored")] + [
        (name, row["formula"], f"{row['paper']:,}", f"{row['stored']:,}") for name, row in params.items()]
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    for r in rows:
        click.echo(f"  {r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]:>{widths[2]}}  {r[3]:>{widths[3]}}")


@main.command()
@click.argument("exemplar")
@click.argument("results", nargs=-1, required=True)
@click.option("--json", "as_json", is_flag=True, help="One JSON object per result (JSON lines).")
@click.option("--metrics", "names", default=None,
              help="Comma-separated subset of: sifid, gram, swd, cooccurrence, novelty, copied (default all).")
def evaluate(exemplar, results, as_json, names):
    """Score RESULT images against EXEMPLAR with texture metrics (lower is better but novelty).

    copied: the fraction of 16x16 result patches nearly equal to an exemplar patch (0: all new).

    With two or more results, also their diversity (higher: more different from each other).
    SIFID and the Gram distance need the metrics extra: pip install 'tghop[metrics]'.
    """
    from . import metrics as M

    with user_errors():
        chosen = None if names is None else [n.strip() for n in names.split(",") if n.strip()]
        ex = load_exemplar(exemplar)
        images = [load_exemplar(r) for r in results]
        rows = [(path, M.evaluate(ex, img, metrics=chosen)) for path, img in zip(results, images)]
        div = M.diversity(*images) if len(images) > 1 else None
    skipped = rows[0][1].skipped if rows else {}
    if as_json:
        for path, scores in rows:
            click.echo(json.dumps({"exemplar": exemplar, "result": path, **scores}))
        if div is not None:
            click.echo(json.dumps({"exemplar": exemplar, "results": list(results), "diversity": div}))
    else:
        cols = list(rows[0][1])
        width = max(len("result"), *(len(p) for p, _ in rows))
        click.echo(f"{'result':<{width}}" + "".join(f"{c:>14}" for c in cols))
        for path, scores in rows:
            click.echo(f"{path:<{width}}" + "".join(f"{scores[c]:>14.4g}" for c in cols))
        if div is not None:
            click.echo(f"diversity of the {len(images)} results: {div:.4g}")
    for name, why in skipped.items():
        click.echo(f"Note: {name} skipped: {why}", err=True)


@main.command()
@click.argument("name", type=click.Choice(["crop", "blurred-crop", "colour-noise", "quilting", "ustyuzhaninov", "cooc"]))
@click.argument("exemplar")
@click.option("-o", "--output", required=True, help="Image to write (.png/.jpg; - for PNG on stdout).")
@click.option("--size", type=Size(), default=None, help="Output HEIGHTxWIDTH (default: the exemplar's).")
@click.option("--seed", type=click.IntRange(min=0), default=None)
@click.option("--iterations", type=click.IntRange(min=1), default=None,
              help="ustyuzhaninov: L-BFGS iterations (default 500; the paper used 2000). "
                   "cooc: training steps (default 5500).")
@click.option("--model", "model_file", default=None,
              help="cooc: a checkpoint from 'tghop cooc train' to generate from instead of training.")
@click.option("--assembly", type=click.Choice(["quilt", "pass", "windows"]), default=None,
              help="cooc: how the image is made from the generator: quilt (default: generated training-size "
                   "crops stitched by image quilting), pass (the paper's: one pass over the whole condition), "
                   "windows (that condition in training-size windows).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bars.")
def baseline(name, exemplar, output, size, seed, iterations, model_file, assembly, quiet):
    """Make a reference texture from EXEMPLAR with baseline NAME.

    \b
    crop           a random crop of the exemplar (best case)
    blurred-crop   a blurred crop
    colour-noise   noise with the exemplar's colour mean and covariance (worst case)
    quilting       classic image quilting of the exemplar's own patches
    ustyuzhaninov  single-layer random CNN, Gram loss, L-BFGS (needs the metrics extra)
    cooc           co-occurrence cGAN (Darzi et al.): trains ~15 min on 2 cores, or --model (metrics extra)
    """
    from .baselines import BASELINES
    from .imageio import save_image

    progress = Progress(not quiet)
    with user_errors(progress):
        check_output(output, allow_stdout=True)
        if iterations is not None and name not in ("ustyuzhaninov", "cooc"):
            raise TGHopError("--iterations applies to the ustyuzhaninov and cooc baselines only")
        for option, value in (("--model", model_file), ("--assembly", assembly)):
            if value is not None and name != "cooc":
                raise TGHopError(f"{option} applies to the cooc baseline only")
        ex = load_exemplar(exemplar)
        kwargs = {"n_iter": iterations} if iterations is not None else {}
        if name == "cooc":
            from .cooc import load

            kwargs = {"n_steps": iterations, "model": None if model_file is None else load(model_file),
                      "assembly": assembly or "quilt"}
        image = BASELINES[name](ex, size, rng=seed, progress=progress, **kwargs)
        progress.close()
        save_image(image, output)
    if output != "-":
        click.echo(f"{name} result written to {output}", err=True)


from .cli_cooc import cooc as _cooc_commands  # noqa: E402  (needs the helpers above; imports no torch)

main.add_command(_cooc_commands)

if __name__ == "__main__":  # pragma: no cover
    main()
