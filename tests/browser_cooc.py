"""The page's Co-occurrence mode, step by step, for both browser tests (Chromium through
Playwright in ``test_server_browser.py``, Firefox through Marionette in
``test_server_firefox.py``): one scenario, written against the few calls of
:class:`marionette.Firefox` that ``test_server_browser.PlaywrightDriver`` also offers
(``run``, ``wait_for``, ``fill``, ``click``, ``send_keys``, ``drag``).

The checkpoint is ``conftest.tiny_cooc_checkpoint``: a 64x64 exemplar, 32 px crops, s = 8,
3 colour clusters.
"""

import os

#: JavaScript (a function body; arguments: a canvas's selector, x0, x1): the distinct
#: colours ``"r,g,b"`` of the canvas's columns x0 to x1 - 1, over its whole height.
COLUMN_COLOURS_JS = """const c = document.querySelector(arguments[0]);
const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data, seen = new Set();
for (let y = 0; y < c.height; y++) for (let x = arguments[1]; x < arguments[2]; x++) {
  const k = 4 * (y * c.width + x); seen.add(`${d[k]},${d[k + 1]},${d[k + 2]}`);
}
return [...seen];"""

#: The brush colours of crops 1 and 2 (board.js's PALETTE).
FIRST, SECOND = "230,25,75", "60,180,75"


def result_size(d):
    return d.run("const i = document.getElementById('result'); return [i.naturalHeight, i.naturalWidth]")


def wait_result(d, caption, old_src=""):
    """Wait until the result is shown with ``caption`` (and a new picture when ``old_src``)."""
    d.wait_for(f"(() => {{ const i = document.getElementById('result');"
               f" return !i.hidden && i.complete && i.naturalWidth > 0 && i.src !== {old_src!r} &&"
               f" document.getElementById('result-caption').textContent === {caption!r}; }})()", timeout=60)


def assert_progress_was_followed(d):
    """The last morph or edit named a job (the bar's ``data-job``) whose stages the server reported, and
    the bar went with its answer."""
    import json

    job = d.run("return document.getElementById('cooc-progress').dataset.job || ''")
    assert len(job) == 32 and d.run("return document.getElementById('cooc-progress').hidden") is True, job
    snap = json.loads(d.run("const r = new XMLHttpRequest(); r.open('GET', '/api/jobs/' + arguments[0], false);"
                            " r.send(); return r.responseText;", job))
    assert snap["state"] == "done" and snap["stages"] == ["generating", "encoding"], snap


def cooc_steps(d, checkpoint):
    """Load ``checkpoint``, place crop 1 top left and crop 2 bottom right by clicking on the
    exemplar, morph from 1 to 2, paint the right half of a 40x64 edit with crop 2 and
    generate, then with a boost of clusters 0 and 1, and a bad boost (the server's line)."""
    d.click("label:has(#mode-cooc)")
    assert d.run("return [document.getElementById('cooc').hidden, document.getElementById('cooc-work').hidden]") \
        == [False, True]
    d.send_keys("#cooc-file", str(checkpoint))
    d.wait_for("document.getElementById('cooc-exemplar').dataset.ready === '1'", timeout=30)
    assert d.run("const c = document.getElementById('cooc-exemplar'); return [c.height, c.width]") == [64, 64]
    assert "exemplar 64x64, 32 px crops" in d.run("return document.getElementById('cooc-summary').textContent")
    assert d.run("return !document.getElementById('cooc-picture-button').hidden")  # not a built-in exemplar
    stem = os.path.splitext(os.path.basename(str(checkpoint)))[0]  # tiny.pt: tiny
    link = d.run("const a = document.getElementById('cooc-download');"
                 "return [a.hidden, a.getAttribute('href'), a.getAttribute('download')]")
    assert link[0] is False and link[1].startswith("/api/cooc/") and link[1].endswith(f"/file?name={stem}")
    assert link[2] == f"tghop-cooc-{stem}-{link[1].split('/')[3][:12]}.pt"  # as the server names it
    assert d.run("return document.getElementById('cooc-boost-a').max") == "2"  # 3 colour clusters
    scale = d.run("const c = document.getElementById('cooc-exemplar');"
                  " return c.getBoundingClientRect().width / c.width")
    for x, y in ((16, 16), (50, 50)):  # a click: crop 1 centred top left, then crop 2 (the next slot) bottom right
        d.drag("#cooc-exemplar", [(x * scale, y * scale)])
    crops = d.run("return document.getElementById('cooc-crops').textContent")
    assert "crop 1 (0, 0)" in crops and "crop 2 (32, 32)" in crops, crops
    d.fill("#cooc-length", "6")
    d.fill("#cooc-morph-seed", "3")
    d.click("#cooc-morph-go")
    wait_result(d, "cooc-morph: 32x48, seed 3")
    assert result_size(d) == [32, 48]
    assert_progress_was_followed(d)
    d.fill("#cooc-height", "40")
    d.fill("#cooc-width", "64")
    assert d.run("const c = document.getElementById('cooc-guide'); return [c.height, c.width]") == [40, 64]
    d.click("label:has(#cooc-crop-1)")  # paint with crop 2 on the right
    assert d.run("return document.getElementById('cooc-crop-1').checked") is True
    d.fill("#cooc-brush", "24")
    scale = d.run("const c = document.getElementById('cooc-guide'); return c.getBoundingClientRect().width / c.width")
    for x in (44, 56):  # two strokes top to bottom, inside the canvas; the brush covers the edges
        d.drag("#cooc-guide", [(x * scale, y * scale) for y in range(1, 39, 6)] + [(x * scale, 38 * scale)])
    assert d.run(COLUMN_COLOURS_JS, "#cooc-guide", 0, 30) == [FIRST]
    assert d.run(COLUMN_COLOURS_JS, "#cooc-guide", 34, 64) == [SECOND]
    d.fill("#cooc-edit-seed", "2")
    d.click("#cooc-edit-go")
    wait_result(d, "cooc-edit: 40x64, seed 2")
    assert result_size(d) == [40, 64]
    assert_progress_was_followed(d)
    plain = d.run("return document.getElementById('result').src")
    for name, value in (("a", "0"), ("b", "1"), ("factor", "4")):
        d.fill(f"#cooc-boost-{name}", value)
    d.click("#cooc-edit-go")
    wait_result(d, "cooc-edit: 40x64, seed 2", old_src=plain)
    assert result_size(d) == [40, 64]
    d.fill("#cooc-boost-factor", "-1")
    d.click("#cooc-edit-go")
    message = d.wait_for("document.getElementById('cooc-message').classList.contains('error') &&"
                         " document.getElementById('cooc-message').textContent", timeout=30)
    assert "boost must be [a, b, factor]" in message, message
    d.fill("#cooc-boost-factor", "1")
