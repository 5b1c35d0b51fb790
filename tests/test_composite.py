"""Painted regions joined by a minimum cut (tghop.composite), on layers made in code."""

import numpy as np
import pytest

from tghop import TGHopError
from tghop.composite import band_boxes, cut_regions, in_band, join_layers, layer_boxes
from tghop.guided import region_weights

from conftest import straight_share


def _halves(h=24, w=64, split=32):
    labels = np.zeros((h, w), dtype=np.int64)
    labels[:, split:] = 1
    return labels


def _noise(shape, seed):
    return np.random.default_rng(seed).random(shape).astype(np.float32)


def _whole(labels, layers):
    return [(slice(0, labels.shape[0]), slice(0, labels.shape[1]))] * len(layers)


def test_the_join_runs_where_the_layers_look_alike():
    labels = _halves()
    a = _noise((24, 64, 3), 0)
    b = _noise((24, 64, 3), 1)
    b[:, :28] = a[:, :28]  # alike left of column 28, unlike from there to the painted edge at 32
    weights = region_weights(labels, 2, 16)
    shows = cut_regions(labels, weights, [a, b], _whole(labels, [a, b]))
    assert shows.shape == labels.shape and shows.dtype == np.int64
    assert (shows[:, 28:] == 1).all()  # the join moved off the painted edge into where they agree
    assert (shows[:, :16] == 0).all()  # outside the band: the own region's layer
    # Unlike everywhere: the join stays near the painted edge (the stray cost), further off without it.
    c = _noise((24, 64, 3), 2)
    off = [(cut_regions(labels, weights, [a, c], _whole(labels, [a, c]), stray_cost=cost) != labels).sum(axis=1)
           for cost in (0.1, 0.0)]
    assert off[0].max() <= 3 and off[1].min() > off[0].max()


def test_the_join_is_not_drawn_along_rows_and_columns():
    """On 4 neighbours (0.62) a cut's length was its Manhattan length: where two layers were unlike, the
    join took the chord across a curved outline as a straight row or column (a remix's gravel in grass:
    edges of 100-150 px along a row). On 8 neighbours weighted for Euclidean length the join's share in
    straight runs of 16 px or more falls (bricks and cells on remix maps: 0.34 -> 0.15 over 6 seeds, each
    lower)."""
    from tghop import data
    from tghop.guided import random_labels

    layers = [data.bricks().astype(np.float64), data.cells().astype(np.float64)]
    shares = []
    for seed in range(6):
        labels = random_labels((256, 256), 2, rng=seed, scale=48)
        shows = cut_regions(labels, region_weights(labels, 2, 32), layers, _whole(labels, layers))
        shares.append(straight_share(shows))
    assert np.mean(shares) < 0.25, shares


def test_the_join_does_not_cut_across_an_inner_corner():
    """Round a region's convex corner its box is mostly the other region's, so the weights' difference (the
    stray cost up to 0.63) fell to 0 up to 7 px into it: where the layers were unlike everywhere the join cut
    across an L's inner corner for nothing (6-8 px deep, 98-140 px of the other region). Since 0.64 the stray
    cost is at least the pixel's distance from the paint's: 2-4 px deep, 21-37 px."""
    from scipy.ndimage import distance_transform_edt

    labels = np.zeros((96, 96), dtype=np.int64)
    labels[16:80, 16:40] = 1
    labels[56:80, 16:80] = 1  # an L; its inner corner at row 56, column 40
    weights = region_weights(labels, 2, 32)
    outside = distance_transform_edt(labels == 0)
    corner = np.zeros(labels.shape, dtype=bool)
    corner[40:56, 40:56] = True
    for seed in range(3):
        rng = np.random.default_rng(seed)
        layers = [(0.4 + 0.2 * rng.random((96, 96, 3))).astype(np.float32) for _ in range(2)]  # unlike everywhere
        shows = cut_regions(labels, weights, layers, _whole(labels, layers))
        cut = corner & (labels == 0) & (shows == 1)
        assert cut.sum() < 60 and outside[cut].max(initial=0) <= 4, (seed, cut.sum(), outside[cut].max(initial=0))


def test_pixels_outside_every_band_show_their_own_region():
    h = w = 80
    yy, xx = np.mgrid[:h, :w]
    labels = ((yy - 40) ** 2 + (xx - 40) ** 2 < 25 ** 2).astype(np.int64)  # a disc: no block staircase to follow
    layers = [_noise((h, w, 3), 0), _noise((h, w, 3), 1)]
    weights = region_weights(labels, 2, 12)
    shows = cut_regions(labels, weights, layers, _whole(labels, layers))
    band = weights.max(axis=0) < 1
    assert np.array_equal(shows[~band], labels[~band]) and band.any()
    assert set(np.unique(shows[band])) == {0, 1}
    assert np.array_equal(cut_regions(labels, region_weights(labels, 2, 0), layers, _whole(labels, layers)), labels)


