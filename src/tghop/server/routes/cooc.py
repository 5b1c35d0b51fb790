"""Co-occurrence checkpoints on the web server (``/api/cooc``; docs/serve.md, "Co-occurrence
checkpoints"): the routes; what they do with a checkpoint is :mod:`tghop.server.cooc`'s (PyTorch
imported only there: 501 without it)."""

from __future__ import annotations

from .. import cooc
from ..core import json_response
from ..requests import RequestError, query_value, safe_name
from ..uploads import MAX_UPLOAD_BYTES, json_body, read_body, read_form, read_image
from .images import png_response
from .models import send_file

__all__ = ["upload_cooc", "checkpoint_id", "cooc_summary", "cooc_file", "cooc_morph", "cooc_edit"]


async def upload_cooc(server, request):
    """``POST /api/cooc``: the checkpoint as the whole body or the multipart field ``checkpoint``."""
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
    cid, notes = await server.decode(request, cooc.store_checkpoint, server.cooc, content,
                                     safe_name(filename, "the upload"), server.still_wanted)
    return json_response({"id": cid, "notes": notes})


def checkpoint_id(server, request) -> str:
    """The path's ``{id}`` (501 without PyTorch, 404 when malformed)."""
    cooc.require_torch()
    cid = request.path_params["id"]
    server.cooc.path(cid)  # 404 for a malformed id before the body is read
    return cid


async def cooc_summary(server, request):
    """``GET /api/cooc/{id}``: the summary kept, or the checkpoint loaded in the decoding threads' turn
    (:meth:`~tghop.server.core.Server.decode`), as ``GET /api/models/{id}`` answers for a model."""
    cid = checkpoint_id(server, request)
    known = server.cooc.summary(cid)
    if known is None:
        known = await server.decode(request, cooc.summary, server.cooc, cid)
    return json_response(known)


async def cooc_file(server, request):
    """``GET /api/cooc/{id}/file``: the checkpoint as uploaded."""
    cid = checkpoint_id(server, request)
    return send_file(server.cooc, cid, server.cooc.missing(cid).message, kind="cooc", name=query_value(request, "name"))


async def cooc_morph(server, request):
    """``POST /api/cooc/{id}/morph``: a strip from crop ``a`` to crop ``b``."""
    cid = checkpoint_id(server, request)
    a, b, crop, length, seed, windows = cooc.parse_morph(await json_body(request))

    def work(seed):
        model = server.checkpoint(cid)  # read before, in its turn, when not in memory
        with server.generating:
            return cooc.morph_png(model, a, b, crop, length, windows, seed, progress=server.unless_stopping)

    return await png_response(server, request, work, seed=seed, checkpoints=[cid])


async def cooc_edit(server, request):
    """``POST /api/cooc/{id}/edit``: an image painted with crops, boosted or not."""
    from ...imageio import load_image

    cid = checkpoint_id(server, request)
    size, labels, crops, boost, seed, windows = cooc.parse_edit(
        await json_body(request, limit=MAX_UPLOAD_BYTES))

    read = []  # what reading the label map said (a colour profile converted), told before the scaling's warning

    def read_labels(content):
        return read_image(content, "labels.png", lambda p: load_image(p, dtype=None), notes=read)

    def work(seed):
        model = server.checkpoint(cid)  # read before, in its turn, when not in memory
        with server.generating:
            png, shape, told = cooc.edit_png(model, size, labels, crops, boost, windows, seed, read_labels,
                                             progress=server.unless_stopping)
        return png, shape, read + told

    return await png_response(server, request, work, seed=seed, checkpoints=[cid])
