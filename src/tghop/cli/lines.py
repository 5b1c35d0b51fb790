"""What the command line prints besides its errors and warnings: each line as a terminal shows it (:func:`say`).

A file name that is not UTF-8 (``caf\\xe9.png``, as Python decodes it: ``caf\\udce9.png``) is shown as ``ls`` shows it
in a UTF-8 terminal, each byte that does not decode as U+FFFD, and a control character in it (a newline) as Python
writes it in a string, so that a line stays one line: :func:`tghop._errors.terminal_line`, which the ``Error:`` and
``Warning:`` lines took in 0.63. 0.64 says every other line so too: the lines naming what was written, the progress
lines and labels, the batch's summary, ``tghop info``. JSON (``info --json``, ``evaluate --json``) keeps Python's
``\\udce9`` escapes: a program reading it gets the file's own name back.
"""

from __future__ import annotations

import click

from .._errors import terminal_line

__all__ = ["say"]


def say(*lines, err: bool = True) -> None:
    """Print each of ``lines`` as one line (:func:`~tghop._errors.terminal_line`), on stderr (``err``, the
    default: what a command says of its work) or stdout (what it was asked for: ``tghop info``'s description)."""
    for line in lines:
        click.echo(terminal_line(line), err=err)
