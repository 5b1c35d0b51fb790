"""Many exemplars at once: a model and N images per exemplar, in process or on Dask.

:func:`run` finds the work (every image of a folder, or the rows of a manifest: :mod:`tghop.manifest`),
skips what a previous run finished (the ledger ``OUTDIR/batch.jsonl``: one JSON line per finished
exemplar with its input's SHA-256, its settings and its outputs; ``interrupted`` for one under way when
a run stops; synced per group of exemplars that came back together, and compacted at a run's end where
many lines are superseded, :func:`tghop.batch_plan.compact_ledger`, 0.59), runs :func:`process_exemplar` for the
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

The parts, by what they do (their public names are importable from here too): :mod:`tghop.batch_plan`
finds the work, names the exemplars' folders and keeps the ledger; :mod:`tghop.batch_dask` runs on
Dask (the local cluster, the workers' set-up, handing out the tasks); :mod:`tghop.batch_task` is one
exemplar's task; :mod:`tghop.contact_sheet` the HTML page. This module holds :func:`run` and the
checks of its arguments (:func:`check_options`).
"""

from __future__ import annotations

import contextlib
import json
import math
import numbers
import os
import signal
import threading
import time
import uuid
import warnings
from pathlib import Path

from . import __version__
from ._errors import MissingExtraError, TGHopError
from .batch_dask import (INSTALL_HINT, QUIET_CLUSTER, WORKER_ENVIRON, WORKER_MALLOC, WORKERS_PER_CORE,
                         SchedulerLostError, affinity_cores, check_cluster, connect, ctrl_c_deferred, ctrl_c_ignored,
                         dask_setup, import_distributed, local_cluster, run_distributed, tune_malloc)
from .batch_plan import (IMAGE_SUFFIXES, LEDGER, NAME_MAX, RUNNING, append_ledger, check_own_files, compact_ledger,
                         find_orphans, find_work, input_digest, inputs_sha256, is_done, is_known_failure,
                         keep_ledger_names, mark_running, move_renamed, open_ledger, prune_orphans,
                         read_hashes, read_ledger, read_ledger_files, remove_stale, renamable, renamed_from,
                         sync_ledger, worker_deaths, write_hashes)
from .batch_task import claimed, disk_full, process_exemplar, remove_temporaries, within
from .contact_sheet import CONTACT_SHEET, write_contact_sheet as _write_sheet
from .manifest import parse_bool, parse_int, parse_size

__all__ = ["run", "find_work", "check_options", "process_exemplar", "read_ledger", "write_contact_sheet",
           "inputs_sha256", "local_cluster", "IMAGE_SUFFIXES", "LEDGER", "CONTACT_SHEET", "INSTALL_HINT",
           "WORKER_MALLOC", "WORKER_ENVIRON", "WORKERS_PER_CORE", "QUIET_CLUSTER", "NAME_MAX", "RUNNING", "tune_malloc",
           "dask_setup", "SchedulerLostError"]


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
    if checked.get("patch_refine") and not model.patch_levels:  # a material's albedo too (0.58 refused materials)
        raise TGHopError("--quality best and --patch-refine need the patch statistics that patch_levels 0 leaves out "
                         "of the fit; give patch_levels above 0 (--patch-levels), or drop them")
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


def _check_call(outdir, fit, generate, workers, callables, task_timeout=None) -> None:
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
    if task_timeout is not None and (isinstance(task_timeout, bool) or not isinstance(task_timeout, numbers.Real)
                                     or not math.isfinite(task_timeout) or task_timeout <= 0):
        raise TGHopError(f"task_timeout must be a number of seconds above 0 (or None: no limit), got {task_timeout!r}")


