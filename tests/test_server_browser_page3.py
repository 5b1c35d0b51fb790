"""An artist's walk through ``tghop serve``'s page at 1024x700 and 400x800, in a real browser (Chromium through
Playwright) against a real uvicorn server (0.63): the last long helps (the maps', quality's, Co-occurrence's exemplar
and edit) cut to two lines and a *more* in a narrow window as the modes' are; Extend's "grow to" fields following the
picture shown after an Undo; a strip of fills that fails partway saying the server's warnings of the fills that came,
and a server gone said with its fix."""

import contextlib
import io

import numpy as np
import pytest

import chromium
from conftest import FAST_FIT, LiveServer, png

chromium.require()


@contextlib.contextmanager
def window(page, width, height):
    """The page in a window of ``width`` x ``height``, scrolled to its top; back to the tests' 1200x1400 after."""
    page.set_viewport_size({"width": width, "height": height})
    try:
        page.evaluate("window.scrollTo(0, 0)")
        yield
    finally:
        page.set_viewport_size({"width": 1200, "height": 1400})


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
    with window(page, 400, 800):
        for help in helps:
            assert lines(page, help) == 2, help
            button = page.evaluate_handle(more, help).as_element()
            assert button is not None and button.is_visible() and button.text_content() == "more", help
            button.click()
            assert lines(page, help) > 2 and button.text_content() == "less", help
            button.click()
            assert lines(page, help) == 2, help
    with window(page, 1024, 700):
        for help in helps:
            assert lines(page, help) >= 2 and not page.evaluate_handle(more, help).as_element().is_visible(), help
    # Why quality is off is a paragraph of its own after the help, never cut with it
    assert page.evaluate("!document.getElementById('quality-off').closest('.help.long')")
    chromium.choose_mode(page, "view")
    assert not page.errors, page.errors
