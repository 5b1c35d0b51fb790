"""A generation's progress on ``tghop serve``: a request that names a job (the header ``X-Tghop-Job``, 32 hex
digits its client chose) reports its progress at ``GET /api/jobs/{job}`` while its image is made, as a fit
does, and ``DELETE`` stops it; without the header nothing changes (the same bytes either way). Against a real
uvicorn server (httpx as the client); the page's bar is tested in test_server_browser_progress.py."""

import io
import threading
import time
import uuid

import pytest

httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

from conftest import FAST_FIT  # noqa: E402

from tghop.server.jobs import GenerationJob, generation_fraction  # noqa: E402


@pytest.fixture(scope="module")
def client(live_server):
    with httpx.Client(base_url=live_server.url, timeout=180) as c:
        yield c


def fit(client, name):
    """builtin:NAME fitted with the fast settings: its model id."""
    r = client.post("/api/models", files={"builtin": (None, name), **{k: (None, v) for k, v in FAST_FIT.items()}})
    assert r.status_code in (200, 202), r.text
    body = r.json()
    deadline = time.monotonic() + 120
    while client.get(f"/api/jobs/{body['job']}").json()["state"] != "done":
        assert time.monotonic() < deadline, "the fit did not end"
        time.sleep(0.1)
    return body["id"]


@pytest.fixture(scope="module")
def models(client):
    return fit(client, "bricks"), fit(client, "cells")


def new_job():
    return uuid.uuid4().hex


def test_a_generations_stages_go_forward_in_one_bar():
    trace = [("layout", 0, 1000), ("layout", 1000, 1000), ("patch pool", 0, 1), ("patch pool", 1, 1),
             ("quilting", 1, 361),
             ("quilting", 200, 361), ("quilting", 361, 361), ("refine", 0, 15), ("refine", 15, 15),
             ("patch refine", 0, 208), ("patch refine", 208, 208), ("encoding", 0, 1)]
    where = [generation_fraction(*step) for step in trace]
    assert where == sorted(where) and where[0] == 0.0 and 0.9 < where[-1] < 1.0
    assert where[5] < where[6]  # within a stage too
    # a painted guide's layers share the part before the join, one after the other
    layered = [generation_fraction(f"{s} {i}/2", d, t) for i in (1, 2) for s, d, t in trace[:-1]]
    layered += [generation_fraction("join", 0, 1), generation_fraction("join", 1, 1), generation_fraction(*trace[-1])]
    assert layered == sorted(layered) and layered[len(trace) - 2] <= 0.5 < layered[len(trace)]
    assert generation_fraction("inpainting", 5, 10) == generation_fraction("quilting", 5, 10)
    assert generation_fraction("something else", 1, 2) is None
    job = GenerationJob(None, new_job())
    job.progress("refine", 1, 2)
    late = job.snapshot()["progress"]
    job.progress("not a stage", 1, 1)  # unknown: the bar stays
    job.progress("quilting", 1, 1)  # earlier: the bar does not go back
    assert job.snapshot()["progress"] == late > 0 and job.snapshot()["stage"] == "quilting"


def test_the_job_of_a_generation_says_its_stages_and_the_bytes_are_the_same(client, models):
    bricks, cells = models
    ask = {"size": [64, 96], "seed": 5, "n_patches": 400}
    plain = client.post(f"/api/models/{bricks}/images", json=ask)
    job = new_job()
    followed = client.post(f"/api/models/{bricks}/images", json=ask, headers={"X-Tghop-Job": job})
    assert followed.status_code == 200 and followed.content == plain.content
    snap = client.get(f"/api/jobs/{job}").json()
    assert snap["kind"] == "generation" and snap["id"] == bricks and snap["state"] == "done"
    assert snap["progress"] == 1.0 and snap["stages"][-1] == "encoding"
    assert {"patch pool", "quilting", "refine"} <= set(snap["stages"])
    fields = {"builtin": (None, "bricks"), **{k: (None, v) for k, v in FAST_FIT.items()}}
    again = client.post("/api/models", files=fields)
    assert client.get(f"/api/jobs/{again.json()['job']}").json()["kind"] == "fit"
    # painted (the layers, then the join), remix and morph: several models, no model of the path
    import base64

    import numpy as np
    from PIL import Image

    guide = np.zeros((48, 64), np.uint8)
    guide[:, 32:] = 255
    buf = io.BytesIO()
    Image.fromarray(guide).save(buf, format="PNG")
    for path, body in [("/api/images/guided", {"models": [bricks, cells], "seed": 1, "n_patches": 400,
                                                "guide": base64.b64encode(buf.getvalue()).decode()}),
                       ("/api/images/guided", {"models": [bricks, cells], "size": [48, 64], "n_patches": 400}),
                       ("/api/images/morph", {"a": bricks, "b": cells, "size": [32, 128], "seed": 1,
                                              "n_patches": 400})]:
        job = new_job()
        alone = client.post(path, json=body)
        r = client.post(path, json=body, headers={"X-Tghop-Job": job})
        assert r.status_code == 200 and (r.content == alone.content or "seed" not in body), r.text
        snap = client.get(f"/api/jobs/{job}").json()
        assert snap["state"] == "done" and snap["id"] is None and snap["stages"][-1] == "encoding", snap
        assert "join" in snap["stages"]  # a morph's regions too are joined as a painted guide's
    # a fill (inpaint) too
    mask = np.zeros((64, 96), np.uint8)
    mask[16:40, 24:64] = 255
    buf = io.BytesIO()
    Image.fromarray(mask).save(buf, format="PNG")
    files = {"image": ("p.png", plain.content), "mask": ("m.png", buf.getvalue()), "seed": (None, "2")}
    job = new_job()
    alone = client.post(f"/api/models/{bricks}/inpaint", files=files)
    r = client.post(f"/api/models/{bricks}/inpaint", files=files, headers={"X-Tghop-Job": job})
    assert r.status_code == 200 and r.content == alone.content
    snap = client.get(f"/api/jobs/{job}").json()
    assert snap["state"] == "done" and "inpainting" in snap["stages"] and snap["id"] == bricks


