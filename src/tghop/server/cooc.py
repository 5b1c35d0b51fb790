"""The co-occurrence cGAN (:mod:`tghop.cooc`, Darzi et al.) on the server: checkpoints
uploaded into the cache, their morph and their edit (docs/serve.md, ``/api/cooc``).

* :func:`cooc_cache` -- the checkpoints' cache folder, ``<cache>/cooc/<id>.pt`` (the id is
  the SHA-256 of the file), bounded and kept in memory like the models;
* :func:`store_checkpoint` -- an upload checked by :func:`tghop.cooc.load` (``torch.load``
  with ``weights_only=True``: no code in the file runs) in a temporary file, then renamed;
* :func:`parse_morph` / :func:`parse_edit` -- the JSON of the two generation routes;
* :func:`morph_png` / :func:`edit_png` -- what ``tghop cooc morph`` and ``tghop cooc edit``
  do with crops of the exemplar (:meth:`tghop.cooc.CoocGAN.crop_condition`,
  :meth:`~tghop.cooc.CoocGAN.morph_strip`, :func:`tghop.cooc.paint_condition`,
  :meth:`~tghop.cooc.CoocGAN.generate`), as PNG bytes.

PyTorch (the ``metrics`` extra) is imported only when a checkpoint is read; without it
every route here answers 501 (:func:`require_torch`) and the rest of the server works.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import io
import math

from .._errors import TGHopError
from .cache import ModelCache
from .requests import RequestError, decode_png_field, json_bool

__all__ = ["TORCH_HINT", "COOC_HINT", "MAX_COOC_PIXELS", "MAX_CROPS", "MAX_LENGTH",
           "has_torch", "require_torch", "cooc_cache",
           "store_checkpoint", "summary", "parse_morph", "parse_edit", "morph_png", "edit_png"]

#: The 501 answer without PyTorch.
TORCH_HINT = "the co-occurrence endpoints need PyTorch; install it with: pip install 'tghop[metrics]'"
#: How to make a checkpoint (404 messages).
COOC_HINT = "load it again with \"Load a checkpoint\" in Co-occurrence mode (the API: POST /api/cooc)"
#: Largest co-occurrence image the server makes (the generator's activations at full size
#: are about 16 x 4 bytes a pixel per layer for the small configuration).
MAX_COOC_PIXELS = 2048 * 2048
#: Most crops (labels) of an edit.
MAX_CROPS = 8
#: Longest morph strip, in condition cells.
MAX_LENGTH = 1024


def has_torch() -> bool:
    """Whether PyTorch can be imported (the co-occurrence routes work): ``GET /api``'s ``cooc``."""
    try:
        return importlib.util.find_spec("torch") is not None
    except (ImportError, ValueError):  # torch set to None in sys.modules
        return False


def require_torch() -> None:
    """501 with one line unless PyTorch can be imported."""
    if not has_torch():
        raise RequestError(501, TORCH_HINT)


def _load(path):
    from ..cooc import load

    return load(path)


def cooc_cache(cache_dir, max_bytes) -> ModelCache:
    """The checkpoints' folder, ``<cache_dir>/cooc`` (bounded by ``max_bytes`` on its own)."""
    return ModelCache(cache_dir, max_bytes, folder="cooc", suffix=".pt", load=_load,
                      what="co-occurrence checkpoint", hint=COOC_HINT)


def store_checkpoint(cache: ModelCache, content: bytes, filename: str, wanted=None) -> tuple:
    """Check an uploaded checkpoint and keep it under its SHA-256 (400 if it is not a good
    co-occurrence checkpoint; nothing is left in the cache either way): ``(id, notes)``, ``notes`` what
    reading it warned of, as a model upload's (:meth:`~tghop.server.cache.ModelCache.notes`). ``wanted``: as
    :meth:`~tghop.server.cache.ModelCache.store`'s."""
    from .uploads import note_line

    try:
        cid = cache.store(content, filename, hint="pick a checkpoint downloaded from this page (Download checkpoint) "
                                                           "or written by tghop cooc train", wanted=wanted)
    except RequestError as exc:  # a texture model's file: the loader's advice names the library and the CLI
        if exc.status == 400 and _is_texture_model(content):
            raise RequestError(400, f"{filename} is a tghop model file, not a co-occurrence checkpoint; open it "
                                    "with \"Continue from a saved model\" (the API: POST it to /api/models/upload)"
                               ) from None
        raise
    return cid, [note_line(line) for line in cache.notes(cid, filename) or []]


