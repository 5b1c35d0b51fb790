"""``tghop serve``'s co-occurrence routes (``/api/cooc``) on a real uvicorn server: upload a
tiny checkpoint trained here, morph and edit with crops of its exemplar (the same images as
the library's calls), and every kind of bad input; without PyTorch, 501."""

import base64
import hashlib
import io
import json
import os

import numpy as np
import pytest

httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

from tghop import TGHopError  # noqa: E402
from test_server import assert_error  # noqa: E402

try:
    import torch  # noqa: F401
except ImportError:
    torch = None
needs_torch = pytest.mark.skipif(torch is None, reason="PyTorch is not installed (pip install -e '.[metrics]'): "
                                                       "the co-occurrence routes answer 501 without it")

@pytest.fixture(scope="module", autouse=True)
def _threads(one_torch_thread):
    yield


@pytest.fixture(scope="module")
def client(live_server):
    with httpx.Client(base_url=live_server.url, timeout=120) as c:
        yield c


@pytest.fixture(scope="module")
def checkpoint(tiny_cooc_checkpoint):
    """A tiny trained checkpoint: (its bytes, the model as tghop.cooc.load reads it)."""
    from tghop import cooc

    return tiny_cooc_checkpoint.read_bytes(), cooc.load(tiny_cooc_checkpoint, device="cpu")


@pytest.fixture(scope="module")
def cid(client, checkpoint):
    r = client.post("/api/cooc", files={"checkpoint": ("tiny.pt", checkpoint[0])})
    assert r.status_code == 200, r.text
    return r.json()["id"]


def decoded(response):
    from PIL import Image

    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == "image/png"
    return np.asarray(Image.open(io.BytesIO(response.content)).convert("RGB"))


def as_uint8(image):
    from tghop.imageio import to_uint8

    return to_uint8(image).astype(int)


def labels_png(levels):
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.asarray(levels, dtype=np.uint8)).save(buf, format="PNG")
    return base64.b64encode(buf.getvalue()).decode()


@needs_torch
def test_upload_is_kept_under_its_hash_and_summarised(client, checkpoint, cid, live_server):
    content, model = checkpoint
    assert cid == hashlib.sha256(content).hexdigest()
    assert (live_server.cache / "cooc" / f"{cid}.pt").read_bytes() == content
    assert not [f for f in os.listdir(live_server.cache / "cooc") if f.endswith(".tmp")]
    again = client.post("/api/cooc", content=content, headers={"content-type": "application/octet-stream"})
    assert again.status_code == 200 and again.json() == {"id": cid, "notes": []}  # the whole body works too
    s = client.get(f"/api/cooc/{cid}").json()
    assert s["exemplar_shape"] == [64, 64, 3] and s["crop_size"] == 32 and s["s"] == 8
    assert s["step"] == s["n_steps"] == 2 and s["builtin"] is None and s["exemplar_hash"] == model.exemplar_hash_


def test_a_checkpoint_of_a_builtin_names_it(checkpoint, tiny_cooc_exemplar, monkeypatch):
    from tghop import data
    from tghop.server import cooc as server_cooc

    monkeypatch.setattr(data, "BUILTIN", {"tiny": None})
    monkeypatch.setattr(data, "builtin", lambda name: tiny_cooc_exemplar)
    server_cooc._builtin_hashes.cache_clear()
    try:
        assert server_cooc._builtin_hashes() == {checkpoint[1].exemplar_hash_: "tiny"}  # the hash training stores
    finally:
        server_cooc._builtin_hashes.cache_clear()


