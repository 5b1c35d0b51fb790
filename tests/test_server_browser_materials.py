"""A whole material on ``tghop serve``'s page in a real browser (Chromium through Playwright)
against a real uvicorn server: add two maps (one 16-bit), pick builtin:bricks as the albedo,
generate, switch the map shown, download every map (the 16-bit one still 16-bit), pick one of
8 seeds, and drop the maps again (a texture model); two materials morphed (0.60)."""

import os
import time
import zipfile

import chromium
from conftest import FAST_FIT, png, save_material, save_texture

chromium.require()

#: Where the test leaves a screenshot of the page (to look at).
SCREENSHOT = os.environ.get("TGHOP_MATERIAL_SCREENSHOT", "/tmp/tghop-material-page.png")


def wait_fitted(page):
    page.wait_for_selector("#fit-status:not([hidden])")
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done'", timeout=90_000)
    page.wait_for_selector("#summary:not([hidden])")


def test_fit_a_material_generate_see_and_download_every_map(page, tmp_path):
    from tghop import data
    from tghop.imageio import load_image, to_uint8, to_uint16
    from tghop.material import example_maps

    maps = example_maps(data.builtin("bricks"))
    normal, height = tmp_path / "bricks normal.png", tmp_path / "bricks_height.png"
    normal.write_bytes(png(to_uint16(maps["normal"])))
    height.write_bytes(png(to_uint8(maps["height"][..., 0])))
    chromium.set_fit_settings(page, FAST_FIT)
    page.set_input_files("#maps", [str(normal), str(height)])
    assert page.text_content("#maps-list") == "maps: bricks_normal, bricks_height"
    assert page.is_visible("#maps-clear")
    page.select_option("#builtin", "bricks")
    wait_fitted(page)
    summary = page.text_content("#summary")
    assert summary.startswith("material ")
    assert "maps: albedo, 8-bit; bricks_normal (normal), 16-bit; bricks_height, 8-bit" in summary
    page.wait_for_function("!document.getElementById('quality').disabled")  # 0.59: the albedo takes best (0.58: off)

    page.fill("#height", "64")
    page.fill("#width", "80")
    page.fill("#seed", "3")
    page.fill("#n_patches", "400")  # a small pool: quick images (this result, the 8 seeds, the texture model's)
    # the generation's answer, waited for as long as the fit (0.61: Playwright's 30 s, which a loaded run passed)
    with page.expect_response(lambda r: r.url.endswith("/images"), timeout=90_000) as answer:
        page.click("#go")
    # The page asks for multipart: the maps as files, nothing to decode
    assert answer.value.headers["content-type"].startswith("multipart/form-data; boundary=")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 64x80, seed 3'")
    assert page.eval_on_selector_all("#maps-view input", "l => l.map(i => i.value)") == [
        "albedo", "bricks_normal", "bricks_height"]
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-64x80-seed3.png"
    page.locator("#maps-view label", has_text="bricks_normal").click()
    page.wait_for_function("document.getElementById('result-caption').textContent"
                           " === 'result (bricks_normal): 64x80, seed 3'")
    # Named as tghop synth names the files: the maps' shared "bricks_" dropped (the server's suffix)
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-64x80-seed3_normal.png"
    page.wait_for_function("document.getElementById('tiled').width === 240")

    with page.expect_download() as download:  # one ZIP of every map, the files as tghop synth names them
        page.click("#download-maps")
    assert download.value.suggested_filename == "tghop-bricks-64x80-seed3.zip"
    download.value.save_as(tmp_path / "maps.zip")
    with zipfile.ZipFile(tmp_path / "maps.zip") as archive:
        assert archive.testzip() is None  # every CRC right
        names = archive.namelist()
        assert names == [f"tghop-bricks-64x80-seed3{m}.png" for m in ("", "_normal", "_height")]
        archive.extractall(tmp_path)
    for name in names:
        image, depth = load_image(tmp_path / name, dtype=None, with_depth=True)
        assert image.shape[:2] == (64, 80)
        assert depth == (16 if "normal" in name else 8), name
    page.screenshot(path=SCREENSHOT, full_page=True)

    page.click("#strip-go")
    page.wait_for_function("document.querySelectorAll('#strip img').length === 8"
                           " && document.getElementById('gen-message').textContent === 'click a seed to pick it'",
                           timeout=60_000)
    page.click("#strip img[data-seed='5']")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 64x80, seed 5'")
    assert page.eval_on_selector_all("#maps-view input", "l => l.length") == 3

    page.click("#maps-clear")  # the same exemplar fitted again without maps: a texture model
    assert page.text_content("#maps-list") == ""
    page.wait_for_function("document.getElementById('summary').textContent.startsWith('model ')", timeout=90_000)
    assert not page.is_disabled("#quality")
    page.fill("#seed", "3")  # picking seed 5 set it
    page.click("#go")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 64x80, seed 3'"
                           " && document.getElementById('maps-view').hidden")
    assert page.is_hidden("#download-maps")
    assert not page.errors, page.errors


def test_map_files_naming_one_map_twice_are_refused_on_the_page_before_any_fit(page, tmp_path):
    from tghop import data
    from tghop.imageio import to_uint8

    chromium.load_empty(page)  # a fresh page: no exemplar, no maps
    grey = png(to_uint8(data.bricks(64))[..., 0])
    for name in ("rock_normal.png", "rock normal.png", "Albedo.png", "height.png"):
        (tmp_path / name).write_bytes(grey)
    page.set_input_files("#maps", [str(tmp_path / "height.png")])  # before an exemplar: the page says what next
    assert page.text_content("#maps-list") == "maps: height"
    assert "pick or drop the albedo (exemplar) now" in page.text_content("#message")
    # Two files whose names make the same map's: said on the page (the server's words were about form fields)
    page.set_input_files("#maps", [str(tmp_path / "rock_normal.png"), str(tmp_path / "rock normal.png")])
    message = page.text_content("#message")
    assert "rock_normal.png and rock normal.png" in message and "rename one" in message, message
    assert page.eval_on_selector("#message", "e => e.classList.contains('error')")
    assert page.text_content("#maps-list") == "maps: height"  # the maps chosen before stay
    page.set_input_files("#maps", [str(tmp_path / "Albedo.png")])
    assert "the exemplar's name" in page.text_content("#message")
    # The maps kept, 64x64, are no maps of bricks (256x256): dropped, said, and bricks fitted alone (0.58 sent them,
    # refused by the server)
    page.select_option("#builtin", "bricks")
    page.wait_for_function("document.getElementById('message').textContent.startsWith('maps dropped: height is 64x64')",
                           timeout=30_000)
    assert page.text_content("#maps-list").startswith("maps dropped: height (64x64)")
    page.click("#cancel")


def test_a_materials_answer_decodes_to_its_bytes(page):
    same = page.evaluate("""async () => {
      const bytes = Uint8Array.from({length: 1024}, (_, i) => (i * 7) % 256);
      const body = {size: [1, 1], seed: 1, maps: [{name: "albedo", depth: 8, normal: false,
                    png: btoa(String.fromCharCode(...bytes))}]};
      const json = {headers: {"Content-Type": "application/json"}};
      const answer = await answerOf(new Response(JSON.stringify(body), json));
      const got = new Uint8Array(await answer.maps[0].blob.arrayBuffer());
      return got.length === bytes.length && got.every((v, i) => v === bytes[i]);
    }""")
    assert same


def test_inpaint_says_a_material_is_not_inpainted(page, tmp_path):
    save_material(tmp_path / "material.npz")
    page.set_input_files("#model-file", str(tmp_path / "material.npz"))
    page.wait_for_function("document.getElementById('summary').textContent.startsWith('material ')")
    page.wait_for_function("document.getElementById('message').textContent"
                           " === 'material material.npz loaded: generate below (every map)'")
    page.click("label:has(#mode-inpaint)")
    assert "is a material" in page.text_content("#inpaint-message")
    page.click("label:has(#mode-view)")
    assert not [e for e in page.errors if "status of 400" not in e], page.errors


def test_fill_and_extend_are_off_for_a_material_and_a_picture_without_maps(page, tmp_path):
    # They were on: Extend sent the picture alone and the page showed the API's words ("send each of
    # them ... as the file field map:<name>"), Fill the same once a hole was painted.
    from tghop import data
    from tghop.imageio import to_uint8

    save_material(tmp_path / "material.npz")
    page.locator("label", has=page.locator("#mode-inpaint")).click()
    page.set_input_files("#model-file", str(tmp_path / "material.npz"))
    page.wait_for_function("document.getElementById('message').textContent"
                           " === 'material material.npz loaded: generate below (every map)'")
    (tmp_path / "own.png").write_bytes(png(to_uint8(data.bricks(64))))
    page.set_input_files("#picture", str(tmp_path / "own.png"))  # a picture of one's own: no maps
    page.wait_for_selector("#editor[data-ready='1']")
    assert page.is_disabled("#fill") and page.is_disabled("#extend-go")
    assert "is a material" in page.text_content("#inpaint-message")
    page.locator("label", has=page.locator("#mode-view")).click()
    page.fill("#height", "64")
    page.fill("#width", "64")
    page.click("#go")  # a result of the material: its maps, so Fill and Extend work
    page.wait_for_function("document.getElementById('maps-view').querySelectorAll('input').length === 2")
    page.locator("label", has=page.locator("#mode-inpaint")).click()
    page.wait_for_selector("#editor[data-ready='1']")
    assert page.is_enabled("#fill") and page.is_enabled("#extend-go")
    assert page.text_content("#inpaint-message") == ""
    page.locator("label", has=page.locator("#mode-view")).click()
    assert not [e for e in page.errors if "status of 400" not in e], page.errors


def test_fill_a_hole_in_every_map_of_a_material_result(page, tmp_path):
    from tghop import data
    from tghop.imageio import to_uint8, to_uint16
    from tghop.material import example_maps

    page.locator("label", has=page.locator("#mode-view")).click()
    # The fast fit: the reload of a test before put the fields back to the defaults, a whole fit of a material
    # with its layout (the group's longest fit, for a test of Fill)
    chromium.set_fit_settings(page, FAST_FIT)
    maps = example_maps(data.builtin("bricks"))
    (tmp_path / "normal.png").write_bytes(png(to_uint16(maps["normal"])))
    (tmp_path / "height.png").write_bytes(png(to_uint8(maps["height"][..., 0])))
    page.set_input_files("#maps", [str(tmp_path / "normal.png"), str(tmp_path / "height.png")])
    page.select_option("#builtin", "")
    page.select_option("#builtin", "bricks")
    # The material's summary and Generate on: a summary of the model before the pick (the test before left a
    # working model, which the maps may have refitted) said "material" while the pick's fit still ran, under
    # load for longer than a click waits; so did that model's Generate, before the pick's fit began (its maps'
    # sizes compared first): the pick's model is waited for by its name.
    page.wait_for_function("state.working && state.working.name === 'builtin:bricks + 2 maps' &&"
                           " document.getElementById('summary').textContent.startsWith('material ') &&"
                           " !document.getElementById('go').disabled", timeout=90_000)
    page.fill("#height", "64")
    page.fill("#width", "80")
    page.fill("#seed", "4")
    page.click("#go")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 64x80, seed 4'")
    page.locator("label", has=page.locator("#mode-inpaint")).click()
    page.wait_for_selector("#editor[data-ready='1']")
    assert "is a material" not in page.text_content("#inpaint-message")
    page.fill("#inpaint-seed", "6")
    box = page.locator("#mask").bounding_box()
    sx, sy = box["width"] / 80, box["height"] / 64
    page.mouse.move(box["x"] + 20 * sx, box["y"] + 30 * sy)
    page.mouse.down()
    page.mouse.move(box["x"] + 60 * sx, box["y"] + 34 * sy, steps=10)
    page.mouse.up()
    with page.expect_response(lambda r: r.url.endswith("/inpaint"), timeout=90_000) as answer:
        page.click("#fill")
    assert answer.value.status == 200
    page.wait_for_function("document.getElementById('result-caption').textContent === 'inpainted: 64x80, seed 6'",
                           timeout=60_000)
    assert page.eval_on_selector_all("#maps-view input", "l => l.map(i => i.value)") == ["albedo", "normal", "height"]
    page.locator("#maps-view label", has_text="normal").click()
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-inpainted-64x80-seed6_normal.png"
    assert not [e for e in page.errors if "status of 4" not in e], page.errors


def test_maps_added_while_a_fit_runs_fit_the_material(page, tmp_path):
    # Dropping the maps and adding them again at once: the first fit's answer came after the second's
    # was asked for and took its place (the page ended with the texture model, the maps listed).
    from tghop import data
    from tghop.imageio import to_uint16
    from tghop.material import example_maps

    (tmp_path / "normal.png").write_bytes(png(to_uint16(example_maps(data.builtin("bricks"))["normal"])))
    page.locator("label", has=page.locator("#mode-view")).click()
    if page.is_visible("#maps-clear"):
        page.click("#maps-clear")
    if not page.eval_on_selector("#fit-settings", "d => d.open"):
        page.click("#fit-settings summary")
    page.fill("#stride", "5")  # settings fitted nowhere yet: each fit takes a while
    page.select_option("#builtin", "")
    posted, answered, failed = chromium.posted_fits(page), [], []  # the fits asked for, the server's answers (jobs)

    def answer(response):
        if response.request.method == "POST" and response.url.endswith("/api/models"):
            answered.append(response)

    def fail(request):
        if request.method == "POST" and request.url.endswith("/api/models"):
            failed.append(request)

    page.on("response", answer)
    page.on("requestfailed", fail)
    page.select_option("#builtin", "bricks")  # a texture fit starts
    page.set_input_files("#maps", [str(tmp_path / "normal.png")])  # and at once the material's
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done'", timeout=90_000)
    page.wait_for_function("document.getElementById('summary').textContent.startsWith('material ')", timeout=30_000)
    # a replaced fit's answer and its end, had they come later, would show by now: each fit asked for answered and
    # its job ended (0.61 waited 1.5 s instead)
    for _ in range(3000):
        if len(answered) + len(failed) >= len(posted):
            break
        page.wait_for_timeout(20)
    assert len(posted) >= 1 and len(answered) + len(failed) >= len(posted), (posted, answered, failed)
    for job in (r.json()["job"] for r in answered):
        page.wait_for_function("async (job) => (await (await fetch(`/api/jobs/${job}`)).json()).state !== 'running'",
                               arg=job, polling=100, timeout=90_000)
    page.remove_listener("response", answer)
    page.remove_listener("requestfailed", fail)
    page.wait_for_timeout(200)
    assert page.text_content("#summary").startswith("material ")
    assert "maps: albedo, 8-bit; normal (normal), 16-bit" in page.text_content("#summary")


#: JavaScript (a function of [[base64 bytes, file name], ...]): drop the files on the drop area at once,
#: as a drag of several files from the desktop does; returns the message said (0.59: once the page has read the
#: files' sizes, a few milliseconds).
DROP_FILES_JS = """async (files) => {
  const transfer = new DataTransfer();
  for (const [data, name] of files) {
    const bytes = Uint8Array.from(atob(data), (c) => c.charCodeAt(0));
    transfer.items.add(new File([bytes], name, { type: name.endsWith('.png') ? 'image/png' : '' }));
  }
  const area = document.getElementById('drop');
  for (const type of ['dragover', 'drop']) {
    area.dispatchEvent(new DragEvent(type, { bubbles: true, cancelable: true, dataTransfer: transfer }));
  }
  const message = document.getElementById('message');
  for (let i = 0; i < 500 && !message.textContent.includes('files dropped'); i++) {
    await new Promise((done) => setTimeout(done, 20));
  }
  return message.textContent;
}"""


