"""The co-occurrence statistics (tghop.cooccurrence) and cGAN (tghop.cooc) of Darzi et al., on tiny inputs."""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from tghop import cooc, cooccurrence, data
from tghop.cooc import assembly, networks
from tghop._errors import MissingExtraError, ModelFileError, NotFittedError, TGHopError

from conftest import TINY_COOC, assert_user_error

torch = pytest.importorskip("torch")

TINY = TINY_COOC


@pytest.fixture(scope="module", autouse=True)
def _threads(one_torch_thread):
    yield


@pytest.fixture(scope="module")
def exemplar():
    return data.bricks(48, rng=3)


@pytest.fixture(scope="module")
def tiny_model(exemplar):
    return cooc.CoocGAN(**TINY, device="cpu", rng=0).fit(exemplar)


def clusters(img, k=3):
    c, s = cooccurrence.fit_colour_clusters(img, n_clusters=k, seed=0)
    return c, s


# ------------------------------------------------------------------ statistics
def direct_tensor(img, centres, spreads, patch, window, sigma, s):
    """Eq. 1-2 by loops: per pixel p, pairs (p', q) with p' in the patch around p and q in
    the window around p' (both inside the image); symmetrised, normalised, pooled by s."""
    h, w, _ = img.shape
    k = len(centres)
    assign = np.exp(-(((img[:, :, None, :] - centres) / spreads) ** 2).sum(-1)) + 1e-6  # (H, W, k)
    rp, rw = patch // 2, window // 2
    per_pixel = np.zeros((h, w, k, k))
    for y in range(h):
        for x in range(w):
            m = np.zeros((k, k))
            for y1 in range(max(0, y - rp), min(h, y + rp + 1)):
                for x1 in range(max(0, x - rp), min(w, x + rp + 1)):
                    for y2 in range(max(0, y1 - rw), min(h, y1 + rw + 1)):
                        for x2 in range(max(0, x1 - rw), min(w, x1 + rw + 1)):
                            g = math.exp(-((y1 - y2) ** 2 + (x1 - x2) ** 2) / (2 * sigma * sigma))
                            m += g * np.outer(assign[y1, x1], assign[y2, x2])
            m = 0.5 * (m + m.T)
            per_pixel[y, x] = m / m.sum()
    hh, ww = h // s, w // s
    pooled = per_pixel[: hh * s, : ww * s].reshape(hh, s, ww, s, k * k).mean((1, 3))
    return pooled.transpose(2, 0, 1)


def test_tensor_matches_direct_loops_in_numpy_and_torch(monkeypatch):
    img = data.bricks(32, rng=4)[5:15, 3:15]
    c, s = clusters(img)
    expected = direct_tensor(img, c, s, patch=5, window=3, sigma=1.5, s=4)
    x = img.transpose(2, 0, 1)[None]
    got_np = cooccurrence.cooccurrence_tensor(x, c, s, patch=5, window=3, sigma=1.5, s=4)[0]
    xt, ct, st = (torch.as_tensor(a, dtype=torch.float64) for a in (x, c, s))
    got_t = cooccurrence.cooccurrence_tensor(xt, ct, st, patch=5, window=3, sigma=1.5, s=4)[0].numpy()
    assert got_np.shape == (9, 2, 3)
    np.testing.assert_allclose(got_np, expected, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got_t, expected, rtol=1e-9, atol=1e-12)
    # The per-pixel path (large images) gives the same numbers as the per-cell weights.
    monkeypatch.setattr(cooccurrence, "_MAX_CELL_WEIGHTS", 0)
    got_np2 = cooccurrence.cooccurrence_tensor(x, c, s, patch=5, window=3, sigma=1.5, s=4)[0]
    np.testing.assert_allclose(got_np2, expected, rtol=1e-9, atol=1e-12)
    got_t2 = cooccurrence.cooccurrence_tensor(xt, ct, st, patch=5, window=3, sigma=1.5, s=4)[0].numpy()
    np.testing.assert_allclose(got_t2, expected, rtol=1e-9, atol=1e-12)


def test_matrix_matches_direct_loops_sums_to_one_and_is_symmetric():
    img = data.bricks(32, rng=5)[:10, :10]
    c, s = clusters(img)
    m = cooccurrence.cooccurrence_matrix(img.transpose(2, 0, 1)[None], c, s, sigma=1.2, window=5)[0]
    assign = np.exp(-(((img[:, :, None, :] - c) / s) ** 2).sum(-1))
    expected = np.zeros_like(m)
    for y in range(10):
        for x in range(10):
            for y2 in range(max(0, y - 2), min(10, y + 3)):
                for x2 in range(max(0, x - 2), min(10, x + 3)):
                    g = math.exp(-((y - y2) ** 2 + (x - x2) ** 2) / (2 * 1.2**2))
                    expected += g * np.outer(assign[y, x], assign[y2, x2])
    np.testing.assert_allclose(m, expected / expected.sum(), rtol=1e-9)
    assert m.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(m, m.T, atol=1e-15)
    # Isotropic: the transposed image has the same matrix.
    mt = cooccurrence.cooccurrence_matrix(img.transpose(2, 1, 0)[None], c, s, sigma=1.2, window=5)[0]
    np.testing.assert_allclose(mt, m, rtol=1e-9)


def test_tensor_cells_sum_to_one_and_are_symmetric():
    img = data.bricks(64, rng=6)
    c, s = clusters(img, k=4)
    t = cooccurrence.cooccurrence_tensor(img.transpose(2, 0, 1)[None], c, s, patch=17, window=9, sigma=3.0, s=16)[0]
    assert t.shape == (16, 4, 4)
    np.testing.assert_allclose(t.sum(0), 1.0, rtol=1e-9)
    k = t.reshape(4, 4, 4, 4)
    np.testing.assert_allclose(k, k.transpose(1, 0, 2, 3), atol=1e-15)
    # Different parts of a brick texture have different local statistics.
    assert np.abs(t[:, 0, 0] - t[:, 1, 2]).sum() > 1e-3


def test_tensor_is_differentiable():
    img = torch.rand(2, 3, 16, 16, dtype=torch.float64, requires_grad=True)
    c = torch.rand(3, 3, dtype=torch.float64)
    s = torch.full((3, 3), 0.2, dtype=torch.float64)
    t = cooccurrence.cooccurrence_tensor(img, c, s, patch=5, window=5, sigma=1.0, s=8)
    assert t.shape == (2, 9, 2, 2)
    t[:, 0].sum().backward()
    assert img.grad is not None and torch.isfinite(img.grad).all() and img.grad.abs().sum() > 0


