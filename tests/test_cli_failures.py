"""Every failure of the command line is one line, a non-zero exit, no traceback, no file left.

Most cases run in-process (click's CliRunner, fast); start-up, Ctrl-C and import checks
need a real process.
"""

import errno
import json
import os
import re
import signal
import struct
import subprocess
import sys
import time
import zlib

import numpy as np
import pytest
from click.testing import CliRunner

from tghop import data
from tghop.cli import main
from tghop.imageio import save_image

FAST = ["--clusters", "6", "--codewords", "30", "--stride", "4", "-q"]


def png_header(width, height):
    """A PNG whose header declares ``width`` x ``height`` (with almost no pixel data)."""
    def chunk(kind, payload):
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\x00" * 10)) + chunk(b"IEND", b""))


def invoke(*args, cwd):
    """Run the CLI in-process in ``cwd``; returns (exit code, stdout, stderr)."""
    old = os.getcwd()
    os.chdir(cwd)
    try:
        result = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=True)
    finally:
        os.chdir(old)
    return result.exit_code, result.stdout, result.stderr, result.exception


def assert_one_line(code, err, *fragments, exception=None):
    assert code not in (0, None), err
    assert exception is None or isinstance(exception, SystemExit), repr(exception)
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    errors = [line for line in lines if line.startswith("Error: ")]
    assert len(errors) == 1, err
    for fragment in fragments:
        assert fragment in errors[0], err


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("failures")
    save_image(data.bricks(72, rng=2), d / "bricks.png")
    (d / "bomb.png").write_bytes(png_header(30000, 30000))
    (d / "big.png").write_bytes(png_header(9000, 9000))
    save_image(np.full((64, 64, 3), 0.5), d / "flat.png")
    save_image(np.random.default_rng(0).random((40, 40, 3)), d / "small.png")
    save_image(np.random.default_rng(0).random((32, 32, 3)), d / "small32.png")
    save_image(np.random.default_rng(0).random((31, 31, 3)), d / "small31.png")
    save_image(np.repeat([[0.0, 1.0]], 32, axis=1).repeat(64, axis=0), d / "two_levels.png")
    code, _, err, _ = invoke("fit", "bricks.png", "-o", "model.npz", *FAST, cwd=d)
    assert code == 0, err
    blob = (d / "model.npz").read_bytes()
    (d / "trunc.npz").write_bytes(blob[: len(blob) // 2])
    return d


CASES = [
    # a PNG whose header declares 30000x30000 pixels
    (["synth", "bomb.png", "-o", "o.png"], ["bomb.png", "pixels"]),
    (["fit", "bomb.png", "-o", "m.npz"], ["bomb.png", "pixels"]),
    (["evaluate", "bomb.png", "bricks.png"], ["bomb.png", "pixels"]),
    (["fit", "big.png", "-o", "m.npz"], ["9000x9000", "--downscale"]),
    # unwritable outputs, checked before the fit
    (["synth", "bricks.png", "-o", "/proc/o.png", *FAST], ["/proc/o.png", "cannot write"]),
    (["fit", "bricks.png", "-o", "/proc/m.npz", *FAST], ["/proc/m.npz", "cannot write"]),
    (["synth", "bricks.png", "-o", "o.png", "--save-model", "/proc/m.npz", *FAST], ["/proc/m.npz", "cannot write"]),
    (["synth", "bricks.png", "-o", "x" * 300 + ".png", *FAST],
     ["xx...xxxx", "x.png: the file's name is 304 bytes, more than a name may have (File name too long); give a "
      "shorter name"]),
    # a flat exemplar, whatever gamma
    (["fit", "flat.png", "-o", "m.npz"], ["no texture"]),
    (["synth", "flat.png", "-o", "o.png", "--gamma", "0"], ["no texture"]),
    # an exemplar too small for the default settings: the smallest that works, and fixes that do
    (["synth", "small31.png", "-o", "o.png", "--size", "64"], ["31x31 pixels", "at least 44x44"]),  # not 32x32
    (["synth", "small.png", "-o", "o.png", "--size", "64"], ["40x40 pixels", "N=4 (auto)", "at least 44x44"]),
    (["synth", "small32.png", "-o", "o.png", "-N", "1"], ["32x32 pixels, 1 training patch", "at least 38x38"]),
    # a guide of a few levels for one SOURCE wants one SOURCE per level, not flat painting
    (["synth", "model.npz", "--guide", "two_levels.png", "-o", "o.png"],
     ["one SOURCE was given", "give one SOURCE per level (2 SOURCEs for 2 levels) or drop --guide"]),
    # non-finite numbers
    (["fit", "bricks.png", "-o", "m.npz", "--gamma", "nan"], ["--gamma", "finite"]),
    (["fit", "bricks.png", "-o", "m.npz", "--gamma", "inf"], ["--gamma", "finite"]),
    (["fit", "bricks.png", "-o", "m.npz", "--reject-threshold", "nan"], ["--reject-threshold", "finite"]),
    (["fit", "bricks.png", "-o", "m.npz", "--reject-threshold", "-inf"], ["--reject-threshold", "finite"]),
    (["fit", "bricks.png", "-o", "m.npz", "--cluster-energy", "nan"], ["--cluster-energy"]),
    (["synth", "model.npz", "-o", "o.png", "--tolerance", "nan"], ["--tolerance", "finite"]),
    # the option's range, not the library's (it said <= 10,000,000, which the option refuses)
    (["synth", "model.npz", "-o", "o.png", "--pool", "0"], ["--pool", "<= 200,000, got 0"]),
    (["synth", "model.npz", "-o", "o.png", "--pool", "200001"], ["--pool", "<= 200,000, got 200001"]),
    (["synth", "model.npz", "-o", "o.png", "--pool-per-block", "1e308"], ["--pool-per-block", "<= 1,000,000"]),
    (["synth", "model.npz", "-o", "o.png", "--layout-weight", "1e100"], ["--layout-weight", "<= 1,000,000"]),
    # None as the command line writes it ('auto' or 'none'), not Python's word
    (["synth", "model.npz", "-o", "o.png", "--layout-patch-refine", "-1"],
     ["--layout-patch-refine", "or auto, got -1"]),
    (["synth", "model.npz", "-o", "o.png", "--region", "5"], ["--region", ">= 256 or none, got 5"]),
    # an image where a model is expected
    (["info", "bricks.png"], ["bricks.png is an image", "tghop fit bricks.png"]),
    # truncated model files
    (["synth", "trunc.npz", "-o", "o.png"], ["trunc.npz", "truncated"]),
    (["info", "trunc.npz"], ["trunc.npz", "truncated"]),
    (["patches", "trunc.npz", "-o", "g.png"], ["trunc.npz", "truncated"]),
    (["fit", "trunc.npz", "-o", "m.npz"], ["model file, not an image"]),
    # a model as the exemplar: what to do with it (0.61 stopped at "this command needs an image")
    (["fit", "model.npz", "-o", "m.npz"], ["model.npz is a model file, not an image; this command needs an image (a "
                                           "model is fitted already: 'tghop synth model.npz -o OUT.png' makes images"]),
    (["fit", "model.npz", "--maps", "bricks.png", "-o", "m.npz"],
     ["EXEMPLAR model.npz is a model file, not an image; give the material's colour map (albedo) image first"]),
    # fit options with a saved model
    (["synth", "model.npz", "-o", "o.png", "--k1", "9"], ["--k1", "saved model"]),
    (["synth", "model.npz", "-o", "o.png", "-N", "9", "--gamma", "0.1"], ["--clusters", "--gamma", "saved model"]),
    (["synth", "model.npz", "-o", "o.png", "--save-model", "again.npz"], ["--save-model", "saved model"]),
    (["synth", "model.npz", "-o", "o.png", "--fit-seed", "3"], ["--fit-seed", "saved model"]),
    # an empty --save-model was taken for none: the image written, the model not, exit status 0
    (["synth", "bricks.png", "-o", "o.png", "--save-model", "", *FAST],
     ["--save-model: the model's file name is empty"]),
    # the albedo given as one of its own maps (a material with the albedo twice; batch's manifest refused it)
    (["fit", "bricks.png", "--maps", "bricks.png", "-o", "m.npz", *FAST], ["--maps bricks.png is EXEMPLAR itself"]),
    (["extend", "bricks.png", "--maps", "./bricks.png", "--size", "96x96", "-o", "o.png"],
     ["MAP ./bricks.png is IMAGE itself"]),
    (["inpaint", "bricks.png", "two_levels.png", "--maps", "bricks.png", "-o", "o.png"],
     ["MAP bricks.png is IMAGE itself", "give the map's own file"]),
    # usage errors are one line too
    (["synth"], ["SOURCE", "--help"]),
    (["fit", "bricks.png", "-o", "m.npz", "--bogus"], ["--bogus"]),
    (["synth", "bricks.png", "-o", "o.png", "--size", "12x"], ["--size"]),
    # a missing option value: the subcommand's help (it said 'tghop --help')
    (["synth", "bricks.png", "-o"], ["'-o' requires an argument", "(see 'tghop synth --help')"]),
    (["cooc", "train", "bricks.png", "-o"], ["'-o' requires an argument", "(see 'tghop cooc train --help')"]),
]


@pytest.mark.parametrize("args, fragments", CASES, ids=[" ".join(a[:3]) + " " + f[0] for a, f in CASES])
def test_failure_is_one_line_and_leaves_nothing(folder, args, fragments):
    before = sorted(os.listdir(folder))
    code, _, err, exc = invoke(*args, cwd=folder)
    assert_one_line(code, err, *fragments, exception=exc)
    assert sorted(os.listdir(folder)) == before


@pytest.mark.parametrize("args, fragments", [
    (["baseline", "ustyuzhaninov", "bricks.png", "-o", "o.png", "--iterations", "99999999999"],
     ["'--iterations'", "ustyuzhaninov baseline runs at most 20,000, got 99,999,999,999"]),
    (["baseline", "gpdm", "bricks.png", "-o", "o.png", "--iterations", "3001"], ["gpdm baseline runs at most 3,000"]),
    (["baseline", "cooc", "bricks.png", "-o", "o.png", "--iterations", "150001"],
     ["cooc baseline runs at most 150,000"]),
    (["cooc", "train", "bricks.png", "-o", "m.pt", "--steps", "99999999999"], ["'--steps'", "at most 150,000"]),
])
def test_too_many_steps_is_a_usage_error(folder, monkeypatch, args, fragments):
    # Without a bound these ran for days; refused before the exemplar is read, exit status 2.
    code, err = _refused_before_reading(folder, monkeypatch, args, fragments)
    assert code == 2, err


def _refused_before_reading(folder, monkeypatch, args, fragments):
    """``tghop ARGS``'s exit status and stderr, checked to be one line with ``fragments``, the
    exemplar never read (the cooc and baseline commands' ``load_exemplar`` fails the test)."""
    from tghop.cli import cooc, evaluation

    def read(*args, **kwargs):
        pytest.fail("the exemplar was read: the command line was not refused first")

    for module in (cooc, evaluation):
        monkeypatch.setattr(module, "load_exemplar", read)
    code, _, err, exc = invoke(*args, cwd=folder)
    assert_one_line(code, err, *fragments, exception=exc)
    return code, err


@pytest.mark.parametrize("args, fragments", [
    (["cooc", "train", "bricks.png", "-o", "m.pt", "--set", "lr=fast"], ["--set 'lr=fast': lr takes a number"]),
    (["cooc", "train", "bricks.png", "-o", "m.pt", "--set", "bogus=1"], ["--set 'bogus=1': write KEY=VALUE"]),
    (["cooc", "train", "bricks.png", "-o", "m.pt", "--set", "crop_size=32.9"],
     ["'--set'", "crop_size must be an integer, got 32.9"]),
    (["cooc", "train", "bricks.png", "-o", "m.pt", "--set", "crop_size=40"], ["'--set'", "multiple of 2**n_layers"]),
    (["cooc", "train", "bricks.png", "-o", "m.pt", "--resume", "--paper"], ["--resume continues a checkpoint"]),
    (["baseline", "crop", "bricks.png", "-o", "o.png", "--iterations", "5"],
     ["--iterations applies to the ustyuzhaninov, cooc and gpdm baselines only"]),
    (["baseline", "crop", "bricks.png", "-o", "o.png", "--assembly", "pass"], ["--assembly applies to the cooc"]),
    (["baseline", "cooc", "bricks.png", "-o", "o.png", "--model", "m.pt", "--iterations", "5"],
     ["--iterations applies to the cooc baseline without --model only"]),
])
def test_set_and_options_of_another_baseline_are_usage_errors(folder, monkeypatch, args, fragments):
    # They exited 1, as a bad file does; a usage error is click's 2, as everywhere else in tghop. Refused before
    # the exemplar is read (a --set value was checked only when the training started).
    code, err = _refused_before_reading(folder, monkeypatch, args, fragments)
    assert code == 2 and " --help')" in err, err


@pytest.mark.parametrize("args, fragments", [
    (["synth", "model.npz", "-o", "o.png", "--transition", "8"], ["--transition applies to several SOURCEs"]),
    (["synth", "model.npz", "model.npz", "-o", "o.png", "--save-model", "m.npz"], ["--save-model takes one exemplar"]),
    (["synth", "model.npz", "model.npz", "-o", "o.png", "--exclude", "two_levels.png"], ["--exclude takes one"]),
    (["synth", "model.npz", "-o", "o.png", "--maps", "bricks.png"], ["synth takes no --maps"]),
    (["inpaint", "bricks.png", "two_levels.png", "-o", "o.png", "--scale", "0.5"],
     ["--scale applies to an exemplar given as --source", "IMAGE's own texture"]),
    (["inpaint", "bricks.png", "two_levels.png", "-o", "o.png", "--source", "model.npz", "--scale", "0.5"],
     ["--scale applies to an exemplar given as --source", "a saved model keeps the scale"]),
    (["extend", "bricks.png", "-o", "o.png", "--size", "96", "--scale", "0.5"], ["--scale applies to an exemplar"]),
    # these exited 1 too
    (["synth", "model.npz", "-o", "o.png", "--clusters", "8"], ["--clusters: fitting option but SOURCE is a saved"]),
    (["synth", "model.npz", "bricks.png", "-o", "o.png", "--clusters", "8"],
     ["--clusters: fitting option but SOURCE 1 (model.npz) is a saved model"]),
    (["evaluate", "bricks.png", "bricks.png", "--json", "--csv"], ["--json and --csv: give one"]),
    (["evaluate", "bricks.png", "bricks.png", "--metrics", " , "], ["--metrics is empty"]),
    (["synth", "model.npz", "-o", "-", "--count", "2"], ["--count > 1 cannot write to stdout"]),
    (["synth", "model.npz", "-o", "-", "--stages"], ["--stages needs a file name"]),
    (["patches", "model.npz", "-o", "-", "--stages"], ["--stages needs a file name"]),
    (["fit", "bricks.png", "two_levels.png", "-o", "m.npz"], ["more than one EXEMPLAR (two_levels.png, ...)"]),
    (["fit", "bricks.png", "--maps", "-o", "m.npz"], ["--maps without maps"]),
    (["fit", "bricks.png", "-o", "-"], ["-o -: a model cannot go to stdout"]),
    (["synth", "bricks.png", "-o", "o.png", "--save-model", "-"], ["--save-model -: a model cannot go to stdout"]),
    (["clusters", "model.npz", "bricks.png", "-o", "-"], ["this command cannot write to stdout"]),
    (["synth", "bricks.png", "-o", "o.png", "--patch-levels", "0", "--patch-refine", "2"],
     ["--patch-refine 2 needs the patch statistics that --patch-levels 0 leaves out"]),
    (["morph", "model.npz", "model.npz", "-o", "o.png", "--size", "4096", "--grid", "8"],
     ["--grid 8 strips of 4096x4096 make a 32768x4096 image"]),
    (["inpaint", "bricks.png", "two_levels.png", "small.png", "-o", "o.png"], ["an argument too many after MASK"]),
    (["inpaint", "bricks.png", "two_levels.png", "--maps", "-o", "o.png"], ["--maps without maps"]),
    (["inpaint", "bricks.png", "two_levels.png", "--maps", "small.png", "-o", "-"], ["--maps writes a file per map"]),
    # a --depth the output cannot hold (--depth 16 -o x.jpg exited 1, where an extension tghop does not write is 2)
    (["synth", "model.npz", "-o", "o.jpg", "--depth", "16"], ["o.jpg: JPEG cannot hold 16-bit", ".png, .tif or .tiff"]),
    (["synth", "bricks.png", "-o", "o.jpeg", "--depth", "16"], ["o.jpeg: JPEG cannot hold 16-bit"]),
    (["synth", "model.npz", "model.npz", "-o", "o.jpg", "--depth", "16"], ["o.jpg: JPEG cannot hold 16-bit"]),
    (["synth", "model.npz", "-o", "o.png", "--depth", "32"], ["o.png: PNG cannot hold 32-bit float", ".tif or .tiff"]),
    (["synth", "model.npz", "-o", "-", "--depth", "32"], ["PNG cannot hold 32-bit float"]),
    (["morph", "model.npz", "model.npz", "-o", "o.jpg", "--depth", "16"], ["o.jpg: JPEG cannot hold 16-bit"]),
    (["baseline", "crop", "bricks.png", "-o", "o.jpg", "--depth", "16"], ["o.jpg: JPEG cannot hold 16-bit"]),
    (["inpaint", "bricks.png", "two_levels.png", "-o", "o.jpg", "--depth", "16"], ["o.jpg: JPEG cannot hold 16-bit"]),
    (["inpaint", "bricks.png", "two_levels.png", "--maps", "small.png", "-o", "o.png", "--depth", "32"],
     ["o.png: PNG cannot hold 32-bit float"]),
    (["extend", "bricks.png", "-o", "o.png", "--size", "96", "--depth", "32"], ["o.png: PNG cannot hold 32-bit"]),
])
def test_options_that_do_not_go_together_are_usage_errors(folder, args, fragments):
    # They exited 1, as a bad file does; an option given where it does not apply is a usage error, 2, as click's
    # own and the baselines' (above), with the command's --help named.
    before = sorted(os.listdir(folder))
    code, _, err, exc = invoke(*args, cwd=folder)
    assert_one_line(code, err, *fragments, f"(see 'main {args[0]} --help')", exception=exc)
    assert code == 2, err
    assert sorted(os.listdir(folder)) == before


def test_the_boost_bound_is_one_value_for_the_command_line_and_the_library():
    # tghop.cli.cooc kept its own MAX_BOOST = 1000.0 beside tghop.cooc.assembly's (the command line does not import
    # NumPy, which the library's module does): a change of one would not have reached the other. Both take
    # tghop._limits's, which imports nothing, so the command line still starts without NumPy.
    import ast
    from pathlib import Path

    from tghop import _limits
    from tghop.cli import cooc as cli_cooc
    from tghop.cooc import assembly

    assert cli_cooc.MAX_BOOST is _limits.MAX_BOOST and assembly.MAX_BOOST is _limits.MAX_BOOST
    tree = ast.parse(Path(_limits.__file__).read_text(encoding="utf-8"))
    assert not [node for node in ast.walk(tree) if isinstance(node, (ast.Import, ast.ImportFrom))]
    p = subprocess.run([sys.executable, "-c", "import sys\nimport tghop.cli.cooc\nprint('numpy' in sys.modules)"],
                       capture_output=True, timeout=120)
    assert p.returncode == 0 and p.stdout.decode().strip() == "False", p.stderr.decode()


#: A stage's line where stderr is no terminal: the clock time it ended, its name and how long it took.
STAGE_LINE = r"^\[\d\d:\d\d:\d\d\] ([a-zA-Z0-9 ]+): done in (\d+\.\d\d? s|\d+ min \d\d s)$"


def test_the_progress_shows_the_images_write(folder):
    # A large PNG took seconds to write after the bar's last stage, showing nothing (a bar's label is its line on a
    # stderr that is no terminal).
    code, _, err, exc = invoke("synth", "model.npz", "-o", "written.png", "--size", "48x64", "--seed", "1",
                               cwd=folder)
    assert code == 0 and exc is None, err
    lines = err.splitlines()
    assert re.match(STAGE_LINE, lines[-2]).group(1) == "writing"
    assert lines[-1] == "1 image of 48x64 written to written.png"


def test_the_progress_in_a_log_is_a_line_per_stage_with_its_time(folder, tmp_path):
    # Where stderr is no terminal (2>log, a CI log) click drew no bar but each stage's label alone, padded
    # ("quilting      "): nothing said when a stage ended or how long it took. Now one line per stage as it ends.
    with open(tmp_path / "log", "wb") as log:
        p = subprocess.run([sys.executable, "-m", "tghop", "synth", "model.npz", "-o", str(tmp_path / "o.png"),
                            "--size", "64x80", "--seed", "1"], cwd=folder, stderr=log, timeout=120)
    text = (tmp_path / "log").read_text()
    assert p.returncode == 0, text
    lines = text.splitlines()
    assert lines[-1] == f"1 image of 64x80 written to {tmp_path / 'o.png'}"
    stages = [re.match(STAGE_LINE, line) for line in lines[:-1]]
    assert all(stages) and "\r" not in text, text
    names = [m.group(1) for m in stages]
    assert names[-1] == "writing" and "quilting" in names and len(set(names)) == len(names), names


def test_a_fits_progress_in_a_log_has_a_line_for_every_part_of_its_work(folder, tmp_path):
    # `tghop fit` in a pipe said nothing of the exemplar's reading and statistics before "hop 1", of the core's
    # responses after the last hop, nor of the model's write: the stage lines' times did not add up to the fit's.
    with open(tmp_path / "log", "wb") as log:
        p = subprocess.run([sys.executable, "-m", "tghop", "fit", "bricks.png", "-o", str(tmp_path / "m.npz"),
                            *FAST[:-1]], cwd=folder, stderr=log, timeout=300)
    text = (tmp_path / "log").read_text()
    assert p.returncode == 0, text
    names = [m.group(1) for m in map(re.compile(STAGE_LINE).match, text.splitlines()) if m]
    assert names == ["reading", "exemplar", "hop 1", "hop 2", "core", "SDR", "clusters", "ICA", "CDF codebook",
                     "saving"], text
    assert text.splitlines()[-1] == f"model written to {tmp_path / 'm.npz'}"


def test_the_progress_in_a_log_says_a_long_stages_tenths_and_where_it_stopped(capsys, monkeypatch):
    import tghop.cli.progress as bars  # where Progress reads LOG_EVERY (tghop.cli.common re-exports Progress only)

    monkeypatch.setattr(bars, "LOG_EVERY", 0.0)  # every tenth, however fast (10 s apart otherwise)
    progress = bars.Progress(True)
    for done in range(0, 101, 3):
        progress("quilting", done, 100)
    progress("quilting", 100, 100)
    for done in range(0, 45, 3):
        progress("refine", done, 100)
    progress.close()
    lines = [re.sub(r"^\[\d\d:\d\d:\d\d\] ", "", line) for line in capsys.readouterr().err.splitlines()]
    tenths = [f"quilting: {p} % after" for p in (12, 21, 30, 42, 51, 60, 72, 81, 90)]
    assert [line[:len(w)] for line, w in zip(lines, tenths)] == tenths, lines
    assert re.match(r"quilting: done in \d\.\d\d s$", lines[9]), lines
    assert [line.split(" after")[0] for line in lines[10:]] == [f"refine: {p} %" for p in (12, 21, 30, 42)] + [
        "refine: stopped at 42 %"], lines
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)  # a terminal: click's bar, as before, and no lines
    bar = bars.Progress(True)
    bar("quilting", 50, 100)
    assert bar.bar is not None and not bar.lines
    bar.close()


@pytest.mark.parametrize("args, fragment", [(["--overlap", "20"], "(overlap, --overlap) must be between 1 and 16"),
                                            (["--size", "20", "--tile"], "at least the patch size 32")])
def test_an_output_quilting_refuses_is_refused_before_the_fit(folder, args, fragment):
    # From an exemplar: the output's blocks are checked at the fit's patch size first (the
    # fit's progress would show its stages before the error).
    code, _, err, exc = invoke("synth", "bricks.png", "-o", "o.png", *args, cwd=folder)
    assert_one_line(code, err, fragment, exception=exc)
    assert err.strip().startswith("Error: "), err
    assert not (folder / "o.png").exists()


def test_full_disk_leaves_no_file(folder, monkeypatch):
    from PIL import Image

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    from tghop import imageio

    monkeypatch.setattr(Image.Image, "save", full)  # JPEG
    monkeypatch.setattr(imageio, "write_png", full)
    before = sorted(os.listdir(folder))
    for name in ("full.png", "full.jpg"):
        code, _, err, exc = invoke("synth", "model.npz", "-o", name, "--size", "40", "--pool", "100", "-q",
                                   cwd=folder)
        # its fix named (0.63; 0.62: "...; nothing was written", no fix)
        assert_one_line(code, err, name, "No space left", "free some space there, or write elsewhere", exception=exc)
        assert sorted(os.listdir(folder)) == before

    monkeypatch.setattr(np, "savez", full)
    code, _, err, exc = invoke("fit", "bricks.png", "-o", "full.npz", *FAST, cwd=folder)
    assert_one_line(code, err, "full.npz", "No space left", "free some space there, or write elsewhere", exception=exc)
    assert sorted(os.listdir(folder)) == before
    monkeypatch.undo()

    def failing(*args, **kwargs):  # a disk that fails another way (EIO): another folder is the fix
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(imageio, "write_png", failing)
    code, _, err, exc = invoke("synth", "model.npz", "-o", "io.png", "--size", "40", "--pool", "100", "-q", cwd=folder)
    assert_one_line(code, err, "io.png: writing the image failed (Input/output error), nothing was written; write "
                    "elsewhere (another folder or disk)", exception=exc)
    assert sorted(os.listdir(folder)) == before


def test_info_json_is_strict_json_and_columns_are_apart(folder):
    code, out, err, _ = invoke("info", "model.npz", "--json", cwd=folder)
    assert code == 0, err
    info = json.loads(out, parse_constant=lambda name: pytest.fail(f"{name} in JSON"))
    assert info["fit_seed"] == 0  # --fit-seed's default, recorded (files said "rng": null)
    code, out, err, _ = invoke("info", "model.npz", cwd=folder)
    assert code == 0, err
    assert "\nfit seed: 0\n" in out
    row = next(line for line in out.splitlines() if "core ICHM (iii)" in line)
    assert "  " in row.split("core ICHM (iii)", 1)[1].strip()  # formula and numbers apart


def test_help_says_what_sizes_cost_and_the_size_order():
    out = CliRunner().invoke(main, ["synth", "--help"]).stdout
    flat = " ".join(out.split())
    assert "8192x8192" in flat and "GB" in flat
    assert "HEIGHTxWIDTH" in flat and "--seed" in flat


def test_every_command_that_writes_files_takes_the_same_quiet_option():
    # patches, cooc morph and cooc edit had no -q: a script passing -q to every command failed there.
    # info prints a description and serve serves; every other command writes files.
    import click

    def leaves(group, path):
        for name in group.list_commands(None):
            command = group.get_command(None, name)
            if isinstance(command, click.Group):
                yield from leaves(command, path + [name])
            else:
                yield path + [name], command

    found = {}
    for path, command in leaves(main, []):
        quiet = [p for p in command.params if "-q" in getattr(p, "opts", ())]
        found[" ".join(path)] = [(p.opts, p.is_flag, p.help) for p in quiet]
    takes = {name: q for name, q in found.items() if name not in ("info", "serve")}
    assert {"patches", "cooc morph", "cooc edit", "synth", "fit"} <= set(takes)
    assert all(q == [(["-q", "--quiet"], True, "No progress bars.")] for q in takes.values()), takes


@pytest.mark.parametrize("command", [["synth"], ["patches"], ["morph"], ["baseline"], ["inpaint"],
                                     ["cooc", "morph"], ["cooc", "edit"]])
def test_image_outputs_name_every_extension_tghop_writes(command):
    # One list (tghop._formats.FORMATS): the help said ".png/.jpg" where .tif and .tiff work too.
    from tghop._formats import FORMATS

    flat = " ".join(CliRunner().invoke(main, [*command, "--help"]).stdout.split())
    output = flat.split("-o, --output TEXT", 1)[1].split("[required]", 1)[0]
    assert all(ext in output for ext in FORMATS), output


def test_an_unknown_extension_names_every_one_tghop_writes(folder):
    from tghop._formats import FORMATS

    code, _, err, exc = invoke("synth", "model.npz", "-o", "o.bmp", cwd=folder)
    assert_one_line(code, err, "o.bmp", *FORMATS, exception=exc)
    assert code == 2  # -o's bad value: a usage error (it was 1, as for a bad file)
    code, _, err, exc = invoke("extend", "bricks.png", "-o", "o.webp", "--size", "80x80", cwd=folder)
    assert_one_line(code, err, "o.webp: unknown image extension .webp", "extend --help", exception=exc)
    assert code == 2
    code, _, err, exc = invoke("synth", "model.npz", "-o", "o.jpeg", "--depth", "16", cwd=folder)
    assert_one_line(code, err, ".png", ".tif", ".tiff", exception=exc)
    assert code == 2  # a clash of options, as above (it was 1)


@pytest.mark.skipif(sys.platform in ("win32", "darwin"), reason="file names there are Unicode")
def test_a_file_name_that_is_not_utf8_is_printed_as_the_terminal_shows_it(tmp_path, capsys):
    # 0.62 printed Python's escapes of its bytes ("Error: caf\\udce9.png: not a readable image ...").
    import warnings

    from tghop.cli.common import user_errors

    name = os.fsdecode(b"caf\xe9.png")
    (tmp_path / name).write_bytes(b"junk")
    code, _, err, exc = invoke("synth", name, "-o", "out.png", cwd=tmp_path)
    assert_one_line(code, err, "Error: caf\ufffd.png: not a readable image", exception=exc)
    assert "\\udc" not in err
    with user_errors():  # warnings too, as they are printed
        warnings.warn(f"{name} has more than 8 bits a channel")
    assert capsys.readouterr().err == "Warning: caf\ufffd.png has more than 8 bits a channel\n"

@pytest.mark.skipif(sys.platform in ("win32", "darwin"), reason="file names there are Unicode")
def test_every_line_naming_a_file_that_is_not_utf8_shows_it_as_the_terminal_does(folder, tmp_path):
    # 0.63 showed it so in errors and warnings alone: "1 image of 64x64 written to caf\\udce9.png", tghop info's
    # "tghop model caf\\udce9.npz" (stdout: the raw byte), the batch's summary
    model, out, junk = (os.fsdecode(b"caf\xe9" + suffix) for suffix in (b".npz", b".png", b"_d"))
    (tmp_path / model).write_bytes((folder / "model.npz").read_bytes())
    code, _, err, _ = invoke("synth", model, "-o", out, "--size", "64x64", "--seed", "1", cwd=tmp_path)
    assert code == 0, err
    assert err.splitlines()[-1] == "1 image of 64x64 written to caf\ufffd.png"
    assert "\\udc" not in err and re.search(r"^\[\d\d:\d\d:\d\d\] writing: done in ", err, re.M)  # progress lines too
    code, text, err, _ = invoke("info", model, cwd=tmp_path)
    assert code == 0 and text.splitlines()[0] == "tghop model caf\ufffd.npz", text + err
    (tmp_path / junk).mkdir()
    (tmp_path / junk / "a.png").write_bytes(b"junk")
    code, _, err, _ = invoke("batch", junk, "-o", junk + "_out", "--workers", "1", cwd=tmp_path)
    assert code == 1 and "\\udc" not in err, err
    assert "results in caf\ufffd_d_out, contact sheet caf\ufffd_d_out/index.html" in err, err


def test_a_folder_as_model_and_an_image_as_batch_source_are_told_what_to_give(folder, tmp_path):
    # 0.63: "adir is a folder, not a model file" and ".../bricks.png: SOURCE is a folder of images or a manifest
    # (.csv or .jsonl)", neither naming what to give (0.64, a new user's walk through the errors)
    (tmp_path / "adir").mkdir()
    code, _, err, exc = invoke("info", "adir", cwd=tmp_path)
    assert_one_line(code, err, "Error: adir is a folder, not a model file; give a model file in it (NAME.npz)",
                    exception=exc)
    code, _, err, exc = invoke("batch", folder / "bricks.png", "-o", "out", "--workers", "1", cwd=tmp_path)
    assert_one_line(code, err, "bricks.png: not a folder or a manifest; give a folder of images or a .csv or .jsonl "
                    "file", exception=exc)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir"]

def test_an_image_given_as_a_model_gets_a_command_that_can_be_pasted(folder):
    # The fit command it suggested left a name with spaces unquoted: pasted, it fitted "my".
    import shlex
    import shutil

    shutil.copy(folder / "bricks.png", folder / "my wall ü.png")
    code, _, err, exc = invoke("info", "my wall ü.png", cwd=folder)
    assert_one_line(code, err, "my wall ü.png is an image, not a model file; fit a model from it first: "
                    "tghop fit 'my wall ü.png' -o model.npz", exception=exc)
    command = err.split("first: ", 1)[1].split(" (or", 1)[0]
    assert shlex.split(command) == ["tghop", "fit", "my wall ü.png", "-o", "model.npz"]


@pytest.mark.parametrize("args, fragment", [
    (["synth", "bricks", "-o", "x.png"], "bricks: no such file; the built-in exemplar is builtin:bricks"),
    (["fit", "cells", "-o", "c.npz"], "cells: no such file; the built-in exemplar is builtin:cells"),
    (["synth", "builtin:bricks", "cells", "-o", "x.png"], "the built-in exemplar is builtin:cells"),
    (["synth", "builtin:bricks", "-o", "x.png", "--size", "512", "512"],
     "512: no such file; --size takes one value, HEIGHTxWIDTH (--size 512x1024: 1024 wide)"),
])
def test_a_newcomers_slip_is_told_what_was_meant(tmp_path, args, fragment):
    # 0.58 said "bricks: no such file; check the path" to a built-in exemplar's name without builtin:, and
    # the same of the second number of `--size 512 512`, which click takes for a SOURCE.
    code, _, err, exc = invoke(*args, cwd=tmp_path)
    assert_one_line(code, err, fragment, exception=exc)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("args", [
    ["synth", "builtin:bricks"], ["synth", "model.npz"], ["synth", "builtin:bricks", "builtin:cells"],
    ["extend", "bricks.png"], ["cooc", "edit", "model.pt", "crop:0,0"]])
def test_a_split_size_is_a_usage_error_before_any_work(tmp_path, args):
    # `--size 512 512`: click takes the second number for one more SOURCE (or extend's MAP). 0.62 said so with exit
    # status 1, as of a missing file (synth), or told extend's user to give maps after --maps; a usage error is 2.
    save_image(data.bricks(40, rng=1), tmp_path / "bricks.png")
    code, _, err, exc = invoke(*args, "-o", "x.png", "--size", "512", "512", cwd=tmp_path)
    assert_one_line(code, err, "512: no such file; --size takes one value, HEIGHTxWIDTH (--size 512x1024: 1024 wide)",
                    exception=exc)
    assert code == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bricks.png"]


def test_a_missing_source_is_named_before_the_guides_levels_are_counted(tmp_path):
    # The README's `tghop synth a.npz b.npz --guide map.png` pasted with a map of 3 levels and no a.npz: 0.58 said
    # "the guide has 3 distinct grey levels/colours but 2 SOURCEs were given", and only then that a.npz was missing.
    levels = np.zeros((64, 96, 3))
    levels[:, 32:64], levels[:, 64:] = 0.5, 1.0
    save_image(levels, tmp_path / "map.png")
    code, _, err, exc = invoke("synth", "a.npz", "b.npz", "--guide", "map.png", "-o", "x.png", cwd=tmp_path)
    assert_one_line(code, err, "a.npz: no such model file", exception=exc)
    code, _, err, exc = invoke("synth", "builtin:bricks", "bricks", "--guide", "map.png", "-o", "x.png", cwd=tmp_path)
    assert_one_line(code, err, "bricks: no such file; the built-in exemplar is builtin:bricks", exception=exc)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.png"]


def test_a_number_is_no_size_slip_where_the_command_has_no_size(tmp_path):
    code, _, err, exc = invoke("fit", "512", "-o", "m.npz", cwd=tmp_path)
    assert_one_line(code, err, "512: no such file; check the path", exception=exc)
    (tmp_path / "bricks").mkdir()  # a folder of that name is there: it is read, and refused as a folder
    code, _, err, exc = invoke("synth", "bricks", "-o", "x.png", cwd=tmp_path)
    assert_one_line(code, err, "bricks is a folder", exception=exc)


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_an_image_to_a_terminal_is_refused(folder):
    # `-o -` without a redirection drew the PNG's bytes in the terminal as garbage, exit status 0.
    main_fd, terminal = os.openpty()
    try:
        p = subprocess.run([sys.executable, "-m", "tghop", "synth", "model.npz", "-o", "-", "--size", "40", "-q"],
                           cwd=folder, stdout=terminal, stderr=subprocess.PIPE, timeout=120)
    finally:
        os.close(terminal)
        os.close(main_fd)
    err = p.stderr.decode()
    assert p.returncode == 2 and err.count("Error: ") == 1 and "Traceback" not in err, err
    assert "-o -: the standard output is a terminal, which shows no image; redirect it" in err


def test_an_output_that_is_a_folder_without_extension_is_called_a_folder(folder):
    # `-o outputs` (a folder, meaning "write in there") was told of an unknown extension "(none)".
    (folder / "outputs").mkdir(exist_ok=True)
    for command in (["synth", "model.npz"], ["extend", "bricks.png", "--size", "72x96"]):
        code, _, err, exc = invoke(*command, "-o", "outputs", cwd=folder)
        assert_one_line(code, err, "outputs is a folder; give a file name for the image in it (e.g. outputs",
                        "texture.png)", exception=exc)
    assert list((folder / "outputs").iterdir()) == []
    code, _, err, exc = invoke("fit", "bricks.png", "-o", "outputs", cwd=folder)  # was "name it outputs.npz"
    assert_one_line(code, err, "-o outputs is a folder; give a model file name in it (e.g. outputs",
                    "model.npz)", exception=exc)
    assert list((folder / "outputs").iterdir()) == []


def test_an_existing_folder_where_a_file_goes_is_a_usage_error(folder, tmp_path):
    # -o's bad value, as an unknown extension is: exit status 2 (0.61: 1), whatever the folder's name; a file
    # the command names from -o's (--count's, --stages') is told to be moved, not to be given a name in it
    for name in ("out.png", "out.npz", "o_2.png", "o_quilt.png"):
        (tmp_path / name).mkdir()
    for args, words in ((["synth", folder / "model.npz", "-o", "out.png"], "out.png is a folder; give a file name for "
                                                                           "the image in it (e.g. out.png"),
                        (["fit", folder / "bricks.png", "-o", "out.npz"], "-o out.npz is a folder; give a model file "
                                                                          "name in it (e.g. out.npz"),
                        (["synth", folder / "model.npz", "-o", "o.png", "--count", "2"],
                         "o_2.png is a folder, where this command writes a file of that name (named from -o's); "
                         "move or remove that folder, or give -o another name"),
                        (["synth", folder / "model.npz", "-o", "o.png", "--stages"], "o_quilt.png is a folder, "
                                                                                      "where this command writes")):
        code, _, err, exc = invoke(*args, "--size", "40", "-q", cwd=tmp_path) if args[0] == "synth" else \
            invoke(*args, "-q", cwd=tmp_path)
        assert_one_line(code, err, words, exception=exc)
        assert code == 2, err
    assert all(not any(p.iterdir()) for p in tmp_path.iterdir())


@pytest.mark.parametrize("args", [["info", "model.npz"], ["info", "model.npz", "--json"],
                                  ["evaluate", "bricks.png", "bricks.png", "--metrics", "swd", "-q"],
                                  ["synth", "model.npz", "-o", "-", "--size", "40", "-q"],
                                  ["serve", "--port", "0"]])
def test_a_result_for_a_closed_stdout_is_one_line(folder, args):
    # `tghop info MODEL >&-` exited 0 and its output was lost without a word.
    p = subprocess.run(["sh", "-c", 'exec "$@" >&-', "sh", sys.executable, "-m", "tghop", *args], cwd=folder,
                       stderr=subprocess.PIPE, timeout=120)
    assert_one_line(p.returncode, p.stderr.decode(), "standard output is closed")


def _to_a_closed_pipe(args, cwd, stream="stdout"):
    """``python -m tghop ARGS`` with ``stream`` a pipe whose reader has already gone (as
    ``| head -1`` leaves it once head has its line): every write there fails with EPIPE."""
    read, write = os.pipe()
    os.close(read)
    try:
        other = {"stderr": subprocess.PIPE} if stream == "stdout" else {"stdout": subprocess.DEVNULL}
        return subprocess.run([sys.executable, "-m", "tghop", *args], cwd=cwd, timeout=120, **{stream: write},
                              **other)
    finally:
        os.close(write)


@pytest.mark.parametrize("args", [["info", "model.npz"], ["info", "model.npz", "--json"], ["--help"],
                                  ["synth", "--help"], ["synth", "model.npz", "-o", "-", "--size", "40", "-q"],
                                  ["patches", "model.npz", "-o", "-", "-n", "4"]])
def test_a_reader_that_went_away_ends_the_command_quietly(folder, args):
    # `tghop info MODEL | head -1` exited 1 (click answers a broken pipe so), an image to such a
    # pipe said "Error: cannot write the output: Broken pipe". Now: no word, exit status 0.
    p = _to_a_closed_pipe(args, folder)
    assert p.returncode == 0 and p.stderr == b"", (p.returncode, p.stderr)


def test_an_error_to_a_stderr_whose_reader_went_away_still_fails(folder):
    # the error line cannot be written, but the exit status says the command failed
    p = _to_a_closed_pipe(["synth", "nope.png", "-o", "o.png"], folder, stream="stderr")
    assert p.returncode == 1 and not (folder / "o.png").exists()


def test_a_broken_pipe_that_is_not_the_outputs_is_one_line(folder, monkeypatch):
    # In process the output is no pipe: a BrokenPipeError is some other pipe's, a failure like any other.
    import tghop.modelfile

    def broken(*args, **kwargs):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(tghop.modelfile, "load_model", broken)
    code, _, err, exc = invoke("info", "model.npz", cwd=folder)
    assert_one_line(code, err, "Broken pipe", exception=exc)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full (a device where every write fails)")
@pytest.mark.parametrize("args", [["info", "model.npz"], ["--help"], ["--version"],
                                  ["evaluate", "bricks.png", "bricks.png", "--metrics", "swd", "-q"],
                                  ["synth", "model.npz", "-o", "-", "--size", "32", "-q"]])  # was a bare strerror
def test_a_full_disk_behind_stdout_is_one_line(folder, args):
    # `tghop info MODEL > /dev/full` ended in a traceback (the write's OSError reached Python);
    # from an empty environment an image to a full stdout failed again at exit (status 120).
    for env in (None, {}):
        with open("/dev/full", "wb") as full:
            p = subprocess.run([sys.executable, "-m", "tghop", *args], cwd=folder, stdout=full,
                               stderr=subprocess.PIPE, timeout=120, env=env)
        assert_one_line(p.returncode, p.stderr.decode(), "cannot write the output: No space left on device; free some")
        assert "Exception ignored" not in p.stderr.decode() and p.returncode in (1, 2), (env, p.returncode)


def test_help_shows_each_default_as_its_kind():
    # A float of 1.0 is not "on", nor 0.0 "off" (they equal True and False as dictionary keys).
    flat = " ".join(CliRunner().invoke(main, ["fit", "--help-all"]).stdout.split())
    norm = flat.split("--norm-match FLOAT", 1)[1].split(" --coupling", 1)[0]
    assert norm.endswith("[default: 1.0; --paper: 0.0; 0<=x<=1]"), norm
    coupling = flat.split("--coupling FLOAT", 1)[1].split(" --min-cluster-size", 1)[0]
    assert coupling.endswith("[default: 0.95; --paper: 0.0; 0<=x<=0.99]"), coupling
    assert "[default: auto; --paper: 50]" in flat.split("--clusters", 1)[1].split(" --codewords", 1)[0]


def test_help_shows_each_paper_value_in_the_command_lines_words():
    # `--paper: False` and `--paper: None` (Python's words) beside `[default: on` for a flag and `--layout none`.
    flat = " ".join(CliRunner().invoke(main, ["synth", "--help-all"]).stdout.split())
    colours = flat.split("--match-colours / --no-match-colours", 1)[1].split(" --refine", 1)[0]
    assert colours.endswith("[default: on; --paper: off]"), colours
    assert "[default: 3; --paper: none]" in flat.split("--layout INT", 1)[1].split(" --fit-seed", 1)[0]
    assert "[default: 1024; --paper: none]" in flat.split("--region INT", 1)[1].split(" --own-shares", 1)[0]
    assert "--paper: None" not in flat and "--paper: False" not in flat and "--paper: True" not in flat


def test_help_gives_the_word_an_option_takes_for_none():
    # The settings table's help says "(None: patch_size / 6, ...)", Python's word; the command line takes
    # none (or auto), so --help says that.
    for command in ("synth", "fit", "inpaint", "batch"):  # their options' own help: --help-all's (0.64)
        flat = " ".join(CliRunner().invoke(main, [command, "--help-all" if command != "inpaint" else "--help"]).stdout
                        .split())
        assert "None:" not in flat, command
    flat = " ".join(CliRunner().invoke(main, ["synth", "--help-all"]).stdout.split())
    assert "Quilting overlap in pixels (none: patch_size / 6, rounded" in flat
    assert "(none: the whole image at once" in flat


def test_help_gives_the_channel_options_defaults():
    # --k1, --k2 and --k3 said the paper's counts but not what tghop takes without them.
    from tghop.synthesis import default_channels

    flat = " ".join(CliRunner().invoke(main, ["fit", "--help-all"]).stdout.split())
    for hop, (colour, grey, six) in enumerate(zip(default_channels(64, 3), default_channels(64, 1),
                                                  default_channels(64, 6))):
        text = flat.split(f"--k{hop + 1} ", 1)[1].split(" --", 1)[0]
        assert f"[default: {colour}; grey exemplars {grey}; a material of C channels {colour} x C / 3, rounded up]" \
            in text, text
        assert six == -(-colour * 6 // 3)


def test_cooc_train_help_gives_the_steps_default():
    # --steps said "(default: the configuration's)", a number nowhere on the page for --paper.
    from tghop.cooc.config import PAPER, SMALL

    flat = " ".join(CliRunner().invoke(main, ["cooc", "train", "--help"]).stdout.split())
    assert (f"[default: the configuration's: {SMALL['n_steps']:,} small, {PAPER['n_steps']:,} with --paper]"
            in flat), flat


def test_serve_and_batch_help_say_what_the_code_does():
    # --host named 127.0.0.1 (localhost) only, though ::1 is quiet too; --retries read "Tries again elsewhere".
    serve = " ".join(CliRunner().invoke(main, ["serve", "--help"]).stdout.split())
    assert "Any other than 127.0.0.1, localhost or ::1 lets other machines use the server" in serve, serve
    batch = " ".join(CliRunner().invoke(main, ["batch", "--help-all"]).stdout.split())
    assert "Times a task whose worker died" in batch and "Tries again elsewhere" not in batch, batch


def test_a_model_without_a_layout_warns_of_the_layout_options(folder, tmp_path):
    # --layout-weight, --layout-refine and --layout-patch-refine on such a model were ignored without a word.
    code, _, err, _ = invoke("fit", folder / "bricks.png", "-o", "flat.npz", *FAST, "--layout", "none", cwd=tmp_path)
    assert code == 0, err
    synth = ["synth", "flat.npz", "-o", "o.png", "--size", "48", "-q"]
    code, _, err, _ = invoke(*synth, "--layout-weight", "2", "--layout-refine", "1", cwd=tmp_path)
    assert code == 0 and "Warning: --layout-weight, --layout-refine have no effect: the model has no coarse layout" \
        in err, err
    code, _, err, _ = invoke(*synth, cwd=tmp_path)
    assert code == 0 and "Warning" not in err, err


def test_a_model_without_colour_classes_warns_of_own_shares_and_info_says_so(folder, tmp_path):
    # `--own-shares 0.5` on a model fitted with --colour-classes 0 had no effect without a word.
    code, _, err, _ = invoke("fit", folder / "bricks.png", "-o", "plain.npz", *FAST, "--colour-classes", "0",
                             cwd=tmp_path)
    assert code == 0, err
    synth = ["synth", "-o", "o.png", "--size", "48", "-q"]
    code, _, err, _ = invoke(*synth, "plain.npz", "--own-shares", "0.5", cwd=tmp_path)
    assert code == 0 and "Warning: --own-shares 0.5 has no effect" in err and "--colour-classes" in err, err
    for args in (["plain.npz"], ["plain.npz", "--own-shares", "1"], [folder / "model.npz", "--own-shares", "0.5"]):
        code, _, err, _ = invoke(*synth, *args, cwd=tmp_path)
        assert code == 0 and "Warning" not in err, (args, err)
    # `tghop info` showed the formula with K (259 for C=1, K=0) against the 257 stored, and no class count.
    code, out, err, _ = invoke("info", "plain.npz", cwd=tmp_path)
    assert code == 0 and "colour classes: none" in out and "C*257, no colour classes" in out, out + err
    code, out, err, _ = invoke("info", "model.npz", cwd=folder)
    assert code == 0 and "colour classes: 4\n" in out and "K=4 colour classes" in out, out + err


def test_help_states_the_range_of_fractions():
    # `--own-shares FLOAT` showed no range, though values outside [0, 1] are refused.
    flat = " ".join(CliRunner().invoke(main, ["synth", "--help-all"]).stdout.split())
    shares = flat.split("--own-shares FLOAT", 1)[1].split(" --layout-refine", 1)[0]
    assert shares.endswith("[default: 1.0; --paper: 0.0; 0<=x<=1]"), shares
    detail = flat.split("--detail FLOAT", 1)[1].split(" --flat-share", 1)[0]
    assert detail.endswith("; 0<=x<1]"), detail  # open at 1
    assert "[default: 0.99; --paper: 0.95; 0<x<=1]" in flat  # --cluster-energy, open at 0
    assert "<=x<=1e+06" not in flat and "<=x<=1000000" not in flat  # caps, not ranges: not shown


@pytest.mark.parametrize("command", ["fit", "synth", "batch"])
def test_help_names_the_values_of_a_choice(command):
    # `--gamma-mode CHOICE` never said which values it takes (only its error did).
    flat = " ".join(CliRunner().invoke(main, [command, "--help-all"]).stdout.split())
    assert "--gamma-mode [absolute|relative] " in flat and "CHOICE" not in flat


@pytest.mark.parametrize("command", [[], ["fit"], ["synth"], ["info"], ["evaluate"], ["patches"], ["baseline"],
                                     ["cooc"], ["cooc", "train"], ["cooc", "morph"], ["cooc", "edit"]])
def test_help_is_plain_text(command):
    # The settings table's help is reStructuredText for the docstrings; --help shows it plain.
    result = CliRunner().invoke(main, [*command, "--help"])
    assert result.exit_code == 0
    assert "`" not in result.stdout and ":mod:" not in result.stdout, result.stdout


def _python(code, *args, **kwargs):
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, **kwargs)


def test_ctrl_c_during_start_up_is_one_line(folder):
    # Python's own start-up is not ours: the child says "go" once it is over, then runs
    # `tghop synth` as the console script does (`from tghop.__main__ import run`, the
    # command line's imports included). (Finding the tghop package on sys.path precedes
    # any tghop code: the child says "go" once `import tghop` has run.)
    code = ("import sys\nsys.argv[0] = 'tghop'\nimport tghop\nprint('go', flush=True)\n"
            "from tghop.__main__ import run\nsys.exit(run())\n")
    for delay in (0.05, 0.15, 0.4, 0.8):
        p = subprocess.Popen([sys.executable, "-c", code, "synth", "builtin:bricks", "-o", "ctrlc.png", *FAST],
                             cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        assert p.stdout.readline() == b"go\n"
        time.sleep(delay)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=120)
        err = err.decode()
        assert p.returncode != 0 or "written" in err
        assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
        if p.returncode == 0:  # it finished before the Ctrl-C
            (folder / "ctrlc.png").unlink()
        else:
            assert p.returncode == 130 and err.strip() == "Error: interrupted", (p.returncode, err)
            assert not (folder / "ctrlc.png").exists()
    for name in os.listdir(folder):
        assert not name.endswith(".tmp"), name


def test_only_the_command_freezes_its_objects(folder):
    # Run as `tghop` (the console script and `python -m tghop` both call
    # tghop.__main__.run), the objects that exist after the imports and at exit go to the
    # garbage collector's permanent generation (fewer objects to walk); a program that runs
    # the command line in-process keeps its collector as it was.
    report = "print('FROZEN', gc.get_freeze_count() > 0, file=sys.stderr)\n"
    as_command = ("import sys, gc, atexit\natexit.register(lambda: " + report.strip() + ")\n"
                  "from tghop.__main__ import run\nrun()\n")
    in_process = ("import sys, gc\nfrom tghop.cli import main\n"
                  "try:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n" + report)
    for code, frozen in ((as_command, True), (in_process, False)):
        for args in (["info", "model.npz"], ["info", "no_such_model.npz"]):  # success and failure alike
            p = _python(code, *args, cwd=folder)
            _, err = p.communicate(timeout=120)
            assert f"FROZEN {frozen}" in err.decode(), (frozen, args, err.decode())
    import gc

    before = gc.get_freeze_count()
    assert CliRunner().invoke(main, ["info", str(folder / "model.npz")]).exit_code == 0
    assert gc.get_freeze_count() == before


def test_python_m_tghop_is_the_command(folder):
    p = subprocess.run([sys.executable, "-m", "tghop", "info", "model.npz"], cwd=folder, capture_output=True,
                       timeout=120)
    assert p.returncode == 0 and b"parameters" in p.stdout, p.stderr
    p = subprocess.run([sys.executable, "-m", "tghop", "info", "missing.npz"], cwd=folder, capture_output=True,
                       timeout=120)
    assert p.returncode == 1 and p.stderr.decode().startswith("Error: ") and b"Traceback" not in p.stderr


def test_help_info_and_generation_do_not_import_sklearn_or_scipy(folder):
    code = (
        "import sys\n"
        "from tghop.cli import main\n"
        "try:\n"
        "    main(sys.argv[1:])\n"
        "except SystemExit:\n"
        "    pass\n"
        "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'sklearn', 'scipy', 'threadpoolctl', 'torch'})\n"
        "print('HEAVY', heavy, file=sys.stderr)\n"
        "print('NUMPY', 'numpy' in sys.modules, file=sys.stderr)\n"
        "print('NUMPY_MA', 'numpy.ma' in sys.modules, file=sys.stderr)\n"  # 10 ms (np.unique imports it)
        "print('LOGGING', 'logging' in sys.modules, file=sys.stderr)\n"  # concurrent.futures imports it: 3 ms
    )
    for args in (["--help"], ["--version"], ["info", "model.npz"],
                 ["synth", "model.npz", "-o", "lazy.png", "--size", "40", "--pool", "100", "-q"],
                 ["patches", "model.npz", "-n", "4", "-o", "lazy_p.png"]):
        p = _python(code, *args, cwd=folder)
        _, err = p.communicate(timeout=120)
        assert p.returncode == 0
        # Generation and sampling patches hold one BLAS thread (0.49.1 and 0.52: the same bytes with any
        # thread count), which threadpoolctl sets: 3 ms of import and 1 ms of its first limit here.
        light = "HEAVY ['threadpoolctl']" if args[0] in ("synth", "patches") else "HEAVY []"
        assert light in err.decode(), (args, err.decode())
        assert "NUMPY_MA False" in err.decode(), (args, err.decode())
        assert "LOGGING False" in err.decode(), (args, err.decode())
        if args[0].startswith("--"):  # help and version do not even import NumPy
            assert "NUMPY False" in err.decode(), (args, err.decode())


def test_evaluate_help_says_which_way_each_score_is_better():
    # "Score RESULT images ... (lower is better but novelty)": RESULTS is the argument, and novelty went unexplained.
    flat = " ".join(CliRunner().invoke(main, ["evaluate", "--help"]).stdout.split())
    assert "Score RESULTS against EXEMPLAR with texture metrics: lower is better, except novelty (the distance to " \
           "the nearest exemplar patch: higher is newer)." in flat, flat


@pytest.mark.parametrize("args, words", [(["--layout", "auto"], "'auto' is not an integer (or none)"),
                                         (["--clusters", "none"], "'none' is not an integer (or auto)"),
                                         (["--reject-threshold", "y"], "'y' is not a number (or none)")])
def test_a_bad_word_for_an_option_that_takes_none_names_the_word(folder, args, words):
    # `--layout auto` said "'auto' is not an integer", never that the option takes `none` (the server's fit said it).
    code, _, err, _ = invoke("synth", "model.npz", "-o", "o.png", *args, cwd=folder)
    assert code == 2 and words in err, err


@pytest.mark.parametrize("args", [[], ["cooc"]])
def test_a_group_without_a_command_prints_its_help_not_an_error(args):
    # `tghop` alone printed "Error: Usage: tghop ..." and the whole help, then "(see 'tghop --help')".
    p = subprocess.run([sys.executable, "-m", "tghop", *args], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and p.stdout == "", (p.returncode, p.stdout)
    assert p.stderr.startswith(f"Usage: {' '.join(['tghop', *args])} [OPTIONS] COMMAND") and "Error" not in p.stderr, \
        p.stderr
    assert "Commands:" in p.stderr and "(see '" not in p.stderr, p.stderr


def test_file_options_name_what_they_take():
    # `baseline --model TEXT` and `cooc edit --mask TEXT` said nothing of the file each takes.
    baseline = " ".join(CliRunner().invoke(main, ["baseline", "--help"]).stdout.split())
    edit = " ".join(CliRunner().invoke(main, ["cooc", "edit", "--help"]).stdout.split())
    assert "--model CHECKPOINT " in baseline and "--mask IMAGE " in edit, (baseline, edit)


def test_a_command_imports_only_its_own_module_of_the_command_line(folder):
    # `tghop synth` builds no other command's options (batch's, evaluate's, cooc's ...; texture's
    # commands take guided's constants); the list of commands (--help) and a mistyped name
    # (click's "Did you mean") see them all.
    # The shared helpers' modules (0.64: common's parts) load with the group, for every command.
    shared = ('common', 'errors', 'progress', 'inputs', 'outputs', 'materials', 'group', 'options', 'lines',
              'help_sections')
    code = (
        "import atexit, sys\n"
        "import tghop.cli\n"
        f"SHARED = {shared!r}\n"
        "def loaded():\n"
        "    return sorted(m.split('.')[2] for m in sys.modules if m.startswith('tghop.cli.')\n"
        "                  and m.split('.')[2] not in SHARED)\n"
        "print('AT_IMPORT', loaded(), file=sys.stderr)\n"
        "atexit.register(lambda: print('AT_EXIT', loaded(), file=sys.stderr))\n"
        "sys.argv[0] = 'tghop'\n"
        "from tghop.__main__ import run\n"
        "run()\n"
    )
    everything = ["batch", "cooc", "evaluation", "guided", "inpaint", "serve", "texture"]
    for args, code_expected, loaded in (
            (["synth", "model.npz", "-o", "own.png", "--size", "40", "--pool", "100", "-q"], 0, ["guided", "texture"]),
            (["info", "model.npz"], 0, ["guided", "texture"]),
            (["evaluate", "--help"], 0, ["evaluation"]),
            (["--version"], 0, []),
            (["--help"], 0, everything),
            (["synt"], 2, everything)):
        p = _python(code, *args, cwd=folder)
        _, err = p.communicate(timeout=120)
        err = err.decode()
        assert p.returncode == code_expected, (args, err)
        assert "AT_IMPORT []" in err, (args, err)
        assert f"AT_EXIT {loaded}" in err, (args, err)
    assert "Did you mean 'synth'?" in err


@pytest.mark.parametrize("word, words", [("fill", "to fill a hole, use 'tghop inpaint IMAGE MASK -o OUT'"),
                                         ("outpaint", "to grow an image, use 'tghop extend IMAGE -o OUT --size HxW'"),
                                         ("Paint", "use 'tghop synth A B ... --guide MAP -o OUT'"),
                                         ("synt", "Did you mean 'synth'?")])
def test_another_name_of_a_commands_task_names_the_command(word, words):
    # click's "Did you mean" picks by spelling: 'tghop outpaint' was sent to inpaint (a hole's fill, not a
    # grown image) and 'tghop fill' had no answer at all.
    from conftest import assert_user_error, cli

    r = cli(word, "x.png")
    assert_user_error(r, f"No such command '{word}'", words)
    assert r.returncode == 2


@pytest.mark.parametrize("args, words", [
    (["inpaint", "a.png", "--mask", "m.png", "-o", "o.png"], "No such option '--mask'; MASK is the second argument"),
    (["synth", "a.png", "--seamless", "-o", "o.png"], "No such option '--seamless'; for a seamless tile, give --tile"),
    (["extend", "a.png", "--width", "512", "-o", "o.png"], "No such option '--width'; give --size HEIGHTxWIDTH"),
    (["synth", "a.png", "--bit-depth", "16", "-o", "o.png"], "No such option '--bit-depth'; give --depth 16"),
    (["fit", "a.png", "--mask", "m.png", "-o", "o.npz"], "No such option '--mask'; to leave part of the exemplar out, "
                                                         "give --exclude MASK"),
    (["info", "--width", "3", "m.npz"], "No such option '--width'.")])  # info has no --size: click's own words
def test_another_name_of_an_option_names_the_option(args, words):
    # click's "Did you mean" picks by spelling: --mask was sent to --maps, --seamless to --scale, --seed or
    # --stages, --width to --depth.
    from conftest import assert_user_error, cli

    r = cli(*args)
    assert_user_error(r, words)
    assert r.returncode == 2 and "--maps" not in r.stderr.decode()


def test_a_file_name_with_a_newline_is_still_a_one_line_error(folder):
    # A name's newline printed as it is made the error two lines (the second without "Error: ").
    code, _, err, exc = invoke("synth", "no\nsuch.png", "-o", "out.png", cwd=folder)
    assert_one_line(code, err, "no\\nsuch.png", exception=exc)
    assert len(err.strip().splitlines()) == 1, err
    assert not (folder / "out.png").exists()
