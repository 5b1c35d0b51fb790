"""benchmarks/bench_paper.py's options do what its help says, without running the reproduction.

Only the argument parsing and Table 2's rows are exercised: no exemplar, fit or Ustyuzhaninov run.
"""

import itertools
import re
import sys
from pathlib import Path

import pytest
from conftest import bench_script

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_paper.py"


@pytest.fixture(scope="module")
def bench():
    """The script as a module; sys.path and sys.modules as they were afterwards."""
    yield from bench_script(SCRIPT)


def _rows(bench, args):
    return [row[0] for row in bench.table2_rows(args, None, with_a=3.0, without=1.0)]


def test_quick_skips_table2s_timed_ustyuzhaninov_run_and_says_so(bench):
    args = bench.parse_args(["--quick"])
    assert args.time_ust_iters == 0  # section_time runs ustyuzhaninov only when it is above 0
    assert args.time_ust_skipped == "--quick"
    first = _rows(bench, args)[0]
    assert "not timed" in first and "--quick" in first and "--time-ust-iters N" in first


def test_the_full_run_times_ustyuzhaninov(bench):
    args = bench.parse_args(["--textures", "a"])  # not the shared folder's listing
    assert args.time_ust_iters == 10
    assert args.time_ust_skipped == ""


def test_an_explicit_time_ust_iters_wins_over_quick(bench):
    args = bench.parse_args(["--quick", "--time-ust-iters", "3"])
    assert (args.time_ust_iters, args.time_ust_skipped) == (3, "")
    args = bench.parse_args(["--textures", "a", "--time-ust-iters", "0"])
    assert (args.time_ust_iters, args.time_ust_skipped) == (0, "--time-ust-iters 0")
    assert "skipped by --time-ust-iters 0" in _rows(bench, args)[0]


def test_empty_ust_textures_leaves_the_timed_run_to_time_ust_iters(bench):
    # --ust-textures "" is the quality table's subset only, as its help says.
    args = bench.parse_args(["--textures", "a", "--ust-textures", ""])
    assert args.ust_textures == "" and args.time_ust_iters == 10


def test_quick_shrinks_the_sweeps_and_the_quality_table(bench):
    args = bench.parse_args(["--quick"])
    assert args.textures.split(",") == ["brick_wall", "grass_lawn", "red_peppers"]
    assert args.ust_textures == "brick_wall" and args.ust_iters == 20
    assert args.settings == ["a", "d"] and tuple(args.clusters) == (50, 110) and tuple(args.gammas) == (0, 0.01, 0.1)


def test_a_negative_time_ust_iters_is_refused(bench, capsys):
    with pytest.raises(SystemExit):
        bench.parse_args(["--quick", "--time-ust-iters", "-1"])
    assert "--time-ust-iters" in capsys.readouterr().err


