"""Filling on the web server: a hole in a picture (``POST /api/models/{id}/inpaint``, the fields
``image``, ``mask``, ``seed``, ``tile``) or a picture grown to a larger canvas (``POST
/api/models/{id}/extend``, ``image``, ``size``, ``anchor``, ``seed``, ``tile``), with a model's
texture, as ``tghop inpaint`` and ``tghop extend`` do; a material's maps come along as ``map:<name>``
fields, and ``fill`` k asks for the k-th fill of the seed, as ``--count`` numbers them (docs/serve.md)."""

from __future__ import annotations

import hashlib
import io
import re
import secrets

from ..._errors import TGHopError
from .. import materials
from ..requests import RequestError, parse_bool, parse_growth, safe_name
from ..uploads import MAX_FIT_BYTES, each_file_within, read_body, read_form, read_image
from .images import WARNING_HEADER, header_text, models_notes

__all__ = ["fill_png", "inpaint", "extend", "fill_request", "mask_note", "grey_mask_note", "fill_key", "MAX_FILL"]

#: The most a request's ``fill`` k may be (the page's strip of fills: 1 to 8): fill k of a seed not kept in
#: :class:`~tghop.server.cache.FillStates` draws the k - 1 before it again.
MAX_FILL = 8


def mask_note(filename: str) -> str:
    """The note of a mask ``filename`` with transparent pixels: its alpha channel is not read as the hole (as
    ``tghop inpaint`` warns of its MASK), its white pixels are."""
    return (f"{filename} has transparent pixels, but transparency is not read as the hole (its white pixels are "
            "the hole); paint the hole white on black")


def grey_mask_note(filename: str, share: float) -> str:
    """The note of a mask ``filename`` that is not black and white (``share`` of its pixels grey or coloured, over
    :data:`tghop.inpaint.MASK_PICTURE_SHARE`: a picture, or the picture and its mask swapped), as ``tghop inpaint``
    warns of its MASK: its pixels lighter than mid-grey are the hole. The fix in the request's words, not the
    command line's (which names the order of IMAGE and MASK)."""
    return (f"{filename} is not black and white: {share:.0%} of its pixels are grey or coloured (a picture?), and "
            "those lighter than mid-grey are taken as the hole; paint the hole white on black (the picture is the "
            "field 'image', its mask 'mask')")


def fill_key(model_id: str, fields: dict, seed: int, tile: bool, grow) -> str:
    """What makes the fills of two requests one sequence (:class:`~tghop.server.cache.FillStates`): the model, the
    picture, its mask or growth, the maps (names and bytes), the seed and tile."""
    digest = hashlib.sha256(f"{model_id}\0{seed}\0{tile}\0{grow}".encode())
    for name in sorted(k for k in fields if k not in ("fill", "seed", "tile", "size", "anchor")):
        value = fields[name]
        content = value[1] if isinstance(value, tuple) else str(value).encode()
        digest.update(b"\0" + name.encode() + b"\0" + hashlib.sha256(content).digest())
    return digest.hexdigest()


