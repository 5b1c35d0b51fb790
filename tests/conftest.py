"""Shared fixtures: small textures made in code and a small fitted model (no ../shared)."""

import os
import signal
import sys

# OpenBLAS's idle threads spin up to 2^28 cycles between calls, taking the CPU from the other worker's tests on
# CI's 2 cores: set as `tghop` sets it for the command (tghop.__main__.run), before NumPy is loaded here and in
# the xdist workers, which inherit it (docs/choices.md, "The test suite on CI's two cores", 0.63). Idle time only:
# the same numbers.
os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")

import numpy as np  # noqa: E402
import pytest

from tghop import data
from tghop.synthesis import TGHop

# Tests send SIGINT, SIGTERM and SIGHUP to commands they start. A suite run in the
# background (`cmd &` ignores SIGINT) or under nohup (SIGHUP) would pass those ignored
# dispositions on to every child: restore the defaults, for the children's sake.
for _sig, _default in ((signal.SIGINT, signal.default_int_handler), (signal.SIGHUP, signal.SIG_DFL),
                       (signal.SIGTERM, signal.SIG_DFL)):
    if signal.getsignal(_sig) == signal.SIG_IGN:
        signal.signal(_sig, _default)


@pytest.hookimpl(trylast=True)
def pytest_runtest_teardown(item, nextitem):
    """The browser test files' one Chromium (chromium.shared_browser) ended once the next test is of a file without
    it (after that file's page fixture closed its page): while it runs, asyncio.run in this thread is refused."""
    shared = sys.modules.get("chromium")
    if shared is not None and getattr(getattr(nextitem, "module", None), "chromium", None) is not shared:
        shared.close_shared()


# The whole suite (`python -m pytest`, the README's and CI's command, which collects pyproject's testpaths) runs on
# pytest-xdist's workers, one per usable core up to PARALLEL_WORKERS; a run naming files or folders, `-n 0`,
# `-p no:xdist` or `--pdb` runs in this process as before. Each test file runs whole on one worker, in its own order
# (module fixtures are made once; the browser files' tests share their page's state), and the files of one
# TOGETHER group run one after another on one worker. docs/choices.md, "The test suite".
PARALLEL_WORKERS = 2

_BROWSERS = ("test_server_browser.py", "test_server_browser_artist.py", "test_server_browser_compare.py",
             "test_server_browser_download.py", "test_server_browser_materials.py", "test_server_browser_page.py",
             "test_server_browser_page3.py", "test_server_browser_page4.py", "test_server_browser_page5.py",
             "test_server_browser_progress.py", "test_server_browser_state.py", "test_server_firefox.py")
_DASK = ("test_batch.py", "test_batch_cluster.py", "test_batch_materials.py", "test_batch_resume.py")

#: Files that must not run at the same time as each other (file name -> group name): one browser at a time, as the
#: page's waits were set for; one Dask cluster of worker processes at a time (their heartbeats and the tests' waits).
TOGETHER = {**dict.fromkeys(_BROWSERS, "browsers"), **dict.fromkeys(_DASK, "dask")}