def test_far_colours_give_finite_values_and_gradients():
    """A generated crop with saturated colours far from every cluster (tiny assignments next to
    large ones) once made a patch total cancel to 0 and the training loss NaN."""
    c = torch.tensor([[0.3, 0.4, 0.1], [0.5, 0.6, 0.35]])
    s = torch.full((2, 3), 0.025)
    x = torch.full((2, 3, 64, 64), 0.45)
    x[:, :, :20] = 1.0
    x[:, 0, 50:] = 0.0
    x.requires_grad_(True)
    t = cooccurrence.cooccurrence_tensor(x, c, s, patch=33, window=25, sigma=13**0.5, s=16)
    assert torch.isfinite(t).all() and (t >= 0).all()
    torch.testing.assert_close(t.sum(1), torch.ones(2, 4, 4))
    t[:, 1].sum().backward()
    assert torch.isfinite(x.grad).all()


def test_metric_uses_the_shared_statistics():
    from tghop.metrics import cooccurrence_distance

    a, b = data.bricks(40, rng=1), data.bricks(40, rng=2)
    assert cooccurrence_distance(a, a) == 0.0
    assert 0 < cooccurrence_distance(a, b, n_clusters=3) <= 2


def test_colour_clusters_name_a_bad_count():
    img = data.bricks(48, rng=3)
    with pytest.raises(TGHopError, match=r"^max_fit_pixels must be an integer >= 1, got 0$"):
        cooccurrence.fit_colour_clusters(img, max_fit_pixels=0)
    with pytest.raises(TGHopError, match=r"^max_fit_pixels must be an integer >= 1, got 10.5$"):
        cooccurrence.fit_colour_clusters(img, max_fit_pixels=10.5)
    with pytest.raises(TGHopError, match=r"^n_clusters must be an integer from 1 to 32, got 0$"):
        cooccurrence.fit_colour_clusters(img, n_clusters=0)


def test_paint_condition_places_sources():
    a, b = np.zeros((4, 1, 1)), np.ones((4, 2, 2))
    labels = np.array([[0, 1, 1], [0, 0, 1]])
    out = cooc.paint_condition([a, b], labels)
    assert out.shape == (4, 2, 3)
    np.testing.assert_array_equal(out[0], labels.astype(float))
    with pytest.raises(TGHopError, match="labels"):
        cooc.paint_condition([a, b], labels + 1)


# ------------------------------------------------------------------ the cGAN
def test_not_fitted_and_bad_settings(exemplar):
    with pytest.raises(NotFittedError):
        cooc.CoocGAN().sample(32)
    with pytest.raises(TGHopError, match="multiple of"):
        cooc.CoocGAN(**{**TINY, "crop_size": 30}).fit(exemplar)
    with pytest.raises(TGHopError, match="crop_size"):
        cooc.CoocGAN(**{**TINY, "crop_size": 64}).fit(exemplar)


def test_scikit_learn_clone_repr_and_params_work_on_the_cgan(tiny_model):
    # CoocGAN had its own get_params without ``deep``: sklearn.base.clone was a TypeError, and its repr the object's.
    sklearn = pytest.importorskip("sklearn")
    import sklearn.base  # noqa: F401

    model = cooc.CoocGAN(n_clusters=3, g_widths=(8, 4), rng=2)
    assert repr(model) == "CoocGAN(g_widths=(8, 4), n_clusters=3, rng=2)"
    copy = sklearn.base.clone(model)
    assert copy is not model and copy.get_params(deep=False) == model.get_params(deep=False) == model.get_params()
    fresh = sklearn.base.clone(tiny_model)
    assert fresh.get_params() == tiny_model.get_params() and not hasattr(fresh, "generator_")
    assert model.set_params(n_steps=4) is model and model.n_steps == 4
    with pytest.raises(TGHopError, match=r"^invalid parameter 'steps' for CoocGAN; valid: "):
        model.set_params(steps=4)


