"""The steps against soft output: the residual Gaussian of the core model, the quilting
choice that does not favour smooth patches, and the pool's flattest patches passed over."""

import numpy as np
import pytest

from tghop import TGHop
from tghop._errors import TGHopError
from tghop.core import ICHM
from tghop.modelfile import load_model, save_model
from tghop.inpaint import inpaint
from tghop.guided import synthesize_guided
from tghop.quilting import FLAT_PENALTY, flat_factors, quilt
from tghop.settings import BY_NAME, PAPER
from tghop.synthesis import PAPER_TABLE4

from conftest import SMALL


def _gradient_energy(x):
    x = np.asarray(x, dtype=np.float64)
    return float(np.square(np.diff(x, axis=-3)).mean() + np.square(np.diff(x, axis=-2)).mean())


# ----------------------------------------------------------------------------- residual


@pytest.fixture(scope="module")
def residual_fit():
    rng = np.random.default_rng(0)
    # Two clusters of 6-dimensional data; the per-cluster PCA keeps 2 components.
    centres = np.array([[5.0] * 6, [-5.0] * 6])
    z = centres[rng.integers(0, 2, 2000)] + rng.standard_normal((2000, 6)) * np.array([3, 2, 1, 1, 0.5, 0.5])
    groups = np.array([0, 0, 0, 1, 1, 1])
    model = ICHM(n_clusters=2, n_codewords=4, max_cluster_components=2, residual=True, rng=0)
    return model.fit(z, groups=groups), z, groups


def test_residual_gaussian_has_the_covariance_of_what_the_pca_drops(residual_fit):
    model, z, groups = residual_fit
    assert model.residual_factor_.shape == (9 + 9,) and np.array_equal(model.residual_group_, groups)
    draws = model.sample_residual(40000, rng=1)
    assert draws.shape == (40000, 6)
    cov = np.cov(draws.T)
    assert abs(cov[0, 4]) < 0.05 and abs(cov[2, 3]) < 0.05  # groups are independent
    # Total residual variance: what 2 of 6 components per cluster leave out.
    assert 0.3 * z.var(axis=0).sum() > np.trace(cov) > 1.0
    # The factors reproduce the draws' covariance within each group.
    f0 = model.residual_factor_[:9].reshape(3, 3)
    np.testing.assert_allclose(cov[:3, :3], f0 @ f0.T, atol=0.05)


def test_residual_off_is_empty_and_the_mixture_unchanged(residual_fit):
    _, z, groups = residual_fit
    kw = dict(n_clusters=2, n_codewords=4, max_cluster_components=2, rng=0)
    off = ICHM(**kw).fit(z, groups=groups)
    on = ICHM(**kw, residual=True).fit(z, groups=groups)
    assert off.residual_factor_.size == 0 and not off.sample_residual(5, rng=0).any()
    np.testing.assert_array_equal(off.mixing_, on.mixing_)
    for a, b in zip(off.sample(50, rng=3), on.sample(50, rng=3)):  # (Z, labels)
        np.testing.assert_array_equal(a, b)


def test_residual_restores_gradient_energy(bricks96):
    # Few components per cluster: the PCA drops much of the fine grain.
    few = dict(SMALL, max_cluster_components=10)
    n = 600
    with_residual = _gradient_energy(TGHop(**few, residual=True).fit(bricks96).sample_patches(n, rng=0))
    without = _gradient_energy(TGHop(**few, residual=False).fit(bricks96).sample_patches(n, rng=0))
    exemplar = _gradient_energy(bricks96[None])
    assert with_residual > 1.1 * without
    assert with_residual < 1.5 * exemplar


@pytest.fixture(scope="module")
def residual_model(bricks96):
    return TGHop(**SMALL, residual=True).fit(bricks96)


def test_sample_vectors_takes_an_int_seed_as_its_generator(residual_model):
    # An int seed was given to the sources' draw and again to the residual's, each restarting default_rng(seed): the
    # residual's normals were the sources' first numbers (and the vectors differed from those of default_rng(seed)).
    for dtype in (np.float32, np.float64):
        by_int = residual_model.sample_vectors(9, 4, dtype)
        by_generator = residual_model.sample_vectors(9, np.random.default_rng(4), dtype)
        assert all(np.array_equal(a, b) for a, b in zip(by_int, by_generator))


def test_residual_same_seed_same_patches_and_survives_save_load(residual_model, tmp_path):
    n = residual_model.ichm_.n_cdfs_ + 7  # the folded path
    a = residual_model.sample_patches(n, rng=5, dtype=np.float32)
    assert np.array_equal(a, residual_model.sample_patches(n, rng=5, dtype=np.float32))
    path = tmp_path / "m.npz"
    save_model(residual_model, path)
    loaded = load_model(path)
    assert loaded.ichm_.residual_factor_.size > 0
    assert np.array_equal(loaded.sample_patches(n, rng=5, dtype=np.float32), a)


def test_paper_mode_has_no_residual():
    assert PAPER_TABLE4["residual"] is False
    assert TGHop().residual is False  # on top of the refinement it adds noise (docs/choices.md)


# ----------------------------------------------------------------------------- quilting


