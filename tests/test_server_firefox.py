"""``tghop serve``'s page in Firefox (Debian's ``firefox-esr``, headless, driven through
its own Marionette protocol: :mod:`marionette`) against a real uvicorn server: upload a
small generated exemplar, watch the fit finish, generate, check the result's natural
size and the 3x3 tiled preview, save a screenshot; then time a 512x512 result from the
click; then fit a second model, paint the right half with its colour in Paint mode
(pointer actions of WebDriver) and generate; then Co-occurrence mode, the same steps as the
Chromium test (:mod:`browser_cooc`): load a tiny checkpoint, place two crops by clicking,
morph, paint an edit, generate, with a boost too; then drop an image on the drop area, cancel
a fit and upload a saved model (:mod:`browser_source`, the Chromium test's steps too).

No driver or browser is downloaded (geckodriver is in neither Debian nor PyPI, and
Playwright drives its own patched Firefox): without a Firefox the test is skipped with
the reason.
"""

import os

import pytest

from browser_cooc import COLUMN_COLOURS_JS, FIRST, SECOND, cooc_steps
from browser_source import cancel_steps, drop_steps, upload_steps
from conftest import CLICK_TO_RESULT_JS, FAST_FIT
from marionette import Firefox, find_firefox

FIREFOX = find_firefox()
if FIREFOX is None:
    pytest.skip("no Firefox (install it: apt-get install firefox-esr; or set TGHOP_FIREFOX)",
                allow_module_level=True)

#: Where the test leaves a screenshot of the page (to look at).
SCREENSHOT = os.environ.get("TGHOP_FIREFOX_SCREENSHOT", "/tmp/tghop-serve-page-firefox.png")
COOC_SCREENSHOT = os.environ.get("TGHOP_FIREFOX_COOC_SCREENSHOT", "/tmp/tghop-cooc-page-firefox.png")
#: Page errors (uncaught exceptions, rejected promises) from here on, in window.__errors.
CATCH_ERRORS = ("window.__errors = [];"
                "window.addEventListener('error', e => window.__errors.push(String(e.message)));"
                "window.addEventListener('unhandledrejection', e => window.__errors.push(String(e.reason)));")


@pytest.fixture(scope="module")
def firefox(live_server):
    with Firefox(FIREFOX) as browser:
        browser.goto(live_server.url + "/")
        browser.wait_for("document.body.dataset.ready === '1'", timeout=30)
        browser.run(CATCH_ERRORS)
        yield browser


def test_upload_fit_generate_and_see_the_tiled_preview_in_firefox(firefox, live_server, tmp_path):
    from tghop import data
    from tghop.imageio import save_image

    ff = firefox
    assert "Firefox/" in ff.run("return navigator.userAgent")
    exemplar = tmp_path / "my exemplar.png"
    save_image(data.cells(128, rng=7), exemplar)
    ff.click("#fit-settings summary")
    ff.click("#layout")  # off: a quicker fit
    assert ff.run("return document.getElementById('layout').checked") is False
    for name in ("n_clusters", "n_codewords", "stride", "max_patches"):
        ff.fill(f"#{name}", FAST_FIT[name])
    ff.send_keys("#file", str(exemplar))  # the hidden file input behind "Pick an image..."
    ff.wait_for("!document.getElementById('fit-status').hidden")
    state = ff.wait_for("['done', 'failed', 'cancelled'].includes(document.getElementById('fit-status').dataset.state)"
                        " && document.getElementById('fit-status').dataset.state", timeout=120)
    assert state == "done", ff.run("return document.body.innerText")
    assert ff.run("return document.getElementById('progress').value") == 1
    ff.wait_for("!document.getElementById('summary').hidden")
    assert "layout off" in ff.run("return document.getElementById('summary').textContent")
    assert ff.run("const i = document.getElementById('exemplar'); return [i.complete, i.naturalWidth]") == [True, 128]
    assert ff.run("return document.getElementById('go').disabled") is False
    ff.fill("#height", "72")
    ff.fill("#width", "104")
    ff.fill("#seed", "4")
    ff.fill("#n_patches", "400")  # a small pool: quick images
    ff.click("#tile")
    ff.click("#go")
    ff.wait_for("(() => { const i = document.getElementById('result');"
                " return !i.hidden && i.complete && i.naturalWidth > 0; })()", timeout=60)
    assert ff.run("const i = document.getElementById('result'); return [i.naturalHeight, i.naturalWidth]") == [72, 104]
    ff.wait_for("document.getElementById('tiled').dataset.ready === '1'")
    assert ff.run("const c = document.getElementById('tiled'); return [c.height, c.width]") == [3 * 72, 3 * 104]
    # the tiled canvas holds the result's pixels: its top-left and its centre copies agree
    same = ff.run("const c = document.getElementById('tiled').getContext('2d');"
                  "const a = c.getImageData(0, 0, 104, 72).data, b = c.getImageData(104, 72, 104, 72).data;"
                  "return a.length > 0 && a.every((v, k) => v === b[k]) && a.some(v => v > 0);")
    assert same is True
    assert ff.run("return document.getElementById('download-png').href").startswith("blob:")
    assert ff.run("return document.getElementById('result-caption').textContent") == "result: 72x104, seed 4"
    ff.screenshot(SCREENSHOT)
    with open(SCREENSHOT, "rb") as fh:
        assert fh.read(8) == b"\x89PNG\r\n\x1a\n"
    assert ff.run("return window.__errors") == []