def test_a_bad_or_reused_job_id_is_refused(client, models):
    bricks, _ = models
    url = f"/api/models/{bricks}/images"
    r = client.post(url, json={"size": [16, 16]}, headers={"X-Tghop-Job": "not hex"})
    assert r.status_code == 400 and "X-Tghop-Job must be 32 hex digits" in r.json()["error"]
    job = new_job()
    assert client.post(url, json={"size": [16, 16]}, headers={"X-Tghop-Job": job}).status_code == 200
    again = client.post(url, json={"size": [16, 16]}, headers={"X-Tghop-Job": job})
    assert again.status_code == 409 and "is in use" in again.json()["error"]


def post_in_background(url, body, job):
    """POST in a thread: a list that gets the response."""
    out = []
    thread = threading.Thread(target=lambda: out.append(httpx.post(url, json=body, headers={"X-Tghop-Job": job},
                                                                   timeout=300)), daemon=True)
    thread.start()
    return out, thread


def test_a_job_asked_for_before_its_request_is_read_is_unknown_when_expected(client, models, live_server):
    # The page's first poll can come before the server has read the request as far as its job header (a body
    # on its way, a loaded server): it got 404, a console error in the browser.
    bricks, _ = models
    job, body_sent = new_job(), threading.Event()

    def body():  # the request's body waits until the job has been asked for
        yield b'{"size": [32, 32], '
        body_sent.wait(60)
        yield b'"seed": 4, "n_patches": 400}'

    out = []
    thread = threading.Thread(target=lambda: out.append(httpx.post(
        f"{live_server.url}/api/models/{bricks}/images", content=body(), timeout=300,
        headers={"X-Tghop-Job": job, "content-type": "application/json"})), daemon=True)
    thread.start()
    try:
        time.sleep(0.2)  # the headers are there, not the whole body
        r = client.get(f"/api/jobs/{job}", params={"expected": "1"})
        assert r.status_code == 200 and r.json()["state"] == "unknown", r.text
        assert set(r.json()) == set(GenerationJob(None, job).snapshot()) and r.json()["job"] == job
        assert client.get(f"/api/jobs/{job}", params={"expected": "true"}).json()["state"] == "unknown"
        plain = client.get(f"/api/jobs/{job}")  # without it (curl, a typo): no such job, said
        assert plain.status_code == 404 and "X-Tghop-Job" in plain.json()["error"], plain.text
        assert client.get(f"/api/jobs/{job}", params={"expected": "0"}).status_code == 404
    finally:
        body_sent.set()
    thread.join(timeout=120)
    assert out and out[0].status_code == 200
    snap = client.get(f"/api/jobs/{job}", params={"expected": "1"}).json()  # the job itself once it is there
    assert snap["kind"] == "generation" and snap["state"] == "done" and snap["id"] == bricks
    assert client.get(f"/api/jobs/{job}").json() == snap
    # a malformed id never becomes a job: 404 even when expected; a bad value of expected: 400
    assert client.get("/api/jobs/nope", params={"expected": "1"}).status_code == 404
    r = client.get(f"/api/jobs/{new_job()}", params={"expected": "yes"})
    assert r.status_code == 400 and r.json()["error"] == "expected must be 1 or 0, got 'yes'"


def test_a_running_generations_progress_advances_before_its_image_comes(client, models, live_server):
    bricks, _ = models
    job = new_job()
    answer, thread = post_in_background(f"{live_server.url}/api/models/{bricks}/images",
                                        {"size": [1536, 1536], "seed": 1, "n_patches": 400}, job)
    seen = []
    while not answer:
        r = client.get(f"/api/jobs/{job}")
        if r.status_code == 200:
            snap = r.json()
            if not answer and snap["state"] == "running":
                seen.append(snap["progress"])
        time.sleep(0.05)
    thread.join()
    assert answer[0].status_code == 200
    during = [p for p in seen if 0 < p < 1]
    assert len(set(during)) >= 3 and during == sorted(during), seen


