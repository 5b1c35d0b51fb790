"""tghop: explainable, fast texture synthesis from one exemplar (TGHop, Lei et al. 2021)."""

__version__ = "0.1.0"

from ._common import InvalidImageError, MissingExtraError, ModelFileError, NotFittedError, TGHopError  # noqa: E402
from .synthesis import TGHop  # noqa: E402
from . import data  # noqa: E402

__all__ = ["TGHop", "data", "InvalidImageError", "MissingExtraError", "ModelFileError", "NotFittedError",
           "TGHopError", "__version__"]
