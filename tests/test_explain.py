"""tghop.explain: the cluster map of an image under a fitted model, and ``tghop clusters``."""

import numpy as np
import pytest
from conftest import SMALL, cli

from tghop import data, explain
from tghop._errors import NotFittedError, TGHopError
from tghop.explain import cluster_colours, cluster_image, cluster_map
from tghop.imageio import load_image, save_image
from tghop.modelfile import save_model
from tghop.patches import extract_patches, patch_origins
from tghop.synthesis import TGHop


def test_map_at_the_fit_stride_is_predict_of_encode(small_model, bricks96):
    p, s = small_model.patch_size, small_model.stride
    labels = cluster_map(small_model, bricks96)
    h, w = bricks96.shape[:2]
    assert labels.shape == ((h - p) // s + 1, (w - p) // s + 1)
    assert np.issubdtype(labels.dtype, np.integer)
    origins = patch_origins(bricks96.shape, p, stride=s)
    expected = small_model.ichm_.predict(small_model.encode(extract_patches(bricks96, p, stride=s)))
    assert len(origins) == labels.size
    np.testing.assert_array_equal(labels.ravel(), expected)
    assert labels.min() >= 0 and labels.max() < len(small_model.ichm_.means_)


def test_same_input_same_map_and_chunks_change_nothing(small_model, bricks96, monkeypatch):
    first = cluster_map(small_model, bricks96, stride=3)
    np.testing.assert_array_equal(first, cluster_map(small_model, bricks96, stride=3))
    monkeypatch.setattr(explain, "CHUNK", 7)
    np.testing.assert_array_equal(first, cluster_map(small_model, bricks96, stride=3))
    # uint8 is read as its floats: the same map
    eight = np.round(bricks96 * 255).astype(np.uint8)
    np.testing.assert_array_equal(cluster_map(small_model, eight, stride=3),
                                  cluster_map(small_model, eight / 255.0, stride=3))


def test_two_textures_get_different_dominant_clusters():
    left, right = data.bricks(96, rng=2), data.cells(96, rng=2)
    image = np.concatenate([left[:, :48], right[:, :48]], axis=1)  # 96 x 96: bricks | cells
    model = TGHop(**{**SMALL, "n_clusters": 6}).fit(image)
    labels = cluster_map(model, image, stride=4)
    p, s = model.patch_size, 4
    cols_left = [j for j in range(labels.shape[1]) if j * s + p <= 48]  # patches wholly in the left half
    cols_right = [j for j in range(labels.shape[1]) if j * s >= 48]
    assert cols_left and cols_right
    dominant_left = np.bincount(labels[:, cols_left].ravel()).argmax()
    dominant_right = np.bincount(labels[:, cols_right].ravel()).argmax()
    assert dominant_left != dominant_right
    # and the halves share little: most of each half is in clusters the other half barely uses
    share = np.mean(labels[:, cols_right] == dominant_left)
    assert share < 0.5


def test_cluster_image_paints_each_patch_centre_with_its_cluster(small_model, bricks96):
    p = small_model.patch_size
    for s in (1, 3, small_model.stride):
        labels = cluster_map(small_model, bricks96, stride=s)
        painted = cluster_image(labels, p, s, bricks96.shape)
        assert painted.shape == bricks96.shape[:2] + (3,)
        assert painted.min() >= 0 and painted.max() <= 1
        colours = cluster_colours(labels.max() + 1)
        for i in range(labels.shape[0]):
            for j in range(labels.shape[1]):
                np.testing.assert_array_equal(painted[i * s + p // 2, j * s + p // 2], colours[labels[i, j]])
        # the corners (no patch centre there) take the nearest cell's colour
        np.testing.assert_array_equal(painted[0, 0], colours[labels[0, 0]])
        np.testing.assert_array_equal(painted[-1, -1], colours[labels[-1, -1]])


def test_palette_is_fixed_and_distinct():
    colours = cluster_colours(64)
    np.testing.assert_array_equal(colours[:10], cluster_colours(10))
    assert colours.min() >= 0 and colours.max() <= 1
    assert len({tuple(np.round(c, 6)) for c in colours}) == 64
    d = np.linalg.norm(colours[:12, None] - colours[None, :12], axis=2) + np.eye(12)
    assert d.min() > 0.05


def test_errors():
    with pytest.raises(NotFittedError):
        cluster_map(TGHop(**SMALL), data.bricks(64, rng=0))


def test_wrong_channels_and_wrong_grid_are_one_line(small_model, bricks96):
    with pytest.raises(TGHopError, match="1 channel but the model was fitted on 3 channels") as info:
        cluster_map(small_model, bricks96[..., :1])
    assert "\n" not in str(info.value)
    with pytest.raises(TGHopError, match="not the grid"):
        cluster_image(np.zeros((3, 3), dtype=int), 32, 4, bricks96.shape)


def test_cli_writes_exemplar_and_map_side_by_side(small_model, bricks96, tmp_path):
    model, exemplar, out = tmp_path / "m.npz", tmp_path / "ex.png", tmp_path / "map.png"
    save_model(small_model, model)
    save_image(bricks96, exemplar)
    r = cli("clusters", model, exemplar, "-o", out, "-q")  # -q: no progress bar (review 60)
    assert r.returncode == 0, r.stderr
    image = load_image(out)
    assert image.shape == (96, 192, 3)
    np.testing.assert_allclose(image[:, :96], load_image(exemplar))
    lines = r.stderr.decode().strip().splitlines()
    assert len(lines) == 1
    total = len(small_model.ichm_.means_)
    assert lines[0].endswith(f"used of {total}; map written to {out}")
    used = len(np.unique(cluster_map(small_model, load_image(exemplar))))
    assert lines[0].startswith(f"{used} cluster")


def test_cli_errors_are_one_line_and_write_nothing(small_model, bricks96, tmp_path):
    model, grey, out = tmp_path / "m.npz", tmp_path / "grey.png", tmp_path / "map.png"
    save_model(small_model, model)
    save_image(bricks96[..., :1], grey)
    for args in [(model, grey), (model, tmp_path / "missing.png"), (tmp_path / "missing.npz", grey)]:
        r = cli("clusters", *args, "-o", out)
        err = r.stderr.decode().strip()
        assert r.returncode != 0
        assert len(err.splitlines()) == 1 and err.startswith("Error: "), err
        assert not out.exists()
    r = cli("clusters", model, grey, "-o", grey)  # the output is an input
    assert r.returncode != 0 and r.stderr.decode().startswith("Error: ")


def test_cli_refuses_a_material_in_one_line(bricks96, tmp_path):
    from tghop.material import Material

    height = bricks96.mean(axis=2, keepdims=True)
    material = Material(model=TGHop(**SMALL), rng=0).fit(bricks96, {"height": height})
    path, exemplar, out = tmp_path / "mat.npz", tmp_path / "ex.png", tmp_path / "map.png"
    save_model(material, path)
    save_image(bricks96, exemplar)
    r = cli("clusters", path, exemplar, "-o", out)
    err = r.stderr.decode().strip()
    assert r.returncode != 0 and len(err.splitlines()) == 1 and err.startswith("Error: "), err
    assert "material" in err and "fit a plain model" in err
    assert not out.exists()


def test_a_material_or_an_ichm_is_named_not_called_unfitted(bricks96):
    # review 60: a fitted Material or ICHM was "not fitted yet"
    from tghop.material import Material

    height = bricks96.mean(axis=2, keepdims=True)
    material = Material(model=TGHop(**SMALL), rng=0).fit(bricks96, {"height": height})
    with pytest.raises(TGHopError, match="expects a fitted TGHop, got Material; give its model_") as info:
        cluster_map(material, bricks96)
    assert "\n" not in str(info.value) and "not fitted" not in str(info.value)
    with pytest.raises(TGHopError, match="got ICHM; give the TGHop whose ichm_ it is"):
        cluster_map(material.model_.ichm_, bricks96)


@pytest.mark.parametrize("shape", [96, (96,), "96x96", (96, 0), (96.0, 96), None])
def test_cluster_image_checks_shape(shape):
    # review 60: shape=96 was a raw TypeError, (96,) a raw ValueError
    with pytest.raises(TGHopError, match="cluster_image: shape") as info:
        cluster_image(np.zeros((3, 3), dtype=int), 32, 32, shape)
    assert "\n" not in str(info.value)


def test_palette_colours_stay_apart_up_to_100():
    # review 60: the golden-ratio hues with three saturation/value levels came within 0.048 in RGB at
    # N = 50 (19 pairs under 0.1) and 0.047 at N = 100 (56 pairs); the farthest-point palette's minima
    # are 0.276 at N = 50 and 0.204 at N = 100.
    for n, bound in ((50, 0.27), (100, 0.2)):
        colours = cluster_colours(n)
        d = np.linalg.norm(colours[:, None] - colours[None, :], axis=2) + 9 * np.eye(n)
        assert d.min() > bound, (n, d.min())
    np.testing.assert_array_equal(cluster_colours(100)[:50], cluster_colours(50))


def test_progress_is_reported_per_chunk(small_model, bricks96, monkeypatch):
    # review 60: the map (minutes at stride 1 on a large image) said nothing while it ran
    monkeypatch.setattr(explain, "CHUNK", 100)
    calls = []
    labels = cluster_map(small_model, bricks96, stride=2, progress=lambda *a: calls.append(a))
    total = labels.size
    assert calls[0] == ("cluster map", 0, total) and calls[-1] == ("cluster map", total, total)
    assert [c[1] for c in calls] == [0, *range(100, total, 100), total]
    with pytest.raises(TGHopError, match="progress must be a function"):
        cluster_map(small_model, bricks96, progress="yes")


def test_cli_shows_progress_unless_quiet(small_model, bricks96, tmp_path):
    model, exemplar, out = tmp_path / "m.npz", tmp_path / "ex.png", tmp_path / "map.png"
    save_model(small_model, model)
    save_image(bricks96, exemplar)
    shown = cli("clusters", model, exemplar, "-o", out, "--stride", "1")
    assert shown.returncode == 0, shown.stderr
    assert "cluster map" in shown.stderr.decode()
    quiet = cli("clusters", model, exemplar, "-o", out, "-q")
    assert quiet.returncode == 0 and "cluster map" not in quiet.stderr.decode()
