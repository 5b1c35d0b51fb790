"""What the web server tells of an upload that the command line warns of: a colour profile converted to
sRGB, only the first frame of several read, a 16-bit exemplar whose images here are 8-bit. Its read warnings
were collected and dropped (only a transparent part reached a fit's notes); now a fit's and a model upload's
``notes``, and a guide's ``X-Tghop-Warning``, in the page's words (no command-line option named)."""

import base64
import io
import json

import numpy as np
import pytest

httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

from conftest import FAST_FIT  # noqa: E402
from test_profiles import P3, matrix_profile  # noqa: E402

from tghop import data  # noqa: E402
from tghop.imageio import to_uint8, to_uint16, write_png  # noqa: E402


@pytest.fixture(scope="module")
def client(live_server):
    with httpx.Client(base_url=live_server.url, timeout=120) as c:
        yield c


def bricks8():
    return to_uint8(data.bricks(96, rng=3))


def png(array, **save):
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(array).save(buf, format="PNG", **save)
    return buf.getvalue()


def fit(client, name, content, **fields):
    r = client.post("/api/models", files={"image": (name, content), **{k: (None, v) for k, v in
                                                                         {**FAST_FIT, **fields}.items()}})
    assert r.status_code in (200, 202), r.text
    return r.json()


def done(client, job):
    """Wait for the job's end (its state polled)."""
    import time

    for _ in range(1200):
        state = client.get(f"/api/jobs/{job}").json()["state"]
        if state not in ("queued", "running"):
            return state
        time.sleep(0.1)
    raise AssertionError("the fit did not end")


def test_a_fits_notes_tell_what_reading_the_upload_said(client):
    from PIL import Image

    p3 = fit(client, "photo p3.png", png(bricks8(), icc_profile=P3))
    assert len(p3["notes"]) == 1  # its reds partly outside sRGB: how many were clipped follows (0.57)
    assert p3["notes"][0].startswith("photo_p3.png: colours converted to sRGB from its colour profile 'Test P3'")
    frames = [Image.fromarray(bricks8()), Image.fromarray(bricks8()[::-1].copy())]
    buf = io.BytesIO()
    frames[0].save(buf, format="GIF", save_all=True, append_images=frames[1:], duration=100, loop=0)
    gif = fit(client, "anim.gif", buf.getvalue())
    assert gif["notes"] == ["anim.gif: 2 frames (or pages); only the first is read"]
    plain = fit(client, "plain.png", png(bricks8()))
    assert plain["notes"] == []
    for job in (p3, gif, plain):
        assert done(client, job["job"]) == "done"


def test_a_16bit_exemplar_and_its_model_say_the_images_here_are_8bit(client, tmp_path):
    # As `tghop synth exemplar16.png` warns, and now `tghop synth model.npz` of it: the model records the depth.
    buf = io.BytesIO()
    write_png(buf, to_uint16(data.bricks(96, rng=3)))
    deep = fit(client, "deep.png", buf.getvalue())
    said = "deep.png has more than 8 bits a channel, but the images made here have 8"
    assert deep["notes"] == [said] and not [n for n in deep["notes"] if "--" in n]
    assert done(client, deep["job"]) == "done"
    assert client.get(f"/api/models/{deep['id']}").json()["exemplar_depth"] == 16
    again = fit(client, "deep.png", buf.getvalue())  # the model is there: the same notes
    assert again["state"] == "done" and again["notes"] == [said]
    flat = fit(client, "flat.png", png(bricks8()))
    assert done(client, flat["job"]) == "done"
    assert client.get(f"/api/models/{flat['id']}").json()["exemplar_depth"] == 8
    # Its model file downloaded and uploaded again (the page's "open model"): the upload's notes say it too.
    from tghop.modelfile import load_model

    content = client.get(f"/api/models/{deep['id']}/file").content
    (tmp_path / "m.npz").write_bytes(content)
    assert load_model(tmp_path / "m.npz").exemplar_depth_ == 16
    up = client.post("/api/models/upload", files={"model": ("wall16.npz", content)})
    assert up.status_code == 200 and up.json() == {
        "id": up.json()["id"],
        "notes": ["wall16.npz was fitted on an exemplar of more than 8 bits a channel, but the images made here "
                  "have 8"]}
    whole = client.post("/api/models/upload", content=content, headers={"content-type": "application/octet-stream"})
    assert whole.json()["notes"] == ["the upload was fitted on an exemplar of more than 8 bits a channel, but the "
                                     "images made here have 8"]
    plain = client.post("/api/models/upload", files={"model": ("flat.npz", client.get(
        f"/api/models/{flat['id']}/file").content)})
    assert plain.status_code == 200 and plain.json()["notes"] == []
    # A file without the depth (tghop 0.55 and older) says nothing.
    arrays = dict(np.load(tmp_path / "m.npz"))
    meta = json.loads(str(arrays["__meta__"]))
    del meta["exemplar_depth"]
    arrays["__meta__"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "old.npz", **arrays)
    old = client.post("/api/models/upload", files={"model": ("old.npz", (tmp_path / "old.npz").read_bytes())})
    assert old.status_code == 200 and old.json()["notes"] == []


