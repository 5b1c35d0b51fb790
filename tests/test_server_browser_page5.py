"""An artist's third walk through ``tghop serve``'s page, in a real browser (Chromium through Playwright) against a
real uvicorn server (0.64): Generate brought into sight by a model restored at a reload, as by a fresh fit; a job's bar
and status line brought into sight when the job starts (they came below the fold, under the button that read Stop);
Co-occurrence's crop buttons each on one line, the four of them in one row at 400 px; a model's long file name breaking
inside the page at 400 px, not widening it."""

import re

import chromium
from conftest import FAST_FIT, save_texture

chromium.require()


IN_SIGHT = "(s) => { const r = document.querySelector(s).getBoundingClientRect();" \
           " return r.top >= 0 && r.bottom <= window.innerHeight; }"


def test_a_restored_model_brings_generate_into_sight_and_a_jobs_bar_comes_into_sight(page):
    # A reload at 1024x700 with the fit settings open said "the model of builtin:bricks is back ...: generate below"
    # with Generate below the fold under the summary (0.63: only a fresh fit brought it into sight).
    chromium.load_fresh(page, FAST_FIT)  # the fit settings open, kept across the reload
    with chromium.window(page, 1024, 700):
        chromium.fit_builtin(page, "bricks")
        page.evaluate("window.scrollTo(0, 0)")
        page.reload()
        page.wait_for_selector("body[data-ready='1']")
        chromium.wait_said(page, "is back")
        page.wait_for_selector("#summary:not([hidden])")
        page.wait_for_function(IN_SIGHT, arg="#go", timeout=5_000)
        assert page.evaluate(IN_SIGHT, "#message")
        # Generate pressed there: its bar and "generating" came below the fold (0.63), the button reading Stop alone
        page.fill("#height", "32")
        page.fill("#width", "40")
        with chromium.HeldAnswers(page) as held:
            page.click("#go")
            held.wait()
            assert page.text_content("#go") == "Stop"
            for shown in ("#go", "#gen-progress", "#gen-message"):
                assert page.evaluate(IN_SIGHT, shown), shown
            assert page.text_content("#gen-message") == "generating"
        page.wait_for_function("document.getElementById('result-caption').textContent.startsWith('result: 32x40')",
                               timeout=60_000)
    assert not page.errors, page.errors


def test_coocs_crop_buttons_stay_on_one_line_in_a_narrow_window(page, tiny_cooc_checkpoint):
    # At 400 px each crop's button broke inside, "crop 1 (0, 0)" on three lines (0.63).
    chromium.choose_mode(page, "cooc")
    page.set_input_files("#cooc-file", str(tiny_cooc_checkpoint))
    page.wait_for_function("document.getElementById('cooc-exemplar').dataset.ready === '1'", timeout=30_000)
    crops = """() => [...document.querySelectorAll('#cooc-crops label')].map((e) => {
      const r = e.getBoundingClientRect(), font = parseFloat(getComputedStyle(e).fontSize);
      return { text: e.textContent, top: r.top, right: r.right, height: r.height, font,
               at: e.querySelector('.crop-at').getBoundingClientRect().width }; })"""
    with chromium.window(page, 400, 800):
        canvas = page.locator("#cooc-exemplar")
        canvas.scroll_into_view_if_needed()
        box = canvas.bounding_box()
        s = box["width"] / 64
        for y, x in ((16, 16), (16, 48), (48, 16), (48, 48)):
            page.mouse.click(box["x"] + x * s, box["y"] + y * s)
        narrow = page.evaluate(crops)
        right = page.evaluate("document.getElementById('cooc-crops').getBoundingClientRect().right")
    wide = page.evaluate(crops)
    assert [re.fullmatch(r"crop (\d) \(\d+, \d+\)", c["text"]).group(1) for c in narrow] == ["1", "2", "3", "4"]
    for c in narrow:
        assert c["height"] < 2 * c["font"] + 8, narrow  # one line each
        assert c["right"] <= right + 0.5, narrow
    assert max(c["top"] for c in narrow) - min(c["top"] for c in narrow) < 2, narrow  # one row
    # where each is: read by a screen reader there, shown in a wider window
    assert all(c["at"] <= 1 for c in narrow) and all(c["at"] > 20 for c in wide), (narrow, wide)
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_a_long_model_name_never_widens_a_narrow_page(page, tmp_path):
    # A model file named without a space ran out of the message, Paint's list and colours and Morph's menus at 400 px:
    # the page scrolled sideways, 601 px wide in a 400 px window (0.63).
    name = "Rock023_2K_Color_from_the_library_of_textures.npz"
    save_texture(tmp_path / name)
    chromium.upload_model(page, tmp_path / name)
    wide = "[document.documentElement.scrollWidth, window.innerWidth]"
    with chromium.window(page, 400, 800):
        assert page.text_content("#message").startswith(f"model {name} loaded")
        widths = {"loaded": page.evaluate(wide)}
        for mode in ("paint", "morph"):
            chromium.choose_mode(page, mode)
            if mode == "paint":
                for box in page.query_selector_all("#paint-models input[type=checkbox]")[:2]:
                    box.check()
                assert page.locator("#paint-colours label").count() >= 1
            widths[mode] = page.evaluate(wide)
        chromium.choose_mode(page, "view")
    assert all(w <= inner for w, inner in widths.values()), widths
    assert not page.errors, page.errors
