"""TIFF files whose tag directories are damaged, written byte by byte in code: read (or refused in one line)
without Pillow's warnings of them ("Tag data larger than file", "Truncated File Read", "Corrupt EXIF data",
"Metadata Warning, tag ... had too many entries") on any thread, with no warnings filter or handler of the
process changed (:mod:`tghop.tiff_tags`, 0.60; 0.59 let them reach the console from the server's and a batch
worker's threads)."""

import io
import struct
import sys
import threading
import warnings

import numpy as np
import pytest

from tghop.imageio import is_image, load_image

WIDTH, HEIGHT = 12, 10

#: Bytes of one value of each field type the tests write.
UNIT = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 7: 1}


def pixels():
    return (np.arange(HEIGHT * WIDTH * 3).reshape(HEIGHT, WIDTH, 3) * 7 % 256).astype(np.uint8)


def tiff_bytes(extra=(), *, order="<", second=None, cut_second=0, next_offset=None, replace=None):
    """An uncompressed RGB TIFF (``pixels()``): its directory at offset 8, out-of-line values after it, the
    pixels last. ``extra``: more entries (tag, type, count, value), the value a list of numbers (written
    after the directory where they take over 4 bytes) or ("at", offset) for an entry pointing at ``offset``
    as it stands; ``replace``: {tag: (type, count, value)} for the usual entries. ``second``: the entries of a
    second directory (the same pixels; its own extra entries), appended, less its last ``cut_second`` bytes;
    ``next_offset``: the first directory's next-directory offset instead."""
    data = pixels().tobytes()
    entries = {256: (3, 1, [WIDTH]), 257: (3, 1, [HEIGHT]), 258: (3, 3, [8, 8, 8]), 259: (3, 1, [1]),
               262: (3, 1, [2]), 273: (4, 1, ["pixels"]), 277: (3, 1, [3]), 278: (3, 1, [HEIGHT]),
               279: (4, 1, [len(data)])}
    entries.update(replace or {})

    def directory(extra_entries, at):
        rows = dict(entries)
        rows.update({tag: (kind, count, value) for tag, kind, count, value in extra_entries})
        size = 2 + 12 * len(rows) + 4
        values, packed = b"", []
        for tag in sorted(rows):
            kind, count, value = rows[tag]
            if isinstance(value, tuple):  # ("at", offset)
                packed.append(struct.pack(order + "HHII", tag, kind, count, value[1]))
                continue
            if value == ["pixels"]:
                packed.append((tag, kind, count))
                continue
            raw = b"".join(struct.pack(order + {1: "B", 3: "H", 4: "I", 5: "II"}[kind], *(v if kind == 5 else (v,)))
                           for v in value) if kind != 2 else value[0]
            if len(raw) <= 4:
                packed.append(struct.pack(order + "HHI", tag, kind, count)[:8] + raw.ljust(4, b"\0"))
            else:
                packed.append(struct.pack(order + "HHII", tag, kind, count, at + size + len(values)))
                values += raw + b"\0" * (len(raw) % 2)
        return size, values, packed

    size, values, packed = directory(extra, 8)
    pixel_at = 8 + size + len(values)
    second_at = pixel_at + len(data)

    def finish(packed_rows, next_at):
        rows = [row if isinstance(row, bytes) else struct.pack(order + "HHII", *row, pixel_at) for row in packed_rows]
        return struct.pack(order + "H", len(rows)) + b"".join(rows) + struct.pack(order + "I", next_at)

    first_next = next_offset if next_offset is not None else (second_at if second is not None else 0)
    blob = (b"II*\0" if order == "<" else b"MM\0*") + struct.pack(order + "I", 8) + finish(packed, first_next)
    blob += values + data
    if second is not None:
        _, values2, packed2 = directory(second, second_at)
        blob += finish(packed2, 0) + values2
        blob = blob[:len(blob) - cut_second]
    return blob


#: Damaged directories Pillow warned of as it read them (0.59), read whole now without a word.
DAMAGED = {
    "a value past the end": dict(extra=[(270, 2, 40, ("at", 100000))]),  # "Truncated File Read", the rest lost
    "a value past the end, big-endian": dict(extra=[(270, 2, 40, ("at", 100000))], order=">"),
    "a huge count": dict(extra=[(270, 2, 0x7FFFFFF0, ("at", 40))]),  # "Tag data larger than file"
    "a colour profile past the end": dict(extra=[(34675, 7, 500, ("at", 100000))]),
    "two values of a one-value tag": dict(replace={259: (3, 2, [1, 1])}),  # "Metadata Warning, tag 259 had ..."
    "three values of a one-value tag": dict(replace={277: (3, 3, [3, 3, 3])}),  # out of the entry
    "two values of the width": dict(replace={256: (3, 2, [WIDTH, WIDTH])}),  # tifffile: NumPy's ValueError (0.59)
    "an Exif directory past the end": dict(extra=[(34665, 4, 1, [100000])]),  # "Corrupt EXIF data" (on load)
    "a GPS directory past the end": dict(extra=[(34853, 4, 1, [100000])]),
    "a next directory past the end": dict(next_offset=100000),  # "Corrupt EXIF data" as the pages are counted
    "a second page's value past the end": dict(second=[(270, 2, 40, ("at", 100000))]),
    "a second page cut short": dict(second=[(270, 2, 40, ("at", 100000))], cut_second=10),
    "a second page with a huge count": dict(second=[(270, 2, 0x7FFFFFF0, ("at", 40))]),
}


