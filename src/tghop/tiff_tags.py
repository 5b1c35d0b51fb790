"""A TIFF file's tag directories checked as Pillow reads them, before it does (for
:func:`tghop.image_decode.open_image`): Pillow warns of a damaged directory as it parses it ("Corrupt EXIF
data", "Tag data larger than file", "Truncated File Read", "Metadata Warning, tag 259 had too many entries"),
with ``warnings.warn``, which on a thread other than the main one reaches the console (the server's uploads, a
batch worker's exemplars): hiding it there would take ``warnings.catch_warnings``, process-wide before Python
3.14. As for a JPEG's damaged EXIF block (0.59), the file is read from a copy in memory that Pillow reads
without a word: each entry it would skip with a warning given a field type it passes over (its value was of no
use: Pillow skipped it), an entry with more values than its tag holds cut to its first (the value Pillow took),
and a next directory past the file's end or cut short dropped (Pillow then failed, "Missing dimensions"). A
first directory cut short is refused in one line (0.59, for files; 0.60 for file objects too: ``is_image``
of an upload in memory)."""

from __future__ import annotations

import io
import os
import struct

from ._errors import InvalidImageError
from ._formats import read_as_it_stands

__all__ = ["quiet_copy", "directory_cut_short", "FIELD_BYTES"]

#: Bytes a value of each field type Pillow reads takes (an entry of another type it passes over without a word).
FIELD_BYTES = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 6: 1, 7: 1, 8: 2, 9: 4, 10: 8, 11: 4, 12: 8, 13: 4, 16: 8}

#: Field types whose values Pillow gives as a tuple of numbers (the others: one string or bytes).
NUMBERS = (3, 4, 5, 6, 8, 9, 10, 11, 12, 13, 16)

#: Directories followed at most (Pillow follows each as it counts a file's pages; a loop it stops silently).
MOST_DIRECTORIES = 65536

#: A field type Pillow passes over without a word.
UNKNOWN_TYPE = 0


class _Cut(Exception):
    """A directory that runs past the file's end."""


def directory_cut_short(source) -> str:
    """The one-line refusal of a TIFF whose first directory runs past the end (``source``: its path or name)."""
    return (f"{os.fsdecode(source)}: not a readable image (a TIFF file, cut short: its first directory ends past "
            "the file's end); save or download it again")


def quiet_copy(source):
    """None where ``source`` (a path, or a binary file object from where it stands, left there) is no TIFF, or a
    TIFF whose directories Pillow reads without a warning; else an :class:`io.BytesIO` of its bytes in which
    Pillow reads them without one (see the module's text). Raises :class:`~tghop.InvalidImageError` for a first
    directory cut short; an unreadable file is left to Pillow (None)."""
    try:
        return read_as_it_stands(source, _copy)
    except InvalidImageError:
        raise
    except (OSError, ValueError, struct.error):  # unreadable: Pillow's error follows
        return None


def _copy(fh, name):
    """:func:`quiet_copy` of the file open as ``fh``, from its start."""
    start = fh.tell()
    head = fh.read(16)
    if head[:4] in (b"II*\x00", b"MM\x00*"):
        big = False
    elif head[:4] in (b"II+\x00", b"MM\x00+") and len(head) == 16:
        big = True
    else:
        return None
    fh.seek(0, io.SEEK_END)
    size = fh.tell() - start
    patches = _patches(_Reader(fh, start, size, head[:2] == b"II", big), name)
    if not patches:
        return None
    fh.seek(start)
    data = bytearray(fh.read())
    for at, value in patches.items():
        data[at:at + len(value)] = value
    return io.BytesIO(bytes(data))


class _Reader:
    """Reads of a (Big)TIFF file's numbers at offsets from its start; :class:`_Cut` past its end."""

    def __init__(self, fh, start, size, little, big):
        self.fh, self.start, self.size, self.big = fh, start, size, big
        self.order = "<" if little else ">"
        self.word = "Q" if big else "I"  # an offset or a count in an entry
        self.entry = 20 if big else 12
        self.inline = 8 if big else 4

    def read(self, at, length):
        if at < 0 or at + length > self.size:
            raise _Cut
        self.fh.seek(self.start + at)
        data = self.fh.read(length)
        if len(data) < length:
            raise _Cut
        return data

    def number(self, at, fmt):
        return struct.unpack(self.order + fmt, self.read(at, struct.calcsize(fmt)))[0]

    def pack(self, fmt, value):
        return struct.pack(self.order + fmt, value)


