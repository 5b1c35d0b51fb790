"""The task :mod:`tghop.batch` runs per exemplar: fit its model (a texture model, or with maps
a whole material, :class:`tghop.material.Material`) and write the model, its images and a
thumbnail into the exemplar's folder, all together or none (:func:`process_exemplar`).

A plain top-level function, so that Dask pickles it by reference; it never raises for bad
input: a failure is a record with its one-line error.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import threading
import time
from pathlib import Path

from ._errors import HINT_DOWNSCALE_YOURSELF, MissingExtraError, TGHopError, collect_warnings, warn
from ._formats import is_model_file, model_file_kind

__all__ = ["process_exemplar", "run_checked", "remove_temporaries", "one_line", "outside_the_files", "disk_full",
           "task_threads", "output_files", "write_claim", "holding_claim", "within", "timed_out_record", "TaskTimeout",
           "STAGE", "THUMBNAIL", "THUMBNAIL_FILE", "RUNNING", "SUPERSEDED", "claimed"]

#: Prefix and suffix of the hidden folder in which :func:`process_exemplar` makes an exemplar's files.
STAGE = (".partial.", ".tmp")
#: In an exemplar's folder from its hand-out until its ledger line is written: a rerun does again
#: an exemplar that has one (the run that wrote it was killed, its task may have run on and
#: replaced the files an earlier line lists: a given cluster's task runs on without its client).
#: It holds the claim of the run that handed the exemplar out (0.62, :func:`write_claim`): a task moves its
#: files into place only while the claim is its own (:func:`holding_claim`).
RUNNING = ".batch-running"
#: The error of a task whose exemplar another run claimed since (0.62): a killed run's task that ran on.
SUPERSEDED = ("superseded: this exemplar's claim (its .batch-running file) was no longer this task's run's when its "
              "files were to be moved in: another run claimed it since (the run that handed it out was stopped or "
              "killed), or the file was removed; its files were dropped, and the next run makes it again")
#: Longest side of the exemplar thumbnail of the contact sheet, and its file in NAME/.
THUMBNAIL, THUMBNAIL_FILE = 128, "exemplar.png"
#: The process-wide thread limits of the tasks running in this process (:func:`task_threads`).
_HOLD = {"lock": threading.Lock(), "count": 0, "limit": None, "stack": None}
#: Whether :func:`within`'s alarm may stop the task now: :func:`process_exemplar` clears it before it moves its
#: files into place, so that they are all moved or none (0.63).
_ALARM = {"armed": False}
#: :func:`within`'s longest timer, seconds (31 years): a longer ``task_timeout`` is this one in this process
#: (setitimer refuses more than about 9.2e9 s; 0.63 raised OverflowError at --task-timeout 1e300, 0.64).
LONGEST_TIMER = 1e9


class TaskTimeout(BaseException):
    """Raised in the main thread by :func:`within`'s alarm: a task past its time. A BaseException, as Ctrl-C's
    KeyboardInterrupt: a task's own ``except Exception`` (a bad exemplar's record) does not take it."""


def timed_out_record(job: dict, seconds: float, started: float, lost: bool = False) -> dict:
    """The ledger record of ``job``'s task stopped after ``seconds`` (``task_timeout``, 0.63): the exemplar's own
    failure (``cause`` "input": reruns skip it, :func:`tghop.batch_plan.is_known_failure`, until its input or settings
    change, a longer timeout is given or ``--retry-failed``). ``lost``: its worker was restarted at an unknown point
    of the task (``task_lost``: it may have moved files in)."""
    record = {"status": "failed", "cause": "input", "outputs": [], "model": None, "thumbnail": None,
              "error": f"stopped after the task timeout ({seconds:g} s, --task-timeout / task_timeout): a huge or "
                       "pathological exemplar, or too much asked of it; give a smaller size, count or exemplar, or a "
                       "longer timeout (a rerun with a longer one tries it again, as --retry-failed does)",
              "seed_used": job.get("seed"), "started": started, "seconds": time.time() - started,
              "timed_out": True, "task_timeout": seconds}
    return {**record, "task_lost": True} if lost else record


def within(task, job: dict, seconds):
    """``task(job)`` in this process, stopped once it has run ``seconds`` (None: no limit; 0.63): a timer's signal
    (SIGALRM) raises :class:`TaskTimeout` in the main thread, which is ``job``'s record then
    (:func:`timed_out_record`). Only where this is the main thread and the system has the signal (POSIX): callers
    check that first. A single call into a library that never returns (C code) is not stopped; a task on Dask is
    (:func:`tghop.batch_dask.run_distributed` restarts its worker)."""
    if seconds is None:
        return task(job)
    import signal

    started = time.time()

    def expired(signum, frame):
        if _ALARM["armed"]:
            _ALARM["armed"] = False
            raise TaskTimeout

    previous = signal.signal(signal.SIGALRM, expired)
    _ALARM["armed"] = True
    try:  # the timer set inside: a short one fires as setitimer returns (0.63's traceback at 1e-9 s, 0.64)
        signal.setitimer(signal.ITIMER_REAL, min(seconds, LONGEST_TIMER))
        return task(job)
    except TaskTimeout:
        return timed_out_record(job, seconds, started)
    finally:
        _ALARM["armed"] = False
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@contextlib.contextmanager
def task_threads(n):
    """Context manager: BLAS (``threadpoolctl``) and tghop's own threads
    (:func:`tghop._resources.limit_cores`) at most ``n`` (None: no limit) while any task of this
    process is inside, OpenMP's in the calling thread.

    Both limits are the process's, not a thread's: on a worker that runs two tasks at once
    (``dask worker --nthreads 2``) each task entering and leaving limits of its own put back,
    when the first ended, the limits from before it while the other still ran (its ICHM clusters
    and refinement on every core, its BLAS too where the worker's default is more than one
    thread: ``--no-nanny``). So the first task to enter sets them, a task asking for fewer
    lowers them, and the last to leave puts back what was there before (BLAS's only where it leaves
    in the thread that set it, or after that thread ended: OpenBLAS (0.3.31, pthreads, measured)
    takes no new limit from another thread while the thread that set the last one lives, so a
    worker, or a program whose Dask client runs tasks in its own threads, may keep one BLAS thread
    after its tasks: :func:`tghop.batch.run`, Notes)."""
    if n is None:
        yield
        return
    from threadpoolctl import threadpool_limits

    from ._resources import limit_cores

    with _HOLD["lock"]:
        if _HOLD["count"] == 0:
            _HOLD["stack"], _HOLD["limit"] = contextlib.ExitStack(), None
        if _HOLD["limit"] is None or n < _HOLD["limit"]:
            _HOLD["stack"].enter_context(threadpool_limits(limits=n, user_api="blas"))
            _HOLD["stack"].enter_context(limit_cores(n))
            _HOLD["limit"] = n
        _HOLD["count"] += 1
    try:
        with threadpool_limits(limits=n, user_api="openmp"):  # a thread's own setting (omp_set_num_threads)
            yield
    finally:
        with _HOLD["lock"]:
            _HOLD["count"] -= 1
            if _HOLD["count"] == 0:
                _HOLD["stack"].close()
                _HOLD["stack"] = _HOLD["limit"] = None


def _numbered(name: str, count: int):
    if count == 1:
        return [f"{name}.png"]
    width = len(str(count))
    return [f"{name}_{i:0{width}d}.png" for i in range(1, count + 1)]


def output_files(name: str, count: int, maps=None) -> list:
    """The images :func:`process_exemplar` writes for exemplar ``name`` (file names in its folder): ``count``
    numbered files, each with its material's maps (``maps``: their names, the settings' ``maps``; None: a
    texture), as :func:`tghop.material_files.map_files` names them."""
    if not maps:
        return _numbered(name, count)
    from .map_names import ALBEDO
    from .material_files import map_files

    return [each for file in _numbered(name, count) for each in map_files(file, [ALBEDO, *maps])]


def _lock(fd) -> None:
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: the claim is checked unlocked
        return
    with contextlib.suppress(OSError):  # a file system without locks: checked unlocked
        fcntl.flock(fd, fcntl.LOCK_EX)


def claimed(folder) -> bool:
    """Whether ``folder`` holds a :data:`RUNNING` file: its exemplar was handed out by a run that wrote no line for it
    (killed, or still running). A folder of that name is none (tghop makes none; 0.62 took it for one, and as
    it cannot be removed as a file, made the exemplar again in every rerun without a word)."""
    path = os.path.join(folder, RUNNING)
    return os.path.lexists(path) and not os.path.isdir(path)


def write_claim(folder, claim) -> bool:
    """Make ``folder``'s :data:`RUNNING` file hold ``claim`` (the run's own id; the folder made as needed), under
    its lock: a task of an earlier run moving its files into place under its own claim (:func:`holding_claim`)
    ends that first. False where it cannot be written (the task then fails and says why, or runs unchecked)."""
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
        fd = os.open(Path(folder) / RUNNING, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError:
        return False
    try:
        _lock(fd)
        os.ftruncate(fd, 0)
        os.write(fd, str(claim).encode("utf-8"))
        return True
    except OSError:
        return False
    finally:
        os.close(fd)  # the lock with it


@contextlib.contextmanager
def holding_claim(folder, claim):
    """Context manager: whether ``folder``'s :data:`RUNNING` file holds ``claim`` (None: no claim to check, True),
    its lock held inside, so that no other run claims the exemplar while the files are moved (0.62). A run killed
    outright (``tghop batch --scheduler`` killed: its tasks run on the cluster) leaves tasks that may move their
    files into place after a rerun's, over them, under the rerun's ledger line: the rerun claims the exemplar
    anew at its hand-out, and its line removes the file, so such a task finds the claim another's, or none."""
    if claim is None:
        yield True
        return
    fd = None
    for mode in (os.O_RDWR, os.O_RDONLY):  # NFS locks a file opened for writing; a worker of another user reads it
        try:
            fd = os.open(Path(folder) / RUNNING, mode)
            break
        except FileNotFoundError:  # none: the exemplar's line was written (by this claim's run or a later one)
            yield False
            return
        except OSError:
            continue
    if fd is None:  # not readable here: unchecked, as before 0.62
        yield True
        return
    try:
        _lock(fd)
        yield os.read(fd, 4096).decode("utf-8", "replace") == str(claim)
    finally:
        os.close(fd)


