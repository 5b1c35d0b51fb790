"""The web server's bounds: finished jobs expire from the job table, waiting fits are
capped, and the model cache folder stays under its size by dropping the least recently
used model files (on disk and in memory); a restart with a lower bound prunes too."""

import os
import sys
import threading
import time

import pytest

from conftest import LiveServer

from tghop.server.jobs import FitQueue, QueueFull


class Held:
    """``func`` wrapped for a test: its calls held until :attr:`release` is set (only those for which
    ``hold(*args)`` is true, where given), counted while they run (``inside``; ``peak``, the most at once) and
    named in order in ``calls`` by ``name(*args)`` (where given)."""

    def __init__(self, func, *, name=None, hold=None):
        self.func, self.name, self.hold = func, name, hold
        self.release, self.lock = threading.Event(), threading.Lock()
        self.inside = self.peak = 0
        self.calls = []

    def __call__(self, *args, **kwargs):
        with self.lock:
            self.inside += 1
            self.peak = max(self.peak, self.inside)
            if self.name is not None:
                self.calls.append(self.name(*args))
        try:
            if self.hold is None or self.hold(*args):
                self.release.wait(60)
            return self.func(*args, **kwargs)
        finally:
            with self.lock:
                self.inside -= 1


def test_finished_jobs_expire_and_their_count_is_bounded():
    queue = FitQueue(1, keep_finished=0.3, max_finished=3)
    try:
        jobs = [queue.finished(f"{i:064x}") for i in range(5)]
        assert len(queue) == 3  # the two oldest finished jobs went
        assert [queue.get(j.id) for j in jobs[:2]] == [None, None]
        assert all(queue.get(j.id) is j for j in jobs[2:])
        release = threading.Event()
        running = queue.submit("a" * 64, lambda job: (job.progress("hop 1", 0, 1), release.wait(10)))
        time.sleep(0.4)
        assert queue.get(jobs[-1].id) is None  # expired...
        assert queue.get(running.id) is running  # ...but a job still running never is
        release.set()
        running.future.result(timeout=10)
        assert running.state == "done" and queue.get(running.id) is running
        time.sleep(0.4)
        assert queue.get(running.id) is None and len(queue) == 0
    finally:
        queue.shutdown()


def test_waiting_fits_are_capped():
    queue = FitQueue(1, max_waiting=2)
    release = threading.Event()
    try:
        work = lambda job: release.wait(10)  # noqa: E731
        first = queue.submit("1" * 64, work)
        deadline = time.monotonic() + 10
        while first.state != "running":
            assert time.monotonic() < deadline
            time.sleep(0.01)
        waiting = [queue.submit(c * 64, work) for c in "23"]
        assert queue.submit("2" * 64, work) is waiting[0]  # the same model: its job, not a new one
        with pytest.raises(QueueFull, match="2 fits are waiting"):
            queue.submit("4" * 64, work)
        queue.cancel(waiting[0].id)  # one of the two that asked for it withdraws: it still waits
        with pytest.raises(QueueFull):
            queue.submit("4" * 64, work)
        queue.cancel(waiting[0].id)  # the other too: a place frees up
        assert queue.submit("4" * 64, work).state == "queued"
    finally:
        release.set()
        queue.shutdown()


def gated_fit():
    """``(started, release, work)``: a fit ``work(job)`` that sets ``started``, waits for ``release``,
    then reports progress (which raises Cancelled once its cancel was asked for)."""
    started, release = threading.Event(), threading.Event()

    def work(job):
        started.set()
        release.wait(10)
        job.progress("hop 1", 0, 1)

    return started, release, work


def test_a_fit_asked_for_again_after_its_cancel_runs_anew():
    # The cancelled fit stops only at its next progress call: until then it still runs, and
    # the same model asked for again must get a job of its own, not the one about to stop.
    queue = FitQueue(2)
    started, release, work = gated_fit()
    try:
        old = queue.submit("5" * 64, work)
        assert started.wait(10)
        assert queue.cancel(old.id).state == "running"
        new = queue.submit("5" * 64, lambda job: job.progress("hop 1", 1, 1))
        assert new is not old
        new.future.result(timeout=10)
        release.set()
        old.future.result(timeout=10)
        assert (old.state, new.state) == ("cancelled", "done")
        assert queue.submit("5" * 64, work) is not new  # a done job is never handed back
    finally:
        release.set()
        queue.shutdown()


def test_a_fit_two_clients_asked_for_stops_only_when_both_withdraw():
    # Two pages that chose the same exemplar and settings share one job; one page's Cancel
    # (or its switch to another exemplar) cancelled the other's fit as well.
    queue = FitQueue(1)
    started, release, work = gated_fit()
    try:
        job = queue.submit("6" * 64, work)
        assert queue.submit("6" * 64, work) is job and job.snapshot()["askers"] == 2
        assert started.wait(10)
        assert queue.cancel(job.id) is job and not job.cancel_requested
        assert job.snapshot()["askers"] == 1 and job.snapshot()["state"] == "running"
        assert queue.cancel(job.id).cancel_requested and job.askers == 0
        release.set()
        job.future.result(timeout=10)
        assert job.state == "cancelled" and queue.cancel(job.id).askers == 0  # once more: nothing changes

        def busy(j):  # reports progress for up to 10 s; done unless cancelled before
            for _ in range(1000):
                j.progress("hop 1", 0, 1)
                time.sleep(0.01)

        shared = queue.submit("7" * 64, busy)
        assert queue.submit("7" * 64, busy) is shared
    finally:
        release.set()
        queue.shutdown()  # cancels for every asker
    assert shared.state == "cancelled" and shared.askers == 0


@pytest.fixture(scope="module")
def two_model_files(small_model, tmp_path_factory):
    """Two different model files (bytes) of the same size, give or take a few bytes."""
    import copy

    from tghop._estimator import fitted_settings
    from tghop.modelfile import save_model

    folder = tmp_path_factory.mktemp("models")
    out = []
    for seed in (0, 1):
        path = folder / f"m{seed}.npz"
        model = copy.deepcopy(small_model).set_params(max_patches=20000 + seed)  # stored, not checked: as if
        model._fitted_params = fitted_settings(model)  # fitted with it, so that it saves
        save_model(model, path)
        out.append(path.read_bytes())
    assert out[0] != out[1] and len(out[0]) == len(out[1])
    return out


