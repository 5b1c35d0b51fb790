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
    save_image(data.bricks(72, rng=2), d / "keep_2.png")
    save_image(data.bricks(72, rng=2)[:40, :40], d / "tiny.png")
    save_model(small_model, d / "model.npz")
    (d / "big.png").write_bytes(png_header(9000, 9000))  # over 64 Mpx, under Pillow's bomb limit
    (d / "garbage.npz").write_bytes(b"not a zip, not an image")
    (d / "notes.npz").write_bytes(b"PK\x03\x04 and then nothing a zip reader wants")
    np.savez(d / "plain.npz", a=np.arange(3))
    hole = np.zeros((72, 72))
    hole[20:40, 20:40] = 1
    save_image(hole, d / "hole.png")
    os.mkdir(d / "cnt_2.png")  # the second file of a --count 3 set is a folder
    os.mkdir(d / "sheet_stages.png")  # the --stages file is a folder
    return d


def snapshot(d):
    """Every entry of ``d`` with its bytes (folders as None): what a refused command must not change."""
    return {name: None if (d / name).is_dir() else (d / name).read_bytes() for name in sorted(os.listdir(d))}


CASES = [
    # item 2: an output that is an input, or another output of the same command
    (["synth", "keep.png", "-o", "x.png", "--save-model", "keep.png", *FAST], ["--save-model", "keep.npz"]),
    (["fit", "keep.png", "-o", "keep.png", *FAST], ["-o keep.png", "image extension", "keep.npz"]),
    (["synth", "keep.png", "-o", "yy.png", "--save-model", "yy.png", *FAST], ["--save-model yy.png", "yy.npz"]),
    (["synth", "keep.png", "-o", "keep.png", *FAST], ["keep.png", "-o would overwrite SOURCE"]),
    (["synth", "keep.png", "-o", "./keep.png", *FAST], ["-o would overwrite SOURCE"]),
    (["synth", "keep_2.png", "-o", "keep.png", "--count", "3", *FAST], ["keep_2.png", "-o would overwrite SOURCE"]),
    (["synth", "nope_2.png", "-o", "nope.png", "--count", "3"], ["nope_2.png: no such file"]),  # not "overwrite"
    (["fit", "model.npz", "-o", "model.npz", *FAST], ["model.npz", "-o would overwrite EXEMPLAR"]),
    (["fit", "keep.png", "-o", "model", *FAST], ["-o model", ".npz", "name it model.npz"]),
    (["fit", "keep.png", "-o", "model.v2", *FAST], ["name it model.v2.npz"]),
    (["fit", "keep.png", "-o", "m.jpg", *FAST], ["image extension", "name it m.npz"]),
    (["synth", "keep.png", "-o", "o.png", "--save-model", "m", *FAST], ["--save-model m", "name it m.npz"]),
    # item 10: models cannot go to stdout
    (["fit", "keep.png", "-o", "-", *FAST], ["-o -", "stdout", "file name"]),
    (["synth", "keep.png", "-o", "o.png", "--save-model", "-", *FAST], ["--save-model -", "stdout"]),
    # item 8: every file of a set is checked before the first is written
    (["synth", "model.npz", "-o", "cnt.png", "--count", "3", "--size", "40"], ["cnt_2.png", "folder"]),
    (["synth", "keep.png", "-o", "cnt.png", "--count", "3", *FAST], ["cnt_2.png", "folder"]),
    (["patches", "model.npz", "-n", "4", "-o", "sheet.png", "--stages"], ["sheet_stages.png", "folder"]),
    # item 9: what is wrong, in the command's own words
    (["synth", "garbage.npz", "-o", "o.png"], ["garbage.npz", "not a tghop model file"]),
    (["synth", "notes.npz", "-o", "o.png"], ["notes.npz", "not a tghop model file"]),
    (["synth", "plain.npz", "-o", "o.png"], ["plain.npz", "not a tghop model file"]),
    (["patches", "model.npz", "-o", "-", "--stages"], ["--stages needs a file name"]),
    (["fit", "big.png", "-o", "m.npz"], ["9000x9000", "pass --downscale"]),
    (["synth", "big.png", "-o", "o.png"], ["9000x9000", "pass --downscale"]),
    (["evaluate", "big.png", "keep.png"], ["9000x9000", "downscale it first"]),
    (["evaluate", "keep.png", "big.png"], ["9000x9000", "downscale it first"]),
    (["baseline", "crop", "big.png", "-o", "o.png"], ["9000x9000", "downscale it first"]),
    # commands without --downscale were told "pass downscale=True" or "pass --downscale"
    (["inpaint", "big.png", "keep.png", "-o", "o.png"], ["9000x9000", "downscale it first"]),
    (["morph", "big.png", "model.npz", "-o", "o.png"], ["9000x9000", "downscale it first"]),
    (["synth", "model.npz", "model.npz", "--guide", "big.png", "-o", "o.png"], ["9000x9000", "downscale it first"]),
    (["synth", "big.png", "model.npz", "-o", "o.png"], ["9000x9000", "pass --downscale"]),
    # an exemplar too small for the default fit (tiny.png is 40x40; 0.57 refused keep.png's 72x72 too):
    # named, with the fixes the command has
    (["morph", "model.npz", "tiny.png", "-o", "o.png"], ["B tiny.png is 40x40 pixels, too small", "44x44"]),
    (["inpaint", "keep.png", "hole.png", "--source", "tiny.png", "-o", "o.png"],
     ["--source tiny.png is 40x40 pixels, too small", "44x44"]),
    (["synth", "model.npz", "tiny.png", "-o", "o.png"], ["SOURCE 2 (tiny.png): exemplar is 40x40", "--stride"]),
    # empty names and folder-like ones: "" was the current folder (a traceback for fit, a batch run
    # into it), "x.png/" wrote a file x.png, and a file taken for a folder "did not exist"
    (["synth", "model.npz", "-o", "", "--size", "40"], ["the image's file name is empty"]),
    (["synth", "", "-o", "o.png"], ["the image's file name is empty"]),
    (["fit", "keep.png", "-o", ""], ["-o: the model's file name is empty", "-o model.npz"]),
    (["synth", "model.npz", "-o", "new.png/", "--size", "40"], ["new.png/ ends with a slash"]),
    (["fit", "keep.png", "-o", "new.npz/"], ["new.npz/ ends with a slash"]),
    (["synth", "model.npz", "-o", "keep.png/x.png", "--size", "40"], ["keep.png is a file, not a folder"]),
    (["batch", "", "-o", "out", "--workers", "1"], ["SOURCE is empty"]),
    (["batch", ".", "-o", "", "--workers", "1"], ["outdir must be a folder path", "got ''"]),
    # the other commands: baseline and the cGAN's (checked before torch or a checkpoint is read)
    (["baseline", "crop", "keep.png", "-o", "keep.png"], ["-o would overwrite EXEMPLAR"]),
    (["cooc", "train", "keep.png", "-o", "-"], ["-o -", "checkpoint cannot go to stdout"]),
    (["cooc", "train", "keep.png", "-o", "ck.png"], ["image extension", "name it ck.pt"]),
    (["cooc", "train", "keep.png", "-o", "ck"], ["name it ck.pt"]),
    (["cooc", "morph", "model.npz", "keep.png", "crop:0,0", "-o", "keep.png"], ["-o would overwrite A"]),
    (["cooc", "edit", "model.npz", "crop:0,0", "keep.png", "-o", "keep.png"], ["-o would overwrite SOURCE"]),
]


