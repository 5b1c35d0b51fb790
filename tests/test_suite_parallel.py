"""How the suite itself runs (tests/conftest.py): the whole suite on pytest-xdist's workers, each test file whole
on one worker; a run naming files, ``-n 0`` or ``-p no:xdist`` in one process (docs/choices.md, "The test suite")."""

import os
from pathlib import Path
from types import SimpleNamespace

import pytest

import conftest


class _Config:
    def __init__(self, args_source="TESTPATHS", numprocesses=None, dist="no", usepdb=False, xdist=True, worker=False):
        self.args_source = getattr(pytest.Config.ArgsSource, args_source)
        self.option = SimpleNamespace(numprocesses=numprocesses, dist=dist, loadscopereorder=True)
        self.pluginmanager = SimpleNamespace(has_plugin=lambda name: xdist and name == "xdist")
        self._usepdb = usepdb
        if worker:
            self.workerinput = {"workerid": "gw0"}

    def getoption(self, name):
        assert name == "usepdb"
        return self._usepdb


def _run(**kwargs):
    config = _Config(**kwargs)
    conftest.pytest_cmdline_main(config)
    return config.option


def test_the_whole_suite_runs_on_workers_one_per_core_up_to_the_limit(monkeypatch):
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(16)), raising=False)
    option = _run()
    assert (option.numprocesses, option.dist, option.loadscopereorder) == (conftest.PARALLEL_WORKERS, "loadfile", False)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0}, raising=False)
    assert _run().numprocesses == 1


@pytest.mark.parametrize("kwargs", [dict(args_source="ARGS"), dict(args_source="INVOCATION_DIR"), dict(numprocesses=0),
                                    dict(xdist=False), dict(usepdb=True), dict(worker=True)])
def test_a_run_naming_files_or_asking_for_none_stays_in_process(kwargs):
    option = _run(**kwargs)
    assert (option.numprocesses, option.dist) == (kwargs.get("numprocesses"), "no")


@pytest.mark.parametrize("numprocesses", [3, "auto"])
def test_workers_asked_for_keep_each_file_whole(numprocesses):
    # `-n 3 tests/` alone: xdist's own default, --dist load, would share a file's tests among workers (a browser
    # file's tests share their page, and its module fixtures would be made on each worker).
    assert _run(args_source="ARGS", numprocesses=numprocesses).dist == "loadfile"
    assert _run(numprocesses=numprocesses, dist="load").dist == "load"  # a --dist given is kept


def test_the_scheduler_keeps_a_file_whole_and_a_group_of_files_together(monkeypatch):
    pytest.importorskip("xdist", reason="pytest-xdist is not installed (pip install -e '.[test]')")
    monkeypatch.setattr(conftest, "TOGETHER", {"test_b.py": "pair", "test_c.py": "pair"})
    config = SimpleNamespace(getvalue={"dist": "loadfile", "tx": ["popen"] * 2}.get)
    scheduler = conftest.pytest_xdist_make_scheduler(config, None)
    assert [scheduler._split_scope(f"tests/test_{f}.py::test_x[1]") for f in "abcd"] == [
        "tests/test_a.py", "pair", "pair", "tests/test_d.py"]
    config = SimpleNamespace(getvalue={"dist": "load", "tx": ["popen"] * 2}.get)
    assert conftest.pytest_xdist_make_scheduler(config, None) is None  # xdist's own


class _Item:
    def __init__(self, path):
        self.path = Path(path)


def test_on_a_worker_the_slow_files_come_first(monkeypatch):
    monkeypatch.setattr(conftest, "SLOW_FIRST", ("test_c.py", "test_b.py"))
    names = ["test_a.py", "test_b.py", "test_c.py", "test_c.py", "test_b.py", "test_d.py"]
    items = [_Item(f"tests/{name}") for name in names]
    conftest.pytest_collection_modifyitems(_Config(worker=True), items)
    assert [i.path.name for i in items] == ["test_c.py", "test_c.py", "test_b.py", "test_b.py", "test_a.py",
                                            "test_d.py"]
    items = [_Item(f"tests/{name}") for name in names]
    conftest.pytest_collection_modifyitems(_Config(), items)  # in one process: the usual order
    assert [i.path.name for i in items] == names


def test_every_file_that_drives_a_browser_or_starts_a_dask_cluster_is_in_its_group():
    # A browser file left out of TOGETHER runs beside the others on the second worker, with a browser of its own
    # (0.60's first ZIP-download file was); likewise a file of Dask clusters beside test_batch's
    here = Path(__file__).parent
    for path in sorted(here.glob("test_*.py")):
        if path.name == Path(__file__).name:
            continue
        text = path.read_text(encoding="utf-8")
        if "\nimport chromium" in text or "\nimport marionette" in text:
            assert conftest.TOGETHER.get(path.name) == "browsers", path.name
        if "LocalCluster" in text or "tghop.batch_dask" in text:
            assert conftest.TOGETHER.get(path.name) == "dask", path.name


def test_the_files_named_to_start_first_or_run_together_exist():
    # A name misspelt or of a file since renamed would be passed over without a word: that file would start late.
    here = Path(__file__).parent
    assert [name for name in (*conftest.SLOW_FIRST, *conftest.TOGETHER) if not (here / name).is_file()] == []
    assert len(set(conftest.SLOW_FIRST)) == len(conftest.SLOW_FIRST)


def test_openblas_idle_threads_sleep_soon_in_the_tests_as_in_the_command():
    # 0.63: the workers ran the library with OpenBLAS's default spin between calls (the command sets it short):
    # on CI's 2 cores each worker's spinning BLAS thread took the CPU from the other worker's tests.
    import subprocess
    import sys

    assert os.environ.get("OPENBLAS_THREAD_TIMEOUT"), "set by tests/conftest.py before NumPy loads"
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
    code = "import os, conftest; print(os.environ['OPENBLAS_THREAD_TIMEOUT'])"
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env,
                       cwd=Path(__file__).parent)
    assert p.returncode == 0 and p.stdout.strip() == "4", p.stderr  # what the workers inherit, unless the user set it
