"""Model files: a fitted :class:`~tghop.synthesis.TGHop` as arrays plus JSON metadata, saved, and
checked as they are loaded (:func:`load_model`: every array against the specs its part gives).

The file is a NumPy ``.npz`` archive (any file name) read with ``allow_pickle=False``, so
loading a file cannot run code. It holds:

* ``__meta__``: a JSON document with ``format`` ("tghop-model"), ``format_version``, the
  tghop version that wrote it, the estimator's parameters and the shapes needed to rebuild
  it;
* one array per learned quantity, named ``<part>.<name>``. The part says which row of the
  paper's Table 4 the numbers belong to (``hop1`` -> transform stage 1, ``hop2``, ``hop3``
  -> stage 2, ``sdr``, ``ichm_i``, ``ichm_ii``, ``ichm_iii``); ``index.*`` arrays are
  bookkeeping (which channel is which, energies) and are not counted as parameters.

Each part names and restores its own arrays (``Hop``, ``SpatialReduction`` and ``ICHM``
``_to_arrays`` / ``_from_arrays``, ``TGHop._to_arrays`` / ``_from_state``); the settings
come from :mod:`tghop.settings`, so a new setting is saved and restored without a change
here. This module is only the container: JSON header, format version, atomic writing.
It imports :mod:`tghop.synthesis`, never the other way round.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
import zlib
from pathlib import Path

import numpy as np

from . import __version__
from ._errors import ModelFileError, TGHopError, warn
from ._archives import array_declaring_more, check_archive_bounds
from ._formats import COOC_CHECKPOINT, checkpoint_note, is_model_file, model_file_kind
from ._json import RepeatedKeyError, loads_unique
from .imageio import check_output_path, write_atomic
from .material import PATCH_PREFIX as MATERIAL_PATCH_PREFIX, Material
from .settings import fit_seed
from .synthesis import TGHop

__all__ = ["save_model", "load_model", "FORMAT", "FORMAT_VERSION", "info_dict"]

FORMAT = "tghop-model"
FORMAT_VERSION = 11  # 2: refinement statistics (refine.*); 3: float16 mixing rows with a scale each;
# 4: tghop 0.14's patch refinement statistics (patch.rotations, patch.quantiles: 5x5 patches on
# random rotations; read without them, with a warning); 5: the sliced Wasserstein statistics
# (patch.directions, patch.quantiles) and whole materials (below); 6: their quantiles' levels
# (patch.levels; version 5 files are read as evenly spaced); 7: the core model's norm quantiles
# (ichm_iv.*, setting norm_match; older files read as norm_match 0); 8: its members' ranks for
# coupled draws (ichm_coupling.member_ranks, index.ichm_member_counts; setting coupling; older files
# read as coupling 0); 9: colour classes (colour.centres, colour.shares, colour.class_quantiles,
# refine.class_quantiles, colour.separation, colour.share_spread; setting colour_classes; older
# files read as colour_classes 0); 10: the coarse layout model's patch statistics (layout.patch.*;
# layout parameter patch_levels; older files read as 0, their guide not patch-refined); 11 (0.59): a
# material's albedo patch statistics (material_patch.*, material.patch_levels), so that tghop 0.58 and
# before refuse such a material by its version (made by a newer tghop) rather than by an unknown array.
# A file is written in the lowest version that holds what it has: with material_patch.*, 11; other
# files with patch statistics, norm quantiles, ranks, colour classes or a material, 10 (a texture
# model's bytes as 0.58 wrote them, which 0.58 reads); files without any of these, 3
#: Files of whole materials (:class:`tghop.material.Material`: the maps in the metadata,
#: each map's statistics as material.<name>.*) are version 5 or later, so that an older tghop
#: refuses them by their version.
MATERIAL_VERSION = 5
#: Versions this tghop reads (version 2 files hold the mixing matrix in float32).
READABLE_VERSIONS = (2, 3, 4, 5, 6, 7, 8, 9, 10, 11)
#: The version of a file with patch statistics (or another of version 4-10's additions) and no material_patch.*:
#: what tghop 0.48-0.58 wrote and read.
WITHOUT_MATERIAL_PATCHES = 10


def save_model(model, path) -> None:
    """Write a fitted model to ``path`` (any name; the file appears whole or not at all), or into a
    binary file object (as :func:`numpy.savez` writes into one).

    Parameters
    ----------
    model : tghop.synthesis.TGHop or tghop.material.Material
        Fitted (:class:`~tghop.NotFittedError` before ``fit``).
    path : str, os.PathLike or binary file object
        The file; an ``.npz`` archive of the learned arrays and JSON metadata whatever its name. A file
        object (``io.BytesIO()``, ``open(name, "wb")``, a web framework's response body; 0.58) gets the
        whole archive in one ``write`` at its position, made in memory first, and is left open there:
        ``seek(0)`` before reading it back with :func:`load_model`.

    Raises
    ------
    ModelFileError
        ``path`` cannot be written (a folder, no permission, a missing folder; a file object open in
        text mode, closed or not writable).
    """
    if not isinstance(model, (TGHop, Material)):
        raise TGHopError(f"save_model writes a fitted TGHop or Material, got {type(model).__name__}")
    stream = _is_stream(path, "save_model", "write", "wb")
    if not stream:
        _check_path(path, "save_model", "write the model to")
    arrays = model._to_arrays()  # NotFittedError before anything else
    meta = {"format": FORMAT, "tghop_version": __version__, **model._state_meta()}
    new = "material" in meta or any(name.startswith("patch.") or "ichm_iv." in name or "ichm_coupling." in name
                                   or name.endswith("colour.centres") for name in arrays)
    patched = any(name.startswith(MATERIAL_PATCH_PREFIX) for name in arrays)  # a material's albedo's (0.59)
    meta["format_version"] = FORMAT_VERSION if patched else WITHOUT_MATERIAL_PATCHES if new else 3
    arrays["__meta__"] = np.array(json.dumps(meta, default=_json_number))
    if stream:  # the archive made first, so that a failure writes nothing into it
        archive = io.BytesIO()
        np.savez(archive, **arrays)
        try:
            path.write(archive.getbuffer())
        except (OSError, ValueError) as exc:  # io.UnsupportedOperation: opened for reading
            why = "not open for writing" if isinstance(exc, io.UnsupportedOperation) else exc
            raise ModelFileError(f"save_model: cannot write the model into {_label(path)} ({why}); give a file "
                                 "object open for writing in binary mode, or a file name") from None
        return
    check_output_path(path, what="model", error=ModelFileError)
    write_atomic(path, lambda fh: np.savez(fh, **arrays), what="model", error=ModelFileError)


def _is_stream(target, caller: str, verb: str, mode: str) -> bool:
    """Whether ``target`` is a file object (it has ``verb``, "read" or "write"); one that cannot be
    one in binary (open in text mode, closed) is a one-line :class:`ModelFileError`."""
    if isinstance(target, (str, os.PathLike)) or not callable(getattr(target, verb, None)):
        return False
    opened = getattr(target, "mode", "b")  # a gzip file's is a number
    if isinstance(target, io.TextIOBase) or isinstance(opened, str) and "b" not in opened:
        raise ModelFileError(f"{caller}: {_label(target)} is open in text mode; a model file is binary: "
                             f"open it with mode {mode!r} (or give its name)")
    if getattr(target, "closed", False):
        raise ModelFileError(f"{caller}: {_label(target)} is closed; give an open file object or a file name")
    return True


def _label(stream) -> str:
    """How messages name a file object: its file's name where it has one, else its type."""
    name = getattr(stream, "name", None)
    return os.fsdecode(name) if isinstance(name, (str, bytes, os.PathLike)) else f"the {type(stream).__name__} given"


def _json_number(value):
    """A NumPy number or array in a model's metadata (a setting given as ``np.int64(6)`` or an array)
    as the Python value JSON writes."""
    if isinstance(value, (np.generic, np.ndarray)):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON data")


def info_dict(model, params=None) -> dict:
    """A fitted model's summary as JSON-ready data: its settings (``rng`` left out: the
    fit's int seed is ``fit_seed``, None when it was a Generator or not recorded),
    dimensions, channels, exemplar shape, parameter count (``params``: its
    :meth:`~tghop.TGHop.n_parameters`, when the caller already has it) and the coarse
    layout's factor (``layout_factor_used``: None without one) and the exemplar's bits per
    channel (``exemplar_depth``: 8, 16 or 32; None when not recorded) and a two-level exemplar's
    two levels (``exemplar_levels``: two lists of a value per channel in [0, 1], its images snapped
    to them, :attr:`~tghop.TGHop.exemplar_levels_`; None for any other). What ``tghop info
    --json`` prints and the web server's ``GET /api/models/{id}`` answers."""
    if not isinstance(model, TGHop):
        raise TGHopError(f"info_dict: model must be a fitted TGHop (e.g. load_model(path)), got {type(model).__name__}")
    if params is not None and not isinstance(params, dict):
        raise TGHopError(f"info_dict: params must be None or the model's n_parameters() (a dict), "
                         f"got {type(params).__name__}")
    params = model.n_parameters() if params is None else params
    levels = getattr(model, "exemplar_levels_", None)
    return {"params": {k: v for k, v in model.get_params().items() if k != "rng"},
            "dims": model.dims_, "channels": model.channels_,
            "exemplar_shape": list(model.exemplar_shape_), "n_parameters": params,
            "layout_factor_used": None if model.layout_ is None else int(model.layout_.factor),
            "fit_seed": fit_seed(model), "exemplar_depth": getattr(model, "exemplar_depth_", None),
            "exemplar_levels": None if levels is None else np.asarray(levels, dtype=float).tolist()}


def _check_path(path, caller: str, verb: str) -> None:
    """Refuse a ``path`` that is not a str or os.PathLike (None, a number) with one line."""
    if not isinstance(path, (str, os.PathLike)):
        raise ModelFileError(f"{caller}: path must be a file name (str or os.PathLike) or a binary file object to "
                             f"{verb}, got {path!r:.80}")
    if not os.fsdecode(path).strip():  # as an image's and a checkpoint's (0.56: "path must be a file name")
        raise ModelFileError("the model's file name is empty; give one")


def _opened(stream):
    """A file object to read a model from, at the archive's start: ``stream`` itself where it can seek
    and is at 0, else a copy of what it has left (one at its end, or empty, is a one-line error)."""
    seekable = getattr(stream, "seekable", None)
    try:
        start = stream.tell() if callable(seekable) and seekable() else None
    except (OSError, ValueError):
        start = None
    if start is not None and start == stream.seek(0, os.SEEK_END):
        raise ModelFileError(f"{_label(stream)}: nothing left to read, it is at its end (position {start}); "
                             "seek(0) after writing the model into it" if start else
                             f"{_label(stream)} is empty; give one a model was written into (save_model)")
    if start is not None:
        stream.seek(start)
    if start == 0:
        return stream
    try:
        return io.BytesIO(stream.read())
    except (OSError, ValueError) as exc:
        raise ModelFileError(f"load_model: cannot read {_label(stream)} ({exc}); give a file object open for "
                             "reading in binary mode, or a file name") from None


def _read(path):
    """The metadata and arrays of the model file at ``path`` (or in the binary file object), its
    container checked, and how messages name it."""
    if _is_stream(path, "load_model", "read", "rb"):
        label, path = _label(path), _opened(path)
    else:
        _check_path(path, "load_model", "read the model from")
        path = label = Path(path)
        if not path.exists():
            raise ModelFileError(f"{path}: no such model file; check the path, or fit a model first")
        if path.is_dir():
            raise ModelFileError(f"{path} is a folder, not a model file; give a model file in it (NAME.npz)")
    try:
        return (*_read_archive(path, label), label)
    finally:
        if not isinstance(path, Path) and not getattr(path, "closed", False):
            path.seek(0)  # at its start, as it came (a copy: nobody's)


def _read_archive(path, label):
    """:func:`_read` of a path or a file object at its start (``path``), named ``label`` in messages."""
    check_archive_bounds(path, label, "a model file", "give a model file tghop wrote, or fit the model again")
    try:
        if not isinstance(path, Path):
            path.seek(0)
        data = np.load(path, allow_pickle=False)
        if not hasattr(data, "files"):  # a .npy file: np.load gives the array itself
            raise ModelFileError(f"{label}: a NumPy array file (.npy), not a tghop model file; give a model file "
                                 "tghop wrote (save_model, 'tghop fit')")
        with data:
            arrays = {name: data[name] for name in data.files}
    except ModelFileError:
        raise
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError, NotImplementedError, MemoryError,
            zlib.error, RuntimeError) as exc:
        from .imageio import is_image

        if is_image(path):
            import shlex  # a name with spaces quoted, so that the command can be pasted as it is

            fix = f"tghop fit {shlex.quote(str(label))} -o model.npz (or TGHop().fit and save_model)" \
                if isinstance(path, Path) else "TGHop().fit(load_image(...)) and save_model"
            raise ModelFileError(f"{label} is an image, not a model file; fit a model from it first: {fix}") from None
        if isinstance(exc, ValueError) and "allow_pickle" in str(exc):  # NumPy's word for "not .npy, not .npz"
            why = ("an array of Python objects, which tghop does not unpickle" if is_model_file(path)
                   else "not a NumPy archive")
            raise ModelFileError(f"{label}: not a tghop model file ({why}); give a model file tghop "
                                 f"wrote{checkpoint_note(path)}") from None
        note = checkpoint_note(path)  # 0.57: a checkpoint cut short is not told to "fit the model again"
        looks = is_model_file(path) and model_file_kind(path) == COOC_CHECKPOINT
        fix = note[2:] if looks else f"fit the model again{note}"
        why = (isinstance(exc, MemoryError) and array_declaring_more(path)) or \
            f"cannot read it: {exc.__class__.__name__}"
        raise ModelFileError(f"{label}: truncated, corrupt or not a tghop model file ({why}); {fix}") from None
    if "__meta__" not in arrays:
        if any(name.endswith("data.pkl") for name in arrays):  # torch.save's zip layout
            if model_file_kind(path) == COOC_CHECKPOINT:  # 0.57 named "the 'tghop cooc' commands" alone
                import shlex

                name = shlex.quote(str(label))
                raise ModelFileError(f"{label}: a co-occurrence cGAN checkpoint, not a tghop model file; generate from "
                                     f"it with 'tghop cooc edit {name} -o OUT.png' (a texture, as synth makes) or "
                                     f"'tghop cooc morph {name} A B -o OUT.png' (a morph), in Python with "
                                     "tghop.cooc.load")
            raise ModelFileError(f"{label}: a PyTorch file, not a tghop model file (nor a co-occurrence cGAN "
                                 "checkpoint of 'tghop cooc train'); give a model file tghop wrote")
        kind = model_file_kind(path)  # 0.59 called a ZIP of images (the page's maps) "a NumPy archive"
        what = f"{kind}, not" if kind.startswith(("a ZIP", "an empty ZIP")) else "a NumPy archive but not"
        raise ModelFileError(f"{label}: {what} a tghop model file; give a model file tghop wrote")
    try:
        meta = loads_unique(str(arrays.pop("__meta__")))
    except RepeatedKeyError as exc:  # 0.58 kept the last value without a word
        raise _unusable(label, None, f"the metadata gives the key {exc.key[:60]!r} twice") from None
    except (ValueError, TypeError, RecursionError):
        raise _unusable(label, None, "its metadata is not JSON") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ModelFileError(f"{label}: not a tghop model file; give a model file tghop wrote")
    version = meta.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise _unusable(label, meta, f"format_version {version!r} is not an integer")
    if version < READABLE_VERSIONS[0] and meta.get("tghop_version") == __version__:
        # this very tghop names a version below any it ever wrote: edited (0.61 said "written in model format version
        # -3 (by tghop 0.61.0), but this tghop 0.61.0 reads versions 2 to 11; refit the model with this version")
        raise _unusable(label, meta, f"format_version {version}, which tghop {__version__} does not write")
    if version not in READABLE_VERSIONS:
        newer = version > READABLE_VERSIONS[-1]  # 0.59: said so (0.58 told only to refit)
        raise ModelFileError(
            f"{label}: written in model format version {version} (by tghop {meta.get('tghop_version', '?')}"
            f"{', a newer tghop' if newer else ''}), but this tghop {__version__} reads versions "
            f"{READABLE_VERSIONS[0]} to {READABLE_VERSIONS[-1]}; "
            + ("upgrade tghop to read it, or refit the model with this version" if newer else
               "refit the model with this version")
        )
    return meta, arrays