@pytest.mark.parametrize("args, fragments", CASES, ids=[" ".join(a[:6]) for a, f in CASES])
def test_refused_before_anything_is_written(folder, args, fragments):
    before = snapshot(folder)
    code, _, err, exc = invoke(*args, cwd=folder)
    assert_one_line(code, err, *fragments, exception=exc)
    if "downscale it first" in fragments:  # no --downscale there: the advice does not name it
        assert "--downscale" not in err and "downscale=True" not in err
    if args[0] in ("morph", "inpaint"):  # nor fit options they lack
        assert "--stride" not in err and "--clusters" not in err
    assert snapshot(folder) == before  # nothing written, nothing replaced, no temporary file


@pytest.mark.parametrize("args", [["fit", "keep.png", "-o", "m.png"], ["fit", "keep.png", "-o", "model"],
                                  ["synth", "keep.png", "-o", "o.png", "--save-model", "m.jpg"],
                                  ["cooc", "train", "keep.png", "-o", "ck.png"]], ids=" ".join)
def test_a_model_file_named_otherwise_is_a_usage_error(folder, args):
    # an option's bad value, as an image's -o x.webp (exit status 2): 0.62's model names exited 1
    code, _, err, exc = invoke(*args, *([] if args[0] == "cooc" else FAST), cwd=folder)
    assert_one_line(code, err, "name it", exception=exc)
    assert code == 2, err


