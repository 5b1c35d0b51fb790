"""The library's ``progress(stage, done, total)`` calls shown by the command line (:class:`Progress`): click's
progress bars on a terminal, and where stderr is no terminal (a log, a pipe) a line per stage as it ends
and its percentage in a long one, at most every :data:`LOG_EVERY` seconds.

It stands on no other module of the command line (0.64: part of :mod:`tghop.cli.common`, which
re-exports :class:`Progress`).
"""

from __future__ import annotations

import sys
import typing

import click

from .._errors import terminal_line

__all__ = ["Progress", "LOG_EVERY"]


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