def test_a_guides_read_warnings_are_in_the_answers_header(client):
    a, b = (fit(client, f"{n}.png", png(to_uint8(image))) for n, image in
            (("bricks", data.bricks(96, rng=3)), ("cells", data.cells(96, rng=4))))
    assert done(client, a["job"]) == done(client, b["job"]) == "done"
    guide = np.zeros((32, 48, 3), np.uint8)
    guide[:, 24:] = 255  # black and white: the same in P3 as in sRGB
    ask = {"models": [a["id"], b["id"]], "seed": 3, "n_patches": 400}
    plain = client.post("/api/images/guided", json={**ask, "guide": base64.b64encode(png(guide)).decode()})
    assert plain.status_code == 200 and "x-tghop-warning" not in plain.headers, plain.text
    told = client.post("/api/images/guided", json={
        **ask, "guide": base64.b64encode(png(guide, icc_profile=P3)).decode()})
    assert told.status_code == 200 and told.content == plain.content, told.text
    assert told.headers["x-tghop-warning"] == "guide.png: colours converted to sRGB from its colour profile 'Test P3'"
    # A profile's name is the file's: any character, any length; the header is one line of printable ASCII.
    odd = matrix_profile("Ecran\tlarge " + "x" * 400, (0.5151, 0.2412, -0.0011), (0.2920, 0.6922, 0.0419),
                         (0.1571, 0.0666, 0.7841))
    r = client.post("/api/images/guided", json={**ask, "guide": base64.b64encode(png(guide, icc_profile=odd)).decode()})
    assert r.status_code == 200 and r.content == plain.content, r.text
    header = r.headers["x-tghop-warning"]
    assert header.startswith("guide.png: colours converted to sRGB from its colour profile '")
    assert header.endswith("...") and len(header) <= 300 and all(" " <= c <= "~" for c in header)


def test_a_warning_header_is_printable_ascii():
    from tghop.server.routes.images import header_text

    assert header_text(["écran: colours converted", "b\u2014c"]) == "?cran: colours converted; b?c"


def gif(*frames):
    """An animated GIF of ``frames`` (uint8 arrays)."""
    from PIL import Image

    buf = io.BytesIO()
    first, *rest = [Image.fromarray(f) for f in frames]
    first.save(buf, format="GIF", save_all=True, append_images=rest, duration=100, loop=0)
    return buf.getvalue()


def test_inpaints_and_extends_read_warnings_are_in_the_answers_header(client):
    # They were dropped: a picture with a colour profile converted, a mask of several frames, said nowhere.
    model = fit(client, "bricks.png", png(bricks8()))
    assert done(client, model["job"]) == "done"
    picture = to_uint8(data.bricks(64, rng=5))[:, :60].copy()
    hole = np.zeros((64, 60), np.uint8)
    hole[20:44, 20:40] = 255
    inpaint, extend = f"/api/models/{model['id']}/inpaint", f"/api/models/{model['id']}/extend"
    ask = {"image": ("picture.png", png(picture)), "mask": ("mask.png", png(hole)), "seed": (None, "3")}
    plain = client.post(inpaint, files=ask)
    assert plain.status_code == 200 and "x-tghop-warning" not in plain.headers, plain.text
    told = client.post(inpaint, files={**ask, "image": ("photo p3.png", png(picture, icc_profile=P3)),
                                       "mask": ("mask.gif", gif(hole, 255 - hole))})
    assert told.status_code == 200, told.text
    assert told.headers["x-tghop-warning"] == ("photo_p3.png: colours converted to sRGB from its colour profile "
                                               "'Test P3'; mask.gif: 2 frames (or pages); only the first is read")
    # A mask's transparent part is said as tghop inpaint says it (an exemplar's words would be wrong here)
    see_through = np.dstack([hole, hole, hole, np.where(np.arange(60) < 5, 0, 255).astype(np.uint8)[None, :]
                             .repeat(64, axis=0)])
    clear = client.post(inpaint, files={**ask, "mask": ("clear.png", png(see_through))})
    assert clear.status_code == 200 and clear.content == plain.content, clear.text
    assert clear.headers["x-tghop-warning"] == ("clear.png has transparent pixels, but transparency is not read as "
                                                "the hole (its white pixels are the hole); paint the hole white on "
                                                "black")
    grow = {"image": ("picture.png", png(picture)), "size": (None, "64x120"), "seed": (None, "3")}
    plain = client.post(extend, files=grow)
    assert plain.status_code == 200 and "x-tghop-warning" not in plain.headers, plain.text
    frames = client.post(extend, files={**grow, "image": ("anim.gif", gif(picture, picture[::-1].copy()))})
    assert frames.status_code == 200, frames.text
    assert frames.headers["x-tghop-warning"] == "anim.gif: 2 frames (or pages); only the first is read"
    # A profile's name is the file's: the header is still one line of printable ASCII, each note capped.
    odd = matrix_profile("Ecran\tlarge " + "x" * 400, (0.5151, 0.2412, -0.0011), (0.2920, 0.6922, 0.0419),
                         (0.1571, 0.0666, 0.7841))
    r = client.post(extend, files={**grow, "image": ("odd.png", png(picture, icc_profile=odd))})
    assert r.status_code == 200, r.text
    header = r.headers["x-tghop-warning"]
    assert header.startswith("odd.png: colours converted to sRGB from its colour profile '")
    assert header.endswith("...") and len(header) <= 300 and all(" " <= c <= "~" for c in header)


