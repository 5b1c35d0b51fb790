"""Thread counts of a fit (issue #26): one BLAS / OpenMP thread inside TGHop.fit, ICA
clusters on the idle cores, and the model the same bit for bit whatever the counts."""

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from tghop import _common, core, data
from tghop.synthesis import TGHop

from conftest import SMALL


def _arrays(model):
    return [model.ichm_.means_, model.ichm_.codebook_, model.sdr_.channel_,
            *[np.asarray(m) for m in model.ichm_.mixing_]]


def test_fit_is_the_same_whatever_the_threads(monkeypatch):
    image = data.bricks(64, rng=2)
    seen = []
    fit_cluster = core.ICHM._fit_cluster

    def spy(self, *args, **kwargs):
        # BLAS only: NumPy uses no OpenMP; an OpenMP runtime in the process (PyTorch's, when
        # other tests loaded it) keeps its count per thread and is not used by the fit.
        seen.append({i["internal_api"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})
        return fit_cluster(self, *args, **kwargs)

    monkeypatch.setattr(core.ICHM, "_fit_cluster", spy)
    monkeypatch.setattr(core, "usable_cores", lambda: 1)
    with threadpool_limits(limits=1):
        one = TGHop(**SMALL).fit(image)
    monkeypatch.setattr(core, "usable_cores", lambda: 4)
    with threadpool_limits(limits=2):
        more = TGHop(**SMALL).fit(image)
        assert {i["num_threads"] for i in threadpool_info()} == {2}  # restored after the fit
    assert seen and all(set(s.values()) == {1} for s in seen)  # one thread inside the fit
    for a, b in zip(_arrays(one), _arrays(more)):
        np.testing.assert_array_equal(a, b)


def test_usable_cores_is_the_affinity_mask(monkeypatch):
    import os

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2, 3}, raising=False)
    assert _common.usable_cores() == 4
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(), raising=False)
    assert _common.usable_cores() == 1  # never 0
