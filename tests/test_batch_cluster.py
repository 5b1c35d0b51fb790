"""``tghop batch --scheduler`` against a cluster started apart, as a studio runs it: a real
``dask scheduler`` and ``dask worker`` processes (no LocalCluster of this process), each test's
own, ended at its end. Exemplars are made in code; the tasks are tiny or stand-ins.
"""

import json
import os
import socket
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import pytest

from tghop import batch, data
from tghop._errors import TGHopError
from tghop.imageio import save_image

pytest.importorskip("distributed")


def _start(args, env=None, cwd=None):
    """``python -m ARGS`` (or ``-c``) with this folder first on its path: its tasks are this module's functions."""
    path = os.pathsep.join(p for p in (str(Path(__file__).parent), os.environ.get("PYTHONPATH")) if p)
    return subprocess.Popen([sys.executable, *(args if args[0] == "-c" else ["-m", *args])], cwd=cwd,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": path, **(env or {})})


def _wait_for(p, text):
    """The line of ``p``'s stderr that holds ``text`` (None where ``p`` ended first)."""
    for line in p.stderr:
        if text in line:
            p.log = []  # the rest of its stderr, drained (a full pipe would block it)
            threading.Thread(target=lambda: p.log.extend(p.stderr), daemon=True).start()
            return line
    return None


def _until_running(out, seconds=120):
    """Wait (at most ``seconds``) until an exemplar of the batch writing into ``out`` has been handed out."""
    deadline = time.time() + seconds
    while time.time() < deadline and not list(out.glob("*/.batch-running")):
        time.sleep(0.1)


def _tghop_of_version(d, version="0.1.0"):
    """A copy of this tghop in ``d`` that says it is ``version``: the PYTHONPATH of a worker that runs it (this
    folder after it, for the tasks of this module)."""
    import shutil

    import tghop

    shutil.copytree(Path(tghop.__file__).parent, d / "tghop", ignore=shutil.ignore_patterns("__pycache__"))
    init = d / "tghop" / "__init__.py"
    init.write_text(init.read_text().replace(f'__version__ = "{tghop.__version__}"', f'__version__ = "{version}"'))
    assert f'__version__ = "{version}"' in init.read_text()
    return os.pathsep.join([str(d), str(Path(__file__).parent)])


class Cluster:
    """A scheduler and worker processes of their own; :meth:`close` ends each by its id."""

    def __init__(self):
        self.scheduler = _start(["distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
                                 "--dashboard-address", ":0"])
        self.procs = [self.scheduler]
        line = _wait_for(self.scheduler, "Scheduler at:")
        assert line, "the scheduler did not start"
        self.address = line.split("Scheduler at:")[1].strip()

    def worker(self, name, env=None):
        p = _start(["distributed.cli.dask_worker", self.address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                    "--name", name], env)
        self.procs.append(p)
        assert _wait_for(p, "Registered to:"), "the worker did not start"
        return p

    def close(self):
        for p in self.procs:
            if p.poll() is None:
                p.kill()
            p.wait(timeout=30)


@pytest.fixture
def cluster():
    c = Cluster()
    try:
        yield c
    finally:
        c.close()


def make_folder(d, n=2):
    d.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        save_image(data.bricks(48, rng=i), d / f"e{i}.png")
    return d


def ledger(out):
    return [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]


def slow_task(job):
    """A task that runs until its worker goes (a stand-in for a long exemplar)."""
    deadline = time.time() + 60
    while time.time() < deadline:
        time.sleep(0.1)
    return {"status": "failed", "error": "ran out", "cause": "run", "outputs": [], "model": None, "thumbnail": None}


def test_a_scheduler_gone_mid_run_is_one_line_and_its_exemplars_are_left_to_the_rerun(tmp_path, cluster):
    # The scheduler stopped mid-run: Dask's client gave up reconnecting after its timeout and the
    # command said "cannot write the output: Timed out trying to connect to tcp://..." (an OSError).
    # 0.58: an error of its own class (a TGHopError), so that a caller can tell "run it again".
    cluster.worker("w1")
    src, out = make_folder(tmp_path / "src"), tmp_path / "out"

    def kill_when_handed_out():
        _until_running(out)
        cluster.scheduler.kill()

    killer = threading.Thread(target=kill_when_handed_out, daemon=True)
    killer.start()
    with pytest.raises(batch.SchedulerLostError, match=r"^lost the Dask scheduler at tcp://127\.0\.0\.1:\d+ in the "
                                                       r"middle of the run .*run the same command$"):
        batch.run(src, out, size=(48, 48), seed=1, scheduler=cluster.address, task=slow_task)
    killer.join()
    lines = ledger(out)
    assert lines and {line["status"] for line in lines} == {"interrupted"}, lines  # done again by the next run
    assert not list(out.glob("*/.batch-running"))


def test_the_command_says_a_lost_scheduler_in_one_line(tmp_path, cluster):
    # As above, by `tghop batch --scheduler` (its exemplars' task a stand-in): Dask's client logged
    # "Failed to reconnect to scheduler" and a traceback above the error (its loggers' levels, which
    # the command lowers, were set again when distributed was imported, after the command's). 0.58: exit
    # status 3, its own; 0.57's 1 read as "some exemplars failed" to a script, which then looked at the ledger.
    cluster.worker("w1")
    make_folder(tmp_path / "src")
    code = ("import sys, tghop.__main__, tghop.batch, test_batch_cluster; "
            "tghop.batch.process_exemplar = test_batch_cluster.slow_task; "
            "sys.argv = ['tghop', *sys.argv[1:]]; tghop.__main__.run()")
    p = _start(["-c", code, "batch", "src", "-o", "out", "--scheduler", cluster.address, "--size", "48", "--seed",
                "1", "-q"], cwd=tmp_path)
    _until_running((tmp_path / "out"))
    cluster.scheduler.kill()
    _, err = p.communicate(timeout=120)
    assert p.returncode == 3, err
    assert err.startswith("Error: lost the Dask scheduler at tcp://") and err.count("\n") == 1, err


def _fake_tghop(d, init, toolz=None):
    """A folder that shadows tghop on a worker's path (``init``: its ``__init__.py``), and where
    ``toolz`` is given, that package's installed version as Dask reads it (its metadata)."""
    (d / "tghop").mkdir(parents=True)
    (d / "tghop" / "__init__.py").write_text(init)
    if toolz:
        (d / f"toolz-{toolz}.dist-info").mkdir()
        meta = f"Metadata-Version: 2.1\nName: toolz\nVersion: {toolz}\n"
        (d / f"toolz-{toolz}.dist-info" / "METADATA").write_text(meta)
    return str(d)


def test_workers_without_tghop_or_with_another_are_refused_before_any_work(tmp_path, cluster):
    # A worker without tghop failed to load every task handed to it and closed itself, and the run
    # went on without a word; one of another version made its exemplars under this version's ledger
    # line; Dask's own VersionMismatchWarning (a table) was hidden by the command (no UserWarning).
    import distributed

    from test_cli_failures import assert_one_line, invoke

    make_folder(tmp_path / "src")
    cluster.worker("w1")
    missing = cluster.worker("w2", {"PYTHONPATH": _fake_tghop(
        tmp_path / "none", "raise ModuleNotFoundError(\"No module named 'tghop'\", name='tghop')")})
    args = ["batch", "src", "-o", "out", "--scheduler", cluster.address, "--size", "48", "-q"]
    code, _, err, exc = invoke(*args, cwd=tmp_path)
    assert_one_line(code, err, "1 of the Dask cluster's 2 workers cannot import tghop (w2 (tcp://", exception=exc)
    assert "No module named 'tghop'): install tghop " in err
    assert not (tmp_path / "out").exists()
    missing.kill()
    missing.wait(timeout=30)
    with distributed.Client(cluster.address, timeout="10s") as client:
        deadline = time.time() + 60
        while time.time() < deadline and len(client.nthreads()) != 1:
            time.sleep(0.1)
        cluster.worker("w3", {"PYTHONPATH": _fake_tghop(tmp_path / "old", "__version__ = '0.1.0'\n", toolz="0.0.1")})
    code, _, err, exc = invoke(*args, cwd=tmp_path)
    assert_one_line(code, err, "1 of the Dask cluster's 2 workers runs another tghop than this command's "
                    f"{batch.__version__} (w3 (tcp://", exception=exc)
    warning, error = err.splitlines()
    assert warning.startswith(f"Warning: the Dask cluster at {cluster.address} runs other versions") and \
        "toolz " in warning and ", 0.0.1 on a worker (tcp://" in warning, err
    assert not (tmp_path / "out").exists()


def quick_task(job):
    """A task that ends at once, but the first of a run's, which records its process's id and its exemplar
    and waits for it to be killed (the test kills that worker)."""
    first = Path(job["folder"]).parent / ".first"
    try:
        with open(first, "x") as f:
            f.write(f"{os.getpid()} {job['name']}")
    except FileExistsError:
        return {"status": "failed", "error": "a stand-in", "cause": "run", "outputs": [], "model": None,
                "thumbnail": None}
    return slow_task(job)


def test_a_worker_killed_mid_run_is_said_and_the_run_ends_on_the_other(tmp_path, cluster):
    # kill -9 of a worker process mid-run: its exemplar ran again on the other worker and the run
    # ended as if nothing had happened (the scheduler's log alone said it).
    workers = [cluster.worker("w1"), cluster.worker("w2")]
    src, out = make_folder(tmp_path / "src", 3), tmp_path / "out"

    def kill_the_first():
        deadline = time.time() + 120
        while time.time() < deadline and not (out / ".first").is_file():
            time.sleep(0.1)
        time.sleep(0.5)
        (p,) = [p for p in workers if p.pid == int((out / ".first").read_text().split()[0])]
        p.kill()

    killer = threading.Thread(target=kill_the_first, daemon=True)
    killer.start()
    # 0.58 names the exemplar it was running (the scheduler's event of the worker's removal); 0.57 said "an
    # exemplar under way on it runs again ..."
    with pytest.warns(UserWarning, match=r"^a Dask worker left the cluster mid-run \(w[12] \(tcp://127\.0\.0\.1:\d+\): "
                                         r"killed, out of memory or stopped\); the exemplar it was running, (e\d), "
                                         r"runs again on another worker") as caught:
        results = batch.run(src, out, size=(48, 48), seed=1, scheduler=cluster.address, task=quick_task)
    killer.join()
    named = (out / ".first").read_text().split()[1]
    assert [str(w.message).split("running, ")[1].split(",")[0] for w in caught if "left the" in str(w.message)] == \
        [named]
    assert [r["error"] for r in results] == ["a stand-in"] * 3  # none lost: the killed one's ran again


def waiting_task(job):
    """A task that waits for the file ``.go`` beside the exemplars' folders (the test makes it), then ends."""
    go = Path(job["folder"]).parent / ".go"
    deadline = time.time() + 60
    while time.time() < deadline and not go.exists():
        time.sleep(0.1)
    return {"status": "failed", "error": "a stand-in", "cause": "run", "outputs": [], "model": None, "thumbnail": None}


def test_a_worker_without_tghop_that_joins_mid_run_stops_it_with_one_line(tmp_path, cluster):
    # Workers were checked once, before any work (0.57): one without tghop that joined later was handed
    # exemplars, which failed on it. 0.58 checks each worker that joins as the next exemplar is handed out.
    cluster.worker("w1")
    make_folder(tmp_path / "src", 3)
    out = tmp_path / "out"
    none = _fake_tghop(tmp_path / "none", "raise ModuleNotFoundError(\"No module named 'tghop'\", name='tghop')")

    def join_late():
        _until_running(out)
        cluster.worker("w2", {"PYTHONPATH": none})
        (out / ".go").touch()

    joiner = threading.Thread(target=join_late, daemon=True)
    joiner.start()
    code = ("import sys, tghop.__main__, tghop.batch, test_batch_cluster; "
            "tghop.batch.process_exemplar = test_batch_cluster.waiting_task; "
            "sys.argv = ['tghop', *sys.argv[1:]]; tghop.__main__.run()")
    p = _start(["-c", code, "batch", "src", "-o", "out", "--scheduler", cluster.address, "--size", "48", "--seed",
                "1", "-q"], cwd=tmp_path)
    _, err = p.communicate(timeout=180)
    joiner.join()
    assert p.returncode == 1, err
    assert err.startswith("Error: 1 Dask worker that joined the cluster mid-run cannot import tghop (w2 (tcp://") and \
        "No module named 'tghop'): install tghop " in err and err.endswith("the next run does the rest\n") and \
        err.count("\n") == 1, err
    lines = ledger(out)
    # the exemplar that ran on w1 before w2 joined is kept; none ran on w2; none failed for its input
    assert [line["error"] for line in lines] == ["a stand-in"], lines
    assert not list(out.glob("*/.batch-running"))


def test_a_task_moved_to_a_worker_of_another_tghop_that_joined_mid_run_stops_the_run(tmp_path, cluster):
    # The worker that ran an exemplar was killed, and the scheduler moved its task to a worker that had
    # joined since with another tghop, before any hand-out saw it: 0.57 made the exemplar there under this
    # version's ledger line. 0.58's task checks its worker's version (tghop.batch_task.run_checked). (A
    # worker whose tghop lacks run_checked, 0.57 and earlier, or that has none, cannot load the task and
    # closes itself when it gets one: Dask's doing; the task goes to another worker.)
    first = cluster.worker("w1")
    src, out = make_folder(tmp_path / "src", 1), tmp_path / "out"
    other = _tghop_of_version(tmp_path / "other")

    def join_late_and_kill_the_first():
        _until_running(out)
        cluster.worker("w2", {"PYTHONPATH": other})
        first.kill()

    joiner = threading.Thread(target=join_late_and_kill_the_first, daemon=True)
    joiner.start()
    with pytest.raises(TGHopError, match=r"^1 Dask worker that joined the cluster mid-run runs another tghop than "
                                         r"this command's [^ ]+ \(w2 \(tcp://127\.0\.0\.1:\d+\): 0\.1\.0\): install "
                                         r".*the next run does the rest$"):
        batch.run(src, out, size=(48, 48), seed=1, scheduler=cluster.address, task=waiting_task)
    joiner.join()
    lines = ledger(out)
    assert [line["status"] for line in lines] == ["interrupted"], lines  # done again by the next run


def test_a_task_on_a_worker_of_another_tghop_fails_in_one_line(monkeypatch):
    # What run_checked does where such a worker could load it (a tghop of 0.58 or later, of another version).
    from tghop import batch_task

    with pytest.raises(TGHopError, match=r"^the Dask worker [^ ]+:\d+ runs tghop [^ ]+, not this batch's 0\.1\.0: "
                                         r"install tghop 0\.1\.0 on every worker and restart it$"):
        batch_task.run_checked(waiting_task, {"folder": "/nonexistent/x"}, "0.1.0")
    assert batch_task.run_checked(len, [1, 2], batch.__version__) == 2


def test_a_worker_gone_while_it_is_checked_is_no_worker_without_tghop():
    # A worker that left between the list of workers and the check (killed as a worker joined, a task
    # failed) answered with its connection's OSError, which read as "cannot import tghop (...; OSError)"
    # and stopped the run. Now such a worker is not counted; an import error still is.
    from tghop.batch_dask import check_workers_tghop

    class Client:
        def __init__(self, answers):
            self.answers = answers

        def run(self, *args, **kwargs):
            return self.answers

        def scheduler_info(self):
            return {"workers": {}}

    gone = OSError("Timed out trying to connect to tcp://127.0.0.1:1")
    check_workers_tghop(Client({"tcp://a:1": batch.__version__, "tcp://b:1": gone}), ["tcp://a:1", "tcp://b:1"])
    with pytest.raises(TGHopError, match=r"^1 Dask worker that joined the cluster mid-run cannot import tghop "
                                         r"\(tcp://c:1; ModuleNotFoundError: No module named 'tghop'\)"):
        check_workers_tghop(Client({"tcp://b:1": gone, "tcp://c:1": ModuleNotFoundError("No module named 'tghop'"),
                                    "tcp://d:1": batch.__version__}), ["tcp://b:1", "tcp://c:1", "tcp://d:1"])
    with pytest.raises(TGHopError, match=r"^2 Dask workers that joined the cluster mid-run run another tghop "):
        check_workers_tghop(Client({"tcp://e:1": "0.1.0", "tcp://f:1": "0.2.0"}), ["tcp://e:1", "tcp://f:1"])


def test_a_timed_out_record_names_its_worker_as_other_records_do():
    # 0.62's timed-out record named the worker by its address (tcp://...), other records by host:pid (run_task's);
    # the host:pid is the nanny's answer (the worker itself is busy with the task). A worker without a nanny: its
    # address, as before.
    from tghop import batch_dask
    from tghop.batch_dask import _stop_overdue

    class Future:
        def __init__(self, key):
            self.key = key

    class Client:
        def __init__(self, nanny):
            self.nanny, self.asked = nanny, []

        def processing(self):
            return {"tcp://10.0.0.7:4100": ["k1"], "tcp://10.0.0.8:4100": []}

        def scheduler_info(self):
            return {"workers": {"tcp://10.0.0.7:4100": {"nanny": "tcp://10.0.0.7:4101" if self.nanny else None}}}

        def run(self, function, workers, nanny, on_error):
            self.asked.append((function, workers, nanny))
            if not self.nanny:
                raise ValueError("no nanny")
            return {address: "node7:1234" for address in workers}

        def cancel(self, futures, force):
            pass

        def restart_workers(self, workers, timeout, raise_for_error):
            pass

    job = {"name": "slow", "seed": 1}
    client = Client(nanny=True)
    [(_, record)], restarted, _ = _stop_overdue(client, [Future("k1")], set(), {"k1": job}, {"k1": (0.0, time.time())},
                                                10)
    assert record["worker"] == "node7:1234" and record["timed_out"] and restarted == ["tcp://10.0.0.7:4100"]
    assert client.asked == [(batch_dask.worker_process, ["tcp://10.0.0.7:4100"], True)]
    [(_, record)], restarted, _ = _stop_overdue(Client(nanny=False), [Future("k1")], set(), {"k1": job},
                                                {"k1": (0.0, time.time())}, 10)
    assert record["worker"] == "tcp://10.0.0.7:4100" and restarted == []  # no nanny: not restarted (0.64: not asked)

    class Nanny:
        pid = 4321

    assert batch_dask.worker_process(Nanny()) == f"{socket.gethostname()}:4321"


def test_an_exemplar_on_two_workers_that_left_is_named_once():
    # its first worker killed, its retry's too: both removals list it, and the warning said "running, a, a" (0.58's
    # first version, seen in CI's warnings)
    from tghop.batch_dask import _workers_gone

    said = _workers_gone(["tcp://1", "tcp://2"], {"tcp://1": "0", "tcp://2": "1"}, True,
                         {"tcp://1": ["a"], "tcp://2": ["a"]})
    assert "the exemplar they were running, a, runs again on another worker" in said, said


def pretend_another_tghop():
    """Run in a worker (``Client.run``): its tghop says another version, as one installed apart would."""
    import tghop

    tghop.__version__ = "0.0.1"


@pytest.fixture
def local():
    """A real LocalCluster of this process (one worker process) and a client of it: a program's own cluster,
    given to ``tghop.batch.run(client=...)``."""
    import distributed

    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0",
                                       silence_logs=50)
    client = distributed.Client(cluster)
    try:
        yield cluster, client
    finally:
        client.close()
        cluster.close()


