"""``tghop serve``'s HTTP API against a real uvicorn server on a free port (httpx as the
client): fit a built-in exemplar, follow the job (polling and server-sent events),
generate, download and upload models, cancel, and every kind of bad input."""

import hashlib
import io
import json
import os
import re
import signal
import struct
import subprocess
import sys
import time
import zlib

import pytest

httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

from conftest import FAST_FIT  # noqa: E402

from tghop.modelfile import load_model  # noqa: E402


def png_header(width, height):
    """A PNG whose header declares ``width`` x ``height`` (with almost no pixel data)."""
    def chunk(kind, payload):
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\x00" * 10)) + chunk(b"IEND", b""))


def exemplar_png(size=96):
    from PIL import Image

    from tghop import data
    from tghop.imageio import to_uint8

    buf = io.BytesIO()
    Image.fromarray(to_uint8(data.bricks(size, rng=3))).save(buf, format="PNG")
    return buf.getvalue()


@pytest.fixture(scope="module")
def client(live_server):
    with httpx.Client(base_url=live_server.url, timeout=120) as c:
        yield c


def events(client, job):
    """The job's server-sent events until the stream ends: a list of (event, data)."""
    out = []
    with client.stream("GET", f"/api/jobs/{job}/events") as response:
        assert response.status_code == 200
        assert response.headers["content-type"].startswith("text/event-stream")
        kind = None
        for line in response.iter_lines():
            if line.startswith("event: "):
                kind = line[7:]
            elif line.startswith("data: "):
                out.append((kind, json.loads(line[6:])))
    return out


def assert_error(response, status, *fragments):
    assert response.status_code == status, response.text
    message = response.json()["error"]
    assert message and "\n" not in message and "Traceback" not in message
    for fragment in fragments:
        assert fragment in message, message
    return message


def model_files(cache):
    return sorted(os.listdir(cache / "models"))


@pytest.fixture(scope="module")
def fitted(client):
    """A fit of builtin:bricks followed by its event stream and polled: (model id, events)."""
    r = client.post("/api/models", files={"builtin": (None, "bricks"), **{k: (None, v) for k, v in FAST_FIT.items()}})
    assert r.status_code == 202, r.text
    body = r.json()
    assert set(body) >= {"id", "job"} and len(body["id"]) == 64
    polled = client.get(f"/api/jobs/{body['job']}").json()
    assert polled["state"] in ("queued", "running", "done") and polled["id"] == body["id"]
    stream = events(client, body["job"])
    return body["id"], body["job"], stream


def test_a_fit_reports_progress_and_ends_done(client, fitted):
    model_id, job, stream = fitted
    assert stream[-1][0] == "end" and stream[-1][1]["state"] == "done"
    progress = [data["progress"] for kind, data in stream]
    assert progress == sorted(progress) and progress[-1] == 1.0
    shown = {data["stage"] for _, data in stream}  # the stream shows the latest state: some may be skipped
    assert "saving" in shown
    stages = stream[-1][1]["stages"]  # but every stage is listed, in order
    assert stages[:5] == ["exemplar", "hop 1", "hop 2", "core", "SDR"] and stages[-1] == "saving"
    assert {"clusters", "ICA", "CDF codebook"} <= set(stages) and shown - {""} <= set(stages)
    for _, data in stream:  # each event's list is a prefix of the final one
        assert data["stages"] == stages[:len(data["stages"])]
    final = client.get(f"/api/jobs/{job}").json()
    assert final["state"] == "done" and final["progress"] == 1.0


def test_the_summary_is_what_info_json_gives(client, fitted, live_server):
    from click.testing import CliRunner

    from tghop.cli import main

    model_id, _, _ = fitted
    r = client.get(f"/api/models/{model_id}")
    assert r.status_code == 200
    summary = r.json()
    assert summary["id"] == model_id and summary["layout"] is False
    assert summary["params"]["n_clusters"] == 8 and summary["params"]["layout_factor"] is None
    cli = CliRunner().invoke(main, ["info", "--json", str(live_server.cache / "models" / f"{model_id}.npz")])
    assert cli.exit_code == 0, cli.output
    info = json.loads(cli.stdout)
    for key in ("params", "dims", "channels", "exemplar_shape", "n_parameters"):
        assert summary[key] == info[key], key


def test_generate_png_of_the_asked_size_and_same_seed_same_bytes(client, fitted):
    from PIL import Image

    model_id, _, _ = fitted
    ask = {"size": [48, 80], "seed": 5, "tile": True, "refine": 1, "n_patches": 400}
    a = client.post(f"/api/models/{model_id}/images", json=ask)
    assert a.status_code == 200, a.text
    assert a.headers["content-type"] == "image/png" and a.headers["x-tghop-seed"] == "5"
    image = Image.open(io.BytesIO(a.content))
    assert image.size == (80, 48) and image.mode == "RGB"
    b = client.post(f"/api/models/{model_id}/images", json=ask)
    assert b.content == a.content
    c = client.post(f"/api/models/{model_id}/images", json={**ask, "seed": 6})
    assert c.status_code == 200 and c.content != a.content
    d = client.post(f"/api/models/{model_id}/images", json={"size": [40, 40], "paper": True, "n_patches": 300})
    assert d.status_code == 200 and int(d.headers["x-tghop-seed"]) >= 0


def test_the_same_exemplar_and_settings_reuse_the_model(client, fitted, live_server):
    model_id, _, _ = fitted
    before = model_files(live_server.cache)
    r = client.post("/api/models", files={"builtin": (None, "builtin:bricks"),
                                          **{k: (None, v) for k, v in FAST_FIT.items()}})
    assert r.status_code == 200 and r.json()["id"] == model_id and r.json()["state"] == "done"
    assert client.get(f"/api/jobs/{r.json()['job']}").json()["state"] == "done"
    assert model_files(live_server.cache) == before


def test_download_the_model_and_upload_it_back(client, fitted, live_server, tmp_path):
    model_id, _, _ = fitted
    r = client.get(f"/api/models/{model_id}/file")
    assert r.status_code == 200 and r.content[:2] == b"PK"
    path = tmp_path / "downloaded.npz"
    path.write_bytes(r.content)
    assert load_model(path).dims_ == client.get(f"/api/models/{model_id}").json()["dims"]
    up = client.post("/api/models/upload", content=r.content, headers={"content-type": "application/octet-stream"})
    assert up.status_code == 200, up.text
    uploaded = up.json()["id"]
    assert uploaded == hashlib.sha256(r.content).hexdigest()
    # Named as the page names it (?name=, safe characters only), or by the id alone
    assert r.headers["content-disposition"] == f'attachment; filename="tghop-{model_id[:12]}.npz"'
    named = client.get(f"/api/models/{model_id}/file", params={"name": '../My "wall" été\\x'})
    assert named.headers["content-disposition"] == (
        f'attachment; filename="tghop-My-wall-ete-x-{model_id[:12]}.npz"; '
        f"filename*=UTF-8''tghop-My-wall-%C3%A9t%C3%A9-x-{model_id[:12]}.npz")
    as_form = client.post("/api/models/upload", files={"model": ("mine.npz", r.content)})
    assert as_form.status_code == 200 and as_form.json()["id"] == uploaded
    ask = {"size": [48, 80], "seed": 5, "refine": 1, "n_patches": 400}
    again = client.post(f"/api/models/{uploaded}/images", json=ask)
    original = client.post(f"/api/models/{model_id}/images", json=ask)
    assert again.status_code == 200 and again.content == original.content


def test_an_uploaded_image_is_fitted(client, live_server):
    png = exemplar_png()
    fields = {**FAST_FIT, "stride": "6"}
    r = client.post("/api/models", files={"image": ("my bricks.png", png, "image/png"),
                                          **{k: (None, v) for k, v in fields.items()}})
    assert r.status_code == 202, r.text
    first = r.json()
    again = client.post("/api/models", files={"image": ("other name.png", png, "image/png"),
                                              **{k: (None, v) for k, v in fields.items()}})
    assert again.json()["id"] == first["id"]  # the content decides, not the name
    assert events(client, first["job"])[-1][1]["state"] == "done"
    assert client.get(f"/api/models/{first['id']}").json()["exemplar_shape"] == [96, 96, 3]