def test_the_cut_wraps_around_a_tileable_image():
    labels = _halves()  # regions meet at column 32 and, wrapping, between the last column and the first
    a = _noise((24, 64, 3), 0)
    b = _noise((24, 64, 3), 1)
    a[:, 58:] = b[:, 58:]  # alike in the last columns: the wrapped join moves off the edge into them
    for tile, shown in ((True, 0), (False, 1)):
        weights = region_weights(labels, 2, 16, tile=tile)
        shows = cut_regions(labels, weights, [a, b], _whole(labels, [a, b]), tile=tile)
        assert (shows[:, 63] == shown).all()


def test_three_regions_meet_and_the_boxes_cover_what_the_cut_reads():
    h, w = 60, 90
    labels = np.zeros((h, w), dtype=np.int64)
    labels[:, 30:] = 1
    labels[30:, 60:] = 2
    weights = region_weights(labels, 3, 10)
    boxes = layer_boxes(weights)
    assert boxes[0] == (slice(0, 60), slice(0, 36)) and boxes[2] == (slice(24, 60), slice(54, 90))  # 5 + 1 px more
    full = [_noise((h, w, 3), seed) for seed in range(3)]
    layers = [layer[box] for layer, box in zip(full, boxes)]  # each only over its box
    shows = cut_regions(labels, weights, layers, boxes)
    assert np.array_equal(shows, cut_regions(labels, weights, full, _whole(labels, full)))
    out = join_layers(shows, layers, boxes)
    far = weights.max(axis=0) == 1
    expected = np.choose(labels[..., None], full)
    assert np.array_equal(out[far], expected[far])


def test_join_layers_antialiases_over_a_pixel():
    labels = _halves(8, 20, 10)
    layers = [np.zeros((8, 20, 1), np.float32), np.ones((8, 20, 1), np.float32)]
    out = join_layers(labels, layers, _whole(labels, layers))
    assert out.dtype == np.float32
    assert np.allclose(out[:, 9, 0], 3 / 9) and np.allclose(out[:, 10, 0], 6 / 9)
    assert (out[:, :9] == 0).all() and (out[:, 11:] == 1).all()
    wrapped = join_layers(labels, layers, _whole(labels, layers), tile=True)
    assert np.allclose(wrapped[:, 0, 0], 3 / 9) and np.allclose(wrapped[:, 19, 0], 6 / 9)


@pytest.mark.parametrize("tile", [False, True])
def test_join_layers_keeps_a_thin_region_its_own_layer(tile):
    # The mean over 3x3 faded a painted 1 px line to a third of its contrast, a 2 px one to two thirds.
    shows = np.zeros((24, 60), dtype=np.int64)
    shows[4:20, 10] = 1  # a line
    shows[4:20, 20:22] = 1  # two pixels wide
    shows[4:20, 30:33] = 1  # three: antialiased as before
    shows[22:, 40:50] = shows[:2, 40:50] = 1  # two pixels at each of the image's edges (four across the wrap)
    shows[[3, 4, 5], [50, 51, 52]] = 1  # a diagonal line
    layers = [np.zeros((24, 60, 1), np.float32), np.ones((24, 60, 1), np.float32)]
    out = join_layers(shows, layers, _whole(shows, layers), tile=tile)[..., 0]
    assert (out[4:20, 10] == 1).all() and (out[4:20, 20:22] == 1).all()
    assert (out[[3, 4, 5], [50, 51, 52]] == 1).all()
    assert np.allclose(out[8:16, 9], 3 / 9) and np.allclose(out[8:16, 19], 3 / 9)  # its neighbours: their share
    assert np.allclose(out[8:16, 30], 6 / 9) and np.allclose(out[8:16, 31], 1) and np.allclose(out[8:16, 29], 3 / 9)
    assert np.allclose(out[[1, 22], 42:48], 6 / 9 if tile else 1)


def test_one_region_or_mismatched_layers():
    labels = np.zeros((8, 8), dtype=np.int64)
    layers = [_noise((8, 8, 3), 0)]
    assert np.array_equal(cut_regions(labels, region_weights(labels, 1, 4), layers, _whole(labels, layers)), labels)
    two = _halves(8, 8, 4)
    with pytest.raises(TGHopError, match="2 layers but 1 boxes"):
        cut_regions(two, region_weights(two, 2, 4), [layers[0], layers[0]], _whole(two, layers))
    # Labels out of range or of another size than the weights: an IndexError, or a wrong answer without a word.
    weights = region_weights(two, 2, 4)
    for bad in (two + 1, two[:4], two.astype(float)):
        with pytest.raises(TGHopError, match=r"labels must be an integer map of shape \(8, 8\) with values in \[0, 2"):
            cut_regions(bad, weights, layers * 2, _whole(two, layers * 2))
    with pytest.raises(TGHopError, match="2 regions' weights but 1 layers"):
        cut_regions(two, weights, layers, _whole(two, layers))
    with pytest.raises(TGHopError, match=r"shows must be .* values in \[0, 2\)"):
        join_layers(two + 1, layers * 2, _whole(two, layers * 2))


