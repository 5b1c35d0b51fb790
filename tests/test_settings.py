"""The settings table: one home for the estimator, the model file and the CLI."""

import importlib
import inspect
import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import SMALL
from tghop import ModelFileError, TGHopError, settings
from tghop.core import ICHM
from tghop.modelfile import load_model, save_model
from tghop.synthesis import PAPER_TABLE4, TGHop


def test_constructor_and_synthesize_follow_the_table():
    # An explicit constructor a reader and a type checker see, agreeing with the table
    # (names, order, defaults), as scikit-learn keeps _parameter_constraints.
    assert inspect.getsourcefile(TGHop.__init__).endswith("synthesis.py")
    params = inspect.signature(TGHop).parameters
    assert list(params) == [s.name for s in settings.fit_settings()]
    for s in settings.fit_settings():
        assert params[s.name].default == s.default
    keywords = inspect.signature(TGHop.synthesize).parameters
    for s in settings.generate_settings():
        assert keywords[s.name].default == s.default, s.name
    for s in settings.fit_settings():
        assert f"{s.name} :" in TGHop.__doc__


@pytest.mark.parametrize("function", ["guided.synthesize_guided", "guided.morph", "inpaint.inpaint",
                                      "material.Material.synthesize"])
def test_other_entry_points_share_the_tables_defaults(function):
    # These functions repeat some of synthesize's keywords in their own signatures: a
    # default changed in the table must change there too, or the same call would make
    # a different image through them.
    module, _, name = function.partition(".")
    obj = importlib.import_module(f"tghop.{module}")
    for part in name.split("."):
        obj = getattr(obj, part)
    keywords = inspect.signature(obj).parameters
    shared = [s for s in settings.generate_settings() if s.name in keywords]
    assert len(shared) >= 2, function
    for s in shared:
        assert keywords[s.name].default == s.default, f"{function}: {s.name}"


def test_paper_values_come_from_the_table():
    assert PAPER_TABLE4["cluster_energy"] == 0.95 and PAPER_TABLE4["max_cluster_components"] == 50
    assert settings.PAPER["match_colours"] is False


@pytest.mark.parametrize("name, value", [
    ("gamma", float("nan")), ("gamma", float("inf")), ("gamma", -1.0), ("reject_threshold", float("nan")),
    ("reject_threshold", float("-inf")), ("cluster_energy", 0.0), ("n_clusters", 2.5), ("n_clusters", True),
    ("stride", 0), ("gamma_mode", "other"), ("ica_max_iter", 0), ("n_channels", (9, float("nan"))),
    ("max_patches", "many"),
])
def test_bad_fit_settings_are_refused_before_work(bricks96, name, value):
    with pytest.raises(TGHopError, match=name if name != "n_channels" else "K2"):
        TGHop(**{**SMALL, name: value}).fit(bricks96)
    with pytest.raises(TGHopError, match=name if name != "n_channels" else "K2"):
        TGHop(**{**SMALL, name: value}).check_settings()  # the same error, without an exemplar


def test_check_settings_includes_the_hops_rules():
    TGHop(**SMALL).check_settings()
    with pytest.raises(TGHopError, match="5 hops need a patch size divisible by 32 leaving a core of at least 2x2"):
        TGHop(**{**SMALL, "n_channels": (5, 5, 5, 5, 5)}).check_settings()


@pytest.mark.parametrize("name, value", [("tolerance", float("nan")), ("n_patches", 0), ("overlap", 0),
                                         ("match_colours", "yes"), ("tolerance", float("inf")),
                                         # finite but too large: float32 errors overflow, or a pool of inf patches
                                         ("layout_weight", 1e100), ("pool_per_block", 1e308), ("reuse", 1e300),
                                         ("tolerance", 1e300)])
def test_bad_generation_settings_are_refused(small_model, name, value):
    with pytest.raises(TGHopError, match=name):
        small_model.synthesize((40, 40), rng=0, **{name: value})


