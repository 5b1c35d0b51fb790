"""What every command of the ``tghop`` command line shares: progress bars, one-line
errors (:func:`user_errors`: a :class:`~tghop.TGHopError` to one line and exit status 1),
reading exemplars and checking output paths.

The commands' modules (:mod:`tghop.cli.texture`, :mod:`tghop.cli.guided`, :mod:`tghop.cli.inpaint`,
:mod:`tghop.cli.evaluation`, :mod:`tghop.cli.cooc`, :mod:`tghop.cli.batch`, :mod:`tghop.cli.serve`)
stand on this module and on :mod:`tghop.cli.options`; the group (:mod:`tghop.cli.group`) stands on them.
Heavy modules (NumPy's linear algebra users, Pillow, scikit-learn, SciPy) are imported inside the
functions that need them, so ``--help``, ``--version`` and ``info`` answer at once.
"""

from __future__ import annotations

import os
import sys
import typing
import warnings
from contextlib import contextmanager
from pathlib import Path

import click

from .._errors import HINT_DOWNSCALE_YOURSELF, InvalidImageError, TGHopError, terminal_line
from .._formats import COOC_CHECKPOINT, READ_SUFFIXES, checkpoint_note, is_model_file, model_file_kind

__all__ = ["Progress", "fail", "Terminated", "stop_message", "user_errors", "load_exemplar", "is_builtin",
           "is_model_file", "summary", "check_output", "check_outputs", "check_model_output", "numbered", "load_mask",
           "check_stdout", "warn_lost_depth", "warn_written_with_8", "read_image",
           "quiet_tifffile", "examples", "tell_steps", "STAGES", "MATERIAL_STAGES", "stage_paths",
           "material_stage_files", "save_with_stages"]


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP to the ``tghop`` command (raised by the handlers that
    :meth:`tghop.cli.group.OneLineGroup.main` installs with ``as_command=True``).

    A KeyboardInterrupt, so that everything that cleans up after Ctrl-C (the temporary
    file of :func:`tghop.imageio.write_atomic`, progress bars) does so here too; the
    command then exits with ``128 + signum`` and ``Error: terminated``.
    """

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def stop_message(exc: BaseException):
    """The one line and exit status for a Ctrl-C or a :class:`Terminated` (or click's
    Abort that wraps one)."""
    for e in (exc, getattr(exc, "__cause__", None), getattr(exc, "__context__", None)):
        if isinstance(e, Terminated):
            return "terminated", 128 + e.signum
    return "interrupted", 130


#: Where stderr is no terminal, the least seconds between two lines of one stage's percentage.
LOG_EVERY = 10.0


class _Paused(typing.NamedTuple):
    """A stage :class:`Progress` left unfinished for another, which it may go on after: its state, and when."""
    stage: str
    done: int
    total: int
    started: float
    logged: float
    tenth: int
    at: float


def _seconds(elapsed: float) -> str:
    """A stage's time for a log line: ``0.41 s``, ``12.3 s``, ``2 min 05 s``."""
    if elapsed < 60:
        return f"{elapsed:.2f} s" if elapsed < 10 else f"{elapsed:.1f} s"
    minutes, rest = divmod(int(round(elapsed)), 60)
    return f"{minutes} min {rest:02d} s"


