"""An artist comparing results on ``tghop serve``'s page, with a mouse and eyes, in a real browser (Chromium
through Playwright) against a real uvicorn server (0.58): a small exemplar shown at a readable size, its pixels
square, and at its size at zoom 1:1; the last results kept side by side in a strip of their own, each with its
settings, brought back with a click (its settings into Generate's fields), downloadable, the strip bounded."""

import numpy as np
import pytest

import chromium
from conftest import FAST_FIT, png

chromium.require()


@pytest.fixture(scope="module")
def page(page):
    """conftest's page, the fast fit's settings in its fields."""
    chromium.set_fit_settings(page, FAST_FIT)
    return page


def shown_width(page, selector):
    """The picture's width on the page, in CSS pixels (its border left out), once it has loaded."""
    page.wait_for_function("(s) => { const i = document.querySelector(s); return i.complete && i.naturalWidth; }",
                           arg=selector, timeout=15_000)
    return page.eval_on_selector(selector, "i => i.clientWidth")


def test_a_small_exemplar_is_shown_at_a_readable_size(page, tmp_path):
    # A 64x64 exemplar was a 64-px thumbnail beside the 256x256 result: its texture could not be seen unless
    # zoom 1:1 was on (which enlarged nothing: it showed it at its size too).
    from tghop import data
    from tghop.imageio import to_uint8

    small = to_uint8(np.asarray(data.builtin("cells"))[:64, :80])
    (tmp_path / "small.png").write_bytes(png(small))
    chromium.fit_builtin(page, "bricks")
    assert shown_width(page, "#exemplar") == 256  # 256 px: at its size, as before
    assert page.text_content("#exemplar-caption") == "exemplar"
    assert page.eval_on_selector("#exemplar", "i => getComputedStyle(i).imageRendering") != "pixelated"
    page.set_input_files("#file", str(tmp_path / "small.png"))
    page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done' &&"
                           " state.working.name === 'small.png'", timeout=90_000)
    assert shown_width(page, "#exemplar") == 3 * 80  # the longer side 80: 3 times, a whole factor
    assert page.eval_on_selector("#exemplar", "i => i.clientHeight") == 3 * 64
    assert page.eval_on_selector("#exemplar", "i => getComputedStyle(i).imageRendering") == "pixelated"
    assert page.text_content("#exemplar-caption") == "exemplar (64x80, shown 3\u00d7 larger)"
    page.check("#zoom")  # 1:1: at its size, said so
    try:
        assert shown_width(page, "#exemplar") == 80
        assert page.text_content("#exemplar-caption") == "exemplar"
    finally:
        page.uncheck("#zoom")
    assert shown_width(page, "#exemplar") == 3 * 80
    page.set_viewport_size({"width": 200, "height": 800})  # narrower than it: within the page still
    try:
        assert shown_width(page, "#exemplar") < 3 * 80
        assert page.eval_on_selector("#exemplar", "i => i.getBoundingClientRect().right") <= 200
    finally:
        page.set_viewport_size({"width": 1200, "height": 1400})
    chromium.fit_builtin(page, "bricks")
    assert shown_width(page, "#exemplar") == 256 and page.text_content("#exemplar-caption") == "exemplar"
    assert not page.errors, page.errors


def generate(page, seed, size=(32, 40), tile=False, refine="", pool=""):
    """Generate a result of ``seed`` at ``size`` and wait for it; ``pool``: the patch pool's field (a small one makes
    quick images; '' the default's 5,000 patches, as a user gets them)."""
    page.fill("#height", str(size[0]))
    page.fill("#width", str(size[1]))
    page.fill("#seed", str(seed))
    page.fill("#refine", refine)
    page.fill("#n_patches", pool)
    page.set_checked("#tile", tile)
    page.click("#go")
    page.wait_for_function("(c) => document.getElementById('result-caption').textContent === c &&"
                           " document.getElementById('go').textContent === 'Generate'",
                           arg=f"result: {size[0]}x{size[1]}, seed {seed}", timeout=90_000)


def recent(page):
    """The recent results' captions, the newest first, and the index of the one marked as shown."""
    captions = page.eval_on_selector_all("#history figcaption", "l => l.map(c => c.textContent)")
    pressed = page.eval_on_selector_all("#history button", "l => l.map(b => b.getAttribute('aria-pressed'))")
    return captions, [i for i, p in enumerate(pressed) if p == "true"]