def test_condition_for_and_noise_take_a_size_as_sample_does(tiny_model):
    # condition_for((0, 10)) and ((-8, 16)) gave empty tensors, (16.7, 16) was cut to 16, 64 was Python's "'int' object
    # is not iterable" and ("a", 3) int()'s ValueError; noise(4) the same TypeError.
    k2, s = len(tiny_model.cond_mean_), tiny_model.s
    assert tiny_model.condition_for(64, rng=0).shape == tiny_model.condition_for((64, 64), rng=0).shape \
        == (k2, 64 // s, 64 // s)
    np.testing.assert_array_equal(tiny_model.condition_for(64, rng=0), tiny_model.condition_for((64, 64), rng=0))
    assert tiny_model.noise(4, rng=0).shape == tiny_model.noise((4, 4), rng=0).shape
    for size in [(0, 10), (-8, 16), (16.7, 16), ("a", 3), (2**14, 2**14)]:
        with pytest.raises(TGHopError, match=r"^size "):
            tiny_model.condition_for(size, rng=0)
    with pytest.raises(TGHopError, match=r"^the noise's shape must be two integers"):
        tiny_model.noise((4.5, 4), rng=0)


def test_fit_leaves_torch_global_generator_as_it_was(exemplar):
    # The fit seeded torch's global generator (torch.manual_seed) to draw the networks' initial weights: after it the
    # caller's torch.rand gave the fit seed's numbers, not those of the caller's own seed.
    torch = pytest.importorskip("torch")
    torch.manual_seed(1234)
    state = torch.get_rng_state()
    a = cooc.CoocGAN(**{**TINY, "n_steps": 0}, device="cpu", rng=0).fit(exemplar)
    assert torch.equal(torch.get_rng_state(), state)
    torch.manual_seed(99)  # the weights do not depend on the global generator's state either
    b = cooc.CoocGAN(**{**TINY, "n_steps": 0}, device="cpu", rng=0).fit(exemplar)
    assert all(torch.equal(x, y) for x, y in zip(a.generator_.state_dict().values(),
                                                 b.generator_.state_dict().values()))


@pytest.mark.parametrize("name, value, words", [
    ("crop_size", 32.5, "crop_size must be an integer, got 32.5"),  # was trained at 32
    ("batch_size", 2.5, "batch_size must be an integer, got 2.5"),
    ("n_steps", True, "n_steps must be an integer, got True"),  # a bool is not an integer
    ("n_clusters", "3", "n_clusters must be an integer"),
    ("g_widths", [8, 4.5], "g_widths entry must be an integer, got 4.5"),
    ("g_widths", 8, "g_widths must be a sequence of integers"),
    ("d_widths", [0, 8], "d_widths entries must be positive"),
    ("lr", True, "lr must be a number, got True"),
    ("context", "no", "context must be True or False"),
    ("tiles", 0, "tiles must be positive, got 0"),
    ("n_steps", -1, "n_steps must be 0 or more, got -1"),
    ("n_steps", 10**11, "n_steps must be at most 150,000, got 100,000,000,000"),  # trained for ever
])
def test_settings_of_the_wrong_kind_are_refused_by_name(exemplar, monkeypatch, name, value, words):
    monkeypatch.setattr(cooc.CoocGAN, "_build", lambda *a: pytest.fail("training started"))
    with pytest.raises(TGHopError) as error:
        cooc.CoocGAN(**{**TINY, name: value}).fit(exemplar)
    assert words in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize("value", [float("nan"), 0, -1.0, "5"])
def test_max_seconds_not_above_zero_is_refused_before_training(exemplar, monkeypatch, value):
    # NaN never compared as "time is up": the training ran its whole n_steps.
    monkeypatch.setattr(cooc.CoocGAN, "_build", lambda *a: pytest.fail("training started"))
    with pytest.raises(TGHopError, match="max_seconds must be a number of seconds above 0, or None"):
        cooc.CoocGAN(**TINY).fit(exemplar, max_seconds=value)


def test_numpy_values_are_settings_and_whole_floats_are_not_integers():
    from tghop.cooc.config import check_settings

    base = {**TINY, **{k: v for k, v in cooc.SMALL.items() if k not in TINY}}
    # A float where an integer belongs is refused, 32.0 too, as TGHop's settings refuse 2.0 (0.35 took it).
    with pytest.raises(TGHopError, match=r"^crop_size must be an integer, got 32\.0; write 32$"):
        check_settings({**base, "crop_size": 32.0})
    p = check_settings({**base, "crop_size": np.int32(32), "batch_size": np.int64(4), "g_widths": np.array([8, 4]),
                        "context": np.bool_(True), "lr": np.float32(0.5)})
    assert p["crop_size"] == 32 and type(p["crop_size"]) is int and type(p["batch_size"]) is int
    assert p["g_widths"] == [8, 4] and all(type(v) is int for v in p["g_widths"]) and p["context"] is True
    json.dumps(p)  # plain JSON values, as a checkpoint stores them


def test_generator_is_fully_convolutional(tiny_model):
    s = tiny_model.s
    assert s == 8
    cond = tiny_model.crop_condition(0, 0)
    assert cond.shape == (9, 4, 4)
    for h, w in [(1, 1), (3, 5), (6, 2)]:
        out = tiny_model.generate(assembly.tile(cond, h, w), rng=0)
        assert out.shape == (h * s, w * s, 3)
        assert out.min() >= 0 and out.max() <= 1
    assert tiny_model.sample((50, 37), rng=1).shape == (50, 37, 3)


def test_generation_is_seeded_and_noise_matters(tiny_model):
    cond = tiny_model.crop_condition(8, 8)
    a, b = tiny_model.generate(cond, rng=3), tiny_model.generate(cond, rng=3)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, tiny_model.generate(cond, rng=4))


def test_crop_pool_generates_from_exemplar_crops(tiny_model, monkeypatch):
    stages = []
    pool = tiny_model.crop_pool(10, rng=0, batch=4, progress=lambda *a: stages.append(a))
    assert stages == [("generate", 4, 10), ("generate", 8, 10), ("generate", 10, 10)]
    assert pool.shape == (10, 32, 32, 3) and pool.dtype == np.float32
    assert pool.min() >= 0 and pool.max() <= 1
    np.testing.assert_array_equal(pool, tiny_model.crop_pool(10, rng=0, batch=4))  # seeded
    # Another batch size: the same crops (up to the convolutions' round-off, which may depend on the batch).
    np.testing.assert_allclose(pool, tiny_model.crop_pool(10, rng=0), atol=1e-5)
    assert not np.array_equal(pool, tiny_model.crop_pool(10, rng=1))
    # Every condition the generator sees is a training-size exemplar crop's tensor, each cell a distribution.
    crops = [tiny_model._check_cond(tiny_model.crop_condition(y, x)) for y in (0, 8, 16) for x in (0, 8, 16)]
    seen = []
    run = cooc.CoocGAN._run_generator
    monkeypatch.setattr(cooc.CoocGAN, "_run_generator",
                        lambda self, torch_, conds, noise: seen.append(conds) or run(self, torch_, conds, noise))
    tiny_model.crop_pool(30, rng=2)
    conds = np.concatenate(seen)
    assert conds.shape == (30, 9, 4, 4)
    for c in conds:
        assert min(np.abs(c - crop).max() for crop in crops) < 1e-12
    assert len({np.argmin([np.abs(c - crop).max() for crop in crops]) for c in conds}) > 3  # many positions
    with pytest.raises(TGHopError, match=r"^n must be an integer >= 1, got 0$"):
        tiny_model.crop_pool(0)


def test_quilted_sample_is_seeded_and_assemblies_differ(tiny_model, exemplar):
    a = tiny_model.sample((50, 37), rng=5)
    assert a.shape == (50, 37, 3) and a.dtype == np.float64 and a.min() >= 0 and a.max() <= 1
    np.testing.assert_array_equal(a, tiny_model.sample((50, 37), rng=5))
    assert not np.array_equal(a, tiny_model.sample((50, 37), rng=6))
    assert not np.array_equal(a, tiny_model.sample((50, 37), rng=5, assembly="pass"))
    # The default is the quilted assembly; the baseline passes its choice on.
    np.testing.assert_array_equal(a, tiny_model.sample((50, 37), rng=5, assembly="quilt"))
    np.testing.assert_array_equal(cooc.baseline(exemplar, (50, 37), rng=5, model=tiny_model, assembly="pass"),
                                  tiny_model.sample((50, 37), rng=5, assembly="pass"))
    with pytest.raises(TGHopError, match="assembly must be one of quilt, pass, windows"):
        tiny_model.sample(32, assembly="whole")


