"""benchmarks/bench_inpaint.py's seeds and comparisons, without fitting or filling anything.

Only the argument parsing, the reading of results files of either format and the statistics
of ``--against`` are exercised.
"""

import argparse
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import bench_script

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_inpaint.py"


@pytest.fixture(scope="module")
def bench():
    """The script as a module; sys.path and sys.modules as they were afterwards."""
    yield from bench_script(SCRIPT)


def test_seeds_are_read_as_lists_and_ranges(bench):
    assert bench.parse_seeds("1,2,3") == [1, 2, 3]
    assert bench.parse_seeds("1-5") == [1, 2, 3, 4, 5]
    assert bench.parse_seeds("0, 4-6") == [0, 4, 5, 6]
    for bad in ("", "a", "1,1", "1-2,2", "-1"):
        with pytest.raises(argparse.ArgumentTypeError):
            bench.parse_seeds(bad)


def test_one_seed_by_default_and_seed_or_seeds_not_both(bench, capsys):
    assert bench.parse_args([]).seeds == [1]  # the results before --seeds used seed 1
    assert bench.parse_args(["--seed", "3"]).seeds == [3]
    assert bench.parse_args(["--seeds", "2,3"]).seeds == [2, 3]
    with pytest.raises(SystemExit) as exc:
        bench.parse_args(["--seed", "1", "--seeds", "2,3"])
    assert exc.value.code == 2 and "not both" in capsys.readouterr().err
    args = bench.parse_args(["--extend"])
    assert (args.crop, args.size, args.name) == (256, 512, "inpaint-extend")
    assert args.exemplars == bench.EXTEND_EXEMPLARS and len(args.exemplars) == 13


def _old(values, seed=1):
    """A results payload as written before --seeds: {(exemplar, hole): value}, one seed in meta."""
    return dict(meta=dict(seed=seed), results=[dict(exemplar=e, hole=h, tghop_sifid=v)
                                                for (e, h), v in values.items()])


def _new(values):
    """A --seeds payload: {(exemplar, hole): {seed: value}}."""
    seeds = sorted({s for v in values.values() for s in v})
    return dict(meta=dict(format=2, seed=seeds[0], seeds=seeds),
                results=[dict(exemplar=e, hole=h, per_seed={str(s): dict(tghop_sifid=x) for s, x in v.items()},
                              tghop_sifid=float(np.mean(list(v.values())))) for (e, h), v in values.items()])


def test_old_results_read_as_their_seed_and_failed_seeds_left_out(bench):
    assert bench.seed_values(_old({("a", 0.1): 2.0}, seed=7), "tghop_sifid") == {("a", 0.1): {7: 2.0}}
    payload = _new({("a", 0.1): {1: 2.0, 2: 3.0}})
    payload["results"][0]["per_seed"]["2"] = dict(tghop_error="ValueError: high <= 0")
    assert bench.seed_values(payload, "tghop_sifid") == {("a", 0.1): {1: 2.0}}


def test_paired_geometric_mean_and_its_error_across_seeds(bench):
    # Each seed's ratio is the same on every exemplar: exp(d) for seed s; the estimate is the
    # mean of the d's, its error their standard deviation over sqrt(3), the interval Student's.
    d = {1: 0.10, 2: -0.02, 3: 0.04}
    old = {(e, 0.1): {s: base for s in d} for e, base in (("a", 1.0), ("b", 2.0))}
    new = {k: {s: v * math.exp(d[s]) for s, v in per.items()} for k, per in old.items()}
    r = bench.ratio_summary(new, old)
    se = np.std(list(d.values()), ddof=1) / math.sqrt(3)
    assert r["paired"] and r["seeds"] == 3 and (r["better"], r["pairs"]) == (2, 6)
    assert r["gmean"] == pytest.approx(math.exp(0.04)) and r["se"] == pytest.approx(se)
    assert r["high"] == pytest.approx(math.exp(0.04 + 4.302653 * se), rel=1e-6)
    assert r["verdict"] == "within noise"
    tight = {k: {s: v * 1.10 ** (1 + 0.01 * s) for s, v in per.items()} for k, per in old.items()}
    assert bench.ratio_summary(tight, old)["verdict"] == "beyond noise"


def test_one_seed_gives_no_noise_estimate(bench):
    r = bench.ratio_summary({("a", 0.1): {1: 1.1}}, {("a", 0.1): {1: 1.0}})
    assert r["gmean"] == pytest.approx(1.1) and math.isnan(r["se"])
    assert r["verdict"] == "one seed: no noise estimate"


def test_without_shared_seeds_the_means_are_compared_unpaired(bench):
    new = {("a", 0.1): {2: math.exp(0.1), 3: math.exp(0.3)}, ("b", 0.1): {2: math.exp(0.1), 3: math.exp(0.3)}}
    old = {("a", 0.1): {1: 1.0}, ("b", 0.1): {1: 1.0}}
    r = bench.ratio_summary(new, old)
    assert not r["paired"] and r["seeds"] == "2 + 1" and (r["better"], r["pairs"]) == (0, 2)
    assert r["gmean"] == pytest.approx(math.exp(0.2))
    # pooled spread: only the new file's two seeds (variance 0.02), over 1/2 + 1/1
    assert r["se"] == pytest.approx(math.sqrt(0.02 * 1.5))


def test_comparison_per_hole_and_over_all_against_an_old_file(bench):
    new = _new({("a", 0.1): {1: 1.1, 2: 1.2}, ("a", 0.3): {1: 0.9, 2: 1.0}, ("b", 0.1): {1: 2.0, 2: 2.0}})
    comp = bench.comparison(new, _old({("a", 0.1): 1.0, ("a", 0.3): 1.0, ("c", 0.1): 1.0}), "old")
    assert [r["hole"] for r in comp["rows"]] == [0.1, 0.3, "all"]
    assert comp["rows"][0]["pairs"] == 1 and comp["rows"][0]["gmean"] == pytest.approx(1.1)  # seed 1 only
    assert comp["rows"][2]["gmean"] == pytest.approx(math.sqrt(1.1 * 0.9))
    for r in new["results"]:  # what the report's tables read besides tghop's SIFID
        r.update({f"{m}_{v}": 1.0 for m in ("tghop", "quilting", "blur", "original") for v in ("sifid", "seam")
                  if f"{m}_{v}" not in r}, fit_s=1.0, tghop_s=1.0, quilting_s=1.0)
    text = bench.report(dict(new, meta=dict(new["meta"], exemplars=2, crop=512, cpus=2, load_average_end=1.0,
                                            minutes=1.0), timing=[], comparison=comp))
    assert "seeds 1, 2 (each fit filled with each" in text and "tghop SIFID sd" in text
    assert "## Against old" in text and "one seed: no noise estimate" in text


def test_an_unreadable_against_file_is_a_usage_error(bench, tmp_path, capsys):
    (tmp_path / "bad.json").write_text("{not json")
    for against in (str(tmp_path / "missing.json"), str(tmp_path / "bad.json")):
        with pytest.raises(SystemExit) as exc:
            bench.main(["--report", "--against", against])
        assert exc.value.code == 2 and f"--against {against}: cannot read" in capsys.readouterr().err
    (tmp_path / "grown.json").write_text('{"meta": {"mode": "extend", "seed": 1}, "results": []}')
    with pytest.raises(SystemExit) as exc:
        bench.main(["--report", "--against", str(tmp_path / "grown.json")])
    assert exc.value.code == 2 and "compare like with like" in capsys.readouterr().err