def test_a_batch_into_its_own_source_folder_is_a_usage_error(tmp_path):
    # OUTDIR that is SOURCE, an option that does not go with SOURCE (as --max-depth with a manifest): 0.62 exited 1
    save_image(data.bricks(72, rng=2), tmp_path / "a.png")
    code, _, err, exc = invoke("batch", "./", "-o", ".", "--workers", "1", "-q", cwd=tmp_path)
    assert_one_line(code, err, "OUTDIR is the SOURCE folder", "give another folder", exception=exc)
    assert code == 2, err
    assert sorted(os.listdir(tmp_path)) == ["a.png"]


def test_an_output_may_replace_a_file_that_is_not_an_input(folder):
    code, _, err, _ = invoke("synth", "model.npz", "-o", "victim.png", "--size", "40", "-q", cwd=folder)
    assert code == 0, err
    first = (folder / "victim.png").read_bytes()
    code, _, err, _ = invoke("synth", "model.npz", "-o", "victim.png", "--size", "48", "-q", cwd=folder)
    assert code == 0, err
    assert (folder / "victim.png").read_bytes() != first
    os.unlink(folder / "victim.png")


@pytest.mark.parametrize("command", ["synth", "extend", "inpaint"])
def test_count_writes_its_numbered_files_beside_a_folder_named_as_o(folder, tmp_path, command):
    # --count 2 -o out.png writes out_1.png and out_2.png, never out.png: 0.60's synth refused a folder named
    # out.png ("is a folder") where inpaint and extend, which check the files they write, did not (0.61: alike)
    (tmp_path / "out.png").mkdir()
    args = {"synth": ["synth", folder / "model.npz", "--size", "40"],
            "extend": ["extend", folder / "keep.png", "--size", "80x80", "--source", folder / "model.npz"],
            "inpaint": ["inpaint", folder / "keep.png", folder / "hole.png", "--source", folder / "model.npz"]}
    code, _, err, _ = invoke(*args[command], "-o", "out.png", "--count", "2", "--seed", "0", "-q", cwd=tmp_path)
    assert code == 0, err
    assert sorted(os.listdir(tmp_path)) == ["out.png", "out_1.png", "out_2.png"]
    assert (tmp_path / "out.png").is_dir()