#: Values per step of the float16 check (its temporaries stay in cache).
_CHECK_CHUNK = 1 << 16


def _all_finite(arr) -> bool:
    """No NaN or infinity in ``arr`` (any dtype). Float16 arrays (the mixing rows, most of
    a file) are checked on their bits, all exponent bits set meaning NaN or infinity: NumPy
    has no fast float16 ``isfinite``. A chunk at a time into one small buffer:
    whole-array temporaries take fresh memory, which a new process pays for in page
    faults."""
    if arr.dtype == np.float16:
        bits = arr.reshape(-1).view(np.uint16)
        exponent = np.uint16(0x7C00)
        buf = np.empty(min(_CHECK_CHUNK, bits.size), dtype=np.uint16)
        for a in range(0, bits.size, _CHECK_CHUNK):
            part = np.bitwise_and(bits[a : a + _CHECK_CHUNK], exponent, out=buf[: min(_CHECK_CHUNK, bits.size - a)])
            if (part == exponent).any():
                return False
        return True
    return arr.dtype.kind not in "fc" or bool(np.all(np.isfinite(arr)))


# ------------------------------------------------------------------ array checks
# Each part of a model declares its arrays (``Hop``, ``SpatialReduction``, ``ICHM``,
# ``BandStatistics`` ``_array_specs``, gathered by ``TGHop._array_specs``): one spec per
# array, ``(name, shape, kind, says, rules)``. ``shape`` holds numbers from the metadata
# and names of dimensions the file itself sets ("D_r", "N", "F", "W": bound by the first
# array that has them, then required of every later one); ``kind`` is "f" (real floating
# point) or "i" (integer); ``says`` is what the metadata or other arrays say, for the
# message; ``rules`` are tuples run by :data:`_RULES` or callables ``rule(arr, dims)``
# returning a problem (or None; they may bind dimensions). One function runs them all.