@needs_torch
def test_morph_is_the_libraries_strip_between_two_crops(client, checkpoint, cid):
    model = checkpoint[1]
    body = {"a": [0, 0], "b": [32, 32], "length": 6, "seed": 3}
    r = client.post(f"/api/cooc/{cid}/morph", json=body)
    got = decoded(r)
    assert got.shape == (32, 48, 3) and r.headers["X-Tghop-Seed"] == "3" and r.headers["X-Tghop-Size"] == "32x48"
    want = as_uint8(model.morph_strip(model.crop_condition(0, 0), model.crop_condition(32, 32), length=6, rng=3))
    assert np.abs(got.astype(int) - want).max() <= 1
    assert client.post(f"/api/cooc/{cid}/morph", json=body).content == r.content  # same seed, same bytes
    other = decoded(client.post(f"/api/cooc/{cid}/morph", json={**body, "seed": 4}))
    assert (other != got).any()
    small = decoded(client.post(f"/api/cooc/{cid}/morph", json={"a": [8, 8], "b": [40, 0], "crop": 16}))
    assert small.shape == (16, 64, 3)  # 16 px crops, the default 8 cells


@needs_torch
def test_edit_paints_each_crops_statistics_where_its_label_is(client, checkpoint, cid):
    from tghop import cooc

    model = checkpoint[1]
    levels = np.zeros((40, 64), dtype=np.uint8)
    levels[:, 32:] = 255  # the left half the first crop, the right half the second
    r = client.post(f"/api/cooc/{cid}/edit", json={"crops": [[0, 0], [32, 32]], "labels": labels_png(levels),
                                                   "seed": 5})
    got = decoded(r)
    assert got.shape == (40, 64, 3) and r.headers["X-Tghop-Size"] == "40x64"
    cells = np.zeros((5, 8), dtype=int)
    cells[:, 4:] = 1
    cond = cooc.paint_condition([model.crop_condition(0, 0), model.crop_condition(32, 32)], cells)
    want = as_uint8(model.generate(cond, rng=5)[:40, :64])
    assert np.abs(got.astype(int) - want).max() <= 1
    one = decoded(client.post(f"/api/cooc/{cid}/edit", json={"crops": [[16, 16]], "size": [24, 40], "seed": 1}))
    assert one.shape == (24, 40, 3)  # one crop everywhere: no labels needed


@needs_torch
def test_an_edits_labels_scaled_to_the_size_tell_the_client(client, cid):
    # Labels of another size than `size` (their shape) were scaled by the library with a warning, which went to
    # the server's console, never to the client: the answer's X-Tghop-Warning says so now, as a guided image's.
    import warnings

    levels = np.zeros((80, 128), dtype=np.uint8)
    levels[:, 64:] = 255
    ask = {"crops": [[0, 0], [32, 32]], "seed": 5}
    with warnings.catch_warnings(record=True) as console:  # the server's thread runs while this one waits
        warnings.simplefilter("always")
        r = client.post(f"/api/cooc/{cid}/edit", json={**ask, "labels": labels_png(levels), "size": [40, 64]})
    assert decoded(r).shape == (40, 64, 3) and r.headers["X-Tghop-Size"] == "40x64"
    assert r.headers["X-Tghop-Warning"] == ("the label map was scaled from 80x128 to 40x64, the output's size "
                                            "(nearest neighbour: its regions kept as painted)")
    assert not [w for w in console if "was scaled" in str(w.message)]  # the client's, not the console's
    # the same image as the labels painted at that size, which are not scaled and say nothing
    painted = client.post(f"/api/cooc/{cid}/edit", json={**ask, "labels": labels_png(levels[::2, ::2])})
    assert painted.status_code == 200 and painted.content == r.content, painted.text
    assert "X-Tghop-Warning" not in painted.headers
    # a region that the scaling loses (thinner than a pixel of the output) is refused, as the guided route's: its crop
    # was painted nowhere, without a word
    thin = np.zeros((80, 128), dtype=np.uint8)
    thin[:, 64] = 255
    assert_error(client.post(f"/api/cooc/{cid}/edit", json={**ask, "labels": labels_png(thin), "size": [40, 64]}),
                 400, "the label map: crops[1]'s region is gone once the map is scaled from 80x128 to size 40x64 (it "
                      "is thinner than a pixel of the output); paint it wider or give a larger size")


