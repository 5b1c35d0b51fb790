"""Tampered model files (issue #26, item 5): every array is checked against the metadata at
load. Each case saves a small fitted model, rewrites the .npz with one array changed
(np.load, then np.savez of the modified dict) and expects one ModelFileError naming the
array, and from ``tghop synth`` / ``tghop patches`` one ``Error:`` line, exit 1, no
traceback and no output file.

Unknown arrays are refused, not ignored: what a format version holds is fixed (a new array
means a new version), so an array no part names is an edited file or another program's.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from tghop import ModelFileError, TGHopError
from tghop._estimator import fitted_settings
from tghop.modelfile import WITHOUT_MATERIAL_PATCHES, load_model, save_model


@pytest.fixture(scope="module")
def saved(small_model, tmp_path_factory):
    path = tmp_path_factory.mktemp("valid") / "m.npz"
    save_model(small_model, path)
    with np.load(path) as f:
        arrays = {k: f[k] for k in f.files}
    assert any(k.startswith("layout.") for k in arrays)  # the nested model is covered too
    return path, arrays


def _write(path, arrays):
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def _set(name, where, value):
    def change(a):
        a = a.copy()
        a[where] = value
        return a
    return name, change


def _complex(a):
    return a.astype(np.complex128) + 1j


#: (array, change of that array (None: delete it), fragment of the message)
CASES = {
    # wrong shape, every group
    "hop1 kernels": ("hop1.kernels", lambda a: a[:, :5], "has shape (9, 5)"),
    "hop2 bias": ("hop2.bias", lambda a: a[:-1], "has shape"),
    "hop2 channels": ("index.hop2_channels", lambda a: a[:-1], "has shape"),
    "hop1 energy": ("index.hop1_energy", lambda a: a[:, None], "has shape"),
    "sdr components": ("sdr.components", lambda a: a[:, :-1], "has shape"),
    "sdr mean": ("sdr.mean", lambda a: a[:-1], "has shape"),
    "sdr variance": ("index.sdr_variance", lambda a: a[:-1], "has shape"),
    "p": ("ichm_i.p", lambda a: a[:-1], "sums to"),  # the first array with N: its sum is wrong
    "means": ("ichm_ii.means", lambda a: a[:, :-1], "has shape"),
    "mixing rows": ("ichm_ii.mixing", lambda a: a[:-1], "has shape"),
    "mixing scale": ("index.ichm_mixing_scale", lambda a: a[:5], "mixing scales"),
    "cdf min": ("ichm_iii.cdf_min", lambda a: a[:-1], "has shape"),
    "residual": ("residual.factor", lambda a: np.ones(3), "has shape"),
    "residual group": ("index.ichm_residual_group", lambda a: np.zeros(4, dtype=np.int64), "has shape"),
    "colour quantiles": ("colour.quantiles", lambda a: a[:2], "has shape"),
    "colour basis": ("refine.colour_basis", lambda a: a[:2], "has shape"),
    "band quantiles": ("refine.band_quantiles", lambda a: a[:, :3], "has shape"),
    "pixel quantiles": ("refine.pixel_quantiles", lambda a: a[:, :-1], "has shape"),
    "layout sdr mean": ("layout.sdr.mean", lambda a: a[:-1], "has shape"),
    "layout hop2 kernels": ("layout.hop2.kernels", lambda a: a[:, :3], "has shape"),
    # bad index
    "hop1 parent": _set("index.hop1_channels", (0, 0), 5) + ("outside 0..0",),
    "hop2 parent": _set("index.hop2_channels", (-1, 0), 99) + ("outside 0..8",),
    "hop2 kernel": _set("index.hop2_channels", (0, 1), 4) + ("outside 0..3",),
    "hop1 kernel": _set("index.hop1_channels", (2, 1), -1) + ("outside 0..11",),
    "hop2 ungrouped": ("index.hop2_channels", lambda a: a[::-1].copy(), "not non-decreasing"),
    "sdr channel": _set("index.sdr_channel", -1, 22) + ("outside 0..21",),
    "cdf index": ("ichm_iii.cdf_index", lambda a: a + 100, "outside 0.."),
    "cdf index negative": _set("ichm_iii.cdf_index", 0, -1) + ("index -1",),
    "no components": _set("index.ichm_n_components", 0, 0) + ("below 1",),
    "too many components": _set("index.ichm_n_components", 0, 10_000) + ("above 100",),
    "layout cdf index": ("layout.ichm_iii.cdf_index", lambda a: a + 1000, "outside"),
    # truncated codebook (bins or codewords)
    "codebook bins": ("ichm_iii.codebook", lambda a: a[:, :128], "has shape (40, 128)"),
    "codebook words": ("ichm_iii.codebook", lambda a: a[:-1], "CDFs"),
    # reversed quantiles and CDFs
    "colour reversed": ("colour.quantiles", lambda a: a[:, ::-1].copy(), "not non-decreasing"),
    "pixel reversed": ("refine.pixel_quantiles", lambda a: a[:, ::-1].copy(), "not non-decreasing"),
    "band reversed": ("refine.band_quantiles", lambda a: a[..., ::-1].copy(), "not non-decreasing"),
    "codebook reversed": ("ichm_iii.codebook", lambda a: a[:, ::-1].copy(), "not non-decreasing"),
    "norms reversed": ("ichm_iv.norm_quantiles", lambda a: a[:, ::-1].copy(), "not non-decreasing"),
    "negative norms": ("layout.ichm_iv.sampled_norm_quantiles", lambda a: a - 1e3, "below 0.0"),
    "norms truncated": ("ichm_iv.sampled_norm_quantiles", lambda a: a[:, :-1], "has shape"),
    "ranks truncated": ("ichm_coupling.member_ranks", lambda a: a[:-1], "has shape"),
    "ranks out of range": ("layout.ichm_coupling.member_ranks", lambda a: a.astype(np.int16) + 256, "above 255"),
    "float ranks": ("ichm_coupling.member_ranks", lambda a: a.astype(np.float32), "not integers"),
    "no members": _set("index.ichm_member_counts", 0, 0) + ("below 1",),
    "member counts short": ("index.ichm_member_counts", lambda a: a[:-1], "has shape"),
    "layout colour reversed": ("layout.colour.quantiles", lambda a: a[:, ::-1].copy(), "not non-decreasing"),
    # complex, wrong dtype
    "complex kernels": ("hop1.kernels", _complex, "complex128, not real"),
    "complex mixing": ("ichm_ii.mixing", lambda a: a.astype(np.complex64), "complex64, not real"),
    "complex layout p": ("layout.ichm_i.p", _complex, "complex128"),
    "float index": ("index.hop1_channels", lambda a: a.astype(np.float64), "not integers"),
    "integer p": ("ichm_i.p", lambda a: (a * 0).astype(np.int64), "not real"),
    "bool kernels": ("hop2.kernels", lambda a: a > 0, "bool"),
    "text codebook": ("ichm_iii.codebook", lambda a: a.astype(str), "not real"),
    # NaN or infinity
    "nan bias": _set("hop1.bias", 0, np.nan) + ("NaN",),
    "inf cdf max": _set("ichm_iii.cdf_max", 3, np.inf) + ("NaN or infinite",),
    "nan colour mean": _set("refine.colour_mean", 1, np.nan) + ("NaN",),
    "nan mixing": _set("ichm_ii.mixing", (2, 2), np.nan) + ("NaN",),
    "nan layout means": _set("layout.ichm_ii.means", (0, 0), np.nan) + ("NaN",),
    # values out of range
    "p sum": ("ichm_i.p", lambda a: a * 2, "sums to"),
    "p negative": ("ichm_i.p", lambda a: a + np.r_[0.5, np.zeros(len(a) - 2), -0.5], "not positive"),
    "zero scale": _set("index.ichm_mixing_scale", 0, 0.0) + ("not positive",),
    "cdf range": ("ichm_iii.cdf_max", lambda a: a - 1e3, "below those of ichm_iii.cdf_min"),
    "codebook above 1": ("ichm_iii.codebook", lambda a: a * 2, "above 1.0"),
    "codebook end": ("ichm_iii.codebook", lambda a: a * 0.5, "do not end at 1.0"),
    "colour basis": ("refine.colour_basis", lambda a: a * 2, "not an orthonormal basis"),
    "colour above 1": ("colour.quantiles", lambda a: a + 2, "above 1.0"),
    "negative variance": _set("index.sdr_variance", 0, -1.0) + ("below 0",),
    "huge means": _set("ichm_ii.means", (0, 0), 1e30) + ("beyond 10000",),
    "huge layout cdf": ("layout.ichm_iii.cdf_max", lambda a: a * 1e6, "beyond 10000"),
    "long directions": ("patch.directions", lambda a: a * np.float32(1.001), "not of unit length"),
    "short layout direction": _set("layout.patch.directions", (0, 1, 2, 3), 0.0) + ("not of unit length",),
    # missing and unknown arrays
    "missing mixing": ("ichm_ii.mixing", None, "array ichm_ii.mixing is missing"),
    "missing kernels": ("hop2.kernels", None, "array hop2.kernels is missing"),
    "missing quantiles": ("refine.band_quantiles", None, "is missing"),
    "missing layout": ("layout.ichm_iii.codebook", None, "array layout.ichm_iii.codebook is missing"),
    "unknown": ("extra.thing", lambda a: np.zeros(3), "array extra.thing is not part of a tghop model"),
}


def _tampered(saved, tmp_path, case):
    name, change, fragment = CASES[case]
    arrays = dict(saved[1])
    if change is None:
        del arrays[name]
    else:
        arrays[name] = change(arrays.get(name))
    path = tmp_path / "t.npz"
    _write(path, arrays)
    return path, name, fragment


@pytest.mark.parametrize("case", sorted(CASES))
def test_tampered_array_is_one_model_file_error_naming_it(saved, tmp_path, case):
    path, name, fragment = _tampered(saved, tmp_path, case)
    with pytest.raises(ModelFileError) as info:
        load_model(path)
    message = str(info.value)
    assert "\n" not in message
    assert name in message and fragment in message, message
    assert "fit the model again" in message and "np." not in message  # plain numbers, not NumPy's reprs
    # 0.62: the file, what happened to it and the fix first, then the internal array names (0.61 began with them)
    head = (f"{path}: this model file was edited, damaged or written by another program, so tghop cannot use it; fit "
            f"the model again from its exemplar: tghop fit EXEMPLAR -o {path} ")
    assert message.startswith(head) and message.index(name) > len(head), message


@pytest.mark.parametrize("case", ["hop1 kernels", "hop2 parent", "codebook bins", "colour reversed",
                                  "complex kernels", "nan layout means", "missing mixing", "unknown",
                                  "text codebook", "p sum"])
@pytest.mark.parametrize("verb", ["synth", "patches"])
def test_cli_on_tampered_model_gives_one_error_line(saved, tmp_path, case, verb):
    from click.testing import CliRunner

    from tghop.cli import main

    path, name, _ = _tampered(saved, tmp_path, case)
    out = tmp_path / "out.png"
    args = [verb, str(path), "-o", str(out)] + (["--size", "48", "-q"] if verb == "synth" else ["-n", "4"])
    result = CliRunner().invoke(main, args, catch_exceptions=True)
    assert result.exit_code == 1, (result.output, repr(result.exception))
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert "Traceback" not in result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("Error: ")]
    assert len(errors) == 1 and name in errors[0], result.stderr
    assert sorted(os.listdir(tmp_path)) == ["t.npz"]


def test_cli_subprocess_on_tampered_model(saved, tmp_path):
    import subprocess
    import sys

    from conftest import assert_user_error

    path, name, _ = _tampered(saved, tmp_path, "hop1 kernels")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(p) for p in sys.path if p])}
    for args in (["synth", str(path), "-o", str(tmp_path / "o.png"), "--size", "48"],
                 ["patches", str(path), "-n", "4", "-o", str(tmp_path / "g.png")]):
        r = subprocess.run([sys.executable, "-m", "tghop", *args], capture_output=True, env=env)
        assert_user_error(r, "hop1.kernels has shape (9, 5)", "the metadata says 9 channels of 12 inputs")
        assert r.returncode == 1
    assert sorted(os.listdir(tmp_path)) == ["t.npz"]


def test_metadata_that_disagrees_with_itself_is_refused(saved, tmp_path):
    path, arrays = saved
    meta = json.loads(str(arrays["__meta__"]))
    for change, fragment in ((lambda m: m["hop_dims"].__setitem__(1, 7), "hop 1"),
                             (lambda m: m["hops"][1].__setitem__("n_channels_in", 8), "hop 2"),
                             (lambda m: m.__setitem__("sdr_shape", [4, 4, 22]), "sdr_shape"),
                             (lambda m: m.__setitem__("exemplar_shape", [96, 96, 4]), "exemplar_shape"),
                             (lambda m: m.__setitem__("hops", m["hops"][:1]), "hops"),
                             (lambda m: m["layout"]["model"].__setitem__("exemplar_shape", [48, 48, 1]), "layout")):
        bad = json.loads(json.dumps(meta))
        change(bad)
        _write(tmp_path / "t.npz", {**arrays, "__meta__": np.array(json.dumps(bad))})
        with pytest.raises(ModelFileError, match=fragment):
            load_model(tmp_path / "t.npz")


def test_valid_files_still_load_and_generate_the_same_image(small_model, saved, tmp_path):
    # Saved and loaded: bit for bit the image of the fitted model; version 2 files load.
    path, arrays = saved
    loaded = load_model(path)
    np.testing.assert_array_equal(loaded.synthesize((48, 40), rng=3, n_patches=200),
                                  small_model.synthesize((48, 40), rng=3, n_patches=200))
    meta = json.loads(str(arrays["__meta__"]))
    meta["format_version"] = 2
    meta["params"]["patch_levels"] = 0  # version 2 had no patch statistics
    old = {k: v for k, v in arrays.items() if not k.endswith("index.ichm_mixing_scale") and not k.startswith("patch.")}
    old["ichm_ii.mixing"] = small_model.ichm_.mixing_.astype(np.float32)
    old["layout.ichm_ii.mixing"] = small_model.layout_.model_.ichm_.mixing_.astype(np.float32)
    old["__meta__"] = np.array(json.dumps(meta))
    _write(tmp_path / "v2.npz", old)
    assert load_model(tmp_path / "v2.npz").synthesize((32, 32), rng=1, n_patches=100).shape == (32, 32, 3)
    # A version 3 file must have its scales.
    _write(tmp_path / "noscale.npz", {k: v for k, v in arrays.items() if k != "index.ichm_mixing_scale"})
    with pytest.raises(ModelFileError, match="index.ichm_mixing_scale is missing"):
        load_model(tmp_path / "noscale.npz")


def test_files_without_the_component_ratio_read_as_fitted(saved, tmp_path):
    # Files of tghop 0.26 and before had no max_component_ratio: their clusters were capped at
    # their size less one only, which is 1.0, not today's default, in their settings.
    path, arrays = saved
    assert load_model(path).max_component_ratio == 0.5
    meta = json.loads(str(arrays["__meta__"]))
    del meta["params"]["max_component_ratio"]
    del meta["layout"]["model"]["params"]["max_component_ratio"]
    _write(tmp_path / "old.npz", {**arrays, "__meta__": np.array(json.dumps(meta))})
    old = load_model(tmp_path / "old.npz")
    assert old.max_component_ratio == 1.0 and old.layout_.model_.max_component_ratio == 1.0


#: Settings added after model files existed, and their arrays: (its value in a new file, the
#: format version before it, fragments of its arrays' names, attributes of ICHM empty without
#: it, the first of its arrays that a file of today's version without them lacks).
ADDED = {
    "norm_match": (1.0, 6, ("ichm_iv.",), ("norm_quantiles_", "sampled_norm_quantiles_"), "ichm_iv.norm_quantiles"),
    "coupling": (0.95, 7, ("ichm_coupling.", "index.ichm_member_counts"), ("member_ranks_", "member_counts_"),
                 "index.ichm_member_counts"),
}


@pytest.mark.parametrize("setting", sorted(ADDED))
def test_files_without_a_later_setting_read_as_fitted(saved, tmp_path, setting):
    # Files written before a setting was added were fitted without it (0: the paper's
    # independent draws, settings.BEFORE_ADDED) and hold none of its arrays. A file of
    # today's version with the setting on must hold them.
    value, version, parts, attrs, first = ADDED[setting]
    path, arrays = saved
    meta = json.loads(str(arrays["__meta__"]))
    assert meta["format_version"] == WITHOUT_MATERIAL_PATCHES and meta["params"][setting] == value
    assert meta["layout"]["model"]["params"][setting] == value
    del meta["params"][setting]
    del meta["layout"]["model"]["params"][setting]
    meta["format_version"] = version
    old_arrays = {k: v for k, v in arrays.items() if not any(part in k for part in parts)}
    assert len(old_arrays) == len(arrays) - 4  # two in the model and two in its layout model
    _write(tmp_path / "old.npz", {**old_arrays, "__meta__": np.array(json.dumps(meta))})
    old = load_model(tmp_path / "old.npz")
    assert getattr(old, setting) == 0.0 and getattr(old.layout_.model_, setting) == 0.0
    assert all(getattr(old.ichm_, attr).size == 0 for attr in attrs)
    plain = load_model(path)
    setattr(plain.ichm_, setting, 0.0)
    setattr(plain.layout_.model_.ichm_, setting, 0.0)
    for model in (plain, plain.layout_.model_):  # set by hand as in a file before the setting
        model._fitted_params = fitted_settings(model)
    expected = plain.synthesize((48, 48), rng=2, n_patches=200)
    assert np.array_equal(old.synthesize((48, 48), rng=2, n_patches=200), expected)
    assert not np.array_equal(load_model(path).synthesize((48, 48), rng=2, n_patches=200), expected)
    _write(tmp_path / "missing.npz", {**old_arrays, "__meta__": arrays["__meta__"]})
    with pytest.raises(ModelFileError, match=f"{first} is missing"):
        load_model(tmp_path / "missing.npz")


def test_files_without_colour_classes_read_as_fitted(saved, tmp_path):
    # Version 8 files (tghop 0.32) have no colour classes: they load with none and generate
    # as own_shares 0 (the exemplar's histograms); today's files hold the classes' arrays.
    path, arrays = saved
    meta = json.loads(str(arrays["__meta__"]))
    assert meta["params"]["colour_classes"] == 4 and meta["layout"]["model"]["params"]["colour_classes"] == 0
    del meta["params"]["colour_classes"], meta["layout"]["model"]["params"]["colour_classes"]
    meta["format_version"] = 8
    old_arrays = {k: v for k, v in arrays.items()
                  if not k.endswith(("class_quantiles", "centres", "shares", "separation", "share_spread"))}
    assert len(old_arrays) == len(arrays) - 6
    _write(tmp_path / "old.npz", {**old_arrays, "__meta__": np.array(json.dumps(meta))})
    old = load_model(tmp_path / "old.npz")
    assert old.colour_classes == 0 and old.classes_ is None
    expected = load_model(path).synthesize((48, 48), rng=2, n_patches=200, own_shares=0.0)
    assert np.array_equal(old.synthesize((48, 48), rng=2, n_patches=200), expected)
    _write(tmp_path / "missing.npz", {**old_arrays, "__meta__": arrays["__meta__"]})
    with pytest.raises(ModelFileError, match="colour.centres is missing"):
        load_model(tmp_path / "missing.npz")
    bad = {**arrays, "colour.shares": arrays["colour.shares"] * 2}
    _write(tmp_path / "bad.npz", bad)
    with pytest.raises(ModelFileError, match="colour.shares sums to"):
        load_model(tmp_path / "bad.npz")


def test_files_without_the_coarse_patch_statistics_read_as_fitted(saved, tmp_path):
    # Version 9 files (tghop 0.47) have no patch statistics in the coarse layout model: they load
    # with none and generate as layout_patch_refine 0; today's files hold them (layout.patch.*).
    path, arrays = saved
    meta = json.loads(str(arrays["__meta__"]))
    assert meta["layout"]["params"]["patch_levels"] == 3 == meta["layout"]["model"]["params"]["patch_levels"]
    del meta["layout"]["params"]["patch_levels"]
    meta["layout"]["model"]["params"]["patch_levels"] = 0
    meta["format_version"] = 9
    old_arrays = {k: v for k, v in arrays.items() if not k.startswith("layout.patch.")}
    assert len(old_arrays) == len(arrays) - 3  # the directions, quantiles and their levels
    _write(tmp_path / "old.npz", {**old_arrays, "__meta__": np.array(json.dumps(meta))})
    old = load_model(tmp_path / "old.npz")
    assert old.layout_.patch_levels == 0 and old.layout_.model_.patches_ is None
    new = load_model(path)
    expected = new.synthesize((64, 64), rng=2, n_patches=200, layout_patch_refine=0)
    assert np.array_equal(old.synthesize((64, 64), rng=2, n_patches=200), expected)
    assert not np.array_equal(new.synthesize((64, 64), rng=2, n_patches=200), expected)
    _write(tmp_path / "missing.npz", {**old_arrays, "__meta__": arrays["__meta__"]})
    with pytest.raises(ModelFileError, match="layout.patch.directions is missing"):
        load_model(tmp_path / "missing.npz")


def test_the_fit_seed_is_recorded_and_files_without_one_load(small_model, saved, tmp_path):
    # Files recorded "rng": null although the fit had an int seed, so `tghop info` could not show it.
    import copy

    from tghop.modelfile import info_dict

    path, arrays = saved
    meta = json.loads(str(arrays["__meta__"]))
    assert meta["params"]["rng"] == 0 and meta["layout"]["params"]["rng"] is None  # the layout's: a Generator
    assert load_model(path).rng == 0 and info_dict(load_model(path))["fit_seed"] == 0
    other = copy.copy(small_model)
    for rng, recorded in ((np.int64(5), 5), (np.random.default_rng(0), None), (None, None)):
        other.rng = rng  # as if fitted with it (the settings it was fitted with too)
        other._fitted_params = fitted_settings(other)
        assert other._state_meta()["params"]["rng"] == recorded and info_dict(other)["fit_seed"] == recorded
    expected = small_model.synthesize((32, 32), rng=1, n_patches=100)
    for old in (None, "x", True, -1, 1.5):  # files of 0.32 and before (null), and edited ones: no seed
        meta["params"]["rng"] = old
        _write(tmp_path / "old.npz", {**arrays, "__meta__": np.array(json.dumps(meta))})
        loaded = load_model(tmp_path / "old.npz")
        assert loaded.rng is None and info_dict(loaded)["fit_seed"] is None
        assert np.array_equal(loaded.synthesize((32, 32), rng=1, n_patches=100), expected)


def test_a_parts_generator_is_recorded_older_files_load_without_it_and_a_bad_record_is_refused(small_model, saved,
                                                                                                   tmp_path):
    from tghop.settings import BIT_GENERATORS, generator_from_record, generator_record

    path, arrays = saved
    meta = json.loads(str(arrays["__meta__"]))
    assert meta["ichm_rng"]["bit_generator"] == "PCG64" and meta["ichm_rng"]["seed"] == 0
    loaded = load_model(path)
    assert loaded.ichm_.rng.bit_generator.state == small_model.ichm_.rng.bit_generator.state
    for name in BIT_GENERATORS:  # every NumPy bit generator, arrays in its state too (MT19937's key, Philox's)
        rng = np.random.Generator(getattr(np.random, name)(7))
        rng.random(3)
        back = generator_from_record(json.loads(json.dumps(generator_record(rng))))
        assert type(back.bit_generator) is type(rng.bit_generator) and back.random(4).tolist() == rng.random(4).tolist()
    assert generator_record(3) is None and generator_record(None) is None and generator_from_record(None) is None
    old = {k: v for k, v in meta.items() if k != "ichm_rng"}  # files of tghop 0.56 and before
    old["layout"] = {k: v for k, v in meta["layout"].items() if k not in ("rng", "model_rng")}
    _write(tmp_path / "old.npz", {**arrays, "__meta__": np.array(json.dumps(old))})
    old_model = load_model(tmp_path / "old.npz")
    assert old_model.ichm_.rng is None and old_model.layout_.rng is None and old_model.layout_.model_.rng is None
    for bad in ({"bit_generator": "os.system", "seed": 0, "state": {}}, {"state": 1},
                {**meta["ichm_rng"], "state": {"bit_generator": "PCG64", "state": "x"}}):
        _write(tmp_path / "bad.npz", {**arrays, "__meta__": np.array(json.dumps({**meta, "ichm_rng": bad}))})
        with pytest.raises(ModelFileError, match=r"^.*bad\.npz: this model file was edited, .*\(what is wrong: the "
                                                 r"metadata's ichm_rng "):
            load_model(tmp_path / "bad.npz")


def test_a_loaded_models_saabs_have_every_channels_energy_and_older_files_say_why_not(small_model, saved, tmp_path):
    # Saab.energy_ (every channel's, kept or not) was not in model files: a loaded model's Saabs had none, a bare
    # AttributeError. The metadata holds it now (no array, so the format version and older readers are unchanged).
    path, arrays = saved

    def saabs(model):
        return [s for m in (model, model.layout_.model_) for hop in m.hops_.hops_ for s in hop.saabs_]

    fitted, loaded = saabs(small_model), saabs(load_model(path))
    assert len(loaded) == len(fitted) == 1 + 9 + 1 + 9  # a joint and a channel-wise hop, in each model
    assert all(np.array_equal(a.energy_, b.energy_) for a, b in zip(fitted, loaded))
    # Its other kernels are not in the file: keep() said "'Saab' object has no attribute '_all_kernels_'".
    with pytest.raises(TGHopError, match=r"^this Saab was loaded from a model file, which keeps the kept channels' "
                                         r"kernels only; fit it again"):
        loaded[0].keep([0, 1])
    meta = json.loads(str(arrays["__meta__"]))
    for part in (meta, meta["layout"]["model"]):  # a file of tghop 0.55: loads, and energy_ says why it is absent
        for hop in part["hops"]:
            del hop["saab_energy"]
    _write(tmp_path / "old.npz", {**arrays, "__meta__": np.array(json.dumps(meta))})
    old = saabs(load_model(tmp_path / "old.npz"))
    assert not [s for s in old if hasattr(s, "energy_")]
    with pytest.raises(AttributeError, match=r"^this Saab was loaded from a model file of tghop 0.55 or "
                                             r"before, which keeps the kept channels' energies only"):
        old[0].energy_
    # An edited file: one line, not a traceback.
    for bad in ([[1.0] * 12] * 2, [[1.0] * 11], [[True] * 12], [[1e400] * 12], "x"):
        meta["hops"][0]["saab_energy"] = bad
        _write(tmp_path / "bad.npz", {**arrays, "__meta__": np.array(json.dumps(meta))})
        with pytest.raises(ModelFileError, match=r"; fit the model again .*saab_energy of a hop .*\)$"):
            load_model(tmp_path / "bad.npz")


def test_a_file_of_a_newer_tghop_warns_naming_both_versions(saved, tmp_path):
    # It loaded without a word; a setting it added was "unknown setting setting 'x'; fit the model again".
    import warnings

    from tghop import __version__

    path, arrays = saved
    meta = json.loads(str(arrays["__meta__"]))

    def load(version, **params):
        changed = {**meta, "tghop_version": version, "params": {**meta["params"], **params}}
        _write(tmp_path / "v.npz", {**arrays, "__meta__": np.array(json.dumps(changed))})
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            load_model(tmp_path / "v.npz")
        return [str(w.message) for w in caught]

    said = load("99.0.0")
    assert len(said) == 1 and f"made by tghop 99.0.0, newer than this {__version__}" in said[0], said
    assert "upgrade tghop" in said[0]
    for version in ("0.1.0", __version__, f"{__version__}.dev1", "not a version", None, 7):
        assert load(version) == [], version
    with pytest.raises(ModelFileError, match=r"v\.npz: made by tghop 99\.0\.0, newer than this .*, and this one cannot "
                                             r"use it; upgrade tghop, or fit the model again .*unknown setting "
                                             r"'brand_new'\)$"):
        load("99.0.0", brand_new=1)


@pytest.mark.parametrize("version", [-3, 0, 1])
def test_a_format_version_below_any_this_tghop_wrote_is_an_edited_file(saved, tmp_path, version):
    # 0.61: "written in model format version -3 (by tghop 0.61.0), but this tghop 0.61.0 reads versions 2 to 11;
    # refit the model with this version", of a file this very version wrote and someone edited.
    from tghop import __version__

    path, arrays = saved
    meta = json.loads(str(arrays["__meta__"]))
    _write(tmp_path / "v.npz", {**arrays, "__meta__": np.array(json.dumps({**meta, "format_version": version}))})
    with pytest.raises(ModelFileError) as caught:
        load_model(tmp_path / "v.npz")
    assert str(caught.value) == (
        f"{tmp_path / 'v.npz'}: this model file was edited, damaged or written by another program, so tghop cannot use "
        f"it; fit the model again from its exemplar: tghop fit EXEMPLAR -o {tmp_path / 'v.npz'} (what is wrong: "
        f"format_version {version}, which tghop {__version__} does not write)")
    # a file of an older tghop in a version this one no longer reads is still told to refit
    _write(tmp_path / "old.npz", {**arrays, "__meta__": np.array(json.dumps(
        {**meta, "format_version": 1, "tghop_version": "0.1.0"}))})
    with pytest.raises(ModelFileError, match=r"written in model format version 1 \(by tghop 0\.1\.0\), but this "):
        load_model(tmp_path / "old.npz")


def test_npy_file_and_missing_paths_are_one_line_errors(tmp_path, small_model):
    from tghop import TGHopError
    from tghop.modelfile import info_dict

    np.save(tmp_path / "arr.npy", np.zeros(3))
    with pytest.raises(ModelFileError, match=r"arr\.npy: a NumPy array file \(\.npy\), not a tghop model file"):
        load_model(tmp_path / "arr.npy")
    with pytest.raises(ModelFileError, match="load_model: path must be a file name.*got None"):
        load_model(None)
    with pytest.raises(ModelFileError, match="save_model: path must be a file name.*got None"):
        save_model(small_model, None)
    with pytest.raises(TGHopError, match="info_dict: model must be a fitted TGHop.*got str"):
        info_dict("x")
    with pytest.raises(TGHopError, match="info_dict: params must be None"):
        info_dict(small_model, params="x")
    assert info_dict(small_model)["n_parameters"] == small_model.n_parameters()
    params = small_model.n_parameters()  # what tghop info and the server pass, as a dict
    assert info_dict(small_model, params=params)["n_parameters"] is params


def test_a_changed_byte_or_a_cut_member_of_the_archive_is_refused(saved, tmp_path):
    path, arrays = saved
    # One byte of an array's values changed (a value that passes every check): the archive's CRC refuses it.
    blob = bytearray(path.read_bytes())
    values = arrays["ichm_ii.mixing"].tobytes()
    at = bytes(blob).index(values[: 64]) + 32
    blob[at] ^= 1
    (tmp_path / "flipped.npz").write_bytes(bytes(blob))
    with pytest.raises(ModelFileError, match=r"flipped\.npz: truncated, corrupt or not a tghop model file"):
        load_model(tmp_path / "flipped.npz")
    # A member cut short inside the archive (its size in the directory kept): refused the same way.
    cut = bytearray(path.read_bytes())
    del cut[at: at + 8]
    (tmp_path / "cut.npz").write_bytes(bytes(cut))
    with pytest.raises(ModelFileError, match=r"cut\.npz: truncated, corrupt or not a tghop model file"):
        load_model(tmp_path / "cut.npz")


def test_directions_within_the_tolerance_of_unit_length_load(saved, tmp_path):
    path, arrays = saved
    scale = np.float32(1 + 5e-5)  # lengths off by less than the check's 1e-4
    _write(tmp_path / "d.npz", {**arrays, "patch.directions": arrays["patch.directions"] * scale,
                                "layout.patch.directions": arrays["layout.patch.directions"] / scale})
    assert load_model(tmp_path / "d.npz").patches_ is not None


def test_an_array_of_objects_and_a_file_of_text_are_named_as_such(saved, tmp_path):
    # Both said "truncated, corrupt or not a tghop model file (cannot read it: ValueError); fit the
    # model again": NumPy's refusal to unpickle, which a text file meets too.
    path, arrays = saved
    _write(tmp_path / "objects.npz", {**arrays, "hop1.kernels": np.array([{"a": 1}], dtype=object)})
    with pytest.raises(ModelFileError) as error:
        load_model(tmp_path / "objects.npz")
    assert str(error.value) == (f"{tmp_path / 'objects.npz'}: not a tghop model file (an array of Python objects, "
                                "which tghop does not unpickle); give a model file tghop wrote")
    (tmp_path / "notes.npz").write_text("hello\n")
    with pytest.raises(ModelFileError, match=r"notes\.npz: not a tghop model file \(not a NumPy archive\)"):
        load_model(tmp_path / "notes.npz")


def _bytes(arrays):
    import io

    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def test_a_model_goes_into_and_comes_from_a_file_object(small_model, saved, tmp_path):
    # 0.57 took a path only ("path must be a file name"): a notebook or a web service could not keep a model in memory.
    import io

    path, arrays = saved
    buf = io.BytesIO()
    save_model(small_model, buf)
    with pytest.raises(ModelFileError, match=r"^the BytesIO given: nothing left to read, it is at its end \(position "
                                             r"\d+\); seek\(0\) after writing the model into it$"):
        load_model(buf)
    buf.seek(0)
    expected = small_model.synthesize((32, 32), rng=1, n_patches=100)
    assert np.array_equal(load_model(buf).synthesize((32, 32), rng=1, n_patches=100), expected)
    assert buf.tell() == 0 and not buf.closed  # left open, at its start
    with open(tmp_path / "f.npz", "wb") as fh:
        save_model(small_model, fh)
    with open(tmp_path / "f.npz", "rb") as fh:
        assert np.array_equal(load_model(fh).synthesize((32, 32), rng=1, n_patches=100), expected)

    class Stream:  # no seek, no tell: an HTTP body
        def __init__(self, data):
            self.read = io.BytesIO(data).read

    assert np.array_equal(load_model(Stream(buf.getvalue())).synthesize((32, 32), rng=1, n_patches=100), expected)

    class Seekable:  # read, seek and tell, nothing else
        def __init__(self, data):
            inner = io.BytesIO(data)
            self.read, self.seek, self.tell, self.seekable = inner.read, inner.seek, inner.tell, inner.seekable

    assert load_model(Seekable(buf.getvalue())).dims_ == small_model.dims_
    after = io.BytesIO()
    after.write(b"header")
    save_model(small_model, after)  # written at its position, as np.savez writes
    after.seek(6)
    assert load_model(after).dims_ == small_model.dims_
    with pytest.raises(ModelFileError, match=r"^the BytesIO given is empty; give one a model was written into"):
        load_model(io.BytesIO())
    with pytest.raises(ModelFileError, match=r"^load_model: the StringIO given is open in text mode; a model file is "
                                             r"binary: open it with mode 'rb' \(or give its name\)$"):
        load_model(io.StringIO("x"))
    with open(tmp_path / "t.npz", "w") as fh, pytest.raises(ModelFileError, match=r"^save_model: .*t\.npz is open in "
                                                                                   r"text mode; .* mode 'wb'"):
        save_model(small_model, fh)
    with open(path, "rb") as fh, pytest.raises(ModelFileError, match=r"^save_model: cannot write the model into "
                                                                     r".*m\.npz \(not open for writing\)"):
        save_model(small_model, fh)
    fh = open(path, "rb")
    fh.close()
    with pytest.raises(ModelFileError, match=r"^load_model: .*m\.npz is closed; give an open file object"):
        load_model(fh)
    assert path.read_bytes()[:4] == b"PK\x03\x04"  # the file given to save_model opened for reading is unchanged


def test_a_file_objects_model_gets_every_check_a_files_does(saved, tmp_path, monkeypatch):
    import io
    import zipfile

    path, arrays = saved
    meta = json.loads(str(arrays["__meta__"]))
    cases = [  # (content, message)
        (_bytes({**arrays, "__meta__": np.array(json.dumps({**meta, "format_version": 99}))}),
         r"the BytesIO given: written in model format version 99 \(by tghop .*\), but this tghop .* reads versions"),
        (_bytes({"weights": np.zeros(3)}), r"the BytesIO given: a NumPy archive but not a tghop model file"),
        (_bytes({**arrays, "hop1.kernels": np.array([{"a": 1}], dtype=object)}),
         r"the BytesIO given: not a tghop model file \(an array of Python objects, which tghop does not unpickle\)"),
        (_bytes({**arrays, "hop1.kernels": arrays["hop1.kernels"][:, :5]}),
         r"the BytesIO given: this model file was edited, .* \(what is wrong: hop1\.kernels has shape \(9, 5\) but "
         r"should be"),
        (_bytes(arrays)[:50_000], r"the BytesIO given: truncated, corrupt or not a tghop model file"),
        (_png(tmp_path),
         r"the BytesIO given is an image, not a model file; fit a model from it first: TGHop\(\)\.fit"),
    ]
    for content, message in cases:
        with pytest.raises(ModelFileError, match="^" + message) as caught:
            load_model(io.BytesIO(content))
        assert "\n" not in str(caught.value)
    bomb = io.BytesIO()
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as archive:
        with archive.open("zeros.npy", "w", force_zip64=True) as member:
            for _ in range(80):
                member.write(bytes(1 << 20))

    def unpacked(*args, **kwargs):
        raise AssertionError("np.load was called on the bomb")

    monkeypatch.setattr(np, "load", unpacked)
    with pytest.raises(ModelFileError, match=r"^the BytesIO given: its contents unpack to 80 MB from a file of 0\.1 MB "
                                             r"\(a decompression bomb\?\), not a model file tghop wrote"):
        load_model(io.BytesIO(bomb.getvalue()))


def _png(tmp_path):
    """The bytes of a small PNG."""
    from PIL import Image

    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(tmp_path / "i.png")
    return (tmp_path / "i.png").read_bytes()


def test_a_generator_given_as_rng_is_recorded_as_the_fit_began_so_a_loaded_models_clone_fits_it_again(
        bricks96, saved, tmp_path):
    # 0.57 loaded a TGHop or Material fitted from a Generator with rng=None: clone(loaded).fit(x) drew fresh entropy.
    from sklearn.base import clone

    from conftest import SMALL
    from tghop import TGHop
    from tghop.material import Material

    def same(a, b):
        one, other = a._to_arrays(), b._to_arrays()
        return one.keys() == other.keys() and all(np.array_equal(v, other[k]) for k, v in one.items())

    path, arrays = saved  # an int seed: recorded as it was, no generator (nor the layout model's, its model_rng)
    meta = json.loads(str(arrays["__meta__"]))
    assert "fit_rngs" not in meta and "fit_rngs" not in meta["layout"]["model"]
    gen = np.random.default_rng(5)
    gen.random(3)  # not at its seed's start
    start = gen.bit_generator.state
    model = TGHop(**{**SMALL, "rng": gen}).fit(bricks96)
    assert model.rng is gen and gen.bit_generator.state != start  # the caller's, advanced (scikit-learn's way)
    save_model(model, tmp_path / "g.npz")
    loaded = load_model(tmp_path / "g.npz")
    assert loaded.rng is not gen and loaded.rng.bit_generator.state == start
    assert same(clone(loaded).fit(bricks96), model) and loaded.rng.bit_generator.state == start
    save_model(loaded, tmp_path / "again.npz")  # the record survives a load and a save
    assert load_model(tmp_path / "again.npz").rng.bit_generator.state == start
    maps = {"height": bricks96[..., 0]}
    mat = Material(TGHop(**{**SMALL, "rng": None}), rng=np.random.default_rng(9)).fit(bricks96, maps)
    save_model(mat, tmp_path / "mat.npz")
    back = load_model(tmp_path / "mat.npz", material=True)
    assert back.rng.bit_generator.state == np.random.default_rng(9).bit_generator.state and back.model.rng is None
    assert same(clone(back).fit(bricks96, maps), mat)
    meta = json.loads(str(np.load(tmp_path / "g.npz")["__meta__"]))
    with np.load(tmp_path / "g.npz") as f:
        g_arrays = {k: f[k] for k in f.files}
    for bad in ({"model__rng": meta["fit_rngs"]["rng"]}, {"rng": {"state": 1}}, [1]):
        _write(tmp_path / "bad.npz", {**g_arrays, "__meta__": np.array(json.dumps({**meta, "fit_rngs": bad}))})
        with pytest.raises(ModelFileError, match=r"bad\.npz: this model file was edited, .*\(what is wrong: the "
                                                 r"metadata's fit_rngs"):
            load_model(tmp_path / "bad.npz")