def test_fits_queue_and_cancel(client, live_server):
    # max_fits=1: the second fit waits; cancelled while queued it never runs, and the
    # running one stops at its next progress call. Neither leaves a file.
    before = model_files(live_server.cache)
    form = {"builtin": (None, "cells"), **{k: (None, v) for k, v in FAST_FIT.items()}}
    slow = {"stride": (None, "2"), "max_patches": (None, "20000")}  # still running when the cancel comes
    a = client.post("/api/models", files={**form, **slow, "n_clusters": (None, "9")}).json()
    b = client.post("/api/models", files={**form, "n_clusters": (None, "10")}).json()
    assert client.get(f"/api/jobs/{b['job']}").json()["state"] == "queued"
    cancelled = client.delete(f"/api/jobs/{b['job']}")
    assert cancelled.status_code == 200 and cancelled.json()["state"] == "cancelled"
    deadline = time.monotonic() + 60
    while client.get(f"/api/jobs/{a['job']}").json()["state"] != "running":
        assert time.monotonic() < deadline
        time.sleep(0.05)
    assert client.delete(f"/api/jobs/{a['job']}").status_code == 200
    stream = events(client, a["job"])
    assert stream[-1][1]["state"] == "cancelled", stream
    for job in (a, b):
        assert_error(client.get(f"/api/models/{job['id']}"), 404, "no model")
    assert model_files(live_server.cache) == before


def test_a_generation_whose_client_went_away_never_runs(client, fitted, live_server, monkeypatch):
    import threading

    from tghop.server.routes import images

    server = live_server.app.state.server
    model_id, _, _ = fitted
    seeds = []
    generate = images.model_png
    monkeypatch.setattr(images, "model_png", lambda server, mid, size, seed, settings: seeds.append(seed) or
                        generate(server, mid, size, seed, settings))
    gate = threading.Event()
    server.executor.submit(gate.wait, 60)  # the one generation thread (max_fits=1) is busy
    submitted, submit = [], server.executor.submit
    monkeypatch.setattr(server.executor, "submit", lambda *a: submitted.append(submit(*a)) or submitted[-1])
    try:
        with pytest.raises(httpx.TimeoutException):  # waits for the thread, and its client gives up
            httpx.post(f"{live_server.url}/api/models/{model_id}/images", json={"size": [16, 16], "seed": 101},
                       timeout=1)
        deadline = time.monotonic() + 30
        while not (len(submitted) == 1 and submitted[0].cancelled()):
            assert time.monotonic() < deadline, "the waiting generation was not dropped"
            time.sleep(0.02)
    finally:
        gate.set()
    r = client.post(f"/api/models/{model_id}/images", json={"size": [16, 16], "seed": 102})
    assert r.status_code == 200 and seeds == [102]  # 101 never ran


def test_a_running_generation_whose_client_went_away_stops(client, fitted, live_server, monkeypatch):
    # It used to run to its end (about 100 s and 4 GB for 8192x8192 on 2 cores), its image thrown
    # away: a page's Stop, a reload or a mistyped size held a generation thread all that time.
    server = live_server.app.state.server
    model_id, _, _ = fitted
    calls, check = [], server.unless_stopping

    def progress(*args):
        try:
            check(*args)
        except Exception as exc:
            calls.append(exc)
            raise
        calls.append(args)

    monkeypatch.setattr(server, "unless_stopping", progress)
    with pytest.raises(httpx.TimeoutException):  # the client gives up while the image is being made
        httpx.post(f"{live_server.url}/api/models/{model_id}/images", json={"size": [2048, 2048], "seed": 1},
                   timeout=1)
    deadline = time.monotonic() + 120
    while not (calls and isinstance(calls[-1], Exception)):
        assert time.monotonic() < deadline, "the running generation did not stop"
        time.sleep(0.05)
    assert len(calls) > 1 and str(calls[-1]) == "the work was dropped"  # stopped between two of its stages
    monkeypatch.undo()
    r = client.post(f"/api/models/{model_id}/images", json={"size": [16, 16], "seed": 3})
    assert r.status_code == 200  # the thread serves the next request


def test_a_client_that_drops_mid_upload_is_dropped_quietly(client, fitted, live_server):
    import logging
    import socket

    model_id, _, _ = fitted
    records = []
    handler = logging.Handler(logging.WARNING)
    handler.emit = records.append
    logger = logging.getLogger("uvicorn.error")  # where uvicorn logs "Exception in ASGI application"
    logger.addHandler(handler)
    port = int(live_server.url.rsplit(":", 1)[1])
    try:
        for path in ("/api/models/upload", f"/api/models/{model_id}/inpaint", f"/api/models/{model_id}/images"):
            with socket.create_connection(("127.0.0.1", port), timeout=10) as s:  # 3 of 10 bytes, then gone
                s.sendall(f"POST {path} HTTP/1.1\r\nHost: x\r\nContent-Length: 10\r\n\r\nabc".encode())
                time.sleep(0.2)
        time.sleep(0.5)
    finally:
        logger.removeHandler(handler)
    assert [r.getMessage() for r in records] == []
    assert client.get("/api").status_code == 200  # the server goes on


