"""The machine's resources as tghop uses them: memory (``available_memory``, ``check_memory``),
cores and threads (``usable_cores``, ``limit_cores``, ``one_blas_thread``, ``in_thread``) and
the optional PyTorch (``import_torch``).
"""

from __future__ import annotations

import contextlib
import os
import threading
from typing import Callable, Optional

from ._errors import MissingExtraError, TGHopError

__all__ = [
    "available_memory",
    "check_memory",
    "INSTALL_HINT",
    "import_torch",
    "usable_cores",
    "limit_cores",
    "one_blas_thread",
    "in_thread",
]


def available_memory() -> Optional[int]:
    """Bytes of memory available to a new allocation now, or None where unknown.

    Linux's ``MemAvailable`` (``/proc/meminfo``: free memory plus the page cache and
    buffers that can be reclaimed), else ``os.sysconf('SC_PAGE_SIZE') *
    os.sysconf('SC_AVPHYS_PAGES')`` (free pages only: an underestimate). Containers'
    cgroup limits are not read.
    """
    import os

    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_AVPHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def _format_bytes(n: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n / 1e6:.2g} MB"


def check_memory(estimate: Callable[[int, int], float], size, *, what: str, name: str = "size") -> None:
    """Refuse, before any work, a ``size`` whose memory ``estimate(h, w)`` (bytes) exceeds
    :func:`available_memory`; the one-line :class:`TGHopError` names the largest size of
    the same aspect ratio that fits. Nothing is checked where the available memory is unknown.

    Parameters
    ----------
    estimate : callable
        ``estimate(h, w)``: bytes the work needs for an ``h x w`` result, non-decreasing in both.
    size : (int, int)
    what : str
        The work, for the message (``"ustyuzhaninov"``).
    name : str
        How the size is called (``"size"``; ``"--size"`` on the command line).
    """
    avail = available_memory()
    if avail is None:
        return
    h, w = (int(v) for v in size)
    need = float(estimate(h, w))
    if need <= avail:
        return
    lo, hi = 0.0, 1.0  # largest scale f with estimate(f h, f w) <= avail, by bisection
    for _ in range(40):
        mid = (lo + hi) / 2
        if estimate(max(1, int(mid * h)), max(1, int(mid * w))) <= avail:
            lo = mid
        else:
            hi = mid
    fh, fw = int(lo * h), int(lo * w)
    if fh < 1 or fw < 1 or estimate(max(1, fh), max(1, fw)) > avail:
        raise TGHopError(f"{what} needs about {_format_bytes(need)} of memory for {h}x{w} and still "
                         f"{_format_bytes(estimate(1, 1))} for the smallest result, but only "
                         f"{_format_bytes(avail)} is available; use a smaller exemplar or free some memory")
    raise TGHopError(f"{what} at {name} {h}x{w} needs about {_format_bytes(need)} of memory but only "
                     f"{_format_bytes(avail)} is available; the largest {name} that fits is about {fh}x{fw}")


#: How to install what the neural baselines, the cGAN and the network metrics need.
INSTALL_HINT = "pip install 'tghop[metrics]'"


def import_torch(what: str):
    """``torch``, or a one-line :class:`MissingExtraError` saying that ``what`` needs it
    and how to install it."""
    try:
        import torch
    except ImportError:
        raise MissingExtraError(f"{what} needs PyTorch; install it with: {INSTALL_HINT} (where pip would fetch a "
                                "CUDA build of several GB, install PyTorch's CPU build of torch 2.13.0 first: "
                                "README)") from None
    return torch


#: The process-wide limit of :func:`limit_cores` (None: no limit).
_core_limit = None


def usable_cores() -> int:
    """Cores this process may run on: its affinity mask (``os.sched_getaffinity``, else
    ``os.cpu_count()``), at most the limit of :func:`limit_cores`, at least 1.

    :meth:`tghop.core.ICHM.fit` runs its clusters in this many Python threads, each with
    one BLAS thread: threads that block do not spin, so beside other work they share the
    cores fairly and a fit is no slower than on one thread, while on an idle machine it
    uses every core (OpenBLAS's own threads spin between calls, and on a loaded machine a
    fit with them took several times as long as with one; docs/choices.md). The steps of
    generation that split a large image over threads (refinement, colour matching, the
    coarse layout's guide, PNG compression) use this too.
    """
    import os

    try:
        n = max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    return n if _core_limit is None else max(1, min(n, _core_limit))


