"""The web server's Starlette application (:func:`create_app`): the page, the HTTP API under
``/api`` and the model cache (see docs/serve.md for the API).

Where things are: the route table is :func:`create_app`'s, below; each route's handler is in
:mod:`tghop.server.routes` (fit and jobs, a model's file, images, inpaint and extend,
co-occurrence checkpoints), the state they share (cache, fit queue, the bound on generations and
their threads) is :class:`tghop.server.core.Server`, and reading a request (body, form, JSON, an
uploaded image) is :mod:`tghop.server.uploads`; the fields' checks are :mod:`tghop.server.requests`.

The cache (:class:`tghop.server.cache.ModelCache`) is a folder, ``<cache>/models``, of model files named
``<id>.npz`` (and ``<cache>/cooc`` of co-occurrence checkpoints, ``<id>.pt``: :mod:`tghop.server.cooc`). An id
is a content hash (SHA-256 of the exemplar's bytes and the fit settings, or of an uploaded model file), so the
same exemplar with the same settings is fitted once. Every file appears whole or not at all
(:func:`tghop.modelfile.save_model` writes atomically; an upload is checked in a temporary file that is removed
whatever happens); leftovers of a killed server (``.*.tmp``) are removed at start. The folder is bounded
(``max_bytes``, ``tghop serve --cache-size``): when a new model makes it larger, the least recently used model
files go (a file's modification time is its last use: set when it is written, loaded, generated from or
downloaded), never the one just added; a client then gets 404 for a model that went and fits it again.

Everything tghop does here is the library's own code: :func:`tghop.imageio.load_image` (with its pixel limit),
:class:`tghop.TGHop` (fit with a progress callback, synthesize), :func:`tghop.inpaint.inpaint`,
:func:`tghop.synthesize_guided` and :func:`tghop.morph` (several models; their JSON is checked by
:mod:`tghop.server.requests`), :func:`tghop.modelfile.save_model` / :func:`~tghop.modelfile.load_model` (with
their checks of a file). Bad input is answered with one line, ``{"error": "..."}``, and a status code: 400 (not
an image, a decompression bomb, a corrupt model, a malformed request), 404 (no such model or job), 409 (a
generation stopped through its job, a job id in use), 413 (over 50 MB or over the exemplar pixel limit), 422 (a
setting out of range, a size over the output limit), 501 (a co-occurrence route without PyTorch), 503 (too
many fits, or uploads to decode or models to read from disk, waiting; with ``Retry-After``); a generation
whose client has gone away is dropped, also while it runs
(:meth:`~tghop.server.core.Server.in_executor`; 499, to nobody), and so is a request whose client goes away
before it has sent the whole body (:func:`~tghop.server.uploads.read_body`). A generation whose request
names a job (the header ``X-Tghop-Job``) reports its progress at ``/api/jobs/{job}``, as a fit does
(:meth:`~tghop.server.core.Server.generation_job`).
"""

from __future__ import annotations

import io
import os
from contextlib import asynccontextmanager
from pathlib import Path

from .._errors import MissingExtraError, TGHopError
from . import cooc
from .cache import DEFAULT_CACHE_BYTES, ModelCache
from .core import Server, error_response, json_response
from .requests import RequestError, fit_fields, http_headers, http_message
from .routes import cooc as cooc_routes
from .routes import fill, fit, images, models
from .routes.fit import model_id_for
from .safety import LocalOnly, allowed_hosts
from .uploads import MAX_DECODES, MAX_DECODES_WAITING, MAX_FIT_BYTES, MAX_UPLOAD_BYTES

try:  # the web extra; create_app says how to install it when it is missing
    from starlette.applications import Starlette
    from starlette.concurrency import run_in_threadpool
    from starlette.exceptions import HTTPException
    from starlette.responses import FileResponse, Response
    from starlette.routing import Mount, Route
    from starlette.staticfiles import StaticFiles
except ImportError:  # pragma: no cover - tested by the missing-extra test in a fresh interpreter
    Starlette = None

__all__ = ["create_app", "require_web", "WEB_HINT", "MAX_UPLOAD_BYTES", "MAX_FIT_BYTES", "STATIC", "model_id_for",
           "ModelCache", "DEFAULT_CACHE_BYTES", "Server"]

#: How to install what the server needs.
WEB_HINT = "pip install 'tghop[web]'"
#: The page's files.
STATIC = Path(__file__).resolve().parent / "static"
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