class Progress:
    """Renders the library's ``progress(stage, done, total)`` calls as click progress bars.

    ``show_eta`` adds the remaining time; a subclass may set ``note`` (a string) to show it
    after the bar. Where stderr is no terminal (``2>log``, a pipe, a CI log), where click draws
    no bar but its label alone, once: a line per stage as it ends, with the clock time and how
    long it took (``[16:52:03] quilting: done in 1.20 s``; ``stopped at 40 %`` when it did not
    finish), and in a long stage its percentage at each tenth, at most one line every
    :data:`LOG_EVERY` seconds (and the ``note``). A stage left unfinished for another that goes on
    after it (a material's ``maps`` after each map's ``refine``) is one stage, said once when it ends.
    """

    def __init__(self, enabled: bool, *, show_eta: bool = False):
        self.enabled = enabled
        self.show_eta = show_eta
        self.note = None
        self.bar = None
        self.stage = None
        self.done = 0
        self.lines = None  # lines instead of bars: decided at the first report (stderr a terminal or not)
        self.paused = None  # a stage left unfinished for another, which may go on after it: a _Paused
        self.total = self.started = self.logged = self.tenth = self.finished = None

    def _line(self, text, when=None):
        import time

        clock = time.strftime("%H:%M:%S", time.localtime(when))
        click.echo(terminal_line(f"[{clock}] {text}" + (f" ({self.note})" if self.note else "")), err=True)

    def _log(self, stage, done, total):
        import time

        now = time.monotonic()
        if stage != self.stage:
            back = self.paused if self.paused is not None and self.paused.stage == stage else None
            if back is None and self.paused is not None:  # it did not go on after the stage that followed it
                self._said_paused()
            self._end(pause=back is None)
            if back is not None:  # a stage that goes on after another (a material's "maps" after each map's refine)
                self.paused = None
                self.stage, self.done, self.total, self.started, self.logged, self.tenth = back[:6]
            else:
                self.stage, self.done, self.started, self.logged, self.tenth = stage, 0, now, now, 0
            self.finished = None
        self.done, self.total = max(self.done, done), max(total, 1)
        if self.done >= self.total and self.finished is None:  # its end: not the next stage's start (work between)
            self.finished = (now, time.time())
        tenth = min(10 * self.done // self.total, 9)
        if tenth > self.tenth and now - self.logged >= LOG_EVERY:
            self._line(f"{stage}: {100 * self.done // self.total} % after {_seconds(now - self.started)}")
            self.logged, self.tenth = now, tenth

    def __call__(self, stage, done, total):
        if not self.enabled:
            return
        if self.lines is None:
            self.lines = not sys.stderr.isatty()
        if self.lines:
            self._log(stage, done, total)
            return
        if stage != self.stage:
            self.close()
            self.stage, self.done = stage, 0
            self.bar = click.progressbar(length=max(total, 1), label=terminal_line(f"{stage:<14}"), file=sys.stderr,
                                         show_eta=self.show_eta, show_percent=True,
                                         item_show_func=None if self.note is None else lambda _: self.note)
            self.bar.__enter__()
        if done > self.done:
            self.bar.update(done - self.done, current_item=self.note)
            self.done = done

    def took(self, stage, started):
        """A stage already over, begun at ``started`` (``time.monotonic()``): its line where stderr is
        no terminal, said only once it succeeded, so that work that fails at once (an input not read)
        leaves the ``Error:`` line alone; a terminal gets no bar for it."""
        import time

        if not self.enabled:
            return
        if self.lines is None:
            self.lines = not sys.stderr.isatty()
        if self.lines:
            if self.paused is not None:
                self._said_paused()
            self._end(pause=False)
            self._line(f"{stage}: done in {_seconds(time.monotonic() - started)}")

    def _said_paused(self):
        """The line of the stage left unfinished that did not go on: stopped where it was paused."""
        p, self.paused = self.paused, None
        self._stopped(p.stage, p.done, p.total, p.started, at=p.at)

    def _stopped(self, stage, done, total, started, at=None):
        import time

        ended = time.monotonic() if at is None else at
        self._line(f"{stage}: stopped at {100 * done // total} % after {_seconds(ended - started)}")

    def _end(self, pause):
        """The line of the stage that ends (``pause``: one left unfinished is kept, not said, while the
        next stage runs: it may go on after it, as a material's "maps" stage goes on after each map's refinement)."""
        if self.stage is None:
            return
        stage, self.stage = self.stage, None
        if self.finished is not None:
            self._line(f"{stage}: done in {_seconds(self.finished[0] - self.started)}", self.finished[1])
            return
        if pause:
            import time

            self.paused = _Paused(stage, self.done, self.total, self.started, self.logged, self.tenth, time.monotonic())
        else:
            self._stopped(stage, self.done, self.total, self.started)

    def close(self):
        if self.lines:
            if self.paused is not None:  # began before this stage: said first
                self._said_paused()
            self._end(pause=False)
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None
            self.stage = None


def fail(message: str, code: int = 1):
    """Print ``Error: message`` on one line (:func:`~tghop._errors.terminal_line`) and exit with ``code``."""
    try:
        click.echo(f"Error: {terminal_line(message)}", err=True)
    except BrokenPipeError:  # stderr's reader went away: the exit status still says it failed
        pass
    sys.exit(code)


def drop_stdout():
    """Point standard output at the null device: what is still buffered for a pipe that was
    closed or a full disk would fail again as the interpreter exits ("Exception ignored")."""
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
        os.close(null)
    except (OSError, ValueError, AttributeError):  # no file descriptor (an in-process run's stdout)
        pass


def output_gone() -> bool:
    """Whether the reader of the standard output or error went away: the other end of its
    pipe is closed (``tghop info M | head -1``), so that writing there fails with EPIPE. A
    broken pipe elsewhere (a socket, a worker's pipe) is not the output's: a failure like any
    other. Where the system cannot tell (no ``poll``), a broken pipe is taken for the output's."""
    import select

    if not hasattr(select, "poll"):
        return True
    for stream in (sys.stdout, sys.stderr):
        try:
            fd = stream.fileno()
            poller = select.poll()
            poller.register(fd, select.POLLOUT)
            if any(event & (select.POLLERR | select.POLLHUP) for _, event in poller.poll(0)):
                return True
        except (AttributeError, OSError, ValueError):  # closed, or no file descriptor (an in-process run's)
            continue
    return False


def os_error_message(exc: OSError) -> str:
    """A file system or output error the checks did not foresee, in one line: the file (or "cannot
    write the output" when it has none, as a full stdout), the system's words, and a fix for a
    full disk."""
    import errno

    hint = "; free some space or write elsewhere" if exc.errno == errno.ENOSPC else ""
    where = f"{str(exc.filename)[:80]}: " if exc.filename else "cannot write the output: "
    return f"{where}{exc.strerror or exc}{hint}"


def _show_now(progress):
    """A ``warnings.showwarning`` that writes a user or runtime warning as its one line at once,
    below the progress bar's line (a long batch's warning is read while it waits, not at its end)."""

    def show(message, category, *args, **kwargs):
        if issubclass(category, (UserWarning, RuntimeWarning)):
            if progress is not None and progress.bar is not None and sys.stderr.isatty():
                click.echo("", err=True)  # the bar's line ends; its next update draws it again below
            click.echo(f"Warning: {terminal_line(message)}", err=True)

    return show


@contextmanager
def user_errors(progress=None):
    """Turn library errors into one line on stderr; show warnings as one line each, as they
    come (before the error, so that the error is the last line)."""
    with warnings.catch_warnings():  # the filters and showwarning restored on exit
        warnings.simplefilter("always")
        warnings.showwarning = _show_now(progress)
        try:
            yield
        except BrokenPipeError:  # the output's reader went away: the group answers it (OneLineGroup.main)
            raise
        except (TGHopError, MemoryError, OSError, KeyboardInterrupt) as exc:
            if progress:
                progress.close()
            if isinstance(exc, TGHopError):
                fail(str(exc))
            if isinstance(exc, MemoryError):
                fail("out of memory; use a smaller output size, pool or exemplar")
            if isinstance(exc, OSError):
                if not exc.filename:  # the output stream (an image to a full stdout): not flushed again at exit
                    drop_stdout()
                fail(os_error_message(exc))
            fail(*stop_message(exc))  # Ctrl-C, or SIGTERM/SIGHUP to the command (Terminated)
        finally:
            if progress:
                progress.close()


#: What to do about an image over the size limit, in a command with ``--downscale`` and in one without.
HINT_DOWNSCALE_OPTION = "pass --downscale to reduce it (or downscale it yourself)"


def is_builtin(spec) -> bool:
    """Whether ``spec`` names a built-in exemplar: ``builtin:NAME`` of a known NAME, or of an unknown
    one that is no file either (its reader refuses the name). A file named ``builtin:x.png`` is read
    as that file (0.56 refused it as an unknown built-in exemplar); ``./builtin:bricks`` always names
    the file, ``builtin:bricks`` the built-in exemplar (:func:`load_exemplar` warns where both exist)."""
    from ..data import BUILTIN

    spec = os.fspath(spec) if isinstance(spec, os.PathLike) else spec
    if not isinstance(spec, str) or not spec.startswith("builtin:"):
        return False
    return spec.split(":", 1)[1] in BUILTIN or not os.path.lexists(spec)


def quiet_tifffile():
    """:mod:`tifffile`'s log kept off the terminal, the command line's choice as an application (the library
    leaves other packages' loggers as they are): tifffile logs a malformed TIFF's oddities as warnings
    (``<tifffile.TiffPage 0 @8> incorrect StripOffsets count``), which Python, with no logging set up, printed
    as lines of their own beside the command's one-line error (0.56). A :class:`logging.NullHandler` on its
    logger stops that last-resort printing only: a program that sets up logging still gets them. Called where
    a command reads image files (:func:`read_image`, ``tghop batch``), not at the command line's start, so
    that ``--help``, ``info`` and a synthesis from a model load no :mod:`logging`."""
    import logging

    logger = logging.getLogger("tifffile")
    if not any(isinstance(handler, logging.NullHandler) for handler in logger.handlers):
        logger.addHandler(logging.NullHandler())


def read_image(path, **kwargs):
    """:func:`tghop.imageio.load_image` of ``path`` (its keyword arguments), as every command reads an image
    file: with tifffile's log quieted (:func:`quiet_tifffile`)."""
    from ..imageio import load_image

    quiet_tifffile()
    return load_image(path, **kwargs)


def load_exemplar(spec: str, *, downscale=False, dtype="float64", has_downscale=False, with_depth=False):
    """An image file, or ``builtin:NAME`` for a built-in exemplar (:func:`is_builtin`); with
    ``with_depth``, and its bits per channel (8 for a built-in one).

    ``has_downscale``: the command has a ``--downscale`` option, so an image over the size
    limit is answered with "pass --downscale"; otherwise with "downscale it first". ``builtin:NAME``
    of an unknown NAME (and no such file) is a :class:`click.UsageError` (exit status 2, 0.57; it was 1),
    as an unknown ``-o`` extension or option value is.
    """
    from ..data import BUILTIN, builtin

    if is_builtin(spec):
        if spec.split(":", 1)[1] not in BUILTIN:  # a name of no built-in exemplar: a usage error (status 2), as a
            try:                                   # choice's unknown value
                builtin(spec.split(":", 1)[1])
            except TGHopError as exc:
                raise click.UsageError(str(exc)) from None
        if os.path.lexists(spec):
            warnings.warn(f"{spec} is read as the built-in exemplar, though a file of that name is here too; "
                          f"give ./{spec} to read the file")
        image = builtin(spec.split(":", 1)[1])
        return (image, 8) if with_depth else image
    if is_model_file(spec):
        kind = model_file_kind(spec)
        hint = (" (a checkpoint goes to 'tghop cooc morph', 'tghop cooc edit' or 'tghop baseline cooc EXEMPLAR "
                "--model CHECKPOINT')" if kind == COOC_CHECKPOINT else
                # 0.62: what to do with a model instead (0.61 stopped at "needs an image")
                f" (a model is fitted already: 'tghop synth {spec} -o OUT.png' makes images from it)"
                if kind == "a model file" else checkpoint_note(spec))
        raise TGHopError(f"{spec} is {kind}, not an image; this command needs an image{hint}")
    _refuse_a_slip(spec, BUILTIN)
    return read_image(spec, downscale=downscale, dtype=dtype, with_depth=with_depth,
                      too_large_hint=HINT_DOWNSCALE_OPTION if has_downscale else HINT_DOWNSCALE_YOURSELF)


def _refuse_a_slip(spec, builtins):
    """An exemplar ``spec`` that is no file but a newcomer's slip, refused saying what was meant (0.59; 0.58 said
    only "no such file; check the path"): a built-in exemplar's name without ``builtin:`` (``tghop synth bricks``),
    or a number, the second of ``--size 512 512`` taken for one more SOURCE (with --size typed a usage error, 0.63)."""
    from .options import refuse_split_size, split_size_message

    name = os.fspath(spec)
    if os.path.lexists(name):
        return
    if name in builtins:
        raise InvalidImageError(f"{name}: no such file; the built-in exemplar is builtin:{name}")
    context = click.get_current_context(silent=True)
    refuse_split_size(context, [name])
    if name.isdecimal() and context is not None and any(p.name == "size" for p in context.command.params):
        raise InvalidImageError(split_size_message(name))


def warn_written_with_8(label: str, spec: str, output=None, *, several=()):
    """The warning of a command that writes 8 bits without ``--depth`` (``synth``, ``baseline``)
    when its input ``label spec`` has more; to an ``output`` of a format of 8 bits only (JPEG),
    the fix names a format that holds 16 first (``--depth 16`` alone is refused there).

    ``several``: instead, the deep ones of several inputs as (label, spec) pairs (``label`` and
    ``spec`` None), all named in the one warning: ``SOURCE 1 (a.png) and SOURCE 3 (c.tif) have ...``."""
    import warnings

    from .._formats import DEPTHS, extensions
    from ..imageio import output_format

    fix = "pass --depth 16 to keep them"
    if output is not None and 16 not in DEPTHS[output_format(output)]:
        fix = f"name the output {extensions([f for f, held in DEPTHS.items() if 16 in held])} and {fix}"
    named = [f"{name} ({path})" for name, path in several] or [f"{label} {spec}"]
    warnings.warn(f"{_and(named)} {'has' if len(named) == 1 else 'have'} more than 8 bits a channel, but the image "
                  f"is written with 8; {fix}")


def _and(names) -> str:
    """``a``, ``a and b``, ``a, b and c``: the names of a warning, in one phrase."""
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def load_mask(path: str, shape, *, label: str = "MASK", image_label: str = "the image", what: str = "hole"):
    """A mask image as an (H, W) bool array: True where its pixels are white (colour channels'
    mean > 0.5). One line when it cannot be read or is not ``shape``'s size (H, W, ...).

    Its alpha channel is not read: where it has transparent pixels, a warning says so and
    to paint the ``what`` (``"hole"``) white on black (a hole painted as transparency was
    "no white pixel" or "leaves too little" without a word why). A mask that is not black and
    white (:func:`tghop.inpaint.grey_share` over :data:`tghop.inpaint.MASK_PICTURE_SHARE`: a photograph, or IMAGE
    and MASK swapped) is warned of likewise: its light pixels are the hole."""
    import warnings

    from ..inpaint import MASK_PICTURE_SHARE, grey_share

    if is_model_file(path):
        raise TGHopError(f"{label} {path} is {model_file_kind(path)}, not an image; give a black and white image")
    mask = read_image(path, too_large_hint=HINT_DOWNSCALE_YOURSELF, keep_alpha=True)  # the colours as without it
    if mask.shape[:2] != tuple(shape[:2]):
        raise TGHopError(f"{label} {path} is {mask.shape[0]}x{mask.shape[1]} but {image_label} is "
                         f"{shape[0]}x{shape[1]}; give a mask of the same size")
    if mask.shape[2] in (2, 4):  # grey or RGB, and alpha
        if (mask[..., -1] < 1).any():
            warnings.warn(f"{label} {path} has transparent pixels, but transparency is not read as the {what} (its "
                          f"alpha channel is ignored; its white pixels are the {what}); paint the {what} white on "
                          "black")
        mask = mask[..., :-1]
    mean = mask.mean(axis=2)
    other = grey_share(mask)
    if other > MASK_PICTURE_SHARE:  # a photograph (or IMAGE and MASK swapped): its light pixels were the hole
        order = " (IMAGE comes first, then MASK)" if label == "MASK" else ""
        warnings.warn(f"{label} {path} is not black and white: {other:.0%} of its pixels are grey or coloured "
                      f"(a picture?), and those lighter than mid-grey are taken as the {what}; paint the {what} white "
                      f"on black{order}")
    return mean > 0.5


def layout_summary(model) -> str:
    """The coarse layout a fitted model holds, in words, and why it is coarser than asked
    or none: the exemplar's size, or, where that allowed it, a sample mask (``--exclude``,
    an inpainted hole) that left too few of its patches."""
    from ..layout import fits
    from ..synthesis import CoarseLayout

    if model.layout_factor is None:
        return "none"
    f = None if model.layout_ is None else model.layout_.factor
    p = CoarseLayout().patch_size if model.layout_ is None else model.layout_.patch_size
    if f == model.layout_factor:
        return f"a coarse model at 1/{f} scale"
    small = not fits(model.exemplar_shape_, 2 if f is None else model.layout_factor, p)
    why = "the exemplar is too small for" if small else "too little of the exemplar lies outside the mask for"
    if f is None:
        return f"none ({why} one)"
    return f"a coarse model at 1/{f} scale (asked {model.layout_factor}: {why} it)"


def summary(model, params=None) -> str:
    """Dimensions, core model and parameter total of a fitted model (``params``: its
    :meth:`~tghop.TGHop.n_parameters`, when the caller already has it)."""
    from ..parameter_count import PAPER_MODULES

    d = model.dims_
    params = model.n_parameters() if params is None else params
    paper = params[PAPER_MODULES]  # what compares with the paper's total: the total holds our additions too
    dims = " -> ".join(f"D{i}={d[f'D{i}']}" for i in range(len(model.channels_) + 1))
    ks = ", ".join(f"K{i + 1}={k}" for i, k in enumerate(model.channels_))
    classes = getattr(model, "classes_", None)
    return (
        f"dimensions: {dims}, D_r={d['D_r']}  ({ks})\n"
        f"core model: N={d['N']} clusters, F={d['F']} CDFs, W={d['W']} codewords\n"
        f"colour classes: {classes.n_classes if classes is not None else 'none (fitted with --colour-classes 0)'}\n"
        f"layout: {layout_summary(model)}\n"
        f"parameters: {params['total']['stored']:,} stored; the paper's modules {paper['stored']:,} "
        f"({paper['paper']:,} by the paper's formulas)"
    )


def check_stdout(what: str):
    """Refuse, before any work, a command whose result goes to the standard output when
    that is closed (``>&-``: Python sets ``sys.stdout`` to None, and ``click.echo`` would
    drop the result without a word). ``what``: what the command writes there."""
    if sys.stdout is None:
        raise TGHopError(f"the standard output is closed, and {what} goes there; leave it open "
                         "or redirect it to a file (> FILE)")


def check_output(path: str, allow_stdout=False, depth=None, *, made=False):
    """Refuse, before any work, an image output ``path`` (``-o``) that cannot be written: stdout
    where the command writes none or to a terminal, an extension tghop does not write, a folder;
    with ``depth`` (``--depth``), a depth the output's format cannot hold (usage errors: two options
    that clash, or -o's bad value; a folder too, 0.62: 0.61 exited 1). ``made``: a file the command names
    from -o's (--count's, --stages', a material's maps), whose folder is told to be moved."""
    from ..imageio import check_depth, check_output_path, output_format

    if path != "-" and os.path.isdir(path):
        if made:
            raise click.UsageError(f"{path} is a folder, where this command writes a file of that name (named from "
                                   "-o's); move or remove that folder, or give -o another name")
        raise click.UsageError(f"{path} is a folder; give a file name for the image in it "
                               f"(e.g. {os.path.join(path, 'texture.png')})")

    if path == "-" and not allow_stdout:
        raise click.UsageError("this command cannot write to stdout; give a file name with -o")
    if path == "-" and sys.stdout is None:  # before the work, not when the image is written
        raise TGHopError("-o -: the standard output is closed; give a file name instead")
    if path == "-" and sys.stdout.isatty():  # a PNG's bytes drawn as garbage in the terminal
        raise click.UsageError("-o -: the standard output is a terminal, which shows no image; redirect it "
                               "(-o - > out.png, or | another command) or give a file name")
    try:
        output_format(path)
    except InvalidImageError as exc:  # an extension tghop does not write: -o's bad value, a usage error
        raise click.UsageError(str(exc)) from None
    if path != "-":
        check_output_path(path)
    if depth is not None:
        try:
            check_depth(path, depth)
        except InvalidImageError as exc:  # --depth 16 -o x.jpg: a clash of options, as an unknown extension
            raise click.UsageError(str(exc)) from None


def _file_key(path: str):
    """What names one file: device and inode of an existing file (so hard and symbolic
    links, ``./x`` and ``x`` are the same), otherwise the resolved absolute path."""
    try:
        st = os.stat(path)
        return ("inode", st.st_dev, st.st_ino)
    except OSError:
        pass
    try:
        return ("path", str(Path(path).resolve()))
    except (OSError, RuntimeError):  # a symlink loop, a name too long: as written
        return ("path", os.path.abspath(path))


def check_outputs(outputs, inputs=()):
    """Refuse an output that is one of the command's inputs or another of its outputs,
    before anything is read or written.

    Parameters
    ----------
    outputs, inputs : sequences of (label, path)
        Compared as files (:func:`_file_key`: the same inode when they exist, else the
        same resolved path). ``label`` says where the path came from on the command line
        (``"-o"``, ``"--save-model"``, ``"--stages"``, ``"EXEMPLAR"``, ...). ``None``,
        ``-`` (stdout or stdin) and ``builtin:NAME`` are not files and are skipped, and so
        are inputs that do not exist (their readers say so).

    Raises
    ------
    TGHopError
        One line naming both and the fix.
    """
    def files(pairs):
        return [(label, str(path)) for label, path in pairs
                if path is not None and str(path) != "-" and not is_builtin(str(path))]

    seen = {}
    for label, path in files(inputs):
        if os.path.lexists(path):  # a missing input is its reader's "no such file", not an overwrite
            seen.setdefault(_file_key(path), (label, path, True))
    for label, path in files(outputs):  # one key each: --count 1000 stays linear
        key = _file_key(path)
        if key in seen:
            other_label, other, is_input = seen[key]
            if is_input:
                raise TGHopError(f"{path}: {label} would overwrite {other_label}, an input of this command; "
                                 f"give {label} another name")
            what = f"{other_label} and {label}" if other_label != label else f"two outputs of {label}"
            raise TGHopError(f"{path} is {what}: one would be written over the other; give each its own name")
        seen[key] = (label, path, False)


def check_model_output(path: str, label: str = "-o", *, suffix: str = ".npz", what: str = "model"):
    """Refuse a model (or checkpoint) output that cannot be one, before any work: ``-``
    (a model cannot go to stdout), a name without ``suffix`` (an image extension or none:
    ``-o model`` is refused, not renamed, so the name the user gave is the file there is),
    a folder or an unwritable place (:func:`tghop.imageio.check_output_path`).

    ``tghop cooc train`` calls it with ``suffix=".pt", what="checkpoint"``.
    """
    from .._errors import ModelFileError
    from ..imageio import check_output_path

    if str(path) == "-":
        raise click.UsageError(f"{label} -: a {what} cannot go to stdout; give a file name, e.g. {label} "
                               f"{what}{suffix}")
    if not str(path).strip():  # Path("") is the current folder, which has no name to add to
        raise ModelFileError(f"{label}: the {what}'s file name is empty; give one, e.g. {label} {what}{suffix}")
    p = Path(path)
    ext = p.suffix.lower()
    if p.is_dir():  # -o models/: "name it models.npz" wrote beside the folder; a usage error (0.62; 0.61: exit 1)
        raise click.UsageError(f"{label} {path} is a folder; give a {what} file name in it (e.g. "
                               f"{os.path.join(path, what + suffix)})")
    if ext != suffix:
        fixed = p.with_suffix(suffix) if ext in READ_SUFFIXES else p.with_name(p.name + suffix)
        why = (f"{ext} is an image extension, but {label} writes a {what}" if ext in READ_SUFFIXES
               else f"a {what} file's name ends in {suffix}")
        # an option's bad value, as an image's -o x.webp: a usage error (0.63; 0.62: exit status 1)
        raise click.UsageError(f"{label} {path}: {why}; name it {fixed}")
    check_output_path(path, what=what, error=ModelFileError)


def draw_seed(seed):
    """``(seed, drawn)``: --seed as given, or one drawn from the system's entropy where none was (0.59), so
    that :func:`tell_seed` can say it: an image made without --seed could not be made again (at another
    depth, with --stages, once more after an edit elsewhere)."""
    if seed is not None:
        return seed, False
    import numpy as np

    return int(np.random.SeedSequence().generate_state(1)[0]), True


def tell_seed(seed, drawn, what="the same image"):
    """After a run without --seed, one line giving the seed drawn (:func:`draw_seed`) and the option that
    makes ``what`` again; nothing where --seed was given."""
    if drawn:
        click.echo(terminal_line(f"seed {seed} drawn (no --seed given): --seed {seed} makes {what} again"), err=True)


def tell_steps(paths, count, maps=False):
    """The line naming --stages' files (``paths``: the first output's, those written; nothing where none), said
    after the line naming the output, by every command alike (0.62; 0.61's textures said it first, materials and
    morph after)."""
    names = [os.path.basename(str(p)) for p in paths]
    if names:
        click.echo(terminal_line(f"steps written beside {'it' if count == 1 else 'each'}"
                                 f"{', each with its maps' if maps else ''}: {', '.join(names)}"), err=True)


def count_outputs(output: str, count: int) -> list:
    """The files of ``count`` images (``--count``): -o's own for one, else numbered (:func:`numbered`:
    ``out_1.png``, ...); ``-o -`` (stdout) takes one only, else a usage error."""
    if count == 1:
        return [output]
    if output == "-":
        raise click.UsageError("--count > 1 cannot write to stdout; give a file name with -o")
    return numbered(output, count)


#: The steps ``--stages`` writes (synth, inpaint, extend), as ``TGHop.synthesize(return_stages=True)`` and
#: :func:`tghop.inpaint.inpaint` name them.
STAGES = ("guide", "quilt", "seams", "refine", "patch refine", "colour", "levels")
#: A material's (``Material.synthesize(return_stages=True)``; 0.61): "maps" its last, the maps written.
MATERIAL_STAGES = ("guide", "quilt", "seams", "refine", "patch refine", "colour", "maps")


def stage_paths(path, names=STAGES):
    """``OUT_<step>.png`` for each step of ``names`` beside the output ``path``."""
    path = Path(path)
    return {name: str(path.with_name(f"{path.stem}_{name.replace(' ', '-')}{path.suffix}")) for name in names}


def save_with_stages(image, path, depth, steps, paths, progress=None):
    """``image`` at ``path`` with its --stages files as one set, every file or none (0.62: 0.61 wrote each step as
    it came, and a full disk left the steps before it, the error saying nothing was written): ``steps``
    ``{step: image}``, ``paths`` ``{step: file}`` (a step not in it is not written: the patch pool)."""
    from ..imageio import save_images

    save_images([(step, paths[name], depth) for name, step in steps.items() if name in paths]
                + [(image, path, depth)], progress=progress)


def numbered(path: str, count: int):
    p = Path(path)
    width = len(str(count))
    return [str(p.with_name(f"{p.stem}_{i:0{width}d}{p.suffix}")) for i in range(1, count + 1)]


def refuse_albedo_as_map(paths, albedo_path, *, label: str = "MAP", albedo: str = "IMAGE") -> None:
    """A one-line error where a map's file is the albedo's own (the manifest of ``tghop batch``
    refuses it too): the material had the albedo twice, one copy as a map."""
    for path in paths:
        try:
            same = os.path.samefile(path, albedo_path)
        except OSError:  # a missing file: said where it is read
            continue
        if same:
            raise TGHopError(f"{label} {path} is {albedo} itself, the albedo; give the map's own file")


def refuse_colour_map_out_of_place(albedo_path, paths, *, label: str = "MAP", albedo: str = "IMAGE",
                                   command: str = "tghop fit {} --maps") -> None:
    """The colour map out of place by the files' names (:func:`tghop.map_names.check_colour_map_order`,
    in the command line's words): a one-line error where the albedo's file is named as another kind of map
    and one of the maps as the colour map (the two swapped), or the albedo's file as a normal map and no map
    as the colour map; a one-line warning where the albedo's file is named as another kind
    (``Rock_Roughness.png``) and no map as the colour map (fitted as the colour map, as asked: a material
    may have none). ``command``: the command line up to the maps, ``{}`` where the colour map goes."""
    from ..map_names import check_colour_map_order

    example = command.format("Rock_Color.png")
    said = check_colour_map_order(
        albedo_path, paths, albedo=f"{albedo} {{albedo}}", map=f"{label} {{colour}}", none=f"no {label}",
        swap=command.format("{colour}") + " {others} ...",
        first=f"give the material's colour map first ({example} {{albedo}} ...)", written="written to OUT",
        expected="first", then=f": {example} {{albedo}} {{maps}}")
    if said is not None:
        warnings.warn(said, UserWarning, stacklevel=2)


def map_names(paths, *, label: str = "MAP", albedo: str = "IMAGE") -> list:
    """The names of the maps in files ``paths`` (:func:`tghop.map_names.map_name`), or a one-line
    error where two are one name (in any case) or one is the albedo's (``label``: what the
    command calls a map, ``albedo``: what it calls the albedo)."""
    from ..map_names import MapNameClashError, check_map_names, map_name

    names = [map_name(path) for path in paths]
    try:
        check_map_names(names, paths)
    except MapNameClashError as exc:
        name = exc.name
        if exc.albedo:
            raise TGHopError(f"{label} {paths[exc.index]} is named {name!r}, the name of {albedo} itself (written to "
                             "OUT, the other maps beside it); rename the file") from None
        if exc.cut:
            raise TGHopError(f"{exc.clash}; {exc.fix}") from None
        raise TGHopError(f"{exc.clash}: the file stem names the map and its output file; rename one") from None
    return names


def material_outputs(material, output, depth):
    """``[(name, path, depth)]`` of a material's maps for output ``output``: the albedo at
    ``output``, each other map at ``OUT_<suffix>.EXT`` (:func:`tghop.material_files.map_files`);
    each at ``depth``, or without it at the depth its file had (as far as the format holds it)."""
    from ..imageio import check_depth, deepest
    from ..material_files import map_files

    out = []
    for name, path, own in zip(material.names_, map_files(output, material.names_), material.depths_):
        out.append((name, path, check_depth(path, depth or deepest(path, own))))
    return out


def warn_lost_depth(items, path, depth, noun=None):
    """One warning naming the images written to ``path``'s format with fewer bits a channel
    than they had (a 16-bit map as JPEG, a float one as PNG), as ``synth`` warns of a deep
    exemplar written with 8: ``items`` are ``(label, own depth, written depth)``; none when
    ``depth`` (``--depth``) was given (the user chose it). ``noun`` (``"map"``) goes before
    the labels, with an s for several."""
    import warnings

    from .._formats import DEPTHS, extensions
    from ..imageio import output_format

    lost = [(label, own) for label, own, written in items if written < own]
    if depth is not None or not lost:
        return
    fmt = output_format(path)
    keep = extensions([f for f, held in DEPTHS.items() if max(own for _, own in lost) in held])
    names = [f"{label} ({'float' if own == 32 else f'{own}-bit'})" for label, own in lost]
    named = _and(names)
    if noun:
        named = f"{noun}{'s' if len(names) > 1 else ''} {named}"
    warnings.warn(f"{named} {'has' if len(names) == 1 else 'have'} more bits a channel than {fmt} holds, but "
                  f"{'is' if len(names) == 1 else 'are'} written with {max(DEPTHS[fmt])}; name the output {keep} "
                  "to keep them")


def material_stage_files(output, plan, names):
    """``{step: [(name, path, depth)]}`` of --stages for a material written to ``output`` (``plan``:
    :func:`material_outputs`', ``(name, path, depth)`` of each map, the albedo first): OUT_<step>.EXT for the albedo,
    OUT_<step>_<suffix>.EXT for each other map, at ``plan``'s depths (not :func:`tghop.material_files.map_files`,
    whose colour word would take OUT_colour's maps for OUT's); ``names``: the steps."""
    from ..material_files import map_suffixes

    out = {}
    for step, path in stage_paths(output, names).items():
        p = Path(path)
        out[step] = [(name, path if suffix is None else str(p.with_name(f"{p.stem}_{suffix}{p.suffix}")), d)
                     for (name, _, d), suffix in zip(plan, map_suffixes([name for name, _, _ in plan]))]
    written = {path: name for name, path, _ in plan}  # a map named as a step (Rock_quilt: OUT_quilt): said so
    for step, files in out.items():
        for name, path, _ in files:
            if path in written:
                raise TGHopError(f"map {written[path]} is written as {path}, the name --stages gives the {step} "
                                 f"step's {name}; drop --stages, or give that map's file another name (a saved "
                                 "material's: fit it again)")
    return out


def write_materials(material, output, outputs, size, depth, make, inputs, progress=None, stages=False):
    """Materials' maps, OUT, OUT_<suffix>, ... for each path of ``outputs``: all checked before any
    work (``inputs``: ``(label, path)`` pairs that no output may be), each set made by ``make()``
    (a dict of maps, ``material``'s names) and written together (all or none); then one line
    says what was written. ``material`` names the maps and their depths; ``progress`` (a
    :class:`Progress`) shows each set's write. ``stages`` (0.61): ``make()`` gives ``(maps, steps)``
    (``Material.synthesize(return_stages=True)``'s), each step's maps written as OUT_<step>, OUT_<step>_<suffix>;
    True: the steps :data:`MATERIAL_STAGES`, or a tuple of others (a painting's). Returns the first set's step files
    written (the albedo's; for :func:`tell_steps`), none without ``stages``."""
    from ..imageio import save_images

    if output == "-":
        raise click.UsageError("a material writes a file per map; give -o a file name (e.g. -o out.png)")
    plans = [material_outputs(material, path, depth) for path in outputs]
    names = stages if isinstance(stages, tuple) else MATERIAL_STAGES
    staged = [material_stage_files(path, plan, names) for path, plan in zip(outputs, plans)] if stages else [
        {}] * len(outputs)
    steps_planned = [("--stages", path) for steps in staged for plan in steps.values() for _, path, _ in plan]
    for plan in plans:
        for _, path, _ in plan:
            check_output(path, made=path != output)
    for _, path in steps_planned:
        check_output(path, made=True)
    check_outputs([("-o", path) for plan in plans for _, path, _ in plan] + steps_planned, inputs)
    warn_lost_depth([(name, own, d) for (name, _, d), own in zip(plans[0], material.depths_)], output, depth, "map")
    first = []  # the first set's step files written (the albedo's)
    for plan, steps_plan in zip(plans, staged):
        maps, steps = make() if stages else (make(), {})
        if stages:
            first = first or [step_plan[0][1] for step, step_plan in steps_plan.items() if step in steps]
        # each step's maps (a step of one image, a painting's regions: at OUT_<step> alone) and the maps: all or
        # none (0.62; 0.61 wrote the steps first, and kept them where the maps failed)
        save_images([(steps[step][name] if isinstance(steps[step], dict) else steps[step], path, d)
                     for step, step_plan in steps_plan.items() if step in steps
                     for name, path, d in (step_plan if isinstance(steps[step], dict) else step_plan[:1])]
                    + [(maps[name], path, d) for name, path, d in plan], progress=progress)
        if progress is not None:
            progress.close()
    written = ", ".join(path for _, path, _ in plans[0])
    more = f" (and {len(plans) - 1} more set{'s' if len(plans) > 2 else ''})" if len(plans) > 1 else ""
    click.echo(terminal_line(f"{len(plans)} material{'s' if len(plans) > 1 else ''} of {size[0]}x{size[1]} written "
                             f"to {written}{more}"), err=True)
    return first


def examples(*lines: str) -> str:
    """A command's ``Examples:`` (its help's epilog, the last lines ``--help`` prints), kept line for line:
    each command as it is typed, each ``# ...`` line saying what the command under it does. A newcomer
    pastes them: a comment on a command's own line in parentheses (``cooc train ... (small config ...)``,
    0.58) stops the shell. tests/test_help_examples.py runs those whose inputs are built in."""
    return "\b\nExamples:\n" + "\n".join(f"  {line}" for line in lines)