def soft_guide(h=48, w=64):
    """A guide of two flat levels (40 and 200, a diagonal edge) drawn 4 times larger and downscaled: antialiased
    edges, many blends of the two levels between them."""
    from PIL import Image

    yy, xx = np.mgrid[: 4 * h, : 4 * w]
    big = np.where(xx + yy // 2 < 2 * w, 40, 200).astype(np.uint8)
    big[20:80, 150:230] = 40  # a block of the dark level inside the light
    return np.asarray(Image.fromarray(big).resize((w, h), Image.BOX))


def test_a_guide_with_soft_edges_is_read_as_the_guided_route_reads_it(client):
    # The page's "Use a guide..." refused one (its blends: more colours than models); the server reads it.
    from tghop.guides import guide_labels

    soft = soft_guide()
    assert len(np.unique(soft)) > 2  # soft edges: more grey levels than models
    r = client.post("/api/guides/labels", json={"guide": base64.b64encode(png(soft)).decode(), "n_models": 2,
                                                "size": [48, 64]})
    assert r.status_code == 200, r.text
    answer = r.json()
    assert answer["size"] == [48, 64] and answer["notes"] == []
    labels = np.frombuffer(base64.b64decode(answer["labels"]), np.uint8).reshape(48, 64)
    assert (labels == guide_labels(soft, 2)).all() and set(np.unique(labels)) == {0, 1}
    # The same regions a generation through it is given: the guided route's answer is the labels' as a flat guide.
    a, b = (fit(client, f"{n}.png", png(to_uint8(image))) for n, image in
            (("bricks", data.bricks(96, rng=3)), ("cells", data.cells(96, rng=4))))
    assert done(client, a["job"]) == done(client, b["job"]) == "done"
    ask = {"models": [a["id"], b["id"]], "seed": 3, "n_patches": 400}
    by_soft = client.post("/api/images/guided", json={**ask, "guide": base64.b64encode(png(soft)).decode()})
    flat = client.post("/api/images/guided", json={**ask, "guide": base64.b64encode(png(labels * 255)).decode()})
    assert by_soft.status_code == flat.status_code == 200 and by_soft.content == flat.content
    # A data: URL (the page's FileReader), a P3 profile said, a guide of the shape scaled (and said), as guided.
    url = "data:image/png;base64," + base64.b64encode(png(np.dstack([soft] * 3), icc_profile=P3)).decode()
    told = client.post("/api/guides/labels", json={"guide": url, "n_models": 2, "size": [96, 128]})
    assert told.status_code == 200, told.text
    assert told.json()["size"] == [96, 128] and told.json()["notes"] == [
        "guide.png: colours converted to sRGB from its colour profile 'Test P3'",
        "the guide was scaled from 48x64 to 96x128, the output's size (nearest neighbour: its regions kept as "
        "painted)"]
    # Refused as the guided route refuses: another shape, another count of levels (the page's words: models)
    shape = client.post("/api/guides/labels", json={"guide": url, "n_models": 2, "size": [48, 48]})
    assert shape.status_code == 400 and shape.json()["error"].startswith(
        "the guide is 48x64 but the output is 48x48, of another shape")
    three = soft.copy()
    three[:10, :10] = 120
    count = client.post("/api/guides/labels", json={"guide": base64.b64encode(png(three)).decode(), "n_models": 2})
    assert count.status_code == 400 and count.json()["error"].startswith(
        "the guide has 3 grey levels/colours with soft or JPEG edges but 2 models were given"), count.text
    for body, status, said in (({"n_models": 2}, 400, "no guide"), ({"guide": url}, 422, "n_models must be"),
                               ({"guide": url, "n_models": 9}, 422, "n_models must be"),
                               ({"guide": url, "n_models": 2, "seed": 1}, 422, "unknown field 'seed'"),
                               ({"guide": "not base64!", "n_models": 2}, 400, "guide is not valid base64")):
        r = client.post("/api/guides/labels", json=body)
        assert r.status_code == status and said in r.json()["error"], (body, r.text)
