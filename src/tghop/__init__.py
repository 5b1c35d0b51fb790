"""tghop: explainable, fast texture synthesis from one exemplar (TGHop, Lei et al. 2021)."""

__version__ = "0.1.0"

from ._common import InvalidImageError, ModelFileError, NotFittedError, TGHopError  # noqa: E402

__all__ = ["InvalidImageError", "ModelFileError", "NotFittedError", "TGHopError", "__version__"]