def test_a_512x512_result_appears_after_the_click_in_firefox(firefox, live_server, record_property):
    ff = firefox
    if ff.run("return document.getElementById('go').disabled"):
        pytest.skip("needs the fitted model of the test before")
    ff.fill("#height", "512")
    ff.fill("#width", "512")
    ff.fill("#n_patches", "")  # the default pool, as a user gets it
    ff.run("document.getElementById('tile').checked = false;")
    # One click; its time is reported (-s, the junit property), never asserted: what a click
    # costs is measured by benchmarks/bench_serve_click.py (docs/serve.md).
    ms, caption, server_ms = ff.run_async(f"({CLICK_TO_RESULT_JS})(arguments[0], arguments[arguments.length - 1]);",
                                          11, timeout=120)
    assert caption == "result: 512x512, seed 11"
    assert server_ms is not None and 0 < server_ms < ms
    record_property("firefox_click_to_result_512_s", (ms / 1000, server_ms / 1000))
    print(f"Firefox: 512x512 result {ms / 1000:.2f} (server {server_ms / 1000:.2f}) s after the click")
    assert ff.run("return window.__errors") == []


def test_paint_the_right_half_with_a_second_model_in_firefox(firefox, live_server):
    ff = firefox
    if ff.run("return document.getElementById('go').disabled"):
        pytest.skip("needs the fitted model of the first test")
    ff.fill("#height", "64")
    ff.fill("#width", "96")
    ff.fill("#n_patches", "300")
    ff.run("const s = document.getElementById('builtin'); s.value = 'bricks';"
           "s.dispatchEvent(new Event('change', {bubbles: true}));")  # a second model, the same fast fit
    ff.wait_for("document.querySelectorAll('#paint-models input').length === 2", timeout=120)
    ff.click("label:has(#mode-paint)")
    ff.wait_for("document.getElementById('guide').dataset.ready === '1'")
    assert ff.run("const c = document.getElementById('guide'); return [c.height, c.width]") == [64, 96]
    ff.click("label:has(#paint-colour-1)")
    assert ff.run("return document.getElementById('paint-colour-1').checked") is True
    ff.fill("#paint-brush", "24")
    scale = ff.run("const c = document.getElementById('guide'); return c.getBoundingClientRect().width / c.width")
    for x in (60, 84):  # two strokes top to bottom: the right half, x 48 to 95
        # from y 1 to 63: inside the canvas after WebDriver's rounding; the 24 px brush covers the edges
        ff.drag("#guide", [(x * scale, y * scale) for y in range(1, 64, 6)] + [(x * scale, 63 * scale)])
    assert ff.run(COLUMN_COLOURS_JS, "#guide", 0, 48) == [FIRST]
    assert ff.run(COLUMN_COLOURS_JS, "#guide", 48, 96) == [SECOND]
    ff.fill("#paint-seed", "2")
    ff.click("#paint-go")
    ff.wait_for("document.getElementById('result-caption').textContent ==="
                " 'painted: 64x96, seed 2 (my-exemplar + bricks)'", timeout=60)
    assert ff.run("const i = document.getElementById('result'); return [i.naturalHeight, i.naturalWidth]") == [64, 96]
    assert ff.run("return window.__errors") == []


def test_cooc_load_a_checkpoint_place_crops_morph_and_edit_in_firefox(firefox, live_server, tiny_cooc_checkpoint):
    cooc_steps(firefox, tiny_cooc_checkpoint)  # the same steps as Chromium's test
    firefox.screenshot(COOC_SCREENSHOT)
    firefox.click("label:has(#mode-view)")
    assert firefox.run("return document.getElementById('cooc').hidden") is True
    assert firefox.run("return window.__errors") == []


def test_drop_an_image_cancel_a_fit_and_upload_a_saved_model_in_firefox(firefox, live_server, small_model, tmp_path):
    from tghop import data
    from tghop.imageio import save_image
    from tghop.modelfile import save_model

    firefox.click("label:has(#mode-view)")
    dropped = tmp_path / "dropped.png"
    save_image(data.bricks(64, rng=11), dropped)
    drop_steps(firefox, dropped.read_bytes())  # the same steps as Chromium's test
    cancel_steps(firefox)
    npz = tmp_path / "saved bricks.npz"
    save_model(small_model, npz)
    upload_steps(firefox, npz, small_model.exemplar_shape_[:2])
    assert firefox.run("return window.__errors") == []
