"""The requests' fields, checked (docs/serve.md): a fit's form fields (``POST /api/models``)
and the JSON bodies of the generation routes: one image from a model (``POST
/api/models/{id}/images``), several models through a painted guide or a remix (``POST
/api/images/guided``), a morph between two (``POST /api/images/morph``).

Every bad value is a :class:`RequestError` with its status and one line: 400 for a body
that is not a JSON object or a guide that is not base64, 422 for a setting out of its
range or unknown, a size over the output limit.
"""

from __future__ import annotations

import base64
import binascii
import re
import unicodedata
import urllib.parse

from .. import manifest
from .._errors import TGHopError

__all__ = ["RequestError", "check_channel_counts", "check_multipart_end", "decode_png_field", "fit_fields", "json_bool",
           "http_headers", "http_message", "parse_bool", "parse_fit_settings", "parse_generation", "parse_growth",
           "parse_guided", "parse_guide_labels", "parse_morph", "page_words", "safe_name", "file_stem",
           "content_disposition", "query_value", "MAX_MODELS", "PAGE_FIELDS",
           "MAX_TRANSITION", "long_part_name", "MAX_PART_HEADER", "field_first"]

#: Most models in one guided image (a painted guide or a remix).
MAX_MODELS = 8
#: Widest transition between painted regions the server takes, in pixels.
MAX_TRANSITION = 512
#: Fit settings the API takes as form fields (besides ``paper`` and ``k1``/``k2``/``k3``).
_NOT_FIELDS = ("n_channels", "rng")


#: A value quoted in a message (a repr) of over 200 characters, which a message does not show whole: its first
#: 57 kept. Prose between two quoted names is shorter (a message is one line).
_LONG_QUOTED = re.compile(r"""(?<![\w'"])(['"])([^'"]{57})[^'"]{144,}\1""")


class RequestError(Exception):
    """A bad request: answered with ``status``, ``{"error": message}`` (one line) and ``headers``
    (e.g. a 503's ``Retry-After``). A value the message quotes, over 200 characters, is cut to 57 and
    ``...`` (0.58: a JSON body's 500 KB seed came back whole in the library's "got '999...'")."""

    def __init__(self, status: int, message: str, headers: dict | None = None):
        super().__init__(message)
        self.status = status
        self.message = _LONG_QUOTED.sub(lambda m: f"{m[1]}{m[2]}{m[1]}...", " ".join(str(message).split()))
        self.headers = dict(headers or {})


def query_value(request, key: str, default=None):
    """The query parameter ``key`` of ``request`` (``default`` where it has none); 400 where it is given twice,
    as a form field is (0.59 took the last of ``?name=a&name=b`` without a word)."""
    values = request.query_params.getlist(key)
    if len(values) > 1:
        raise RequestError(400, f"the query parameter {key!r} is given twice; send it once")
    return values[0] if values else default


#: A command-line option named after the library's name of a setting, in the library's messages ("lower N
#: (n_clusters, --clusters)", "a smaller stride, --stride, or ..."): the page and the API have the first alone.
_CLI_OPTION = re.compile(r", --[a-z][a-z0-9-]*(?=[,)])")


#: The fit settings the page has a field for under another name (index.html's labels): a library message naming the
#: setting ("N of at most 2 (n_clusters, --clusters)") names the page's field first, then the API's (0.63; 0.62 named
#: n_clusters alone, where the page says "clusters (N)").
PAGE_FIELDS = {"n_clusters": "clusters (N)", "n_codewords": "codewords (W)", "max_patches": "training patches"}
_FIELD_SETTING = "|".join(PAGE_FIELDS)
_SETTING_IN_PARENS = re.compile(rf"\(({_FIELD_SETTING})\)")
_LARGER_SETTING = re.compile(rf"\ba larger ({_FIELD_SETTING})\b")


def page_words(message: str) -> str:
    """A message of the library told to the page or an API client (an error, a failed job's, a note): one line,
    without the command-line options it names beside the setting's own name (``(patch_size, --patch-size)``
    -> ``(patch_size)``), which neither the page nor the API has; a setting the page's field names otherwise
    (:data:`PAGE_FIELDS`) as that field, then the API's (``(n_clusters, --clusters)`` -> ``(the field clusters (N);
    the API's n_clusters)``)."""
    text = _CLI_OPTION.sub("", " ".join(str(message).split()))
    text = _SETTING_IN_PARENS.sub(lambda m: f"(the field {PAGE_FIELDS[m[1]]}; the API's {m[1]})", text)
    return _LARGER_SETTING.sub(lambda m: f"a larger number in the field {PAGE_FIELDS[m[1]]} (the API's {m[1]})", text)


