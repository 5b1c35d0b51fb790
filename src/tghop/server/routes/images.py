"""Images on the web server: one model's (``POST /api/models/{id}/images``), several models
through a painted guide or a remix (``POST /api/images/guided``), a morph between two (``POST
/api/images/morph``); docs/serve.md. Each runs on a generation thread
(:meth:`tghop.server.core.Server.in_executor`) under the bound on generations; a material's
answer is every map (:func:`tghop.server.materials.answer`)."""

from __future__ import annotations

import io
import secrets
import time

from ..._errors import TGHopError
from ...settings import BY_NAME
from .. import materials
from ..core import json_response
from ..requests import RequestError, page_words, parse_generation, parse_guide_labels, parse_guided, parse_morph
from ..uploads import MAX_UPLOAD_BYTES, json_body, read_image

#: The patch size of the page's fits (it has no field for another).
DEFAULT_PATCH = BY_NAME["patch_size"].default

__all__ = ["header_text", "check_patch_refine", "model_png", "png_response", "generate", "several_png", "same_patches",
           "guided_png", "guided", "morph_png", "morph", "read_guide", "guide_label_map", "guide_labels_route",
           "WARNING_HEADER", "PAGE_RESHAPE", "PAGE_ENLARGE", "models_notes"]

#: The answer's header that tells the client what the library warned of (one line, its words; several joined by
#: "; "): a painted guide scaled to the size asked, what reading it said (a colour profile converted; docs/serve.md).
WARNING_HEADER = "X-Tghop-Warning"


def header_text(lines) -> str:
    """``lines`` joined by "; " as a header's value: printable ASCII, any other character "?" (a colour
    profile's name, from the upload, may hold any)."""
    return "".join(c if " " <= c <= "~" else "?" for c in "; ".join(page_words(line) for line in lines))


def models_notes(server, ids) -> list:
    """What reading the files of the models ``ids`` warned of (a model made by a newer tghop, statistics of an old
    one not used), told with every image made of them as ``tghop synth`` warns at each run, first in the answer's
    :data:`WARNING_HEADER` (:meth:`~tghop.server.cache.ModelCache.model_notes`)."""
    return [line for model_id in dict.fromkeys(ids) for line in server.cache.model_notes(model_id)]


def check_patch_refine(model, settings, name: str) -> None:
    """422 where ``settings`` ask for the patch refinement (``patch_refine``, ``quality`` best) of a ``model`` that
    has no patch statistics, ``name`` naming it (``this model``, ``models[1]``): a model fitted without them (as
    ``tghop synth`` says; the library's words called a guided route's model "input 2"), or a material whose albedo
    has none (fitted by tghop 0.58: 0.59 patch-refines a material's albedo; 0.60 a painted or remixed one's too)."""
    if not settings.get("patch_refine"):
        return
    if materials.is_material(model):
        if model.albedo_patches() is None:
            raise RequestError(422, f"{name} is a material without patch statistics of its albedo for patch_refine "
                                    "or quality best (fitted by tghop 0.58 or older, or with patch_levels 0); fit it "
                                    "again")
        return
    if getattr(model, "patches_", None) is None:
        raise RequestError(422, f"{name} holds no patch statistics for patch_refine or quality best (fitted "
                                "with patch_levels 0, or by tghop 0.14 or older); fit it again")


def model_png(server, model_id: str, size, seed, settings):
    """One model's image as PNG bytes; a material's maps as a list (:func:`materials.encode_maps`)."""
    import numpy as np

    from ...imageio import write_png

    model = server.model(model_id)  # read before, in its turn, when not in memory (png_response's models)
    material = materials.is_material(model)
    check_patch_refine(model, settings, "this model")  # a material's albedo is refined by it too (0.59)
    with server.generating:
        try:
            image = model.synthesize(size, rng=seed, dtype=np.float32 if material else np.uint8,
                                     progress=server.unless_stopping, **settings)
        except MemoryError:
            raise RequestError(422, "out of memory; ask for a smaller image") from None
        except TGHopError as exc:
            raise RequestError(422, str(exc)) from None
    server.unless_stopping("encoding", 0, 1)  # the PNG (a job's last stage)
    if material:
        return materials.encode_maps(image, model)
    buf = io.BytesIO()
    write_png(buf, image)
    return buf.getvalue()