def _put(cache, model_id, content, mtime=None):
    path = cache.path(model_id)
    path.write_bytes(content)
    if mtime is not None:
        os.utime(path, (mtime, mtime))


def _in_cache_folder(tmp_path, contents, ids=None):
    """Model files ``contents`` (bytes) in the server's cache folder under ``tmp_path`` (made), each under its
    id (by default its SHA-256, as an upload's), not in memory as on a fresh server: the ids."""
    import hashlib

    ids = ids or [hashlib.sha256(content).hexdigest() for content in contents]
    (tmp_path / "models").mkdir()
    for model_id, content in zip(ids, contents):
        (tmp_path / "models" / f"{model_id}.npz").write_bytes(content)
    return ids


def test_the_cache_folder_drops_the_least_recently_used_models(tmp_path, two_model_files):
    from tghop.modelfile import load_model
    from tghop.server.app import ModelCache

    content = two_model_files[0]
    size = len(content)
    cache = ModelCache(tmp_path, max_bytes=int(2.5 * size))
    a, b, c = ("a" * 64, "b" * 64, "c" * 64)
    now = time.time()
    _put(cache, a, content, now - 100)
    _put(cache, b, content, now - 50)
    cache.load(a)  # used: now the most recent of the two
    assert cache.prune() == [] and cache.size() == 2 * size
    _put(cache, c, content)
    cache.added(c, load_model(cache.path(c)))
    assert sorted(p.name[:1] for p in cache.models.glob("*.npz")) == ["a", "c"]  # b, the least recently used, went
    with pytest.raises(Exception, match="no model"):
        cache.load(b)
    # the newest model stays even when it alone is over the bound
    tiny = ModelCache(tmp_path, max_bytes=1)
    assert sorted(p.name[:1] for p in tiny.models.glob("*.npz")) == []  # a restart with a lower bound prunes
    _put(tiny, c, content)
    tiny.added(c, load_model(tiny.path(c)))
    assert [p.name[:1] for p in tiny.models.glob("*.npz")] == ["c"]
    # no bound: nothing goes
    free = ModelCache(tmp_path, max_bytes=None)
    _put(free, a, content)
    assert free.prune() == [] and free.size() == 2 * size


def test_the_server_keeps_its_cache_under_the_bound(tmp_path, two_model_files):
    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

    first, second = two_model_files
    server = LiveServer(tmp_path, cache_bytes=int(1.5 * len(first)))
    client = httpx.Client(base_url=server.url, timeout=60)
    try:
        a = client.post("/api/models/upload", content=first).json()["id"]
        assert client.post(f"/api/models/{a}/images", json={"size": [40, 40], "n_patches": 100}).status_code == 200
        b = client.post("/api/models/upload", content=second).json()["id"]
        assert client.get(f"/api/models/{b}").status_code == 200
        gone = client.post(f"/api/models/{a}/images", json={"size": [40, 40]})
        assert gone.status_code == 404 and "no model" in gone.json()["error"]  # evicted: from memory too
        assert sorted(os.listdir(tmp_path / "models")) == [f"{b}.npz"]
        assert client.post("/api/models/upload", content=first).json()["id"] == a  # sent again: back
        assert sorted(os.listdir(tmp_path / "models")) == [f"{a}.npz"]
    finally:
        client.close()
        server.stop()


def test_a_cache_folder_that_cannot_take_a_file_is_one_line(tmp_path, two_model_files, monkeypatch):
    """An upload the folder cannot keep (gone, read-only, a full disk): 507 and one line naming the
    folder, not a text 500 and a traceback in the terminal; the server goes on."""
    import errno
    import shutil

    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

    server = LiveServer(tmp_path)
    client = httpx.Client(base_url=server.url, timeout=60)
    models = tmp_path / "models"
    try:
        shutil.rmtree(models)
        models.write_bytes(b"")  # a file where the folder was
        r = client.post("/api/models/upload", content=two_model_files[0])
        assert r.status_code == 507, r.text
        message = r.json()["error"]
        # the fix is whoever started the server's, said so to the page (0.62: "start the server with another --cache")
        assert message.startswith(f"cannot write to the cache folder {models} (Not a directory); the server keeps no "
                                  "new model until whoever started it frees some space there or starts it again with "
                                  "another folder (tghop serve --cache FOLDER)"), message
        # a fit that cannot keep its model says the same (0.62: "... is a file, not a folder; give the model a path
        # in a folder", the library's words, no fix the page has)
        from conftest import FAST_FIT

        fields = {"builtin": (None, "bricks"), **{k: (None, v) for k, v in FAST_FIT.items()}}
        r = client.post("/api/models", files=fields)
        assert r.status_code == 202, r.text
        for _ in range(1200):
            job = client.get(f"/api/jobs/{r.json()['job']}").json()
            if job["state"] not in ("queued", "running"):
                break
            time.sleep(0.1)
        assert job["state"] == "failed" and job["error"] == message, job
        models.unlink()
        models.mkdir()

        def full(*args, **kwargs):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        monkeypatch.setattr(os, "replace", full)
        r = client.post("/api/models/upload", content=two_model_files[0])
        assert r.status_code == 507 and "(No space left on device)" in r.json()["error"], r.text
        assert os.listdir(models) == []  # the temporary file went
        monkeypatch.undo()
        r = client.post("/api/models/upload", content=two_model_files[0])
        assert r.status_code == 200 and os.listdir(models) == [f"{r.json()['id']}.npz"]
    finally:
        client.close()
        server.stop()


@pytest.mark.parametrize("text, expected", [("2G", 2 * 1000**3), ("500M", 500 * 1000**2), ("1.5GB", 1_500_000_000),
                                            ("800kb", 800_000), ("12345", 12345), ("none", None)])
def test_cache_size_values(text, expected):
    from tghop.cli.serve import ByteSize

    assert ByteSize().convert(text, None, None) == expected


