"""An artist's second walk through ``tghop serve``'s page, in a real browser (Chromium through Playwright) against a
real uvicorn server (0.63): Generate brought into sight with "model ready: generate below" at 1024x700; Paint's Undo
saying what it undid, as Inpaint's does; zoom 1:1 acting on Inpaint's picture; Co-occurrence's crop numbers crisp
over its exemplar, never under another crop's outline; the boost's fields on one line at 400 px."""


import numpy as np

import chromium
from conftest import FAST_FIT, png

chromium.require()


IN_SIGHT = "(s) => { const r = document.querySelector(s).getBoundingClientRect();" \
           " return r.top >= 0 && r.bottom <= window.innerHeight; }"


def test_model_ready_brings_generate_into_sight(page):
    # At 1024x700 with the fit settings open, "model ready: generate below" came with Generate below the fold, under
    # the model's summary (0.62): the artist had to find it.
    chromium.load_fresh(page, FAST_FIT)  # the fit settings open
    with chromium.window(page, 1024, 700):
        page.select_option("#builtin", "bricks")
        chromium.fit_builtin(page, "bricks")
        page.wait_for_function(IN_SIGHT, arg="#go", timeout=10_000)
        assert page.evaluate(IN_SIGHT, "#message")  # and what it says with it
        assert page.text_content("#message").startswith("model ready: generate below")
    assert not page.errors, page.errors


def test_paints_undo_says_what_it_undid(page):
    # Paint's Undo changed the canvas and said nothing, its line before staying (0.62); Inpaint's says (0.63).
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    chromium.fit_builtin(page, "cells")
    chromium.open_paint(page, 48, 64)
    box = page.locator("#guide").bounding_box()
    s = box["width"] / 64
    page.mouse.move(box["x"] + 8 * s, box["y"] + 12 * s)
    page.mouse.down()
    page.mouse.move(box["x"] + 56 * s, box["y"] + 12 * s, steps=5)
    page.mouse.up()
    guide = np.zeros((48, 64), np.uint8)
    guide[:, 32:] = 255
    page.set_input_files("#guide-file", files=[{"name": "halves.png", "mimeType": "image/png", "buffer": png(guide)}])
    page.wait_for_function("document.getElementById('paint-message').textContent.startsWith('the guide is halves.png')")
    page.click("#paint-reset")
    said = chromium.undo_said(page, "#paint-undo", "#paint-message", 3)
    assert said == ["Reset undone", "the guide file halves.png undone", "a stroke undone (nothing more to undo)"], said
    assert page.is_disabled("#paint-undo")
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_zoom_acts_on_inpaints_picture(page):
    # "zoom 1:1" left Inpaint's picture shown 3 times larger, changing only the tiling far below it (0.62).
    chromium.load_empty(page)
    chromium.choose_mode(page, "inpaint")
    width = "document.getElementById('editor-base').getBoundingClientRect().width"

    def picture(h, w):
        page.set_input_files("#picture", files=[{"name": f"p{w}.png", "mimeType": "image/png",
                                                 "buffer": png(np.full((h, w, 3), 90, np.uint8))}])
        page.wait_for_function(f"editor.name === 'p{w}.png' && document.getElementById('editor').dataset.ready === '1'")

    try:
        picture(48, 64)
        assert page.evaluate(width) == 192  # shown larger to paint on
        page.check("#zoom")
        assert page.evaluate(width) == 64
        picture(40, 1600)  # wider than the page: it scrolls in its box, the page does not scroll sideways
        assert page.evaluate(width) == 1600
        assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
        page.uncheck("#zoom")
        assert page.evaluate(width) < 1200
    finally:
        page.uncheck("#zoom")
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_coocs_crop_numbers_are_crisp_and_readable(page, tiny_cooc_checkpoint):
    # The numbers were drawn on the canvas at the exemplar's resolution (64x64 shown 128 px: blurred), crop 2's half
    # under crop 1's outline where the two crops overlap (0.62).
    chromium.load_empty(page)
    chromium.choose_mode(page, "cooc")
    page.set_input_files("#cooc-file", str(tiny_cooc_checkpoint))
    page.wait_for_function("document.getElementById('cooc-exemplar').dataset.ready === '1'", timeout=30_000)
    canvas = page.locator("#cooc-exemplar")
    canvas.scroll_into_view_if_needed()
    box = canvas.bounding_box()
    s = box["width"] / 64
    page.mouse.click(box["x"] + 16 * s, box["y"] + 16 * s)  # crop 1 at (0, 0)
    page.mouse.click(box["x"] + 40 * s, box["y"] + 40 * s)  # crop 2 over crop 1's corner
    corners = page.evaluate("cooc.crops.slice(0, 2)")
    assert corners[0] == [0, 0] and 0 < corners[1][0] < 32 and 0 < corners[1][1] < 32, corners
    numbers = page.eval_on_selector_all("#cooc-exemplar-box .crop-number", """l => l.map((e) => {
      const r = e.getBoundingClientRect();
      return [e.textContent, parseFloat(getComputedStyle(e).fontSize), r.left, r.top, r.right, r.bottom]; })""")
    assert [n[0] for n in numbers] == ["1", "2"], numbers
    inner = page.evaluate("(() => { const r = document.getElementById('cooc-exemplar').getBoundingClientRect();"
                          " return [r.left + 1, r.top + 1, r.width - 2]; })()")
    scale = inner[2] / 64
    for (_, font, left, top, right, bottom), (y, x) in zip(numbers, corners):
        assert font >= 12  # the page's text, whatever the canvas's scale
        x0, y0 = inner[0] + x * scale, inner[1] + y * scale
        assert x0 <= left and y0 <= top and right <= x0 + 32 * scale and bottom <= y0 + 32 * scale
    one, two = numbers
    assert one[4] <= two[2] or one[5] <= two[3]  # apart
    # over the canvas and its outlines, not under them
    assert page.evaluate("getComputedStyle(document.querySelector('.crop-number')).position") == "absolute"
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_the_boosts_fields_stay_on_one_line_in_a_narrow_window(page, tiny_cooc_checkpoint):
    # At 400 px the boost's "x factor" field wrapped onto a line of its own, away from the clusters it scales (0.62).
    chromium.choose_mode(page, "cooc")
    if page.evaluate("document.getElementById('cooc-work').hidden"):
        page.set_input_files("#cooc-file", str(tiny_cooc_checkpoint))
        page.wait_for_function("document.getElementById('cooc-exemplar').dataset.ready === '1'", timeout=30_000)
    middle = "(s) => { const r = document.querySelector(s).getBoundingClientRect(); return (r.top + r.bottom) / 2; }"
    for width in (400, 1024):
        with chromium.window(page, width, 800):
            tops = [page.evaluate(middle, f"#cooc-boost-{k}") for k in ("a", "b", "factor")]
            assert max(tops) - min(tops) < 4, (width, tops)
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors
