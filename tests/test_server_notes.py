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
    # In the page's words: it said "(or leave the size out to take the guide's)", which the page cannot do.
    assert shape.json()["error"].endswith(
        "set the height and width above to the guide's shape (e.g. 48 and 64; a guide of the canvas's shape is "
        "scaled to its size), or paint the guide at the canvas's shape"), shape.text
    assert "leave" not in shape.json()["error"]
    # The API's own route may leave the size out, and says so.
    guided = client.post("/api/images/guided", json={"models": [a["id"], b["id"]], "guide": url, "size": [48, 48]})
    assert guided.status_code == 400 and "leave the size out" in guided.json()["error"], guided.text
    # A region the scaling to the canvas loses: the page's height and width, not a size field.
    thin = np.full((48, 64), 40, np.uint8)
    thin[:, 31] = 200  # a line one pixel wide, lost at a quarter of the size (columns 2, 6, ..., 62 are read)
    lost = client.post("/api/guides/labels", json={"guide": base64.b64encode(png(thin)).decode(), "n_models": 2,
                                                   "size": [12, 16]})
    assert lost.status_code == 400 and lost.json()["error"].endswith(
        "paint it wider, or set a larger height and width above"), lost.text
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


def test_a_guides_refusals_call_a_model_a_model_in_both_routes(client):
    # /api/guides/labels said "2 models were given", /api/images/guided "2 inputs were given" of the same thing.
    a, b = (fit(client, f"{n}.png", png(to_uint8(image))) for n, image in
            (("bricks", data.bricks(96, rng=3)), ("cells", data.cells(96, rng=4))))
    assert done(client, a["job"]) == done(client, b["job"]) == "done"
    three = np.full((32, 48), 0, np.uint8)
    three[:, 16:] = 128
    three[:, 32:] = 255
    guide = base64.b64encode(png(three)).decode()
    labels = client.post("/api/guides/labels", json={"guide": guide, "n_models": 2})
    guided = client.post("/api/images/guided", json={"models": [a["id"], b["id"]], "guide": guide})
    for r in (labels, guided):
        assert r.status_code == 400, r.text
        said = r.json()["error"]
        assert said.startswith("the guide has 3 distinct grey levels/colours but 2 models were given; give one "
                               "model per level (3 models for 3 levels) or "), said
        assert "input" not in said
    assert guided.json()["error"].endswith("or send no guide (a remix): the darkest is the first model")


def test_the_servers_words_name_no_command_line_option():
    # The library's messages name a setting and its option together ("(patch_size, --patch-size)"); the page
    # and the API have the setting's name alone.
    from tghop.server.core import error_response
    from tghop.server.requests import page_words

    said = ("n_clusters=8 needs at least 400 training patches; lower N (n_clusters, --clusters) or the least cluster "
            "size (min_cluster_size, --min-cluster-size), take more training patches (a smaller stride, --stride, "
            "or a larger max_patches, --max-patches) or use a larger exemplar")
    assert page_words(said) == (  # a setting the page's field names otherwise: the field, then the API's (0.63)
        "n_clusters=8 needs at least 400 training patches; lower N (the field clusters (N); the API's n_clusters) or "
        "the least cluster size (min_cluster_size), take more training patches (a smaller stride, or a larger number "
        "in the field training patches (the API's max_patches)) or use a larger exemplar")
    assert page_words("K1 (n_channels[0], --k1) is 3") == "K1 (n_channels[0]) is 3"
    assert page_words("give --tile once") == "give --tile once"  # an option alone, not beside a setting: as it is
    assert json.loads(error_response(422, "a tileable output (tile, --tile) needs more").body) == {
        "error": "a tileable output (tile) needs more"}


def test_a_generations_refusal_names_the_field_not_the_option(client):
    # A tileable image lower than a patch: the library's words named "--tile" and "--patch-size".
    model = fit(client, "bricks.png", png(bricks8()))
    assert done(client, model["job"]) == "done"
    r = client.post(f"/api/models/{model['id']}/images", json={"size": [16, 64], "tile": True, "seed": 1})
    assert r.status_code == 422 and "--" not in r.json()["error"], r.text
    assert "(tile)" in r.json()["error"] and "(patch_size)" in r.json()["error"], r.text