def field_first(name: str, message: str) -> str:
    """A ``message`` on the fit setting ``name`` that begins with that name, begun with the page's field where the page
    names it otherwise (:data:`PAGE_FIELDS`), then the API's: ``n_clusters: 'abc' is not ...`` -> ``the field clusters
    (N) (the API's n_clusters): 'abc' is not ...`` (0.63, as :func:`page_words` names them inside a message; 0.62 began
    with n_clusters)."""
    if name in PAGE_FIELDS and re.match(rf"{name}\b", message):
        return f"the field {PAGE_FIELDS[name]} (the API's {name}){message[len(name):]}"
    return message


def _name_chars(name) -> str:
    """``name`` as text in NFC (a Mac sends a name's accents apart: NFD), each character that is no letter, digit
    or combining mark of any script, nor ``.``, ``_`` or ``-``, as NUL: spaces, punctuation, path separators,
    control and format characters (a right-to-left override that would show ``gnp.exe`` as ``exe.png``),
    symbols."""
    text = unicodedata.normalize("NFC", str(name or ""))
    return "".join(c if c in "._-" or unicodedata.category(c)[0] in "LNM" else "\0" for c in text)


def safe_name(name, default: str) -> str:
    """An uploaded file's name as it may appear in a message and a temporary file: the last part of the path,
    only letters and digits (of any script, 0.58: 0.57 made "дом.png" "___.png"), their combining marks, ``.``,
    ``_`` and ``-``, others as ``_``; no leading ``.``; at most 80 characters and 200 bytes of UTF-8 (a file
    name may have 255), cut before its extension."""
    base = _name_chars(re.split(r"[\\/]", str(name or ""))[-1]).replace("\0", "_").lstrip(".")
    stem, dot, ext = base.rpartition(".")
    if not dot or not stem or len(ext) > 10:
        stem, ext = base, ""
    ext = dot + ext if stem != base else ""
    while stem and (len(stem + ext) > 80 or len((stem + ext).encode()) > 200):
        stem = stem[:-1]
    return stem + ext if stem else default


def file_stem(name, *, ascii_only: bool = False) -> str:
    """A name as part of a download's file name (``?name=`` of a file's download, as the page makes it
    too): runs of other characters than letters and digits (of any script, 0.58; only ASCII ones with
    ``ascii_only``, accents dropped: a Content-Disposition's plain ``filename``), their combining marks,
    ``.``, ``_`` and ``-`` as one ``-``, none at either end, at most 40 characters; ``""`` for none."""
    if ascii_only:  # accents dropped ("été": "ete"), other letters as any other character
        name = "".join(c for c in unicodedata.normalize("NFKD", str(name or "")) if not unicodedata.combining(c))
        text = "".join(c if c.isascii() else "\0" for c in _name_chars(name))
    else:
        text = _name_chars(name)
    stem = re.sub("\0+", "-", text).strip("-._")
    return stem[:40].rstrip("-._")


def content_disposition(filename: str, ascii_name: str) -> str:
    """A download's ``Content-Disposition``: ``filename`` in UTF-8 as RFC 6266's ``filename*`` where it is not
    ``ascii_name``, the plain ``filename`` (which older clients read) ``ascii_name``."""
    if filename == ascii_name:
        return f'attachment; filename="{ascii_name}"'
    return f"attachment; filename=\"{ascii_name}\"; filename*=UTF-8''{urllib.parse.quote(filename, safe='')}"


def _boundary(content_type: str):
    """A multipart ``content_type``'s boundary (bytes), or None."""
    found = re.search(r'boundary=(?:"([^"]+)"|([^;,\s]+))', content_type, re.IGNORECASE)
    return None if found is None else (found.group(1) or found.group(2)).encode("latin-1", "replace")


