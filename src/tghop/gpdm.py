"""GPDM (Elnekave & Weiss, ECCV 2022): optimise the output's pixels so that its patch
distribution matches the exemplar's, coarse to fine.

"Generating natural images with direct patch distributions matching": no network and no
training. At every level of a pyramid, the output image itself is the parameter; Adam
lowers the sliced Wasserstein distance (SWD) between the output's 7 x 7 patches and the
exemplar's patches at that level. Used by :func:`tghop.baselines.gpdm` and
``tghop baseline gpdm``. Needs PyTorch (``pip install 'tghop[metrics]'``).
"""

from __future__ import annotations

import math
import time
from typing import Optional

import numpy as np

from ._arrays import check_int, check_number
from ._errors import TGHopError
from ._estimator import check_rng
from ._images import check_image, check_size
from ._progress import ProgressCallback, report
from ._resources import check_memory, import_torch, usable_cores

__all__ = ["gpdm", "gpdm_levels", "gpdm_memory", "GPDM_MAX_STEPS"]

#: Most Adam steps per level :func:`gpdm` runs: ten times the paper's 300 (a larger count is
#: refused instead of running for days).
GPDM_MAX_STEPS = 3_000

#: Bytes of an element of the float32 tensors GPDM works with.
_F32 = 4


def gpdm_levels(exemplar_shape, size, *, scale_factor: float = 0.85, coarsest: int = 21,
                patch_size: int = 7) -> list:
    """The pyramid of :func:`gpdm`: ``[(output (h, w), exemplar (h, w)), ...]``, coarse to fine.

    Level ``k`` (0 the finest) scales both the output and the exemplar by
    ``scale_factor ** k``; there are as many levels as keep the smallest side of the two
    (the output's and the exemplar's) at least ``coarsest`` pixels -- one level when it
    is already below. No side goes below ``patch_size``. The finest level is the output
    size and the exemplar itself.

    Parameters
    ----------
    exemplar_shape : tuple of int
        The exemplar's shape, (H, W) or (H, W, C).
    size : (int, int)
        The output's (height, width).
    scale_factor : float
        Scale between neighbouring levels, in (0, 1).
    coarsest : int
        The least smallest side (pixels) a coarser level may have.
    patch_size : int
        The least side of any level.

    Returns
    -------
    list of ((int, int), (int, int))
        Per level, coarse to fine: the output's and the exemplar's (height, width).
    """
    (h, w), (eh, ew) = tuple(size), tuple(exemplar_shape[:2])
    side = min(h, w, eh, ew)
    n = 1 if side <= coarsest else int(math.floor(math.log(coarsest / side) / math.log(scale_factor) + 1e-9)) + 1

    def scaled(length, s):
        return max(patch_size, int(round(length * s)))

    levels = []
    for k in range(n - 1, -1, -1):
        s = scale_factor ** k
        levels.append(((scaled(h, s), scaled(w, s)), (scaled(eh, s), scaled(ew, s))))
    levels[-1] = ((h, w), (eh, ew))
    return levels


def gpdm_memory(exemplar_shape, size, *, n_projections: int = 64, patch_size: int = 7) -> int:
    """Estimated peak bytes of :func:`gpdm` (its finest level, the largest).

    Per pixel of the exemplar: its projections onto every direction, their sorted copy
    and sort indices (int64), and the convolution's unfolded patches; per pixel of the
    output the same twice over (forward and backward), plus the interpolated target
    quantiles, the gradient and Adam's two moments. Measured peaks (growth of the
    process's resident memory, 256 x 256 exemplar): 162 MB at 128 x 128 (estimate 158 MB),
    268 MB at 256 x 256 (estimate 326 MB).

    Parameters
    ----------
    exemplar_shape : tuple of int
        The exemplar's shape, (H, W) or (H, W, C) (no C: one channel).
    size : (int, int)
        The output's (height, width).
    n_projections : int
        Random directions of the sliced distance (:func:`gpdm`'s).
    patch_size : int
        Side of the compared patches.

    Returns
    -------
    int
        Bytes.
    """
    (h, w), (eh, ew) = tuple(size), tuple(exemplar_shape[:2])
    c = exemplar_shape[2] if len(exemplar_shape) > 2 else 1
    patch = c * patch_size * patch_size
    ex = eh * ew * (4 * n_projections + patch + 2 * c)
    out = h * w * (9 * n_projections + 2 * patch + 8 * c)
    return int(_F32 * (ex + out))


