"""``tghop serve``'s page used as an artist uses it, in a real browser (Chromium through Playwright) against a real
uvicorn server (0.59): Generate's fields and the fit settings outlive a reload as the model and the results do, and
(0.60) so do the result shown and the modes' fields (a result generated again with the same settings and seed is
kept once); Fill makes fills to pick from (0.60, as tghop inpaint --count; a strip stopped shows fill 1, 0.61);
maps of another size than their albedo are refused on the page, not sent (dropped at once with it, or added while a
built-in browsed to by keyboard waits); a result shown beside another model's exemplar names its model; Inpaint
shows its picture whole with its tools at 1024x700, and so does Paint its canvas, and (0.60) Co-occurrence its
edit's."""

import contextlib

import chromium
from conftest import FAST_FIT, png

sync_api = chromium.require()


def generate(page, seed, size=(32, 40)):
    page.fill("#height", str(size[0]))
    page.fill("#width", str(size[1]))
    page.fill("#seed", str(seed))
    page.click("#go")
    page.wait_for_function("(s) => document.getElementById('result-caption').textContent.includes(s) &&"
                           " document.getElementById('go').textContent === 'Generate'", arg=f"seed {seed}",
                           timeout=90_000)


def bricks_result(page, seed, size):
    """A fresh page with builtin:bricks fitted (the fast settings) and its result of ``seed`` at ``size`` shown, made
    from a patch pool of 400 (the default's 5,000 patches, a quarter to half more of the server's work at these sizes,
    are not what the tests of it check)."""
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    page.fill("#n_patches", "400")
    generate(page, seed, size=size)


def choose_inpaint(page):
    """Inpaint chosen, its picture ready to paint on."""
    chromium.choose_mode(page, "inpaint")
    page.wait_for_selector("#editor[data-ready='1']")


def rock_files():
    """[[base64 PNG, name]] of a 128x160 albedo (another size than the built-ins') and its normal map."""
    import base64

    from tghop import data
    from tghop.imageio import to_uint8, to_uint16
    from tghop.material import example_maps

    rock = data.builtin("cells")[:128, :160]
    files = {"rock_albedo.png": png(to_uint8(rock)), "rock_normal.png": png(to_uint16(example_maps(rock)["normal"]))}
    return [[base64.b64encode(b).decode(), name] for name, b in files.items()]


#: JavaScript (a function of [[base64 bytes, file name], ...]): File objects of them.
FILES_JS = """(files) => files.map(([data, name]) =>
  new File([Uint8Array.from(atob(data), (c) => c.charCodeAt(0))], name, { type: "image/png" }))"""


def test_a_reload_keeps_generates_fields_and_the_fit_settings(page):
    # A reload brought the model and the recent results back, but Generate's fields and the fit settings went back to
    # their defaults: the next Generate made a 256x256 of seed 1, untiled, and the next fit the default settings.
    chromium.load_fresh(page, FAST_FIT)
    page.fill("#height", "48")
    page.fill("#width", "64")
    page.fill("#seed", "7")
    page.fill("#refine", "2")
    page.check("#tile")
    page.select_option("#quality", "best")
    page.fill("#scale", "0.5")
    kept = "(r) => r && r.seed === '7' && r.scale === '0.5' && r.quality === 'best' && r.tile === true && r.open"
    for _ in range(100):  # kept at each change (a few milliseconds)
        if page.evaluate(f"storeDo('readonly', (s) => s.get('fields'), 'page').then({kept})"):
            break
        page.wait_for_timeout(50)
    page.reload()
    page.wait_for_selector("body[data-ready='1']")
    values = page.evaluate("""() => Object.fromEntries(["height", "width", "seed", "refine", "n_patches", "tile",
      "paper-gen", "quality", "layout", "scale", "n_clusters", "n_codewords", "stride", "max_patches"].map((id) => {
        const e = document.getElementById(id);
        return [id, e.type === "checkbox" ? e.checked : e.value];
      }))""")
    assert values == {"height": "48", "width": "64", "seed": "7", "refine": "2", "n_patches": "", "tile": True,
                      "paper-gen": False, "quality": "best", "layout": False, "scale": "0.5",
                      **{k: v for k, v in FAST_FIT.items() if k != "layout_factor"}}, values
    assert page.eval_on_selector("#fit-settings", "d => d.open")  # the settings shown as they were left
    chromium.load_empty(page)  # forgotten with the rest
    assert page.input_value("#height") == "256" and page.input_value("#seed") == "1" and not page.is_checked("#tile")
    assert page.is_checked("#layout") and page.input_value("#n_clusters") == ""
    assert not page.errors, page.errors