def test_a_bad_cache_size_is_one_line(tmp_path):
    from click.testing import CliRunner

    from tghop.cli import main

    r = CliRunner().invoke(main, ["serve", "--cache", str(tmp_path), "--cache-size", "lots"])
    assert r.exit_code == 2 and "'lots' is not a size; write e.g. 500M, 2G or none" in r.output
    assert "Traceback" not in r.output and not (tmp_path / "models").exists()


@pytest.mark.parametrize("value, said", [("0", "0 is not in the range 1<=x<=64"), ("65", "65 is not in the range"),
                                         ("two", "'two' is not a valid integer")])
def test_a_bad_max_decodes_is_one_line(tmp_path, value, said):
    from click.testing import CliRunner

    from tghop.cli import main

    r = CliRunner().invoke(main, ["serve", "--cache", str(tmp_path), "--max-decodes", value])
    assert r.exit_code == 2 and f"Invalid value for '--max-decodes': {said}" in r.output, r.output
    assert "Traceback" not in r.output and not (tmp_path / "models").exists()


def _serve_gates(tmp_path, monkeypatch, runs):
    """The decode gate of the server ``tghop serve OPTIONS`` makes, for each OPTIONS of ``runs``: the real
    application, stopped by a one-line error before it listens."""
    from click.testing import CliRunner

    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    from tghop._errors import TGHopError
    from tghop.cli import main
    from tghop.server import app as server_app

    made, create = [], server_app.create_app

    def create_and_stop(*args, **kwargs):
        made.append(create(*args, **kwargs))
        raise TGHopError("stopped by the test")

    monkeypatch.setattr(server_app, "create_app", create_and_stop)
    gates = []
    for options in runs:
        r = CliRunner().invoke(main, ["serve", "--port", "0", "--cache", str(tmp_path), *options])
        assert r.exit_code != 0 and "stopped by the test" in r.output, r.output
        gates.append(made[-1].state.server.decoding)
    return gates, " ".join(CliRunner().invoke(main, ["serve", "--help"]).output.split())


def test_max_decodes_sets_the_servers_decode_gate(tmp_path, monkeypatch):
    """create_app(max_decodes=) had no option of tghop serve: the gate of uploads decoded at once was 2
    whatever the machine. The option reaches the server's gate; its default is the library's."""
    from tghop.server.uploads import MAX_DECODES

    gates, help_text = _serve_gates(tmp_path, monkeypatch, [["--max-decodes", "5"], []])
    assert [g.slots for g in gates] == [5, MAX_DECODES]
    assert "--max-decodes" in help_text and "[default: 2; 1<=x<=64]" in help_text, help_text


@pytest.mark.parametrize("value, said", [("-1", "-1 is not in the range 0<=x<=256"),
                                         ("257", "257 is not in the range 0<=x<=256"),
                                         ("many", "'many' is not a valid integer")])
def test_a_bad_decodes_waiting_is_one_line(tmp_path, value, said):
    from click.testing import CliRunner

    from tghop.cli import main

    r = CliRunner().invoke(main, ["serve", "--cache", str(tmp_path), "--decodes-waiting", value])
    assert r.exit_code == 2 and f"Invalid value for '--decodes-waiting': {said}" in r.output, r.output
    assert "Traceback" not in r.output and not (tmp_path / "models").exists()


def test_decodes_waiting_sets_how_many_wait_for_the_decode_gate(tmp_path, monkeypatch):
    """create_app(decodes_waiting=) had no option of tghop serve: 16 uploads or reads waited for the decode
    gate whatever the machine. --decodes-waiting reaches the gate (0: none waits); its default is the library's."""
    from tghop.server.uploads import MAX_DECODES_WAITING

    runs = [["--decodes-waiting", "40"], ["--decodes-waiting", "0"], []]
    gates, help_text = _serve_gates(tmp_path, monkeypatch, runs)
    assert [g.max_waiting for g in gates] == [40, 0, MAX_DECODES_WAITING]
    assert "--decodes-waiting" in help_text and "[default: 16; 0<=x<=256]" in help_text, help_text


def test_a_restarted_server_finds_the_cached_models_again(tmp_path, two_model_files):
    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

    ask = {"size": [24, 32], "seed": 5, "n_patches": 100}
    images = []
    for run in range(2):  # the same cache folder, a new server (and process state) each time
        server = LiveServer(tmp_path)
        try:
            with httpx.Client(base_url=server.url, timeout=60) as client:
                if run == 0:
                    model_id = client.post("/api/models/upload", content=two_model_files[0]).json()["id"]
                assert client.get(f"/api/models/{model_id}").status_code == 200
                r = client.post(f"/api/models/{model_id}/images", json=ask)
                assert r.status_code == 200, r.text
                images.append(r.content)
        finally:
            server.stop()
    assert images[0] == images[1] and os.listdir(tmp_path / "models") == [f"{model_id}.npz"]


@pytest.mark.skipif(sys.platform in ("win32", "darwin"), reason="the XDG rule is the Linux one")
def test_the_default_cache_is_the_users_cache_folder(tmp_path, monkeypatch):
    from pathlib import Path

    from tghop.cli.serve import default_cache_dir

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert default_cache_dir() == tmp_path / "tghop"
    for unset in ("", "relative/cache"):  # empty or relative: ignored, as the XDG specification says
        monkeypatch.setenv("XDG_CACHE_HOME", unset)
        assert default_cache_dir() == Path.home() / ".cache" / "tghop"


