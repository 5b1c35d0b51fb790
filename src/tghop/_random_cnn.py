"""The random multiscale single-layer CNN of Ustyuzhaninov et al. (ICLR 2017).

One convolutional layer of random Glorot-uniform filters at several sizes, ReLU, and the
Gram matrix of its feature maps: the texture model that :func:`tghop.baselines.ustyuzhaninov`
synthesises with and that :func:`tghop.metrics.gram_distance` measures with. Both import
it from here; neither reaches into the other.

Nothing here imports PyTorch: the caller passes the ``torch`` module in (from
:func:`tghop._resources.import_torch`), so importing this module costs only numpy and SciPy.
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from scipy.fft import next_fast_len

from ._errors import TGHopError

__all__ = [
    "USTYUZHANINOV_SCALES",
    "DIRECT_MAX",
    "random_filters",
    "check_scales",
    "RandomCNN",
    "to_tensor",
]

#: Filter sizes of Ustyuzhaninov et al.'s "RandomMultiscale" model (128 maps each).
USTYUZHANINOV_SCALES = (3, 5, 7, 11, 15, 23, 37, 55)

#: Filters up to this size are applied by direct convolution, larger ones by FFT: the
#: measured break-even of the two, forward and backward (the figures: docs/choices.md).
DIRECT_MAX = 11


def random_filters(scales, n_maps: int, channels: int, rng: np.random.Generator) -> list:
    """Random convolution filters, Glorot-uniform as in Ustyuzhaninov et al.

    Filters of size ``k`` are drawn from ``U(-b, b)`` with
    ``b = sqrt(6 / ((channels + n_maps) * k * k))`` (Glorot & Bengio 2010, as Lasagne
    initialises a convolution; the authors' code leaves them at that initialisation).
    The squared norm of a filter is then about ``2 * channels / (channels + n_maps)`` at
    every scale, so no scale is weighted by hand.

    Returns
    -------
    list of ndarray, each shape (n_maps, channels, k, k), float32
    """
    out = []
    for k in scales:
        bound = math.sqrt(6.0 / ((channels + n_maps) * k * k))
        out.append(rng.uniform(-bound, bound, size=(n_maps, channels, k, k)).astype(np.float32))
    return out


def check_scales(scales) -> tuple:
    """``scales`` as a tuple of odd positive filter sizes, or a one-line :class:`TGHopError`
    (a size that is not an integer, such as 3.5, "3" or True, is refused, not truncated)."""
    try:
        items = tuple(scales)
    except TypeError:
        raise TGHopError(f"scales must be a sequence of odd filter sizes, got {scales!r}") from None
    whole = all(isinstance(k, (numbers.Integral, np.integer)) and not isinstance(k, (bool, np.bool_)) for k in items)
    if not items or not whole or any(k < 1 or k % 2 == 0 for k in items):
        raise TGHopError(f"scales must be odd positive filter sizes, got {items}")
    return tuple(int(k) for k in items)


class RandomCNN:
    """One convolutional layer of random filters at several sizes, ReLU, and its Gram matrix.

    The layer is a cross-correlation with stride 1 and no bias, as in the paper (Lasagne,
    ``flip_filters=False``). Filters up to :data:`DIRECT_MAX` pixels are applied
    directly (``conv2d``); larger ones by FFT, which is much faster for the 23 to 55 pixel
    filters of the paper. Inputs are ``(C, H, W)`` float32 tensors, already centred (the
    caller subtracts the exemplar's mean colour, so zero padding means "mean colour").

    ``mode="same"``: outputs at all ``H x W`` positions, zero padding at the borders (the
    paper's model, used for synthesis). ``mode="valid"``: only positions where the largest
    filter lies inside the image, so every feature is a true texture statistic (used by
    the metric, where border effects would make images of different sizes incomparable).
    """

    def __init__(self, torch, filters):
        self.torch = torch
        self.filters = [torch.from_numpy(np.ascontiguousarray(f)) for f in filters]
        self.sizes = [int(f.shape[-1]) for f in filters]
        self.n_features = sum(int(f.shape[0]) for f in filters)
        self._cache: dict = {}

    def margin(self, mode: str) -> int:
        return max(self.sizes) // 2 if mode == "valid" else 0

    def _spectra(self, h: int, w: int, mode: str):
        """FFT sizes and spectra of the large filters for an ``h x w`` input (two sizes cached)."""
        key = (h, w, mode)
        if key not in self._cache:
            torch = self.torch
            m = self.margin(mode)
            entries = {}
            for i, (k, filt) in enumerate(zip(self.sizes, self.filters)):
                if k <= DIRECT_MAX:
                    continue
                # Output rows m..h-m-1 (in "same" coordinates) are free of circular
                # wrap-around iff the FFT length is at least h + k//2 - m.
                fh = next_fast_len(max(h, h + k // 2 - m), real=True)
                fw = next_fast_len(max(w, w + k // 2 - m), real=True)
                with torch.no_grad():
                    # Flipped: FFT products convolve, the layer cross-correlates.
                    spec = torch.fft.rfft2(torch.flip(filt, dims=(-2, -1)), s=(fh, fw))  # (M, C, fh, fw//2+1)
                entries[i] = (fh, fw, spec)
            if len(self._cache) >= 2:  # exemplar and result: bound the memory to two sizes
                self._cache.pop(next(iter(self._cache)))
            self._cache[key] = entries
        return self._cache[key]

    def forget(self, h: int, w: int, mode: str) -> None:
        """Free the cached filter spectra for one input size."""
        self._cache.pop((h, w, mode), None)

    def features(self, x, mode: str = "same"):
        """ReLU feature maps.

        Parameters
        ----------
        x : torch.Tensor, shape (C, H, W), float32
        mode : {"same", "valid"}

        Returns
        -------
        torch.Tensor, shape (n_features, P), float32
            ``P`` is ``H * W`` ("same") or the number of valid positions.
        """
        torch = self.torch
        c, h, w = x.shape
        m = self.margin(mode)
        if h - 2 * m < 1 or w - 2 * m < 1:
            raise TGHopError(f"a {h}x{w} image is smaller than the largest filter ({max(self.sizes)})")
        spectra = self._spectra(h, w, mode)
        outs = []
        for i, (k, filt) in enumerate(zip(self.sizes, self.filters)):
            if i in spectra:
                fh, fw, spec = spectra[i]
                xs = torch.fft.rfft2(x, s=(fh, fw))  # (C, fh, fw//2+1)
                ys = xs[0] * spec[:, 0]
                for ch in range(1, c):
                    ys = ys + xs[ch] * spec[:, ch]
                y = torch.fft.irfft2(ys, s=(fh, fw))  # (M, fh, fw): full linear convolution
                off = k // 2 + m
            else:
                y = torch.nn.functional.conv2d(x[None], filt, padding=k // 2)[0]  # (M, H, W)
                off = m
            y = y[:, off : off + h - 2 * m, off : off + w - 2 * m]
            outs.append(torch.relu(y).reshape(y.shape[0], -1))
        return torch.cat(outs, dim=0)

    def gram(self, x, mode: str = "same"):
        """Gram matrix ``F F^T / P`` (the mean outer product of the feature vectors).

        Returns
        -------
        torch.Tensor, shape (n_features, n_features), float32
        """
        f = self.features(x, mode)
        return (f @ f.T) / f.shape[1]


def to_tensor(torch, img: np.ndarray, mean: np.ndarray):
    """``(H, W, C)`` float image minus ``mean`` -> ``(C, H, W)`` float32 tensor."""
    return torch.from_numpy(np.ascontiguousarray((img - mean).transpose(2, 0, 1), dtype=np.float32))
