"""Model files: a fitted :class:`~tghop.synthesis.TGHop` as arrays plus JSON metadata.

The file is a NumPy ``.npz`` archive (any file name) read with ``allow_pickle=False``, so
loading a file cannot run code. It holds:

* ``__meta__``: a JSON document with ``format`` ("tghop-model"), ``format_version``, the
  tghop version that wrote it, the estimator's parameters and the shapes needed to rebuild
  it;
* one array per learned quantity, named ``<part>.<name>``. The part says which row of the
  paper's Table 4 the numbers belong to (``hop1`` -> transform stage 1, ``hop2``, ``hop3``
  -> stage 2, ``sdr``, ``ichm_i``, ``ichm_ii``, ``ichm_iii``); ``index.*`` arrays are
  bookkeeping (which channel is which, energies) and are not counted as parameters.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from . import __version__
from ._common import ModelFileError
from .core import ICHM, SpatialReduction
from .hops import Hop, HopStack
from .imageio import check_output_path, write_atomic
from .saab import Saab

__all__ = ["save_model", "load_model", "model_arrays", "parameter_groups", "FORMAT", "FORMAT_VERSION"]

FORMAT = "tghop-model"
FORMAT_VERSION = 1

#: Table 4 row of each array-name prefix.
GROUPS = {
    "hop1": "transform stage 1",
    "hop": "transform stage 2",  # hop2, hop3, ...
    "sdr": "core SDR",
    "ichm_i": "core ICHM (i)",
    "ichm_ii": "core ICHM (ii)",
    "ichm_iii": "core ICHM (iii)",
    "colour": "colour matching (ours)",
}


#: Arrays of the core model and colour matching: (file name, estimator part, attribute,
#: dtype on loading). Saving and loading both follow this one table.
CORE_ARRAYS = [
    ("sdr.components", "sdr_", "components_", np.float64),
    ("sdr.mean", "sdr_", "mean_", np.float64),
    ("index.sdr_channel", "sdr_", "channel_", np.int64),
    ("index.sdr_variance", "sdr_", "explained_variance_", np.float64),
    ("ichm_i.p", "ichm_", "p_", np.float64),
    ("ichm_ii.mixing", "ichm_", "mixing_", np.float64),
    ("ichm_ii.means", "ichm_", "means_", np.float64),
    ("index.ichm_n_components", "ichm_", "n_components_", np.int64),
    ("ichm_iii.cdf_index", "ichm_", "cdf_index_", np.int64),
    ("ichm_iii.cdf_min", "ichm_", "cdf_min_", np.float64),
    ("ichm_iii.cdf_max", "ichm_", "cdf_max_", np.float64),
    ("ichm_iii.codebook", "ichm_", "codebook_", np.float64),
    ("ichm_ii.residual_factor", "ichm_", "residual_factor_", np.float64),
    ("index.ichm_residual_group", "ichm_", "residual_group_", np.int64),
    ("colour.quantiles", None, "colour_quantiles_", np.float64),
]


#: Arrays that older files of the same format version may lack (read as empty).
OPTIONAL_ARRAYS = {"ichm_ii.residual_factor", "index.ichm_residual_group"}


def _group(name: str):
    part = name.split(".", 1)[0]
    if part == "index":
        return None
    if part in GROUPS:
        return GROUPS[part]
    if part.startswith("hop"):
        return GROUPS["hop"]
    raise KeyError(name)


def parameter_groups(arrays) -> dict:
    """Count the numbers in ``arrays`` (name -> array) per Table 4 row; bookkeeping excluded."""
    counts = {}
    for name, arr in arrays.items():
        group = _group(name)
        if group is not None:
            counts[group] = counts.get(group, 0) + int(np.asarray(arr).size)
    return counts


def model_arrays(model) -> dict:
    """Every array a fitted model stores, by file name (see the module docstring)."""
    out = {}
    for i, hop in enumerate(model.hops_.hops_, start=1):
        if hop.channelwise:
            # Each kept channel: one 4-tap kernel of its parent's Saab transform.
            compact = np.array([hop.saabs_[p].kernels_[list(hop.saabs_[p].channels_).index(j)]
                                for p, j in hop.channels_])
            out[f"hop{i}.kernels"] = compact
            out[f"hop{i}.bias"] = np.array([s.bias_ for s in hop.saabs_])
        else:
            out[f"hop{i}.kernels"] = hop.saabs_[0].kernels_
            out[f"hop{i}.bias"] = np.array([hop.saabs_[0].bias_])
        out[f"index.hop{i}_channels"] = hop.channels_
        out[f"index.hop{i}_energy"] = hop.energy_
    for name, part, attribute, _ in CORE_ARRAYS:
        out[name] = getattr(getattr(model, part) if part else model, attribute)
    return out


def _params_json(model) -> dict:
    params = model.get_params()
    params["rng"] = None  # a Generator is not data; the fitted state already holds its effect
    if params["n_channels"] is not None:
        params["n_channels"] = list(params["n_channels"])
    return params


def save_model(model, path) -> None:
    """Write a fitted model to ``path`` (any name; the file appears whole or not at all)."""
    from sklearn.utils.validation import check_is_fitted

    check_is_fitted(model, "ichm_")
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "tghop_version": __version__,
        "params": _params_json(model),
        "exemplar_shape": list(model.exemplar_shape_),
        "n_patches": model.n_patches_,
        "hops": [{"channelwise": hop.channelwise, "n_channels_in": hop.n_channels_in_} for hop in model.hops_.hops_],
        "hop_dims": model.hops_.dims_,
        "sdr_shape": list(model.sdr_.shape_),
        "ica_unconverged": int(model.ichm_.n_ica_unconverged_),
    }
    arrays = model_arrays(model)
    arrays["__meta__"] = np.array(json.dumps(meta))
    check_output_path(path, what="model", error=ModelFileError)
    write_atomic(path, lambda fh: np.savez(fh, **arrays))


def _read(path):
    path = Path(path)
    if not path.exists():
        raise ModelFileError(f"{path}: no such model file; check the path or fit one with 'tghop fit'")
    if path.is_dir():
        raise ModelFileError(f"{path} is a folder, not a model file")
    try:
        with np.load(path, allow_pickle=False) as data:
            if not hasattr(data, "files"):
                raise ValueError("not an archive")
            arrays = {name: data[name] for name in data.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError) as exc:
        raise ModelFileError(
            f"{path}: not a tghop model file (cannot read it as one: {exc.__class__.__name__}); "
            "fit a model with 'tghop fit'"
        ) from None
    if "__meta__" not in arrays:
        raise ModelFileError(f"{path}: a NumPy archive but not a tghop model file; fit a model with 'tghop fit'")
    try:
        meta = json.loads(str(arrays.pop("__meta__")))
    except (ValueError, TypeError):
        raise ModelFileError(f"{path}: corrupt model metadata; fit the model again") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ModelFileError(f"{path}: not a tghop model file; fit a model with 'tghop fit'")
    version = meta.get("format_version")
    if version != FORMAT_VERSION:
        raise ModelFileError(
            f"{path}: written in model format version {version} (by tghop {meta.get('tghop_version', '?')}), "
            f"but this tghop {__version__} reads version {FORMAT_VERSION}; refit the model with this version"
        )
    return meta, arrays


def load_model(path):
    """Read a model written by :func:`save_model`.

    Raises
    ------
    ModelFileError
        The file is missing, not a tghop model, corrupt, or of another format version.
    """
    from .synthesis import TGHop

    meta, arrays = _read(path)
    try:
        model = TGHop(**meta["params"])
        model.exemplar_shape_ = tuple(meta["exemplar_shape"])
        model.n_patches_ = int(meta["n_patches"])
        stack = HopStack(n_channels=model._channel_rules(model.exemplar_shape_[2]))
        stack.hops_ = []
        for i, info in enumerate(meta["hops"], start=1):
            stack.hops_.append(_rebuild_hop(info, arrays, i))
        stack.dims_ = [int(d) for d in meta["hop_dims"]]
        model.hops_ = stack
        model.sdr_ = SpatialReduction(gamma=model.gamma, gamma_mode=model.gamma_mode)
        model.sdr_.shape_ = tuple(meta["sdr_shape"])
        model.ichm_ = ICHM(
            n_clusters=model.n_clusters, n_codewords=model.n_codewords, n_bins=model.n_bins,
            cluster_energy=model.cluster_energy, max_cluster_components=model.max_cluster_components,
            min_cluster_size=model.min_cluster_size, reject_threshold=model.reject_threshold,
            residual=bool(model.residual),
        )
        model.ichm_.n_ica_unconverged_ = int(meta.get("ica_unconverged", 0))
        for name, part, attribute, dtype in CORE_ARRAYS:
            # Files written before the residual Gaussian existed have none: empty.
            value = arrays[name] if name in arrays or name not in OPTIONAL_ARRAYS else np.zeros(0)
            setattr(getattr(model, part) if part else model, attribute, value.astype(dtype, copy=False))
        model.sdr_.kept_per_channel_ = np.bincount(model.sdr_.channel_, minlength=model.sdr_.shape_[2])
        _check_consistent(model)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise ModelFileError(f"{path}: corrupt or incomplete tghop model ({exc}); fit the model again") from None
    model._decoder = None
    return model


def _rebuild_hop(info, arrays, i):
    hop = Hop(channelwise=bool(info["channelwise"]))
    c = hop.n_channels_in_ = int(info["n_channels_in"])
    hop.channels_ = arrays[f"index.hop{i}_channels"].astype(np.int64)
    hop.energy_ = arrays[f"index.hop{i}_energy"]
    kernels, bias = arrays[f"hop{i}.kernels"], arrays[f"hop{i}.bias"]
    parents = range(c) if hop.channelwise else [0]
    hop.saabs_ = []
    for p in parents:
        saab = Saab()
        rows = hop.channels_[:, 0] == p
        saab.channels_ = hop.channels_[rows, 1]
        saab.kernels_ = kernels[rows]
        saab.bias_ = float(bias[p])
        saab.n_features_in_ = kernels.shape[1]
        hop.saabs_.append(saab)
    hop._build_matrix()
    return hop


def _check_consistent(model):
    """Shapes that must agree; a mismatch means a damaged or hand-edited file."""
    ichm, sdr = model.ichm_, model.sdr_
    d_r = sdr.components_.shape[0]
    f = int(ichm.n_components_.sum())
    checks = [
        ichm.mixing_.shape == (f, d_r),
        ichm.means_.shape == (len(ichm.p_), d_r),
        len(ichm.n_components_) == len(ichm.p_),
        ichm.cdf_index_.shape == (f,) and ichm.cdf_min_.shape == (f,) and ichm.cdf_max_.shape == (f,),
        ichm.cdf_index_.size == 0 or (0 <= ichm.cdf_index_.min() and ichm.cdf_index_.max() < len(ichm.codebook_)),
        model.hops_.hops_[-1].n_channels_out_ == sdr.shape_[2],
        abs(float(ichm.p_.sum()) - 1.0) < 1e-6,
    ]
    if not all(checks):
        raise ValueError("array shapes disagree")
