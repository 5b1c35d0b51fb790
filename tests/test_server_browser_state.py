"""What ``tghop serve``'s page keeps when something is refused, in a real browser (Chromium through
Playwright) against a real uvicorn server: a refused exemplar (not an image, flat, too small) or map
set, a cancelled fit or a refused model file leaves the working model and its exemplar as they were,
and "Add maps..." then refits that exemplar; maps added before any exemplar, or of another size than the
working one's, wait for it; nothing empty is
shown before there is something to show (the tiling, a model file's exemplar caption); the canvases read
back are made for it; the built-in the menu shows, picked again, is fitted again; Cancel works before the
fit's job is known, says "cancelling" until the fit stops, and a reload withdraws the fit; the brush
colour focused by keyboard shows it; waiting maps of another size than the next exemplar are dropped, not sent; the
page's take on same-sized maps is said and undone in one click; a reload keeps the working model (0.59)."""


import pytest

import chromium
from conftest import FAST_FIT, png, save_texture

chromium.require()


@pytest.fixture(scope="module")
def page(page):
    """conftest's page, its console's warnings collected in ``page.warnings``."""
    page.warnings = []
    page.on("console", lambda msg: page.warnings.append(msg.text) if msg.type == "warning" else None)
    return page


def wait_model(page, what):
    """Wait for the fit's end and the summary of a ``what`` ('model' or 'material')."""
    page.wait_for_function("(w) => document.getElementById('fit-status').dataset.state === 'done' &&"
                           " !document.getElementById('summary').hidden &&"
                           " document.getElementById('summary').textContent.startsWith(w + ' ')", arg=what,
                           timeout=90_000)


def exemplar_shown(page):
    """The exemplar's picture as shown: [its src's end, loaded, its natural width] (None when hidden), once it
    has loaded (a picture put back, as the working model's after a refusal, loads again: under load its
    ``complete`` was read before it had)."""
    page.wait_for_function("(() => { const i = document.getElementById('exemplar');"
                           " return i.hidden || i.complete; })()", timeout=15_000)
    return page.eval_on_selector("#exemplar", "i => i.hidden ? null :"
                                 " [i.getAttribute('src').split('/').pop(), i.complete, i.naturalWidth]")


def refused_files(tmp_path):
    """Exemplars the server refuses before a fit: a text file named .png, a flat image, a tiny one."""
    import numpy as np

    (tmp_path / "notes.png").write_bytes(b"just some notes, not an image\n")
    (tmp_path / "flat.png").write_bytes(png(np.full((64, 64, 3), 128, np.uint8)))
    (tmp_path / "tiny.png").write_bytes(png(np.random.default_rng(1).integers(0, 255, (4, 4, 3), np.uint8)))
    return [tmp_path / name for name in ("notes.png", "flat.png", "tiny.png")]


def rock_files(tmp_path):
    """``rock_albedo.png`` and ``rock_normal.png`` in ``tmp_path``: a 128x160 picture (another size than the
    built-ins') and its normal map."""
    from tghop import data
    from tghop.imageio import to_uint8, to_uint16
    from tghop.material import example_maps

    rock = data.builtin("cells")[:128, :160]
    (tmp_path / "rock_normal.png").write_bytes(png(to_uint16(example_maps(rock)["normal"])))
    (tmp_path / "rock_albedo.png").write_bytes(png(to_uint8(rock)))


def test_a_refused_exemplar_leaves_the_working_model_and_its_exemplar(page, tmp_path):
    # The refused file stayed shown as the exemplar (a broken picture for a text file), the page had no
    # model, and "Add maps..." fitted the refused file again.
    from tghop import data
    from tghop.imageio import to_uint16
    from tghop.material import example_maps

    bad = refused_files(tmp_path)
    chromium.load_fresh(page, FAST_FIT)
    page.set_input_files("#file", str(bad[0]))  # nothing before it: the page is empty again
    page.wait_for_function("document.getElementById('message').classList.contains('error')", timeout=30_000)
    assert exemplar_shown(page) is None and page.is_hidden("#fit-status") and page.is_disabled("#go")
    page.select_option("#builtin", "bricks")
    wait_model(page, "model")
    summary = page.text_content("#summary")
    for path in bad:
        page.set_input_files("#file", str(path))
        said = chromium.wait_said(page, "builtin:bricks")  # the model kept is named
        assert path.name in said and page.eval_on_selector("#message", "e => e.classList.contains('error')"), said
        assert exemplar_shown(page) == ["bricks.png", True, 256]
        assert page.is_enabled("#go") and page.is_visible("#download-model")
        page.wait_for_selector("#summary:not([hidden])")
        assert page.text_content("#summary") == summary
        assert page.input_value("#builtin") == "bricks" and page.is_hidden("#fit-status")
    (tmp_path / "normal.png").write_bytes(png(to_uint16(example_maps(data.builtin("bricks"))["normal"])))
    page.set_input_files("#maps", str(tmp_path / "normal.png"))  # the working exemplar with the maps
    wait_model(page, "material")
    assert "exemplar 256x256" in page.text_content("#summary")  # bricks (tiny.png was refitted: 400)
    assert exemplar_shown(page) == ["bricks.png", True, 256]
    assert not [e for e in page.errors if "status of 400" not in e], page.errors


def test_a_refused_map_set_leaves_the_working_model(page, tmp_path):
    # A map set the server refused lost the working model (the page was left with none) and stayed listed.
    from tghop import data
    from tghop.imageio import to_uint8

    height = to_uint8(data.builtin("bricks")[..., 0])
    (tmp_path / "height.png").write_bytes(png(height))
    (tmp_path / "bricks_normal.png").write_bytes(png(height))  # a normal map by its name, of 1 channel: refused
    chromium.load_fresh(page, FAST_FIT)
    page.set_input_files("#maps", str(tmp_path / "height.png"))  # no exemplar yet: they wait for it
    assert page.text_content("#maps-list") == "maps: height"
    assert "pick or drop the albedo (exemplar) now" in page.text_content("#message")
    assert page.is_hidden("#fit-status")
    page.select_option("#builtin", "bricks")
    wait_model(page, "material")
    summary = page.text_content("#summary")
    assert "maps: albedo, 8-bit; height, 8-bit" in summary
    for listed in ("maps: height", ""):  # a material's maps replaced, then a texture model's maps added
        page.set_input_files("#maps", str(tmp_path / "bricks_normal.png"))
        said = chromium.wait_said(page, "not added")
        assert "bricks_normal" in said and "1 channel" in said, said
        assert page.eval_on_selector("#message", "e => e.classList.contains('error')")
        assert page.text_content("#maps-list") == listed
        assert page.is_visible("#maps-clear") == bool(listed)
        assert page.is_enabled("#go") and page.is_hidden("#fit-status")
        assert exemplar_shown(page) == ["bricks.png", True, 256]
        page.wait_for_selector("#summary:not([hidden])")
        assert page.text_content("#summary") == summary
        if listed:
            page.click("#maps-clear")  # the texture model
            wait_model(page, "model")
            summary = page.text_content("#summary")
    assert not [e for e in page.errors if "status of 400" not in e], page.errors


def test_maps_added_before_their_albedo_wait_for_it(page, tmp_path):
    # A normal map added while another exemplar's model was working refitted that exemplar with it (400: another
    # size), and the albedo picked next cleared it ("maps cleared: rock_normal went with builtin:bricks").
    rock_files(tmp_path)
    fits = chromium.posted_fits(page)
    chromium.load_fresh(page, FAST_FIT)
    page.select_option("#builtin", "bricks")
    wait_model(page, "model")
    summary, sent = page.text_content("#summary"), len(fits)
    for step in ("add", "drop", "add"):  # No maps drops maps that wait, the working model kept
        if step == "add":
            page.set_input_files("#maps", str(tmp_path / "rock_normal.png"))
            said = chromium.wait_said(page, "wait for their albedo")
            assert "rock_normal is 128x160, not the 256x256 of builtin:bricks" in said, said
            assert page.text_content("#maps-list") == "maps for the next exemplar: rock_normal"
        else:
            page.click("#maps-clear")
            assert "maps dropped" in chromium.wait_said(page, "dropped")
            assert page.text_content("#maps-list") == "" and page.is_hidden("#maps-clear")
        assert not page.eval_on_selector("#message", "e => e.classList.contains('error')")
        assert page.is_enabled("#go") and len(fits) == sent
        assert page.text_content("#summary") == summary and exemplar_shown(page) == ["bricks.png", True, 256]
    page.set_input_files("#file", str(tmp_path / "rock_albedo.png"))  # their albedo: a material
    wait_model(page, "material")
    assert "exemplar 128x160" in page.text_content("#summary")
    assert "normal (normal), 16-bit" in page.text_content("#summary")
    assert page.text_content("#maps-list") == "maps: rock_normal"
    assert not page.errors, page.errors


def cancel_a_fit_of_cells(page):
    """Pick builtin:cells with the default fit settings (seconds), click Cancel once it runs, then put the
    fast settings back; returns the message."""
    for name in ("n_clusters", "n_codewords", "stride", "max_patches"):
        page.fill(f"#{name}", "")
    page.select_option("#builtin", "cells")
    page.wait_for_function("document.getElementById('stage').textContent.endsWith('%')", timeout=60_000)
    assert page.is_disabled("#go") and page.is_hidden("#summary")
    page.click("#cancel")
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'cancelled'", timeout=60_000)
    for name in ("n_clusters", "n_codewords", "stride", "max_patches"):
        page.fill(f"#{name}", FAST_FIT[name])
    return chromium.wait_said(page, "fit cancelled (")


