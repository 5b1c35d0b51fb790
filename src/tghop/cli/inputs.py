"""What a command reads, as every command reads it: an exemplar given as a file or ``builtin:NAME``
(:func:`load_exemplar`, :func:`is_builtin`; a newcomer's slip refused saying what was meant), any image
file (:func:`read_image`, with tifffile's log quieted: :func:`quiet_tifffile`), and a mask image as a
hole (:func:`load_mask`).

It stands on :mod:`tghop.cli.options` (inside a function) and on the library (0.64: part of
:mod:`tghop.cli.common`, which re-exports its names).
"""

from __future__ import annotations

import os
import warnings

import click

from .._errors import HINT_DOWNSCALE_YOURSELF, InvalidImageError, TGHopError
from .._formats import COOC_CHECKPOINT, checkpoint_note, is_model_file, model_file_kind

__all__ = ["HINT_DOWNSCALE_OPTION", "is_builtin", "quiet_tifffile", "read_image", "load_exemplar", "load_mask"]


#: What to do about an image over the size limit, in a command with ``--downscale`` and in one without.
HINT_DOWNSCALE_OPTION = "pass --downscale to reduce it (or downscale it yourself)"


def is_builtin(spec) -> bool:
    """Whether ``spec`` names a built-in exemplar: ``builtin:NAME`` of a known NAME, or of an unknown
    one that is no file either (its reader refuses the name). A file named ``builtin:x.png`` is read
    as that file (0.56 refused it as an unknown built-in exemplar); ``./builtin:bricks`` always names
    the file, ``builtin:bricks`` the built-in exemplar (:func:`load_exemplar` warns where both exist)."""
    from ..data import BUILTIN

    spec = os.fspath(spec) if isinstance(spec, os.PathLike) else spec
    if not isinstance(spec, str) or not spec.startswith("builtin:"):
        return False
    return spec.split(":", 1)[1] in BUILTIN or not os.path.lexists(spec)


def quiet_tifffile():
    """:mod:`tifffile`'s log kept off the terminal, the command line's choice as an application (the library
    leaves other packages' loggers as they are): tifffile logs a malformed TIFF's oddities as warnings
    (``<tifffile.TiffPage 0 @8> incorrect StripOffsets count``), which Python, with no logging set up, printed
    as lines of their own beside the command's one-line error (0.56). A :class:`logging.NullHandler` on its
    logger stops that last-resort printing only: a program that sets up logging still gets them. Called where
    a command reads image files (:func:`read_image`, ``tghop batch``), not at the command line's start, so
    that ``--help``, ``info`` and a synthesis from a model load no :mod:`logging`."""
    import logging

    logger = logging.getLogger("tifffile")
    if not any(isinstance(handler, logging.NullHandler) for handler in logger.handlers):
        logger.addHandler(logging.NullHandler())


def read_image(path, **kwargs):
    """:func:`tghop.imageio.load_image` of ``path`` (its keyword arguments), as every command reads an image
    file: with tifffile's log quieted (:func:`quiet_tifffile`)."""
    from ..imageio import load_image

    quiet_tifffile()
    return load_image(path, **kwargs)