def test_maps_of_another_size_than_their_albedo_are_refused_on_the_page(page):
    # Dropping an albedo and a map of another size at once, or adding maps while a built-in browsed to by keyboard
    # waited, sent the maps unchecked: the server refused the fit, naming the sizes (a 400 in the console).
    import base64

    from tghop import data
    from tghop.imageio import to_uint8

    chromium.load_fresh(page, FAST_FIT)
    sent = chromium.posted_fits(page)
    rock = rock_files()
    wall = [[base64.b64encode(png(to_uint8(data.bricks(96)))).decode(), "wall_color.png"],
            [rock[1][0], "wall_normal.png"]]  # the normal map of a 128x160 picture
    page.evaluate(f"""(files) => {{
      const transfer = new DataTransfer();
      for (const file of ({FILES_JS})(files)) transfer.items.add(file);
      const area = document.getElementById("drop");
      for (const type of ["dragover", "drop"]) {{
        area.dispatchEvent(new DragEvent(type, {{ bubbles: true, cancelable: true, dataTransfer: transfer }}));
      }}
    }}""", wall)
    said = chromium.wait_said(page, "files dropped")
    assert said == ("2 files dropped: wall_normal is 128x160, not the 96x96 of wall_color.png, the albedo; "
                    "a material's maps are of its albedo's size (nothing was used)"), said
    assert page.eval_on_selector("#message", "e => e.classList.contains('error')")
    assert not sent and page.is_hidden("#fit-status") and page.text_content("#maps-list") == ""
    # Maps added while a built-in browsed to by keyboard waits (fitted once the choice settles): of another size than
    # it, they wait for their albedo, and the built-in is fitted without them.
    page.evaluate(f"""(files) => {{
      fitBuiltinSoon("bricks");  // ArrowDown on the closed menu...
      setMapFiles(({FILES_JS})(files).slice(1));  // ...and maps added before it settles
    }}""", rock)
    said = chromium.wait_said(page, "this fit is without them")
    assert said == "rock_normal is 128x160, not the 256x256 of builtin:bricks: the maps wait for their albedo " \
                   "(this fit is without them)", said
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done' &&"
                           " document.getElementById('summary').textContent.startsWith('model ')", timeout=90_000)
    assert len(sent) == 1 and b"map:" not in sent[0] and b"bricks" in sent[0]
    assert page.text_content("#maps-list") == "maps for the next exemplar: rock_normal"
    assert page.evaluate("state.working.name") == "builtin:bricks"
    assert not page.errors, page.errors  # no refusal: nothing was sent to be refused


def test_a_result_beside_another_models_exemplar_names_its_model(page):
    # Another exemplar picked and fitted left the last result beside it, its caption naming no model: the cells
    # exemplar stood beside a bricks result, as if cells' model had made it.
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    generate(page, 1)
    assert page.text_content("#result-caption") == "result: 32x40, seed 1"
    page.select_option("#builtin", "cells")  # said from the moment the cells exemplar is shown
    page.wait_for_function("document.getElementById('result-caption').textContent ==="
                           " 'result: 32x40, seed 1 (made with builtin:bricks, not builtin:cells)'", timeout=10_000)
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done' &&"
                           " state.working.name === 'builtin:cells' && !document.getElementById('summary').hidden",
                           timeout=90_000)
    assert page.text_content("#result-caption") == "result: 32x40, seed 1 (made with builtin:bricks, not builtin:cells)"
    generate(page, 2)  # cells' own: nothing to say
    assert page.text_content("#result-caption") == "result: 32x40, seed 2"
    page.click("#history figure[data-index='1'] button")  # bricks' shown again beside cells
    page.wait_for_function("document.getElementById('result-caption').textContent ==="
                           " 'result: 32x40, seed 1 (made with builtin:bricks, not builtin:cells)'")
    chromium.fit_builtin(page, "bricks")  # its model working again: no more said
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 32x40, seed 1'")
    assert not page.errors, page.errors