async def png_response(server, request, work, *args, seed, models=(), checkpoints=()):
    """Run ``work(*args, seed)`` on a generation thread once the ``models`` and ``checkpoints`` (ids) it needs
    are read (:meth:`~tghop.server.core.Server.in_executor`): its ``(png, (h, w))`` as the answer, or
    ``(maps, (h, w))`` of a material (a list, :func:`materials.encode_maps`) as JSON or multipart; a third
    item, warnings to tell the client (lines), goes in :data:`WARNING_HEADER`."""
    from starlette.responses import Response

    if seed is None:
        seed = secrets.randbelow(2**31)
    start = time.perf_counter()
    png, size, *told = await server.in_executor(request, work, *args, seed, models=models, checkpoints=checkpoints)
    took = (time.perf_counter() - start) * 1000
    headers = {"X-Tghop-Seed": str(seed), "X-Tghop-Size": f"{size[0]}x{size[1]}",
               "Server-Timing": f"generate;dur={took:.1f}", "Cache-Control": "no-store"}
    told = [*models_notes(server, models), *(told[0] if told else [])]
    if told:
        headers[WARNING_HEADER] = header_text(told)
    if isinstance(png, list):  # a material: every map, as multipart where the client takes it (the page)
        body, kind = materials.answer(request.headers.get("accept", ""), png, size, seed)
        return Response(body, headers=headers, media_type=kind)
    return Response(png, media_type="image/png", headers=headers)


async def generate(server, request):
    """``POST /api/models/{id}/images``."""
    model_id = request.path_params["id"]
    server.cache.path(model_id)  # 404 for a malformed id before the body is read
    size, seed, settings = parse_generation(await json_body(request))

    def work(seed):
        return model_png(server, model_id, size, seed, settings), size

    return await png_response(server, request, work, seed=seed, models=[model_id])


def several_png(server, make, models, seed) -> tuple:
    """``make(models, seed, dtype)`` under the bound on generations: the PNG and its size (the
    maps of materials: a list, :func:`materials.encode_maps`)."""
    import numpy as np

    from ...imageio import write_png

    material = materials.is_material(models[0])
    with server.generating:
        try:
            image = make(models, seed, np.float32 if material else np.uint8)
        except MemoryError:
            raise RequestError(422, "out of memory; ask for a smaller image") from None
        except TGHopError as exc:  # models that cannot be combined, a setting the library refuses
            raise RequestError(422, str(exc)) from None
    server.unless_stopping("encoding", 0, 1)
    if isinstance(image, dict):  # materials (the library checked that all are, with the same maps)
        return materials.encode_maps(image, models[0]), next(iter(image.values())).shape[:2]
    buf = io.BytesIO()
    write_png(buf, image)
    return buf.getvalue(), image.shape[:2]


def same_patches(models, names) -> None:
    """Models to combine have one patch size, or 422 naming them as the request does, and the fix on the page (its
    fits' patch size) and the API's fit field (the library's words name the command line's --patch-size; 0.61 named
    the API's field alone, "fit them with the same patch_size (a field of POST /api/models)")."""
    p = materials.patch_size(models[0])
    for name, model in zip(names[1:], models[1:]):
        q = materials.patch_size(model)
        if q != p:
            raise RequestError(422, f"{name} has {q}x{q} patches but {names[0]} has {p}x{p}; give models of one "
                                    f"patch size: fit both on this page (its fits have {DEFAULT_PATCH}x{DEFAULT_PATCH} "
                                    "patches; the API's fit field patch_size sets another)")


def read_guide(guide: bytes, n_models: int, size, **words) -> tuple:
    """A painted guide's PNG bytes -> ``(labels, told)``: its labels as uint8 (grey levels 0, 1, ...; at most 8
    models), read once by :func:`tghop.guides.guide_labels` (soft or JPEG edges snapped to the flat levels; a
    guide of another size but the shape of ``size`` scaled to it), and what to tell the client (what reading it
    said, as :func:`read_image`'s notes; a guide scaled: the library's warning, collected on this thread instead
    of the server's console). Its refusals are 400 in the library's words (``words``: guide_labels' names)."""
    import numpy as np

    from ..._errors import collect_warnings
    from ...guides import guide_labels
    from ...imageio import load_image

    told = []
    painted = read_image(guide, "guide.png", lambda p: load_image(p, dtype=None), notes=told)
    try:
        with collect_warnings() as said:
            labels = guide_labels(painted, n_models, size=size, **words)
    except TGHopError as exc:  # another count of levels, another shape, a region the scaling loses
        raise RequestError(400, str(exc)) from None
    told.extend(str(w) for w in said)
    return labels.astype(np.uint8), told