class limit_cores:
    """Context manager: :func:`usable_cores` says at most ``n`` (None: no limit) while it
    is active, in every thread of the process (like ``threadpoolctl.threadpool_limits``,
    whose BLAS limit it complements: tghop's own threads).

    A batch worker process runs one exemplar at a time on one core
    (:func:`tghop.batch.process_exemplar` with ``threads=1``): its fit and generation
    then start no threads of their own to compete with the other workers.
    """

    def __init__(self, n: Optional[int]):
        self.n = None if n is None else max(1, int(n))

    def __enter__(self):
        global _core_limit
        self._previous = _core_limit
        if self.n is not None:
            _core_limit = self.n if _core_limit is None else min(_core_limit, self.n)
        return self

    def __exit__(self, *exc):
        global _core_limit
        _core_limit = self._previous
        return False


#: The process's holds of one BLAS thread (:func:`one_blas_thread`): how many are active, in any thread,
#: and the limiter the first set, which the last to leave restores.
_BLAS_HOLD = {"count": 0, "limiter": None}


_BLAS_LOCK = threading.Lock()


_BLAS_OWN = threading.local()  # this thread's holds: the ones a child of os.fork keeps


def _blas_holds_after_fork():
    """In a child of ``os.fork`` only the forking thread's holds go on (0.57; 0.56's child stayed on one BLAS
    thread)."""
    global _BLAS_LOCK
    _BLAS_LOCK, own = threading.Lock(), getattr(_BLAS_OWN, "count", 0)  # the lock: another thread's at the fork
    if _BLAS_HOLD["count"] > own:
        _BLAS_HOLD["count"] = own
        import threadpoolctl  # imported by the hold

        controller = threadpoolctl.OpenBLASController
        if hasattr(controller, "clear_controlling_thread"):  # threadpoolctl >= 3.8: the holder is not in the child
            controller.clear_controlling_thread(force=True)
        if not own:
            _BLAS_HOLD.pop("limiter").restore_original_limits()
            _BLAS_HOLD["limiter"] = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_blas_holds_after_fork)


@contextlib.contextmanager
def one_blas_thread():
    """Context manager (and decorator): one BLAS thread while inside, in every thread of the process.

    OpenBLAS's products round differently on more threads, so generating inside it gives the
    same image on a machine of any number of cores (a batch worker's one thread, ``tghop
    synth``'s all). Its limit is the process's, so the holds are counted process-wide (0.57): the
    first sets it (``threadpoolctl.threadpool_limits(limits=1, user_api="blas")``), the last to
    leave, in whichever thread, puts back what the first found. Until 0.56 each hold set and
    restored its own, so two threads' calls at once left the later one on the process's threads
    (other bytes: a fit in two threads gave another model) and the process on one BLAS thread after
    both. A thread that leaves while another holds on gives up threadpoolctl's control of OpenBLAS's
    limit (since threadpoolctl 3.8, only the thread that set it first may change it), unless a
    ``threadpool_limits`` of its own is active.
    """
    import threadpoolctl

    with _BLAS_LOCK:
        if not _BLAS_HOLD["count"]:
            _BLAS_HOLD["limiter"] = threadpoolctl.threadpool_limits(limits=1, user_api="blas")
        _BLAS_HOLD["count"] += 1
        _BLAS_OWN.count = getattr(_BLAS_OWN, "count", 0) + 1
    try:
        yield
    finally:
        with _BLAS_LOCK:
            _BLAS_HOLD["count"] -= 1
            _BLAS_OWN.count -= 1
            if not _BLAS_HOLD["count"]:
                _BLAS_HOLD.pop("limiter").restore_original_limits()
                _BLAS_HOLD["limiter"] = None
            own = getattr(threadpoolctl, "CONTROLLING_THREAD_OWNERSHIP", None)  # threadpoolctl >= 3.8
            if own is not None and not own.count:
                threadpoolctl.OpenBLASController.clear_controlling_thread()


def in_thread(fn, *args, **kwargs) -> Callable:
    """Start ``fn(*args, **kwargs)`` in a thread of its own; return a function that waits
    for it and returns its result (or raises its exception).

    The thread is a daemon: an interrupted caller does not wait for it. (``threading``
    alone: ``concurrent.futures`` imports ``logging``, a noticeable part of a small
    ``tghop synth``.) With one usable core (:func:`usable_cores`, e.g. a batch worker's
    task) no thread is started: ``fn`` runs in the caller's thread when its result is asked for.
    The thread runs in a copy of the caller's context (as ``asyncio.to_thread``): its warnings
    go where the caller's would (:func:`tghop._errors.collect_warnings`).
    """
    if usable_cores() == 1:
        return lambda: fn(*args, **kwargs)
    import contextvars

    outcome = {}

    def run():
        try:
            outcome["result"] = fn(*args, **kwargs)
        except BaseException as exc:  # handed to the caller, who raises it
            outcome["error"] = exc

    thread = threading.Thread(target=contextvars.copy_context().run, args=(run,), daemon=True)
    thread.start()

    def result():
        thread.join()
        if "error" in outcome:
            raise outcome.pop("error")
        return outcome["result"]

    return result
