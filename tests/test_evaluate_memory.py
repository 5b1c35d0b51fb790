"""Bounded memory of the metrics on large images (issue #26): the strip and tile paths give
the scores of the one-piece paths, small images are untouched, sizes are checked before
any work, and evaluate reports progress. Images are made in code and kept small: the
thresholds are lowered with monkeypatch so that the bounded paths run on them."""

from __future__ import annotations


import numpy as np
import pytest

from tghop import data, metrics
from tghop.metrics import common, distributions, evaluation, networks
from tghop._errors import InvalidImageError, TGHopError
from tghop._images import MAX_PIXELS
from tghop.imageio import save_image

from conftest import assert_user_error, cli

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def pair():
    rng = np.random.default_rng(3)
    ex = data.bricks(150, rng=1)[:, :140]
    res = np.clip(data.bricks(130, rng=2) + 0.05 * rng.standard_normal((130, 130, 3)), 0, 1)
    return ex, res


# ------------------------------------------------------------------ the bounded paths agree with one piece


def test_gram_tiles_give_the_one_piece_gram(pair, monkeypatch):
    pytest.importorskip("torch")
    ex, res = pair
    plain = metrics.gram_distance(ex, res)
    monkeypatch.setattr(networks, "GRAM_TILE", 30)  # 96x86 valid positions: 4x3 tiles
    assert len(networks._gram_tiles(ex, 27)) == 12
    tiled = metrics.gram_distance(ex, res)
    assert tiled == pytest.approx(plain, rel=1e-5)
    assert metrics.gram_distance(ex, res) == tiled  # deterministic
    assert metrics.gram_distance(ex, ex) == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("before_pool", [False, True])
def test_sifid_strips_give_every_feature_row_once(pair, before_pool):
    torch = pytest.importorskip("torch")
    img = pair[0]
    blocks = networks._inception_blocks(torch, before_pool)
    full = networks._inception_run(torch, blocks, img)
    old = common.PLAIN_MAX_PIXELS
    try:
        common.PLAIN_MAX_PIXELS = 12 * img.shape[1]
        strips = list(networks._inception_strips(img, before_pool))
    finally:
        common.PLAIN_MAX_PIXELS = old
    assert len(strips) > 3
    pieces = [networks._inception_run(torch, blocks, img[r0:r1])[:, lo:hi] for r0, r1, lo, hi in strips]
    joined = torch.cat(pieces, dim=1)
    assert joined.shape == full.shape
    assert torch.allclose(joined, full, atol=1e-4, rtol=1e-4)


@pytest.mark.parametrize("before_pool", [False, True])
def test_sifid_strips_give_the_one_piece_score(pair, monkeypatch, before_pool):
    pytest.importorskip("torch")
    ex, res = pair
    plain = metrics.sifid(ex, res, before_pool=before_pool)
    monkeypatch.setattr(common, "PLAIN_MAX_PIXELS", 40 * 140)
    strips = metrics.sifid(ex, res, before_pool=before_pool)
    assert strips == pytest.approx(plain, rel=1e-5)
    assert metrics.sifid(ex, res, before_pool=before_pool) == strips


def test_cooccurrence_strips_give_the_one_piece_score(pair, monkeypatch):
    ex, res = pair
    plain = metrics.cooccurrence_distance(ex, res)
    monkeypatch.setattr(common, "PLAIN_MAX_PIXELS", 20 * 140)
    assert len(distributions._cooc_strips(ex, 51)) == 8
    strips = metrics.cooccurrence_distance(ex, res)
    assert strips == pytest.approx(plain, rel=1e-9)
    assert metrics.cooccurrence_distance(ex, res) == strips


@pytest.mark.parametrize("name", ["sifid", "gram", "cooccurrence"])
def test_small_images_take_the_one_piece_path_bit_for_bit(pair, monkeypatch, name):
    """Below the thresholds nothing changes: raising them changes no bit of the score."""
    if metrics.METRICS[name].needs_torch:
        pytest.importorskip("torch")
    ex, res = pair
    fn = metrics.METRICS[name].function
    value = fn(ex, res)
    monkeypatch.setattr(common, "PLAIN_MAX_PIXELS", 10**9)
    monkeypatch.setattr(networks, "GRAM_TILE", 10**6)
    assert fn(ex, res) == value


# ------------------------------------------------------------------ checks before the work


def test_sizes_are_checked_before_any_work():
    side = int(np.sqrt(MAX_PIXELS)) + 1
    with pytest.raises(InvalidImageError, match="above the"):
        metrics.check_sizes({"result": (side, side, 3)})
    with pytest.raises(InvalidImageError, match="swd needs at least 28x28"):
        metrics.check_sizes({"result": (20, 100, 3)})
    metrics.check_sizes({"result": (20, 100, 3)}, ["sifid", "novelty"])  # 16 and 8 are enough
    with pytest.raises(InvalidImageError, match="diversity needs at least 8x8"):
        metrics.check_sizes({"result": (5, 5, 3)}, ["cooccurrence"], diversity=True)


def test_the_exemplar_is_held_only_to_the_metrics_that_use_it():
    # self_repetition (and diversity) look at the results alone: an 8x8 exemplar was refused for them.
    metrics.check_sizes({"exemplar": (8, 8, 3), "result": (64, 64, 3)}, ["self_repetition"], diversity=True)
    with pytest.raises(InvalidImageError, match="^exemplar is 8x8 pixels but swd needs at least 28x28"):
        metrics.check_sizes({"exemplar": (8, 8, 3), "result": (64, 64, 3)}, ["self_repetition", "swd"])
    with pytest.raises(InvalidImageError, match="^result is 12x12 pixels but self_repetition needs at least 16x16"):
        metrics.check_sizes({"exemplar": (8, 8, 3), "result": (12, 12, 3)}, ["self_repetition"])
    with pytest.raises(InvalidImageError, match="^ex.png is 8x8 pixels but self_repetition"):  # no exemplar named
        metrics.check_sizes({"ex.png": (8, 8, 3)}, ["self_repetition"], exemplar=None)
    with pytest.raises(InvalidImageError, match="above the"):  # the exemplar's own limits still hold
        metrics.check_sizes({"exemplar": (MAX_PIXELS, 2, 3)}, ["self_repetition"])
    tiny = np.random.default_rng(0).random((8, 8, 3))
    tiled = np.tile(data.bricks(32, rng=1), (2, 2, 1))
    scores = metrics.evaluate(tiny, tiled, metrics=["self_repetition"])
    assert scores == {"self_repetition": metrics.self_repetition(tiled)}


def test_evaluate_refuses_a_tiny_image_saying_what_size_is_needed():
    with pytest.raises(InvalidImageError) as info:
        metrics.evaluate(data.bricks(64), np.zeros((1, 1, 3)))
    message = str(info.value)
    assert "28x28" in message and "1x1" in message and "patch size" not in message
    assert "\n" not in message


@pytest.mark.parametrize("chosen", [[], ()])
def test_evaluate_refuses_no_metrics(chosen):
    with pytest.raises(TGHopError, match="sifid, gram, swd"):
        metrics.evaluate(data.bricks(64), data.bricks(64), metrics=chosen)


# ------------------------------------------------------------------ progress


def test_evaluate_reports_progress_per_metric(pair, monkeypatch):
    monkeypatch.setattr(common, "PLAIN_MAX_PIXELS", 40 * 140)
    ex, res = pair
    calls = []
    names = ["swd", "cooccurrence", "novelty", "copied"]
    metrics.evaluate(ex, res, metrics=names, progress=lambda *a: calls.append(a))
    assert [c[0] for c in calls if c[1] == 0] == names  # one stage per metric, in order
    for name in names:
        seen = [(done, total) for stage, done, total in calls if stage == name]
        assert seen[-1][0] == seen[-1][1] > 0  # every stage ends complete
        assert [d for d, _ in seen] == sorted(d for d, _ in seen)
    assert len([c for c in calls if c[0] == "cooccurrence"]) > 3  # strips counted


def test_diversity_reports_progress(pair):
    calls = []
    value = metrics.diversity(pair[0], pair[1], progress=lambda *a: calls.append(a))
    assert value == metrics.diversity(pair[0], pair[1])
    assert calls[0][1] == 0 and calls[-1][1] == calls[-1][2] and {c[0] for c in calls} == {"diversity"}


