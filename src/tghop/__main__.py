"""The ``tghop`` command: ``python -m tghop`` and the console script both run :func:`run`.

What only the command does to its process happens here, never on ``import tghop``: a
program that imports tghop keeps its signal handling, its environment and its garbage
collector as they were.
"""

import os
import signal
import sys


def _interrupted_while_starting(signum, frame):  # pragma: no cover - timing dependent
    sys.stderr.write("Error: interrupted\n")
    os._exit(130)


def run():
    """Run the ``tghop`` command line as this process's command.

    Before the command line is imported: Ctrl-C while the command starts (its modules and
    click being imported) gives one line and exit status 130, no traceback
    (:meth:`tghop.cli.group.OneLineGroup.main` puts the command's own handler in place
    once the command's modules are in); and OpenBLAS's idle worker threads spin briefly before
    they sleep (``OPENBLAS_THREAD_TIMEOUT=4``, unless the user has set it, and only while
    NumPy is not yet loaded): their default long spin takes the CPU from the thread with
    the work when other programs keep the cores busy (docs/choices.md).
    """
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _interrupted_while_starting)
    if "numpy" not in sys.modules:
        os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")
    from .cli import main

    main.main(prog_name="tghop", as_command=True)


if __name__ == "__main__":
    run()
