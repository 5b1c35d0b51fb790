"""What a request sends, read: its body within a size limit, a multipart form's fields, a JSON
body, an uploaded image decoded by the library (docs/serve.md, "The API"); and the bound on
uploads decoded at once (:class:`Gate`).

Starlette is imported only inside these functions: the module imports without the web extra,
as the rest of :mod:`tghop.server` does.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import tempfile
from pathlib import Path

from .._errors import ImageTooLargeError, OpaqueAlphaWarning, TGHopError, TransparencyWarning, collect_warnings
from .._json import RepeatedKeyError, loads_unique
from ..image_decode import share_text
from . import materials
from .requests import RequestError, check_multipart_end, long_part_name, page_words, safe_name

__all__ = ["MAX_UPLOAD_BYTES", "MAX_FIT_BYTES", "DRAIN", "MAX_DECODES", "MAX_DECODES_WAITING", "RETRY_AFTER", "Gate",
           "read_body", "read_form", "each_file_within", "json_body", "read_image", "read_notes", "note_line",
           "depth_note", "MAX_NOTE"]

#: Largest request body accepted (an exemplar or a model file).
MAX_UPLOAD_BYTES = 50 * 1024 * 1024
#: Largest body of a fit (``POST /api/models``), an inpaint or an extend: a material's albedo and maps
#: together, each file still at most MAX_UPLOAD_BYTES (a 2K set with a 16-bit normal map is about 40 MB).
MAX_FIT_BYTES = 4 * MAX_UPLOAD_BYTES
#: An upload over the limit is read (and dropped) up to this many times the limit, then the
#: connection is closed.
DRAIN = 4
#: Uploads decoded or prepared at once (a fit's exemplar and maps, a model file or checkpoint read), by
#: default: a small file may decode to hundreds of MB (an 8000x8000 PNG of 760 KB: a peak of 700 MB),
#: so their number has a bound of its own, whatever the number of cores (``create_app(max_decodes=)``).
MAX_DECODES = 2
#: Uploads that wait for their turn beyond the decoding ones, by default; one more is 503 with Retry-After.
MAX_DECODES_WAITING = 16
#: Seconds a busy server tells a client to wait before it tries again (``Retry-After``).
RETRY_AFTER = 5


class Gate:
    """At most ``slots`` holders at once (``async with gate:``); up to ``waiting`` more wait for
    their turn, in order, and one more is refused at once: 503 with ``Retry-After``
    (:data:`RETRY_AFTER`). For the event loop only (its counts need no lock)."""

    def __init__(self, slots: int, waiting: int, *, what: str = "uploads are being read"):
        if slots < 1 or waiting < 0:
            raise ValueError(f"a gate needs slots >= 1 and waiting >= 0, got {slots} and {waiting}")
        self.slots, self.max_waiting, self.what = slots, waiting, what
        self.holding = 0  # in the gate now
        self.waiting = 0  # waiting for a slot
        self._free = asyncio.Semaphore(slots)

    async def __aenter__(self):
        return await self.enter()

    async def enter(self, gone=None):
        """Take a slot, waiting for one in order (503 when too many wait); ``gone()``: an awaitable that,
        done first (its client went away), withdraws the wait: its place is freed, it never holds a slot,
        499. Leave with :meth:`__aexit__`."""
        if self.holding >= self.slots and self.waiting >= self.max_waiting:
            raise RequestError(503, f"the server is busy: {self.holding} {self.what} and {self.waiting} wait; "
                                    f"try again in {RETRY_AFTER} s", headers={"Retry-After": str(RETRY_AFTER)})
        self.waiting += 1
        try:
            if gone is None:
                await self._free.acquire()
            elif not await self._acquire_unless(gone):
                raise RequestError(499, "the client went away while its upload waited; it was dropped")
        finally:
            self.waiting -= 1
        self.holding += 1
        return self

    async def _acquire_unless(self, gone) -> bool:
        """A slot (True), or none once ``gone`` is done first (False: out of the queue)."""
        acquiring = asyncio.ensure_future(self._free.acquire())
        gone = asyncio.ensure_future(gone())
        got = False
        try:
            await asyncio.wait({acquiring, gone}, return_when=asyncio.FIRST_COMPLETED)
            got = acquiring.done() and not gone.done()
        finally:
            gone.cancel()
            if not got:  # still waiting, it leaves the queue (a slot granted meanwhile is given back on its cancel)
                acquiring.cancel()
                if acquiring.done() and not acquiring.cancelled():  # granted before: given back here
                    self._free.release()
        return got

    async def __aexit__(self, *exc_info):
        self.leave()

    def leave(self) -> None:
        """Give the slot taken by :meth:`enter` back (on the event loop)."""
        self.holding -= 1
        self._free.release()


async def read_body(request, limit: int = MAX_UPLOAD_BYTES, *, what: str = "the upload") -> bytes:
    """The request's body, or 413 as soon as it is over ``limit`` bytes (``what``: the message's
    words for it); 499 (to nobody) when the client goes away before it has sent the whole body."""
    from starlette.requests import ClientDisconnect

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
                if n > DRAIN * limit:
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
    from starlette.formparsers import MultiPartException, MultiPartParser

    async def stream():
        yield body

    if not request.headers.get("content-type", "").startswith("multipart/form-data"):
        raise RequestError(400, f"send the fields as multipart/form-data ({fields})")
    check_multipart_end(request.headers["content-type"], body)
    try:
        form = await MultiPartParser(request.headers, stream(), max_files=4 + materials.MAX_MAPS,
                                     max_fields=64).parse()
    except (MultiPartException, ValueError) as exc:
        words = str(getattr(exc, "message", exc))
        if words.startswith("Part exceeded maximum size"):  # a file part without a file name is a field: 1 MB at most
            raise RequestError(400, f"a form field over 1 MB ({words}): a file sent without a file name? Send each "
                                    "file with its file name, as a browser or curl -F NAME=@FILE does") from None
        raise RequestError(400, long_part_name(request.headers["content-type"], body)
                           or f"malformed multipart request ({words}); send the form as a browser or "
                              "curl -F NAME=@FILE sends it") from None
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


async def json_body(request, limit: int = 1024 * 1024):
    """The request's body as JSON (400 when it is not JSON; 413 over ``limit`` bytes)."""
    body = await read_body(request, limit=limit)
    try:
        return loads_unique(body or b"{}")
    except RepeatedKeyError as exc:  # 0.58 took the last value without a word
        raise RequestError(400, f"the body gives the key {exc.key[:60]!r} twice; send each key once") from None
    except (ValueError, RecursionError):  # RecursionError: nested deeper than the parser goes
        raise RequestError(400, "the body is not JSON; send e.g. {\"size\": [256, 256], \"seed\": 1}") from None


