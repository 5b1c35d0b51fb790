"""Where a command writes, checked before any work: an image's ``-o`` (:func:`check_output`), a model's
(:func:`check_model_output`), the standard output (:func:`check_stdout`), no output over an input or
another output (:func:`check_outputs`); ``--count``'s numbered files (:func:`count_outputs`), ``--stages``'
files (:data:`STAGES`, :func:`stage_paths`, :func:`save_with_stages`, :func:`tell_steps`), and the warnings
of an image written with fewer bits than it had (:func:`warn_written_with_8`, :func:`warn_lost_depth`).

It stands on :mod:`tghop.cli.inputs` (which paths are files) and on the library (0.64: part of
:mod:`tghop.cli.common`, which re-exports its names).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import click

from .._errors import InvalidImageError, TGHopError, terminal_line
from .._formats import READ_SUFFIXES
from .inputs import is_builtin

__all__ = ["check_stdout", "check_output", "check_outputs", "check_model_output", "count_outputs", "numbered", "STAGES",
           "MATERIAL_STAGES", "stage_paths", "save_with_stages", "tell_steps", "warn_written_with_8", "warn_lost_depth"]


def check_stdout(what: str):
    """Refuse, before any work, a command whose result goes to the standard output when
    that is closed (``>&-``: Python sets ``sys.stdout`` to None, and ``click.echo`` would
    drop the result without a word). ``what``: what the command writes there."""
    if sys.stdout is None:
        raise TGHopError(f"the standard output is closed, and {what} goes there; leave it open "
                         "or redirect it to a file (> FILE)")


def check_output(path: str, allow_stdout=False, depth=None, *, made=False):
    """Refuse, before any work, an image output ``path`` (``-o``) that cannot be written: stdout
    where the command writes none or to a terminal, an extension tghop does not write, a folder;
    with ``depth`` (``--depth``), a depth the output's format cannot hold (usage errors: two options
    that clash, or -o's bad value; a folder too, 0.62: 0.61 exited 1). ``made``: a file the command names
    from -o's (--count's, --stages', a material's maps), whose folder is told to be moved."""
    from ..imageio import check_depth, check_output_path, output_format

    if path != "-" and os.path.isdir(path):
        if made:
            raise click.UsageError(f"{path} is a folder, where this command writes a file of that name (named from "
                                   "-o's); move or remove that folder, or give -o another name")
        raise click.UsageError(f"{path} is a folder; give a file name for the image in it "
                               f"(e.g. {os.path.join(path, 'texture.png')})")

    if path == "-" and not allow_stdout:
        raise click.UsageError("this command cannot write to stdout; give a file name with -o")
    if path == "-" and sys.stdout is None:  # before the work, not when the image is written
        raise TGHopError("-o -: the standard output is closed; give a file name instead")
    if path == "-" and sys.stdout.isatty():  # a PNG's bytes drawn as garbage in the terminal
        raise click.UsageError("-o -: the standard output is a terminal, which shows no image; redirect it "
                               "(-o - > out.png, or | another command) or give a file name")
    try:
        output_format(path)
    except InvalidImageError as exc:  # an extension tghop does not write: -o's bad value, a usage error
        raise click.UsageError(str(exc)) from None
    if path != "-":
        check_output_path(path)
    if depth is not None:
        try:
            check_depth(path, depth)
        except InvalidImageError as exc:  # --depth 16 -o x.jpg: a clash of options, as an unknown extension
            raise click.UsageError(str(exc)) from None


def _file_key(path: str):
    """What names one file: device and inode of an existing file (so hard and symbolic
    links, ``./x`` and ``x`` are the same), otherwise the resolved absolute path."""
    try:
        st = os.stat(path)
        return ("inode", st.st_dev, st.st_ino)
    except OSError:
        pass
    try:
        return ("path", str(Path(path).resolve()))
    except (OSError, RuntimeError):  # a symlink loop, a name too long: as written
        return ("path", os.path.abspath(path))


def check_outputs(outputs, inputs=()):
    """Refuse an output that is one of the command's inputs or another of its outputs,
    before anything is read or written.

    Parameters
    ----------
    outputs, inputs : sequences of (label, path)
        Compared as files (:func:`_file_key`: the same inode when they exist, else the
        same resolved path). ``label`` says where the path came from on the command line
        (``"-o"``, ``"--save-model"``, ``"--stages"``, ``"EXEMPLAR"``, ...). ``None``,
        ``-`` (stdout or stdin) and ``builtin:NAME`` are not files and are skipped, and so
        are inputs that do not exist (their readers say so).

    Raises
    ------
    TGHopError
        One line naming both and the fix.
    """
    def files(pairs):
        return [(label, str(path)) for label, path in pairs
                if path is not None and str(path) != "-" and not is_builtin(str(path))]

    seen = {}
    for label, path in files(inputs):
        if os.path.lexists(path):  # a missing input is its reader's "no such file", not an overwrite
            seen.setdefault(_file_key(path), (label, path, True))
    for label, path in files(outputs):  # one key each: --count 1000 stays linear
        key = _file_key(path)
        if key in seen:
            other_label, other, is_input = seen[key]
            if is_input:
                raise TGHopError(f"{path}: {label} would overwrite {other_label}, an input of this command; "
                                 f"give {label} another name")
            what = f"{other_label} and {label}" if other_label != label else f"two outputs of {label}"
            raise TGHopError(f"{path} is {what}: one would be written over the other; give each its own name")
        seen[key] = (label, path, False)


def check_model_output(path: str, label: str = "-o", *, suffix: str = ".npz", what: str = "model"):
    """Refuse a model (or checkpoint) output that cannot be one, before any work: ``-``
    (a model cannot go to stdout), a name without ``suffix`` (an image extension or none:
    ``-o model`` is refused, not renamed, so the name the user gave is the file there is),
    a folder or an unwritable place (:func:`tghop.imageio.check_output_path`).

    ``tghop cooc train`` calls it with ``suffix=".pt", what="checkpoint"``.
    """
    from .._errors import ModelFileError
    from ..imageio import check_output_path

    if str(path) == "-":
        raise click.UsageError(f"{label} -: a {what} cannot go to stdout; give a file name, e.g. {label} "
                               f"{what}{suffix}")
    if not str(path).strip():  # Path("") is the current folder, which has no name to add to
        raise ModelFileError(f"{label}: the {what}'s file name is empty; give one, e.g. {label} {what}{suffix}")
    p = Path(path)
    ext = p.suffix.lower()
    if p.is_dir():  # -o models/: "name it models.npz" wrote beside the folder; a usage error (0.62; 0.61: exit 1)
        raise click.UsageError(f"{label} {path} is a folder; give a {what} file name in it (e.g. "
                               f"{os.path.join(path, what + suffix)})")
    if ext != suffix:
        fixed = p.with_suffix(suffix) if ext in READ_SUFFIXES else p.with_name(p.name + suffix)
        why = (f"{ext} is an image extension, but {label} writes a {what}" if ext in READ_SUFFIXES
               else f"a {what} file's name ends in {suffix}")
        # an option's bad value, as an image's -o x.webp: a usage error (0.63; 0.62: exit status 1)
        raise click.UsageError(f"{label} {path}: {why}; name it {fixed}")
    check_output_path(path, what=what, error=ModelFileError)


def tell_steps(paths, count, maps=False):
    """The line naming --stages' files (``paths``: the first output's, those written; nothing where none), said
    after the line naming the output, by every command alike (0.62; 0.61's textures said it first, materials and
    morph after)."""
    names = [os.path.basename(str(p)) for p in paths]
    if names:
        click.echo(terminal_line(f"steps written beside {'it' if count == 1 else 'each'}"
                                 f"{', each with its maps' if maps else ''}: {', '.join(names)}"), err=True)


def count_outputs(output: str, count: int) -> list:
    """The files of ``count`` images (``--count``): -o's own for one, else numbered (:func:`numbered`:
    ``out_1.png``, ...); ``-o -`` (stdout) takes one only, else a usage error."""
    if count == 1:
        return [output]
    if output == "-":
        raise click.UsageError("--count > 1 cannot write to stdout; give a file name with -o")
    return numbered(output, count)


#: The steps ``--stages`` writes (synth, inpaint, extend), as ``TGHop.synthesize(return_stages=True)`` and
#: :func:`tghop.inpaint.inpaint` name them.
STAGES = ("guide", "quilt", "seams", "refine", "patch refine", "colour", "levels")
#: A material's (``Material.synthesize(return_stages=True)``; 0.61): "maps" its last, the maps written.
MATERIAL_STAGES = ("guide", "quilt", "seams", "refine", "patch refine", "colour", "maps")


def stage_paths(path, names=STAGES):
    """``OUT_<step>.png`` for each step of ``names`` beside the output ``path``."""
    path = Path(path)
    return {name: str(path.with_name(f"{path.stem}_{name.replace(' ', '-')}{path.suffix}")) for name in names}


def save_with_stages(image, path, depth, steps, paths, progress=None):
    """``image`` at ``path`` with its --stages files as one set, every file or none (0.62: 0.61 wrote each step as
    it came, and a full disk left the steps before it, the error saying nothing was written): ``steps``
    ``{step: image}``, ``paths`` ``{step: file}`` (a step not in it is not written: the patch pool)."""
    from ..imageio import save_images

    save_images([(step, paths[name], depth) for name, step in steps.items() if name in paths]
                + [(image, path, depth)], progress=progress)


def numbered(path: str, count: int):
    p = Path(path)
    width = len(str(count))
    return [str(p.with_name(f"{p.stem}_{i:0{width}d}{p.suffix}")) for i in range(1, count + 1)]


def warn_written_with_8(label: str, spec: str, output=None, *, several=()):
    """The warning of a command that writes 8 bits without ``--depth`` (``synth``, ``baseline``)
    when its input ``label spec`` has more; to an ``output`` of a format of 8 bits only (JPEG),
    the fix names a format that holds 16 first (``--depth 16`` alone is refused there).

    ``several``: instead, the deep ones of several inputs as (label, spec) pairs (``label`` and
    ``spec`` None), all named in the one warning: ``SOURCE 1 (a.png) and SOURCE 3 (c.tif) have ...``."""
    import warnings

    from .._formats import DEPTHS, extensions
    from ..imageio import output_format

    fix = "pass --depth 16 to keep them"
    if output is not None and 16 not in DEPTHS[output_format(output)]:
        fix = f"name the output {extensions([f for f, held in DEPTHS.items() if 16 in held])} and {fix}"
    named = [f"{name} ({path})" for name, path in several] or [f"{label} {spec}"]
    warnings.warn(f"{_and(named)} {'has' if len(named) == 1 else 'have'} more than 8 bits a channel, but the image "
                  f"is written with 8; {fix}")


def _and(names) -> str:
    """``a``, ``a and b``, ``a, b and c``: the names of a warning, in one phrase."""
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def warn_lost_depth(items, path, depth, noun=None):
    """One warning naming the images written to ``path``'s format with fewer bits a channel
    than they had (a 16-bit map as JPEG, a float one as PNG), as ``synth`` warns of a deep
    exemplar written with 8: ``items`` are ``(label, own depth, written depth)``; none when
    ``depth`` (``--depth``) was given (the user chose it). ``noun`` (``"map"``) goes before
    the labels, with an s for several."""
    import warnings

    from .._formats import DEPTHS, extensions
    from ..imageio import output_format

    lost = [(label, own) for label, own, written in items if written < own]
    if depth is not None or not lost:
        return
    fmt = output_format(path)
    keep = extensions([f for f, held in DEPTHS.items() if max(own for _, own in lost) in held])
    names = [f"{label} ({'float' if own == 32 else f'{own}-bit'})" for label, own in lost]
    named = _and(names)
    if noun:
        named = f"{noun}{'s' if len(names) > 1 else ''} {named}"
    warnings.warn(f"{named} {'has' if len(names) == 1 else 'have'} more bits a channel than {fmt} holds, but "
                  f"{'is' if len(names) == 1 else 'are'} written with {max(DEPTHS[fmt])}; name the output {keep} "
                  "to keep them")