#: Slack of the value checks of float arrays (rounding of fitted quantiles).
_TOL = 1e-9
#: Largest magnitude of a float array used in generation (fitted ones stay below 100: pixels
#: are in [0, 1]); beyond it float32 generation can overflow into NaN. Specs with the rule
#: ("unbounded",) (energies, variances: not used in generation) are exempt.
_LIMIT = 1e4


def _bound(value, dims):
    return dims[value] if isinstance(value, str) else value


def _column(arr, column):
    return arr if column is None else arr[:, column]


def _rule_range(arr, dims, lo, hi, column=None):
    """Values within [lo, hi] (None: unbounded; a name: a dimension)."""
    values = _column(arr, column)
    if values.size == 0:
        return None
    slack = _TOL if arr.dtype.kind == "f" else 0
    lo, hi = _bound(lo, dims), _bound(hi, dims)
    where = "" if column is None else f" in column {column}"
    if lo is not None and values.min() < lo - slack:
        return f"holds {values.min().item()!r}{where}, below {lo}"
    if hi is not None and values.max() > hi + slack:
        return f"holds {values.max().item()!r}{where}, above {hi}"
    return None


def _rule_index(arr, dims, bound, column=None):
    """Indices in 0 .. bound - 1."""
    n = _bound(bound, dims)
    values = _column(arr, column)
    if values.size and (values.min() < 0 or values.max() >= n):
        bad = values.min() if values.min() < 0 else values.max()
        return f"holds index {bad}{'' if column is None else f' in column {column}'}, outside 0..{n - 1}"
    return None