def _is_texture_model(content: bytes) -> bool:
    """Whether ``content`` is a zip archive holding a tghop model's metadata (``__meta__``)."""
    import zipfile

    try:
        with zipfile.ZipFile(io.BytesIO(content)) as archive:
            return "__meta__.npy" in archive.namelist()
    except (zipfile.BadZipFile, OSError, EOFError, NotImplementedError, ValueError):
        return False


@functools.lru_cache(maxsize=1)
def _builtin_hashes() -> dict:
    """``{exemplar hash: name}`` of the built-in exemplars as ``tghop cooc train builtin:NAME``
    reads them (the hash a checkpoint stores: SHA-1 of the 8-bit pixels, 16 hex digits)."""
    import numpy as np

    from ..data import BUILTIN, builtin

    return {hashlib.sha1(np.round(builtin(name) * 255).astype(np.uint8).tobytes()).hexdigest()[:16]: name
            for name in sorted(BUILTIN)}


def summary(cache: ModelCache, cid: str) -> dict:
    """What the page needs of a checkpoint: the exemplar's shape (to pick crops on), the
    crop size, ``s`` (crop positions are rounded down to multiples of it), the training
    steps, and ``builtin``: the built-in exemplar it was trained on, or None. Kept once made
    (:meth:`~tghop.server.cache.ModelCache.keep_summary`: the file of an id never changes), as a
    model's; the file's size is read first, so that a file the bound drops meanwhile is 404."""
    known = cache.summary(cid)  # made while this one waited its turn
    if known is not None:
        return known
    try:
        file_bytes = cache.path(cid).stat().st_size
    except FileNotFoundError:
        raise cache.missing(cid) from None
    model = cache.load(cid)  # 404 when the file went since
    st = model.settings_
    made = {"id": cid, "file_bytes": file_bytes, "exemplar_shape": list(model.exemplar_shape_),
            "crop_size": int(st["crop_size"]), "s": int(model.s), "n_clusters": int(st["n_clusters"]),
            "step": int(model.step_), "n_steps": int(st["n_steps"]), "exemplar_hash": model.exemplar_hash_,
            "builtin": _builtin_hashes().get(model.exemplar_hash_)}
    cache.keep_summary(cid, made)
    return made


# ------------------------------------------------------------------ the JSON
def _int(name, value, low, high, *, none_ok=False):
    if value is None and none_ok:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise RequestError(422, f"{name} must be an integer from {low} to {high:,}{' or null' if none_ok else ''}, "
                                f"got {str(value)[:40]!r}")
    return value


def _crop(name, value):
    """A crop's position ``[y, x]`` (pixels of the exemplar, >= 0): ``(y, x)``."""
    if (not isinstance(value, (list, tuple)) or len(value) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v < 2**31 for v in value)):
        raise RequestError(422, f"{name} must be a crop's position [y, x] in pixels of the exemplar, "
                                f"got {str(value)[:60]!r}")
    return int(value[0]), int(value[1])


def _object(body, known, example):
    if not isinstance(body, dict):
        raise RequestError(400, f"the body must be a JSON object, e.g. {example}")
    unknown = [k for k in body if k not in known]
    if unknown:
        raise RequestError(422, f"unknown field {str(unknown[0])[:40]!r}; known: {', '.join(known)}")
    return body


def _common(body) -> tuple:
    seed = _int("seed", body.get("seed"), 0, 2**63 - 1, none_ok=True)
    return seed, json_bool("windows", body.get("windows"))


