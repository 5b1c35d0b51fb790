"""A model's file on the web server: ``GET /api/models/{id}`` (its summary, as ``tghop info --json``),
``GET /api/models/{id}/file`` (the download) and ``POST /api/models/upload`` (a saved model file,
checked and kept under its content hash); docs/serve.md, "Models"."""

from __future__ import annotations

import io
import os

from ..core import json_response
from ..requests import RequestError, content_disposition, file_stem, query_value, safe_name
from ..uploads import depth_note, note_line, read_body, read_form

__all__ = ["summary", "model_summary", "download_name", "send_file", "model_file", "store_upload", "upload_model"]


def summary(server, model_id: str) -> dict:
    """The summary of ``GET /api/models/{id}`` (the model loaded: a decoding thread), kept once made
    (:meth:`~tghop.server.cache.ModelCache.keep_summary`). The file's size is read first: a file the bound
    drops meanwhile is 404, as one gone before."""
    from ...modelfile import info_dict

    known = server.cache.summary(model_id)  # made while this one waited its turn
    if known is not None:
        return known
    try:
        file_bytes = server.cache.path(model_id).stat().st_size
    except FileNotFoundError:
        raise server.cache.missing(model_id) from None
    loaded = server.cache.load(model_id)  # 404 when the file went since
    model = getattr(loaded, "model_", loaded)  # a material's joint model
    levels = patch_levels(loaded)
    made = {"id": model_id, "file_bytes": file_bytes,
            "layout": model.layout_ is not None, **info_dict(model), "patch_levels": levels,
            **({"material": {"maps": loaded.map_info(), "patch_levels": levels}} if model is not loaded else {})}
    server.cache.keep_summary(model_id, made)
    return made


def patch_levels(model) -> int:
    """The levels of the patch statistics a texture model holds, or a material's albedo (0.59 a material's; 0.61 a
    texture model's too; 0: none, a model fitted with ``patch_levels`` 0 (the paper's settings), a texture model of
    tghop 0.14 or a material of 0.58): whether the page's quality switch applies to it."""
    if hasattr(model, "albedo_patch_levels"):  # a material: the count its file's metadata says too
        return model.albedo_patch_levels()
    stats = getattr(model, "patches_", None)  # none on a model of tghop 0.14 and older
    return 0 if stats is None else len(stats.directions_)


async def model_summary(server, request):
    """``GET /api/models/{id}``: the summary kept, or the model loaded in the decoding threads' turn
    (:meth:`~tghop.server.core.Server.decode`: a model may take hundreds of MB while it is read), with ``notes``:
    what reading its file warned of (:meth:`~tghop.server.cache.ModelCache.model_notes`) and what its fit here
    warned of (:meth:`~tghop.server.cache.ModelCache.fit_notes`)."""
    model_id = request.path_params["id"]
    known = server.cache.summary(model_id)
    if known is None:
        known = await server.decode(request, summary, server, model_id)
    said = server.cache.model_notes(model_id) + server.cache.fit_notes(model_id)
    return json_response({**known, "notes": [note_line(line) for line in said]})


def download_name(file_id: str, suffix: str, *, kind: str = "", name=None, ascii_only: bool = False) -> str:
    """A download's file name: ``tghop``, then ``-kind`` and ``-name`` where given, then
    ``-<first 12 of the id><suffix>``; ``name`` (``?name=``, the page's name of the model: its
    exemplar's or file's) made safe by :func:`file_stem` (in ASCII alone with ``ascii_only``)."""
    stem = file_stem(name, ascii_only=ascii_only)
    return "-".join(part for part in ("tghop", kind, stem, file_id[:12]) if part) + suffix


def send_file(cache, file_id: str, missing: str, *, kind: str = "", name=None):
    """The file ``file_id`` of ``cache`` (a :class:`~tghop.server.cache.ModelCache`) as a download
    (404 with ``missing`` if none), named by :func:`download_name`. The file is opened here and sent from
    the open file: one the cache's bound drops meanwhile (another model added) is still sent whole."""
    from starlette.responses import StreamingResponse

    path = cache.path(file_id)
    try:
        handle = open(path, "rb")
    except (FileNotFoundError, IsADirectoryError):
        raise RequestError(404, missing) from None
    cache.touch(file_id)

    def chunks():
        with handle:
            while block := handle.read(1024 * 1024):
                yield block

    filename = download_name(file_id, path.suffix, kind=kind, name=name)
    plain = download_name(file_id, path.suffix, kind=kind, name=name, ascii_only=True)
    headers = {"Content-Length": str(os.fstat(handle.fileno()).st_size),
               "Content-Disposition": content_disposition(filename, plain)}
    return StreamingResponse(chunks(), media_type="application/octet-stream", headers=headers)