def load_exemplar(spec: str, *, downscale=False, dtype="float64", has_downscale=False, with_depth=False):
    """An image file, or ``builtin:NAME`` for a built-in exemplar (:func:`is_builtin`); with
    ``with_depth``, and its bits per channel (8 for a built-in one).

    ``has_downscale``: the command has a ``--downscale`` option, so an image over the size
    limit is answered with "pass --downscale"; otherwise with "downscale it first". ``builtin:NAME``
    of an unknown NAME (and no such file) is a :class:`click.UsageError` (exit status 2, 0.57; it was 1),
    as an unknown ``-o`` extension or option value is.
    """
    from ..data import BUILTIN, builtin

    if is_builtin(spec):
        if spec.split(":", 1)[1] not in BUILTIN:  # a name of no built-in exemplar: a usage error (status 2), as a
            try:                                   # choice's unknown value
                builtin(spec.split(":", 1)[1])
            except TGHopError as exc:
                raise click.UsageError(str(exc)) from None
        if os.path.lexists(spec):
            warnings.warn(f"{spec} is read as the built-in exemplar, though a file of that name is here too; "
                          f"give ./{spec} to read the file")
        image = builtin(spec.split(":", 1)[1])
        return (image, 8) if with_depth else image
    if is_model_file(spec):
        kind = model_file_kind(spec)
        hint = (" (a checkpoint goes to 'tghop cooc morph', 'tghop cooc edit' or 'tghop baseline cooc EXEMPLAR "
                "--model CHECKPOINT')" if kind == COOC_CHECKPOINT else
                # 0.62: what to do with a model instead (0.61 stopped at "needs an image")
                f" (a model is fitted already: 'tghop synth {spec} -o OUT.png' makes images from it)"
                if kind == "a model file" else checkpoint_note(spec))
        raise TGHopError(f"{spec} is {kind}, not an image; this command needs an image{hint}")
    _refuse_a_slip(spec, BUILTIN)
    return read_image(spec, downscale=downscale, dtype=dtype, with_depth=with_depth,
                      too_large_hint=HINT_DOWNSCALE_OPTION if has_downscale else HINT_DOWNSCALE_YOURSELF)


def _refuse_a_slip(spec, builtins):
    """An exemplar ``spec`` that is no file but a newcomer's slip, refused saying what was meant (0.59; 0.58 said
    only "no such file; check the path"): a built-in exemplar's name without ``builtin:`` (``tghop synth bricks``),
    or a number, the second of ``--size 512 512`` taken for one more SOURCE (with --size typed a usage error, 0.63)."""
    from .options import refuse_split_size, split_size_message

    name = os.fspath(spec)
    if os.path.lexists(name):
        return
    if name in builtins:
        raise InvalidImageError(f"{name}: no such file; the built-in exemplar is builtin:{name}")
    context = click.get_current_context(silent=True)
    refuse_split_size(context, [name])
    if name.isdecimal() and context is not None and any(p.name == "size" for p in context.command.params):
        raise InvalidImageError(split_size_message(name))


def load_mask(path: str, shape, *, label: str = "MASK", image_label: str = "the image", what: str = "hole"):
    """A mask image as an (H, W) bool array: True where its pixels are white (colour channels'
    mean > 0.5). One line when it cannot be read or is not ``shape``'s size (H, W, ...).

    Its alpha channel is not read: where it has transparent pixels, a warning says so and
    to paint the ``what`` (``"hole"``) white on black (a hole painted as transparency was
    "no white pixel" or "leaves too little" without a word why). A mask that is not black and
    white (:func:`tghop.inpaint.grey_share` over :data:`tghop.inpaint.MASK_PICTURE_SHARE`: a photograph, or IMAGE
    and MASK swapped) is warned of likewise: its light pixels are the hole."""
    import warnings

    from ..inpaint import MASK_PICTURE_SHARE, grey_share

    if is_model_file(path):
        raise TGHopError(f"{label} {path} is {model_file_kind(path)}, not an image; give a black and white image")
    mask = read_image(path, too_large_hint=HINT_DOWNSCALE_YOURSELF, keep_alpha=True)  # the colours as without it
    if mask.shape[:2] != tuple(shape[:2]):
        raise TGHopError(f"{label} {path} is {mask.shape[0]}x{mask.shape[1]} but {image_label} is "
                         f"{shape[0]}x{shape[1]}; give a mask of the same size")
    if mask.shape[2] in (2, 4):  # grey or RGB, and alpha
        if (mask[..., -1] < 1).any():
            warnings.warn(f"{label} {path} has transparent pixels, but transparency is not read as the {what} (its "
                          f"alpha channel is ignored; its white pixels are the {what}); paint the {what} white on "
                          "black")
        mask = mask[..., :-1]
    mean = mask.mean(axis=2)
    other = grey_share(mask)
    if other > MASK_PICTURE_SHARE:  # a photograph (or IMAGE and MASK swapped): its light pixels were the hole
        order = " (IMAGE comes first, then MASK)" if label == "MASK" else ""
        warnings.warn(f"{label} {path} is not black and white: {other:.0%} of its pixels are grey or coloured "
                      f"(a picture?), and those lighter than mid-grey are taken as the {what}; paint the {what} white "
                      f"on black{order}")
    return mean > 0.5