def _rule_nondecreasing(arr, dims, column=None):
    """Non-decreasing along the last axis (or down ``column``)."""
    values = _column(arr, column)
    if values.shape[-1] > 1 and (np.diff(values, axis=-1) < -_TOL).any():
        return "is not non-decreasing" + ("" if column is None else f" in column {column}") + " (reversed or shuffled)"
    return None


def _rule_positive(arr, dims):
    return f"holds {arr.min().item()!r}, not positive" if arr.size and arr.min() <= 0 else None


def _rule_sum(arr, dims, total, tol):
    s = float(arr.sum(dtype=np.float64))
    return None if abs(s - total) <= tol else f"sums to {s!r}, not {total}"


def _rule_dim(arr, dims, axis, lo, hi):
    """``lo <= arr.shape[axis] <= hi`` (None: unbounded)."""
    n = arr.shape[axis]
    if n < lo or (hi is not None and n > hi):
        return f"has {n} entries along axis {axis}; the metadata allows {lo} to {'any' if hi is None else hi}"
    return None


def _rule_sum_defines(arr, dims, name):
    """Bind dimension ``name`` to the array's sum (after its range was checked)."""
    dims[name] = int(arr.sum(dtype=np.int64))
    return None


def _rule_last(arr, dims, value, tol):
    """Every row ends at ``value``."""
    if arr.size and (np.abs(arr[..., -1] - value) > tol).any():
        return f"has rows that do not end at {value}"
    return None


def _rule_products_define(arr, dims, name, other):
    """Bind dimension ``name`` to the sum of the array's entries times ``other``'s (an array of
    the same shape checked before it): e.g. each cluster's members times its components."""
    dims[name] = int((arr.astype(np.int64) * other.astype(np.int64)).sum())
    return None


def _rule_not_below(arr, dims, other, arrays):
    if (arr < arrays[other]).any():
        return f"holds values below those of {other}"
    return None


_RULES = {"range": _rule_range, "index": _rule_index, "nondecreasing": _rule_nondecreasing,
          "positive": _rule_positive, "sum": _rule_sum, "dim": _rule_dim, "sum_defines": _rule_sum_defines,
          "last": _rule_last}


def _shape_text(shape, dims):
    parts = [str(d) if not isinstance(d, str) else (f"{d}={dims[d]}" if d in dims else d) for d in shape]
    return "(" + ", ".join(parts) + ("," if len(parts) == 1 else "") + ")"


def _check_array(spec, arrays, dims, prefix):
    """The problem with one array (a phrase naming it), or None."""
    name, shape, kind, says, rules = spec
    full = prefix + name
    arr = arrays.get(full)
    if arr is None:
        return f"array {full} is missing ({says})"
    if arr.dtype.kind not in ("f" if kind == "f" else "iu"):
        return (f"array {full} holds values of type {arr.dtype}, not "
                f"{'real floating-point numbers' if kind == 'f' else 'integers'}")
    if arr.ndim != len(shape) or any(not (isinstance(d, str) and d not in dims) and _bound(d, dims) != n
                                     for d, n in zip(shape, arr.shape)):
        return f"{full} has shape {arr.shape} but should be {_shape_text(shape, dims)} ({says})"
    for d, n in zip(shape, arr.shape):
        if isinstance(d, str):
            dims.setdefault(d, n)
    if kind == "f":
        if not _all_finite(arr):
            return f"array {full} holds NaN or infinite values"
        # float16 values are at most 65504; larger ones overflow float32 generation.
        if arr.dtype != np.float16 and ("unbounded",) not in rules and arr.size and np.abs(arr).max() > _LIMIT:
            return (f"{full} holds {np.abs(arr).max().item()!r} in magnitude, beyond {_LIMIT:g}: "
                    "no fitted model comes near")
    for rule in rules:
        if callable(rule):
            problem = rule(arr, dims)
        elif rule[0] == "unbounded":
            problem = None
        elif rule[0] == "not_below":
            problem = _rule_not_below(arr, dims, prefix + rule[1], arrays)
        elif rule[0] == "products_define":
            problem = _rule_products_define(arr, dims, rule[1], arrays[prefix + rule[2]])
        else:
            problem = _RULES[rule[0]](arr, dims, *rule[1:])
        if problem:
            return f"{full} {problem}"
    return None


