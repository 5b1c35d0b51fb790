"""The patch refinement (tghop.patch_refine): statistics, sliced transport, wiring, model files."""

import json

import numpy as np
import pytest

from tghop import data, settings
from tghop._common import TGHopError
from tghop import patch_refine as pr
from tghop.modelfile import ModelFileError, load_model, save_model
from tghop.synthesis import TGHop

from conftest import SMALL


@pytest.fixture(scope="module")
def patch_model():
    return TGHop(**SMALL, patch_levels=3).fit(data.cells(96, rng=3))


def _patch_swd(dec, stats):
    """Mean distance of the image's projection quantiles to the stored ones, per level."""
    out = []
    for i, img in enumerate(pr._levels_of(dec, len(stats.rotations_), "reflect")):
        for r in range(pr.ROTATIONS):
            proj = pr._windows(img, pr.PATCH) @ stats.rotations_[i, r].T
            q = np.quantile(proj, np.linspace(0, 1, pr.QUANTILES), axis=0).T
            out.append(np.abs(q - stats.quantiles_[i, r]).mean())
    return np.array(out)


def test_statistics_shapes_and_rotations(patch_model):
    st = patch_model.patches_
    d = pr.PATCH * pr.PATCH * 3
    assert st.rotations_.shape == (3, pr.ROTATIONS, d, d)
    assert st.quantiles_.shape == (3, pr.ROTATIONS, d, pr.QUANTILES)
    eye = np.eye(d)
    assert np.abs(st.rotations_ @ np.swapaxes(st.rotations_, -1, -2) - eye).max() < 1e-9
    assert (np.diff(st.quantiles_, axis=-1) >= 0).all()
    # Stored only when asked for: no arrays, no parameters.
    plain = TGHop(**SMALL).fit(data.cells(96, rng=3))
    assert plain.patches_ is None and not any(k.startswith("patch.") for k in plain._to_arrays())
    assert plain.n_parameters()["patch refinement (ours)"]["stored"] == 0
    assert patch_model.n_parameters()["patch refinement (ours)"]["stored"] == 3 * pr.ROTATIONS * d * (d + pr.QUANTILES)


def test_refinement_moves_patch_statistics_towards_the_exemplar(patch_model, rng):
    st = patch_model.patches_
    img = patch_model.synthesize((80, 72), rng=2, match_colours=False).astype(np.float32)
    dec = patch_model.bands_.to_decorrelated(img)
    before = _patch_swd(dec, st)
    out = pr.patch_refine(dec, st, n_iter=2)
    assert out.shape == dec.shape and out.dtype == np.float32
    after = _patch_swd(out, st)
    assert after.mean() < 0.8 * before.mean()
    assert np.array_equal(pr.patch_refine(dec, st, n_iter=0), dec)
    tiled = pr.patch_refine(dec, st, n_iter=1, tile=True)
    assert tiled.shape == dec.shape and _patch_swd(tiled, st).mean() < before.mean()
    with pytest.raises(TGHopError):
        pr.patch_refine(dec[..., :1], st, n_iter=1)


def test_synthesis_is_deterministic_and_off_by_default(patch_model):
    a = patch_model.synthesize((64, 64), rng=5, patch_refine=2)
    b = patch_model.synthesize((64, 64), rng=5, patch_refine=2)
    off = patch_model.synthesize((64, 64), rng=5)
    assert a.shape == (64, 64, 3) and np.array_equal(a, b)
    assert not np.array_equal(a, off)
    assert (a >= 0).all() and (a <= 1).all()
    u8 = patch_model.synthesize((64, 64), rng=5, patch_refine=1, dtype=np.uint8, tile=True)
    assert u8.dtype == np.uint8 and u8.shape == (64, 64, 3)


def test_paper_pipeline_is_unaffected():
    assert settings.PAPER["patch_refine"] == 0 and settings.PAPER["patch_levels"] == 0
    assert settings.BY_NAME["patch_refine"].default == 0 and settings.BY_NAME["patch_levels"].default == 0


def test_model_without_statistics_ignores_the_setting(small_model):
    a = small_model.synthesize((48, 48), rng=1, patch_refine=3)
    assert np.array_equal(a, small_model.synthesize((48, 48), rng=1))


def test_fit_is_unchanged_by_the_statistics(patch_model):
    plain = TGHop(**SMALL).fit(data.cells(96, rng=3))
    assert np.array_equal(plain.synthesize((64, 64), rng=3), patch_model.synthesize((64, 64), rng=3))


def test_model_file_round_trip(patch_model, tmp_path):
    save_model(patch_model, tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz") as f:
        assert json.loads(str(f["__meta__"]))["format_version"] == 4
    loaded = load_model(tmp_path / "m.npz")
    assert np.array_equal(loaded.synthesize((64, 64), rng=4, patch_refine=2),
                          patch_model.synthesize((64, 64), rng=4, patch_refine=2))


def _rewrite(src, dst, edit):
    with np.load(src) as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays.pop("__meta__")))
    edit(meta, arrays)
    np.savez(dst, __meta__=np.array(json.dumps(meta)), **arrays)


def test_old_files_load_and_damaged_arrays_are_refused(small_model, patch_model, tmp_path):
    save_model(small_model, tmp_path / "plain.npz")
    with np.load(tmp_path / "plain.npz") as f:  # nothing new in it: still readable by older tghop
        assert json.loads(str(f["__meta__"]))["format_version"] == 3

    def old(meta, arrays):  # a file of tghop 0.13: no patch_levels setting at all
        meta["params"].pop("patch_levels")
    _rewrite(tmp_path / "plain.npz", tmp_path / "old.npz", old)
    loaded = load_model(tmp_path / "old.npz")
    assert loaded.patches_ is None
    assert loaded.synthesize((48, 48), rng=1, patch_refine=2).shape == (48, 48, 3)

    save_model(patch_model, tmp_path / "p.npz")

    def skew(meta, arrays):
        arrays["patch.rotations"] = arrays["patch.rotations"] * 1.5
    _rewrite(tmp_path / "p.npz", tmp_path / "skew.npz", skew)
    with pytest.raises(ModelFileError, match="patch.rotations.*orthonormal"):
        load_model(tmp_path / "skew.npz")

    def missing(meta, arrays):
        arrays.pop("patch.quantiles")
    _rewrite(tmp_path / "p.npz", tmp_path / "missing.npz", missing)
    with pytest.raises(ModelFileError, match="patch.quantiles is missing"):
        load_model(tmp_path / "missing.npz")

    def unknown(meta, arrays):  # arrays of a model that says it has none
        meta["params"]["patch_levels"] = 0
    _rewrite(tmp_path / "p.npz", tmp_path / "unknown.npz", unknown)
    with pytest.raises(ModelFileError, match="array patch."):
        load_model(tmp_path / "unknown.npz")
