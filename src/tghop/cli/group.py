"""The ``tghop`` command group: every command of the command line, and how it fails (click's usage
errors, exit status 2, here; a library error in a command, exit status 1: :func:`tghop.cli.common.user_errors`).

Every command reports bad input as one line on stderr and a non-zero exit status, never
a traceback, and never leaves a half-written output file. Progress bars go to stderr.

Running as the ``tghop`` command (:func:`tghop.__main__.run`, the console script and
``python -m tghop``) adds what only the command may do to its process: see
:meth:`OneLineGroup.main` with ``as_command=True``.
"""

from __future__ import annotations

import gc
import signal
import sys
import threading
from contextlib import contextmanager

import click

from .. import __version__
from .common import Terminated, drop_stdout, fail, os_error_message, output_gone, stop_message

__all__ = ["OneLineGroup", "main", "after_a_stop"]

#: Each command of ``tghop`` and the module of :mod:`tghop.cli` that defines it, imported
#: when the command is run or listed (:class:`OneLineGroup` ``lazy_commands``): ``tghop
#: synth`` does not build the options of ``batch``, ``evaluate``, ``cooc`` and the others.
#: In this order ``tghop --help`` lists them: making textures, then editing images, many at once or in a
#: browser, and last the tools that study and compare.
_COMMANDS = {"synth": "texture", "fit": "texture", "info": "texture", "patches": "texture",
             "inpaint": "inpaint", "extend": "inpaint", "morph": "guided", "batch": "batch", "serve": "serve",
             "evaluate": "evaluation", "clusters": "texture", "baseline": "evaluation", "cooc": "cooc"}

#: The modules each command imports when it runs (besides those of the command line).
_COMMAND_MODULES = {
    "synth": ("numpy", "threadpoolctl", "tghop.imageio", "tghop.modelfile", "tghop.synthesis"),
    "fit": ("numpy", "threadpoolctl", "tghop.imageio", "tghop.modelfile", "tghop.synthesis"),
    "patches": ("numpy", "tghop.imageio", "tghop.modelfile", "tghop.patches"),
    "clusters": ("numpy", "tghop.imageio", "tghop.modelfile", "tghop.synthesis", "tghop.explain"),
    "info": ("numpy", "tghop.modelfile"),
    "inpaint": ("numpy", "threadpoolctl", "tghop.imageio", "tghop.modelfile", "tghop.synthesis", "tghop.inpaint"),
    "extend": ("numpy", "threadpoolctl", "tghop.imageio", "tghop.modelfile", "tghop.synthesis", "tghop.inpaint"),
    "morph": ("numpy", "threadpoolctl", "tghop.imageio", "tghop.modelfile", "tghop.synthesis", "tghop.guided"),
    "batch": ("numpy", "threadpoolctl", "tghop.imageio", "tghop.modelfile", "tghop.synthesis", "tghop.batch"),
}


#: Signals that stop the command as Ctrl-C does (with their own line and exit status).
_STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


def _interrupted(signum, frame):
    """Ctrl-C stops the command once: the Ctrl-Cs after it are ignored while the command
    cleans up and exits. (Python puts the default action back as the interpreter shuts
    down, so a Ctrl-C then would kill the process by the signal, exit status -2, after its
    ``Error: interrupted`` line; held Ctrl-C or a terminal sending several does that.)"""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    raise KeyboardInterrupt


def after_a_stop(handler):
    """The Ctrl-C handler to put back in place of ``handler`` once the command has stopped on a signal
    it caught itself (``tghop serve``): SIG_IGN where ``handler`` is the command's own
    (:func:`_interrupted`), which, having stopped the command, would ignore the Ctrl-Cs after it
    to the end of the process; ``handler`` itself in a program that runs the command line in-process."""
    return signal.SIG_IGN if handler is _interrupted else handler


def _terminated(signum, frame):
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # as in _interrupted: the command is stopping
    raise Terminated(signum)


