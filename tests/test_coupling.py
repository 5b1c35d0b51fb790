"""Coupled draws of the core model's components (tghop.coupling, ICHM's ``coupling``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from tghop import TGHopError
from tghop.core import ICHM
from tghop.coupling import RANK_LEVELS, coupled_uniforms, member_ranks, normal_cdf, normal_ppf


def test_normal_cdf_and_its_inverse():
    z = np.random.default_rng(0).uniform(-6, 6, 1000)
    exact = np.array([0.5 * math.erfc(-x / math.sqrt(2)) for x in z])
    np.testing.assert_allclose(normal_cdf(z), exact, atol=1e-6)
    u = np.linspace(0.001, 0.999, 999)
    np.testing.assert_allclose(normal_cdf(normal_ppf(u)), u, atol=1e-6)
    assert normal_cdf(np.array([-50.0]))[0] < 1e-15 and normal_cdf(np.array([50.0]))[0] > 1 - 1e-15


def test_member_ranks_are_each_columns_quantised_ranks():
    s = np.array([[3.0, -1.0], [1.0, 5.0], [2.0, 0.0], [0.0, 2.0]])
    r = member_ranks(s)
    assert r.dtype == np.uint8 and r.shape == s.shape
    # ranks 3, 1, 2, 0 and 0, 3, 1, 2 of 4: floor(256 * (rank + 0.5) / 4)
    assert r[:, 0].tolist() == [224, 96, 160, 32] and r[:, 1].tolist() == [32, 224, 96, 160]
    big = member_ranks(np.random.default_rng(1).standard_normal((1000, 3)))
    assert big.min() == 0 and big.max() == RANK_LEVELS - 1


@pytest.mark.parametrize("rho", [0.0, 0.6, 0.95])
def test_coupled_uniforms_are_uniform_and_follow_their_member(rho):
    rng = np.random.default_rng(2)
    ranks = member_ranks(rng.standard_normal((500, 4)))
    u = coupled_uniforms(ranks, rho, 20000, np.random.default_rng(3))
    assert u.shape == (20000, 4) and u.min() >= 0 and u.max() <= 1
    for j in range(4):  # each component's probabilities stay uniform whatever rho is
        assert stats.kstest(u[:, j], "uniform").statistic < 0.02
    # The draws' normal scores correlate with their members' by rho: the same generator
    # picks the same members first.
    members = ranks[np.random.default_rng(3).integers(0, 500, 20000)]
    z_member = normal_ppf((members + 0.5) / RANK_LEVELS)
    r = np.corrcoef(normal_ppf(np.clip(u, 1e-12, 1 - 1e-12)).ravel(), z_member.ravel())[0, 1]
    assert abs(r - rho) < 0.02


def test_coupling_keeps_the_histograms_and_part_of_the_dependence_without_copying(near_sphere):
    z = near_sphere
    kw = dict(n_clusters=1, cluster_energy=1.0, norm_match=0, rng=0)
    off, on = ICHM(**kw, coupling=0.0).fit(z), ICHM(**kw, coupling=0.9).fit(z)
    assert off.member_ranks_.size == 0 and off.member_counts_.size == 0
    assert on.member_counts_.tolist() == [4000] and on.member_ranks_.shape == (4000 * 6,)
    _, (coupled,) = on.sample_sources(20000, rng=1)
    _, (independent,) = on.set_params(coupling=0.0).sample_sources(20000, rng=1)
    on.set_params(coupling=0.9)
    for j in range(6):  # the same fitted histogram either way
        assert stats.ks_2samp(coupled[:, j], independent[:, j]).statistic < 0.03
    spread = {name: np.subtract(*np.quantile(np.linalg.norm(s, axis=1), [0.9, 0.1]))
              for name, s in (("coupled", coupled), ("independent", independent))}
    assert spread["coupled"] < 0.7 * spread["independent"]
    # New vectors: no nearer the training vectors than those are to each other.
    x, _ = on.sample(1000, rng=2)
    nearest = np.sqrt(((x[:, None] - z[None]) ** 2).sum(-1)).min(axis=1)
    own = np.sqrt(((z[:1000, None] - z[None]) ** 2).sum(-1))
    own[np.arange(1000), np.arange(1000)] = np.inf
    assert np.median(nearest) > 0.9 * np.median(own.min(axis=1))


def test_coupling_zero_draws_as_before_and_bad_values_are_refused(near_sphere):
    z = near_sphere
    kw = dict(n_clusters=1, cluster_energy=1.0, norm_match=0, rng=0)
    a = ICHM(**kw, coupling=0.0).fit(z)
    b = ICHM(**kw, coupling=0.9).fit(z).set_params(coupling=0.0)
    # The ranks take nothing from the fit's random stream: with the setting off afterwards,
    # the model draws what a model fitted without it draws (norm matching off: its
    # simulated norms are the coupled draws').
    np.testing.assert_array_equal(a.sample(500, rng=4)[0], b.sample(500, rng=4)[0])
    for bad in (-0.1, 1.0, "high"):
        with pytest.raises(TGHopError, match="coupling"):
            ICHM(**kw, coupling=bad).fit(z)


def test_coupled_uniforms_take_any_rng_and_check_their_arguments():
    ranks = member_ranks(np.random.default_rng(5).standard_normal((50, 3)))
    # An int seed gives the same draws every time, as the Generator it seeds; None fresh ones.
    seeded = coupled_uniforms(ranks, 0.5, 10, 7)
    np.testing.assert_array_equal(seeded, coupled_uniforms(ranks, 0.5, 10, 7))
    np.testing.assert_array_equal(seeded, coupled_uniforms(ranks, 0.5, 10, np.random.default_rng(7)))
    assert coupled_uniforms(ranks, 0.5, 10, None).shape == (10, 3)
    assert coupled_uniforms(ranks, 0.0, 0, 0).shape == (0, 3)
    for rho in (1.5, -0.5, 1.0, float("nan"), "a", None):
        with pytest.raises(TGHopError, match=r"^rho must be a number in \[0, 1\), got"):
            coupled_uniforms(ranks, rho, 10, 0)
    for m in (-1, 2.5, "3"):
        with pytest.raises(TGHopError, match=r"^m must be an integer >= 0, got"):
            coupled_uniforms(ranks, 0.5, m, 0)
    with pytest.raises(TGHopError, match=r"^ranks must be a 2-D .* at least one member, got shape \(0, 3\)$"):
        coupled_uniforms(ranks[:0], 0.5, 10, 0)
    with pytest.raises(TGHopError, match=r"^rng must be None, an int seed"):
        coupled_uniforms(ranks, 0.5, 10, "seed")
    with pytest.raises(TGHopError, match=r"^sources must be a 2-D \(members, components\) array, got shape \(50,\)$"):
        member_ranks(np.zeros(50))


def test_normal_cdf_of_nan_is_nan_as_documented():
    assert np.isnan(normal_cdf(np.nan))
    out = normal_cdf(np.array([[np.nan, 0.0], [-np.inf, np.inf]]))
    assert out.shape == (2, 2) and np.isnan(out[0, 0]) and out[0, 1] == 0.5
    assert out[1, 0] < 1e-15 and out[1, 1] > 1 - 1e-15
    assert np.isnan(normal_ppf(np.nan))