@needs_torch
def test_what_reading_an_edits_labels_said_tells_the_client(client, cid):
    # The upload's read warnings (a colour profile converted to sRGB) were dropped; the command line warns of them.
    from PIL import Image

    from test_profiles import P3

    levels = np.zeros((40, 64, 3), dtype=np.uint8)
    levels[:, 32:] = 255  # black and white: the same in P3 as in sRGB
    ask = {"crops": [[0, 0], [32, 32]], "seed": 5}
    plain = client.post(f"/api/cooc/{cid}/edit", json={**ask, "labels": labels_png(levels)})
    buf = io.BytesIO()
    Image.fromarray(levels).save(buf, format="PNG", icc_profile=P3)
    p3 = base64.b64encode(buf.getvalue()).decode()
    r = client.post(f"/api/cooc/{cid}/edit", json={**ask, "labels": p3})
    assert r.status_code == 200 and r.content == plain.content and "X-Tghop-Warning" not in plain.headers
    said = "labels.png: colours converted to sRGB from its colour profile 'Test P3'"
    assert r.headers["X-Tghop-Warning"] == said
    scaled = client.post(f"/api/cooc/{cid}/edit", json={**ask, "labels": p3, "size": [20, 32]})
    assert scaled.headers["X-Tghop-Warning"] == (f"{said}; the label map was scaled from 40x64 to 20x32, the "
                                                 "output's size (nearest neighbour: its regions kept as painted)")


@needs_torch
def test_edit_with_a_boost_is_the_libraries_boosted_condition(client, checkpoint, cid):
    from tghop import cooc

    model = checkpoint[1]
    body = {"crops": [[0, 0]], "size": [32, 48], "seed": 2}
    plain = decoded(client.post(f"/api/cooc/{cid}/edit", json=body))
    for boost in ([0, 1, 8], [2, 2, 0.25]):
        got = decoded(client.post(f"/api/cooc/{cid}/edit", json={**body, "boost": boost}))
        cond = cooc.paint_condition([model.crop_condition(0, 0)], np.zeros((4, 6), dtype=int))
        want = as_uint8(model.generate(cooc.boost_condition(cond, *boost), rng=2)[:32, :48])
        assert np.abs(got.astype(int) - want).max() <= 1
        assert (got != plain).any()  # the boost changed the image
    same = decoded(client.post(f"/api/cooc/{cid}/edit", json={**body, "boost": [1, 0, 1]}))
    assert np.abs(same.astype(int) - plain).max() <= 1  # a factor of 1 changes nothing


@needs_torch
def test_a_morph_or_edit_with_a_job_reports_its_stages_there_same_bytes(client, cid):
    """As the other generations (the page's progress bar): a request naming a job (X-Tghop-Job) reports
    the generator's pass and the PNG's encoding there, and its image is the same as without one."""
    import secrets

    from tghop.server.jobs import generation_fraction

    for path, body in (("morph", {"a": [0, 0], "b": [32, 32], "length": 6, "seed": 3}),
                       ("edit", {"crops": [[0, 0]], "size": [32, 48], "seed": 2})):
        plain = client.post(f"/api/cooc/{cid}/{path}", json=body)
        job = secrets.token_hex(16)
        followed = client.post(f"/api/cooc/{cid}/{path}", json=body, headers={"X-Tghop-Job": job})
        assert followed.status_code == 200 and followed.content == plain.content, followed.text
        snap = client.get(f"/api/jobs/{job}").json()
        assert snap["kind"] == "generation" and snap["id"] == cid and snap["state"] == "done"
        assert snap["stages"] == ["generating", "encoding"] and snap["progress"] == 1.0
    assert 0 < generation_fraction("generating", 0, 1) < generation_fraction("generating", 1, 1) < 1