def fill_png(server, model_id: str, fields: dict, seed: int, tile: bool, grow, k: int = 1):
    """Read the picture and its mask (``grow`` None) or grow the picture to ``grow``'s
    ``(size, anchor)`` (:func:`tghop.inpaint.expand_canvas`), and fill the mask's white
    pixels or the new area with the model's texture (:func:`tghop.inpaint.inpaint`): the
    PNG's bytes. As ``tghop inpaint`` and ``tghop extend`` do (their code): an alpha channel
    is kept (opaque where filled), and so are 16 bits per channel (a float picture: 16
    bits, the most a PNG holds). A material fills its maps too (``map:<name>`` fields):
    ``(maps, (h, w))`` (:func:`materials.fill`). Returned with what reading the uploads said (lines,
    :func:`read_image`'s notes: a colour profile converted, only a first frame read; a mask's transparency,
    :func:`mask_note`; a mask that is not black and white, :func:`grey_mask_note`), for the answer's
    :data:`~tghop.server.routes.images.WARNING_HEADER`. ``k``: the k-th fill drawn from the seed's generator, as
    ``tghop inpaint --count`` numbers its fills (0.61), from fill k - 1's where :attr:`Server.fill_states` keeps it,
    else from the seed, the fills before drawn again and dropped."""
    import numpy as np

    from ..._errors import HINT_DOWNSCALE_YOURSELF
    from ...imageio import deepest, load_image, to_uint8, to_uint16, write_png
    from ...inpaint import MASK_PICTURE_SHARE, check_hole, expand_canvas, grey_share, require_hole, split_alpha
    from ...inpaint import with_alpha
    from ...inpaint import inpaint as fill_hole

    model = server.model(model_id)  # read before, in its turn, when not in memory (fill_request)
    uploads = materials.map_uploads(fields)  # a material's maps (none for a texture model)
    if uploads and not materials.is_material(model):
        raise RequestError(422, f"model {model_id[:12]} is a texture model; map:<name> fields go with a material")
    picture = mask = None
    told = []  # what reading the uploads said, in the order read
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
            picture, depth = read_image(content, filename, lambda p: load_image(
                p, dtype=None, too_large_hint=HINT_DOWNSCALE_YOURSELF, with_depth=True, keep_alpha=True),
                notes=told)
            picture, alpha = split_alpha(picture)
            picture_name, p, (h, w) = filename, materials.patch_size(model), picture.shape[:2]
            if not grow and min(h, w) < p:  # 0.61: the library's "use a model fitted with a smaller patch_size"
                raise RequestError(400, f"the picture {filename} is {h}x{w}, smaller than the model's {p}x{p} "
                                        f"patches; use a picture of at least {p}x{p}, or grow it first (Extend)")
            if grow:  # 0.61: the library's "the size HxW ..." and "a model fitted with a smaller patch_size"
                check_growth(filename, (h, w), grow[0], p)
        else:  # its alpha apart: a transparent part is said as tghop inpaint says it (not an exemplar's words)
            read = read_image(content, filename, lambda p: load_image(
                p, dtype=np.float32, too_large_hint=HINT_DOWNSCALE_YOURSELF, keep_alpha=True), notes=told)
            if read.shape[2] in (2, 4):
                if (read[..., -1] < 1).any():
                    told.append(mask_note(filename))
                read = read[..., :-1]
            grey = grey_share(read)
            if grey > MASK_PICTURE_SHARE:  # as tghop inpaint warns: its light pixels are the hole
                told.append(grey_mask_note(filename, grey))
            mask, mask_name = read.mean(axis=2), filename
            if mask.shape != picture.shape[:2]:  # 0.61: the library's "give an (H, W) or (H, W, C) mask"
                raise RequestError(400, f"the mask {filename} is {mask.shape[0]}x{mask.shape[1]} but the picture "
                                        f"{picture_name} is {h}x{w}; give a mask of the picture's size")
    try:
        if grow:
            picture, hole, _ = expand_canvas(picture, grow[0], anchor=grow[1],
                                             patch_size=materials.patch_size(model))  # as tghop.inpaint.extend
            alpha = None if alpha is None else expand_canvas(alpha, grow[0], anchor=grow[1])[0]
        else:
            hole = check_hole(mask, picture.shape)
            require_hole(hole, f"the mask {mask_name}")  # as tghop inpaint: nothing would change
    except TGHopError as exc:
        raise RequestError(400, str(exc)) from None
    key = fill_key(model_id, fields, seed, tile, grow)
    done, state = server.fill_states.after(key, k)
    rng = np.random.default_rng(seed)
    if state is not None:
        rng.bit_generator.state = state
    with server.generating:
        for j in range(done + 1, k + 1):  # the fills before k not kept: drawn again, and dropped
            progress = server.unless_stopping if j == k else (lambda *_: server.unless_stopping())
            if materials.is_material(model):  # every map alike
                filled = materials.fill(model, picture, alpha, hole, uploads, lambda data, filename, load: (
                    read_image(data, filename, load, notes=told if j == k else [])), depth=depth, grow=grow,
                    seed=rng, tile=tile, progress=progress)
            else:
                try:
                    filled = fill_hole(model, picture, hole, rng=rng, tile=tile, progress=progress,
                                       order="edge" if grow is None else "raster")  # as tghop.inpaint.extend (0.60)
                except MemoryError:
                    raise RequestError(413, "out of memory; send a smaller picture") from None
                except TGHopError as exc:
                    raise RequestError(400, str(exc)) from None
            server.fill_states.keep(key, j, rng.bit_generator.state)
    if materials.is_material(model):
        return filled, told
    server.unless_stopping("encoding", 0, 1)
    filled = with_alpha(filled, alpha, hole)  # a PNG holds it
    buf = io.BytesIO()
    write_png(buf, to_uint16(filled) if deepest("filled.png", depth) == 16 else to_uint8(filled))
    return buf.getvalue(), told


