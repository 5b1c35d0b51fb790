"""A material's mask maps (metalness of 0 and 1, an opacity of a few levels) come out holding only their
exemplar's levels (tghop.masks), aligned with the other maps; maps of many levels are left as they were."""

import json
import warnings

import numpy as np
import pytest

from tghop import ModelFileError, TGHop, data
from tghop.masks import channel_levels, mask_levels, snap_channels, snap_to_levels
from tghop.material import Material, example_maps
from tghop.modelfile import load_model, save_model

#: A small, fast joint model (as tests/test_material.py's).
FAST = dict(max_patches=1500, n_clusters=10, layout_factor=None)


@pytest.fixture(scope="module")
def made():
    """bricks' albedo, its example maps and two masks made from its luminance."""
    albedo = data.bricks()[:128, :128]
    lum = albedo.mean(axis=2)
    maps = example_maps(albedo)
    maps["metalness"] = (lum > np.quantile(lum, 0.6)).astype(np.float64)[..., None]
    maps["opacity"] = np.where(lum < 0.3, 0.0, np.where(lum < 0.5, 0.5, 1.0))[..., None]
    return albedo, maps


@pytest.fixture(scope="module")
def material(made):
    albedo, maps = made
    return Material(model=TGHop(**FAST), rng=0).fit(albedo, maps)


def test_mask_levels_are_a_maps_few_values_and_none_for_more():
    binary = np.zeros((20, 30, 1))
    binary[5:9, 3:20] = 1.0
    np.testing.assert_array_equal(mask_levels(binary), [[0.0], [1.0]])
    ramp = np.linspace(0, 1, 600).reshape(20, 30, 1)
    assert mask_levels(ramp) is None
    five = np.repeat(np.arange(5) / 4, 120).reshape(20, 30, 1)
    assert mask_levels(five) is None and mask_levels(five[:, :, :], most=5).shape == (5, 1)
    ids = np.zeros((20, 30, 3))
    ids[:10] = (1.0, 0.0, 0.0)
    ids[10:, :15] = (0.0, 1.0, 0.0)  # three colours: snapped as colours, not channel by channel
    assert mask_levels(ids).tolist() == [[0, 0, 0], [0, 1, 0], [1, 0, 0]]
    rare = binary.copy()
    rare[19, 29] = 0.5  # a value the sample misses: still found
    assert mask_levels(rare).shape == (3, 1)
    excluded = np.zeros((20, 30), dtype=bool)
    excluded[19, 29] = True
    assert mask_levels(rare, excluded).shape == (2, 1)


def test_snap_moves_each_value_to_its_nearest_level_and_no_pixel():
    img = np.array([[[0.1], [0.45], [0.55]], [[0.9], [1.0], [0.0]]], dtype=np.float32)
    out = snap_to_levels(img, [[0.0], [1.0]])
    assert out.dtype == np.float32 and out[..., 0].tolist() == [[0, 0, 1], [1, 1, 0]]
    ids = np.array([[[0.6, 0.4, 0.0], [0.2, 0.3, 0.1]]])
    np.testing.assert_array_equal(snap_to_levels(ids, [[0, 0, 0], [1, 0, 0], [0, 1, 0]]),
                                  [[[1, 0, 0], [0, 0, 0]]])


def test_a_mask_map_comes_out_at_its_levels_and_the_other_maps_as_before(material, made):
    # An artist's metalness of 0 and 1 came out with 0.3, 0.7 at its elements' edges (0.4 % of the pixels here).
    _, maps = made
    assert [lv is not None for lv in material.levels_] == [False, False, False, False, True, True]
    out = material.synthesize((160, 160), rng=1)
    for name in ("metalness", "opacity"):
        assert set(np.unique(out[name])) <= set(np.unique(maps[name])), name
    levels, material.levels_ = material.levels_, [None] * len(material.levels_)
    try:
        soft = material.synthesize((160, 160), rng=1)
    finally:
        material.levels_ = levels
    assert not set(np.unique(soft["metalness"])) <= {0.0, 1.0}  # what the snap is for
    for name in ("albedo", "normal", "roughness", "height"):  # maps of many levels: untouched
        np.testing.assert_array_equal(out[name], soft[name], err_msg=name)
    for name in ("metalness", "opacity"):  # aligned: each pixel's value moved to its nearest level, no pixel moved
        np.testing.assert_array_equal(out[name], snap_to_levels(soft[name], material.levels_[-2 if name[0] == "m"
                                                                                             else -1]))