def run(source, outdir, *, count=1, size=(256, 256), seed=None, tile=False, fit=None, generate=None,
        workers=None, client=None, scheduler=None, retries=3, progress=None, on_result=None, contact_sheet=True,
        task=None, prune=False, on_orphans=None, retry_failed=False, max_depth=None, on_plan=None,
        worker_setup=None, force=False, task_timeout=None):
    """Fit every exemplar of ``source`` and write a model and ``count`` images of each.

    Parameters
    ----------
    source : str or Path
        A folder of images (recursively) or a manifest (:func:`find_work`).
    outdir : str or Path
        Created if needed. ``OUTDIR/<name>/`` gets ``<name>.npz``, ``<name>.png`` (or ``<name>_1.png``
        ...) and ``exemplar.png`` (a thumbnail); ``OUTDIR/batch.jsonl`` one line per finished
        exemplar; ``OUTDIR/index.html`` the contact sheet; ``OUTDIR/.batch-hashes.json`` the inputs'
        SHA-256 with their files' size, times and inode, so that a rerun does not read unchanged files
        again (:func:`tghop.batch_plan.input_digest`; 0.58).
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
        Run on this client's cluster (left open). Its workers are checked as ``scheduler``'s are (0.59; 0.58
        checked none): before any work, every one must import this tghop, and one that joins mid-run with
        another or none stops the run (:func:`tghop.batch_dask.check_cluster`), but for those a cluster object
        of this process (``client.cluster``, a LocalCluster) starts itself: its restarts, its ``scale`` (0.60; 0.59
        checked no worker that joined such a cluster, one started elsewhere against its scheduler too).
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
        Called with each finished exemplar's record and ``counts``: ``done`` (this run's exemplars
        finished, ``failed`` among them), ``running``, ``total`` (this run's to make), ``skipped``
        (done by an earlier run, not made again) and ``failed_before`` (skipped as failed before,
        :func:`tghop.batch_plan.is_known_failure`; 0.57: 0.56 counted them in ``skipped``, so
        ``skipped + failed_before`` is 0.56's ``skipped``).
    contact_sheet : bool
        Write ``OUTDIR/index.html`` at the end (also after an interruption).
    task : callable(job) -> record, optional
        What runs per exemplar (default :func:`process_exemplar`); a wrapper of it, e.g. to log
        or to test what a dying worker does. Dask must be able to pickle it.
    prune : bool
        Delete the folders an earlier run made in OUTDIR for exemplars no longer in ``source``
        (removed or renamed there since; :func:`tghop.batch_plan.find_orphans`): the files their
        ledger lines list, and the folder where nothing else is in it (:func:`tghop.batch_plan.prune_orphans`).
        Kept, each said in a warning (0.62; :func:`prune_held`): those whose source folder cannot be
        read, always; those whose source folder is missing (a share down), and all where more than half of the
        exemplars would go (over 10), unless ``force``.
    force : bool
        With ``prune``: also the exemplars whose source folder is missing, however many (0.62).
    task_timeout : float, optional
        Seconds after which an exemplar's task is stopped and recorded as its failure (0.63; None, the default: no
        limit): ``cause`` "input", skipped by reruns until its input or settings change, a longer ``task_timeout``
        is given, or ``retry_failed``; the run goes on. On Dask, counted from its hand-out; the task is cancelled
        and its worker restarted (through its nanny: one without runs on to the task's end, its files dropped),
        beside the run (0.64), its other tasks handed out again without a death counted against them (0.64). In
        this process (``workers=1``), by a timer's signal in the main thread (POSIX; elsewhere refused): a single
        call into C code that never returns is not stopped there.
    on_orphans : callable(orphans), optional
        Called once, before any work, where there are such folders: a list of dicts, ``name``
        (the folder's), ``pruned`` (its files removed), ``kept`` (the entries left in it: not
        tghop's, so the folder stays) and ``held`` (0.62: why ``prune`` kept it, else None). Without it, a warning
        names them.

    retry_failed : bool
        Try again the exemplars whose input failed in an earlier run (``cause`` "input": not an
        image, flat, too small, a bad map) although their files, settings and tghop's version are
        unchanged. Without it a rerun skips them (:func:`tghop.batch_plan.is_known_failure`) and
        returns their earlier record; a failure of the run's (memory, a lost worker, an
        interruption) is tried again, but for a worker dead on every try in
        :data:`~tghop.batch_plan.LOST_RUNS` runs in a row (0.62: the exemplar's own failure, a decoder's crash).
    max_depth : int, optional
        How many levels of subfolders of a folder ``source`` are searched: 0 its own images only,
        1 those of its subfolders too, ...; None (the default) every level. Refused for a manifest.
    on_plan : callable(plan), optional
        Called once before any work with a dict: ``exemplars`` (all of ``source``), ``done_before``
        (skipped: done by an earlier run), ``failed_before`` (skipped: failed before, input unchanged)
        and ``to_do`` (what this run makes; ``progress``'s total).
    worker_setup : callable(), optional
        Run in each worker process of the local cluster this function starts, before its first task,
        and in one started after a worker's death (``Client.register_worker_callbacks``; 0.58): a
        program's own choices for its workers, such as logging (``tghop batch`` keeps tifffile's log
        lines of a malformed TIFF off the terminal there, :func:`tghop.cli.common.quiet_tifffile`, as in
        its own process). Dask must be able to pickle it (a module's top-level function). Ignored in
        this process (``workers=1``) and with ``client`` or ``scheduler``: their processes are the caller's.

    Returns
    -------
    list of dict
        One record per exemplar, in the order of ``source``: the ledger's fields (``name``, ``source``,
        ``sha256``, ``settings``, ``status``, ``error``, ``cause``, ``outputs``, ``model``, ``version``,
        times, ...) and ``skipped`` (True: an earlier run's record, done or a known failure); ``renamed`` (True, 0.62:
        an exemplar done before under another name, ``renamed_from``, its files moved to its name by this run:
        :func:`tghop.batch_plan.renamed_from`).

    Raises
    ------
    SchedulerLostError
        The Dask scheduler went away mid-run (0.58: a :class:`~tghop.TGHopError` of its own class, so that a
        caller can tell "run it again" from a refusal; ``tghop batch`` exits with status 3 for it).
    TGHopError
        Bad arguments or settings, an OUTDIR that cannot be used, a scheduler that cannot be reached, a Dask
        worker without this tghop (also one that joins mid-run, 0.58), a full disk under OUTDIR (0.61: the run stops at
        the first exemplar whose files met it, or at a ledger line that could not be written). A bad exemplar is a
        failed record, not an exception.

    Notes
    -----
    What the calling process keeps: its environment (a local cluster's workers get their limits, one
    BLAS and OpenMP thread and :data:`WORKER_ENVIRON`, in their own; Dask's nanny writes them into this
    process's ``os.environ`` while it starts them, and ``run`` puts back the values from before, also
    after a worker restarted); its threads with ``workers=1`` (no limit is set) and with a cluster of
    worker processes (the default, a scheduler's). A given ``client`` whose workers are threads of this
    process (``processes=False``) is the exception: each task limits BLAS and tghop's own threads for
    the whole process while it runs (:func:`tghop.batch_task.task_threads`), and the last to end puts
    back tghop's limit but may leave OpenBLAS's at one thread: OpenBLAS takes a new limit only from the
    thread that set the last one while that thread lives, and Dask keeps its worker threads until the
    client closes (measured: 2 BLAS threads before such a run, 1 after it and after ``client.close()``).
    Run such a batch in worker processes, or set BLAS's limit again once the client is closed (its
    threads ended), e.g. ``threadpoolctl.threadpool_limits(limits=2, user_api="blas")``.
    """
    _check_call(outdir, fit, generate, workers, {"progress": progress, "on_result": on_result, "task": task,
                                                  "on_orphans": on_orphans, "on_plan": on_plan,
                                                  "worker_setup": worker_setup}, task_timeout)
    most = WORKERS_PER_CORE * affinity_cores()
    if client is None and scheduler is None and workers is not None and workers > most:
        raise TGHopError(f"the worker processes (workers, --workers): {workers} on this machine's "
                         f"{affinity_cores()} cores; a local cluster takes at most {most} "
                         f"({WORKERS_PER_CORE} per core: each exemplar runs on one core); give fewer, none for one per "
                         "core, or a scheduler's cluster")
    outdir = Path(os.path.abspath(outdir))
    items = find_work(source, outdir, max_depth=max_depth)
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
    check_own_files(outdir, contact_sheet)
    in_process = client is None and scheduler is None and (workers == 1 or (workers is None and affinity_cores() == 1))
    if not in_process and client is None:
        try:
            import_distributed()  # a missing extra is said before any work
        except MissingExtraError:
            if workers is not None or scheduler is not None:
                raise
            # The default on a core install: it works the first time, one exemplar after another.
            warnings.warn(f"Dask is not installed: the exemplars run one after another in this process; for one "
                          f"worker per core install it with: {INSTALL_HINT}", stacklevel=2)
            in_process = True
    if in_process and task_timeout is not None and (threading.current_thread() is not threading.main_thread()
                                                    or not hasattr(signal, "setitimer")):
        raise TGHopError("task_timeout in this process (workers=1) needs the main thread on a POSIX system (a timer's "
                         "signal stops the task); call run from the main thread, or run on Dask (workers=2 or more)")
    task = process_exemplar if task is None else task
    standing = {}  # the last line done of each exemplar, where only failed tries follow it (0.62)
    lost = {}  # the runs in a row each exemplar's worker died on every try (0.62)
    previous, earlier_files = read_ledger_files(outdir, standing, lost)
    keep_ledger_names(items, previous)
    orphans = find_orphans(outdir, earlier_files, [it["name"] for it in items])
    jobs, results, failed_before, renames = [], {}, 0, []
    hashes, found = read_hashes(outdir), {}
    candidates = renamable(previous, [it["name"] for it in items])  # done before under names no longer given
    # This run's claim on the exemplars it hands out (0.62): their RUNNING files hold it, and a task moves its files
    # into place only while it is the claim there, so that a killed run's tasks that ran on (a --scheduler cluster)
    # cannot replace a rerun's files after its line (tghop.batch_task.holding_claim).
    claim = uuid.uuid4().hex
    try:  # unchanged files not read again (0.58)
        digests = [input_digest(it["path"], it.get("maps") or [], hashes, found) for it in items]
    except BaseException:  # Ctrl-C while a library is read: what was hashed is kept (0.62; 0.61 read it all again)
        if found:
            with contextlib.suppress(OSError):
                outdir.mkdir(parents=True, exist_ok=True)
            write_hashes(outdir, hashes, found, [r.get("source") for r in previous.values()])
        raise
    for it, digest in zip(items, digests):
        settings = _settings(it["settings"], defaults, fit, generate)
        maps = it.get("maps") or []
        if maps:  # a material: its maps' names are settings too (none: the settings of a texture, as before)
            settings["maps"] = [name for name, _ in maps]
        job = {"name": it["name"], "source": str(it["path"]), "folder": str(outdir / it["name"]),
               "maps": [[name, str(file)] for name, file in maps],
               "sha256": digest,
               "settings": settings, "size": settings["size"],
               "count": settings["count"], "seed": settings["seed"], "fit": settings["fit"],
               "generate": {**generate, "tile": settings["tile"]}, "threads": None if in_process else 1,
               "claim": claim, "task_timeout": task_timeout}
        if is_done(previous.get(it["name"]), job, outdir):
            results[it["name"]] = {**previous[it["name"]], "skipped": True}
        elif standing.get(it["name"]) not in (None, previous.get(it["name"])) \
                and is_done(standing[it["name"]], job, outdir):  # failed tries since (its input missing a while):
            results[it["name"]] = {**standing[it["name"]], "skipped": True}  # its files untouched (0.61 made it again)
        elif not retry_failed and is_known_failure(previous.get(it["name"]), job, __version__):
            results[it["name"]] = {**previous[it["name"]], "skipped": True}
            failed_before += 1
        elif (old := renamed_from(job, previous, candidates, outdir)) is not None:
            renames.append((job, old))  # its files moved to its new name under the ledger's lock, not made again
        else:
            jobs.append(job)
    orphans = [name for name in orphans if name not in {old for _, old in renames}]
    # Those a killed run left under way last (0.62): in this process, an exemplar that kills it (out of memory, a
    # decoder's crash) came first again on every rerun, and no exemplar after it was ever made (stable: else in order).
    jobs.sort(key=lambda job: claimed(job["folder"]))
    own_client = ledger_file = None
    try:
        if (jobs or renames) and scheduler is not None and client is None:  # a move that fails: made on it
            client = own_client = connect(scheduler)  # before OUTDIR is made: no empty OUTDIR when it fails
        elif (jobs or renames) and client is not None:
            check_cluster(client)  # connect's checks of the workers (0.59: a given client's too)
        try:
            outdir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:  # 0.61 named no fix
            raise TGHopError(f"{outdir}: cannot create the output folder ({exc.strerror or exc}); "
                             f"{_outdir_fix(exc)}") from None
        from .imageio import check_output_path

        check_output_path(outdir / LEDGER, what="ledger", error=TGHopError)  # a file can be made in OUTDIR
        # Locked whatever there is to do: a run with nothing to make writes the hashes and the contact sheet too, which
        # 0.61 wrote unlocked, over those of a run under way (0.62); pruning and moving wait for no other run either.
        ledger_file = open_ledger(outdir)
        # The inputs' hashes as soon as they are known (0.61; 0.60 wrote them at the end, so that after a kill -9 or
        # a lost machine the next run read every byte of every exemplar again: hours of a studio's library).
        write_hashes(outdir, hashes, found, [r.get("source") for r in previous.values()])
        _move_renamed(outdir, ledger_file, renames, previous, earlier_files, jobs, results)
        if not jobs and own_client is not None:  # every one moved: the scheduler has nothing to do
            own_client.close()
            client = own_client = None
    except BaseException:
        if own_client is not None:
            own_client.close()
        raise
    counts = {"done": 0, "failed": 0, "running": 0, "total": len(jobs), "skipped": len(results) - failed_before,
              "failed_before": failed_before}
    started = {}  # name -> job: handed out, no ledger line yet

    def begin(job):
        mark_running(job, True)  # before the task can move any file into place
        started[job["name"]] = job

    def stop_lines():
        """A line ``interrupted`` for each exemplar handed out and not finished, its RUNNING file removed (the task
        then moves nothing in): called by the Dask driver before it closes the cluster (0.63; 0.62 wrote them after
        the close, which a local cluster's busy worker can make long), and at the end. A second Ctrl-C must not
        leave a started exemplar without its line."""
        with ctrl_c_ignored(), contextlib.suppress(OSError):
            for job in list(started.values()):
                append_ledger(ledger_file, {"name": job["name"], "source": job["source"], "sha256": job["sha256"],
                                             "settings": job["settings"], **_interrupted_record(job)})
                started.pop(job["name"], None)
                mark_running(job, False)  # the line says it now

    def finish(done):
        """Record ``done``, the (job, record) pairs of the exemplars that came back together: their
        lines written, then synced once (0.59; 0.58 synced each line), and only then their RUNNING files
        removed, so that a crash of the machine before the sync leaves those files and a rerun redoes
        exactly the exemplars whose lines it lost (a kill of this process loses no line written)."""
        recs = []
        with ctrl_c_deferred():  # the lines and their RUNNING files' removal as one (else a rerun redoes them)
            try:
                for job, record in done:
                    rec = {"name": job["name"], "source": job["source"], "sha256": job["sha256"],
                           "settings": job["settings"], "version": __version__, **record}
                    rec["finished"] = time.time()
                    if rec.get("worker_died"):  # in LOST_RUNS runs in a row: the exemplar's own failure (0.62)
                        worker_deaths(rec, lost.get(job["name"]))
                    append_ledger(ledger_file, rec, sync=False)
                    recs.append((job, rec))
                sync_ledger(ledger_file)
            except OSError as exc:  # 0.60: "cannot write the output: ...", which said neither what nor what next
                raise _ledger_error(outdir, exc) from None
            for job, _ in recs:
                started.pop(job["name"], None)
                mark_running(job, False)
        for job, rec in recs:
            results[job["name"]] = {**rec, "skipped": False}
        for job, rec in recs:
            if rec["status"] == "ok":
                remove_stale(outdir, earlier_files.get(job["name"], ()), rec)
            counts["done"] += 1
            counts["failed"] += rec["status"] != "ok"
            if counts["done"] == counts["total"]:
                counts["running"] = 0
            if on_result is not None:  # first: a progress bar shows the counts it sets
                on_result(results[job["name"]], dict(counts))
            if progress is not None:
                progress("exemplars", counts["done"], counts["total"])
        full = [rec for _, rec in recs if rec.get("disk_full")]
        if full:  # 0.60 went on: every exemplar after it was fitted, then failed alike (thousands, in a studio's run)
            raise TGHopError(f"the disk of {outdir} is full ({full[0]['name']}: {full[0]['error']}); the run stopped: "
                             f"{_WHAT_NEXT}; free some space first")

    if on_plan is not None:  # once OUTDIR and its ledger are ready: a refused run says no plan
        on_plan({"exemplars": len(items), "done_before": len(results) - failed_before,
                 "failed_before": failed_before, "to_do": len(jobs)})
    if progress is not None and jobs:
        progress("exemplars", 0, len(jobs))
    stopped = False  # by an exception: the contact sheet's own failure (a full disk) must not hide its line
    try:
        if orphans:  # before the work: a long run's log says it at its start
            held, said = prune_held(orphans, previous, len(items), force) if prune else ({}, [])
            for line in said:  # a source folder missing or unreadable, too many at once: kept (0.62)
                warnings.warn(f"{outdir}: {line}", stacklevel=2)
            kept = prune_orphans(outdir, [n for n in orphans if n not in held], earlier_files) if prune else None
            _report_orphans(outdir, orphans, kept, on_orphans, held)
        if in_process:
            for job in jobs:
                counts["running"] = 1
                begin(job)
                finish([(job, within(task, job, task_timeout))])
            counts["running"] = 0
        elif jobs:
            run_distributed(jobs, finish, counts, task, workers=workers, client=client, own_client=own_client,
                             retries=retries, begin=begin, worker_setup=worker_setup, on_stop=stop_lines,
                             task_timeout=task_timeout)
    except BaseException:
        stopped = True
        raise
    finally:
        if ledger_file is not None:
            stop_lines()  # a full disk must not leave the temporaries and the contact sheet below undone
            with ctrl_c_ignored(), contextlib.suppress(OSError):
                # superseded lines dropped where they are many (0.59), while the lock is held: atomic
                known = set(previous) | {name for name, r in results.items() if not r["skipped"]}
                compact_ledger(outdir, known=len(known))
            with contextlib.suppress(OSError):  # every line was flushed when appended
                ledger_file.close()
        for job in jobs:
            remove_temporaries(job["folder"])
            with contextlib.suppress(OSError):
                os.rmdir(job["folder"])  # only when empty: a failed exemplar's
        ordered = [results[it["name"]] for it in items if it["name"] in results]
        if contact_sheet and ordered:  # nothing finished, now or before (e.g. no scheduler): no empty page
            try:
                write_contact_sheet(outdir, ordered, total=len(items))
            except (OSError, TGHopError):
                if not stopped:  # 0.60: "index.html: writing the contact sheet failed ...", in place of the stop's
                    raise
    return ordered


