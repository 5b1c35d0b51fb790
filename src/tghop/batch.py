"""Many exemplars at once: a model and N images per exemplar, in process or on Dask.

:func:`run` finds the work (every image of a folder, or the rows of a manifest: :mod:`tghop.manifest`),
skips what a previous run finished (the ledger ``OUTDIR/batch.jsonl``: one JSON line per finished
exemplar with its input's SHA-256, its settings and its outputs; ``interrupted`` for one under way when
a run stops), runs :func:`process_exemplar` for the
rest, in this process (``workers=1``), on a local ``dask.distributed`` cluster of worker processes (the
default), or on a given :class:`distributed.Client`, and writes an HTML contact sheet ``OUTDIR/index.html``.

* Every file is written atomically (:func:`tghop.imageio.write_atomic`); a worker killed
  mid-task leaves at most a temporary file, which the retry (or the end of the run)
  removes. A task whose worker dies is run again elsewhere, up to ``retries`` times
  (distributed's ``allowed-failures``), then recorded as failed.
* A bad exemplar (not an image, flat, too small) is recorded with its one-line error; the others go on.
* Dask is an optional extra (``pip install 'tghop[batch]'``), imported inside the functions that use it;
  ``workers=1`` never needs it.

The library never prints: ``progress(stage, done, total)`` reports exemplars finished,
``on_result(record, counts)`` each finished exemplar with the running counts.
"""

from __future__ import annotations

import contextlib
import gc
import hashlib
import json
import numbers
import os
import re
import signal
import threading
import time
import unicodedata
import warnings
from pathlib import Path

from ._errors import MissingExtraError, TGHopError
from .batch_task import THUMBNAIL_FILE, one_line, process_exemplar, remove_temporaries
from .contact_sheet import CONTACT_SHEET, write_contact_sheet as _write_sheet
from .manifest import parse_bool, parse_int, parse_size, read_manifest

__all__ = ["run", "find_work", "check_options", "process_exemplar", "read_ledger", "write_contact_sheet",
           "inputs_sha256", "local_cluster", "IMAGE_SUFFIXES", "LEDGER", "CONTACT_SHEET", "INSTALL_HINT",
           "WORKER_MALLOC", "WORKER_ENVIRON", "WORKERS_PER_CORE", "NAME_MAX", "RUNNING", "tune_malloc", "dask_setup"]

#: File extensions taken as exemplars when SOURCE is a folder.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".gif", ".tif", ".tiff", ".webp", ".ppm", ".pgm", ".pnm")
#: The ledger, in OUTDIR (beside the contact sheet, :data:`tghop.contact_sheet.CONTACT_SHEET`).
LEDGER = "batch.jsonl"
INSTALL_HINT = "pip install 'tghop[batch]'"
#: glibc ``malloc`` settings a worker makes (:func:`dask_setup`, ``mallopt``): no array gets
#: a mapping of its own (``M_MMAP_MAX`` 0: every array, however large, comes from the heap and
#: goes back to it), and up to 1 GB freed at the top of the heap is kept for the next one. A
#: task allocates and frees arrays of tens to hundreds of MB many times; each fresh mapping is
#: page-faulted and zeroed by the kernel again. Dask starts its workers with
#: ``MALLOC_TRIM_THRESHOLD_=65536`` (every array above 64 KB a fresh mapping: an exemplar took
#: 37 % longer); glibc's own adaptive thresholds map arrays above 32 MB (docs/batch.md).
WORKER_MALLOC = {"M_MMAP_MAX": 0, "M_TRIM_THRESHOLD": 1 << 30}
#: Set in a worker's environment before it starts (:func:`local_cluster`): one malloc arena,
#: so that the task's thread allocates from the main heap (the only one ``M_MMAP_MAX``
#: keeps large arrays in: a thread's own arena maps anything above 64 MB). glibc reads it at
#: start only; a value of one's own in the environment is kept.
WORKER_ENVIRON = {"MALLOC_ARENA_MAX": "1"}
#: A local cluster's worker processes per usable core at most (:func:`run`'s ``workers``): each
#: exemplar runs on one core, so more only share the cores and the memory (a typo's million
#: worker processes kept the run starting for ever, with Ctrl-C ignored while a cluster starts).
WORKERS_PER_CORE = 4
_MALLOPT = {"M_TRIM_THRESHOLD": -1, "M_MMAP_MAX": -4}  # glibc's malloc.h
#: Each WORKER_MALLOC setting's environment variable, and the value Dask puts there (None: none).
_MALLOC_ENV = {"M_MMAP_MAX": ("MALLOC_MMAP_MAX_", None), "M_TRIM_THRESHOLD": ("MALLOC_TRIM_THRESHOLD_", "65536")}