def test_baseline_with_a_model_takes_only_its_exemplar(tiny_model, exemplar):
    from tghop import baselines

    other = data.bricks(48, rng=9)
    for make in (cooc.baseline, baselines.cooc):
        with pytest.raises(TGHopError) as error:  # it made the model's texture, whatever the exemplar
            make(other, 32, rng=0, model=tiny_model)
        assert str(error.value) == ("the cooc baseline: this exemplar is not the one the model was trained on; "
                                    "give the same image, or as model (--model) a checkpoint trained on this exemplar")
        with pytest.raises(TGHopError, match="not the one"):  # the same pixels in another shape
            make(exemplar.reshape(96, 24, 3), 32, rng=0, model=tiny_model)
        with pytest.raises(TGHopError, match=r"n_steps \(--iterations\) trains the baseline's own model"):
            make(exemplar, 32, rng=0, model=tiny_model, n_steps=5)  # was ignored
        with pytest.raises(TGHopError, match="model must be a trained CoocGAN .*got str"):
            make(exemplar, 32, rng=0, model="m.pt")
    assert baselines.cooc(exemplar, 32, rng=0, model=tiny_model).shape == (32, 32, 3)


@pytest.mark.parametrize("cells, pool", [(4, 1000), (8, 1000), (16, 250), (64, 100)])
def test_quilted_pool_is_about_4_mpx_of_crops(tiny_model, monkeypatch, cells, pool):
    asked = []

    def fake_pool(self, n, *, rng=None, batch=64, progress=None):
        asked.append(n)  # the count asked is what is checked: quilting draws from a few crops of the size
        return np.full((min(n, 4), cells * 8, cells * 8, 3), 0.5, dtype=np.float32)

    monkeypatch.setattr(cooc.CoocGAN, "_window_cells", property(lambda self: cells))
    monkeypatch.setattr(cooc.CoocGAN, "crop_pool", fake_pool)
    assert tiny_model.sample((40, 40), rng=0).shape == (40, 40, 3)
    assert asked == [pool]  # s = 8: crops of 32, 64, 128 and 512 px
    with pytest.raises(TGHopError, match="assembly"):  # at once, before any training
        cooc.baseline(exemplar, 32, assembly="tiles")


class _PointwiseGenerator(torch.nn.Module):
    """A stand-in generator without any spatial context: each cell's output depends only on
    that cell's condition and noise, so windows agree wherever they overlap."""

    def __init__(self, s):
        super().__init__()
        self.s = s

    def forward(self, cond, noise):
        x = torch.tanh(noise[:, [0, 1, 0]] * 0.5 + cond[:, :3] * 0.1)
        return torch.nn.functional.interpolate(x, scale_factor=self.s, mode="nearest")


def test_windowed_generation_sizes_seeds_and_one_window(tiny_model):
    s, n = tiny_model.s, tiny_model._window_cells
    assert n == 4
    cond = tiny_model.crop_condition(0, 0)
    for h, w in [(5, 9), (4, 7), (9, 3), (12, 12)]:
        big = assembly.tile(cond, h, w)
        out = tiny_model.generate(big, rng=0, windows=True)
        assert out.shape == (h * s, w * s, 3) and out.min() >= 0 and out.max() <= 1
        np.testing.assert_array_equal(out, tiny_model.generate(big, rng=0, windows=True))
        assert not np.array_equal(out, tiny_model.generate(big, rng=1, windows=True))
        assert not np.array_equal(out, tiny_model.generate(big, rng=0))
    assert tiny_model.sample((70, 45), rng=2, assembly="windows").shape == (70, 45, 3)
    # Up to the training size: one window, exactly the plain (whole) generation.
    for shape in [(4, 4), (2, 3)]:
        small = cond[:, : shape[0], : shape[1]]
        z = tiny_model.noise(shape, rng=0)
        np.testing.assert_array_equal(tiny_model.generate(small, noise=z, windows=True),
                                      tiny_model.generate(small, noise=z))
        np.testing.assert_array_equal(tiny_model.generate(small, rng=3, windows=True),
                                      tiny_model.generate(small, rng=3))
    with pytest.raises(TGHopError, match="feather"):
        tiny_model.generate(assembly.tile(cond, 8, 8), rng=0, windows=True, feather=17)


def test_windows_blend_into_one_image(tiny_model, monkeypatch):
    # With a generator that has no spatial context every window agrees with the others
    # where they overlap: the blend weights sum to one, so windows == one whole pass.
    tiny_model = tiny_model.raw()  # generates with generator_, not the average
    monkeypatch.setattr(tiny_model, "generator_", _PointwiseGenerator(tiny_model.s))
    cond = assembly.tile(tiny_model.crop_condition(0, 0), 11, 6)
    z = tiny_model.noise(cond.shape[1:], rng=4)
    whole = tiny_model.generate(cond, noise=z)
    for feather in (0, 5, 16):
        np.testing.assert_allclose(tiny_model.generate(cond, noise=z, windows=True, feather=feather), whole, atol=1e-12)
    np.testing.assert_allclose(tiny_model.generate_batch(np.stack([cond] * 2), np.stack([z] * 2), windows=True),
                               np.stack([whole] * 2), atol=1e-12)


def test_blend_weights_are_a_continuous_partition_of_unity():
    n, stride, s = 4, 2, 8
    starts, (before, after), size = assembly.window_layout(13, n, stride)
    assert size == n and before == 1 and starts == list(range(0, 14, 2))
    assert starts[-1] + n == before + 13 + after  # the last window ends at the padded edge
    for feather in (0, 7, 16):
        w = assembly.blend_weights(n * s, before * s, (before + stride) * s, feather, True)
        total = np.zeros((before + 13 + after) * s)
        for t in starts:
            total[t * s : (t + n) * s] += w
        core = total[before * s + s : (before + 13) * s - s]  # away from the image's two ends
        np.testing.assert_allclose(core, 1.0, atol=1e-12)
        if feather:  # raised-cosine ramps: no step larger than pi / (2 feather)
            assert np.abs(np.diff(w)).max() <= np.pi / (2 * feather) + 1e-12
    assert assembly.window_layout(3, n, stride) == ([0], (0, 0), 3)