def test_delete_stops_a_running_generation(client, models, live_server):
    bricks, _ = models
    job = new_job()
    answer, thread = post_in_background(f"{live_server.url}/api/models/{bricks}/images",
                                        {"size": [2048, 2048], "seed": 1}, job)
    deadline = time.monotonic() + 60
    while True:
        r = client.get(f"/api/jobs/{job}")
        if r.status_code == 200 and r.json()["stage"] == "quilting":
            break
        assert time.monotonic() < deadline and not answer, "the generation did not start quilting"
        time.sleep(0.05)
    assert client.delete(f"/api/jobs/{job}").status_code == 200
    thread.join(timeout=120)
    assert answer and answer[0].status_code == 409, answer
    assert "cancelled" in answer[0].json()["error"]
    assert client.get(f"/api/jobs/{job}").json()["state"] == "cancelled"
    r = client.post(f"/api/models/{bricks}/images", json={"size": [16, 16], "seed": 3})
    assert r.status_code == 200  # the thread serves the next request


def test_a_fits_bar_counts_the_stages_that_fit_reports(client, live_server):
    # The bar's whole counted "hop 3" (64x64 patches only) in every fit, whose default has two hops, and gave a
    # material's "maps" a guessed share beside it: a two-hop fit's bar stood at 0.90 as its last stage began.
    import numpy as np

    from conftest import png
    from tghop import data
    from tghop.imageio import to_uint8
    from tghop.server.jobs import FIT_STAGES, Job, fit_stages

    job = Job("a" * 64)
    job.stages = fit_stages(2)
    for stage in job.stages[:-1]:
        job.progress(stage, 0, 1)
        job.progress(stage, 1, 1)
    job.progress("saving", 0, 1)
    assert job.fraction() == pytest.approx(1 - FIT_STAGES["saving"] / sum(FIT_STAGES[s] for s in job.stages))
    # A fit of the server expects the stages it reports: a texture model's, a material's (fast settings: no layout).
    settings = {**{k: (None, v) for k, v in FAST_FIT.items()}, "max_patches": (None, "1400")}  # fitted nowhere else
    height = png(to_uint8(np.asarray(data.builtin("cells"))[..., 0]))
    for maps in ({}, {"map:height": ("height.png", height)}):
        r = client.post("/api/models", files={"builtin": (None, "cells"), **settings, **maps})
        assert r.status_code == 202, r.text
        deadline = time.monotonic() + 120
        while client.get(f"/api/jobs/{r.json()['job']}").json()["state"] != "done":
            assert time.monotonic() < deadline, "the fit did not end"
            time.sleep(0.1)
        job = live_server.app.state.server.queue.get(r.json()["job"])
        assert job.stages == tuple(client.get(f"/api/jobs/{job.id}").json()["stages"]), maps
        assert ("maps" in job.stages) == bool(maps) and "hop 3" not in job.stages


def test_a_fits_bar_never_steps_back_when_its_layout_comes(client, live_server):
    # "layout" was counted in the whole only once it came (whether the exemplar is large enough for it was the
    # fit's to decide), and the bar stepped back a little then: 0.95 at the end of "CDF codebook", 0.86 as
    # "layout" began. The server now knows before the fit whether it makes a layout, and a fraction once told
    # is never taken back.
    from tghop.server.jobs import FIT_STAGES, Job, fit_stages

    job = Job("a" * 64)
    job.stages = fit_stages(2)  # a layout unexpected (a stage of its own that comes): the bar holds, then goes on
    seen = []
    for stage in [*job.stages[:-1], "layout", "saving"]:
        for done in (0, 1):
            job.progress(stage, done, 1)
            seen.append(job.fraction())
    assert seen == sorted(seen) and seen[-1] < 1, seen
    expected = fit_stages(2, layout=True)
    assert expected.index("layout") == expected.index("CDF codebook") + 1 and "layout" in FIT_STAGES
    # Fits of the server expect "layout" exactly when they make one: the layout on (the default factor), at the
    # exemplar's size, and at a working scale that leaves it too small for one.
    settings = {k: (None, v) for k, v in FAST_FIT.items() if k != "layout_factor"}
    for scale, layout in (("1", True), ("0.3", False)):
        r = client.post("/api/models", files={"builtin": (None, "cells"), **settings, "scale": (None, scale),
                                              "max_patches": (None, "1300")})
        assert r.status_code == 202, r.text
        fractions = []
        deadline = time.monotonic() + 180
        while (snap := client.get(f"/api/jobs/{r.json()['job']}").json())["state"] != "done":
            assert time.monotonic() < deadline, "the fit did not end"
            fractions.append(snap["progress"])
            time.sleep(0.05)
        job = live_server.app.state.server.queue.get(r.json()["job"])
        assert job.stages == tuple(client.get(f"/api/jobs/{job.id}").json()["stages"]), scale
        assert ("layout" in job.stages) == layout and fractions == sorted(fractions), (scale, fractions)