def test_uploads_decoded_at_once_are_bounded_the_next_wait_and_one_more_is_503(tmp_path, monkeypatch):
    """A small file may decode to hundreds of MB (an 8000x8000 PNG of 760 KB: 700 MB): uploads are
    decoded max_decodes at once, decodes_waiting more wait their turn (a page's user sees a wait, not
    an error), and one more is refused at once with Retry-After; real requests at once, a real server."""
    import io

    import numpy as np
    from PIL import Image

    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    from tghop.server.routes import fit

    buf = io.BytesIO()
    Image.fromarray(np.full((64, 64, 3), 128, np.uint8)).save(buf, format="PNG")  # flat: read, then refused
    flat = buf.getvalue()
    held = Held(fit.prepare_fit)  # the real preparation (decoding included), held until released
    monkeypatch.setattr(fit, "prepare_fit", held)
    live = LiveServer(tmp_path, max_decodes=1, decodes_waiting=1)
    gate = live.app.state.server.decoding
    answers = {}

    def post(name, path, **kwargs):
        with httpx.Client(base_url=live.url, timeout=60) as client:
            answers[name] = client.post(path, **kwargs)

    threads = []
    try:
        for name in ("first", "second"):
            threads.append(threading.Thread(target=post, args=(name, "/api/models"),
                                            kwargs={"files": {"image": (f"{name}.png", flat)}}))
            threads[-1].start()
            until(lambda: held.inside == 2 or gate.waiting == 1 if name == "second" else held.inside == 1)
        third = httpx.post(f"{live.url}/api/models/upload", content=b"not a model", timeout=60)  # the same bound
        assert third.status_code == 503, third.text
        assert third.headers["retry-after"] == "5" and "the server is busy" in third.json()["error"]
        assert "first" not in answers and "second" not in answers  # still decoding, still waiting
        held.release.set()
        for thread in threads:
            thread.join(60)
    finally:
        held.release.set()
        live.stop()
    assert held.peak == 1  # one decoded at a time; the second waited its turn and was read, not refused
    for name in ("first", "second"):
        answer = answers[name]
        assert answer.status_code == 400 and "has no texture" in answer.json()["error"], answer.text
    assert gate.holding == 0 and gate.waiting == 0


def test_a_model_the_bound_drops_meanwhile_is_404_or_sent_whole_never_500(tmp_path, two_model_files, monkeypatch):
    """The bound may drop a model file between a route's look at it and its use (another model
    added meanwhile): a download then still sends the file it opened, whole; a summary or an
    image whose file went is 404 with one line; never a 500 (nor a 400 naming the server's path)."""
    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

    first = two_model_files[0]
    server = LiveServer(tmp_path)
    cache = server.app.state.server.cache
    client = httpx.Client(base_url=server.url, timeout=60)

    def drop():  # the bound, lowered for a moment, drops every file (as a new model over the bound does)
        cache.max_bytes = 0
        cache.prune()
        cache.max_bytes = None

    def one_line_404(r):
        assert r.status_code == 404, r.text
        said = r.json()["error"]  # 0.62: the id's first 12 digits (0.61: all 64)
        assert said.startswith(f"no model {model_id[:12]}... on the server") and str(tmp_path) not in r.text

    try:
        model_id = client.post("/api/models/upload", content=first).json()["id"]
        touch = cache.touch  # called once the route has found the file
        monkeypatch.setattr(cache, "touch", lambda mid: (drop(), touch(mid)))
        r = client.get(f"/api/models/{model_id}/file")
        assert r.status_code == 200 and r.content == first  # the file it opened, whole
        monkeypatch.undo()
        assert os.listdir(tmp_path / "models") == []
        one_line_404(client.get(f"/api/models/{model_id}/file"))

        assert client.post("/api/models/upload", content=first).json()["id"] == model_id
        load = cache.load
        monkeypatch.setattr(cache, "load", lambda mid: (load(mid), drop())[0])  # gone once loaded
        r = client.get(f"/api/models/{model_id}")
        assert r.status_code == 200 and r.json()["file_bytes"] == len(first), r.text
        monkeypatch.undo()

        read = cache._load  # reads a file not in memory
        for ask in (lambda: client.get(f"/api/models/{model_id}"),
                    lambda: client.post(f"/api/models/{model_id}/images", json={"size": [16, 16]})):
            assert client.post("/api/models/upload", content=first).json()["id"] == model_id
            with cache._lock:  # as a fresh server: neither the model nor its summary in memory
                cache._loaded.clear()
                cache._summaries.clear()
            monkeypatch.setattr(cache, "_load", lambda path: (drop(), read(path))[1])  # gone just before it is read
            one_line_404(ask())
            monkeypatch.undo()
        assert client.get("/api").status_code == 200
    finally:
        client.close()
        server.stop()


def test_an_upload_waiting_for_the_gate_whose_client_went_away_leaves_the_queue_never_decoded(tmp_path, monkeypatch):
    """An upload waiting its turn to be decoded whose client disconnects is dropped at once: it is never
    decoded (the real preparation counts its calls), and its waiting place goes to the next request."""
    import io
    import socket

    import numpy as np
    from PIL import Image

    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    from tghop.server.routes import fit

    buf = io.BytesIO()
    Image.fromarray(np.full((64, 64, 3), 128, np.uint8)).save(buf, format="PNG")  # flat: read, then refused
    flat = buf.getvalue()
    held = Held(fit.prepare_fit, name=lambda server, fields: fields["image"][0])  # counted by the exemplar's name
    monkeypatch.setattr(fit, "prepare_fit", held)
    live = LiveServer(tmp_path, max_decodes=1, decodes_waiting=1)
    gate = live.app.state.server.decoding
    answers = {}

    def post(name):
        with httpx.Client(base_url=live.url, timeout=60) as client:
            answers[name] = client.post("/api/models", files={"image": (f"{name}.png", flat)})

    threads = []
    try:
        threads.append(threading.Thread(target=post, args=("first",)))
        threads[-1].start()
        until(lambda: held.calls == ["first.png"])
        request = httpx.Request("POST", f"{live.url}/api/models", files={"image": ("gone.png", flat)})
        raw = (f"POST /api/models HTTP/1.1\r\nHost: {live.url[7:]}\r\n"
               + "".join(f"{k}: {v}\r\n" for k, v in request.headers.items() if k.lower() != "host")
               + "\r\n").encode() + request.read()
        with socket.create_connection(("127.0.0.1", int(live.url.rsplit(":", 1)[1])), timeout=10) as sock:
            sock.sendall(raw)  # the whole request, then waits its turn...
            until(lambda: gate.waiting == 1)
        until(lambda: gate.waiting == 0, seconds=10)  # ...and is gone: out of the queue at once
        threads.append(threading.Thread(target=post, args=("next",)))
        threads[-1].start()  # its place: the next waits, not refused
        until(lambda: gate.waiting == 1)
        held.release.set()
        for thread in threads:
            thread.join(60)
    finally:
        held.release.set()
        live.stop()
    assert held.calls == ["first.png", "next.png"]  # the one whose client went away was never decoded
    for name in ("first", "next"):
        answer = answers[name]
        assert answer.status_code == 400 and "has no texture" in answer.json()["error"], answer.text
    assert gate.holding == 0 and gate.waiting == 0


