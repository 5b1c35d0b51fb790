"""The state behind the web server's routes (:class:`Server`): the model cache, the fit queue,
the bound on generations and the thread pool they run on, and how a request's work is dropped
when its client goes away or the server stops; the JSON answers every route gives.

Generations run on a thread pool of their own (:attr:`Server.executor`, as many threads as
generations may run at once), not on Starlette's pool of 40 threads: fewer threads touching
big arrays keep fewer glibc malloc arenas (docs/serve.md: 20 clients peaked at 375-382 MiB
instead of 905-924 MiB).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import functools
import json
import threading
from concurrent.futures import ThreadPoolExecutor

from . import cooc
from .cache import DEFAULT_CACHE_BYTES, ModelCache
from .jobs import FINAL, JOB_ID, FitQueue, GenerationJob
from .requests import RequestError
from .uploads import MAX_DECODES, MAX_DECODES_WAITING, Gate

__all__ = ["Server", "json_response", "error_response", "disconnected", "JOB_HEADER"]

#: The request header naming a generation's job (32 hex digits the client chose): its progress is then
#: ``GET /api/jobs/{job}`` (docs/serve.md, "Jobs").
JOB_HEADER = "X-Tghop-Job"


def error_response(status: int, message: str, headers: dict | None = None):
    """``{"error": message}`` (one line) with ``status``."""
    from starlette.responses import JSONResponse

    return JSONResponse({"error": " ".join(str(message).split())}, status_code=status, headers=headers)


def json_response(data, status: int = 200):
    """``data`` as JSON (what JSON cannot hold, as text; no NaN)."""
    from starlette.responses import Response

    return Response(json.dumps(data, default=str, allow_nan=False), status_code=status,
                    media_type="application/json")


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
        # reads from disk takes a turn here too (:meth:`model`).
        self.decoding = Gate(max_decodes, decodes_waiting, what="uploads or models are being read")
        self.decoder = ThreadPoolExecutor(max_workers=max_decodes, thread_name_prefix="tghop-decode")
        self.stopping = asyncio.Event()
        # The running request's flags on its thread: .dropped, .job, .loop and .withdrawn on a generation thread
        # (unless_stopping, reading_turn), .left on a decoding thread (still_wanted)
        self._work = threading.local()

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
            return work(*args)
        finally:
            self._work.left = None

    def still_wanted(self) -> bool:
        """On a decoding thread (:meth:`decode`): whether the request's client is still there, so that what it
        decoded is worth keeping (an upload is not kept once its client has gone). True elsewhere."""
        left = getattr(self._work, "left", None)
        return left is None or not left.is_set()

    def model(self, model_id: str):
        """The model ``model_id`` for a generation (on its thread, :meth:`in_executor`): one not in memory is
        read from disk in the turn of uploads decoded at once (:attr:`decoding`; 503 with ``Retry-After`` when
        too many wait; dropped when the request's client goes away meanwhile), so that generations of many
        models not in memory do not read them all at once."""
        return self.cache.load(model_id, turn=self.reading_turn)

    def checkpoint(self, cid: str):
        """The co-occurrence checkpoint ``cid`` for a generation, read in its turn as :meth:`model` reads a model."""
        return self.cooc.load(cid, turn=self.reading_turn)

    @contextlib.contextmanager
    def reading_turn(self):
        """A slot of :attr:`decoding` held by a generation thread (:meth:`in_executor`'s) while it reads a file:
        waited for on the event loop, in order with the uploads; 503 when too many wait, 499 once the request's
        work is dropped (its client gone, the server stopping). Outside a request's work, no slot is taken."""
        loop, withdrawn = getattr(self._work, "loop", None), getattr(self._work, "withdrawn", None)
        if loop is None:
            yield
            return
        entered = asyncio.run_coroutine_threadsafe(self.decoding.enter(gone=withdrawn.wait), loop)
        while True:  # the loop answers once the slot is taken, refused or withdrawn (in_executor sets withdrawn)
            try:
                entered.result(timeout=1.0)
                break
            except concurrent.futures.TimeoutError:
                if loop.is_closed():  # no loop left to answer: the server has stopped
                    raise RequestError(503, "the server is stopping; the work was dropped") from None
        try:
            yield
        finally:
            try:
                loop.call_soon_threadsafe(self.decoding.leave)
            except RuntimeError:  # the loop closed meanwhile: the server has stopped, its gate with it
                pass

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

    def _flagged(self, dropped, job, turn, work, *args):
        """``work(*args)`` with ``dropped`` and ``job`` (or None) as this thread's for :meth:`unless_stopping`,
        ``turn`` (the event loop, and the asyncio event set when the work is dropped) for :meth:`reading_turn`;
        the job's state follows the work."""
        self._work.dropped, self._work.job = dropped, job
        self._work.loop, self._work.withdrawn = turn
        try:
            if job is not None:
                self.unless_stopping()  # dropped or cancelled while it waited: it never starts
                if job.cancel_requested:
                    raise RequestError(409, f"the generation was cancelled (DELETE /api/jobs/{job.id})")
                job.set_state("running")
            result = work(*args)
        except BaseException as exc:
            if job is not None and not job.final:
                if job.cancel_requested or dropped.is_set() or self.stopping.is_set():
                    job.set_state("cancelled")
                else:
                    job.set_state("failed", error=getattr(exc, "message", None) or str(exc) or type(exc).__name__)
            raise
        else:
            if job is not None and not job.final:
                job.set_state("done")
            return result
        finally:
            self._work.dropped = self._work.job = self._work.loop = self._work.withdrawn = None

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

    async def in_executor(self, request, work, *args):
        """``work(*args)`` on a generation thread (:attr:`executor`), dropped if the client of ``request``
        goes away first (a page's Stop or reload): still waiting, it never runs; running, it stops at its
        next progress report; then 499. Dropped the same way when the server stops (:meth:`stop`): 503.
        A request with a job (:data:`JOB_HEADER`, :meth:`generation_job`) reports its progress there."""
        job = self.generation_job(request)
        dropped, withdrawn = threading.Event(), asyncio.Event()  # withdrawn: its wait for a reading turn ends
        loop = asyncio.get_running_loop()
        future = loop.run_in_executor(
            self.executor, functools.partial(self._flagged, dropped, job, (loop, withdrawn), work, *args))
        gone = asyncio.ensure_future(disconnected(request))
        stopped = asyncio.ensure_future(self.stopping.wait())
        try:
            await asyncio.wait({future, gone, stopped}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            gone.cancel()
            stopped.cancel()
        if not future.done():
            dropped.set()
            withdrawn.set()
            future.cancel()
            if job is not None and job.state not in FINAL:
                job.set_state("cancelled")
            if not gone.done() and self.stopping.is_set():
                raise RequestError(503, "the server is stopping; the work was dropped (try again when it is back)")
            raise RequestError(499, "the client went away; its work was dropped")
        return future.result()
