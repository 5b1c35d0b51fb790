"""An artist comparing results on ``tghop serve``'s page, with a mouse and eyes, in a real browser (Chromium
through Playwright) against a real uvicorn server (0.58): a small exemplar shown at a readable size, its pixels
square, and at its size at zoom 1:1; the last results kept side by side in a strip of their own, each with its
settings, brought back with a click (its settings into Generate's fields), downloadable, the strip bounded."""

import numpy as np
import pytest

import chromium

if chromium.missing():
    pytest.skip(chromium.missing(), allow_module_level=True)
sync_api = pytest.importorskip("playwright.sync_api",
                               reason="Playwright is not installed: pip install -e '.[web-test]'")

from conftest import FAST_FIT, png  # noqa: E402


@pytest.fixture(scope="module")
def page(live_server):
    with chromium.served_page(live_server.url + "/") as page:
        chromium.set_fit_settings(page, FAST_FIT)
        yield page


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
