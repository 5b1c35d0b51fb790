"""What a batch does, decided before any work: the exemplars and their folder names, and the
ledger that says what an earlier run finished.

* :func:`find_work` -- the exemplars of a folder (recursively) or a manifest (:mod:`tghop.manifest`),
  each with a unique folder name in OUTDIR (at most :data:`NAME_MAX` characters);
* :func:`inputs_sha256` -- what the ledger compares to know an exemplar unchanged; :func:`input_digest`
  takes it from the hashes an earlier run found (:data:`HASHES`, :func:`read_hashes`, :func:`write_hashes`)
  without reading the files where their size, times and inode (:func:`inputs_stat`) are as they were then;
* the ledger ``OUTDIR/batch.jsonl`` (:data:`LEDGER`): read (:func:`read_ledger`,
  :func:`read_ledger_files`), opened locked for a run (:func:`open_ledger`), appended to
  (:func:`append_ledger`, synced by :func:`sync_ledger`), compacted (:func:`compact_ledger`);
  :func:`is_done` tells an exemplar a rerun skips, :func:`keep_ledger_names`
  keeps the names it had, :func:`is_known_failure` an exemplar whose input failed before and is
  unchanged, :func:`remove_stale` deletes the files a new line no longer lists, and
  :func:`mark_running` the :data:`RUNNING` file of an exemplar handed out;
* :func:`find_orphans` -- the folders an earlier run made for exemplars no longer in SOURCE, and
  :func:`prune_orphans`, which deletes the files the ledger says a run made there;
* :func:`renamed_from` -- an exemplar done before under another name (a manifest row renamed, a file
  renamed in SOURCE: its input and settings unchanged), whose files :func:`move_renamed` moves to the new name.

:func:`tghop.batch.run` uses them; :mod:`tghop.batch_dask` runs the work on Dask.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import numbers
import os
import re
import time
import unicodedata
import warnings
from pathlib import Path

from ._errors import TGHopError
from ._json import loads_unique
from ._formats import OTHER_IMAGE_SUFFIXES, READ_SUFFIXES
from .batch_task import RUNNING, THUMBNAIL_FILE, claimed, output_files, remove_temporaries, write_claim
from .contact_sheet import CONTACT_SHEET
from .manifest import MAX_MAPS, read_manifest

__all__ = ["IMAGE_SUFFIXES", "LEDGER", "RUNNING", "NAME_MAX", "HASHES", "STAT_MARGIN", "WINDOWS_RESERVED",
           "windows_reserved", "check_outdir", "find_work", "inputs_sha256", "inputs_stat", "input_digest",
           "read_hashes", "write_hashes", "file_sha256", "read_ledger", "read_ledger_files", "keep_ledger_names",
           "check_own_files", "open_ledger", "append_ledger", "sync_ledger", "compact_ledger", "COMPACT_MIN",
           "is_done", "is_known_failure", "mark_running", "remove_stale", "find_orphans", "prune_orphans",
           "renamable", "renamed_from", "move_renamed"]


#: File extensions taken as exemplars when SOURCE is a folder: those tghop reads
#: (:data:`tghop._formats.READ_SUFFIXES`, the one list: .tga, .psd, .dds, JPEG 2000, .avif and .ico were
#: skipped as of another type though fit read them). Other images' (:data:`OTHER_IMAGE_SUFFIXES`) are
#: skipped, and said (a studio's .tga were left out unsaid).
IMAGE_SUFFIXES = READ_SUFFIXES
#: The ledger, in OUTDIR (beside the contact sheet, :data:`tghop.contact_sheet.CONTACT_SHEET`).
LEDGER = "batch.jsonl"
#: The longest folder name of an exemplar (ASCII): its files' names add up to 88 characters
#: (``.NAME_0001_<map of 64>.png.XXXXXXXX.tmp`` while written) to a file name's 255 bytes.
NAME_MAX = 160
#: The fewest superseded ledger lines (an exemplar made again writes a line after its earlier ones) for which
#: a run compacts the ledger (:func:`compact_ledger`; 0.59), which it does where they are as many as the lines
#: kept too (a ledger of 1.8 KB a line: 1.8 MB dropped at least).
COMPACT_MIN = 1000

#: The runs in a row after which an exemplar whose worker died on every try (a decoder's crash, a size beyond the
#: memory) counts as its own failure, skipped by reruns as a bad input is (0.62: :func:`worker_deaths`).
LOST_RUNS = 3

#: In OUTDIR: the SHA-256 a run found for each exemplar's files, with their size, times and inode then
#: (:func:`input_digest`), so that a rerun need not read unchanged files again. A cache: without it (removed,
#: unreadable) the files are hashed, as 0.57 hashed them on every run.
HASHES = ".batch-hashes.json"
#: Seconds: files changed this recently before a run looked at them (their modification or change time)
#: are hashed again by the next run (:func:`inputs_stat`): the coarsest timestamps of a common file system
#: (FAT's 2 s) could give a change right after the look the same times.
STAT_MARGIN = 2.0


# ------------------------------------------------------------------ finding work
def _scan_folder(folder: Path, outdir: Path, max_depth=None):
    """The images of ``folder``, recursively (``max_depth`` levels of subfolders at most; None:
    every level), symbolic links to folders followed (each folder
    once: a link back up is no loop); hidden files and folders, and what is not a regular file
    (a named pipe: a broken link is kept, to be said), are skipped, and so are
    ``outdir`` and every folder holding a ledger (an earlier batch's OUTDIR: its thumbnails and
    results are no exemplars)."""
    out = Path(outdir).resolve()
    items, others, seen = [], [], {os.path.realpath(folder)}

    def new(path):
        real = os.path.realpath(path)
        if real in seen:
            return False
        seen.add(real)
        return True

    for root, dirs, files in os.walk(folder, followlinks=True):
        deep = max_depth is not None and len(Path(root).relative_to(folder).parts) >= max_depth
        dirs[:] = [] if deep else [d for d in sorted(dirs) if not d.startswith(".") and Path(root, d).resolve() != out
                                   and not os.path.lexists(os.path.join(root, d, LEDGER))
                                   and new(os.path.join(root, d))]
        for f in sorted(files):
            p = Path(root, f)  # a named pipe, socket or device is no image (reading one waited for ever)
            if not f.startswith(".") and p.suffix.lower() in IMAGE_SUFFIXES and (p.is_file() or not p.exists()):
                items.append({"path": p, "rel": p.relative_to(folder), "name": None, "settings": {}})
            elif not f.startswith(".") and p.suffix.lower() in OTHER_IMAGE_SUFFIXES:
                others.append(str(p.relative_to(folder)))
    skipped = (f"{len(others)} image file{'s' if len(others) != 1 else ''} of another type skipped "
               f"({', '.join(others[:3])}{', ...' if len(others) > 3 else ''}): a batch reads "
               f"{', '.join(IMAGE_SUFFIXES)}; convert them to PNG") if others else ""
    if not items:
        within = "" if max_depth is None else \
            " itself" if max_depth == 0 else f" or {max_depth} level{'s' if max_depth != 1 else ''} of subfolders"
        raise TGHopError(f"{folder}: no image files in this folder{within} ({', '.join(IMAGE_SUFFIXES[:3])}, ...)"
                         + (f"; {skipped}" if skipped else "")
                         + ("; a larger max depth (--max-depth) searches deeper" if max_depth is not None else ""))
    if skipped:
        warnings.warn(f"{folder}: {skipped}", stacklevel=3)
    _warn_material_sets(folder, items)
    return items


def _warn_material_sets(folder: Path, items) -> None:
    """Warn of the folders whose images are named as one material's maps (a colour map and another
    kind of map, :func:`tghop.map_names.map_kind`: ambientCG's ``Rock023_2K_Color.jpg`` beside its
    ``Rock023_2K_NormalGL.png``): a folder SOURCE makes each a texture of its own, so the warning gives
    the manifest line that makes them one material."""
    from .map_names import ALBEDO, map_kind

    sets = {}
    for item in items:
        sets.setdefault(item["rel"].parent, []).append((map_kind(item["rel"]), item["rel"]))
    sets = {d: files for d, files in sets.items() if sum(kind == ALBEDO for kind, _ in files) == 1
            and any(kind not in (None, ALBEDO) for kind, _ in files)}
    if not sets:
        return
    first, files = next(iter(sets.items()))
    albedo = next(rel for kind, rel in files if kind == ALBEDO)
    maps, left = _manifest_maps([(kind, rel) for kind, rel in files if kind not in (None, ALBEDO)])
    out = io.StringIO()
    csv.writer(out, lineterminator="").writerow([albedo.as_posix(), ";".join(maps)])  # a comma in a name quoted
    where = "it" if first == Path(".") else first.as_posix()
    where += f" and {len(sets) - 1} other folder{'s' if len(sets) > 2 else ''}" if len(sets) > 1 else ""
    limit = (f" (a material takes at most {MAX_MAPS} maps: {', '.join(left[:3])}{', ...' if len(left) > 3 else ''} "
             "left out)") if left else ""
    warnings.warn(f"{folder}: {where} hold{'s' if len(sets) == 1 else ''} a material's maps by their names, and a "
                  "folder makes each image a texture of its own (maps not aligned, a normal map not kept unit); "
                  "to make whole materials list them in a CSV manifest in this folder (header path,maps), e.g. "
                  f"the line {out.getvalue()}{limit}", stacklevel=4)


def _manifest_maps(files):
    """The maps of a folder's material set that one manifest row can list (``[(kind, rel)]``): paths that
    hold no ``;`` (the row's separator), each map name once (in any case) and at most :data:`MAX_MAPS`, one of
    each kind first (:data:`tghop.map_names.MAP_KINDS`' order), in the folder's order; and those left out."""
    from .map_names import MAP_KINDS, map_name

    names, usable, left = set(), [], []
    for kind, rel in files:
        name = map_name(rel).lower()
        if ";" in rel.as_posix() or name in names:
            left.append(rel.as_posix())
        else:
            names.add(name)
            usable.append((kind, rel))
    order = list(MAP_KINDS)
    ranked = sorted(range(len(usable)), key=lambda i: (any(usable[j][0] == usable[i][0] for j in range(i)),
                                                       order.index(usable[i][0])))
    keep = set(ranked[:MAX_MAPS])
    left += [rel.as_posix() for i, (_, rel) in enumerate(usable) if i not in keep]
    return [rel.as_posix() for i, (_, rel) in enumerate(usable) if i in keep], left


#: Names Windows keeps for devices, with or without an extension and in any case (``con``,
#: ``Nul.png``, ``com1.tar.gz``): no file or folder can have one there.
WINDOWS_RESERVED = frozenset({"CON", "PRN", "AUX", "NUL", *(f"{d}{i}" for d in ("COM", "LPT") for i in range(10))})


def windows_reserved(name: str) -> bool:
    """Whether ``name`` cannot name a file or folder on Windows: a device's name
    (:data:`WINDOWS_RESERVED`, before its first ``.``, trailing spaces aside) or one ending in
    ``.`` or a space (Windows drops them: ``a.`` is ``a``)."""
    return name.endswith((".", " ")) or name.split(".", 1)[0].rstrip(" ").upper() in WINDOWS_RESERVED


def _safe(text: str, reserved: bool = True) -> str:
    # Accents dropped first (NFKD: "é" is "e" and a combining mark), so that "béans" is "beans", not "b_ans".
    text = "".join(ch for ch in unicodedata.normalize("NFKD", text) if not unicodedata.combining(ch))
    # No leading "-" either (as a map's name): "-x/-x.npz" was taken for options by tghop synth, ls, ...
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", text).lstrip("._-").rstrip("._") or "unnamed"
    if reserved and windows_reserved(name):  # "con" -> "con_", "nul.x" -> "nul_.x": no such folder on Windows
        first, dot, rest = name.partition(".")
        name = f"{first}_{dot}{rest}"
    # OUTDIR's own files (a folder of that name would stand there) and the thumbnail (<name>.png's).
    return name + "_exemplar" if name.lower() in (LEDGER, CONTACT_SHEET, Path(THUMBNAIL_FILE).stem) else name


def _unique_names(items):
    """A folder name per exemplar. A name a manifest row gives is kept (made safe for a
    file name: ``_`` for other characters); two that are one folder name, compared without
    case, are a :class:`TGHopError` naming both lines. Others: the path without the
    extension, folders joined by ``__`` (``a/x.png`` -> ``a__x``; over 140 characters, its
    first 131 and a short hash of the path); a name taken (by another exemplar or a given
    name) gets its extension, then a short hash of the path, then a number. No name is longer
    than :data:`NAME_MAX` (a longer given one is refused)."""
    given = {}
    for it in items:
        if not it.get("named"):
            continue
        it["name"] = _safe(it["name"])
        if len(it["name"]) > NAME_MAX:
            raise TGHopError(f"{it['where']}: the name {it['given'][:40]!r}... is {len(it['name'])} characters long; "
                             f"its files could not be named (at most {NAME_MAX}); give a shorter name")
        other = given.setdefault(it["name"].lower(), it)
        if other is not it:
            raise TGHopError(f"{it['where']}: the name {it['given']!r} and {other['where']}'s {other['given']!r} are "
                             "one folder name in OUTDIR (names are compared without case); give each its own name")
    free = [it for it in items if not it.get("named")]
    for it in free:
        rel = it["rel"]
        it["name"] = _safe("__".join(rel.parts[:-1] + (rel.stem,)))
        if len(it["name"]) > NAME_MAX - 20:  # a deep path: its start and a hash (the steps below add up to 20)
            it["name"] = it["name"][:NAME_MAX - 29] + "_" + hashlib.sha256(str(rel).encode()).hexdigest()[:8]
    for step in ("suffix", "hash"):
        seen = {}
        for it in free:
            seen.setdefault(it["name"].lower(), []).append(it)
        for key, group in seen.items():
            if len(group) < 2 and key not in given:
                continue
            for it in group:
                if step == "suffix" and it["rel"].suffix:
                    it["name"] += "_" + _safe(it["rel"].suffix[1:], reserved=False)  # not its name's start
                elif step == "hash":
                    it["name"] += "_" + hashlib.sha256(str(it["rel"]).encode()).hexdigest()[:8]
    seen = dict.fromkeys(given, 1)
    for it in free:  # a manifest that lists one file twice: _2, _3, ...
        n = seen[it["name"].lower()] = seen.get(it["name"].lower(), 0) + 1
        if n > 1:
            it["name"] += f"_{n}"
    return items


def check_outdir(source, outdir):
    """Refuse an ``outdir`` that is the folder ``source`` itself (a :class:`TGHopError`; ``tghop batch`` makes it a
    usage error, exit status 2, since 0.63)."""
    if outdir is None or not os.fsdecode(outdir).strip():  # none, or "" (not the current folder: refused as empty)
        return
    source = Path(os.path.abspath(source))
    if source.is_dir() and Path(outdir).resolve() == source.resolve():
        raise TGHopError(f"{source}: OUTDIR is the SOURCE folder, and the next run would take its outputs for "
                         "exemplars; give another folder, e.g. -o " + str(source.parent / (source.name + "_out")))


def find_work(source, outdir=None, max_depth=None):
    """The exemplars of ``source``: a folder (every image in it, recursively, ``max_depth``
    levels of subfolders at most: 0 the folder's own, None every level; hidden files,
    ``outdir`` and the folders that hold a ledger ``batch.jsonl`` skipped) or a manifest
    (``.csv`` with a ``path`` column, or JSON lines ``{"path": ...}``; optional ``name``,
    ``size``, ``count``, ``seed``, ``tile``; paths relative to the manifest's folder).

    Returns a list of dicts: ``path`` (Path), ``rel`` (as listed), ``name`` (unique folder
    name in OUTDIR) and ``settings`` (the row's own settings). A bad manifest row is a
    :class:`TGHopError` naming its line, before any work.
    """
    if not os.fsdecode(source).strip():  # "" would be the current folder
        raise TGHopError("SOURCE is empty; give a folder of exemplars or a manifest")
    if max_depth is not None and (isinstance(max_depth, bool) or not isinstance(max_depth, numbers.Integral)
                                  or max_depth < 0):
        raise TGHopError(f"max_depth must be an integer >= 0 (0: the folder's own images; None: every level), "
                         f"got {max_depth!r}")
    source = Path(os.path.abspath(source))  # workers may run elsewhere (another folder, another machine)
    check_outdir(source, outdir)
    if source.is_dir():
        items = _scan_folder(source, outdir if outdir is not None else source / ".none", max_depth)
    elif source.is_file():
        if max_depth is not None:
            raise TGHopError(f"{source}: max depth (--max-depth) is for a folder SOURCE; a manifest lists its files: "
                             "drop it (the manifest's rows are the exemplars)")
        if source.suffix.lower() not in (".csv", ".jsonl", ".json", ".ndjson"):
            raise TGHopError(f"{source}: not a folder or a manifest; give a folder of images or a .csv or .jsonl file")
        items = read_manifest(source)
    else:
        raise TGHopError(f"{source}: no such folder or manifest; check the path")
    return _unique_names(items)


def inputs_sha256(path, maps=()) -> str | None:
    """What the ledger compares to know an exemplar unchanged: its file's SHA-256, or for a
    material (``maps``: ``[(name, path)]``) the SHA-256 of the albedo's and each named map's
    (None when one cannot be read)."""
    first = file_sha256(path)
    if not maps or first is None:
        return first
    h = hashlib.sha256(first.encode())
    for name, file in maps:
        digest = file_sha256(file)
        if digest is None:
            return None
        h.update(f"\0{name}\0{digest}".encode())
    return h.hexdigest()


def inputs_stat(path, maps=()) -> list | None:
    """What a rerun compares before it hashes an exemplar's files (:func:`input_digest`): for its file and
    each map (``[(name, path)]``), ``[path, size, mtime_ns, ctime_ns, inode]``, as git compares a file
    with its index. None when a file cannot be looked at, or was changed less than :data:`STAT_MARGIN`
    seconds ago (its times could stay the same through a change now). No program sets the change time
    (``touch -d``, ``cp -p`` and ``rsync -t`` set the modification time), and a file written anew under
    its old name (``rsync``, many editors) has another inode."""
    now = time.time()
    out = []
    for file in [path, *(file for _, file in maps)]:
        try:
            st = os.stat(file)
        except (OSError, ValueError):
            return None
        if max(st.st_mtime, st.st_ctime) > now - STAT_MARGIN:
            return None
        out.append([str(file), st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino])
    return out


def _hash_key(path, maps) -> str:
    return "\0".join([str(path), *(f"{name}={file}" for name, file in maps)])


def input_digest(path, maps=(), hashes=None, found=None) -> str | None:
    """:func:`inputs_sha256` of an exemplar's files, taken from ``hashes`` (:func:`read_hashes`: an earlier
    run's) without reading them where their :func:`inputs_stat` is the one recorded there: a rerun of
    thousands of exemplars, all done, read every byte of them again to find them unchanged (0.57; gigabytes
    for a studio's library). ``found`` (a dict): gets the entry for :func:`write_hashes` where the files'
    stat can be trusted."""
    key, stat = _hash_key(path, maps), inputs_stat(path, maps)
    entry = (hashes or {}).get(key)
    if stat is not None and isinstance(entry, dict) and entry.get("stat") == stat \
            and isinstance(entry.get("sha256"), str):
        sha256 = entry["sha256"]
    else:
        sha256 = inputs_sha256(path, maps)
    if found is not None and stat is not None and sha256 is not None:
        found[key] = {"stat": stat, "sha256": sha256}
    return sha256


def read_hashes(outdir) -> dict:
    """The hashes an earlier run found (:data:`HASHES`), by the exemplar's files; ``{}`` where there are none
    or they cannot be read."""
    try:
        found = loads_unique((Path(outdir) / HASHES).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):  # a key given twice too: the files read again (0.59: its last)
        return {}
    return found if isinstance(found, dict) else {}


def write_hashes(outdir, earlier: dict, found: dict, sources) -> None:
    """Write :data:`HASHES`: this run's ``found`` (:func:`input_digest`), and the ``earlier`` ones of files
    that ``sources`` (the ledger's exemplar files) still name, as another SOURCE into the same OUTDIR
    left them; nothing where that is what the file holds (a rerun of nothing changed writes nothing). A
    failure to write is no failure of the run: the next run reads the files again."""
    from .output_files import write_atomic

    sources = set(sources)
    merged = {k: v for k, v in earlier.items() if k.split("\0", 1)[0] in sources}
    merged.update(found)
    if merged == earlier:
        return
    text = json.dumps(merged, sort_keys=True, separators=(",", ":"))
    with contextlib.suppress(OSError, TGHopError):
        write_atomic(Path(outdir) / HASHES, lambda fh: fh.write(text.encode("utf-8")), what="hashes",
                     error=TGHopError)


def file_sha256(path) -> str | None:
    """SHA-256 of a file's bytes (None when it cannot be read)."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return None
    return h.hexdigest()


# ------------------------------------------------------------------ the ledger
def read_ledger(outdir) -> dict:
    """The last ledger line of each exemplar (by name); unreadable lines are skipped."""
    return read_ledger_files(outdir)[0]


def read_ledger_files(outdir, standing=None, lost=None):
    """:func:`read_ledger`'s lines, and the files every line of each exemplar lists (by name):
    an earlier run's outputs stay in its folder after a later line that lists none (a failed
    try), until a run of it succeeds (:func:`remove_stale`). ``standing`` (a dict): gets, by name, the last
    line done ("ok") of each exemplar where only failures its task returned follow it (0.62): such a task moved
    no file (it moves them all at its end), so the folder still holds that line's files (:func:`tghop.batch.run`
    skips them where that line's input and settings are the job's). A line ``interrupted``, a task lost
    (its worker dead on every try) or a rename ends it: files may have changed (:func:`_ends_standing`). ``lost`` (a
    dict): gets, by name, the last lines in a row whose worker died on every try, as ``(count, (sha256, settings))``
    (:func:`worker_deaths`)."""
    records, files = {}, {}
    standing = {} if standing is None else standing
    lost = {} if lost is None else lost
    try:  # line by line, as compact_ledger reads it: 0.62 decoded the whole file, and a line not in UTF-8 hid them all
        lines = (Path(outdir) / LEDGER).read_bytes().split(b"\n")
    except OSError:
        return records, files
    for line in lines:
        try:
            rec = loads_unique(line)
        except (ValueError, RecursionError):  # a line torn by a crash or not in UTF-8; hand-edited: a key given twice
            continue  # (0.59 took its last value), arrays nested thousands deep (0.59: a traceback)
        if isinstance(rec, dict) and isinstance(rec.get("name"), str):
            records[rec["name"]] = rec
            if rec.get("worker_died"):
                lost[rec["name"]] = (_deaths(rec, lost.get(rec["name"])), (rec.get("sha256"), rec.get("settings")))
            else:
                lost.pop(rec["name"], None)
            if rec.get("status") == "ok":
                standing[rec["name"]] = rec
            elif _ends_standing(rec):
                standing.pop(rec["name"], None)
            with contextlib.suppress(TypeError):  # a hand-edited line's odd fields list nothing
                files.setdefault(rec["name"], set()).update(f for f in _listed_files(rec) if isinstance(f, str))
    return records, files


def _deaths(rec: dict, before) -> int:
    """How many runs in a row ``rec``'s worker died on every try of its exemplar: 1 and those of ``before`` (the
    exemplar's earlier count, :func:`read_ledger_files`' ``lost``) where its input and settings were the same."""
    return 1 + (before[0] if before and before[1] == (rec.get("sha256"), rec.get("settings")) else 0)


def worker_deaths(rec: dict, before) -> None:
    """Count in ``rec`` (a ledger line whose worker died on every try, ``worker_died``) the runs in a row that ended so
    (``before``: :func:`read_ledger_files`' ``lost`` of its exemplar); from :data:`LOST_RUNS` on, it is the exemplar's
    own failure (``cause`` "input", :func:`is_known_failure`): reruns skip it until it changes or ``--retry-failed``
    is given. 0.61 tried it again in every run, and an exemplar that crashes the decoder killed workers in each."""
    rec["worker_deaths"] = runs = _deaths(rec, before)
    if runs >= LOST_RUNS:
        rec["cause"] = "input"
        rec["error"] = (f"{rec.get('error')}; so in {runs} runs in a row: taken as this exemplar's own failure (it "
                        "crashes its worker: a decoder's crash, or a size beyond the memory), skipped by reruns until "
                        "it changes; --retry-failed (retry_failed=True) tries it again")


def _ends_standing(rec: dict) -> bool:
    """Whether a ledger line may follow files moved into its exemplar's folder (:func:`read_ledger_files`'
    ``standing``): any but "ok" and a failure its task returned (which moved none), i.e. "interrupted", "renamed"
    and a task lost (its worker died on every try, or it raised: :mod:`tghop.batch_dask`'s ``task_lost`` record;
    0.61 wrote that without the field, its error said so)."""
    status = rec.get("status")
    return status != "ok" and (status != "failed" or bool(rec.get("task_lost"))
                               or str(rec.get("error") or "").startswith("the worker running it died"))


def keep_ledger_names(items, previous) -> None:
    """An exemplar keeps the name its ledger line has (a file added next to it can change the
    name :func:`find_work` gives it: ``sub/a.png`` is ``sub__a`` until a ``sub__a.png``
    arrives, then both get longer names, and it would be done again under the new one): where
    one earlier line names its file and no other exemplar takes that name or lists that file
    (a name a manifest row gives is kept as it is)."""
    by_source = {}
    for name, rec in previous.items():
        by_source.setdefault(str(rec.get("source")), []).append(name)
    sources = [str(it["path"]) for it in items]
    taken = {it["name"].lower() for it in items}
    for it, source in zip(items, sources):
        names = by_source.get(source, [])
        if it.get("named") or it["name"] in names or len(names) != 1 or sources.count(source) != 1 \
                or len(names[0]) > NAME_MAX or windows_reserved(names[0]):  # too long for its files (that run
            continue  # failed), or a name Windows keeps for a device (an earlier version's): the plan's instead
        if names[0].lower() not in taken:
            taken.discard(it["name"].lower())
            it["name"] = names[0]
            taken.add(names[0].lower())


def check_own_files(outdir: Path, contact_sheet: bool) -> None:
    """Refuse a folder where OUTDIR's ledger or contact sheet goes (found before any work); warn of one where the
    inputs' hashes go (:data:`HASHES`, a cache: the run is right without it, but reads every input again; 0.63,
    0.62 said nothing)."""
    for name, what in ((LEDGER, "the ledger"), (CONTACT_SHEET, "the contact sheet")):
        if name == CONTACT_SHEET and not contact_sheet:
            continue
        if (outdir / name).is_dir():
            raise TGHopError(f"{outdir / name} is a folder, where {what} of the batch goes; remove that folder "
                             "or choose another OUTDIR")
    if (outdir / HASHES).is_dir():
        warnings.warn(f"{outdir / HASHES} is a folder, where the inputs' hashes go: this run and every rerun read "
                      "every input whole again; remove that folder", stacklevel=3)


def open_ledger(outdir: Path):
    """The ledger opened for appending, for the whole run: one that cannot be written to is
    found before any exemplar's files are made (or overwritten). It is locked (``flock``) while
    the run lasts: a second batch into the same OUTDIR is refused (it would redo the exemplars
    under way and remove their files in the making, which then failed)."""
    path = outdir / LEDGER
    try:
        fh = open(path, "a", encoding="utf-8")
    except OSError as exc:
        raise TGHopError(f"{path}: cannot add to the ledger ({exc.strerror or exc.__class__.__name__}); make it a "
                         "writable file (chmod u+w, or chattr -i where it is immutable) or choose another OUTDIR; "
                         "nothing was done") from None
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        return fh
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        fh.close()
        raise TGHopError(f"{outdir}: another tghop batch is writing to this OUTDIR (its ledger is locked); wait for "
                         "it to end or choose another OUTDIR; nothing was done") from None
    except OSError:  # a file system without locks: the run goes on unlocked
        pass
    try:  # a line torn by a crash or a full disk ends apart: this run's first line would join it, and be lost too
        with open(path, "rb") as tail:
            if tail.seek(0, os.SEEK_END) and (tail.seek(-1, os.SEEK_END), tail.read(1))[1] != b"\n":
                fh.write("\n")
    except OSError:
        pass
    return fh


def append_ledger(fh, record: dict, sync: bool = True):
    """Write ``record`` as one JSON line to the open ledger ``fh`` and hand it to the system (flush: a
    kill of this process loses it no more), and make it durable (``sync``: :func:`sync_ledger`); without
    ``sync`` the caller syncs a group of lines at once (0.59: :func:`tghop.batch.run` syncs the lines of
    the exemplars that came back together once, before their :data:`RUNNING` files are removed)."""
    line = json.dumps(record, sort_keys=True, allow_nan=False, default=str) + "\n"
    fh.write(line)
    fh.flush()
    if sync:
        sync_ledger(fh)


def sync_ledger(fh) -> None:
    """Make the lines written to the open ledger ``fh`` durable (``fsync``): a machine's crash or power
    loss keeps them."""
    fh.flush()
    os.fsync(fh.fileno())


def compact_ledger(outdir: Path, known: int = 0) -> int:
    """Rewrite the ledger without its superseded lines where they are many (0.59; 0.58's only grew, a line
    per exemplar made again): at least :data:`COMPACT_MIN`, and as many as the lines kept, so that a ledger
    is rewritten at most once per as many lines as it holds. Kept: each exemplar's last line, each line that may
    follow files moved in (0.62: :func:`read_ledger_files`' ``standing`` reads the same), and each earlier
    line that lists a file no later kept line of its exemplar lists (:func:`read_ledger_files` reads the same
    records and files from the new ledger: :func:`remove_stale` and :func:`prune_orphans` still find every
    file a run made); dropped: the others, and lines torn by a crash. Called by a run while it holds the
    ledger's lock, as its last step; ``known``: exemplars known to have a line (none read where the ledger
    holds fewer than ``known + COMPACT_MIN`` lines). The new ledger is written and synced beside the old one
    and moved over it (``os.replace``), its folder synced: a kill or a crash at any point leaves the old
    ledger or the new one, whole; a temporary file left by one is removed by the next call. Returns the lines
    dropped (0: nothing rewritten)."""
    from .output_files import write_atomic

    path = Path(outdir) / LEDGER
    for left in Path(outdir).glob(f".{LEDGER}.*.tmp"):  # a compaction killed before its move
        with contextlib.suppress(OSError):
            left.unlink()
    try:
        lines = path.read_bytes().split(b"\n")
    except OSError:
        return 0
    if len(lines) - known < COMPACT_MIN:
        return 0
    keep, covered = [], {}
    for i in range(len(lines) - 1, -1, -1):  # the last line of each exemplar first
        try:
            rec = loads_unique(lines[i])
        except (ValueError, RecursionError):
            continue  # a torn line (or an empty one): read_ledger_files skips it too
        if not isinstance(rec, dict) or not isinstance(rec.get("name"), str):
            continue
        try:
            files = {f for f in _listed_files(rec) if isinstance(f, str)}
        except TypeError:  # a hand-edited line's odd fields: kept as it is
            files = None
        seen = covered.get(rec["name"])
        if seen is None or files is None or files - seen or _ends_standing(rec):  # the same standing line after
            keep.append(i)
            covered.setdefault(rec["name"], set()).update(files or ())
    dropped = sum(1 for line in lines if line.strip()) - len(keep)
    if dropped < max(COMPACT_MIN, len(keep)):
        return 0

    def write(fh):
        fh.writelines(lines[i] + b"\n" for i in reversed(keep))
        fh.flush()
        os.fsync(fh.fileno())  # the new ledger's lines on the disk before it replaces the old

    try:
        write_atomic(path, write, what="ledger", error=TGHopError)
        fd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(fd)  # the move itself
        finally:
            os.close(fd)
    except (OSError, TGHopError):  # not compacted: the ledger is as it was, the next run tries again
        return 0
    return dropped


def is_done(prev: dict | None, job: dict, outdir: Path) -> bool:
    """Whether an earlier run finished ``job`` (its last ledger line ``prev``): same inputs and
    settings, no :data:`RUNNING` file left, and every file the line lists still in OUTDIR."""
    if not prev or prev.get("status") != "ok" or prev.get("sha256") != job["sha256"]:
        return False
    if claimed(job["folder"]):  # handed out by a run killed before its line
        return False
    if prev.get("settings") != job["settings"]:
        return False
    # A model and no empty output name, and every file the line lists (the thumbnail too: the contact sheet shows it),
    outputs = prev.get("outputs") or []  # all names (0.64; 0.63: a hand-edited 7 or [1, 2] raised a traceback)
    return isinstance(outputs, list) and all([*outputs, prev.get("model")]) and all(
        isinstance(f, str) and (outdir / f).is_file() for f in _listed_files(prev))


def is_known_failure(prev: dict | None, job: dict, version: str) -> bool:
    """Whether ``job`` failed in an earlier run (its last ledger line ``prev``) for a cause in its
    input (``cause`` "input": not an image, flat, too small, a bad map), which a rerun would only
    repeat: the same inputs (their SHA-256, read), settings and tghop ``version``, the same name of
    the exemplar's file (0.57: a material's row fails by its files' names, a normal map as its path,
    and a misnamed file renamed holds the same bytes), and no :data:`RUNNING` file left. A failure of
    the run's (memory, a lost worker, an interruption, an unexpected error), or of a line written
    before causes were recorded, is not one: it is tried again. Nor is a task stopped by the task timeout (0.63)
    where ``job``'s is longer, or none."""
    if not prev or prev.get("status") != "failed" or prev.get("cause") != "input" or job["sha256"] is None:
        return False
    if prev.get("timed_out") and (job.get("task_timeout") is None
                                  or job["task_timeout"] > (prev.get("task_timeout") or 0)):
        return False
    if claimed(job["folder"]):
        return False
    renamed = Path(str(prev.get("source", job["source"]))).name != Path(job["source"]).name
    return prev.get("sha256") == job["sha256"] and prev.get("settings") == job["settings"] \
        and prev.get("version") == version and not renamed


def _listed_files(rec: dict) -> list:
    """The files (relative to OUTDIR) a ledger line lists: images, model, thumbnail."""
    return [f for f in [*(rec.get("outputs") or []), rec.get("model"), rec.get("thumbnail")] if f]


def mark_running(job, on: bool) -> None:
    """Make (``on``) or remove the exemplar's :data:`RUNNING` file (its folder made as needed;
    one that cannot be made: its task fails and says why). Made, it holds the job's ``claim`` (the run's
    id, 0.62: :func:`tghop.batch_task.write_claim`), which its task checks before it moves its files into
    place; a job whose claim cannot be written is run unchecked (its ``claim`` dropped), as before 0.62."""
    path = Path(job["folder"]) / RUNNING
    if on:
        if not write_claim(job["folder"], job.get("claim") or ""):
            job.pop("claim", None)
        return
    with contextlib.suppress(OSError):
        path.unlink()


def remove_stale(outdir: Path, earlier: set, rec: dict) -> None:
    """Delete the files of an exemplar's earlier ledger lines (``earlier``: all of them, not
    only the last, which may be a failed try's and list none) that its new one does not list
    (e.g. ``a_1.png``, ``a_2.png`` after a rerun with count 1 wrote ``a.png``): only in its
    own folder."""
    keep = set(_listed_files(rec))
    folder = (outdir / rec["name"]).resolve()
    for f in set(earlier) - keep:
        if (outdir / f).resolve().parent == folder:
            with contextlib.suppress(OSError):
                (outdir / f).unlink()


# ------------------------------------------------------------------ exemplars no longer in SOURCE
def _own_folder(outdir: Path, name: str):
    """OUTDIR/NAME where ``name`` (a ledger's) names a real folder right in OUTDIR, else None
    (a hand-edited line's ``..``, ``a/b`` or a symbolic link)."""
    if not name or name in (".", "..") or "/" in name or "\\" in name or "\0" in name:
        return None
    folder = outdir / name
    try:  # a name too long for a file (an earlier version's line) is no folder either
        if folder.is_symlink() or not folder.is_dir() or folder.resolve().parent != outdir.resolve():
            return None
    except OSError:
        return None
    return folder


def _own_files(outdir: Path, folder: Path, listed) -> list:
    """The regular files in ``folder`` that ledger lines list (``listed``, relative to OUTDIR)."""
    inside = folder.resolve()
    out = []
    for f in sorted(listed):
        path = outdir / f
        with contextlib.suppress(OSError):
            if not path.is_symlink() and path.is_file() and path.resolve().parent == inside:
                out.append(path)
    return out


def find_orphans(outdir: Path, files: dict, names) -> list:
    """The names of the exemplars an earlier run made a folder for, which are not among
    ``names`` (this run's exemplars, compared without case: one folder on macOS and Windows)
    and whose folder still holds a file a ledger line of theirs lists (``files``:
    :func:`read_ledger_files`'s second part) or their :data:`RUNNING` file: exemplars removed
    from SOURCE (or renamed there) since, sorted. A name given again in another case only (``Rock``, now ``rock``) is
    one where its folder is another than the new name's (0.62; 0.61 said none: a case-sensitive file system's)."""
    current, given = {n.lower(): n for n in names}, set(names)
    found = []
    for name in sorted(files):
        if name.lower() in current and (name in given or _same_folder(outdir, name, current[name.lower()])):
            continue
        folder = _own_folder(outdir, name)
        if folder is not None and (_own_files(outdir, folder, files[name]) or os.path.isfile(folder / RUNNING)):
            found.append(name)
    return found


def _same_folder(outdir: Path, name: str, other: str) -> bool:
    """Whether OUTDIR/``name`` and OUTDIR/``other`` are one folder (names apart in case on a file system without it)."""
    try:
        return os.path.samefile(outdir / name, outdir / other)
    except OSError:  # either missing: on such a file system both are
        return False


def prune_orphans(outdir: Path, orphans, files: dict) -> dict:
    """Delete what a run made in each orphan's folder (:func:`find_orphans`): the files its
    ledger lines list, its :data:`RUNNING` file and a killed task's temporaries; then the folder
    where it is empty. Nothing else is touched. Returns, by name, the entries left in a folder
    kept (files not made by tghop: they and the folder stay); a name not in it was removed whole."""
    kept = {}
    for name in orphans:
        folder = _own_folder(outdir, name)
        if folder is None:
            continue
        for path in [*_own_files(outdir, folder, files.get(name, ())), folder / RUNNING]:
            with contextlib.suppress(OSError):
                if path.is_file() and not path.is_symlink():
                    path.unlink()
        remove_temporaries(folder)
        try:
            folder.rmdir()
        except OSError:
            with contextlib.suppress(OSError):
                kept[name] = sorted(p.name for p in folder.iterdir())
    return kept


# ------------------------------------------------------------------ exemplars renamed
def renamable(previous: dict, names) -> dict:
    """The earlier exemplars done (``previous``: :func:`read_ledger`) whose names no exemplar of this run has
    (``names``), by their inputs' SHA-256: where an exemplar of this run has no line of its own, one of them with its
    input and settings may be it, renamed (:func:`renamed_from`). A name given in another case only is one (0.62:
    ``Rock`` to ``rock``; 0.61 compared without case, and neither moved it nor said its folder)."""
    current = set(names)
    found = {}
    for name, rec in previous.items():
        if name not in current and rec.get("status") == "ok" and isinstance(rec.get("sha256"), str):
            found.setdefault(rec["sha256"], []).append(name)
    return found


def _renamed_files(prev: dict, old: str, new: str):
    """``[(file, renamed)]`` (relative to OUTDIR) of the files ``prev`` (exemplar ``old``'s line) lists, named for
    exemplar ``new`` as a run names them (:func:`tghop.batch_task.output_files`); None where the line does not name
    them so (an earlier version's names): such an exemplar is made again."""
    settings = prev.get("settings") if isinstance(prev.get("settings"), dict) else {}
    try:
        count, maps = int(settings.get("count", 1)), settings.get("maps")
        before = [f"{old}/{f}" for f in output_files(old, count, maps)]
        after = [f"{new}/{f}" for f in output_files(new, count, maps)]
    except (TypeError, ValueError):
        return None
    if before != prev.get("outputs") or prev.get("model") != f"{old}/{old}.npz" \
            or prev.get("thumbnail") != f"{old}/{THUMBNAIL_FILE}":
        return None
    return [*zip(before, after), (f"{old}/{old}.npz", f"{new}/{new}.npz"),
            (f"{old}/{THUMBNAIL_FILE}", f"{new}/{THUMBNAIL_FILE}")]


def renamed_from(job: dict, previous: dict, candidates: dict, outdir: Path):
    """The name an earlier run made ``job``'s exemplar under (0.62), or None: a name of ``candidates``
    (:func:`renamable`, by SHA-256; the one taken is removed from it) whose last line is done with ``job``'s input and
    settings (:func:`is_done`, in its own folder, no :data:`RUNNING` file) and names its files as this version does.
    A manifest row given a new name, or a file renamed in a folder SOURCE, was made again under the new name and its
    old folder said "no longer in SOURCE" (0.61)."""
    for old in candidates.get(job["sha256"], ()):
        prev = previous[old]
        if _own_folder(outdir, old) is not None and is_done(prev, {**job, "folder": str(outdir / old)}, outdir) \
                and _renamed_files(prev, old, job["name"]) is not None:
            candidates[job["sha256"]].remove(old)
            return old
    return None


def _rename_folder(outdir: Path, old: str, new: str) -> None:
    """OUTDIR/``old`` renamed ``new``, names apart in case only on a file system without it, through a name of its own
    (the folder as it was where that fails)."""
    step = outdir / f".{old}.renamed.tmp"
    try:
        os.replace(outdir / old, step)
    except OSError:
        return
    try:
        os.replace(step, outdir / new)
    except OSError:
        with contextlib.suppress(OSError):
            os.replace(step, outdir / old)


def move_renamed(outdir: Path, prev: dict, old: str, job: dict):
    """Move exemplar ``old``'s files (its last line ``prev``) to ``job``'s folder under ``job``'s name, and return
    the ledger line that says them (``renamed_from``: ``old``); None where a move failed (those done are moved back:
    the exemplar is made again). Called under the ledger's lock; the old folder is removed where it is left empty."""
    pairs = _renamed_files(prev, old, job["name"])
    if pairs is None:
        return None
    moved = []
    try:
        (outdir / job["name"]).mkdir(exist_ok=True)
        for before, after in pairs:
            os.replace(outdir / before, outdir / after)
            moved.append((before, after))
    except OSError:
        for before, after in reversed(moved):
            with contextlib.suppress(OSError):
                os.replace(outdir / after, outdir / before)
        return None
    with contextlib.suppress(OSError):
        (outdir / old).rmdir()  # only when empty: files of one's own stay
    if old.lower() == job["name"].lower() and _same_folder(outdir, old, job["name"]):  # one folder (macOS, Windows):
        _rename_folder(outdir, old, job["name"])  # its files renamed in it; the folder's own name too
    return {**prev, "name": job["name"], "source": job["source"], "sha256": job["sha256"], "settings": job["settings"],
            "outputs": [after for _, after in pairs[:-2]], "model": pairs[-2][1], "thumbnail": pairs[-1][1],
            "renamed_from": old, "finished": time.time()}
