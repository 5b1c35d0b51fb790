"""``tghop serve`` stops on Ctrl-C (SIGTERM, SIGHUP) at any moment with one line, never a traceback.

Each test starts the real command in a subprocess. Under uvicorn's own signal handling a second Ctrl-C
during the stop (``timeout -s INT`` signals the process and then its group; the second one arrives apart
under load), or a SIGHUP, logged the application's lifespan cancelled with a traceback
("ERROR: Traceback ... KeyboardInterrupt ... CancelledError") and skipped its shutdown.
"""

import os
import signal
import subprocess
import sys
import time

import httpx
import pytest

pytest.importorskip("uvicorn", reason="tghop serve needs the web extra")

#: Run as the console script does (``from tghop.__main__ import run``); "go" once Python's own start-up,
#: which is not tghop's, is over (as in test_cli_failures' test of Ctrl-C during start-up).
COMMAND = ("import sys\nsys.argv[0] = 'tghop'\nimport tghop\nprint('go', flush=True)\n"
           "from tghop.__main__ import run\nsys.exit(run())\n")


def _start(tmp_path, command=COMMAND):
    return subprocess.Popen([sys.executable, "-c", command, "serve", "--port", "0", "--cache", str(tmp_path / "cache")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _answering(url):
    for _ in range(600):  # the server answers: uvicorn runs its main loop
        try:
            if httpx.get(url + "api", timeout=30).status_code == 200:
                return
        except httpx.TransportError:
            time.sleep(0.05)
    raise AssertionError("the server never answered")


def _finish(p):
    try:
        out, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
    return out, err


def _stopped(p, out, err, tmp_path):
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert err.strip().splitlines() == ["tghop server stopped"] and p.returncode == 0, (p.returncode, out, err)
    assert not [name for _, _, names in os.walk(tmp_path) for name in names if name.endswith(".tmp")]


@pytest.mark.parametrize("signals", [["SIGINT", "SIGINT", "SIGINT"], ["SIGHUP"], ["SIGTERM"]],
                         ids=["ctrl-c-thrice", "SIGHUP", "SIGTERM"])
def test_a_running_server_stops_with_one_line(tmp_path, signals):
    p = _start(tmp_path)
    try:
        assert p.stdout.readline() == "go\n"
        _answering(p.stdout.readline().split()[3])
        for name in signals:  # each while the server stops (it waits at least 0.1 s for its connections)
            p.send_signal(getattr(signal, name))
            time.sleep(0.03)
    finally:
        out, err = _finish(p)
    _stopped(p, out, err, tmp_path)


def test_an_ignored_ctrl_c_stays_ignored(tmp_path):
    # `tghop serve &` in a script ignores Ctrl-C, as every command does then; uvicorn stopped on it.
    p = _start(tmp_path, "import signal\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\n" + COMMAND)
    try:
        assert p.stdout.readline() == "go\n"
        url = p.stdout.readline().split()[3]
        _answering(url)
        p.send_signal(signal.SIGINT)
        time.sleep(0.5)
        assert httpx.get(url + "api", timeout=30).status_code == 200
        p.send_signal(signal.SIGTERM)
    finally:
        out, err = _finish(p)
    _stopped(p, out, err, tmp_path)


def test_ctrl_c_held_down_stops_once_to_the_end(tmp_path):
    # A terminal that sends Ctrl-C again and again: the first stops the server, the others are ignored up to
    # the end of the process (the command's convention), neither "Error: interrupted" nor, once Python has put
    # the default action back as its interpreter shuts down, death by the signal (exit status -2).
    p = _start(tmp_path)
    try:
        assert p.stdout.readline() == "go\n"
        assert p.stdout.readline().startswith("tghop serving on ")
        for _ in range(6000):
            if p.poll() is not None:
                break
            p.send_signal(signal.SIGINT)
            time.sleep(0.02)
    finally:
        out, err = _finish(p)
    _stopped(p, out, err, tmp_path)


def test_ctrl_c_at_any_moment_of_the_start_is_one_line(tmp_path):
    # Before the address is printed Ctrl-C stops the command as any other's ("Error: interrupted",
    # 130); from then on it stops the server, even before uvicorn has started it ("tghop server stopped", 0).
    seen = set()
    for delay in (None, 0.05, 0.15, 0.3, 0.6, 1.0, 1.5, 2.5):
        p = _start(tmp_path)
        try:
            assert p.stdout.readline() == "go\n"
            if delay is None:  # at once after the address: uvicorn has not started yet
                assert p.stdout.readline().startswith("tghop serving on ")
            else:
                time.sleep(delay)
            p.send_signal(signal.SIGINT)
        finally:
            out, err = _finish(p)
        if "tghop serving on" in out or delay is None:
            _stopped(p, out, err, tmp_path)
            seen.add("stopped")
        else:
            assert p.returncode == 130 and err.strip() == "Error: interrupted", (delay, p.returncode, err)
            seen.add("interrupted")
    assert "stopped" in seen, seen


def test_an_upload_s_malformed_tiff_leaves_the_terminal_alone(tmp_path):
    """tifffile logs a malformed TIFF's oddities, and Pillow warned of its directory from the server's threads:
    0.59 printed "<TiffTag.fromfile> raised TiffFileError(...)" and "UserWarning: Truncated File Read" beside the
    server's address. The client is answered; the terminal shows the address and the stop."""
    from test_hostile_tiff import tiff_bytes

    p = _start(tmp_path)
    try:
        assert p.stdout.readline() == "go\n"
        url = p.stdout.readline().split()[3]
        _answering(url)
        blob = tiff_bytes(extra=[(270, 2, 40, ("at", 100000))])  # a description whose value lies past the end
        answer = httpx.post(url + "api/models", files={"image": ("damaged.tif", blob, "image/tiff")},
                            headers={"Origin": url.rstrip("/")}, timeout=120)
        assert answer.status_code == 400 and "10x12 pixels" in answer.json()["error"], answer.text  # too small
        p.send_signal(signal.SIGTERM)
    finally:
        out, err = _finish(p)
    assert err.strip().splitlines() == ["tghop server stopped"], err