# ------------------------------------------------------------------ finding work
def _scan_folder(folder: Path, outdir: Path):
    """The images of ``folder``, recursively, symbolic links to folders followed (each folder
    once: a link back up is no loop); hidden files and folders, and what is not a regular file
    (a named pipe: a broken link is kept, to be said), are skipped, and so are
    ``outdir`` and every folder holding a ledger (an earlier batch's OUTDIR: its thumbnails and
    results are no exemplars)."""
    out = Path(outdir).resolve()
    items, seen = [], {os.path.realpath(folder)}

    def new(path):
        real = os.path.realpath(path)
        if real in seen:
            return False
        seen.add(real)
        return True

    for root, dirs, files in os.walk(folder, followlinks=True):
        dirs[:] = [d for d in sorted(dirs) if not d.startswith(".") and Path(root, d).resolve() != out
                   and not os.path.lexists(os.path.join(root, d, LEDGER)) and new(os.path.join(root, d))]
        for f in sorted(files):
            p = Path(root, f)  # a named pipe, socket or device is no image (reading one waited for ever)
            if not f.startswith(".") and p.suffix.lower() in IMAGE_SUFFIXES and (p.is_file() or not p.exists()):
                items.append({"path": p, "rel": p.relative_to(folder), "name": None, "settings": {}})
    if not items:
        raise TGHopError(f"{folder}: no image files in this folder ({', '.join(IMAGE_SUFFIXES[:3])}, ...)")
    return items


#: In an exemplar's folder from its hand-out until its ledger line is written: a rerun does again
#: an exemplar that has one (the run that wrote it was killed, its task may have run on and
#: replaced the files an earlier line lists: a given cluster's task runs on without its client).
RUNNING = ".batch-running"
#: The longest folder name of an exemplar (ASCII): its files' names add up to 88 characters
#: (``.NAME_0001_<map of 64>.png.XXXXXXXX.tmp`` while written) to a file name's 255 bytes.
NAME_MAX = 160


def _safe(text: str) -> str:
    # Accents dropped first (NFKD: "é" is "e" and a combining mark), so that "béans" is "beans", not "b_ans".
    text = "".join(ch for ch in unicodedata.normalize("NFKD", text) if not unicodedata.combining(ch))
    # No leading "-" either (as a map's name): "-x/-x.npz" was taken for options by tghop synth, ls, ...
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", text).lstrip("._-").rstrip("._") or "unnamed"
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
                    it["name"] += "_" + _safe(it["rel"].suffix[1:])
                elif step == "hash":
                    it["name"] += "_" + hashlib.sha256(str(it["rel"]).encode()).hexdigest()[:8]
    seen = dict.fromkeys(given, 1)
    for it in free:  # a manifest that lists one file twice: _2, _3, ...
        n = seen[it["name"].lower()] = seen.get(it["name"].lower(), 0) + 1
        if n > 1:
            it["name"] += f"_{n}"
    return items


def find_work(source, outdir=None):
    """The exemplars of ``source``: a folder (every image in it, recursively; hidden files,
    ``outdir`` and the folders that hold a ledger ``batch.jsonl`` skipped) or a manifest
    (``.csv`` with a ``path`` column, or JSON lines ``{"path": ...}``; optional ``name``,
    ``size``, ``count``, ``seed``, ``tile``; paths relative to the manifest's folder).

    Returns a list of dicts: ``path`` (Path), ``rel`` (as listed), ``name`` (unique folder
    name in OUTDIR) and ``settings`` (the row's own settings). A bad manifest row is a
    :class:`TGHopError` naming its line, before any work.
    """
    if not os.fsdecode(source).strip():  # "" would be the current folder
        raise TGHopError("SOURCE is empty; give a folder of exemplars or a manifest")
    source = Path(os.path.abspath(source))  # workers may run elsewhere (another folder, another machine)
    if source.is_dir() and outdir is not None and Path(outdir).resolve() == source.resolve():
        raise TGHopError(f"{source}: OUTDIR is the SOURCE folder, and the next run would take its outputs for "
                         "exemplars; give another folder, e.g. -o " + str(source.parent / (source.name + "_out")))
    if source.is_dir():
        items = _scan_folder(source, outdir if outdir is not None else source / ".none")
    elif source.is_file():
        if source.suffix.lower() not in (".csv", ".jsonl", ".json", ".ndjson"):
            raise TGHopError(f"{source}: SOURCE is a folder of images or a manifest (.csv or .jsonl)")
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
    return _read_ledger(outdir)[0]


