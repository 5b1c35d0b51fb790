"""The fit queue of the web server: fits run on a pool of threads, at most ``max_fits`` at
once (the rest wait in order), report progress through the library's ``progress``
callback and stop when cancelled (the callback raises :class:`Cancelled`).

The job table is bounded: a finished job is kept ``keep_finished`` seconds (its client
reads the outcome in that time) and at most ``max_finished`` finished fits and as many finished
generations are kept, each kind on its own (the oldest of the kind go first: a flood of generations
never drops a fit's outcome); at most ``max_waiting`` jobs wait for a thread (a further one is
refused with :class:`QueueFull`). Queued and running jobs are never dropped.

Nothing here knows about HTTP; :mod:`tghop.server.routes.fit` turns jobs into JSON and
server-sent events. Only the standard library is imported.
"""

from __future__ import annotations

import re
import threading
import time
import uuid
from concurrent.futures import ThreadPoolExecutor

from .requests import page_words

__all__ = ["JOB_ID", "Cancelled", "QueueFull", "Job", "GenerationJob", "FitQueue", "STATES", "FIT_STAGES", "fit_stages",
           "GENERATION_STAGES", "generation_fraction", "unknown_snapshot"]

#: A job's id: 32 hex digits.
JOB_ID = re.compile(r"[0-9a-f]{32}\Z")

#: Job states; the last three are final.
STATES = ("queued", "running", "done", "failed", "cancelled")
FINAL = ("done", "failed", "cancelled")

#: The stages :meth:`tghop.TGHop.fit` reports, in order, and their share of the whole fit
#: (rough times of a small fit): the progress bar's fraction. "hop 3" is a fit's of 64x64 patches only, "layout"
#: one's with an exemplar large enough for its layout, "maps" a material's (:meth:`tghop.material.Material.fit`),
#: "saving" the server's; a job counts those its fit will report (:func:`fit_stages`).
FIT_STAGES = {"exemplar": 0.05, "hop 1": 0.1, "hop 2": 0.1, "hop 3": 0.05, "core": 0.05, "SDR": 0.05,
              "clusters": 0.15, "ICA": 0.3, "CDF codebook": 0.1, "layout": 0.1, "maps": 0.05, "saving": 0.05}

#: The share of a stage not in :data:`FIT_STAGES` (a guess, counted in the whole once it comes).
OTHER_STAGE = 0.05


def fit_stages(n_hops: int, *, material: bool = False, layout: bool = False) -> tuple:
    """The stages a fit of ``n_hops`` hops reports, in order, then the server's "saving": "layout" when the fit
    will make one (``layout``: its exemplar, after any working scale, is large enough for it; the server reads
    that before the fit, :func:`tghop.server.routes.fit.prepare_fit`), a material's "maps" after its joint
    model's."""
    return ("exemplar", *(f"hop {i}" for i in range(1, n_hops + 1)), "core", "SDR", "clusters", "ICA",
            "CDF codebook", *(("layout",) if layout else ()), *(("maps",) if material else ()), "saving")


#: The stages a generation reports (:meth:`tghop.TGHop.synthesize`, :func:`tghop.inpaint.inpaint`,
#: :func:`tghop.guided.morph`; the server's own "encoding" of the PNG), in the order they come, and their
#: rough share of the whole: the progress bar's fraction. "quilting", "inpainting" and "generating" (the
#: co-occurrence generator's pass, :mod:`tghop.server.cooc`) take one place (a generation makes one of
#: them). Stages left out (no layout, no refinement) count as passed once a
#: later one comes; a painted guide's or a remix's layers ("quilting 1/2": layer 1 of 2) share the part
#: before "join" equally.
GENERATION_STAGES = (("layout", 0.06), ("patch pool", 0.04), (("quilting", "inpainting", "generating"), 0.42),
                     ("seams", 0.05), ("refine", 0.2), ("patch refine", 0.15), ("colour", 0.01), ("maps", 0.02),
                     ("join", 0.03), ("encoding", 0.02))


