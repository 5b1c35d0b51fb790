"""The web server's Starlette application: the page, the HTTP API under ``/api`` and the
model cache (see docs/serve.md for the API).

The cache (:class:`tghop.server.cache.ModelCache`) is a folder, ``<cache>/models``, of model files named
``<id>.npz`` (and ``<cache>/cooc`` of co-occurrence checkpoints, ``<id>.pt``: :mod:`tghop.server.cooc`). An id
is a content hash (SHA-256 of the exemplar's bytes and the fit settings, or of an uploaded model file), so the
same exemplar with the same settings is fitted once. Every file appears whole or not at all
(:func:`tghop.modelfile.save_model` writes atomically; an upload is checked in a temporary file that is removed
whatever happens); leftovers of a killed server (``.*.tmp``) are removed at start. The folder is bounded
(``max_bytes``, ``tghop serve --cache-size``): when a new model makes it larger, the least recently used model
files go (a file's modification time is its last use: set when it is written, loaded, generated from or
downloaded), never the one just added; a client then gets 404 for a model that went and fits it again.

Everything tghop does here is the library's own code: :func:`tghop.imageio.load_image`
(with its pixel limit), :class:`tghop.TGHop` (fit with a progress callback, synthesize),
:func:`tghop.inpaint.inpaint`, :func:`tghop.synthesize_guided` and :func:`tghop.morph` (several
models; their JSON is checked by :mod:`tghop.server.requests`), :func:`tghop.modelfile.save_model` /
:func:`~tghop.modelfile.load_model` (with their checks of a file). Bad input is answered with
one line, ``{"error": "..."}``, and a status code: 400 (not an image, a decompression bomb, a
corrupt model, a malformed request), 404 (no such model or job), 413 (over 50 MB or over the exemplar pixel limit),
422 (a setting out of range, a size over the output limit), 501 (a co-occurrence route
without PyTorch), 503 (too many fits waiting); a generation whose client has gone away is
dropped, also while it runs (:meth:`Server.in_executor`; 499, to nobody), and so is a request
whose client goes away before it has sent the whole body (:func:`read_body`).

Generations run on a thread pool of their own (:attr:`Server.executor`, as many threads as
generations may run at once), not on Starlette's pool of 40 threads: fewer threads touching
big arrays keep fewer glibc malloc arenas (docs/serve.md: 20 clients peaked at 375-382 MiB
instead of 905-924 MiB).
"""

from __future__ import annotations

import asyncio
import functools
import hashlib
import io
import json
import os
import re
import secrets
import tempfile
import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from contextlib import asynccontextmanager
from pathlib import Path

from .._errors import ImageTooLargeError, MissingExtraError, TGHopError
from . import cooc, materials
from .cache import DEFAULT_CACHE_BYTES, ModelCache
from .jobs import FINAL, FitQueue, QueueFull
from .requests import (RequestError, check_channel_counts, check_multipart_end, fit_fields, http_headers, http_message,
                       parse_bool, parse_fit_settings, parse_generation, parse_growth, parse_guided, parse_morph,
                       safe_name)
from .safety import LocalOnly, allowed_hosts

try:  # the web extra; create_app says how to install it when it is missing
    from starlette.applications import Starlette
    from starlette.concurrency import run_in_threadpool
    from starlette.exceptions import HTTPException
    from starlette.formparsers import MultiPartException, MultiPartParser
    from starlette.requests import ClientDisconnect
    from starlette.responses import FileResponse, JSONResponse, Response, StreamingResponse
    from starlette.routing import Mount, Route
    from starlette.staticfiles import StaticFiles
except ImportError:  # pragma: no cover - tested by the missing-extra test in a fresh interpreter
    Starlette = None

__all__ = ["create_app", "require_web", "WEB_HINT", "MAX_UPLOAD_BYTES", "MAX_FIT_BYTES", "STATIC", "model_id_for",
           "ModelCache", "DEFAULT_CACHE_BYTES"]

#: How to install what the server needs.
WEB_HINT = "pip install 'tghop[web]'"
#: Largest request body accepted (an exemplar or a model file).
MAX_UPLOAD_BYTES = 50 * 1024 * 1024
#: Largest body of a fit (``POST /api/models``), an inpaint or an extend: a material's albedo and maps
#: together, each file still at most MAX_UPLOAD_BYTES (a 2K set with a 16-bit normal map is about 40 MB).
MAX_FIT_BYTES = 4 * MAX_UPLOAD_BYTES
#: The page's files.
STATIC = Path(__file__).resolve().parent / "static"
_JOB = re.compile(r"[0-9a-f]{32}\Z")
#: An upload over the limit is read (and dropped) up to this many times the limit, then the
#: connection is closed.
_DRAIN = 4


