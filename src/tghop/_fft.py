"""The refinement's fast FFT: ``scipy.fft``'s compiled pocketfft, without ``scipy.fft``'s import.

Importing ``scipy.fft`` costs a large share of a large image's generation (SciPy's
array-API layer loads ``numpy.f2py`` and ``numpy.testing``, and ``scipy.special``), and
it holds the interpreter lock while the coarse guide's thread works (docs/choices.md).
The compiled module that does the transforms loads alone at a fraction of that cost.
This module is the one place that knows how: :func:`fft_for` picks ``numpy.fft`` or
SciPy's pocketfft by array size; :func:`scipy_fft` loads the compiled module
(:func:`load_pocketfft`), checks it against ``numpy.fft`` on a small array, and falls
back to ``scipy.fft`` itself if SciPy lays its files out otherwise or the check fails.
It is loaded on first use only (never on ``import tghop``), and registered under its own
name so that a later ``import scipy.fft`` takes this very module. ``tests/test_refine.py``
checks it bit for bit against ``scipy.fft`` and checks the fallback.
"""

from __future__ import annotations

import functools
import os
import sys
import threading

import numpy as np

__all__ = ["SCIPY_FFT_PIXELS", "fft_for", "scipy_fft", "load_pocketfft", "PocketFFT"]

#: Arrays from this many pixels on are transformed with SciPy's pocketfft.
SCIPY_FFT_PIXELS = 512 * 512


def fft_for(n_pixels):
    """The FFT module for arrays of ``n_pixels``: ``numpy.fft`` below
    :data:`SCIPY_FFT_PIXELS`, so that generating small images never loads SciPy; SciPy's
    pocketfft from there on (:func:`scipy_fft`: it vectorises over several rows at once,
    which makes it faster than ``numpy.fft`` on large float32 arrays; measured:
    docs/choices.md).

    Either gives ``rfft2``, ``ifft`` and ``irfft`` with ``scipy.fft``'s arguments
    (``workers``, ``overwrite_x``) or NumPy's.
    """
    if n_pixels >= SCIPY_FFT_PIXELS:
        return scipy_fft()
    return np.fft


#: The compiled module behind ``scipy.fft`` (its functions are what the refinement uses of
#: ``scipy.fft``, less the argument checks).
_POCKETFFT = "scipy.fft._pocketfft.pypocketfft"


_LOADING = threading.Lock()


@functools.lru_cache(maxsize=1)
def scipy_fft():
    """What the refinement uses of ``scipy.fft`` (``rfft2``, ``ifft``, ``irfft``), from SciPy's
    compiled pocketfft module loaded alone when ``scipy.fft`` is not imported yet.

    Loaded once, whichever thread asks first (see the module's docstring). The same
    transforms as ``scipy.fft``, bit for bit (tested). If SciPy lays its files out
    otherwise, or the module does not give what ``scipy.fft`` gives on a small array,
    ``scipy.fft`` itself is used.
    """
    with _LOADING:  # one load, whichever thread asks first
        if "scipy.fft" not in sys.modules:
            try:
                fft = PocketFFT(load_pocketfft())
                x = np.linspace(0.0, 1.0, 12, dtype=np.float32).reshape(3, 4) ** 2
                spectrum = fft.rfft2(x, axes=(0, 1))
                back = fft.irfft(fft.ifft(spectrum.copy(), axis=0, overwrite_x=True), n=4, axis=1)
                if (np.allclose(spectrum, np.fft.rfft2(x), atol=1e-5) and np.allclose(back, x, atol=1e-5)
                        and back.dtype == np.float32):
                    return fft
            except Exception:  # noqa: BLE001 - any surprise: the public module below
                pass
        import scipy.fft

        return scipy.fft


def load_pocketfft():
    """SciPy's compiled pocketfft module, loaded from its file without ``scipy.fft``'s
    package (registered under its own name, so that a later ``import scipy.fft`` takes it)."""
    import importlib.machinery
    import importlib.util

    if _POCKETFFT in sys.modules:
        return sys.modules[_POCKETFFT]
    spec = importlib.util.find_spec("scipy")  # finds the package without importing it
    folder = os.path.join(os.path.dirname(spec.origin), "fft", "_pocketfft")
    name = next(f for f in sorted(os.listdir(folder))
                if f.startswith("pypocketfft.") and f.endswith(tuple(importlib.machinery.EXTENSION_SUFFIXES)))
    path = os.path.join(folder, name)
    loader = importlib.machinery.ExtensionFileLoader(_POCKETFFT, path)
    module = importlib.util.module_from_spec(importlib.util.spec_from_file_location(_POCKETFFT, path, loader=loader))
    loader.exec_module(module)
    sys.modules[_POCKETFFT] = module
    return module


class PocketFFT:
    """``rfft2``, ``ifft`` and ``irfft`` as ``scipy.fft`` has them (default normalisation),
    and the orthonormal ``dctn``, calling its compiled module as ``scipy.fft`` does."""

    def __init__(self, module):
        self._m = module

    def rfft2(self, x, axes=(-2, -1), workers=1):
        return self._m.r2c(np.asarray(x), tuple(axes), True, 0, None, int(workers))

    def ifft(self, x, axis=-1, overwrite_x=False, workers=1):
        return self._m.c2c(x, (axis,), False, 2, x if overwrite_x else None, int(workers))

    def dctn(self, x, type=2, axes=None, norm="ortho", workers=1):
        # Only the orthonormal transform (the seam removal's), as scipy.fft.dctn(norm="ortho").
        if norm != "ortho":
            raise ValueError("only norm='ortho' is supported")
        return self._m.dct(np.asarray(x), int(type), None if axes is None else tuple(axes), 1, None, int(workers), True)

    def irfft(self, x, n=None, axis=-1, overwrite_x=False, workers=1):
        # (scipy.fft does not use overwrite_x here either)
        return self._m.c2r(x, (axis,), (x.shape[axis] - 1) * 2 if n is None else n, False, 2, None, int(workers))