async def inpaint(server, request):
    """``POST /api/models/{id}/inpaint``."""
    return await fill_request(server, request, grow=False)


async def extend(server, request):
    """``POST /api/models/{id}/extend``."""
    return await fill_request(server, request, grow=True)


async def fill_request(server, request, *, grow: bool):
    """``POST /api/models/{id}/inpaint`` (the fields image, mask, seed, tile) or
    ``/extend`` (image, size, anchor, seed, tile)."""
    from starlette.responses import Response

    model_id = request.path_params["id"]
    server.cache.path(model_id)  # 404 for a malformed id before the body is read
    # A material's picture comes with its maps: as much in all as its fit
    body = await read_body(request, MAX_FIT_BYTES, what="the upload (the picture and its maps together)")
    names = ("image", "size", "anchor", "seed", "tile", "fill") if grow else ("image", "mask", "seed", "tile", "fill")
    fields = each_file_within(await read_form(
        request, body, "the file field 'image' and the fields 'size' (HEIGHTxWIDTH) and optionally 'anchor', "
        "'seed', 'tile' and 'fill'" if grow else "the file fields 'image' and 'mask', white where to fill; "
        "optionally the fields 'seed', 'tile' and 'fill'"))
    unknown = [k for k in fields if k not in names and not k.startswith(materials.MAP_FIELD)]
    if unknown:
        raise RequestError(422, f"unknown field {unknown[0]!r}; known: {', '.join(names)} (and a material's "
                                "map:<name>)")
    plain = {k: fields.get(k) for k in names if k not in ("image", "mask")}
    files = [k for k, v in plain.items() if isinstance(v, tuple)]
    if files:  # 0.60 named every plain field ("size, anchor, seed, tile: plain fields, not files")
        raise RequestError(422, f"the field {files[0]!r} is sent as a file; send it as a plain field (text)")
    seed = (plain["seed"] or "").strip()
    if seed == "":
        seed = secrets.randbelow(2**31)
    elif not re.fullmatch(r"[0-9]{1,19}", seed) or int(seed) >= 2**63:
        raise RequestError(422, f"seed must be an integer from 0 to 2**63 - 1, got {seed[:40]!r}")
    else:
        seed = int(seed)
    tile = parse_bool("tile", plain["tile"] or "false")
    k = (plain["fill"] or "").strip() or "1"  # blank as empty: the first (0.61 refused " ", "got ''")
    if not re.fullmatch(r"[0-9]{1,19}", k) or not 1 <= int(k) <= MAX_FILL:  # 0.61: "08" taken, "008" refused
        raise RequestError(422, f"fill must be an integer from 1 to {MAX_FILL} (the k-th fill of the seed, as tghop "
                                f"inpaint --count numbers them), got {k[:40]!r}")
    growth = parse_growth(plain["size"], plain["anchor"]) if grow else None
    png, told = await server.in_executor(request, fill_png, server, model_id, fields, seed, tile, growth, int(k),
                                         models=[model_id])
    headers = {"X-Tghop-Seed": str(seed), "X-Tghop-Fill": str(int(k)), "Cache-Control": "no-store"}  # 0.61: "08"
    told = [*models_notes(server, [model_id]), *told]  # reading the model's file, then the picture, mask and maps
    if told:  # what reading them said, as a guide's (one line, printable ASCII)
        headers[WARNING_HEADER] = header_text(told)
    if isinstance(png, tuple):  # a material's maps and their size
        body, kind = materials.answer(request.headers.get("accept", ""), *png, seed)
        return Response(body, media_type=kind, headers=headers)
    return Response(png, media_type="image/png", headers=headers)


def check_growth(filename: str, shape, size, p: int) -> None:
    """400 where Extend's size (``size``) does not grow the picture of ``shape``, or leaves it thinner than the
    model's ``p``x``p`` patches, in the page's words (its fields "grow to height" and "width")."""
    (h, w), (hh, ww) = shape, size
    if hh < h or ww < w or (hh, ww) == (h, w):
        raise RequestError(400, f"the picture {filename} is {h}x{w}; grow it to a size of at least {h}x{w}, larger "
                                f"in one (asked: {hh}x{ww})")
    if min(hh, ww) < p:
        raise RequestError(400, f"the picture {filename} ({h}x{w}) grown to {hh}x{ww} is thinner than the model's "
                                f"{p}x{p} patches; grow it to at least {max(hh, p)}x{max(ww, p)}")