def require_web(*, server: bool = False):
    """Raise a one-line :class:`MissingExtraError` unless Starlette and python-multipart (and,
    with ``server``, uvicorn) are installed."""
    import importlib.util

    def present(name):
        try:
            return importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # a module set to None in sys.modules
            return False

    if (Starlette is None or not any(present(m) for m in ("python_multipart", "multipart"))
            or (server and not present("uvicorn"))):
        raise MissingExtraError(f"tghop serve needs Starlette, uvicorn and python-multipart; "
                                f"install them with: {WEB_HINT}")


def _error(status: int, message: str):
    return JSONResponse({"error": " ".join(str(message).split())}, status_code=status)


def _json(data, status: int = 200):
    return Response(json.dumps(data, default=str, allow_nan=False), status_code=status,
                    media_type="application/json")


def model_id_for(content: bytes, settings: dict) -> str:
    """The content hash naming a model: SHA-256 of the exemplar's bytes (or ``builtin:NAME``)
    and the fit settings (as sorted JSON)."""
    digest = hashlib.sha256(content)
    digest.update(b"\0tghop-fit-settings\0")
    digest.update(json.dumps(settings, sort_keys=True, default=str).encode())
    return digest.hexdigest()


# ------------------------------------------------------------------ requests
async def read_body(request, limit: int = MAX_UPLOAD_BYTES, *, what: str = "the upload") -> bytes:
    """The request's body, or 413 as soon as it is over ``limit`` bytes (``what``: the message's
    words for it); 499 (to nobody) when the client goes away before it has sent the whole body."""
    too_large = RequestError(413, f"{what} is over the limit of {limit // (1024 * 1024)} MB; "
                                  "send a smaller file")
    declared = request.headers.get("content-length")
    over = bool(declared and declared.isdigit() and int(declared) > limit)
    chunks, n = [], 0
    try:
        async for chunk in request.stream():
            n += len(chunk)
            if n > limit:
                over = True
            if over:  # the rest is read and dropped, so that the client gets the answer and not a reset
                chunks = []
                if n > _DRAIN * limit:
                    break
                continue
            chunks.append(chunk)
    except ClientDisconnect:  # not the server's error: no traceback, and the answer goes nowhere
        raise RequestError(499, "the client went away before it sent the whole body") from None
    if over:
        raise too_large
    return b"".join(chunks)


async def read_form(request, body: bytes, fields: str = "a form with an 'image' file or a 'builtin' name") -> dict:
    """A multipart body -> ``{name: str or (filename, bytes)}`` (400 when malformed; when it
    is not multipart, the message says to send ``fields``, what the route takes)."""
    async def stream():
        yield body

    if not request.headers.get("content-type", "").startswith("multipart/form-data"):
        raise RequestError(400, f"send the fields as multipart/form-data ({fields})")
    check_multipart_end(request.headers["content-type"], body)
    try:
        form = await MultiPartParser(request.headers, stream(), max_files=4 + materials.MAX_MAPS,
                                     max_fields=64).parse()
    except (MultiPartException, ValueError) as exc:
        raise RequestError(400, f"malformed multipart request ({getattr(exc, 'message', exc)})") from None
    out, twice = {}, []
    for name, value in form.multi_items():
        if name in out:
            twice.append(name)
        if hasattr(value, "read"):
            out[name] = (value.filename, await value.read())
            await value.close()
        else:
            out[name] = value
    if twice:  # which one counts would be a guess
        raise RequestError(400, f"the field {twice[0][:40]!r} is given twice; send it once")
    return out


def each_file_within(fields: dict) -> dict:
    """``fields`` (:func:`read_form`'s) once each file is at most :data:`MAX_UPLOAD_BYTES` (a body
    of several files may be up to :data:`MAX_FIT_BYTES`); else 413 naming the file."""
    for value in fields.values():
        if isinstance(value, tuple) and len(value[1]) > MAX_UPLOAD_BYTES:
            raise RequestError(413, f"{safe_name(value[0], 'a file')} is over the limit of "
                                    f"{MAX_UPLOAD_BYTES // (1024 * 1024)} MB a file; send a smaller file")
    return fields


