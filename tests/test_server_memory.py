"""A server left open gives memory back (0.58): when the last generation, fit or decode running ends, the
memory the C allocator kept of their arrays goes back to the system (glibc's ``malloc_trim``;
docs/serve.md, "Memory of a long-running server"). Counted, not measured: RSS on a shared machine is too
noisy for a test."""

import platform
import sys
import threading
import time

import pytest

from conftest import FAST_FIT, LiveServer

from tghop.server import core


def test_release_memory_says_whether_it_could():
    glibc = sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"
    said = core.release_memory()
    assert said is True if glibc else said in (True, False)  # glibc has malloc_trim; elsewhere it may not


def test_the_memory_is_given_back_once_the_last_work_ends_not_before(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(core, "release_memory", lambda: calls.append(threading.current_thread().name) or True)
    server = core.Server(tmp_path, 2)
    try:
        started, finish = threading.Event(), threading.Event()

        def long_work():
            with server.working():
                started.set()
                finish.wait(30)

        thread = threading.Thread(target=long_work, name="long")
        thread.start()
        assert started.wait(30)
        for _ in range(3):  # short works end while the long one runs: nothing given back yet
            with server.working():
                pass
        assert calls == [] and server.releases == 0
        finish.set()
        thread.join(30)
        assert calls == ["long"] and server.releases == 1  # the last to end, once
        with pytest.raises(ValueError), server.working():  # a work that fails ends too
            raise ValueError("failed")
        assert calls == ["long", "MainThread"] and server.releases == 2
    finally:
        server.queue.shutdown()
        server.executor.shutdown()
        server.decoder.shutdown()


def test_the_server_gives_memory_back_after_an_upload_a_generation_and_a_fit(tmp_path, small_model, monkeypatch):
    httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    from tghop.modelfile import save_model

    calls = []
    monkeypatch.setattr(core, "release_memory", lambda: calls.append(1) or True)
    save_model(small_model, tmp_path / "m.npz")
    live = LiveServer(tmp_path / "cache")
    server = live.app.state.server
    client = httpx.Client(base_url=live.url, timeout=60)
    try:
        model = client.post("/api/models/upload", content=(tmp_path / "m.npz").read_bytes())
        assert model.status_code == 200
        after_upload = len(calls)
        assert after_upload >= 1  # the upload was read on a decoding thread
        r = client.post(f"/api/models/{model.json()['id']}/images", json={"size": [40, 40], "seed": 1})
        assert r.status_code == 200
        after_generation = len(calls)
        assert after_generation == after_upload + 1
        fit = client.post("/api/models", files={"builtin": (None, "cells"),
                                                **{k: (None, v) for k, v in FAST_FIT.items()}}).json()
        deadline = time.monotonic() + 120
        while client.get(f"/api/jobs/{fit['job']}").json()["state"] not in ("done", "failed"):
            assert time.monotonic() < deadline
            time.sleep(0.05)
        assert client.get(f"/api/jobs/{fit['job']}").json()["state"] == "done"
        assert len(calls) >= after_generation + 2  # the exemplar's decode, then the fit
        assert server.releases == len(calls)
    finally:
        client.close()
        live.stop()
