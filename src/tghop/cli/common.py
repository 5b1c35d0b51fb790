"""What every command of the ``tghop`` command line shares, and the map of where it is: each name below
imports from here, as up to 0.63, when this module held them all (0.64 split it by what they do):

* :mod:`tghop.cli.errors`: how a command fails and stops (:func:`user_errors`: a :class:`~tghop.TGHopError`
  to one line and exit status 1; :func:`fail`, :class:`Terminated`, :func:`stop_message`, ...);
* :mod:`tghop.cli.progress`: the library's progress shown as bars or log lines (:class:`Progress`);
* :mod:`tghop.cli.inputs`: exemplars, image files and masks read (:func:`load_exemplar`, :func:`is_builtin`,
  :func:`read_image`, :func:`load_mask`, ...);
* :mod:`tghop.cli.outputs`: outputs checked before any work and ``--count``'s and ``--stages``' files
  (:func:`check_output`, :func:`check_outputs`, :func:`check_model_output`, :func:`stage_paths`, ...);
* :mod:`tghop.cli.materials`: a whole material's maps named, checked and written (:func:`write_materials`, ...);
* here: a fitted model in words (:func:`summary`), ``--seed`` drawn and told (:func:`draw_seed`,
  :func:`tell_seed`) and a command's ``Examples:`` (:func:`examples`).

The commands' modules (:mod:`tghop.cli.texture`, :mod:`tghop.cli.guided`, :mod:`tghop.cli.inpaint`,
:mod:`tghop.cli.evaluation`, :mod:`tghop.cli.cooc`, :mod:`tghop.cli.batch`, :mod:`tghop.cli.serve`)
stand on this module and on :mod:`tghop.cli.options`; the group (:mod:`tghop.cli.group`) stands on them.
Heavy modules (NumPy's linear algebra users, Pillow, scikit-learn, SciPy) are imported inside the
functions that need them, so ``--help``, ``--version`` and ``info`` answer at once.
"""

from __future__ import annotations

import click

from .._errors import terminal_line
from .._formats import is_model_file
from .errors import Terminated, drop_stdout, fail, os_error_message, output_gone, stop_message, user_errors
from .inputs import HINT_DOWNSCALE_OPTION, is_builtin, load_exemplar, load_mask, quiet_tifffile, read_image
from .materials import (map_names, material_outputs, material_stage_files, refuse_albedo_as_map,
                        refuse_colour_map_out_of_place, write_materials)
from .outputs import (MATERIAL_STAGES, STAGES, check_model_output, check_output, check_outputs, check_stdout,
                      count_outputs, numbered, save_with_stages, stage_paths, tell_steps, warn_lost_depth,
                      warn_written_with_8)
from .progress import Progress

__all__ = ["Progress", "fail", "Terminated", "stop_message", "user_errors", "load_exemplar", "is_builtin",
           "is_model_file", "summary", "check_output", "check_outputs", "check_model_output", "numbered", "load_mask",
           "check_stdout", "warn_lost_depth", "warn_written_with_8", "read_image",
           "quiet_tifffile", "examples", "tell_steps", "STAGES", "MATERIAL_STAGES", "stage_paths",
           "material_stage_files", "save_with_stages",
           # re-exported too, as the commands import them from here (0.64)
           "drop_stdout", "output_gone", "os_error_message", "HINT_DOWNSCALE_OPTION", "count_outputs", "map_names",
           "material_outputs", "refuse_albedo_as_map", "refuse_colour_map_out_of_place", "write_materials"]


def layout_summary(model) -> str:
    """The coarse layout a fitted model holds, in words, and why it is coarser than asked
    or none: the exemplar's size, or, where that allowed it, a sample mask (``--exclude``,
    an inpainted hole) that left too few of its patches."""
    from ..layout import fits
    from ..synthesis import CoarseLayout

    if model.layout_factor is None:
        return "none"
    f = None if model.layout_ is None else model.layout_.factor
    p = CoarseLayout().patch_size if model.layout_ is None else model.layout_.patch_size
    if f == model.layout_factor:
        return f"a coarse model at 1/{f} scale"
    small = not fits(model.exemplar_shape_, 2 if f is None else model.layout_factor, p)
    why = "the exemplar is too small for" if small else "too little of the exemplar lies outside the mask for"
    if f is None:
        return f"none ({why} one)"
    return f"a coarse model at 1/{f} scale (asked {model.layout_factor}: {why} it)"


def summary(model, params=None) -> str:
    """Dimensions, core model and parameter total of a fitted model (``params``: its
    :meth:`~tghop.TGHop.n_parameters`, when the caller already has it)."""
    from ..parameter_count import PAPER_MODULES

    d = model.dims_
    params = model.n_parameters() if params is None else params
    paper = params[PAPER_MODULES]  # what compares with the paper's total: the total holds our additions too
    dims = " -> ".join(f"D{i}={d[f'D{i}']}" for i in range(len(model.channels_) + 1))
    ks = ", ".join(f"K{i + 1}={k}" for i, k in enumerate(model.channels_))
    classes = getattr(model, "classes_", None)
    return (
        f"dimensions: {dims}, D_r={d['D_r']}  ({ks})\n"
        f"core model: N={d['N']} clusters, F={d['F']} CDFs, W={d['W']} codewords\n"
        f"colour classes: {classes.n_classes if classes is not None else 'none (fitted with --colour-classes 0)'}\n"
        f"layout: {layout_summary(model)}\n"
        f"parameters: {params['total']['stored']:,} stored; the paper's modules {paper['stored']:,} "
        f"({paper['paper']:,} by the paper's formulas)"
    )


def draw_seed(seed):
    """``(seed, drawn)``: --seed as given, or one drawn from the system's entropy where none was (0.59), so
    that :func:`tell_seed` can say it: an image made without --seed could not be made again (at another
    depth, with --stages, once more after an edit elsewhere)."""
    if seed is not None:
        return seed, False
    import numpy as np

    return int(np.random.SeedSequence().generate_state(1)[0]), True


def tell_seed(seed, drawn, what="the same image"):
    """After a run without --seed, one line giving the seed drawn (:func:`draw_seed`) and the option that
    makes ``what`` again; nothing where --seed was given."""
    if drawn:
        click.echo(terminal_line(f"seed {seed} drawn (no --seed given): --seed {seed} makes {what} again"), err=True)


def examples(*lines: str) -> str:
    """A command's ``Examples:`` (its help's epilog, the last lines ``--help`` prints), kept line for line:
    each command as it is typed, each ``# ...`` line saying what the command under it does. A newcomer
    pastes them: a comment on a command's own line in parentheses (``cooc train ... (small config ...)``,
    0.58) stops the shell. tests/test_help_examples.py runs those whose inputs are built in."""
    return "\b\nExamples:\n" + "\n".join(f"  {line}" for line in lines)
