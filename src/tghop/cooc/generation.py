"""Generation from a trained co-occurrence cGAN, and its controls (its networks are
:mod:`tghop.cooc.networks`; TGHop's own image pipeline is :mod:`tghop.generation`).

:class:`GenerationMixin` holds the methods that make images from the generator; it is mixed
into :class:`tghop.cooc.model.CoocGAN`, whose statistics and state it uses (``s``,
``settings_``, ``exemplar_cooc_``, ``exemplar_shape_``, ``cond_mean_``, ``_check_fitted``,
``_normalise``, ``_output_generator``, ``_device``):

* :meth:`~GenerationMixin.generate` and :meth:`~GenerationMixin.generate_batch` -- texture from
  co-occurrence tensors and noise (:meth:`~GenerationMixin.noise`), in one generator pass or in
  overlapping training-size windows (:meth:`~GenerationMixin.generate_windows`);
* :meth:`~GenerationMixin.crop_condition`, :meth:`~GenerationMixin.condition_for` -- conditions
  taken from the exemplar's own tensor;
* :meth:`~GenerationMixin.sample` -- a texture of any size by one of the
  :data:`~tghop.cooc.assembly.ASSEMBLIES` (quilting :meth:`~GenerationMixin.crop_pool`'s
  crops by default);
* :meth:`~GenerationMixin.morph_strip`, :meth:`~GenerationMixin.morph_grid` -- interpolated
  conditions and noise.

The pieces the assemblies are made of (windows, blends, tiling) are in :mod:`tghop.cooc.assembly`.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .._arrays import check_int
from .._errors import TGHopError
from .._estimator import check_rng
from .._images import check_size
from .._progress import ProgressCallback, report
from .._resources import import_torch
from .assembly import (
    FEATHER,
    QUILT_DETAIL,
    QUILT_POOL,
    QUILT_TOLERANCE,
    blend_weights,
    check_assembly,
    mirror_pad,
    reflect_tile,
    tile,
    window_layout,
)

__all__ = ["GenerationMixin", "check_noise"]


def check_noise(noise: np.ndarray) -> None:
    """Refuse a noise tensor with NaN or infinite values (they give a NaN image).

    Parameters
    ----------
    noise : ndarray
        The noise the generator is given (:meth:`CoocGAN.noise <tghop.cooc.model.CoocGAN.noise>` draws it).

    Raises
    ------
    TGHopError
        If any value of ``noise`` is NaN or infinite.
    """
    if not np.isfinite(noise).all():
        raise TGHopError("noise contains NaN or infinite values; give finite noise (CoocGAN.noise draws it)")


class GenerationMixin:
    """Generation and the controls, for :class:`tghop.cooc.model.CoocGAN` (see the module's docstring)."""

    def _check_cond(self, cond) -> np.ndarray:
        self._check_fitted()  # the morphs read cond_mean_ first: an AttributeError before fit (0.59)
        k2 = len(self.cond_mean_)
        cond = np.asarray(cond, dtype=np.float64)
        if cond.ndim != 3 or cond.shape[0] != k2:
            raise TGHopError(f"a co-occurrence tensor of this model has shape ({k2}, h, w), got {cond.shape}")
        if cond.size == 0:
            raise TGHopError(f"a co-occurrence tensor needs at least one cell (h, w >= 1), got shape {cond.shape}")
        if not np.all(np.isfinite(cond)) or cond.min() < 0:
            raise TGHopError("a co-occurrence tensor must be finite and non-negative")
        sums = cond.sum(axis=0)
        if np.any(sums <= 0):
            raise TGHopError("every cell of a co-occurrence tensor needs a positive sum")
        return cond / sums  # each cell a distribution, as after the paper's re-normalisation

    def noise(self, shape, *, rng=None) -> np.ndarray:
        """A noise tensor for a condition of spatial ``shape = (h, w)``.

        Parameters
        ----------
        shape : int or (int, int)
            The condition's cells (h, w); ``n`` means ``(n, n)``.
        rng : int or numpy.random.Generator, optional
            Same seed, same noise.

        Returns
        -------
        ndarray, shape (noise_channels, h, w), float32, N(0, 1)
        """
        self._check_fitted()
        h, w = check_size(shape, name="the noise's shape")
        return check_rng(rng).standard_normal((int(self.settings_["noise_channels"]), h, w)).astype(np.float32)

    def generate(self, cond, *, noise=None, rng=None, windows: bool = False,
                 feather: Optional[int] = None) -> np.ndarray:
        """Texture from a co-occurrence tensor (and noise).

        The generator runs once on the whole condition (the paper's way). With
        ``windows=True`` a condition larger than the generator's training conditions
        (``tiles * crop_size // s`` cells a side) is generated in overlapping
        training-size windows instead (:meth:`generate_windows`); on the models tried
        that gave no better images (docs/choices.md), so it is not the default.

        Parameters
        ----------
        cond : array_like, shape (k*k, h, w)
            Co-occurrence tensor (from :meth:`cooccurrence`, :func:`paint_condition`, an
            interpolation or an edit); each cell is re-normalised to sum to 1.
        noise : array_like, shape (noise_channels, h, w), optional
            Noise tensor (:meth:`noise`), finite; default drawn from ``rng``.
        rng : int or numpy.random.Generator, optional
        windows : bool
            Generate in overlapping training-size windows (:meth:`generate_windows`).
        feather : int, optional
            With ``windows``: width in pixels of the raised-cosine blend between windows
            (see :meth:`generate_windows`).

        Returns
        -------
        ndarray, shape (h * s, w * s, C), float64 in [0, 1]
        """
        if windows:
            return self.generate_windows(cond, noise=noise, rng=rng, feather=feather)
        return self.generate_batch(np.asarray(cond)[None], None if noise is None else np.asarray(noise)[None],
                                   rng=rng)[0]

    def generate_batch(self, conds, noise=None, *, rng=None, windows: bool = False) -> np.ndarray:
        """:meth:`generate` for a batch: ``conds (N, k*k, h, w)`` -> ``(N, h*s, w*s, C)``.

        ``windows=True`` generates each item in windows (:meth:`generate_windows`);
        conditions no larger than the training crops' are one window, i.e. one pass.

        Parameters
        ----------
        conds : sequence of array_like, shape (k*k, h, w) each
            Co-occurrence tensors of one shape (:meth:`crop_condition`, :meth:`condition_for`).
        noise : array_like, shape (N, noise_channels, h, w), optional
            Default: drawn from ``rng`` (:meth:`noise`, item by item).
        rng : int or numpy.random.Generator, optional
            The noise's, when ``noise`` is not given.
        windows : bool
            As :meth:`generate`.

        Returns
        -------
        ndarray, shape (N, h*s, w*s, C), float64 in [0, 1]
        """
        self._check_fitted()
        torch = import_torch("the co-occurrence cGAN")
        conds = [self._check_cond(c) for c in conds]
        if not conds:
            raise TGHopError("conds is empty: give at least one co-occurrence tensor")
        if len({c.shape for c in conds}) > 1:
            raise TGHopError(f"the conditions of a batch need one shape, got {sorted({c.shape for c in conds})}")
        conds = np.stack(conds)
        n, _, h, w = conds.shape
        if noise is None:
            r = check_rng(rng)
            noise = np.stack([self.noise((h, w), rng=r) for _ in range(n)])
        noise = np.asarray(noise, dtype=np.float32)
        if noise.shape != (n, int(self.settings_["noise_channels"]), h, w):
            raise TGHopError(f"noise must have shape {(n, self.settings_['noise_channels'], h, w)}, got {noise.shape}")
        check_noise(noise)
        if windows and (h > self._window_cells or w > self._window_cells):
            return np.stack([self.generate_windows(c, noise=z) for c, z in zip(conds, noise)])
        return np.clip(self._run_generator(torch, conds, noise), 0.0, 1.0)

    def _run_generator(self, torch, conds, noise) -> np.ndarray:
        """The generator on raw conditions ``(N, k*k, h, w)`` and float32 noise ``(N, noise_channels,
        h, w)``: ``(N, h*s, w*s, C)`` float64, mapped from [-1, 1] to [0, 1] but not clipped."""
        with torch.no_grad():
            c = self._normalise(torch.as_tensor(conds, dtype=torch.float32, device=self._device))
            out = self._output_generator(c, torch.as_tensor(noise, device=self._device))
        return (out.double().cpu().numpy().transpose(0, 2, 3, 1) + 1.0) * 0.5

    @property
    def _window_cells(self) -> int:
        """Side of the generator's training condition in cells (``tiles * crop_size // s``)."""
        return max(1, int(self.settings_["tiles"]) * int(self.settings_["crop_size"]) // self.s)

    def generate_windows(self, cond, *, noise=None, rng=None, feather: Optional[int] = None,
                         batch: int = 64) -> np.ndarray:
        """Texture from a condition of any size, generated in overlapping training-size windows.

        The condition (and one noise field for the whole image) is cut into windows of
        ``n = tiles * crop_size // s`` cells a side -- the size the generator was trained at --
        with a stride of ``max(1, n // 2)`` cells, each window is generated on its own,
        and each window contributes its central ``stride x stride`` cells, cross-faded
        into its neighbours' with raised-cosine ramps ``feather`` pixels wide (the ramps
        sum to one, so the blend is a partition of unity). Adjacent windows see the same
        noise and condition where they overlap, so they mostly agree there. The condition
        and noise are mirror-padded by the window's margin so that the image border, too,
        comes from windows' centres. Along an axis of at most ``n`` cells there is one
        window of that axis's length; a condition of at most ``n x n`` cells is one
        window, i.e. exactly ``generate(cond, noise=noise, rng=rng)``.

        Parameters
        ----------
        cond : array_like, shape (k*k, h, w)
            Co-occurrence tensor, as for :meth:`generate`.
        noise : array_like, shape (noise_channels, h, w), optional
            Noise tensor; mirror-padded with the condition. Default: drawn from ``rng``
            for the padded grid.
        rng : int or numpy.random.Generator, optional
        feather : int, optional
            Blend width in pixels, from 0 (hard seams between the windows' centres) to
            ``min(stride, 2 * margin) * s`` with ``margin = (n - stride) // 2`` (for
            ``n = 4``: 2 cells, the window's whole margin, a sin^2 window). Default
            :data:`~tghop.cooc.assembly.FEATHER` times that.
        batch : int
            Windows per generator call.

        Returns
        -------
        ndarray, shape (h * s, w * s, C), float64 in [0, 1]
        """
        self._check_fitted()
        torch = import_torch("the co-occurrence cGAN")
        cond = self._check_cond(cond)
        k2, h, w = cond.shape
        n, s = self._window_cells, self.s
        if h <= n and w <= n:
            return self.generate(cond, noise=noise, rng=rng)
        stride = max(1, n // 2)
        limit = min(stride, 2 * ((n - stride) // 2)) * s  # ramps within the overlap and the window
        feather = int(round(FEATHER * limit)) if feather is None else check_int(feather, "feather", 0)
        batch = check_int(batch, "batch")
        if not 0 <= feather <= limit:
            raise TGHopError(f"feather must lie in 0..{limit} pixels (the windows' overlap), got {feather}")
        ys, pads_y, wy = window_layout(h, n, stride)
        xs, pads_x, wx = window_layout(w, n, stride)
        channels = int(self.settings_["noise_channels"])
        padded_shape = (h + sum(pads_y), w + sum(pads_x))
        if noise is None:
            z = self.noise(padded_shape, rng=rng)
        else:
            z = np.asarray(noise, dtype=np.float32)
            if z.shape != (channels, h, w):
                raise TGHopError(f"noise must have shape {(channels, h, w)}, got {z.shape}")
            check_noise(z)
            z = mirror_pad(z, pads_y, pads_x)
        c = mirror_pad(cond, pads_y, pads_x)
        weight_y = blend_weights(wy * s, pads_y[0] * s, (pads_y[0] + stride) * s, feather, h > n)
        weight_x = blend_weights(wx * s, pads_x[0] * s, (pads_x[0] + stride) * s, feather, w > n)
        weight = (weight_y[:, None] * weight_x[None, :])[:, :, None]
        canvas = np.zeros((padded_shape[0] * s, padded_shape[1] * s, self.exemplar_shape_[2]))
        total = np.zeros(canvas.shape[:2] + (1,))
        starts = [(y, x) for y in ys for x in xs]
        for i in range(0, len(starts), int(batch)):
            part = starts[i : i + int(batch)]
            conds = np.stack([c[:, y : y + wy, x : x + wx] for y, x in part])
            noises = np.stack([z[:, y : y + wy, x : x + wx] for y, x in part])
            for (y, x), piece in zip(part, self._run_generator(torch, conds, noises)):
                canvas[y * s : (y + wy) * s, x * s : (x + wx) * s] += weight * piece
                total[y * s : (y + wy) * s, x * s : (x + wx) * s] += weight
        out = canvas / np.maximum(total, 1e-12)
        y0, x0 = pads_y[0] * s, pads_x[0] * s
        return np.clip(out[y0 : y0 + h * s, x0 : x0 + w * s], 0.0, 1.0)

    def crop_condition(self, y: int, x: int, size: Optional[int] = None) -> np.ndarray:
        """The co-occurrence tensor of the exemplar's ``size`` x ``size`` crop at pixel ``(y, x)``.

        Taken from :attr:`exemplar_cooc_` at cell resolution (``y``, ``x`` and ``size``,
        integers, are rounded down to multiples of ``s``; default size ``crop_size``).

        Parameters
        ----------
        y, x : int
            The crop's top-left pixel, at least 0.
        size : int, optional
            Its side in pixels (default ``crop_size``); the crop must lie inside the exemplar.

        Returns
        -------
        ndarray, shape (k*k, size // s, size // s)
        """
        self._check_fitted()
        s = self.s
        size = int(self.settings_["crop_size"]) if size is None else check_int(size, "size")
        y, x = check_int(y, "y", 0), check_int(x, "x", 0)
        t = self.exemplar_cooc_
        cy, cx, n = y // s, x // s, max(1, size // s)
        if min(cy, cx) < 0 or cy + n > t.shape[1] or cx + n > t.shape[2]:
            raise TGHopError(f"a {size}x{size} crop at ({y}, {x}) is not inside the "
                             f"{self.exemplar_shape_[0]}x{self.exemplar_shape_[1]} exemplar")
        return t[:, cy : cy + n, cx : cx + n].copy()

    def condition_for(self, size, *, rng=None) -> np.ndarray:
        """The exemplar's own co-occurrence tensor, mirror-tiled from a random offset to cover ``size``.

        Parameters
        ----------
        size : int or (int, int)
            The image (h, w) in pixels it is for (:func:`tghop._images.check_size`: at least 1,
            at most :data:`tghop._images.MAX_PIXELS`); ``n`` means ``(n, n)``.
        rng : int or numpy.random.Generator, optional
            The offset's.

        Returns
        -------
        ndarray, shape (k*k, ceil(h / s), ceil(w / s))
        """
        self._check_fitted()
        h, w = check_size(size)
        s = self.s
        hh, ww = -(-h // s), -(-w // s)
        t = self.exemplar_cooc_
        r = check_rng(rng)
        offset = (int(r.integers(2 * t.shape[1])), int(r.integers(2 * t.shape[2])))
        return reflect_tile(t, hh, ww, offset)

    def sample(self, size=(256, 256), *, rng=None, progress: Optional[ProgressCallback] = None,
               assembly: str = "quilt") -> np.ndarray:
        """A texture of any size with the exemplar's statistics.

        Parameters
        ----------
        size : int or (int, int)
        rng : int or numpy.random.Generator, optional
            Chooses the conditions and the noise (and, with ``"quilt"``, the quilting).
        progress : callable, optional
            Stage "generate" (and "quilting" with ``"quilt"``).
        assembly : {"quilt", "pass", "windows"}
            How the image is made from the generator (see :data:`~tghop.cooc.assembly.ASSEMBLIES`):

            - ``"quilt"`` (ours, the default): :meth:`crop_pool` generates
              :data:`~tghop.cooc.assembly.QUILT_POOL` crops of the training size (fewer
              for crops larger than 64 px), each from a random exemplar crop's tensor, and image
              quilting (:func:`tghop.quilting.quilt`, overlap a quarter of a crop,
              preferring detailed candidates as TGHop does) stitches them, so the
              generator only ever runs at the size it was trained at;
            - ``"pass"`` (the paper's): one generator pass over the exemplar's tensor,
              mirror-tiled from a random offset to the output size (:meth:`condition_for`);
            - ``"windows"``: that tensor in overlapping training-size windows
              (:meth:`generate_windows`).

        Returns
        -------
        ndarray, shape (h, w, C), float64 in [0, 1]
        """
        self._check_fitted()
        check_assembly(assembly)
        h, w = check_size(size, default=(1, 1))
        r = check_rng(rng)
        if assembly == "quilt":
            from ..quilting import quilt

            side = self._window_cells * self.s
            n = min(QUILT_POOL, max(100, QUILT_POOL * 64 * 64 // (side * side)))
            pool = self.crop_pool(n, rng=r, progress=progress)
            return quilt(pool, (h, w), overlap=max(1, side // 4), tolerance=QUILT_TOLERANCE, detail=QUILT_DETAIL,
                         rng=r, progress=progress)  # float64 already
        out = self.generate(self.condition_for((h, w), rng=r), rng=r, windows=assembly == "windows")
        report(progress, "generate", 1, 1)
        return out[:h, :w]

    def crop_pool(self, n: int, *, rng=None, batch: int = 64,
                  progress: Optional[ProgressCallback] = None) -> np.ndarray:
        """``n`` generated crops of the training size, each from a random exemplar crop's tensor.

        Each crop's condition is the tensor of an exemplar crop of the generator's training
        size (``tiles * crop_size`` px) at a random cell-aligned position
        (:meth:`crop_condition`): the distribution the generator was trained on. Each has
        its own noise.

        Parameters
        ----------
        n : int
        rng : int or numpy.random.Generator, optional
        batch : int
            Crops per generator call.
        progress : callable, optional
            Stage "generate", crops done of ``n``.

        Returns
        -------
        ndarray, shape (n, side, side, C), float32 in [0, 1]
        """
        self._check_fitted()
        n, batch = check_int(n, "n"), check_int(batch, "batch")
        r = check_rng(rng)
        cells, s = self._window_cells, self.s
        _, hc, wc = self.exemplar_cooc_.shape
        ys = r.integers(0, hc - cells + 1, size=n) * s  # fit makes sure that a window fits
        xs = r.integers(0, wc - cells + 1, size=n) * s
        side = cells * s
        out = np.empty((n, side, side, self.exemplar_shape_[2]), dtype=np.float32)
        for a in range(0, n, batch):
            conds = [self.crop_condition(y, x, side) for y, x in zip(ys[a : a + batch], xs[a : a + batch])]
            out[a : a + len(conds)] = self.generate_batch(conds, rng=r)
            report(progress, "generate", a + len(conds), n)
        return out

    def morph_strip(self, a, b, *, length: int = 8, rng=None, windows: bool = False) -> np.ndarray:
        """One image whose co-occurrence moves from ``a`` to ``b`` left to right, under one noise tensor.

        Parameters
        ----------
        a, b : array_like, shape (k*k, h, w)
            Co-occurrence tensors (e.g. of two crops); tiled along the strip.
        length : int
            Strip length in condition cells (the image is ``length * s`` pixels wide).
        rng : int or numpy.random.Generator, optional
        windows : bool
            Training-size windows instead of one generator pass (see :meth:`generate`).

        Returns
        -------
        ndarray, shape (h * s, length * s, C)
        """
        a, b = self._check_cond(a), self._check_cond(b)
        if a.shape[1] != b.shape[1]:
            raise TGHopError(f"the two tensors need the same height, got {a.shape[1]} and {b.shape[1]}")
        length = check_int(length, "length", 2)
        t = np.linspace(0.0, 1.0, length)[None, None, :]
        cond = (1 - t) * tile(a, a.shape[1], length) + t * tile(b, b.shape[1], length)
        return self.generate(cond, rng=rng, windows=windows)

    def morph_grid(self, a, b, *, n_cols: int = 5, n_rows: int = 3, rng=None) -> np.ndarray:
        """The paper's Fig. 2: co-occurrence interpolated across (``a`` to ``b``), noise interpolated down.

        Parameters
        ----------
        a, b : array_like, shape (k*k, h, w)
        n_cols, n_rows : int
            Interpolation steps of the co-occurrence and of the noise (between two random
            noise tensors, on the great circle so every row's noise is N(0, 1)-like).
        rng : int or numpy.random.Generator, optional

        Returns
        -------
        ndarray, shape (n_rows, n_cols, h * s, w * s, C)
        """
        a, b = self._check_cond(a), self._check_cond(b)
        if a.shape != b.shape:
            raise TGHopError(f"the two tensors need the same shape, got {a.shape} and {b.shape}")
        n_cols, n_rows = check_int(n_cols, "n_cols"), check_int(n_rows, "n_rows")
        r = check_rng(rng)
        z0, z1 = self.noise(a.shape[1:], rng=r), self.noise(a.shape[1:], rng=r)
        rows = []
        for v in np.linspace(0.0, 1.0, n_rows):
            z = (math.cos(v * math.pi / 2) * z0 + math.sin(v * math.pi / 2) * z1).astype(np.float32)
            conds = [(1 - u) * a + u * b for u in np.linspace(0.0, 1.0, n_cols)]
            rows.append(self.generate_batch(np.stack(conds), np.stack([z] * n_cols)))
        return np.stack(rows)