def _check_arrays(path, groups, arrays, meta=None):
    """Every array of ``arrays`` against its spec; :class:`ModelFileError` naming the first
    bad one. ``groups``: ``[(prefix, specs), ...]`` (the model and its coarse layout model,
    each with its own dimensions). An array no spec names is refused too: what a format
    version holds is fixed (a new array means a new version), so an unknown one is an
    edited file or another program's, and ignoring it would hide that."""
    known = set()
    for prefix, specs in groups:
        dims = {}
        for spec in specs:
            known.add(prefix + spec[0])
            problem = _check_array(spec, arrays, dims, prefix)
            if problem:
                raise _unusable(path, meta, problem)
    unknown = sorted(set(arrays) - known)
    if unknown:
        raise _unusable(path, meta, f"array {unknown[0]} is not part of a tghop model of format version "
                                    f"{meta.get('format_version')}")


def load_model(path, *, material=False):
    """Read a model written by :func:`save_model`: a :class:`~tghop.synthesis.TGHop`, or,
    with ``material``, a :class:`~tghop.material.Material` too (format version 5 or later; without
    ``material`` such a file is refused with a one-line error, so that no caller is handed
    a material where it expects a plain model).

    Every array is checked against the metadata before it is used (shape, type, finite
    values, ranges; see :func:`_check_arrays`).

    Parameters
    ----------
    path : str, os.PathLike or binary file object
        A file :func:`save_model` (or ``tghop fit``) wrote; read with ``allow_pickle=False``. A file
        object (``io.BytesIO(data)``, ``open(name, "rb")``, an upload's; 0.58) is read from its position
        to its end (one that cannot seek, or is not at its start, copied into memory first), with every
        check a file gets, and left open; one at its end (written into, not rewound) is refused naming
        ``seek(0)``. Messages name it by its ``name``, else its type ("the BytesIO given").
    material : bool
        Accept a file of a whole material too.

    Returns
    -------
    tghop.synthesis.TGHop or tghop.material.Material
        Fitted: it generates what the saved model generated, bit for bit, with the same seeds.

    Raises
    ------
    ModelFileError
        The file is missing, not a tghop model, corrupt, or of another format version (a file
        object: open in text mode, closed or unreadable too); or an
        archive whose arrays would unpack to more than 20 times its size (a decompression bomb;
        0.57: :func:`tghop._archives.unpacks_too_far`), refused before any is unpacked.
    """
    meta, arrays, path = _read(path)  # path: how messages name it (a file object's name or type)
    if meta["format_version"] == 4 and isinstance(meta.get("params"), dict):
        # tghop 0.14's opt-in patch statistics: replaced by other ones, so left out.
        for name in ("patch.rotations", "patch.quantiles"):
            arrays.pop(name, None)
        if meta["params"].get("patch_levels"):
            meta["params"]["patch_levels"] = 0
            warn(f"{path}: its patch refinement statistics are of tghop 0.14 and are not used; "
                 "fit the model again (patch_levels, --patch-levels) for the patch refinement",
                 stacklevel=2)
    # Files before the settings (0.13 and older) have none: no patch statistics (0.20 and
    # older: directions not whitened).
    for part in (meta, (meta.get("layout") or {}).get("model") if isinstance(meta.get("layout"), dict) else None):
        if isinstance(part, dict) and isinstance(part.get("params"), dict):
            part["params"].setdefault("patch_levels", 0)
            part["params"].setdefault("patch_whitening", 0.0)  # random directions before 0.21
    if meta["format_version"] == 2 and isinstance(meta.get("params"), dict):
        meta["params"].setdefault("ica_tol", 1e-4)  # what version 2 (tghop 0.2.0) fitted with
    try:
        # Version 3 scales every mixing matrix; version 2 none (read as _from_arrays does: by what is there).
        quantised = meta["format_version"] >= 3 or {p for p in ("", "layout.")
                                                     if f"{p}index.ichm_mixing_scale" in arrays}
        kind = Material if "material" in meta else TGHop
        if kind is Material and meta["format_version"] < MATERIAL_VERSION:
            raise TGHopError(f"a material in format version {meta['format_version']}; materials are version "
                             f"{MATERIAL_VERSION}")
        if kind is Material and meta["format_version"] < FORMAT_VERSION and (
                "patch_levels" in meta["material"] or any(n.startswith(MATERIAL_PATCH_PREFIX) for n in arrays)):
            # 0.60 read them: a version holds a fixed set of arrays, and these came with 11 (0.59)
            raise TGHopError(f"the albedo's patch statistics (material_patch.*) in format version "
                             f"{meta['format_version']}; they are version {FORMAT_VERSION}'s")
        groups = kind._array_specs(meta, quantised=quantised)
    except TGHopError as exc:
        raise _unusable(path, meta, exc) from None
    except (KeyError, TypeError, ValueError, IndexError, AttributeError, OverflowError) as exc:
        raise _unusable(path, meta, _metadata_problem(exc)) from None
    if kind is Material and not material:
        names = ", ".join(m["name"] for m in meta["material"]["maps"])
        raise ModelFileError(f"{path} is a material ({names}), not a plain model: a material makes every map at "
                             "once ('tghop synth', painted with --guide too; 'tghop inpaint' and 'extend' with --maps; "
                             "load_model(path, material=True)); for this, fit a plain model from its albedo")
    _check_arrays(path, groups, arrays, meta)
    try:
        model = kind._from_state(meta, arrays)
    except TGHopError as exc:
        raise _unusable(path, meta, exc) from None
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        raise _unusable(path, meta, _metadata_problem(exc)) from None
    newer = _newer_maker(meta)
    if newer:
        warn(f"{path}: made by tghop {newer}, newer than this {__version__}, which reads it as a model of "
             "its own version (what the newer one added is not used); upgrade tghop to use it", stacklevel=2)
    return model