def parse_morph(body) -> tuple:
    """The JSON of ``POST /api/cooc/{id}/morph`` -> ``(a, b, crop, length, seed, windows)``.

    ``a``, ``b``: crop positions ``[y, x]``; ``crop``: the crops' side in pixels (null: the
    checkpoint's training crop size); ``length``: the strip's length in cells (2 to
    :data:`MAX_LENGTH`, default 8); ``seed``; ``windows``.
    """
    body = _object(body, ("a", "b", "crop", "length", "seed", "windows"),
                   '{"a": [0, 0], "b": [64, 64], "length": 8, "seed": 1}')
    for name in ("a", "b"):
        if name not in body:
            raise RequestError(422, f"no {name}: give \"a\" and \"b\", the crops' positions [y, x] in the exemplar")
    a, b = _crop("a", body["a"]), _crop("b", body["b"])
    crop = _int("crop", body.get("crop"), 1, 8192, none_ok=True)
    length = _int("length", body.get("length", 8), 2, MAX_LENGTH)
    return (a, b, crop, length, *_common(body))


def _boost(value):
    """``boost``: ``[a, b, factor]`` (colour clusters, checked against the checkpoint's
    ``n_clusters`` by :func:`tghop.cooc.boost_condition`; a finite factor from 0 to the library's
    :data:`tghop.cooc.assembly.MAX_BOOST`) or null."""
    if value is None:
        return None
    from ..cooc.assembly import MAX_BOOST  # NumPy's, not PyTorch's: only when a boost is given

    if (isinstance(value, list) and len(value) == 3
            and all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v < 2**31 for v in value[:2])
            and isinstance(value[2], (int, float)) and not isinstance(value[2], bool)
            and math.isfinite(value[2]) and 0 <= value[2] <= MAX_BOOST):
        return int(value[0]), int(value[1]), float(value[2])
    raise RequestError(422, f"boost must be [a, b, factor]: two colour clusters (0 to the checkpoint's n_clusters - 1) "
                            f"and a factor from 0 to {MAX_BOOST:g}, e.g. [0, 1, 2]; got {str(value)[:60]!r}")


def parse_edit(body) -> tuple:
    """The JSON of ``POST /api/cooc/{id}/edit`` -> ``(size, labels PNG bytes or None, crops,
    boost, seed, windows)``.

    ``size``: ``[height, width]`` (or one number; default the labels' size, or ``[256, 256]``
    without labels; at most :data:`MAX_COOC_PIXELS` pixels; None is returned for the labels'
    size); ``crops``: 1 to :data:`MAX_CROPS` positions ``[y, x]``,
    one per label; ``labels``: a PNG of ``size`` as base64, one flat grey level per crop, the
    darkest for the first (:func:`tghop.guides.guide_labels`; may be left out with one crop);
    ``boost``: ``[a, b, factor]`` or null (``tghop cooc edit --boost A,B,FACTOR``,
    :func:`tghop.cooc.boost_condition`); ``seed``; ``windows``.
    """
    from .._images import check_size

    body = _object(body, ("size", "labels", "crops", "boost", "seed", "windows"),
                   '{"size": [256, 256], "crops": [[0, 0], [64, 64]], "labels": "<PNG as base64>", "seed": 1}')
    crops = body.get("crops")
    if not isinstance(crops, list) or not 1 <= len(crops) <= MAX_CROPS:
        raise RequestError(422, f"crops must be a list of 1 to {MAX_CROPS} crop positions [y, x] (one per label), "
                                f"got {str(crops)[:60]!r}")
    crops = [_crop(f"crops[{i}]", c) for i, c in enumerate(crops)]
    labels = body.get("labels")
    size = body.get("size")
    try:
        size = None if size is None and labels is not None else check_size(
            [256, 256] if size is None else size, limit=MAX_COOC_PIXELS, name="size")
    except TGHopError as exc:
        raise RequestError(422, str(exc)) from None
    if labels is None and len(crops) > 1:
        raise RequestError(422, f"{len(crops)} crops but no labels: send labels, a PNG painted with one grey "
                                "level per crop (the darkest for the first)")
    boost = _boost(body.get("boost"))
    return (size, None if labels is None else decode_png_field(labels, "labels", paint="one grey level per crop"),
            crops, boost, *_common(body))


# ------------------------------------------------------------------ the work
def _png(image) -> bytes:
    from ..imageio import to_uint8, write_png

    buf = io.BytesIO()
    write_png(buf, to_uint8(image))
    return buf.getvalue()


