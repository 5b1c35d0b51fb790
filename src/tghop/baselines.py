"""Baselines and reference points to compare TGHop against.

Reference points (instant, numpy only; they bracket what a metric can say):

* :func:`crop` -- a crop of the exemplar itself (the best case a metric can see),
* :func:`blurred_crop` -- the same, Gaussian-blurred (right structure, lost detail),
* :func:`colour_noise` -- white noise with the exemplar's colour mean and covariance
  (right colours, no structure: the worst case).

Synthesis baselines:

* :func:`quilting` -- Efros & Freeman's image quilting of the exemplar's own patches
  (high fidelity, but the result is made of verbatim copies: zero novelty),
* :func:`ustyuzhaninov` -- Ustyuzhaninov et al. (ICLR 2017), "What does it take to
  generate natural textures?": match the Gram matrix of a single convolutional layer of
  random filters at eight scales by L-BFGS. TGHop's paper benchmarks against it
  (its reference [25]). Needs PyTorch (``pip install 'tghop[metrics]'``).
* :func:`cooc` -- Darzi et al.'s co-occurrence cGAN (:mod:`tghop.cooc`): trains its small
  configuration on the exemplar (minutes), then generates. Needs PyTorch.
* :func:`gpdm` -- Elnekave & Weiss (ECCV 2022), "Generating natural images with direct
  patch distributions matching" (:mod:`tghop.gpdm`): coarse to fine, Adam optimises the
  output's pixels to match the exemplar's 7 x 7 patch distribution in sliced
  Wasserstein distance (minutes on a CPU). Needs PyTorch.

:data:`BASELINES` maps a name to each of them, for ``tghop baseline NAME``. Every entry
is called as ``fn(exemplar, size=None, *, rng=None, progress=None)`` and returns a float
``(h, w, C)`` image in [0, 1]; ``size=None`` means the exemplar's own size. Sizes are
checked by :func:`tghop._images.check_size` before any work: above
:data:`tghop._images.MAX_PIXELS` (8192x8192) they are refused; and so is a size whose
estimated memory (:func:`memory_estimate`, measured peaks plus a margin) exceeds the
memory available now (:func:`tghop._resources.check_memory`, which names the largest size
that fits).

The random multiscale CNN of :func:`ustyuzhaninov` (:mod:`tghop._random_cnn`) is also the
texture model behind :func:`tghop.metrics.gram_distance`.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy import ndimage

from ._arrays import check_int, check_number
from ._errors import MissingExtraError, TGHopError
from ._estimator import check_rng
from ._images import check_image, check_size
from ._progress import ProgressCallback, report
from ._resources import check_memory, import_torch
from ._random_cnn import USTYUZHANINOV_SCALES, RandomCNN, check_scales, random_filters, to_tensor

__all__ = [
    "MissingExtraError",
    "BASELINES",
    "USTYUZHANINOV_SCALES",
    "USTYUZHANINOV_MAX_ITER",
    "crop",
    "blurred_crop",
    "colour_noise",
    "quilting",
    "ustyuzhaninov",
    "cooc",
    "memory_estimate",
    "gpdm",
]

#: Default L-BFGS iteration budget of :func:`ustyuzhaninov`. The paper runs 2,000
#: (scipy's ``maxfun``); on a CPU one iteration of the full 1,024-map model takes about
#: a second at 128 x 128 and several at 256 x 256, so the default is a compromise: at
#: 128 x 128, 300 iterations already reduce the relative Gram loss from about 9 to 1e-4
#: and give clean brick courses.
USTYUZHANINOV_N_ITER = 500

#: Most L-BFGS iterations :func:`ustyuzhaninov` runs: ten times the paper's 2,000 (hours
#: on a CPU at 128 x 128); a larger count is refused instead of running for days.
USTYUZHANINOV_MAX_ITER = 20_000


# ---------------------------------------------------------------------------------------
# Shared helpers
# ---------------------------------------------------------------------------------------


def _random_offset(rng: np.random.Generator, image_shape, size) -> tuple[int, int]:
    """Top-left corner of a uniformly random ``size`` window inside ``image_shape``."""
    h, w = size
    if h > image_shape[0] or w > image_shape[1]:
        raise TGHopError(
            f"a {h}x{w} crop does not fit in the {image_shape[0]}x{image_shape[1]} exemplar; "
            "ask for a smaller size"
        )
    return int(rng.integers(image_shape[0] - h + 1)), int(rng.integers(image_shape[1] - w + 1))


_MB = 1e6


def memory_estimate(name: str, exemplar_shape, *, patch_size: int = 32, max_patches: Optional[int] = 10_000,
                    scales=USTYUZHANINOV_SCALES, n_maps: int = 128):
    """``estimate(h, w)``: about how many bytes baseline ``name`` needs for an ``h x w`` result.

    From measured peaks (resident memory, bricks exemplars) with a margin:

    * crop, blurred-crop: the float64 result (blurred-crop: and the blurred exemplar);
    * colour-noise: about 17 bytes per output pixel and channel (the normal draws, their
      colour transform, the clipped result: 50 B/px measured for RGB);
    * quilting: the patch pool (float64 patches and a float32 copy: 12 bytes per value)
      and about 45 bytes per output pixel and channel (overlap tables, canvas, result:
      125 B/px measured for RGB);
    * ustyuzhaninov: every feature map (``n_maps * len(scales)``, 1,024 by default) at every
      position of the FFT-padded image (side + the largest filter): 24 bytes per map and
      padded pixel for the result (features, their gradient, the products of the Gram
      loss; 3.5 GB measured at 384 x 384) and 12 for the exemplar's Gram matrix, plus 150 MB.
    * cooc: see :func:`tghop.cooc.model.memory_estimate`.
    * gpdm: :func:`tghop.gpdm.gpdm_memory` at GPDM's own defaults (64 projections of 7 x 7
      patches; ``patch_size`` and ``max_patches`` here are quilting's).

    Raises
    ------
    TGHopError
        ``name`` is not a key of :data:`BASELINES`.
    """
    eh, ew = int(exemplar_shape[0]), int(exemplar_shape[1])
    c = int(exemplar_shape[2]) if len(exemplar_shape) > 2 else 1
    if name == "crop":
        return lambda h, w: 8.0 * c * h * w + _MB
    if name == "blurred-crop":
        return lambda h, w: 16.0 * c * eh * ew + 8.0 * c * h * w + _MB
    if name == "colour-noise":
        return lambda h, w: 17.0 * c * h * w + _MB
    if name == "quilting":
        p = int(patch_size)
        n = max(1, eh - p + 1) * max(1, ew - p + 1)
        if max_patches is not None:
            n = min(n, int(max_patches))
        pool = 12.0 * n * p * p * c
        return lambda h, w: pool + 45.0 * c * h * w + 50 * _MB
    if name == "ustyuzhaninov":
        k = max(check_scales(scales))
        maps = int(n_maps) * len(check_scales(scales))
        exemplar = 12.0 * maps * (eh + k) * (ew + k)
        return lambda h, w: 150 * _MB + max(exemplar, 24.0 * maps * (h + k) * (w + k))
    if name == "cooc":
        from .cooc.model import memory_estimate as cooc_estimate

        return cooc_estimate(exemplar_shape)
    if name == "gpdm":
        from .gpdm import gpdm_memory

        shape = (eh, ew, c)
        return lambda h, w: float(gpdm_memory(shape, (h, w)))
    raise TGHopError(f"unknown baseline {name!r}; one of {', '.join(BASELINES)}")


# ---------------------------------------------------------------------------------------
# Reference points
# ---------------------------------------------------------------------------------------


def crop(exemplar, size=None, *, rng=None, progress: Optional[ProgressCallback] = None) -> np.ndarray:
    """A crop of the exemplar at a random position: the best case for every fidelity metric.

    Parameters
    ----------
    exemplar : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1] (see :func:`tghop._images.check_image`).
    size : int or (int, int), optional
        Output height and width, at most the exemplar's; default the exemplar's size
        (the crop is then the exemplar itself).
    rng : int or numpy.random.Generator, optional
        Chooses the position.
    progress : callable, optional
        Accepted for a uniform baseline signature; the crop is instant.

    Returns
    -------
    ndarray, shape (h, w, C), float64 in [0, 1]
    """
    img = check_image(exemplar, name="exemplar")
    h, w = check_size(size, default=img.shape[:2])
    check_memory(memory_estimate("crop", img.shape), (h, w), what="the crop baseline")
    y, x = _random_offset(check_rng(rng), img.shape, (h, w))
    report(progress, "crop", 1, 1)
    return img[y : y + h, x : x + w].copy()


def blurred_crop(
    exemplar, size=None, *, sigma: float = 1.0, rng=None, progress: Optional[ProgressCallback] = None
) -> np.ndarray:
    """A random crop of the Gaussian-blurred exemplar: right layout, lost fine detail.

    Parameters
    ----------
    exemplar : array_like, shape (H, W) or (H, W, C)
    size : int or (int, int), optional
        Output size, at most the exemplar's; default the exemplar's size.
    sigma : float
        Standard deviation of the blur in pixels, finite and positive (default 1: the
        finest grain goes, the layout and most edges stay -- the typical failure of a patch
        model that averages). Beware: on real photographs SIFID, the Gram distance and the
        co-occurrence distance already rank a sigma = 1 blur *below* colour noise,
        because they weigh fine grain heavily; the sliced Wasserstein distance does not.
    rng : int or numpy.random.Generator, optional
    progress : callable, optional
        Accepted for a uniform baseline signature.

    Returns
    -------
    ndarray, shape (h, w, C), float64 in [0, 1]
        The blur is applied to the whole exemplar (reflecting at its borders) before
        cropping, so the crop's own borders are not darkened.
    """
    img = check_image(exemplar, name="exemplar")
    sigma = check_number(sigma, "sigma", positive=True)
    h, w = check_size(size, default=img.shape[:2])
    check_memory(memory_estimate("blurred-crop", img.shape), (h, w), what="the blurred-crop baseline")
    y, x = _random_offset(check_rng(rng), img.shape, (h, w))
    blurred = ndimage.gaussian_filter(img, sigma=(sigma, sigma, 0), mode="reflect")
    report(progress, "blurred crop", 1, 1)
    return np.clip(blurred[y : y + h, x : x + w], 0.0, 1.0)


def colour_noise(exemplar, size=None, *, rng=None, progress: Optional[ProgressCallback] = None) -> np.ndarray:
    """White Gaussian noise with the exemplar's colour mean and covariance: the worst case.

    Every pixel is drawn independently from ``N(mean, cov)`` of the exemplar's pixel
    colours and clipped to [0, 1]. It has the right palette and no spatial structure.

    Parameters
    ----------
    exemplar : array_like, shape (H, W) or (H, W, C)
    size : int or (int, int), optional
        Output size (any up to :data:`tghop._images.MAX_PIXELS`); default the exemplar's size.
    rng : int or numpy.random.Generator, optional
    progress : callable, optional
        Accepted for a uniform baseline signature.

    Returns
    -------
    ndarray, shape (h, w, C), float64 in [0, 1]
    """
    img = check_image(exemplar, name="exemplar")
    h, w = check_size(size, default=img.shape[:2])
    check_memory(memory_estimate("colour-noise", img.shape), (h, w), what="the colour-noise baseline")
    rng = check_rng(rng)
    pixels = img.reshape(-1, img.shape[2])
    mean = pixels.mean(axis=0)
    cov = np.atleast_2d(np.cov(pixels, rowvar=False))
    # Symmetric square root: safe for the rank-deficient covariance of a grey RGB image.
    evals, evecs = np.linalg.eigh(cov)
    root = evecs * np.sqrt(np.clip(evals, 0.0, None))
    noise = rng.standard_normal((h * w, img.shape[2])) @ root.T + mean
    report(progress, "colour noise", 1, 1)
    return np.clip(noise.reshape(h, w, img.shape[2]), 0.0, 1.0)


# ---------------------------------------------------------------------------------------
# Image quilting of the exemplar
# ---------------------------------------------------------------------------------------


def _all_patches(img: np.ndarray, patch_size: int, max_patches: Optional[int], rng) -> np.ndarray:
    """Every ``patch_size`` patch of ``img`` at stride 1 (a random subset if too many).

    Returns
    -------
    ndarray, shape (n, patch_size, patch_size, C), float64
    """
    windows = sliding_window_view(img, (patch_size, patch_size), axis=(0, 1))  # (nh, nw, C, P, P)
    nh, nw = windows.shape[:2]
    index = np.arange(nh * nw)
    if max_patches is not None and index.size > max_patches:
        index = np.sort(rng.choice(index.size, size=max_patches, replace=False))
    rows, cols = np.divmod(index, nw)
    return np.ascontiguousarray(windows[rows, cols].transpose(0, 2, 3, 1))


def quilting(
    exemplar,
    size=None,
    *,
    patch_size: int = 32,
    overlap: Optional[int] = None,
    tolerance: float = 0.1,
    tile: bool = False,
    max_patches: Optional[int] = 10_000,
    rng=None,
    progress: Optional[ProgressCallback] = None,
) -> np.ndarray:
    """Image quilting (Efros & Freeman 2001) of the exemplar's own patches.

    The pool is every ``patch_size`` patch of the exemplar at stride 1 (a random subset
    of ``max_patches`` if there are more); :func:`tghop.quilting.quilt` stitches it. This
    is what TGHop's stitching step does with generated patches instead, so the pair
    separates what the patch generator contributes from what quilting contributes.

    Parameters
    ----------
    exemplar : array_like, shape (H, W) or (H, W, C)
        At least ``patch_size`` pixels on each side.
    size : int or (int, int), optional
        Output size (any up to :data:`tghop._images.MAX_PIXELS`); default the exemplar's size.
    patch_size : int
        Side of the quilted patches (default 32, TGHop's patch size).
    overlap : int, optional
        Overlap between neighbouring patches; default that of :func:`tghop.quilting.quilt`
        (about 1/6 of the patch).
    tolerance : float
        Candidates within ``(1 + tolerance)`` of the best overlap error are drawn from.
    tile : bool
        Make the output tileable (see :func:`tghop.quilting.quilt`).
    max_patches : int or None
        Pool size limit (default 10,000, the upper end of the paper's 5,000-10,000; a
        256 x 256 exemplar has 50,625 patches of 32 x 32). None keeps them all.
    rng : int or numpy.random.Generator, optional
        Draws the pool subset and the quilting choices.
    progress : callable, optional
        Passed on to the quilting step.

    Returns
    -------
    ndarray, shape (h, w, C), float64 in [0, 1]
    """
    from .quilting import quilt  # another stage of the pipeline; imported when used

    patch_size = check_int(patch_size, "patch_size", 2)  # 16.7 is refused, not a 16
    max_patches = None if max_patches is None else check_int(max_patches, "max_patches")
    img = check_image(exemplar, min_size=patch_size, name="exemplar")
    h, w = check_size(size, default=img.shape[:2])
    check_memory(memory_estimate("quilting", img.shape, patch_size=patch_size, max_patches=max_patches), (h, w),
                 what="image quilting")
    rng = check_rng(rng)
    pool = _all_patches(img, patch_size, max_patches, rng)
    out = quilt(pool.astype(np.float32), (h, w), overlap=overlap, tolerance=tolerance, tile=tile,
                rng=rng, progress=progress)
    return np.clip(np.asarray(out, dtype=np.float64), 0.0, 1.0)


# ---------------------------------------------------------------------------------------
# Ustyuzhaninov et al. 2017: Gram matching in a random multiscale CNN
# ---------------------------------------------------------------------------------------


def ustyuzhaninov(
    exemplar,
    size=None,
    *,
    n_iter: int = USTYUZHANINOV_N_ITER,
    scales=USTYUZHANINOV_SCALES,
    n_maps: int = 128,
    rng=None,
    progress: Optional[ProgressCallback] = None,
    return_info: bool = False,
):
    """Texture synthesis with a single layer of random multiscale filters (Ustyuzhaninov et al. 2017).

    The exemplar, minus its mean colour, goes through one convolutional layer of
    ``n_maps`` random filters at each size in ``scales`` (the paper's "RandomMultiscale":
    3 to 55 pixels, 128 maps each, 1,024 in total), Glorot-uniform, no bias, zero padding
    to keep the image size, then ReLU. The texture is the Gram matrix ``G = F F^T / P`` of
    all 1,024 maps over the ``P`` positions (across scales, as in the authors' code). From
    uniform noise in [0, 1], L-BFGS (``torch.optim.LBFGS``, strong-Wolfe line search) then
    minimises ``||G(x) - G(exemplar)||^2 / ||G(exemplar)||^2``. Being relative, the loss
    needs no hand-tuned scale factor (the paper multiplies by 1e7 to keep scipy's
    L-BFGS-B from stopping early); tolerances are set so that only ``n_iter`` stops it.
    The paper's box constraint [0, 1] is not available in torch's L-BFGS: the image is
    optimised unconstrained and clipped at the end, as the authors' code does.

    Parameters
    ----------
    exemplar : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1]; C = 1 synthesises greyscale.
    size : int or (int, int), optional
        Output size (any up to :data:`tghop._images.MAX_PIXELS`); default the exemplar's size.
    n_iter : int
        L-BFGS iterations (default :data:`USTYUZHANINOV_N_ITER` = 500; the paper runs
        2,000 function evaluations), at most :data:`USTYUZHANINOV_MAX_ITER` = 20,000.
        Each iteration takes one or a few evaluations.
    scales : sequence of odd int
        Filter sizes (default the paper's ``(3, 5, 7, 11, 15, 23, 37, 55)``).
    n_maps : int
        Feature maps per filter size (default 128).
    rng : int or numpy.random.Generator, optional
        Draws the filters and the starting noise.
    progress : callable, optional
        ``progress("ustyuzhaninov", done_iterations, n_iter)``.
    return_info : bool
        Also return a dict with the iterations actually run.

    Returns
    -------
    image : ndarray, shape (h, w, C), float64 in [0, 1]
    info : dict, only if ``return_info``
        ``n_iter`` (L-BFGS iterations run), ``n_evals`` (loss and gradient evaluations),
        ``loss`` (final relative Gram loss, as minimised), ``initial_loss``, ``n_features``.

    Notes
    -----
    Cost grows with ``n_features**2 * h * w`` (the Gram matrix) and the FFTs of 1,024 maps:
    on one busy CPU core about 1.2 s per iteration at 128 x 128 and 7 s at 256 x 256, and
    about 2 GB of memory at 256 x 256 (:func:`memory_estimate`; larger sizes than the
    memory available are refused before any work). PyTorch's thread count is left as configured.
    """
    torch = import_torch("the Ustyuzhaninov et al. baseline")
    img = check_image(exemplar, name="exemplar")
    h, w = check_size(size, default=img.shape[:2])
    scales = check_scales(scales)
    n_iter, n_maps = check_int(n_iter, "n_iter", 0, USTYUZHANINOV_MAX_ITER), check_int(n_maps, "n_maps", 1)
    check_memory(memory_estimate("ustyuzhaninov", img.shape, scales=scales, n_maps=n_maps), (h, w),
                 what="the ustyuzhaninov baseline")
    rng = check_rng(rng)
    c = img.shape[2]
    cnn = RandomCNN(torch, random_filters(scales, n_maps, c, rng))
    mean = img.reshape(-1, c).mean(axis=0)
    with torch.no_grad():
        target = cnn.gram(to_tensor(torch, img, mean), "same")
        norm = float((target * target).sum()) or 1.0
    if (h, w) != img.shape[:2]:
        cnn.forget(img.shape[0], img.shape[1], "same")  # the exemplar's filter spectra are done with
    start = rng.uniform(0.0, 1.0, size=(h, w, c))
    x = to_tensor(torch, start, mean).requires_grad_(True)
    optimizer = torch.optim.LBFGS(
        [x], lr=1.0, max_iter=1, history_size=100, tolerance_grad=0.0, tolerance_change=0.0,
        line_search_fn="strong_wolfe",
    )
    n_evals = 0
    losses = []  # first and last evaluated loss; the first is at the starting noise

    def closure():
        nonlocal n_evals
        optimizer.zero_grad()
        feats = cnn.features(x, "same")
        with torch.no_grad():
            positions = feats.shape[1]
            diff = (feats @ feats.T) / positions - target
            loss = (diff * diff).sum() / norm
            # d loss / d F = 4 (G - A) F / (P ||A||^2): one matrix product instead of autograd's two.
            grad_feats = (diff @ feats) * (4.0 / (positions * norm))
        feats.backward(grad_feats)
        n_evals += 1
        losses[1:] = [float(loss)]
        # L-BFGS counts its iterations in its state: the bar moves every iteration, not every chunk.
        report(progress, "ustyuzhaninov", min(int(optimizer.state[x].get("n_iter", 0)), n_iter), n_iter)
        return loss

    def relative_loss() -> float:
        with torch.no_grad():
            return float(((cnn.gram(x.detach(), "same") - target) ** 2).sum() / norm)

    done = 0
    report(progress, "ustyuzhaninov", 0, n_iter)
    chunk = 25  # L-BFGS keeps its history across step() calls; each call costs one extra evaluation
    while done < n_iter:
        optimizer.param_groups[0]["max_iter"] = min(chunk, n_iter - done)
        optimizer.param_groups[0]["max_eval"] = 10 * min(chunk, n_iter - done)
        optimizer.step(closure)
        state = optimizer.state[x]
        ran = int(state.get("n_iter", 0)) - done
        done += ran
        report(progress, "ustyuzhaninov", min(done, n_iter), n_iter)
        if ran <= 0 or not math.isfinite(losses[-1]):
            break  # converged or stalled: no further progress possible
    if done < n_iter:
        report(progress, "ustyuzhaninov", n_iter, n_iter)
    out = np.clip(x.detach().numpy().transpose(1, 2, 0).astype(np.float64) + mean, 0.0, 1.0)
    if not return_info:
        return out
    info = {
        "n_iter": done,
        "n_evals": n_evals,
        "loss": relative_loss(),  # the last evaluation may have been a rejected line-search point
        "initial_loss": losses[0] if losses else relative_loss(),
        "n_features": cnn.n_features,
    }
    return out, info


def cooc(exemplar, size=None, *, rng=None, progress: Optional[ProgressCallback] = None, **options) -> np.ndarray:
    """The co-occurrence cGAN of Darzi et al.: see :func:`tghop.cooc.baseline` (needs PyTorch).

    Parameters
    ----------
    exemplar : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], or uint8 / uint16.
    size : int or (int, int), optional
        Output (height, width); default the exemplar's.
    rng : int or numpy.random.Generator, optional
        Same seed, same image.
    progress : callable, optional
        ``progress(stage, done, total)``.
    **options
        Further keywords of :func:`tghop.cooc.baseline`.

    Returns
    -------
    ndarray, shape (h, w, C), float64 in [0, 1]
    """
    from .cooc import baseline

    return baseline(exemplar, size, rng=rng, progress=progress, **options)


def gpdm(exemplar, size=None, *, rng=None, progress: Optional[ProgressCallback] = None, n_steps: int = 300,
         n_projections: int = 64, patch_size: int = 7, scale_factor: float = 0.85, coarsest: int = 21,
         lr: float = 0.01, **options):
    """GPDM, direct patch distribution matching (Elnekave & Weiss 2022): see :func:`tghop.gpdm.gpdm`.

    Coarse to fine over a pyramid of the exemplar (scale factor 0.85, from about 21 pixels),
    the output's pixels are optimised by Adam (``n_steps`` = 300 per level) to lower the
    sliced Wasserstein distance between its 7 x 7 patches and the exemplar's (64 random
    projections per step). Needs PyTorch; minutes on a CPU at 128 x 128.

    Parameters
    ----------
    exemplar : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], or uint8 / uint16.
    size : int or (int, int), optional
        Output (height, width); default the exemplar's.
    rng : int or numpy.random.Generator, optional
        Same seed, same image.
    progress : callable, optional
        ``progress(stage, done, total)``.
    n_steps, n_projections, patch_size, scale_factor, coarsest, lr
        As :func:`tghop.gpdm.gpdm`.
    **options
        Further keywords of :func:`tghop.gpdm.gpdm`.

    Returns
    -------
    ndarray, shape (h, w, C), float64 in [0, 1]
    """
    from .gpdm import gpdm as run

    return run(exemplar, size, rng=rng, progress=progress, n_steps=n_steps, n_projections=n_projections,
               patch_size=patch_size, scale_factor=scale_factor, coarsest=coarsest, lr=lr, **options)


#: name -> baseline, each called as ``fn(exemplar, size=None, *, rng=None, progress=None)``.
BASELINES = {
    "crop": crop,
    "blurred-crop": blurred_crop,
    "colour-noise": colour_noise,
    "quilting": quilting,
    "ustyuzhaninov": ustyuzhaninov,
    "cooc": cooc,
    "gpdm": gpdm,
}