#: The longest note of an upload told to the client (a colour profile's name is the file's, of any length).
MAX_NOTE = 300


@contextlib.contextmanager
def read_notes(notes: list):
    """Within it, tghop's warnings of reading an upload (:func:`read_image`) add a line each to
    ``notes``, in the page's words: what the command line warns of, told to the client (a fit's
    ``notes``, an image's ``X-Tghop-Warning``). A colour profile converted to sRGB (or one that could not
    be read), the first of several frames read: the library's words, which name no option. A partly
    transparent image (:class:`tghop.TransparencyWarning`): the colours under its transparent part are
    learnt as texture, and the fix is the page's (crop it; the command line's names its ``--exclude``,
    which the page has not). An opaque alpha channel dropped (:class:`tghop.OpaqueAlphaWarning`) changes no
    pixel: nothing. Each line at
    most :data:`MAX_NOTE` characters. This thread's warnings alone
    (:func:`tghop._errors.collect_warnings`: other threads' warnings, and the process's filters, untouched)."""
    with collect_warnings() as said:
        yield
    for w in said:
        if isinstance(w, TransparencyWarning):
            line = (f"{w.name}: {share_text(w.share)} of its pixels are transparent, and the colours under them are "
                    "learnt as texture; to leave them out, crop the image to its opaque part")
        elif isinstance(w, OpaqueAlphaWarning):  # an opaque alpha channel dropped: no pixel shows otherwise
            continue
        else:
            line = str(w)
        notes.append(note_line(line))


def note_line(text: str) -> str:
    """A warning as a line of an upload's notes: one line in the page's words
    (:func:`~tghop.server.requests.page_words`), at most :data:`MAX_NOTE` characters."""
    line = page_words(text)
    return line if len(line) <= MAX_NOTE else line[:MAX_NOTE - 3] + "..."


def depth_note(name: str, *, model: bool = False) -> str:
    """The note of an exemplar ``name`` (or with ``model``, a model file fitted on one) of more than 8 bits a
    channel: the page's images of a texture model have 8, as ``tghop synth`` warns without ``--depth 16``
    (which the page has not: no fix named)."""
    what = f"{name} was fitted on an exemplar of" if model else f"{name} has"
    return f"{what} more than 8 bits a channel, but the images made here have 8"


def read_image(content: bytes, filename: str, load, *, notes=None):
    """``load(path)`` of the uploaded ``content`` written as ``filename`` (already
    :func:`~tghop.server.requests.safe_name`'d) in a temporary folder, removed at once: the
    library's reading (e.g. :func:`tghop.imageio.load_image`). Its errors are one line without
    the folder: 413 over the pixel limit or out of memory, 400 otherwise. Its warnings (a colour
    profile converted, only the first frame read): lines added to ``notes`` (:func:`read_notes`), or
    without ``notes`` nowhere (not errors; this thread's alone)."""
    with tempfile.TemporaryDirectory(prefix="tghop-upload-") as folder:
        path = Path(folder) / filename
        path.write_bytes(content)
        try:
            with read_notes([] if notes is None else notes):
                return load(path)
        except ImageTooLargeError as exc:
            raise RequestError(413, str(exc).replace(f"{folder}{os.sep}", "")) from None
        except TGHopError as exc:
            raise RequestError(400, str(exc).replace(f"{folder}{os.sep}", "")) from None
        except MemoryError:
            raise RequestError(413, f"{filename}: not enough memory to decode this image; "
                                    "downscale it first") from None