def test_an_output_that_is_a_symbolic_link_is_written_through_it(folder, tmp_path):
    # -o link.png replaced the link with a file; now the link stays and its target gets the image
    # (a model through --save-model alike). A link into a missing folder is refused before any work.
    (tmp_path / "real").mkdir()
    (tmp_path / "real" / "out.png").write_bytes(b"old")
    os.symlink("real/out.png", tmp_path / "link.png")
    os.symlink("real/saved.npz", tmp_path / "model_link.npz")  # dangling: its folder exists
    code, _, err, _ = invoke("synth", folder / "keep.png", "-o", "link.png", "--save-model", "model_link.npz",
                             "--size", "40", *FAST, cwd=tmp_path)
    assert code == 0, err
    assert os.path.islink(tmp_path / "link.png") and os.path.islink(tmp_path / "model_link.npz")
    assert (tmp_path / "real" / "out.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "real" / "saved.npz").read_bytes()[:2] == b"PK"
    assert sorted(os.listdir(tmp_path / "real")) == ["out.png", "saved.npz"]
    os.symlink("missing/out.png", tmp_path / "nowhere.png")
    before = sorted(os.listdir(tmp_path))
    code, _, err, exc = invoke("synth", "real/saved.npz", "-o", "nowhere.png", "--size", "40", "-q", cwd=tmp_path)
    assert_one_line(code, err, "nowhere.png is a symbolic link to", "does not exist; create that folder",
                    exception=exc)
    assert sorted(os.listdir(tmp_path)) == before and os.path.islink(tmp_path / "nowhere.png")


def test_a_model_output_named_npz_is_written(folder):
    code, _, err, _ = invoke("fit", "keep.png", "-o", "new.NPZ", *FAST, cwd=folder)
    assert code == 0, err
    assert (folder / "new.NPZ").read_bytes()[:2] == b"PK"
    code, _, err, _ = invoke("info", "new.NPZ", cwd=folder)
    assert code == 0, err
    os.unlink(folder / "new.NPZ")


def test_check_outputs_sees_links_and_spellings(tmp_path, monkeypatch):
    (tmp_path / "a.png").write_bytes(b"x")
    os.link(tmp_path / "a.png", tmp_path / "hard.png")
    os.symlink(tmp_path / "a.png", tmp_path / "soft.png")
    from tghop._errors import TGHopError
    from tghop.cli.common import check_outputs

    for out in ("hard.png", "soft.png", "a.png", "./a.png", str(tmp_path / "a.png")):
        with pytest.raises(TGHopError, match="would overwrite IN"):
            check_outputs([("-o", tmp_path / out if not os.path.isabs(out) else out)], [("IN", tmp_path / "a.png")])
    # two outputs that do not exist yet, spelled differently
    with pytest.raises(TGHopError, match="-o and --stages"):
        check_outputs([("-o", tmp_path / "n.png"), ("--stages", tmp_path / "sub" / ".." / "n.png")])
    # not files: stdout, built-in exemplars, options not given
    check_outputs([("-o", "-"), ("--save-model", None)], [("SOURCE", "builtin:bricks"), ("IN", "-")])
    check_outputs([("-o", tmp_path / "b.png")], [("IN", tmp_path / "a.png")])
    check_outputs([("-o", tmp_path / "c.png")], [("IN", tmp_path / "c.png")])  # no such input: its reader says so
    # --count's largest set: each name looked at once, not every pair (1000 names: 38 s pairwise)
    import tghop.cli.outputs as outputs  # where check_outputs looks _file_key up

    looked_at = []
    file_key = outputs._file_key
    monkeypatch.setattr(outputs, "_file_key", lambda path: looked_at.append(path) or file_key(path))
    check_outputs([("-o", path) for path in outputs.numbered(str(tmp_path / "n.png"), 1000)],
                  [("IN", tmp_path / "a.png")])
    assert len(looked_at) == 1001
    monkeypatch.undo()
    (tmp_path / "a_0500.png").write_bytes(b"x")
    with pytest.raises(TGHopError, match="would overwrite IN"):
        check_outputs([("-o", path) for path in outputs.numbered(str(tmp_path / "a.png"), 1000)],
                      [("IN", tmp_path / "a_0500.png")])


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
    "if sys.argv[1].startswith('ignore-'):  # ignore-SIGHUP as nohup does, ignore-SIGINT as `cmd &` in a script\n"
    "    import signal\n"
    "    signal.signal(getattr(signal, sys.argv.pop(1)[len('ignore-'):]), signal.SIG_IGN)\n"
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


@pytest.mark.parametrize("signum", [signal.SIGHUP, signal.SIGINT], ids=["SIGHUP", "SIGINT"])
def test_an_ignored_signal_stays_ignored(folder, tmp_path, signum):
    p = subprocess.Popen([sys.executable, "-c", SLOW_WRITE, "1", f"ignore-{signal.Signals(signum).name}", "synth",
                          str(folder / "model.npz"), "-o", "out.png", "--size", "64", "-q"], cwd=tmp_path,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert p.stdout.readline() == b"writing\n"
    p.send_signal(signum)
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



@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_stop_lost_in_a_garbage_collector_callback_is_delivered_again(signame):
    # A Ctrl-C whose KeyboardInterrupt was raised inside a gc callback (Dask's GCDiagnosis)
    # was printed as "Exception ignored ... Traceback" and dropped; the Ctrl-Cs after it were
    # ignored, so a batch ran on to its end (exit 0).
    code = (
        "import gc, os, signal, sys, time\n"
        "from tghop.cli import group\n"
        "signal.signal(signal.SIGINT, group._interrupted)\n"
        "signal.signal(signal.SIGTERM, group._terminated)\n"
        "sys.unraisablehook = group._redeliver_lost_stops(sys.unraisablehook)\n"
        "fired = []\n"
        "def callback(phase, info):\n"
        "    if phase == 'start' and not fired:\n"
        f"        fired.append(1); os.kill(os.getpid(), signal.{signame})\n"
        "        for _ in range(100000): pass  # the handler runs here, in the callback\n"
        "gc.callbacks.append(callback)\n"
        "try:\n"
        "    gc.collect()\n"
        "    for _ in range(300): time.sleep(0.01)\n"
        "    print('ran on', flush=True)\n"
        "except KeyboardInterrupt as exc:\n"
        "    print('stopped', type(exc).__name__, flush=True)\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60)
    name = "KeyboardInterrupt" if signame == "SIGINT" else "Terminated"
    assert p.stdout.decode() == f"stopped {name}\n" and p.stderr == b"", (p.stdout, p.stderr.decode())


def test_ctrl_c_after_the_first_is_ignored_to_the_end(folder, tmp_path):
    # Ctrl-C held down (or a terminal that sends several): the first stops the command; the
    # others, up to the end of the process, neither raise again (a second line, a
    # traceback) nor, once Python has put the default action back as its interpreter shuts
    # down, kill the process by the signal (exit status -2 after "Error: interrupted").
    # The child sends itself one more as the command returns.
    code = SLOW_WRITE.replace("run()\n", "import signal\ntry:\n    run()\nfinally:\n"
                              "    signal.raise_signal(signal.SIGINT)\n    print('still here', flush=True)\n")
    p = subprocess.Popen([sys.executable, "-c", code, "60", "synth", str(folder / "model.npz"), "-o", "out.png",
                          "--size", "64", "-q"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert p.stdout.readline() == b"writing\n"
    deadline = time.time() + 60
    while p.poll() is None and time.time() < deadline:
        p.send_signal(signal.SIGINT)
        time.sleep(0.02)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 130 and err.decode().strip() == "Error: interrupted", (p.returncode, err.decode())
    assert out == b"still here\n"
    assert os.listdir(tmp_path) == []


STAGED_WRITES = [
    ["synth", "model.npz", "--size", "40"],
    ["synth", "model.npz", "model.npz", "--size", "40"],  # painted: regions, layers, join
    ["synth", "mat.npz", "--size", "40"],
    ["synth", "mat.npz", "mat.npz", "--size", "40"],
    ["morph", "model.npz", "model.npz", "--size", "40x80"],
    ["morph", "mat.npz", "mat.npz", "--size", "40x80"],
    ["inpaint", "keep.png", "hole.png", "--source", "model.npz"],
    ["extend", "keep.png", "--size", "80x88", "--source", "model.npz"],
    ["inpaint", "keep.png", "hole.png", "height.png", "--maps", "--source", "mat.npz"],
    ["patches", "model.npz", "-n", "4"],  # its grid, then OUT_stages (0.61): the sheet's write fails
]


@pytest.mark.parametrize("args", STAGED_WRITES, ids=[" ".join(a[:4]) for a in STAGED_WRITES])
def test_a_failed_write_leaves_no_step_of_stages(folder, tmp_path, monkeypatch, args):
    # --stages' files and the output are one set: a full disk at the last file written (the output's; patches'
    # sheet of stages) left every file written before it in 0.61 (OUT_quilt.png ... beside no OUT.png, "nothing
    # was written" said); 0.62 writes the set as save_images does, all or none.
    from pathlib import Path

    from conftest import save_material

    import tghop.imageio
    from tghop import InvalidImageError
    from tghop.material import example_maps

    save_material(tmp_path / "mat.npz")
    for name in ("model.npz", "keep.png", "hole.png"):
        os.symlink(folder / name, tmp_path / name)
    save_image(example_maps(data.bricks(72, rng=2))["height"], tmp_path / "height.png")
    real = tghop.imageio.save_image

    last = "out_stages" if args[0] == "patches" else "out"

    def full_disk(image, path, **kwargs):
        if Path(path).stem == last or Path(path).name.startswith(f".{last}."):  # the file or its temporary one
            raise InvalidImageError(f"{path}: writing the image failed (No space left on device); nothing was "
                                    "written")
        return real(image, path, **kwargs)

    monkeypatch.setattr(tghop.imageio, "save_image", full_disk)
    before = snapshot(tmp_path)
    code, _, err, exc = invoke(*args, "-o", "out.png", "--stages", "--seed", "1", "-q", cwd=tmp_path)
    assert_one_line(code, err, "No space left on device", exception=exc)
    assert snapshot(tmp_path) == before, sorted(set(os.listdir(tmp_path)) - set(before))