def generation_fraction(stage: str, done: int, total: int):
    """Where ``progress(stage, done, total)`` of a generation is in the whole, in [0, 1]
    (:data:`GENERATION_STAGES`); None for a stage not in the table."""
    whole = sum(share for _, share in GENERATION_STAGES)
    layer = re.fullmatch(r"(.+) ([0-9]+)/([0-9]+)", stage)
    if layer is not None:  # one layer of several: its stages in the part before "join"
        inner = generation_fraction(layer.group(1), done, total)
        i, k = int(layer.group(2)), int(layer.group(3))
        before_join = generation_fraction("join", 0, 1)
        if inner is None or not 1 <= i <= k or before_join is None:
            return None
        return before_join * ((i - 1) + min(1.0, inner / before_join)) / k
    passed = 0.0
    for names, share in GENERATION_STAGES:
        if stage in ((names,) if isinstance(names, str) else names):
            return (passed + share * (min(done, total) / total if total > 0 else 0.0)) / whole
        passed += share
    return None


def unknown_snapshot(job_id: str) -> dict:
    """What a client that expects the job ``job_id`` is told while it is not in the table: the keys of
    :meth:`Job.snapshot`, ``state`` ``unknown`` (a generation's request not yet read as far as its job header,
    or one that never will be: refused before, or its job finished and dropped)."""
    return {"job": job_id, "kind": None, "id": None, "state": "unknown", "stage": "", "stages": [], "done": 0,
            "total": 0, "progress": 0.0, "version": 0, "askers": 0}


class Cancelled(Exception):
    """Raised from a cancelled job's progress callback: the fit stops there."""


class QueueFull(Exception):
    """More fits are waiting than the queue takes (:attr:`FitQueue.max_waiting`)."""


class Job:
    """One fit: its state, its progress and, when it failed, the one-line reason.

    Attributes
    ----------
    id : str
    model_id : str
        The model the fit makes (its file appears in the cache when the job is done).
    state : str
        One of :data:`STATES`.
    stage, done, total : str, int, int
        The last ``progress(stage, done, total)`` call.
    stages : list of str
        Every stage reported so far, in order (a client that looks now and then may have
        missed some of them in ``stage``).
    error : str or None
    version : int
        Grows with every change (what the event stream waits on).
    askers : int
        The requests that asked for this fit and have not withdrawn (:meth:`FitQueue.cancel`).
    on_cancel : callable or None
        Called (on any thread) once the job is asked to stop: a generation waiting for its turn or a
        thread leaves its queue at once (:meth:`tghop.server.core.Server.in_executor`).
    """

    kind = "fit"

    def __init__(self, model_id, state: str = "queued", job_id: str | None = None):
        self.id = job_id or uuid.uuid4().hex
        self.model_id = model_id
        self.state = state
        self.stage = ""
        self.done = 0
        self.total = 0
        self.error = None
        self.version = 0
        self.finished_at = None  # time.monotonic() when it became final
        self.cancel_requested = False
        self.askers = 1
        self.future = None
        self.on_cancel = None  # called (on any thread) once the job is asked to stop: a generation's wait ends
        self._seen = []  # stages in the order they came
        # The stages the fit will report (fit_stages; set before it starts), or None: those of FIT_STAGES but
        # "layout". Any other that comes (or "layout") is counted in the whole once it comes.
        self.stages = None
        self._reached = 0.0  # the fraction told so far: a stage that was not expected does not take it back
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ reading
    @property
    def final(self) -> bool:
        return self.state in FINAL

    def fraction(self) -> float:
        """Progress of the whole fit in [0, 1] (1 when done). It never goes back: a stage that comes unexpected
        (not in :attr:`stages`) grows the whole, and the fraction stays where it was until the fit catches up."""
        if self.state == "done":
            return 1.0
        if not self._seen:
            return 0.0
        finished = sum(FIT_STAGES.get(s, OTHER_STAGE) for s in self._seen[:-1])
        current = FIT_STAGES.get(self.stage, OTHER_STAGE) * (self.done / self.total if self.total else 0.0)
        expected = self.stages if self.stages is not None else (s for s in FIT_STAGES if s != "layout")
        whole = sum(FIT_STAGES.get(s, OTHER_STAGE) for s in dict.fromkeys([*expected, *self._seen]))
        self._reached = max(self._reached, min(0.99, (finished + current) / whole))
        return self._reached

    def snapshot(self) -> dict:
        """The job as JSON-ready data."""
        with self._lock:
            out = {"job": self.id, "kind": self.kind, "id": self.model_id, "state": self.state, "stage": self.stage,
                   "stages": list(self._seen), "done": self.done, "total": self.total,
                   "progress": round(self.fraction(), 4), "version": self.version, "askers": self.askers}
            if self.error:
                out["error"] = self.error
            return out

    # ------------------------------------------------------------------ writing
    def _update(self, **changes):
        with self._lock:
            for key, value in changes.items():
                setattr(self, key, value)
            if self.state in FINAL and self.finished_at is None:
                self.finished_at = time.monotonic()
            self.version += 1

    def set_state(self, state: str, *, error: str | None = None) -> None:
        """Move the job to ``state`` (one of :data:`STATES`), with its message when it ``failed``."""
        self._update(state=state, **({} if error is None else {"error": error}))

    def progress(self, stage: str, done: int, total: int, *, cancellable: bool = True) -> None:
        """The library's progress callback; raises :class:`Cancelled` once cancelled (unless
        not ``cancellable``: past the point of no return, such as a file written)."""
        if self.cancel_requested and cancellable:
            raise Cancelled()
        if stage != self.stage and stage not in self._seen:
            self._seen.append(stage)
        self._update(stage=stage, done=int(done), total=int(total))