def test_a_mask_that_is_not_black_and_white_is_warned_of(client):
    # tghop inpaint warned of a picture given as its MASK (its light pixels the hole); the server said nothing.
    model = fit(client, "bricks.png", png(bricks8()))
    assert done(client, model["job"]) == "done"
    picture = to_uint8(data.bricks(64, rng=5))[:, :60].copy()
    hole = np.zeros((64, 60), np.uint8)
    hole[20:44, 20:40] = 255
    inpaint = f"/api/models/{model['id']}/inpaint"
    ask = {"image": ("picture.png", png(picture)), "seed": (None, "3")}
    plain = client.post(inpaint, files={**ask, "mask": ("mask.png", png(hole))})
    assert plain.status_code == 200 and "x-tghop-warning" not in plain.headers, plain.text
    swapped = client.post(inpaint, files={**ask, "mask": ("photo.png", png(picture))})
    assert swapped.status_code == 200, swapped.text
    header = swapped.headers["x-tghop-warning"]
    assert header.startswith("photo.png is not black and white: ") and header.endswith(
        " of its pixels are grey or coloured (a picture?), and those lighter than mid-grey are taken as the hole; "
        "paint the hole white on black (the picture is the field 'image', its mask 'mask')"), header
    assert "IMAGE" not in header and "--" not in header
    # A feathered brush's soft edges are not a picture: nothing said.
    from scipy.ndimage import gaussian_filter

    soft = np.round(gaussian_filter(hole.astype(float), 2)).astype(np.uint8)
    feathered = client.post(inpaint, files={**ask, "mask": ("soft.png", png(soft))})
    assert feathered.status_code == 200 and "x-tghop-warning" not in feathered.headers, feathered.headers


def test_an_opaque_alpha_dropped_is_told_apart_by_its_class():
    # read_notes passed over it by its words (": alpha channel dropped"): now by its class, whatever the words.
    from tghop import OpaqueAlphaWarning, TransparencyWarning
    from tghop._errors import warn
    from tghop.server.uploads import read_notes

    notes = []
    with read_notes(notes):
        warn(OpaqueAlphaWarning("a.png: alpha channel dropped", "a.png"))
        warn(OpaqueAlphaWarning("another wording", "b.png"))
        warn(UserWarning("c.png: alpha channel dropped"))  # not known opaque (a downscaled read): said
        warn(TransparencyWarning("d.png: ...", "d.png", 0.25))
    assert notes == ["c.png: alpha channel dropped", "d.png: 25% of its pixels are transparent, and the colours "
                     "under them are learnt as texture; to leave them out, crop the image to its opaque part"]


def test_an_uploaded_models_read_warnings_are_its_notes(client, tmp_path):
    # A model made by a newer tghop warned on the server's console, and the page said nothing.
    from tghop import __version__

    model = fit(client, "bricks.png", png(bricks8()))
    assert done(client, model["job"]) == "done"
    arrays = dict(np.load(io.BytesIO(client.get(f"/api/models/{model['id']}/file").content)))
    meta = json.loads(str(arrays["__meta__"]))
    arrays["__meta__"] = np.array(json.dumps({**meta, "tghop_version": "99.0.0"}))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    said = (f"newer.npz: made by tghop 99.0.0, newer than this {__version__}, which reads it as a model of its own "
            "version (what the newer one added is not used); upgrade tghop to use it")
    up = client.post("/api/models/upload", files={"model": ("newer.npz", buf.getvalue())})
    assert up.status_code == 200 and up.json()["notes"] == [said], up.text
    assert "/tmp" not in str(up.json()) and ".upload-" not in str(up.json())
    # Sent again (the file kept): the same notes, under the name it is sent with now.
    again = client.post("/api/models/upload", content=buf.getvalue(),
                        headers={"content-type": "application/octet-stream"})
    assert again.json()["notes"] == [said.replace("newer.npz", "the upload")]


def test_a_caches_read_warnings_are_kept_as_the_files_notes(tmp_path):
    # What reading an upload warned of (a checkpoint's, a model's) went to the server's console: now its notes,
    # for the upload's answer, read again for a file kept by an earlier server.
    from tghop._errors import warn
    from tghop.server.cache import ModelCache

    def load(path):
        warn(f"{path}: read with care")
        return object()

    cache = ModelCache(tmp_path, folder="cooc", suffix=".pt", load=load, what="checkpoint")
    cid = cache.store(b"a checkpoint", "c.pt", hint="")
    assert cache.notes(cid, "c.pt") == ["c.pt: read with care"]
    later = ModelCache(tmp_path, folder="cooc", suffix=".pt", load=load, what="checkpoint")  # a new server
    assert later.notes(cid, "c.pt") is None
    assert later.store(b"a checkpoint", "d.pt", hint="") == cid
    assert later.notes(cid, "d.pt") == ["d.pt: read with care"]