def shown_while(read, where):
    """What ``read()`` returns and the warnings shown (the process's handler watched) while it runs ``where``."""
    from tghop._errors import collect_warnings

    got, shown, kept = [], [], []

    def run():
        with collect_warnings() as collected:  # as the server and a batch worker read
            got.append(read())
        kept.extend(str(w) for w in collected)

    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = lambda message, *args, **kwargs: shown.append(str(message))
        before = (list(warnings.filters), warnings.showwarning)
        if where == "main thread":
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                run()
            shown.extend(str(w.message) for w in caught)
        else:
            reader = threading.Thread(target=run)
            reader.start()
            reader.join()
        after = (list(warnings.filters), warnings.showwarning)
    assert before == after
    return got[0], shown, kept


@pytest.mark.parametrize("where", ["main thread", "another thread"])
@pytest.mark.parametrize("case, reader", [(case, reader) for case in DAMAGED for reader in ("tifffile", "Pillow")
                                          if reader == "Pillow" or not ("directory past" in case or "page" in case)])
def test_a_damaged_tiff_directory_is_read_without_pillow_s_warnings_on_any_thread(tmp_path, monkeypatch, case, where,
                                                                                   reader):
    """0.59: Pillow's words on the console from the server's and a batch worker's threads (and passed on on the
    main thread), once for each time it read the directory. Pillow reads the Exif and GPS directories as it
    decodes the pixels (tifffile decodes them where it is installed)."""
    if reader == "Pillow":
        monkeypatch.setitem(sys.modules, "tifffile", None)  # as without the tiff extra
    path = tmp_path / "damaged.tif"
    path.write_bytes(tiff_bytes(**DAMAGED[case]))
    arr, shown, kept = shown_while(lambda: load_image(path, dtype=None), where)
    assert shown == [] and [k for k in kept if "frames" not in k] == [], (shown, kept)
    assert np.array_equal(arr, pixels())


@pytest.mark.parametrize("case", ["a value past the end", "two values of a one-value tag", "a huge count",
                                  "a colour profile past the end"])
def test_is_image_of_a_damaged_tiff_in_memory_says_nothing_on_a_thread(case):
    """The server asks ``is_image`` of an upload that is no model, from memory, on a thread; a TIFF whose value
    lies past the end was no image to it (0.59: Pillow, stopping at that value, lost the pixels' place)."""
    answer, shown, _ = shown_while(lambda: is_image(io.BytesIO(tiff_bytes(**DAMAGED[case]))), "another thread")
    assert answer is True and shown == []


@pytest.mark.parametrize("cut", [12, 30, 8 + 2 + 12 * 9 + 2])
def test_is_image_of_a_tiff_cut_in_its_first_directory_is_false_without_a_word(cut):
    """0.59 refused such a file by its path in one line (``_check_tiff_directory``), but Pillow warned "Corrupt
    EXIF data" (or "Truncated File Read") of it from memory, twice."""
    answer, shown, _ = shown_while(lambda: is_image(io.BytesIO(tiff_bytes()[:cut])), "another thread")
    assert answer is False and shown == []


def test_a_directory_read_into_another_is_not_followed_nor_patched():
    """A next-directory offset into the first directory (garbage, or a hostile file) would read its entries
    as another directory's: the copy Pillow reads must leave the first one as it is."""
    from tghop.tiff_tags import quiet_copy

    blob = tiff_bytes(next_offset=20)
    copy = quiet_copy(io.BytesIO(blob))
    assert copy is not None and copy.getvalue()[:8 + 2 + 12 * 9] == blob[:8 + 2 + 12 * 9]
    answer, shown, _ = shown_while(lambda: is_image(io.BytesIO(blob)), "another thread")
    assert answer is True and shown == []


def test_a_sound_tiff_is_read_from_its_file_not_a_copy(tmp_path):
    from tghop.tiff_tags import quiet_copy

    path = tmp_path / "sound.tif"
    path.write_bytes(tiff_bytes(extra=[(270, 2, 6, [b"hello\0"])], second=[]))
    assert quiet_copy(path) is None and quiet_copy(io.BytesIO(path.read_bytes())) is None