def test_a_cancelled_fit_goes_back_to_the_working_model(page):
    # Cancel left no model (Generate off, no summary) and the cancelled exemplar shown, though the model
    # before that pick was working.
    chromium.load_fresh(page, FAST_FIT)
    said = cancel_a_fit_of_cells(page)  # nothing before it: the page is empty again
    assert said == "fit cancelled (builtin:cells was not used; no model yet)"
    assert exemplar_shown(page) is None and page.is_disabled("#go") and page.is_hidden("#summary")
    assert page.is_hidden("#download-model") and page.input_value("#builtin") == ""
    page.select_option("#builtin", "bricks")
    wait_model(page, "model")
    summary = page.text_content("#summary")
    said = cancel_a_fit_of_cells(page)
    assert said == "fit cancelled (builtin:cells was not used; the model of builtin:bricks stays)"
    assert not page.eval_on_selector("#message", "e => e.classList.contains('error')")
    assert exemplar_shown(page) == ["bricks.png", True, 256] and page.is_hidden("#fit-status")
    page.wait_for_selector("#summary:not([hidden])")
    assert page.text_content("#summary") == summary  # the working model's, not the cancelled pick's
    assert page.is_enabled("#go") and page.is_visible("#download-model")
    assert page.input_value("#builtin") == "bricks"
    page.select_option("#builtin", "cells")  # picked again: fitted
    wait_model(page, "model")
    assert page.text_content("#summary") != summary
    assert not page.errors, page.errors


def test_a_refused_model_file_goes_back_to_the_working_model(page, tmp_path):
    # A model file the server refused left no model, though the model before it was working.
    (tmp_path / "broken.npz").write_bytes(b"PK\x03\x04 not a model")
    save_texture(tmp_path / "saved.npz")
    chromium.load_fresh(page, FAST_FIT)
    page.set_input_files("#model-file", str(tmp_path / "broken.npz"))  # nothing before it: the empty page
    said = chromium.wait_said(page, "was not used")
    assert "not a tghop model file" in said and said.endswith("(broken.npz was not used; no model yet)"), said
    assert page.eval_on_selector("#message", "e => e.classList.contains('error')")
    assert exemplar_shown(page) is None and page.is_disabled("#go") and page.is_hidden("#summary")
    page.select_option("#builtin", "bricks")
    wait_model(page, "model")
    summary = page.text_content("#summary")
    page.set_input_files("#model-file", str(tmp_path / "broken.npz"))  # an exemplar's model before it
    said = chromium.wait_said(page, "was not used")
    assert said.endswith("(broken.npz was not used; the model of builtin:bricks stays)"), said
    assert exemplar_shown(page) == ["bricks.png", True, 256] and page.input_value("#builtin") == "bricks"
    page.wait_for_selector("#summary:not([hidden])")
    assert page.text_content("#summary") == summary
    assert page.is_enabled("#go") and page.is_visible("#download-model")
    page.set_input_files("#model-file", str(tmp_path / "saved.npz"))  # a model file's model before it
    chromium.wait_said(page, "model saved.npz loaded")
    page.wait_for_selector("#summary:not([hidden])")
    summary = page.text_content("#summary")
    page.set_input_files("#model-file", str(tmp_path / "broken.npz"))
    said = chromium.wait_said(page, "was not used")
    assert said.endswith("(broken.npz was not used; the model of saved.npz stays)"), said
    assert exemplar_shown(page) is None and "saved.npz" in page.text_content("#exemplar-caption")
    page.wait_for_selector("#summary:not([hidden])")
    assert page.text_content("#summary") == summary
    assert page.is_enabled("#go") and page.is_visible("#download-model")
    assert not [e for e in page.errors if "status of 400" not in e], page.errors


def test_nothing_empty_before_a_result_and_a_model_files_caption(page, tmp_path):
    # The 3x3 tiling's heading and empty canvas showed before any result; a model file left the caption
    # "exemplar" under no picture.
    save_texture(tmp_path / "saved bricks.npz")
    chromium.load_fresh(page, FAST_FIT)
    assert page.is_hidden("#tiled-title") and page.is_hidden("#tiled-box")
    assert page.is_hidden("#exemplar-caption") and page.is_hidden("#result-caption")
    page.set_input_files("#model-file", str(tmp_path / "saved bricks.npz"))
    page.wait_for_selector("#summary:not([hidden])")
    assert page.is_hidden("#exemplar") and page.is_visible("#exemplar-caption")
    assert "saved bricks.npz" in page.text_content("#exemplar-caption")
    page.fill("#height", "40")
    page.fill("#width", "48")
    page.click("#go")
    page.wait_for_selector("#tiled[data-ready='1']")
    assert page.is_visible("#tiled-title") and page.is_visible("#tiled-box") and page.is_visible("#result-caption")
    page.select_option("#builtin", "bricks")  # an exemplar: its caption again
    assert page.text_content("#exemplar-caption") == "exemplar"
    wait_model(page, "model")
    assert not page.errors, page.errors


def test_the_canvases_read_back_are_made_for_it(page):
    # Chromium warned "Multiple readback operations using getImageData are faster with the
    # willReadFrequently attribute set to true" (the mask read at each Fill, the tests' reads).
    if not page.query_selector("#tiled[data-ready='1']"):  # run alone
        chromium.load_fresh(page, FAST_FIT)
        page.select_option("#builtin", "bricks")
        wait_model(page, "model")
        page.click("#go")
        page.wait_for_selector("#tiled[data-ready='1']")
    page.locator("label", has=page.locator("#mode-inpaint")).click()
    page.wait_for_selector("#editor[data-ready='1']")
    page.locator("label", has=page.locator("#mode-paint")).click()
    page.wait_for_selector("#guide[data-ready='1']")
    page.locator("label", has=page.locator("#mode-view")).click()
    for canvas in ("#tiled", "#mask", "#guide"):
        # getContext gives the context the page made first, with its attributes
        assert page.eval_on_selector(canvas, "c => c.getContext('2d').getContextAttributes().willReadFrequently"
                                     " === true"), canvas
        page.eval_on_selector(canvas, "c => { for (let i = 0; i < 4; i++)"
                              " c.getContext('2d').getImageData(0, 0, c.width, c.height); }")
    page.wait_for_timeout(200)
    assert not [w for w in page.warnings if "willReadFrequently" in w], page.warnings
    assert not [e for e in page.errors if "status of 400" not in e], page.errors


def pick_builtin(page, name):
    """Pick ``name`` in the built-in menu as a browser does: its list opened by a click, the option chosen,
    a change event only when that option is not the one selected (Playwright's select_option always sends one)."""
    page.click("#builtin")
    page.eval_on_selector("#builtin", """(s, name) => {
      const i = [...s.options].findIndex((o) => !o.hidden && o.value === name);
      if (s.selectedIndex === i) return;
      s.selectedIndex = i;
      s.dispatchEvent(new Event("input", { bubbles: true }));
      s.dispatchEvent(new Event("change", { bubbles: true }));
    }""", name)


def test_the_built_in_shown_picked_again_is_fitted_again(page, tmp_path):
    # After a cancelled fit of the working model's built-in (with maps), the menu showed that built-in, so
    # picking it again was no change: nothing was fitted; nor with other fit settings.
    from tghop import data
    from tghop.imageio import to_uint8

    (tmp_path / "height.png").write_bytes(png(to_uint8(data.builtin("bricks")[..., 0])))
    chromium.load_fresh(page, FAST_FIT)
    pick_builtin(page, "bricks")
    wait_model(page, "model")
    summary = page.text_content("#summary")
    for name in ("n_clusters", "n_codewords", "stride", "max_patches"):
        page.fill(f"#{name}", "")  # the default settings: seconds, time to cancel
    page.set_input_files("#maps", str(tmp_path / "height.png"))
    page.wait_for_function("document.getElementById('stage').textContent.endsWith('%')", timeout=60_000)
    page.click("#cancel")
    assert chromium.wait_said(page, "fit cancelled (") == ("fit cancelled (the maps were not added;"
                                                  " the model of builtin:bricks stays)")
    assert page.input_value("#builtin") == "bricks" and page.text_content("#maps-list") == ""
    for name in ("n_clusters", "n_codewords", "stride", "max_patches"):
        page.fill(f"#{name}", FAST_FIT[name])
    page.fill("#n_codewords", "41")  # another model than the working one
    pick_builtin(page, "bricks")
    page.wait_for_selector("#fit-status:not([hidden])", timeout=10_000)
    wait_model(page, "model")
    assert page.text_content("#summary") != summary and page.input_value("#builtin") == "bricks"
    summary = page.text_content("#summary")
    pick_builtin(page, "")  # "choose...": nothing fitted, the menu shows the working model's built-in
    page.click("#fit-settings summary")  # the menu loses the focus
    assert page.input_value("#builtin") == "bricks" and page.text_content("#summary") == summary
    assert page.eval_on_selector("#builtin", "s => s.selectedOptions[0].textContent") == "builtin:bricks"
    assert not page.eval_on_selector("#builtin", "s => [...s.options].some((o) => o.hidden)")
    assert not [e for e in page.errors if "status of 400" not in e], page.errors


def test_a_cancel_before_the_fit_started_is_not_ignored(page):
    # Cancel clicked while the exemplar was still being sent did nothing: the fit ran on and its model
    # replaced the working one.
    chromium.load_fresh(page, FAST_FIT)
    pick_builtin(page, "bricks")
    wait_model(page, "model")
    summary = page.text_content("#summary")
    with page.expect_request(lambda r: r.method == "DELETE" and "/api/jobs/" in r.url, timeout=30_000):
        page.eval_on_selector("#builtin", """(s) => {
          s.value = "cells";
          s.dispatchEvent(new Event("change", { bubbles: true }));
          document.getElementById("cancel").click();  // before the server answered
        }""")
    assert chromium.wait_said(page, "fit cancelled (", timeout=10_000) == ("fit cancelled (builtin:cells was not used;"
                                                                  " the model of builtin:bricks stays)")
    assert page.input_value("#builtin") == "bricks" and page.is_hidden("#fit-status")
    page.wait_for_selector("#summary:not([hidden])")
    assert page.text_content("#summary") == summary and page.is_enabled("#go")
    assert exemplar_shown(page) == ["bricks.png", True, 256]
    assert not page.errors, page.errors