def test_inpaint_shows_its_picture_whole_with_its_tools_at_1024x700(page):
    # At 1024x700 the picture to paint on (a 256x256 result shown 640 px high) began below the fold when Inpaint was
    # chosen: the artist had to scroll to paint, and could not see the brush's tools and the whole picture at once.
    bricks_result(page, 3, (256, 256))
    with chromium.window(page, 1024, 700):
        choose_inpaint(page)
        boxes = {s: page.locator(s).bounding_box() for s in ("#modes-row", "#brush", "#fill", "#mask")}
        for selector, box in boxes.items():
            assert box["y"] >= 0 and box["y"] + box["height"] <= 700, (selector, box)
        assert boxes["#mask"]["height"] >= 256  # never smaller than the picture itself
        stroke = boxes["#mask"]  # painting where the pointer is, at the size shown
        page.mouse.move(stroke["x"] + 10, stroke["y"] + stroke["height"] / 2)
        page.mouse.down()
        page.mouse.move(stroke["x"] + stroke["width"] - 10, stroke["y"] + stroke["height"] / 2, steps=5)
        page.mouse.up()
        row = page.eval_on_selector("#mask", "c => { const d = c.getContext('2d').getImageData(0, 128, 256, 1).data;"
                                    " return [d[4 * 20 + 3], d[4 * 128 + 3], d[4 * 236 + 3]]; }")
        assert all(alpha > 127 for alpha in row), row
        chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_inpaint_shows_its_picture_with_the_brushs_tools_in_a_narrow_window(page):
    # At 400x800 the mode's row, its help, the tools and the Extend row took the window, and the picture to paint on
    # began below the fold: chosen, Inpaint showed no picture.
    bricks_result(page, 3, (128, 192))
    with chromium.window(page, 400, 800):
        choose_inpaint(page)
        with contextlib.suppress(sync_api.TimeoutError):  # laid out (0.61 waited 300 ms); the checks below say what
            page.wait_for_function("() => ['brush', 'fill', 'mask'].every((id) => {"
                                   " const r = document.getElementById(id).getBoundingClientRect();"
                                   " return r.height > 0 && r.top >= 0 && r.bottom <= 800; })", timeout=5_000)
        for selector in ("#brush", "#fill", "#mask"):
            box = page.locator(selector).bounding_box()
            assert box["y"] >= 0 and box["y"] + box["height"] <= 800, (selector, box)
        assert page.locator("#mask").bounding_box()["height"] >= 128  # never smaller than the picture itself
        chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_paint_shows_its_canvas_whole_with_its_tools_at_1024x700(page):
    # At 1024x700 Paint's canvas (a 256x256 output shown 640 px high) began low under Paint's tools when the mode was
    # chosen: two thirds of it below the fold, the artist scrolling between the brush colours and the canvas.
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    chromium.fit_builtin(page, "cells")
    page.fill("#height", "256")
    page.fill("#width", "256")
    with chromium.window(page, 1024, 700):
        chromium.choose_mode(page, "paint")
        boxes = {s: page.locator(s).bounding_box() for s in ("#modes-row", "#paint-colours", "#paint-go", "#guide")}
        for selector, box in boxes.items():
            assert box["y"] >= 0 and box["y"] + box["height"] <= 700, (selector, box)
        assert boxes["#guide"]["height"] >= 256
        page.locator("#paint-colours label").nth(1).click()  # cells' colour, across the middle
        box = boxes["#guide"]
        page.mouse.move(box["x"] + 10, box["y"] + box["height"] / 2)
        page.mouse.down()
        page.mouse.move(box["x"] + box["width"] - 10, box["y"] + box["height"] / 2, steps=5)
        page.mouse.up()
        row = page.evaluate("[20, 128, 236].map((x) => guide.labels[128 * 256 + x])")
        assert row == [1, 1, 1] and page.evaluate("guide.labels[0]") == 0, row
        chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def stored(page, key, check, store="page"):
    """Wait until the page's store holds ``key`` (of ``store``) as ``check`` (a JavaScript function of it) says: each
    is written at its change, a few milliseconds after it."""
    for _ in range(100):
        if page.evaluate(f"storeDo('readonly', (s) => s.get({key!r}), {store!r}).then({check})"):
            return
        page.wait_for_timeout(50)
    raise AssertionError(f"{key!r} never stored as {check}")


def test_a_reload_shows_the_result_shown_before_it(page):
    # 0.59 kept the recent results across a reload, but the result beside the exemplar was empty after it: the last
    # result (or the one shown again from Recent results) was only a thumbnail there, its tiling gone.
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    generate(page, 4)
    generate(page, 5)
    page.click("#history figure[data-index='1'] button")  # seed 4 shown again: that is what stays shown
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 32x40, seed 4'")
    stored(page, "shown", "(k) => k === recent.entries[1].key")
    page.reload()
    page.wait_for_selector("body[data-ready='1']")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 32x40, seed 4'",
                           timeout=10_000)
    assert page.is_visible("#result") and page.is_visible("#tiled") and page.is_visible("#download-png")
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-32x40-seed4.png"
    pressed = page.eval_on_selector_all("#history .history-item", "b => b.map((e) => e.getAttribute('aria-pressed'))")
    assert pressed == ["false", "true"], pressed
    assert page.evaluate("editor.blob === state.lastShown.blob")  # Inpaint paints on it, as before the reload
    assert page.input_value("#seed") == "4"  # the fields as the click on seed 4 left them (kept)
    chromium.load_empty(page)  # forgotten with the rest: nothing shown
    assert page.is_hidden("#result")
    assert not page.errors, page.errors


