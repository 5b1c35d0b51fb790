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