def test_boost_condition_scales_one_bin_and_its_mirror():
    from tghop.cooc import boost_condition

    cond = np.random.default_rng(0).random((9, 2, 3))
    out = boost_condition(cond, 0, 2, 3.0)
    assert (np.allclose(out[[2, 6]], 3 * cond[[2, 6]])
            and np.allclose(np.delete(out, [2, 6], 0), np.delete(cond, [2, 6], 0)))
    assert np.allclose(boost_condition(cond, 1, 1, 0.5)[4], 0.5 * cond[4])
    assert out is not cond and np.array_equal(cond, np.random.default_rng(0).random((9, 2, 3)))  # a copy
    for a, b in ((0, 3), (-1, 0), (True, 0), (0, 1.0)):
        with pytest.raises(TGHopError, match=r"^the boosted clusters must lie in 0\.\.2 \(this model has 3 colour "
                                             r"clusters\), got "):
            boost_condition(cond, a, b, 2.0)
    for f in (-1.0, float("inf"), float("nan"), "2", True):
        with pytest.raises(TGHopError, match=r"^the factor must be a finite number >= 0, got "):
            boost_condition(cond, 0, 0, f)
    assert np.allclose(boost_condition(cond, 0, 0, 1000)[0], 1000 * cond[0])
    with pytest.raises(TGHopError, match=r"^the factor must be at most 1,000, got 1e\+308$"):  # sums overflowed
        boost_condition(cond, 0, 0, 1e308)


def test_an_edits_boost_is_bounded_by_the_librarys_bound(monkeypatch):
    """tghop.server.cooc kept its own copy of the library's bound of a boost's factor
    (tghop.cooc.assembly.MAX_BOOST): a change of the library's did not reach the server's check of
    an edit's JSON. The server asks the library's bound now."""
    from tghop.cooc import assembly
    from tghop.server.cooc import parse_edit
    from tghop.server.requests import RequestError

    monkeypatch.setattr(assembly, "MAX_BOOST", 10.0)
    body = {"crops": [[0, 0]], "size": [16, 16]}
    assert parse_edit({**body, "boost": [0, 1, 10]})[3] == (0, 1, 10.0)
    with pytest.raises(RequestError) as refused:
        parse_edit({**body, "boost": [0, 1, 11]})
    assert refused.value.status == 422 and "and a factor from 0 to 10, e.g." in refused.value.message


@needs_torch
def test_the_checkpoint_downloads_as_uploaded(client, checkpoint, cid):
    r = client.get(f"/api/cooc/{cid}/file")
    assert r.status_code == 200 and r.content == checkpoint[0]
    assert r.headers["content-type"] == "application/octet-stream"
    # Named as the page names the link (tghop-cooc-..., ?name= its file's name): the header wins over the link's
    assert r.headers["content-disposition"] == f'attachment; filename="tghop-cooc-{cid[:12]}.pt"'
    named = client.get(f"/api/cooc/{cid}/file", params={"name": "my run"}).headers["content-disposition"]
    assert named == f'attachment; filename="tghop-cooc-my-run-{cid[:12]}.pt"'
    assert client.post("/api/cooc", content=r.content).json()["id"] == cid  # uploads back to the same id
    assert_error(client.get(f"/api/cooc/{'0' * 64}/file"), 404, "no co-occurrence checkpoint", "POST /api/cooc")
    assert_error(client.get("/api/cooc/not-an-id/file"), 404, "no co-occurrence checkpoint")
    assert_error(client.get("/api/cooc/../../etc/passwd/file"), 404)


