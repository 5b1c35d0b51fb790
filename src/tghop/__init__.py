"""tghop: explainable, fast texture synthesis from one exemplar (TGHop, Lei et al. 2021)."""

import os as _os
import signal as _signal
import sys as _sys


def _interrupted_while_starting(signum, frame):  # pragma: no cover - timing dependent
    _sys.stderr.write("Error: interrupted\n")
    _os._exit(130)


# Whether this process is the `tghop` command (the console script or `python -m tghop`),
# not a program that imports tghop: some process-wide settings are the command's alone.
# (`python -m tghop` imports this package while its argv[0] is still "-m"; the
# interpreter's own arguments say which module it runs.)
_argv0 = (_sys.argv[0] if _sys.argv else "") or ""
_orig = list(getattr(_sys, "orig_argv", []))
_AS_COMMAND = (_os.path.basename(_argv0) == "tghop" or _argv0.endswith(_os.path.join("tghop", "__main__.py"))
               or (_argv0 == "-m" and ("-mtghop" in _orig or ["-m", "tghop"] in
                                       [_orig[i: i + 2] for i in range(len(_orig) - 1)])))

# Ctrl-C while the `tghop` command starts (its modules and click being imported): one line,
# no traceback. tghop.cli puts the usual handler back inside the try block that reports
# Ctrl-C.
if _AS_COMMAND and _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler:
    _signal.signal(_signal.SIGINT, _interrupted_while_starting)

__version__ = "0.13.0"

from ._errors import InvalidImageError, MissingExtraError, ModelFileError, NotFittedError, TGHopError  # noqa: E402

__all__ = ["TGHop", "data", "InvalidImageError", "MissingExtraError", "ModelFileError", "NotFittedError",
           "TGHopError", "__version__"]


def __getattr__(name):
    """``tghop.TGHop`` and ``tghop.data`` on first use: ``import tghop`` stays cheap (the CLI's
    ``--help`` and ``--version`` need nothing else)."""
    if name == "TGHop":
        from .synthesis import TGHop

        return TGHop
    if name in ("data", "settings"):
        import importlib

        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'tghop' has no attribute {name!r}")