def test_summaries_asked_at_once_load_the_model_in_the_decoding_turn_once(tmp_path, two_model_files, monkeypatch):
    """A model may take hundreds of MB while it is read: summaries of models not in memory (a fresh server)
    asked at once load them max_decodes at a time, and each model once: its summary is kept (the file of an
    id never changes), still 404 once the file is gone."""
    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    from tghop import modelfile

    ids = _in_cache_folder(tmp_path, two_model_files)
    held = Held(modelfile.load_model, name=lambda path: path.name[:64])  # the real loading, until every request is in
    monkeypatch.setattr(modelfile, "load_model", held)
    live = LiveServer(tmp_path, max_decodes=1, decodes_waiting=16)
    gate = live.app.state.server.decoding
    answers = []

    def get(model_id):
        answers.append(httpx.get(f"{live.url}/api/models/{model_id}", timeout=60))

    threads = [threading.Thread(target=get, args=(ids[i % 2],)) for i in range(8)]
    try:
        for thread in threads:
            thread.start()
        deadline = time.monotonic() + 30
        while held.inside + gate.waiting < len(threads):  # all in: loading, or waiting their turn
            assert time.monotonic() < deadline
            time.sleep(0.01)
        held.release.set()
        for thread in threads:
            thread.join(60)
        assert [a.status_code for a in answers] == [200] * 8, [a.text for a in answers]
        assert held.peak == 1 and sorted(held.calls) == sorted(ids)  # one at a time, each model once
        assert {a.json()["id"] for a in answers} == set(ids)
        again = httpx.get(f"{live.url}/api/models/{ids[0]}", timeout=60)
        assert again.json() == next(a.json() for a in answers if a.json()["id"] == ids[0]) and len(held.calls) == 2
        (tmp_path / "models" / f"{ids[0]}.npz").unlink()
        gone = httpx.get(f"{live.url}/api/models/{ids[0]}", timeout=60)
        assert gone.status_code == 404 and "no model" in gone.json()["error"], gone.text
    finally:
        held.release.set()
        live.stop()
    assert gate.holding == 0 and gate.waiting == 0


def test_a_model_asked_for_at_once_is_loaded_once_and_a_failed_load_fails_each_asker(tmp_path):
    """Generations and summaries of one model not in memory each read it from disk at once: twice
    the memory and time. They share one load; other models' loads do not wait for it; a failed
    load's error reaches each asker, and the next call loads again."""
    from tghop._errors import TGHopError
    from tghop.server.cache import ModelCache

    ids = [c * 64 for c in "ab"]
    release, lock, fail = threading.Event(), threading.Lock(), [True]
    loads = []

    def held(path):  # model a held until every caller is in (and failing the first time); b at once
        with lock:
            loads.append(path.stem)
        if path.stem == ids[0]:
            if not release.wait(30):  # a lock across models: b's load never came back to release it
                raise RuntimeError("model a was never released")
            if fail[0]:
                raise TGHopError("a broken model file")
        return path.stem

    cache = ModelCache(tmp_path, None, load=held)
    for model_id in ids:
        cache.path(model_id).write_bytes(b"model")
    entered, load = [0], cache.load

    def counted(model_id):
        with lock:
            entered[0] += 1
        return load(model_id)

    cache.load = counted
    for round_ in ("fails", "loads"):
        answers = []

        def ask():
            try:
                answers.append(cache.load(ids[0]))
            except TGHopError as exc:
                answers.append(str(exc))

        release.clear()
        entered[0] = 0
        threads = [threading.Thread(target=ask) for _ in range(6)]
        for thread in threads:
            thread.start()
        deadline = time.monotonic() + 30
        while entered[0] < len(threads):
            assert time.monotonic() < deadline
            time.sleep(0.01)
        time.sleep(0.2)  # each in its load, or waiting for one
        if round_ == "fails":
            assert cache.load(ids[1]) == ids[1]  # another model: not held up by the first's load
        release.set()
        for thread in threads:
            thread.join(30)
        expected = "a broken model file" if round_ == "fails" else ids[0]
        assert answers == [expected] * len(threads)
        fail[0] = False
    assert sorted(loads) == [ids[0], ids[0], ids[1]]  # one load a round: the failed one, then the next
    assert cache.load(ids[0]) == ids[0] and len(loads) == 3  # in memory now
    assert not cache._loading


def test_summaries_of_one_model_asked_at_once_load_it_once(tmp_path, two_model_files, monkeypatch):
    """Summaries of a model not in memory asked at once, each on a decoding thread of its own: one load."""
    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    from tghop import modelfile

    [model_id] = _in_cache_folder(tmp_path, two_model_files[:1])
    release, loads, load = threading.Event(), [], modelfile.load_model

    def held(path, **kwargs):
        loads.append(path)
        release.wait(60)
        return load(path, **kwargs)

    monkeypatch.setattr(modelfile, "load_model", held)
    live = LiveServer(tmp_path, max_decodes=4)
    server = live.app.state.server
    entered, cache_load = [], server.cache.load
    monkeypatch.setattr(server.cache, "load", lambda mid: (entered.append(mid), cache_load(mid))[1])
    answers = []
    threads = [threading.Thread(target=lambda: answers.append(httpx.get(f"{live.url}/api/models/{model_id}",
                                                                         timeout=60))) for _ in range(4)]
    try:
        for thread in threads:
            thread.start()
        deadline = time.monotonic() + 30
        while len(entered) < len(threads):
            assert time.monotonic() < deadline
            time.sleep(0.01)
        time.sleep(0.2)  # each in its load, or waiting for one
        release.set()
        for thread in threads:
            thread.join(60)
        assert [a.status_code for a in answers] == [200] * 4, [a.text for a in answers]
        assert len(loads) == 1 and {a.json()["id"] for a in answers} == {model_id}
    finally:
        release.set()
        live.stop()