def test_a_mask_maps_levels_are_kept_in_the_model_file(material, tmp_path):
    save_model(material, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz", material=True)
    assert [None if lv is None else lv.tolist() for lv in loaded.levels_] == \
        [None if lv is None else lv.tolist() for lv in material.levels_]
    made_here = material.synthesize((96, 96), rng=2)  # once: it was made again for each of the six maps
    for name, img in loaded.synthesize((96, 96), rng=2).items():
        np.testing.assert_array_equal(img, made_here[name], err_msg=name)
    with np.load(tmp_path / "m.npz") as f:
        arrays = dict(f)
    meta = json.loads(str(arrays["__meta__"]))
    for levels, words in (({"metalness": [[0.0], [2.0]]}, "levels of map 'metalness'"),
                          ({"normal": [[0.0, 0.0, 1.0]]}, "not the albedo.s or a normal map.s"),
                          ({"bark": [[0.0]]}, "levels are not a dict of its maps' names")):
        meta["material"]["levels"] = levels
        np.savez(tmp_path / "bad.npz", **{**arrays, "__meta__": np.array(json.dumps(meta))})
        with pytest.raises(ModelFileError, match=words):
            load_model(tmp_path / "bad.npz", material=True)
    del meta["material"]["levels"]  # a file of tghop 0.56: no levels, its maps as they come
    np.savez(tmp_path / "old.npz", **{**arrays, "__meta__": np.array(json.dumps(meta))})
    assert load_model(tmp_path / "old.npz", material=True).levels_ == [None] * 6


def test_a_mask_maps_hole_is_filled_at_its_levels(material, made):
    from tghop.inpaint import inpaint_material

    albedo, maps = made
    hole = np.zeros(albedo.shape[:2], dtype=bool)
    hole[40:90, 30:100] = True
    out = inpaint_material(material, {"albedo": albedo, **maps}, hole, rng=0, n_patches=1000)
    for name in ("metalness", "opacity"):
        assert set(np.unique(out[name][hole])) <= set(np.unique(maps[name])), name
        np.testing.assert_array_equal(out[name][~hole], maps[name][~hole])


def test_painted_materials_join_their_masks_at_their_levels(material, made):
    # Two materials painted side by side: the join's means of a metalness of 0 and 1 were 0.5 across the band.
    from tghop import synthesize_guided

    albedo, maps = made
    flipped = Material(model=TGHop(**FAST), rng=0).fit(albedo[:, ::-1], {k: v[:, ::-1] for k, v in maps.items()})
    guide = np.zeros((64, 96), np.uint8)
    guide[:, 48:] = 255
    out = synthesize_guided([material, flipped], guide, rng=2, transition=16, n_patches=1000)
    for name in ("metalness", "opacity"):
        assert set(np.unique(out[name])) <= set(np.unique(maps[name])), name
    assert len(np.unique(out["roughness"])) > 100


@pytest.fixture(scope="module")
def packed(made):
    """bricks' albedo, its normal map and an ORM (occlusion and roughness of many values, a metalness of 0 and 1)."""
    albedo, maps = made
    orm = np.concatenate([maps["height"], maps["roughness"], maps["metalness"]], axis=2)
    return albedo, {"normal": maps["normal"], "T_Rock_ORM": orm}


@pytest.fixture(scope="module")
def packed_material(packed):
    albedo, maps = packed
    return Material(model=TGHop(**FAST), rng=0).fit(albedo, maps)


def test_channel_levels_are_each_channels_few_values_and_snap_moves_only_those():
    img = np.zeros((20, 30, 3))
    img[..., 0] = np.linspace(0, 1, 600).reshape(20, 30)  # many values
    img[5:9, 3:20, 1] = 1.0  # 0 and 1
    img[..., 2] = 0.25  # one value
    got = channel_levels(img)
    assert got[0] is None and got[1].tolist() == [0.0, 1.0] and got[2].tolist() == [0.25]
    assert mask_levels(img) is None and channel_levels(img[..., :1]) is None
    soft = np.random.default_rng(0).random((4, 5, 3)).astype(np.float32)
    out = snap_channels(soft, got)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out[..., 0], soft[..., 0])
    np.testing.assert_array_equal(out[..., 1], np.where(soft[..., 1] > 0.5, 1.0, 0.0))
    assert (out[..., 2] == 0.25).all()
    assert snap_channels(soft, got, out=soft) is soft and np.array_equal(soft, out)


def test_a_packed_maps_mask_channel_comes_out_at_its_levels_and_the_rest_as_before(packed_material, packed):
    # An ORM's metalness of 0 and 1 came out with soft values at its elements' edges: its map has many values,
    # so it was not a mask map (tghop.masks.mask_levels), and its metalness was not snapped.
    _, maps = packed
    mat = packed_material
    assert mat.levels_ == [None, None, None]
    assert mat.channel_levels_[:2] == [None, None] and mat.channel_levels_[2][:2] == [None, None]
    assert mat.channel_levels_[2][2].tolist() == [0.0, 1.0]
    out = mat.synthesize((160, 160), rng=1)
    assert set(np.unique(out["T_Rock_ORM"][..., 2])) <= {0.0, 1.0}
    kept, mat.channel_levels_ = mat.channel_levels_, [None] * 3
    try:
        soft = mat.synthesize((160, 160), rng=1)
    finally:
        mat.channel_levels_ = kept
    assert not set(np.unique(soft["T_Rock_ORM"][..., 2])) <= {0.0, 1.0}  # what the snap is for
    for name in ("albedo", "normal"):
        np.testing.assert_array_equal(out[name], soft[name], err_msg=name)
    np.testing.assert_array_equal(out["T_Rock_ORM"][..., :2], soft["T_Rock_ORM"][..., :2])  # occlusion, roughness
    np.testing.assert_array_equal(out["T_Rock_ORM"][..., 2], np.where(soft["T_Rock_ORM"][..., 2] > 0.5, 1.0, 0.0))


