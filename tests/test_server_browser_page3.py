"""An artist's walk through ``tghop serve``'s page at 1024x700 and 400x800, in a real browser (Chromium through
Playwright) against a real uvicorn server (0.63): the last long helps (the maps', quality's, Co-occurrence's exemplar
and edit) cut to two lines and a *more* (on a line of its own) in a narrow window as the modes' are; Extend's "grow to"
fields following the picture shown after an Undo; a strip of fills that fails partway saying the server's warnings of
the fills that came, and a server gone said with its fix (a checkpoint loaded then too); the built-in menu showing no
built-in for a model file; a fit's and an upload's progress in sight in a narrow window; Enter in a mode's field
pressing its button; Inpaint's Undo of a stroke or a Clear said."""

import io

import numpy as np
import pytest

import chromium
from conftest import FAST_FIT, LiveServer, png, save_texture

chromium.require()


def lines(page, selector):
    """How many lines of its text the element ``selector`` shows (its height over its line height)."""
    return page.eval_on_selector(selector, """e => {
      const probe = e.cloneNode(false);  // one line of the same style
      probe.removeAttribute("id");
      probe.textContent = "x";
      e.after(probe);
      const line = probe.getBoundingClientRect().height;
      probe.remove();
      return Math.round(e.getBoundingClientRect().height / line);
    }""")


def test_the_last_long_helps_are_cut_to_two_lines_in_a_narrow_window(page, tiny_cooc_checkpoint):
    # At 400x800 the maps' help took 4 lines, quality's 4 to 5 and Co-occurrence's exemplar and edit help 4 and 5
    # (0.62), whole where the modes' help is cut to two lines and a "more".
    chromium.choose_mode(page, "cooc")
    page.set_input_files("#cooc-file", str(tiny_cooc_checkpoint))
    page.wait_for_function("document.getElementById('cooc-exemplar').dataset.ready === '1'", timeout=30_000)
    helps = ("#maps-help", "#quality-help", "#cooc-exemplar-help", "#cooc-guide-help")
    more = "(h) => document.querySelector(`${h} + button.more-help`)"
    with chromium.window(page, 400, 800):
        for help in helps:
            assert lines(page, help) == 2, help
            button = page.evaluate_handle(more, help).as_element()
            assert button is not None and button.is_visible() and button.text_content() == "more", help
            button.click()
            assert lines(page, help) > 2 and button.text_content() == "less", help
            button.click()
            assert lines(page, help) == 2, help
        # quality's "more" on a line of its own, above Generate (beside it, it read as one of the form's buttons)
        assert page.eval_on_selector("#quality-help + button.more-help", "b => b.getBoundingClientRect().bottom") <= \
            page.eval_on_selector("#go", "b => b.getBoundingClientRect().top")
    with chromium.window(page, 1024, 700):
        for help in helps:
            assert lines(page, help) >= 2 and not page.evaluate_handle(more, help).as_element().is_visible(), help
    # Why quality is off is a paragraph of its own after the help, never cut with it
    assert page.evaluate("!document.getElementById('quality-off').closest('.help.long')")
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def caption_is(page, caption):
    page.wait_for_function("(c) => document.getElementById('result-caption').textContent === c &&"
                           " document.getElementById('editor').dataset.ready === '1'", arg=caption, timeout=60_000)


def extend(page, caption):
    page.click("#extend-go")
    caption_is(page, caption)


def grow_to(page):
    return [page.input_value("#extend-height"), page.input_value("#extend-width")]


