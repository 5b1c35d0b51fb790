"""Fitting on the web server: ``POST /api/models`` (an exemplar, or a material's albedo and maps,
checked and read before a job is queued) and the jobs under ``/api/jobs`` (state, server-sent
events of the progress, cancel); docs/serve.md, "POST /api/models" and "Jobs"."""

from __future__ import annotations

import asyncio
import hashlib
import json

from ..._errors import ModelFileError, TGHopError, collect_warnings
from .. import materials
from ..core import json_response
from ..jobs import FINAL, JOB_ID, QueueFull, fit_stages, unknown_snapshot
from ..requests import RequestError, check_channel_counts, parse_fit_settings, query_value, safe_name
from ..uploads import (MAX_FIT_BYTES, RETRY_AFTER, depth_note, each_file_within, note_line, read_body, read_form,
                       read_image)

__all__ = ["model_id_for", "prepare_fit", "makes_layout", "fit_work", "create_model", "find_job", "job_state",
           "cancel_job", "job_events", "JOB"]

#: A job's id: 32 hex digits.
JOB = JOB_ID


def model_id_for(content: bytes, settings: dict) -> str:
    """The content hash naming a model: SHA-256 of the exemplar's bytes (or ``builtin:NAME``)
    and the fit settings (as sorted JSON)."""
    digest = hashlib.sha256(content)
    digest.update(b"\0tghop-fit-settings\0")
    digest.update(json.dumps(settings, sort_keys=True, default=str).encode())
    return digest.hexdigest()


def prepare_fit(server, fields: dict):
    """Check the request and read the exemplar, and the maps of a material (fields ``map:<name>``;
    :mod:`tghop.server.materials`), in a worker thread: returns ``(model id, fit, notes)``, ``fit(progress)``
    fitting the model (a TGHop, or with maps a Material); ``fit`` is None when the model is in the cache.
    ``notes``: what the page should tell of the images, as the command line warns of them: an upload's
    transparent part, whose hidden colours are learnt as texture, a colour profile converted to sRGB, only
    the first frame read (:func:`tghop.server.uploads.read_notes`), and the bits of a 16-bit or float
    exemplar that a texture model's images, 8-bit, lose (:func:`~tghop.server.uploads.depth_note`)."""
    from ..._errors import HINT_DOWNSCALE_YOURSELF
    from ...data import builtin
    from ...fit_options import build_model, fit_params, material_model
    from ...imageio import load_image
    from ...material import Material
    from ...synthesis import prepare_exemplar

    notes = []

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
        if uploads:  # the colour map out of place: refused or noted as tghop fit --maps refuses or warns of it
            said = materials.check_colour_map(safe_name(filename, "exemplar"), uploads)
            notes.extend([] if said is None else [note_line(said)])
        image, depth = read_image(content, safe_name(filename, "exemplar"), read, notes=notes)
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
            uploads, lambda data, filename, load: read_image(data, filename, load, notes=notes), image.shape)
        joint = material_model(fit_params(options, api=True))  # channels for the maps too, as fit --maps
        materials.check_channels(joint, image, maps)
        model_id = materials.material_id(content, uploads, joint.get_params(), model_id_for)

        def fit(progress):
            return Material(model=joint).fit(image, maps, depths={"albedo": depth, **depths}, progress=progress)
        fit.stages = fit_stages(len(joint.check_channels(None)), material=True, layout=makes_layout(joint, image))
    else:
        model_id = model_id_for(content, params)
        if depth > 8:  # a material's maps keep their depths; a texture model's images are 8-bit
            notes.append(depth_note(safe_name(filename, "exemplar")))

        def fit(progress):
            return model.fit(image, depth=depth, progress=progress)  # recorded: its file tells tghop synth
        fit.stages = fit_stages(len(model.check_channels(image.shape[2])), layout=makes_layout(model, image))
    return model_id, (None if server.cache.has(model_id) else fit), notes


def makes_layout(model, image) -> bool:
    """Whether fitting ``model`` (a TGHop, or a material's joint model) on ``image`` makes a coarse layout, as
    :meth:`tghop.TGHop.fit` decides it: a ``layout_factor``, and the exemplar, after the working scale, large
    enough for it. Known before the fit, so that its progress counts "layout" from the start (0.57 counted it
    once it came, and the bar stepped back)."""
    from ...scale import scaled_shape
    from ...synthesis import CoarseLayout

    if not model.layout_factor:
        return False
    return bool(CoarseLayout(factor=model.layout_factor).usable_factor(scaled_shape(image.shape, model.scale)))


def fit_work(server, model_id: str, fit):
    """What a fit job runs: ``fit(progress)``, then save atomically into the cache."""
    from ...modelfile import save_model

    def work(job):
        job.stages = getattr(fit, "stages", None)  # before any progress: the fraction's whole
        with server.working():  # the last work to end gives the memory back
            with collect_warnings() as said:  # told with the model's summary, not on the server's console
                model = fit(job.progress)
            job.progress("saving", 0, 1)  # the last point where a cancel stops the fit
            try:
                save_model(model, server.cache.path(model_id))
            except ModelFileError:  # the cache folder's trouble (full, gone, read-only), told as an upload's is
                raise server.cache.cannot_keep() from None
            server.cache.added(model_id, model)
            server.cache.fitted(model_id, said)
            job.progress("saving", 1, 1, cancellable=False)  # the file is there: the job is done

    return work


async def create_model(server, request):
    """``POST /api/models``: check the fields and read the exemplar (a decoding thread, in its turn:
    :meth:`~tghop.server.core.Server.decode`), then queue the fit (202), or answer the model already in
    the cache (200)."""
    body = await read_body(request, MAX_FIT_BYTES, what="the upload (the exemplar and its maps together)")
    fields = each_file_within(await read_form(request, body))
    model_id, fit, notes = await server.decode(request, prepare_fit, server, fields)  # exemplar, maps: in turn, or 503
    if fit is None:
        server.cache.touch(model_id)
        job = server.queue.finished(model_id)
    else:
        try:
            job = server.queue.submit(model_id, fit_work(server, model_id, fit))
        except QueueFull as exc:
            raise RequestError(503, f"the server is busy: {exc}", headers={"Retry-After": str(RETRY_AFTER)}) from None
    return json_response({"id": model_id, "job": job.id, "state": job.state, "notes": notes},
                         status=202 if not job.final else 200)


def find_job(server, request):
    """The job of the path's ``{job}`` (404 when there is none)."""
    job_id = request.path_params["job"]
    job = server.queue.get(job_id) if JOB.match(job_id) else None
    if job is None:
        raise RequestError(404, f"no job {job_id[:80]!r}; POST /api/models starts one, and so does a generation "
                                "that names it (X-Tghop-Job) once the server has read its request")
    return job


async def job_state(server, request):
    """``GET /api/jobs/{job}``: its snapshot. With ``?expected=1`` (a client that has sent, or is sending, a
    generation naming this job: the page's poll), a well-formed id not in the table is 200 and state ``unknown``
    (:func:`~tghop.server.jobs.unknown_snapshot`), not 404: its request may not be read as far as its header yet
    (a body on its way, a request waiting for the event loop)."""
    expected = query_value(request, "expected", "0").strip().lower()
    if expected not in ("0", "1", "false", "true"):
        raise RequestError(400, f"expected must be 1 or 0, got {expected[:40]!r}")
    try:
        return json_response(find_job(server, request).snapshot())
    except RequestError:
        job_id = request.path_params["job"]
        if expected in ("1", "true") and JOB.match(job_id):
            return json_response(unknown_snapshot(job_id))
        raise


async def cancel_job(server, request):
    """``DELETE /api/jobs/{job}``: withdraw one request for it (:meth:`tghop.server.jobs.FitQueue.cancel`)."""
    job = server.queue.cancel(find_job(server, request).id)
    return json_response(job.snapshot())


async def job_events(server, request):
    """``GET /api/jobs/{job}/events``: server-sent events of its progress, then its end."""
    from starlette.responses import StreamingResponse

    job = find_job(server, request)

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
            if server.stopping.is_set():  # the server is stopping (its fits are cancelled): the stream ends
                return
            if idle >= 15.0:  # a comment now and then keeps proxies from closing the stream
                idle = 0.0
                yield ": waiting\n\n"
            await asyncio.sleep(0.1)
            idle += 0.1

    return StreamingResponse(events(), media_type="text/event-stream",
                             headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})