def _read_ledger(outdir):
    """:func:`read_ledger`'s lines, and the files every line of each exemplar lists (by name):
    an earlier run's outputs stay in its folder after a later line that lists none (a failed
    try), until a run of it succeeds (:func:`_remove_stale`)."""
    records, files = {}, {}
    try:
        text = (Path(outdir) / LEDGER).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return records, files
    for line in text.splitlines():
        try:
            rec = json.loads(line)
        except ValueError:
            continue  # a line torn by a crash
        if isinstance(rec, dict) and isinstance(rec.get("name"), str):
            records[rec["name"]] = rec
            with contextlib.suppress(TypeError):  # a hand-edited line's odd fields list nothing
                files.setdefault(rec["name"], set()).update(f for f in _listed_files(rec) if isinstance(f, str))
    return records, files


def _keep_ledger_names(items, previous) -> None:
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
                or len(names[0]) > NAME_MAX:  # a name too long for its files: that run failed
            continue
        if names[0].lower() not in taken:
            taken.discard(it["name"].lower())
            it["name"] = names[0]
            taken.add(names[0].lower())


def _check_own_files(outdir: Path, contact_sheet: bool) -> None:
    """Refuse a folder where OUTDIR's ledger or contact sheet goes (found before any work)."""
    for name, what in ((LEDGER, "the ledger"), (CONTACT_SHEET, "the contact sheet")):
        if name == CONTACT_SHEET and not contact_sheet:
            continue
        if (outdir / name).is_dir():
            raise TGHopError(f"{outdir / name} is a folder, where {what} of the batch goes; remove that folder "
                             "or choose another OUTDIR")


def _open_ledger(outdir: Path):
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


def _append_ledger(fh, record: dict):
    line = json.dumps(record, sort_keys=True, allow_nan=False, default=str) + "\n"
    fh.write(line)
    fh.flush()
    os.fsync(fh.fileno())


def _is_done(prev: dict | None, job: dict, outdir: Path) -> bool:
    if not prev or prev.get("status") != "ok" or prev.get("sha256") != job["sha256"]:
        return False
    if os.path.lexists(os.path.join(job["folder"], RUNNING)):  # handed out by a run killed before its line
        return False
    if prev.get("settings") != job["settings"]:
        return False
    # A model and no empty output name, and every file the line lists (the thumbnail too: the
    # contact sheet shows it).
    return all([*(prev.get("outputs") or []), prev.get("model")]) and all(
        (outdir / f).is_file() for f in _listed_files(prev))


def _listed_files(rec: dict) -> list:
    """The files (relative to OUTDIR) a ledger line lists: images, model, thumbnail."""
    return [f for f in [*(rec.get("outputs") or []), rec.get("model"), rec.get("thumbnail")] if f]


def _mark_running(job, on: bool) -> None:
    """Make (``on``) or remove the exemplar's :data:`RUNNING` file (its folder made as needed;
    one that cannot be made: its task fails and says why)."""
    path = Path(job["folder"]) / RUNNING
    with contextlib.suppress(OSError):
        if on:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.touch()
        else:
            path.unlink()


def _remove_stale(outdir: Path, earlier: set, rec: dict) -> None:
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


# ------------------------------------------------------------------ running
def _import_distributed():
    try:
        import distributed
    except ImportError:
        raise MissingExtraError(f"running on Dask needs dask.distributed; install it with: {INSTALL_HINT} "
                                "(or run in this process with workers=1 / --workers 1)") from None
    return distributed