def test_extends_fields_follow_the_picture_shown_after_an_undo(page):
    # An Extend undone put its size back in the "grow to" fields, a size for the picture brought back; kept when
    # another picture was shown next (the extension again from Recent results, a new result), Extend refused it as
    # no larger than that picture (0.62).
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    for field, value in (("height", "48"), ("width", "64"), ("seed", "3"), ("n_patches", "300")):
        page.fill(f"#{field}", value)
    page.click("#go")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 48x64, seed 3'",
                           timeout=60_000)
    chromium.choose_mode(page, "inpaint")
    page.fill("#inpaint-seed", "2")
    page.fill("#extend-width", "96")
    extend(page, "extended: 48x96, seed 2")
    assert grow_to(page) == ["48", "128"]
    page.click("#undo")
    caption_is(page, "result: 48x64, seed 3")
    assert grow_to(page) == ["48", "96"]  # that Extend, to try again (0.57)
    page.click("#history figure:first-child button.history-item")  # the extension, shown again
    caption_is(page, "extended: 48x96, seed 2")
    assert grow_to(page) == ["48", "128"]  # grown as much again from it
    extend(page, "extended: 48x128, seed 2")
    assert not page.eval_on_selector("#inpaint-message", "e => e.classList.contains('error')")
    page.click("#undo")
    caption_is(page, "extended: 48x96, seed 2")
    assert grow_to(page) == ["48", "128"]
    # A new result of another size: the same step from it
    chromium.choose_mode(page, "view")
    page.fill("#height", "64")
    page.click("#go")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 64x64, seed 3'",
                           timeout=60_000)
    chromium.choose_mode(page, "inpaint")
    page.wait_for_selector("#editor[data-ready='1']")
    assert grow_to(page) == ["64", "96"]
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_a_strip_of_fills_cut_by_the_server_gone_says_its_warnings_and_the_fix(page, tmp_path, request):
    # Fill 2 of 3 failing dropped the server's warning of fill 1 (its picture's colour profile converted) from the
    # line that said what came (0.62), and a server gone was the browser's bare "Failed to fetch".
    from PIL import Image
    from test_profiles import P3

    server = LiveServer(tmp_path / "cache")
    home = page.url
    try:
        page.goto(server.url + "/")
        page.wait_for_selector("body[data-ready='1']")
        save_texture(tmp_path / "wall.npz")
        chromium.upload_model(page, tmp_path / "wall.npz")
        chromium.choose_mode(page, "inpaint")
        buf = io.BytesIO()
        Image.fromarray(np.random.default_rng(0).integers(0, 256, (40, 40, 3), dtype=np.uint8)).save(
            buf, format="PNG", icc_profile=P3)
        page.set_input_files("#picture", files=[{"name": "p3.png", "mimeType": "image/png", "buffer": buf.getvalue()}])
        page.wait_for_function("editor.name === 'p3.png' && document.getElementById('editor').dataset.ready === '1'")
        hole = np.zeros((40, 40), np.uint8)
        hole[10:20, 10:30] = 255
        page.set_input_files("#mask-file", files=[{"name": "hole.png", "mimeType": "image/png", "buffer": png(hole)}])
        page.fill("#inpaint-seed", "2")
        page.fill("#inpaint-count", "3")
        with chromium.HeldAnswers(page, "**/api/models/*/inpaint") as held:
            page.click("#fill")
            held.wait()  # fill 1 made; the server stops before the page asks for fill 2
            server.stop()
        page.wait_for_function("document.getElementById('fill').textContent === 'Fill'", timeout=60_000)
        said = page.text_content("#inpaint-message")
        assert said.startswith("fill 2 of 3 failed: the server did not answer (") and (
            "is tghop serve still running? Start it again, then try again; fill 1 is under the picture, fill 1 shown "
            "(click one to pick it); Undo goes back to the picture before. Warning: p3.png: colours converted to sRGB "
            "from its colour profile 'Test P3'; ") in said, said
        assert page.text_content("#result-caption") == "inpainted: 40x40, seed 2, fill 1"
        # A checkpoint loaded then: said so, not "uploading tiny.pt" for good and an error on the console (0.62)
        try:
            tiny_cooc_checkpoint = request.getfixturevalue("tiny_cooc_checkpoint")
        except pytest.skip.Exception:  # no PyTorch here: no checkpoint to load
            return
        chromium.choose_mode(page, "cooc")
        page.errors.clear()
        page.set_input_files("#cooc-file", str(tiny_cooc_checkpoint))
        page.wait_for_function("document.getElementById('cooc-message').classList.contains('error')")
        said = page.text_content("#cooc-message")
        assert said.startswith("the server did not answer (") and said.endswith(
            "is tghop serve still running? Start it again, then try again"), said
        assert not [e for e in page.errors if "Uncaught" in e or "Failed to fetch" in e], page.errors
    finally:
        server.stop()
        page.goto(home)
        page.wait_for_selector("body[data-ready='1']")
        page.errors.clear()  # the server gone: the browser's errors of the requests it refused


def test_the_built_in_menu_shows_no_built_in_for_a_model_file(page, tmp_path):
    # A model file loaded after builtin:cells left the menu showing builtin:cells beside the file's model (0.62),
    # as if cells were the working model's exemplar; a refused file puts it back with the model that stays.
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "cells")
    save_texture(tmp_path / "wall.npz")
    chromium.upload_model(page, tmp_path / "wall.npz")
    assert page.input_value("#builtin") == ""
    chromium.fit_builtin(page, "cells")
    (tmp_path / "broken.npz").write_bytes(b"not a model file")
    page.set_input_files("#model-file", str(tmp_path / "broken.npz"))
    chromium.wait_said(page, "broken.npz was not used; the model of builtin:cells stays")
    assert page.input_value("#builtin") == "cells"
    page.errors.clear()  # the refusal: Chromium logs its 4xx as a console error


def in_sight(page, selector):
    return page.eval_on_selector(selector, "e => { const r = e.getBoundingClientRect();"
                                 " return r.top >= 0 && r.bottom <= window.innerHeight; }")


def test_a_fit_and_an_upload_show_their_progress_in_a_narrow_window(page, tmp_path):
    # At 400x800 with the fit settings open, a built-in picked fitted below the fold: its bar, Cancel and "model
    # ready" out of sight, the pick seeming to do nothing (0.62); so did a model file's "uploading" and "loaded".
    chromium.load_fresh(page, FAST_FIT)  # the fit settings open
    save_texture(tmp_path / "wall.npz")
    with chromium.window(page, 400, 800):
        page.select_option("#builtin", "bricks")
        page.wait_for_selector("#fit-status:not([hidden])")
        assert in_sight(page, "#fit-status") and in_sight(page, "#message")
        chromium.fit_builtin(page, "bricks")
        page.evaluate("window.scrollTo(0, 0)")
        chromium.upload_model(page, tmp_path / "wall.npz")
        assert in_sight(page, "#message") and page.text_content("#message").startswith("model wall.npz loaded")
    assert not page.errors, page.errors


def test_enter_in_a_modes_field_presses_its_button(page):
    # Enter in a field of Generate generated, but in Inpaint's, Extend's, Paint's, Morph's or Co-occurrence's fields
    # it did nothing (0.62): the artist typing a size or a seed had to reach for the mouse.
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    for field, value in (("height", "48"), ("width", "64"), ("seed", "3"), ("n_patches", "300")):
        page.fill(f"#{field}", value)
    page.press("#seed", "Enter")  # as before
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 48x64, seed 3'",
                           timeout=60_000)
    chromium.choose_mode(page, "inpaint")
    page.wait_for_selector("#editor[data-ready='1']")
    page.fill("#inpaint-seed", "2")
    page.press("#inpaint-seed", "Enter")  # Fill, with no hole painted: said
    page.wait_for_function("document.getElementById('inpaint-message').textContent.startsWith('paint the hole first')")
    page.fill("#extend-width", "80")
    page.press("#extend-width", "Enter")
    caption_is(page, "extended: 48x80, seed 2")
    chromium.choose_mode(page, "view")
    chromium.fit_builtin(page, "cells")
    chromium.choose_mode(page, "morph")
    page.fill("#morph-height", "32")
    page.fill("#morph-width", "40")
    page.press("#morph-width", "Enter")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'morph: 32x40, seed 1 (bricks "
                           "to cells)'", timeout=60_000)
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_inpaints_undo_of_a_stroke_or_a_clear_says_so(page):
    # Undo of a stroke changed only the mask: the line before stayed, "fill undone: the picture before it, with its
    # hole" after a stroke painted on that picture was undone (0.62).
    chromium.load_empty(page)
    chromium.choose_mode(page, "inpaint")
    page.set_input_files("#picture", files=[{"name": "mine.png", "mimeType": "image/png",
                                             "buffer": png(np.full((48, 64, 3), 90, np.uint8))}])
    page.wait_for_selector("#editor[data-ready='1']")
    box = page.locator("#mask").bounding_box()
    for y in (0.3, 0.7):
        page.mouse.move(box["x"] + 10, box["y"] + box["height"] * y)
        page.mouse.down()
        page.mouse.move(box["x"] + box["width"] - 10, box["y"] + box["height"] * y, steps=4)
        page.mouse.up()
    page.click("#clear")
    said = chromium.undo_said(page, "#undo", "#inpaint-message", 3)
    assert said == ["Clear undone", "a stroke undone", "a stroke undone (nothing more to undo)"], said
    assert page.is_disabled("#undo")
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors
