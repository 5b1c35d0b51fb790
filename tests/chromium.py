"""Headless Chromium (Debian's ``chromium-headless-shell``, else its ``chromium``; never a downloaded browser)
driven by Playwright: used by the ``test_server_browser*.py`` tests and by
``scripts/make_gallery.py serve`` (the README's screenshot of ``tghop serve``'s page)."""

import contextlib
import functools
import os
import time

#: Debian's ``chromium-headless-shell``: the same Chromium built for headless use alone (Playwright's choice for
#: headless runs), lighter on the CPU than the whole browser (docs/choices.md, "The test suite on CI's two cores").
HEADLESS_SHELL = "/usr/bin/chromium-headless-shell"
#: Debian's whole browser, where the headless shell is not installed.
FALLBACK = "/usr/bin/chromium"


def _default_browser():
    """:data:`HEADLESS_SHELL` where it is an executable, else :data:`FALLBACK`."""
    if os.path.isfile(HEADLESS_SHELL) and os.access(HEADLESS_SHELL, os.X_OK):
        return HEADLESS_SHELL
    return FALLBACK


#: The browser: ``$TGHOP_CHROMIUM``, else Debian's headless shell, else Debian's chromium.
CHROMIUM = os.environ.get("TGHOP_CHROMIUM") or _default_browser()
#: Headless, no GPU, nothing fetched in the background.
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
#: How often a page of :func:`served_page` evaluates a ``wait_for_function`` condition, in milliseconds, unless the
#: call says: Playwright's default, each animation frame, had headless Chromium draw frames for the whole wait,
#: about five times the browser's CPU of a look every 20 ms (docs/choices.md, "The test suite on CI's two cores").
POLL_MS = 20
#: Why there is no browser to drive, when :func:`missing` says so.
INSTALL = "install it: apt-get install chromium-headless-shell (or chromium); or set TGHOP_CHROMIUM"


@contextlib.contextmanager
def window(page, width, height):
    """The page in a window of ``width`` x ``height``, scrolled to its top; back to the tests' 1200x1400 after."""
    page.set_viewport_size({"width": width, "height": height})
    try:
        page.evaluate("window.scrollTo(0, 0)")
        yield
    finally:
        page.set_viewport_size({"width": 1200, "height": 1400})

def missing():
    """None when :data:`CHROMIUM` is an executable, else the reason (with the fix)."""
    if os.path.isfile(CHROMIUM) and os.access(CHROMIUM, os.X_OK):
        return None
    return f"no Chromium at {CHROMIUM} ({INSTALL})"


def require():
    """Skip the test file importing this (at its import, ``allow_module_level``) where there is no Chromium or no
    Playwright, saying which and the fix; else ``playwright.sync_api``. conftest's ``page`` fixture is the file's
    page (:func:`served_page` in :func:`shared_browser`)."""
    import pytest

    if missing():
        pytest.skip(missing(), allow_module_level=True)
    return pytest.importorskip("playwright.sync_api",
                               reason="Playwright is not installed: pip install -e '.[web-test]'")


def launch(playwright):
    """The headless browser, from a started ``playwright.sync_api.sync_playwright()``."""
    return playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)


#: The test session's one browser (:func:`shared_browser`): "manager" (Playwright's, started) and "browser".
_SHARED = {}


def shared_browser():
    """The headless browser the browser test files share, started at its first use: Playwright's driver and
    Chromium started once, not once a file; each file's page has a context of its own (:func:`served_page`).
    :func:`close_shared` ends it (conftest's hook, after the last of those files in a row): while it runs,
    Playwright's sync API marks its event loop as the thread's running one, which ``asyncio.run`` refuses."""
    if "browser" not in _SHARED or not _SHARED["browser"].is_connected():
        close_shared()
        from playwright import sync_api

        manager = sync_api.sync_playwright()
        playwright = manager.__enter__()
        try:
            _SHARED["browser"] = launch(playwright)
        except BaseException:
            manager.__exit__(None, None, None)
            raise
        _SHARED["manager"] = manager
    return _SHARED["browser"]