def local_cluster(n_workers=None, *, retries=3, memory_limit="auto"):
    """A local ``dask.distributed`` cluster of ``n_workers`` worker processes (default:
    one per available core), one thread each, BLAS limited to one thread per worker, the
    scheduler's HTTP server on a free port, a worker's death allowed ``retries`` times per task.

    Each worker runs :func:`dask_setup` first (a preload): among others, its ``malloc``
    keeps freed memory for reuse (:data:`WORKER_MALLOC`, :data:`WORKER_ENVIRON`)."""
    distributed = _import_distributed()
    import logging

    import dask

    n = n_workers or _cores()
    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    environ.update({v: "1" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")})
    environ.update(WORKER_ENVIRON)
    # Ctrl-C is ignored while the workers start: a worker process inherits that (its preload
    # ignores Ctrl-C only once its imports are done; before, each printed a traceback), and a
    # cluster interrupted half-started cannot be closed cleanly. It lasts a few seconds.
    with _ctrl_c_ignored(), dask.config.set({"distributed.scheduler.allowed-failures": int(retries),
                                             "distributed.nanny.pre-spawn-environ": environ}):
        # ":0": the scheduler's HTTP server (health, metrics) on a free port; None still took 8787,
        # and a second cluster (another batch, a notebook's) printed Dask's "Port 8787 is already in use".
        try:
            return distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                            dashboard_address=":0", memory_limit=memory_limit,
                                            silence_logs=logging.CRITICAL, preload=[__name__])
        except RuntimeError as exc:  # most often a script without the guard: each worker ran it again
            raise TGHopError(f"the local Dask cluster's workers did not start ({exc}); a script that runs a "
                             "batch needs 'if __name__ == \"__main__\":' around the call (workers import it), "
                             "or workers=1") from exc


@contextlib.contextmanager
def _ctrl_c_ignored():
    """Ctrl-C (SIGINT) ignored inside, where this is the main thread (else nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def dask_setup(worker):
    """Run in each worker process of :func:`local_cluster` (a Dask preload): Ctrl-C in a
    terminal reaches the whole process group, but only the caller stops the batch (it
    closes the cluster, which ends the workers), so the workers ignore it instead of each
    printing a traceback; malloc keeps freed memory for reuse (:func:`tune_malloc`); and
    the modules of a task are imported. (Workers started by hand for ``--scheduler`` get
    the same from the environment: ``MALLOC_ARENA_MAX=1 MALLOC_MMAP_MAX_=0
    MALLOC_TRIM_THRESHOLD_=1073741824 dask worker ...``.)"""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    # Dask's MALLOC_TRIM_THRESHOLD_ is replaced; a value of one's own in the environment is kept.
    tune_malloc(keep=[k for k, (name, dask_value) in _MALLOC_ENV.items()
                      if os.environ.get(name, dask_value) != dask_value])
    # What a task needs, imported while the cluster starts (in every worker at once), not in its first task.
    import numpy.fft  # noqa: F401
    import PIL.Image  # noqa: F401
    import threadpoolctl  # noqa: F401

    from . import batch_task, fit_options, imageio, material, modelfile, synthesis  # noqa: F401


def tune_malloc(keep=()) -> bool:
    """Set :data:`WORKER_MALLOC` in this process's glibc ``malloc`` (``mallopt``), but for
    the settings named in ``keep``; False where there is no glibc."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    return all(mallopt(_MALLOPT[k], int(v)) == 1 for k, v in WORKER_MALLOC.items() if k not in keep)


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _cost(job) -> float:
    """A job's rough relative cost, to start the longest first (a shorter tail): one fit (more
    for a larger exemplar: its header's pixels, capped at 4 MP) plus a tenth of a fit per 512x512
    output pixels (in one thread a fit takes about 11 s, a 512x512 image about 1 s; docs/choices.md)."""
    try:
        from PIL import Image

        with Image.open(job["source"]) as img:
            pixels = img.size[0] * img.size[1]
    except Exception:  # noqa: BLE001 - not an image: it fails at once, last is fine
        return 0.0
    out = job["size"][0] * job["size"][1] * job["count"]
    maps = len(job.get("maps") or ())  # a material's joint fit and maps: about 1.6 times with three
    return (1.0 + 0.25 * min(pixels, 4 << 20) / (1 << 20) + 0.1 * out / (512 * 512)) * (1 + 0.3 * maps)


def _settings(item_settings, defaults, fit, generate):
    s = {**defaults, **item_settings}
    fit = {**fit, "scale": item_settings["scale"]} if "scale" in item_settings else fit  # a row's own working scale
    return {"size": list(s["size"]), "count": int(s["count"]), "seed": s["seed"], "tile": bool(s["tile"]),
            "fit": fit, "generate": generate}


def check_options(items, defaults, fit, generate) -> None:
    """Refuse bad fit and generation settings before any work, with the checks the fit and
    :meth:`TGHop.synthesize <tghop.synthesis.TGHop.synthesize>` make: every setting against
    the settings table (:func:`tghop.settings.check_settings`), the patch size's channel
    counts, and each exemplar's size, ``tile`` and ``overlap`` against the patch size of the
    fit settings (the quilting's own check, :func:`tghop.quilting.block_count`).

    Parameters
    ----------
    items : list of dict
        :func:`find_work`'s exemplars; a manifest row's are named by its line (``where``).
    defaults : dict
        ``size``, ``count``, ``seed`` and ``tile`` for the exemplars that give none.
    fit, generate : dict
        TGHop's parameters and the other keywords of ``synthesize`` (``tile`` apart).

    Raises
    ------
    TGHopError
        The first bad setting, prefixed with the manifest line that gives it.
    """
    from .fit_options import model_for
    from .quilting import block_count
    from .settings import check_settings

    model = model_for(fit, 3)
    model.check_settings()  # what TGHop.fit checks first
    checked = check_settings(generate)
    overlap = checked.get("overlap")
    material = next((it for it in items if it.get("maps")), None)
    if material is not None and checked.get("patch_refine"):
        raise TGHopError(f"{material.get('where')}: a material (maps) has no patch statistics for --quality best or "
                         "--patch-refine; drop them, or batch the materials apart")
    seen = set()
    for it in items:
        own = it["settings"]
        size, tile = tuple(own.get("size", defaults["size"])), bool(own.get("tile", defaults["tile"]))
        where = it.get("where") if "size" in own or "tile" in own else None
        if (size, tile, where) in seen:
            continue
        seen.add((size, tile, where))
        try:
            block_count(size, model.patch_size, overlap=overlap, tile=tile)
        except TGHopError as exc:
            raise TGHopError(f"{where}: {exc}" if where else str(exc)) from None


def _jsonable(value, name):
    try:
        return json.loads(json.dumps(value, default=str, allow_nan=False))
    except ValueError:
        raise TGHopError(f"{name}: every number must be finite (no NaN or infinity)") from None


def _check_call(outdir, fit, generate, workers, callables) -> None:
    """Refuse :func:`run`'s bad arguments (not its settings' values) before any work or file."""
    from .settings import fit_settings

    if not isinstance(outdir, (str, os.PathLike)) or not os.fsdecode(outdir).strip():  # "": the current folder
        raise TGHopError(f"outdir must be a folder path (str or Path), got {outdir!r}")
    names = {s.name for s in fit_settings()}
    for name, value in (("fit", fit), ("generate", generate)):
        if value is not None and not isinstance(value, dict):
            raise TGHopError(f"{name} must be a dict of settings by name, got {type(value).__name__}")
    bad = [k for k in fit or {} if k not in names] + [k for k in generate or {} if k in names]
    if bad:
        raise TGHopError(f"fit: unknown TGHop setting {bad[0]!r}; give TGHop's parameters" if bad[0] not in names else
                         f"generate: {bad[0]!r} is not a synthesize setting (run sets rng itself from seed)")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, numbers.Integral) or workers < 1):
        raise TGHopError(f"workers must be an integer >= 1 (or None: one per core), got {workers!r}")
    for name, fn in callables.items():
        if fn is not None and not callable(fn):
            raise TGHopError(f"{name} must be a callable (or None), got {fn!r}")