def _patches(tiff, name):
    """{offset: bytes} that make Pillow read every directory of ``tiff`` (a :class:`_Reader`) without a warning."""
    patches = {}
    pointer = 8 if tiff.big else 4  # where the offset of the next directory is
    at = tiff.number(pointer, tiff.word)
    seen, spans, remaining = set(), [], tiff.size  # Pillow's budget of values out of entries, over all directories
    while at and at not in seen and len(seen) < MOST_DIRECTORIES:
        try:
            entries = tiff.number(at, "Q" if tiff.big else "H")
            first = at + (8 if tiff.big else 2)
            tiff.read(first, tiff.entry * entries + tiff.inline)  # the directory and its next offset whole
        except _Cut:
            if not seen:
                raise InvalidImageError(directory_cut_short(name)) from None
            patches[pointer] = tiff.pack(tiff.word, 0)  # one page fewer, as Pillow could read none after it
            break
        end = first + tiff.entry * entries + tiff.inline
        if any(at < stop and start < end for start, stop in spans):  # a directory read into another (garbage, or
            patches[pointer] = tiff.pack(tiff.word, 0)  # a hostile file): not followed, nor patched
            break
        seen.add(at)
        spans.append((at, end))
        subs = [] if len(seen) == 1 else None  # the first page's Exif and GPS directories, which Pillow reads too
        remaining -= _directory(tiff, first, entries, remaining, patches, subs=subs)
        for entry, offset, group in subs or ():
            _sub_directory(tiff, entry, offset, group, spans, patches)
        pointer = end - tiff.inline
        at = tiff.number(pointer, tiff.word)
    return patches


def _sub_directory(tiff, entry, at, group, spans, patches):
    """Add to ``patches`` what the Exif or GPS directory (``group``: its tag) at offset ``at`` needs, which the
    first directory's ``entry`` points to: that entry passed over where it is cut short or lies in another."""
    try:
        entries = tiff.number(at, "Q" if tiff.big else "H")
        first = at + (8 if tiff.big else 2)
        end = first + tiff.entry * entries + tiff.inline
        tiff.read(first, end - first)
    except _Cut:
        end = None
    if end is None or any(at < stop and start < end for start, stop in spans):
        patches[entry + 2] = tiff.pack("H", UNKNOWN_TYPE)
        return
    spans.append((at, end))
    _directory(tiff, first, entries, tiff.size, patches, group=group)


def _directory(tiff, first, entries, limit, patches, *, group=None, subs=None):
    """Add to ``patches`` what one directory (its ``entries`` from offset ``first``; ``group``: the Exif or GPS
    directory's tag, or None) needs; the bytes of its values Pillow reads out of their entries (its budget
    ``limit``: it warns of values beyond it). ``subs``: a list given the Exif and GPS directories the directory
    points to, (its entry, their offset, their tag)."""
    from PIL import TiffTags

    stored, total, read = set(), 0, 0
    for entry in range(first, first + tiff.entry * entries, tiff.entry):
        tag, kind, count = struct.unpack(tiff.order + "HH" + tiff.word, tiff.read(entry, 4 + tiff.inline))
        if tag in stored or kind not in FIELD_BYTES:
            continue
        value = entry + 4 + tiff.inline
        size = count * FIELD_BYTES[kind]
        if size > tiff.inline:
            offset = tiff.number(value, tiff.word)
            total += size
            if offset >= 2 ** 63 or total > limit or offset + size > tiff.size:  # Pillow: "Tag data larger ..."
                patches[entry + 2] = tiff.pack("H", UNKNOWN_TYPE)
                total -= size
                continue
            read += size
        if not size:
            continue
        stored.add(tag)
        if subs is not None and tag in (34665, 34853) and kind in (4, 13) and count == 1:
            subs.append((entry, tiff.number(value, "I"), tag))
        if count > 1 and kind in NUMBERS and tag != 262 and TiffTags.lookup(tag, group).length == 1:
            patches[entry + 4] = tiff.pack(tiff.word, 1)  # "Metadata Warning, tag ... had too many entries"
            unit = FIELD_BYTES[kind]
            if size > tiff.inline >= unit:  # its first value into the entry, where one value of its type lies
                patches[value] = tiff.read(tiff.number(value, tiff.word), unit).ljust(tiff.inline, b"\x00")
            if size > tiff.inline:  # the copy's value: one, in its entry or still out of it
                kept = unit if unit > tiff.inline else 0
                total, read = total - size + kept, read - size + kept
    return read