def test_finished_generations_are_bounded_apart_from_fits_and_never_drop_a_fits_outcome():
    """Generation jobs (X-Tghop-Job) shared the bound of finished jobs with the fits: a flood of
    generations dropped the outcome of a fit its page had not read yet. Each kind has its own bound."""
    from tghop.server.jobs import GenerationJob

    queue = FitQueue(1, max_finished=3)  # as many finished generations, counted apart
    try:
        fits = [queue.finished(f"{i:064x}") for i in range(2)]
        generations = []
        for i in range(10):  # a flood of finished generations, all after the fits
            job = GenerationJob("a" * 64, f"{i:032x}")
            assert queue.add(job)
            job.set_state("done")
            generations.append(job)
        assert all(queue.get(j.id) is j for j in fits)  # the fits' outcomes stay
        assert [queue.get(j.id) for j in generations[:7]] == [None] * 7  # the oldest generations went
        assert all(queue.get(j.id) is j for j in generations[7:]) and len(queue) == 5
        newer = [queue.finished(c * 64) for c in "ef"]  # two more fits: the oldest fit goes, not a generation
        assert queue.get(fits[0].id) is None and all(queue.get(j.id) is j for j in [fits[1], *newer])
        assert all(queue.get(j.id) is j for j in generations[7:])
    finally:
        queue.shutdown()
    small = FitQueue(1, max_finished=5, max_finished_generations=1)
    try:
        for i in range(3):
            job = GenerationJob(None, f"{i:032x}")
            small.add(job)
            job.set_state("failed", error="x")
        assert len(small) == 1 and small.get(job.id) is job
    finally:
        small.shutdown()


def test_generations_read_models_not_in_memory_in_the_decoding_turn_and_one_more_is_503(
        tmp_path, two_model_files, monkeypatch):
    """Generations read a model not in memory on their own threads, outside the bound of uploads decoded at
    once: requests for many models not in memory read them all at once (hundreds of MB each). They take the
    decoding turn now: max_decodes read at once, decodes_waiting more wait, one more is 503 with Retry-After,
    and one whose client goes away while it waits leaves the queue, its model never read. Real requests, a
    real server; the library's loading is only held (and counted) until the test lets it go."""
    import hashlib
    import socket

    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    from tghop import modelfile

    # Four models not in memory (the same file under other ids: each is its own model to the cache)
    ids = [hashlib.sha256(two_model_files[0]).hexdigest(), hashlib.sha256(two_model_files[1]).hexdigest(),
           "c" * 64, "d" * 64]
    _in_cache_folder(tmp_path, two_model_files * 2, ids)
    held = Held(modelfile.load_model, name=lambda path: path.name[:64])  # the real loading, held until released
    monkeypatch.setattr(modelfile, "load_model", held)
    live = LiveServer(tmp_path, max_fits=4, max_decodes=1, decodes_waiting=1)
    gate = live.app.state.server.decoding
    ask = {"size": [16, 16], "seed": 1, "n_patches": 100}
    answers = {}

    def post(model_id):
        answers[model_id] = httpx.post(f"{live.url}/api/models/{model_id}/images", json=ask, timeout=60)

    threads = []
    try:
        threads.append(threading.Thread(target=post, args=(ids[0],)))
        threads[-1].start()
        until(lambda: held.inside == 1 and gate.holding == 1)  # the first model read, holding the turn
        request = httpx.Request("POST", f"{live.url}/api/models/{ids[3]}/images", json=ask)
        raw = (f"POST /api/models/{ids[3]}/images HTTP/1.1\r\nHost: {live.url[7:]}\r\n"
               + "".join(f"{k}: {v}\r\n" for k, v in request.headers.items() if k.lower() != "host")
               + "\r\n").encode() + request.read()
        with socket.create_connection(("127.0.0.1", int(live.url.rsplit(":", 1)[1])), timeout=10) as sock:
            sock.sendall(raw)  # waits its turn to read its model...
            until(lambda: gate.waiting == 1)
        until(lambda: gate.waiting == 0, seconds=10)  # ...and leaves the queue once its client has gone
        threads.append(threading.Thread(target=post, args=(ids[1],)))
        threads[-1].start()
        until(lambda: gate.waiting == 1)  # the second waits its turn, not read beside the first
        third = httpx.post(f"{live.url}/api/models/{ids[2]}/images", json=ask, timeout=60)
        assert third.status_code == 503, third.text
        assert third.headers["retry-after"] == "5" and "the server is busy" in third.json()["error"]
        assert held.inside == 1 and not answers  # still reading the first, the second waiting
        held.release.set()
        for thread in threads:
            thread.join(60)
        assert [answers[m].status_code for m in ids[:2]] == [200, 200], [answers[m].text for m in ids[:2]]
        assert held.peak == 1 and held.calls == ids[:2]  # one read at a time; not the gone one's nor the refused one's
        again = httpx.post(f"{live.url}/api/models/{ids[2]}/images", json=ask, timeout=60)
        assert again.status_code == 200 and again.content == answers[ids[0]].content  # its turn now: the same file
    finally:
        held.release.set()
        live.stop()
    assert gate.holding == 0 and gate.waiting == 0


def _held_loads(monkeypatch, held_ids):
    """The library's model loading, held (until ``release`` is set) for the ids in ``held_ids`` (a set the test
    may fill later) and counted: a :class:`Held` (``calls``: the ids loaded in order)."""
    from tghop import modelfile

    held = Held(modelfile.load_model, name=lambda path: path.name[:64],
                hold=lambda path: path.name[:64] in held_ids)
    monkeypatch.setattr(modelfile, "load_model", held)
    return held


