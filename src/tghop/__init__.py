"""tghop: explainable, fast texture synthesis from one exemplar (TGHop, Lei et al. 2021)."""

__version__ = "0.57.0"

from ._errors import (ImageTooLargeError, InvalidImageError, MissingExtraError, ModelFileError, NotFittedError,
                      OpaqueAlphaWarning, TGHopError, TransparencyWarning)

__all__ = ["TGHop", "data", "synthesize_guided", "morph", "ImageTooLargeError", "InvalidImageError",
           "MissingExtraError", "ModelFileError", "NotFittedError", "TGHopError", "TransparencyWarning",
           "OpaqueAlphaWarning", "__version__"]


def __getattr__(name):
    """``tghop.TGHop``, ``tghop.data``, ``tghop.synthesize_guided`` and ``tghop.morph`` on first
    use: ``import tghop`` stays cheap (the CLI's ``--help`` and ``--version`` need nothing else)."""
    if name == "TGHop":
        from .synthesis import TGHop

        return TGHop
    if name in ("synthesize_guided", "morph"):  # several models in one image (tghop.guided)
        from . import guided

        return getattr(guided, name)
    if name in ("data", "settings"):
        import importlib

        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'tghop' has no attribute {name!r}")
