"""The bounds a zip archive given as a model file (``.npz``) or a co-occurrence checkpoint (``.pt``) is held to
before NumPy or PyTorch reads it: its members' count and its directory's size (:func:`too_many_members`, from
the few bytes of its end record) and what its members unpack to against the file's size
(:func:`unpacks_too_far`, a decompression bomb). :func:`check_archive_bounds` runs both and words the refusal
once for both readers (:func:`tghop.modelfile.load_model`, :func:`tghop.cooc.checkpoints.read`; 0.58 wrote it out
in each, in other words). :func:`tghop._formats.model_file_kind` names an archive of too many members by
:func:`too_many_members`' words, and the server's upload check (:mod:`tghop.server.safety`) counts members against
:data:`MAX_MEMBERS`. Only the standard library is imported, and only when a file is checked."""

from ._errors import ModelFileError

__all__ = ["MAX_UNPACK_RATIO", "UNPACK_SLACK", "MAX_MEMBERS", "MAX_DIRECTORY_BYTES", "zip_directory",
           "too_many_members", "unpacks_too_far", "check_archive_bounds", "array_declaring_more"]

#: The most a model file's or checkpoint's members may unpack to, as a multiple of the file's size
#: (plus :data:`UNPACK_SLACK` bytes): save_model and torch.save store them uncompressed (1x), and a
#: model's floats deflated by another program are at most a few times smaller. A zip bomb (deflated
#: zeros, 1000x: a 1 MB file of 1 GB) is refused from the sizes its directory declares, which NumPy's
#: and PyTorch's readers do not read past, before any is unpacked (0.56 unpacked it all, and only
#: then found it was not a model).
MAX_UNPACK_RATIO = 20
UNPACK_SLACK = 64 * 1024**2


#: The most members a model file or checkpoint may have (a model file has tens, a material's a few hundred, a
#: checkpoint one per tensor), and the most bytes its zip directory may take (a member's entry is 46 bytes and
#: its name: 1 KB each is ample). The server refuses an upload over them too (:mod:`tghop.server.safety`).
MAX_MEMBERS = 4096
MAX_DIRECTORY_BYTES = MAX_MEMBERS * 1024


def zip_directory(path):
    """``(members, directory bytes)`` as the end record of the zip archive at ``path`` (a path or a binary
    file object) declares them, ZIP64's where it defers to that; None where it has none in its last 64 KiB
    (not an archive, or cut short: the reader's own error says so). Reads a few bytes at the file's end,
    whatever the archive holds: :mod:`zipfile` parses every entry of the directory first (a million empty
    members: 51 MB, many seconds and 470 MB before 0.58 refused them)."""
    import struct

    fh = path if hasattr(path, "read") else open(path, "rb")
    try:
        size = fh.seek(0, 2)
        start = max(0, size - 22 - 0xFFFF)
        fh.seek(start)
        tail = fh.read()
        at = tail.rfind(b"PK\x05\x06")
        if at < 0 or len(tail) - at < 22:
            return None
        members, directory = struct.unpack("<HI", tail[at + 10:at + 16])
        if (members == 0xFFFF or directory == 0xFFFFFFFF) and at >= 20 and tail[at - 20:at - 16] == b"PK\x06\x07":
            fh.seek(struct.unpack("<Q", tail[at - 12:at - 4])[0])
            record = fh.read(56)  # ZIP64's end record: members at 32, directory bytes at 40
            if len(record) == 56 and record[:4] == b"PK\x06\x06":
                members, directory = struct.unpack("<QQ", record[32:48])
        return members, directory
    except (OSError, ValueError, OverflowError):
        return None
    finally:
        if fh is not path:
            fh.close()
        else:
            fh.seek(0)