def test_a_generation_cancelled_while_it_waits_to_read_its_model_leaves_the_queue_at_once(
        tmp_path, two_model_files, monkeypatch):
    """DELETE /api/jobs/{job} of a generation waiting for its turn to read its model did not wake it: it
    stayed in the queue until its turn came and stopped only at its first progress report. It leaves the
    queue at once now (its place to the next, its model never read), answers 409 and ends cancelled."""
    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    import uuid

    ids = _in_cache_folder(tmp_path, two_model_files)
    held = _held_loads(monkeypatch, {ids[0]})
    live = LiveServer(tmp_path, max_fits=2, max_decodes=1, decodes_waiting=1)
    gate = live.app.state.server.decoding
    ask, job, answers = {"size": [16, 16], "seed": 1, "n_patches": 100}, uuid.uuid4().hex, {}

    def post(model_id, headers=None):
        answers[model_id] = httpx.post(f"{live.url}/api/models/{model_id}/images", json=ask, headers=headers,
                                       timeout=60)

    threads = [threading.Thread(target=post, args=(ids[0],)),
               threading.Thread(target=post, args=(ids[1], {"X-Tghop-Job": job}))]
    try:
        threads[0].start()
        until(lambda: held.inside == 1 and gate.holding == 1)  # the first model read, holding the only turn
        threads[1].start()
        until(lambda: gate.waiting == 1)  # the second waits its turn
        assert httpx.delete(f"{live.url}/api/jobs/{job}").status_code == 200
        until(lambda: gate.waiting == 0 and ids[1] in answers, seconds=10)  # out of the queue, answered
        cancelled = answers[ids[1]]
        assert cancelled.status_code == 409 and "cancelled" in cancelled.json()["error"], cancelled.text
        assert httpx.get(f"{live.url}/api/jobs/{job}").json()["state"] == "cancelled"
        assert ids[0] not in answers and gate.holding == 1  # the first still reading, in its turn
        held.release.set()
        threads[0].join(60)
        assert answers[ids[0]].status_code == 200, answers[ids[0]].text
        assert held.calls == ids[:1]  # the cancelled one's model never read
    finally:
        held.release.set()
        live.stop()
    assert gate.holding == 0 and gate.waiting == 0


def test_a_generation_cancelled_while_it_waits_for_a_generation_thread_ends_at_once(
        tmp_path, two_model_files, monkeypatch):
    """A generation whose job was cancelled while it waited for a generation thread answered only once a
    thread was free (then it stopped before it began). It leaves the thread pool's queue at once now: 409,
    cancelled, its work never run."""
    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    import uuid

    from tghop.server.routes import images

    ids = _in_cache_folder(tmp_path, two_model_files[:1])
    release, started, made = threading.Event(), [], images.model_png

    def held(*args):  # the real generation, held (counted) until released
        started.append(args[1])
        release.wait(60)
        return made(*args)

    monkeypatch.setattr(images, "model_png", held)
    live = LiveServer(tmp_path, max_fits=1)
    ask, job, answers = {"size": [16, 16], "seed": 1, "n_patches": 100}, uuid.uuid4().hex, {}

    def post(name, headers=None):
        answers[name] = httpx.post(f"{live.url}/api/models/{ids[0]}/images", json=ask, headers=headers, timeout=60)

    threads = [threading.Thread(target=post, args=("first",)),
               threading.Thread(target=post, args=("second", {"X-Tghop-Job": job}))]
    try:
        threads[0].start()
        until(lambda: len(started) == 1)  # the only generation thread taken
        threads[1].start()
        until(lambda: httpx.get(f"{live.url}/api/jobs/{job}").status_code == 200)  # queued for a thread
        assert httpx.delete(f"{live.url}/api/jobs/{job}").status_code == 200
        until(lambda: "second" in answers, seconds=10)  # answered while the first still holds the thread
        assert answers["second"].status_code == 409 and "cancelled" in answers["second"].json()["error"]
        assert httpx.get(f"{live.url}/api/jobs/{job}").json()["state"] == "cancelled"
        release.set()
        threads[0].join(60)
        assert answers["first"].status_code == 200 and len(started) == 1  # the cancelled one never ran
    finally:
        release.set()
        live.stop()


def test_a_generation_waiting_for_or_reading_its_model_holds_no_generation_thread(
        tmp_path, two_model_files, monkeypatch):
    """A generation read its model not in memory on its generation thread, and waited for its turn there:
    generations waiting to read (a slow disk, many models) took every generation thread, and one of a model
    in memory, which needs no read, waited behind them. Its model is read first now, on a decoding thread,
    before the generation takes a thread: the one in memory is made while the others wait and read."""
    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

    ids = _in_cache_folder(tmp_path, two_model_files + two_model_files[:1], ["a" * 64, "b" * 64, "c" * 64])
    held_ids = set()
    held = _held_loads(monkeypatch, held_ids)
    live = LiveServer(tmp_path, max_fits=2, max_decodes=1)
    gate = live.app.state.server.decoding
    ask, answers = {"size": [16, 16], "seed": 1, "n_patches": 100}, {}

    def post(model_id):
        answers[model_id] = httpx.post(f"{live.url}/api/models/{model_id}/images", json=ask, timeout=60)

    threads = [threading.Thread(target=post, args=(model_id,)) for model_id in ids]
    try:
        post(ids[2])  # read now: in memory
        assert answers.pop(ids[2]).status_code == 200 and held.calls == ids[2:]
        held_ids.update(ids[:2])
        threads[0].start()
        until(lambda: held.inside == 1 and gate.holding == 1)  # one model read (held), in the only turn...
        threads[1].start()
        until(lambda: gate.waiting == 1)  # ...the other waiting: as many as there are generation threads
        threads[2].start()
        until(lambda: ids[2] in answers, seconds=20)  # the model in memory is made meanwhile
        assert answers[ids[2]].status_code == 200, answers[ids[2]].text
        assert not answers.keys() & ids[:2] and gate.waiting == 1  # the others still reading and waiting
        held.release.set()
        for thread in threads:
            thread.join(60)
        assert [answers[m].status_code for m in ids] == [200] * 3
    finally:
        held.release.set()
        live.stop()
    assert gate.holding == 0 and gate.waiting == 0


def until(done, seconds=30):
    """Wait until ``done()`` (a test's condition), failing after ``seconds``."""
    deadline = time.monotonic() + seconds
    while not done():
        assert time.monotonic() < deadline
        time.sleep(0.01)