@needs_torch
def test_bad_checkpoints_get_400_and_leave_nothing(client, live_server, tmp_path):
    import torch

    before = sorted(os.listdir(live_server.cache / "cooc"))
    assert_error(client.post("/api/cooc", files={"checkpoint": ("junk.pt", os.urandom(5000))}), 400,
                 "junk.pt", "not a tghop co-occurrence checkpoint")
    foreign = io.BytesIO()
    torch.save({"weight": torch.zeros(3)}, foreign)
    assert_error(client.post("/api/cooc", files={"checkpoint": ("other.pt", foreign.getvalue())}), 400,
                 "other.pt", "not a tghop co-occurrence checkpoint")
    marker = tmp_path / "code-ran"

    class Evil:
        def __reduce__(self):
            return (os.mkdir, (str(marker),))

    evil = io.BytesIO()
    torch.save({"settings_json": Evil()}, evil)
    assert_error(client.post("/api/cooc", files={"checkpoint": ("evil.pt", evil.getvalue())}), 400,
                 "not a tghop co-occurrence checkpoint")
    assert not marker.exists()  # weights_only: the pickle's call never ran
    assert_error(client.post("/api/cooc", files={"checkpoint": ("empty.pt", b"")}), 400,  # 0.62: the page's fix first
                 "empty.pt is empty; pick a checkpoint downloaded from this page (Download checkpoint) or written by "
                 "tghop cooc train")
    # A texture model's file, loaded as a checkpoint on the page: where it goes there, not the library's words.
    from tghop import TGHop, data
    from tghop.modelfile import save_model

    save_model(TGHop(n_clusters=4, n_codewords=20, stride=8, max_patches=300, layout_factor=None, patch_levels=0,
                     rng=0).fit(data.bricks(96, rng=1)), tmp_path / "m.npz")
    assert assert_error(client.post("/api/cooc", files={"checkpoint": ("m.npz", (tmp_path / "m.npz").read_bytes())}),
                        400) == ("m.npz is a tghop model file, not a co-occurrence checkpoint; open it with \"Continue "
                                 "from a saved model\" (the API: POST it to /api/models/upload)")
    assert_error(client.post("/api/cooc", files={"model": ("x.pt", b"x")}), 400, "field 'checkpoint'")
    assert_error(client.post("/api/cooc", content=b"\0" * (51 * 1024 * 1024)), 413, "50 MB")
    assert sorted(os.listdir(live_server.cache / "cooc")) == before


@needs_torch
def test_bad_requests_get_one_line_and_their_status(client, cid):
    morph, edit = f"/api/cooc/{cid}/morph", f"/api/cooc/{cid}/edit"
    assert_error(client.get("/api/cooc/" + "0" * 64), 404, "no co-occurrence checkpoint", "POST /api/cooc",
                 'load it again with "Load a checkpoint" in Co-occurrence mode')
    assert_error(client.post("/api/cooc/../../etc/morph", json={}), 404)
    assert_error(client.post(f"/api/cooc/{'ab' * 32}/morph", json={"a": [0, 0], "b": [0, 0]}), 404)
    assert_error(client.post(morph, json={"a": [60, 0], "b": [0, 0]}), 422, "32x32 crop at (60, 0)", "64x64 exemplar")
    assert_error(client.post(morph, json={"a": [-8, 0], "b": [0, 0]}), 422, "a must be a crop's position [y, x]")
    assert_error(client.post(morph, json={"a": "0,0", "b": [0, 0]}), 422, "a must be a crop's position")
    assert_error(client.post(morph, json={"a": [0, 0]}), 422, "no b")
    assert_error(client.post(morph, json={"a": [0, 0], "b": [0, 0], "length": 1}), 422, "length must be")
    assert_error(client.post(morph, json={"a": [0, 0], "b": [0, 0], "zoom": 2}), 422, "unknown field 'zoom'")
    assert_error(client.post(morph, content=b"{", headers={"content-type": "application/json"}), 400, "not JSON")
    assert_error(client.post(morph, json=[1]), 400, "JSON object")
    two = [[0, 0], [32, 32]]
    assert_error(client.post(edit, json={"crops": two}), 422, "2 crops but no labels")
    assert_error(client.post(edit, json={"crops": [[0, 0], [99, 0]], "size": 16}), 422, "no labels")
    assert_error(client.post(edit, json={"crops": [[0, 0], [40, 0]], "labels": labels_png([[0, 255]])}), 422,
                 "crop at (40, 0)")
    assert_error(client.post(edit, json={"crops": []}), 422, "crops must be a list of 1 to 8")
    assert_error(client.post(edit, json={"crops": two, "labels": "!!"}), 400, "labels is not valid base64")
    assert_error(client.post(edit, json={"crops": two, "labels": labels_png([[0, 128, 255]])}), 400,
                 "3 distinct grey levels", "2 crops were given; give one crop per level (3 crops for 3 levels)")
    assert_error(client.post(edit, json={"crops": two, "labels": labels_png([[0, 255]]), "size": [8, 8]}), 400,
                 "the label map is 1x2 but the output is 8x8")
    assert_error(client.post(edit, json={"crops": [[0, 0]], "size": [4096, 4096]}), 422, "size")
    assert_error(client.post(edit, json={"crops": [[0, 0]], "seed": -1}), 422, "seed must be an integer")
    for boost in ([0, 1], [0, 1, -1], [0, 1, "2"], [True, 0, 2], [0, 1, 1e9], "0,1,2", "[0, 1, NaN]",
                  "[0, 1, Infinity]"):
        raw = '{"crops": [[0, 0]], "boost": %s}' % (boost if isinstance(boost, str) and "[" in boost
                                                    else json.dumps(boost))
        assert_error(client.post(edit, content=raw, headers={"content-type": "application/json"}), 422,
                     "boost must be [a, b, factor]")  # NaN, Infinity: Python's JSON reads them
    assert_error(client.post(edit, json={"crops": [[0, 0]], "boost": [0, 3, 2]}), 422, "boost [0, 3, 2.0]",
                 "0..2 (this model has 3 colour clusters)")