#: What a run stopped by its disk says of its work (:func:`run`'s ``finish``).
_WHAT_NEXT = ("the exemplars recorded are in the ledger, those under way or not recorded are done again by the next "
              "run (the same command)")


def _ledger_error(outdir, exc) -> TGHopError:
    """The one line of a ledger line that could not be written (``exc``, an OSError): the run stops."""
    why = exc.strerror or exc.__class__.__name__
    space = "; free some space" if disk_full(exc) else ""
    return TGHopError(f"{outdir / LEDGER}: cannot add to the ledger ({why}{space}); the run stopped: {_WHAT_NEXT}")


def _move_renamed(outdir, ledger_file, renames, previous, earlier_files, jobs, results) -> None:
    """Move each renamed exemplar's files (``renames``: ``(job, old name)``, :func:`tghop.batch_plan.renamed_from`)
    to its new name, under the ledger's lock, and record it: its line under the new name (``renamed_from``), and a
    line ``renamed`` (``renamed_to``) under the old, whose files it no longer has (0.62; 0.61 made it again and kept
    the old folder as "no longer in SOURCE"). One whose move fails goes to ``jobs``: it is made again."""
    for job, old in renames:
        mark_running(job, True)  # this run's claim: a killed run's task of the new name moves nothing in meanwhile
        with ctrl_c_deferred():  # the move and its lines as one (a Ctrl-C between: moved, and made again)
            rec = move_renamed(outdir, previous[old], old, job)
            if rec is None:
                jobs.append(job)
                continue
            gone = {"name": old, "source": previous[old].get("source"), "sha256": previous[old].get("sha256"),
                    "settings": previous[old].get("settings"), "version": __version__, "status": "renamed",
                    "renamed_to": job["name"], "error": None, "cause": None, "outputs": [], "model": None,
                    "thumbnail": None, "finished": time.time()}
            try:
                append_ledger(ledger_file, rec, sync=False)
                append_ledger(ledger_file, gone)
            except OSError as exc:  # its files are in the new folder, without a line: the next run makes it again
                raise _ledger_error(outdir, exc) from None
            mark_running(job, False)
        remove_stale(outdir, earlier_files.get(job["name"], ()), rec)  # an older run's files of the new name
        results[job["name"]] = {**rec, "skipped": True, "renamed": True}


