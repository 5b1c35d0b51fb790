"""Running a batch's exemplars on ``dask.distributed``: a local cluster of worker processes
(:func:`local_cluster`) or a running scheduler's (:func:`connect`), the tasks handed out the
longest first, one per free thread (:func:`run_distributed`), and what each worker sets up
(:func:`dask_setup`: Ctrl-C ignored, :func:`tune_malloc`, the task's modules imported).

Dask is an optional extra (:data:`INSTALL_HINT`), imported inside the functions that use it
(:func:`import_distributed`). :func:`tghop.batch.run` plans the work and calls these.
"""

from __future__ import annotations

import collections
import contextlib
import gc
import os
import queue
import signal
import threading
import time
import warnings

from ._errors import MissingExtraError, TGHopError
from .batch_task import one_line, run_checked, timed_out_record

__all__ = ["INSTALL_HINT", "WORKER_MALLOC", "WORKER_ENVIRON", "WORKERS_PER_CORE", "QUIET_CLUSTER", "import_distributed",
           "local_cluster",
           "worker_environ", "environ_kept", "ctrl_c_ignored", "ctrl_c_deferred", "dask_setup", "tune_malloc",
           "affinity_cores", "connect", "check_cluster", "check_workers_tghop", "run_distributed", "SchedulerLostError",
           "worker_process"]


#: What to install for running on Dask.
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
#: A local cluster's worker processes per usable core at most (:func:`tghop.batch.run`'s ``workers``): each
#: exemplar runs on one core, so more only share the cores and the memory (a typo's million
#: worker processes kept the run starting for ever, with Ctrl-C ignored while a cluster starts).
WORKERS_PER_CORE = 4
#: Dask's own periodic work in the processes of a local cluster (:func:`local_cluster`), made rarer:
#: its statistical profiler (a stack sample of the task's thread every 10 ms in each worker), the event
#: loop's tick (every 20 ms in each process: a metric and a "loop was unresponsive" log line) and the
#: system monitor (every 500 ms: the dashboard's CPU and network plots). A busy worker's event loop took
#: about 0.04 cores beside its task, and an idle cluster of 2 workers 0.09-0.10 cores, 0.01 with these:
#: on 2 cores about 5 % of the machine taken from the tasks (docs/batch.md, "Dask's own periodic work").
QUIET_CLUSTER = {"distributed.worker.profile.enabled": False, "distributed.admin.tick.interval": "1s",
                 "distributed.admin.system-monitor.interval": "5s"}


class SchedulerLostError(TGHopError):
    """The Dask scheduler went away in the middle of a batch (stopped, its machine lost): the exemplars
    finished are in the ledger, and running the same batch again, once the scheduler and its workers are
    back, does the rest. Its own class so that a caller can tell "run it again" from a failure of the
    exemplars (``tghop batch`` exits with status 3 for it, 0.58; 0.57 exited 1, as for failed exemplars)."""


_MALLOPT = {"M_TRIM_THRESHOLD": -1, "M_MMAP_MAX": -4}  # glibc's malloc.h
#: Each WORKER_MALLOC setting's environment variable, and the value Dask puts there (None: none).
_MALLOC_ENV = {"M_MMAP_MAX": ("MALLOC_MMAP_MAX_", None), "M_TRIM_THRESHOLD": ("MALLOC_TRIM_THRESHOLD_", "65536")}