def close_shared():
    """:func:`shared_browser`'s browser and Playwright's driver ended (nothing where none runs)."""
    browser, manager = _SHARED.pop("browser", None), _SHARED.pop("manager", None)
    try:
        if browser is not None and browser.is_connected():
            browser.close()
    finally:
        if manager is not None:
            manager.__exit__(None, None, None)


@contextlib.contextmanager
def served_page(url, browser=None):
    """A page of the headless browser at ``url`` (tghop serve's page), ready (its body's
    ``data-ready``); ``page.errors`` collects its JavaScript errors and console errors. ``browser``: a
    launched one (the tests': :func:`shared_browser`), the page in a context of its own (its storage, its
    IndexedDB, its downloads) closed at the end; None: a browser of its own, closed at the end."""
    if browser is None:
        from playwright import sync_api

        with sync_api.sync_playwright() as p:
            own = launch(p)
            try:
                with served_page(url, own) as page:
                    yield page
            finally:
                own.close()
        return
    context = browser.new_context(viewport={"width": 1200, "height": 1400}, accept_downloads=True)
    try:
        page = context.new_page()
        page.wait_for_function = functools.partial(page.wait_for_function, polling=POLL_MS)
        errors = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.on("console", lambda msg: errors.append(msg.text) if msg.type == "error" else None)
        page.goto(url)
        page.wait_for_selector("body[data-ready='1']", timeout=30_000)
        page.errors = errors
        yield page
    finally:
        context.close()


def load_empty(page):
    """The page loaded again as on a first visit: what it keeps across a reload (0.59: its working model and recent
    results, in the browser's IndexedDB) forgotten first."""
    page.evaluate("""() => new Promise((done) => {
      if (historyDb) historyDb.close();
      const request = indexedDB.deleteDatabase("tghop");
      request.onsuccess = request.onerror = request.onblocked = () => done();
    })""")
    page.goto(page.url)
    page.wait_for_selector("body[data-ready='1']")


def load_fresh(page, fit_settings, *, clear_errors=True):
    """:func:`load_empty`, then :func:`set_fit_settings` of ``fit_settings``: the page as on a first visit, ready to
    fit fast. ``clear_errors``: the errors collected so far forgotten (the refusals of the test before: Chromium logs
    each 4xx response as a console error)."""
    load_empty(page)
    if clear_errors:
        page.errors.clear()
    set_fit_settings(page, fit_settings)


def set_fit_settings(page, values):
    """Open the page's fit settings, turn the coarse-to-fine layout off and fill the fields of
    ``values`` (``{field id: text}``: the tests' fast fit, ``conftest.FAST_FIT``). Open already (0.59: kept open across
    a reload), they are left open."""
    if not page.eval_on_selector("#fit-settings", "d => d.open"):
        page.click("#fit-settings summary")
    page.uncheck("#layout")
    for name in ("n_clusters", "n_codewords", "stride", "max_patches"):
        page.fill(f"#{name}", values[name])


def choose_mode(page, name):
    """Click the result's mode ``name`` (its label: the radio button is hidden behind it), as a user does."""
    page.locator("label", has=page.locator(f"#mode-{name}")).click()
    assert page.is_checked(f"#mode-{name}")


def undo_said(page, button, message, times):
    """What ``message`` (a selector) says after each of ``times`` clicks of the Undo ``button``: a list."""
    said = []
    for _ in range(times):
        page.click(button)
        said.append(page.text_content(message))
    return said


def open_paint(page, height, width):
    """Paint on a canvas of ``height`` x ``width``: the first two models ticked, the second colour chosen, the guide
    scrolled into view."""
    page.fill("#height", str(height))
    page.fill("#width", str(width))
    choose_mode(page, "paint")
    for box in page.query_selector_all("#paint-models input[type=checkbox]")[:2]:
        box.check()
    page.locator("#paint-colours label").nth(1).click()
    page.locator("#guide").scroll_into_view_if_needed()


