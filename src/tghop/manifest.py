"""A ``tghop batch`` manifest: the exemplars to process, one row each, as CSV with a header
line naming a ``path`` column, or as JSON lines ``{"path": ...}``; each row optionally
with its own ``name``, ``maps`` (:func:`parse_maps`: the row is a whole material, ``path`` its
albedo) and :data:`ROW_SETTINGS` (:func:`tghop.batch.find_work` reads one).

Every bad row is a one-line :class:`~tghop.TGHopError` naming its line, before any work.
Only the standard library is imported here (and, when called, :func:`tghop._images.check_size`,
:func:`tghop._arrays.check_int` and :mod:`tghop.settings`).
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
from pathlib import Path

from ._errors import TGHopError
from ._json import RepeatedKeyError, loads_unique

__all__ = ["ROW_SETTINGS", "read_manifest", "manifest_rows", "row_settings", "parse_size", "parse_bool", "parse_int",
           "parse_scale", "parse_maps", "split_size", "MAX_MAPS"]

#: Per-exemplar settings a manifest row may give.
ROW_SETTINGS = ("size", "count", "seed", "tile", "scale")
#: Most maps of one material besides its albedo, in a manifest row (and a web server's fit).
MAX_MAPS = 8


def _shown(value, most: int = 60) -> str:
    """``repr(value)``, cut to ``most`` characters (a message shows the start of a long value)."""
    text = repr(value)
    return text if len(text) <= most else text[: most - 3] + "..."


def _json_kind(value) -> str:
    """What a JSON value is, in words ("a JSON object", "a number", ...), for a message."""
    return {dict: "a JSON object", list: "a JSON list", bool: "true or false", type(None): "null"}.get(
        type(value), "a number")


def split_size(text, *, signed=False):
    """``HxW`` text (or ``H*W``, ``H,W``; ``N``: a square) -> ``(height, width)`` ints,
    unchecked; None where it is not one. ``signed``: a minus sign is read too (the command
    line's ``--size``, whose check then states the range).

    Parameters
    ----------
    text : str or object
        ``"512x256"``, ``"512*256"``, ``"512, 256"`` or ``"512"`` (spaces around allowed);
        anything else is read as ``str(text)``.
    signed : bool
        Read ``-5x10`` too (default: digits only).

    Returns
    -------
    (int, int) or None
        ``(height, width)``, not checked against any bound; None where ``text`` is not a size.
    """
    number = r"(-?\d+)" if signed else r"(\d+)"
    m = re.fullmatch(rf"\s*{number}\s*(?:[xX*,]\s*{number}\s*)?", str(text))
    return None if m is None else (int(m.group(1)), int(m.group(2) or m.group(1)))


def parse_size(value, where):
    """A size (``HxW``, ``N``, ``[H, W]`` or ``[N]``) -> ``[height, width]``, checked.

    Parameters
    ----------
    value : str or list
        A CSV cell's or JSON value's size: text as :func:`split_size` reads it, or a JSON
        list of one or two whole numbers.
    where : str
        The row, for messages (``"list.csv line 3"``).

    Returns
    -------
    list of int
        ``[height, width]``, within :func:`tghop._images.check_size`'s bounds.

    Raises
    ------
    TGHopError
        One line starting with ``where``.
    """
    from ._images import check_size

    if isinstance(value, (list, tuple)):
        if len(value) not in (1, 2):
            raise TGHopError(f"{where}: size {value!r} is not [HEIGHT, WIDTH] (e.g. [512, 512])")
        h, w = (parse_int(v, where, "size", 1) for v in (list(value) * 2)[:2])
    else:
        pair = split_size(value)
        if pair is None:
            raise TGHopError(f"{where}: size {value!r} is not HEIGHTxWIDTH (e.g. 512x512)")
        h, w = pair
    return list(check_size((int(h), int(w)), name=f"{where}: size"))


def parse_bool(value, name, *, where=None, empty=None):
    """``value`` as a bool: a bool, or true/false, yes/no, on/off, 1/0 (any case, spaces
    around ignored); ``empty``: what blank text means (a web form sends a field left unset
    empty: its default), None: refused. The manifest's ``tile`` and the server's form fields.

    Otherwise a one-line :class:`~tghop.TGHopError`: ``name must be true or false, got value``
    (after ``where: `` where given).

    Parameters
    ----------
    value : bool, str or object
        The cell, JSON value or form field; anything else is read as ``str(value)``.
    name : str
        The setting's name, for the message.
    where : str, optional
        The row or the request, put before the message.
    empty : bool, optional
        The value of blank text; None refuses it.

    Returns
    -------
    bool
    """
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in ("1", "true", "yes", "on"):
        return True
    if text in ("0", "false", "no", "off"):
        return False
    if text == "" and empty is not None:
        return empty
    raise TGHopError(("" if where is None else f"{where}: ") + f"{name} must be true or false, got {value!r}")


def parse_int(value, where, what, low, high=None):
    """A whole number from ``low`` to ``high`` (None: no bound): text is parsed, then
    :func:`tghop._arrays.check_int` checks it (not a bool, nor a float: a JSON ``2.0``; as
    ``"2.0"`` in a CSV cell and as the library's sizes).

    Parameters
    ----------
    value : int, str or object
        A JSON number or a CSV cell's text (spaces around ignored).
    where : str
        The row, for messages.
    what : str
        The column's name, for messages (``"count"``).
    low : int
        The least value allowed.
    high : int, optional
        The most value allowed; None: no bound.

    Returns
    -------
    int

    Raises
    ------
    TGHopError
        One line starting with ``where``, for text that is not a whole number, a float, a
        bool or a value out of range.
    """
    from ._arrays import check_int

    if isinstance(value, float) and value.is_integer():
        raise TGHopError(f"{where}: {what} {value!r} has a decimal point; write {int(value)}")
    if isinstance(value, str):
        try:
            value = int(value.strip())
        except ValueError:
            raise TGHopError(f"{where}: {what} {value!r} is not a whole number") from None
    return check_int(value, what, low, high, where=where)


def row_settings(row: dict, where: str) -> dict:
    """The settings a manifest row gives (empty cells left out), checked.

    Parameters
    ----------
    row : dict
        The row's column -> cell (text from a CSV, any JSON value from JSON lines).
    where : str
        The row, for messages.

    Returns
    -------
    dict
        The :data:`ROW_SETTINGS` the row gives, each checked: ``size`` a list
        ``[height, width]`` (:func:`parse_size`), ``count`` an int in 1..1000, ``seed`` an
        int >= 0, ``tile`` a bool, ``scale`` a float (:func:`parse_scale`).
    """
    out = {}
    for key in ROW_SETTINGS:
        value = row.get(key)
        if value is None or (isinstance(value, str) and not value.strip()):
            continue
        if key == "size":
            out["size"] = parse_size(value, where)
        elif key == "count":
            out["count"] = parse_int(value, where, "count", 1, 1000)
        elif key == "seed":
            out["seed"] = parse_int(value, where, "seed", 0)
        elif key == "tile":
            out["tile"] = parse_bool(value, "tile", where=where)
        else:
            out["scale"] = parse_scale(value, where)
    return out


def parse_scale(value, where):
    """A row's working scale (the fit setting ``scale``, :mod:`tghop.scale`): a number, or its text.

    Parameters
    ----------
    value : float or str
        A JSON number or a CSV cell's text.
    where : str
        The row, for messages.

    Returns
    -------
    float
        In (0, 4], as the setting allows (:data:`tghop.settings.BY_NAME` ``["scale"]``).
    """
    from .settings import BY_NAME

    setting = BY_NAME["scale"]
    try:
        value = setting.parse(value) if isinstance(value, str) else value
    except TGHopError as exc:  # the text's words name no setting: the column's name goes first
        raise TGHopError(f"{where}: scale {exc}") from None
    try:
        return setting.check(value)
    except TGHopError as exc:
        raise TGHopError(f"{where}: {exc}") from None


def parse_maps(value, where, base: Path) -> list:
    """A row's ``maps``: the maps of a whole material whose albedo is the row's ``path``, as
    ``[(name, Path)]``. JSON: an object ``{"normal": "rock_n.png", ...}`` or a list of paths;
    CSV: paths separated by ``;``, each optionally ``name=path``. A map without a name is
    named by its file (:func:`tghop.map_names.map_name`, as ``tghop fit --maps``). Relative paths
    are from ``base`` (the manifest's folder). A name that cannot name a file, a name given twice
    (without case; ``albedo`` is the exemplar's: :func:`tghop.map_names.check_map_names`) or more
    than :data:`MAX_MAPS` maps is refused, naming the line.

    Parameters
    ----------
    value : dict, list or str
        The row's ``maps``: a JSON object of name -> path, a JSON list of paths, or CSV text.
    where : str
        The row, for messages.
    base : pathlib.Path
        The folder relative paths are from.

    Returns
    -------
    list of (str, pathlib.Path)
        Each map's name and file, in the order given; the files are not opened here.
    """
    # A map's name names its output file (NAME_<map>.png).
    from .map_names import MAP_NAME, MAP_NAME_MAX, MapNameClashError, check_map_names, map_name

    if isinstance(value, dict):
        pairs = list(value.items())
    elif isinstance(value, list):
        pairs = [(None, v) for v in value]
    elif isinstance(value, str):
        pairs = []
        for part in (s.strip() for s in value.split(";")):
            if not part:
                continue
            name, eq, file = part.partition("=")
            pairs.append((name.strip(), file.strip()) if eq else (None, part))
    else:
        raise TGHopError(f'{where}: maps {_shown(value)} must be paths separated by ";" (CSV), or a JSON object '
                         '{"normal": "a_normal.png", ...} or list of paths')
    if not pairs and isinstance(value, str):  # only separators: a slip (an empty cell is a texture)
        raise TGHopError(f"{where}: maps {_shown(value)} lists no file; give the maps' files, or leave the cell "
                         "empty for a texture")
    out, named_by = [], []  # named_by: the file that names each map (None: named in the manifest)
    for name, file in pairs:
        if file is not None and not isinstance(file, str):  # 0.59: "has no path" of {"normal": {"path": ...}}
            raise TGHopError(f"{where}: the file of the map {_shown(name if name is not None else file)} must be a "
                             f"path (a string), not {_json_kind(file)}; give each map's image file")
        if not isinstance(file, str) or not file.strip():
            raise TGHopError(f"{where}: the map {_shown(name if name is not None else file)} has no path; "
                             "give each map's image file")
        file = file.strip()
        _check_path_text(file, where)
        named_by.append(file if name is None else None)
        name = map_name(file) if name is None else name
        if not isinstance(name, str) or not MAP_NAME.fullmatch(name):
            raise TGHopError(f"{where}: the map name {_shown(name)} cannot name a file; use letters, digits, "
                             "'_', '-' and '.' (name=path in CSV)")
        if len(name) > MAP_NAME_MAX:  # 0.59 fitted it, then failed writing its file ("File name too long")
            raise TGHopError(f"{where}: the map name {_shown(name)} is {len(name)} characters, more than the "
                             f"{MAP_NAME_MAX} a map's name may have (it names the map's file); shorten it")
        out.append((name, Path(file) if os.path.isabs(file) else base / file))
    try:
        check_map_names([name for name, _ in out], named_by)
    except MapNameClashError as exc:
        fix = (f"name each map, e.g. normal=rock_n.png, or {exc.fix}" if exc.cut
               else f"{exc.fix}, e.g. normal=rock_n.png")
        raise TGHopError(f"{where}: {exc.clash}; {fix}") from None
    if len(out) > MAX_MAPS:
        raise TGHopError(f"{where}: {len(out)} maps; a material takes at most {MAX_MAPS}")
    return out


def manifest_rows(path: Path):
    """(line number, row dict) of a CSV or JSON-lines manifest.

    A ``.jsonl``, ``.json`` or ``.ndjson`` file is read as JSON lines, anything else as CSV
    with a header line; blank lines are skipped. A one-line :class:`~tghop.TGHopError`
    names the file and the line of the first unreadable row (raised as the rows are read).

    Parameters
    ----------
    path : pathlib.Path
        The manifest (UTF-8, a byte-order mark allowed).

    Yields
    ------
    number : int
        The row's line in the file (for a CSV row over several lines, its last).
    row : dict
        Column -> cell: CSV text (columns the header leaves unnamed dropped), or the JSON
        object.
    """
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:  # 0.57 gave the codec's words alone
        kind = "UTF-16 text" if exc.object[:2] in (b"\xff\xfe", b"\xfe\xff") else "not UTF-8 text"
        raise TGHopError(f"{path}: cannot read the manifest ({kind}: byte 0x{exc.object[exc.start]:02x} at "
                         f"{exc.start:,}); save it as UTF-8 (a spreadsheet's 'CSV UTF-8')") from None
    except OSError as exc:
        raise TGHopError(f"{path}: cannot read the manifest ({getattr(exc, 'strerror', None) or exc})") from None
    if path.suffix.lower() in (".jsonl", ".json", ".ndjson"):  # not splitlines: a JSON string may hold U+2028
        for number, line in enumerate(text.split("\n"), 1):
            if not line.strip():
                continue
            try:
                row = loads_unique(line)
            except RepeatedKeyError as exc:  # 0.58 kept the last value without a word
                raise TGHopError(f"{path} line {number}: the key {_shown(exc.key)} is given twice; keep one (a JSON "
                                 "reader keeps the last without a word)") from None
            except (ValueError, RecursionError):  # RecursionError: arrays nested thousands deep
                raise TGHopError(f"{path} line {number}: not a JSON object; write one "
                                 '{"path": ..., "size": ..., ...} per line') from None
            if not isinstance(row, dict):
                raise TGHopError(f"{path} line {number}: not a JSON object; write one per line")
            yield number, row
        return
    reader = csv.reader(io.StringIO(text, newline=""))  # as the csv module asks: a quoted cell keeps its breaks
    try:
        header = [f.strip() for f in next(reader, [])]
        yield from _csv_rows(path, reader, header)
    except csv.Error as exc:  # a cell over the csv module's limit (131,072 characters): 0.57 a traceback
        raise TGHopError(f"{path} line {reader.line_num}: {exc} (a quote left open?); close the quote, or "
                         "shorten the cell") from None


def _csv_rows(path, reader, header):
    """:func:`manifest_rows`' CSV rows after the ``header`` line, ``reader`` a :func:`csv.reader`."""
    if "path" not in header:
        other = [d for d in (";", "\t", "|") if len(header) == 1 and "path" in header[0].split(d)]
        if other:  # a spreadsheet's export where the decimal comma is taken (one cell: path;size;count)
            raise TGHopError(f"{path}: the header line is separated by {other[0]!r}, not commas; a CSV manifest's "
                             "cells are separated by commas: save it with commas")
        raise TGHopError(f"{path}: a CSV manifest needs a header line with a 'path' column "
                         f"(and optionally name, maps, {', '.join(ROW_SETTINGS)})")
    seen = set()  # 0.57 compared each column with all before it: 100,000 columns ran for minutes
    for column in header:
        if column and column in seen:
            raise TGHopError(f"{path}: the header names the column {_shown(column)} twice; keep one")
        seen.add(column)
    for cells in reader:
        if not cells:  # a blank line
            continue
        number = reader.line_num  # the line the row ends on (its cells may hold line breaks)
        if any(c.strip() for c in cells[len(header):]):  # empty ones, as spreadsheets write, are no cells
            raise TGHopError(f"{path} line {number} has {len(cells)} cells, the header {len(header)}; "
                             "remove the extra cells or name their column in the header")
        unnamed = [c.strip() for f, c in zip(header, cells) if not f and c.strip()]
        if unnamed:
            raise TGHopError(f"{path} line {number}: {unnamed[0][:40]!r} is in a column the header does not "
                             "name; name the column or remove the cell")
        yield number, {f: c for f, c in zip(header, cells) if f}


def _check_path_text(text, where) -> None:
    """A one-line :class:`~tghop.TGHopError` for a path no file can have (a NUL: 0.57 a traceback) or that holds
    a line break (CSV: a quote left open took the next rows into it; 0.57 ran the batch and failed the row)."""
    if "\0" in text:
        raise TGHopError(f"{where}: the path {_shown(text)} holds a NUL character, which no file name can; remove it")
    if "\n" in text or "\r" in text:
        raise TGHopError(f"{where}: the path {_shown(text)} holds a line break (a quote left open?); close the "
                         "quote, or remove the break")


def read_manifest(path: Path):
    """The exemplars a manifest lists, every row checked before any is returned.

    Parameters
    ----------
    path : pathlib.Path
        The manifest, CSV or JSON lines (:func:`manifest_rows`).

    Returns
    -------
    list of dict
        One per row, in the file's order: ``path`` (the exemplar's file, relative paths from
        the manifest's folder), ``rel`` (the row's path as written), ``name`` and ``given``
        (the row's name, or None), ``named`` (whether it gave one), ``settings``
        (:func:`row_settings`), ``maps`` (:func:`parse_maps`; empty for a texture) and
        ``where`` (the row's line, for messages).

    Raises
    ------
    TGHopError
        One line naming the file and line of the first bad row, or saying that the
        manifest lists no exemplar.
    """
    items = []
    for number, row in manifest_rows(path):
        where = f"{path} line {number}"  # as manifest_rows names it
        unknown = sorted(k for k in row if k not in ("path", "name", "maps") + ROW_SETTINGS)
        if unknown:
            shown = ", ".join(k if k and k.strip() == k else _shown(k) for k in unknown[:5])
            shown += f" and {len(unknown) - 5:,} more" if len(unknown) > 5 else ""
            raise TGHopError(f"{where}: unknown column {shown}; a manifest gives path, name, maps, "
                             f"{', '.join(ROW_SETTINGS)}")
        for key, example in (("path", "textures/a.png"), ("name", "bricks")):
            if row.get(key) is not None and not isinstance(row[key], str):  # JSON: not str() of a list
                raise TGHopError(f"{where}: {key} {_shown(row[key])} is not a string; write it in quotes, "
                                 f'e.g. "{key}": "{example}"')
        source = (row.get("path") or "").strip()
        if not source:
            raise TGHopError(f"{where}: no path")
        _check_path_text(source, where)
        file = Path(source) if os.path.isabs(source) else path.parent / source
        name = (row.get("name") or "").strip() or None
        maps = row.get("maps")
        maps = [] if maps is None or (isinstance(maps, str) and not maps.strip()) else parse_maps(
            maps, where, path.parent)
        for map_name, map_file in maps:
            if os.path.abspath(map_file) == os.path.abspath(file):
                raise TGHopError(f"{where}: the map {map_name} is the row's path itself, the albedo; give the map's "
                                 "own file")
        items.append({"path": file, "rel": Path(source), "name": name, "named": name is not None, "given": name,
                      "settings": row_settings(row, where), "maps": maps, "where": where})
    if not items:
        raise TGHopError(f"{path}: the manifest lists no exemplar")
    _warn_repeated(items, path)
    return items


def _warn_repeated(items, path) -> None:
    """Warn of rows that list the same file, maps and settings as an earlier row without a name of their
    own: each was made again (as NAME_2, ...), naming both lines."""
    import warnings

    first = {}
    for it in items:
        key = (os.path.abspath(it["path"]), json.dumps(it["settings"], sort_keys=True),
               tuple((name, os.path.abspath(file)) for name, file in it["maps"]))
        earlier = first.setdefault(key, it)
        if earlier is not it and not (it["named"] and earlier["named"]):
            warnings.warn(f"{it['where']} lists {it['rel']} as {earlier['where'].removeprefix(f'{path} ')} does, "
                          "with the same settings: it is made twice; remove the line, or give count for more results "
                          "of one exemplar", UserWarning, stacklevel=3)