def _sent_and_left(live, request, entered, until):
    """Send ``request`` (an httpx.Request) whole on a socket of its own, wait until ``entered()`` (its
    decoding has begun), then close the socket: its client goes away while it is decoded; returns once the
    server has seen the connection go."""
    import socket

    raw = (f"{request.method} {request.url.raw_path.decode()} HTTP/1.1\r\nHost: {live.url[7:]}\r\n"
           + "".join(f"{k}: {v}\r\n" for k, v in request.headers.items() if k.lower() != "host")
           + "\r\n").encode() + request.read()
    with socket.create_connection(("127.0.0.1", int(live.url.rsplit(":", 1)[1])), timeout=10) as sock:
        sock.sendall(raw)
        until(entered)
    until(lambda: not live.server.server_state.connections)  # the server saw it go...
    time.sleep(0.1)  # ...and its loop has run the request's watch of its client


def test_a_fit_whose_client_went_away_while_its_exemplar_was_decoded_is_never_queued(tmp_path, monkeypatch):
    """Decoding cannot be stopped midway, but a fit whose client went away while its exemplar was decoded
    was then queued and fitted for nobody. Its result is dropped: no job, no model; the next one is served."""
    import io

    import numpy as np
    from PIL import Image

    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    from conftest import FAST_FIT
    from tghop.server.routes import fit

    buf = io.BytesIO()
    Image.fromarray(np.random.default_rng(0).integers(0, 256, (96, 96, 3), dtype=np.uint8)).save(buf, format="PNG")
    release, entered, prepare = threading.Event(), threading.Event(), fit.prepare_fit

    def held(server, fields):  # the real preparation (decoding included), held until released
        entered.set()
        release.wait(60)
        return prepare(server, fields)

    monkeypatch.setattr(fit, "prepare_fit", held)
    live = LiveServer(tmp_path, max_decodes=1)
    state = live.app.state.server

    try:
        request = httpx.Request("POST", f"{live.url}/api/models", data=FAST_FIT,
                                files={"image": ("noise.png", buf.getvalue())})
        _sent_and_left(live, request, entered.is_set, until)
        release.set()
        until(lambda: state.decoding.holding == 0)
        time.sleep(0.2)  # the route has gone on (or not) after its decoding
        assert len(state.queue) == 0 and os.listdir(tmp_path / "models") == []  # no fit started for nobody
        r = httpx.post(f"{live.url}/api/models", data=FAST_FIT, files={"image": ("noise.png", buf.getvalue())},
                       timeout=60)
        assert r.status_code == 202 and len(state.queue) == 1, r.text  # the same upload, its client still there
        state.queue.cancel(r.json()["job"], everyone=True)
    finally:
        release.set()
        live.stop()
    assert state.decoding.holding == 0 and state.decoding.waiting == 0


def test_a_model_file_whose_client_went_away_while_it_was_read_is_not_kept(tmp_path, two_model_files, monkeypatch):
    """An uploaded model file whose client went away while it was read was kept in the cache for nobody
    (its id never reached anyone). It is not kept now: no file left in the folder, not even a temporary one."""
    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    from tghop import modelfile

    release, entered, load = threading.Event(), threading.Event(), modelfile.load_model

    def held(path, **kwargs):  # the real loading, held until released
        entered.set()
        release.wait(60)
        return load(path, **kwargs)

    monkeypatch.setattr(modelfile, "load_model", held)
    live = LiveServer(tmp_path, max_decodes=1)
    state = live.app.state.server

    try:
        request = httpx.Request("POST", f"{live.url}/api/models/upload", content=two_model_files[0])
        _sent_and_left(live, request, entered.is_set, until)
        release.set()
        until(lambda: state.decoding.holding == 0)
        assert os.listdir(tmp_path / "models") == []  # neither kept nor left as a temporary file
        r = httpx.post(f"{live.url}/api/models/upload", content=two_model_files[0], timeout=60)
        assert r.status_code == 200 and os.listdir(tmp_path / "models") == [f"{r.json()['id']}.npz"], r.text
    finally:
        release.set()
        live.stop()
    assert state.decoding.holding == 0 and state.decoding.waiting == 0


def test_every_generation_route_reads_its_models_in_the_decoding_turn(tmp_path, two_model_files):
    """An image, a remix, a morph and an extend each read the models they need that are not in memory on
    a decoding thread holding a slot of the decoding turn (given back after), once per model, before the
    generation takes its thread."""
    import io

    import numpy as np
    from PIL import Image

    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

    ids = _in_cache_folder(tmp_path, two_model_files)
    live = LiveServer(tmp_path, max_decodes=1)
    state = live.app.state.server
    seen, read = [], state.cache._load

    def watched(path):  # the cache's real reading, with the thread and the gate seen as it starts
        seen.append((path.name[:64], threading.current_thread().name, state.decoding.holding))
        return read(path)

    state.cache._load = watched
    buf = io.BytesIO()
    Image.fromarray(np.random.default_rng(1).integers(0, 256, (32, 32, 3), dtype=np.uint8)).save(buf, format="PNG")
    asks = {"image": lambda c: c.post(f"/api/models/{ids[0]}/images", json={"size": [16, 16], "n_patches": 100}),
            "remix": lambda c: c.post("/api/images/guided", json={"models": ids, "size": [24, 24], "n_patches": 100}),
            "morph": lambda c: c.post("/api/images/morph", json={"a": ids[0], "b": ids[1], "size": [32, 48]}),
            "extend": lambda c: c.post(f"/api/models/{ids[1]}/extend", data={"size": "48x48"},
                                       files={"image": ("picture.png", buf.getvalue())})}
    try:
        with httpx.Client(base_url=live.url, timeout=120) as client:
            for name, ask in asks.items():
                with state.cache._lock:  # neither model in memory, as on a fresh server
                    state.cache._loaded.clear()
                seen.clear()
                r = ask(client)
                assert r.status_code == 200, (name, r.text)
                wanted = {"image": ids[:1], "extend": ids[1:]}.get(name, ids)
                assert sorted(m for m, _, _ in seen) == sorted(wanted), (name, seen)
                assert all(thread.startswith("tghop-decode") and holding == 1 for _, thread, holding in seen), \
                    (name, seen)
                assert state.decoding.holding == 0 and state.decoding.waiting == 0
    finally:
        live.stop()