def test_the_help_says_what_skips_the_timed_run(bench, capsys):
    with pytest.raises(SystemExit):
        bench.parse_args(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "0 skips it, the default with --quick" in text
    assert "not Table 2's timed one" in text



def _options(text):
    return set(re.findall(r"(?<![\w-])(--[a-z][\w-]*)", text))


def test_the_docs_name_only_the_scripts_options(bench, capsys):
    with pytest.raises(SystemExit):
        bench.parse_args(["--help"])
    known = _options(capsys.readouterr().out.split("\n\n")[0])  # argparse's usage lines: the real options
    assert {"--quick", "--time-ust-iters", "--ust-textures"} <= known
    usage, options = bench.__doc__.split("\nOptions:\n", 1)
    listed = set(re.findall(r"^  (--[a-z][\w-]*)", options.split("\nSections")[0], re.M))
    assert listed == known - {"--help"}  # the docstring's list (--help shows it) has every option
    readme = (SCRIPT.parents[1] / "README.md").read_text(encoding="utf-8").splitlines()
    start = next(i for i, line in enumerate(readme) if line.startswith("python benchmarks/bench_paper.py"))
    block = [readme[start]] + list(itertools.takewhile(lambda line: line.startswith(" "), readme[start + 1:]))
    assert "--quick" in " ".join(block)
    assert _options(usage + " ".join(block)) <= known


def test_a_missing_exemplar_stops_the_run_before_any_work_or_output(bench, tmp_path, monkeypatch, capsys):
    # A fresh checkout without ../shared/textures: one line naming what is missing and the fix, status 2,
    # no output folder (it stopped with a traceback-free SystemExit at the first fit, the folder made).
    monkeypatch.setattr(sys.modules["_common"], "TEXTURES", tmp_path / "no-such-folder")
    out = tmp_path / "out"
    assert bench.main(["--quick", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("Error: exemplars brick_wall, grass_lawn, red_peppers not found in ")
    assert "TGHOP_TEXTURES" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_every_exemplar_a_run_reads_is_looked_for(bench, tmp_path, monkeypatch):
    monkeypatch.setattr(sys.modules["_common"], "TEXTURES", tmp_path)
    (tmp_path / "brick_wall.jpg").write_bytes(b"")
    args = bench.parse_args(["--textures", "bricks,knit", "--ust-textures", "brick_wall,fur"])
    assert bench.needed_exemplars(args) == ["brick_wall", "grass_lawn", "bricks", "knit", "fur"]
    assert bench.missing_exemplars(bench.needed_exemplars(args)) == ["grass_lawn", "knit", "fur"]  # bricks: built in


def test_fig3_follows_the_paper_panels_and_claim(bench):
    # The paper's Fig. 3: (a) without SDR, (b) with SDR, and "the quality with SDR significantly improves";
    # the report said SDR left the grass "about as it was" (the paper's Fig. 9 remark) and put "with" first.
    (first, first_kw), (second, second_kw) = bench.FIG3_PANELS
    assert first.startswith("(a) without SDR") and first_kw == {"gamma": 0.0}
    assert second.startswith("(b) with SDR") and second_kw == {}
    rows = [{"label": label, "dims": {"D2": 1408, "D_r": 1408}, "fit_s": 1.0, "scores": {}}
            for label, _ in bench.FIG3_PANELS]
    res = {"sheet": "fig3_sdr.png", "rows": rows}
    text = bench.md_fig3(res)
    assert "significantly improves" in text and "about as it was" not in text
    assert text.index("(a) without SDR") < text.index("(b) with SDR")


def test_only_runs_the_sections_named_by_key_or_the_papers_name_and_writes_beside_a_full_runs_report(bench, capsys):
    # A researcher who wanted one figure ran the whole reproduction (--quick: 5-8 min), and a run's report.md
    # replaced the full one. --only names sections (fig6, table4, ...); its results go to a folder of their own.
    args = bench.parse_args(["--only", "fig6,Table 4"])
    assert args.sections == ["params", "stages"] and args.out == bench.RESULTS / "paper-params-stages"
    assert bench.needed_exemplars(args) == ["brick_wall"]  # no quality table, no grass_lawn
    assert bench.parse_args(["--only", "fig3"]).sections == ["fig3"]
    assert bench.needed_exemplars(bench.parse_args(["--only", "fig3"])) == ["grass_lawn"]
    assert bench.parse_args(["--textures", "a"]).sections == list(bench.SECTION_NAMES)
    assert bench.parse_args(["--textures", "a"]).out == bench.RESULTS / "paper"
    with pytest.raises(SystemExit):
        bench.parse_args(["--only", "fig99"])
    assert "--only takes sections among time, table2" in capsys.readouterr().err


def test_the_reports_command_line_runs_again_as_written(bench):
    # `--ust-textures ""` (the README's quick run) was written as `--ust-textures  --out DIR`: pasted back, the run
    # took "--out" for its exemplars.
    import shlex

    argv = ["--quick", "--ust-textures", "", "--out", "/tmp/a b"]
    line = bench.command_line(argv)
    assert line == "python benchmarks/bench_paper.py --quick --ust-textures '' --out '/tmp/a b'"
    assert shlex.split(line)[2:] == argv


def test_table1_says_how_many_hop2_channels_sdr_keeps(bench):
    # With gamma 0.01, setting (a) (K2 = 32) and Fig. 7's K2 = 27 made the same model and the same scores: the
    # five extra hop-2 channels keep no SDR component. The table gave no hint of why.
    dims = {"D0": 3072, "D1": 2560, "D2": 2048, "D_r": 920, "F": 2500}
    res = {"sheet": "fig8_settings.png",
           "rows": [{"setting": "a", "K1": 10, "K2": 32, "K2_kept": 21, "dims": dims, "fit_s": 1.0, "scores": {}}]}
    text = bench.md_settings(res)
    assert "| setting | K1 | K2 | K2 kept |" in text and "| (a) | 10 | 32 | 21 |" in text


def test_table3_gives_each_processs_cpu_time_beside_its_wall_time(bench):
    # 0.59's Table 3 gave wall times alone: on the shared machine (load 55-100) its first 10,000-patch pool, which
    # pays for the float32 mixing matrix, came out faster than the later ones (0.80 s against 1.74 s).
    rows = bench.table3_rows((16.5, 15.9), ([0.80, 1.7, 1.9, 1.6], [0.36, 0.09, 0.10, 0.11]),
                             ([0.5, 0.4, 0.6, 0.5], [0.20, 0.21, 0.19, 0.22]))
    assert [len(r) for r in rows] == [4] * 4
    assert rows[0][1:] == [16.5, 15.9, bench.PAPER_TABLE3["analysis"]]
    assert rows[1][1:3] == [0.80, 0.36] and "first image" in rows[1][0]
    assert rows[2][1:3] == [1.7, 0.10] and "median of 3" in rows[2][0]
    assert rows[3][1:] == [0.5, pytest.approx(0.205), bench.PAPER_TABLE3["quilting"]] and "median of 4" in rows[3][0]