#: The files that take longest, started first so that no worker is left with a long one at the end (a file not
#: named here goes after them, in the usual order; a stale list only balances the workers less well). The server's
#: two longest files would otherwise come near the end of that order (0.61).
SLOW_FIRST = (*_DASK, "test_material.py", *_BROWSERS, "test_server.py", "test_material_fill.py",
              "test_server_materials.py", "test_help_examples.py", "test_extend.py", "test_core_model.py",
              "test_material_masks.py", "test_material_names.py")


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config):
    import os

    if not config.pluginmanager.has_plugin("xdist") or hasattr(config, "workerinput"):
        return
    whole_suite = config.args_source == pytest.Config.ArgsSource.TESTPATHS
    if whole_suite and config.option.numprocesses is None and not config.getoption("usepdb"):
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        config.option.numprocesses = min(cores, PARALLEL_WORKERS)
    if config.option.numprocesses and config.option.dist == "no":  # -n N alone too: files kept whole
        # Not --dist loadgroup and xdist_group marks: xdist 3.8 tags a test's id with its group through
        # Item._nodeid, which pytest 9 no longer reads (every test was scheduled alone).
        config.option.dist = "loadfile"
        config.option.loadscopereorder = False  # SLOW_FIRST's order, not the files' test counts


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """--dist loadfile with TOGETHER's files in one unit of work each."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class FileGroups(LoadFileScheduling):
        def _split_scope(self, nodeid):
            file = nodeid.split("::", 1)[0]
            return TOGETHER.get(file.rsplit("/", 1)[-1], file)

    return FileGroups(config, log)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    if hasattr(config, "workerinput"):  # the order that each worker's collection sends, for the scheduler
        rank = {name: i for i, name in enumerate(SLOW_FIRST)}
        items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


def straight_share(labels, run=16):
    """The share of a label map's boundary (pixel edges between two labels) in horizontal or vertical
    straight runs of at least ``run`` pixels."""
    total = long = 0
    for edges in (labels[:-1] != labels[1:], (labels[:, :-1] != labels[:, 1:]).T):
        steps = np.diff(np.pad(edges, ((0, 0), (1, 1))).astype(np.int8), axis=1)
        lengths = np.nonzero(steps == -1)[1] - np.nonzero(steps == 1)[1]
        total += lengths.sum()
        long += lengths[lengths >= run].sum()
    return long / max(total, 1)


def png(pixels) -> bytes:
    """``pixels`` (an (H, W, C) or (H, W) array, as :func:`tghop.imageio.write_png` takes) as a PNG file's bytes."""
    import io

    from tghop.imageio import write_png

    buf = io.BytesIO()
    write_png(buf, pixels)
    return buf.getvalue()


#: The small model files of :func:`save_material` and :func:`save_texture`, fitted once a test session: (kind,
#: settings) -> the file's bytes. The tests only read them (an upload, a load); np.savez stamps a file with the
#: time it was written, so two saves of one model are now the same bytes, one model id on a server.
_MODEL_FILES = {}

#: The small models' fast settings (:func:`save_material`, :func:`save_texture`).
_SMALL_FIT = dict(n_clusters=6, n_codewords=30, stride=4, max_patches=1500, layout_factor=None)


def _saved(path, key, make):
    """``make(path)`` saves a model at ``path``: its bytes kept under ``key`` (fitted the first time only)."""
    from pathlib import Path

    path = Path(path)
    if key not in _MODEL_FILES:
        make(path)
        _MODEL_FILES[key] = path.read_bytes()
    else:
        path.write_bytes(_MODEL_FILES[key])


def save_material(path, **settings):
    """A small material (64x64 bricks and their height map), fitted fast (once a session for each ``settings``),
    saved at ``path``; ``settings``: more of the joint model's (``patch_levels=0``: no patch statistics of the
    albedo, as a material of tghop 0.58)."""

    def make(path):
        from tghop import TGHop, data
        from tghop.material import Material, example_maps
        from tghop.modelfile import save_model

        albedo = data.bricks(64)
        save_model(Material(model=TGHop(**_SMALL_FIT, **settings), rng=0).fit(
            albedo, {"height": example_maps(albedo)["height"]}), path)

    _saved(path, ("material", tuple(sorted(settings.items()))), make)


def save_texture(path):
    """A small texture model of 64x64 bricks, fitted fast (once a session), saved at ``path``."""

    def make(path):
        from tghop import TGHop, data
        from tghop.modelfile import save_model

        save_model(TGHop(**_SMALL_FIT).fit(data.bricks(64)), path)

    _saved(path, ("texture",), make)


def cli(*args, cwd=None, stdin=None):
    """The ``tghop`` command line in this process, as :func:`subprocess.run` would give it.

    Returns a :class:`subprocess.CompletedProcess` with ``returncode`` and bytes ``stdout``
    and ``stderr``. An exception the command did not turn into its one-line error is a
    traceback in ``stderr`` (exit status 1), as in a real process. Starting an interpreter
    costs a second or more a command: tests of the process itself (signals, start-up,
    imports, exit on a broken pipe) run ``python -m tghop`` instead.
    """
    import os
    import subprocess
    import traceback

    from click.testing import CliRunner

    from tghop.cli import main

    old = os.getcwd()
    if cwd is not None:
        os.chdir(cwd)
    try:
        result = CliRunner().invoke(main, [str(a) for a in args], input=stdin, prog_name="tghop")
    finally:
        os.chdir(old)
    err, code = result.stderr_bytes or b"", result.exit_code
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        err += "".join(traceback.format_exception(result.exception)).encode()
        code = 1
    return subprocess.CompletedProcess(["tghop", *map(str, args)], code, result.stdout_bytes, err)