# ---------------------------------------------------------------- the page and the built-in exemplars
async def builtin_image(server, request):
    """``GET /api/builtins/{name}.png``."""
    from ..data import BUILTIN, builtin
    from ..imageio import to_uint8, write_png

    name = request.path_params["name"]
    if name not in BUILTIN:
        raise RequestError(404, f"no built-in exemplar {name[:40]!r}; choose one of {', '.join(sorted(BUILTIN))}")
    buf = io.BytesIO()
    write_png(buf, to_uint8(await run_in_threadpool(builtin, name)))
    return Response(buf.getvalue(), media_type="image/png")


async def builtins(server, request):
    """``GET /api``: the built-in exemplars, the fit settings and whether co-occurrence works."""
    from ..data import BUILTIN

    return json_response({"builtins": sorted(BUILTIN), "fit_settings": fit_fields(), "cooc": cooc.has_torch()})


async def index(server, request):
    """``GET /``: the page."""
    return FileResponse(STATIC / "index.html", media_type="text/html")


def _wrap(handler, server):
    """``handler(server, request)`` as a route that answers :class:`RequestError` and library errors
    with one JSON line."""
    async def route(request):
        try:
            return await handler(server, request)
        except RequestError as exc:
            return error_response(exc.status, exc.message, exc.headers)
        except TGHopError as exc:  # a library check the route did not foresee: the input's fault
            return error_response(400, str(exc))

    return route
def create_app(cache_dir, max_fits: int | None = None, cache_bytes: int | None = DEFAULT_CACHE_BYTES,
               host: str = "127.0.0.1", max_decodes: int = MAX_DECODES, decodes_waiting: int = MAX_DECODES_WAITING):
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
    max_decodes, decodes_waiting : int
        Uploads decoded or read at once (a fit's exemplar and maps, a model file, a checkpoint: each may
        take hundreds of MB; and a model or checkpoint read from disk for a summary or a generation), and how
        many more wait their turn; one more is refused, 503 with ``Retry-After`` (``tghop serve --max-decodes``).

    Raises
    ------
    MissingExtraError
        Starlette or python-multipart is not installed (one line naming ``tghop[web]``).
    """
    require_web()
    server = Server(cache_dir, max_fits or os.cpu_count() or 1, cache_bytes, max_decodes=max_decodes,
                    decodes_waiting=decodes_waiting)
    routes = [
        Route("/", _wrap(index, server)),
        Route("/api", _wrap(builtins, server)),
        Route("/api/builtins/{name}.png", _wrap(builtin_image, server)),
        Route("/api/models", _wrap(fit.create_model, server), methods=["POST"]),
        Route("/api/models/upload", _wrap(models.upload_model, server), methods=["POST"]),
        Route("/api/models/{id}", _wrap(models.model_summary, server)),
        Route("/api/models/{id}/file", _wrap(models.model_file, server)),
        Route("/api/models/{id}/images", _wrap(images.generate, server), methods=["POST"]),
        Route("/api/models/{id}/inpaint", _wrap(fill.inpaint, server), methods=["POST"]),
        Route("/api/models/{id}/extend", _wrap(fill.extend, server), methods=["POST"]),
        Route("/api/images/guided", _wrap(images.guided, server), methods=["POST"]),
        Route("/api/images/morph", _wrap(images.morph, server), methods=["POST"]),
        Route("/api/guides/labels", _wrap(images.guide_labels_route, server), methods=["POST"]),
        Route("/api/cooc", _wrap(cooc_routes.upload_cooc, server), methods=["POST"]),
        Route("/api/cooc/{id}", _wrap(cooc_routes.cooc_summary, server)),
        Route("/api/cooc/{id}/file", _wrap(cooc_routes.cooc_file, server)),
        Route("/api/cooc/{id}/morph", _wrap(cooc_routes.cooc_morph, server), methods=["POST"]),
        Route("/api/cooc/{id}/edit", _wrap(cooc_routes.cooc_edit, server), methods=["POST"]),
        Route("/api/jobs/{job}", _wrap(fit.job_state, server)),
        Route("/api/jobs/{job}", _wrap(fit.cancel_job, server), methods=["DELETE"]),
        Route("/api/jobs/{job}/events", _wrap(fit.job_events, server)),
        Mount("/static", app=StaticFiles(directory=STATIC), name="static"),
    ]

    async def http_error(request, exc):
        response = error_response(exc.status_code, http_message(exc, request.method, request.url.path))
        response.headers.update(http_headers(exc))  # a 405's Allow
        return response

    async def lifespan(app):
        yield
        await run_in_threadpool(server.queue.shutdown)
        server.executor.shutdown(wait=False, cancel_futures=True)
        server.decoder.shutdown(wait=False, cancel_futures=True)

    app = Starlette(routes=routes, exception_handlers={HTTPException: http_error},
                    lifespan=asynccontextmanager(lifespan))
    app.state.server = server
    app.add_middleware(LocalOnly, hosts=allowed_hosts(host))
    return app
