"""Writing output files safely: the path checked before any long work (:func:`check_output_path`),
the file written whole or not at all (:func:`write_atomic`), a symbolic link's target written and the
link kept (:func:`written_file`). Images, models and the batch's files are all written this way."""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path

from ._errors import InvalidImageError

__all__ = ["written_file", "check_output_path", "write_atomic", "temporary_prefix", "write_fix"]


def written_file(path, *, what: str = "image", error=InvalidImageError) -> Path:
    """The file that writing ``path`` replaces: ``path`` itself, or, where ``path`` is a
    symbolic link, the file the link (through a chain of links) points to, so that the link
    stays and its target gets the new content, as ``cp`` and a shell's ``>`` do. A dangling
    link gives the file it names (written if that file's folder exists,
    :func:`check_output_path`); a loop of links is an ``error``.

    Parameters
    ----------
    path : str or os.PathLike
    what : str, what is written, in the error message ("image", "model", ...)
    error : type, the exception class raised

    Returns
    -------
    pathlib.Path : ``path``, or the link's resolved target (nothing is created)
    """
    path = Path(path)
    if not path.is_symlink():
        return path
    target = Path(os.path.realpath(path))
    if target.is_symlink():  # realpath stops at a loop of links
        raise error(f"{path} is a loop of symbolic links; point the link at a file, or give the {what} another name")
    return target


def check_output_path(path, *, what: str = "image", error=InvalidImageError) -> Path:
    """Refuse an output path that is a folder, whose folder does not exist, or where no
    file can be created (read-only or unwritable folder, name too long): checked by
    creating and removing a probe file, before any long work. A symbolic link is checked
    as the file it points to (:func:`written_file`).

    Parameters
    ----------
    path : str or os.PathLike
    what : str, what is written, in the error messages ("image", "model", ...)
    error : type, the exception class raised

    Returns
    -------
    pathlib.Path : the folder the file will be written to (the link's target's, for a link)
    """
    text = os.fsdecode(path)
    if not text.strip():
        raise error(f"the {what}'s file name is empty; give one")
    if text.endswith(("/", os.sep)):  # Path() would drop the slash and write a file of that name
        raise error(f"{text} ends with a slash, as a folder does; give a file name for the {what}")
    path = Path(path)
    try:
        is_dir = path.is_dir()
        target = written_file(path, what=what, error=error)
    except OSError as exc:  # e.g. a name too long
        said = str(path) if len(str(path)) <= 120 else f"{str(path)[:60]}...{str(path)[-40:]}"  # a step's, a map's end
        size = len(os.fsencode(path.name))
        if exc.errno == errno.ENAMETOOLONG and size > 255:
            raise error(f"{said}: the file's name is {size} bytes, more than a name may have ({exc.strerror}); give a "
                        f"shorter name for the {what}") from None
        raise error(f"{said}: cannot write the {what} there ({exc.strerror}); choose another name") from None
    if is_dir:
        raise error(f"{path} is a folder; give a file name for the {what}")
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        if target != path:
            fix = "point the link elsewhere" if directory.exists() else "create that folder or point the link elsewhere"
            raise error(f"{path} is a symbolic link to {target}, whose folder {directory} "
                        f"{'is a file' if directory.exists() else 'does not exist'}; {fix}")
        if directory.exists():
            raise error(f"{directory} is a file, not a folder; give the {what} a path in a folder")
        raise error(f"{directory}: output folder does not exist; create it first")
    limit = _name_max(directory)
    size = len(os.fsencode(target.name))
    if limit is not None and size > limit:
        raise error(f"{path}: the file's name is {size} bytes, more than the {limit} a name may have there; give a "
                    f"shorter name for the {what}")
    try:
        fd, probe = tempfile.mkstemp(prefix=temporary_prefix(target), suffix=".probe", dir=directory)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise error(f"{path}: cannot write the {what} there ({exc.strerror or exc.__class__.__name__}); "
                    "choose another folder or name") from None
    return directory


def _name_max(directory):
    """The most bytes a file's name may have in ``directory`` (255 on most file systems), None where not known."""
    try:
        return int(os.pathconf(directory, "PC_NAME_MAX"))
    except (AttributeError, OSError, ValueError):  # not POSIX, or a file system that does not say
        return None


def temporary_prefix(target) -> str:
    """``.NAME.``, the start of a temporary file's name beside file ``target`` (a probe, the file while written, the
    one it replaces kept aside), ``NAME`` its name cut (whole characters) so that the prefix, 8 random characters and
    a suffix of up to 6 (``.probe``) fit the bytes a name may have there (0.63: 0.62's were the whole name and 14-16
    more, so that a name of 240 to 255 bytes, which the file system takes, was refused as too long). The whole name
    where the folder's limit is not known."""
    target = Path(target)
    name, limit = target.name, _name_max(target.parent if str(target.parent) else ".")
    if limit is not None:
        while name and len(os.fsencode(name)) > limit - 16:
            name = name[:-1]
    return f".{name}."


def write_atomic(path, write, *, what: str = "image", error=InvalidImageError) -> None:
    """Call ``write(fileobj)`` on a temporary file next to ``path``, then move it into place.

    If ``write`` raises, no file (and no partial file) is left at ``path``; an operating
    system error (disk full, ...) becomes one ``error`` line. Where ``path`` is a symbolic
    link, its target is written (:func:`written_file`; the temporary file beside the
    target, so that the move stays atomic) and the link stays.

    Parameters
    ----------
    path : str or os.PathLike, the file to write (checked first by :func:`check_output_path`)
    write : callable, ``write(fileobj)`` writes the content to a binary file object
    what : str, what is written, in the error messages
    error : type, the exception class raised for a bad path or an operating system error
    """
    path = Path(path)
    directory = check_output_path(path, what=what, error=error)
    target = written_file(path, what=what, error=error)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=temporary_prefix(target), suffix=".tmp", dir=directory)
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the usual permissions
        os.replace(tmp, target)
    except BaseException as exc:  # Ctrl-C and the command's SIGTERM/SIGHUP (tghop.cli.common.Terminated) too
        if tmp is None:  # mkstemp failed: nothing to remove
            if isinstance(exc, OSError):
                raise error(f"{path}: cannot write the {what} ({exc.strerror or exc.__class__.__name__}); "
                            f"{write_fix(exc)}") from None
            raise
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError):
            raise error(f"{path}: writing the {what} failed ({exc.strerror or exc.__class__.__name__}), nothing was "
                        f"written; {write_fix(exc)}") from None
        raise


def write_fix(exc: OSError) -> str:
    """The fix a failed write's one line names (0.63; 0.62's said "nothing was written" and no fix): free space for
    a full disk or quota, else another folder."""
    if exc.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)):
        return "free some space there, or write elsewhere"
    return "write elsewhere (another folder or disk)"