def _redeliver_lost_stops(hook):
    """A :data:`sys.unraisablehook` that gives the command a Ctrl-C (or SIGTERM/SIGHUP) that
    Python lost: raised inside a garbage-collector callback or a ``__del__`` (Dask's
    ``GCDiagnosis`` has one), the KeyboardInterrupt is printed as "Exception ignored" with a
    traceback and dropped, and since :func:`_interrupted` ignores the Ctrl-Cs after the
    first, the command would run on to its end. The signal is sent again a moment later,
    with its handler back in place, so that it stops the command in ordinary code; other
    unraisable exceptions go to ``hook``."""

    def handle(unraisable):
        exc = unraisable.exc_value
        if isinstance(exc, KeyboardInterrupt) and threading.current_thread() is threading.main_thread():
            import os

            signum = exc.signum if isinstance(exc, Terminated) else signal.SIGINT
            signal.signal(signum, _terminated if isinstance(exc, Terminated) else _interrupted)
            # Sent from a thread a moment later: sent here, its handler would raise in this hook.
            timer = threading.Timer(0.05, os.kill, (os.getpid(), signum))
            timer.daemon = True
            timer.start()
            return
        hook(unraisable)

    return handle


def _stop_on_signals():
    """SIGTERM and SIGHUP raise :class:`~tghop.cli.common.Terminated` (a KeyboardInterrupt)
    in the command, so that they clean up as Ctrl-C does (no temporary file left) and end
    with one ``Error: terminated`` line and exit status 128 + the signal's number. A signal
    the caller set to be ignored (``nohup`` ignores SIGHUP) stays ignored."""
    for signum in _STOP_SIGNALS:
        if signal.getsignal(signum) == signal.SIG_DFL:
            signal.signal(signum, _terminated)


def _import_for(group, args):
    """Import what the command named in ``args`` will import, its own module of ``group``'s
    first (nothing for ``--help``)."""
    import importlib

    words = [a for a in args if isinstance(a, str)]
    if any(a in ("-h", "--help", "--help-all", "--version") for a in words):
        return
    command = next((a for a in words if not a.startswith("-")), None)
    if command is not None:
        group.get_command(None, command)
    for name in _COMMAND_MODULES.get(command, ()):
        try:
            importlib.import_module(name)
        except ImportError:  # reported where the command needs it
            pass


class _OutputGone(Exception):
    """A command's BrokenPipeError (its ``__cause__``), carried past click to
    :meth:`OneLineGroup.main`: click answers a broken pipe itself, with exit status 1."""


@contextmanager
def _past_click():
    try:
        yield
    except BrokenPipeError as exc:
        raise _OutputGone() from exc


def _output_gone(exc: BrokenPipeError):
    """Exit 0 without a word where the output's reader went away (``tghop info M | head -1``:
    the reader took what it wanted, as with the tools that exit quietly there), standard
    output pointed at the null device first so that the interpreter's last flush does not
    fail again ("Exception ignored"). A broken pipe that is not the output's is one line."""
    gone = output_gone()
    drop_stdout()
    if not gone:
        fail(os_error_message(exc))
    sys.exit(0)


#: click 8.2's usage error for a group called without a command, whose message is the whole help (none before 8.2,
#: which prints the help itself).
_NO_ARGS_IS_HELP = getattr(click.exceptions, "NoArgsIsHelpError", ())


