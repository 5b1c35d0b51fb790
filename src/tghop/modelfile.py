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

Each part names and restores its own arrays (``Hop``, ``SpatialReduction`` and ``ICHM``
``_to_arrays`` / ``_from_arrays``, ``TGHop._to_arrays`` / ``_from_state``); the settings
come from :mod:`tghop.settings`, so a new setting is saved and restored without a change
here. This module is only the container: JSON header, format version, atomic writing.
It imports :mod:`tghop.synthesis`, never the other way round.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from pathlib import Path

import numpy as np

from . import __version__
from ._common import ModelFileError, TGHopError
from .imageio import check_output_path, write_atomic
from .synthesis import TGHop, model_arrays, parameter_groups  # noqa: F401 (re-exported)

__all__ = ["save_model", "load_model", "model_arrays", "parameter_groups", "FORMAT", "FORMAT_VERSION"]

FORMAT = "tghop-model"
FORMAT_VERSION = 3  # 2: refinement statistics (refine.*); 3: float16 mixing rows with a scale each
#: Versions this tghop reads (version 2 files hold the mixing matrix in float32).
READABLE_VERSIONS = (2, 3)


def save_model(model, path) -> None:
    """Write a fitted model to ``path`` (any name; the file appears whole or not at all)."""
    arrays = model._to_arrays()  # NotFittedError before anything else
    meta = {"format": FORMAT, "format_version": FORMAT_VERSION, "tghop_version": __version__,
            **model._state_meta()}
    arrays["__meta__"] = np.array(json.dumps(meta))
    check_output_path(path, what="model", error=ModelFileError)
    write_atomic(path, lambda fh: np.savez(fh, **arrays), what="model", error=ModelFileError)


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
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError, NotImplementedError, MemoryError,
            zlib.error, RuntimeError) as exc:
        if _is_image(path):
            raise ModelFileError(f"{path} is an image, not a model file; fit a model from it with "
                                 f"'tghop fit {path} -o model.npz'") from None
        raise ModelFileError(
            f"{path}: truncated, corrupt or not a tghop model file (cannot read it: {exc.__class__.__name__}); "
            "fit the model again with 'tghop fit'"
        ) from None
    if "__meta__" not in arrays:
        if any(name.endswith("data.pkl") for name in arrays):  # torch.save's zip layout
            raise ModelFileError(f"{path}: a PyTorch checkpoint, not a tghop model file (co-occurrence cGAN "
                                 "checkpoints are used with 'tghop cooc morph' or 'edit' and 'tghop baseline cooc --model')")
        raise ModelFileError(f"{path}: a NumPy archive but not a tghop model file; fit a model with 'tghop fit'")
    try:
        meta = json.loads(str(arrays.pop("__meta__")))
    except (ValueError, TypeError):
        raise ModelFileError(f"{path}: corrupt model metadata; fit the model again") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ModelFileError(f"{path}: not a tghop model file; fit a model with 'tghop fit'")
    version = meta.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise ModelFileError(f"{path}: corrupt model metadata (format_version {version!r} is not an integer); "
                             "fit the model again")
    if version not in READABLE_VERSIONS:
        raise ModelFileError(
            f"{path}: written in model format version {version} (by tghop {meta.get('tghop_version', '?')}), "
            f"but this tghop {__version__} reads versions {READABLE_VERSIONS[0]} to {READABLE_VERSIONS[-1]}; "
            "refit the model with this version"
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


def _is_image(path) -> bool:
    """Whether Pillow recognises ``path`` as an image (asked only once reading it as a model failed)."""
    from PIL import Image

    try:
        with Image.open(path):
            return True
    except Image.DecompressionBombError:
        return True
    except Exception:  # noqa: BLE001 (any failure: not an image Pillow can open)
        return False


def load_model(path):
    """Read a model written by :func:`save_model`.

    Raises
    ------
    ModelFileError
        The file is missing, not a tghop model, corrupt, or of another format version.
    """
    meta, arrays = _read(path)
    if meta["format_version"] == 2 and isinstance(meta.get("params"), dict):
        meta["params"].setdefault("ica_tol", 1e-4)  # what version 2 (tghop 0.2.0) fitted with
    for name, arr in arrays.items():
        if not _all_finite(arr):
            raise ModelFileError(f"{path}: corrupt tghop model (array {name} holds NaN or infinite values); "
                                 "fit the model again")
    try:
        return TGHop._from_state(meta, arrays)
    except TGHopError as exc:
        raise ModelFileError(f"{path}: invalid tghop model ({exc}); fit the model again") from None
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        raise ModelFileError(f"{path}: corrupt or incomplete tghop model ({exc}); fit the model again") from None
