"""The co-occurrence cGAN model: its settings, its statistics and generation from it.

:class:`CoocGAN` holds a trained generator and the statistics it was trained with (colour
clusters, the exemplar's co-occurrence tensor); training is in :mod:`tghop.cooc.training`
(mixed in), the networks in :mod:`tghop.cooc.networks`, the checkpoint file in
:mod:`tghop.cooc.checkpoints`, the pieces of the assemblies in :mod:`tghop.cooc.assembly`.
Generation and the controls (in :mod:`tghop.cooc.generation`, mixed in too):

* :meth:`CoocGAN.generate` -- texture from a co-occurrence tensor and noise (one generator
  pass, or overlapping training-size windows: :meth:`CoocGAN.generate_windows`);
* :meth:`CoocGAN.sample` -- a texture of any size with the exemplar's statistics, by one of
  the :data:`~tghop.cooc.assembly.ASSEMBLIES`;
* :meth:`CoocGAN.morph_strip`, :meth:`CoocGAN.morph_grid` -- interpolated conditions and noise;
* :func:`load` reads a checkpoint, :func:`baseline` is the model as one of tghop's baselines.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .._arrays import check_int
from .._errors import NotFittedError, TGHopError
from .._estimator import BaseEstimator, ImageInputMixin, check_rng
from .._images import check_image, check_size, check_texture
from .._progress import ProgressCallback
from .._resources import check_memory, import_torch
from ..cooccurrence import cooccurrence_tensor
from .assembly import QUILT_POOL, check_assembly
from .checkpoints import read as read_checkpoint
from .checkpoints import save as save_checkpoint
from .config import check_settings, torch_device
from .generation import GenerationMixin, check_noise
from .training import TrainingMixin

# check_noise lives in tghop.cooc.generation since the split; still importable from here.
__all__ = ["CoocGAN", "load", "baseline", "memory_estimate", "check_noise"]


class CoocGAN(ImageInputMixin, TrainingMixin, GenerationMixin, BaseEstimator):
    """Co-occurrence conditional GAN of Darzi et al. (texture from local statistics and noise).

    Parameters are those of :data:`~tghop.cooc.config.SMALL` (the defaults) and
    :data:`~tghop.cooc.config.PAPER`; ``CoocGAN(**PAPER)`` is the paper's setting. Settings
    are stored as given; :meth:`fit` checks them (:func:`~tghop.cooc.config.check_settings`).
    ``get_params``, ``set_params``, the repr and ``sklearn.base.clone`` are those of every tghop
    estimator (:class:`tghop._estimator.BaseEstimator`).

    Parameters
    ----------
    n_clusters : int
        k colour clusters (the condition has k*k channels).
    crop_size : int
        Side n of the training crops; a multiple of ``2**n_layers``.
    n_layers : int
        Layers of the generator (each upsamples by 2) and of the critic (each halves);
        the co-occurrence downsampling is ``s = 2**n_layers``.
    patch, window, sigma
        Co-occurrence patch side, pair window side, spatial sigma (:func:`cooccurrence_tensor`).
    g_widths, d_widths : tuple of int
        Filters of the hidden generator and critic layers (``n_layers - 1`` each).
    noise_channels : int
        Channels of the N(0, 1) noise tensor, same spatial size as the condition.
    n_crops : int
        Training crops cut at random positions from the exemplar.
    batch_size, n_steps, n_critic : int
        Crops per batch, generator steps, critic steps per generator step.
    lr, beta1, beta2 : float
        Adam settings of both networks.
    lambda_gp, lambda_cooc : float
        Weights of the gradient penalty (Eq. 4) and the co-occurrence consistency loss (Eq. 3).
    tiles : int
        The generator trains on crops of ``tiles x tiles`` training crops (conditions of
        ``tiles * crop_size / s`` cells a side, ``batch_size / tiles**2`` of them per
        batch); the critic and the consistency loss see their ``crop_size`` tiles, each
        with its own tensor, so a step costs about the same as with ``tiles=1`` while the
        generator also learns the inside of a larger grid. 1: the paper's training.
    ema : float
        Decay of an exponential moving average of the generator's weights, updated after
        every generator step (Karras et al.'s ProGAN / StyleGAN, Yazici et al. 2019);
        generation uses the averaged generator (:meth:`raw` the last weights). The default
        0.995 is a half-life of 138 steps (1,100 crops at ``SMALL``'s batch 8); 0.999 (693 steps,
        StyleGAN's 10k images) and 0.9995 averaged in too many of the weights of 3,000
        steps that still improve and were worse than the raw generator (docs/choices.md).
        The average is bias-corrected (no share of the initial weights); its batch-norm
        statistics are recomputed for its weights at the end of :meth:`fit`. 0: no
        average (the paper's).
    kernel : int
        Side of the convolution kernels of both networks (odd; 5 as PSGAN).
    padding : str
        Padding of the generator's convolutions: ``"zeros"`` (the paper's), ``"reflect"``
        (needs conditions of at least 2 cells a side) or ``"replicate"``. The critic pads with zeros.
    gp_every : int
        Lazy gradient penalty (as StyleGAN2's lazy R1): the penalty only on every
        ``gp_every``-th critic step, weighted ``gp_every * lambda_gp``; the other critic
        steps skip its extra forward pass and double backward. 1: every step (WGAN-GP's).
    lr_decay : float
        Share of the ``n_steps`` at the end over which both learning rates fall linearly
        to 0 (0: constant, the paper's).
    context : bool
        Compute the *condition* of a training crop (what the generator and the critic see)
        with the exemplar's pixels around the crop (patches not clipped at the crop's
        border; the exemplar mirror-padded by ``s`` at its own border), and the
        exemplar's tensor (:meth:`sample`'s condition) likewise, so that the cells at a
        crop's border look like the inside cells of a large condition. The consistency
        loss still compares the crop-only tensors of the generated and the real crop
        (measured identically). False: one crop-only tensor for both (as before).
    device : str
        ``"auto"`` (CUDA when present), ``"cpu"`` or a torch device name.
    rng : int or numpy.random.Generator, optional
        Seeds k-means, the crops, the initial weights and the training noise.

    Attributes
    ----------
    centres_, spreads_ : ndarray, shape (k, C)
        Colour clusters.
    cond_mean_, cond_std_ : ndarray, shape (k*k,)
        Per-channel statistics of the training tensors; the networks see normalised ones.
    exemplar_cooc_ : ndarray, shape (k*k, H // s, W // s)
        The exemplar's own co-occurrence tensor (the default condition of :meth:`sample`).
    exemplar_shape_ : tuple
    step_ : int
        Generator steps trained.
    history_ : ndarray, shape (n, 5)
        Per logged step: step, critic loss, generator adversarial loss, consistency loss
        (the mean L1 per cell), gradient penalty.
    generator_, critic_ : torch.nn.Module
    generator_ema_ : torch.nn.Module
        The averaged generator (only with ``ema > 0``); :meth:`generate` and the controls use it.
    """

    def __init__(self, *, n_clusters=8, crop_size=64, n_layers=4, patch=33, window=25, sigma=math.sqrt(13.0),
                 g_widths=(64, 32, 16), d_widths=(16, 32, 64), noise_channels=16, n_crops=1000, batch_size=8,
                 n_steps=5500, n_critic=1, lr=2e-4, beta1=0.5, beta2=0.999, lambda_gp=1.0, lambda_cooc=10.0,
                 tiles=1, ema=0.995, kernel=5, padding="zeros", gp_every=4, lr_decay=0.0, context=False,
                 device="auto", rng=None):
        self.n_clusters = n_clusters
        self.crop_size = crop_size
        self.n_layers = n_layers
        self.patch = patch
        self.window = window
        self.sigma = sigma
        self.g_widths = g_widths
        self.d_widths = d_widths
        self.noise_channels = noise_channels
        self.n_crops = n_crops
        self.batch_size = batch_size
        self.n_steps = n_steps
        self.n_critic = n_critic
        self.lr = lr
        self.beta1 = beta1
        self.beta2 = beta2
        self.lambda_gp = lambda_gp
        self.lambda_cooc = lambda_cooc
        self.tiles = tiles
        self.ema = ema
        self.kernel = kernel
        self.padding = padding
        self.gp_every = gp_every
        self.lr_decay = lr_decay
        self.context = context
        self.device = device
        self.rng = rng

    # ------------------------------------------------------------------ parameters
    @property
    def s(self) -> int:
        """Co-occurrence downsampling factor ``2**n_layers``."""
        return 2 ** int(self.n_layers)

    def _settings(self) -> dict:
        """The parameters as plain JSON values, checked (:func:`~tghop.cooc.config.check_settings`)."""
        return check_settings(self.get_params())

    def _check_fitted(self):
        if not hasattr(self, "generator_"):
            raise NotFittedError("This CoocGAN is not trained yet; call fit(exemplar) or load a checkpoint first")

    def _torch_device(self, torch):
        return torch_device(torch, self.device)

    # ------------------------------------------------------------------ statistics
    def _cooc(self, images):
        """Co-occurrence tensor of a ``(N, C, H, W)`` tensor in [0, 1] with this model's clusters."""
        p = self.settings_
        return cooccurrence_tensor(images, self._centres_t.to(images.dtype), self._spreads_t.to(images.dtype),
                                   patch=p["patch"], window=p["window"], sigma=p["sigma"], s=self.s)

    def _cooc_context(self, images, cells_h: int, cells_w: int):
        """Tensor of the cells of ``images`` that lie inside a margin of ``s`` pixels (one
        cell) on every side: ``(N, k*k, cells_h, cells_w)``, patches reaching into the margin."""
        return self._cooc(images)[:, :, 1 : 1 + cells_h, 1 : 1 + cells_w]

    def _exemplar_tensor(self, torch, img: np.ndarray) -> np.ndarray:
        """The exemplar's own tensor (with ``context``: from the exemplar mirror-padded by ``s``)."""
        s = self.s
        hh, ww = img.shape[0] // s, img.shape[1] // s
        if self.settings_["context"]:
            img = np.pad(img, ((s, s), (s, s), (0, 0)), mode="symmetric")
        with torch.no_grad():
            whole = torch.as_tensor(img.transpose(2, 0, 1)[None], dtype=torch.float64, device=self._device)
            t = self._cooc(whole)
            return (t[:, :, 1 : 1 + hh, 1 : 1 + ww] if self.settings_["context"] else t)[0].cpu().numpy()

    #: Output pixels per side of the tiles :meth:`cooccurrence` measures a large image in
    #: (each with a margin of the patch and window around it), bounding its memory.
    TILE = 512

    def cooccurrence(self, image) -> np.ndarray:
        """Co-occurrence tensor of an image with this model's colour clusters.

        A large image is measured in tiles of :attr:`TILE` pixels a side, each with the
        pixels within a patch and a window around it (the same values as in one pass,
        up to round-off), so the memory stays bounded whatever the image's size.

        Parameters
        ----------
        image : array_like, shape (H, W) or (H, W, C)
            Float in [0, 1], at least ``s`` pixels on each side; C as the exemplar's.

        Returns
        -------
        ndarray, shape (k*k, H // s, W // s), float64
            Unnormalised (each cell sums to 1): the form :meth:`generate` takes.
        """
        self._check_fitted()
        torch = import_torch("the co-occurrence cGAN")
        img = self._check_colours(check_image(image, min_size=self.s, name="image"))
        s, p = self.s, self.settings_
        hh, ww = img.shape[0] // s, img.shape[1] // s
        margin = -(-(int(p["patch"]) // 2 + int(p["window"]) // 2) // s) * s  # whole cells
        step = max(1, self.TILE // s)  # cells per tile side
        out = np.empty((len(self.cond_mean_), hh, ww))
        with torch.no_grad():
            for cy in range(0, hh, step):
                for cx in range(0, ww, step):
                    y0, x0 = max(0, cy * s - margin), max(0, cx * s - margin)
                    y1 = min(img.shape[0], min(hh, cy + step) * s + margin)
                    x1 = min(img.shape[1], min(ww, cx + step) * s + margin)
                    part = img[y0:y1, x0:x1].transpose(2, 0, 1)[None]
                    x = torch.as_tensor(np.ascontiguousarray(part), dtype=torch.float64, device=self._device)
                    t = self._cooc(x)[0].cpu().numpy()
                    oy, ox = (cy * s - y0) // s, (cx * s - x0) // s
                    ny, nx = min(step, hh - cy), min(step, ww - cx)
                    out[:, cy : cy + ny, cx : cx + nx] = t[:, oy : oy + ny, ox : ox + nx]
        return out

    def image_condition(self, image, cells: Optional[int] = None) -> np.ndarray:
        """An image's co-occurrence statistics as a condition of a training crop's size.

        The image's own tensor (:meth:`cooccurrence`, at the model's scale: ``s`` pixels
        a cell) averaged over ``cells x cells`` equal regions (adaptive average pooling;
        an image smaller than that repeats its cells). Every cell still sums to 1. So
        an image of any size stands for its statistics as :meth:`crop_condition` stands
        for a crop: an image of exactly the crop's size gives its own tensor.

        Parameters
        ----------
        image : array_like, shape (H, W) or (H, W, C)
            At least ``s`` pixels on each side.
        cells : int, optional
            Side of the condition in cells (default ``crop_size // s``, a training crop's).

        Returns
        -------
        ndarray, shape (k*k, cells, cells), float64
        """
        torch = import_torch("the co-occurrence cGAN")
        t = self.cooccurrence(image)
        n = max(1, int(self.settings_["crop_size"]) // self.s) if cells is None else check_int(cells, "cells")
        pooled = torch.nn.functional.adaptive_avg_pool2d(torch.as_tensor(t)[None], (n, n))[0]
        return pooled.numpy()

    def _check_colours(self, img: np.ndarray) -> np.ndarray:
        c = self.exemplar_shape_[2]
        if img.shape[2] != c:
            if c == 3 and img.shape[2] == 1:
                return np.repeat(img, 3, axis=2)
            raise TGHopError(f"the model was trained on {c}-channel images, got a {img.shape[2]}-channel one; "
                             "convert it first")
        return img

    # ------------------------------------------------------------------ tensors on the device
    def _to_device(self, torch):
        """The torch device, the clusters and the condition statistics on it."""
        self._device = self._torch_device(torch)
        self._centres_t = torch.as_tensor(self.centres_, dtype=torch.float32, device=self._device)
        self._spreads_t = torch.as_tensor(self.spreads_, dtype=torch.float32, device=self._device)
        if hasattr(self, "cond_mean_"):
            self._mean_t = torch.as_tensor(self.cond_mean_, dtype=torch.float32, device=self._device)[:, None, None]
            self._std_t = torch.as_tensor(self.cond_std_, dtype=torch.float32, device=self._device)[:, None, None]

    def _normalise(self, cond):
        """A co-occurrence tensor as the networks see it (per-channel standardised)."""
        return (cond - self._mean_t) / self._std_t

    def _noise(self, torch, n, h, w, generator=None):
        """N(0, 1) noise ``(n, noise_channels, h, w)`` on the device (default: training's generator)."""
        return torch.randn((n, int(self.settings_["noise_channels"]), h, w), generator=generator or self._torch_gen,
                           device=self._device)

    @property
    def _output_generator(self):
        """The generator that generation uses: the averaged one when there is one."""
        return getattr(self, "generator_ema_", self.generator_)

    def raw(self) -> "CoocGAN":
        """This model generating with the raw (last, not averaged) generator.

        A shallow copy sharing the networks and statistics; without an average (``ema=0``)
        the same as this model. For comparing the two (benchmarks/bench_cooc.py).

        Returns
        -------
        CoocGAN
            The copy, without ``generator_ema_``: it generates with ``generator_``. This model is
            left as it is.
        """
        import copy

        self._check_fitted()
        other = copy.copy(self)
        if hasattr(other, "generator_ema_"):
            del other.generator_ema_
        return other

    # ------------------------------------------------------------------ files
    def save(self, path) -> None:
        """Write a ``.pt`` checkpoint: tensors only (networks, optimisers, statistics, random
        states) and the settings as JSON bytes inside; loads with ``weights_only=True``
        (:func:`load`; the format: :mod:`tghop.cooc.checkpoints`).

        Parameters
        ----------
        path : str or os.PathLike
            The ``.pt`` file to write.

        Returns
        -------
        None
        """
        save_checkpoint(self, path)


def load(path, *, device: str = "auto") -> CoocGAN:
    """Read a checkpoint written by :meth:`CoocGAN.save`.

    Parameters
    ----------
    path : str or os.PathLike
    device : str
        Where to put the networks (``"auto"``: CUDA when present).

    Returns
    -------
    CoocGAN
        Trained, in evaluation mode; ``fit(exemplar, resume=True)`` continues it.

    Raises
    ------
    ModelFileError
        Missing file, not a tghop co-occurrence checkpoint, or another format version.
    TGHopError
        An unknown ``device``, or CUDA where there is none.
    """
    return read_checkpoint(path, CoocGAN, device=device)


def memory_estimate(exemplar_shape, *, model: Optional["CoocGAN"] = None, assembly: str = "quilt"):
    """``estimate(h, w)``: about how many bytes :func:`baseline` needs for an ``h x w`` result.

    Training the small configuration (``model=None``): 900 MB (860 MB peak resident
    measured on 256 x 256 exemplars, torch included) plus 2 KB per exemplar pixel (its
    co-occurrence tensor). Generation: ``"quilt"`` keeps the pool of generated crops
    (float32) and about 45 bytes per output pixel and channel for the quilting;
    ``"pass"`` and ``"windows"`` about 60 (the generator's output, the canvas and the
    float64 result).

    Parameters
    ----------
    exemplar_shape : tuple of int
        ``(H, W)`` or ``(H, W, C)`` of the exemplar.
    model : CoocGAN, optional
        A trained model, whose window size sets the pool's crops; None: the small configuration,
        trained first (its training counted).
    assembly : {"quilt", "pass", "windows"}, default="quilt"
        How the result is assembled (:func:`baseline`'s ``assembly``).

    Returns
    -------
    callable
        ``estimate(h, w) -> float``: bytes for an ``h x w`` result.
    """
    eh, ew = int(exemplar_shape[0]), int(exemplar_shape[1])
    c = int(exemplar_shape[2]) if len(exemplar_shape) > 2 else 1
    train = 0.0 if model is not None else 900e6 + 2048.0 * eh * ew
    side = 64 if model is None else model._window_cells * model.s
    pool = 4.0 * QUILT_POOL * side * side * c if assembly == "quilt" else 0.0
    per_pixel = 45.0 * c if assembly == "quilt" else 60.0 * c
    return lambda h, w: train + pool + per_pixel * h * w + 50e6


def baseline(exemplar, size=None, *, rng=None, progress: Optional[ProgressCallback] = None,
             model: Optional[CoocGAN] = None, n_steps: Optional[int] = None, assembly: str = "quilt") -> np.ndarray:
    """The co-occurrence cGAN as a baseline: train the small configuration, then :meth:`CoocGAN.sample`.

    Parameters
    ----------
    exemplar : array_like, shape (H, W) or (H, W, C)
    size : int or (int, int), optional
        Output size (any, up to :data:`tghop._images.MAX_PIXELS`); default the exemplar's.
    rng : int or numpy.random.Generator, optional
        Seeds training (when ``model`` is None) and generation.
    progress : callable, optional
    model : CoocGAN, optional
        A trained model to use instead of training one; ``exemplar`` must be the image it
        was trained on (else :class:`TGHopError`).
    n_steps : int, optional
        Generator steps of the training (default :data:`~tghop.cooc.config.SMALL`'s); only
        without ``model`` (with it, :class:`TGHopError`).
    assembly : {"quilt", "pass", "windows"}
        How the image is made from the generator (see :meth:`CoocGAN.sample`; ``"pass"``
        is the paper's way).

    Returns
    -------
    ndarray, shape (h, w, C), float64 in [0, 1]
    """
    check_assembly(assembly)  # before any training
    img = check_image(exemplar, name="exemplar")
    if model is not None:
        if not isinstance(model, CoocGAN):
            raise TGHopError("model must be a trained CoocGAN (tghop.cooc.load(path) reads a checkpoint), "
                             f"got {type(model).__name__}")
        if n_steps is not None:
            raise TGHopError("n_steps (--iterations) trains the baseline's own model: drop it, or drop model (--model)")
        model._check_exemplar(img, "the cooc baseline", "give the same image, or as model (--model) a checkpoint "
                              "trained on this exemplar")
    h, w = check_size(size, default=img.shape[:2])  # likewise
    if model is None:
        check_texture(img)  # fit's own check, made before the memory's
    check_memory(memory_estimate(img.shape, model=model, assembly=assembly), (h, w),
                 what="the cooc baseline")  # likewise
    r = check_rng(rng)
    if model is None:
        model = CoocGAN(rng=r)
        if n_steps is not None:
            model.set_params(n_steps=n_steps)
        model.fit(img, progress=progress)
    return model.sample((h, w), rng=r, progress=progress, assembly=assembly)