def test_without_torch_the_routes_say_how_to_install_it(tmp_path, monkeypatch, without_torch):
    from conftest import LiveServer

    server = LiveServer(tmp_path)
    try:
        with httpx.Client(base_url=server.url, timeout=60) as c:
            for r in (c.post("/api/cooc", content=b"x"), c.get("/api/cooc/" + "0" * 64),
                      c.get("/api/cooc/" + "0" * 64 + "/file"),
                      c.post("/api/cooc/" + "0" * 64 + "/morph", json={})):
                assert_error(r, 501, "PyTorch", "pip install 'tghop[metrics]'")
            assert c.get("/api").status_code == 200  # the rest works
            assert c.get("/api").json()["cooc"] is False  # the page says so before any upload
    finally:
        server.stop()


def test_the_checkpoints_folder_is_bounded(tmp_path):
    from tghop.server.cooc import cooc_cache

    folder = tmp_path / "cooc"
    folder.mkdir()
    for i, name in enumerate(("a" * 64, "b" * 64)):
        (folder / f"{name}.pt").write_bytes(b"x" * 1000)
        os.utime(folder / f"{name}.pt", (1000 + i, 1000 + i))
    cache = cooc_cache(tmp_path, 1500)  # the older one goes at start
    assert sorted(os.listdir(folder)) == ["b" * 64 + ".pt"] and cache.size() == 1000


def _served_checkpoint(tmp_path, checkpoint):
    """A live server (one decode at a time) with ``checkpoint`` in its cache folder, not in memory, and a
    list where each read of a checkpoint file puts (its thread's name, the decode gate's slots held)."""
    import threading

    from conftest import LiveServer

    (tmp_path / "cooc").mkdir()
    cid = hashlib.sha256(checkpoint[0]).hexdigest()
    (tmp_path / "cooc" / f"{cid}.pt").write_bytes(checkpoint[0])
    server = LiveServer(tmp_path, max_decodes=1)
    state = server.app.state.server
    seen, load = [], state.cooc._load

    def watched(path):
        seen.append((threading.current_thread().name, state.decoding.holding))
        return load(path)

    state.cooc._load = watched
    return server, state, cid, seen