class GenerationJob(Job):
    """A generation's progress, under an id its client chose (the request's ``X-Tghop-Job`` header:
    :meth:`tghop.server.core.Server.in_executor`), in the same table as the fits: ``GET /api/jobs/{job}``
    follows it and ``DELETE`` stops it. ``model_id``: the model of the route's path, or None (several)."""

    kind = "generation"

    def __init__(self, model_id, job_id: str):
        super().__init__(model_id, job_id=job_id)
        self._fraction = 0.0

    def fraction(self) -> float:
        """Progress of the whole generation in [0, 1] (1 when done), by :data:`GENERATION_STAGES`;
        it never goes back (a stage not in the table keeps the last value)."""
        if self.state == "done":
            return 1.0
        where = generation_fraction(self.stage, self.done, self.total) if self.stage else None
        if where is not None:
            self._fraction = max(self._fraction, min(0.99, where))
        return self._fraction

    def progress(self, stage: str, done: int, total: int, *, cancellable: bool = True) -> None:
        super().progress(stage, done, total, cancellable=cancellable)
        with self._lock:
            self.fraction()  # remembered at every report, not only when read


class FitQueue:
    """At most ``max_fits`` fits at once on a thread pool; jobs by id.

    ``submit(model_id, work)`` runs ``work(job)`` (which calls ``job.progress``) in turn;
    a second submit of a model that is still queued or running returns the same job, and
    the job is cancelled only once every submit that got it has withdrawn (:meth:`cancel`).

    Parameters
    ----------
    max_fits : int
        Fits that run at once.
    max_waiting : int
        Jobs that may wait for a thread; :meth:`submit` raises :class:`QueueFull` beyond.
    keep_finished : float
        Seconds a finished job stays in the table (then :meth:`get` answers None).
    max_finished : int
        Finished fits kept at most (the oldest are dropped first).
    max_finished_generations : int, optional
        Finished generation jobs kept at most, counted apart from the fits (default ``max_finished``).
    """

    def __init__(self, max_fits: int, *, max_waiting: int = 64, keep_finished: float = 3600.0,
                 max_finished: int = 1000, max_finished_generations: int | None = None):
        if max_fits < 1:
            raise ValueError(f"max_fits must be at least 1, got {max_fits}")
        self.max_fits = max_fits
        self.max_waiting = max_waiting
        self.keep_finished = keep_finished
        self.max_finished = max_finished
        self.max_finished_generations = max_finished if max_finished_generations is None else max_finished_generations
        self._pool = ThreadPoolExecutor(max_workers=max_fits, thread_name_prefix="tghop-fit")
        self._jobs = {}  # in the order they were made
        self._active = {}  # model id -> job still queued or running
        self._lock = threading.Lock()

    def _prune(self) -> None:
        """Drop expired finished jobs, then the oldest finished fits over ``max_finished`` and the
        oldest finished generations over ``max_finished_generations``, each kind counted on its own
        (with the lock held)."""
        now = time.monotonic()
        finished = [j for j in self._jobs.values() if j.final and j.finished_at is not None]
        for job in finished:
            if now - job.finished_at > self.keep_finished:
                del self._jobs[job.id]
        for generations, bound in ((False, self.max_finished), (True, self.max_finished_generations)):
            kept = [j for j in finished if j.id in self._jobs and (j.kind == "generation") == generations]
            if len(kept) > bound:
                kept.sort(key=lambda j: j.finished_at)
                for job in kept[: len(kept) - bound]:
                    del self._jobs[job.id]

    def __len__(self) -> int:
        """Jobs in the table (finished ones not yet dropped included)."""
        with self._lock:
            self._prune()
            return len(self._jobs)

    def finished(self, model_id: str) -> Job:
        """A job that is already done (the model was in the cache)."""
        job = Job(model_id)
        job._update(state="done")
        with self._lock:
            self._prune()
            self._jobs[job.id] = job
        return job

    def add(self, job: Job) -> bool:
        """Put a job made elsewhere (a generation's) in the table; False when its id is taken."""
        with self._lock:
            self._prune()
            if job.id in self._jobs:
                return False
            self._jobs[job.id] = job
            return True

    def submit(self, model_id: str, work) -> Job:
        """Queue ``work(job)`` for ``model_id`` (or return its job still queued or running,
        unless that job was asked to stop: then a new one, so that the model is still made).

        Raises
        ------
        QueueFull
            ``max_waiting`` jobs are already waiting for a thread.
        """
        with self._lock:
            self._prune()
            active = self._active.get(model_id)
            if active is not None and not active.final and not active.cancel_requested:
                active._update(askers=active.askers + 1)
                return active
            waiting = sum(1 for j in self._active.values() if j.state == "queued")
            if waiting >= self.max_waiting:
                raise QueueFull(f"{waiting} fits are waiting; try again when one has finished")
            job = Job(model_id)
            self._jobs[job.id] = job
            self._active[model_id] = job
        job.future = self._pool.submit(self._run, job, work)
        return job

    def _run(self, job: Job, work) -> None:
        if job.cancel_requested:
            job._update(state="cancelled")
            return
        job._update(state="running")
        try:
            work(job)
        except Cancelled:
            job._update(state="cancelled")
        except BaseException as exc:  # one line for the client; the thread goes on serving
            message = page_words(str(exc).strip().splitlines()[0]) if str(exc).strip() else exc.__class__.__name__
            if isinstance(exc, MemoryError):
                message = "out of memory; use a smaller exemplar or fewer training patches"
            job._update(state="failed", error=message)
        else:
            job._update(state="done")
        finally:
            with self._lock:
                if self._active.get(job.model_id) is job:
                    del self._active[job.model_id]

    def get(self, job_id: str):
        """The job, or None (never made, or finished and dropped)."""
        with self._lock:
            self._prune()
            return self._jobs.get(job_id)

    def cancel(self, job_id: str, *, everyone: bool = False):
        """Withdraw one request for the job (``everyone``: all of them); the last to withdraw
        stops it (a queued one never starts). Returns the job or None."""
        job = self.get(job_id)
        if job is None or job.final or job.cancel_requested:
            return job
        with self._lock:  # with submit's count
            job._update(askers=0 if everyone else max(0, job.askers - 1))  # wakes the event streams
        if job.askers:  # another client still waits for this model: it goes on for them
            return job
        job.cancel_requested = True
        if job.on_cancel is not None:
            job.on_cancel()
        if job.future is not None and job.future.cancel():  # still waiting: it never runs
            job._update(state="cancelled")
            with self._lock:
                if self._active.get(job.model_id) is job:
                    del self._active[job.model_id]
        else:
            job._update()  # wake the event streams; the fit stops at its next progress call
        return job

    def shutdown(self) -> None:
        """Cancel every job and wait for the running ones to stop."""
        with self._lock:
            ids = list(self._jobs)
        for job_id in ids:
            self.cancel(job_id, everyone=True)
        self._pool.shutdown(wait=True, cancel_futures=True)