class Server:
    """The state behind the routes: the cache, the fit queue, a bound on generations."""

    def __init__(self, cache_dir, max_fits: int, cache_bytes=DEFAULT_CACHE_BYTES):
        self.cache = ModelCache(cache_dir, cache_bytes)
        self.cooc = cooc.cooc_cache(cache_dir, cache_bytes)
        self.queue = FitQueue(max_fits)
        self.generating = threading.BoundedSemaphore(max_fits)
        # Generations (and their image reading and PNG encoding) run on threads of their own, as many as
        # may generate at once, not on Starlette's pool of 40: fewer threads touching big arrays, fewer
        # glibc malloc arenas holding freed memory (docs/serve.md).
        self.executor = ThreadPoolExecutor(max_workers=max_fits, thread_name_prefix="tghop-generate")
        self.stopping = asyncio.Event()
        self._work = threading.local()  # .dropped: the running request's flag, on its generation thread

    def stop(self) -> None:
        """The server is stopping (``tghop serve``'s Ctrl-C; call it on the event loop):
        requests waiting for a generation answer 503 at once and event streams end, so that
        uvicorn's graceful shutdown finds no request to cancel (a cancelled one was logged
        with a traceback, and its client got a text 500)."""
        self.stopping.set()

    def unless_stopping(self, stage=None, done=0, total=0) -> None:
        """A generation's progress callback: stops it (to nobody: :meth:`in_executor` has answered)
        once its client went away or the server stops: no thread or process waits for it."""
        dropped = getattr(self._work, "dropped", None)
        if self.stopping.is_set() or (dropped is not None and dropped.is_set()):
            raise RequestError(503, "the work was dropped")

    def _flagged(self, dropped, work, *args):
        """``work(*args)`` with ``dropped`` as this thread's flag for :meth:`unless_stopping`."""
        self._work.dropped = dropped
        try:
            return work(*args)
        finally:
            self._work.dropped = None

    async def in_executor(self, request, work, *args):
        """``work(*args)`` on a generation thread (:attr:`executor`), dropped if the client of ``request``
        goes away first (a page's Stop or reload): still waiting, it never runs; running, it stops at its
        next progress report; then 499. Dropped the same way when the server stops (:meth:`stop`): 503."""
        dropped = threading.Event()
        future = asyncio.get_running_loop().run_in_executor(
            self.executor, functools.partial(self._flagged, dropped, work, *args))
        gone = asyncio.ensure_future(_disconnected(request))
        stopped = asyncio.ensure_future(self.stopping.wait())
        try:
            await asyncio.wait({future, gone, stopped}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            gone.cancel()
            stopped.cancel()
        if not future.done():
            dropped.set()
            future.cancel()
            if not gone.done() and self.stopping.is_set():
                raise RequestError(503, "the server is stopping; the work was dropped (try again when it is back)")
            raise RequestError(499, "the client went away; its work was dropped")
        return future.result()

    # ---------------------------------------------------------------- fitting
    def prepare_fit(self, fields: dict):
        """Check the request and read the exemplar, and the maps of a material (fields ``map:<name>``;
        :mod:`tghop.server.materials`), in a worker thread: returns ``(model id, fit)``, ``fit(progress)``
        fitting the model (a TGHop, or with maps a Material); ``fit`` is None when the model is in the cache."""
        from .._errors import HINT_DOWNSCALE_YOURSELF
        from ..data import builtin
        from ..fit_options import build_model, fit_params, material_model
        from ..imageio import load_image
        from ..material import Material
        from ..synthesis import prepare_exemplar

        def read(path):
            return load_image(path, dtype=None, too_large_hint=HINT_DOWNSCALE_YOURSELF, with_depth=True)

        upload = fields.pop("image", None)
        name = fields.pop("builtin", None)
        if isinstance(upload, str):
            raise RequestError(400, "the field 'image' must be a file upload")
        if isinstance(name, tuple):
            raise RequestError(400, "the field 'builtin' must be a plain field naming a built-in exemplar "
                                    "(bricks or cells), not a file; send a file as 'image'")
        if upload is not None and name:
            raise RequestError(400, "give either an 'image' file or a 'builtin' name, not both")
        if upload is None and not name:
            raise RequestError(400, "no exemplar: send an 'image' file or a 'builtin' name (bricks or cells)")
        uploads = materials.map_uploads(fields)  # before the settings: they are not settings
        options = parse_fit_settings(fields)
        depth = 8
        if name:
            name = str(name).removeprefix("builtin:")
            try:
                image, content = builtin(name), f"builtin:{name}".encode()
            except TGHopError as exc:
                raise RequestError(400, str(exc)) from None
        else:
            filename, content = upload
            if not content:
                raise RequestError(400, f"{safe_name(filename, 'the upload')} is empty; send an image file")
            image, depth = self._read_image(content, safe_name(filename, "exemplar"), read)
        try:
            image = prepare_exemplar(image)
            model = build_model(options, n_colours=image.shape[2], api=True)
        except TGHopError as exc:
            raise RequestError(400, str(exc)) from None
        if not uploads:  # a channel count out of the image's range: 422 before a job (a material's: its maps')
            check_channel_counts(model, image.shape[2])
        try:
            model.check_exemplar_size(image.shape)  # the smallest exemplar that works, before a job starts
        except TGHopError as exc:
            raise RequestError(400, str(exc)) from None
        params = {k: v for k, v in model.get_params().items()}
        if uploads:
            maps, depths = materials.read_maps(
                uploads, lambda data, filename: self._read_image(data, filename, read), image.shape)
            joint = material_model(fit_params(options, api=True))  # channels for the maps too, as fit --maps
            materials.check_channels(joint, image, maps)
            model_id = materials.material_id(content, uploads, joint.get_params(), model_id_for)

            def fit(progress):
                return Material(model=joint).fit(image, maps, depths={"albedo": depth, **depths}, progress=progress)
        else:
            model_id = model_id_for(content, params)

            def fit(progress):
                return model.fit(image, progress=progress)
        return model_id, (None if self.cache.has(model_id) else fit)

    @staticmethod
    def _read_image(content: bytes, filename: str, load):
        with tempfile.TemporaryDirectory(prefix="tghop-upload-") as folder:
            path = Path(folder) / filename
            path.write_bytes(content)
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # an alpha channel dropped: not an error
                    return load(path)
            except ImageTooLargeError as exc:
                raise RequestError(413, str(exc).replace(f"{folder}{os.sep}", "")) from None
            except TGHopError as exc:
                raise RequestError(400, str(exc).replace(f"{folder}{os.sep}", "")) from None
            except MemoryError:
                raise RequestError(413, f"{filename}: not enough memory to decode this image; "
                                        "downscale it first") from None

    def fit_work(self, model_id: str, fit):
        """What a fit job runs: ``fit(progress)``, then save atomically into the cache."""
        from ..modelfile import save_model

        def work(job):
            model = fit(job.progress)
            job.progress("saving", 0, 1)  # the last point where a cancel stops the fit
            save_model(model, self.cache.path(model_id))
            self.cache.added(model_id, model)
            job.progress("saving", 1, 1, cancellable=False)  # the file is there: the job is done

        return work

    async def create_model(self, request):
        body = await read_body(request, MAX_FIT_BYTES, what="the upload (the exemplar and its maps together)")
        fields = each_file_within(await read_form(request, body))
        model_id, fit = await run_in_threadpool(self.prepare_fit, fields)
        if fit is None:
            self.cache.touch(model_id)
            job = self.queue.finished(model_id)
        else:
            try:
                job = self.queue.submit(model_id, self.fit_work(model_id, fit))
            except QueueFull as exc:
                raise RequestError(503, f"the server is busy: {exc}") from None
        return _json({"id": model_id, "job": job.id, "state": job.state}, status=202 if not job.final else 200)

    # ---------------------------------------------------------------- jobs
    def job(self, request):
        job_id = request.path_params["job"]
        job = self.queue.get(job_id) if _JOB.match(job_id) else None
        if job is None:
            raise RequestError(404, f"no job {job_id[:80]!r}; POST /api/models starts one")
        return job

    async def job_state(self, request):
        return _json(self.job(request).snapshot())

    async def cancel_job(self, request):
        job = self.queue.cancel(self.job(request).id)
        return _json(job.snapshot())

    async def job_events(self, request):
        job = self.job(request)

        async def events():
            version, idle = -1, 0.0
            while True:
                snap = job.snapshot()
                if snap["version"] != version:
                    version, idle = snap["version"], 0.0
                    yield f"event: progress\ndata: {json.dumps(snap)}\n\n"
                if snap["state"] in FINAL:  # the snapshot's state, not the job's now: the end event says it
                    yield f"event: end\ndata: {json.dumps(snap)}\n\n"
                    return
                if self.stopping.is_set():  # the server is stopping (its fits are cancelled): the stream ends
                    return
                if idle >= 15.0:  # a comment now and then keeps proxies from closing the stream
                    idle = 0.0
                    yield ": waiting\n\n"
                await asyncio.sleep(0.1)
                idle += 0.1

        return StreamingResponse(events(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})

    # ---------------------------------------------------------------- models
    def _summary(self, model_id: str) -> dict:
        from ..modelfile import info_dict

        loaded = self.cache.load(model_id)
        model = getattr(loaded, "model_", loaded)  # a material's joint model
        return {"id": model_id, "file_bytes": self.cache.path(model_id).stat().st_size,
                "layout": model.layout_ is not None, **info_dict(model),
                **({"material": {"maps": loaded.map_info()}} if model is not loaded else {})}

    async def model_summary(self, request):
        return _json(await run_in_threadpool(self._summary, request.path_params["id"]))

    @staticmethod
    def _file(cache, file_id: str, missing: str):
        """The file ``file_id`` of ``cache`` as a download (404 with ``missing`` if none)."""
        path = cache.path(file_id)
        if not path.is_file():
            raise RequestError(404, missing)
        cache.touch(file_id)
        return FileResponse(path, media_type="application/octet-stream",
                            filename=f"tghop-{file_id[:12]}{path.suffix}")

    async def model_file(self, request):
        model_id = request.path_params["id"]
        return self._file(self.cache, model_id, f"no model {model_id}; fit one with POST /api/models")

    def _store_upload(self, content: bytes, filename: str) -> str:
        """Check an uploaded model file and keep it under its content hash (400 if it is not
        a good tghop model; nothing is left in the cache either way)."""
        from ..imageio import is_image

        try:
            return self.cache.store(content, filename, hint="send a model file written by 'tghop fit'")
        except RequestError as exc:  # the loader's advice for an image is a command line's
            if exc.status == 400 and is_image(io.BytesIO(content)):
                raise RequestError(400, f"{filename} is an image, not a model file; to fit a model from it, POST it "
                                        "to /api/models as the file field 'image'") from None
            raise

    async def upload_model(self, request):
        body = await read_body(request)
        if request.headers.get("content-type", "").startswith("multipart/form-data"):
            fields = await read_form(request, body)
            files = [v for v in fields.values() if isinstance(v, tuple)]
            if not files:
                raise RequestError(400, "no model file: send it as the field 'model' (or as the whole body)")
            filename, content = fields["model"] if isinstance(fields.get("model"), tuple) else files[0]
        else:
            filename, content = None, body  # no name: messages say "the upload"
        model_id = await run_in_threadpool(self._store_upload, content, safe_name(filename, "the upload"))
        return _json({"id": model_id})

    def _generate(self, model_id: str, size, seed, settings):
        """One model's image as PNG bytes; a material's maps as a list (:func:`materials.encode_maps`)."""
        import numpy as np

        from ..imageio import write_png

        model = self.cache.load(model_id)
        material = materials.is_material(model)
        if settings.get("patch_refine") and material:
            raise RequestError(422, "patch_refine and quality best do not apply to a material (it has no patch "
                                    "statistics); leave them out")
        if settings.get("patch_refine") and getattr(model, "patches_", None) is None:  # as tghop synth says
            raise RequestError(422, "this model holds no patch statistics for patch_refine or quality best (fitted "
                                    "with patch_levels 0, or by tghop 0.14 or older); fit it again")
        if material:
            settings = {k: v for k, v in settings.items() if k != "patch_refine"}  # 0 or None: nothing to do
        with self.generating:
            try:
                image = model.synthesize(size, rng=seed, dtype=np.float32 if material else np.uint8,
                                         progress=self.unless_stopping, **settings)
            except MemoryError:
                raise RequestError(422, "out of memory; ask for a smaller image") from None
            except TGHopError as exc:
                raise RequestError(422, str(exc)) from None
        if material:
            return materials.encode_maps(image, model)
        buf = io.BytesIO()
        write_png(buf, image)
        return buf.getvalue()

    @staticmethod
    async def _json_body(request, limit=1024 * 1024):
        body = await read_body(request, limit=limit)
        try:
            return json.loads(body or b"{}")
        except (ValueError, RecursionError):  # RecursionError: nested deeper than the parser goes
            raise RequestError(400, "the body is not JSON; send e.g. {\"size\": [256, 256], \"seed\": 1}") from None

    async def _png_response(self, request, work, *args, seed):
        """Run ``work(*args, seed)`` on a generation thread: its ``(png, (h, w))`` as the answer, or
        ``(maps, (h, w))`` of a material (a list, :func:`materials.encode_maps`) as JSON or multipart."""
        if seed is None:
            seed = secrets.randbelow(2**31)
        start = time.perf_counter()
        png, size = await self.in_executor(request, work, *args, seed)
        took = (time.perf_counter() - start) * 1000
        headers = {"X-Tghop-Seed": str(seed), "X-Tghop-Size": f"{size[0]}x{size[1]}",
                   "Server-Timing": f"generate;dur={took:.1f}", "Cache-Control": "no-store"}
        if isinstance(png, list):  # a material: every map, as multipart where the client takes it (the page)
            body, kind = materials.answer(request.headers.get("accept", ""), png, size, seed)
            return Response(body, headers=headers, media_type=kind)
        return Response(png, media_type="image/png", headers=headers)

    async def generate(self, request):
        model_id = request.path_params["id"]
        self.cache.path(model_id)  # 404 for a malformed id before the body is read
        size, seed, settings = parse_generation(await self._json_body(request))

        def work(seed):
            return self._generate(model_id, size, seed, settings), size

        return await self._png_response(request, work, seed=seed)

    def _several(self, make, models, seed) -> tuple:
        """``make(models, seed, dtype)`` under the bound on generations: the PNG and its size (the
        maps of materials: a list, :func:`materials.encode_maps`)."""
        import numpy as np

        from ..imageio import write_png

        material = materials.is_material(models[0])
        with self.generating:
            try:
                image = make(models, seed, np.float32 if material else np.uint8)
            except MemoryError:
                raise RequestError(422, "out of memory; ask for a smaller image") from None
            except TGHopError as exc:  # models that cannot be combined, a setting the library refuses
                raise RequestError(422, str(exc)) from None
        if isinstance(image, dict):  # materials (the library checked that all are, with the same maps)
            return materials.encode_maps(image, models[0]), next(iter(image.values())).shape[:2]
        buf = io.BytesIO()
        write_png(buf, image)
        return buf.getvalue(), image.shape[:2]

    @staticmethod
    def _same_patches(models, names) -> None:
        """Models to combine have one patch size, or 422 naming them as the request does and
        the fit field (the library's words name the command line's --patch-size)."""
        p = materials.patch_size(models[0])
        for name, model in zip(names[1:], models[1:]):
            q = materials.patch_size(model)
            if q != p:
                raise RequestError(422, f"{name} has {q}x{q} patches but {names[0]} has "
                                        f"{p}x{p}; fit them with the same patch_size (a field of POST /api/models)")

    def _guided(self, ids, guide, size, transition, settings, seed) -> tuple:
        """Several models through a painted guide (its PNG's bytes), or a remix (None)."""
        from ..guided import guide_labels, synthesize_guided
        from ..imageio import load_image

        models = [self.cache.load(model_id) for model_id in ids]
        materials.same_kind(models, ids)
        self._same_patches(models, [f"models[{i}]" for i in range(len(models))])
        painted = None
        if guide is not None:
            painted = self._read_image(guide, "guide.png", lambda p: load_image(p, dtype=None))
            try:
                guide_labels(painted, len(models), size=size)
            except TGHopError as exc:
                raise RequestError(400, str(exc)) from None
        return self._several(lambda m, rng, dtype: synthesize_guided(
            m, painted, size=size, transition=transition, rng=rng, dtype=dtype, progress=self.unless_stopping,
            **settings), models, seed)

    async def guided(self, request):
        ids, guide, size, seed, transition, settings = parse_guided(
            await self._json_body(request, limit=MAX_UPLOAD_BYTES))
        for model_id in ids:
            self.cache.path(model_id)  # 404 for a malformed id before any work
        return await self._png_response(request, self._guided, ids, guide, size, transition, settings, seed=seed)

    def _morph(self, ids, size, stations, settings, seed) -> tuple:
        from ..guided import morph

        models = [self.cache.load(model_id) for model_id in ids]
        for label, model in zip(["a", "b"], models):
            materials.texture_only(model, label, "a morph")
        self._same_patches(models, ["a", "b"])
        return self._several(lambda m, rng, dtype: morph(m[0], m[1], size, rng=rng, stations=stations, dtype=dtype,
                                                         progress=self.unless_stopping, **settings), models, seed)

    async def morph(self, request):
        a, b, size, seed, stations, settings = parse_morph(await self._json_body(request))
        for model_id in (a, b):
            self.cache.path(model_id)
        return await self._png_response(request, self._morph, [a, b], size, stations, settings, seed=seed)

    def _inpaint(self, model_id: str, fields: dict, seed: int, tile: bool, grow):
        """Read the picture and its mask (``grow`` None) or grow the picture to ``grow``'s
        ``(size, anchor)`` (:func:`tghop.inpaint.expand_canvas`), and fill the mask's white
        pixels or the new area with the model's texture (:func:`tghop.inpaint.inpaint`): the
        PNG's bytes. As ``tghop inpaint`` and ``tghop extend`` do (their code): an alpha channel
        is kept (opaque where filled), and so are 16 bits per channel (a float picture: 16
        bits, the most a PNG holds). A material fills its maps too (``map:<name>`` fields):
        ``(maps, (h, w))`` (:func:`materials.fill`)."""
        import numpy as np

        from .._errors import HINT_DOWNSCALE_YOURSELF
        from ..imageio import deepest, load_image, to_uint8, to_uint16, write_png
        from ..inpaint import check_hole, expand_canvas, inpaint, require_hole, split_alpha, with_alpha

        model = self.cache.load(model_id)
        uploads = materials.map_uploads(fields)  # a material's maps (none for a texture model)
        if uploads and not materials.is_material(model):
            raise RequestError(422, f"model {model_id[:12]} is a texture model; map:<name> fields go with a material")
        picture = mask = None
        for name in ("image",) if grow else ("image", "mask"):
            upload = fields.get(name)
            if not isinstance(upload, tuple):
                raise RequestError(400, f"no {name}: send the picture as the file field 'image'" + (
                    "" if grow else " and its mask (white: the hole) as the file field 'mask'"))
            filename, content = upload
            filename = safe_name(filename, name)
            if not content:
                raise RequestError(400, f"{filename} is empty; send an image file")
            if name == "image":  # 8-bit stays 8-bit (copied as bytes); an alpha channel is kept apart
                picture, depth = self._read_image(content, filename, lambda p: load_image(
                    p, dtype=None, too_large_hint=HINT_DOWNSCALE_YOURSELF, with_depth=True, keep_alpha=True))
                picture, alpha = split_alpha(picture)
            else:
                read = self._read_image(content, filename, lambda p: load_image(
                    p, dtype=np.float32, too_large_hint=HINT_DOWNSCALE_YOURSELF))
                mask, mask_name = read.mean(axis=2), filename
        try:
            if grow:
                picture, hole, _ = expand_canvas(picture, grow[0], anchor=grow[1])
                alpha = None if alpha is None else expand_canvas(alpha, grow[0], anchor=grow[1])[0]
            else:
                hole = check_hole(mask, picture.shape)
                require_hole(hole, f"the mask {mask_name}")  # as tghop inpaint: nothing would change
        except TGHopError as exc:
            raise RequestError(400, str(exc)) from None
        with self.generating:
            if materials.is_material(model):  # every map alike
                return materials.fill(model, picture, alpha, hole, uploads, lambda data, filename: self._read_image(
                    data, filename, lambda p: load_image(p, dtype=None, with_depth=True)), depth=depth, grow=grow,
                    seed=seed, tile=tile, progress=self.unless_stopping)
            try:
                filled = inpaint(model, picture, hole, rng=seed, tile=tile, progress=self.unless_stopping)
            except MemoryError:
                raise RequestError(413, "out of memory; send a smaller picture") from None
            except TGHopError as exc:
                raise RequestError(400, str(exc)) from None
        filled = with_alpha(filled, alpha, hole)  # a PNG holds it
        buf = io.BytesIO()
        write_png(buf, to_uint16(filled) if deepest("filled.png", depth) == 16 else to_uint8(filled))
        return buf.getvalue()

    async def inpaint(self, request):
        return await self._fill_request(request, grow=False)

    async def extend(self, request):
        return await self._fill_request(request, grow=True)

    async def _fill_request(self, request, *, grow: bool):
        """``POST /api/models/{id}/inpaint`` (the fields image, mask, seed, tile) or
        ``/extend`` (image, size, anchor, seed, tile)."""
        model_id = request.path_params["id"]
        self.cache.path(model_id)  # 404 for a malformed id before the body is read
        # A material's picture comes with its maps: as much in all as its fit
        body = await read_body(request, MAX_FIT_BYTES, what="the upload (the picture and its maps together)")
        names = ("image", "size", "anchor", "seed", "tile") if grow else ("image", "mask", "seed", "tile")
        fields = each_file_within(await read_form(
            request, body, "the file field 'image' and the fields 'size' (HEIGHTxWIDTH) and optionally 'anchor', "
            "'seed' and 'tile'" if grow else "the file fields 'image' and 'mask', white where to fill; optionally "
            "the fields 'seed' and 'tile'"))
        unknown = [k for k in fields if k not in names and not k.startswith(materials.MAP_FIELD)]
        if unknown:
            raise RequestError(422, f"unknown field {unknown[0]!r}; known: {', '.join(names)} (and a material's "
                                    "map:<name>)")
        plain = {k: fields.get(k) for k in names if k not in ("image", "mask")}
        if any(isinstance(v, tuple) for v in plain.values()):
            raise RequestError(422, f"{', '.join(plain)}: plain fields, not files")
        seed = (plain["seed"] or "").strip()
        if seed == "":
            seed = secrets.randbelow(2**31)
        elif not re.fullmatch(r"[0-9]{1,19}", seed) or int(seed) >= 2**63:
            raise RequestError(422, f"seed must be an integer from 0 to 2**63 - 1, got {seed[:40]!r}")
        else:
            seed = int(seed)
        tile = parse_bool("tile", plain["tile"] or "false")
        growth = parse_growth(plain["size"], plain["anchor"]) if grow else None
        png = await self.in_executor(request, self._inpaint, model_id, fields, seed, tile, growth)
        headers = {"X-Tghop-Seed": str(seed), "Cache-Control": "no-store"}
        if isinstance(png, tuple):  # a material's maps and their size
            body, kind = materials.answer(request.headers.get("accept", ""), *png, seed)
            return Response(body, media_type=kind, headers=headers)
        return Response(png, media_type="image/png", headers=headers)

    # ---------------------------------------------------------------- co-occurrence
    async def upload_cooc(self, request):
        cooc.require_torch()
        body = await read_body(request)
        if request.headers.get("content-type", "").startswith("multipart/form-data"):
            fields = await read_form(request, body)
            upload = fields.get("checkpoint")
            if not isinstance(upload, tuple):
                raise RequestError(400, "no checkpoint: send it as the file field 'checkpoint' (or as the whole body)")
            filename, content = upload
        else:
            filename, content = None, body  # no name: messages say "the upload"
        cid = await run_in_threadpool(cooc.store_checkpoint, self.cooc, content, safe_name(filename, "the upload"))
        return _json({"id": cid})

    def _cooc_id(self, request) -> str:
        cooc.require_torch()
        cid = request.path_params["id"]
        self.cooc.path(cid)  # 404 for a malformed id before the body is read
        return cid

    async def cooc_summary(self, request):
        cid = self._cooc_id(request)
        return _json(await run_in_threadpool(cooc.summary, self.cooc, cid))

    async def cooc_file(self, request):
        cid = self._cooc_id(request)
        return self._file(self.cooc, cid, f"no co-occurrence checkpoint {cid}; {cooc.COOC_HINT}")

    async def cooc_morph(self, request):
        cid = self._cooc_id(request)
        a, b, crop, length, seed, windows = cooc.parse_morph(await self._json_body(request))

        def work(seed):
            with self.generating:
                return cooc.morph_png(self.cooc.load(cid), a, b, crop, length, windows, seed)

        return await self._png_response(request, work, seed=seed)

    async def cooc_edit(self, request):
        from ..imageio import load_image

        cid = self._cooc_id(request)
        size, labels, crops, boost, seed, windows = cooc.parse_edit(
            await self._json_body(request, limit=MAX_UPLOAD_BYTES))

        def read_labels(content):
            return self._read_image(content, "labels.png", lambda p: load_image(p, dtype=None))

        def work(seed):
            with self.generating:
                return cooc.edit_png(self.cooc.load(cid), size, labels, crops, boost, windows, seed, read_labels)

        return await self._png_response(request, work, seed=seed)

    # ---------------------------------------------------------------- the rest
    async def builtin_image(self, request):
        from ..data import BUILTIN, builtin
        from ..imageio import to_uint8, write_png

        name = request.path_params["name"]
        if name not in BUILTIN:
            raise RequestError(404, f"no built-in exemplar {name[:40]!r}; choose one of {', '.join(sorted(BUILTIN))}")
        buf = io.BytesIO()
        write_png(buf, to_uint8(await run_in_threadpool(builtin, name)))
        return Response(buf.getvalue(), media_type="image/png")

    async def builtins(self, request):
        from ..data import BUILTIN

        return _json({"builtins": sorted(BUILTIN), "fit_settings": fit_fields(), "cooc": cooc.has_torch()})

    async def index(self, request):
        return FileResponse(STATIC / "index.html", media_type="text/html")


async def _disconnected(request) -> None:
    """Return when the client of ``request`` (whose body has been read) disconnects."""
    while (await request.receive())["type"] != "http.disconnect":
        pass


def _wrap(handler):
    """A route that answers :class:`RequestError` and library errors with one JSON line."""
    async def route(request):
        try:
            return await handler(request)
        except RequestError as exc:
            return _error(exc.status, exc.message)
        except TGHopError as exc:  # a library check the route did not foresee: the input's fault
            return _error(400, str(exc))

    return route


def create_app(cache_dir, max_fits: int | None = None, cache_bytes: int | None = DEFAULT_CACHE_BYTES,
               host: str = "127.0.0.1"):
    """The Starlette application of ``tghop serve``.

    Parameters
    ----------
    cache_dir : str or os.PathLike
        Where fitted and uploaded models are kept (``<cache_dir>/models/<id>.npz``);
        created if needed.
    max_fits : int, optional
        Fits that run at once (the rest wait in order); default: the number of cores.
    cache_bytes : int or None
        Bound of the model files' total size (the least recently used go first; the
        newest is kept even when it alone is larger); None: no bound.
    host : str
        The address the server listens on (``tghop serve --host``): requests whose Host header names
        another (or whose Origin is another site) are refused, 403 (:class:`~tghop.server.safety.LocalOnly`).

    Raises
    ------
    MissingExtraError
        Starlette or python-multipart is not installed (one line naming ``tghop[web]``).
    """
    require_web()
    server = Server(cache_dir, max_fits or os.cpu_count() or 1, cache_bytes)
    routes = [
        Route("/", _wrap(server.index)),
        Route("/api", _wrap(server.builtins)),
        Route("/api/builtins/{name}.png", _wrap(server.builtin_image)),
        Route("/api/models", _wrap(server.create_model), methods=["POST"]),
        Route("/api/models/upload", _wrap(server.upload_model), methods=["POST"]),
        Route("/api/models/{id}", _wrap(server.model_summary)),
        Route("/api/models/{id}/file", _wrap(server.model_file)),
        Route("/api/models/{id}/images", _wrap(server.generate), methods=["POST"]),
        Route("/api/models/{id}/inpaint", _wrap(server.inpaint), methods=["POST"]),
        Route("/api/models/{id}/extend", _wrap(server.extend), methods=["POST"]),
        Route("/api/images/guided", _wrap(server.guided), methods=["POST"]),
        Route("/api/images/morph", _wrap(server.morph), methods=["POST"]),
        Route("/api/cooc", _wrap(server.upload_cooc), methods=["POST"]),
        Route("/api/cooc/{id}", _wrap(server.cooc_summary)),
        Route("/api/cooc/{id}/file", _wrap(server.cooc_file)),
        Route("/api/cooc/{id}/morph", _wrap(server.cooc_morph), methods=["POST"]),
        Route("/api/cooc/{id}/edit", _wrap(server.cooc_edit), methods=["POST"]),
        Route("/api/jobs/{job}", _wrap(server.job_state)),
        Route("/api/jobs/{job}", _wrap(server.cancel_job), methods=["DELETE"]),
        Route("/api/jobs/{job}/events", _wrap(server.job_events)),
        Mount("/static", app=StaticFiles(directory=STATIC), name="static"),
    ]

    async def http_error(request, exc):
        response = _error(exc.status_code, http_message(exc, request.method, request.url.path))
        response.headers.update(http_headers(exc))  # a 405's Allow
        return response

    async def lifespan(app):
        yield
        await run_in_threadpool(server.queue.shutdown)
        server.executor.shutdown(wait=False, cancel_futures=True)

    app = Starlette(routes=routes, exception_handlers={HTTPException: http_error},
                    lifespan=asynccontextmanager(lifespan))
    app.state.server = server
    app.add_middleware(LocalOnly, hosts=allowed_hosts(host))
    return app