def fit_builtin(page, name):
    """Pick builtin:``name`` in the menu and wait until its fit is done (from the server's cache when it is
    there) and its model is the working one, summarised."""
    page.select_option("#builtin", name)
    page.wait_for_function("(n) => document.getElementById('fit-status').dataset.state === 'done' &&"
                           " state.working && state.working.name === 'builtin:' + n &&"
                           " document.getElementById('builtin').value === n &&"
                           " document.getElementById('summary').textContent.startsWith('model ')",
                           arg=name, timeout=90_000)
    page.wait_for_selector("#summary:not([hidden])")


def upload_model(page, path, timeout=60_000):
    """Load the model file at ``path`` with the page's model-file input and wait until it is the working model and
    the page has settled on it: its summary shown, naming it (a summary of the model before, or its box still
    hidden and the page's layout still to move, passed a wait on the message alone). Returns the model's id (the
    file's SHA-256, as the server keeps it)."""
    import hashlib
    from pathlib import Path

    model_id = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    page.set_input_files("#model-file", str(path))
    page.wait_for_function("(id) => state.modelId === id && !document.getElementById('summary').hidden &&"
                           " /^(model|material) /.test(document.getElementById('summary').textContent) &&"
                           " document.getElementById('summary').textContent.includes(' ' + id.slice(0, 12) + ':')",
                           arg=model_id, timeout=timeout)
    return model_id


def wait_said(page, fragment, timeout=90_000):
    """Wait until the page's message says ``fragment``; the message. AssertionError naming what it says
    instead after ``timeout`` milliseconds."""
    from playwright import sync_api

    try:
        page.wait_for_function("(f) => document.getElementById('message').textContent.includes(f)", arg=fragment,
                               timeout=timeout)
    except sync_api.TimeoutError:
        raise AssertionError(f"{fragment!r} never said: {page.text_content('#message')!r}") from None
    return page.text_content("#message")


def posted_fits(page):
    """The bodies of the fits the page asks for from now on (``POST /api/models``): a list that fills as they are
    sent."""
    bodies = []
    page.on("request", lambda r: bodies.append(r.post_data_buffer) if r.method == "POST" and r.url.endswith(
        "/api/models") else None)
    return bodies


class HeldAnswers:
    """The server's answers to the page's requests matching ``pattern`` (the strip's seeds by default), held
    until the test sends them on (:meth:`send_next`, :meth:`release`): a strip still runs when the test acts on
    it, however quick its images are. ``urls``: the address of each request, in order. A context manager: the
    requests after its exit go straight to the server (and what is still held then is sent on)."""

    def __init__(self, page, pattern="**/api/models/*/images"):
        self.page, self.pattern, self.urls, self.held, self.holding = page, pattern, [], [], True

    def __enter__(self):
        self.page.route(self.pattern, self._hold)
        return self

    def __exit__(self, *exc):
        self.release()
        self.page.unroute(self.pattern, self._hold)

    def _hold(self, route):
        self.urls.append(route.request.url)
        if not self.holding:
            route.continue_()
            return
        answer = route.fetch()
        if self.holding:
            self.held.append((route, answer))
        else:  # released while the server answered
            route.fulfill(response=answer)

    def wait(self, timeout=120.0):
        """Wait until an answer is held (the page has asked, and the server answered); AssertionError after
        ``timeout`` seconds without one."""
        deadline = time.monotonic() + timeout
        while not self.held:
            assert time.monotonic() < deadline, f"no answer to {self.pattern} came within {timeout:g} s"
            self.page.wait_for_timeout(20)

    def send_next(self):
        """Send on the next answer held, once there is one."""
        self.wait()
        route, answer = self.held.pop(0)
        route.fulfill(response=answer)

    def release(self):
        """Send on the answers held and hold no more."""
        self.holding = False
        while self.held:
            route, answer = self.held.pop(0)
            route.fulfill(response=answer)