#: Fast settings for tests: the paper's pipeline, fewer clusters and patches.
SMALL = dict(n_channels=(9, 22), gamma=0.01, n_clusters=8, n_codewords=40, stride=4, rng=0)


#: A tiny co-occurrence cGAN (tghop.cooc): 32 x 32 crops, s = 8, a few filters, two steps; trains in a few seconds.
TINY_COOC = dict(n_clusters=3, crop_size=32, n_layers=3, patch=9, window=7, sigma=2.0, g_widths=(8, 4), d_widths=(4, 8),
                 noise_channels=2, n_crops=12, batch_size=4, n_steps=2, n_critic=1)


class _NoTorch:
    """A finder that answers every ``import torch`` as if PyTorch were not installed."""

    def find_spec(self, name, path=None, target=None):
        if name == "torch" or name.startswith("torch."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None


@pytest.fixture
def without_torch(monkeypatch):
    """As if PyTorch were not installed: ``import torch`` raises ModuleNotFoundError. ``torch`` is
    taken out of ``sys.modules`` rather than set to None there, which SciPy's array API helpers
    read as a module (a test of it alone failed with "'NoneType' object has no attribute 'Tensor'")."""
    monkeypatch.delitem(sys.modules, "torch", raising=False)
    monkeypatch.setattr(sys, "meta_path", [_NoTorch(), *sys.meta_path])


@pytest.fixture(scope="session")
def near_sphere():
    """(4000, 6) points near a sphere of radius 3: their components' norms are nearly equal,
    which independent draws of the components do not keep (the core model's norm matching
    and coupling)."""
    r = np.random.default_rng(7)
    u = r.standard_normal((4000, 6))
    return u / np.linalg.norm(u, axis=1, keepdims=True) * r.uniform(2.9, 3.1, size=(4000, 1))


@pytest.fixture(scope="session")
def bricks96():
    return data.bricks(96, rng=1)


@pytest.fixture(scope="session")
def small_model(bricks96):
    return TGHop(**SMALL).fit(bricks96)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(scope="module")
def one_torch_thread():
    """Tiny tensors: on a loaded machine, torch's spinning worker threads made tests 40x slower."""
    try:
        import torch
    except ImportError:
        yield
        return
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def tiny_cooc_exemplar():
    """The exemplar of :func:`tiny_cooc_checkpoint`: 64 x 64 bricks."""
    return data.bricks(64, rng=3)


@pytest.fixture(scope="session")
def tiny_cooc_checkpoint(tiny_cooc_exemplar, tmp_path_factory):
    """A ``.pt`` of :data:`TINY_COOC` trained on :func:`tiny_cooc_exemplar` (64x64, 32 px
    crops, s = 8) with one torch thread; skipped without PyTorch."""
    torch = pytest.importorskip("torch", reason="PyTorch is not installed (pip install -e '.[metrics]'): "
                                                "no co-occurrence checkpoint")
    from tghop import cooc

    path = tmp_path_factory.mktemp("cooc") / "tiny.pt"
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        cooc.CoocGAN(**TINY_COOC, device="cpu", rng=0).fit(tiny_cooc_exemplar).save(path)
    finally:
        torch.set_num_threads(threads)
    return path



def bench_script(script):
    """A benchmarks/ script (a ``Path``) imported as a module, for a module-scoped fixture to ``yield from``:
    the script's folder first on sys.path (its ``_common``), and sys.path and sys.modules as they were
    afterwards."""
    import importlib.util

    path, modules = list(sys.path), set(sys.modules)
    sys.path.insert(0, str(script.parent))
    name = f"{script.stem}_under_test"
    spec = importlib.util.spec_from_file_location(name, script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    yield module
    sys.path[:] = path
    for added in set(sys.modules) - modules:
        if added in ("_common", name):
            del sys.modules[added]

def assert_user_error(r, *fragments, status=None):
    """Non-zero exit, one 'Error:' line naming the problem, no traceback. ``r``: a finished
    process (``subprocess.run``'s) or click's in-process ``Result``; ``status``: the exit status
    it must be (2 for a usage error), where given."""
    if hasattr(r, "exit_code"):  # click's CliRunner: the exception would have been a traceback
        err, code = r.stderr, r.exit_code
        assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)
    else:
        err, code = r.stderr.decode(), r.returncode
    assert code != 0
    assert status is None or code == status, (code, err)
    assert "Traceback" not in err
    lines = [line for line in err.strip().splitlines() if line.startswith("Error")]
    assert len(lines) == 1, err
    for fragment in fragments:
        assert fragment in lines[0], err


class LiveServer:
    """``tghop serve``'s application on a real uvicorn server, in a thread, on a free port."""

    def __init__(self, cache, max_fits=1, **options):
        import socket
        import threading

        import uvicorn

        from tghop.server.app import create_app

        self.cache = cache
        self.app = create_app(cache, max_fits=max_fits, **options)
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(64)
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}"
        self.server = uvicorn.Server(uvicorn.Config(self.app, log_level="warning", lifespan="on",
                                                    timeout_graceful_shutdown=2))
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.sock]}, daemon=True)
        self.thread.start()
        import time

        deadline = time.monotonic() + 30
        while not self.server.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise RuntimeError("uvicorn did not start")
            time.sleep(0.02)

    def stop(self):
        self.server.should_exit = True
        self.thread.join(timeout=30)
        self.sock.close()


