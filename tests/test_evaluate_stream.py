"""``tghop evaluate`` writes each result's row as soon as it is scored: rows show before the
last result is scored, Ctrl-C (or SIGTERM) keeps the rows written, whole lines, with one line
saying how many; and --csv gives the numbers of --json."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from tghop import data, metrics
from tghop.imageio import save_image

from conftest import cli

ARGS = ["--metrics", "swd,novelty", "-q"]

# The command, with metrics.evaluate holding at its HOLD_AT-th call (the HOLD_AT-th result) until
# the file 'go' exists: the earlier results are scored by then. It writes 'holding' when it starts
# to wait, and 'released' if it gave up waiting (20 s).
HELD = """\
import os, sys, time
import tghop.metrics as M
plain, calls = M.evaluate, []
def evaluate(*args, **kwargs):
    calls.append(1)
    if len(calls) == int(os.environ["HOLD_AT"]):
        open("holding", "w").close()
        end = time.time() + 20
        while not os.path.exists("go") and time.time() < end:
            time.sleep(0.05)
        if not os.path.exists("go"):
            open("released", "w").close()
    return plain(*args, **kwargs)
M.evaluate = evaluate
from tghop.__main__ import run
sys.argv[0] = "tghop"
run()
"""


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    d = tmp_path_factory.mktemp("stream")
    save_image(data.bricks(64, rng=1), d / "ex.png")
    for i in range(3):
        save_image(data.bricks(48, rng=2 + i), d / f"r{i}.png")
    return d


def held(args, cwd, hold_at):
    env = {**os.environ, "HOLD_AT": str(hold_at)}
    return subprocess.Popen([sys.executable, "-c", HELD, "evaluate", *map(str, args)], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def wait_for(path, p, seconds=60):
    deadline = time.time() + seconds
    while not path.exists() and p.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    return path.exists()


@pytest.mark.parametrize("fmt", [[], ["--json"], ["--csv"]])
def test_rows_are_written_before_the_last_result_is_scored(images, tmp_path, fmt):
    args = [images / "ex.png", *(images / f"r{i}.png" for i in range(3)), *ARGS, *fmt]
    p = held(args, tmp_path, hold_at=3)
    try:
        first = [p.stdout.readline() for _ in range(2 if fmt == ["--json"] else 3)]  # with the header
        assert not (tmp_path / "released").exists(), first  # written while the last result waits
        assert wait_for(tmp_path / "holding", p)
    finally:
        (tmp_path / "go").touch()
    out, err = p.communicate(timeout=120)
    assert p.returncode == 0, err.decode()
    # The same output, line for line, as the command in one piece.
    whole = cli("evaluate", *args)
    assert whole.returncode == 0, whole.stderr.decode()
    assert b"".join(first) + out == whole.stdout
    assert len(whole.stdout.decode().splitlines()) == len(first) + 2  # the third row, then the diversity


@pytest.mark.parametrize("signum, message, code", [(signal.SIGINT, "interrupted", 130),
                                                   (signal.SIGTERM, "terminated", 128 + signal.SIGTERM)])
@pytest.mark.parametrize("fmt", [["--json"], ["--csv"]])
def test_a_stop_keeps_the_rows_scored_and_says_how_many(images, tmp_path, signum, message, code, fmt):
    args = [images / "ex.png", *(images / f"r{i}.png" for i in range(3)), *ARGS, *fmt]
    p = held(args, tmp_path, hold_at=2)
    try:
        assert wait_for(tmp_path / "holding", p), p.communicate(timeout=60)
        p.send_signal(signum)
        out, err = p.communicate(timeout=60)
    finally:
        (tmp_path / "go").touch()
    err = err.decode()
    assert p.returncode == code, err
    assert "Traceback" not in err
    errors = [line for line in err.splitlines() if line.startswith("Error: ")]
    assert errors == [f"Error: {message} after 1 of 3 results scored, their rows written; "
                      "running the same command again scores them all again"], err
    assert not (tmp_path / "released").exists()
    whole = cli("evaluate", *args).stdout.decode().splitlines(keepends=True)
    first = 1 if fmt == ["--json"] else 2  # the header too
    assert out.decode() == "".join(whole[:first])  # the first result's row, whole, and nothing more


def test_csv_has_the_numbers_of_json(images, monkeypatch):
    paths = [images / "ex.png", *(images / f"r{i}.png" for i in range(3))]
    plain = metrics.evaluate
    calls = []

    def evaluate(*args, **kwargs):  # the second result's novelty is not a number: null in JSON, empty in CSV
        scores = plain(*args, **kwargs)
        calls.append(1)
        if len(calls) % 3 == 2:
            scores["novelty"] = math.nan
        return scores

    monkeypatch.setattr(metrics, "evaluate", evaluate)
    names = "swd,novelty,cooccurrence"
    as_json = cli("evaluate", *paths, "--metrics", names, "-q", "--json")
    as_csv = cli("evaluate", *paths, "--metrics", names, "-q", "--csv")
    assert as_json.returncode == 0 and as_csv.returncode == 0, as_csv.stderr.decode()
    lines = [json.loads(line) for line in as_json.stdout.decode().splitlines()]
    rows = list(csv.reader(io.StringIO(as_csv.stdout.decode())))
    assert rows[0] == ["exemplar", "result", "swd", "cooccurrence", "novelty", "diversity"]  # the metrics' order
    table = [dict(zip(rows[0], row)) for row in rows[1:]]
    assert len(table) == 4 and all(len(row) == 6 for row in rows)
    for line, row in zip(lines[:3], table[:3]):
        assert row["exemplar"] == line["exemplar"] and row["result"] == line["result"] and row["diversity"] == ""
        for name in ("swd", "novelty", "cooccurrence"):
            assert (None if row[name] == "" else float(row[name])) == line[name]
    assert lines[1]["novelty"] is None and np.isfinite(lines[0]["novelty"])
    assert table[3]["result"] == "" and float(table[3]["diversity"]) == lines[3]["diversity"]
    assert {table[3][name] for name in ("swd", "novelty", "cooccurrence")} == {""}
    # Without the diversity: no column for it; one row per result.
    one = cli("evaluate", paths[0], paths[1], "--metrics", "swd", "-q", "--csv", "--no-diversity")
    assert list(csv.reader(io.StringIO(one.stdout.decode()))) == [
        ["exemplar", "result", "swd"], [str(paths[0]), str(paths[1]), repr(json.loads(
            cli("evaluate", paths[0], paths[1], "--metrics", "swd", "-q", "--json", "--no-diversity").stdout)["swd"])]]


def test_json_and_csv_together_are_refused(images):
    r = cli("evaluate", images / "ex.png", images / "r0.png", "--json", "--csv")
    assert r.returncode == 2 and r.stdout == b""  # a usage error (it exited 1)
    assert r.stderr.decode().strip() == ("Error: --json and --csv: give one (the scores are written in one format) "
                                         "(see 'tghop evaluate --help')")