def run(source, outdir, *, count=1, size=(256, 256), seed=None, tile=False, fit=None, generate=None,
        workers=None, client=None, scheduler=None, retries=3, progress=None, on_result=None, contact_sheet=True,
        task=None):
    """Fit every exemplar of ``source`` and write a model and ``count`` images of each.

    Parameters
    ----------
    source : str or Path
        A folder of images (recursively) or a manifest (:func:`find_work`).
    outdir : str or Path
        Created if needed. ``OUTDIR/<name>/`` gets ``<name>.npz``, ``<name>.png`` (or ``<name>_1.png``
        ...) and ``exemplar.png`` (a thumbnail); ``OUTDIR/batch.jsonl`` one line per finished
        exemplar; ``OUTDIR/index.html`` the contact sheet.
    count, size, seed, tile
        Defaults for every exemplar (a manifest row gives its own). ``seed`` None: a fresh seed each, in the ledger.
    fit : dict
        :class:`~tghop.synthesis.TGHop` parameters; ``n_channels`` entries may be None (the default
        for the exemplar's colours).
    generate : dict
        Other keywords of :meth:`TGHop.synthesize` (``tile`` comes from ``tile``).
    workers : int, optional
        1: in this process, without Dask, each exemplar on every core. Otherwise a local cluster of
        that many worker processes (None: one per core, :func:`local_cluster`, or in this process
        with a warning where Dask is not installed), which import the calling script: call ``run``
        under its ``if __name__ == "__main__":``. On a cluster (also a
        given one) each exemplar runs on one thread (BLAS's and tghop's own), the longest first.
        At most :data:`WORKERS_PER_CORE` per usable core. Ignored when ``client`` or ``scheduler`` is given.
    client : distributed.Client, optional
        Run on this client's cluster.
    scheduler : str, optional
        The address of a running dask.distributed scheduler to connect to (``tcp://host:8786``, as
        ``tghop batch --scheduler``).
    retries : int
        How often a task whose worker died (killed, out of memory) is run again elsewhere
        before it is recorded as failed: ``distributed.scheduler.allowed-failures`` of the
        local cluster this function starts. A given ``client`` or ``scheduler`` keeps its
        own setting (Dask's default: 3). The task itself never raises for bad input.
    progress : callable(stage, done, total), optional
    on_result : callable(record, counts), optional
        Called with each finished exemplar's record and ``counts`` (done, failed, running, total, skipped).
    contact_sheet : bool
        Write ``OUTDIR/index.html`` at the end (also after an interruption).
    task : callable(job) -> record, optional
        What runs per exemplar (default :func:`process_exemplar`); a wrapper of it, e.g. to log
        or to test what a dying worker does. Dask must be able to pickle it.

    Returns
    -------
    list of dict
        One record per exemplar, in the order of ``source``: the ledger's fields (``name``, ``source``,
        ``sha256``, ``settings``, ``status``, ``error``, ``outputs``, ``model``, times, ...) and
        ``skipped`` (True: done by an earlier run).
    """
    _check_call(outdir, fit, generate, workers, {"progress": progress, "on_result": on_result, "task": task})
    most = WORKERS_PER_CORE * _cores()
    if client is None and scheduler is None and workers is not None and workers > most:
        raise TGHopError(f"the worker processes (workers, --workers): {workers} on this machine's {_cores()} cores; "
                         f"a local cluster takes at most {most} ({WORKERS_PER_CORE} per core: each exemplar runs on "
                         "one core); give fewer, none for one per core, or a scheduler's cluster")
    outdir = Path(os.path.abspath(outdir))
    items = find_work(source, outdir)
    defaults = {"size": list(parse_size(size, "size")), "count": parse_int(count, "run", "count", 1, 1000),
                "seed": None if seed is None else parse_int(seed, "run", "seed", 0),
                "tile": parse_bool(tile, "tile", where="run")}
    from .fit_options import fit_params
    from .settings import generate_settings

    fit = _jsonable({**fit_params({}), **(fit or {})}, "fit")  # every setting, as tghop batch records them
    generate = _jsonable({**{s.name: s.default for s in generate_settings() if s.name != "tile"},
                          **{k: v for k, v in (generate or {}).items() if k != "tile"}}, "generate")
    check_options(items, defaults, fit, generate)  # before any work, as synth would refuse them
    if outdir.exists() and not outdir.is_dir():
        raise TGHopError(f"{outdir} is a file; OUTDIR must be a folder")
    _check_own_files(outdir, contact_sheet)
    in_process = client is None and scheduler is None and (workers == 1 or (workers is None and _cores() == 1))
    if not in_process and client is None:
        try:
            _import_distributed()  # a missing extra is said before any work
        except MissingExtraError:
            if workers is not None or scheduler is not None:
                raise
            # The default on a core install: it works the first time, one exemplar after another.
            warnings.warn(f"Dask is not installed: the exemplars run one after another in this process; for one "
                          f"worker per core install it with: {INSTALL_HINT}", stacklevel=2)
            in_process = True
    task = process_exemplar if task is None else task
    previous, earlier_files = _read_ledger(outdir)
    _keep_ledger_names(items, previous)
    jobs, results = [], {}
    for it in items:
        settings = _settings(it["settings"], defaults, fit, generate)
        maps = it.get("maps") or []
        if maps:  # a material: its maps' names are settings too (none: the settings of a texture, as before)
            settings["maps"] = [name for name, _ in maps]
        job = {"name": it["name"], "source": str(it["path"]), "folder": str(outdir / it["name"]),
               "maps": [[name, str(file)] for name, file in maps],
               "sha256": inputs_sha256(it["path"], maps), "settings": settings, "size": settings["size"],
               "count": settings["count"], "seed": settings["seed"], "fit": settings["fit"],
               "generate": {**generate, "tile": settings["tile"]}, "threads": None if in_process else 1}
        if _is_done(previous.get(it["name"]), job, outdir):
            results[it["name"]] = {**previous[it["name"]], "skipped": True}
        else:
            jobs.append(job)
    own_client = ledger_file = None
    try:
        if jobs and scheduler is not None and client is None:
            client = own_client = _connect(scheduler)  # before OUTDIR is made: no empty OUTDIR when it fails
        try:
            outdir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise TGHopError(f"{outdir}: cannot create the output folder ({exc.strerror or exc})") from None
        from .imageio import check_output_path

        check_output_path(outdir / LEDGER, what="ledger", error=TGHopError)  # a file can be made in OUTDIR
        if jobs:
            ledger_file = _open_ledger(outdir)
    except BaseException:
        if own_client is not None:
            own_client.close()
        raise
    counts = {"done": 0, "failed": 0, "running": 0, "total": len(jobs), "skipped": len(results)}
    started = {}  # name -> job: handed out, no ledger line yet

    def begin(job):
        _mark_running(job, True)  # before the task can move any file into place
        started[job["name"]] = job

    def finish(job, record):
        rec = {"name": job["name"], "source": job["source"], "sha256": job["sha256"], "settings": job["settings"],
               **record}
        rec["finished"] = time.time()
        _append_ledger(ledger_file, rec)
        started.pop(job["name"], None)
        _mark_running(job, False)
        if rec["status"] == "ok":
            _remove_stale(outdir, earlier_files.get(job["name"], ()), rec)
        results[job["name"]] = {**rec, "skipped": False}
        counts["done"] += 1
        counts["failed"] += rec["status"] != "ok"
        if counts["done"] == counts["total"]:
            counts["running"] = 0
        if on_result is not None:  # first: a progress bar shows the counts it sets
            on_result(results[job["name"]], dict(counts))
        if progress is not None:
            progress("exemplars", counts["done"], counts["total"])

    if progress is not None and jobs:
        progress("exemplars", 0, len(jobs))
    try:
        if in_process:
            for job in jobs:
                counts["running"] = 1
                begin(job)
                finish(job, task(job))
            counts["running"] = 0
        elif jobs:
            _run_distributed(jobs, finish, counts, task, workers=workers, client=client, own_client=own_client,
                             retries=retries, begin=begin)
    finally:
        if ledger_file is not None:
            # A second Ctrl-C must not leave a started exemplar without its line; a full disk must not
            # leave the temporaries and the contact sheet below undone.
            with _ctrl_c_ignored(), contextlib.suppress(OSError):
                for job in list(started.values()):
                    _append_ledger(ledger_file, {"name": job["name"], "source": job["source"], "sha256": job["sha256"],
                                                 "settings": job["settings"], **_interrupted_record(job)})
                    _mark_running(job, False)  # the line says it now
            with contextlib.suppress(OSError):  # every line was flushed when appended
                ledger_file.close()
        for job in jobs:
            remove_temporaries(job["folder"])
            with contextlib.suppress(OSError):
                os.rmdir(job["folder"])  # only when empty: a failed exemplar's
        ordered = [results[it["name"]] for it in items if it["name"] in results]
        if contact_sheet and ordered:  # nothing finished, now or before (e.g. no scheduler): no empty page
            write_contact_sheet(outdir, ordered, total=len(items))
    return ordered


