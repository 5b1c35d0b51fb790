"""``tghop serve``'s page in a real browser (Chromium through Playwright) against a real
uvicorn server: pick builtin:bricks, watch the fit's progress bar finish, generate, and
check the result's natural size and the 3x3 tiled preview."""

import os
import shutil

import pytest

CHROMIUM = os.environ.get("TGHOP_CHROMIUM", "/usr/bin/chromium")
if not (os.path.isfile(CHROMIUM) and os.access(CHROMIUM, os.X_OK)):
    pytest.skip(f"no Chromium at {CHROMIUM} (install it: apt-get install chromium; or set TGHOP_CHROMIUM)",
                allow_module_level=True)
sync_api = pytest.importorskip("playwright.sync_api",
                               reason="Playwright is not installed: pip install -e '.[web-test]'")

from conftest import FAST_FIT  # noqa: E402

ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
#: Where the test leaves a screenshot of the page (to look at).
SCREENSHOT = os.environ.get("TGHOP_SCREENSHOT", "/tmp/tghop-serve-page.png")


@pytest.fixture(scope="module")
def page(live_server):
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 1400})
            errors = []
            page.on("pageerror", lambda exc: errors.append(str(exc)))
            page.on("console", lambda msg: errors.append(msg.text) if msg.type == "error" else None)
            page.goto(live_server.url + "/")
            page.wait_for_selector("body[data-ready='1']", timeout=30_000)
            page.errors = errors
            yield page
        finally:
            browser.close()


def test_pick_builtin_fit_generate_and_see_the_tiled_preview(page, live_server):
    page.click("#fit-settings summary")
    page.uncheck("#layout")
    for name in ("n_clusters", "n_codewords", "stride", "max_patches"):
        page.fill(f"#{name}", FAST_FIT[name])
    page.select_option("#builtin", "bricks")
    page.wait_for_selector("#fit-status:not([hidden])")
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done'", timeout=90_000)
    assert page.eval_on_selector("#progress", "p => p.value") == 1
    assert page.is_enabled("#go")
    page.wait_for_selector("#summary:not([hidden])")
    assert "layout off" in page.text_content("#summary")
    assert page.eval_on_selector("#exemplar", "i => i.complete && i.naturalWidth") == 256
    page.fill("#height", "72")
    page.fill("#width", "104")
    page.fill("#seed", "4")
    page.fill("#n_patches", "400")  # a small pool: quick images
    page.check("#tile")
    page.click("#go")
    page.wait_for_function("(() => { const i = document.getElementById('result');"
                           " return !i.hidden && i.complete && i.naturalWidth > 0; })()", timeout=60_000)
    size = page.eval_on_selector("#result", "i => [i.naturalHeight, i.naturalWidth]")
    assert size == [72, 104]
    page.wait_for_selector("#tiled[data-ready='1']")
    assert page.eval_on_selector("#tiled", "c => [c.height, c.width]") == [3 * 72, 3 * 104]
    assert page.get_attribute("#download-png", "href").startswith("blob:")
    model_link = page.get_attribute("#download-model", "href")
    assert model_link.startswith("/api/models/") and model_link.endswith("/file")
    page.click("#strip-go")  # 8 seeds from the seed field on; clicking one makes it the result
    page.wait_for_function("document.querySelectorAll('#strip img').length === 8 && "
                           "[...document.querySelectorAll('#strip img')].every(i => i.complete && i.naturalWidth)",
                           timeout=90_000)
    page.click("#strip img[data-seed='7']")
    page.wait_for_function("document.getElementById('result-caption').textContent.endsWith('seed 7')")
    assert page.input_value("#seed") == "7"
    page.check("#zoom")
    assert "zoom" in page.eval_on_selector("body", "b => b.className")
    page.screenshot(path=SCREENSHOT, full_page=True)
    assert not page.errors, page.errors