def gpdm(
    exemplar,
    size=None,
    *,
    rng=None,
    progress: Optional[ProgressCallback] = None,
    n_steps: int = 300,
    n_projections: int = 64,
    patch_size: int = 7,
    scale_factor: float = 0.85,
    coarsest: int = 21,
    lr: float = 0.01,
    init: str = "noise",
    noise_sigma: float = 0.75,
    n_threads: Optional[int] = None,
    return_info: bool = False,
):
    """Texture synthesis by direct patch distribution matching (GPDM, Elnekave & Weiss 2022).

    Method. Images are scaled to [-1, 1]. A pyramid of the exemplar and of the output is
    made with ``scale_factor`` (0.85) between levels, from about ``coarsest`` (21) pixels
    on the smaller side up to the exemplar's and the output's own sizes
    (:func:`gpdm_levels`; the exemplar's levels are antialiased bilinear downscales). The
    output starts at the coarsest level as Gaussian noise of standard deviation
    ``noise_sigma`` around mid-grey (``init="noise"``, GPDM's default) or as the coarsest
    exemplar, Gaussian-blurred and resized, plus that noise (``init="blurred"``). At
    each level the output's pixels are optimised by Adam (``lr``, times 0.9 every 100
    steps) for ``n_steps`` steps to lower the sliced Wasserstein distance between the
    output's ``patch_size`` x ``patch_size`` patches (all, stride 1) and the exemplar's at
    that level: ``n_projections`` random unit directions, drawn anew every step, project
    every patch (one convolution each); each direction's sorted projections of the
    output are compared, in L1, with the exemplar's at the same quantiles (1-D optimal
    transport; the exemplar's sorted values are linearly interpolated when the two patch
    counts differ). The output is then clipped to [-1, 1] and upsampled (bilinear) to
    the next level.

    Parameters
    ----------
    exemplar : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], at least ``patch_size`` on each side; C = 1 synthesises greyscale.
    size : int or (int, int), optional
        Output size, at least ``patch_size`` on each side; default the exemplar's size.
    rng : int or numpy.random.Generator, optional
        Seeds the starting noise and the projections (same seed and threads: same output).
    progress : callable, optional
        ``progress("gpdm level k/n", done_steps, n_steps)``, one stage per level.
    n_steps : int
        Adam steps per level (default 300, the paper's), at most :data:`GPDM_MAX_STEPS` = 3,000;
        0 returns the upsampled start.
    n_projections : int
        Random directions per step (default 64).
    patch_size : int
        Side of the matched patches (default 7).
    scale_factor : float
        Downscale between levels, in (0, 1) (default 0.85).
    coarsest : int
        Smallest side of the coarsest level, roughly (default 21).
    lr : float
        Adam's learning rate, in the [-1, 1] pixel units (default 0.01).
    init : {"noise", "blurred"}
        The start at the coarsest level (see above).
    noise_sigma : float
        Standard deviation of the starting noise in [-1, 1] units (default 0.75).
    n_threads : int, optional
        PyTorch threads while it runs (default: the CPUs this process may use); the
        previous setting is restored afterwards.
    return_info : bool
        Also return a dict: ``levels`` (output and exemplar size per level), ``losses``
        (first and last SWD loss per level), ``seconds``.

    Returns
    -------
    image : ndarray, shape (h, w, C), float64 in [0, 1]
    info : dict, only if ``return_info``

    Notes
    -----
    The output's border pixels lie in fewer patches (a corner pixel in one), so they get
    little gradient and traces of the starting noise can stay along the borders. Large
    rounded elements (beach pebbles) come out as soft, cloud-like blobs at these
    defaults; regular ones (brick courses, knit holes) are reproduced
    (``benchmarks/results/gpdm*.md``).

    Cost: every step convolves both the output and the exemplar with ``n_projections``
    filters of ``C * patch_size**2`` weights, sorts the projections, and back-propagates
    through the output's side: about ``2 * n_projections * C * patch_size**2 * (H W + 3 h w)``
    flops per step at the finest level, and the whole pyramid costs about 3.6 times its
    finest level (``1 / (1 - 0.85**2)``). A 128 x 128 output from a 256 x 256 exemplar
    (12 levels) took 12 minutes at 300 steps per level on 2 CPU cores shared with other
    work, and 1.7 minutes at 100 steps when they were less loaded
    (``benchmarks/results/gpdm*.md``). Memory is dominated by the
    finest level's projections (:func:`gpdm_memory`); sizes whose estimate exceeds this
    machine's memory are refused before any work, as are sizes above
    :data:`tghop._images.MAX_PIXELS`.
    """
    img = check_image(exemplar, name="exemplar")
    h, w = check_size(size, default=img.shape[:2])
    n_steps = check_int(n_steps, "n_steps", 0, GPDM_MAX_STEPS, where="gpdm")
    n_projections = check_int(n_projections, "n_projections", where="gpdm")
    patch_size = check_int(patch_size, "patch_size", where="gpdm")
    coarsest = check_int(coarsest, "coarsest", where="gpdm")
    scale_factor = check_number(scale_factor, "scale_factor", positive=True, where="gpdm")
    if not scale_factor < 1.0:
        raise TGHopError(f"gpdm: scale_factor must lie in (0, 1), got {scale_factor!r}")
    lr = check_number(lr, "lr", positive=True, where="gpdm")
    noise_sigma = check_number(noise_sigma, "noise_sigma", where="gpdm")
    if n_threads is not None:
        n_threads = check_int(n_threads, "n_threads", where="gpdm")  # 0 was torch's RuntimeError
    if init not in ("noise", "blurred"):
        raise TGHopError(f"init must be 'noise' or 'blurred', got {init!r}")
    if min(img.shape[:2]) < patch_size or min(h, w) < patch_size:
        raise TGHopError(
            f"gpdm needs the exemplar ({img.shape[0]}x{img.shape[1]}) and the output ({h}x{w}) to be at least "
            f"{patch_size}x{patch_size} pixels (the patch size)"
        )
    check_memory(lambda hh, ww: gpdm_memory(img.shape, (hh, ww), n_projections=n_projections, patch_size=patch_size),
                 (h, w), what="the gpdm baseline")
    torch = import_torch("the GPDM baseline")
    rng = check_rng(rng)
    threads = torch.get_num_threads()
    torch.set_num_threads(int(n_threads) if n_threads is not None else usable_cores())
    try:
        return _run(torch, img, (h, w), rng, progress, n_steps, n_projections, patch_size, scale_factor,
                    coarsest, lr, init, noise_sigma, return_info)
    finally:
        torch.set_num_threads(threads)