def test_cancel_says_cancelling_until_the_fit_stops(page):
    # After Cancel the stage went on showing the fit's progress ("hop 2 26 %", then "ICA 56 %") until the
    # fit stopped at its next progress report: the cancel looked ignored.
    chromium.load_fresh(page, FAST_FIT)
    for name in ("n_clusters", "n_codewords", "stride", "max_patches"):
        page.fill(f"#{name}", "")
    page.select_option("#builtin", "cells")
    page.wait_for_function("document.getElementById('stage').textContent.endsWith('%')", timeout=60_000)
    # The watcher set and Cancel clicked in one task: a progress report between the two is not a report after Cancel
    page.evaluate("""() => { window.stages = [];
      new MutationObserver(() => stages.push(document.getElementById("stage").textContent))
        .observe(document.getElementById("stage"), { childList: true, characterData: true, subtree: true });
      document.getElementById("cancel").click(); }""")
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'cancelled'", timeout=60_000)
    stages = page.evaluate("stages")
    first = stages.index("cancelled")  # no progress shown after the click
    assert stages[0] == "cancelling" and set(stages[:first]) == {"cancelling"}, stages
    assert set(stages[first:]) == {"cancelled"}, stages
    assert not page.errors, page.errors


def test_the_focused_brush_colour_shows_its_focus(page):
    # The brush colours (radios hidden in their labels) showed no focus: Tab reached the chosen one,
    # which looked the same with the focus or without.
    chromium.load_fresh(page, FAST_FIT)
    for name in ("bricks", "cells"):
        page.select_option("#builtin", name)
        wait_model(page, "model")
    page.locator("label", has=page.locator("#mode-paint")).click()
    page.focus("#paint-models label:last-child input")
    page.keyboard.press("Tab")
    assert page.evaluate("document.activeElement.name") == "paint-colour"
    outline = "() => getComputedStyle(document.activeElement.closest('label')).outlineStyle"
    assert page.evaluate(outline) == "solid"
    page.keyboard.press("ArrowLeft")  # the other colour: chosen, with the focus
    assert page.evaluate("document.activeElement.checked && document.activeElement.value") == "0"
    assert page.evaluate(outline) == "solid"
    page.click("#paint-reset")  # a click: no ring on the colours
    assert page.eval_on_selector_all("#paint-colours label", "ls => ls.map((l) => getComputedStyle(l).outlineStyle)"
                                     ) == ["none", "none"]
    assert not page.errors, page.errors


def test_an_option_in_the_text_is_not_broken_at_its_hyphens(page):
    # "the paper's settings (--paper)" broke "--paper" after its first hyphen at 1200 px.
    chromium.load_fresh(page, FAST_FIT)
    assert page.eval_on_selector("#fit-settings code", "c => c.getClientRects().length") == 1


def test_a_reload_withdraws_the_running_fit(page):
    # A reload left the page's fit running on the server for no page (its generations are stopped).
    chromium.load_fresh(page, FAST_FIT)
    for name in ("n_clusters", "n_codewords", "stride", "max_patches"):
        page.fill(f"#{name}", "")
    page.fill("#max_patches", "19999")  # a model no other test fits: its own job
    page.select_option("#builtin", "cells")
    page.wait_for_function("document.getElementById('stage').textContent.endsWith('%')", timeout=60_000)
    job = page.get_attribute("#fit-status", "data-job")
    page.reload()
    page.wait_for_selector("body[data-ready='1']")
    for _ in range(600):  # the fit stops at its next progress report
        snap = page.evaluate("(job) => fetch(`/api/jobs/${job}`).then((r) => r.json())", job)
        if snap["state"] != "running":
            break
        page.wait_for_timeout(100)
    assert snap["state"] == "cancelled" and snap["askers"] == 0, snap
    assert not page.errors, page.errors


def test_arrow_keys_on_the_built_in_menu_fit_only_the_option_settled_on(page):
    # Each arrow press on the closed menu (a change per option passed) started a fit of that option, the one
    # before it cancelled: browsing the built-ins by keyboard asked the server for a fit per option.
    chromium.load_fresh(page, FAST_FIT)
    fits = chromium.posted_fits(page)
    page.focus("#builtin")
    page.keyboard.press("ArrowDown")  # builtin:bricks
    page.keyboard.press("ArrowDown")  # builtin:cells
    assert page.input_value("#builtin") == "cells"
    assert page.is_hidden("#fit-status") and not fits  # the choice not settled yet
    page.wait_for_selector("#fit-status:not([hidden])", timeout=10_000)
    wait_model(page, "model")
    assert len(fits) == 1 and b'name="builtin"\r\n\r\ncells' in fits[0], fits
    assert exemplar_shown(page) == ["cells.png", True, 256]
    page.keyboard.press("ArrowUp")  # away and back to the model's built-in before it settles: nothing to fit
    page.keyboard.press("ArrowDown")
    page.wait_for_timeout(1500)
    assert len(fits) == 1 and page.is_visible("#summary") and page.input_value("#builtin") == "cells"
    page.keyboard.press("ArrowUp")  # Enter settles the choice at once
    page.keyboard.press("Enter")
    assert page.is_visible("#fit-status") and len(fits) == 2 and b"bricks" in fits[1]
    wait_model(page, "model")
    page.click("#fit-settings summary")  # the focus elsewhere: a click's pick is fitted at once
    started = page.eval_on_selector("#builtin", """(s) => {
      s.value = "cells";
      s.dispatchEvent(new Event("input", { bubbles: true }));
      s.dispatchEvent(new Event("change", { bubbles: true }));
      return !document.getElementById("fit-status").hidden && document.getElementById("stage").textContent;
    }""")
    assert started == "sending"
    wait_model(page, "model")
    assert len(fits) == 3 and exemplar_shown(page) == ["cells.png", True, 256]
    assert not page.errors, page.errors