def test_generate_again_with_the_same_settings_and_seed_keeps_one_recent_entry(page):
    # Generate pressed again with the same model, settings and seed added a second entry of the same image to Recent
    # results (0.59), pushing an older result out of the 12 for nothing.
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    generate(page, 6)
    generate(page, 7)
    generate(page, 6)  # seed 6 again: its entry, now the first
    texts = page.eval_on_selector_all("#history figcaption", "f => f.map((e) => e.textContent)")
    assert texts == ["result 32x40, seed 6 (bricks)", "result 32x40, seed 7 (bricks)"], texts
    assert page.text_content("#gen-message") == ("seed 6 done: the same model, settings and seed as a recent result, "
                                                 "the same image (one entry, now the first)")
    pressed = page.eval_on_selector_all("#history .history-item", "b => b.map((e) => e.getAttribute('aria-pressed'))")
    assert pressed == ["true", "false"], pressed
    page.check("#tile")  # another setting: another image, another entry
    generate(page, 6)
    assert page.eval_on_selector_all("#history figcaption", "f => f.map((e) => e.textContent)") == [
        "result 32x40, seed 6, tileable (bricks)", "result 32x40, seed 6 (bricks)", "result 32x40, seed 7 (bricks)"]
    assert page.text_content("#gen-message") == ""
    page.uncheck("#tile")
    stored(page, "fields", "(r) => r && r.tile === false")  # kept (a few milliseconds) before the reload
    page.reload()  # the entry replaced is gone from the store too
    page.wait_for_selector("body[data-ready='1']")
    page.wait_for_function("document.querySelectorAll('#history figcaption').length === 3")
    generate(page, 7)  # the same as an entry kept across the reload
    assert page.eval_on_selector_all("#history figcaption", "f => f.map((e) => e.textContent)") == [
        "result 32x40, seed 7 (bricks)", "result 32x40, seed 6, tileable (bricks)", "result 32x40, seed 6 (bricks)"]
    assert not page.errors, page.errors


#: The modes' fields kept across a reload (0.60), each with a value other than its default: Paint's, Morph's, Inpaint's
#: and Extend's, Co-occurrence's, the brushes' sizes.
MODE_FIELDS = {"paint-brush": "40", "transition": "12", "paint-seed": "9", "morph-height": "64", "morph-width": "300",
               "morph-seed": "4", "brush": "30", "inpaint-seed": "8", "inpaint-count": "3", "inpaint-tile": True,
               "extend-height": "300",
               "extend-width": "320", "extend-anchor": "top-left", "cooc-length": "12", "cooc-morph-seed": "5",
               "cooc-height": "96", "cooc-width": "160", "cooc-brush": "20", "cooc-boost-a": "1", "cooc-boost-b": "2",
               "cooc-boost-factor": "3", "cooc-edit-seed": "6"}

#: JavaScript: the values of the fields named (a checkbox's checked state).
FIELD_VALUES_JS = """(ids) => Object.fromEntries(ids.map((id) => {
  const e = document.getElementById(id);
  return [id, e.type === "checkbox" ? e.checked : e.value];
}))"""


def stroke_across(page):
    """Paint a hole across the middle of Inpaint's picture."""
    box = page.locator("#mask").bounding_box()
    page.mouse.move(box["x"] + 10, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] - 10, box["y"] + box["height"] / 2, steps=5)
    page.mouse.up()


def ask_fills(page, seed, count):
    """Inpaint chosen, a hole painted across its picture, and ``count`` fills of ``seed`` asked for (not yet sent)."""
    choose_inpaint(page)
    stroke_across(page)
    page.fill("#inpaint-seed", str(seed))
    page.fill("#inpaint-count", str(count))


def load_checkpoint(page, checkpoint):
    """Co-occurrence chosen and ``checkpoint`` loaded, its exemplar ready for crops."""
    chromium.choose_mode(page, "cooc")
    page.set_input_files("#cooc-file", str(checkpoint))
    page.wait_for_function("document.getElementById('cooc-exemplar').dataset.ready === '1'", timeout=30_000)