def test_a_packed_maps_channel_levels_are_kept_in_the_model_file_and_old_files_load(packed_material, tmp_path):
    save_model(packed_material, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz", material=True)
    assert loaded.channel_levels_[2][2].tolist() == [0.0, 1.0] and loaded.channel_levels_[:2] == [None, None]
    np.testing.assert_array_equal(loaded.synthesize((96, 96), rng=2)["T_Rock_ORM"],
                                  packed_material.synthesize((96, 96), rng=2)["T_Rock_ORM"])
    with np.load(tmp_path / "m.npz") as f:
        arrays = dict(f)
    meta = json.loads(str(arrays["__meta__"]))
    assert meta["material"]["channel_levels"] == {"T_Rock_ORM": [None, None, [0.0, 1.0]]}
    assert "levels" not in meta["material"]
    for levels, words in (({"T_Rock_ORM": [None, None, [0.0, 2.0]]}, "channel levels of map 'T_Rock_ORM'"),
                          ({"T_Rock_ORM": [None, [0.0, 1.0]]}, "channel levels of map 'T_Rock_ORM'"),
                          ({"T_Rock_ORM": [None, None, 1.0]}, "channel levels of map 'T_Rock_ORM'"),
                          ({"T_Rock_ORM": [None, None, []]}, "channel levels of map 'T_Rock_ORM'"),
                          ({"normal": [[0.0], None, None]}, "channel levels are not a dict")):
        meta["material"]["channel_levels"] = levels
        np.savez(tmp_path / "bad.npz", **{**arrays, "__meta__": np.array(json.dumps(meta))})
        with pytest.raises(ModelFileError, match=words):
            load_model(tmp_path / "bad.npz", material=True)
    del meta["material"]["channel_levels"]  # a file of tghop 0.56: no channel levels, its maps as they come
    np.savez(tmp_path / "old.npz", **{**arrays, "__meta__": np.array(json.dumps(meta))})
    assert load_model(tmp_path / "old.npz", material=True).channel_levels_ == [None] * 3


def test_a_packed_maps_hole_and_painted_join_keep_its_mask_channel_at_its_levels(packed_material, packed):
    from tghop import synthesize_guided
    from tghop.inpaint import inpaint_material

    albedo, maps = packed
    hole = np.zeros(albedo.shape[:2], dtype=bool)
    hole[40:90, 30:100] = True
    out = inpaint_material(packed_material, {"albedo": albedo, **maps}, hole, rng=0, n_patches=1000)
    assert set(np.unique(out["T_Rock_ORM"][..., 2][hole])) <= {0.0, 1.0}
    np.testing.assert_array_equal(out["T_Rock_ORM"][~hole], maps["T_Rock_ORM"][~hole])
    flipped = Material(model=TGHop(**FAST), rng=0).fit(albedo[:, ::-1], {k: v[:, ::-1] for k, v in maps.items()})
    guide = np.zeros((64, 96), np.uint8)
    guide[:, 48:] = 255
    with warnings.catch_warnings():  # 0.59 read the mirrored normal map as OpenGL's and flipped it, warning
        warnings.simplefilter("error")  # 0.60: its slopes run against the ORM's occlusion: no convention known
        joined = synthesize_guided([packed_material, flipped], guide, rng=2, transition=16, n_patches=1000)
    assert flipped.conventions_ == [None, None, None]
    assert set(np.unique(joined["T_Rock_ORM"][..., 2])) <= {0.0, 1.0}
    assert len(np.unique(joined["T_Rock_ORM"][..., 1])) > 100


def test_info_shows_a_materials_mask_levels_and_its_packed_channels(material, packed_material, tmp_path):
    # 0.56's `tghop info` showed a two-level exemplar's levels but none of a material's masks.
    from click.testing import CliRunner

    from tghop.cli import main

    save_model(material, tmp_path / "m.npz")
    save_model(packed_material, tmp_path / "p.npz")
    runner = CliRunner()
    text = runner.invoke(main, ["info", str(tmp_path / "m.npz")])
    assert text.exit_code == 0, text.output
    assert "mask levels of metalness: 0, 1 (its images are snapped to them)" in text.output
    assert "mask levels of opacity: 0, 0.5, 1 (its images are snapped to them)" in text.output
    text = runner.invoke(main, ["info", str(tmp_path / "p.npz")])
    assert "mask levels of T_Rock_ORM, channel 3: 0, 1 (snapped to them)" in text.output
    assert "channel 1" not in text.output
    meta = json.loads(runner.invoke(main, ["info", "--json", str(tmp_path / "m.npz")]).output)["material"]
    assert meta["levels"] == {"metalness": [[0.0], [1.0]], "opacity": [[0.0], [0.5], [1.0]]}
    assert "channel_levels" not in meta
    meta = json.loads(runner.invoke(main, ["info", "--json", str(tmp_path / "p.npz")]).output)["material"]
    assert meta["channel_levels"] == {"T_Rock_ORM": [None, None, [0.0, 1.0]]}