def _mixed_pool(n=400, p=12, seed=0):
    """Half flat grey patches (they match any overlap best), half grey noise."""
    rng = np.random.default_rng(seed)
    flat = np.full((n // 2, p, p, 1), 0.5)
    noisy = np.clip(0.5 + 0.15 * rng.standard_normal((n // 2, p, p, 1)), 0, 1)
    return np.concatenate([flat, noisy]).astype(np.float32)


def test_detail_zero_is_the_classic_choice():
    pool = _mixed_pool()
    a = quilt(pool, (40, 40), rng=2)
    b = quilt(pool, (40, 40), rng=2, detail=0.0)
    assert np.array_equal(a, b)


def test_detail_prefers_patches_with_gradient_energy():
    pool = _mixed_pool()
    smooth = quilt(pool, (60, 60), tolerance=2.0, rng=0)
    sharp = quilt(pool, (60, 60), tolerance=2.0, detail=0.5, rng=0)
    assert _gradient_energy(sharp) > 2 * _gradient_energy(smooth)
    assert np.array_equal(sharp, quilt(pool, (60, 60), tolerance=2.0, detail=0.5, rng=0))


@pytest.mark.parametrize("detail", [-0.1, 1.0, True, "high", float("nan")])
def test_bad_detail(detail):
    with pytest.raises(TGHopError, match="detail"):
        quilt(_mixed_pool(20), (20, 20), detail=detail)


# ----------------------------------------------------------------------------- flat_share


def test_flat_factors_mark_the_least_energy_share():
    energy = np.arange(100, dtype=np.float32)[::-1]
    factors = flat_factors(energy, 0.25)
    assert factors.dtype == np.float32
    assert np.array_equal(np.flatnonzero(factors == FLAT_PENALTY), np.arange(75, 100)) and (factors[:75] == 1).all()


def test_flat_share_places_textured_patches_where_only_flat_ones_were_near_best():
    # Flat patches of 0.6 match an overlap of noise (0.5, sd 0.15) with an error of 0.01 +
    # 0.0225 per value, noisy ones with 0.045: within a tolerance of 0.1 only the flat ones
    # qualify, and the detail preference cannot help. Counted FLAT_PENALTY (>= 1.5) times,
    # they lose.
    assert FLAT_PENALTY >= 1.5
    pool = _mixed_pool()
    pool[: len(pool) // 2] = 0.6
    plain = quilt(pool, (60, 60), rng=0, detail=0.5)
    flat_passed = quilt(pool, (60, 60), rng=0, detail=0.5, flat_share=0.5)
    assert _gradient_energy(flat_passed) > 2 * _gradient_energy(plain)
    assert np.array_equal(flat_passed, quilt(pool, (60, 60), rng=0, detail=0.5, flat_share=0.5))
    assert np.array_equal(plain, quilt(pool, (60, 60), rng=0, detail=0.5, flat_share=0.0))


@pytest.mark.parametrize("share", [-0.1, 1.0, True, "high", float("nan")])
def test_bad_flat_share(share, small_model):
    with pytest.raises(TGHopError, match="flat_share"):
        quilt(_mixed_pool(20), (20, 20), flat_share=share)
    with pytest.raises(TGHopError, match="flat_share"):
        small_model.synthesize((40, 40), flat_share=share)


def test_flat_share_reaches_every_quilt_and_is_off_in_paper_mode(small_model, bricks96):
    assert PAPER["flat_share"] == 0.0
    assert FLAT_PENALTY == 2.0 and "twice" in BY_NAME["flat_share"].help  # the option's help says the factor
    size = (64, 64)
    image = small_model.synthesize(size, rng=1, patch_refine=0)
    assert not np.array_equal(image, small_model.synthesize(size, rng=1, patch_refine=0, flat_share=0.0))
    assert np.array_equal(image, small_model.synthesize(size, rng=1, patch_refine=0))
    hole = np.zeros(bricks96.shape[:2], dtype=bool)
    hole[20:70, 20:70] = True
    filled = inpaint(small_model, bricks96, hole, rng=1, patch_refine=0)
    assert not np.array_equal(filled, inpaint(small_model, bricks96, hole, rng=1, patch_refine=0, flat_share=0.0))
    painted = synthesize_guided([small_model, small_model], size=size, rng=1)
    assert not np.array_equal(painted, synthesize_guided([small_model, small_model], size=size, rng=1, flat_share=0))


def test_flat_share_zero_passes_over_nothing_in_any_quilt(small_model, bricks96, monkeypatch):
    # 0 switches the step off everywhere, the coarse layout's guide and coarse fill included
    # (their quilts are the coarse model's own, whose default is on).
    import tghop.inpaint
    import tghop.quilting

    calls = []

    def recorded(energy, share, **kw):
        calls.append(len(energy))
        return flat_factors(energy, share, **kw)

    monkeypatch.setattr(tghop.quilting, "flat_factors", recorded)
    monkeypatch.setattr(tghop.inpaint, "flat_factors", recorded)
    assert small_model.layout_ is not None
    hole = np.zeros(bricks96.shape[:2], dtype=bool)
    hole[20:70, 20:70] = True
    small_model.synthesize((64, 64), rng=1, patch_refine=0, flat_share=0.0)
    inpaint(small_model, bricks96, hole, rng=1, patch_refine=0, flat_share=0.0)
    synthesize_guided([small_model, small_model], size=(64, 64), rng=1, flat_share=0.0)
    assert calls == []
    small_model.synthesize((64, 64), rng=1, patch_refine=0)
    assert len(calls) == 2  # the fine pool's and the coarse guide's
    inpaint(small_model, bricks96, hole, rng=1, patch_refine=0)
    assert len(calls) == 4  # the fill's and the coarse fill's