async def model_file(server, request):
    """``GET /api/models/{id}/file``: the model file as ``tghop fit`` writes it (``?name=``: a name for
    its file, ``tghop-<name>-<id>.npz``)."""
    model_id = request.path_params["id"]
    return send_file(server.cache, model_id, server.cache.missing(model_id).message, name=query_value(request, "name"))


def store_upload(server, content: bytes, filename: str) -> tuple:
    """Check an uploaded model file and keep it under its content hash (400 if it is not
    a good tghop model; nothing is left in the cache either way): ``(id, notes)``, ``notes`` what the page
    tells with it: what reading the file warned of (a model made by a newer tghop; :meth:`ModelCache.notes
    <tghop.server.cache.ModelCache.notes>`), a texture model fitted on a 16-bit or float exemplar, whose images
    here are 8-bit, as ``tghop synth`` warns (:func:`tghop.server.uploads.depth_note`)."""
    from ..._formats import COOC_CHECKPOINT, model_file_kind
    from ...imageio import is_image

    try:
        model_id = server.cache.store(content, filename, hint="pick a model file downloaded from this page "
                                      "(Download model) or written by tghop fit",
                                      wanted=server.still_wanted, refit=lambda exc: page_refit(exc, filename))
    except RequestError as exc:  # the loader's advice for an image or a checkpoint is a command line's
        if exc.status == 400 and is_image(io.BytesIO(content)):
            raise RequestError(400, f"{filename} is an image, not a model file; to fit a model from it, pick it "
                                    "as the exemplar (the API: POST it to /api/models as the file field 'image')"
                               ) from None
        if exc.status == 400 and model_file_kind(io.BytesIO(content)) == COOC_CHECKPOINT:
            raise RequestError(400, f"{filename} is a co-occurrence checkpoint, not a model file; load it in "
                                    "Co-occurrence mode (the API: POST it to /api/cooc)") from None
        raise
    model = server.cache.load(model_id)  # in memory once stored (a file kept before: read here, in its turn)
    deep = (getattr(model, "exemplar_depth_", None) or 8) > 8  # a material's maps keep their depths: none
    read = [note_line(line) for line in server.cache.notes(model_id, filename) or []]
    return model_id, read + ([depth_note(filename, model=True)] if deep else [])


def page_refit(exc, filename: str) -> str:
    """How the page's user fits a model file again that tghop cannot use (0.62; 0.61 gave the command line's
    "tghop fit EXEMPLAR -o NAME", "-o the upload" for an upload without a name): on the page from its exemplar
    (a material: its albedo and maps), or with that command naming the file as it was uploaded."""
    import shlex

    out = "MODEL.npz" if filename == "the upload" else shlex.quote(filename)
    if exc.material:
        return (f"on this page, pick its albedo (Pick an image...) with its maps (Add maps...), or run "
                f"tghop fit ALBEDO --maps MAP ... -o {out}")
    return f"on this page, pick its exemplar (Pick an image...), or run tghop fit EXEMPLAR -o {out}"


async def upload_model(server, request):
    """``POST /api/models/upload``: the file as the whole body or the multipart field ``model`` (0.63: that field
    alone, as ``/api/cooc`` takes ``checkpoint`` alone; 0.62 took a file field of any name)."""
    body = await read_body(request)
    if request.headers.get("content-type", "").startswith("multipart/form-data"):
        fields = await read_form(request, body)
        upload = fields.get("model")
        if not isinstance(upload, tuple):
            others = sorted(name for name, value in fields.items() if isinstance(value, tuple))
            sent = f" (a file came as {', '.join(repr(n) for n in others)})" if others else ""
            raise RequestError(400, f"no model file{sent}: send it as the file field 'model' (or as the whole body)")
        filename, content = upload
    else:
        filename, content = None, body  # no name: messages say "the upload"
    model_id, notes = await server.decode(request, store_upload, server, content, safe_name(filename, "the upload"))
    return json_response({"id": model_id, "notes": notes})