def _interrupted_record(job) -> dict:
    """The ledger line of an exemplar handed out but not finished when the run stopped (Ctrl-C, an
    error): its task may still have moved its files into place (a local cluster's worker finishes
    its task while the cluster closes; a given cluster's runs on), so the earlier line no longer
    describes the folder, and the next run does it again whatever its settings."""
    return {"status": "interrupted", "error": "the batch stopped before this exemplar's result came back (its "
            "files may be this run's or an earlier one's); the next run does it again", "outputs": [], "model": None,
            "thumbnail": None, "seed_used": job.get("seed"), "started": None, "seconds": None, "finished": time.time()}


def _died_record(job, exc, retries) -> dict:
    name = exc.__class__.__name__
    if name == "KilledWorker":
        error = ("the worker running it died on every try (killed or out of memory; "
                 f"{retries + 1} {'try' if retries == 0 else 'tries'} on a local cluster); use fewer workers per "
                 "machine or a smaller size")
    else:
        error = one_line(exc)
    return {"status": "failed", "error": error, "outputs": [], "model": None, "thumbnail": None,
            "seed_used": job.get("seed"), "started": None, "seconds": None}


def _connect(scheduler):
    """A client of the Dask scheduler at address ``scheduler``; one line when it cannot be reached."""
    distributed = _import_distributed()
    try:
        client = distributed.Client(scheduler, timeout="5s")
    except (OSError, TimeoutError, ValueError) as exc:  # ValueError: not an address
        reason = one_line(exc)
    else:
        if not client.nthreads():  # the run would wait without a word
            warnings.warn(f"the Dask scheduler at {scheduler} has no workers yet: the exemplars wait until one joins "
                          f"(start one: dask worker {scheduler} --nthreads 1; docs/batch.md)", stacklevel=2)
        return client
    # The half-started Client is in a reference cycle: collected later, inside a LocalCluster's
    # start, its __del__ deadlocks on the loop runner's lock. Collect it now (after the except).
    gc.collect()
    raise TGHopError(f"cannot reach the Dask scheduler at {scheduler} ({reason})")


def _run_distributed(jobs, finish, counts, task, *, workers, client, own_client, retries, begin):
    """Run ``jobs`` on ``client``'s cluster (None: a local cluster of ``workers``, started
    here); ``own_client``, and the cluster started here, are closed at the end. Each job
    goes to ``begin`` before it is handed out; ``finish`` takes its result."""
    distributed = _import_distributed()
    own_cluster = None
    futures = []
    try:
        if client is None:
            own_cluster = local_cluster(workers, retries=retries)
            client = own_client = distributed.Client(own_cluster)
        # The longest first (a shorter tail), handed out one per free thread as tasks finish:
        # a worker holds only the task it runs. Dask would place every task on a worker at
        # once (tasks of different names are not "root-ish", so it queues none on the
        # scheduler), and a worker's death would count against the tasks waiting on it too.
        order = iter(sorted(jobs, key=_cost, reverse=True))
        # This client's loop: as_completed would take the default client's, which may be another
        # (one closed by now: its futures were never reported, and the run waited for ever).
        by_key, running = {}, distributed.as_completed(loop=client.loop)

        def hand_out():
            slots = max(1, sum(client.nthreads().values()))  # again each time: a cluster may grow
            while running.count() < slots:
                job = next(order, None)
                if job is None:
                    break
                key = f"tghop-batch-{job['name']}-{job['sha256'] or 'none'}-{time.time_ns()}"
                begin(job)
                fut = client.submit(task, job, key=key, pure=False)
                by_key[fut.key] = job
                futures.append(fut)
                running.add(fut)
            counts["running"] = running.count()

        hand_out()
        for fut in running:
            job = by_key[fut.key]
            try:
                record = fut.result()
            except Exception as exc:  # noqa: BLE001 - KilledWorker, or a task that raised every time
                record = _died_record(job, exc, retries)
            fut.release()
            hand_out()  # before the ledger line: the freed worker starts at once
            finish(job, record)
    except BaseException:
        try:
            if client is not None:
                client.cancel([f for f in futures if not f.done()])
        except Exception:  # noqa: BLE001 - stopping anyway
            pass
        raise
    finally:
        with _ctrl_c_ignored():  # a second Ctrl-C must not leave the cluster half-closed
            if own_client is not None:
                own_client.close()
            if own_cluster is not None:
                own_cluster.close()


def write_contact_sheet(outdir, records, total=None) -> Path:
    """``OUTDIR/index.html`` of a batch (:func:`tghop.contact_sheet.write_contact_sheet`,
    linking the ledger)."""
    return _write_sheet(outdir, records, total=total, ledger=LEDGER)
