"""benchmarks/bench_material.py's ``--albedo-refine`` (0.59: the measurement behind docs/choices.md's "The albedo
patch-refined"), on a small built-in exemplar with small fit settings and a cheap score in place of SIFID."""

from pathlib import Path

import numpy as np
import pytest
from conftest import bench_script

from tghop import data

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_material.py"
FIT = dict(n_clusters=6, n_codewords=30, stride=4, max_patches=1500, layout_factor=None)


@pytest.fixture(scope="module")
def bench():
    """The script as a module; sys.path and sys.modules as they were afterwards."""
    yield from bench_script(SCRIPT)


def test_albedo_refine_rows_compare_the_texture_and_the_material_before_and_after(bench):
    assert bench.parse_args(["bricks", "--albedo-refine", "--seeds", "2"]).albedo_refine
    assert not bench.parse_args(["bricks"]).albedo_refine
    ex = data.bricks(64)
    scored = []

    def score(exemplar, image):  # the albedo's mean distance from the exemplar's mean colour
        assert exemplar is ex and image.shape == (48, 48, 3)
        scored.append(image)
        return float(np.abs(image.mean(axis=(0, 1)) - exemplar.mean(axis=(0, 1))).mean())

    row = bench.albedo_refine_row(ex, (48, 48), [0, 1], fit=FIT, score=score)
    assert len(scored) == 6 and set(bench.ALBEDO_WAYS) <= set(row)
    assert not np.array_equal(scored[1], scored[2])  # the albedo without and with its patch refinement
    assert -1 <= row["corr 0.59"] <= 1 and row["corr crop"] > 0.5 and row["normal error"] < 1e-3
    table = bench.albedo_refine_table({"bricks": row, "again": row})
    assert table.splitlines()[0].startswith("| exemplar | texture (plain) | material 0.58 | material 0.59 |")
    assert table.splitlines()[-1].startswith(f"| mean | {row['texture (plain)']:.2f} |")


def test_painted_rows_score_each_regions_albedo_by_its_own_crop(bench):
    """0.60's ``--painted``: materials painted half and half, unrefined, by default and with quality best."""
    assert bench.parse_args(["bricks", "cells", "--painted"]).painted
    a, b = data.bricks(64), data.cells(64, rng=3)
    scored = []

    def score(exemplar, image):  # the region's mean distance from its exemplar's mean colour
        assert image.shape == (48, 16, 3) and (exemplar is a) == (len(scored) % 2 == 0)
        scored.append(image)
        return float(np.abs(image.mean(axis=(0, 1)) - exemplar.mean(axis=(0, 1))).mean())

    row = bench.painted_row(a, b, (48, 64), [0], fit=FIT, score=score, transition=32)
    assert len(scored) == 6 and {f"{w} {s}" for w in bench.PAINTED_WAYS for s in "AB"} <= set(row)
    assert not np.array_equal(scored[0], scored[4]) and not np.array_equal(scored[1], scored[5])  # best refines both
    assert row["maps kept"] and row["normal error"] < 1e-3 and 0 <= row["best band moved"] <= 1
    table = bench.painted_table({"bricks / cells": row})
    assert table.splitlines()[0].startswith("| A / B | unrefined A / B | default A / B | best A / B |")
    assert table.splitlines()[-1].startswith("| mean |")


@pytest.mark.parametrize("flag", ["--albedo-refine", "--painted"])
def test_the_two_tables_runs_crop_score_write_and_print_alike(bench, monkeypatch, capsys, flag):
    """--albedo-refine and --painted: one loop (0.61; two copies before), a row per texture (per pair) of the
    textures cropped to --crop, printed as it is made, then written with the table under its own title."""
    painted = flag == "--painted"
    args = bench.parse_args(["bricks", "cells", flag, "--seeds", "2", "--crop", "40", "--size", "48"])
    monkeypatch.setattr(bench, "texture", lambda name: getattr(data, name)(64))
    got = []

    def row(*given):  # (textures..., size, seeds): their shapes, for the row
        *crops, size, seeds = given
        assert all(c.shape == (40, 40, 3) for c in crops) and size == (48, 48) and seeds == [0, 1]
        return {"score": float(len(crops)) + 0.12345}

    monkeypatch.setattr(bench, "painted_row" if painted else "albedo_refine_row", row)
    monkeypatch.setattr(bench, "painted_table" if painted else "albedo_refine_table", lambda rows: f"| {list(rows)} |")
    monkeypatch.setattr(bench, "write_results", lambda name, payload, md: got.append((name, payload, md)))
    (bench.painted_main if painted else bench.albedo_refine_main)(args)
    [(name, payload, md)] = got
    key = "pair" if painted else "texture"
    rows = [("bricks / cells", 2.12345)] if painted else [("bricks", 1.12345), ("cells", 1.12345)]
    assert name == ("material_painted" if painted else "material_albedo")
    assert payload == [{key: k, "score": v, "size": 48, "seeds": [0, 1]} for k, v in rows]
    title = ("Painted materials' albedos patch-refined (0.60): each region's albedo SIFID against its own 40x40 "
             "crop, A left and B right of 48x48" if painted else
             "The material albedo's patch refinement (0.59): albedo SIFID against the 40x40 crop, 48x48")
    assert md == f"{title}, seeds 0-1, means (benchmarks/bench_material.py {flag})\n\n| {[k for k, _ in rows]} |"
    out = capsys.readouterr().out
    assert out.startswith("bricks cells {'score': 2.123}\n" if painted else
                          "bricks {'score': 1.123}\ncells {'score': 1.123}\n") and out.endswith(md + "\n")