def remove_temporaries(folder) -> int:
    """Remove what :func:`tghop.imageio.write_atomic` leaves when its process is killed
    (``.NAME.*.tmp``) in ``folder``, and :func:`process_exemplar`'s folders of files not yet
    moved into place (``.partial.*.tmp``); returns how many."""
    removed = 0
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return 0
    for entry in entries:
        if entry.name.startswith(STAGE[0]) and entry.name.endswith(STAGE[1]) and entry.is_dir(follow_symlinks=False):
            shutil.rmtree(entry.path, ignore_errors=True)
            removed += 1
        elif entry.name.startswith(".") and entry.name.endswith((".tmp", ".probe")) and entry.is_file():
            try:
                os.unlink(entry.path)
                removed += 1
            except OSError:
                pass
    return removed


def _thumbnail(image, path):
    import numpy as np
    from PIL import Image

    from .imageio import save_image

    arr = np.asarray(image)
    pil = Image.fromarray(arr[..., 0] if arr.shape[2] == 1 else arr)
    pil.thumbnail((THUMBNAIL, THUMBNAIL))
    save_image(np.asarray(pil), path)


def _read_maps(maps) -> dict:
    """A material's maps, ``{name: (image, depth)}`` in the order listed (none: ``{}``), each read as
    every reader of a material's maps reads it (:func:`tghop.material_files.read_map`: an alpha channel
    that holds data fails the row)."""
    from .material_files import read_map

    return {name: read_map(file, name, too_large_hint=HINT_DOWNSCALE_YOURSELF) for name, file in maps or ()}