def test_a_strip_of_fills_still_coming_stops_when_the_mode_or_the_model_changes(page):
    # 0.60 went on adding the fills to the strip that another mode had cleared, and once another exemplar's fit ended
    # it asked for the rest of them of that model (askPicture read the working model at each fill).
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "cells")  # in the server's cache: picked again below, it is the working model at once
    chromium.fit_builtin(page, "bricks")
    bricks = page.evaluate("state.modelId")
    page.fill("#n_patches", "400")  # a small pool: a quick picture to fill (bricks_result's)
    generate(page, 5, size=(64, 64))
    ask_fills(page, 4, 3)
    page.evaluate("""() => { window.stripImages = 0; new MutationObserver((changes) => {
      for (const c of changes) window.stripImages += [...c.addedNodes].filter((n) => n.querySelector).length;
    }).observe(document.getElementById('strip'), { childList: true }); }""")
    with chromium.HeldAnswers(page, "**/api/models/*/inpaint") as answers:
        page.click("#fill")
        answers.send_next()  # fill 1
        page.wait_for_function("document.querySelectorAll('#strip img').length === 1", timeout=60_000)
        answers.wait()  # fill 2's, held while View is chosen
        chromium.choose_mode(page, "view")
        page.wait_for_function("document.getElementById('fill').textContent === 'Fill'", timeout=30_000)
        answers.release()
    page.wait_for_timeout(300)
    assert page.evaluate("window.stripImages") == 1 and len(answers.urls) == 2  # fill 3 never asked for
    assert page.eval_on_selector_all("#strip img", "l => l.length") == 0
    assert page.text_content("#inpaint-message") == ("the fills stopped at fill 2 of 3: another mode or model was "
                                                     "chosen, and their strip went")
    choose_inpaint(page)
    if not page.evaluate("maskPainted()"):
        stroke_across(page)
    with chromium.HeldAnswers(page, "**/api/models/*/inpaint") as answers:
        page.click("#fill")
        answers.send_next()
        page.wait_for_function("document.querySelectorAll('#strip img').length === 1", timeout=60_000)
        answers.wait()  # fill 2's, held while cells becomes the working model
        page.select_option("#builtin", "cells")
        page.wait_for_function("state.working.name === 'builtin:cells'"
                               " && document.getElementById('fill').textContent === 'Fill'", timeout=30_000)
        answers.release()
    page.wait_for_timeout(300)
    assert page.evaluate("window.stripImages") == 2 and len(answers.urls) == 2
    assert all(f"/api/models/{bricks}/inpaint" in url for url in answers.urls), answers.urls  # none of cells
    assert page.eval_on_selector_all("#strip img", "l => l.length") == 0
    # The mode changed as the last fill came (its thumbnail still decoding): no fill picked into the strip gone
    chromium.fit_builtin(page, "bricks")
    choose_inpaint(page)
    if not page.evaluate("maskPainted()"):
        stroke_across(page)
    page.fill("#inpaint-count", "2")
    page.evaluate("""() => {
      const decode = window.plainDecode = HTMLImageElement.prototype.decode;
      window.decodes = [];  // the strip's thumbnails' decodes, held until the test lets each go
      HTMLImageElement.prototype.decode = function () {
        if (!this.closest("#strip")) return decode.call(this);
        return new Promise((done) => decodes.push(() => decode.call(this).then(done, done)));
      };
    }""")
    caption = page.text_content("#result-caption")
    try:
        page.click("#fill")
        page.wait_for_function("decodes.length === 1", timeout=60_000)
        page.evaluate("() => { decodes.shift()(); }")
        page.wait_for_function("decodes.length === 1", timeout=60_000)  # the last fill's
        chromium.choose_mode(page, "view")
        page.evaluate("() => { decodes.shift()(); }")
        page.wait_for_function("document.getElementById('fill').textContent === 'Fill'", timeout=30_000)
    finally:
        page.evaluate("() => { HTMLImageElement.prototype.decode = plainDecode; }")  # the browser's own again
    assert page.text_content("#result-caption") == caption  # fill 1 not picked
    assert page.eval_on_selector_all("#strip img", "l => l.length") == 0
    assert page.text_content("#inpaint-message") == "the fills' strip went: another mode or model was chosen"
    chromium.choose_mode(page, "view")
    assert not [e for e in page.errors if "status of 4" not in e], page.errors

def image_part(body: bytes) -> bytes:
    """The file field 'image' of a multipart body, as sent."""
    boundary = body.split(b"\r\n", 1)[0]
    part = next(p for p in body.split(boundary) if b'name="image"' in p.split(b"\r\n\r\n", 1)[0])
    return part.split(b"\r\n\r\n", 1)[1]


def test_a_fill_picked_while_the_strip_still_comes_leaves_the_rest_of_the_strip_as_it_was(page):
    # A fill picked from the strip becomes the picture to paint on: 0.60 sent it as the picture of the fills still to
    # come, which were then fills of a fill (and, 0.61, not tghop inpaint --count's fill k).
    bricks_result(page, 6, (64, 64))
    ask_fills(page, 9, 3)
    bodies = []
    page.on("request", lambda r: bodies.append(r.post_data_buffer) if r.url.endswith("/inpaint") else None)
    with chromium.HeldAnswers(page, "**/api/models/*/inpaint") as answers:
        page.click("#fill")
        answers.send_next()  # fill 1
        page.wait_for_function("document.querySelectorAll('#strip img').length === 1", timeout=60_000)
        page.click("#strip img")  # picked while fills 2 and 3 come
        page.wait_for_function("document.getElementById('result-caption').textContent.endsWith('fill 1')")
        answers.release()
        page.wait_for_function("document.getElementById('fill').textContent === 'Fill' &&"
                               " document.querySelectorAll('#strip img').length === 3", timeout=120_000)
    assert len(bodies) == 3 and len({image_part(b) for b in bodies}) == 1  # the picture the strip began with
    # its name to a screen reader: its own, not the 8 seeds' (0.60: "eight seeds to pick from")
    sync_api.expect(page.locator("#strip")).to_have_accessible_name("3 fills to pick from")
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors

def test_a_strip_of_fills_stopped_shows_the_first_fill_that_came(page):
    # Stop pressed while fill 3 of 3 came kept fills 1 and 2 in the strip but showed neither as the result, "stopped"
    # said alone (0.60): a finished strip shows fill 1.
    bricks_result(page, 7, (64, 64))
    ask_fills(page, 5, 3)
    with chromium.HeldAnswers(page, "**/api/models/*/inpaint") as answers:
        page.click("#fill")
        answers.send_next()  # fill 1
        answers.send_next()  # fill 2
        page.wait_for_function("document.querySelectorAll('#strip img').length === 2", timeout=60_000)
        answers.wait()  # fill 3's, held while Stop is pressed
        page.click("#fill")  # it reads Stop
        page.wait_for_function("document.getElementById('fill').textContent === 'Fill'", timeout=30_000)
    page.wait_for_function("document.getElementById('result-caption').textContent === 'inpainted: 64x64, seed 5, "
                           "fill 1'", timeout=10_000)
    assert page.text_content("#inpaint-message") == (
        "stopped at fill 3 of 3: fills 1 and 2 are under the picture, fill 1 shown (click one to pick it); Undo goes "
        "back to the picture before")
    assert page.eval_on_selector_all("#strip img", "l => l.map((i) => i.classList.contains('chosen'))") == [
        True, False]
    page.click("#strip figure:nth-child(2) img")
    page.wait_for_function("document.getElementById('result-caption').textContent.endsWith('fill 2')")
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_a_strip_of_fills_is_seen_with_its_picture_at_1024x700(page):
    # At 1024x700 a 128x192 result filled the window to paint on, and the fills to pick from came under it, below the
    # fold: "3 fills ... under the picture: click one to pick it", of which the artist saw none.
    bricks_result(page, 3, (128, 192))
    with chromium.window(page, 1024, 700):
        choose_inpaint(page)
        stroke_across(page)
        page.fill("#inpaint-seed", "2")
        page.fill("#inpaint-count", "2")  # a strip (0.61 made 3 fills of 128x192: one more to wait for)
        page.click("#fill")
        page.wait_for_function("document.getElementById('fill').textContent === 'Fill' &&"
                               " document.querySelectorAll('#strip img').length === 2", timeout=120_000)
        page.wait_for_function("[...document.querySelectorAll('#strip img')].every((i) => i.complete)")
        boxes = {s: page.locator(s).bounding_box() for s in ("#modes-row", "#fill", "#mask", "#strip")}
        for selector, box in boxes.items():
            assert box["y"] >= 0 and box["y"] + box["height"] <= 700, (selector, box)
        assert boxes["#mask"]["height"] >= 128  # never smaller than the picture itself
        chromium.choose_mode(page, "view")
    assert not page.errors, page.errors

def test_a_reload_keeps_the_modes_fields(page):
    # Generate's fields and the fit settings came back after a reload (0.59), but Paint's, Morph's, Inpaint's and
    # Co-occurrence's went back to their defaults: a seed, a transition, a morph's size, a brush set for the work.
    chromium.load_fresh(page, FAST_FIT)
    defaults = page.evaluate(FIELD_VALUES_JS, list(MODE_FIELDS))
    page.evaluate("""(values) => { for (const [id, value] of Object.entries(values)) {  // as typed, each its event
      const e = document.getElementById(id);
      if (e.type === "checkbox") e.checked = value; else e.value = value;
      e.dispatchEvent(new Event(e.type === "checkbox" || e.tagName === "SELECT" ? "change" : "input"));
    } }""", MODE_FIELDS)
    stored(page, "fields", "(r) => r && r['cooc-edit-seed'] === '6' && r['inpaint-tile'] === true")
    page.reload()
    page.wait_for_selector("body[data-ready='1']")
    assert page.evaluate(FIELD_VALUES_JS, list(MODE_FIELDS)) == MODE_FIELDS
    # The brushes' sizes said beside them as they are
    assert [page.text_content(f"#{i}-size") for i in ("paint-brush", "brush", "cooc-brush")] == ["40 px", "30 px",
                                                                                                  "20 px"]
    chromium.load_empty(page)  # forgotten with the rest
    assert page.evaluate(FIELD_VALUES_JS, list(MODE_FIELDS)) == defaults
    assert defaults["paint-seed"] == "1" and defaults["extend-height"] == "" and defaults["inpaint-tile"] is False
    assert not page.errors, page.errors


def test_the_cooc_edit_shows_its_canvas_whole_with_the_crops_at_1024x700(page, tiny_cooc_checkpoint):
    # At 1024x700 the co-occurrence edit's canvas (128x192, shown 640 px wide) began 700 px under the mode's row when a
    # checkpoint was loaded (0.59): the artist scrolled between the crops placed on the exemplar and the canvas.
    chromium.load_empty(page)
    with chromium.window(page, 1024, 700):
        load_checkpoint(page, tiny_cooc_checkpoint)
        selectors = ("#cooc-message", "#cooc-crops", "#cooc-exemplar", "#cooc-edit-go", "#cooc-guide")

        def in_view():
            boxes = {s: page.locator(s).bounding_box() for s in selectors}
            for selector, box in boxes.items():
                assert box["y"] >= 0 and box["y"] + box["height"] <= 700, (selector, box)
            assert boxes["#cooc-guide"]["height"] >= 128  # never smaller than the canvas itself
            return boxes

        in_view()
        page.click("#cooc-exemplar", position={"x": 20, "y": 20})  # crop 1 placed
        assert page.text_content("#cooc-message").startswith("crop 1 is at (0, 0)")  # said in view
        page.click("label:has(#cooc-crop-1)")  # crop 2's colour, painted across the middle
        box = in_view()["#cooc-guide"]
        page.mouse.move(box["x"] + 5, box["y"] + box["height"] / 2)
        page.mouse.down()
        page.mouse.move(box["x"] + box["width"] - 5, box["y"] + box["height"] / 2, steps=5)
        page.mouse.up()
        row = page.evaluate("[10, 96, 182].map((x) => coocBoard.labels[64 * 192 + x])")
        assert row == [1, 1, 1] and page.evaluate("coocBoard.labels[0]") == 0, row
        chromium.choose_mode(page, "view")  # the mode chosen again, from the top: in view again
        page.evaluate("window.scrollTo(0, 0)")
        chromium.choose_mode(page, "cooc")
        in_view()
        chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_fill_with_a_count_makes_fills_to_pick_from(page):
    # tghop inpaint --count N made fills to pick from (0.59); the page's Fill made one at a time, a seed typed between.
    # 0.61: they are the command's, fill k of seed s (0.60: seeds s, s + 1, ..., named by seed), named as it names them.
    bricks_result(page, 2, (64, 64))
    choose_inpaint(page)
    box = page.locator("#mask").bounding_box()  # a hole across the middle
    page.mouse.move(box["x"] + 10, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] - 10, box["y"] + box["height"] / 2, steps=5)
    page.mouse.up()
    page.fill("#inpaint-count", "9")  # said, not sent
    page.click("#fill")
    assert page.text_content("#inpaint-message") == "fills 9 is more than 8: give a number from 1 to 8"
    page.fill("#inpaint-seed", "4")
    page.fill("#inpaint-count", "3")
    page.click("#fill")
    page.wait_for_function("document.getElementById('fill').textContent === 'Fill' &&"
                           " document.querySelectorAll('#strip img').length === 3", timeout=120_000)
    assert page.text_content("#inpaint-message") == (
        "3 fills of seed 4 under the picture, as tghop inpaint --seed 4 --count 3 makes them: click one to pick it "
        "(fill 1 is shown); Undo goes back to the picture before")
    assert page.eval_on_selector_all("#strip figcaption", "f => f.map((e) => e.textContent)") == [
        "fill 1", "fill 2", "fill 3"]
    page.wait_for_function("document.getElementById('result-caption').textContent === 'inpainted: 64x64, seed 4, "
                           "fill 1'")
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-inpainted-64x64-seed4_1.png"
    page.click("#strip figure:nth-child(3) img")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'inpainted: 64x64, seed 4, "
                           "fill 3'")
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-inpainted-64x64-seed4_3.png"  # out_3.png
    bytes_of = "async (url) => [...new Uint8Array(await (await fetch(url)).arrayBuffer())].join(',')"
    first = page.evaluate(bytes_of, page.get_attribute("#strip figure:nth-child(1) img", "src"))
    captions = page.eval_on_selector_all("#history figcaption", "f => f.map((e) => e.textContent)")
    assert captions == ["inpainted 64x64, seed 4, fill 3 (bricks)", "result 64x64, seed 2, patch pool 400 (bricks)"], (
        captions)
    assert page.get_attribute("#history figure a", "download") == "tghop-bricks-inpainted-64x64-seed4_3.png"
    page.click("#undo")  # back to the picture before the fills, its hole painted
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 64x64, seed 2'")
    assert page.evaluate("maskPainted()")
    page.fill("#inpaint-count", "1")
    page.click("#fill")  # a Fill of seed 4 alone: the strip's first (fill 1 of --count is --count 1's), the strip gone
    page.wait_for_function("document.getElementById('result-caption').textContent === 'inpainted: 64x64, seed 4'"
                           " && document.getElementById('fill').textContent === 'Fill'", timeout=120_000)
    assert page.evaluate("document.querySelectorAll('#strip img').length") == 0
    assert page.evaluate(bytes_of, page.get_attribute("#result", "src")) == first
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-inpainted-64x64-seed4.png"
    captions = page.eval_on_selector_all("#history figcaption", "f => f.map((e) => e.textContent)")
    assert captions[0] == "inpainted 64x64, seed 4 (bricks)"
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_an_error_partway_through_a_strip_of_fills_shows_the_fills_that_came(page):
    # A server error at fill 2 of 3 kept fill 1 in the strip but showed it nowhere else, the error said alone (0.61):
    # now fill 1 is shown as Stop shows it, and the error and what came are said in one line.
    import json

    bricks_result(page, 8, (64, 64))
    ask_fills(page, 5, 3)
    asked = []

    def second_fails(route):
        asked.append(route.request.url)
        if len(asked) == 2:
            route.fulfill(status=500, content_type="application/json", body=json.dumps({"error": "the server broke."}))
        else:
            route.continue_()

    page.route("**/api/models/*/inpaint", second_fails)
    try:
        page.click("#fill")
        page.wait_for_function("document.getElementById('fill').textContent === 'Fill'", timeout=120_000)
    finally:
        page.unroute("**/api/models/*/inpaint", second_fails)
    page.wait_for_function("document.getElementById('result-caption').textContent === 'inpainted: 64x64, seed 5, "
                           "fill 1'", timeout=10_000)
    assert page.text_content("#inpaint-message") == (
        "fill 2 of 3 failed: the server broke; fill 1 is under the picture, fill 1 shown (click one to pick it); Undo "
        "goes back to the picture before")
    assert page.eval_on_selector("#inpaint-message", "e => e.classList.contains('error')") and len(asked) == 2
    assert page.eval_on_selector_all("#strip img", "l => l.map((i) => i.classList.contains('chosen'))") == [True]
    chromium.choose_mode(page, "view")
    assert not [e for e in page.errors if "status of 500" not in e], page.errors
    page.errors.clear()  # the 500 answered on purpose, not the next test's