# ------------------------------------------------------------------ running
def import_distributed():
    """The ``distributed`` module, or a one-line :class:`~tghop.MissingExtraError` saying what to install."""
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
    keeps freed memory for reuse (:data:`WORKER_MALLOC`, :data:`WORKER_ENVIRON`). Dask's own
    periodic work is made rarer (:data:`QUIET_CLUSTER`: no profiler, a tick a second).

    The workers' environment (those settings, one BLAS and OpenMP thread) is theirs alone: Dask's
    nanny writes it into this process's ``os.environ`` before it starts each worker, and the values
    from before are put back once they have started, so that what this process starts later (a
    subprocess, its own pool) does not run on one thread. A worker Dask restarts (after a death)
    writes them again: :func:`run_distributed` puts them back when it closes its cluster."""
    distributed = import_distributed()
    import logging

    import dask

    n = n_workers or affinity_cores()
    environ = worker_environ()
    # Ctrl-C is ignored while the workers start: a worker process inherits that (its preload
    # ignores Ctrl-C only once its imports are done; before, each printed a traceback), and a
    # cluster interrupted half-started cannot be closed cleanly. It lasts a few seconds.
    with ctrl_c_ignored(), environ_kept(environ), \
            dask.config.set({**QUIET_CLUSTER, "distributed.scheduler.allowed-failures": int(retries),
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


def worker_environ() -> dict:
    """The environment a local cluster's worker starts with (:func:`local_cluster`): Dask's
    ``distributed.nanny.pre-spawn-environ``, one BLAS and OpenMP thread, :data:`WORKER_ENVIRON`."""
    import dask

    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    environ.update({v: "1" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")})
    environ.update(WORKER_ENVIRON)
    return environ


@contextlib.contextmanager
def environ_kept(names):
    """Context manager: the environment variables ``names`` as they were on entry, put back on
    exit (set again, or removed where they were not set)."""
    before = {name: os.environ.get(name) for name in names}
    try:
        yield
    finally:
        for name, value in before.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextlib.contextmanager
def ctrl_c_ignored():
    """Ctrl-C (SIGINT) ignored inside, where this is the main thread (else nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def ctrl_c_deferred():
    """A Ctrl-C (SIGINT) inside takes effect once the block is done (where this is the main thread), as
    :func:`ctrl_c_ignored` but not lost."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if caught:
            signal.raise_signal(signal.SIGINT)  # to the handler it had: KeyboardInterrupt, as a Ctrl-C anywhere


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


def affinity_cores() -> int:
    """Cores this process may run on (its affinity mask; ``os.cpu_count()`` where there is none)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _cost(job) -> float:
    """A job's rough relative cost, to start the longest first (a shorter tail): one fit (more
    for a larger exemplar: its header's pixels, capped at 4 MP) plus a tenth of a fit per 512x512
    output pixels (in one thread a fit takes about 11 s, a 512x512 image about 1 s; docs/choices.md)."""
    try:
        from .image_decode import open_image  # a damaged EXIF block said once, by the task that reads it

        with open_image(job["source"], say=False) as img:
            pixels = img.size[0] * img.size[1]
    except Exception:  # noqa: BLE001 - not an image: it fails at once, last is fine
        return 0.0
    out = job["size"][0] * job["size"][1] * job["count"]
    maps = len(job.get("maps") or ())  # a material's joint fit and maps: about 1.6 times with three
    return (1.0 + 0.25 * min(pixels, 4 << 20) / (1 << 20) + 0.1 * out / (512 * 512)) * (1 + 0.3 * maps)


def _died_record(job, exc, retries) -> dict:
    name = exc.__class__.__name__
    if name == "KilledWorker":
        # retries None: a cluster of one's own (--scheduler, client=), whose scheduler sets the tries, not retries
        tries = f"{retries + 1} {'try' if retries == 0 else 'tries'} on a local cluster" if retries is not None \
            else "as many tries as the scheduler's distributed.scheduler.allowed-failures allows"
        error = (f"the worker running it died on every try (killed or out of memory; {tries}); use fewer workers per "
                 "machine or a smaller size")
    else:
        error = one_line(exc)
    # task_lost (0.62): it may have moved files before its worker died, so an earlier line done no longer says the
    # exemplar's folder (tghop.batch_plan.read_ledger_files' standing)
    return {"status": "failed", "error": error, "cause": "run", "outputs": [], "model": None, "thumbnail": None,
            "seed_used": job.get("seed"), "started": None, "seconds": None, "task_lost": True,
            "worker_died": name == "KilledWorker"}  # counted over runs (0.62: tghop.batch_plan.worker_deaths)


#: How long :func:`connect` tries to reach a scheduler (Dask tries again until then, a refused connection too: one
#: starting up may not listen yet).
CONNECT_TIMEOUT = "5s"


def connect(scheduler):
    """A client of the Dask scheduler at address ``scheduler``; one line when it cannot be reached within
    :data:`CONNECT_TIMEOUT`."""
    distributed = import_distributed()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            client = distributed.Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:  # ValueError: not an address
        reason = one_line(exc)
    else:
        for w in caught:
            if w.category.__name__ == "VersionMismatchWarning":  # a Warning, not a UserWarning: the command hid it
                warnings.warn(_mismatch_line(client, scheduler), stacklevel=2)
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        try:
            check_cluster(client, scheduler)
        except TGHopError:
            client.close()
            raise
        return client
    # The half-started Client is in a reference cycle: collected later, inside a LocalCluster's
    # start, its __del__ deadlocks on the loop runner's lock. Collect it now (after the except).
    gc.collect()
    raise TGHopError(f"cannot reach the Dask scheduler at {scheduler} ({reason})")


def check_cluster(client, address=None, stacklevel=2) -> None:
    """What a run checks of a cluster it did not start, before any work: every worker imports this tghop
    (:func:`check_workers_tghop`), and a warning where it has no worker yet (the run would wait without a
    word). For ``tghop batch --scheduler`` (:func:`connect`) and, since 0.59, a client given to
    :func:`tghop.batch.run` (0.58 checked neither its workers at the start nor those that joined mid-run)."""
    check_workers_tghop(client)
    if not client.nthreads():
        address = address or getattr(client.scheduler, "address", None) or "ADDRESS"
        warnings.warn(f"the Dask scheduler at {address} has no workers yet: the exemplars wait until one joins "
                      f"(start one: dask worker {address} --nthreads 1; docs/batch.md)", stacklevel=stacklevel + 1)


def check_workers_tghop(client, workers=None) -> None:
    """A one-line :class:`~tghop.TGHopError` where a worker of ``client``'s cluster has no tghop or
    another version than this process's: every task of such a worker failed ("No module named
    'tghop'"), or made its exemplar with another tghop under this version's ledger line. ``workers``:
    the addresses of workers that joined the cluster mid-run (0.58), the only ones checked; the error
    says so, and that the run stopped (:func:`run_distributed`)."""
    from . import __version__

    # eval, not a function of tghop's: it is pickled by reference, so a worker without tghop could not load it
    found = client.run(eval, "__import__('tghop').__version__", on_error="return", workers=workers)
    # a worker that left between the list and the call (its connection refused or closed): not asked, no fault
    found = {a: v for a, v in found.items() if not isinstance(v, (OSError, TimeoutError))}
    if not found:
        return
    info = client.scheduler_info().get("workers", {})
    named = {a: (f"{info[a]['name']} ({a})" if info.get(a, {}).get("name") not in (None, a) else a) for a in found}
    missing = sorted(named[a] for a, v in found.items() if not isinstance(v, str))
    other = sorted(f"{named[a]}: {v}" for a, v in found.items() if isinstance(v, str) and v != __version__)
    install = f"install tghop {__version__} on every worker (pip install 'tghop[batch]=={__version__}') and restart it"
    if workers is None:
        of, stopped = f"of the Dask cluster's {len(found)} worker{'s' if len(found) != 1 else ''}", ""
    else:  # "1 Dask worker", "2 Dask workers": the count said
        of = f"Dask worker{'s' if len(missing or other) != 1 else ''} that joined the cluster mid-run"
        stopped = "; the run stopped: the exemplars finished are in the ledger, the next run does the rest"
    if missing:
        raise TGHopError(f"{len(missing)} {of} cannot import tghop "
                         f"({', '.join(missing[:5])}{' ...' if len(missing) > 5 else ''}; "
                         f"{one_line(next(v for v in found.values() if not isinstance(v, str)))}): {install}{stopped}")
    if other:
        raise TGHopError(f"{len(other)} {of} {'runs' if len(other) == 1 else 'run'} another tghop than this "
                         f"command's {__version__} ({', '.join(other[:5])}{' ...' if len(other) > 5 else ''}): "
                         f"{install} (an exemplar's images and its ledger line are one version's){stopped}")


def _mismatch_line(client, scheduler) -> str:
    """Dask's ``VersionMismatchWarning`` (a table of many lines) as one line: each package whose
    version differs between this process, the scheduler and the workers."""
    try:
        versions = client.get_versions()
    except Exception:  # noqa: BLE001 - said without the details
        versions = None
    said = []
    if versions:
        own = versions["client"]["packages"]
        others = [("the scheduler", versions["scheduler"].get("packages") or {})]
        others += [(f"a worker ({a})", (v or {}).get("packages") or {}) for a, v in sorted(versions["workers"].items())]
        for package, mine in own.items():
            theirs = {}
            for who, packages in others:
                if package in packages and packages[package] != mine:
                    theirs.setdefault(packages[package], who)  # the first of each other version
            if theirs:
                said.append(f"{package} {mine} here, " + ", ".join(f"{v} on {w}" for v, w in theirs.items()))
    details = "; ".join(said[:4]) + (" ..." if len(said) > 4 else "") if said else "see client.get_versions()"
    return (f"the Dask cluster at {scheduler} runs other versions of Python or its packages than this command "
            f"({details}); Dask may fail to move tasks and results between them: install the same versions "
            "everywhere (Dask's VersionMismatchWarning)")


def _workers_gone(gone, names, local, running=None) -> str:
    """The warning of Dask workers that left the cluster mid-run (``gone``: their addresses; ``names``:
    address -> the worker's name); ``running``: address -> the names of this run's exemplars it was running
    (:func:`_running_on`), an address missing where the scheduler did not say."""
    running = running or {}
    one = len(gone) == 1
    named = ", ".join(str(names[a]) if str(names[a]) == a else f"{names[a]} ({a})" for a in gone[:5])
    what = "a Dask worker" if one else f"{len(gone)} Dask workers"
    restart = "its nanny starts another" if local else "start another if it was not restarted"
    tries = "up to the scheduler's tries (distributed.scheduler.allowed-failures)"
    if all(a in running for a in gone):
        lost = sorted({n for a in gone for n in running[a]})  # an exemplar retried on a worker that left too: once
        shown = ", ".join(lost[:5]) + (" ..." if len(lost) > 5 else "")
        under_way = f"{'it was' if one else 'they were'} running none of this run's exemplars" if not lost else \
            f"the exemplar {'it was' if one else 'they were'} running, {shown}, runs again on another worker, {tries}" \
            if len(lost) == 1 else \
            f"the exemplars {'it was' if one else 'they were'} running, {shown}, run again on other workers, {tries}"
    else:  # 0.57 said this always: it named no exemplar
        under_way = f"an exemplar under way on {'it' if one else 'them'} runs again on another worker, {tries}"
    return (f"{what} left the cluster mid-run ({named}{' ...' if len(gone) > 5 else ''}: killed, out of memory or "
            f"stopped); {under_way}; the run goes on with the others ({restart})")


def _running_on(client, gone, by_key) -> dict:
    """The names of this run's exemplars (``by_key``: a task's key -> its job) that each worker of ``gone``
    (addresses) was running when it left: the keys the scheduler's event of its removal lists
    (``Client.get_events(address)``, the action "remove-worker", its "processing-tasks"). An address of which
    the scheduler has no such event (its event log trimmed, a scheduler without them) is left out."""
    found = {}
    for address in gone:
        try:
            events = client.get_events(address)
        except Exception:  # noqa: BLE001 - the warning is said without the exemplars
            continue
        removed = [msg for _, msg in events if isinstance(msg, dict) and msg.get("action") == "remove-worker"]
        if removed:
            found[address] = sorted(by_key[k]["name"] for k in removed[-1].get("processing-tasks") or () if k in by_key)
    return found


def _lost_scheduler(client, exc, *, dask_call) -> SchedulerLostError | None:
    """The one-line :class:`SchedulerLostError` to raise where ``client`` lost its scheduler (it
    stopped, or its machine went away, mid-run), else None. Dask's client tries to reconnect for
    its timeout, then closes itself; meanwhile its calls raise ``OSError`` (a comm closed, "Timed
    out trying to connect to tcp://..."), which the command said as "cannot write the output:
    ...", and futures a ``CancelledError`` ("scheduler-connection-lost"). ``dask_call``: ``exc``
    came from a call of Dask's (handing out, waiting), not from this run's own files."""
    if client.status == "running" and getattr(exc, "reason", None) != "scheduler-connection-lost" \
            and not (dask_call and isinstance(exc, OSError)):
        return None
    address = getattr(client.scheduler, "address", None) or "its address"
    # a future's reason names its key (the exemplar's name, SHA-256 and a time): long, and said better below
    why = one_line(exc) if isinstance(exc, OSError) else "the connection closed and was not regained"
    return SchedulerLostError(f"lost the Dask scheduler at {address} in the middle of the run ({why}); the "
                      "exemplars finished are in the ledger, those under way are done again by the next run: "
                      "start the scheduler and its workers again and run the same command")


def _results(client, group, by_key, retries, check_joined):
    """The (job, record) of each future of ``group`` (done; ``by_key``: a task's key -> its job): the
    results of those finished in one gather, a record of :func:`_died_record` for a task that failed (its
    worker killed on every try); a lost scheduler raises :class:`SchedulerLostError`. ``retries``: the
    local cluster's (None: another's); ``check_joined``: called with the workers' addresses where a task failed
    other than by a killed worker, to check their tghop first (None: no check)."""
    finished = [fut for fut in group if fut.status == "finished"]
    try:  # one round trip for the group, where each result was one (Future.result)
        values = dict(zip([f.key for f in finished], client.gather(finished))) if finished else {}
    except Exception:  # noqa: BLE001 - taken one by one below, as 0.58 did, which says what failed
        values = {}
    out = []
    for fut in group:
        if fut.key in values:
            out.append((by_key[fut.key], values[fut.key]))
            continue
        try:
            record = fut.result()
        except Exception as exc:  # noqa: BLE001 - KilledWorker, or a task that raised every time
            lost = _lost_scheduler(client, exc, dask_call=False)  # no failure of this exemplar's
            if lost is not None:
                raise lost from exc
            if check_joined is not None and exc.__class__.__name__ != "KilledWorker":
                # its worker may have joined since and lack this tghop (run_checked raised, or the task could
                # not be loaded there): the run stops with one line, as the check before any work refuses it
                check_joined(list(client.nthreads()))
            record = _died_record(by_key[fut.key], exc, retries)
        out.append((by_key[fut.key], record))
    return out


def _own_workers(client):
    """``its_own(address)``: whether the worker at ``address`` is one that ``client``'s cluster object of this
    process, a ``LocalCluster``, started itself (a name of its ``plan``: its first workers, those of its
    ``scale``, a nanny's restart of one of them), all with this interpreter; False for every worker of another
    client's cluster, and for one that joined a LocalCluster's scheduler from elsewhere (``dask worker ADDRESS``)."""
    distributed = import_distributed()
    cluster = getattr(client, "cluster", None)
    if not isinstance(cluster, distributed.LocalCluster):
        return lambda address: False

    def its_own(address):
        try:  # the cluster's own record, kept by its event loop's thread: copied, not iterated
            info = dict(cluster.scheduler_info.get("workers", {})).get(address) or \
                client.scheduler_info().get("workers", {}).get(address) or {}
            return "name" in info and info["name"] in cluster.plan  # the names it means to run (its worker_spec's)
        except (AttributeError, RuntimeError, TypeError):  # a name unknown: the worker is checked
            return False

    return its_own


def _workers_lost(client, own_cluster, had_workers):
    """``lost()``: whether the run's cluster, a ``LocalCluster`` of this process (``own_cluster``, or a given
    client's), has lost every worker for good: it had some (``had_workers``: at the first hand-out, or since), none
    is registered now, the cluster still plans some (``cluster.plan``, the workers it means to have: empty once
    scaled to zero, by ``adapt`` or by hand, whose cluster is waited for as before) and keeps none of them
    (``cluster.requested``: its nannies, or thread workers, started and not closed). Dask's LocalCluster closes a
    nanny whose worker died where no worker of its name registered again within
    ``distributed.deploy.lost-worker-timeout`` (15 s): a restart slower than that (a busy machine) loses the worker,
    and with the last one the run waited for ever (0.59). An adaptive cluster starts such workers again itself
    (its next look finds ``plan`` and ``requested`` apart), which the run waits for as long as Dask's timeout: the
    first look that finds the cluster so is the time kept. Another cluster's workers may join later: ``lost()`` is
    then always False. Public state alone (0.61; 0.60 read the cluster's private ``_adaptive``)."""
    distributed = import_distributed()
    import dask
    from dask.utils import parse_timedelta

    cluster = own_cluster if own_cluster is not None else getattr(client, "cluster", None)
    if not isinstance(cluster, distributed.LocalCluster):
        return lambda: False
    had, since = [had_workers], [None]

    def lost():
        try:
            if client.nthreads():
                had[0], since[0] = True, None
                return False
            if not (had[0] and cluster.plan and not cluster.requested):
                since[0] = None
                return False
        except Exception:  # noqa: BLE001 - a cluster closing: the wait goes on as before
            return False
        now = time.monotonic()
        since[0] = now if since[0] is None else since[0]
        patience = parse_timedelta(dask.config.get("distributed.deploy.lost-worker-timeout"), default="s")
        return now - since[0] >= patience

    return lost


def _next_group(finished, lost, every=2.0, overdue=None):
    """The futures that finished since the last call (``finished``: a queue each future is put into once done, by
    ``Future.add_done_callback``), waiting for the first: looking every ``every`` seconds without one whether the
    cluster ``lost()`` its workers for good, twice in a row, then a one-line :class:`~tghop.TGHopError`, and whether a
    task is ``overdue()`` (past the task timeout: none returned then, 0.63). (0.60 waited on ``as_completed``'s
    undocumented ``thread_condition``; 0.61 on a queue of its own, Dask's documented callback.)"""
    looks = 0
    while True:
        try:
            group = [finished.get(timeout=every)]
            break
        except queue.Empty:
            pass
        if overdue is not None and overdue():
            return []
        looks = looks + 1 if lost() else 0  # only after a wait without a result: no round trip per group
        if looks >= 2:
            raise TGHopError("the local Dask cluster lost every worker for good (each killed, by the system when out "
                             "of memory or by a task, and not started again within Dask's "
                             "distributed.deploy.lost-worker-timeout, as on a busy machine); the run stopped: the "
                             "exemplars finished are in the ledger, the next run does the rest (fewer workers per "
                             "machine or a smaller size use less memory)")
    with contextlib.suppress(queue.Empty):
        while True:
            group.append(finished.get_nowait())
    return group


#: How long a restart after a task timeout (:func:`run_distributed`; 0.63) may take, the worker back included: it
#: runs beside the run (0.64; 0.63's driver waited for it, collecting no result meanwhile); one that fails is said
#: in a warning.
RESTART_TIMEOUT = 120
#: How long the driver waits for the nannies of timed-out workers to name them (:func:`_worker_names`; 0.64: 0.63 waited
#: without a limit); past it, or where one fails, a worker is named by its address.
NAME_TIMEOUT = 5.0


def worker_process(dask_worker) -> str:
    """Run on a worker's nanny (``Client.run(..., nanny=True)``): the worker process's ``host:pid``, as the records of
    its tasks name it (:func:`tghop.batch_task.run_task`)."""
    import socket

    return f"{socket.gethostname()}:{dask_worker.pid}"


def _worker_names(client, addresses) -> dict:
    """address -> ``host:pid`` of the workers at ``addresses``, asked of their nannies (a busy worker's own event loop
    may wait on its task); a worker without a nanny, one whose nanny fails, and all where the answer takes longer than
    :data:`NAME_TIMEOUT` (0.64: ``Client.run`` has no timeout; the call is left to end in a thread of its own) are left
    out (named by their address)."""
    if not addresses:
        return {}
    answer = queue.SimpleQueue()

    def ask():
        try:
            answer.put(client.run(worker_process, workers=list(addresses), nanny=True, on_error="return"))
        except Exception:  # noqa: BLE001 - no nanny, or the scheduler lost: the address names it
            answer.put({})

    threading.Thread(target=ask, name="tghop-batch-names", daemon=True).start()
    try:
        said = answer.get(timeout=NAME_TIMEOUT)
    except queue.Empty:
        return {}
    return {address: name for address, name in said.items() if isinstance(name, str)}


class _Restart:
    """Workers restarted through their nannies (``Client.restart_workers``) in a thread of its own, so that the run
    goes on meanwhile (0.64); once done (or failed: ``failed``, address -> Dask's word, "timed out" or an error), put
    into the run's queue of finished futures (``wake``), which it wakes. ``key`` None: no future's."""

    key = None

    def __init__(self, client, addresses, wake):
        self.addresses, self.failed = list(addresses), {}
        threading.Thread(target=self._run, args=(client, wake), name="tghop-batch-restart", daemon=True).start()

    def _run(self, client, wake):
        try:
            said = client.restart_workers(self.addresses, timeout=RESTART_TIMEOUT, raise_for_error=False) or {}
        except Exception as exc:  # noqa: BLE001 - said in the run's warning
            said = dict.fromkeys(self.addresses, one_line(exc))
        self.failed = {a: str(v) for a, v in said.items() if v != "OK"}
        wake.put(self)


def _restart_failed(failed) -> str:
    """The warning of workers (``failed``: address -> Dask's word) whose restart after a task timeout failed."""
    shown = ", ".join(f"{a}: {v}" for a, v in list(failed.items())[:5]) + (" ..." if len(failed) > 5 else "")
    return (f"{'a Dask worker' if len(failed) == 1 else f'{len(failed)} Dask workers'} restarted after a task timeout "
            f"did not come back within {RESTART_TIMEOUT} s ({shown}); the run goes on with the other workers (a local "
            "cluster without any stops with one line once Dask's distributed.deploy.lost-worker-timeout has passed; "
            "another waits until a worker joins)")


def _stop_overdue(client, late, running, by_key, handed, seconds) -> tuple:
    """``(done, restarted, taken)``: the (job, record) of each future of ``late`` (running past the task timeout,
    ``seconds``; ``handed``: key -> the (monotonic, wall) time it was handed out), a record of
    :func:`tghop.batch_task.timed_out_record` naming its worker as other records do, ``host:pid`` (0.63; 0.62 gave its
    address, ``tcp://...``); the addresses of their workers that have a nanny, to restart (Dask cannot stop a running
    thread) once the tasks are cancelled, so that they are free again; and the futures of ``running`` (not late) on
    those workers, which the restart would kill: cancelled too (0.64), their jobs to hand out again under new keys, so
    that they count no death against the exemplar's tries (0.63 left them to Dask, which counted one, and with
    ``retries=0`` recorded them failed). A worker without a nanny (``dask worker --no-nanny``, a cluster of threads) is
    not restarted: its thread runs on to the task's end, its other tasks with it, and the late task's files are
    dropped (the exemplar's claim is gone once its line is written)."""
    try:  # the workers running them: the scheduler's record; which have a nanny
        on = {key: address for address, keys in client.processing().items() for key in keys}
        info = client.scheduler_info().get("workers", {})
    except Exception:  # noqa: BLE001 - a scheduler lost: said by the next call of the run
        on, info = {}, {}
    restarted = sorted({on[fut.key] for fut in late if fut.key in on and (info.get(on[fut.key]) or {}).get("nanny")})
    named = _worker_names(client, sorted({on[fut.key] for fut in late if fut.key in on}))
    done = [(by_key[fut.key], {**timed_out_record(by_key[fut.key], seconds, handed[fut.key][1], lost=fut.key in on),
                               "worker": named.get(on.get(fut.key), on.get(fut.key))}) for fut in late]
    taken = [fut for fut in running if fut not in late and on.get(fut.key) in restarted and not fut.done()]
    with contextlib.suppress(Exception):
        client.cancel([*late, *taken], force=True)
    return done, restarted, taken


def run_distributed(jobs, finish, counts, task, *, workers, client, own_client, retries, begin, worker_setup=None,
                    on_stop=None, task_timeout=None):
    """Run ``jobs`` on ``client``'s cluster (None: a local cluster of ``workers``, started
    here); ``own_client``, and the cluster started here, are closed at the end. Each job
    goes to ``begin`` before it is handed out; ``finish`` takes a list of the (job, record) pairs that came
    back together (0.59; 0.58 gave it one job and its record). ``worker_setup``: run
    in each worker of the cluster started here before its first task (and in one that replaces a
    dead one), none of another cluster's. ``on_stop``: called when the run stops early (Ctrl-C, an error),
    before anything is cancelled or closed: the ledger's ``interrupted`` lines (0.63; 0.62 wrote them once the
    cluster had closed). ``task_timeout``: seconds from a task's hand-out after which it is the exemplar's failure
    and its worker is restarted (:func:`_stop_overdue`; None: no limit; 0.63)."""
    from . import __version__

    distributed = import_distributed()
    # a cluster not started here (--scheduler, or a given client since 0.59): its workers were checked before any
    # work (check_cluster), those that join mid-run are checked as they are seen, but for the workers a given
    # client's LocalCluster of this process starts itself with this interpreter (its_own: a restart, scale), whose
    # check was suspected of losing a test's cluster every worker (Dask's lost-worker-timeout does so without it:
    # _next_group). 0.59 left every worker of such a cluster unchecked, one that joined its scheduler from
    # elsewhere too (another tghop's: each task failed on it, and the run went on).
    its_own = _own_workers(client) if client is not None and own_client is not client else (lambda address: False)

    def check_joined(addresses):
        others = [a for a in addresses if not its_own(a)]
        if others:
            check_workers_tghop(client, others)

    own_cluster = None
    futures = []
    own_files = [False]  # True while begin or finish writes this run's own files (their OSError is theirs)
    # A worker restarted after a death writes its environment into this process's again (local_cluster).
    kept = environ_kept(worker_environ()) if client is None else contextlib.nullcontext()
    kept.__enter__()
    try:
        if client is None:
            own_cluster = local_cluster(workers, retries=retries)
            client = own_client = distributed.Client(own_cluster)
            if worker_setup is not None:  # on the workers there now, and on every one that registers later
                client.register_worker_callbacks(worker_setup)
        # The longest first (a shorter tail), handed out one per free thread as tasks finish:
        # a worker holds only the task it runs. Dask would place every task on a worker at
        # once (tasks of different names are not "root-ish", so it queues none on the
        # scheduler), and a worker's death would count against the tasks waiting on it too.
        order = collections.deque(sorted(jobs, key=_cost, reverse=True))
        # Each future put into `finished` once done (Future.add_done_callback: in Dask's callback thread, on the
        # future's own client's loop; as_completed would take the default client's, which may be another, one closed
        # by now: its futures were never reported, and the run waited for ever). `running`: handed out, not taken.
        by_key, running, finished = {}, set(), queue.SimpleQueue()
        handed, dropped = {}, set()  # key -> (monotonic, wall) time of its hand-out; keys stopped by the timeout
        # 0.64: a restart after a task timeout runs beside the run (_Restart); meanwhile its worker is handed nothing
        # (what it got would die with it), and the other tasks it ran are handed out again first (requeued)
        restarting, requeued = set(), []

        def overdue():
            if task_timeout is None:
                return []
            now = time.monotonic()
            return [fut for fut in running if now - handed[fut.key][0] > task_timeout and not fut.done()]

        seen = {}  # the workers at the last hand-out: address -> name
        known = set(client.nthreads()) if own_cluster is None else set()  # every worker checked (check_cluster)

        def hand_out():
            nthreads = client.nthreads()
            free = {a: n for a, n in nthreads.items() if a not in restarting}
            # again each time: a cluster may grow; none while every worker is being restarted (0.64: a task's time
            # counts from its hand-out, and a worker's start is no part of it)
            slots = sum(free.values()) if restarting else max(1, sum(nthreads.values()))
            gone = [a for a in seen if a not in nthreads and a not in restarting]
            if gone:  # a worker killed (the run went on without a word) or stopped
                warnings.warn(_workers_gone(gone, seen, own_cluster is not None, _running_on(client, gone, by_key)),
                              stacklevel=2)
            joined = [a for a in nthreads if a not in known]
            if joined and own_cluster is None:
                check_joined(joined)
            known.update(joined)
            if not seen or gone or set(nthreads) - set(seen):
                info = client.scheduler_info().get("workers", {})
                seen.clear()
                seen.update({a: info.get(a, {}).get("name", a) for a in nthreads if a not in restarting})
            n = max(0, slots - len(running))
            again, requeued[:] = requeued[:n], requeued[n:]  # begun already: their claims stand
            now = again + [order.popleft() for _ in range(min(n - len(again), len(order)))]
            keys = [f"tghop-batch-{job['name']}-{job['sha256'] or 'none'}-{time.time_ns()}" for job in now]
            for job in now[len(again):]:
                own_files[0] = True
                begin(job)
                own_files[0] = False
            if now:  # one message to the scheduler for them all (0.59: client.submit each)
                # run_checked: a worker that joins later, past the check above, may have another tghop or none; not to
                # a worker being restarted while it is still there (0.64; loose: where those others left, anywhere)
                away = {"workers": list(free), "allow_other_workers": True} if set(nthreads) & restarting else {}
                new = client.map(run_checked, [task] * len(now), now, [__version__] * len(now), key=keys, pure=False,
                                 **away)
                by_key.update({fut.key: job for fut, job in zip(new, now)})
                handed.update(dict.fromkeys([fut.key for fut in new], (time.monotonic(), time.time())))
                futures.extend(new)
                running.update(new)
                for fut in new:
                    fut.add_done_callback(finished.put)
            counts["running"] = len(running) + len(requeued)

        hand_out()
        lost = _workers_lost(client, own_cluster, bool(seen))
        while running or requeued or (order and restarting):
            # What came back since the last group, taken together (0.59; 0.58 took one result at a time): one
            # gather of their results, one look at the workers (hand_out) and one sync of their ledger lines
            # (finish) for the group; each a round trip or a disk's flush, which per exemplar bounded a large
            # cluster to tens of exemplars a second (docs/batch.md, "The driver's cost per exemplar").
            came = _next_group(finished, lost, overdue=overdue)
            for restart in [r for r in came if isinstance(r, _Restart)]:  # done: its worker may have work again
                restarting.difference_update(restart.addresses)
                if restart.failed:
                    warnings.warn(_restart_failed(restart.failed), stacklevel=2)
            group = [fut for fut in came if not isinstance(fut, _Restart) and fut.key not in dropped]
            running.difference_update(group)
            done = _results(client, group, by_key, retries if own_cluster is not None else None,
                            None if own_cluster is not None else check_joined) if group else []
            for fut in group:
                fut.release()
            late = overdue()
            if late:  # past the task timeout (0.63): the exemplar's failure, its worker restarted
                dropped.update(fut.key for fut in late)
                running.difference_update(late)
                stopped, restarted, taken = _stop_overdue(client, late, running, by_key, handed, task_timeout)
                done += stopped
                dropped.update(fut.key for fut in taken)  # handed out again: no death of theirs (0.64)
                running.difference_update(taken)
                requeued.extend(by_key[fut.key] for fut in taken)
                for address in restarted:  # not "a worker left the cluster mid-run": restarted on purpose
                    seen.pop(address, None)
                if restarted:
                    restarting.update(restarted)
                    _Restart(client, restarted, finished)
            try:
                hand_out()  # before the ledger lines: the freed workers start at once
            except TGHopError:  # a worker that joined without this tghop (check_workers_tghop): the run stops
                finish(done)  # after these exemplars' lines: they were made by this tghop
                raise
            own_files[0] = True
            finish(done)
            own_files[0] = False
    except BaseException as exc:
        if on_stop is not None:  # the exemplars under way recorded first: closing a busy cluster takes a while
            on_stop()
        lost = None
        if client is not None and isinstance(exc, Exception) and not isinstance(exc, TGHopError):
            lost = _lost_scheduler(client, exc, dask_call=not own_files[0])
        try:
            if client is not None:
                client.cancel([f for f in futures if not f.done()])
        except Exception:  # noqa: BLE001 - stopping anyway
            pass
        if lost is not None:
            raise lost from exc
        raise
    finally:
        with ctrl_c_ignored():  # a second Ctrl-C must not leave the cluster half-closed
            try:
                if own_client is not None:
                    own_client.close()
                if own_cluster is not None:
                    own_cluster.close()
            finally:
                kept.__exit__(None, None, None)
