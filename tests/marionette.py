"""A small client of Firefox's Marionette protocol, enough for the web page's browser test.

Firefox (Debian's ``firefox-esr``) speaks Marionette itself when started with
``--marionette``: JSON messages over TCP, each framed as ``<length>:<json>``; a command
is ``[0, id, name, params]`` and its answer ``[1, id, error, result]``. Selenium and
Playwright would each need a driver or a browser build downloaded at run time
(geckodriver is in neither Debian nor PyPI; Playwright drives its own patched Firefox),
which CI cannot fetch; this needs only the standard library. The commands are the
WebDriver ones (``WebDriver:Navigate``, ``WebDriver:FindElement``, ...), named as in
Firefox's remote/marionette/driver.sys.mjs.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path

#: The key of a web element reference in WebDriver's JSON.
ELEMENT = "element-6066-11e4-a52e-4f735466cecf"
#: JavaScript (a function of an input and a value): set the value as typing does (the
#: input and change events fire); works on range inputs too.
FILL_JS = ("(e, value) => { e.value = value; e.dispatchEvent(new Event('input', {bubbles: true}));"
           " e.dispatchEvent(new Event('change', {bubbles: true})); }")

#: Profile preferences: no first-run pages, updates, telemetry or other traffic; Marionette
#: on a free port (written to the profile's MarionetteActivePort).
PREFS = {
    "marionette.port": 0,
    "browser.shell.checkDefaultBrowser": False,
    "browser.startup.homepage_override.mstone": "ignore",
    "browser.startup.page": 0,
    "browser.aboutwelcome.enabled": False,
    "datareporting.policy.dataSubmissionEnabled": False,
    "datareporting.healthreport.uploadEnabled": False,
    "toolkit.telemetry.reportingpolicy.firstRun": False,
    "toolkit.telemetry.enabled": False,
    "app.update.disabledForTesting": True,
    "app.normandy.enabled": False,
    "extensions.update.enabled": False,
    "network.captive-portal-service.enabled": False,
    "network.connectivity-service.enabled": False,
    "browser.safebrowsing.malware.enabled": False,
    "browser.safebrowsing.phishing.enabled": False,
    "browser.safebrowsing.downloads.enabled": False,
    "services.settings.server": "http://127.0.0.1:9/",
    "browser.region.network.url": "",
    "remote.prefs.recommended": True,
}


class MarionetteError(RuntimeError):
    """An error answered by Firefox (``error``: the WebDriver error code)."""

    def __init__(self, error: dict):
        super().__init__(f"{error.get('error')}: {error.get('message')}")
        self.code = error.get("error")


def find_firefox():
    """The Firefox to drive: ``$TGHOP_FIREFOX``, else ``firefox-esr`` or ``firefox`` on PATH
    (None when there is none)."""
    given = os.environ.get("TGHOP_FIREFOX")
    if given:
        return given if os.path.isfile(given) and os.access(given, os.X_OK) else None
    return shutil.which("firefox-esr") or shutil.which("firefox")


class Firefox:
    """A headless Firefox on a fresh profile, driven through Marionette.

    Use as a context manager; :meth:`call` sends one command and returns its result.
    """

    def __init__(self, executable: str, *, width: int = 1200, height: int = 1400, timeout: float = 60.0):
        self.profile = Path(tempfile.mkdtemp(prefix="tghop-firefox-"))
        (self.profile / "user.js").write_text(
            "".join(f"user_pref({json.dumps(k)}, {json.dumps(v)});\n" for k, v in PREFS.items()))
        env = dict(os.environ, MOZ_HEADLESS="1", MOZ_HEADLESS_WIDTH=str(width), MOZ_HEADLESS_HEIGHT=str(height),
                   HOME=str(self.profile), MOZ_CRASHREPORTER_DISABLE="1")
        self.log = open(self.profile / "firefox.log", "wb")
        self.process = subprocess.Popen(
            [executable, "--marionette", "--headless", "--no-remote", "-profile", str(self.profile), "about:blank"],
            stdout=self.log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env)
        self._id = 0
        self.sock = None
        try:
            self._connect(timeout)
            self.call("WebDriver:NewSession", {"capabilities": {"alwaysMatch": {"strictFileInteractability": False}}})
            self.call("WebDriver:SetWindowRect", {"width": width, "height": height})
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ protocol
    def _connect(self, timeout):
        port_file = self.profile / "MarionetteActivePort"
        deadline = time.monotonic() + timeout
        while True:
            if self.process.poll() is not None:
                raise RuntimeError(f"Firefox exited with status {self.process.returncode}: {self.log_tail()}")
            if port_file.is_file() and port_file.read_text().strip().isdigit():
                try:
                    self.sock = socket.create_connection(("127.0.0.1", int(port_file.read_text())), timeout=timeout)
                    break
                except OSError:
                    pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"Firefox's Marionette did not start in {timeout:.0f} s: {self.log_tail()}")
            time.sleep(0.1)
        self._buffer = b""
        hello = self._receive()
        if hello.get("marionetteProtocol", 0) < 3:
            raise RuntimeError(f"unexpected Marionette hello {hello}")

    def _receive(self):
        while b":" not in self._buffer:
            self._read_more()
        length, _, rest = self._buffer.partition(b":")
        length = int(length)
        self._buffer = rest
        while len(self._buffer) < length:
            self._read_more()
        message, self._buffer = self._buffer[:length], self._buffer[length:]
        return json.loads(message)

    def _read_more(self):
        chunk = self.sock.recv(1 << 16)
        if not chunk:
            raise RuntimeError(f"Firefox closed the Marionette connection: {self.log_tail()}")
        self._buffer += chunk

    def call(self, name: str, params: dict | None = None):
        """Send command ``name`` and return its result (a dict; ``{"value": ...}`` for most)."""
        self._id += 1
        data = json.dumps([0, self._id, name, params or {}]).encode()
        self.sock.sendall(str(len(data)).encode() + b":" + data)
        while True:
            kind, msg_id, error, result = self._receive()
            if kind == 1 and msg_id == self._id:
                break
        if error:
            raise MarionetteError(error)
        return result

    def log_tail(self, n: int = 2000) -> str:
        try:
            return (self.profile / "firefox.log").read_bytes()[-n:].decode(errors="replace")
        except OSError:
            return ""

    # ------------------------------------------------------------------ WebDriver
    def goto(self, url: str):
        self.call("WebDriver:Navigate", {"url": url})

    def find(self, selector: str) -> dict:
        """A web element reference (for :meth:`click`, :meth:`send_keys`, script arguments)."""
        found = self.call("WebDriver:FindElement", {"using": "css selector", "value": selector})
        return found.get("value", found)

    def click(self, selector: str):
        self.call("WebDriver:ElementClick", {"id": self.find(selector)[ELEMENT]})

    def send_keys(self, selector: str, text: str):
        """Type ``text`` into an input; for a file input, ``text`` is the file's path."""
        self.call("WebDriver:ElementSendKeys", {"id": self.find(selector)[ELEMENT], "text": text})

    def run(self, script: str, *args):
        """Run ``script`` (a function body: ``return ...``; ``arguments[i]``) in the page."""
        return self.call("WebDriver:ExecuteScript", {"script": script, "args": list(args)}).get("value")

    def run_async(self, script: str, *args, timeout: float = 60.0):
        """Run ``script``, which calls ``arguments[arguments.length - 1](result)`` when done."""
        self.call("WebDriver:SetTimeouts", {"script": int(timeout * 1000)})
        return self.call("WebDriver:ExecuteAsyncScript", {"script": script, "args": list(args)}).get("value")

    def wait_for(self, expression: str, timeout: float = 30.0):
        """Wait until the JavaScript ``expression`` is truthy; return its value."""
        deadline = time.monotonic() + timeout
        while True:
            value = self.run(f"return ({expression});")
            if value:
                return value
            if time.monotonic() > deadline:
                raise TimeoutError(f"not true after {timeout:.0f} s: {expression}")
            time.sleep(0.05)

    def fill(self, selector: str, value: str):
        """Set an input's value as typing does (the input and change events fire)."""
        self.run(f"({FILL_JS})(arguments[0], arguments[1]);", self.find(selector), value)

    def drag(self, selector: str, points):
        """Press the left mouse button at the first point, move through the others, release:
        points (x, y) in CSS pixels from the element's top-left corner (scrolled into view)."""
        element = self.find(selector)
        # after a scroll, two frames: Firefox hit-tests with the scrolled layout only then
        width, height = self.run_async("const e = arguments[0], done = arguments[arguments.length - 1];"
                                       "e.scrollIntoView({block: 'center'}); requestAnimationFrame(() =>"
                                       " requestAnimationFrame(() => { const r = e.getBoundingClientRect();"
                                       " done([r.width, r.height]); }));", element, timeout=10)

        def move(x, y):  # WebDriver measures from the element's centre, in whole pixels
            return {"type": "pointerMove", "origin": element, "x": int(round(x - width / 2)),
                    "y": int(round(y - height / 2)), "duration": 0}

        actions = [move(*points[0]), {"type": "pointerDown", "button": 0}]
        actions += [move(*p) for p in points[1:]] + [{"type": "pointerUp", "button": 0}]
        self.call("WebDriver:PerformActions", {"actions": [
            {"type": "pointer", "id": "mouse", "parameters": {"pointerType": "mouse"}, "actions": actions}]})
        self.call("WebDriver:ReleaseActions")

    def screenshot(self, path):
        data = self.call("WebDriver:TakeScreenshot", {"full": True, "hash": False}).get("value")
        Path(path).write_bytes(base64.b64decode(data))

    # ------------------------------------------------------------------ lifetime
    def close(self):
        try:
            if self.sock is not None:
                try:
                    self.call("Marionette:Quit", {"flags": ["eForceQuit"]})
                except (OSError, RuntimeError):
                    pass
                self.sock.close()
            try:
                self.process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(timeout=15)
        finally:
            self.log.close()
            shutil.rmtree(self.profile, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