def test_refine_takes_integers_only_at_every_entry_point(small_model, bricks96):
    # 2.0 is refused as 2.5 is, as the server, tghop.refine.refine and inpaint always did.
    from tghop import guided
    from tghop.inpaint import inpaint, refine_hole
    from tghop.refine import refine

    with pytest.raises(TGHopError, match=r"refine must be an integer >= 0 and <= 20, got 2.0; write 2"):
        small_model.synthesize((40, 40), rng=0, refine=2.0)
    with pytest.raises(TGHopError, match=r"refine must be an integer >= 0 and <= 20, got 2.0; write 2"):
        guided.synthesize_guided([small_model, small_model], size=(40, 40), rng=0, refine=2.0)
    with pytest.raises(TGHopError, match=r"refine must be an integer >= 0 and <= 20, got 2.0; write 2"):
        guided.morph(small_model, small_model, (40, 80), rng=0, refine=2.0)
    hole = np.zeros(bricks96.shape[:2], dtype=bool)
    hole[40:50, 40:50] = True
    with pytest.raises(TGHopError, match=r"refine must be an integer >= 0 and <= 20, got 2.0; write 2"):
        inpaint(small_model, bricks96, hole, rng=0, refine=2.0)  # the settings table, as synthesize (0.49)
    with pytest.raises(TGHopError, match=r"refine: n_iter must be an integer >= 0, got 2.0"):
        refine(bricks96, small_model.bands_, n_iter=2.0)
    with pytest.raises(TGHopError, match=r"refine_hole: n_iter must be an integer >= 0, got 2.0"):
        refine_hole(bricks96, hole, small_model.bands_, n_iter=2.0)
    assert settings.BY_NAME["refine"].check(np.int64(2)) == 2


def test_whole_floats_are_refused_for_integer_settings_but_read_from_old_files():
    with pytest.raises(TGHopError, match=r"stride must be an integer >= 1, got 2.0; write 2"):
        TGHop(**{**SMALL, "stride": 2.0}).check_settings()
    checked = settings.file_settings({"stride": 2.0})  # a file fitted with stride=2.0 before it was refused
    assert checked["stride"] == 2 and type(checked["stride"]) is int


def test_ica_max_iter_reaches_ichm_and_survives_the_model_file(bricks96, tmp_path):
    model = TGHop(**{**SMALL, "ica_max_iter": 3}).fit(bricks96)
    assert model.ichm_.max_iter == 3
    save_model(model, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz")
    assert loaded.ica_max_iter == 3 and loaded.ichm_.max_iter == 3
    assert loaded.ichm_.get_params()["n_clusters"] == SMALL["n_clusters"]


def _rewrite_meta(src, dst, edit):
    with np.load(src, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(str(arrays["__meta__"]))
    edit(meta)
    arrays["__meta__"] = np.array(json.dumps(meta))
    with open(dst, "wb") as fh:
        np.savez(fh, **arrays)


def test_model_file_settings_missing_unknown_or_invalid(small_model, tmp_path):
    save_model(small_model, tmp_path / "m.npz")
    # A file from before a setting existed: the setting takes its default.
    _rewrite_meta(tmp_path / "m.npz", tmp_path / "old.npz", lambda m: m["params"].pop("ica_max_iter"))
    assert load_model(tmp_path / "old.npz").ica_max_iter == 200
    _rewrite_meta(tmp_path / "m.npz", tmp_path / "new.npz", lambda m: m["params"].update(warp_speed=9))
    with pytest.raises(ModelFileError, match="warp_speed"):
        load_model(tmp_path / "new.npz")
    _rewrite_meta(tmp_path / "m.npz", tmp_path / "nan.npz", lambda m: m["params"].update(gamma="nan"))
    with pytest.raises(ModelFileError, match="gamma"):
        load_model(tmp_path / "nan.npz")
    _rewrite_meta(tmp_path / "m.npz", tmp_path / "v.npz", lambda m: m.update(format_version="1"))
    with pytest.raises(ModelFileError, match="format_version '1' is not an integer"):
        load_model(tmp_path / "v.npz")


def test_ichm_refit_samples_from_the_new_model(rng):
    a = rng.standard_normal((400, 3))
    model = ICHM(n_clusters=2, n_codewords=5, rng=0).fit(a)
    model.sample(10, rng=0)  # builds the sampling tables of the first fit
    b = np.exp(rng.standard_normal((400, 3)))  # other CDF shapes, other codebook
    model.fit(b)
    fresh = ICHM(n_clusters=2, n_codewords=5, rng=0).fit(b)
    z, labels = model.sample(500, rng=1)
    expected, expected_labels = fresh.sample(500, rng=1)
    np.testing.assert_array_equal(z, expected)
    np.testing.assert_array_equal(labels, expected_labels)


def test_synthesis_does_not_import_modelfile():
    code = "import sys, tghop.synthesis; print('tghop.modelfile' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_an_explicit_none_on_the_command_line_is_off_not_the_default():
    # `--layout none` fits without the coarse layout (it used to give the default factor 2).
    from tghop.cli.options import SettingType
    from tghop.fit_options import build_model
    from tghop.settings import BY_NAME

    off = SettingType(BY_NAME["layout_factor"]).convert("none", None, None)
    assert build_model({"layout_factor": off}).layout_factor is None
    assert build_model({"layout_factor": None}).layout_factor == BY_NAME["layout_factor"].default
    assert build_model(
        {"layout_factor": SettingType(BY_NAME["layout_factor"]).convert("3", None, None)}).layout_factor == 3