def test_several_files_dropped_at_once_are_a_material(page):
    import base64

    from tghop import data
    from tghop.imageio import to_uint8, to_uint16
    from tghop.material import example_maps

    chromium.load_fresh(page, FAST_FIT, clear_errors=False)
    albedo = data.bricks(96)
    maps = example_maps(albedo)
    files = {"rock_normal.png": png(to_uint16(maps["normal"])), "rock_color.png": png(to_uint8(albedo)),
             "rock_height.png": png(to_uint8(maps["height"][..., 0]))}
    dropped = [[base64.b64encode(b).decode(), name] for name, b in files.items()]
    # The file named like an albedo is the exemplar (not the first), the others its maps; the page says so
    said = page.evaluate(DROP_FILES_JS, dropped)
    assert said.startswith("3 files dropped: rock_color.png is the exemplar (the albedo), the others its maps "
                           "(rock_normal, rock_height)"), said
    assert page.text_content("#maps-list") == "maps: rock_normal, rock_height"
    wait_fitted(page)
    summary = page.text_content("#summary")
    assert summary.startswith("material ") and "exemplar 96x96" in summary, summary
    assert "maps: albedo, 8-bit; rock_normal (normal), 16-bit; rock_height, 8-bit" in summary
    assert page.eval_on_selector("#exemplar", "i => i.complete && i.naturalWidth") == 96
    # None named like an albedo: the first is the exemplar
    chromium.load_fresh(page, FAST_FIT, clear_errors=False)
    said = page.evaluate(DROP_FILES_JS, [[d, name.replace("_color", "_base")] for d, name in dropped[1:]])
    assert said.startswith("2 files dropped: rock_base.png is the exemplar (the albedo), the others its maps "
                           "(rock_height)"), said
    wait_fitted(page)
    assert "maps: albedo, 8-bit; rock_height, 8-bit" in page.text_content("#summary")
    # A model file among them: said, nothing used (the maps and the model stay)
    said = page.evaluate(DROP_FILES_JS, [dropped[1], [base64.b64encode(b"x").decode(), "saved.npz"]])
    assert said == "2 files dropped: drop the model file saved.npz on its own (nothing was used)"
    assert page.eval_on_selector("#message", "e => e.classList.contains('error')")
    assert page.text_content("#maps-list") == "maps: rock_height"
    assert page.is_hidden("#fit-status") is False and page.is_enabled("#go")
    assert not [e for e in page.errors if "status of 400" not in e], page.errors  # the test before's refusal


def test_the_quality_menu_and_generate_wait_for_the_models_kind(page, tmp_path):
    # The quality menu was offered from the fit's end until the summary said "material": a quick pick of
    # best gave a one-line 422. Summaries are held here to see the page in between.
    from tghop import data
    from tghop.imageio import to_uint16
    from tghop.material import example_maps

    chromium.load_fresh(page, FAST_FIT, clear_errors=False)
    held = []

    def hold(route):
        if route.request.method == "GET" and not route.request.url.endswith("/file"):
            held.append(route)  # a model's summary: answered when the test says
        else:
            route.continue_()

    (tmp_path / "normal.png").write_bytes(png(to_uint16(example_maps(data.builtin("bricks"))["normal"])))
    save_texture(tmp_path / "texture.npz")
    page.route("**/api/models/*", hold)
    try:
        page.set_input_files("#maps", [str(tmp_path / "normal.png")])
        page.select_option("#builtin", "bricks")  # a material fit: known to be one when it ends
        page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done'", timeout=90_000)
        deadline = time.monotonic() + 60
        while not held:  # the page asks for the summary as the fit ends; its route comes to Python a moment later
            assert time.monotonic() < deadline, "the page never asked for the model's summary"
            page.wait_for_timeout(20)
        assert page.is_hidden("#summary")
        # a material fitted here has its albedo's patch statistics unless fitted with patch_levels 0: quality and
        # Generate off until its summary says (0.60; 0.59 turned quality on at the fit's end, and best pressed then was
        # a 422 for a material without them)
        assert page.is_disabled("#quality") and page.is_disabled("#go") and page.is_disabled("#strip-go")
        assert page.text_content("#quality-off") == ("Off until the page knows whether this material's albedo has "
                                                     "patch statistics (its summary).")
        held.pop(0).continue_()
        page.wait_for_selector("#summary:not([hidden])")
        assert page.is_enabled("#quality") and page.is_enabled("#go")  # it has them
        page.click("#maps-clear")  # a texture fit: quality at once
        page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done'"
                               " && document.getElementById('summary').hidden", timeout=90_000)
        assert page.is_enabled("#quality") and page.is_enabled("#go")
        # An uploaded file: neither quality nor Generate until its summary says what it is
        page.set_input_files("#model-file", str(tmp_path / "texture.npz"))
        page.wait_for_function("document.getElementById('message').textContent"
                               " === 'model texture.npz loaded: generate below'", timeout=30_000)
        assert page.is_disabled("#quality") and page.is_disabled("#go") and page.is_disabled("#strip-go")
        for route in held:
            route.continue_()
        page.wait_for_selector("#summary:not([hidden])")
        assert page.is_enabled("#quality") and page.is_enabled("#go")
    finally:
        page.unroute("**/api/models/*")
    assert not [e for e in page.errors if "status of 4" not in e], page.errors