def test_tiled_training(exemplar):
    x = torch.arange(2 * 4 * 3 * 6 * 4, dtype=torch.float32).reshape(2 * 4, 3, 6, 4)
    joined = networks.join_tiles(x, 2)
    assert joined.shape == (2, 3, 12, 8)
    torch.testing.assert_close(joined[1, :, 6:, :4], x[6])  # crop 1, tile (1, 0)
    torch.testing.assert_close(networks.split_tiles(joined, 2), x)
    with pytest.raises(TGHopError, match="tiles"):
        cooc.CoocGAN(**{**TINY, "tiles": 2}, device="cpu").fit(exemplar)  # 48 px < 2 x 32
    logs = []
    model = cooc.CoocGAN(**{**TINY, "tiles": 2}, device="cpu", rng=0).fit(
        data.bricks(72, rng=3), log=lambda step, losses: logs.append(losses))
    assert len(logs) == 2 and all(np.isfinite(list(v.values())).all() for v in logs)
    assert model._crops.shape == (4 * TINY["n_crops"], 3, 32, 32) and model._window_cells == 8
    real, cond = model._batch(torch)
    assert real.shape == (4, 3, 32, 32) and cond.shape == (1, 9, 8, 8)  # batch 4 = one 2 x 2 crop
    assert model.crop_pool(3, rng=0).shape == (3, 64, 64, 3)  # the quilted assembly's crops: 2 x 2 tiles' size
    assert model.generate(assembly.tile(model.crop_condition(0, 0), 12, 10), rng=0, windows=True).shape == (96, 80, 3)


def test_context_conditions(exemplar):
    """``context``: the generator's and critic's conditions see the pixels around each crop,
    the consistency targets stay the crops' own tensors."""
    plain = cooc.CoocGAN(**TINY, device="cpu", rng=0).fit(exemplar)
    model = cooc.CoocGAN(**{**TINY, "context": True}, device="cpu", rng=0).fit(exemplar)
    assert model._targets is not model._conds and plain._targets is plain._conds
    torch.testing.assert_close(model._targets, plain._conds)  # the same crops, measured alone
    assert model._conds.shape == model._targets.shape == (TINY["n_crops"], 9, 4, 4)
    torch.testing.assert_close(model._conds.sum(1), torch.ones(TINY["n_crops"], 4, 4))
    # Inner cells' patches (radius 4 < s = 8) and pair windows lie inside the crop: the same
    # numbers; the border cells' patches reach outside it: other numbers.
    torch.testing.assert_close(model._conds[:, :, 1:3, 1:3], model._targets[:, :, 1:3, 1:3])
    assert (model._conds[:, :, 0] - model._targets[:, :, 0]).abs().amax() > 1e-3
    # The exemplar's tensor: same cells, its border cells from the mirror-padded exemplar.
    assert model.exemplar_cooc_.shape == plain.exemplar_cooc_.shape == (9, 6, 6)
    np.testing.assert_allclose(model.exemplar_cooc_[:, 1:-1, 1:-1], plain.exemplar_cooc_[:, 1:-1, 1:-1], atol=1e-6)
    assert not np.allclose(model.exemplar_cooc_[:, 0], plain.exemplar_cooc_[:, 0], atol=1e-3)
    real, cond, target = model._batch(torch, targets=True)
    assert cond.shape == target.shape == (4, 9, 4, 4) and not torch.equal(cond, target)
    assert model.sample((40, 24), rng=0).shape == (40, 24, 3)


def test_lazy_penalty_learning_rate_decay_kernel_and_padding(exemplar, tmp_path):
    settings = {**TINY, "n_steps": 4, "gp_every": 2, "lr_decay": 0.5, "kernel": 3, "padding": "replicate"}
    model = cooc.CoocGAN(**settings, device="cpu", rng=0).fit(exemplar)
    h = model.history_
    assert h.shape == (4, 5) and np.isfinite(h).all()
    assert h[0, 4] == h[1, 4] and h[2, 4] == h[3, 4]  # penalties at critic steps 0 and 2 only
    # lr constant for the first half, then down linearly: lr / 2 for the last step.
    assert (model._opt_g.param_groups[0]["lr"] == model._opt_d.param_groups[0]["lr"]
            == pytest.approx(TINY.get("lr", 2e-4) / 2))
    convs = [m for m in model.generator_.modules() if isinstance(m, torch.nn.Conv2d)]
    assert all(c.kernel_size == (3, 3) and c.padding_mode == "replicate" for c in convs)
    assert all(c.kernel_size == (3, 3) and c.padding_mode == "zeros"
               for c in model.critic_.modules() if isinstance(c, torch.nn.Conv2d))
    assert model.generate(assembly.tile(model.crop_condition(0, 0), 3, 5), rng=0).shape == (24, 40, 3)
    # A skipped penalty: no mix, no random number.
    real, cond = model._batch(torch)
    state = model._torch_gen.get_state()
    model._noise(torch, len(cond), cond.shape[2], cond.shape[3])
    after_noise = model._torch_gen.get_state()
    model._torch_gen.set_state(state)
    assert math.isnan(model._critic_step(torch, real, cond, with_gp=False)[1])
    assert torch.equal(model._torch_gen.get_state(), after_noise)
    # The schedule is a function of the step: resuming 2 + 2 steps equals 4 at once.
    half = cooc.CoocGAN(**{**settings, "n_steps": 2}, device="cpu", rng=0).fit(exemplar)
    half.save(tmp_path / "half.pt")
    resumed = cooc.load(tmp_path / "half.pt", device="cpu").set_params(n_steps=4).fit(exemplar, resume=True)
    for p, q in zip(_state(model.generator_).values(), _state(resumed.generator_).values()):
        torch.testing.assert_close(p, q)
    for bad, match in [({"kernel": 4}, "kernel"), ({"padding": "circular"}, "padding"), ({"lr_decay": 1.5}, "lr_decay"),
                       ({"gp_every": 0}, "positive")]:
        with pytest.raises(TGHopError, match=match):
            cooc.CoocGAN(**{**TINY, **bad}).fit(exemplar)


def test_one_step_lowers_the_consistency_loss(exemplar):
    model = cooc.CoocGAN(**{**TINY, "n_steps": 0, "lr": 1e-3}, device="cpu", rng=1).fit(exemplar)
    model.generator_.train()
    cond = model._conds[:4]
    noise = model._noise(torch, 4, cond.shape[2], cond.shape[3])
    with torch.no_grad():
        before = float(model._generator_loss(cond, noise)[2])
    model._generator_step(torch, cond, noise)
    with torch.no_grad():
        after = float(model._generator_loss(cond, noise)[2])
    assert after < before


def _channels_last(p):
    return p.is_contiguous(memory_format=torch.channels_last) and not p.is_contiguous()


def test_training_logs_losses_and_progress(exemplar):
    logs, stages = [], []
    model = cooc.CoocGAN(**TINY, device="cpu", rng=2).fit(
        exemplar, log=lambda step, losses: logs.append((step, losses)), progress=lambda *a: stages.append(a))
    assert [s for s, _ in logs] == [1, 2]
    assert set(logs[0][1]) == {"critic", "adversarial", "consistency", "gp"}
    assert ("training", 2, 2) in stages and any(s[0] == "co-occurrences" for s in stages)
    assert model.history_.shape == (2, 5) and model.step_ == 2
    # Trained channels-last on a CPU; afterwards the generator stays channels-last (faster
    # generation), the critic is back in the default layout, as in a loaded checkpoint.
    assert all(_channels_last(p) for p in model.generator_.parameters() if p.dim() == 4)
    assert all(p.is_contiguous() for p in model.critic_.parameters())


def test_checkpoint_roundtrip_and_resume(tiny_model, exemplar, tmp_path):
    path = tmp_path / "m.pt"
    tiny_model.save(path)
    again = cooc.load(path, device="cpu")
    cond = tiny_model.crop_condition(16, 0)
    np.testing.assert_array_equal(again.generate(cond, rng=5), tiny_model.generate(cond, rng=5))
    assert all(_channels_last(p) for p in again._output_generator.parameters() if p.dim() == 4)  # as after fit
    np.testing.assert_array_equal(again.exemplar_cooc_, tiny_model.exemplar_cooc_)
    # weights_only loading: only tensors inside.
    raw = torch.load(path, weights_only=True)
    assert all(isinstance(v, torch.Tensor) for v in raw.values())
    # Resuming 2 + 2 steps equals training 4 steps at once.
    direct = cooc.CoocGAN(**{**TINY, "n_steps": 4}, device="cpu", rng=0).fit(exemplar)
    resumed = cooc.load(path, device="cpu").set_params(n_steps=4).fit(exemplar, resume=True)
    assert resumed.step_ == 4
    for p, q in zip(direct.generator_.state_dict().values(), resumed.generator_.state_dict().values()):
        torch.testing.assert_close(p, q)
    with pytest.raises(TGHopError, match="resume: this exemplar is not the one the model was trained on"):
        cooc.load(path, device="cpu").fit(data.bricks(48, rng=9), resume=True)


# ------------------------------------------------------------------ generator average (ema)
def _state(module):
    return {k: v.detach().clone().contiguous() for k, v in module.state_dict().items()}


def test_average_is_the_weighted_mean_of_the_steps(exemplar):
    b = 0.9
    seen = []
    model = cooc.CoocGAN(**{**TINY, "ema": b}, device="cpu", rng=4)
    model.fit(exemplar, log=lambda step, losses: seen.append(_state(model.generator_)))
    assert len(seen) == 2
    avg = _state(model.generator_ema_)
    for name, value in avg.items():
        if not (name.endswith("num_batches_tracked") or "running_" in name):
            # weights b^(t-i) normalised: (b theta_1 + theta_2) / (1 + b)
            torch.testing.assert_close(value, (b * seen[0][name] + seen[1][name]) / (1 + b))
    assert not torch.equal(avg["net.1.weight"], seen[1]["net.1.weight"])
    # Batch-norm statistics: recomputed for the averaged weights (train-mode passes over the
    # 12 training tensors in batches of 4), repeatably.
    bn = next(m for m in model.generator_ema_.modules() if isinstance(m, torch.nn.BatchNorm2d))
    inputs = []
    hook = bn.register_forward_hook(lambda module, args, out: inputs.append(args[0].detach().clone()))
    model._recompute_average_statistics(torch)
    hook.remove()
    assert len(inputs) == 3 and int(bn.num_batches_tracked) == 3 and bn.momentum == 0.1
    torch.testing.assert_close(bn.running_mean, torch.stack([x.mean((0, 2, 3)) for x in inputs]).mean(0))
    torch.testing.assert_close(bn.running_var, torch.stack([x.var((0, 2, 3)) for x in inputs]).mean(0))
    for name, value in _state(model.generator_ema_).items():
        torch.testing.assert_close(value, avg[name], rtol=0, atol=0)
    assert not torch.equal(bn.running_mean, model.generator_.state_dict()["net.2.running_mean"])
    # Generation uses the average; raw() the last weights; both channels-last, eval mode.
    cond = model.crop_condition(0, 0)
    assert not np.array_equal(model.generate(cond, rng=1), model.raw().generate(cond, rng=1))
    assert not model.generator_ema_.training
    assert all(_channels_last(p) for p in model.generator_ema_.parameters() if p.dim() == 4)
    assert not any(p.requires_grad for p in model.generator_ema_.parameters())


def test_no_average_is_the_old_training(exemplar):
    plain = cooc.CoocGAN(**{**TINY, "ema": 0}, device="cpu", rng=4).fit(exemplar)
    averaged = cooc.CoocGAN(**{**TINY, "ema": 0.9}, device="cpu", rng=4).fit(exemplar)
    assert not hasattr(plain, "generator_ema_")
    # The average takes no random numbers and does not touch training.
    for p, q in zip(_state(plain.generator_).values(), _state(averaged.generator_).values()):
        torch.testing.assert_close(p, q, rtol=0, atol=0)
    cond = plain.crop_condition(0, 0)
    np.testing.assert_array_equal(plain.generate(cond, rng=1), averaged.raw().generate(cond, rng=1))
    np.testing.assert_array_equal(plain.generate(cond, rng=1), plain.raw().generate(cond, rng=1))
    with pytest.raises(TGHopError, match="ema"):
        cooc.CoocGAN(**{**TINY, "ema": 1.0}).fit(exemplar)
    with pytest.raises(TGHopError, match="ema"):
        cooc.CoocGAN(**{**TINY, "ema": -0.1}).fit(exemplar)
    assert cooc.SMALL["ema"] > 0 and cooc.PAPER["ema"] == 0  # the paper has no average


