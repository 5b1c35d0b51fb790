"""``tghop serve``'s page in a real browser (Chromium through Playwright) against a real
uvicorn server: pick builtin:bricks, watch the fit's progress bar finish, generate, and
check the result's natural size and the 3x3 tiled preview; paint a hole with the brush in
Inpaint mode and fill it; with a second model, paint the right half in Paint mode, generate,
and make a morph strip; load a co-occurrence checkpoint, place two crops, morph and edit
(with a boost too; the steps of :mod:`browser_cooc`, shared with the Firefox test); drop an
image on the drop area, cancel a fit, upload a saved model (:mod:`browser_source`, shared too)."""

import io
import os

import chromium
from browser_cooc import cooc_steps
from browser_source import cancel_steps, drop_steps, upload_steps
from conftest import CLICK_TO_RESULT_JS, FAST_FIT
from marionette import FILL_JS

chromium.require()

#: Where the test leaves a screenshot of the page (to look at).
SCREENSHOT = os.environ.get("TGHOP_SCREENSHOT", "/tmp/tghop-serve-page.png")
INPAINT_SCREENSHOT = os.environ.get("TGHOP_INPAINT_SCREENSHOT", "/tmp/tghop-inpaint-page.png")
PAINT_SCREENSHOT = os.environ.get("TGHOP_PAINT_SCREENSHOT", "/tmp/tghop-paint-page.png")
COOC_SCREENSHOT = os.environ.get("TGHOP_COOC_SCREENSHOT", "/tmp/tghop-cooc-page.png")


def fit_bricks(page):
    """Fit builtin:bricks with the fast settings (from the server's cache when it is there)."""
    chromium.set_fit_settings(page, FAST_FIT)
    page.select_option("#builtin", "bricks")
    page.wait_for_selector("#fit-status:not([hidden])")
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done'", timeout=90_000)


def test_pick_builtin_fit_generate_and_see_the_tiled_preview(page, live_server):
    # Hidden links were shown (.button's display beat the hidden attribute) and did nothing.
    assert page.is_hidden("#download-png") and page.is_hidden("#download-model")
    # The file inputs take the keyboard's focus, and Enter on the drop zone opens the chooser.
    assert page.eval_on_selector_all("input[type=file]", "l => l.every(i => !i.hidden && i.tabIndex >= 0)")
    with page.expect_file_chooser() as chooser:
        page.focus("#drop")
        page.keyboard.press("Enter")
    assert chooser.value.element.evaluate("i => i.id") == "file"
    page.set_viewport_size({"width": 390, "height": 900})  # a phone: the toolbars wrap (they ran off the page)
    assert page.evaluate("document.documentElement.scrollWidth") <= 390
    page.set_viewport_size({"width": 1200, "height": 1400})
    fit_bricks(page)
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
    assert model_link.startswith("/api/models/") and model_link.endswith("/file?name=bricks")
    page.click("#strip-go")  # 8 seeds from the seed field on; clicking one makes it the result
    page.wait_for_function("document.querySelectorAll('#strip img').length === 8 && "
                           "[...document.querySelectorAll('#strip img')].every(i => i.complete && i.naturalWidth)",
                           timeout=90_000)
    page.focus("#strip img[data-seed='5']")  # by keyboard too
    page.keyboard.press("Enter")
    page.wait_for_function("document.getElementById('result-caption').textContent.endsWith('seed 5')")
    page.click("#strip img[data-seed='7']")
    page.wait_for_function("document.getElementById('result-caption').textContent.endsWith('seed 7')")
    assert page.input_value("#seed") == "7"
    page.check("#zoom")
    assert "zoom" in page.eval_on_selector("body", "b => b.className")
    page.screenshot(path=SCREENSHOT, full_page=True)
    assert not page.errors, page.errors


