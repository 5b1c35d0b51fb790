"""tghop: explainable, fast texture synthesis from one exemplar (TGHop, Lei et al. 2021).

Where to start (each has its ``help``; the README's "Python" section shows them together):

* :class:`tghop.TGHop` -- fit one exemplar, then ``synthesize`` images of any size;
* :mod:`tghop.imageio` -- ``load_image`` and ``save_image`` (PNG, JPEG, 16-bit PNG, float TIFF);
  :mod:`tghop.data` -- the built-in exemplars (``data.bricks()``);
* :mod:`tghop.modelfile` -- ``save_model`` and ``load_model`` (a path or a binary file object);
* :mod:`tghop.inpaint` -- ``inpaint`` (fill a hole) and ``extend`` (grow an image);
* :func:`tghop.synthesize_guided` and :func:`tghop.morph` -- several models in one image;
* :mod:`tghop.material` -- ``Material``: an albedo and its maps, aligned;
* :mod:`tghop.metrics` -- how close a result is to its exemplar, and how new;
* :mod:`tghop.settings` -- every setting, its default and range, in one table
  (:data:`tghop.synthesis.PAPER_TABLE4`: the paper's).
"""

__version__ = "0.64.0"

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
