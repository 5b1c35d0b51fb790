"""Co-occurrence based texture synthesis (Darzi et al.): a conditional GAN and its controls.

After A. Darzi, I. Lang, A. Taklikar, H. Averbuch-Elor, S. Avidan, "Co-occurrence based
texture synthesis" (``../shared/papers/003_db2109f0a38f9c15.txt``). A texture is
described locally by soft colour co-occurrence matrices; a generator turns a grid of
them (a *co-occurrence tensor*) plus noise into texture, so the user controls the local
statistics: morph between two textures by interpolating their tensors, walk through
variations by interpolating the noise, paint statistics where they are wanted.

Co-occurrence (NumPy or PyTorch; in :mod:`tghop.cooccurrence`, re-exported here; this is
also what :func:`tghop.metrics.cooccurrence_distance` measures, with the same functions):

* :func:`fit_colour_clusters` -- k-means colour centres ``tau_l`` and per-cluster,
  per-channel spreads ``sigma_l`` (Eq. 2);
* :func:`soft_assign` -- ``K(I_p, tau_l)`` for every pixel and cluster (Eq. 2);
* :func:`cooccurrence_matrix` -- one ``k x k`` matrix of a whole image (Eq. 1);
* :func:`cooccurrence_tensor` -- a matrix per pixel over a patch around it, row-stacked
  to ``k*k`` channels and average-pooled by ``s`` (Sec. 3): ``(k*k, H/s, W/s)``.

All are vectorised (separable convolutions and integral images) and, on tensors,
differentiable -- the generator is trained through them.

The cGAN (needs PyTorch: ``pip install 'tghop[metrics]'``):

* :class:`CoocGAN` -- ``fit(exemplar)`` trains it (WGAN-GP plus the paper's co-occurrence
  consistency loss); ``sample``, ``generate``, ``morph_strip``, ``morph_grid`` and
  :func:`paint_condition` are the controls; ``save`` / :func:`load` write and read a
  ``.pt`` checkpoint of tensors only (JSON settings inside), and ``fit(..., resume=True)``
  continues a loaded one.
* ``sample`` quilts generated training-size crops by default (``assembly="quilt"``,
  :meth:`CoocGAN.crop_pool` and :func:`tghop.quilting.quilt`; ours: the generator never
  runs at a size it was not trained at); ``assembly="pass"`` is the paper's one pass.
* ``generate(..., windows=True)`` (:meth:`CoocGAN.generate_windows`) generates a large
  condition in overlapping training-size windows, and ``tiles=2`` trains the generator on
  2 x 2 training crops at once; both are options (docs/choices.md: neither was clearly
  better on the small configuration).
* ``ema`` keeps an exponential moving average of the generator's weights while training
  and generates with it (:data:`SMALL`: on; :data:`PAPER`: off, as the paper).
* :data:`SMALL` (the default: about 14 minutes on a 2-core CPU) and :data:`PAPER` (the
  paper's setting: about 10 minutes on an H100 GPU) are the two configurations;
  ``CoocGAN(**PAPER)`` selects the latter.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import numbers
import time
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from ._common import (
    MissingExtraError,
    ModelFileError,
    NotFittedError,
    ProgressCallback,
    TGHopError,
    check_image,
    check_rng,
    report,
)
from .cooccurrence import cooccurrence_matrix, cooccurrence_tensor, fit_colour_clusters, soft_assign  # noqa: F401

__all__ = [
    "SMALL",
    "PAPER",
    "CoocGAN",
    "fit_colour_clusters",
    "soft_assign",
    "cooccurrence_matrix",
    "cooccurrence_tensor",
    "paint_condition",
    "load",
]

#: ``kind`` field of a checkpoint's settings; a ``.pt`` without it is not ours.
KIND = "tghop.cooc"
#: Checkpoint format version.
FORMAT = 1

_INSTALL_HINT = "pip install 'tghop[metrics]'"


def _import_torch(what: str = "The co-occurrence cGAN"):
    try:
        import torch
    except ImportError:
        raise MissingExtraError(f"{what} needs PyTorch; install it with: {_INSTALL_HINT}") from None
    return torch


def paint_condition(tensors, labels):
    """Compose a co-occurrence tensor from several, cell by cell: ``out[:, y, x] = tensors[labels[y, x]][:, y, x]``.

    Each source is tiled (repeated periodically) to the label map's size first, so a
    source may be one crop's tensor. This is the paper's Sec. 5.2 / Fig. 14 control:
    spatially varying statistics for one generated image.

    Parameters
    ----------
    tensors : sequence of ndarray, each shape (k*k, h_i, w_i)
    labels : array_like of int, shape (h, w)
        Index of the source of each cell.

    Returns
    -------
    ndarray, shape (k*k, h, w), float64
    """
    labels = np.asarray(labels)
    if labels.ndim != 2 or labels.dtype.kind not in "iu":
        raise TGHopError(f"labels must be a 2-D integer array, got shape {labels.shape} and dtype {labels.dtype}")
    srcs = [np.asarray(t, dtype=np.float64) for t in tensors]
    if not srcs or any(t.ndim != 3 for t in srcs) or len({t.shape[0] for t in srcs}) > 1:
        raise TGHopError("tensors must be one or more (k*k, h, w) co-occurrence tensors with the same k")
    if labels.min() < 0 or labels.max() >= len(srcs):
        raise TGHopError(f"labels must lie in 0..{len(srcs) - 1}, got {labels.min()}..{labels.max()}")
    h, w = labels.shape
    tiled = np.stack([_tile(t, h, w) for t in srcs])  # (n, k*k, h, w)
    return np.take_along_axis(tiled, labels[None, None], axis=0)[0]


def _tile(t: np.ndarray, h: int, w: int, offset=(0, 0)) -> np.ndarray:
    """Periodic tiling of a ``(c, th, tw)`` tensor to ``(c, h, w)`` from ``offset``."""
    rows = (np.arange(h) + offset[0]) % t.shape[1]
    cols = (np.arange(w) + offset[1]) % t.shape[2]
    return t[:, rows][:, :, cols]


def _reflect_tile(t: np.ndarray, h: int, w: int, offset=(0, 0)) -> np.ndarray:
    """Mirror tiling (..., a b c c b a a b ...) of ``(c, th, tw)`` to ``(c, h, w)``: no jumps at the joins."""

    def index(n, size, start):
        period = 2 * size
        i = (np.arange(n) + start) % period
        return np.where(i < size, i, period - 1 - i)

    return t[:, index(h, t.shape[1], offset[0])][:, :, index(w, t.shape[2], offset[1])]


#: Default blend width of :meth:`CoocGAN.generate_windows`, as a fraction of the windows'
#: stride (1: the whole overlap, a sin^2 window; 0: hard seams).
FEATHER = 0.5

#: How :meth:`CoocGAN.sample` makes an image from the generator.
ASSEMBLIES = ("quilt", "pass", "windows")

#: Generated crops quilted by :meth:`CoocGAN.sample` (``assembly="quilt"``) for crops of
#: up to 64 px (:data:`SMALL`); larger crops get proportionally fewer, the same 4 Mpx of
#: generator work, and at least 100 (:data:`PAPER`'s 128 px crops: 250).
QUILT_POOL = 1000

#: Quilting's tolerance and detail preference for that assembly (see
#: :func:`tghop.quilting.quilt`; the values TGHop generates with).
QUILT_TOLERANCE = 0.1
QUILT_DETAIL = 0.5


def _check_assembly(assembly) -> None:
    if assembly not in ASSEMBLIES:
        raise TGHopError(f"assembly must be one of {', '.join(ASSEMBLIES)}, got {assembly!r}")


def _window_layout(length: int, n: int, stride: int):
    """Windows along one axis of ``length`` cells: ``(starts, (pad_before, pad_after), window)``.

    Windows are ``n`` cells long and ``stride`` apart; window ``t`` contributes the cells
    ``[t*stride, (t+1)*stride)`` of the image (its centre), so the axis is padded by the
    margin ``(n - stride) // 2`` before and up to the last window's end after. An axis of
    at most ``n`` cells is one window of its own length, unpadded.
    """
    if length <= n:
        return [0], (0, 0), length
    margin = (n - stride) // 2
    count = -(-length // stride)
    after = (count - 1) * stride + n - margin - length
    return [t * stride for t in range(count)], (margin, after), n


def _blend_weights(size: int, lo: int, hi: int, feather: int, blend: bool) -> np.ndarray:
    """Per-pixel weight of a window along one axis: 1 on ``[lo, hi)``, raised-cosine ramps
    ``feather`` pixels wide centred on ``lo`` and ``hi``; a neighbour's ramp is the
    complement, so overlapping windows' weights sum to one. All ones if ``not blend``."""
    if not blend:
        return np.ones(size)
    x = np.arange(size) + 0.5

    def ramp(t):
        if feather <= 0:
            return (t >= 0).astype(np.float64)
        return 0.5 - 0.5 * np.cos(np.pi * np.clip(t / feather + 0.5, 0.0, 1.0))

    return ramp(x - lo) * ramp(hi - x)