def _run(torch, img, size, rng, progress, n_steps, n_projections, patch_size, scale_factor, coarsest, lr, init,
         noise_sigma, return_info):
    import torch.nn.functional as F

    started = time.perf_counter()
    levels = gpdm_levels(img.shape, size, scale_factor=scale_factor, coarsest=coarsest, patch_size=patch_size)
    gen = torch.Generator().manual_seed(int(rng.integers(2**62)))
    c = img.shape[2]
    full = torch.from_numpy(np.ascontiguousarray(img.transpose(2, 0, 1), dtype=np.float32))[None] * 2.0 - 1.0

    def exemplar_at(shape):
        if tuple(shape) == tuple(full.shape[2:]):
            return full
        return F.interpolate(full, size=tuple(shape), mode="bilinear", align_corners=False, antialias=True)

    (h0, w0), ex_shape0 = levels[0]
    start = torch.zeros(1, c, h0, w0)
    if init == "blurred":
        from scipy import ndimage

        coarse = exemplar_at(ex_shape0)[0].numpy().transpose(1, 2, 0)
        coarse = ndimage.gaussian_filter(coarse, sigma=(2.0, 2.0, 0), mode="reflect")
        start = F.interpolate(torch.from_numpy(np.ascontiguousarray(coarse.transpose(2, 0, 1)))[None],
                              size=(h0, w0), mode="bilinear", align_corners=False, antialias=True)
    if noise_sigma > 0:
        start = start + noise_sigma * torch.randn(start.shape, generator=gen)
    x = start.clamp_(-1.0, 1.0).contiguous()
    dim = c * patch_size * patch_size
    losses = []
    for k, ((h, w), ex_shape) in enumerate(levels):
        stage = f"gpdm level {k + 1}/{len(levels)}"
        report(progress, stage, 0, n_steps)
        if tuple(x.shape[2:]) != (h, w):
            x = F.interpolate(x, size=(h, w), mode="bilinear", align_corners=False)
        x = x.detach().requires_grad_(True)
        target = exemplar_at(ex_shape)
        n_out = (h - patch_size + 1) * (w - patch_size + 1)
        n_ex = (ex_shape[0] - patch_size + 1) * (ex_shape[1] - patch_size + 1)
        # The exemplar's sorted projections at the output's quantiles (i + 1/2) / n_out.
        pos = ((torch.arange(n_out, dtype=torch.float64) + 0.5) * (n_ex / n_out) - 0.5).clamp_(0, n_ex - 1)
        lo = pos.floor().long()
        hi = (lo + 1).clamp_(max=n_ex - 1)
        frac = (pos - lo).float()
        optimizer = torch.optim.Adam([x], lr=lr)
        first = last = float("nan")
        for step in range(n_steps):
            if step and step % 100 == 0:
                for group in optimizer.param_groups:
                    group["lr"] *= 0.9
            directions = torch.randn(n_projections, dim, generator=gen)
            directions = (directions / directions.norm(dim=1, keepdim=True)).reshape(n_projections, c, patch_size,
                                                                                      patch_size)
            with torch.no_grad():
                # numpy's (vectorised) sort is several times faster than torch's on a CPU.
                ref = torch.from_numpy(np.sort(F.conv2d(target, directions).reshape(n_projections, n_ex).numpy(),
                                               axis=1))
                ref = torch.lerp(ref[:, lo], ref[:, hi], frac) if n_ex != n_out else ref
            optimizer.zero_grad(set_to_none=True)
            mine = F.conv2d(x, directions).reshape(n_projections, n_out)
            order = torch.from_numpy(np.argsort(mine.detach().numpy(), axis=1))
            loss = (mine.gather(1, order) - ref).abs().mean()  # sorted values; the gradient follows the order
            loss.backward()
            optimizer.step()
            last = float(loss.detach())
            if step == 0:
                first = last
            report(progress, stage, step + 1, n_steps)
        with torch.no_grad():
            x = x.detach().clamp_(-1.0, 1.0)
        losses.append((first, last))
    out = ((x[0].numpy().transpose(1, 2, 0).astype(np.float64) + 1.0) / 2.0).clip(0.0, 1.0)
    if not return_info:
        return out
    info = {"levels": levels, "losses": losses, "seconds": time.perf_counter() - started}
    return out, info