@needs_torch
def test_a_summary_loads_the_checkpoint_in_the_decoding_turn(tmp_path, checkpoint):
    """A checkpoint read for its summary may take hundreds of MB, as a model: it is read on a decoding
    thread holding the decode gate's slot (as GET /api/models/{id}), not on Starlette's threads."""
    server, state, cid, seen = _served_checkpoint(tmp_path, checkpoint)
    try:
        with httpx.Client(base_url=server.url, timeout=120) as c:
            r = c.get(f"/api/cooc/{cid}")
            assert r.status_code == 200 and r.json()["id"] == cid, r.text
        assert len(seen) == 1 and seen[0][0].startswith("tghop-decode") and seen[0][1] == 1, seen
    finally:
        server.stop()
    assert state.decoding.holding == 0 and state.decoding.waiting == 0


@needs_torch
def test_a_checkpoints_summary_is_kept_as_a_models_is(tmp_path, checkpoint):
    """GET /api/cooc/{id} read the checkpoint from disk (in the decoding turn) each time it was not in
    memory; a model's summary is kept once made. A checkpoint's is kept too: asked again once the
    checkpoint has left memory, it is answered without reading the file; a file gone is still 404."""
    from conftest import LiveServer

    (tmp_path / "cooc").mkdir()
    cid = hashlib.sha256(checkpoint[0]).hexdigest()
    (tmp_path / "cooc" / f"{cid}.pt").write_bytes(checkpoint[0])
    server = LiveServer(tmp_path, max_decodes=1)
    state = server.app.state.server
    reads, load = [], state.cooc._load
    state.cooc._load = lambda path: (reads.append(path), load(path))[1]
    try:
        with httpx.Client(base_url=server.url, timeout=120) as c:
            first = c.get(f"/api/cooc/{cid}")
            assert first.status_code == 200 and first.json()["id"] == cid, first.text
            for _ in range(3):
                with state.cooc._lock:  # out of memory (as after four other checkpoints were used)
                    state.cooc._loaded.clear()
                again = c.get(f"/api/cooc/{cid}")
                assert again.status_code == 200 and again.json() == first.json(), again.text
            assert len(reads) == 1, reads  # read once, for the first summary
            (tmp_path / "cooc" / f"{cid}.pt").unlink()
            assert_error(c.get(f"/api/cooc/{cid}"), 404, f"no co-occurrence checkpoint {cid[:12]}... on the server")
    finally:
        server.stop()
    assert state.decoding.holding == 0 and state.decoding.waiting == 0


@needs_torch
def test_a_morph_and_an_edit_read_the_checkpoint_in_the_decoding_turn(tmp_path, checkpoint):
    """A checkpoint not in memory that a morph or an edit needs is read on a decoding thread holding a slot
    of the decoding turn before the generation takes its thread, as an upload is decoded (503 when too many
    wait: tests/test_server_bounds.py)."""
    server, state, cid, seen = _served_checkpoint(tmp_path, checkpoint)
    try:
        with httpx.Client(base_url=server.url, timeout=120) as c:
            for path, body in (("morph", {"a": [0, 0], "b": [32, 32], "length": 2, "seed": 1}),
                               ("edit", {"crops": [[0, 0]], "size": [16, 16], "seed": 1})):
                with state.cooc._lock:  # not in memory, as on a fresh server
                    state.cooc._loaded.clear()
                seen.clear()
                r = c.post(f"/api/cooc/{cid}/{path}", json=body)
                assert r.status_code == 200, r.text
                assert len(seen) == 1 and seen[0][0].startswith("tghop-decode") and seen[0][1] == 1, (path, seen)
    finally:
        server.stop()
    assert state.decoding.holding == 0 and state.decoding.waiting == 0


@needs_torch
def test_a_checkpoint_sent_as_a_model_file_is_told_where_it_goes(client, checkpoint):
    # The library's words: "a co-occurrence cGAN checkpoint is read by tghop.cooc.load and the 'tghop cooc'
    # commands", a command line's advice on the page's "Continue from a saved model".
    r = client.post("/api/models/upload", files={"model": ("tiny.pt", checkpoint[0])})
    assert assert_error(r, 400) == ("tiny.pt is a co-occurrence checkpoint, not a model file; load it in "
                                    "Co-occurrence mode (the API: POST it to /api/cooc)")