def _mirror_pad(t: np.ndarray, pads_y, pads_x) -> np.ndarray:
    """Mirror padding (edge cell repeated) of a ``(c, h, w)`` array: :func:`_reflect_tile`
    started ``pads_y[0]`` rows and ``pads_x[0]`` columns before the array."""
    if not any(pads_y) and not any(pads_x):
        return t
    _, h, w = t.shape
    return _reflect_tile(t, h + sum(pads_y), w + sum(pads_x), offset=(-pads_y[0], -pads_x[0]))


# =======================================================================================
# The cGAN
# =======================================================================================

#: The small configuration, the default of :class:`CoocGAN`: trains on a 2-core CPU in
#: about 15 minutes for a 256 x 256 exemplar. Everything spatial is at half the paper's
#: scale (64 px crops, 33 px patches, 25 px windows, sigma^2 = 13), the networks have 4
#: layers instead of 5 (so s = 16 keeps a 4 x 4 condition) and 8 to 16 times fewer
#: filters, one critic step per generator step (as the authors' released code, ``dIter=1``).
#: Not in the paper (issue 9, docs/choices.md): 5,500 generator steps of 8 crops with a
#: lazy gradient penalty (``gp_every=4``; about 0.15 s per step with 2 threads), which
#: in a GPU sweep at equal CPU time beat 3,000 steps of 16 crops on brick_wall, grass_lawn
#: and red_peppers (3 seeds each); and it generates with an exponential moving average of
#: the generator's weights, ``ema=0.995`` (a half-life of 138 steps; better than the raw
#: generator on the brick_wall seeds measured, longer averages worse).
SMALL = dict(
    n_clusters=8, crop_size=64, n_layers=4, patch=33, window=25, sigma=math.sqrt(13.0),
    g_widths=(64, 32, 16), d_widths=(16, 32, 64), noise_channels=16,
    n_crops=1000, batch_size=8, n_steps=5500, n_critic=1,
    lr=2e-4, beta1=0.5, beta2=0.999, lambda_gp=1.0, lambda_cooc=10.0, tiles=1, ema=0.995,
    kernel=5, padding="zeros", gp_every=4, lr_decay=0.0, context=False,
)

#: The paper's configuration (Sec. 4.1): k = 8, 2,000 crops of 128 x 128, s = 32 (5 layers,
#: a 4 x 4 condition), 65 px patches, 51 px windows, sigma^2 = 51, 120 epochs, Adam
#: (lr 2e-4, beta1 0.5), gradient penalty weight 1. From PSGAN (Bergmann et al. 2017,
#: the paper's base): 5 x 5 filters, widths 512-256-128-64 (generator) and 64-128-256-512
#: (critic), batch 64, Adam beta2 = 0.999, N(0, 0.02) initialisation, tanh output, leaky
#: ReLU 0.2 in the critic; 30 noise channels (PSGAN's released model uses 30 local noise
#: dimensions). From WGAN-GP (Gulrajani et al.): 5 critic steps per generator step, no
#: batch norm in the critic. Not in any of them: the consistency weight 10.
#: One epoch is n_crops / batch_size generator steps: 120 epochs = 3,750 steps (6.2 steps
#: per second on an H100: about 10 minutes). The authors' released code
#: (github.com/Ashu7397/cooc_texture) differs from these borrowed values: batch 16, one
#: critic step, widths 960-480-240-120 / 120-240-480-960, 64 noise channels, so 120 epochs
#: are 15,000 steps there; see docs/choices.md.
PAPER = dict(
    n_clusters=8, crop_size=128, n_layers=5, patch=65, window=51, sigma=math.sqrt(51.0),
    g_widths=(512, 256, 128, 64), d_widths=(64, 128, 256, 512), noise_channels=30,
    n_crops=2000, batch_size=64, n_steps=3750, n_critic=5,
    lr=2e-4, beta1=0.5, beta2=0.999, lambda_gp=1.0, lambda_cooc=10.0, tiles=1, ema=0.0,
    kernel=5, padding="zeros", gp_every=1, lr_decay=0.0, context=False,
)

_PARAMS = tuple(SMALL) + ("device", "rng")


def average_step(torch, average, module, decay: float, step: int) -> None:
    """One bias-corrected update of a weight average after training step ``step`` (from 1).

    ``average <- beta average + (1 - beta) module`` for every parameter, with
    ``beta = decay (1 - decay**(step-1)) / (1 - decay**step)``: the average is then exactly
    the normalised mean of the weights after steps 1..step with weights
    ``decay**(step-i)``. Buffers (batch-norm statistics) are copied from ``module``.
    """
    beta = decay * (1.0 - decay ** (step - 1)) / (1.0 - decay**step)
    with torch.no_grad():
        for avg, cur in zip(average.parameters(), module.parameters()):
            avg.mul_(beta).add_(cur, alpha=1.0 - beta)
        for avg, cur in zip(average.buffers(), module.buffers()):
            avg.copy_(cur)


