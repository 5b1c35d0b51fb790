"""``tghop serve``: the local web server (:mod:`tghop.server`), on uvicorn.

Starlette and uvicorn (the ``web`` extra) are imported only when the command runs.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager
from pathlib import Path

import click

from .._errors import TGHopError
from .lines import say
from .common import check_stdout, examples, quiet_tifffile, user_errors
from .group import after_a_stop

__all__ = ["serve", "default_cache_dir", "ByteSize"]


class ByteSize(click.ParamType):
    """A size in bytes: a number with an optional unit (``500M``, ``2G``, ``1.5GB``, ``800KB``;
    powers of 1000), or ``none`` for no bound (None)."""

    name = "SIZE"
    UNITS = {"": 1, "B": 1, "K": 1000, "KB": 1000, "M": 1000**2, "MB": 1000**2, "G": 1000**3, "GB": 1000**3,
             "T": 1000**4, "TB": 1000**4}

    def convert(self, value, param, ctx):
        import re

        if value is None or isinstance(value, int):
            return value
        text = str(value).strip().upper()
        if text in ("NONE", "OFF"):
            return None
        m = re.fullmatch(r"(\d+(?:\.\d*)?)\s*([KMGT]?B?)", text)
        if not m:
            self.fail(f"{value!r} is not a size; write e.g. 500M, 2G or none", param, ctx)
        size = int(float(m.group(1)) * self.UNITS[m.group(2)])
        if size < 1:
            self.fail(f"{value!r} is not a size of at least 1 byte; write e.g. 500M, 2G or none", param, ctx)
        return size


def default_cache_dir() -> Path:
    """The user's cache folder for tghop: ``$XDG_CACHE_HOME/tghop`` or ``~/.cache/tghop``
    (Linux and others), ``~/Library/Caches/tghop`` (macOS), ``%LOCALAPPDATA%\\tghop\\Cache``
    (Windows)."""
    if sys.platform.startswith("win"):
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
        return Path(base) / "tghop" / "Cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "tghop"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg and os.path.isabs(xdg) else Path.home() / ".cache") / "tghop"


def _bind(host: str, port: int):
    """A listening socket (``port`` 0: a free one), or a one-line error."""
    import socket

    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as exc:
        raise TGHopError(f"--host {host}: not an address of this machine ({exc.strerror}); "
                         "use 127.0.0.1 or 0.0.0.0") from None
    family, kind, proto, _, address = infos[0]
    sock = socket.socket(family, kind, proto)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(address)
        sock.listen(128)
    except OSError as exc:
        sock.close()
        raise TGHopError(f"cannot listen on {host}:{port} ({exc.strerror}); "
                         "choose another --port (0 picks a free one)") from None
    sock.set_inheritable(True)
    return sock


#: The signals that stop the server as Ctrl-C does: gracefully, with the one line "tghop server stopped".
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


def _server(app):
    """The uvicorn server of ``tghop serve`` for ``app``: every stop signal, at any moment of its start, its run
    or its stop and however many come, asks for one graceful stop, the application's shutdown included.

    uvicorn's own handling did otherwise: a second Ctrl-C during the stop (a terminal's, or ``timeout -s INT``,
    which signals the process and then its group) skipped the application's shutdown (its fit queue and
    threads), and the signals it had caught were raised again, to the command's handlers, while the event
    loop still ran: the KeyboardInterrupt then cancelled the application's lifespan, logged with a
    traceback. SIGHUP (the terminal closed) reached the command's handler in the middle of the loop, with
    the same traceback.
    """
    import uvicorn

    class Server(uvicorn.Server):
        ignored = frozenset()
        signalled = False

        def handle_exit(self, sig, frame):
            # Not uvicorn's: neither a force_exit that skips the lifespan's shutdown nor a signal to raise
            # again after the run; an ignored signal (nohup, `tghop serve &` in a script) stays ignored.
            if sig not in self.ignored:
                self.should_exit = self.signalled = True

        @contextmanager
        def stop_signals(self):
            """From here to the end of the block the stop signals call :meth:`handle_exit` (uvicorn's
            capture of them does the same while it runs): a Ctrl-C before the run starts makes it stop as
            soon as it has started. The handlers before are put back at the end (none where this is not
            the main thread, which alone receives signals), the command's Ctrl-C handler as it would be had it
            stopped the command itself (:func:`~tghop.cli.group.after_a_stop`)."""
            self.ignored = set()
            before = {}
            if threading.current_thread() is threading.main_thread():
                for signum in STOP_SIGNALS:
                    handler = signal.getsignal(signum)
                    if handler == signal.SIG_IGN:
                        self.ignored.add(signum)
                    elif handler is not None:  # None: a handler not set from Python, which could not be put back
                        before[signum] = signal.signal(signum, self.handle_exit)
            self.signalled = False
            try:
                yield
            finally:
                if self.signalled and signal.SIGINT in before:  # the Ctrl-Cs after the stop are ignored to the end
                    before[signal.SIGINT] = after_a_stop(before[signal.SIGINT])
                for signum, handler in before.items():
                    signal.signal(signum, handler)

        async def shutdown(self, sockets=None):
            # Requests still waiting for a generation answer 503 now (JSON): none is left for
            # uvicorn to cancel when timeout_graceful_shutdown runs out (a traceback, a text 500).
            app.state.server.stop()
            await super().shutdown(sockets=sockets)

    return Server(uvicorn.Config(app, log_level="warning", timeout_graceful_shutdown=2, lifespan="on"))


@click.command(short_help='Start the local web page: fit, generate and download in a browser', epilog=examples(
    "# then open the address it prints, http://127.0.0.1:8000/",
    "tghop serve",
    "# a free port, the page opened in your browser, models kept under ./models",
    "tghop serve --port 0 --open --cache ./models"))
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on. Any other than 127.0.0.1, localhost or ::1 lets other machines use the "
                   "server (it has no login): a warning is printed.")
@click.option("--port", type=click.IntRange(0, 65535), default=8000, show_default=True,
              help="Port to listen on (0: a free one).")
@click.option("--open", "open_browser", is_flag=True, help="Open the page in a web browser.")
@click.option("--cache", "cache", type=click.Path(file_okay=False), default=None,
              help="Folder for fitted models. [default: the user's cache folder, e.g. ~/.cache/tghop]")
@click.option("--cache-size", type=ByteSize(), default="2G", show_default=True,
              help="Bound of the model files in --cache (e.g. 500M, 10G; none: no bound): the least recently "
                   "used models are removed first.")
@click.option("--max-fits", type=click.IntRange(min=1, max=256), default=None,
              help="Fits that run at once; the rest wait. [default: the number of cores]")
@click.option("--max-decodes", type=click.IntRange(min=1, max=64), default=2, show_default=True,
              help="Uploads decoded at once (exemplars, model files, checkpoints) and models read from disk: "
                   "each may take hundreds of MB whatever its file's size. --decodes-waiting more wait their "
                   "turn; one more is refused (503).")
@click.option("--decodes-waiting", type=click.IntRange(min=0, max=256), default=16, show_default=True,
              help="Uploads and reads from disk that wait their turn beyond --max-decodes (their bodies are held "
                   "meanwhile); one more is refused (503 with Retry-After).")
def serve(host, port, open_browser, cache, cache_size, max_fits, max_decodes, decodes_waiting):
    """Start a local web server: fit, generate and download textures in a browser.

    Prints the page's address; the same HTTP API the page uses is under /api
    (docs/serve.md). Stop it with Ctrl-C.
    """
    with user_errors():
        check_stdout("the server's address")  # (uvicorn's logging fails there too)
        from ..server.app import create_app, require_web
        from ..server.safety import LOOPBACK

        require_web(server=True)
        import logging

        # python-multipart logs a warning of its own for some malformed bodies, which the client is
        # answered (400): the terminal shows the server's address and its end, not the clients' mistakes.
        for name in ("python_multipart", "multipart"):
            logging.getLogger(name).setLevel(logging.ERROR)
        quiet_tifffile()  # an upload's malformed TIFF: a 400 or a note, not tifffile's log lines (0.59: printed)
        cache_dir = Path(cache) if cache else default_cache_dir()
        app = create_app(cache_dir, max_fits=max_fits, cache_bytes=cache_size, host=host, max_decodes=max_decodes,
                         decodes_waiting=decodes_waiting)
        sock = _bind(host, port)
    server = _server(app)
    try:
        with server.stop_signals():  # from here on Ctrl-C, SIGTERM and SIGHUP stop the server, once
            bound = sock.getsockname()[1]
            shown = f"[{host}]" if ":" in host else host
            url = f"http://{'127.0.0.1' if host in ('0.0.0.0', '::', '') else shown}:{bound}/"
            if host not in LOOPBACK:  # the addresses whose clients LocalOnly lets in
                say(f"Warning: listening on {host}: other machines on the network can use this server "
                    "(it has no login); use --host 127.0.0.1 to keep it to this machine")
            say(f"tghop serving on {url} (models in {cache_dir}; Ctrl-C stops it)", err=False)
            sys.stdout.flush()
            if open_browser:
                import webbrowser

                webbrowser.open(url)
            import numpy  # noqa: F401 - their BLAS libraries loaded, so that the limit below reaches them
            import scipy.linalg  # noqa: F401
            from threadpoolctl import threadpool_limits

            # One BLAS thread for the whole process, held by this thread: generation in the
            # request threads then gives the same image for the same seed whatever runs beside it
            # (threadpoolctl's limit is the process's; a request thread's own would come and go).
            with threadpool_limits(limits=1, user_api="blas"):
                server.run(sockets=[sock])
    finally:
        sock.close()
    say("tghop server stopped")