def test_a_material_fitted_without_patch_statistics_never_offers_quality_best(page, tmp_path):
    # A material fitted on the page with patch_levels 0 (no patch statistics of its albedo) had the quality menu on
    # from the fit's end until its summary came (0.59): best picked then was a 422.
    from tghop import data
    from tghop.imageio import to_uint16
    from tghop.material import example_maps

    chromium.load_fresh(page, FAST_FIT)
    page.select_option("#quality", "best")  # the artist's choice, kept: sent only where it applies
    page.evaluate("""() => {
      const plain = fitFields;  // the fit asked with patch_levels 0, which the page has no field for
      fitFields = () => { const form = plain(); form.append("patch_levels", "0"); return form; };
      window.qualityOn = [];  // the menu's every change, from now on
      new MutationObserver(() => qualityOn.push(!document.getElementById("quality").disabled))
        .observe(document.getElementById("quality"), { attributes: true, attributeFilter: ["disabled"] });
    }""")
    (tmp_path / "normal.png").write_bytes(png(to_uint16(example_maps(data.builtin("bricks"))["normal"])))
    page.set_input_files("#maps", [str(tmp_path / "normal.png")])
    page.select_option("#builtin", "bricks")
    wait_fitted(page)
    page.wait_for_function("document.getElementById('summary').textContent.startsWith('material ')")
    assert page.is_disabled("#quality") and page.text_content("#quality-off").startswith(
        "Off now: this material's albedo has no patch statistics")
    assert True not in page.evaluate("qualityOn"), page.evaluate("qualityOn")  # never on since the fit began
    page.fill("#height", "32")
    page.fill("#width", "32")
    page.click("#go")  # quality best left out, as it does not apply: no 422
    page.wait_for_function("document.getElementById('result-caption').textContent.startsWith('result: 32x32')",
                           timeout=90_000)
    assert page.text_content("#gen-message") == ""
    assert not page.errors, page.errors


def test_two_materials_morph_on_the_page_every_map(page, tmp_path):
    # Morph was off with a material as A or B (0.59), though tghop morph took two materials with the same maps: now
    # the page morphs them, every map of the strip shown and downloadable; a material with a texture model is said.
    chromium.load_fresh(page, FAST_FIT)
    save_material(tmp_path / "wall.npz")
    save_material(tmp_path / "plaster.npz", gamma=0.02)  # another model of the same maps
    for name in ("wall", "plaster"):
        page.set_input_files("#model-file", str(tmp_path / f"{name}.npz"))
        page.wait_for_function("(n) => document.getElementById('summary').textContent.startsWith('material ') &&"
                               " state.working && state.working.name === n", arg=f"{name}.npz")
    chromium.fit_builtin(page, "bricks")  # a texture model
    chromium.choose_mode(page, "morph")
    page.select_option("#morph-a", "0")
    page.select_option("#morph-b", "2")
    assert page.is_disabled("#morph-go")
    assert page.text_content("#morph-message").startswith("A, wall.npz (") and "a texture model: morph two " \
        "materials (with the same maps) or two texture models" in page.text_content("#morph-message")
    page.select_option("#morph-b", "1")
    assert page.is_enabled("#morph-go") and page.text_content("#morph-message") == ""
    page.fill("#morph-height", "32")
    page.fill("#morph-width", "96")
    page.click("#morph-go")
    page.wait_for_function("document.getElementById('result-caption').textContent.startsWith('morph: 32x96')",
                           timeout=90_000)
    assert page.text_content("#result-caption") == "morph: 32x96, seed 1 (wall to plaster)"
    shown = page.eval_on_selector_all("#maps-view input", "l => l.map((r) => r.value)")
    assert shown == ["albedo", "height"], shown
    assert page.is_visible("#download-maps")
    assert page.get_attribute("#download-png", "download") == "tghop-wall-to-plaster-morph-32x96-seed1.png"
    page.locator("#maps-view label", has_text="height").click()  # the height map's strip shown
    page.wait_for_function("document.getElementById('result-caption').textContent.startsWith('morph (height)')")
    entry = page.evaluate("recent.entries[0].maps.map((m) => m.name)")
    assert entry == ["albedo", "height"], entry  # kept whole in Recent results
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors
