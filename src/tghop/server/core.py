"""The state behind the web server's routes (:class:`Server`): the model cache, the fit queue,
the bound on generations and the thread pool they run on, and how a request's work is dropped
when its client goes away or the server stops; the JSON answers every route gives.

Generations run on a thread pool of their own (:attr:`Server.executor`, as many threads as
generations may run at once), not on Starlette's pool of 40 threads: fewer threads touching
big arrays keep fewer glibc malloc arenas (docs/serve.md: 20 clients peaked at 375-382 MiB
instead of 905-924 MiB). When the last generation, fit or decode running ends, the memory the C
allocator kept of it is given back to the system (:func:`release_memory`, :meth:`Server.working`): a
server left open after a few large images no longer holds their peak while idle (0.58).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import json
import threading
from concurrent.futures import ThreadPoolExecutor

from . import cooc
from .cache import DEFAULT_CACHE_BYTES, FillStates, ModelCache
from .jobs import FINAL, JOB_ID, FitQueue, GenerationJob
from .requests import RequestError, page_words

from .uploads import MAX_DECODES, MAX_DECODES_WAITING, Gate

__all__ = ["Server", "json_response", "error_response", "disconnected", "release_memory", "JOB_HEADER"]

#: The request header naming a generation's job (32 hex digits the client chose): its progress is then
#: ``GET /api/jobs/{job}`` (docs/serve.md, "Jobs").
JOB_HEADER = "X-Tghop-Job"


def error_response(status: int, message: str, headers: dict | None = None):
    """``{"error": message}`` (one line, in the page's words: :func:`~tghop.server.requests.page_words`) with
    ``status``."""
    from starlette.responses import JSONResponse

    return JSONResponse({"error": page_words(message)}, status_code=status, headers=headers)


def json_response(data, status: int = 200):
    """``data`` as JSON (what JSON cannot hold, as text; no NaN)."""
    from starlette.responses import Response

    return Response(json.dumps(data, default=str, allow_nan=False), status_code=status,
                    media_type="application/json")


#: glibc's ``malloc_trim``, once looked up (None: this C library has none).
_TRIM = {}


def release_memory() -> bool:
    """Give the memory the C allocator keeps after ``free`` back to the system, where it can: glibc's
    ``malloc_trim(0)`` (every thread's arena). False where the C library has no such call (macOS, Windows,
    musl): nothing is done.

    NumPy's arrays of a large generation (under glibc's mmap threshold, which grows to 32 MB as large
    blocks are freed) come from the allocator's heaps, one per thread that allocated them; once freed, the
    process kept most of them for good: an idle server held the peak of its largest images (docs/serve.md,
    "Memory of a long-running server").
    """
    if "call" not in _TRIM:
        import ctypes

        try:
            _TRIM["call"] = ctypes.CDLL(None).malloc_trim
        except (AttributeError, OSError, TypeError):  # no malloc_trim; Windows: no CDLL(None)
            _TRIM["call"] = None
    trim = _TRIM["call"]
    if trim is None:
        return False
    trim(0)
    return True


async def disconnected(request) -> None:
    """Return when the client of ``request`` (whose body has been read) disconnects."""
    while (await request.receive())["type"] != "http.disconnect":
        pass


class Server:
    """The state behind the routes: the cache, the fit queue, a bound on generations and one on
    uploads decoded and models read from disk at once (:attr:`decoding`, :class:`~tghop.server.uploads.Gate`)."""

    def __init__(self, cache_dir, max_fits: int, cache_bytes=DEFAULT_CACHE_BYTES, *, max_decodes: int = MAX_DECODES,
                 decodes_waiting: int = MAX_DECODES_WAITING):
        self.cache = ModelCache(cache_dir, cache_bytes)
        self.cooc = cooc.cooc_cache(cache_dir, cache_bytes)
        self.queue = FitQueue(max_fits)
        self.generating = threading.BoundedSemaphore(max_fits)
        # Generations (and their image reading and PNG encoding) run on threads of their own, as many as
        # may generate at once, not on Starlette's pool of 40: fewer threads touching big arrays, fewer
        # glibc malloc arenas holding freed memory (docs/serve.md).
        self.executor = ThreadPoolExecutor(max_workers=max_fits, thread_name_prefix="tghop-generate")
        # Uploads decoded or read at once (a fit's exemplar and maps, a model file, a checkpoint, a stored model
        # or checkpoint read for its summary), the rest waiting in order: each may take hundreds of MB, whatever
        # its file's size. On threads of their own, as generations: on Starlette's pool each new thread kept its freed
        # memory (8 decodes of an 8000x8000 PNG, 2 at a time, peaked at 2.3 GB there). Fills, painted guides
        # and labels are decoded on the generation threads, bounded by them; a model or checkpoint a generation
        # needs from disk is read here too, in its turn, before the generation takes a thread (:meth:`_read_first`).
        self.decoding = Gate(max_decodes, decodes_waiting, what="uploads or models are being read")
        self.decoder = ThreadPoolExecutor(max_workers=max_decodes, thread_name_prefix="tghop-decode")
        self.stopping = asyncio.Event()
        # Generations, fits and decodes running now (:meth:`working`); the times the memory was given back.
        self._working, self.releases = 0, 0
        self._working_lock = threading.Lock()
        # The running request's flags on its thread: .dropped, .job and .read on a generation thread
        # (unless_stopping, model), .left on a decoding thread (still_wanted)
        self._work = threading.local()
        # Where a fill's sequence of the same request stands (cache.FillStates: fill k of a seed, as tghop
        # inpaint --count draws it, goes on from fill k - 1's generator, not from the seed again)
        self.fill_states = FillStates()

    async def decode(self, request, work, *args):
        """``work(*args)`` on a decoding thread once :attr:`decoding` lets it in (503 when too many wait); a request
        whose client goes away while it waits leaves the queue, never decoded, and so does one whose client has
        gone when its turn comes. Decoding cannot be stopped midway: a request whose client goes away while it
        is decoded has its result dropped (no fit queued; an upload kept only if :meth:`still_wanted` says so
        before it is). All three: 499, to nobody."""
        await self.decoding.enter(gone=functools.partial(disconnected, request))
        left = threading.Event()
        gone = asyncio.ensure_future(disconnected(request))
        gone.add_done_callback(lambda task: task.cancelled() or left.set())
        try:
            await asyncio.sleep(0)  # a disconnect the server already knows of ends `gone` here
            if gone.done():
                raise RequestError(499, "the client went away before its upload was decoded; it was dropped")
            result = await asyncio.get_running_loop().run_in_executor(
                self.decoder, functools.partial(self._decoding, left, work, *args))
            if gone.done():
                raise RequestError(499, "the client went away while its upload was decoded; the result was dropped")
            return result
        finally:
            gone.cancel()
            await self.decoding.__aexit__(None, None, None)

    def _decoding(self, left, work, *args):
        """``work(*args)`` with ``left`` (set once the request's client goes away) as this thread's for
        :meth:`still_wanted`."""
        self._work.left = left
        try:
            with self.working():
                return work(*args)
        finally:
            self._work.left = None

    @contextlib.contextmanager
    def working(self):
        """Context manager around a generation's, a fit's or a decode's work (on its thread): when the last of
        them running ends, the memory the C allocator kept of their arrays is given back to the system
        (:func:`release_memory`; :attr:`releases` counts the times). Not while another still runs: its next
        arrays would take the pages back at once."""
        with self._working_lock:
            self._working += 1
        try:
            yield
        finally:
            with self._working_lock:
                self._working -= 1
                idle = not self._working
                if idle:
                    self.releases += 1
            if idle:
                release_memory()

    def still_wanted(self) -> bool:
        """On a decoding thread (:meth:`decode`): whether the request's client is still there, so that what it
        decoded is worth keeping (an upload is not kept once its client has gone). True elsewhere."""
        left = getattr(self._work, "left", None)
        return left is None or not left.is_set()

    def model(self, model_id: str):
        """The model ``model_id`` for a generation (on its thread, :meth:`in_executor`): read before the generation
        took its thread (``in_executor(models=)``, :meth:`_read_first`). Outside a request's work, read here."""
        return self._read_before(self.cache, model_id)

    def checkpoint(self, cid: str):
        """The co-occurrence checkpoint ``cid`` for a generation, read before it as :meth:`model` reads a model
        (``in_executor(checkpoints=)``)."""
        return self._read_before(self.cooc, cid)

    def _read_before(self, cache, key: str):
        read = getattr(self._work, "read", None)
        if read is None:  # not a request's work (a script's call): read here, in no turn
            return cache.load(key)
        try:
            return read[cache, key]
        except KeyError:  # a route that did not name it: it would read it outside the turn
            raise RuntimeError(f"{cache.what} {key} was not read before its generation; name it in "
                               "in_executor's models or checkpoints") from None

    async def _read_first(self, needs, ended: asyncio.Event):
        """``{(cache, id): model}`` of ``needs`` (``(cache, id)`` pairs: models and checkpoints a generation
        needs), on the event loop before the generation takes a thread: one in memory as it is; one another
        request is reading, once that read ends (its error too); one neither, read on a decoding thread in
        its turn of :attr:`decoding` (503 when too many wait; 404 when its file is not there). Waiting holds
        no thread. None as soon as ``ended`` is set (its client gone, its job cancelled, the server
        stopping): a wait is withdrawn, its place goes to the next. A read cannot be stopped midway: it ends,
        and its model stays in memory for the next."""
        loop = asyncio.get_running_loop()
        read = {}
        for cache, key in needs:
            if (cache, key) in read:
                continue
            model, loading = cache.in_memory(key)
            if loading is not None:  # another request reads it: its read, shared
                shared = asyncio.wrap_future(loading)
                shared.add_done_callback(lambda future: future.cancelled() or future.exception())  # seen, if left
                if not await _first(shared, ended):
                    return None
                model = shared.result()
            if model is None:
                if not cache.has(key):  # no turn to wait for a 404
                    raise cache.missing(key)
                try:
                    await self.decoding.enter(gone=ended.wait)
                except RequestError as exc:
                    if exc.status == 499:  # withdrawn while it waited
                        return None
                    raise
                try:
                    if ended.is_set():
                        return None
                    model = await loop.run_in_executor(self.decoder, cache.load, key)
                finally:
                    self.decoding.leave()
            read[cache, key] = model
        return None if ended.is_set() else read

    def stop(self) -> None:
        """The server is stopping (``tghop serve``'s Ctrl-C; call it on the event loop):
        requests waiting for a generation answer 503 at once and event streams end, so that
        uvicorn's graceful shutdown finds no request to cancel (a cancelled one was logged
        with a traceback, and its client got a text 500)."""
        self.stopping.set()

    def unless_stopping(self, stage=None, done=0, total=0) -> None:
        """A generation's progress callback: stops it (to nobody: :meth:`in_executor` has answered)
        once its client went away or the server stops: no thread or process waits for it. A generation
        with a job (:data:`JOB_HEADER`) reports its progress there, and stops once the job is cancelled."""
        dropped = getattr(self._work, "dropped", None)
        if self.stopping.is_set() or (dropped is not None and dropped.is_set()):
            raise RequestError(503, "the work was dropped")
        job = getattr(self._work, "job", None)
        if job is not None and stage is not None:
            if job.cancel_requested:
                raise RequestError(409, f"the generation was cancelled (DELETE /api/jobs/{job.id})")
            job.progress(stage, done, total, cancellable=False)

    def _flagged(self, dropped, job, read, work, *args):
        """``work(*args)`` with ``dropped`` and ``job`` (or None) as this thread's for :meth:`unless_stopping`,
        ``read`` (:meth:`_read_first`'s) for :meth:`model` and :meth:`checkpoint`; the job's state follows
        the work."""
        self._work.dropped, self._work.job, self._work.read = dropped, job, read
        try:
            if job is not None:
                self.unless_stopping()  # dropped or cancelled while it waited: it never starts
                if job.cancel_requested:
                    raise RequestError(409, f"the generation was cancelled (DELETE /api/jobs/{job.id})")
                job.set_state("running")
            with self.working():
                result = work(*args)
        except BaseException as exc:
            self._job_ended(job, exc, dropped.is_set())
            raise
        else:
            if job is not None and not job.final:
                job.set_state("done")
            return result
        finally:
            self._work.dropped = self._work.job = self._work.read = None

    def _job_ended(self, job, exc: BaseException, dropped: bool) -> None:
        """A generation's job ended by ``exc``: cancelled (asked to, dropped, the server stopping) or failed."""
        if job is None or job.final:
            return
        if job.cancel_requested or dropped or self.stopping.is_set() or isinstance(exc, asyncio.CancelledError):
            job.set_state("cancelled")
        else:
            said = getattr(exc, "message", None) or str(exc) or type(exc).__name__
            job.set_state("failed", error=page_words(said))

    def generation_job(self, request):
        """The job of a request that names one (:data:`JOB_HEADER`), put in the job table; None without
        the header. 400 for a malformed id, 409 for one in use."""
        job_id = request.headers.get(JOB_HEADER)
        if job_id is None:
            return None
        job_id = job_id.strip().lower()
        if not JOB_ID.match(job_id):
            raise RequestError(400, f"{JOB_HEADER} must be 32 hex digits (a new id for this generation's "
                                    f"progress), got {job_id[:40]!r}")
        job = GenerationJob(request.path_params.get("id"), job_id)
        if not self.queue.add(job):
            raise RequestError(409, f"{JOB_HEADER} {job_id} is in use; choose a new id for each generation")
        return job

    async def in_executor(self, request, work, *args, models=(), checkpoints=()):
        """``work(*args)`` on a generation thread (:attr:`executor`) once the ``models`` and ``checkpoints``
        (ids) it needs are read (:meth:`_read_first`: in the turn of :attr:`decoding`, holding no generation
        thread while they wait or are read; :meth:`model` and :meth:`checkpoint` give them to the work).
        Dropped if the client of ``request`` goes away first (a page's Stop or reload): still waiting, it never
        runs; running, it stops at its next progress report; then 499. Dropped the same way when the server
        stops (:meth:`stop`): 503. A request with a job (:data:`JOB_HEADER`, :meth:`generation_job`) reports
        its progress there; the job cancelled (``DELETE /api/jobs/{job}``) while it waits, it leaves the queue
        at once, running at its next progress report: 409."""
        job = self.generation_job(request)
        loop = asyncio.get_running_loop()
        dropped, ended = threading.Event(), asyncio.Event()
        gone = asyncio.ensure_future(disconnected(request))
        stopped = asyncio.ensure_future(self.stopping.wait())
        watched = [gone, stopped]
        if job is not None:
            withdrawn = asyncio.Event()
            job.on_cancel = functools.partial(_soon, loop, withdrawn.set)
            watched.append(asyncio.ensure_future(withdrawn.wait()))
        for end in watched:
            end.add_done_callback(lambda task: task.cancelled() or ended.set())
        try:
            needs = [(self.cache, m) for m in models] + [(self.cooc, c) for c in checkpoints]
            try:
                read = await self._read_first(needs, ended)
            except BaseException as exc:
                self._job_ended(job, exc, ended.is_set())
                raise
            if read is None:
                raise self._dropped(job, gone)
            submitted = self.executor.submit(self._flagged, dropped, job, read, work, *args)
            future, ends = asyncio.wrap_future(submitted), set(watched)
            while True:
                await asyncio.wait({future, *ends}, return_when=asyncio.FIRST_COMPLETED)
                if future.done():
                    return future.result()
                if gone.done() or stopped.done() or submitted.cancel():  # cancelled still waiting: it never runs
                    break
                ends = {gone, stopped}  # cancelled while it runs: it stops at its next progress report (409)
            dropped.set()
            future.cancel()
            raise self._dropped(job, gone)
        finally:
            gone.cancel()
            stopped.cancel()
            for end in watched:
                end.cancel()
            if job is not None:
                job.on_cancel = None

    def _dropped(self, job, gone) -> RequestError:
        """The answer of a generation dropped before its work ended, its job (if any) cancelled: 499 (its client
        gone, to nobody), 503 (the server stopping) or 409 (its job cancelled through ``DELETE``)."""
        if job is not None and job.state not in FINAL:
            job.set_state("cancelled")
        if gone.done():
            return RequestError(499, "the client went away; its work was dropped")
        if self.stopping.is_set():
            return RequestError(503, "the server is stopping; the work was dropped (try again when it is back)")
        return RequestError(409, f"the generation was cancelled (DELETE /api/jobs/{job.id if job else ''})")


async def _first(future, ended: asyncio.Event) -> bool:
    """Whether ``future`` is done before ``ended`` is set (neither is cancelled)."""
    ending = asyncio.ensure_future(ended.wait())
    try:
        await asyncio.wait({future, ending}, return_when=asyncio.FIRST_COMPLETED)
    finally:
        ending.cancel()
    return future.done() and not ended.is_set()


def _soon(loop, callback) -> None:
    """``callback()`` on ``loop`` (from any thread); nothing once the loop has closed (the server stopped)."""
    try:
        loop.call_soon_threadsafe(callback)
    except RuntimeError:
        pass