def test_diversity_is_the_mean_of_both_novelties_of_every_pair():
    # diversity converts each result to float64 when a pair needs it (not all at once): its value is unchanged,
    # the mean over pairs, in order, of each one's nearest-patch distance to the other.
    rng = np.random.default_rng(5)
    results = [data.bricks(40, rng=1), (data.bricks(36, rng=2) * 255).round().astype(np.uint8),
               np.clip(data.bricks(44, rng=3) + 0.1 * rng.standard_normal((44, 44, 3)), 0, 1).tolist()]
    options = dict(patch_size=6, max_patches=50, seed=3)
    both = [metrics.novelty(a, b, **options) for i, j in [(0, 1), (0, 2), (1, 2)]
            for a, b in [(results[i], results[j]), (results[j], results[i])]]
    assert metrics.diversity(*results, **options) == float(np.mean(both))
    assert metrics.diversity(results, **options) == float(np.mean(both))


def test_diversity_holds_two_results_as_float64_at_a_time_not_all():
    import tracemalloc

    n, side = 8, 256
    base = (data.bricks(side, rng=1) * 255).astype(np.uint8)
    results = [np.roll(base, 9 * k, axis=1) for k in range(n)]
    one = side * side * 3 * 8  # one result in float64: 1.6 MB, 12.6 MB for all eight
    tracemalloc.start()
    try:
        metrics.diversity(*results, patch_size=2, max_patches=8)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 4 * one, f"peak {peak / 1e6:.1f} MB"


# ------------------------------------------------------------------ the command line


def run(*args):
    return cli(*args)  # in this process: the same exit status and output, no interpreter to start


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    d = tmp_path_factory.mktemp("evaluate")
    save_image(data.bricks(64, rng=1), d / "ex.png")
    save_image(data.bricks(48, rng=2), d / "res.png")
    save_image(np.zeros((1, 1, 3)), d / "dot.png")
    return d


def test_cli_refuses_empty_metrics(images):
    r = run("evaluate", images / "ex.png", images / "res.png", "--metrics", "")
    assert_user_error(r, "--metrics", "sifid, gram, swd, cooccurrence, novelty, copied")
    assert r.stdout == b""


def test_cli_self_repetition_is_opt_in(images):
    import json

    r = run("evaluate", images / "ex.png", images / "res.png", "--json", "--metrics", "swd,copied_textured", "-q")
    assert r.returncode == 0, r.stderr.decode()
    line = json.loads(r.stdout)
    assert set(line) == {"exemplar", "result", "swd", "copied_textured"}
    for extra in (["--repetition"], ["--metrics", "swd,self_repetition"]):
        args = ["--metrics", "swd"] if extra == ["--repetition"] else []
        r = run("evaluate", images / "ex.png", images / "res.png", "--json", "-q", *args, *extra)
        assert r.returncode == 0, r.stderr.decode()
        line = json.loads(r.stdout)
        assert set(line) == {"exemplar", "result", "swd", "self_repetition"}
        assert 0.0 <= line["self_repetition"] <= 1.0
    r = run("evaluate", "--help")
    assert "--repetition" in r.stdout.decode() and "self_repetition" in r.stdout.decode()
    # The table: one column per metric, long names (15 characters) apart from their neighbours.
    names = "copied,copied_textured,self_repetition"
    r = run("evaluate", images / "ex.png", images / "res.png", "-q", "--metrics", names)
    assert r.returncode == 0, r.stderr.decode()
    header, row = r.stdout.decode().splitlines()[:2]
    assert header.split() == ["result", "copied", "copied_textured", "self_repetition"]
    assert len(row.split()) == 4


def test_cli_refuses_a_tiny_image_naming_the_size(images):
    r = run("evaluate", images / "ex.png", images / "dot.png")
    assert_user_error(r, "dot.png", "1x1", "28x28")
    assert "patch size" not in r.stderr.decode()
    r = run("evaluate", images / "ex.png", images / "res.png", images / "dot.png", "--metrics", "cooccurrence")
    assert_user_error(r, "dot.png", "diversity needs at least 8x8")