def test_a_new_exemplar_clears_the_maps_of_the_last_one(page, tmp_path):
    # The maps listed for a material went on to the next exemplar: builtin:cells picked after a bricks material
    # was fitted with bricks' height map, and so was the exemplar after a model file.
    from tghop import data
    from tghop.imageio import to_uint8

    (tmp_path / "height.png").write_bytes(png(to_uint8(data.builtin("bricks")[..., 0])))
    fits = chromium.posted_fits(page)
    chromium.load_fresh(page, FAST_FIT)
    page.set_input_files("#maps", str(tmp_path / "height.png"))  # no exemplar yet: they wait for it
    page.select_option("#builtin", "bricks")
    wait_model(page, "material")
    page.set_input_files("#file", str(refused_files(tmp_path)[0]))  # refused: the maps listed again
    assert "bricks" in chromium.wait_said(page, "notes.png")
    assert page.text_content("#maps-list") == "maps: height" and page.is_visible("#maps-clear")
    pick_builtin(page, "bricks")  # the same exemplar again: fitted with its maps
    page.wait_for_selector("#fit-status:not([hidden])", timeout=10_000)
    wait_model(page, "material")
    assert page.text_content("#maps-list") == "maps: height"
    page.select_option("#builtin", "cells")
    assert page.text_content("#maps-list") == "maps cleared: height went with builtin:bricks, not this exemplar's"
    assert page.is_hidden("#maps-clear")
    wait_model(page, "model")
    assert b"map:" not in fits[-1] and b"cells" in fits[-1]
    assert page.text_content("#maps-list").startswith("maps cleared: height")  # still said once fitted
    page.set_input_files("#maps", str(tmp_path / "height.png"))  # cells' own maps (its size): a material
    wait_model(page, "material")
    model = tmp_path / "cells.npz"  # a model file loaded: the maps listed are not its own either
    model.write_bytes(page.request.get(page.url.rstrip("/") + page.get_attribute("#download-model", "href")).body())
    page.set_input_files("#model-file", str(model))
    assert "loaded" in chromium.wait_said(page, "loaded: generate below")
    assert page.text_content("#maps-list") == "maps cleared: height went with builtin:cells, not the model file's"
    page.select_option("#builtin", "bricks")
    wait_model(page, "model")
    assert b"map:" not in fits[-1] and b"bricks" in fits[-1]
    assert not [e for e in page.errors if "status of 400" not in e], page.errors


def test_waiting_maps_stay_waiting_when_the_exemplar_they_are_not_of_is_picked_again(page, tmp_path):
    # Maps waiting for their albedo (another size than the working exemplar's) were sent with that exemplar when it
    # was picked again (to refit it with other settings, say): refused for their size, and listed as waiting again.
    rock_files(tmp_path)
    sent = chromium.posted_fits(page)
    chromium.load_fresh(page, FAST_FIT)
    pick_builtin(page, "bricks")
    wait_model(page, "model")
    page.set_input_files("#maps", str(tmp_path / "rock_normal.png"))
    chromium.wait_said(page, "wait for their albedo")
    before = len(sent)
    page.fill("#n_codewords", "42")  # the same exemplar again, with other settings
    pick_builtin(page, "bricks")
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done' &&"
                           " document.getElementById('summary').textContent.includes('W=42')", timeout=90_000)
    assert len(sent) == before + 1 and b"map:" not in sent[-1]  # fitted without them
    assert not page.eval_on_selector("#message", "e => e.classList.contains('error')"), page.text_content("#message")
    assert page.text_content("#maps-list") == "maps for the next exemplar: rock_normal"
    assert "W=42" in page.text_content("#summary")
    page.fill("#n_codewords", FAST_FIT["n_codewords"])
    page.set_input_files("#file", str(tmp_path / "rock_albedo.png"))  # their albedo, still: a material
    wait_model(page, "material")
    assert page.text_content("#maps-list") == "maps: rock_normal"
    assert not page.errors, page.errors