def _check_colour_map(source, maps) -> None:
    """A manifest row's material whose path (the albedo) is named as another kind of map fails or is
    warned of as ``tghop fit --maps`` refuses or warns of it (:func:`tghop.map_names.check_colour_map_order`,
    in a manifest's words; ``maps``: the row's ``[(name, file)]``, a map's kind its name's, as
    ``color=Rock_C.png`` gives it, else its file's): a map of the row named as the colour map (the two
    swapped), or the path named as a normal map and no map as the colour map, is a
    :class:`~tghop.TGHopError` naming the fix (0.56 fitted both without a word); the path named as another
    kind (``Rock_Roughness.png``) and no map as the colour map is fitted as given, with a warning in the
    row's ledger line (a material may have no colour map)."""
    from .map_names import check_colour_map_order

    said = check_colour_map_order(
        Path(source).name, [file for _, file in maps], names=[name for name, _ in maps],
        shown=[Path(file).name for _, file in maps], albedo="the row's path {albedo}", map="its map {colour}",
        none="none of its maps", swap="swap them, {colour} as the row's path and {albedo} among its maps",
        first="give the material's colour map as the row's path (e.g. Rock_Color.png) and {albedo} among its maps",
        written="its images' albedo, NAME.png", expected="as the row's path")
    if said is not None:
        warn(said, UserWarning)


def one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text if isinstance(exc, TGHopError) else f"{exc.__class__.__name__}: {text}"


def outside_the_files(exc: BaseException) -> bool:
    """Whether a failure of reading an exemplar has its cause outside its files, so that the same
    files may pass another time: a library or decoder missing (:class:`~tghop.MissingExtraError`:
    a WebP file where Pillow was built without WebP, a 16-bit colour TIFF without tifffile), or
    tghop's one line raised while handling an ``ImportError`` or a ``MemoryError`` ("not enough
    memory to decode this image")."""
    cause = exc.__cause__ or exc.__context__  # the latter also where tghop's one line was raised "from None"
    return isinstance(exc, MissingExtraError) or isinstance(cause, (ImportError, MemoryError))


def disk_full(exc: BaseException) -> bool:
    """Whether ``exc``, or an error it was raised from or while handling (tghop's one line of a write,
    :func:`tghop.output_files.write_atomic`'s, is raised "from None" while handling the system's), is a full disk
    or quota (``ENOSPC``, ``EDQUOT``): every exemplar after it would fail alike (0.61, :func:`tghop.batch.run`)."""
    import errno

    seen = 0
    while exc is not None and seen < 8:
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)):
            return True
        exc, seen = exc.__cause__ or exc.__context__, seen + 1
    return False


def process_exemplar(job: dict) -> dict:
    """Fit one exemplar and write its model, images and thumbnail (a plain top-level
    function, so that Dask pickles it by reference).

    ``job``: ``source`` (the image file), ``folder`` (its output folder), ``name``, ``size``, ``count``,
    ``seed`` (None: a fresh one, recorded), ``fit`` (TGHop's parameters), ``generate`` (keywords of
    :meth:`TGHop.synthesize`), ``threads`` (threads at most, BLAS's and tghop's own:
    :func:`task_threads`; None: no limit), ``maps`` (``[[name, file]]``: the exemplar
    is the albedo of a whole material, :class:`tghop.material.Material`; each image is then the
    albedo ``NAME.png`` and a file per map, ``NAME_<suffix>.png``
    (:func:`tghop.material_files.map_files`), at the map's depth, as ``tghop synth`` writes a material).

    Returns what the ledger records: ``status`` ("ok" or "failed"), ``error`` (one line), ``cause`` (of a
    failure: "input" where reading, checking or fitting the exemplar refused it, the same each time for
    the same files and settings; "run" for what may pass, memory, writing, an unexpected error, a library or
    decoder missing (0.57: :func:`outside_the_files`; it was "input"), ``outputs``,
    ``model`` and ``thumbnail`` (relative to OUTDIR), ``disk_full`` (True only where its files met a full disk:
    :func:`disk_full`, the run then stops; 0.61), ``seed_used``, ``warnings`` (the messages of tghop's own,
    :func:`tghop._errors.collect_warnings`: of this task alone where a worker runs several on threads),
    times (``seconds``, ``cpu_seconds`` of the whole process and ``sys_seconds``, the kernel's part of
    them, with its ``page_faults``; ``fit_seconds``, ``synth_seconds``), ``threads``, the worker and
    its peak memory. Bad input is a "failed" record, never an exception. The files are made in a
    hidden folder and moved into place together at the end: a failed or interrupted exemplar (Ctrl-C,
    a killed worker: :func:`remove_temporaries`) leaves none of its own, and an earlier run's files of
    it as they were.
    """
    import resource
    import socket

    start, cpu_start, usage = time.time(), time.process_time(), resource.getrusage(resource.RUSAGE_SELF)
    folder = Path(job["folder"])
    name = job["name"]
    record = {"status": "failed", "error": None, "cause": None, "outputs": [], "model": None, "thumbnail": None,
              "seed_used": job.get("seed"), "started": start, "fit_seconds": None, "synth_seconds": None,
              "worker": f"{socket.gethostname()}:{os.getpid()}"}
    stage, caught, phase = None, [], "input"  # phase: what a TGHopError is blamed on (the record's cause)
    with holding_claim(folder, job.get("claim")) as current:
        pass
    if not current:  # a stopped run's task started late: another run has the exemplar (0.62)
        return {**record, "error": SUPERSEDED, "cause": "run", "superseded": True, "seconds": time.time() - start}
    try:
        import numpy as np

        from .fit_options import material_model, model_for
        from .imageio import deepest, load_image, save_image
        from .material import Material
        from .material_files import map_files
        from .modelfile import save_model
        from .synthesis import prepare_exemplar

        if folder.is_file() or folder.is_symlink() and not folder.is_dir():  # 0.61 said FileExistsError, Errno 17
            phase = "run"  # not the exemplar's fault: a rerun tries it again once the file is gone
            raise TGHopError(f"{folder} is a file, where the folder of {name}'s results goes; move or remove that "
                             "file, or choose another OUTDIR")
        folder.mkdir(parents=True, exist_ok=True)
        remove_temporaries(folder)  # left by a worker killed while writing here
        # Every file is made in a hidden folder of its own, then moved into place together
        # once all are made: a failed, interrupted or killed task leaves none of its files
        # (and the files of an earlier run of this exemplar as they were).
        stage = Path(tempfile.mkdtemp(prefix=STAGE[0], suffix=STAGE[1], dir=folder))
        with task_threads(job.get("threads")), collect_warnings() as caught:  # the ledger line: this task's own
            fit = job.get("fit") or {}
            if is_model_file(job["source"]):  # by its content, as fit reads it (0.58: any *.npz, a missing one too)
                kind = model_file_kind(job["source"])
                raise TGHopError(f"{job['source']} is {kind}, not an image; list the exemplar image")
            if job.get("maps"):  # the colour map out of place by the files' names: refused or said, as fit does
                _check_colour_map(job["source"], job["maps"])
            raw, depth = load_image(job["source"], dtype=None, too_large_hint=HINT_DOWNSCALE_YOURSELF,
                                    with_depth=True)
            image = prepare_exemplar(raw)
            model = model_for(fit, image.shape[2])
            model.check_exemplar_size(image.shape)  # the fit's check: names the smallest exemplar that works
            maps = _read_maps(job.get("maps"))
            t = time.time()
            if maps:
                model = Material(model=material_model(fit)).fit(
                    image, {k: v for k, (v, _) in maps.items()},
                    depths={"albedo": depth, **{k: d for k, (_, d) in maps.items()}})
            else:
                model.fit(image, depth=depth)  # recorded: synth from the model warns of a 16-bit exemplar's bits
            record["fit_seconds"] = time.time() - t
            phase = "run"  # read, checked and fitted: what fails from here on is the run's (disk, memory)
            thumb = THUMBNAIL_FILE
            _thumbnail(raw if raw.dtype == np.uint8 else np.round(np.clip(raw, 0, 1) * 255).astype(np.uint8),
                       stage / thumb)
            model_file = f"{name}.npz"
            save_model(model, stage / model_file)
            seed = job.get("seed")
            if seed is None:
                seed = int(np.random.SeedSequence().generate_state(1)[0])
            record["seed_used"] = seed
            rng = np.random.default_rng(seed)
            t = time.time()
            outputs = []
            for file in _numbered(name, job.get("count", 1)):
                if maps:  # NAME.png, each map at NAME_<suffix>.png (map_files; a PNG holds 16 bits at most)
                    made = model.synthesize(tuple(job["size"]), rng=rng, dtype=np.float32,
                                            **(job.get("generate") or {}))
                    files = map_files(file, model.names_)
                    for img, each, d in zip(made.values(), files, model.depths_):
                        save_image(img, stage / each, depth=deepest(each, d))
                    outputs.extend(files)
                    continue
                img = model.synthesize(tuple(job["size"]), rng=rng, dtype=np.uint8, **(job.get("generate") or {}))
                save_image(img, stage / file)
                outputs.append(file)
            record["synth_seconds"] = time.time() - t
        for file in [*outputs, thumb, model_file]:  # a folder in the way failed a move, the files before it moved
            if (folder / file).is_dir():  # (0.61): none moved
                raise TGHopError(f"{folder / file} is a folder, where {name}'s file of that name goes; move or remove "
                                 "that folder, or choose another OUTDIR")
        _ALARM["armed"] = False  # the task timeout (in process) stops it no more: its files all moved, or none
        with holding_claim(folder, job.get("claim")) as current:  # no other run claims it meanwhile
            if not current:  # a stopped run's task that ran on: its files would replace a later run's (0.62)
                record["superseded"] = True
                raise TGHopError(SUPERSEDED)
            for file in [*outputs, thumb, model_file]:
                os.replace(stage / file, folder / file)
        prefix = folder.name
        record.update(status="ok", outputs=[f"{prefix}/{f}" for f in outputs], model=f"{prefix}/{model_file}",
                      thumbnail=f"{prefix}/{thumb}")
    except MemoryError:
        record["error"] = "out of memory; use a smaller size or exemplar, or fewer workers per machine"
        record["cause"] = "run"
    except Exception as exc:  # noqa: BLE001 - one exemplar's failure is recorded, the batch goes on
        record["error"] = one_line(exc)
        if stage is not None:  # a file named where it goes, not in the hidden folder (0.60: .../.partial.x.tmp/N.npz)
            record["error"] = record["error"].replace(f"{stage}{os.sep}", f"{folder}{os.sep}")
        # The input's (not an image, flat, too small, a bad map): a rerun skips it until its files or
        # settings change (tghop.batch_plan.is_known_failure). Anything else is tried again.
        input_fault = phase == "input" and isinstance(exc, TGHopError) and not outside_the_files(exc)
        record["cause"] = "input" if input_fault else "run"
        if disk_full(exc):  # the run stops: every exemplar after it would fit, then fail alike (tghop.batch.run)
            record.update(cause="run", disk_full=True)
    finally:  # Ctrl-C (KeyboardInterrupt) and the command's SIGTERM too: they go on once this is done
        if stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
        if record["status"] != "ok":
            with contextlib.suppress(OSError):
                folder.rmdir()  # only when empty
    record["warnings"] = [str(w) for w in caught if isinstance(w, (UserWarning, RuntimeWarning))]
    record["seconds"] = time.time() - start
    record["cpu_seconds"] = time.process_time() - cpu_start  # this process's threads, all of them
    now = resource.getrusage(resource.RUSAGE_SELF)
    record["sys_seconds"] = now.ru_stime - usage.ru_stime  # mostly page faults of fresh memory
    record["page_faults"] = (now.ru_minflt + now.ru_majflt) - (usage.ru_minflt + usage.ru_majflt)
    record["threads"] = job.get("threads")
    record["peak_rss_mb"] = _peak_rss_mb(resource)
    return record


