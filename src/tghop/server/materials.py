"""Whole materials on the web server (docs/serve.md, "Materials"): an albedo fitted with its
maps (:class:`tghop.material.Material`), and a material's images as one answer of every map.

- ``POST /api/models`` takes each map as a file field ``map:<name>`` beside the albedo
  (``image`` or ``builtin``), as ``tghop fit ALBEDO --maps NAME.png ...`` takes files whose
  stems name the maps. The maps are checked (names, sizes) before a fit job starts.
- A material's ``POST /api/models/{id}/images``, and a painted guide or a remix of materials
  (``POST /api/images/guided``), answer every map instead of one PNG, each a PNG at its file's
  depth (8 or 16 bits; a float map's 32 as 16, the most a PNG holds), as ``tghop synth`` writes
  each map, the albedo first: JSON ``{"size": [h, w], "seed": s, "maps": [{"name", "depth",
  "normal", "png"}, ...]}`` with base64 PNGs (:func:`maps_json`), or, for a request that
  accepts ``multipart/form-data`` (the page: a browser's ``Response.formData()`` reads it, a
  third smaller and nothing to decode), a part per map, named by the map, its PNG as a file,
  after a part ``_meta`` with the JSON without the PNGs (:func:`maps_multipart`).
- A material's inpaint and extend (``POST /api/models/{id}/inpaint``, ``/extend``) take its maps
  beside the picture (its albedo) as file fields ``map:<name>``, every map of the material, and
  fill them alike (:func:`tghop.inpaint.inpaint_material`; :func:`fill`): the answer is every
  map, as a generation's. A morph takes texture models only: a material is refused in one
  line (422).
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import secrets

from ..manifest import MAX_MAPS
from .requests import RequestError, check_channel_counts, safe_name

__all__ = ["MAP_FIELD", "MAX_MAPS", "is_material", "map_uploads", "check_colour_map", "read_map", "read_maps",
           "check_channels", "material_id", "same_kind", "patch_size", "encode_maps", "maps_json", "maps_multipart",
           "answer", "fill", "META_PART"]

#: The multipart answer's first part: the maps' names, depths and normal flags as JSON (a map's
#: name cannot begin with "_", so no map's part has this name).
META_PART = "_meta"
#: Prefix of a map's form field: ``map:normal`` is the map named "normal".
MAP_FIELD = "map:"


def is_material(model) -> bool:
    """Whether ``model`` is a whole material (:class:`tghop.material.Material`)."""
    from ..material import Material

    return isinstance(model, Material)


def map_uploads(fields: dict) -> list:
    """Take the maps' fields (``map:<name>``) out of a form (a fit's, an inpaint's or an
    extend's): ``[(name, filename, bytes)]`` in the order sent; 400 for a bad name, a name given
    twice (in any case), a map that is not a file or is empty, or more than :data:`MAX_MAPS`."""
    from ..map_names import MAP_NAME, MAP_NAME_MAX, MapNameClashError, check_map_names

    named = [(field[len(MAP_FIELD):], field) for field in fields if field.startswith(MAP_FIELD)]
    for name, field in named:
        if len(name) > MAP_NAME_MAX and MAP_NAME.fullmatch(name):  # 0.59 said its characters were wrong
            raise RequestError(400, f"the map name {name[:40] + '...'!r} (field 'map:...') is {len(name)} characters, "
                                    f"more than the {MAP_NAME_MAX} a map's name may have (it names the map's file); "
                                    "shorten it")
        if not MAP_NAME.fullmatch(name):
            raise RequestError(400, f"the map name {name[:40]!r} (field {field[:44]!r}) must be letters, digits, "
                                    "'.', '_' or '-', starting with a letter or digit (it names the map's file)")
    try:
        check_map_names([name for name, _ in named])
    except MapNameClashError as exc:
        raise RequestError(400, f"{exc.clash}; {exc.fix} (fields map:NAME)") from None
    out = []
    for name, field in named:
        value = fields.pop(field)
        if not isinstance(value, tuple):
            raise RequestError(400, f"the field {field!r} must be a file upload (the map's image)")
        filename, content = value
        filename = safe_name(filename, f"{name}.png")
        if not content:
            raise RequestError(400, f"the map {name} ({filename}) is empty; send an image file")
        out.append((name, filename, content))
    if len(out) > MAX_MAPS:
        raise RequestError(400, f"{len(out)} maps; a material takes at most {MAX_MAPS}")
    return out


def check_colour_map(filename: str, uploads):
    """A material's colour map out of place (:func:`tghop.map_names.check_colour_map_order`), as ``tghop fit
    --maps`` and a batch manifest's row refuse or warn of it, in the page's words: 400 where the exemplar's
    file (``filename``, the albedo) is named as another kind of map and a map (``uploads``, :func:`map_uploads`)
    as the colour map (the two swapped), or the exemplar's file as a normal map and no map as the colour map
    (its vectors would be modelled as the albedo's colours); the note to give (str; else None) where the
    exemplar's file is named as another kind and no map as the colour map: it is fitted as the colour map,
    as asked (0.57 said nothing). A map's kind is its name's (its field's, ``map:<name>``), else, a name of
    no kind, its file's."""
    from .._errors import TGHopError
    from ..map_names import check_colour_map_order

    try:
        return check_colour_map_order(
            filename, [file for _, file, _ in uploads], names=[name for name, _, _ in uploads],
            shown=[name for name, _, _ in uploads], swap="send {colour}'s file as the exemplar and {albedo} as a map",
            first="send the material's colour map as the exemplar (e.g. Rock_Color.png) and {albedo} as a map")
    except TGHopError as exc:
        raise RequestError(400, str(exc)) from None


def read_map(read, name: str, filename: str, content: bytes, *, normal=None) -> tuple:
    """One map sent as ``map:<name>``: ``(image, depth)``, read as every reader of a material's maps
    reads it (:func:`tghop.material_files.read_map`: as data or colours by ``name``, an alpha that holds
    data refused, a normal map stored turned read upright with its vectors turned), named ``the map NAME
    (FILENAME)`` in a message. ``read(content, filename, load)``: the server's upload reader
    (:func:`tghop.server.uploads.read_image`, its errors 400 or 413); ``normal``: as ``read_map``'s (a
    saved material's flag; None: by the name)."""
    from .._errors import HINT_DOWNSCALE_YOURSELF
    from ..material_files import read_map as read_file

    label = f"the map {name} ({filename})"
    return read(content, filename, lambda path: read_file(path, name, normal=normal, label=label,
                                                          too_large_hint=HINT_DOWNSCALE_YOURSELF))


def read_maps(uploads, read, albedo_shape) -> tuple:
    """The maps' images: ``({name: array}, {name: depth})``, each read by :func:`read_map` (``read``: as
    its). A map of another height and width than the albedo's, or a normal map by its name that holds no
    unit vectors (:func:`tghop.material.check_normal_map`), is refused (400) before a fit job starts."""
    from .._images import check_image
    from .._errors import TGHopError
    from ..map_names import is_normal_name
    from ..material import check_normal_map

    maps, depths = {}, {}
    for name, filename, content in uploads:
        image, depth = read_map(read, name, filename, content)
        if image.shape[:2] != tuple(albedo_shape[:2]):
            h, w = albedo_shape[:2]
            raise RequestError(400, f"the map {name} ({filename}) is {image.shape[0]}x{image.shape[1]} but the "
                                    f"albedo is {h}x{w}; give maps of the albedo's size, aligned with it")
        if is_normal_name(name):
            try:
                check_normal_map(check_image(image[::2, ::2], name=f"map {name!r}"), name)  # a sample: the median
            except TGHopError as exc:
                raise RequestError(400, f"{filename}: {exc}") from None
        maps[name], depths[name] = image, depth
    return maps, depths


def check_channels(joint, albedo, maps: dict) -> None:
    """The joint model's channel counts (``k1``) against the stacked channels of ``albedo`` and
    ``maps`` (:meth:`tghop.material.Material.stacked_channels`), as a texture fit's against its
    exemplar's (:func:`~tghop.server.requests.check_channel_counts`): 422 before a fit job starts."""
    from .._errors import TGHopError
    from ..material import Material

    try:
        stacked = Material(model=joint).stacked_channels(albedo, maps)
    except TGHopError as exc:
        raise RequestError(400, str(exc)) from None
    check_channel_counts(joint, sum(stacked.values()), stacked)


def material_id(albedo_content: bytes, uploads, settings: dict, model_id_for) -> str:
    """The content hash of a material's fit: the albedo's bytes, each map's name and bytes,
    and the settings (``model_id_for`` hashes the first and last)."""
    digest = hashlib.sha256(albedo_content)
    for name, _, content in uploads:
        digest.update(b"\0tghop-map\0" + name.encode() + b"\0" + hashlib.sha256(content).digest())
    return model_id_for(digest.digest(), {**settings, "material": [name for name, _, _ in uploads]})


def same_kind(models, ids, names=None, verb="paint or remix", every="all") -> None:
    """Models to paint or remix (``verb``) together: all texture models, or all materials with the same maps;
    else 422 naming ``models[i]`` (or ``names[i]``: a morph's A and B) and the start of its id (as the page lists
    each model). ``every``: "all", or "two" (a morph's)."""
    from ..material_files import maps_refused  # maps matched by their kinds or suffixes: Stone_Normal, Gravel_Normal

    def named(i):
        return f"{names[i] if names else f'models[{i}]'} ({ids[i][:8]})"

    first = is_material(models[0])
    for i, model in enumerate(models[1:], start=1):
        if is_material(model) != first:
            kinds = ("a texture model", "a material") if first else ("a material", "a texture model")
            raise RequestError(422, f"{named(i)} is {kinds[0]} but {named(0)} is {kinds[1]}; {verb} "
                                    f"{every} materials (with the same maps) or {every} texture models")
        refused = maps_refused(model, models[0], named(i), named(0), given="(the fields map:NAME)") if first else ""
        if refused:  # 0.60: "has the maps albedo, height, normal but ... has albedo, normal, height", in another order
            raise RequestError(422, refused)


def patch_size(model) -> int:
    """A texture model's or a material's patch size (a material's joint model's)."""
    return (model.model_ if is_material(model) else model).patch_size


def encode_maps(maps: dict, material, depths=None) -> list:
    """A material's maps (``name -> (H, W, c)`` floats in [0, 1]) as PNGs: a list of ``{"name",
    "suffix", "depth", "normal", "png"}`` (``suffix``: what the map's file adds to the result's name,
    ``<result>_<suffix>.png``, as ``tghop synth`` names it, :func:`tghop.material_files.map_suffixes`;
    None for the albedo; ``png``: the file's bytes, at the map's depth: 8, else 16 bits), in
    ``material``'s order. ``depths``: ``{name: 8, 16 or 32}``, a depth other than the material's (a
    fill's: the depth of the file sent)."""
    from ..imageio import to_uint8, to_uint16, write_png
    from ..material_files import map_suffixes

    out = []
    for name, suffix, depth, normal in zip(material.names_, map_suffixes(material.names_), material.depths_,
                                           material.normal_):
        depth = (depths or {}).get(name, depth)
        buf = io.BytesIO()
        write_png(buf, to_uint8(maps[name]) if depth == 8 else to_uint16(maps[name]))
        out.append({"name": name, "suffix": suffix, "depth": 8 if depth == 8 else 16, "normal": bool(normal),
                    "png": buf.getvalue()})
    return out


def maps_json(maps: list, size, seed) -> bytes:
    """The JSON answer of :func:`encode_maps`'s ``maps``: each PNG as base64."""
    return json.dumps({"size": list(size), "seed": seed, "maps": [
        {**m, "png": base64.b64encode(m["png"]).decode("ascii")} for m in maps]}).encode()


def maps_multipart(maps: list, size, seed) -> tuple:
    """The ``multipart/form-data`` answer of :func:`encode_maps`'s ``maps`` (RFC 7578): a part
    :data:`META_PART` (the JSON of :func:`maps_json` without the PNGs), then a part per map named
    by it, its PNG as the file ``<name>.png``. Returns ``(body, content type)``."""
    boundary = "tghop-" + secrets.token_hex(16)  # 38 characters: no PNG is likely to hold it at a line start
    meta = {"size": list(size), "seed": seed, "maps": [{k: v for k, v in m.items() if k != "png"} for m in maps]}
    parts = [(f'Content-Disposition: form-data; name="{META_PART}"\r\nContent-Type: application/json',
              json.dumps(meta).encode())]
    parts += [(f'Content-Disposition: form-data; name="{m["name"]}"; filename="{m["name"]}.png"\r\n'
               "Content-Type: image/png", m["png"]) for m in maps]
    body = b"".join(f"--{boundary}\r\n{head}\r\n\r\n".encode() + data + b"\r\n" for head, data in parts)
    return body + f"--{boundary}--\r\n".encode(), f"multipart/form-data; boundary={boundary}"


def answer(accept: str, maps: list, size, seed) -> tuple:
    """``(body, media type)`` of a material's maps (:func:`encode_maps`): multipart where the
    request's ``Accept`` header names ``multipart/form-data`` (the page), else JSON."""
    if "multipart/form-data" in accept:
        return maps_multipart(maps, size, seed)
    return maps_json(maps, size, seed), "application/json"


def fill(material, picture, alpha, hole, uploads, read, *, depth, grow, seed, tile, progress) -> tuple:
    """A material's inpaint or extend: ``picture`` (its albedo, of ``depth`` bits, grown already
    with ``grow``, ``(size, anchor)``, else None) and the maps sent as ``map:<name>`` (``uploads``,
    as :func:`map_uploads` gives them, each read by :func:`read_map` with ``read``), filled
    alike in ``hole`` (:func:`tghop.inpaint.inpaint_material`; the albedo's alpha channel kept,
    opaque in the hole): ``(the maps encoded (:func:`encode_maps`), (h, w))``, each at the depth of
    the file sent, as a texture's fill keeps its picture's and ``tghop inpaint --maps`` writes each
    map (a float file's as 16 bits, the most a PNG holds). A map missing, unknown or of another
    size than the picture is 400."""
    from .._errors import TGHopError
    from ..inpaint import expand_canvas, inpaint_material, with_alpha

    names = material.names_[1:]
    given = {name: (filename, content) for name, filename, content in uploads}
    if sorted(given) != sorted(names):
        missing = {n.lower(): n for n in names if n not in given}
        unknown = [n for n in given if n not in names]
        # 0.60 said the maps' list alone of a map named in another case (map:Normal for normal) or not sent
        if unknown and unknown[0].lower() in missing:
            said = (f"map:{unknown[0]} names its map {missing[unknown[0].lower()]!r} in another case (a field's name "
                    "is matched as it is); ")
        elif unknown:
            said = f"map:{unknown[0]} is no map of this material; "
        else:
            said = f"the map {next(iter(missing.values()))!r} was not sent; "
        raise RequestError(400, f"{said}this material's maps are {', '.join(names)}; send each of them, and no "
                                "other, as the file field map:<name> beside the picture (its albedo)")
    known = ~hole  # grown: the picture as sent is the known rectangle
    shape = picture.shape[:2] if grow is None else (int(known.any(axis=1).sum()), int(known.any(axis=0).sum()))
    maps, depths = {}, {"albedo": depth}
    for name, normal in zip(names, material.normal_[1:]):
        image, depths[name] = read_map(read, name, given[name][0], given[name][1], normal=bool(normal))
        if image.shape[:2] != shape:  # before it is grown: a map of another size would be grown to the same
            raise RequestError(400, f"the map {name} ({given[name][0]}) is {image.shape[0]}x{image.shape[1]} but the "
                                    f"picture is {shape[0]}x{shape[1]}; give maps of its size")
        maps[name] = image if grow is None else expand_canvas(image, grow[0], anchor=grow[1])[0]
    try:
        filled = inpaint_material(material, {"albedo": picture, **maps}, hole, rng=seed, tile=tile, progress=progress,
                                  **({"order": "raster"} if grow is not None else {}))
    except MemoryError:
        raise RequestError(413, "out of memory; send a smaller picture") from None
    except TGHopError as exc:
        raise RequestError(400, str(exc)) from None
    filled["albedo"] = with_alpha(filled["albedo"], alpha, hole)
    return encode_maps(filled, material, depths), picture.shape[:2]