def test_a_512x512_result_appears_after_the_click(page, live_server, record_property):
    chromium.choose_mode(page, "view")
    if not page.is_enabled("#go"):  # run alone: fit first
        fit_bricks(page)
    page.fill("#height", "512")
    page.fill("#width", "512")
    page.fill("#n_patches", "")  # the default pool, as a user gets it
    page.uncheck("#tile")
    # One click; its time is reported (-s, the junit property), never asserted: what a click
    # costs is measured by benchmarks/bench_serve_click.py (docs/serve.md).
    ms, caption, server_ms = page.evaluate(f"(seed) => new Promise((done) => ({CLICK_TO_RESULT_JS})(seed, done))", 11)
    assert caption == "result: 512x512, seed 11"
    assert server_ms is not None and 0 < server_ms < ms
    record_property("chromium_click_to_result_512_s", (ms / 1000, server_ms / 1000))
    print(f"Chromium: 512x512 result {ms / 1000:.2f} (server {server_ms / 1000:.2f}) s after the click")
    assert not page.errors, page.errors


#: The result's pixels (RGBA, row by row), drawn on a canvas.
PIXELS = ("i => { const c = document.createElement('canvas'); c.width = i.naturalWidth; c.height = i.naturalHeight;"
          " const x = c.getContext('2d'); x.drawImage(i, 0, 0);"
          " return Array.from(x.getImageData(0, 0, c.width, c.height).data); }")
RESULT_SHOWN = ("(() => { const i = document.getElementById('result');"
                " return !i.hidden && i.complete && i.naturalWidth > 0 && "
                "document.getElementById('result-caption').textContent.startsWith('%s'); })()")


def stroke(page, start, end, canvas="#mask"):
    """Drag the mouse over the canvas from ``start`` to ``end`` (x, y in the canvas's pixels)."""
    page.locator(canvas).scroll_into_view_if_needed()
    box = page.locator(canvas).bounding_box()
    width, height = page.eval_on_selector(canvas, "c => [c.width, c.height]")
    sx, sy = box["width"] / width, box["height"] / height
    page.mouse.move(box["x"] + start[0] * sx, box["y"] + start[1] * sy)
    page.mouse.down()
    for t in (i / 10 for i in range(1, 11)):
        x, y = start[0] + (end[0] - start[0]) * t, start[1] + (end[1] - start[1]) * t
        page.mouse.move(box["x"] + x * sx, box["y"] + y * sy)
    page.mouse.up()


def mask_of(page, shape=(96, 128)):
    """The painted pixels of the mask canvas (more than half opaque), as bool (H, W)."""
    import numpy as np

    alpha = page.eval_on_selector("#mask", "c => Array.from(c.getContext('2d').getImageData(0, 0, c.width, c.height)"
                                           ".data.filter((v, k) => k % 4 === 3))")
    return np.array(alpha).reshape(shape) > 127