def too_many_members(path) -> str | None:
    """Why the zip archive at ``path`` is refused unread, its directory not parsed: it lists more than
    :data:`MAX_MEMBERS` members or takes more than :data:`MAX_DIRECTORY_BYTES` (from its end record alone,
    :func:`zip_directory`), in words for "PATH: ...; FIX"; None otherwise."""
    found = zip_directory(path)
    if found is None:
        return None
    members, directory = found
    if members > MAX_MEMBERS:
        return f"a zip archive of {members:,} members (a model file or checkpoint has at most {MAX_MEMBERS:,})"
    if directory > MAX_DIRECTORY_BYTES:
        return (f"a zip archive whose directory takes {directory / 1024**2:,.0f} MB (a model file's or "
                f"checkpoint's takes at most {MAX_DIRECTORY_BYTES // 1024**2} MB)")
    return None


def unpacks_too_far(path) -> str | None:
    """Why the zip archive at ``path`` (or in a binary file object) is refused unread (its members unpack to more than
    :data:`MAX_UNPACK_RATIO` times its size plus :data:`UNPACK_SLACK`), in words for
    "PATH: ...; FIX"; None where it is within that or is not a readable archive (the reader's
    own error then says what it is)."""
    import os
    import zipfile

    try:
        with zipfile.ZipFile(path) as archive:
            unpacked = sum(member.file_size for member in archive.infolist())
        size = path.seek(0, os.SEEK_END) if hasattr(path, "seek") else os.path.getsize(path)
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, NotImplementedError):
        return None
    if unpacked <= MAX_UNPACK_RATIO * size + UNPACK_SLACK:
        return None
    return (f"its contents unpack to {unpacked / 1024**2:,.0f} MB from a file of {size / 1024**2:,.1f} MB "
            "(a decompression bomb?)")


def check_archive_bounds(path, label, what: str, fix: str) -> None:
    """Refuse the zip archive at ``path`` (a path, or a binary file object at its start) before its reader parses
    it: a :class:`~tghop.ModelFileError` "LABEL: WHY, not WHAT tghop wrote; FIX" where it has too many members
    or too large a directory (:func:`too_many_members`, checked first: its end record alone is read) or unpacks
    too far (:func:`unpacks_too_far`). ``label``: how messages name the file; ``what``: the kind of file the
    caller reads ("a model file", "a checkpoint"); ``fix``: the caller's advice ("give a model file tghop
    wrote, or fit the model again"). Anything else (not an archive, cut short) passes: the reader's own error
    says what it is."""
    why = too_many_members(path) or unpacks_too_far(path)
    if why:
        raise ModelFileError(f"{label}: {why}, not {what} tghop wrote; {fix}")


def array_declaring_more(path):
    """Why NumPy could not allocate an array of the model file at ``path`` (a path or a binary file object, left
    at its start), in words: "its array NAME declares shape (3, 32, 32, 4000000000) of float32, 49 TB, but holds
    1,000 bytes" for the first ``.npy`` member whose header declares more bytes than the member holds (0.59 said
    "cannot read it: MemoryError", which reads as the machine's shortage); None where none does."""
    import zipfile

    import numpy as np

    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                if not info.filename.endswith(".npy"):
                    continue
                with archive.open(info) as member:
                    version = np.lib.format.read_magic(member)
                    read_header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                                   else np.lib.format.read_array_header_2_0)
                    shape, _, dtype = read_header(member, max_header_size=10000)
                    holds = info.file_size - member.tell()
                declares = int(np.prod(shape, dtype=object)) * dtype.itemsize
                if declares > holds:
                    return (f"its array {info.filename[:-4][:60]!r} declares shape {shape} of {dtype}, "
                            f"{_bytes(declares)}, but holds {holds:,} bytes")
    except Exception:  # noqa: BLE001 - any other damage: the reader's own words stand
        return None
    finally:
        if hasattr(path, "seek"):
            path.seek(0)
    return None


def _bytes(n) -> str:
    """``n`` bytes in words: "49 TB", "3.2 GB", "12 MB", "900 bytes"."""
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= size:
            return f"{n / size:.2g} {unit}" if n < 10 * size else f"{n / size:,.0f} {unit}"
    return f"{n:,} bytes"