def test_a_given_clients_workers_are_checked_before_any_work(tmp_path, local):
    # 0.58 checked a --scheduler cluster's workers but not those of a client given to run (client=): a worker of
    # another tghop made its exemplars under this version's ledger line. 0.59 checks them as --scheduler's.
    cluster, client = local
    client.run(pretend_another_tghop)
    src, out = make_folder(tmp_path / "src", 1), tmp_path / "out"
    with pytest.raises(TGHopError, match=r"^1 of the Dask cluster's 1 worker runs another tghop than this "
                                         r"command's [^ ]+ \(0 \(tcp://127\.0\.0\.1:\d+\): 0\.0\.1\): install "):
        batch.run(src, out, size=(48, 48), seed=1, client=client, task=waiting_task)
    assert not out.exists()  # before any work
    assert client.submit(sum, [1, 2], pure=False).result(timeout=30) == 3  # the caller's client is not closed


def test_a_given_clients_worker_of_another_tghop_that_joins_mid_run_stops_it(tmp_path, cluster):
    # The client of a cluster started apart (a program's own Client(address)); a worker that joins it mid-run
    # with another tghop stops the run, as with --scheduler (0.58 checked none of a given client's workers).
    import distributed

    cluster.worker("w1")
    src, out = make_folder(tmp_path / "src", 3), tmp_path / "out"
    other = _tghop_of_version(tmp_path / "other")

    def join_late():
        _until_running(out)
        cluster.worker("w2", {"PYTHONPATH": other})
        (out / ".go").touch()

    client = distributed.Client(cluster.address, timeout="30s")
    try:
        joiner = threading.Thread(target=join_late, daemon=True)
        joiner.start()
        with pytest.raises(TGHopError, match=r"^1 Dask worker that joined the cluster mid-run runs another tghop "
                                             r"than this command's [^ ]+ \(w2 \(tcp://127\.0\.0\.1:\d+\): 0\.1\.0\): "
                                             r"install .*the next run does the rest$"):
            batch.run(src, out, size=(48, 48), seed=1, client=client, task=waiting_task)
        joiner.join()
    finally:
        client.close()
    assert [line["error"] for line in ledger(out)] == ["a stand-in"]  # made before the worker joined
    assert not list(out.glob("*/.batch-running"))