def test_inpaint_paint_a_stroke_and_fill_it(page, live_server):
    import numpy as np

    chromium.choose_mode(page, "view")
    if not page.is_enabled("#go"):  # run alone: fit first
        fit_bricks(page)
    page.fill("#height", "96")
    page.fill("#width", "128")
    page.fill("#seed", "3")
    page.fill("#n_patches", "400")
    page.uncheck("#tile")
    page.click("#go")
    page.wait_for_function(RESULT_SHOWN % "result: 96x128, seed 3", timeout=60_000)
    before = np.array(page.eval_on_selector("#result", PIXELS)).reshape(96, 128, 4)
    assert page.is_hidden("#inpaint")
    chromium.choose_mode(page, "inpaint")
    assert page.is_visible("#inpaint") and page.is_hidden("#pair")
    page.wait_for_selector("#editor[data-ready='1']")
    assert page.eval_on_selector("#mask", "c => [c.height, c.width]") == [96, 128]
    page.fill("#inpaint-seed", "5")
    page.eval_on_selector("#brush", "b => { b.value = '10'; b.dispatchEvent(new Event('input')); }")
    assert page.text_content("#brush-size") == "10 px"
    stroke(page, (40, 40), (88, 56))
    assert page.is_visible("#brush-cursor")
    painted = mask_of(page)
    assert painted[48, 64] and not painted[:30].any() and not painted[70:].any() and 300 < painted.sum() < 1500
    page.screenshot(path=INPAINT_SCREENSHOT, full_page=True)
    page.check("#erase")  # erase the stroke's right end
    stroke(page, (84, 54), (90, 57))
    page.uncheck("#erase")
    erased = painted & ~mask_of(page)
    assert erased[55, 86] and erased.sum() > 20 and not (mask_of(page) & ~painted).any()
    painted = mask_of(page)
    page.click("#fill")
    page.wait_for_function(RESULT_SHOWN % "inpainted: 96x128, seed 5", timeout=60_000)
    assert page.eval_on_selector("#result", "i => [i.naturalHeight, i.naturalWidth]") == [96, 128]
    after = np.array(page.eval_on_selector("#result", PIXELS)).reshape(96, 128, 4)
    changed = (after != before).any(axis=2)
    assert changed[painted].mean() > 0.5  # the painted stroke is filled...
    assert not changed[:28].any() and not changed[72:].any()  # ...and far from it nothing changed
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-inpainted-96x128-seed5.png"
    assert page.get_attribute("#download-png", "href") == page.get_attribute("#result", "src")
    page.wait_for_selector("#editor[data-ready='1']")  # the filled picture is the one to paint on next
    assert not mask_of(page).any()
    page.click("#fill")  # nothing painted: said, not sent
    page.wait_for_function("document.getElementById('inpaint-message').textContent.startsWith('paint the hole')")
    stroke(page, (10, 10), (30, 20))
    assert mask_of(page).any()
    page.click("#clear")
    assert not mask_of(page).any()
    stroke(page, (50, 50), (50, 50))  # a click paints a disc of the brush (a line of length 0 painted nothing)
    assert mask_of(page)[48:53, 48:53].all() and 40 < mask_of(page).sum() < 120
    page.click("#clear")
    # A picture of the user's own: painted and filled the same way.
    from PIL import Image

    from tghop import data
    from tghop.imageio import to_uint8

    own = to_uint8(data.bricks(96, rng=5))[:64, :80]
    buf = io.BytesIO()
    Image.fromarray(own).save(buf, format="PNG")
    page.set_input_files("#picture", files=[{"name": "mine.png", "mimeType": "image/png", "buffer": buf.getvalue()}])
    page.wait_for_function("document.getElementById('mask').width === 80 && "
                           "document.getElementById('editor').dataset.ready === '1'")
    stroke(page, (20, 30), (60, 30))
    hole = mask_of(page, (64, 80))
    page.click("#fill")
    page.wait_for_function(RESULT_SHOWN % "inpainted: 64x80, seed 5", timeout=60_000)
    filled = np.array(page.eval_on_selector("#result", PIXELS)).reshape(64, 80, 4)[..., :3]
    assert (filled[~hole] == own[~hole]).all()  # the picture's pixels outside the stroke, as they were
    assert (filled[hole] != own[hole]).any(axis=1).mean() > 0.5
    # Extend: the filled picture grown to 80x120, kept at its top-left corner; a bad size is said.
    page.wait_for_selector("#editor[data-ready='1']")
    page.fill("#extend-height", "80")
    page.fill("#extend-width", "120")
    page.select_option("#extend-anchor", "top-left")
    page.click("#extend-go")
    page.wait_for_function(RESULT_SHOWN % "extended: 80x120, seed 5", timeout=60_000)
    grown = np.array(page.eval_on_selector("#result", PIXELS)).reshape(80, 120, 4)[..., :3]
    assert (grown[:64, :80] == filled).all() and grown[64:].reshape(-1, 3).std(axis=0).min() > 5
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-extended-80x120-seed5.png"
    page.wait_for_selector("#editor[data-ready='1']")
    page.fill("#extend-height", "40")  # smaller than the picture: said, not sent
    page.click("#extend-go")
    page.wait_for_function("document.getElementById('inpaint-message').textContent.startsWith("
                           "\"give a height and width of at least the picture's 80x120\")")
    chromium.choose_mode(page, "view")
    assert page.is_visible("#pair") and page.is_hidden("#inpaint")
    assert not page.errors, page.errors