def test_average_checkpoint_roundtrip_resume_and_old_files(exemplar, tmp_path):
    model = cooc.CoocGAN(**{**TINY, "ema": 0.9}, device="cpu", rng=0).fit(exemplar)
    path = tmp_path / "m.pt"
    model.save(path)
    raw = torch.load(path, weights_only=True)
    assert all(isinstance(v, torch.Tensor) for v in raw.values()) and "generator_ema.net.1.weight" in raw
    again = cooc.load(path, device="cpu")
    cond = model.crop_condition(16, 0)
    np.testing.assert_array_equal(again.generate(cond, rng=5), model.generate(cond, rng=5))
    np.testing.assert_array_equal(again.raw().generate(cond, rng=5), model.raw().generate(cond, rng=5))
    # Resuming 2 + 2 steps continues the average: equal to 4 steps at once.
    direct = cooc.CoocGAN(**{**TINY, "ema": 0.9, "n_steps": 4}, device="cpu", rng=0).fit(exemplar)
    resumed = cooc.load(path, device="cpu").set_params(n_steps=4).fit(exemplar, resume=True)
    for p, q in zip(_state(direct.generator_ema_).values(), _state(resumed.generator_ema_).values()):
        torch.testing.assert_close(p, q)
    assert not torch.equal(direct.generator_ema_.state_dict()["net.1.weight"],
                           model.generator_ema_.state_dict()["net.1.weight"])
    # A checkpoint written before the setting (no "ema" in its settings, no average) loads without one.
    settings = json.loads(bytes(raw["settings_json"].numpy().tobytes()).decode())
    del settings["settings"]["ema"]
    old = {k: v for k, v in raw.items() if not k.startswith("generator_ema.")}
    old["settings_json"] = torch.frombuffer(bytearray(json.dumps(settings).encode()), dtype=torch.uint8)
    torch.save(old, tmp_path / "old.pt")
    loaded = cooc.load(tmp_path / "old.pt", device="cpu")
    assert loaded.settings_["ema"] == 0 and not hasattr(loaded, "generator_ema_")
    np.testing.assert_array_equal(loaded.generate(cond, rng=5), model.raw().generate(cond, rng=5))
    # An average announced by the settings but missing from the file is a corrupt checkpoint.
    broken = {k: v for k, v in raw.items() if not k.startswith("generator_ema.")}
    torch.save(broken, tmp_path / "broken.pt")
    with pytest.raises(ModelFileError, match="corrupt"):
        cooc.load(tmp_path / "broken.pt", device="cpu")


def test_bad_checkpoints(tmp_path):
    # The messages say what to do in Python too, not only on the command line.
    with pytest.raises(ModelFileError, match="no such checkpoint") as error:
        cooc.load(tmp_path / "missing.pt")
    assert "CoocGAN().fit(exemplar).save(path)" in str(error.value)
    assert "'tghop cooc train EXEMPLAR -o missing.pt'" in str(error.value)
    other = tmp_path / "other.pt"
    torch.save({"weight": torch.zeros(3)}, other)
    with pytest.raises(ModelFileError, match="not a tghop co-occurrence checkpoint") as error:
        cooc.load(other)
    assert "CoocGAN.save" in str(error.value) and "'tghop cooc train'" in str(error.value)
    foreign = tmp_path / "foreign.pt"
    settings = b'{"kind": "something.else", "format": 1}'
    torch.save({"settings_json": torch.frombuffer(bytearray(settings), dtype=torch.uint8)}, foreign)
    with pytest.raises(ModelFileError, match="another kind") as error:
        cooc.load(foreign)
    assert "CoocGAN().fit(exemplar).save(path)" in str(error.value) and "'tghop cooc train'" in str(error.value)
    text = tmp_path / "text.pt"
    text.write_text("hello")
    with pytest.raises(ModelFileError, match="not a tghop"):
        cooc.load(text)


def test_condition_checks(tiny_model):
    with pytest.raises(TGHopError, match="shape"):
        tiny_model.generate(np.ones((4, 2, 2)))
    with pytest.raises(TGHopError, match="non-negative"):
        tiny_model.generate(-np.ones((9, 2, 2)))
    with pytest.raises(TGHopError, match="not inside"):
        tiny_model.crop_condition(40, 40)


def test_generation_arguments_are_checked_by_name(tiny_model):
    a = tiny_model.crop_condition(0, 0)
    z = tiny_model.noise(a.shape[1:], rng=0)
    z[0, 0, 0] = np.nan
    with pytest.raises(TGHopError, match="noise contains NaN"):
        tiny_model.generate(a, noise=z)
    big = np.concatenate([a, a, a], axis=2)
    zz = tiny_model.noise(big.shape[1:], rng=0)
    zz[0, 0, 0] = np.inf
    with pytest.raises(TGHopError, match="noise contains NaN or infinite"):
        tiny_model.generate(big, noise=zz, windows=True)
    with pytest.raises(TGHopError, match=r"length must be an integer >= 2, got 4.5"):
        tiny_model.morph_strip(a, a, length=4.5)
    with pytest.raises(TGHopError, match=r"n_cols must be an integer >= 1, got 2.5"):
        tiny_model.morph_grid(a, a, n_cols=2.5)
    with pytest.raises(TGHopError, match=r"n_rows must be an integer >= 1, got 2.0"):
        tiny_model.morph_grid(a, a, n_rows=2.0)
    with pytest.raises(TGHopError, match=r"y must be an integer >= 0, got 0.5"):
        tiny_model.crop_condition(0.5, 0)
    with pytest.raises(TGHopError, match=r"x must be an integer >= 0, got 1.5"):
        tiny_model.crop_condition(0, 1.5)
    with pytest.raises(TGHopError, match="at least one cell"):
        tiny_model.generate(np.ones((a.shape[0], 0, 2)))
    with pytest.raises(TGHopError, match="conds is empty"):
        tiny_model.generate_batch([])


def test_load_names_a_bad_device_not_a_corrupt_file(tiny_model, tmp_path):
    path = tmp_path / "m.pt"
    tiny_model.save(path)
    with pytest.raises(TGHopError, match="device must be 'auto', 'cpu', 'cuda' or a torch device name, got 'tpu'") \
            as error:
        cooc.load(path, device="tpu")
    assert "corrupt" not in str(error.value)
    if not torch.cuda.is_available():
        with pytest.raises(TGHopError, match="CUDA is not available here; use device='cpu'"):
            cooc.load(path, device="cuda")
    assert cooc.load(path, device="cpu").step_ == tiny_model.step_


def test_morph_strip_and_grid(tiny_model):
    a, b = tiny_model.crop_condition(0, 0), tiny_model.crop_condition(16, 16)
    strip = tiny_model.morph_strip(a, b, length=6, rng=0)
    assert strip.shape == (32, 48, 3)
    grid = tiny_model.morph_grid(a, b, n_cols=3, n_rows=2, rng=0)
    assert grid.shape == (2, 3, 32, 32, 3)
    # The first column of the first row is generated from a, the last from b, under one noise.
    z = tiny_model.noise(a.shape[1:], rng=np.random.default_rng(0))
    np.testing.assert_allclose(grid[0, 0], tiny_model.generate(a, noise=z), atol=1e-6)


def test_without_torch(monkeypatch, exemplar, without_torch):
    with pytest.raises(MissingExtraError, match=r"pip install 'tghop\[metrics\]'"):
        cooc.CoocGAN(**TINY).fit(exemplar)
    with pytest.raises(MissingExtraError):
        cooc.load(__file__)  # an existing file: the torch check comes after the existence check
    # The NumPy statistics (and the metric) do not need torch.
    c, s = clusters(exemplar)
    assert cooccurrence.cooccurrence_matrix(exemplar.transpose(2, 0, 1)[None], c, s)[0].sum() == pytest.approx(1.0)