def test_an_exemplar_picked_while_the_maps_sizes_are_read_takes_the_maps(page):
    # Maps added are compared with the working exemplar's size (read by the browser, a few milliseconds): an
    # exemplar picked meanwhile cleared them ("maps cleared: cells_height went with builtin:bricks") and was fitted
    # as a texture model.
    import base64

    from tghop import data
    from tghop.imageio import to_uint8

    height = base64.b64encode(png(to_uint8(data.builtin("cells")[..., 0]))).decode()
    chromium.load_fresh(page, FAST_FIT)
    pick_builtin(page, "bricks")
    wait_model(page, "model")
    page.evaluate("""(b64) => {
      const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
      setMapFiles([new File([bytes], "cells_height.png", { type: "image/png" })]);  // its size being read...
      fitBuiltin("cells");  // ...when cells is picked
    }""", height)
    wait_model(page, "material")
    assert page.text_content("#maps-list") == "maps: cells_height"
    summary = page.text_content("#summary")
    assert "exemplar 256x256" in summary and "cells_height, 8-bit" in summary, summary
    assert page.evaluate("state.working.name") == "builtin:cells + 1 maps"
    assert not page.errors, page.errors


def test_maps_named_for_another_picture_wait_for_it(page, tmp_path):
    # A same-sized map set of another picture (rock_normal.png added while builtin:bricks worked) refitted bricks with
    # it, a material of no use, and rock's albedo picked next cleared the maps as bricks' ("maps cleared").
    from tghop import data
    from tghop.imageio import to_uint8, to_uint16
    from tghop.material import example_maps

    rock = data.builtin("cells")
    (tmp_path / "rock_normal_2k.png").write_bytes(png(to_uint16(example_maps(rock)["normal"])))
    (tmp_path / "Rock_Color_2K.png").write_bytes(png(to_uint8(rock)))
    sent = chromium.posted_fits(page)
    chromium.load_fresh(page, FAST_FIT)
    pick_builtin(page, "bricks")
    wait_model(page, "model")
    summary, before = page.text_content("#summary"), len(sent)
    page.set_input_files("#maps", str(tmp_path / "rock_normal_2k.png"))
    said = chromium.wait_said(page, "wait for their albedo")
    assert said.startswith("rock_normal_2k.png is named for another picture than builtin:bricks"), said
    assert page.text_content("#maps-list") == "maps for the next exemplar: rock_normal_2k"
    assert len(sent) == before and page.text_content("#summary") == summary and page.is_enabled("#go")
    page.set_input_files("#file", str(tmp_path / "Rock_Color_2K.png"))  # their albedo: a material
    wait_model(page, "material")
    assert page.text_content("#maps-list") == "maps: rock_normal_2k"
    # Named for the exemplar ("bricks normal") or by their kind alone ("normal"), they refit it as before; and the
    # exemplar picked again takes maps named for another.
    chromium.load_fresh(page, FAST_FIT)
    pick_builtin(page, "bricks")
    wait_model(page, "model")
    page.set_input_files("#maps", str(tmp_path / "rock_normal_2k.png"))
    chromium.wait_said(page, "wait for their albedo")
    pick_builtin(page, "bricks")
    wait_model(page, "material")
    assert page.text_content("#maps-list") == "maps: rock_normal_2k" and page.input_value("#builtin") == "bricks"
    assert not page.errors, page.errors


def test_waiting_maps_of_another_size_than_the_new_exemplar_are_dropped_not_sent(page, tmp_path):
    # Maps waiting for their albedo (added before any exemplar, or of another size than the working one's) were sent
    # with whatever exemplar was picked next: a normal click sequence the server refused, naming the sizes
    # ("... is 128x160, not the exemplar's 256x256"). Another size than the new exemplar's: they are dropped, said
    # on the page, and it is fitted as a texture model; of its size they make the material (the tests above).
    rock_files(tmp_path)
    sent = chromium.posted_fits(page)
    for first in ("bricks", None):  # waiting beside a working model, and before any exemplar
        chromium.load_fresh(page, FAST_FIT)
        if first:
            pick_builtin(page, first)
            wait_model(page, "model")
        page.set_input_files("#maps", str(tmp_path / "rock_normal.png"))
        chromium.wait_said(page, "wait for their albedo" if first else "pick or drop the albedo")
        before = len(sent)
        pick_builtin(page, "cells")
        said = chromium.wait_said(page, "builtin:cells")  # dropped, or (0.58) refused
        assert not page.eval_on_selector("#message", "e => e.classList.contains('error')"), said
        assert said.startswith("maps dropped: rock_normal is 128x160, not the 256x256 of builtin:cells"), said
        assert len(sent) == before + 1 and b"map:" not in sent[-1] and b"cells" in sent[-1]
        page.wait_for_function("state.working && state.working.name === 'builtin:cells'", timeout=90_000)
        wait_model(page, "model")
        said = chromium.wait_said(page, "model ready")  # said again when the fit ends (the message then changes)
        assert "ready: generate below. maps dropped: rock_normal is 128x160, not the 256x256 of builtin:cells" in said
        assert page.text_content("#maps-list").startswith("maps dropped: rock_normal (128x160)")
        assert page.is_hidden("#maps-clear") and page.is_enabled("#go")
        assert page.evaluate("state.working.name") == "builtin:cells"
    assert not page.errors, page.errors