def check_multipart_end(content_type: str, body: bytes) -> None:
    """400 when a multipart ``body`` lacks its closing delimiter (``--BOUNDARY--``): empty or cut short.
    The parser takes such a body without a word and drops its last part (the fields sent then seemed
    missing: "no exemplar")."""
    boundary = _boundary(content_type)
    if boundary is None:  # the parser says what is wrong
        return
    if b"--" + boundary + b"--" not in body:
        shown = boundary.decode("latin-1")[:70]
        raise RequestError(400, f"malformed multipart request (no closing boundary --{shown}--: the body of "
                                f"{len(body):,} bytes is empty or cut short); send the whole form")


#: The longest header line of a multipart part the parser reads (python-multipart's limit, 4096 + 128 bytes: its
#: "Invalid multipart data." beyond), rounded down: the header names the field and the file.
MAX_PART_HEADER = 4096


def long_part_name(content_type: str, body: bytes):
    """The one line saying what is too long in a multipart ``body`` the parser refused, or None: a part's header line
    over :data:`MAX_PART_HEADER` bytes, by its file name or its field name (0.63; 0.62 said "malformed multipart
    request (Invalid multipart data.)" of a file name of 5,000 characters)."""
    boundary = _boundary(content_type)
    if boundary is None:
        return None
    for part in body.split(b"--" + boundary)[1:]:
        for line in part.split(b"\r\n\r\n", 1)[0].split(b"\r\n"):
            if len(line) <= MAX_PART_HEADER:
                continue
            filename = re.search(rb'filename\*?="?([^"\r\n]*)', line)
            field = re.search(rb'(?<![\w*])name="([^"\r\n]*)"', line)
            fix = "(a multipart part's header holds about 4,000 characters)"
            if filename is not None and len(filename.group(1)) > MAX_PART_HEADER // 2:
                return (f"a file name of {len(filename.group(1).decode('utf-8', 'replace')):,} characters is too long "
                        f"{fix}; rename the file shorter and send it again")
            if field is not None and len(field.group(1)) > MAX_PART_HEADER // 2:
                return (f"a field name of {len(field.group(1).decode('utf-8', 'replace')):,} characters is too long "
                        f"{fix}; name each field as docs/serve.md does ('image', 'model', ...)")
            return (f"a multipart part's header line of {len(line):,} bytes is too long {fix}; send shorter names "
                    "and headers")
    return None


def http_headers(exc) -> dict:
    """The headers of an error the router answers, a 405's ``Allow`` in alphabetical order (Starlette
    writes a route's methods from a set: ``GET, HEAD`` or ``HEAD, GET`` from one run to the next)."""
    headers = dict(exc.headers or {})
    if "Allow" in headers:
        headers["Allow"] = ", ".join(sorted(m.strip() for m in headers["Allow"].split(",")))
    return headers


def http_message(exc, method: str, path: str) -> str:
    """The one line of an error the router answers (Starlette's ``HTTPException``): no route (404),
    or a method the route does not take (405; its ``Allow`` header names the ones it takes)."""
    status, allow = exc.status_code, http_headers(exc).get("Allow")
    if status == 404:
        return f"nothing at {path[:200]}; the API is under /api (docs/serve.md)"
    if status == 405 and allow:
        return f"{method[:20]} is not allowed at {path[:200]}; use {allow} (docs/serve.md)"
    return exc.detail


def parse_bool(name, value) -> bool:
    """A form field's boolean, by a JSON body's rule (:func:`json_bool`): ``true`` or ``false`` (any
    case, spaces around ignored), or 1 or 0; an empty field false (a form sends an unset field empty:
    its default); 422 otherwise (yes/no and on/off too, as in JSON)."""
    text = str(value).strip().lower()
    if text in ("true", "1"):
        return True
    if text in ("false", "0", ""):
        return False
    raise RequestError(422, f"{name} must be true or false (or 1 or 0), got {str(value)[:40]!r}")


def fit_fields():
    """Names of the fit settings the API takes (form fields of ``POST /api/models``)."""
    from ..settings import fit_settings

    return [s.name for s in fit_settings() if s.name not in _NOT_FIELDS] + ["k1", "k2", "k3", "paper"]


def parse_fit_settings(fields: dict) -> dict:
    """Form fields -> the options :func:`tghop.fit_options.build_model` takes, each checked by
    the settings table, and together by :func:`~tghop.fit_options.fit_params` (422 with its
    one line, naming the field)."""
    from ..fit_options import OFF, fit_params
    from ..settings import BY_NAME, check_channel_rule

    known = fit_fields()
    options = {}
    for name, raw in fields.items():
        if name not in known:
            raise RequestError(422, f"unknown fit setting {name!r}; known: {', '.join(known)}")
        if not isinstance(raw, str):  # a file upload: (filename, bytes)
            raise RequestError(422, f"{name} must be a plain form field, not a file")
        text = raw.strip()
        if len(text) > 64:  # the messages below repeat the value
            raise RequestError(422, field_first(name, f"{name}: {text[:40]!r}... is {len(text):,} characters, too long "
                                                      "for a setting; give a value of at most 64 characters"))
        try:
            if name == "paper":
                options[name] = parse_bool(name, text)
            elif name in ("k1", "k2", "k3"):
                if text == "":
                    continue
                rule = text if text == "knee" else (float(text) if "." in text else int(text))
                options[name] = check_channel_rule(rule, name)
            else:
                s = BY_NAME[name]
                if text == "" and not s.none_ok:
                    continue
                if s.kind == "bool":
                    options[name] = parse_bool(name, text)
                else:
                    value = s.check(None if text == "" else _parse_field(s, text), label=name, cli=True)
                    if s.cli_high is not None and value is not None and value > s.cli_high:
                        raise TGHopError(f"{name}: {text} is more than the server allows; give at most "
                                         f"{s.cli_high:,g}")
                    options[name] = OFF if value is None else value  # "none": off, not the default
        except ValueError as exc:  # TGHopError is one
            message = str(exc) if isinstance(exc, TGHopError) else (
                f"{name}: {text[:40]!r} is not a channel count; give a count, a fraction in (0, 1] or 'knee'")
            raise RequestError(422, field_first(name, message)) from None
    try:
        fit_params(options, api=True)  # settings that do not go together (patch_size without k1, k2)
    except TGHopError as exc:
        raise RequestError(422, str(exc)) from None
    return options


def check_channel_counts(model, n_colours: int, stacked=None) -> None:
    """A fit's channel counts (``k1``...) against its exemplar's ``n_colours`` channels, by the
    library's own check (:meth:`tghop.synthesis.TGHop.check_channels`: its limits), before a job
    starts: 422 naming the form field ``k1``, not the command line's ``--k1``. ``stacked``: a
    material's channels by map (``{name: count}``), named in the message (the joint model's
    exemplar is the maps stacked)."""
    try:
        model.check_channels(n_colours)
    except TGHopError as exc:
        parts = "" if not stacked else (" (a material's albedo and maps stacked: "
                                        + ", ".join(f"{name} {c}" for name, c in stacked.items()) + ")")
        raise RequestError(422, str(exc).replace("n_channels[0], --k1", "k1") + parts) from None


def _parse_field(s, text: str):
    """A form field's text -> the value of setting ``s``; the one line names the field."""
    try:
        return s.parse(text)
    except TGHopError as exc:
        raise TGHopError(f"{s.name}: {exc}") from None


def parse_growth(size, anchor) -> tuple:
    """``/extend``'s form fields -> ``(size, anchor)``: ``size`` HEIGHTxWIDTH within the
    output limit, ``anchor`` one of :data:`tghop.inpaint.ANCHORS` (empty: ``center``); 422
    otherwise. Whether the size is larger than the picture is the fill's check (400)."""
    from .._images import MAX_PIXELS, check_size
    from ..inpaint import ANCHORS

    if size is None or not size.strip():  # 0.60: "size must be HEIGHTxWIDTH ..., got ''"
        raise RequestError(422, "the field 'size' is missing: send the size to grow the picture to, HEIGHTxWIDTH in "
                                "pixels, e.g. 512x1024")
    pair = manifest.split_size(size)
    if pair is None:
        raise RequestError(422, f"size must be HEIGHTxWIDTH in pixels, e.g. 512x1024, got {(size or '')[:40]!r}")
    try:
        size = check_size(pair, limit=MAX_PIXELS, name="size")
    except TGHopError as exc:
        raise RequestError(422, str(exc)) from None
    anchor = (anchor or "center").strip().lower()
    if anchor not in ANCHORS:
        raise RequestError(422, f"anchor must be one of {', '.join(ANCHORS)}; got {anchor[:40]!r}")
    return size, anchor