def _release(version):
    """The numbers a version string starts with ("0.32.0rc1" -> (0, 32, 0)), or None."""
    import re

    found = re.match(r"\d+(\.\d+)*", version) if isinstance(version, str) else None
    return tuple(int(part) for part in found.group().split(".")) if found else None


def _newer_maker(meta):
    """The tghop version that wrote a file when it is newer than this one (else None):
    the same format version, but perhaps settings or meanings this one does not know."""
    theirs, ours = _release(meta.get("tghop_version")), _release(__version__)
    if theirs is None or ours is None:
        return None
    width = max(len(theirs), len(ours))
    pad = lambda v: v + (0,) * (width - len(v))  # noqa: E731
    return meta["tghop_version"] if pad(theirs) > pad(ours) else None


def _unusable(label, meta, detail) -> ModelFileError:
    """The one message for a model file whose contents this tghop cannot use (0.62): the file, what happened to it
    (a newer tghop's; else edited, damaged or another program's), the fix (the command that makes it again), and only
    then what was found (``detail``: the array or metadata key, the internal names a user cannot act on). 0.61 put
    the internal names first ("invalid tghop model (...)", "material_patch.patch.directions is not part of ...").
    The error's ``fix`` is that command as the message gives it, ``material`` whether the file is a material's."""
    import shlex

    material = isinstance(meta, dict) and "material" in meta
    out = shlex.quote(str(label)) if isinstance(label, Path) else "MODEL.npz"
    fix = f"tghop fit ALBEDO --maps MAP ... -o {out}" if material else f"tghop fit EXEMPLAR -o {out}"
    newer = _newer_maker(meta) if isinstance(meta, dict) else None
    what = (f"made by tghop {newer}, newer than this {__version__}, and this one cannot use it; upgrade tghop, or "
            if newer else "this model file was edited, damaged or written by another program, so tghop cannot use "
            "it; ")
    error = ModelFileError(f"{label}: {what}fit the {'material' if material else 'model'} again from its "
                           f"{'maps' if material else 'exemplar'}: {fix} (what is wrong: {detail})")
    error.fix, error.material = fix, material  # for a caller whose user fixes it otherwise (the web page, 0.62)
    return error


def _metadata_problem(exc) -> str:
    """What a Python error met reading a model's metadata says, in words (0.61 gave its repr, "KeyError('x')")."""
    if isinstance(exc, KeyError):
        return f"the metadata has no {str(exc.args[0])[:60]!r}" if exc.args else "the metadata lacks a key"
    return f"the metadata is not as tghop writes it: {str(exc)[:200]}"