class OneLineGroup(click.Group):
    """Every failure of the command line, click's usage errors and Ctrl-C included, is one
    line on stderr (``Error: ...``) and a non-zero exit status, never a traceback. A reader
    of the output that went away (``tghop info M | head -1``) is no failure: the command
    stops there, without a word, exit status 0 (:func:`~tghop.cli.common.output_gone`). ``tghop``
    (or ``tghop cooc``) without a command prints its help on stderr, as click does, exit status 2.

    ``lazy_commands``: ``{name: module}``, commands defined in those modules of
    :mod:`tghop.cli` (``"texture"``), each imported when its command is first looked up
    (run, listed in ``--help``), not when the group is made. ``synonyms``: ``{word: hint}``,
    other names of a command's task, answered with the hint (click's "Did you mean" picks by
    spelling: ``outpaint`` was sent to ``inpaint``).
    """

    def __init__(self, *args, lazy_commands=None, synonyms=None, **kwargs):
        super().__init__(*args, **kwargs)
        self.lazy_commands = dict(lazy_commands or {})
        self.synonyms = dict(synonyms or {})

    def list_commands(self, ctx):
        """The lazy commands in their order (the order of a user's work), then any others by name."""
        return [*self.lazy_commands, *sorted(set(self.commands) - set(self.lazy_commands))]

    def get_command(self, ctx, cmd_name):
        if cmd_name not in self.commands and cmd_name in self.lazy_commands:
            import importlib

            module = importlib.import_module(f"{__package__}.{self.lazy_commands[cmd_name]}")
            self.add_command(getattr(module, cmd_name), cmd_name)
        return self.commands.get(cmd_name)

    def resolve_command(self, ctx, args):
        if self.get_command(ctx, args[0]) is None and args[0].lower() in self.synonyms:
            raise click.UsageError(f"No such command {args[0]!r}; {self.synonyms[args[0].lower()]}", ctx)
        if self.get_command(ctx, args[0]) is None:  # not a command: click's "Did you mean" looks through them all
            for name in self.list_commands(ctx):
                self.get_command(ctx, name)
        return super().resolve_command(ctx, args)

    def main(self, args=None, prog_name=None, as_command=False, **extra):
        """Run the command line and exit.

        ``as_command``: this process is the ``tghop`` command (:func:`tghop.__main__.run`,
        which installed a start-up Ctrl-C handler). Then, still under that handler, the
        modules the command will import are imported (Python loses a KeyboardInterrupt
        that arrives at the end of an import, "Exception ignored in ... _get_module_lock",
        and the command would go on as if nothing had happened); then Ctrl-C, unless the
        caller set it to be ignored, raises KeyboardInterrupt once (:func:`_interrupted`:
        the first stops the command, those after it are ignored while it cleans up and
        exits; one that Python lost in a callback is sent again,
        :func:`_redeliver_lost_stops`); and the objects that exist after the imports and at
        exit are handed to the garbage collector's permanent generation (``gc.freeze``), so
        that its collections during the run and at exit do not walk them. A program that runs the command line
        in-process keeps its signal handling and its collector as they were.
        """
        try:
            if as_command:
                _import_for(self, sys.argv[1:] if args is None else list(args))
                gc.freeze()
                if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:  # `tghop ... &` in a script ignores it
                    signal.signal(signal.SIGINT, _interrupted)
                _stop_on_signals()
                sys.unraisablehook = _redeliver_lost_stops(sys.unraisablehook)
            rc = super().main(args=args, prog_name=prog_name, standalone_mode=False, **extra)
            sys.stdout.flush()  # a full disk behind `> file` shows here, not at exit
        except click.exceptions.Abort as exc:  # Ctrl-C (or SIGTERM/SIGHUP) or EOF inside click
            fail(*stop_message(exc))
        except _NO_ARGS_IS_HELP as exc:  # `tghop` or `tghop cooc` alone: its help, as click shows it (stderr, 2)
            exc.show()
            sys.exit(exc.exit_code)
        except click.UsageError as exc:
            command = (exc.ctx.command_path if exc.ctx is not None and exc.ctx.command is not self
                       else self._command_path(sys.argv[1:] if args is None else list(args)))
            message = _option_synonym(exc) or _missing_output(exc) or exc.format_message()
            fail(f"{message} (see '{command} --help')", exc.exit_code)
        except click.ClickException as exc:
            fail(exc.format_message(), exc.exit_code)
        except KeyboardInterrupt as exc:
            fail(*stop_message(exc))
        except _OutputGone as exc:  # `tghop info M | head -1`, `tghop synth ... -o - | head -c 10`
            _output_gone(exc.__cause__)
        except BrokenPipeError as exc:  # the flush above
            _output_gone(exc)
        except OSError as exc:  # printing failed (`tghop info M > /dev/full`); files fail in user_errors
            drop_stdout()
            fail(os_error_message(exc))
        finally:
            if as_command:
                gc.freeze()  # nothing left for the collections at exit to walk
        sys.exit(rc if isinstance(rc, int) else 0)

    def make_context(self, *args, **kwargs):  # `tghop --help | head -1` writes here
        with _past_click():
            return super().make_context(*args, **kwargs)

    def invoke(self, ctx):  # the commands, and their --help
        with _past_click():
            return super().invoke(ctx)

    def _command_path(self, args):
        """``tghop SUBCOMMAND ...`` as far as ``args`` name commands (click reports some usage
        errors, a missing option value, before the subcommand has a context)."""
        path, group = ["tghop"], self
        for arg in args:
            command = group.get_command(None, arg) if isinstance(group, click.Group) else None
            if command is None:
                if arg.startswith("-") or not isinstance(group, click.Group):
                    continue  # an option of the group, or the command's own arguments
                break
            path.append(arg)
            group = command
        return " ".join(path)