def _conditions(model, crops, crop=None):
    try:
        return [model.crop_condition(y, x, crop) for y, x in crops]
    except TGHopError as exc:  # a crop outside the exemplar
        raise RequestError(422, str(exc)) from None


def _reported(progress):
    """``progress`` (a generation's callback: stages ``generating``, then ``encoding``), or one doing nothing."""
    return progress if progress is not None else (lambda stage, done, total: None)


def morph_png(model, a, b, crop, length, windows, seed, progress=None) -> tuple:
    """``tghop cooc morph MODEL crop:A crop:B --length LENGTH``: ``(png, (h, w))``; ``progress(stage, done,
    total)`` told ``generating`` before and after the generator's pass, then ``encoding``."""
    progress = _reported(progress)
    s = model.s
    side = max(1, int(model.settings_["crop_size"] if crop is None else crop) // s) * s
    if side * length * s > MAX_COOC_PIXELS:
        raise RequestError(422, f"a {side}x{length * s} strip is over the server's {MAX_COOC_PIXELS:,} pixels; "
                                "ask for a shorter strip or smaller crops")
    ca, cb = _conditions(model, [a, b], crop)
    progress("generating", 0, 1)
    try:
        image = model.morph_strip(ca, cb, length=length, rng=seed, windows=windows)
    except MemoryError:
        raise RequestError(422, "out of memory; ask for a shorter strip") from None
    progress("generating", 1, 1)
    progress("encoding", 0, 1)
    return _png(image), image.shape[:2]


def edit_png(model, size, labels, crops, boost, windows, seed, read_labels, progress=None) -> tuple:
    """``tghop cooc edit MODEL crop:... --mask LABELS [--boost A,B,FACTOR]``: every crop's
    statistics where its label is painted (each cell of ``s`` x ``s`` pixels takes its centre
    pixel's label), bin ``(a, b)`` of every cell times ``factor`` with a ``boost``:
    ``(png, (h, w), told)``, ``told`` what to tell the client (a label map scaled to ``size``:
    the library's warning, in the answer's ``X-Tghop-Warning``). ``read_labels(png bytes)``
    decodes the label map's image; ``progress``: as :func:`morph_png`'s."""
    import numpy as np

    from ..cooc import boost_condition, cell_labels, paint_condition
    from .._errors import collect_warnings
    from ..guides import guide_labels

    tensors = _conditions(model, crops)
    pixels, told = None, []
    if labels is not None:
        painted = read_labels(labels)
        if size is None:
            size = painted.shape[:2]
            if size[0] * size[1] > MAX_COOC_PIXELS:
                raise RequestError(422, f"labels is {size[0]}x{size[1]}, over the server's {MAX_COOC_PIXELS:,} pixels")
        # The library's warning of one scaled to the size, collected on this thread (it would go to the server's
        # console), is the client's header instead.
        try:
            with collect_warnings() as said:
                pixels = guide_labels(painted, len(crops), size=size, input_name="crop", no_guide="send no labels",
                                      names=[f"crops[{i}]" for i in range(len(crops))], guide_name="the label map")
        except TGHopError as exc:  # a region that the scaling to the size loses too
            raise RequestError(400, str(exc).replace("the guide", "the label map")) from None
        told.extend(str(w).replace("the guide", "the label map") for w in said)
    s, (h, w) = model.s, size
    hh, ww = -(-h // s), -(-w // s)
    cells = np.zeros((hh, ww), dtype=np.int64) if pixels is None else cell_labels(pixels, s)
    cond = paint_condition(tensors, cells)
    if boost is not None:
        try:
            cond = boost_condition(cond, *boost)
        except TGHopError as exc:
            raise RequestError(422, f"boost {list(boost)}: {exc}") from None
    progress = _reported(progress)
    progress("generating", 0, 1)
    try:
        image = model.generate(cond, rng=seed, windows=windows)[:h, :w]
    except MemoryError:
        raise RequestError(422, "out of memory; ask for a smaller image") from None
    except TGHopError as exc:
        if boost is None:
            raise
        raise RequestError(422, f"boost {list(boost)}: {exc}; use a factor above 0") from None  # a cell emptied
    progress("generating", 1, 1)
    progress("encoding", 0, 1)
    return _png(image), image.shape[:2], told