@pytest.mark.parametrize("processes", [False, True])
def test_a_worker_of_another_tghop_that_joins_a_given_clients_local_cluster_from_elsewhere_stops_the_run(
        tmp_path, processes):
    # A program's own LocalCluster (its workers threads of this process, or processes its nannies start with this
    # interpreter) given as client=: 0.59 checked none of the workers that joined it mid-run, so one started apart
    # against its scheduler with another tghop was handed exemplars, each failed there (run_checked), and the run
    # went on. Now only the cluster's own workers (its worker_spec's names: restarts, scale) are left unchecked.
    import distributed

    src, out = make_folder(tmp_path / "src", 3), tmp_path / "out"
    other = _tghop_of_version(tmp_path / "other")
    # tcp: threads' default is inproc://, which no worker of another process can join
    local = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=processes, dashboard_address=":0",
                                     silence_logs=50, protocol="tcp://")
    client = distributed.Client(local)
    joiner_procs = []

    def join_late():
        _until_running(out)
        p = _start(["distributed.cli.dask_worker", local.scheduler_address, "--nthreads", "1", "--no-nanny",
                    "--no-dashboard", "--name", "w2"],
                   {"PYTHONPATH": other})
        joiner_procs.append(p)
        assert _wait_for(p, "Registered to:"), "the worker did not start"
        (out / ".go").touch()

    try:
        joiner = threading.Thread(target=join_late, daemon=True)
        joiner.start()
        with pytest.raises(TGHopError, match=r"^1 Dask worker that joined the cluster mid-run runs another tghop "
                                             r"than this command's [^ ]+ \(w2 \(tcp://127\.0\.0\.1:\d+\): 0\.1\.0\): "
                                             r"install .*the next run does the rest$"):
            batch.run(src, out, size=(48, 48), seed=1, client=client, task=waiting_task)
        joiner.join()
        assert [line["error"] for line in ledger(out)] == ["a stand-in"]  # made before the worker joined
        # the cluster's own workers (a restart's, scale's) are not asked: a LocalCluster lost them (docs/batch.md)
        from tghop.batch_dask import _own_workers

        its_own, names = _own_workers(client), {a: w["name"] for a, w in client.scheduler_info()["workers"].items()}
        assert sorted(str(names[a]) for a in names if its_own(a)) == ["0"] and len(names) == 2, names
    finally:
        for p in joiner_procs:
            p.kill()
            p.wait(timeout=30)
        client.close()
        local.close()