def test_the_pages_take_on_maps_of_the_exemplars_size_is_said_and_one_click_from_undone(page, tmp_path):
    # Whether maps of the exemplar's size were its own or another picture's was guessed from the files' names, and a
    # wrong guess had no way back but picking the exemplar again, or adding the maps again once their albedo was
    # picked ("maps cleared: normal went with builtin:bricks"). The page says what it took them for, and a button
    # gives them to the exemplar shown.
    from tghop import data
    from tghop.imageio import to_uint16
    from tghop.material import example_maps

    normal = png(to_uint16(example_maps(data.builtin("cells"))["normal"]))
    (tmp_path / "rock_normal_2k.png").write_bytes(normal)
    (tmp_path / "normal.png").write_bytes(normal)
    chromium.load_fresh(page, FAST_FIT)
    pick_builtin(page, "bricks")
    wait_model(page, "model")
    assert page.is_hidden("#maps-use")
    page.set_input_files("#maps", str(tmp_path / "rock_normal_2k.png"))  # named for another picture: waiting
    assert 'press "Use them with builtin:bricks"' in chromium.wait_said(page, "wait for their albedo")
    assert page.text_content("#maps-use") == "Use them with builtin:bricks"
    page.click("#maps-use")  # they are bricks' after all
    wait_model(page, "material")
    assert page.text_content("#maps-list") == "maps: rock_normal_2k" and page.is_hidden("#maps-use")
    # Named by their kind alone, they refit the exemplar, said; the next exemplar picked (of their size) clears them,
    # and offers them to it.
    chromium.load_fresh(page, FAST_FIT)
    pick_builtin(page, "bricks")
    wait_model(page, "model")
    page.set_input_files("#maps", str(tmp_path / "normal.png"))
    assert "fitting builtin:bricks with normal, maps of its size" in chromium.wait_said(page, "fitting builtin:bricks")
    wait_model(page, "material")
    pick_builtin(page, "cells")
    page.wait_for_function("state.working && state.working.name === 'builtin:cells'", timeout=90_000)
    wait_model(page, "model")
    assert page.text_content("#maps-list").startswith("maps cleared: normal went with builtin:bricks")
    page.wait_for_selector("#maps-use:not([hidden])", timeout=15_000)
    assert page.text_content("#maps-use") == "Use them with builtin:cells"
    page.focus("#maps-use")
    page.keyboard.press("Enter")  # by keyboard too
    page.wait_for_function("state.working.name === 'builtin:cells + 1 maps'", timeout=90_000)
    wait_model(page, "material")
    assert page.text_content("#maps-list") == "maps: normal" and page.is_hidden("#maps-use")
    assert page.evaluate("document.activeElement.id") == "maps"
    assert not page.errors, page.errors


def test_a_reload_keeps_the_working_model(page, tmp_path):
    # A reload (or the browser closed and opened again) left the page empty: the model, still in the server's cache,
    # had to be fitted again (seconds, minutes with the default settings) before another image could be made.
    from tghop import data
    from tghop.imageio import to_uint8
    from tghop.material import example_maps

    height = tmp_path / "bricks_height.png"
    height.write_bytes(png(to_uint8(example_maps(data.builtin("bricks"))["height"][..., 0])))
    chromium.load_fresh(page, FAST_FIT)
    pick_builtin(page, "bricks")
    wait_model(page, "model")
    page.set_input_files("#maps", str(height))
    wait_model(page, "material")
    summary, model = page.text_content("#summary"), page.evaluate("state.modelId")
    sent = chromium.posted_fits(page)
    page.reload()
    page.wait_for_selector("body[data-ready='1']")
    said = chromium.wait_said(page, "is back")
    assert said == "the model of builtin:bricks + 1 maps is back (kept across the reload): generate below", said
    page.wait_for_function("(s) => document.getElementById('summary').textContent === s", arg=summary)
    assert page.evaluate("state.modelId") == model and page.is_enabled("#go")
    assert exemplar_shown(page) == ["bricks.png", True, 256] and page.input_value("#builtin") == "bricks"
    assert page.text_content("#maps-list") == "maps: bricks_height"
    page.fill("#height", "32")
    page.fill("#width", "40")
    page.click("#go")
    page.wait_for_function("document.getElementById('result-caption').textContent.startsWith('result: 32x40')",
                           timeout=90_000)
    assert page.eval_on_selector_all("#maps-view input", "l => l.map(i => i.value)") == ["albedo", "bricks_height"]
    assert not sent  # nothing fitted again
    # A model the server no longer has (its cache bounded): said, the page empty
    page.evaluate("(id) => storeDo('readwrite', (s) => s.put({ modelId: id, name: 'builtin:cells', material: false,"
                  " builtin: 'cells', file: null, maps: [] }, 'working'), 'page')", "f" * len(model))
    page.reload()
    page.wait_for_selector("body[data-ready='1']")
    said = chromium.wait_said(page, "no longer on the server")
    assert said.startswith("the model of builtin:cells is no longer on the server"), said
    assert page.is_disabled("#go") and exemplar_shown(page) is None
    assert not [e for e in page.errors if "404" not in e], page.errors