def test_paint_two_models_and_morph(page, live_server):
    import numpy as np

    chromium.choose_mode(page, "view")
    if not page.is_enabled("#go"):  # run alone: fit first
        fit_bricks(page)
    page.fill("#height", "40")
    page.fill("#width", "40")
    page.fill("#n_patches", "300")
    page.uncheck("#tile")
    page.select_option("#quality", "best")  # the preset goes with the request
    page.click("#go")
    page.wait_for_function(RESULT_SHOWN % "result: 40x40", timeout=60_000)
    page.select_option("#quality", "default")
    chromium.choose_mode(page, "paint")  # one model: each mode asks for a second
    assert page.text_content("#paint-message") == "fit or load a second model above to paint with two"
    chromium.choose_mode(page, "morph")
    assert page.text_content("#morph-message") == "fit or load a second model above: A and B"
    page.select_option("#builtin", "cells")  # a second model, with the same fast fit settings
    page.wait_for_function("document.querySelectorAll('#paint-models input').length === 2", timeout=90_000)
    # Those requests went stale once it came (they stayed, next to enabled buttons)
    assert page.text_content("#morph-message") == "" and page.text_content("#paint-message") == ""
    chromium.choose_mode(page, "view")
    page.fill("#height", "64")
    page.fill("#width", "96")
    chromium.choose_mode(page, "paint")
    assert page.is_visible("#paint") and page.is_visible("#pair")
    page.wait_for_selector("#guide[data-ready='1']")
    assert page.eval_on_selector("#guide", "c => [c.height, c.width]") == [64, 96]
    assert page.eval_on_selector_all("#paint-models input", "b => b.map(x => x.checked)") == [True, True]
    assert page.is_checked("#paint-colour-1")  # the brush starts on the second model (the first is the background)
    page.locator("label", has=page.locator("#paint-colour-0")).click()
    page.locator("label", has=page.locator("#paint-colour-1")).click()  # the user's choice is kept from here on
    assert page.is_checked("#paint-colour-1")
    page.eval_on_selector("#paint-brush", "b => { b.value = '24'; b.dispatchEvent(new Event('input')); }")
    for x in (60, 84):  # two strokes top to bottom: the right half, x 48 to 95
        stroke(page, (x, 1), (x, 62), canvas="#guide")  # inside the canvas; the brush covers the edges
    rgb = np.array(page.eval_on_selector("#guide", "c => Array.from(c.getContext('2d').getImageData("
                                                   "0, 0, c.width, c.height).data)")).reshape(64, 96, 4)[..., :3]
    first, second = (0xE6, 0x19, 0x4B), (0x3C, 0xB4, 0x4B)
    assert (rgb[:, :48] == first).all() and (rgb[:, 48:] == second).all()
    page.fill("#paint-seed", "2")
    page.click("#paint-go")
    page.wait_for_function(RESULT_SHOWN % "painted: 64x96, seed 2", timeout=60_000)
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-cells-painted-64x96-seed2.png"
    assert page.eval_on_selector("#result", "i => [i.naturalHeight, i.naturalWidth]") == [64, 96]
    painted = np.array(page.eval_on_selector("#result", PIXELS)).reshape(64, 96, 4)[..., :3]
    assert painted[:, :40].std() > 5 and painted[:, 56:].std() > 5  # texture on both sides
    page.screenshot(path=PAINT_SCREENSHOT, full_page=True)
    page.click("#remix-go")  # random regions of both, at the same size
    page.wait_for_function(RESULT_SHOWN % "remix: 64x96, seed 2", timeout=60_000)
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-cells-remix-64x96-seed2.png"
    page.click("#paint-reset")  # all the first model's colour: said, not sent
    page.click("#paint-go")
    page.wait_for_function("document.getElementById('paint-message').textContent"
                           ".startsWith('paint some of builtin:cells')")
    chromium.choose_mode(page, "morph")
    assert page.is_visible("#morph") and page.is_hidden("#paint")
    assert page.eval_on_selector_all("#morph-b option", "o => o.length") == 2 and page.input_value("#morph-b") == "1"
    page.fill("#morph-height", "32")
    page.fill("#morph-width", "128")
    page.click("#morph-go")
    page.wait_for_function(RESULT_SHOWN % "morph: 32x128", timeout=60_000)
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-to-cells-morph-32x128-seed1.png"
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_stop_a_generation_and_a_large_tiled_preview(page, live_server):
    chromium.choose_mode(page, "view")
    if not page.is_enabled("#go"):  # run alone: fit first
        fit_bricks(page)
    page.fill("#n_patches", "400")
    page.fill("#height", "1376")  # 3 x 3 of it is over 16 Mpx: the preview is scaled down, not left blank
    page.fill("#width", "1376")
    page.uncheck("#tile")
    page.fill("#seed", "1")
    page.click("#go")
    page.wait_for_function(RESULT_SHOWN % "result: 1376x1376, seed 1", timeout=120_000)
    page.wait_for_selector("#tiled[data-ready='1']")
    assert page.eval_on_selector("#tiled", "c => [c.height, c.width]") == [3 * 1365, 3 * 1365]
    assert page.text_content("#tiled-title").startswith("Tiled 3\u00d73, shown at 99 %")
    corner = page.eval_on_selector("#tiled", "c => Array.from(c.getContext('2d').getImageData(4090, 4090, 1, 1).data)")
    assert corner[3] == 255  # drawn (a canvas over the browser's limit reads as transparent)
    page.check("#zoom")  # 1:1: the tiling scrolls in its box (it ran off the page, which scrolled sideways)
    assert page.evaluate("document.documentElement.scrollWidth") <= page.viewport_size["width"]
    assert page.eval_on_selector("#tiled-box", "b => b.scrollWidth > b.clientWidth && b.clientWidth > 0")
    page.uncheck("#zoom")
    # Long enough to stop: the button reads Stop while it works. 2048x2048, not 0.62's 4096x4096, whose pool of
    # 30,000 patches the server made whole before the Stop could end it (the next progress report): seconds of its
    # CPU after the test had moved on; at 2048x2048 the Stop lands in quilting, which reports each block
    page.fill("#height", "2048")
    page.fill("#width", "2048")
    page.click("#go")
    page.wait_for_function("document.getElementById('go').textContent === 'Stop'")
    assert page.is_enabled("#go") and not page.is_enabled("#strip-go")
    page.click("#go")
    page.wait_for_function("document.getElementById('gen-message').textContent === 'stopped'", timeout=30_000)
    assert page.text_content("#go") == "Generate" and page.is_enabled("#go")
    assert page.text_content("#result-caption") == "result: 1376x1376, seed 1"  # the last result stays
    page.fill("#height", "256")
    page.fill("#width", "256")
    page.errors.clear()  # Chromium logs the aborted request


class PlaywrightDriver:
    """The calls of :class:`marionette.Firefox` that :func:`browser_cooc.cooc_steps` uses, on
    a Playwright page: one scenario for both browsers."""

    def __init__(self, page):
        self.page = page

    def run(self, script, *args):
        """``script`` is a function body (``return ...``, ``arguments[i]``), as WebDriver's."""
        return self.page.evaluate(f"(args) => (function () {{ {script} }}).apply(null, args)", list(args))

    def wait_for(self, expression, timeout=30.0):
        return self.page.wait_for_function(expression, timeout=timeout * 1000).json_value()

    def fill(self, selector, value):
        self.page.eval_on_selector(selector, FILL_JS, value)

    def click(self, selector):
        self.page.click(selector)

    def send_keys(self, selector, path):
        self.page.set_input_files(selector, path)

    def drag(self, selector, points):
        """Press at the first point, move through the others, release (CSS pixels from the
        element's top-left corner): one point is a click."""
        self.page.locator(selector).scroll_into_view_if_needed()
        box = self.page.locator(selector).bounding_box()
        self.page.mouse.move(box["x"] + points[0][0], box["y"] + points[0][1])
        self.page.mouse.down()
        for x, y in points[1:]:
            self.page.mouse.move(box["x"] + x, box["y"] + y)
        self.page.mouse.up()


def test_cooc_load_a_checkpoint_place_crops_morph_and_edit(page, live_server, tiny_cooc_checkpoint):
    cooc_steps(PlaywrightDriver(page), tiny_cooc_checkpoint)
    page.screenshot(path=COOC_SCREENSHOT, full_page=True)
    chromium.choose_mode(page, "view")
    assert page.is_hidden("#cooc")
    # the bad boost's answer, which Chromium also logs; nothing else
    assert page.errors == ["Failed to load resource: the server responded with a status of 422 (Unprocessable Entity)"]
    page.errors.clear()


def png_bytes(image):
    """``image`` (H, W, 3) float in [0, 1] as the bytes of a PNG file."""
    from PIL import Image

    from tghop.imageio import to_uint8

    buf = io.BytesIO()
    Image.fromarray(to_uint8(image)).save(buf, format="PNG")
    return buf.getvalue()


def test_drop_an_image_cancel_a_fit_and_upload_a_saved_model(page, live_server, small_model, tmp_path):
    from tghop import data
    from tghop.modelfile import save_model

    driver = PlaywrightDriver(page)
    chromium.choose_mode(page, "view")
    drop_steps(driver, png_bytes(data.bricks(64, rng=11)))
    cancel_steps(driver)
    npz = tmp_path / "saved bricks.npz"
    save_model(small_model, npz)
    upload_steps(driver, npz, small_model.exemplar_shape_[:2])
    assert not page.errors, page.errors


def test_cooc_says_where_a_crop_is_and_how_to_paint_the_edit(page, live_server, tiny_cooc_checkpoint):
    # After a click the message still said "click on the exemplar to place crop 1", and nothing beside the
    # edit's board (a block of crop 1's red) said what it was or how to change it.
    page = page.context.browser.new_page(viewport={"width": 1200, "height": 1200})  # a fresh page, its own state
    try:
        page.goto(live_server.url + "/")
        page.wait_for_selector("body[data-ready='1']")
        chromium.choose_mode(page, "cooc")
        page.set_input_files("#cooc-file", str(tiny_cooc_checkpoint))
        page.wait_for_function("document.getElementById('cooc-exemplar').dataset.ready === '1'", timeout=30_000)
        page.wait_for_function("document.getElementById('cooc-guide').width > 0")
        for canvas, caption, below in (("#cooc-exemplar", "#cooc-exemplar-help", True),
                                       ("#cooc-guide", "#cooc-guide-help", False)):
            assert page.is_visible(caption) and page.get_attribute(canvas, "aria-describedby") == caption[1:]
            c, t = page.locator(canvas).bounding_box(), page.locator(caption).bounding_box()
            gap = t["y"] - (c["y"] + c["height"]) if below else c["y"] - (t["y"] + t["height"])
            assert 0 <= gap < 30, (caption, c, t)  # right under the exemplar, right above the board
        assert "each placed crop is outlined in its colour" in page.text_content("#cooc-exemplar-help")
        assert "all crop 1 at first): choose a crop above and drag over it to paint" in " ".join(
            page.text_content("#cooc-guide-help").split())
        box = page.locator("#cooc-exemplar").bounding_box()
        for fx, fy, said in ((0.25, 0.25, "crop 1 is at (0, 0), outlined on the exemplar; the next click places crop "
                                          "2, and the brush paints with it below"),
                             (0.8, 0.8, "crop 2 is at (32, 32), outlined on the exemplar; the next click places "
                                          "crop 3, and the brush paints with it below")):
            page.mouse.click(box["x"] + fx * box["width"], box["y"] + fy * box["height"])
            assert page.text_content("#cooc-message") == said
        page.click("label:has(#cooc-crop-0)")  # crop 1 chosen again: a click moves it
        page.mouse.click(box["x"] + 0.25 * box["width"], box["y"] + 0.8 * box["height"])
        assert page.text_content("#cooc-message") == ("crop 1 is at (32, 0), outlined on the exemplar; a click moves "
                                                      "it, and the brush paints with it below")
    finally:
        page.close()