@pytest.fixture(scope="module")
def live_server(tmp_path_factory):
    """A real server (uvicorn on a free port) with an empty model cache; skipped without the web extra."""
    pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")
    pytest.importorskip("starlette", reason="the web extra is not installed: pip install -e '.[web]'")
    server = LiveServer(tmp_path_factory.mktemp("cache"))
    yield server
    server.stop()


@pytest.fixture(scope="module")
def page(live_server):
    """tghop serve's page (:func:`live_server`'s) in the browser test files' one headless Chromium
    (``tests/chromium.py``): one page a test file, in a browser context of its own; its tests share its state. A
    file that calls ``chromium.require()`` at its import is skipped where there is no Chromium or Playwright."""
    import chromium

    with chromium.served_page(live_server.url + "/", chromium.shared_browser()) as page:
        yield page


#: Fit settings that make a fit of a built-in exemplar quick (form fields): 0.62 fits 600 patches, not 0.61's 1500
#: (the tests use the model, never judge it; docs/choices.md, "The test suite on CI's two cores").
FAST_FIT = {"n_clusters": "8", "n_codewords": "40", "stride": "4", "max_patches": "600", "layout_factor": "none"}


#: JavaScript (a function of a seed and a callback) that sets the seed, clicks Generate and
#: calls back with the milliseconds from the click to the new result shown (its caption
#: naming the seed, one frame later), the caption, and the server's part (generation and
#: PNG encoding, its Server-Timing header): what the browser tests measure at 512x512.
CLICK_TO_RESULT_JS = """(seed, done) => {
  const caption = document.getElementById("result-caption");
  document.getElementById("seed").value = String(seed);
  const want = "seed " + seed;
  const t0 = performance.now();
  document.getElementById("go").click();
  const poll = () => {
    if (caption.textContent.startsWith("result: ") && caption.textContent.endsWith(want)) {
      requestAnimationFrame(() => {
        const calls = performance.getEntriesByType("resource").filter((e) => e.name.endsWith("/images"));
        const timing = calls.length ? calls[calls.length - 1].serverTiming : [];
        done([performance.now() - t0, caption.textContent, timing.length ? timing[0].duration : null]);
      });
    } else {
      setTimeout(poll, 2);
    }
  };
  poll();
}"""
