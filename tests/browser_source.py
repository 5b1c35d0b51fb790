"""The page's ways to a model besides picking a file, step by step, for both browser tests
(Chromium through Playwright in ``test_server_browser.py``, Firefox through Marionette in
``test_server_firefox.py``), written against the calls both drivers offer (``run``,
``wait_for``, ``fill``, ``click``, ``send_keys``): drop an image on the drop area, cancel a
running fit with the Cancel button (back to the dropped image's model), and upload a saved ``.npz``
model, then generate."""

import base64

from conftest import FAST_FIT

#: JavaScript (a function body; arguments: base64 bytes, file name, MIME type): drop the
#: file on the drop area as a drag from the desktop does (dragover, then drop, with a
#: DataTransfer holding it); returns whether the drop area was highlighted during the drag.
DROP_JS = """const bytes = Uint8Array.from(atob(arguments[0]), (c) => c.charCodeAt(0));
const transfer = new DataTransfer();
transfer.items.add(new File([bytes], arguments[1], { type: arguments[2] }));
const area = document.getElementById('drop');
const event = (type) => new DragEvent(type, { bubbles: true, cancelable: true, dataTransfer: transfer });
area.dispatchEvent(event('dragover'));
const over = area.classList.contains('over');
area.dispatchEvent(event('drop'));
return [over, area.classList.contains('over')];"""

#: The fit's end, once it has one: 'done', 'failed' or 'cancelled'.
FIT_END = ("['done', 'failed', 'cancelled'].includes(document.getElementById('fit-status').dataset.state)"
           " && document.getElementById('fit-status').dataset.state")


def text(d, selector):
    return d.run(f"return document.querySelector({selector!r}).textContent")


def fit_settings(d, fields):
    """Layout off and ``fields`` (name: value; '' for the default) in the fit settings."""
    d.run("document.getElementById('layout').checked = false;")
    for name in ("scale", "n_clusters", "n_codewords", "stride", "max_patches"):
        d.fill(f"#{name}", fields.get(name, ""))


def drop_steps(d, png, name="dropped bricks.png"):
    """Drop ``png`` (bytes of a 64x64 image) on the drop area: it is fitted (fast settings, at
    the working scale 1.5) and shown as the exemplar, and the model's summary says 96x96."""
    fit_settings(d, {**FAST_FIT, "scale": "1.5"})
    over, after = d.run(DROP_JS, base64.b64encode(png).decode(), name, "image/png")
    assert over is True and after is False  # highlighted while dragged over, not after the drop
    assert d.wait_for(FIT_END, timeout=120) == "done", text(d, "#message")
    d.wait_for("!document.getElementById('summary').hidden")
    assert "exemplar 96x96 (resampled by 1.5), 3 channels" in text(d, "#summary")
    assert d.run("const i = document.getElementById('exemplar'); return [i.complete, i.naturalWidth]") == [True, 64]
    assert name in text(d, "#morph-a")  # the session's models are named by the file
    assert d.run("return document.getElementById('go').disabled") is False


def cancel_steps(d, working="dropped bricks.png"):
    """Pick builtin:cells with the default fit (seconds), click Cancel once it runs: the job
    ends cancelled on the server, and the page goes back to the ``working`` model (that of
    :func:`drop_steps`): the message says so, its exemplar, its summary (not the cancelled
    pick's) and Generate are back."""
    summary = text(d, "#summary")
    fit_settings(d, {})
    d.run("const s = document.getElementById('builtin'); s.value = 'cells';"
          "s.dispatchEvent(new Event('change', {bubbles: true}));")
    d.wait_for("document.getElementById('stage').textContent.endsWith('%')", timeout=60)  # running
    assert d.run("return document.getElementById('go').disabled") is True
    assert d.run("return document.getElementById('summary').hidden") is True  # the model it replaces: not shown
    d.click("#cancel")
    assert d.wait_for(FIT_END, timeout=60) == "cancelled", text(d, "#message")
    d.wait_for("!document.getElementById('summary').hidden")
    assert text(d, "#message") == f"fit cancelled (builtin:cells was not used; the model of {working} stays)"
    assert d.run("return document.getElementById('message').classList.contains('error')") is False
    assert text(d, "#summary") == summary  # the working model's, as before the pick
    assert d.run("const i = document.getElementById('exemplar'); return [i.hidden, i.naturalWidth]") == [False, 64]
    assert d.run("return document.getElementById('cancel').disabled") is True
    assert d.run("return document.getElementById('go').disabled") is False
    assert d.run("return document.getElementById('builtin').value") == ""  # cells again fits it again
    # the page's job, as the server has it
    snap = d.run("return fetch(`/api/jobs/${document.getElementById('fit-status').dataset.job}`)"
                 ".then((r) => r.json());")
    assert snap["state"] == "cancelled" and snap["progress"] < 1


def upload_steps(d, npz, exemplar_size):
    """Load the saved model ``npz`` (a path) with "Continue from a saved model", then
    generate a 48x64 image from it."""
    d.send_keys("#model-file", str(npz))
    name = npz.name
    d.wait_for(f"document.getElementById('message').textContent === 'model {name} loaded: generate below'",
               timeout=60)
    d.wait_for("!document.getElementById('summary').hidden")
    h, w = exemplar_size
    assert f"exemplar {h}x{w}, 3 channels" in text(d, "#summary")
    assert d.run("return document.getElementById('exemplar').hidden") is True  # a model has no exemplar to show
    # Named for the file ("saved bricks.npz": saved-bricks), as the server's Content-Disposition names it
    href, download = d.run("const a = document.getElementById('download-model');"
                           " return [a.getAttribute('href'), a.getAttribute('download')]")
    stem = "-".join(npz.stem.split())
    assert href.endswith(f"/file?name={stem}") and download == f"tghop-{stem}-{href.split('/')[3][:12]}.npz"
    d.fill("#height", "48")
    d.fill("#width", "64")
    d.fill("#seed", "9")
    d.fill("#n_patches", "300")
    d.click("#go")
    d.wait_for("(() => { const i = document.getElementById('result');"
               " return !i.hidden && i.complete && i.naturalWidth > 0 &&"
               " document.getElementById('result-caption').textContent === 'result: 48x64, seed 9'; })()", timeout=60)
    assert d.run("const i = document.getElementById('result'); return [i.naturalHeight, i.naturalWidth]") == [48, 64]
