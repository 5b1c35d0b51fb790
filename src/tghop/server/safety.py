"""What keeps ``tghop serve`` to its own users and its memory bounded (docs/serve.md, "Files and
safety"):

* :class:`LocalOnly`, an ASGI middleware: a request whose ``Host`` header names another server
  than this one (a page of another site that rebinds its name to 127.0.0.1, "DNS rebinding") or
  whose ``Origin`` is another site (a page that posts a form to the server from the user's
  browser) is refused with 403 and one line, before its body is read;
* :func:`check_archive`: an uploaded model file (``.npz``) or checkpoint (``.pt``), both ZIP
  archives, is refused (400) when its members would unpack to more than
  :data:`MAX_UNPACKED_BYTES` or it has more than :data:`MAX_MEMBERS` or too large a directory
  (:mod:`tghop._archives`, the local files' check), before NumPy or PyTorch reads it (a deflated
  member of zeros unpacks about 1,000 times larger).

Only the standard library is imported, besides tghop's own small modules (no Starlette, no NumPy).
"""

from __future__ import annotations

import io
import json
import zipfile

from .._archives import MAX_MEMBERS as FILE_MAX_MEMBERS, too_many_members
from .requests import RequestError

__all__ = ["LocalOnly", "allowed_hosts", "check_archive", "MAX_UNPACKED_BYTES", "MAX_MEMBERS", "LOOPBACK"]

#: The names of this machine that a local server answers to.
LOOPBACK = ("127.0.0.1", "localhost", "::1")
#: Addresses that listen on every interface: any name may reach the server, so the Host is not checked.
_ANY = ("", "0.0.0.0", "::")
#: Most bytes the members of an uploaded archive may unpack to (a model file tghop writes is stored
#: uncompressed: as large as the file, at most the upload limit of 50 MB).
MAX_UNPACKED_BYTES = 200 * 1024 * 1024
#: Most members of an uploaded archive (a model file has a few dozen arrays, a material's a few hundred): the
#: local files' limit (:data:`tghop._archives.MAX_MEMBERS`).
MAX_MEMBERS = FILE_MAX_MEMBERS


def _hostname(netloc: str) -> str:
    """``host:port`` (or ``[v6]:port``) -> the host, lower case, without brackets or a final dot."""
    netloc = netloc.strip().lower()
    if netloc.startswith("["):
        return netloc[1:].split("]", 1)[0]
    if netloc.count(":") == 1:
        netloc = netloc.split(":", 1)[0]
    return netloc.rstrip(".") if netloc not in (".", "") else netloc


def allowed_hosts(host: str | None):
    """The names a request's ``Host`` may give for a server listening on ``host`` (``tghop serve
    --host``): the loopback names and ``host``; None (any) for an address of every interface."""
    if host is None:
        return set(LOOPBACK)
    name = _hostname(host if not (":" in host and not host.startswith("[")) else f"[{host}]")
    if name in _ANY:
        return None
    return set(LOOPBACK) | {name}


class LocalOnly:
    """ASGI middleware: refuse (403, one line of JSON) an HTTP request whose ``Host`` is not one of
    ``hosts`` (None: any) or whose ``Origin`` is not the server itself (``http://`` and the Host).
    A request without these headers (a script's) passes: browsers always send the Host, and the
    Origin with a cross-origin request and with any POST or DELETE."""

    def __init__(self, app, hosts):
        self.app = app
        self.hosts = hosts

    async def __call__(self, scope, receive, send):
        if scope["type"] == "http":
            message = self.refusal(dict(scope.get("headers") or ()), scope)
            if message:
                body = json.dumps({"error": message}).encode()
                await send({"type": "http.response.start", "status": 403,
                            "headers": [(b"content-type", b"application/json"),
                                        (b"content-length", str(len(body)).encode())]})
                await send({"type": "http.response.body", "body": body})
                return
        await self.app(scope, receive, send)

    def refusal(self, headers: dict, scope) -> str | None:
        """The 403's line for a request with these headers (bytes to bytes), or None."""
        host = headers.get(b"host", b"").decode("latin-1")
        port = (scope.get("server") or (None, None))[1]
        own = f"http://127.0.0.1:{port}/" if port else "http://127.0.0.1/"
        if host and self.hosts is not None and _hostname(host) not in self.hosts:
            names = ", ".join(f"[{h}]" if ":" in h else h for h in sorted(self.hosts))
            return (f"refused: the Host {host[:80]!r} is not this server's name ({names}); open {own} (a page of "
                    "another site may not use this server; tghop serve --host NAME answers to NAME too)")
        origin = headers.get(b"origin")
        if origin is None:
            return None
        origin = origin.decode("latin-1").strip()
        if host and origin.lower().rstrip("/") in (f"http://{host.lower()}", f"https://{host.lower()}"):
            return None
        return (f"refused: a page of {origin[:80]!r} may not use this server, only its own page ({own} or "
                "another of its names); a script may leave the Origin header out")


def check_archive(content: bytes, filename: str, what: str) -> None:
    """400 when ``content`` is a ZIP archive with more than :data:`MAX_MEMBERS` members or a larger
    directory than a model file's or checkpoint's (:func:`tghop._archives.too_many_members`, the local
    files' check and words, from the archive's end record: a 50 MB directory of empty members holds a
    million, 3 s and 700 MB to parse) or members that unpack to more than :data:`MAX_UNPACKED_BYTES` (a
    decompression bomb); anything else (not an archive: the loader's error says what it is) passes.
    ``what``: the kind of file, as the message names it. The sizes are those the archive declares, which
    Python's and PyTorch's readers do not read past."""
    crowded = too_many_members(io.BytesIO(content))
    if crowded:  # 0.58 counted the directory's entry signatures in the whole body, in words of its own
        raise RequestError(400, f"{filename} is {crowded}, not a {what}; send a {what} tghop wrote")
    try:
        with zipfile.ZipFile(io.BytesIO(content)) as archive:
            members = archive.infolist()
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, NotImplementedError):
        return
    unpacked = sum(member.file_size for member in members)
    if unpacked > MAX_UNPACKED_BYTES:
        raise RequestError(400, f"{filename} unpacks to {unpacked / 1024**2:,.0f} MB, more than the "
                                f"{MAX_UNPACKED_BYTES // 1024**2} MB a {what} may hold (a decompression bomb?); "
                                f"send a {what} tghop wrote")
