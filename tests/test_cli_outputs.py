"""The command line never writes over the user's files, never writes half a set, and a
SIGTERM or SIGHUP leaves no temporary file (issue #26, items 2, 7, 8, 9, 10).

Outputs are checked before any work: an output that is an input or another output of the
same command, a model output that is not NAME.npz (or is stdout), and every file of a set
(--count, --stages) are refused with one line, the folder left as it was.
"""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from click.testing import CliRunner

from tghop import data
from tghop.cli import main
from tghop.imageio import save_image
from tghop.modelfile import save_model

from test_cli_failures import FAST, assert_one_line, invoke, png_header


@pytest.fixture(scope="module")
def folder(tmp_path_factory, small_model):
    d = tmp_path_factory.mktemp("outputs")
    save_image(data.bricks(72, rng=2), d / "keep.png")
    save_model(small_model, d / "model.npz")
    (d / "big.png").write_bytes(png_header(9000, 9000))  # over 64 Mpx, under Pillow's bomb limit
    (d / "garbage.npz").write_bytes(b"not a zip, not an image")
    (d / "notes.npz").write_bytes(b"PK\x03\x04 and then nothing a zip reader wants")
    np.savez(d / "plain.npz", a=np.arange(3))
    os.mkdir(d / "cnt_2.png")  # the second file of a --count 3 set is a folder
    os.mkdir(d / "sheet_stages.png")  # the --stages file is a folder
    return d


def snapshot(d):
    """Every entry of ``d`` with its bytes (folders as None): what a refused command must not change."""
    return {name: None if (d / name).is_dir() else (d / name).read_bytes() for name in sorted(os.listdir(d))}


def test_in_process_runs_keep_the_signal_handlers(folder):
    before = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP)}
    assert CliRunner().invoke(main, ["info", str(folder / "model.npz")]).exit_code == 0
    assert {s: signal.getsignal(s) for s in before} == before


#: The command as the console script runs it, its PNG writing slowed down: the child says
#: "writing" once the temporary file exists and is half written, then waits for the signal.
SLOW_WRITE = (
    "import sys, time\n"
    "import tghop.imageio as io\n"
    "delay = float(sys.argv.pop(1))\n"
    "def slow(fh, pixels, **kw):\n"
    "    fh.write(b'\\x89PNG partial')\n"
    "    fh.flush()\n"
    "    print('writing', flush=True)\n"
    "    time.sleep(delay)\n"
    "    return original(fh, pixels, **kw)\n"
    "original, io.write_png = io.write_png, slow\n"
    "if sys.argv[1] == 'ignore-hup':\n"
    "    import signal\n"
    "    sys.argv.pop(1)\n"
    "    signal.signal(signal.SIGHUP, signal.SIG_IGN)  # as nohup does\n"
    "sys.argv[0] = 'tghop'\n"
    "from tghop.__main__ import run\n"
    "run()\n"
)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_sigterm_and_sighup_during_the_write_leave_no_temporary_file(folder, tmp_path, signum):
    p = subprocess.Popen([sys.executable, "-c", SLOW_WRITE, "60", "synth", str(folder / "model.npz"), "-o",
                          "out.png", "--size", "64", "-q"], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    assert p.stdout.readline() == b"writing\n"
    assert any(name.endswith(".tmp") for name in os.listdir(tmp_path))  # the write is under way
    p.send_signal(signum)
    _, err = p.communicate(timeout=60)
    err = err.decode()
    assert p.returncode == 128 + signum, err
    assert err.strip() == "Error: terminated", err
    assert os.listdir(tmp_path) == []  # no out.png, no hidden .out.png.XXXX.tmp


def test_an_ignored_sighup_stays_ignored(folder, tmp_path):
    p = subprocess.Popen([sys.executable, "-c", SLOW_WRITE, "1", "ignore-hup", "synth", str(folder / "model.npz"),
                          "-o", "out.png", "--size", "64", "-q"], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    assert p.stdout.readline() == b"writing\n"
    p.send_signal(signal.SIGHUP)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 0, err.decode()
    assert os.listdir(tmp_path) == ["out.png"]


def test_ctrl_c_during_the_write_still_says_interrupted(folder, tmp_path):
    p = subprocess.Popen([sys.executable, "-c", SLOW_WRITE, "60", "synth", str(folder / "model.npz"), "-o",
                          "out.png", "--size", "64", "-q"], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    assert p.stdout.readline() == b"writing\n"
    time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and err.decode().strip() == "Error: interrupted", err.decode()
    assert os.listdir(tmp_path) == []
