"""What keeps ``tghop serve`` to its own users (docs/serve.md, "Files and safety"):

* :class:`LocalOnly`, an ASGI middleware: a request whose ``Host`` header names another server
  than this one (a page of another site that rebinds its name to 127.0.0.1, "DNS rebinding") or
  whose ``Origin`` is another site (a page that posts a form to the server from the user's
  browser) is refused with 403 and one line, before its body is read.

Only the standard library is imported.
"""

from __future__ import annotations

import json

__all__ = ["LocalOnly", "allowed_hosts", "LOOPBACK"]

#: The names of this machine that a local server answers to.
LOOPBACK = ("127.0.0.1", "localhost", "::1")
#: Addresses that listen on every interface: any name may reach the server, so the Host is not checked.
_ANY = ("", "0.0.0.0", "::")


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