def dying_task(job):
    os._exit(1)  # the worker process dies mid-task, every time


def test_a_local_cluster_that_loses_every_worker_for_good_stops_the_run_with_one_line(tmp_path):
    # Dask's LocalCluster closes a nanny whose worker died where none of its name registered again within
    # distributed.deploy.lost-worker-timeout (15 s): on a busy machine a restart is slower, and a test whose tasks
    # killed its workers waited for ever once the last was gone (0.59). Here the timeout is 0: the first death loses
    # the cluster's one worker, and the run stops with one line.
    import cloudpickle
    import dask
    import distributed

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    src, out = make_folder(tmp_path / "src", 2), tmp_path / "out"
    local = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0",
                                     silence_logs=50)
    client = distributed.Client(local)
    said = []

    def run():
        try:
            batch.run(src, out, size=(48, 48), seed=1, client=client, task=dying_task)
        except TGHopError as exc:
            said.append(str(exc))

    try:
        with dask.config.set({"distributed.deploy.lost-worker-timeout": "0s"}):
            runner = threading.Thread(target=run, daemon=True)
            runner.start()
            runner.join(timeout=120)
        assert not runner.is_alive(), "the run waits for ever on a cluster without workers"
        assert len(said) == 1 and said[0].startswith("the local Dask cluster lost every worker for good"), said
        assert "the next run does the rest" in said[0]
        # the exemplar under way (one worker: one at a time) is redone by the next run
        assert [line["status"] for line in ledger(out)] == ["interrupted"], ledger(out)
    finally:
        client.close()
        local.close()