def test_bad_inputs_get_one_line_and_their_status(client, fitted, live_server):
    model_id, _, _ = fitted
    before = model_files(live_server.cache)
    post = client.post
    # 413: over the exemplar pixel limit (the CLI's words), over 50 MB
    message = assert_error(post("/api/models", files={"image": ("big.png", png_header(9000, 9000))}), 413,
                           "big.png: the image is 9000x9000 pixels, more than the 67,108,864 tghop reads")
    assert "tghop-upload" not in message
    assert_error(post("/api/models", files={"image": ("huge.png", b"\0" * (50 * 1024 * 1024 + 10))}), 413, "50 MB")
    assert_error(post("/api/models/upload", content=b"\0" * (50 * 1024 * 1024 + 10)), 413, "50 MB")
    # 400: a decompression bomb, not an image, no exemplar, a flat one, an unknown built-in, corrupt models
    assert_error(post("/api/models", files={"image": ("bomb.png", png_header(30000, 30000))}), 400,
                 "bomb.png", "too many pixels")
    assert_error(post("/api/models", files={"image": ("notes.txt", b"hello")}), 400, "notes.txt: not a readable image")
    from PIL import Image

    cut = io.BytesIO()  # 0.58: "(truncated or corrupt: OSError: ...); give a PNG, JPEG or other common image file"
    Image.frombytes("RGB", (64, 64), bytes(range(256)) * 48).save(cut, format="TGA")
    assert_error(post("/api/models", files={"image": ("cut.tga", cut.getvalue()[:5000])}), 400,
                 "cut.tga: not a readable image (a TGA file, cut short (", "; save or download it again")
    assert_error(post("/api/models", files={"n_clusters": (None, "8")}), 400, "no exemplar")
    assert_error(post("/api/models", data={"builtin": "bricks"}), 400, "multipart")
    assert_error(post("/api/models", files={"builtin": (None, "marble")}), 400, "unknown built-in exemplar")
    from PIL import Image

    flat = io.BytesIO()
    Image.new("RGB", (64, 64), (120, 120, 120)).save(flat, format="PNG")
    assert_error(post("/api/models", files={"image": ("flat.png", flat.getvalue())}), 400, "no texture")
    # Too small for the settings: the smallest that works (it said "at least 32x32" to a 40x40 image).
    # Its fixes in the page's words (0.63; 0.62: "N of at most 2 (n_clusters)", the page's field "clusters (N)").
    assert_error(post("/api/models", files={"image": ("small.png", exemplar_png(40))}), 400,
                 "40x40 pixels", "at least 44x44", "N of at most 2 (the field clusters (N); the API's n_clusters)")
    good = client.get(f"/api/models/{model_id}/file").content
    assert_error(post("/api/models/upload", files={"model": ("cut.npz", good[: len(good) // 2])}), 400,
                 "cut.npz: truncated, corrupt")
    message = assert_error(post("/api/models/upload", files={"model": ("pic.npz", exemplar_png(40))}), 400,
                           "pic.npz is an image, not a model file; to fit a model from it, pick it as the exemplar "
                           "(the API: POST it to /api/models as the file field 'image')")
    assert "tghop fit" not in message  # a command line's advice means nothing to a web client
    # The field `model` alone, as docs/serve.md says (0.62 took a file field of any name: `other`).
    assert_error(post("/api/models/upload", files={"other": ("mine.npz", good)}), 400,
                 "no model file (a file came as 'other'): send it as the file field 'model' (or as the whole body)")
    assert_error(post("/api/models/upload", content=exemplar_png(40)), 400, "the upload is an image", "/api/models")
    # 0.62: the page's fix first ("send a model file written by 'tghop fit'" before)
    assert_error(post("/api/models/upload", content=b""), 400, "the upload is empty; pick a model file downloaded "
                 "from this page (Download model) or written by tghop fit")
    # 422: settings out of range, sizes over the output limit
    assert_error(post("/api/models", files={"builtin": (None, "bricks"), "n_clusters": (None, "0")}), 422,
                 "(the API's n_clusters) must be")
    assert_error(post("/api/models", files={"builtin": (None, "bricks"), "colour": (None, "1")}), 422,
                 "unknown fit setting 'colour'")
    images = f"/api/models/{model_id}/images"
    assert_error(post(images, json={"size": [10000, 10000]}), 422, "above the limit of 67,108,864")
    assert_error(post(images, json={"size": [0, 5]}), 422, "size must be positive")
    assert_error(post(images, json={"size": [64, 64], "refine": 99}), 422, "refine must be")
    assert_error(post(images, json={"size": [64, 64], "seed": -1}), 422, "seed")
    assert_error(post(images, json={"size": [64, 64], "zoom": 2}), 422, "unknown setting 'zoom'")
    assert_error(post(images, json={"size": [64, 64], "pool_per_block": 1e308}), 422, "pool_per_block must be")
    assert_error(post(images, json={"size": [64, 64], "layout_weight": 1e100}), 422, "layout_weight must be")
    assert_error(post(images, json={"size": [64, 64], "flat_share": 1}), 422, "flat_share must be")
    assert_error(post(images, json={"size": [64, 64], "layout_patch_refine": -1}), 422, "layout_patch_refine must be")
    assert_error(post(images, content=b"[" * 100_000 + b"]" * 100_000), 400, "not JSON")  # nested too deep
    assert_error(post(images, content=b"{not json"), 400, "not JSON")
    assert_error(post(images, content=b'{"size": [64, 64], "size": [96, 96]}'), 400,  # 0.58: the last one, silently
                 "the body gives the key 'size' twice; send each key once")
    # 404: no such model, job, or path; never a file outside the static folder and the cache
    missing = "0" * 64
    # 0.62: what may have happened and the page's fix (0.61: the whole id, "fit one with POST /api/models")
    gone = (f"no model {missing[:12]}... on the server (never made here, or its fit has not ended, or its cache "
            "dropped it); pick its exemplar again to fit it (the API: POST /api/models)")
    assert_error(client.get(f"/api/models/{missing}"), 404, gone)
    assert_error(client.get(f"/api/models/{missing}/file"), 404, gone)
    assert_error(post(f"/api/models/{missing}/images", json={"size": [8, 8]}), 404, "no model")
    assert_error(client.get("/api/models/..%2F..%2Fetc%2Fpasswd"), 404)
    assert_error(client.get("/api/jobs/nope"), 404, "no job")
    assert_error(client.delete("/api/jobs/" + "a" * 32), 404, "no job")
    for path in ("/static/../app.py", "/static/%2e%2e/app.py", "/static/..%2fapp.py", "/nothing"):
        assert client.get(path).status_code == 404, path
    # nothing was written, nothing half-written is left
    assert model_files(live_server.cache) == before
    assert all(name.endswith(".npz") and not name.startswith(".") for name in before)


def test_a_damaged_model_file_is_told_to_be_fitted_again_in_the_pages_words(client, fitted):
    # 0.61 gave the command line's fix, the temporary file's path replaced by the upload's name: "tghop fit EXEMPLAR
    # -o mine.npz", and "-o the upload" for a body without a name
    import numpy as np

    model_id, _, _ = fitted
    with np.load(io.BytesIO(client.get(f"/api/models/{model_id}/file").content)) as data:
        arrays = {name: data[name] for name in data.files if name != "ichm_ii.mixing"}
    damaged = io.BytesIO()
    np.savez(damaged, **arrays)
    named = assert_error(client.post("/api/models/upload", files={"model": ("mine.npz", damaged.getvalue())}), 400,
                         "mine.npz: this model file was edited, damaged or written by another program",
                         "fit the model again from its exemplar: on this page, pick its exemplar (Pick an image...), "
                         "or run tghop fit EXEMPLAR -o mine.npz (what is wrong: ")
    unnamed = assert_error(client.post("/api/models/upload", content=damaged.getvalue()), 400,
                           "the upload: this model file", "or run tghop fit EXEMPLAR -o MODEL.npz (what is wrong: ")
    assert "-o the upload" not in unnamed and "tmp" not in named + unnamed


def fit_with(client, **fields):
    """POST /api/models of builtin:bricks with these form fields."""
    return client.post("/api/models", files={"builtin": (None, "bricks"), **{k: (None, v) for k, v in fields.items()}})


def test_a_fit_field_that_does_not_parse_is_named(client):
    # The page's field first, then the API's name, as the fit's messages name them (0.63; 0.62: "n_clusters: ...")
    assert_error(fit_with(client, n_clusters="abc"), 422,
                 "the field clusters (N) (the API's n_clusters): 'abc' is not an integer (or auto)")
    assert_error(fit_with(client, gamma_mode="xyz"), 422, "gamma_mode: 'xyz' is not one of 'absolute', 'relative'")
    assert_error(fit_with(client, stride="1.5"), 422, "stride: '1.5' is not an integer")
    assert_error(fit_with(client, layout_factor="abc"), 422, "layout_factor: 'abc' is not an integer (or none)")
    assert_error(fit_with(client, k1="abc"), 422, "k1: 'abc' is not a channel count; give a count")
    # a value out of range named Python's None, where the form writes auto (its field's placeholder)
    assert_error(fit_with(client, n_clusters="0"), 422,
                 "the field clusters (N) (the API's n_clusters) must be an integer >= 1 or auto, got 0")
    assert_error(fit_with(client, n_clusters="99999"), 422,
                 "the field clusters (N) (the API's n_clusters): 99999 is more than the server allows; give at most "
                 "5,000")
    for name, field in (("n_clusters", "clusters (N)"), ("n_codewords", "codewords (W)"),
                        ("max_patches", "training patches")):  # 0.62 named the API's name alone
        assert_error(fit_with(client, **{name: "1" * 100_000}), 422,
                     f"the field {field} (the API's {name}): '{'1' * 40}'... is 100,000 characters, too long for a "
                     "setting; give a value of at most 64 characters")
    # out of the image's range: refused before a job starts (the job failed), in the API's name
    message = assert_error(fit_with(client, k1="100000"), 422, "K1 (k1) is 100000, but hop 1 of an exemplar of 3 ")
    assert "--k1" not in message
    for value in ("x" * 5000, "9" * 1000):  # not the whole value back
        message = assert_error(fit_with(client, n_bins=value), 422, f"n_bins: '{value[:9]}")
        assert len(message) < 200


def test_a_fit_at_a_working_scale(client):
    body = fit_with(client, **FAST_FIT, scale="0.75").json()
    assert events(client, body["job"])[-1][1]["state"] == "done"
    summary = client.get(f"/api/models/{body['id']}").json()
    assert summary["params"]["scale"] == 0.75 and summary["exemplar_shape"][:2] == [192, 192]
    assert_error(fit_with(client, scale="0"), 422, "scale must be a finite number > 0 and <= 4, got 0.0")
    assert_error(fit_with(client, scale="half"), 422, "scale: 'half' is not a number")


def test_fit_fields_that_do_not_go_together_are_named_as_the_apis_fields(client):
    for fields, words in (({"patch_size": "7"}, "patch_size 7 needs k1 and k2 (defaults exist for 32 and 64)"),
                          ({"k3": "3"}, "k3 applies to patch_size 64 only")):
        message = assert_error(fit_with(client, **fields), 422, words)
        assert "--" not in message  # the command line's options are not the API's
    from tghop._errors import TGHopError
    from tghop.fit_options import fit_params

    with pytest.raises(TGHopError, match="--patch-size 7 needs --k1 and --k2"):  # the command line keeps its words
        fit_params({"patch_size": 7})


def test_a_file_where_a_fit_takes_a_plain_field_is_refused(client):
    post = client.post
    message = assert_error(post("/api/models", files={"builtin": ("b.png", b"secret bytes")}), 400,
                           "the field 'builtin' must be a plain field", "send a file as 'image'")
    assert "secret" not in message  # not the file, taken as a name
    for name in ("n_clusters", "colour"):  # they were dropped, and the fit ran without them
        files = [("builtin", (None, "bricks")), (name, ("x.txt", b"0"))]
        assert_error(post("/api/models", files=files), 422, name)


def test_a_form_field_given_twice_is_refused(client):
    files = [("builtin", (None, "bricks")), ("n_clusters", (None, "0")), ("n_clusters", (None, "8"))]
    assert_error(client.post("/api/models", files=files), 400, "the field 'n_clusters' is given twice; send it once")


def test_an_integer_setting_given_a_float_is_refused_as_seed_and_size_are(client):
    images = f"/api/models/{'0' * 64}/images"  # the body is checked before the model is looked up
    assert_error(client.post(images, json={"refine": 5.0}), 422, "refine must be an integer", "got 5.0; write 5")
    assert_error(client.post(images, json={"overlap": 8.0}), 422, "overlap must be an integer >= 1 or null")
    # JSON's null, not Python's None, for a value out of range too
    assert_error(client.post(images, json={"region": 1}), 422, "region must be an integer >= 256 or null, got 1")
    assert_error(client.post("/api/images/guided", json={"models": ["0" * 64] * 2, "n_patches": 400.0}), 422,
                 "n_patches must be an integer")
    assert_error(client.post(images, json={"refine": 5, "tolerance": 1}), 404, "no model")  # 1 is a number


def test_a_boolean_setting_is_asked_for_in_jsons_words(client):
    images = f"/api/models/{'0' * 64}/images"
    for value in ("yes", "True", 1.0, 2):
        message = assert_error(client.post(images, json={"tile": value}), 422, "tile must be true or false")
        assert "True or False" not in message  # Python's words; JSON writes true
    assert_error(client.post(images, json={"tile": True, "match_colours": 0}), 404, "no model")
    # paper (and co-occurrence's windows) take what the settings table's booleans take: JSON's words, null the default
    for value in ("yes", "false", "1", 2, 1.0):
        assert_error(client.post(images, json={"paper": value}), 422, "paper must be true or false (a JSON boolean)")
    for body in ({"paper": None, "tile": None, "seed": None}, {"paper": 1, "tile": 0}, {"paper": False}):
        assert_error(client.post(images, json=body), 404, "no model")
    from tghop.server.cooc import _common
    from tghop.server.requests import RequestError

    assert _common({"windows": None}) == (None, False) and _common({"windows": True}) == (None, True)
    with pytest.raises(RequestError, match="windows must be true or false"):
        _common({"windows": "yes"})


def test_a_form_boolean_is_the_json_rule_and_an_empty_field_is_false():
    from tghop.server.requests import RequestError, parse_bool

    assert parse_bool("paper", "") is False and parse_bool("paper", " ") is False  # an unset form field
    assert parse_bool("tile", "true") is True and parse_bool("tile", " False ") is False
    assert parse_bool("tile", "1") is True and parse_bool("tile", "0") is False
    for word in ("maybe", "yes", "no", "on", "off", "2", "1.0"):  # what a JSON body refuses
        expected = re.escape(f"tile must be true or false (or 1 or 0), got {word!r}")
        with pytest.raises(RequestError, match=expected) as info:
            parse_bool("tile", word)
        assert info.value.status == 422


def test_a_boolean_is_one_rule_in_a_form_and_in_json(client):
    """paper=yes was taken as a form field and refused in JSON: now true or false (or 1 or 0) in both,
    yes/no/on/off refused by both; an empty field or a null, the default."""
    images, inpaint = f"/api/models/{'0' * 64}/images", f"/api/models/{'0' * 64}/inpaint"
    for word in ("yes", "no", "on", "off"):
        assert_error(client.post(images, json={"paper": word}), 422, "paper must be true or false")
        assert_error(client.post("/api/models", files={"builtin": (None, "bricks"), "paper": (None, word)}), 422,
                     f"paper must be true or false (or 1 or 0), got {word!r}")
        assert_error(client.post("/api/models", files={"builtin": (None, "bricks"), "residual": (None, word)}), 422,
                     f"residual must be true or false (or 1 or 0), got {word!r}")
        fill = {"image": ("a.png", b"x"), "mask": ("m.png", b"x"), "tile": (None, word)}
        assert_error(client.post(inpaint, files=fill), 422, f"tile must be true or false (or 1 or 0), got {word!r}")
    for word, value in (("true", True), ("0", False)):  # JSON's own literals, or 1 or 0, in both
        assert_error(client.post(images, json={"paper": value}), 404, "no model")
        fill = {"image": ("a.png", b"x"), "mask": ("m.png", b"x"), "tile": (None, word)}
        assert_error(client.post(inpaint, files=fill), 404, "no model")


def test_a_body_that_is_not_a_form_is_told_what_the_route_takes(client):
    message = assert_error(client.post(f"/api/models/{'0' * 64}/inpaint", json={"seed": 1}), 400,
                           "multipart/form-data", "'image' and 'mask'")
    assert "builtin" not in message
    assert_error(client.post("/api/models", json={"builtin": "bricks"}), 400, "multipart/form-data", "'builtin' name")


def png_of(pixels):
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(pixels).save(buf, format="PNG")
    return buf.getvalue()


def decoded(content):
    import numpy as np
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(content)).convert("RGB"))


@pytest.fixture(scope="module")
def to_fill(client, fitted):
    """A generated image (PNG bytes) and a mask (PNG bytes, a white square) of its size."""
    import numpy as np

    model_id, _, _ = fitted
    r = client.post(f"/api/models/{model_id}/images", json={"size": [64, 80], "seed": 2, "n_patches": 400})
    assert r.status_code == 200, r.text
    hole = np.zeros((64, 80), np.uint8)
    hole[20:44, 28:56] = 255
    return r.content, png_of(hole), hole > 0


def inpaint_ask(fitted, to_fill, seed):
    """``(url, fields)``: an inpaint of :func:`to_fill`'s picture and mask by :func:`fitted`'s model with ``seed``."""
    model_id, _, _ = fitted
    image, mask, _ = to_fill
    return f"/api/models/{model_id}/inpaint", {"image": ("generated.png", image, "image/png"),
                                                "mask": ("mask.png", mask, "image/png"), "seed": (None, seed)}


def test_inpaint_keeps_the_pixels_outside_the_mask_and_fills_the_inside(client, fitted, to_fill):
    image, _, hole = to_fill
    url, ask = inpaint_ask(fitted, to_fill, "3")
    a = client.post(url, files=ask)
    assert a.status_code == 200, a.text
    assert a.headers["content-type"] == "image/png" and a.headers["x-tghop-seed"] == "3"
    before, after = decoded(image), decoded(a.content)
    assert after.shape == before.shape
    assert (after[~hole] == before[~hole]).all()  # every pixel outside the hole, byte for byte
    assert (after[hole] != before[hole]).any(axis=1).mean() > 0.5
    assert client.post(url, files=ask).content == a.content  # same seed, same bytes
    other = client.post(url, files={**ask, "seed": (None, "4")})
    assert other.status_code == 200 and other.content != a.content
    assert (decoded(other.content)[~hole] == before[~hole]).all()
    tiled = client.post(url, files={**ask, "tile": (None, "true")})
    assert tiled.status_code == 200 and (decoded(tiled.content)[~hole] == before[~hole]).all()
    jpeg = io.BytesIO()  # a JPEG picture: its decoded pixels are kept
    from PIL import Image

    Image.open(io.BytesIO(image)).save(jpeg, format="JPEG", quality=90)
    j = client.post(url, files={**ask, "image": ("photo.jpg", jpeg.getvalue(), "image/jpeg")})
    assert j.status_code == 200, j.text
    assert (decoded(j.content)[~hole] == decoded(jpeg.getvalue())[~hole]).all()
    unseeded = client.post(url, files={k: v for k, v in ask.items() if k != "seed"})
    assert unseeded.status_code == 200 and int(unseeded.headers["x-tghop-seed"]) >= 0


def test_inpaint_keeps_alpha_and_16_bits_as_tghop_inpaint_does(client, fitted, to_fill, live_server, tmp_path):
    import numpy as np
    from click.testing import CliRunner
    from PIL import Image

    from tghop.cli import main
    from tghop.imageio import load_image, write_png

    model_id, _, _ = fitted
    image, mask, hole = to_fill
    url = f"/api/models/{model_id}/inpaint"
    rgb = decoded(image)
    alpha = np.tile((np.arange(80) * 3).astype(np.uint8), (64, 1))[..., None]
    rgba = np.concatenate([rgb, alpha], axis=2)
    (tmp_path / "rgba.png").write_bytes(png_of(rgba))
    (tmp_path / "mask.png").write_bytes(mask)
    r = client.post(url, files={"image": ("rgba.png", png_of(rgba)), "mask": ("mask.png", mask), "seed": (None, "3")})
    assert r.status_code == 200, r.text
    out = Image.open(io.BytesIO(r.content))
    assert out.mode == "RGBA"
    out = np.asarray(out)
    assert (out[~hole] == rgba[~hole]).all() and (out[hole][:, 3] == 255).all()  # opaque in the hole
    cli = CliRunner().invoke(main, ["inpaint", str(tmp_path / "rgba.png"), str(tmp_path / "mask.png"), "--seed", "3",
                                    "--source", str(live_server.cache / "models" / f"{model_id}.npz"), "-q",
                                    "-o", str(tmp_path / "cli.png")])
    assert cli.exit_code == 0, cli.output
    assert (np.asarray(Image.open(tmp_path / "cli.png")) == out).all()  # the command's very pixels
    # 16 bits per channel: a 16-bit PNG, every pixel outside the hole the same 16-bit levels
    deep = np.minimum(rgb.astype(np.uint16) * 257 + np.arange(80, dtype=np.uint16)[None, :, None], 65535)
    buf = io.BytesIO()
    write_png(buf, deep.astype(np.uint16))
    r = client.post(url, files={"image": ("deep.png", buf.getvalue()), "mask": ("mask.png", mask), "seed": (None, "3")})
    assert r.status_code == 200, r.text
    assert r.content[24:26] == bytes([16, 2])  # IHDR: 16 bits, RGB
    (tmp_path / "out16.png").write_bytes(r.content)
    levels = np.round(load_image(tmp_path / "out16.png", dtype=None) * 65535).astype(np.uint16)
    assert (levels[~hole] == deep[~hole]).all() and (levels[hole] != deep[hole]).any(axis=1).mean() > 0.5


def test_inpaint_bad_inputs_get_one_line_and_their_status(client, fitted, to_fill, live_server):
    import numpy as np

    model_id, _, _ = fitted
    image, mask, _ = to_fill
    url = f"/api/models/{model_id}/inpaint"
    good = {"image": ("generated.png", image, "image/png"), "mask": ("mask.png", mask, "image/png")}
    post = client.post
    # 400: not an image, a mask of another size, a picture too small for the model's patches, no mask
    assert_error(post(url, files={**good, "image": ("notes.txt", b"hello")}), 400, "notes.txt: not a readable image")
    assert_error(post(url, files={**good, "mask": ("mask.txt", b"hello")}), 400, "mask.txt: not a readable image")
    small = png_of(np.zeros((32, 40), np.uint8))
    assert_error(post(url, files={**good, "mask": ("small.png", small)}), 400,  # 0.62: named, no (H, W) arrays
                 "the mask small.png is 32x40 but the picture ", " is 64x80; give a mask of the picture's size")
    tiny = png_of(np.full((4, 4, 3), 128, np.uint8))
    tiny_hole = png_of(np.full((4, 4), 255, np.uint8))
    assert_error(post(url, files={"image": ("tiny.png", tiny), "mask": ("m.png", tiny_hole)}), 400,  # 0.61: "use a
                 "the picture tiny.png is 4x4, smaller than the model's 32x32 patches; use a picture of at least "
                 "32x32, or grow it first (Extend)")  # model fitted with a smaller patch_size", no field of the page
    assert_error(post(url, files={"image": good["image"]}), 400, "no mask")
    black = png_of(np.zeros((64, 80), np.uint8))  # as tghop inpaint: an all-black mask has nothing to fill
    assert_error(post(url, files={**good, "mask": ("black.png", black)}), 400,
                 "the mask black.png has no white pixel, so there is nothing to fill; paint the hole white")
    assert_error(post(url, data={"seed": "1"}), 400, "multipart")
    # 413: over the pixel limit, over 50 MB
    assert_error(post(url, files={**good, "image": ("big.png", png_header(9000, 9000))}), 413,
                 "big.png: the image is 9000x9000 pixels")
    assert_error(post(url, files={**good, "image": ("huge.png", b"\0" * (50 * 1024 * 1024 + 10))}), 413, "50 MB")
    # 422: a bad seed or tile, an unknown field
    for seed in ("-1", "x", "1.5", str(2**63)):
        assert_error(post(url, files={**good, "seed": (None, seed)}), 422, "seed must be")
    assert_error(post(url, files={**good, "tile": (None, "maybe")}), 422, "tile must be true or false")
    assert_error(post(url, files={**good, "refine": (None, "2")}), 422, "unknown field 'refine'")
    # 404: no such model
    assert_error(post(f"/api/models/{'0' * 64}/inpaint", files=good), 404, "no model")
    assert_error(post("/api/models/nope/inpaint", files=good), 404, "no model")


def test_extend_grows_the_picture_as_tghop_extend_does(client, fitted, to_fill, live_server, tmp_path):
    import numpy as np
    from click.testing import CliRunner
    from PIL import Image

    from tghop.cli import main

    model_id, _, _ = fitted
    image, _, _ = to_fill  # 64x80
    url = f"/api/models/{model_id}/extend"
    ask = {"image": ("generated.png", image, "image/png"), "size": (None, "96x120"), "anchor": (None, "top-right"),
           "seed": (None, "3")}
    r = client.post(url, files=ask)
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "image/png" and r.headers["x-tghop-seed"] == "3"
    out = decoded(r.content)
    assert out.shape == (96, 120, 3) and (out[:64, 40:] == decoded(image)).all()
    assert out[64:].reshape(-1, 3).std(axis=0).min() > 5  # texture in the new area
    (tmp_path / "in.png").write_bytes(image)
    model_file = str(live_server.cache / "models" / f"{model_id}.npz")
    cli = CliRunner().invoke(main, ["extend", str(tmp_path / "in.png"), "--size", "96x120", "--anchor", "top-right",
                                    "--seed", "3", "-q", "--source", model_file, "-o", str(tmp_path / "c.png")])
    assert cli.exit_code == 0, cli.output
    assert (np.asarray(Image.open(tmp_path / "c.png")) == out).all()  # the command's very pixels
    centred = client.post(url, files={k: v for k, v in ask.items() if k != "anchor"})  # center by default
    assert centred.status_code == 200 and (decoded(centred.content)[16:80, 20:100] == decoded(image)).all()
    post = client.post
    # 0.62: in the page's words (0.61: the library's, "the size 60x80 is smaller than the image (64x80) in height",
    # "nothing to extend", "... or use a model fitted with a smaller patch_size")
    for size in ("60x80", "64x80"):
        assert_error(post(url, files={**ask, "size": (None, size)}), 400, " is 64x80; grow it to a size of at least "
                     f"64x80, larger in one (asked: {size})")
    strip = png_of(np.full((8, 50, 3), 128, np.uint8))
    message = assert_error(post(url, files={**ask, "image": ("strip.png", strip), "size": (None, "8x400")}), 400,
                           "the picture strip.png (8x50) grown to 8x400 is thinner than the model's 32x32 patches; "
                           "grow it to at least 32x400")
    assert "patch_size" not in message
    # 0.60: "size must be HEIGHTxWIDTH in pixels, e.g. 512x1024, got ''" of no size, and "size, anchor, seed, tile:
    # plain fields, not files" of one sent as a file
    assert_error(post(url, files={k: v for k, v in ask.items() if k != "size"}), 422,
                 "the field 'size' is missing: send the size to grow the picture to, HEIGHTxWIDTH")
    assert_error(post(url, files={**ask, "size": (None, "big")}), 422, "size must be HEIGHTxWIDTH", "got 'big'")
    assert_error(post(url, files={**ask, "seed": ("seed.txt", b"3")}), 422,
                 "the field 'seed' is sent as a file; send it as a plain field (text)")
    assert_error(post(url, files={**ask, "size": (None, "9000x9000")}), 422, "size")
    assert_error(post(url, files={**ask, "anchor": (None, "middle")}), 422, "anchor must be one of center, top")
    assert_error(post(url, files={**ask, "mask": ("m.png", image)}), 422, "unknown field 'mask'")
    assert_error(post(url, files={"size": (None, "96x120")}), 400, "no image")


def test_fill_k_is_tghop_inpaint_counts_kth_fill(client, fitted, to_fill, live_server, tmp_path):
    # 0.60's page numbered a strip's fills by seed (s, s + 1, ...), each a Fill of its own seed, where tghop inpaint
    # --seed s --count N draws N fills from one generator and names them out_1.png ... out_N.png: the field fill k
    # (0.61) is the command's k-th, from fill k - 1's generator when the server kept it, else drawn again.
    import numpy as np
    from click.testing import CliRunner
    from PIL import Image

    from tghop.cli import main

    model_id, _, _ = fitted
    image, mask, _ = to_fill
    url, ask = inpaint_ask(fitted, to_fill, "5")
    fills, states, went_on = [], live_server.app.state.server.fill_states, []
    states.after = lambda key, k, after=states.after: went_on.append(after(key, k)) or went_on[-1]
    try:
        for k in (1, 2, 3):
            r = client.post(url, files={**ask, "fill": (None, str(k))})
            assert r.status_code == 200, r.text
            assert r.headers["x-tghop-seed"] == "5" and r.headers["x-tghop-fill"] == str(k)
            fills.append(r.content)
    finally:
        del states.after
    assert [j for j, _ in went_on] == [0, 1, 2]  # each from the fill before's generator: one fill each
    assert len(set(fills)) == 3 and client.post(url, files=ask).content == fills[0]  # fill 1 is a plain fill's
    (tmp_path / "in.png").write_bytes(image)
    (tmp_path / "hole.png").write_bytes(mask)
    model_file = str(live_server.cache / "models" / f"{model_id}.npz")
    cli = CliRunner().invoke(main, ["inpaint", str(tmp_path / "in.png"), str(tmp_path / "hole.png"), "--seed", "5",
                                    "--count", "3", "-q", "--source", model_file, "-o", str(tmp_path / "out.png")])
    assert cli.exit_code == 0, cli.output
    for k, body in enumerate(fills, start=1):
        assert (np.asarray(Image.open(tmp_path / f"out_{k}.png")) == decoded(body)).all(), k  # the command's pixels
    # the same picture in other bytes (another PNG writer's): no fill of it kept, fill 3 drawn after 1 and 2 again
    other = png_of(decoded(image))
    assert other != image
    again = client.post(url, files={**ask, "image": ("again.png", other, "image/png"), "fill": (None, "3")})
    assert again.status_code == 200 and (decoded(again.content) == decoded(fills[2])).all()
    for bad in ("0", "9", "x", "1.5"):
        assert_error(client.post(url, files={**ask, "fill": (None, bad)}), 422, "fill must be an integer from 1 to 8")

# ------------------------------------------------------------------ quality, several models
@pytest.fixture(scope="module")
def second(client):
    """A second fitted model: builtin:cells with the fast settings (its id)."""
    r = client.post("/api/models", files={"builtin": (None, "cells"), **{k: (None, v) for k, v in FAST_FIT.items()}})
    assert r.status_code in (200, 202), r.text
    stream = events(client, r.json()["job"])
    assert stream[-1][1]["state"] == "done", stream[-3:]
    return r.json()["id"]


def test_quality_best_adds_the_patch_refinement(client, fitted):
    model_id, _, _ = fitted
    url = f"/api/models/{model_id}/images"
    ask = {"size": [40, 40], "seed": 2, "n_patches": 300}
    default = client.post(url, json=ask)
    best = client.post(url, json={**ask, "quality": "best"})
    assert default.status_code == best.status_code == 200, best.text
    assert decoded(best.content).shape == (40, 40, 3) and best.content != default.content
    assert client.post(url, json={**ask, "quality": "default"}).content == default.content
    # a setting given as well overrides the preset, as with tghop synth --quality
    assert client.post(url, json={**ask, "quality": "best", "patch_refine": 0}).content == \
        client.post(url, json={**ask, "patch_refine": 0}).content
    for bad in ("great", 1, None, ["best"]):
        assert_error(client.post(url, json={**ask, "quality": bad}), 422, "quality must be one of 'best', 'default'")
    # a model without patch statistics: said, as tghop synth says it
    r = client.post("/api/models", files={"builtin": (None, "bricks"), "patch_levels": (None, "0"),
                                          **{k: (None, v) for k, v in FAST_FIT.items()}})
    assert events(client, r.json()["job"])[-1][1]["state"] == "done"
    flat = f"/api/models/{r.json()['id']}/images"
    assert client.post(flat, json=ask).status_code == 200
    assert_error(client.post(flat, json={**ask, "quality": "best"}), 422, "no patch statistics", "fit it again")
    # the summary says so (0.61; the page's quality menu offers best only where it applies): a material's albedo's too
    assert client.get(flat[:-len("/images")]).json()["patch_levels"] == 0
    assert client.get(f"/api/models/{model_id}").json()["patch_levels"] > 0


def guide_b64(pixels, prefix=""):
    import base64

    return prefix + base64.b64encode(png_of(pixels)).decode()


def closer(region, to, other):
    """Whether the region's mean colour is nearer ``to``'s than ``other``'s."""
    import numpy as np

    mean = region.reshape(-1, 3).mean(axis=0)
    return np.abs(mean - to.reshape(-1, 3).mean(axis=0)).sum() < np.abs(mean - other.reshape(-1, 3).mean(axis=0)).sum()


def test_guided_paints_each_model_in_its_region_and_remixes_without_a_guide(client, fitted, second):
    import numpy as np

    bricks, cells = fitted[0], second
    alone = {m: decoded(client.post(f"/api/models/{m}/images", json={"size": [64, 96], "seed": 1,
                                                                     "n_patches": 400}).content)
             for m in (bricks, cells)}
    guide = np.zeros((64, 96), np.uint8)
    guide[:, 48:] = 255  # the right half light: the second model
    ask = {"models": [bricks, cells], "guide": guide_b64(guide), "seed": 3, "n_patches": 400, "transition": 8}
    r = client.post("/api/images/guided", json=ask)
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "image/png" and r.headers["x-tghop-size"] == "64x96"
    image = decoded(r.content)
    assert image.shape == (64, 96, 3)
    assert closer(image[:, :40], alone[bricks], alone[cells]) and closer(image[:, 56:], alone[cells], alone[bricks])
    # the same request gives the same bytes; a data: URL and a size that agrees are taken too
    again = client.post("/api/images/guided", json={**ask, "guide": guide_b64(guide, "data:image/png;base64,"),
                                                     "size": [64, 96]})
    assert again.content == r.content
    swapped = decoded(client.post("/api/images/guided", json={**ask, "models": [cells, bricks]}).content)
    assert closer(swapped[:, :40], alone[cells], alone[bricks])
    # each region is its model's own synthesis: one model's settings apply (refused up to 0.49.2)
    refined = client.post("/api/images/guided", json={**ask, "patch_refine": 2, "patch_stride": 1})
    assert refined.status_code == 200 and refined.content != r.content, refined.text
    remix = client.post("/api/images/guided", json={"models": [bricks, cells], "size": [48, 64], "seed": 1,
                                                    "n_patches": 400})
    assert remix.status_code == 200, remix.text
    assert decoded(remix.content).shape == (48, 64, 3) and int(remix.headers["x-tghop-seed"]) == 1


def test_a_guide_scaled_to_the_size_is_read_once_and_the_client_is_told(client, fitted, second, monkeypatch):
    # A guide of another size than `size` (its shape) is scaled by the library with a warning, which went to the
    # server's console, never to the client; and its labels were read twice (a check, then synthesize_guided),
    # so it was scaled twice. Read and scaled once now, the warning the answer's X-Tghop-Warning.
    import warnings

    import numpy as np

    from tghop import guides

    scalings = []
    scale = guides.scale_labels
    monkeypatch.setattr(guides, "scale_labels", lambda *a: scalings.append(a[1]) or scale(*a))
    guide = np.zeros((64, 96), np.uint8)
    guide[:, 48:] = 255
    ask = {"models": [fitted[0], second], "seed": 3, "n_patches": 400, "transition": 8}
    with warnings.catch_warnings(record=True) as console:  # the server's thread runs while this one waits
        warnings.simplefilter("always")
        r = client.post("/api/images/guided", json={**ask, "guide": guide_b64(guide), "size": [32, 48]})
    assert r.status_code == 200, r.text
    assert r.headers["x-tghop-warning"] == ("the guide was scaled from 64x96 to 32x48, the output's size (nearest "
                                            "neighbour: its regions kept as painted)")
    assert r.headers["x-tghop-size"] == "32x48" and decoded(r.content).shape == (32, 48, 3)
    assert [tuple(s) for s in scalings] == [(32, 48)], scalings  # once
    assert not [w for w in console if "the guide was scaled" in str(w.message)]  # the client's, not the console's
    # the same image as the guide painted at that size, which is not scaled and says nothing
    painted = client.post("/api/images/guided", json={**ask, "guide": guide_b64(guide[::2, ::2])})
    assert painted.status_code == 200 and painted.content == r.content, painted.text
    assert "x-tghop-warning" not in painted.headers and len(scalings) == 1
    # a region thinner than a pixel of the output would be gone: said, not the library's "one grey level but 2"
    thin = np.zeros((64, 96), np.uint8)
    thin[:, 48] = 255
    assert_error(client.post("/api/images/guided", json={**ask, "guide": guide_b64(thin), "size": [32, 48]}), 400,
                 "the guide: models[1]'s region is gone once the map is scaled from 64x96 to size 32x48 (it is "
                 "thinner than a pixel of the output); paint it wider or give a larger size")


def test_morph_goes_from_a_to_b(client, fitted, second):
    bricks, cells = fitted[0], second
    alone = {m: decoded(client.post(f"/api/models/{m}/images", json={"size": [40, 64], "seed": 1,
                                                                     "n_patches": 400}).content)
             for m in (bricks, cells)}
    r = client.post("/api/images/morph", json={"a": bricks, "b": cells, "size": [40, 192], "seed": 4,
                                               "n_patches": 400})
    assert r.status_code == 200, r.text
    strip = decoded(r.content)
    assert strip.shape == (40, 192, 3) and r.headers["x-tghop-size"] == "40x192"
    assert closer(strip[:, :32], alone[bricks], alone[cells]) and closer(strip[:, -32:], alone[cells], alone[bricks])
    again = client.post("/api/images/morph", json={"a": bricks, "b": cells, "size": [40, 192], "seed": 4,
                                                   "n_patches": 400})
    assert again.content == r.content and "x-tghop-warning" not in r.headers
    # stations no longer applies: the same strip, and the answer says so
    told = client.post("/api/images/morph", json={"a": bricks, "b": cells, "size": [40, 192], "seed": 4,
                                                  "n_patches": 400, "stations": 5})
    assert told.content == r.content and told.headers["x-tghop-warning"].startswith("stations no longer applies")
    plain = client.post("/api/images/morph", json={"a": bricks, "b": cells, "size": [40, 192], "seed": 4,
                                                   "n_patches": 400, "flat_share": 0})
    assert plain.status_code == 200 and plain.content != r.content  # the setting reaches the morph's quilt


def test_guided_and_morph_bad_inputs_get_one_line_and_their_status(client, fitted, second, live_server, tmp_path):
    import base64

    import numpy as np

    before = model_files(live_server.cache)
    post = client.post
    two = [fitted[0], second]
    half = np.zeros((32, 48), np.uint8)
    half[:, 24:] = 255
    guided, morph = "/api/images/guided", "/api/images/morph"
    # 422: sizes over the limit, settings out of range or unknown, too few or too many models
    assert_error(post(guided, json={"models": two, "size": [10000, 10000]}), 422, "above the limit of 67,108,864")
    assert_error(post(morph, json={"a": two[0], "b": two[1], "size": [9000, 9000]}), 422, "above the limit")
    assert_error(post(morph, json={"a": two[0], "b": two[1], "size": [16, 256]}), 422,
                 "a morph strip must be at least 32 px tall", "give a height of 32 or more")  # whole columns below
    assert_error(post(guided, json={"models": two, "size": [0, 8]}), 422, "size must be positive")
    assert_error(post(guided, json={"models": two[:1], "size": [32, 32]}), 422, "give 2 to 8")
    assert_error(post(guided, json={"models": two * 5, "size": [32, 32]}), 422, "has 10 model ids")
    assert_error(post(guided, json={"models": two[0], "size": [32, 32]}), 422, "models must be a list")
    assert_error(post(guided, json={"size": [32, 32]}), 422, "no models")
    assert_error(post(guided, json={"models": two, "transition": -1}), 422, "transition must be an integer")
    assert_error(post(guided, json={"models": two, "seed": "x"}), 422, "seed must be")
    assert_error(post(guided, json={"models": two, "zoom": 1}), 422, "unknown setting 'zoom'")
    for setting in ("quality", "patch_refine", "region", "own_shares"):  # each region is its model's own synthesis
        assert_error(post(morph, json={"a": two[0], "b": two[1], setting: 1}), 422, f"unknown setting '{setting}'")
    assert_error(post(morph, json={"a": two[0], "size": [32, 64]}), 422, "b must be a model id")
    assert_error(post(morph, json={"a": two[0], "b": two[1], "tile": True}), 422, "unknown setting 'tile'")
    assert_error(post(morph, json={"a": two[0], "b": two[1], "stations": 1}), 422, "stations must be")
    # models of other patch sizes: named as the request names them, and the fit's field (not --patch-size)
    from tghop import TGHop, data
    from tghop.modelfile import save_model

    save_model(TGHop(patch_size=16, n_channels=(9, 22), gamma=0.01, n_clusters=8, n_codewords=40, stride=4,
                     rng=0).fit(data.bricks(64, rng=1)), tmp_path / "p16.npz")
    small = post("/api/models/upload", content=(tmp_path / "p16.npz").read_bytes()).json()["id"]
    # 0.61: "fit them with the same patch_size (a field of POST /api/models)", which the page has not
    words = ("; give models of one patch size: fit both on this page (its fits have 32x32 patches; the API's fit "
             "field patch_size sets another)")
    for response in (post(morph, json={"a": two[0], "b": small, "size": [32, 64]}),
                     post(guided, json={"models": [two[0], small], "size": [32, 32]})):
        message = assert_error(response, 422, "has 16x16 patches but", "has 32x32", words)
        assert "--patch-size" not in message and ("b has 16x16" in message or "models[1] has 16x16" in message)
    (live_server.cache / "models" / f"{small}.npz").unlink()
    # 404: no such model (well formed or not)
    missing = "0" * 64
    assert_error(post(guided, json={"models": [two[0], missing], "size": [32, 32]}), 404, "no model")
    assert_error(post(guided, json={"models": ["../x", two[0]], "size": [32, 32]}), 404, "no model")
    assert_error(post(morph, json={"a": missing, "b": two[1]}), 404, "no model")
    # 400: bad guides (one line), a body that is not JSON or not an object
    assert_error(post(guided, json={"models": two, "guide": "not base64!"}), 400, "guide is not valid base64")
    assert_error(post(guided, json={"models": two, "guide": 7}), 400, "guide must be a PNG as a base64 string")
    assert_error(post(guided, json={"models": two, "guide": base64.b64encode(b"hello").decode()}), 400,
                 "guide.png: not a readable image")
    three = half.copy()
    three[:8] = 128
    assert_error(post(guided, json={"models": two, "guide": guide_b64(three)}), 400,
                 "the guide has 3 distinct grey levels/colours but 2 models")
    assert_error(post(guided, json={"models": two, "guide": guide_b64(half), "size": [48, 48]}), 400,
                 "the guide is 32x48 but the output is 48x48")
    assert_error(post(guided, json={"models": two, "guide": base64.b64encode(png_header(30000, 30000)).decode()}),
                 400, "too many pixels")
    assert_error(post(guided, content=b"{not json"), 400, "not JSON")
    assert_error(post(morph, json=[1, 2]), 400, "JSON object")
    assert model_files(live_server.cache) == before


def test_the_page_and_its_files_are_served(client):
    from tghop.server.app import STATIC

    page = client.get("/")
    assert page.status_code == 200 and "text/html" in page.headers["content-type"]
    scripts = sorted(p.name for p in STATIC.glob("*.js"))
    assert {"app.js", "cooc.js"} <= set(scripts)
    for name in (*scripts, "style.css"):  # every script of the folder is the page's
        assert f"/static/{name}" in page.text
        assert client.get(f"/static/{name}").status_code == 200
    for name in scripts:  # nothing from the network
        assert "http" not in client.get(f"/static/{name}").text.replace("HTTP API", "")
    assert client.get("/api/builtins/bricks.png").content[:4] == b"\x89PNG"
    assert client.get("/api").json()["builtins"] == ["bricks", "cells"]


def test_the_pages_empty_fields_show_the_settings_defaults(client):
    # An empty field sends nothing, so the library's default applies: its placeholder must say which.
    import re

    from tghop.settings import BY_NAME

    page = client.get("/").text
    for name in ("refine", "n_patches"):
        field = re.search(rf'<input [^>]*id="{name}"[^>]*>', page).group(0)
        assert "value=" not in field, field
        assert f'placeholder="{BY_NAME[name].default}"' in field, field


def test_the_pages_morph_height_is_at_least_a_patch(client, fitted, second):
    # The field took 1 px, which the server refuses (422) for a morph lower than a patch: the page's least height
    # is the default patch size, and its script raises it to the patch size of the models' summaries.
    import re

    from tghop.settings import BY_NAME

    patch = BY_NAME["patch_size"].default
    field = re.search(r'<input [^>]*id="morph-height"[^>]*>', client.get("/").text).group(0)
    assert f'min="{patch}"' in field, field
    script = client.get("/static/paint.js").text
    assert f"const DEFAULT_PATCH_SIZE = {patch};" in script and "m.patchSize" in script
    assert "listed.patchSize = s.params.patch_size" in client.get("/static/fit.js").text
    assert client.get(f"/api/models/{second}").json()["params"]["patch_size"] == patch  # what the page reads
    ask = {"a": fitted[0], "b": second, "seed": 1, "n_patches": 400}
    assert_error(client.post("/api/images/morph", json={**ask, "size": [patch - 1, 128]}), 422)
    assert client.post("/api/images/morph", json={**ask, "size": [patch, 128]}).status_code == 200


def test_the_serve_command_prints_its_address_opens_it_and_stops_on_ctrl_c(tmp_path):
    opened = tmp_path / "opened"  # --open: the browser of $BROWSER (Python's webbrowser) gets the address
    browser = f"{sys.executable} -c \"import sys; open(sys.argv[1], 'w').write(sys.argv[2])\" {opened} %s"
    p = subprocess.Popen([sys.executable, "-m", "tghop", "serve", "--port", "0", "--host", "0.0.0.0",
                          "--cache", str(tmp_path / "cache"), "--open"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env={**os.environ, "BROWSER": browser})
    try:
        line = p.stdout.readline()
        assert line.startswith("tghop serving on http://127.0.0.1:"), line
        url = line.split()[3]
        assert httpx.get(url + "api", timeout=30).json()["builtins"] == ["bricks", "cells"]
        deadline = time.monotonic() + 30
        while not (opened.exists() and opened.read_text()):
            assert time.monotonic() < deadline, "--open opened nothing"
            time.sleep(0.05)
        assert opened.read_text() == url
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert "Warning: listening on 0.0.0.0" in err
    assert "Traceback" not in err and p.returncode == 0, err
    assert (tmp_path / "cache" / "models").is_dir()


def test_ctrl_c_during_a_generation_stops_with_one_line_and_answers_json(tmp_path, fitted, live_server):
    import shutil
    import threading

    model_id, _, _ = fitted
    (tmp_path / "cache" / "models").mkdir(parents=True)
    shutil.copy(live_server.cache / "models" / f"{model_id}.npz", tmp_path / "cache" / "models")
    p = subprocess.Popen([sys.executable, "-m", "tghop", "serve", "--port", "0", "--cache", str(tmp_path / "cache"),
                          "--max-fits", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    answers = []
    try:
        url = p.stdout.readline().split()[3]
        asked = threading.Thread(target=lambda: answers.append(httpx.post(
            f"{url}api/models/{model_id}/images", json={"size": [2048, 2048], "seed": 1}, timeout=120)))
        asked.start()
        time.sleep(1.5)  # the generation runs (it takes far longer)
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=60)
        asked.join(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert err.strip().splitlines() == ["tghop server stopped"] and p.returncode == 0, err  # no traceback
    assert_error(answers[0], 503, "the server is stopping")  # JSON, not uvicorn's text 500


def test_concurrent_requests_of_one_seed_get_the_same_bytes(tmp_path, fitted, live_server):
    # `tghop serve` holds its process at one BLAS thread: a request's image no longer depends on
    # the requests beside it (4 threads gave 4 images of one seed in 0.49.0).
    import shutil
    from concurrent.futures import ThreadPoolExecutor

    model_id, _, _ = fitted
    (tmp_path / "cache" / "models").mkdir(parents=True)
    shutil.copy(live_server.cache / "models" / f"{model_id}.npz", tmp_path / "cache" / "models")
    p = subprocess.Popen([sys.executable, "-m", "tghop", "serve", "--port", "0", "--cache", str(tmp_path / "cache")],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = p.stdout.readline().split()[3] + f"api/models/{model_id}/images"

        def ask(_):
            r = httpx.post(url, json={"size": [72, 72], "seed": 1}, timeout=120)
            assert r.status_code == 200, r.text
            return r.content

        alone = ask(0)
        with ThreadPoolExecutor(max_workers=4) as pool:
            together = list(pool.map(ask, range(6)))
    finally:
        p.send_signal(signal.SIGINT)
        try:
            p.communicate(timeout=60)
        finally:
            if p.poll() is None:
                p.kill()
    assert all(image == alone for image in together), [hash(i) for i in [alone, *together]]

def test_a_generation_stops_at_its_next_progress_report_once_the_server_stops(tmp_path, fitted, live_server):
    # What lets `tghop serve` exit at once on Ctrl-C: the generation's progress callback
    # raises once the server is stopping, so the thread ends instead of finishing the image.
    from tghop.server.app import Server
    from tghop.server.requests import RequestError

    model_id, _, _ = fitted
    model = load_model(live_server.cache / "models" / f"{model_id}.npz")
    server = Server(tmp_path / "cache", max_fits=1)
    reports = []

    def progress(stage, done, total):
        reports.append(stage)
        server.unless_stopping(stage, done, total)
        if len(reports) == 2:
            server.stop()

    try:
        with pytest.raises(RequestError) as caught:
            model.synthesize((64, 64), rng=1, progress=progress)
    finally:
        server.executor.shutdown()
    assert caught.value.status == 503 and len(reports) == 3  # stopped at the report after stop()


def test_without_the_web_extra_serve_says_how_to_install_it(tmp_path):
    code = ("import sys\n"
            "sys.modules['starlette'] = None\nsys.modules['uvicorn'] = None\n"
            "from tghop.cli import main\n"
            f"main.main(['serve', '--cache', {str(tmp_path)!r}], prog_name='tghop')\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 1
    assert p.stderr.strip().splitlines() == ["Error: tghop serve needs Starlette, uvicorn and python-multipart; "
                                             "install them with: pip install 'tghop[web]'"]


def test_a_fit_of_a_partly_transparent_upload_says_so(client):
    # A cut-out (the texture on a transparent background) dropped on the page: the colours under the
    # transparent part (black here) were learnt as texture, the results full of black, and the page said
    # nothing (the command line warned). The fit's answer now carries a note the page shows with
    # "model ready"; an opaque upload, or a built-in, has none.
    import numpy as np
    from PIL import Image

    from tghop import data
    from tghop.imageio import to_uint8

    rgba = np.zeros((96, 96, 4), np.uint8)
    rgba[:, :48, :3], rgba[:, :48, 3] = to_uint8(data.bricks(96, rng=3))[:, :48], 255  # the right half transparent
    fits = []
    for alpha in (rgba, np.dstack([rgba[..., :3], np.full((96, 96), 255, np.uint8)])):
        buf = io.BytesIO()
        Image.fromarray(alpha, "RGBA").save(buf, format="PNG")
        r = client.post("/api/models", files={"image": ("cut out.png", buf.getvalue(), "image/png"),
                                              **{k: (None, v) for k, v in FAST_FIT.items()}})
        assert r.status_code in (200, 202), r.text
        fits.append(r.json())
    assert fits[0]["notes"] == ["cut_out.png: 50% of its pixels are transparent, and the colours under them are "
                                "learnt as texture; to leave them out, crop the image to its opaque part"]
    assert fits[1]["notes"] == [] and fit_with(client, **FAST_FIT).json()["notes"] == []
    for fit in fits:
        assert events(client, fit["job"])[-1][1]["state"] == "done"


@pytest.mark.parametrize("query", ["/api/models/{id}/file?name=a&name=b", "/api/jobs/{job}?expected=0&expected=1",
                                   "/api/cooc/{cid}/file?name=a&name=b"])
def test_a_query_parameter_given_twice_is_refused(client, query):
    """0.59 took the last (the download named after "b") without a word, where a form field given twice is a 400."""
    path = query.format(id="0" * 64, job="0" * 32, cid="0" * 64)
    assert_error(client.get(path), 400, f"the query parameter {query.split('?')[1].split('=')[0]!r} is given twice")


def test_fill_k_blank_or_with_leading_zeros_is_that_fill(client, fitted, to_fill):
    # 0.61 took an empty fill as 1 but refused a blank one ("got ''"), took "08" (and answered X-Tghop-Fill: 08) but
    # refused "008": the field is a number, whitespace and leading zeros aside, and the header says it plainly.
    url, ask = inpaint_ask(fitted, to_fill, "6")
    first = client.post(url, files=ask)
    second = client.post(url, files={**ask, "fill": (None, "2")})
    assert first.status_code == second.status_code == 200 and first.content != second.content
    for value, body in ((" ", first.content), ("\t\n", first.content), ("01", first.content),
                        ("002", second.content), (" 0002 ", second.content)):
        r = client.post(url, files={**ask, "fill": (None, value)})
        assert r.status_code == 200, (value, r.text)
        assert r.content == body and r.headers["x-tghop-fill"] == ("1" if body == first.content else "2"), value
    for bad in ("009", "00", "0" * 20 + "1"):
        assert_error(client.post(url, files={**ask, "fill": (None, bad)}), 422, "fill must be an integer from 1 to 8")