def test_the_last_results_are_kept_side_by_side_and_brought_back(page):
    # Each Generate replaced the result: an artist trying settings could not compare the last few, and a seed
    # liked was gone once another was made (the 8-seed strip was the only side by side).
    chromium.choose_mode(page, "view")
    chromium.load_empty(page)
    chromium.set_fit_settings(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    assert page.is_hidden("#history-box")
    generate(page, 1)
    generate(page, 2, tile=True)
    generate(page, 3, refine="2")
    captions, shown = recent(page)
    assert captions == ["result 32x40, seed 3, 2 refinement rounds (bricks)", "result 32x40, seed 2, tileable (bricks)",
                        "result 32x40, seed 1 (bricks)"] and shown == [0], captions
    page.wait_for_function("document.querySelectorAll('#history canvas').length === 3")  # thumbnails, drawn once
    assert page.eval_on_selector_all("#history canvas", "l => l.map(c => [c.width, c.height])") == [[40, 32]] * 3
    # Brought back: the result, its tiling, its download, and its settings in Generate's fields.
    page.click("#history figure[data-index='1'] button")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 32x40, seed 2'")
    assert recent(page) == (captions, [1])
    assert page.input_value("#seed") == "2" and page.is_checked("#tile") and page.input_value("#refine") == ""
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-32x40-seed2-tile.png"
    assert "seed 2 shown again" in page.text_content("#gen-message")
    # Each downloadable as it is: the PNG the server made.
    link = "#history figure[data-index='2'] a"
    assert page.get_attribute(link, "download") == "tghop-bricks-32x40-seed1.png"
    with page.expect_download() as download:
        page.click(link)
    assert download.value.suggested_filename == "tghop-bricks-32x40-seed1.png"
    from PIL import Image

    assert Image.open(download.value.path()).size == (40, 32)
    # A seed picked from the strip is kept; another pick from the same strip takes its place.
    page.fill("#seed", "11")
    page.fill("#n_patches", "300")  # the strip's and the rest's images quick (the first three at the default pool)
    page.click("#strip-go")
    page.wait_for_function("document.getElementById('strip-go').textContent === '8 seeds' &&"
                           " document.querySelectorAll('#strip img').length === 8", timeout=120_000)
    page.click("#strip img[data-seed='12']")
    page.click("#strip img[data-seed='15']")
    captions, shown = recent(page)
    assert captions[:2] == ["result 32x40, seed 15, tileable, patch pool 300 (bricks)", captions[1]] and len(
        captions) == 4, captions
    assert captions[1].startswith("result 32x40, seed 3") and shown == [0]
    # Bounded: the last 12 (4 above and 9 more: the oldest, seed 1's, dropped).
    for seed in range(20, 29):
        generate(page, seed, pool="300")
    captions, shown = recent(page)
    assert len(captions) == 12 and captions[0] == "result 32x40, seed 28, patch pool 300 (bricks)" and shown == [0], (
        captions)
    assert captions[-1] == "result 32x40, seed 2, tileable (bricks)"
    assert not page.errors, page.errors


def test_the_recent_results_outlive_a_reload_and_a_materials_downloads_every_map(page, tmp_path):
    # The recent results were the page's only: a reload (or the browser closed) forgot them all; and a material's
    # entry downloaded its albedo alone, its maps lost unless it was shown again for "Download all maps".
    import zipfile

    from tghop import data
    from tghop.imageio import to_uint8
    from tghop.material import example_maps

    height = tmp_path / "bricks_height.png"
    height.write_bytes(png(to_uint8(example_maps(data.builtin("bricks"))["height"][..., 0])))
    chromium.load_empty(page)
    assert page.is_hidden("#history-box")
    chromium.set_fit_settings(page, FAST_FIT)
    chromium.fit_builtin(page, "bricks")
    generate(page, 4, tile=True)
    page.set_input_files("#maps", str(height))  # bricks again, a material
    page.wait_for_function("document.getElementById('summary').textContent.startsWith('material ')", timeout=90_000)
    generate(page, 5)
    before, _ = recent(page)
    assert before == ["result 32x40, seed 5 (bricks)", "result 32x40, seed 4, tileable (bricks)"], before
    page.wait_for_function("recent.entries.every((e) => e.key !== null)")  # stored (a few milliseconds)
    page.reload()
    page.wait_for_selector("body[data-ready='1']")
    page.wait_for_function("document.querySelectorAll('#history canvas').length === 2", timeout=60_000)
    assert recent(page) == (before, [0])  # the result shown before the reload shown again (0.60; 0.59: none)
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 32x40, seed 5'")
    # A material's entry: every map, one ZIP
    link = "#history figure[data-index='0'] a"
    assert page.get_attribute(link, "download") == "tghop-bricks-32x40-seed5.zip"
    with page.expect_download() as download:
        page.click(link)
    assert download.value.suggested_filename == "tghop-bricks-32x40-seed5.zip"
    download.value.save_as(tmp_path / "maps.zip")
    with zipfile.ZipFile(tmp_path / "maps.zip") as archive:
        assert archive.testzip() is None
        assert archive.namelist() == ["tghop-bricks-32x40-seed5.png", "tghop-bricks-32x40-seed5_height.png"]
    # Shown again from the store, with its settings
    page.click("#history figure[data-index='1'] button")  # the texture model's, beside the material (0.59: said)
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 32x40, seed 4"
                           " (made with builtin:bricks, not builtin:bricks + 1 maps)'")
    assert page.input_value("#seed") == "4" and page.is_checked("#tile")
    assert page.get_attribute("#download-png", "download") == "tghop-bricks-32x40-seed4-tile.png"
    page.click("#history figure[data-index='0'] button")
    page.wait_for_function("document.getElementById('result-caption').textContent === 'result: 32x40, seed 5'")
    assert page.eval_on_selector_all("#maps-view input", "l => l.map(i => i.value)") == ["albedo", "bricks_height"]
    # Forgotten on asking, across a reload too
    page.click("#history-forget")
    assert page.is_hidden("#history-box")
    assert page.evaluate("storeDo('readonly', (store) => store.count())") == 0
    page.reload()
    page.wait_for_selector("body[data-ready='1']")
    assert page.is_hidden("#history-box")
    assert not page.errors, page.errors