def instant_task(job):
    return {"status": "failed", "error": "a stand-in", "cause": "run", "outputs": [], "model": None, "thumbnail": None}


def test_an_adaptive_local_cluster_scaled_to_zero_is_not_lost_and_dasks_private_state_is_not_read(tmp_path,
                                                                                                   monkeypatch):
    # The run's look for a cluster that lost every worker, and its wait for results, use Dask's documented API alone
    # (0.61): 0.60 read LocalCluster's private `_adaptive` and waited on as_completed's undocumented
    # `thread_condition`. An adaptive cluster scaled to zero plans no worker: not lost, whatever Dask's timeout.
    import inspect

    import dask
    import distributed

    from tghop.batch_dask import _workers_lost

    touched = []

    def recording(cls):
        class Recording(cls):
            def __getattribute__(self, name):
                if (name == "thread_condition" or name.startswith("_") and not name.startswith("__")) and \
                        inspect.currentframe().f_back.f_globals.get("__name__") == "tghop.batch_dask":
                    touched.append(f"{cls.__name__}.{name}")
                return super().__getattribute__(name)
        return Recording

    monkeypatch.setattr(distributed, "as_completed", recording(distributed.as_completed))
    local = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0",
                                     silence_logs=50)
    local.__class__ = recording(type(local))
    client = distributed.Client(local)
    try:
        src, out = make_folder(tmp_path / "src", 3), tmp_path / "out"
        assert [r["error"] for r in batch.run(src, out, size=(48, 48), seed=1, client=client, task=instant_task)] == \
            ["a stand-in"] * 3
        local.adapt(minimum=0, maximum=1, interval="100ms", wait_count=1)
        deadline = time.time() + 60
        while client.nthreads() and time.time() < deadline:
            time.sleep(0.1)
        assert not client.nthreads(), "the adaptive cluster did not scale to zero"
        lost = _workers_lost(client, None, True)  # it had workers
        with dask.config.set({"distributed.deploy.lost-worker-timeout": "0s"}):
            assert [lost() for _ in range(3)] == [False] * 3
        assert touched == []
    finally:
        client.close()
        local.close()