#: ``--prune`` removes without ``--force`` at most this share of the exemplars (those pruned and SOURCE's), where
#: more than :data:`PRUNE_MIN` would go (0.62: a library's share not mounted looks like its exemplars removed).
PRUNE_SHARE = 0.5
PRUNE_MIN = 10


def prune_held(orphans, previous: dict, exemplars: int, force: bool = False) -> tuple:
    """Which of ``orphans`` (:func:`tghop.batch_plan.find_orphans`) ``--prune`` must keep, and why: ``(held, lines)``,
    ``held`` by name the reason, ``lines`` one message per reason (0.62; 0.61 pruned them all, and a studio whose
    share was down lost its finished results). Kept whatever ``force`` says: those whose source folder (of their
    last line's ``source``) cannot be read; unless ``force``: those whose source folder is missing (unmounted, a
    share down), and all of them where more than :data:`PRUNE_SHARE` of the exemplars (``exemplars``: SOURCE's, and
    these) and over :data:`PRUNE_MIN` would go."""
    held, lines, seen = {}, {}, {}
    for name in orphans:
        source = (previous.get(name) or {}).get("source")
        if not isinstance(source, str) or not os.path.isabs(source):
            continue
        folder = os.path.dirname(source)
        if folder not in seen:
            try:
                os.listdir(folder)
                seen[folder] = None
            except (FileNotFoundError, NotADirectoryError):
                seen[folder] = None if force else (
                    f"{folder} is missing (a share down, a disk not mounted?); mount it and run again, or "
                    "prune=True, force=True (tghop batch --prune --force) removes them")
            except OSError as exc:
                seen[folder] = (f"{folder} cannot be read ({exc.strerror or exc.__class__.__name__}); results whose "
                                "source folder cannot be read are never pruned: make it readable and run again")
        if seen[folder] is not None:
            held[name] = seen[folder]
            lines.setdefault(seen[folder], []).append(name)
    rest = [n for n in orphans if n not in held]
    if not force and len(rest) > PRUNE_MIN and len(rest) > PRUNE_SHARE * (exemplars + len(rest)):
        why = (f"{len(rest):,} of {exemplars + len(rest):,} exemplars would go, more than {PRUNE_SHARE:.0%} (a share "
               "not mounted?); mount it and run again, or prune=True, force=True (tghop batch --prune --force) "
               "removes them")
        held.update(dict.fromkeys(rest, why))
        lines[why] = rest
    return held, [f"{len(names):,} folder{'s' if len(names) != 1 else ''} of exemplars no longer in SOURCE not pruned "
                  f"({', '.join(names[:3])}{' ...' if len(names) > 3 else ''}): {why}" for why, names in lines.items()]