# ------------------------------------------------------------------ command line
def run(*args, env_extra=None):
    env = {**os.environ, "PYTHONWARNINGS": "ignore::DeprecationWarning", **(env_extra or {})}
    return subprocess.run([sys.executable, "-m", "tghop", *map(str, args)], capture_output=True, env=env, timeout=300)


def invoke(*args):
    """The command line in-process (:func:`run` starts an interpreter and PyTorch each time)."""
    from click.testing import CliRunner

    from tghop.cli import main

    return CliRunner().invoke(main, [str(a) for a in args])


TINY_SET = ["--set", "n_clusters=3", "--set", "crop_size=32", "--set", "n_layers=3", "--set", "patch=9",
            "--set", "window=7", "--set", "sigma=2", "--set", "g_widths=[8,4]", "--set", "d_widths=[4,8]",
            "--set", "noise_channels=2", "--set", "n_crops=8", "--set", "batch_size=4", "--set", "n_critic=1"]


def test_cli_end_to_end(tmp_path):
    # The first command as a process of its own; the others in-process (no interpreter and
    # PyTorch to start each time).
    from PIL import Image

    from tghop.imageio import save_image

    save_image(data.bricks(48, rng=3), tmp_path / "ex.png")
    model = tmp_path / "m.pt"
    r = run("cooc", "train", tmp_path / "ex.png", "-o", model, "--steps", "1", "-q", *TINY_SET)
    assert r.returncode == 0, r.stderr.decode()
    assert "1 step trained" in r.stderr.decode()
    r = invoke("cooc", "train", tmp_path / "ex.png", "-o", model, "--steps", "2", "--resume", "-q")
    assert r.exit_code == 0, r.output
    assert "2 steps trained" in r.output
    r = invoke("baseline", "cooc", tmp_path / "ex.png", "--model", model, "-o", tmp_path / "b.png", "--size", "40x70",
               "--seed", "1", "-q")
    assert r.exit_code == 0, r.output
    assert np.asarray(Image.open(tmp_path / "b.png")).shape == (40, 70, 3)
    r = invoke("baseline", "cooc", tmp_path / "ex.png", "--model", model, "-o", tmp_path / "p.png", "--size", "40x70",
               "--seed", "1", "-q", "--assembly", "pass")
    assert r.exit_code == 0, r.output
    one_pass = np.asarray(Image.open(tmp_path / "p.png"))
    assert one_pass.shape == (40, 70, 3) and not np.array_equal(one_pass, np.asarray(Image.open(tmp_path / "b.png")))
    r = invoke("cooc", "morph", model, "crop:0,0", "crop:16,16", "-o", tmp_path / "strip.png", "--length", "5")
    assert r.exit_code == 0, r.output
    assert np.asarray(Image.open(tmp_path / "strip.png")).shape == (32, 40, 3)
    r = invoke("cooc", "morph", model, "crop:0,0", tmp_path / "ex.png", "-o", tmp_path / "grid.png", "--grid", "3x2")
    assert r.exit_code == 0, r.output
    assert np.asarray(Image.open(tmp_path / "grid.png")).shape == (2 * 34 - 2, 3 * 34 - 2, 3)
    r = invoke("cooc", "edit", model, "crop:0,0", "crop:16,16", "-o", tmp_path / "edit.png", "--size", "24x64",
               "--boost", "0,1,2")
    assert r.exit_code == 0, r.output
    assert np.asarray(Image.open(tmp_path / "edit.png")).shape == (24, 64, 3)
    # --windows: training-size windows; another image of the same size.
    r = invoke("cooc", "edit", model, "crop:0,0", "crop:16,16", "-o", tmp_path / "win.png", "--size", "24x64",
               "--boost", "0,1,2", "--windows")
    assert r.exit_code == 0, r.output
    win = np.asarray(Image.open(tmp_path / "win.png"))
    assert win.shape == (24, 64, 3) and not np.array_equal(win, np.asarray(Image.open(tmp_path / "edit.png")))


def test_set_parses_words_for_word_settings():
    from tghop.cli.cooc import parse_settings

    assert parse_settings(["padding=replicate", "gp_every=2", "context=true", "g_widths=[8,4]"]) == {
        "padding": "replicate", "gp_every": 2, "context": True, "g_widths": [8, 4]}
    # The message gives the form the setting takes (the old one said "a number or a JSON list" for all).
    for item, words in (("lr=fast", "lr takes a number, e.g. lr=0.0002"),
                        ("context=False", "context takes true or false, e.g. context=true"),
                        ("crop_size=big", "crop_size takes an integer, e.g. crop_size=64"),
                        ("g_widths=(8,4)", "g_widths takes a JSON list of integers, e.g. g_widths=[64,32,16]")):
        with pytest.raises(TGHopError) as error:
            parse_settings([item])
        assert str(error.value) == f"--set {item!r}: {words}"


def test_cli_errors(tmp_path):
    import torch as _torch

    out = tmp_path / "o.png"
    assert_user_error(run("cooc", "morph", tmp_path / "none.pt", "crop:0,0", "crop:0,0", "-o", out),
                      "no such checkpoint")
    other = tmp_path / "other.pt"
    _torch.save({"w": _torch.zeros(2)}, other)
    assert_user_error(run("cooc", "edit", other, "-o", out), "not a tghop co-occurrence checkpoint")
    assert_user_error(run("cooc", "train", "builtin:bricks", "-o", tmp_path / "m.pt", "--set", "bogus=1"), "--set")
    assert not out.exists()
    # Without torch: a fake package that fails to import stands in for a missing install.
    fake = tmp_path / "fake"
    (fake / "torch").mkdir(parents=True)
    (fake / "torch" / "__init__.py").write_text("raise ImportError('no torch here')\n")
    path = os.pathsep.join([str(fake), os.environ.get("PYTHONPATH", "")])
    r = run("cooc", "train", "builtin:bricks", "-o", tmp_path / "m.pt", env_extra={"PYTHONPATH": path})
    assert_user_error(r, "needs PyTorch", "pip install 'tghop[metrics]'")
    r = run("baseline", "cooc", "builtin:bricks", "-o", out, env_extra={"PYTHONPATH": path})
    assert_user_error(r, "needs PyTorch")
    assert not out.exists()