def test_a_local_cluster_without_its_workers_is_lost_only_after_dasks_lost_worker_timeout():
    # Its plan names a worker, and neither the scheduler nor the cluster keeps one (Dask closed it for good): lost,
    # but not before the time Dask gives a restart (an adaptive cluster starts a lost worker again itself: 0.60 never
    # looked at one). Public state alone: LocalCluster.plan and .requested, the scheduler's workers.
    import dask
    import distributed

    from tghop.batch_dask import _workers_lost

    local = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0",
                                     silence_logs=50)
    client = distributed.Client(local)
    try:
        lost = _workers_lost(client, None, False)
        assert not lost()  # it has its worker
        with dask.config.set({"distributed.deploy.lost-worker-timeout": "0s"}):
            client.retire_workers()  # the cluster's plan keeps the worker's name
            deadline = time.time() + 60
            while (client.nthreads() or local.requested) and time.time() < deadline:
                time.sleep(0.1)
            assert local.plan and not local.requested and not client.nthreads()
            with dask.config.set({"distributed.deploy.lost-worker-timeout": "1h"}):
                assert not lost()
            assert lost()
    finally:
        client.close()
        local.close()


FIT = dict(n_clusters=6, n_codewords=30, stride=4)
GEN = dict(n_patches=300)


def gated_task(job):
    """:func:`tghop.batch.process_exemplar` once a file ``gate`` beside OUTDIR exists (a task of a killed run that
    runs on, slow or started late), its record then written to ``gate.record``."""
    gate = Path(job["folder"]).parent.parent / "gate"
    Path(f"{gate}.waiting").touch()
    while not gate.exists():
        time.sleep(0.05)
    record = batch.process_exemplar(job)
    Path(f"{gate}.record").write_text(json.dumps(record, default=str))
    return record