def test_cli_takes_a_small_exemplar_for_self_repetition_alone(images, tmp_path):
    save_image(np.random.default_rng(0).random((8, 8, 3)), tmp_path / "tiny.png")
    save_image(data.bricks(32, rng=3)[:12, :12], tmp_path / "small.png")
    for args in (["--metrics", "self_repetition"], ["--metrics", "self_repetition", images / "res.png"]):
        r = run("evaluate", tmp_path / "tiny.png", images / "res.png", "-q", *args)
        assert r.returncode == 0, r.stderr.decode()
        assert r.stdout.decode().split()[:2] == ["result", "self_repetition"]
    r = run("evaluate", tmp_path / "tiny.png", images / "res.png", "-q", "--metrics", "swd", "--repetition")
    assert_user_error(r, "tiny.png is 8x8 pixels but swd needs at least 28x28")
    r = run("evaluate", tmp_path / "tiny.png", tmp_path / "small.png", "-q", "--metrics", "self_repetition")
    assert_user_error(r, "small.png is 12x12 pixels but self_repetition needs at least 16x16")
    r = run("evaluate", tmp_path / "small.png", tmp_path / "small.png", "-q", "--metrics", "self_repetition")
    assert_user_error(r, "small.png is 12x12 pixels but self_repetition needs at least 16x16")  # as a result


def test_cli_shows_progress_unless_quiet(images):
    r = run("evaluate", images / "ex.png", images / "res.png", "--metrics", "swd,cooccurrence")
    assert r.returncode == 0, r.stderr.decode()
    assert "swd" in r.stderr.decode() and "cooccurrence" in r.stderr.decode()
    assert "res.png" in r.stdout.decode()
    r = run("evaluate", images / "ex.png", images / "res.png", "--metrics", "swd,cooccurrence", "-q")
    assert r.returncode == 0 and r.stderr.decode().strip() == ""
    r = run("evaluate", "--help")
    assert "512x512" in r.stdout.decode() and "8192x8192" in r.stdout.decode()


def test_evaluate_checks_the_size_before_copying_the_image(monkeypatch):
    side = int(np.sqrt(MAX_PIXELS)) + 1
    huge = np.broadcast_to(np.zeros((1, 1, 3)), (side, side, 3))  # no memory behind it

    def no_copy(*args, **kwargs):
        raise AssertionError("the images were copied before their size was checked")

    monkeypatch.setattr(evaluation, "pair", no_copy)
    with pytest.raises(InvalidImageError, match="above the"):
        metrics.evaluate(data.bricks(64), huge, metrics=["cooccurrence"])


def test_evaluate_holds_8bit_results_as_bytes(tmp_path):
    # A researcher scores hundreds of results at once: each 8-bit result is held as uint8 until
    # scored, not as float64 (8 bytes a value: 500 results of 1024x1024 were 12.6 GB). The
    # growth of the peak from 8 to 16 results is the 8 more held; the scores are the same.
    import json
    import tracemalloc

    save_image(data.bricks(96), tmp_path / "ex.png")
    paths = []
    for i in range(16):
        paths.append(tmp_path / f"r{i}.png")
        save_image(data.bricks(128, rng=i), paths[-1])
    peaks, outputs = [], []
    cli("evaluate", tmp_path / "ex.png", paths[0], "--metrics", "swd", "-q")  # imports done before measuring
    for n in (8, 16):
        tracemalloc.start()
        r = cli("evaluate", tmp_path / "ex.png", *paths[:n], "--metrics", "swd", "--no-diversity", "--json", "-q")
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        assert r.returncode == 0, r.stderr.decode()
        outputs.append([json.loads(line) for line in r.stdout.decode().splitlines()])
    assert outputs[1][:8] == outputs[0]
    float64_each = 128 * 128 * 3 * 8
    assert peaks[1] - peaks[0] < 8 * float64_each / 4  # uint8: an eighth of it
    from tghop import metrics as m
    from tghop.imageio import load_image

    assert outputs[0][3]["swd"] == m.sliced_wasserstein(load_image(tmp_path / "ex.png"), load_image(paths[3]))