def json_bool(name, value) -> bool:
    """A boolean of a JSON body, one rule for all (``paper``, ``windows`` and the settings
    table's, e.g. ``tile``): ``true``/``false`` (or 1/0); missing or ``null``: false (a setting's
    ``null`` never comes here: it is the setting's default); 422 otherwise ("yes" too). A form
    field's is the same rule in text (:func:`parse_bool`)."""
    if value is None:
        return False
    if isinstance(value, bool):
        return value
    if type(value) is int and value in (0, 1):
        return bool(value)
    raise RequestError(422, f"{name} must be true or false (a JSON boolean), got {value!r}")


def _integer(name, value, low, high, *, none_ok=False):
    if value is None and none_ok:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        top = "2**63 - 1" if high == 2**63 - 1 else f"{high:,}"
        raise TGHopError(f"{name} must be an integer from {low} to {top}{' or null' if none_ok else ''}, "
                         f"got {value!r}")
    return value


def parse_generation(body, *, skip=(), default_size=(256, 256), what="images") -> tuple:
    """A generation's JSON -> ``(size, seed, settings)`` (422 for a bad value, with the
    library's one line).

    Parameters
    ----------
    body : object
        The decoded JSON: ``size``, ``seed``, ``paper``, ``quality`` (unless skipped) and
        the generation settings of the settings table.
    skip : sequence of str
        Settings the route does not take (refused as unknown).
    default_size : (int, int) or None
        The size when ``size`` is missing (None: None is returned).
    what : str
        The route's name in the message of a body that is not an object.
    """
    from .._images import MAX_PIXELS, check_size
    from ..settings import QUALITY, generate_settings

    if not isinstance(body, dict):
        raise RequestError(400, f"the body of {what} must be a JSON object, e.g. {{\"size\": [256, 256], \"seed\": 1}}")
    table = [s for s in generate_settings() if s.name not in skip]
    known = ["size", "seed", "paper"] + (["quality"] if "quality" not in skip else []) + [s.name for s in table]
    unknown = [k for k in body if k not in known]
    if unknown:
        raise RequestError(422, f"unknown setting {str(unknown[0])[:40]!r}; known: {', '.join(known)}")
    try:
        size = body.get("size")
        size = default_size if size is None else size
        size = None if size is None else check_size(size, limit=MAX_PIXELS, name="size")
        seed = _integer("seed", body.get("seed"), 0, 2**63 - 1, none_ok=True)
        paper = json_bool("paper", body.get("paper"))
        quality = body.get("quality", "default")
        if not isinstance(quality, str) or quality not in QUALITY:
            raise TGHopError(f"quality must be one of {', '.join(repr(q) for q in sorted(QUALITY))}, "
                             f"got {quality!r}")
        preset = QUALITY[quality]
        settings = {}
        for s in table:
            if s.name in body and (body[s.name] is not None or s.none_ok):
                given = body[s.name]
                if s.kind == "int" and isinstance(given, float):  # as seed and size: 5.0 is not taken as 5
                    raise TGHopError(f"{s.name} must be {s.range_text(json=True)}, got {given!r}"
                                     + (f"; write {int(given)}" if given.is_integer() else ""))
                if s.kind == "bool":
                    given = json_bool(s.name, given)
                value = s.check(given, label=s.name, json=True)
                if s.cli_high is not None and value is not None and value > s.cli_high:
                    raise TGHopError(f"{s.name} {value} is more than the server allows ({s.cli_high:,g})")
                settings[s.name] = value
            elif s.name in preset:  # as tghop synth --quality: a setting given as well overrides it
                settings[s.name] = preset[s.name]
            elif paper and s.has_paper:
                settings[s.name] = s.paper
    except TGHopError as exc:
        raise RequestError(422, str(exc)) from None
    return size, seed, settings


def _model_ids(value, name, low, high) -> list:
    """A list of model ids (each a string; a malformed one is 404 when it is looked up)."""
    ids = value if isinstance(value, list) else None
    if ids is None or not all(isinstance(i, str) for i in ids):
        raise RequestError(422, f"{name} must be a list of model ids (the \"id\" of POST /api/models), "
                                f"got {str(value)[:60]!r}")
    if not low <= len(ids) <= high:
        raise RequestError(422, f"{name} has {len(ids)} model ids; give {low} to {high}")
    return ids