def test_a_killed_drivers_task_that_runs_on_leaves_the_reruns_files_alone(tmp_path, cluster):
    # `tghop batch --scheduler` killed (SIGKILL): its task runs on in the cluster and, in 0.61, moved its files (seed 2)
    # into place after the rerun's (seed 1) were made and recorded, so the ledger said seed 1 of seed 2's images and
    # every later run kept them. 0.62: the rerun claims the exemplar, and the task of the killed run moves nothing.
    cluster.worker("w1")
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    save_image(data.bricks(64, rng=3), src / "e0.png")
    code = ("import sys; from tghop import batch; import test_batch_cluster as t; "
            "batch.run(sys.argv[1], sys.argv[2], size=(48, 48), seed=2, fit=t.FIT, generate=t.GEN, "
            "scheduler=sys.argv[3], task=t.gated_task, contact_sheet=False)")
    driver = _start(["-c", code, str(src), str(out), cluster.address], cwd=tmp_path)
    deadline = time.time() + 120
    while time.time() < deadline and driver.poll() is None and not (tmp_path / "gate.waiting").exists():
        time.sleep(0.05)
    assert (tmp_path / "gate.waiting").exists(), driver.stderr.read() if driver.poll() is not None else "no task"
    driver.kill()
    driver.wait(timeout=30)
    [result] = batch.run(src, out, size=(48, 48), seed=1, fit=FIT, generate=GEN, workers=1)  # the rerun
    assert result["status"] == "ok" and not result["skipped"], result["error"]
    made = {p.name: p.read_bytes() for p in (out / "e0").iterdir()}
    (tmp_path / "gate").touch()  # the killed run's task goes on now
    deadline = time.time() + 120
    while time.time() < deadline and not (tmp_path / "gate.record").exists():
        time.sleep(0.05)
    assert {p.name: p.read_bytes() for p in (out / "e0").iterdir()} == made  # the rerun's files, as its line says
    stale = json.loads((tmp_path / "gate.record").read_text())
    assert stale["status"] == "failed" and stale.get("superseded"), stale
    [again] = batch.run(src, out, size=(48, 48), seed=1, fit=FIT, generate=GEN, workers=1)
    assert again["skipped"] and again["seed_used"] == 1


def test_a_task_past_the_timeout_is_its_exemplars_failure_and_its_worker_restarted(tmp_path, local):
    # 0.62 had no time limit per task: one exemplar that never ends held its worker for ever, and with one worker the
    # batch stopped there. 0.63: task_timeout (--task-timeout) records it as the exemplar's failure and restarts the
    # worker through its nanny, so the run goes on. A real input made slow (a row of 1,000 images of 256x256, handed
    # out first: the longest), on a real LocalCluster of one worker process: the others can only run once it is freed.
    # The timeout is short (the test's own wait); the fast rows end well within it on the restarted worker under
    # load (docs/choices.md, "The test suite on CI's two cores").
    cluster, client = local
    (before,) = client.run(os.getpid).values()
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    for i in range(3):
        save_image(data.bricks(64, rng=i), src / f"e{i}.png")
    (src / "list.csv").write_text("path,count,size\ne0.png,1000,256\ne1.png,1,32\ne2.png,1,32\n")
    run = dict(size=32, seed=1, fit=FIT, generate=GEN, client=client, task_timeout=4)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        results = batch.run(src / "list.csv", out, **run)
    assert not [str(w.message) for w in said if "left the cluster" in str(w.message)]  # restarted on purpose
    slow, *others = results
    assert (slow["status"], slow["cause"], slow.get("timed_out"), slow.get("task_timeout")) == ("failed", "input", True,
                                                                                                4), slow["error"]
    assert slow["error"].startswith("stopped after the task timeout (4 s, --task-timeout / task_timeout)")
    assert slow["worker"] == f"{socket.gethostname()}:{before}"  # as other records name it (0.62: tcp://...)
    assert [r["status"] for r in others] == ["ok", "ok"], [(r["error"], r.get("seconds")) for r in others]
    assert str(before) not in {r["worker"].split(":")[1] for r in others}  # on the worker restarted
    assert list(client.nthreads().values()) == [1]
    assert not (out / "e0").exists() and not list(out.glob("*/.batch-running")) and not list(out.rglob("*.tmp"))
    again = batch.run(src / "list.csv", out, **run)  # skipped by a rerun, as a failure of its input
    assert [r["skipped"] for r in again] == [True, True, True]


def _stand_in_ok(name):
    return {"status": "ok", "error": None, "cause": None, "outputs": [], "model": None, "thumbnail": None,
            "seconds": 0.0, "worker": f"{socket.gethostname()}:{os.getpid()}"}