def _report_orphans(outdir, names, kept, on_orphans, held) -> None:
    """Say the folders of exemplars no longer in SOURCE (``kept``: None when not pruned, else
    :func:`prune_orphans`'s folders left; ``held``: those ``prune`` kept, :func:`prune_held`) to
    ``on_orphans``, or in a warning."""
    found = [{"name": n, "pruned": kept is not None and n not in held, "kept": (kept or {}).get(n, []),
              "held": held.get(n)} for n in names]
    if on_orphans is not None:
        on_orphans(found)
        return
    shown = ", ".join(names[:10]) + (" ..." if len(names) > 10 else "")
    if kept is None:
        warnings.warn(f"{outdir}: {len(names)} folder{'s' if len(names) != 1 else ''} of exemplars no longer in "
                      f"SOURCE: {shown}; prune=True (tghop batch --prune) removes them", stacklevel=3)
    elif kept:
        warnings.warn(f"{outdir}: {len(kept)} folder{'s' if len(kept) != 1 else ''} of exemplars no longer in SOURCE "
                      f"kept, with files tghop did not make: {', '.join(sorted(kept)[:10])}", stacklevel=3)


def _interrupted_record(job) -> dict:
    """The ledger line of an exemplar handed out but not finished when the run stopped (Ctrl-C, an
    error): its task may still have moved its files into place (a local cluster's worker finishes
    its task while the cluster closes; a given cluster's runs on), so the earlier line no longer
    describes the folder, and the next run does it again whatever its settings."""
    return {"status": "interrupted", "cause": "run",
            "error": "the batch stopped before this exemplar's result came back (its "
            "files may be this run's or an earlier one's); the next run does it again", "outputs": [], "model": None,
            "thumbnail": None, "seed_used": job.get("seed"), "started": None, "seconds": None, "finished": time.time()}


def write_contact_sheet(outdir, records, total=None) -> Path:
    """``OUTDIR/index.html`` of a batch (:func:`tghop.contact_sheet.write_contact_sheet`,
    linking the ledger)."""
    return _write_sheet(outdir, records, total=total, ledger=LEDGER)


def _outdir_fix(exc: OSError) -> str:
    """What to do about OUTDIR that cannot be made (``exc``: why), in one clause."""
    import errno

    if exc.errno == errno.ENOSPC:
        return "free some space on that disk, or give an OUTDIR on another one"
    if exc.errno in (errno.EEXIST, errno.ENOTDIR):
        return "a file stands where OUTDIR or a folder above it goes; give another OUTDIR"
    return "give an OUTDIR on a disk and in a folder you can write to (e.g. under your home folder)"