def test_a_checkpoint_loaded_in_a_narrow_window_shows_where_to_place_the_crops(page, tiny_cooc_checkpoint):
    # At 400x800 a checkpoint loaded brought the edit's canvas into view, the crops, the exemplar and the message
    # "click on the exemplar to place crop 1" above it, out of sight (0.61): placing crops comes first.
    chromium.load_empty(page)
    with chromium.window(page, 400, 800):
        load_checkpoint(page, tiny_cooc_checkpoint)
        assert page.text_content("#cooc-message").startswith("click on the exemplar to place crop 1")
        for selector in ("#cooc-message", "#cooc-crops", "#cooc-exemplar"):
            box = page.locator(selector).bounding_box()
            assert box["y"] >= -1 and box["y"] + box["height"] <= 800, (selector, box)  # scrolled to the message
        chromium.choose_mode(page, "view")
    assert not page.errors, page.errors


def test_a_window_made_lower_sizes_paints_canvas_again(page):
    # Paint's canvas (and Inpaint's picture, Co-occurrence's edit) kept the size it had for the window the mode was
    # chosen in: a window made lower, 1200x1400 to 1024x700, cut a 256x256 canvas shown 640 px high at its foot (0.61).
    chromium.load_fresh(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    page.fill("#height", "256")
    page.fill("#width", "256")
    chromium.choose_mode(page, "paint")
    assert page.locator("#guide").bounding_box()["height"] > 600  # room for it in the tall window
    with chromium.window(page, 1024, 700):
        page.evaluate("document.getElementById('modes-row').scrollIntoView({ block: 'start' })")
        page.wait_for_function("(() => { const r = document.getElementById('guide').getBoundingClientRect();"
                               " return r.bottom <= innerHeight && r.height >= 256; })()", timeout=5_000)
        chromium.choose_mode(page, "view")
    assert not page.errors, page.errors