def _networks(torch, n_colours: int, n_cond: int, p: dict):
    """Generator and critic modules for settings ``p``."""
    nn = torch.nn
    n_layers = int(p["n_layers"])
    kernel = int(p.get("kernel", 5))

    class Generator(nn.Module):
        """``n_layers`` x (nearest upsampling x2, ``kernel`` x ``kernel`` conv with ``padding``,
        batch norm, ReLU); the last conv -> tanh."""

        def __init__(self):
            super().__init__()
            widths = list(p["g_widths"]) + [n_colours]
            layers, cin = [], n_cond + int(p["noise_channels"])
            for i, cout in enumerate(widths):
                layers += [nn.Upsample(scale_factor=2, mode="nearest"),
                           nn.Conv2d(cin, cout, kernel, padding=kernel // 2, padding_mode=p["padding"])]
                layers += [nn.BatchNorm2d(cout), nn.ReLU()] if i < len(widths) - 1 else [nn.Tanh()]
                cin = cout
            self.net = nn.Sequential(*layers)

        def forward(self, cond, noise):
            return self.net(torch.cat([cond, noise], dim=1))

    class Critic(nn.Module):
        """``n_layers`` ``kernel`` x ``kernel`` stride-2 convs (zero padding, leaky ReLU); the
        condition joins after the third."""

        def __init__(self):
            super().__init__()
            self.join = min(3, n_layers - 1)
            widths = list(p["d_widths"]) + [1]
            self.convs = nn.ModuleList()
            cin = n_colours
            for i, cout in enumerate(widths):
                if i == self.join:
                    cin += n_cond
                self.convs.append(nn.Conv2d(cin, cout, kernel, stride=2, padding=kernel // 2))
                cin = cout
            self.act = nn.LeakyReLU(0.2)

        def forward(self, x, cond):
            for i, conv in enumerate(self.convs):
                if i == self.join:
                    c = nn.functional.interpolate(cond, size=x.shape[-2:], mode="nearest")
                    x = torch.cat([x, c], dim=1)
                x = conv(x)
                if i < len(self.convs) - 1:
                    x = self.act(x)
            return x.mean((1, 2, 3))  # one critic value per crop (the map of a fully convolutional critic)

    if len(p["g_widths"]) != n_layers - 1 or len(p["d_widths"]) != n_layers - 1:
        raise TGHopError(f"g_widths and d_widths need n_layers - 1 = {n_layers - 1} entries each")
    gen, critic = Generator(), Critic()
    for module in list(gen.modules()) + list(critic.modules()):  # DCGAN / PSGAN initialisation
        if isinstance(module, nn.Conv2d):
            nn.init.normal_(module.weight, 0.0, 0.02)
            nn.init.zeros_(module.bias)
        elif isinstance(module, nn.BatchNorm2d):
            nn.init.normal_(module.weight, 1.0, 0.02)
            nn.init.zeros_(module.bias)
    return gen, critic


def _split_tiles(x, t: int):
    """``(m, c, t*a, t*b)`` -> ``(m*t*t, c, a, b)``: each item's t x t tiles, row by row."""
    if t == 1:
        return x
    m, c, h, w = x.shape
    x = x.reshape(m, c, t, h // t, t, w // t).permute(0, 2, 4, 1, 3, 5)
    return x.reshape(m * t * t, c, h // t, w // t)


def _join_tiles(x, t: int):
    """The inverse of :func:`_split_tiles`: ``(m*t*t, c, a, b)`` -> ``(m, c, t*a, t*b)``."""
    if t == 1:
        return x
    n, c, a, b = x.shape
    x = x.reshape(n // (t * t), t, t, c, a, b).permute(0, 3, 1, 4, 2, 5)
    return x.reshape(n // (t * t), c, t * a, t * b)


def _exemplar_hash(img: np.ndarray) -> str:
    return hashlib.sha1(np.round(img * 255).astype(np.uint8).tobytes()).hexdigest()[:16]


class CoocGAN:
    """Co-occurrence conditional GAN of Darzi et al. (texture from local statistics and noise).

    Parameters are those of :data:`SMALL` (the defaults) and :data:`PAPER`; ``CoocGAN(**PAPER)``
    is the paper's setting. Settings are stored as given; :meth:`fit` checks them.

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
        0.995 is a half-life of 138 steps (1,100 crops at :data:`SMALL`'s batch 8); 0.999 (693 steps,
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
    def get_params(self) -> dict:
        return {name: getattr(self, name) for name in _PARAMS}

    def set_params(self, **params) -> "CoocGAN":
        for name, value in params.items():
            if name not in _PARAMS:
                raise TGHopError(f"unknown CoocGAN parameter {name!r}")
            setattr(self, name, value)
        return self

    @property
    def s(self) -> int:
        """Co-occurrence downsampling factor ``2**n_layers``."""
        return 2 ** int(self.n_layers)

    def _settings(self) -> dict:
        """The parameters as plain JSON values, checked."""
        p = {name: getattr(self, name) for name in SMALL}
        ints = ("n_clusters", "crop_size", "n_layers", "patch", "window", "noise_channels", "n_crops",
                "batch_size", "n_steps", "n_critic", "tiles", "kernel", "gp_every")
        try:
            for name in ints:
                p[name] = int(p[name])
            for name in ("sigma", "lr", "beta1", "beta2", "lambda_gp", "lambda_cooc", "ema", "lr_decay"):
                p[name] = float(p[name])
            p["g_widths"] = [int(v) for v in p["g_widths"]]
            p["d_widths"] = [int(v) for v in p["d_widths"]]
        except (TypeError, ValueError):
            raise TGHopError(f"CoocGAN settings must be numbers (widths: sequences of int), got {p}") from None
        if any(p[name] < 1 for name in ints if name != "n_steps") or p["n_steps"] < 0:
            raise TGHopError("CoocGAN integer settings must be positive (n_steps may be 0)")
        if p["n_layers"] < 2:
            raise TGHopError(f"n_layers must be at least 2, got {p['n_layers']}")
        if p["crop_size"] % (2 ** p["n_layers"]):
            raise TGHopError(f"crop_size ({p['crop_size']}) must be a multiple of 2**n_layers = {2 ** p['n_layers']}")
        if not (p["sigma"] > 0 and p["lr"] > 0 and 0 <= p["beta1"] < 1 and 0 <= p["beta2"] < 1
                and p["lambda_gp"] >= 0 and p["lambda_cooc"] >= 0 and 0 <= p["ema"] < 1):
            raise TGHopError("sigma and lr must be positive, betas and ema in [0, 1), the loss weights >= 0")
        if p["kernel"] % 2 == 0:
            raise TGHopError(f"kernel must be odd, got {p['kernel']}")
        if p["padding"] not in ("zeros", "reflect", "replicate"):
            raise TGHopError(f"padding must be 'zeros', 'reflect' or 'replicate', got {p['padding']!r}")
        p["context"] = bool(p["context"])
        if not 0 <= p["lr_decay"] <= 1:
            raise TGHopError(f"lr_decay must be in [0, 1], got {p['lr_decay']}")
        return p

    def _check_fitted(self):
        if not hasattr(self, "generator_"):
            raise NotFittedError("This CoocGAN is not trained yet; call fit(exemplar) or load a checkpoint first")

    def _torch_device(self, torch):
        if self.device in (None, "auto"):
            return torch.device("cuda" if torch.cuda.is_available() else "cpu")
        try:
            return torch.device(self.device)
        except (RuntimeError, TypeError):
            raise TGHopError(f"device must be 'auto', 'cpu', 'cuda' or a torch device name, got {self.device!r}") from None

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

    def cooccurrence(self, image) -> np.ndarray:
        """Co-occurrence tensor of an image with this model's colour clusters.

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
        torch = _import_torch()
        img = self._check_colours(check_image(image, min_size=self.s, name="image"))
        x = torch.as_tensor(img.transpose(2, 0, 1)[None], dtype=torch.float64, device=self._device)
        with torch.no_grad():
            return self._cooc(x)[0].cpu().numpy()

    def _check_colours(self, img: np.ndarray) -> np.ndarray:
        c = self.exemplar_shape_[2]
        if img.shape[2] != c:
            if c == 3 and img.shape[2] == 1:
                return np.repeat(img, 3, axis=2)
            raise TGHopError(f"the model was trained on {c}-channel images, got a {img.shape[2]}-channel one; "
                             "convert it first")
        return img

    # ------------------------------------------------------------------ training
    def _build(self, torch, img: np.ndarray, rng: np.random.Generator, progress):
        """Clusters, training crops and their tensors, networks and optimisers (a fresh fit)."""
        p = self.settings_
        seed = int(rng.integers(2**31))
        self.centres_, self.spreads_ = fit_colour_clusters(img, n_clusters=p["n_clusters"], seed=seed)
        self._to_device(torch)
        self._cut_crops(torch, img, rng, progress)
        flat = self._conds.double().transpose(0, 1).reshape(self._conds.shape[1], -1)
        self.cond_mean_ = flat.mean(1).cpu().numpy()
        self.cond_std_ = np.maximum(flat.std(1).cpu().numpy(), 1e-4)
        self._to_device(torch)
        self.exemplar_cooc_ = self._exemplar_tensor(torch, img)
        torch.manual_seed(seed)
        self.generator_, self.critic_ = _networks(torch, img.shape[2], self._conds.shape[1], p)
        self.generator_.to(self._device)
        self.critic_.to(self._device)
        self._make_averaged(torch)
        self._make_optimisers(torch)
        self.step_ = 0
        self.history_ = np.zeros((0, 5))
        self._torch_gen = torch.Generator(device=self._device).manual_seed(seed + 1)

    def _make_averaged(self, torch):
        """The averaged generator (``ema > 0``): a copy of the generator, outside autograd."""
        import copy

        if self.settings_["ema"] > 0:
            self.generator_ema_ = copy.deepcopy(self.generator_).requires_grad_(False).eval()
        elif hasattr(self, "generator_ema_"):
            del self.generator_ema_

    def _update_average(self, torch):
        """After generator step ``t = step_``: ``avg <- beta_t avg + (1 - beta_t) theta_t``.

        ``beta_t = ema (1 - ema**(t-1)) / (1 - ema**t)`` makes the average exactly the
        normalised exponentially weighted mean of the weights after steps 1..t (weights
        ``ema**(t-i)``; Adam's bias correction): no share of the random initialisation is
        left in it, and ``t = 1`` gives the weights themselves. Batch-norm buffers (running
        statistics) are copied from the generator while training; :meth:`fit` recomputes
        them for the averaged weights at its end (:meth:`_recompute_average_statistics`).
        """
        if hasattr(self, "generator_ema_"):
            average_step(torch, self.generator_ema_, self.generator_, self.settings_["ema"], self.step_)

    def _recompute_average_statistics(self, torch, conds=None):
        """Batch-norm running statistics of the averaged generator, recomputed for its own weights.

        The raw generator's statistics (which :meth:`_update_average` copies) belong to
        other weights: on brick_wall the averaged generator with them gave SIFID 10-22
        against 4-5 for the raw one (docs/choices.md). So, as for stochastic weight
        averaging (Izmailov et al. 2018, ``update_bn``), one train-mode pass over the
        training conditions (``conds``, default the training crops' tensors, in
        generator batches, tiles joined as in training) with fresh noise sets them to the
        plain average of the batch statistics. The noise comes from its own seeded
        generator, so training's random numbers are untouched and the result is repeatable.
        """
        gen = self.generator_ema_
        conds = self._conds if conds is None else conds
        t = int(self.settings_["tiles"])
        per = max(1, int(self.settings_["batch_size"]) // (t * t)) * t * t
        noise_gen = torch.Generator(device=self._device).manual_seed(int(self._seed_) + 2)
        norms = [m for m in gen.modules() if isinstance(m, torch.nn.BatchNorm2d)]
        momenta = [m.momentum for m in norms]
        for m in norms:
            m.reset_running_stats()
            m.momentum = None  # cumulative: the mean over the batches
        gen.train()
        with torch.no_grad():
            for i in range(0, len(conds) - t * t + 1, per):
                cn = self._normalise(_join_tiles(conds[i : i + per], t))
                gen(cn, self._noise(torch, len(cn), cn.shape[2], cn.shape[3], generator=noise_gen))
        for m, momentum in zip(norms, momenta):
            m.momentum = momentum
        gen.eval()

    def _checkpoint_modules(self):
        """``(prefix, module)`` of the networks a checkpoint stores (the average with ``ema > 0``)."""
        modules = [("generator", self.generator_), ("critic", self.critic_)]
        if hasattr(self, "generator_ema_"):
            modules.append(("generator_ema", self.generator_ema_))
        return modules

    @property
    def _output_generator(self):
        """The generator that generation uses: the averaged one when there is one."""
        return getattr(self, "generator_ema_", self.generator_)

    def raw(self) -> "CoocGAN":
        """This model generating with the raw (last, not averaged) generator.

        A shallow copy sharing the networks and statistics; without an average (``ema=0``)
        the same as this model. For comparing the two (benchmarks/bench_cooc.py).
        """
        import copy

        self._check_fitted()
        other = copy.copy(self)
        if hasattr(other, "generator_ema_"):
            del other.generator_ema_
        return other

    def _set_learning_rate(self, total: int) -> None:
        """``lr`` until the last ``lr_decay`` share of ``total`` steps, then linearly down to
        0 at step ``total`` (both networks); a function of the step, so resume continues it."""
        p = self.settings_
        span = p["lr_decay"] * total
        lr = p["lr"] if span <= 0 else p["lr"] * min(1.0, max(0.0, (total - self.step_) / span))
        for opt in (self._opt_g, self._opt_d):
            for group in opt.param_groups:
                group["lr"] = lr

    def _make_optimisers(self, torch):
        p = self.settings_
        betas = (p["beta1"], p["beta2"])
        self._opt_g = torch.optim.Adam(self.generator_.parameters(), lr=p["lr"], betas=betas)
        self._opt_d = torch.optim.Adam(self.critic_.parameters(), lr=p["lr"], betas=betas)

    def _to_device(self, torch):
        self._device = self._torch_device(torch)
        self._centres_t = torch.as_tensor(self.centres_, dtype=torch.float32, device=self._device)
        self._spreads_t = torch.as_tensor(self.spreads_, dtype=torch.float32, device=self._device)
        if hasattr(self, "cond_mean_"):
            self._mean_t = torch.as_tensor(self.cond_mean_, dtype=torch.float32, device=self._device)[:, None, None]
            self._std_t = torch.as_tensor(self.cond_std_, dtype=torch.float32, device=self._device)[:, None, None]

    def _normalise(self, cond):
        return (cond - self._mean_t) / self._std_t

    def _noise(self, torch, n, h, w, generator=None):
        return torch.randn((n, int(self.settings_["noise_channels"]), h, w), generator=generator or self._torch_gen,
                           device=self._device)

    def _batch(self, torch, targets: bool = False):
        """Real tiles in [-1, 1] and the generator's conditions: ``max(1, batch_size // tiles**2)``
        crops, i.e. their ``tiles**2`` tiles each and their tiles' tensors joined into one grid;
        ``targets=True`` adds the consistency targets (joined likewise)."""
        t = self.settings_["tiles"]
        m = max(1, self.settings_["batch_size"] // (t * t))
        idx = torch.randint(len(self._crops) // (t * t), (m,), generator=self._torch_gen, device=self._device)
        if t > 1:
            idx = (idx[:, None] * (t * t) + torch.arange(t * t, device=self._device)).reshape(-1)
        if targets:
            return self._crops[idx] * 2.0 - 1.0, _join_tiles(self._conds[idx], t), _join_tiles(self._targets[idx], t)
        return self._crops[idx] * 2.0 - 1.0, _join_tiles(self._conds[idx], t)

    def _critic_step(self, torch, real, cond, with_gp: bool = True):
        """One critic update; ``with_gp=False`` leaves the gradient penalty out (lazy
        regularisation, ``gp_every > 1``: the penalty, weighted ``gp_every`` times, only on
        every ``gp_every``-th critic step) and returns NaN for it."""
        p = self.settings_
        t = p["tiles"]
        cn = self._normalise(cond)
        with torch.no_grad():
            fake = _split_tiles(self.generator_(cn, self._noise(torch, len(cn), cn.shape[2], cn.shape[3])), t)
        cn = _split_tiles(cn, t)
        d_real, d_fake = self.critic_(real, cn), self.critic_(fake, cn)
        # Eq. 4 as written is E[D(x_r)] - E[D(x_g)]: a critic that scores real crops high
        # must *maximise* it, so its loss is the negative (Gulrajani et al.'s sign).
        loss = d_fake.mean() - d_real.mean()
        gp = None
        if with_gp:
            u = torch.rand((len(real), 1, 1, 1), generator=self._torch_gen, device=self._device)
            mix = (u * real + (1 - u) * fake).requires_grad_(True)
            (grad,) = torch.autograd.grad(self.critic_(mix, cn).sum(), mix, create_graph=True)
            gp = ((grad.flatten(1).norm(dim=1) - 1.0) ** 2).mean()
            loss = loss + p["lambda_gp"] * p["gp_every"] * gp
        self._opt_d.zero_grad(set_to_none=True)
        loss.backward()
        self._opt_d.step()
        return float(loss.detach()), (float(gp.detach()) if gp is not None else float("nan"))

    def _generator_loss(self, torch, cond, noise, target=None):
        """Eq. 3: ``-E[D(G(z, C), C)] + lambda_M |M_g - M_r|_1``; returns (total, adversarial, consistency).

        ``target``: the crop-only tensors ``M_r`` (default ``cond``; they differ with ``context``).

        With ``tiles > 1`` the generator draws whole ``tiles x tiles``-crop conditions and
        the critic and the consistency loss see the generated image's training-size tiles,
        each with its own part of the condition.
        """
        t = self.settings_["tiles"]
        cn = self._normalise(cond)
        fake = _split_tiles(self.generator_(cn, noise), t)
        cn, target = _split_tiles(cn, t), _split_tiles(cond if target is None else target, t)
        adv = -self.critic_(fake, cn).mean()
        cooc = (self._cooc((fake + 1.0) * 0.5) - target).abs().sum(1).mean()  # L1 per cell, averaged
        return adv + self.settings_["lambda_cooc"] * cooc, adv, cooc

    def _generator_step(self, torch, cond, noise=None, target=None):
        if noise is None:
            noise = self._noise(torch, len(cond), cond.shape[2], cond.shape[3])
        for q in self.critic_.parameters():
            q.requires_grad_(False)
        total, adv, cooc = self._generator_loss(torch, cond, noise, target)
        self._opt_g.zero_grad(set_to_none=True)
        total.backward()
        self._opt_g.step()
        for q in self.critic_.parameters():
            q.requires_grad_(True)
        return float(adv.detach()), float(cooc.detach())

    def fit(self, exemplar, *, resume: bool = False, max_seconds: Optional[float] = None,
            progress: Optional[ProgressCallback] = None,
            log: Optional[Callable[[int, dict], None]] = None) -> "CoocGAN":
        """Train on one exemplar.

        Parameters
        ----------
        exemplar : array_like, shape (H, W) or (H, W, C)
            Float in [0, 1], at least ``crop_size`` on each side.
        resume : bool
            Continue a loaded checkpoint (or an earlier fit) up to ``n_steps`` instead of
            starting afresh; the exemplar must be the one it was trained on. Crops are cut
            again from the same seed; optimiser and random-number states come from the
            checkpoint.
        max_seconds : float, optional
            Stop after this much training time (the steps done are in ``step_``).
        progress : callable, optional
            ``progress("co-occurrences", done, total)`` then ``progress("training", step, n_steps)``.
        log : callable, optional
            ``log(step, losses)`` after every generator step, ``losses`` a dict with
            ``critic``, ``adversarial``, ``consistency`` and ``gp``.

        Returns
        -------
        self
        """
        torch = _import_torch()
        img = check_image(exemplar, name="exemplar")
        if resume:
            self._check_fitted()
            if _exemplar_hash(img) != self.exemplar_hash_:
                raise TGHopError("resume: this exemplar is not the one the checkpoint was trained on; "
                                 "give the same image, or train afresh")
            self.settings_ = {**self.settings_, "n_steps": self._settings()["n_steps"]}
            self._rebuild_crops(torch, img, progress)
        else:
            self.settings_ = self._settings()
            self.exemplar_shape_ = tuple(int(v) for v in img.shape)
            self.exemplar_hash_ = _exemplar_hash(img)
            self._seed_ = int(check_rng(self.rng).integers(2**31))
            self._build(torch, img, np.random.default_rng(self._seed_), progress)
        total = self.settings_["n_steps"]
        if self._device.type == "cpu":
            self._fixed_mmap_threshold()
        self._memory_format(torch, train=True)
        self.generator_.train()
        self.critic_.train()
        history = [self.history_]
        start = time.perf_counter()
        report(progress, "training", self.step_, max(total, self.step_))
        n_critic, gp_every = self.settings_["n_critic"], self.settings_["gp_every"]
        gp = float("nan")
        while self.step_ < total:
            self._set_learning_rate(total)
            for i in range(n_critic):
                real, cond = self._batch(torch)
                # critic steps are counted from the start (so resume keeps the schedule)
                d_loss, gp_now = self._critic_step(torch, real, cond, (self.step_ * n_critic + i) % gp_every == 0)
                gp = gp_now if math.isfinite(gp_now) else gp
            _, cond, target = self._batch(torch, targets=True)
            adv, cooc = self._generator_step(torch, cond, target=target)
            self.step_ += 1
            self._update_average(torch)
            history.append(np.array([[self.step_, d_loss, adv, cooc, gp]]))
            if log is not None:
                log(self.step_, {"critic": d_loss, "adversarial": adv, "consistency": cooc, "gp": gp})
            report(progress, "training", self.step_, total)
            if not all(math.isfinite(v) for v in (d_loss, adv, cooc)):
                raise TGHopError(f"training diverged at step {self.step_} (a loss is not finite); "
                                 "train again with a lower lr or another seed")
            if max_seconds is not None and time.perf_counter() - start > max_seconds:
                break
        if self.step_ < total:
            report(progress, "training", total, total)
        self.history_ = np.concatenate(history)
        self._memory_format(torch, train=False)
        self.generator_.eval()
        self.critic_.eval()
        if hasattr(self, "generator_ema_"):
            self._recompute_average_statistics(torch)
        return self

    @staticmethod
    def _fixed_mmap_threshold():
        """Keep glibc's mmap threshold at its initial 128 KiB for the whole process.

        glibc raises the threshold whenever a large mmapped block is freed; from then on
        the step's large temporary tensors come from the heap, whose free pieces are not
        given back, and the resident memory of a CPU training grew by about 5 MB per step
        after the first 500-1,000 steps (4.2 GB after 3,000 steps, 8.6 GB in one run).
        With the threshold fixed it stays flat (440 MB over 700 steps, same code). The same
        as ``MALLOC_MMAP_THRESHOLD_=131072`` in the environment; nothing elsewhere.
        """
        import ctypes
        import ctypes.util

        try:
            libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
            libc.mallopt(-3, 128 * 1024)  # M_MMAP_THRESHOLD
        except (OSError, AttributeError):
            pass

    def _memory_format(self, torch, *, train: bool):
        """Channels-last networks on a CPU, where oneDNN's convolutions run faster in it.

        While training (``train=True``): every network and the crops (about 20 % per step).
        Afterwards and after :func:`load`: the generators stay channels-last (generation
        takes about half the time of the default layout), the critic and the crops go back
        to the default one. A trained model and one loaded from its checkpoint therefore
        generate identically.
        """
        if self._device.type != "cpu":
            return
        fmt = torch.channels_last if train else torch.contiguous_format
        for module in (self.generator_, getattr(self, "generator_ema_", None)):
            if module is not None:
                module.to(memory_format=torch.channels_last)
        self.critic_.to(memory_format=fmt)
        if getattr(self, "_crops", None) is not None:
            self._crops = self._crops.contiguous(memory_format=fmt)

    def _rebuild_crops(self, torch, img, progress):
        """The training crops of a fresh fit with this seed (a resumed fit needs them again)."""
        rng = np.random.default_rng(self._seed_)
        rng.integers(2**31)  # the clustering seed of _build
        self._cut_crops(torch, img, rng, progress)

    def _cut_crops(self, torch, img, rng, progress):
        """``n_crops`` random crops of ``tiles x tiles`` training crops each, cut into their
        ``crop_size`` tiles, and each tile's own co-occurrence tensor.

        ``_crops`` is ``(n_crops * tiles**2, C, n, n)`` and ``_conds`` ``(n_crops * tiles**2, k*k, n/s, n/s)``,
        crop by crop, each crop's tiles row by row (the order of :func:`_split_tiles`);
        ``_targets`` (the consistency targets, the crops' own tensors) is ``_conds`` unless
        ``context``, where ``_conds`` are computed with the pixels around each crop.
        """
        p = self.settings_
        n, t = p["crop_size"], p["tiles"]
        if img.shape[0] < n * t or img.shape[1] < n * t:
            raise TGHopError(f"the exemplar is {img.shape[0]}x{img.shape[1]} pixels but the training crops are "
                             f"{n * t} (crop_size {n} x tiles {t}); use a larger exemplar or a smaller crop_size")
        ys = rng.integers(img.shape[0] - n * t + 1, size=p["n_crops"])
        xs = rng.integers(img.shape[1] - n * t + 1, size=p["n_crops"])
        crops = np.stack([img[y + i * n : y + (i + 1) * n, x + j * n : x + (j + 1) * n]
                          for y, x in zip(ys, xs) for i in range(t) for j in range(t)]).transpose(0, 3, 1, 2)
        self._crops = torch.as_tensor(crops, dtype=torch.float32, device=self._device)
        conds = []
        chunk = 64
        with torch.no_grad():
            for i in range(0, len(crops), chunk):
                conds.append(self._cooc(self._crops[i : i + chunk]))
                report(progress, "co-occurrences", min(i + chunk, len(crops)), len(crops))
        self._targets = self._conds = torch.cat(conds)
        if p["context"]:  # each t x t block with one cell of the (mirror-padded) exemplar around it
            s, cells = self.s, n * t // self.s
            padded = np.pad(img, ((s, s), (s, s), (0, 0)), mode="symmetric")
            side = n * t + 2 * s
            ctx = []
            with torch.no_grad():
                for i in range(0, len(ys), chunk):
                    block = np.stack([padded[y : y + side, x : x + side] for y, x in zip(ys[i : i + chunk], xs[i : i + chunk])])
                    block = torch.as_tensor(block.transpose(0, 3, 1, 2), dtype=torch.float32, device=self._device)
                    ctx.append(_split_tiles(self._cooc_context(block, cells, cells), t))
            self._conds = torch.cat(ctx)

    # ------------------------------------------------------------------ generation
    def _check_cond(self, cond) -> np.ndarray:
        k2 = len(self.cond_mean_)
        cond = np.asarray(cond, dtype=np.float64)
        if cond.ndim != 3 or cond.shape[0] != k2:
            raise TGHopError(f"a co-occurrence tensor of this model has shape ({k2}, h, w), got {cond.shape}")
        if not np.all(np.isfinite(cond)) or cond.min() < 0:
            raise TGHopError("a co-occurrence tensor must be finite and non-negative")
        sums = cond.sum(axis=0)
        if np.any(sums <= 0):
            raise TGHopError("every cell of a co-occurrence tensor needs a positive sum")
        return cond / sums  # each cell a distribution, as after the paper's re-normalisation

    def noise(self, shape, *, rng=None) -> np.ndarray:
        """A noise tensor for a condition of spatial ``shape = (h, w)``.

        Returns
        -------
        ndarray, shape (noise_channels, h, w), float32, N(0, 1)
        """
        self._check_fitted()
        h, w = (int(v) for v in shape)
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
            Noise tensor (:meth:`noise`); default drawn from ``rng``.
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
        """
        self._check_fitted()
        torch = _import_torch()
        conds = np.stack([self._check_cond(c) for c in conds])
        n, _, h, w = conds.shape
        if noise is None:
            r = check_rng(rng)
            noise = np.stack([self.noise((h, w), rng=r) for _ in range(n)])
        noise = np.asarray(noise, dtype=np.float32)
        if noise.shape != (n, int(self.settings_["noise_channels"]), h, w):
            raise TGHopError(f"noise must have shape {(n, self.settings_['noise_channels'], h, w)}, got {noise.shape}")
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
            :data:`FEATHER` times that.
        batch : int
            Windows per generator call.

        Returns
        -------
        ndarray, shape (h * s, w * s, C), float64 in [0, 1]
        """
        self._check_fitted()
        torch = _import_torch()
        cond = self._check_cond(cond)
        k2, h, w = cond.shape
        n, s = self._window_cells, self.s
        if h <= n and w <= n:
            return self.generate(cond, noise=noise, rng=rng)
        stride = max(1, n // 2)
        limit = min(stride, 2 * ((n - stride) // 2)) * s  # ramps within the overlap and the window
        feather = int(round(FEATHER * limit)) if feather is None else int(feather)
        if not 0 <= feather <= limit:
            raise TGHopError(f"feather must lie in 0..{limit} pixels (the windows' overlap), got {feather}")
        ys, pads_y, wy = _window_layout(h, n, stride)
        xs, pads_x, wx = _window_layout(w, n, stride)
        channels = int(self.settings_["noise_channels"])
        padded_shape = (h + sum(pads_y), w + sum(pads_x))
        if noise is None:
            z = self.noise(padded_shape, rng=rng)
        else:
            z = np.asarray(noise, dtype=np.float32)
            if z.shape != (channels, h, w):
                raise TGHopError(f"noise must have shape {(channels, h, w)}, got {z.shape}")
            z = _mirror_pad(z, pads_y, pads_x)
        c = _mirror_pad(cond, pads_y, pads_x)
        weight_y = _blend_weights(wy * s, pads_y[0] * s, (pads_y[0] + stride) * s, feather, h > n)
        weight_x = _blend_weights(wx * s, pads_x[0] * s, (pads_x[0] + stride) * s, feather, w > n)
        weight = (weight_y[:, None] * weight_x[None, :])[:, :, None]
        canvas = np.zeros((padded_shape[0] * s, padded_shape[1] * s, self.exemplar_shape_[2]))
        total = np.zeros(canvas.shape[:2] + (1,))
        starts = [(y, x) for y in ys for x in xs]
        for i in range(0, len(starts), int(batch)):
            part = starts[i : i + int(batch)]
            conds = np.stack([c[:, y : y + wy, x : x + wx] for y, x in part])
            noises = np.stack([z[:, y : y + wy, x : x + wx] for y, x in part])
            for (y, x), tile in zip(part, self._run_generator(torch, conds, noises)):
                canvas[y * s : (y + wy) * s, x * s : (x + wx) * s] += weight * tile
                total[y * s : (y + wy) * s, x * s : (x + wx) * s] += weight
        out = canvas / np.maximum(total, 1e-12)
        y0, x0 = pads_y[0] * s, pads_x[0] * s
        return np.clip(out[y0 : y0 + h * s, x0 : x0 + w * s], 0.0, 1.0)

    def crop_condition(self, y: int, x: int, size: Optional[int] = None) -> np.ndarray:
        """The co-occurrence tensor of the exemplar's ``size`` x ``size`` crop at pixel ``(y, x)``.

        Taken from :attr:`exemplar_cooc_` at cell resolution (``y``, ``x`` and ``size``
        are rounded down to multiples of ``s``; default size ``crop_size``).

        Returns
        -------
        ndarray, shape (k*k, size // s, size // s)
        """
        self._check_fitted()
        s = self.s
        size = int(self.settings_["crop_size"] if size is None else size)
        t = self.exemplar_cooc_
        cy, cx, n = int(y) // s, int(x) // s, max(1, size // s)
        if min(cy, cx) < 0 or cy + n > t.shape[1] or cx + n > t.shape[2]:
            raise TGHopError(f"a {size}x{size} crop at ({y}, {x}) is not inside the "
                             f"{self.exemplar_shape_[0]}x{self.exemplar_shape_[1]} exemplar")
        return t[:, cy : cy + n, cx : cx + n].copy()

    def condition_for(self, size, *, rng=None) -> np.ndarray:
        """The exemplar's own co-occurrence tensor, mirror-tiled from a random offset to cover ``size``.

        Returns
        -------
        ndarray, shape (k*k, ceil(h / s), ceil(w / s))
        """
        self._check_fitted()
        h, w = (int(v) for v in size)
        s = self.s
        hh, ww = -(-h // s), -(-w // s)
        t = self.exemplar_cooc_
        r = check_rng(rng)
        offset = (int(r.integers(2 * t.shape[1])), int(r.integers(2 * t.shape[2])))
        return _reflect_tile(t, hh, ww, offset)

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
            How the image is made from the generator (see :data:`ASSEMBLIES`):

            - ``"quilt"`` (ours, the default): :meth:`crop_pool` generates
              :data:`QUILT_POOL` crops of the training size (fewer for crops larger
              than 64 px), each from a random exemplar crop's tensor, and image
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
        from .baselines import _output_size

        self._check_fitted()
        _check_assembly(assembly)
        h, w = _output_size(size, (1, 1))
        r = check_rng(rng)
        if assembly == "quilt":
            from .quilting import quilt

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
        if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 1:
            raise TGHopError(f"n must be a positive integer, got {n!r}")
        n, batch = int(n), int(batch)
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
        length = int(length)
        if length < 2:
            raise TGHopError(f"length must be at least 2 cells, got {length}")
        t = np.linspace(0.0, 1.0, length)[None, None, :]
        cond = (1 - t) * _tile(a, a.shape[1], length) + t * _tile(b, b.shape[1], length)
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
        n_cols, n_rows = int(n_cols), int(n_rows)
        if n_cols < 1 or n_rows < 1:
            raise TGHopError("n_cols and n_rows must be positive")
        r = check_rng(rng)
        z0, z1 = self.noise(a.shape[1:], rng=r), self.noise(a.shape[1:], rng=r)
        rows = []
        for v in np.linspace(0.0, 1.0, n_rows):
            z = (math.cos(v * math.pi / 2) * z0 + math.sin(v * math.pi / 2) * z1).astype(np.float32)
            conds = [(1 - u) * a + u * b for u in np.linspace(0.0, 1.0, n_cols)]
            rows.append(self.generate_batch(np.stack(conds), np.stack([z] * n_cols)))
        return np.stack(rows)

    # ------------------------------------------------------------------ files
    def save(self, path) -> None:
        """Write a ``.pt`` checkpoint: tensors only (networks, optimisers, statistics, random
        states) and the settings as JSON bytes inside; loads with ``weights_only=True``.
        """
        self._check_fitted()
        torch = _import_torch()
        from .imageio import check_output_path, write_atomic

        check_output_path(path, what="checkpoint", error=ModelFileError)
        tensors = {}
        for prefix, module in self._checkpoint_modules():
            for name, value in module.state_dict().items():
                tensors[f"{prefix}.{name}"] = value.detach().cpu()
        groups = {}
        for prefix, opt in (("opt_g", self._opt_g), ("opt_d", self._opt_d)):
            sd = opt.state_dict()
            groups[prefix] = sd["param_groups"]
            for index, state in sd["state"].items():
                for name, value in state.items():
                    tensors[f"{prefix}.{index}.{name}"] = torch.as_tensor(value).detach().cpu()
        for name in ("centres_", "spreads_", "cond_mean_", "cond_std_", "exemplar_cooc_", "history_"):
            tensors[name] = torch.as_tensor(np.asarray(getattr(self, name), dtype=np.float64))
        tensors["torch_rng"] = self._torch_gen.get_state().cpu()
        settings = {"kind": KIND, "format": FORMAT, "settings": self.settings_, "step": int(self.step_),
                    "seed": int(self._seed_), "exemplar_shape": list(self.exemplar_shape_),
                    "exemplar_hash": self.exemplar_hash_, "optimiser_groups": groups,
                    "device": self.device if isinstance(self.device, str) else "auto"}
        tensors["settings_json"] = torch.frombuffer(bytearray(json.dumps(settings).encode()), dtype=torch.uint8)

        def write(f):
            buffer = io.BytesIO()
            torch.save(tensors, buffer)
            f.write(buffer.getvalue())

        write_atomic(path, write)


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
    """
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"{path}: no such checkpoint; train one with: tghop cooc train EXEMPLAR -o {path.name}")
    torch = _import_torch()
    try:
        tensors = torch.load(path, map_location="cpu", weights_only=True)
        settings = json.loads(bytes(tensors["settings_json"].numpy().tobytes()).decode())
    except Exception:
        raise ModelFileError(f"{path}: not a tghop co-occurrence checkpoint (written by 'tghop cooc train')") from None
    if not isinstance(settings, dict) or settings.get("kind") != KIND:
        raise ModelFileError(f"{path}: a checkpoint of another kind ({settings.get('kind') if isinstance(settings, dict) else '?'!r}), "
                             "not a tghop co-occurrence model; train one with 'tghop cooc train'")
    if settings.get("format") != FORMAT:
        raise ModelFileError(f"{path}: checkpoint format {settings.get('format')} but this tghop reads format {FORMAT}; "
                             "train it again with this version")
    try:
        p = {"tiles": 1, "ema": 0.0, "kernel": 5, "padding": "zeros", "gp_every": 1, "lr_decay": 0.0,
             "context": False, **settings["settings"]}  # checkpoints from before these settings
        model = CoocGAN(**p, device=device)
        model.settings_ = model._settings()
        model.exemplar_shape_ = tuple(settings["exemplar_shape"])
        model.exemplar_hash_ = settings["exemplar_hash"]
        model._seed_ = int(settings["seed"])
        model.rng = model._seed_
        model.step_ = int(settings["step"])
        for name in ("centres_", "spreads_", "cond_mean_", "cond_std_", "exemplar_cooc_", "history_"):
            setattr(model, name, tensors[name].numpy())
        model._to_device(torch)
        model.generator_, model.critic_ = _networks(torch, model.exemplar_shape_[2], len(model.cond_mean_),
                                                    model.settings_)
        model._make_averaged(torch)
        for prefix, module in model._checkpoint_modules():
            module.load_state_dict({k[len(prefix) + 1 :]: v for k, v in tensors.items() if k.startswith(prefix + ".")})
            module.to(model._device).eval()
        model._memory_format(torch, train=False)
        model._make_optimisers(torch)
        for prefix, opt in (("opt_g", model._opt_g), ("opt_d", model._opt_d)):
            state: dict = {}
            for key, value in tensors.items():
                if key.startswith(prefix + "."):
                    _, index, name = key.split(".", 2)
                    state.setdefault(int(index), {})[name] = value
            opt.load_state_dict({"state": state, "param_groups": settings["optimiser_groups"][prefix]})
        model._torch_gen = torch.Generator(device=model._device)
        model._torch_gen.set_state(tensors["torch_rng"])
    except ModelFileError:
        raise
    except Exception as exc:
        raise ModelFileError(f"{path}: corrupt tghop co-occurrence checkpoint ({exc.__class__.__name__}); "
                             "train it again") from None
    return model


def baseline(exemplar, size=None, *, rng=None, progress: Optional[ProgressCallback] = None,
             model: Optional[CoocGAN] = None, n_steps: Optional[int] = None, assembly: str = "quilt") -> np.ndarray:
    """The co-occurrence cGAN as a baseline: train the small configuration, then :meth:`CoocGAN.sample`.

    Parameters
    ----------
    exemplar : array_like, shape (H, W) or (H, W, C)
    size : int or (int, int), optional
        Output size (any); default the exemplar's.
    rng : int or numpy.random.Generator, optional
        Seeds training (when ``model`` is None) and generation.
    progress : callable, optional
    model : CoocGAN, optional
        A trained model to use instead of training one.
    n_steps : int, optional
        Generator steps of the training (default :data:`SMALL`'s).
    assembly : {"quilt", "pass", "windows"}
        How the image is made from the generator (see :meth:`CoocGAN.sample`; ``"pass"``
        is the paper's way).

    Returns
    -------
    ndarray, shape (h, w, C), float64 in [0, 1]
    """
    from .baselines import _output_size

    _check_assembly(assembly)  # before a quarter of an hour of training
    img = check_image(exemplar, name="exemplar")
    r = check_rng(rng)
    if model is None:
        model = CoocGAN(rng=r)
        if n_steps is not None:
            model.set_params(n_steps=n_steps)
        model.fit(img, progress=progress)
    return model.sample(_output_size(size, img.shape), rng=r, progress=progress, assembly=assembly)