def run_checked(task, job: dict, version: str):
    """``task(job)``, run on a Dask worker only where its tghop is ``version`` (the batch's: the calling
    process's), else a one-line :class:`~tghop.TGHopError` naming the worker (0.58). What :func:`tghop.batch.run`
    hands to Dask: a worker that joined the cluster after the check of its workers
    (:func:`tghop.batch_dask.check_workers_tghop`) may have another tghop, which made its exemplar under this
    version's ledger line, or none. It cannot run this either (a tghop without it, 0.57 and earlier, or
    none: the task cannot be loaded there, and Dask's worker closes itself), so such a worker's task fails,
    and a ``--scheduler`` run stops with one line naming the worker (:func:`tghop.batch_dask.run_distributed`)."""
    from . import __version__

    if __version__ != version:
        import socket

        raise TGHopError(f"the Dask worker {socket.gethostname()}:{os.getpid()} runs tghop {__version__}, not this "
                         f"batch's {version}: install tghop {version} on every worker and restart it")
    return task(job)


def _peak_rss_mb(resource) -> float:
    """This process's peak resident memory in MB: VmHWM where Linux gives it, since
    ``ru_maxrss`` survives fork and exec (a spawned Dask worker would report its parent's
    peak when that is larger)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except (OSError, ValueError):
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