def restart_task(job):
    """A stand-in whose time is its name's: ``slow`` runs until its worker goes, ``wait`` 4.5 s, ``b*`` 1 s; another's
    first try runs until its worker goes (a mark beside OUTDIR says it ran), its next returns at once."""
    here, name = Path(job["folder"]).parent.parent, job["name"]
    tried = here / f"{name}.tried"
    if name == "slow" or (name not in ("wait",) and not name.startswith("b") and not tried.exists()):
        tried.touch()
        time.sleep(120)
    time.sleep(4.5 if name == "wait" else 1 if name.startswith("b") else 0)
    return _stand_in_ok(name)


def _rows(src, rows):
    """A manifest of ``rows`` (name, count), each a copy of one small exemplar: the count sets the hand-out order
    (the longest first), the stand-in task ignores it."""
    src.mkdir()
    save_image(data.bricks(48, rng=0), src / "x.png")
    (src / "list.csv").write_text("path,name,count,size\n" + "".join(f"x.png,{n},{c},32\n" for n, c in rows))
    return src / "list.csv"


def test_the_other_tasks_of_a_worker_restarted_for_a_timeout_are_run_again_uncharged(tmp_path):
    # A worker of 2 threads restarted for its timed-out task (0.63) took its other task with it: Dask counted a death
    # against that exemplar, and with no tries left (allowed-failures 0 here) recorded it failed, "the worker running
    # it died". 0.64 cancels it before the restart and hands it out again under a new key. `other` is handed out 4.5 s
    # after `slow` (once `wait` ends), so the driver's look 2 s later finds `slow` past its 6 s alone (4 s to spare for
    # a busy machine's delays: at 4 s, with 2 to spare, `other` was found late too once at a load average of 12).
    import cloudpickle
    import dask
    import distributed

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        local = distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=True, dashboard_address=":0",
                                         silence_logs=50)
    client = distributed.Client(local)
    try:
        (before,) = client.run(os.getpid).values()
        manifest, out = _rows(tmp_path / "src", [("slow", 1000), ("wait", 2), ("other", 1)]), tmp_path / "out"
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            results = batch.run(manifest, out, size=32, seed=1, client=client, task=restart_task, task_timeout=6,
                                contact_sheet=False)
        assert not [str(w.message) for w in said if "left the cluster" in str(w.message)]
        got = {r["name"]: r for r in results}
        assert got["slow"].get("timed_out") and got["wait"]["status"] == "ok"
        assert (got["other"]["status"], got["other"].get("worker_died")) == ("ok", None), got["other"]["error"]
        assert (tmp_path / "other.tried").exists() and got["other"]["worker"].split(":")[1] != str(before)
        assert sorted(line["name"] for line in ledger(out)) == ["other", "slow", "wait"]  # each once
        assert not list(out.glob("*/.batch-running"))
    finally:
        client.close()
        local.close()


async def late_name(dask_worker):
    """A nanny's answer that comes late (``Client.run`` has no timeout): a coroutine, so the nanny's loop goes on."""
    import asyncio

    await asyncio.sleep(30)
    return "late:1"


def test_a_restart_for_a_timeout_blocks_neither_results_nor_the_run(tmp_path, monkeypatch):
    # 0.63's driver waited for the restart of a timed-out task's worker (up to 120 s: Dask's restart_workers waits for
    # the new worker) and for its nanny's name (no limit), collecting no result meanwhile. Here the restarted worker
    # starts slowly (its preload sleeps 3 s, then writes `up`) and the nanny answers late: the exemplars of the other
    # worker (1 s each) come back while the restart is under way, and the timed-out one is named by its address.
    import cloudpickle
    import distributed

    from tghop import batch_dask

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    slow_start = tmp_path / "slow-start"
    preload = (f"import os, time\ndef dask_setup(worker):\n    if os.path.exists({str(slow_start)!r}):\n"
               f"        time.sleep(3)\n        open({str(slow_start)!r} + '.up', 'w').close()\n")
    local = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                     silence_logs=50, preload=[preload])
    client = distributed.Client(local)
    monkeypatch.setattr(batch_dask, "worker_process", late_name)
    monkeypatch.setattr(batch_dask, "NAME_TIMEOUT", 1.0)
    try:
        slow_start.touch()
        manifest = _rows(tmp_path / "src", [("slow", 1000), *[(f"b{i}", 1) for i in range(6)]])
        order = []
        results = batch.run(manifest, tmp_path / "out", size=32, seed=1, client=client, task=restart_task,
                            task_timeout=4, contact_sheet=False,
                            on_result=lambda r, counts: order.append((r["name"], Path(f"{slow_start}.up").exists())))
        got = {r["name"]: r for r in results}
        assert got["slow"].get("timed_out") and got["slow"]["worker"].startswith("tcp://"), got["slow"]["worker"]
        assert [got[f"b{i}"]["status"] for i in range(6)] == ["ok"] * 6
        after = order[[name for name, _ in order].index("slow") + 1:]
        assert after and not after[0][1], order  # the next result came back before the restarted worker
    finally:
        client.close()
        local.close()