#: Other names of options that an artist types, with the option of a command that does it: click's "Did you
#: mean" picks by spelling (--mask was sent to --maps, --seamless to --scale, --width to --depth).
OPTION_SYNONYMS = {
    **dict.fromkeys(("--seamless", "--tileable", "--tiled", "--wrap"), ("tile", "for a seamless tile, give --tile")),
    **dict.fromkeys(("--width", "--height", "--resolution", "--res", "--dimensions"),
                    ("size", "give --size HEIGHTxWIDTH (e.g. --size 512x1024: 1024 wide), or one number for a "
                             "square")),
    **dict.fromkeys(("--bit-depth", "--bits", "--16bit", "--16-bit"), ("depth", "give --depth 16 (or 8, or 32)")),
    **dict.fromkeys(("--mask", "--hole"), ("mask", "MASK is the second argument: 'tghop inpaint IMAGE MASK -o OUT'")),
    # tghop batch's: --depth is a bit depth elsewhere (batch writes 8-bit PNGs, a material's maps at their own)
    **dict.fromkeys(("--depth", "--maxdepth", "--recursive", "--recurse", "--no-recursive", "-r", "-R"),
                    ("max_depth", "SOURCE is searched at every level of subfolders by default; to limit it, give "
                                  "--max-depth N (0: the folder's own images only)")),
}


def _option_synonym(exc):
    """The message of a usage error for an option that a command lacks but does under
    another name (:data:`OPTION_SYNONYMS`), or None."""
    name = getattr(exc, "option_name", None)
    if not isinstance(exc, click.NoSuchOption) or exc.ctx is None or name not in OPTION_SYNONYMS:
        return None
    param, hint = OPTION_SYNONYMS[name]
    if param == "mask" and exc.ctx.command.name != "inpaint":
        param, hint = "exclude", "to leave part of the exemplar out, give --exclude MASK (its white pixels)"
    if param not in {p.name for p in exc.ctx.command.params}:
        return None
    return f"No such option '{name}'; {hint}"


def _missing_output(exc):
    """The message of a usage error for a command run without its ``-o``, naming what to give
    (click's own, "Missing option '-o' / '--output'.", says nothing of what it takes), or None."""
    param = getattr(exc, "param", None)
    if not isinstance(exc, click.MissingParameter) or exc.ctx is None or "-o" not in getattr(param, "opts", ()):
        return None
    command, exemplar = exc.ctx.command.name, exc.ctx.params.get("exemplar")
    stem = str(exemplar).split(":", 1)[1] if str(exemplar).startswith("builtin:") else None
    if command == "fit":
        from pathlib import Path

        what = f"the model file to write, e.g. -o {stem or (Path(exemplar).stem if exemplar else 'texture')}.npz"
    elif command == "batch":
        what = "the folder to write the results into, e.g. -o results"
    elif command == "train":
        what = "the checkpoint to write, e.g. -o cooc.pt"
    else:
        what = "the image to write, e.g. -o out.png"
    return f"Missing option '-o': give {what}"


#: Other names of the commands' tasks that an artist types (``tghop fill``), with the command to use.
SYNONYMS = {
    **dict.fromkeys(("fill", "repair", "heal"), "to fill a hole, use 'tghop inpaint IMAGE MASK -o OUT'"),
    **dict.fromkeys(("outpaint", "grow", "expand", "enlarge"),
                    "to grow an image, use 'tghop extend IMAGE -o OUT --size HxW'"),
    **dict.fromkeys(("paint", "guide", "guided"),
                    "to paint with several textures, use 'tghop synth A B ... --guide MAP -o OUT'"),
    "remix": "to remix several textures, use 'tghop synth A B ... -o OUT'",
    **dict.fromkeys(("generate", "synthesize", "synthesise"), "to make a texture, use 'tghop synth SOURCE -o OUT'"),
    **dict.fromkeys(("train", "learn"), "to learn a model, use 'tghop fit EXEMPLAR -o MODEL.npz'"),
    **dict.fromkeys(("material", "maps"), "to learn a whole material, use 'tghop fit ALBEDO --maps MAP... -o MAT.npz'"),
}


@click.group(cls=OneLineGroup, lazy_commands=_COMMANDS, synonyms=SYNONYMS,
             context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="tghop")
def main():
    """tghop: explainable, fast texture synthesis from one exemplar (TGHop).

    \b
    Quick start (synth learns the exemplar's model, then makes the images):
      tghop synth builtin:bricks -o bricks.png --size 512x512
      tghop synth my_texture.jpg -o out.png --count 4 --seed 7 --tile
    To make many images from one exemplar, learn its model once and reuse it:
      tghop fit my_texture.jpg -o my_texture.npz
      tghop synth my_texture.npz -o more.png --count 8
    Each command's options and examples: tghop COMMAND --help (synth, fit and batch
    name their rarer options there: --help-all gives each one's help).
    """