def test_a_guided_refinement_of_a_model_without_patch_statistics_names_the_model(client):
    # The library's words: "needs the patch statistics input 2 lacks ...; fit it again, or leave patch_refine at
    # None or 0": another word for a model than the route's, and a field the page has not (its quality menu).
    with_stats = fit(client, "bricks.png", png(bricks8()))
    without = fit(client, "bricks.png", png(bricks8()), patch_levels="0")
    assert done(client, with_stats["job"]) == done(client, without["job"]) == "done"
    r = client.post("/api/images/guided", json={"models": [with_stats["id"], without["id"]], "size": [32, 48],
                                                "quality": "best", "seed": 1})
    assert r.status_code == 422 and r.json()["error"] == (
        "models[1] holds no patch statistics for patch_refine or quality best (fitted with patch_levels 0, or by "
        "tghop 0.14 or older); fit it again"), r.text


def test_a_kept_models_read_warnings_are_told_when_it_is_used(client, live_server):
    # A model file kept by an earlier server (its cache folder shared, or the server restarted) was read at its
    # first use, and what reading it warned of (a newer tghop's file) went nowhere: its summary and its images said
    # nothing, and the page heard of it only when the file was uploaded again.
    import hashlib

    from tghop import __version__

    model = fit(client, "bricks.png", png(bricks8()), max_patches="1444")  # fitted nowhere else
    assert done(client, model["job"]) == "done"
    assert client.get(f"/api/models/{model['id']}").json()["notes"] == []  # this tghop's file: nothing to tell
    arrays = dict(np.load(io.BytesIO(client.get(f"/api/models/{model['id']}/file").content)))
    meta = json.loads(str(arrays["__meta__"]))
    arrays["__meta__"] = np.array(json.dumps({**meta, "tghop_version": "98.0.0"}))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    kept = hashlib.sha256(buf.getvalue()).hexdigest()
    (live_server.cache / "models" / f"{kept}.npz").write_bytes(buf.getvalue())  # as an earlier server kept it
    newer = (f"made by tghop 98.0.0, newer than this {__version__}, which reads it as a model of its own version "
             "(what the newer one added is not used); upgrade tghop to use it")
    said = client.get(f"/api/models/{kept}").json()["notes"]
    assert said == [f"model {kept[:12]}: {newer}"], said
    for url, body in ((f"/api/models/{kept}/images", {"size": [32, 32], "seed": 1}),
                      ("/api/images/guided", {"models": [kept, model["id"]], "size": [32, 48], "seed": 1})):
        r = client.post(url, json=body)
        assert r.status_code == 200 and r.headers["x-tghop-warning"] == f"model {kept[:12]}: {newer}", r.headers
    picture = png(to_uint8(data.bricks(48, rng=1)))
    mask = np.zeros((48, 48), np.uint8)
    mask[16:32, 16:32] = 255
    r = client.post(f"/api/models/{kept}/inpaint", files={"image": ("p.png", picture), "mask": ("m.png", png(mask))},
                    data={"seed": "1"})
    assert r.status_code == 200 and r.headers["x-tghop-warning"] == f"model {kept[:12]}: {newer}", r.text
    plain = client.post(f"/api/models/{model['id']}/images", json={"size": [32, 32], "seed": 1})
    assert plain.status_code == 200 and "x-tghop-warning" not in plain.headers
    # Uploaded now: its notes name the file, and so do the answers that use it from then on.
    up = client.post("/api/models/upload", files={"model": ("newer.npz", buf.getvalue())})
    assert up.json()["id"] == kept and up.json()["notes"] == [f"newer.npz: {newer}"], up.text
    assert client.get(f"/api/models/{kept}").json()["notes"] == [f"newer.npz: {newer}"]
    r = client.post(f"/api/models/{kept}/images", json={"size": [32, 32], "seed": 1})
    assert r.headers["x-tghop-warning"] == f"newer.npz: {newer}"
