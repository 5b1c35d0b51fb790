"""How a command of the ``tghop`` command line fails and stops: library errors as one ``Error:`` line and
exit status 1 (:func:`user_errors`, :func:`fail`), warnings as one line each as they come, a file system
error in one line (:func:`os_error_message`), Ctrl-C and SIGTERM/SIGHUP (:class:`Terminated`,
:func:`stop_message`), and an output whose reader went away (:func:`output_gone`, :func:`drop_stdout`).

The group (:mod:`tghop.cli.group`) and every command stand on it; it stands on no other module of the
command line (0.64: part of :mod:`tghop.cli.common`, which re-exports its names).
"""

from __future__ import annotations

import os
import sys
import warnings
from contextlib import contextmanager

import click

from .._errors import TGHopError, terminal_line

__all__ = ["Terminated", "stop_message", "fail", "drop_stdout", "output_gone", "os_error_message", "user_errors"]


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