def decode_png_field(value, name: str, *, paint: str, missing: str = "") -> bytes:
    """A JSON field holding an image file as base64 (a ``data:`` URL's prefix is dropped):
    its bytes; 400 naming ``name`` when it is not a base64 string or is empty (``paint``:
    what the PNG should hold; ``missing``: what leaving the field out does, if anything)."""
    if not isinstance(value, str):
        raise RequestError(400, f"{name} must be a PNG as a base64 string (or a data: URL){missing}")
    text = re.sub(r"^data:[^,]{0,100},", "", value.strip())
    try:
        content = base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError):
        raise RequestError(400, f"{name} is not valid base64; send the PNG's bytes base64-encoded") from None
    if not content:
        raise RequestError(400, f"{name} is empty; send a PNG painted with {paint}")
    return content


def decode_guide(value) -> bytes:
    """The guide's image file from base64; 400 when it is not base64."""
    return decode_png_field(value, "guide", paint="one grey level per model", missing=", or left out for a remix")


def parse_guided(body) -> tuple:
    """The JSON of ``POST /api/images/guided`` -> ``(ids, guide bytes or None, size, seed,
    transition, settings)``. ``size`` is None when a guide gives it."""
    if not isinstance(body, dict):
        raise RequestError(400, "the body must be a JSON object, e.g. {\"models\": [ID1, ID2], \"size\": [256, 256]}")
    body = dict(body)
    if "models" not in body:
        raise RequestError(422, "no models: give \"models\": a list of 2 or more model ids (1 with a guide)")
    guide = body.pop("guide", None)
    ids = _model_ids(body.pop("models"), "models", 1 if guide is not None else 2, MAX_MODELS)
    guide = None if guide is None else decode_guide(guide)
    try:
        transition = _integer("transition", body.pop("transition", 32), 0, MAX_TRANSITION)
    except TGHopError as exc:
        raise RequestError(422, str(exc)) from None
    size, seed, settings = parse_generation(body, default_size=None if guide is not None else (256, 256),
                                            what="/api/images/guided")
    return ids, guide, size, seed, transition, settings


def parse_guide_labels(body) -> tuple:
    """The JSON of ``POST /api/guides/labels`` -> ``(guide bytes, n_models, size or None)``: ``guide`` as
    :func:`parse_guided` takes it, ``n_models`` (1 to :data:`MAX_MODELS`), ``size`` (optional, as a
    generation's)."""
    from .._images import MAX_PIXELS, check_size

    if not isinstance(body, dict):
        raise RequestError(400, "the body must be a JSON object, e.g. {\"guide\": PNG_BASE64, \"n_models\": 2}")
    unknown = [k for k in body if k not in ("guide", "n_models", "size")]
    if unknown:
        raise RequestError(422, f"unknown field {str(unknown[0])[:40]!r}; known: guide, n_models, size")
    if "guide" not in body:
        raise RequestError(400, "no guide: give \"guide\", a PNG as a base64 string")
    guide = decode_guide(body["guide"])
    try:
        n_models = _integer("n_models", body.get("n_models"), 1, MAX_MODELS)
        size = None if body.get("size") is None else check_size(body["size"], limit=MAX_PIXELS, name="size")
    except TGHopError as exc:
        raise RequestError(422, str(exc)) from None
    return guide, n_models, size


def parse_morph(body) -> tuple:
    """The JSON of ``POST /api/images/morph`` -> ``(id_a, id_b, size, seed, stations,
    settings)``."""
    if not isinstance(body, dict):
        raise RequestError(400, "the body must be a JSON object, e.g. {\"a\": ID1, \"b\": ID2, \"size\": [256, 1024]}")
    body = dict(body)
    ids = []
    for name in ("a", "b"):
        value = body.pop(name, None)
        if not isinstance(value, str):
            raise RequestError(422, f"{name} must be a model id (the \"id\" of POST /api/models), got {value!r}")
        ids.append(value)
    try:
        stations = _integer("stations", body.pop("stations", None), 2, 256, none_ok=True)
    except TGHopError as exc:
        raise RequestError(422, str(exc)) from None
    size, seed, settings = parse_generation(body, skip=("patch_refine", "patch_stride", "quality", "tile", "region",
                                                        "own_shares"),
                                            default_size=(256, 1024), what="/api/images/morph")
    return ids[0], ids[1], size, seed, stations, settings