def test_cooc_mode_says_when_the_server_has_no_pytorch(page, live_server):
    # It asked for a checkpoint, and only the upload's 501 told that none could be used.
    other = page.context.browser.new_page()
    try:
        def no_torch(route):
            answer = route.fetch()
            route.fulfill(response=answer, json={**answer.json(), "cooc": False})  # as without PyTorch

        other.route(live_server.url + "/api", no_torch)
        other.goto(live_server.url + "/")
        other.wait_for_selector("body[data-ready='1']")
        chromium.choose_mode(other, "cooc")
        assert "no PyTorch" in other.text_content("#cooc-message")
        assert "pip install 'tghop[metrics]'" in other.text_content("#cooc-message")
    finally:
        other.close()
    chromium.choose_mode(page, "cooc")  # this server has it (the tests of this module load a checkpoint)
    assert "no PyTorch" not in page.text_content("#cooc-message")
    chromium.choose_mode(page, "view")


def test_the_strip_of_seeds_goes_on_with_its_model_when_another_exemplar_is_picked(page, live_server):
    # The rest of the strip asked for /api/models/null/images ("no model 'null'") once the new fit began.
    chromium.choose_mode(page, "view")
    page.eval_on_selector("#fit-settings", "d => { d.open = false; }")  # fit_bricks opens it
    page.select_option("#builtin", "")
    fit_bricks(page)
    bricks = page.evaluate("state.modelId")
    page.fill("#height", "64")
    page.fill("#width", "64")
    page.fill("#n_patches", "400")
    page.fill("#seed", "20")
    page.evaluate("""() => { window.stripImages = 0; new MutationObserver((changes) => {
      for (const c of changes) window.stripImages += [...c.addedNodes].filter((n) => n.querySelector).length;
    }).observe(document.getElementById('strip'), { childList: true }); }""")
    with chromium.HeldAnswers(page) as answers:  # the strip runs until the fit of cells has begun
        page.click("#strip-go")
        answers.send_next()  # seed 20
        page.wait_for_function("document.querySelectorAll('#strip img').length >= 1", timeout=60_000)
        answers.wait()  # seed 21's: seeds 22 to 27 are asked for once cells is picked
        page.select_option("#builtin", "cells")  # another exemplar: its fit starts while the strip runs
        page.wait_for_function("state.source && state.source.builtin === 'cells'")
        answers.release()
        page.wait_for_function("document.getElementById('strip-go').textContent === '8 seeds'", timeout=120_000)
    assert page.evaluate("window.stripImages") == 8  # all of them, of its model
    assert answers.urls == [f"{live_server.url}/api/models/{bricks}/images"] * 8  # seeds 22 to 27 too
    assert "null" not in page.text_content("#message") and "null" not in page.text_content("#gen-message")
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done'", timeout=90_000)
    # Cleared once cells is the working model: when the fit ends after the strip, or when the strip ends after it
    page.wait_for_function("document.querySelectorAll('#strip img').length === 0")
    assert not page.errors, page.errors