#: The page's fix of a guide of another shape than its canvas ("Use a guide..."): the page cannot leave the size
#: out, as the API can; its height and width can take the guide's shape ({h} and {w}: the guide's).
PAGE_RESHAPE = ("set the height and width above to the guide's shape (e.g. {h} and {w}; a guide of the canvas's "
                "shape is scaled to its size), or paint the guide at the canvas's shape")
#: The page's fix of a region that the scaling to the canvas loses.
PAGE_ENLARGE = "paint it wider, or set a larger height and width above"


def guide_label_map(guide: bytes, n_models: int, size) -> dict:
    """``POST /api/guides/labels``'s answer: the guide's labels as the guided route reads them
    (:func:`read_guide`), in the page's words (models, painting the canvas instead of a guide, and the page's
    height and width: :data:`PAGE_RESHAPE`, :data:`PAGE_ENLARGE`):
    ``{"size": [h, w], "labels": base64 of the (h, w) uint8 labels row by row, "notes": [...]}``."""
    import base64

    labels, told = read_guide(guide, n_models, size, input_name="model", no_guide="paint the canvas instead",
                              reshape=PAGE_RESHAPE, enlarge=PAGE_ENLARGE, size_name="the canvas's size")
    return {"size": list(labels.shape), "labels": base64.b64encode(labels.tobytes()).decode("ascii"), "notes": told}


async def guide_labels_route(server, request):
    """``POST /api/guides/labels``: a guide painted elsewhere read as :func:`guided` reads it (the page's "Use a
    guide..."), on a decoding thread (:meth:`~tghop.server.core.Server.decode`)."""
    guide, n_models, size = parse_guide_labels(await json_body(request, limit=MAX_UPLOAD_BYTES))
    return json_response(await server.decode(request, guide_label_map, guide, n_models, size))


def guided_png(server, ids, guide, size, transition, settings, seed) -> tuple:
    """Several models through a painted guide (its PNG's bytes), or a remix (None): the PNG (a material's
    maps), its size and what to tell the client (what reading the guide said, as :func:`read_image`'s notes; a
    guide scaled to ``size``: the library's warning)."""
    from ...guided import synthesize_guided

    models = [server.model(model_id) for model_id in ids]
    materials.same_kind(models, ids)
    same_patches(models, [f"models[{i}]" for i in range(len(models))])
    for i, model in enumerate(models):
        check_patch_refine(model, settings, f"models[{i}]")
    labels, told = None, []
    if guide is not None:  # its labels read once (a guide of another size was scaled twice when read again)
        labels, told = read_guide(guide, len(models), size, names=[f"models[{i}]" for i in range(len(models))],
                                  input_name="model", no_guide="send no guide (a remix)")
    png, shape = several_png(server, lambda m, rng, dtype: synthesize_guided(
        m, labels, size=size, transition=transition, rng=rng, dtype=dtype, progress=server.unless_stopping,
        **settings), models, seed)
    return png, shape, told


async def guided(server, request):
    """``POST /api/images/guided``."""
    ids, guide, size, seed, transition, settings = parse_guided(
        await json_body(request, limit=MAX_UPLOAD_BYTES))
    for model_id in ids:
        server.cache.path(model_id)  # 404 for a malformed id before any work
    return await png_response(server, request, guided_png, server, ids, guide, size, transition, settings, seed=seed,
                              models=ids)


def morph_png(server, ids, size, stations, settings, seed) -> tuple:
    """A morph from model ``ids[0]`` to ``ids[1]`` (texture models, or materials with the same maps since 0.60, as
    ``tghop morph`` takes them: every map morphed alike; of one patch size); ``stations`` (no longer applies) is told
    in the answer's warning header, not passed on (the library's warning would go to the server's console)."""
    from ...guided import STATIONS_GONE
    from ...guided import morph as morph_strip

    models = [server.model(model_id) for model_id in ids]
    # In a person's words: the page's A and B, each model as it lists it (0.59 refused every material)
    materials.same_kind(models, ids, names=["A", "B"], verb="morph", every="two")
    same_patches(models, ["a", "b"])
    png, shape = several_png(server, lambda m, rng, dtype: morph_strip(
        m[0], m[1], size, rng=rng, dtype=dtype, progress=server.unless_stopping, **settings), models, seed)
    return png, shape, [] if stations is None else [STATIONS_GONE]


async def morph(server, request):
    """``POST /api/images/morph``."""
    a, b, size, seed, stations, settings = parse_morph(await json_body(request))
    for model_id in (a, b):
        server.cache.path(model_id)
    return await png_response(server, request, morph_png, server, [a, b], size, stations, settings, seed=seed,
                              models=[a, b])