@pytest.mark.parametrize("transition", [0, 1, 2, 12])
@pytest.mark.parametrize("tile", [False, True])
def test_the_band_boxes_hold_what_the_join_reads(transition, tile):
    # Without a band (transition 0 or 1) the boxes were empty, and the antialiased join read
    # outside them: IndexError for `tghop synth A B --guide map --transition 0`.
    h, w = 40, 56
    yy, xx = np.mgrid[:h, :w]
    labels = ((yy - 20) ** 2 + (xx - 20) ** 2 < 12 ** 2).astype(np.int64)
    labels[:, 44:] = 2  # three regions, one at the image's edge
    full = [_noise((h, w, 3), seed) for seed in range(3)]
    weights = region_weights(labels, 3, transition, tile=tile)
    shows = cut_regions(labels, weights, full, _whole(labels, full), tile=tile)
    keep = band_boxes(weights, tile=tile)
    image = np.choose(labels[..., None], full)  # every pixel its own region's layer, as _layered writes it
    joined = join_layers(shows, [layer[box] for layer, box in zip(full, keep)], keep, tile=tile, out=image)
    assert np.array_equal(joined, join_layers(shows, full, _whole(labels, full), tile=tile))


@pytest.mark.parametrize("tile", [False, True])
def test_a_region_narrower_than_the_band_keeps_its_middle(tile):
    # Showing the other layer cost nothing where the other region's weight was the larger, which is
    # everywhere in a region narrower than the band: a painted line, a dot or a stripe narrower than
    # the transition vanished whole (and with --transition 512, a disc of 300 px).
    h, w = 64, 160
    labels = np.zeros((h, w), dtype=np.int64)
    labels[8:56, 10] = 1  # a line
    labels[8:56, 40:42] = 1  # two pixels wide
    labels[8:56, 70:82] = 1  # 12
    labels[30:33, 120:123] = 1  # a dot
    labels[0:6, 140:] = 1  # a short strip at the image's edge (across the wrap with tile)
    layers = [_noise((h, w, 3), 0), _noise((h, w, 3), 1)]
    shows = cut_regions(labels, region_weights(labels, 2, 32, tile=tile), layers, _whole(labels, layers), tile=tile)
    assert (shows[8:56, 10] == 1).all() and (shows[8:56, 40:42] == 1).all() and shows[31, 121] == 1
    assert (shows[14:50, 73:79] == 1).all()  # the middle half of the 12 (its ends rounded off at most as much)
    assert (shows[1:3, 146:154] == 1).all()
    assert (shows == 1).sum() >= 0.5 * (labels == 1).sum()


@pytest.mark.parametrize("tile", [False, True])
def test_region_weights_are_each_maps_box_mean(tile):
    # The last map's weights are the box's area less the others' sums: the same numbers as its own box sums.
    labels = np.random.default_rng(0).integers(0, 4, (37, 53))
    labels[labels == 2] = 1  # a label with no pixel
    for transition in (0, 1, 6, 31):
        weights = region_weights(labels, 4, transition, tile=tile)
        r = transition // 2
        padded = np.pad(labels, r, mode="wrap" if tile else "edge")
        windows = np.lib.stride_tricks.sliding_window_view(padded, (2 * r + 1, 2 * r + 1))
        for k in range(4):
            mean = (windows == k).sum(axis=(2, 3)).astype(np.float32) / np.float32((2 * r + 1) ** 2)
            assert np.array_equal(weights[k], mean)


def test_the_band_given_is_the_one_found():
    h = w = 48
    yy, xx = np.mgrid[:h, :w]
    labels = ((yy - 24) ** 2 + (xx - 20) ** 2 < 14 ** 2).astype(np.int64)
    layers = [_noise((h, w, 3), 0), _noise((h, w, 3), 1)]
    weights = region_weights(labels, 2, 10)
    band = in_band(weights)
    kept = band.copy()
    assert np.array_equal(band, weights.max(axis=0) < 1 - 1e-6) and band.any()
    assert band_boxes(weights, band=band) == band_boxes(weights)
    shows = cut_regions(labels, weights, layers, _whole(labels, layers), band=band)
    assert np.array_equal(shows, cut_regions(labels, weights, layers, _whole(labels, layers)))
    assert np.array_equal(band, kept)  # not changed


def test_separate_shapes_are_cut_as_each_alone():
    # The bands of separate shapes are separate minimum cuts (small ones together): the same pixels
    # as each shape's cut alone.
    h = w = 260
    yy, xx = np.mgrid[:h, :w]
    shapes = [(yy - 65) ** 2 + (xx - 65) ** 2 < 50 ** 2, (yy - 185) ** 2 + (xx - 180) ** 2 < 55 ** 2]
    shapes += [(yy - y) ** 2 + (xx - x) ** 2 < 9 for y, x in ((20, 230), (230, 20), (130, 250))]
    layers = [_noise((h, w, 3), 0), _noise((h, w, 3), 1)]
    labels = np.any(shapes, axis=0).astype(np.int64)
    shows = cut_regions(labels, region_weights(labels, 2, 24), layers, _whole(labels, layers))
    for shape in shapes:
        alone = shape.astype(np.int64)
        cut = cut_regions(alone, region_weights(alone, 2, 24), layers, _whole(alone, layers))
        near = region_weights(alone, 2, 26)[1] > 0
        assert np.array_equal(shows[near], cut[near]) and (cut[near] != alone[near]).any()
