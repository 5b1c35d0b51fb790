"""Several TGHop models in one image: painted regions, a remix, a morph (ours). A painted guide is read
into labels by :mod:`tghop.guides`; the regions' layers are joined by :mod:`tghop.composite`.

Every function here makes one image from the *generated* patches of several fitted
models (never pieces of an exemplar), with the quality steps of
:meth:`tghop.TGHop.synthesize`:

* :func:`synthesize_guided` with a ``guide``: a painted map with one grey level (or
  colour) per model; each region is texture of its model, joined to its neighbours
  along the content within ``transition`` pixels of the painted edge.
* :func:`synthesize_guided` without a guide: one texture that mixes the models ("remix"):
  random regions of each.
* :func:`morph`: from model A's texture on the left to B's on the right.

How painted regions (and a remix) are made
-------------------------------------------
1. **Weights.** Each model ``k`` has a share ``W_k(x)`` of every pixel (they sum to 1):
   the guide's regions as one-hot maps blurred by a box of ``transition`` pixels
   (:func:`region_weights`). The remix is a guided synthesis whose map is random: a
   smooth random field cut into ``K`` classes of equal area (:func:`random_labels`, blobs
   of about 2.3 :func:`remix_blob` across: 150 px at 0.63's 64 px for all, 0.64 by the textures' elements).
2. **Layers.** Each model synthesises its own image (:meth:`tghop.TGHop.synthesize`, all
   its steps and settings) over the box where its weight is above 0, so every region is as
   good as a plain image of its model.
3. **Join** (:mod:`tghop.composite`). A pixel away from the painted edges shows its own
   region's layer; in the band of ``transition`` pixels around an edge, one minimum cut
   decides which of the two layers each pixel shows, so the join runs where the layers
   look alike (along their elements' outlines) and stays near the paint. The join is
   antialiased over about a pixel (a region 1-2 px wide keeps its own layer on its pixels).

How a morph is made
-------------------
A morph is a painted guide that nobody paints: :func:`morph_labels` draws its two regions
from a smooth random field (a Gaussian of :data:`MORPH_BLOB` patch sizes), B where the field is
above a threshold chosen over a window of columns so that a column at ``t = x / (W - 1)`` of the
way gives about the share ``t`` of its pixels to B: all A at the left edge, all B at the right,
and organic outlines in between. Islands smaller than :data:`MORPH_ISLAND` blob areas (specks that
an artist takes for dirt, near the ends mostly) are given to the region around them, and the share
they held is asked for again. A strip lower than a patch cannot show the mix (its regions would be
whole columns, A's half then B's) and is refused. Then as painted regions: each model's own
synthesis over the box its region reaches, joined along the content. Each region keeps its own
model's statistics and colours; the columns go from A to B by the share of each.

Example
-------
>>> import numpy as np
>>> import tghop
>>> from tghop import TGHop, data
>>> a, b = TGHop(rng=0).fit(data.bricks()), TGHop(rng=0).fit(data.cells())  # doctest: +SKIP
>>> guide = np.zeros((256, 256), np.uint8); guide[:, 128:] = 255             # doctest: +SKIP
>>> image = tghop.synthesize_guided([a, b], guide, rng=1)                    # doctest: +SKIP
>>> strip = tghop.morph(a, b, (256, 1024), rng=1)                            # doctest: +SKIP
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from . import settings
from ._arrays import check_dtype, check_int, check_not_path, check_number
from ._errors import TGHopError, check_progress
from ._estimator import check_is_fitted, check_rng
from ._images import check_size
from ._progress import report
from ._resources import one_blas_thread
from .composite import band_boxes, cut_regions, in_band, join_layers, layer_boxes, wraps
from .exemplar import drop_alpha
from .guides import guide_labels
from .masks import snap_channels, snap_to_levels
from .material import Material, renormalise
from .material_files import NORMAL_BY_NAME, maps_refused
from .normals import convention_flips, flip_green
from .quilting import block_count

__all__ = ["synthesize_guided", "morph", "morph_labels", "guide_labels", "region_weights", "random_labels",
           "element_size", "remix_blob", "DEFAULT_TRANSITION", "MAX_TRANSITION", "MORPH_BLOB", "MORPH_ISLAND",
           "REMIX_ISLAND", "REMIX_BLOB", "REMIX_BLOB_RANGE"]

#: Default width in pixels of the band around a painted edge where the join follows the textures.
DEFAULT_TRANSITION = 32
#: The widest band (the command line's ``--transition`` range): wider took memory for nothing.
MAX_TRANSITION = 4096
#: Length scale in pixels of the random regions of a remix, where no models say otherwise (0.63: every remix's).
_BLOB = 64
#: A remix's blobs (the Gaussian of its random field, :func:`random_labels`), in the coarser texture's element
#: sizes (:func:`element_size`; 0.64): the built-in bricks and cells (8 and 9 px) keep about 0.63's 64 px.
REMIX_BLOB = 7.0
#: The smallest and largest blob :func:`remix_blob` gives, in pixels.
REMIX_BLOB_RANGE = (32.0, 256.0)
#: Length scale of a morph's regions (the Gaussian of its random field), in the models' patch sizes: blobs
#: of about a patch, as fine as the textures' elements allow (at 2 patch sizes a few large regions, the
#: ramp lost; the quilt's blocks as outlines, 32 px squares, were a staircase).
MORPH_BLOB = 0.75
#: A morph's smallest region, in blob areas (``scale`` squared; in a strip lower than 4 blobs, a quarter of
#: its height squared): a smaller island of one texture in the other's region (the field's lone peaks,
#: near the ends mostly, which an artist takes for dirt) is given to the region around it (at 3 blob areas
#: the share of B fell behind the position at the ends; at 1, specks of 10-20 px stayed).
MORPH_ISLAND = 2.0
#: A remix's smallest region, in blob areas (``scale`` squared; 2,048 px at 64 px blobs, 0.63): a smaller one,
#: cut off by the image's edge or a lone peak of the field (specks down to a few pixels), is given to the
#: regions around it. The smallest left are about 45x45 px, patches of the texture rather than dirt.
REMIX_ISLAND = 0.5
#: The warning for a morph given ``stations`` (the server's header says it too).
STATIONS_GONE = "stations no longer applies to a morph (each region keeps its own model's statistics); leave it out"


# ----------------------------------------------------------------------------- region weights


def region_weights(labels, n_models, transition=DEFAULT_TRANSITION, *, tile=False) -> np.ndarray:
    """Soft region weights: each label's one-hot map blurred by a box of ``transition`` pixels.

    Parameters
    ----------
    labels : array_like of int, shape (H, W)
        Each pixel's region, in ``[0, n_models)``; another shape, dtype or value raises
        :class:`~tghop.TGHopError`.
    n_models : int
        Number of regions (at least 1).
    transition : float
        Width in pixels of the box (``2 (transition // 2) + 1`` samples a side); below 2: hard edges.
    tile : bool
        Blur periodically (the weights of a tileable output), else with repeated edges.

    Returns
    -------
    ndarray of float32, shape (n_models, H, W)
        In [0, 1], summing to 1 at every pixel; 0 or 1 everywhere for ``transition`` 0.
    """
    n_models = check_int(n_models, "n_models", 1)
    check_number(transition, "transition", unit="pixels")
    labels = np.asarray(labels)
    if labels.ndim != 2 or labels.size == 0 or labels.dtype.kind not in "iu" or labels.min() < 0 \
            or labels.max() >= n_models:
        raise TGHopError(f"labels must be a non-empty (H, W) integer map of values in [0, {n_models}) "
                         f"(n_models), got {labels.dtype} {labels.shape}")
    out = np.stack([(labels == k).astype(np.float32) for k in range(n_models)])
    radius = int(transition) // 2
    if radius:
        # Box sums of the 0/1 maps are whole numbers (exact in float32), divided once.
        area = np.float32((2 * radius + 1) ** 2)
        h, w = labels.shape
        # While every running sum stays below 2^24 they are exact, and the maps' box sums add up to the
        # box's area everywhere: the last map's is the area less the others'.
        exact = n_models > 1 and max(h + 2 * radius + 1, (w + 2 * radius + 1) * (2 * radius + 1)) < 1 << 24
        for k in range(n_models - 1 if exact else n_models):
            out[k] = _box_sum(_box_sum(out[k], radius, 0, tile), radius, 1, tile)
        if exact:
            np.subtract(area, out[:-1].sum(axis=0) if n_models > 2 else out[0], out=out[-1])
        out /= area
    return out


def _box_sum(x, radius, axis, wrap):
    """Sums of ``2 radius + 1`` samples along ``axis`` of the 2-d ``x`` (edges: repeated,
    or periodic with ``wrap``), by cumulative sums; float32."""
    pad = [(0, 0), (0, 0)]
    pad[axis] = (radius + 1, radius)
    total = np.cumsum(np.pad(x, pad, mode="wrap" if wrap else "edge"), axis=axis, dtype=np.float32)
    n = x.shape[axis]
    if axis == 0:
        return total[2 * radius + 1:2 * radius + 1 + n] - total[:n]
    return total[:, 2 * radius + 1:2 * radius + 1 + n] - total[:, :n]


def _smooth(field, sigma, wrap):
    """A small 2-d array blurred by a Gaussian of ``sigma`` samples (edges mirrored, or
    periodic with ``wrap``), a separable convolution of radius ``3 sigma``."""
    radius = max(1, int(math.ceil(3 * sigma)))
    taps = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    taps /= taps.sum()
    for axis in (0, 1):
        n = field.shape[axis]
        pad = [(0, 0), (0, 0)]
        pad[axis] = (radius, radius)
        padded = np.pad(field, pad, mode="wrap" if wrap else "symmetric")
        field = sum(t * np.take(padded, np.arange(i, i + n), axis=axis) for i, t in enumerate(taps))
    return field


# ----------------------------------------------------------------------------- checks


def _check_models(models, minimum=1, materials=False):
    """The fitted models as a list, refused in one line where they cannot share an image. With
    ``materials``, all may be :class:`tghop.material.Material` s with the same maps (their joint
    models are then checked)."""
    if not isinstance(models, (list, tuple)):
        raise TGHopError(f"models must be a list of fitted models, got {type(models).__name__}; "
                         "give [model] for one")
    models = list(models)
    if len(models) < minimum:
        raise TGHopError(f"give at least {minimum} fitted model{'s' if minimum > 1 else ''}, got {len(models)}")
    whole = [isinstance(m, Material) for m in models]
    if any(whole):
        if not materials:
            raise TGHopError(f"input {whole.index(True) + 1} is a material; a morph takes texture models")
        if not all(whole):
            raise TGHopError(f"input {whole.index(not whole[0]) + 1} is {'not ' if whole[0] else ''}a material but "
                             f"input 1 is{'' if whole[0] else ' not'}; give all materials or all texture models")
        for m in models:
            check_is_fitted(m, "model_")
        for i, m in enumerate(models[1:], start=2):  # maps matched by their kinds or suffixes (Stone_Normal, Normal)
            refused = maps_refused(m, models[0], f"input {i}", "input 1", given="(Material.fit's maps)",
                                   normal_by="Material's normal; with 'auto', " + NORMAL_BY_NAME)
            if refused:  # as the command line and the server say it (0.61)
                raise TGHopError(refused)
        _check_models([m.model_ for m in models])
        return models
    for m in models:
        check_is_fitted(m, "ichm_")
    first = models[0]
    for i, m in enumerate(models[1:], start=2):
        if m.patch_size != first.patch_size:
            raise TGHopError(f"input {i} has {m.patch_size}x{m.patch_size} patches but input 1 has "
                             f"{first.patch_size}x{first.patch_size}; fit them with the same patch size "
                             "(patch_size, --patch-size)")
        if m.exemplar_shape_[2] != first.exemplar_shape_[2]:
            raise TGHopError(f"input {i} is {'grey' if m.exemplar_shape_[2] == 1 else 'colour'} but input 1 is not; "
                             "give all colour or all greyscale exemplars")
        if m.bands_.band_quantiles_.shape[1] != first.bands_.band_quantiles_.shape[1]:
            raise TGHopError(f"input {i} was fitted with another band_orientations than input 1; refit with the same")
    return models


# ----------------------------------------------------------------------------- public API


@one_blas_thread()  # the same image with any number of threads or concurrent callers
def synthesize_guided(models, guide=None, *, size=None, transition=DEFAULT_TRANSITION, blob=None, rng=None,
                      n_patches=settings.BY_NAME["n_patches"].default, tile=False, overlap=None, tolerance=0.1,
                      detail=0.8, flat_share=0.25, refine=5, match_colours=True, reuse=1.0, pool_per_block=1.5,
                      layout_weight=3.0, layout_refine=3, layout_patch_refine=None, patch_refine=None, patch_stride=2,
                      region=1024, own_shares=1.0, seam_window=9, progress=None, dtype=np.float64, return_stages=False):
    """One image from several fitted models: painted regions, or a remix without a guide.

    Parameters
    ----------
    models : sequence of tghop.TGHop, or of tghop.material.Material
        Fitted, with the same patch size and colour channels; materials with the same maps, in one
        order (matched by :func:`tghop.material_files.map_keys`: ``Stone_NormalGL`` is
        ``Gravel_NormalGL`` and ``gravel_nor_gl_2k``; the result is keyed by the first material's names;
        every map is painted alike: the join follows all of them; a normal map recorded in the other
        convention than the first material's, :attr:`~tghop.material.Material.conventions_`, is flipped to
        the first's with a warning, 0.59). A model given more than
        once (the same object) paints its regions as one synthesis, with no join between them.
    guide : array_like, shape (H, W) or (H, W, C), optional
        One grey level (or colour) per model, the darkest for the first
        (:func:`guide_labels`). None: a remix (``size`` needed) of the models' textures. Of 2 or 4
        channels, grey or RGB with alpha: the alpha dropped with :meth:`tghop.TGHop.fit`'s warnings
        (:func:`tghop.exemplar.drop_alpha`, 0.59), as a guide's file is read.
    size : (int, int), optional
        Output (height, width); default the guide's size. A guide of another size but the
        output's shape (aspect ratios within 2 %) is scaled to it by nearest neighbour, with a
        warning; one of another shape is refused, and so is one whose scaling loses a model's
        region (:class:`tghop.guides.LostRegionError`; :func:`guide_labels`).
    transition : int
        Width in pixels of the band around each painted edge in which the join between two
        regions follows the content (:mod:`tghop.composite`); 0: the join is the painted
        edge itself. At most :data:`MAX_TRANSITION`.
    blob : float, optional
        A remix's region size in pixels (the Gaussian of its random field, :func:`random_labels`: regions
        about 2.3 times as wide); None (0.64): :func:`remix_blob` of the models, 7 times the coarser texture's
        :func:`element_size` within 32-256 px (0.63: 64 px for all). Only without a guide.
    rng : int or numpy.random.Generator, optional
        Same seed, same image (on the same machine).
    n_patches, tile, overlap, tolerance, detail, flat_share, refine, match_colours, reuse, pool_per_block
        As :meth:`tghop.TGHop.synthesize`, for each model's layer (its synthesis over the
        box its region reaches).
    layout_weight, layout_refine, layout_patch_refine, patch_refine, patch_stride, region, own_shares, seam_window
        As :meth:`tghop.TGHop.synthesize`, for each layer. Of materials, ``patch_refine`` refines each layer's
        albedo with its own material's statistics (:meth:`tghop.material.Material.synthesize`; 0.60: 0.59
        refused it above 0, its None refined them already); a material without them is refused above 0.
    progress : callable, optional
        Each layer's stages of :meth:`tghop.TGHop.synthesize` named with the layer's
        number, e.g. "quilting 2/3"; then "join".
    dtype : {numpy.float64, numpy.float32, numpy.uint8}
    return_stages : bool
        Also return each step's image (0.61), as :meth:`tghop.TGHop.synthesize` does.

    Returns
    -------
    ndarray, shape (H, W, C), ``dtype``, in [0, 1] (uint8: 0 to 255)
        For materials a dict ``name -> (H, W, c)`` array as
        :meth:`tghop.material.Material.synthesize` gives, each map of that ``dtype``. Where every
        model in the image has the same two levels (:attr:`tghop.TGHop.exemplar_levels_`), each
        pixel is at one of them, the joins too (0.57).
    stages : dict, only with ``return_stages``
        float32 images in [0, 1] (of materials: dicts of maps, as the result): ``"regions"`` (the labels,
        region ``i`` at ``i / (k - 1)``, (H, W)); each layer's own steps (0.62), ``"layer<i>_<step>"`` for layer
        ``i`` = 1 ... k (the model of region ``i - 1``; a model given twice is one layer) and each step its
        model's synthesis returns (``"guide"``, ``"quilt"``, ``"seams"``, ``"refine"``, ``"patch refine"`` or
        ``"colour"``, ...; not ``"pool"``), in that order, over the box its region reaches, black outside it;
        ``"layers"`` (each region its own model's synthesis, before the join: the hard edges the join removes),
        ``"join"`` (the result; uint8: levels / 255; two-level models': at their levels).
    """
    check_progress(progress)
    models = _check_models(models, 1 if guide is not None else 2, materials=True)
    transition = check_int(transition, "transition", 0, MAX_TRANSITION)
    k = len(models)
    rng = check_rng(rng)
    if guide is None:
        if size is None:
            raise TGHopError("a remix without a guide needs a size")
        size = check_size(size)
        if blob is not None:
            check_number(blob, "blob", positive=True, unit="pixels")
    else:
        if blob is not None:
            raise TGHopError("blob sizes a remix's random regions; a guide paints them: leave blob out")
        size = None if size is None else check_size(size)
        check_not_path(guide, "the guide")
        # RGBA or grey+alpha: the alpha dropped with fit's warnings, as a guide's file is read (0.59)
        labels = guide_labels(drop_alpha(guide, name="the guide", exclude=None, keep=None), k, size=size)
        size = labels.shape
    # The quilt's checks (a size, tile or overlap it refuses) before any work: the random regions and their
    # weights took 45 s at 33554432x2, whose canvas quilting refuses.
    block_count(size, (models[0].model_ if isinstance(models[0], Material) else models[0]).patch_size,
                overlap=overlap, tile=tile)
    if guide is None:
        labels = random_labels(size, k, rng=rng, tile=tile, scale=remix_blob(models) if blob is None else blob)
    flips = convention_flips(models) if isinstance(models[0], Material) else None  # warned of by input (0.59)
    models, labels = _one_region_per_model(models, labels)
    weights = region_weights(labels, len(models), transition, tile=tile)
    return _layered(models, labels, weights, rng=rng, progress=progress, dtype=dtype, flips=flips, n_patches=n_patches,
                    return_stages=return_stages,
                    tile=tile,
                    overlap=overlap, tolerance=tolerance, detail=detail, flat_share=flat_share, refine=refine,
                    match_colours=match_colours, reuse=reuse, pool_per_block=pool_per_block,
                    layout_weight=layout_weight, layout_refine=layout_refine, layout_patch_refine=layout_patch_refine,
                    patch_refine=patch_refine, patch_stride=patch_stride, region=region, own_shares=own_shares,
                    seam_window=seam_window)


@one_blas_thread()  # the same image with any number of threads or concurrent callers
def morph(model_a, model_b, size=(256, 1024), *, rng=None, stations=None,
          n_patches=settings.BY_NAME["n_patches"].default, overlap=None, tolerance=0.1, detail=0.8,
          flat_share=0.25, refine=5, match_colours=True, reuse=1.0, pool_per_block=1.5, layout_weight=3.0,
          layout_refine=3, layout_patch_refine=None, seam_window=9, progress=None, dtype=np.float64,
          return_stages=False):
    """A strip from ``model_a``'s texture on the left to ``model_b``'s on the right.

    Column ``x`` is at ``t = x / (W - 1)`` of the way: a share ``t`` of its pixels are B's
    texture, the others A's, in regions with organic outlines (:func:`morph_labels`); then as
    :func:`synthesize_guided` with that map: each region its own model's synthesis, joined
    along the content (see the module's notes).

    Parameters
    ----------
    model_a, model_b : tghop.TGHop, or tghop.material.Material
        Two texture models, or two materials with the same maps (0.59; as :func:`synthesize_guided` takes
        them: every map morphed alike, the result a dict of maps keyed by A's names).
    size : (int, int)
        (height, width) of the strip.
    stations : optional
        No longer applies (the windows across the width in which the statistics were matched);
        accepted with a :class:`FutureWarning`, and ignored.
    rng, n_patches, overlap, tolerance, detail, flat_share, refine, match_colours, reuse, pool_per_block, seam_window
        As :meth:`tghop.TGHop.synthesize`, for each model's layer (its synthesis over the box its
        regions reach).
    layout_weight, layout_refine, layout_patch_refine
        As :meth:`tghop.TGHop.synthesize`, for each layer.
    progress : callable, optional
        Each layer's stages of :meth:`tghop.TGHop.synthesize` named with the layer's number,
        e.g. "quilting 2/2"; then "join" (as :func:`synthesize_guided`).
    dtype : {numpy.float64, numpy.float32, numpy.uint8}
    return_stages : bool
        Also return each step's image (0.61), as :func:`synthesize_guided` does.

    Returns
    -------
    ndarray, shape (H, W, C), ``dtype``
        At the two models' two levels where both have the same (as :func:`synthesize_guided`); for
        materials a dict ``name -> (H, W, c)`` array, as :func:`synthesize_guided` gives.
    stages : dict, only with ``return_stages``
        As :func:`synthesize_guided`'s: ``"regions"`` (A's at 0, B's at 1), ``"layer1_<step>"`` (A's steps, 0.62)
        and ``"layer2_<step>"`` (B's), ``"layers"`` (each region its own model's synthesis, before the join),
        ``"join"`` (the result).
    """
    check_progress(progress)
    models = _check_models([model_a, model_b], 2, materials=True)  # materials too (0.59)
    h, w = check_size(size)
    if stations is not None:
        warnings.warn(STATIONS_GONE, FutureWarning, stacklevel=3)
    rng = check_rng(rng)
    materials = isinstance(models[0], Material)
    p = int((models[0].model_ if materials else models[0]).patch_size)
    if h < p:  # up to about a blob (MORPH_BLOB patches) the regions are whole columns: A's half, then B's
        raise TGHopError(f"a morph strip must be at least {p} px tall (the models' patch size; a lower one cannot "
                         f"mix the two textures by position), got {h}x{w}; give a height of {p} or more")
    block_count((h, w), p, overlap=overlap, tile=False)  # the quilt's refusals before any work
    labels = morph_labels((h, w), rng=rng, scale=MORPH_BLOB * p)
    flips = convention_flips(models) if materials else None
    models, labels = _one_region_per_model(models, labels)
    weights = region_weights(labels, len(models), DEFAULT_TRANSITION)
    return _layered(models, labels, weights, rng=rng, progress=progress, dtype=dtype, tile=False, flips=flips,
                    n_patches=n_patches, return_stages=return_stages,
                    overlap=overlap, tolerance=tolerance, detail=detail, flat_share=flat_share, refine=refine,
                    match_colours=match_colours, reuse=reuse, pool_per_block=pool_per_block,
                    layout_weight=layout_weight, layout_refine=layout_refine, layout_patch_refine=layout_patch_refine,
                    patch_refine=None, patch_stride=2, region=1024, own_shares=1.0, seam_window=seam_window)


def morph_labels(size, *, rng=None, scale=MORPH_BLOB * 32) -> np.ndarray:
    """A morph's regions: 0 (A) and 1 (B), where a smooth random field (a Gaussian of ``scale``
    pixels) is above a threshold that falls across the width: at column ``x``, ``t = x / (W - 1)``
    of the way, the field's ``1 - t`` quantile over the columns within ``scale / 2`` of it. Islands
    smaller than :data:`MORPH_ISLAND` blob areas are given to the region around them, and the
    thresholds drawn once more with the share each window lost or gained that way added back. So the
    share of B follows ``t`` (at 256x1024 and 24 px blobs, 0.013 from it on average over 64 columns,
    0.027 in a column), the first column is all A and the last all B, and the outlines are the
    field's smooth level lines, with no specks; (H, W) int64.

    Parameters
    ----------
    size : int or (int, int)
        (height, width); ``n`` means ``(n, n)``. The share follows ``t`` in strips taller than a
        blob; in lower ones the regions are whole columns, A's half then B's (:func:`morph` refuses
        strips lower than a patch).
    rng : int or numpy.random.Generator, optional
        Same seed, same regions.
    scale : float
        Size of the blobs in pixels (positive); the field is drawn on a grid of ``scale // 4``
        pixels, smoothed and interpolated linearly up to ``size``.

    Returns
    -------
    ndarray, shape (height, width)
        0 where A's texture goes, 1 where B's.
    """
    from scipy import ndimage

    h, w = check_size(size)
    check_number(scale, "scale", positive=True, unit="pixels")
    rng = check_rng(rng)
    cell = max(1, int(scale) // 4)
    field = _smooth(rng.standard_normal((-(-h // cell), -(-w // cell))), scale / cell, False).astype(np.float32)
    field = _upsample(_upsample(field, cell, h, 0), cell, w, 1)  # float32: a large strip's field at half the memory
    t = np.linspace(0.0, 1.0, w) if w > 1 else np.zeros(1)
    smallest = MORPH_ISLAND * min(scale, h / 4) ** 2  # in a low strip, specks by its height
    share = t
    for again in (True, False):
        labels = _ranked_columns(field, t, share, scale, cell)
        _drop_islands(labels, smallest)
        if again:  # the share the islands took away (or added) in each window, asked for again
            window = 2 * int(scale) + 1
            got = ndimage.uniform_filter1d(labels.mean(axis=0), window, mode="nearest")
            share = np.clip(share + ndimage.uniform_filter1d(t, window, mode="nearest") - got, 0.0, 1.0)
    return labels


def _ranked_columns(field, t, share, scale, cell):
    """B (1) where ``field`` is above each column's threshold: the ``1 - share`` quantile of the
    columns within ``scale / 2``, taken every ``cell`` columns and interpolated between (one
    column's quantiles jump where its few blobs leave gaps between their values: straight vertical
    edges and slivers); the columns at ``t`` 0 all A, at 1 all B."""
    w = field.shape[1]
    radius = max(1, int(scale) // 2)
    at = np.arange(1, w - 1, cell)
    threshold = np.zeros(w)
    if at.size:
        levels = [np.quantile(field[:, max(0, x - radius):x + radius + 1], 1.0 - share[x]) for x in at]
        threshold = np.interp(np.arange(w), at, levels)
    threshold[t == 0.0] = np.inf
    threshold[t == 1.0] = -np.inf
    return (field > threshold[None, :]).astype(np.int64)


def _drop_islands(labels, smallest):
    """Give each region (4-connected) of fewer than ``smallest`` pixels to the other label, in
    ``labels`` (0/1): B's first, then A's; A's regions in the first column and B's in the last stay."""
    from scipy import ndimage

    for value, edge in ((1, -1), (0, 0)):
        parts, _ = ndimage.label(labels == value)
        small = np.bincount(parts.ravel()) < smallest
        small[0] = False  # the other label's pixels
        small[parts[:, edge]] = False
        labels[small[parts]] = 1 - value


def _upsample(field, cell, n, axis, wrap=False):
    """``field`` sampled on a grid of ``cell`` pixels, linearly interpolated to ``n`` pixels
    along ``axis`` (pixel centres; ends held). ``wrap``: the grid's samples span the ``n`` pixels
    whatever ``cell``, periodic (the last sample's neighbour the first), so the result tiles."""
    m = field.shape[axis]
    if wrap:
        pos = ((np.arange(n) + 0.5) * (m / n) - 0.5) % m
        lo = np.floor(pos).astype(np.int64) % m
        hi = (lo + 1) % m
    else:
        pos = np.clip((np.arange(n) + 0.5) / cell - 0.5, 0.0, m - 1)
        lo = np.floor(pos).astype(np.int64)
        hi = np.minimum(lo + 1, m - 1)
    shape = [1, 1]
    shape[axis] = n
    frac = (pos - lo).astype(field.dtype).reshape(shape)
    out = np.take(field, lo, axis=axis)
    out *= 1 - frac
    out += np.take(field, hi, axis=axis) * frac
    return out


# ----------------------------------------------------------------------------- the pipeline


def _one_region_per_model(models, labels):
    """``(models, labels)`` with the regions of a model given more than once (the same object) made
    one: one layer for them, so that no join shows where they meet (two syntheses of one regular
    texture do not line up)."""
    first = {}
    index = np.array([first.setdefault(id(m), len(first)) for m in models])
    if len(first) == len(models):
        return models, labels
    return [models[index.tolist().index(j)] for j in range(len(first))], index[labels]


def _layered(models, labels, weights, *, rng, progress, dtype, tile, flips=None, return_stages=False, **generation):
    """Painted regions: each model's own synthesis over the box its region reaches (a layer),
    joined by :func:`tghop.composite.cut_regions`; (H, W, C) ``dtype``. ``flips``: materials' normal maps
    made the first's convention (:func:`tghop.normals.convention_flips`). ``return_stages``: also the
    steps' images (:func:`synthesize_guided`'s)."""
    dtype = check_dtype(dtype, (np.float64, np.float32, np.uint8), "float64, float32 or uint8")
    checked = settings.check_settings(dict(generation, tile=tile))  # refused before any layer is made
    materials = isinstance(models[0], Material)
    for i, model in enumerate(models, start=1):  # a material's: its albedo's, each layer refined by its own (0.60)
        if checked["patch_refine"] and getattr(model, "patches_", None) is None:
            whose = "the albedo's patch statistics" if materials else "the patch statistics"
            old = "by tghop 0.58 or older" if materials else "by tghop 0.14 or older"
            raise TGHopError(f"patch_refine={checked['patch_refine']} needs {whose} input {i} lacks (fitted with "
                             f"patch_levels=0, or {old}); fit it again, or leave patch_refine at None or 0")
    k = len(models)
    boxes = layer_boxes(weights, tile=tile)
    # Each layer's pixels of its own region go to the image as it is made; only the part the join
    # reads is kept (one layer in memory at a time besides the bands).
    band = in_band(weights)
    keep = band_boxes(weights, tile=tile, band=band)
    image, kept, layer_steps = None, [], {}
    dtype_layers = np.float64 if dtype == np.float64 else np.float32
    for i, (model, (rows, cols), near) in enumerate(zip(models, boxes, keep), start=1):
        layer_rng = np.random.default_rng(rng.integers(0, 2**63 - 1))
        if rows.stop == rows.start:  # no pixel of this model (a remix too small for every class)
            kept.append(None)
            continue
        staged = None if progress is None else \
            (lambda stage, done, total, i=i: report(progress, f"{stage} {i}/{k}", done, total))
        # float for an 8-bit image too, rounded once at the end: the joins' means are those of a deeper image
        layer = model.synthesize((rows.stop - rows.start, cols.stop - cols.start), rng=layer_rng,
                                 tile=wraps((rows, cols), labels.shape, tile), progress=staged, dtype=dtype_layers,
                                 return_stages=return_stages, **generation)
        if return_stages:  # the layer's own steps (0.62), on the image's canvas (the same draws: only copies kept)
            layer, steps = layer
            layer_steps.update(_layer_steps(i, steps, labels.shape, (rows, cols), (flips or {}).get(id(model), ())))
        if materials:  # the maps stacked: the join follows them all and is the same in every map
            for name in (flips or {}).get(id(model), ()):  # in the first's convention (0.59)
                layer[name] = flip_green(layer[name])
            layer = np.concatenate(list(layer.values()), axis=2)
        if image is None:
            image = np.empty(labels.shape + layer.shape[2:], dtype=layer.dtype)
        np.copyto(image[rows, cols], layer, where=(labels[rows, cols] == i - 1)[..., None])
        inside = (slice(near[0].start - rows.start, near[0].stop - rows.start),
                  slice(near[1].start - cols.start, near[1].stop - cols.start))
        kept.append(layer[inside].copy() if near[0].stop > near[0].start else layer[:0, :0].copy())
        del layer
    levels = None if materials else _shared_levels([m for m, layer in zip(models, kept) if layer is not None])
    kept = [np.zeros((0, 0) + image.shape[2:], image.dtype) if layer is None else layer for layer in kept]
    stages = {"regions": (labels / max(k - 1, 1)).astype(np.float32), **layer_steps,
              "layers": image.astype(np.float32)} if return_stages else None
    report(progress, "join", 0, 1)
    shows = cut_regions(labels, weights, kept, keep, tile=tile, band=band)
    image = join_layers(shows, kept, keep, tile=tile, out=image)
    report(progress, "join", 1, 1)
    if materials:
        first = models[0]
        maps = {name: image[..., part] for name, part in zip(first.names_, first.map_slices())}
        for name, normal in zip(first.names_, first.normal_):
            if normal:  # the join's means of unit vectors, unit again
                maps[name] = renormalise(maps[name]).astype(image.dtype, copy=False)
        for i, name in enumerate(first.names_):  # a mask map of every material: the join's means at their levels
            levels = [model.levels_[i] for model in models]
            if all(lv is not None for lv in levels):
                maps[name] = snap_to_levels(maps[name], np.unique(np.concatenate(levels), axis=0))
                continue
            per = [_channel_levels(model, i) for model in models]  # a channel that is a mask in every material
            joint = [None if any(p[c] is None for p in per) else np.unique(np.concatenate([p[c] for p in per]))
                     for c in range(len(per[0]))]
            if any(lv is not None for lv in joint):
                maps[name] = snap_channels(maps[name], joint)
        out = {name: _as_dtype(m, dtype) for name, m in maps.items()}
    else:
        if levels is not None:  # the join's means of two-level layers, at their levels
            snap_to_levels(image, levels, out=image)
        out = _as_dtype(image, dtype, scratch=not return_stages)
    if not return_stages:
        return out
    as_float = (lambda a: a / np.float32(255) if a.dtype == np.uint8 else a.astype(np.float32))
    stages["join"] = {n: as_float(m) for n, m in out.items()} if materials else as_float(out)
    if materials:  # the layers cut into the first material's maps, as the result
        stages["layers"] = {n: stages["layers"][..., part] for n, part in zip(models[0].names_, models[0].map_slices())}
    return out, stages


def _layer_steps(i, steps, shape, box, flipped):
    """Layer ``i``'s steps (its model's ``synthesize(return_stages=True)``'s, over its ``box`` of the image) as
    ``layer<i>_<step>`` images of the image's ``shape``, black outside the box (so that they lie over the image
    and its regions), in the model's order; not its patch pool (patches, no picture). A material's: dicts of maps,
    the normal maps of ``flipped`` in the first material's convention, as its layer is joined."""
    rows, cols = box

    def placed(step):
        canvas = np.zeros(shape + step.shape[2:], np.float32)
        canvas[rows, cols] = step
        return canvas

    out = {}
    for name, step in steps.items():
        if name == "pool":
            continue
        out[f"layer{i}_{name}"] = ({m: placed(flip_green(v) if m in flipped else v) for m, v in step.items()}
                                   if isinstance(step, dict) else placed(step))
    return out


def _shared_levels(models):
    """The two levels (:attr:`tghop.TGHop.exemplar_levels_`) every one of ``models`` (those in the
    image) has, or None: where one has none or other levels, the join is left as it is (0.57; each
    layer is at its own model's levels already, :meth:`tghop.TGHop.synthesize`)."""
    levels = [getattr(m, "exemplar_levels_", None) for m in models]
    if not levels or any(lv is None or not np.array_equal(lv, levels[0]) for lv in levels):
        return None
    return levels[0]


def _channel_levels(material, i):
    """Each channel's mask levels of a material's map ``i`` (:mod:`tghop.masks`): its pixels' levels
    column by column, or its channels' own (an ORM's metalness), None for a channel of more values."""
    if material.levels_[i] is not None:
        return [np.unique(column) for column in material.levels_[i].T]
    return material.channel_levels_[i] or [None] * material.map_channels_[i]


def _as_dtype(image, dtype, scratch=False):
    """A float image in [0, 1] as a contiguous array of ``dtype`` (uint8: rounded to 0-255; with
    ``scratch``, in ``image`` itself on the way)."""
    if dtype == np.uint8:
        if not scratch:
            return np.round(image * np.float32(255.0)).astype(np.uint8)
        image *= np.float32(255.0)
        return np.round(image, out=image).astype(np.uint8)
    return np.ascontiguousarray(image, dtype=dtype)


def element_size(model) -> float:
    """The size of a texture's elements in pixels, as its model's band statistics see it (0.64).

    The energy of each Laplacian band of the exemplar (:attr:`tghop.TGHop.bands_`: the variance of its
    stored quantiles, over orientations and colour axes; band ``k`` holds wavelengths of about ``3 * 2**k``
    pixels), with the coarse layout model's coarser bands (its band ``k`` at ``factor`` times that, where it
    has one), gives each wavelength a weight; the size is the weighted geometric mean of the wavelengths.
    Fine grain (grass, denim) measures 6-8 px, spots and stones (leopard, beach gravel) about 22 px.
    Textures whose energy is in fine detail on large elements (a brick wall's rough faces and mortar lines)
    measure fine.

    Parameters
    ----------
    model : tghop.TGHop or tghop.material.Material
        Fitted (a material: its albedo's model).

    Returns
    -------
    float
        Pixels of the model's output (its working ``scale`` applied).
    """
    model = model.model_ if isinstance(model, Material) else model
    check_is_fitted(model, "bands_")

    def energies(bands):
        q = np.asarray(bands.band_quantiles_, dtype=np.float64)
        return q.var(axis=-1).sum(axis=(1, 2))

    energy = list(energies(model.bands_))
    wavelength = [3.0 * 2 ** k for k in range(len(energy))]
    layout = getattr(model, "layout_", None)
    if layout is not None and wavelength:
        for k, e in enumerate(energies(layout.model_.bands_)):
            if layout.factor * 3.0 * 2 ** k > 1.2 * wavelength[-1]:  # only where the fine bands end
                energy.append(e)
                wavelength.append(layout.factor * 3.0 * 2 ** k)
    energy = np.asarray(energy)
    if energy.sum() <= 0:  # a flat exemplar
        return float(wavelength[0]) if wavelength else 3.0
    return float(np.exp(np.sum(energy * np.log(wavelength)) / energy.sum()))


def remix_blob(models) -> float:
    """A remix's blob size in pixels for ``models`` (0.64): :data:`REMIX_BLOB` times the largest
    :func:`element_size` among them, within :data:`REMIX_BLOB_RANGE` (0.63: 64 px whatever the textures:
    a remix of two fine ones in huge blobs, of coarse ones in blobs hardly larger than a stone)."""
    lo, hi = REMIX_BLOB_RANGE
    return float(np.clip(REMIX_BLOB * max(element_size(m) for m in models), lo, hi))


def random_labels(size, n_models, *, rng=None, scale=_BLOB, tile=False) -> np.ndarray:
    """Random regions for a remix: a smooth random field (Gaussian of ``scale`` pixels)
    cut at its quantiles into ``n_models`` classes of equal area; (H, W) int64. Regions smaller
    than :data:`REMIX_ISLAND` blob areas (``scale`` squared), but each class's largest, are given to
    the class around them (0.63).

    Parameters
    ----------
    size : int or (int, int)
        Output (height, width); ``n`` means ``(n, n)``.
    n_models : int
        Number of classes (at least 1).
    rng : int or numpy.random.Generator, optional
        Same seed, same regions.
    scale : float
        Size of the blobs in pixels (positive); the field is drawn on a grid of ``scale // 4``
        pixels, smoothed and interpolated linearly up to ``size`` (0.62: each sample repeated over its
        cell, outlines of cell-sized steps).
    tile : bool
        Make the field periodic, so that the regions tile (and a region across an edge is one).

    Returns
    -------
    ndarray of int64, shape (H, W)
        Each pixel's class in ``[0, n_models)``, the classes of about equal area.
    """
    h, w = check_size(size)
    n_models = check_int(n_models, "n_models", 1)
    check_number(scale, "scale", positive=True, unit="pixels")
    rng = check_rng(rng)
    cell = max(1, int(scale) // 4)
    small = (max(1, -(-h // cell)), max(1, -(-w // cell)))
    field = _smooth(rng.standard_normal(small), scale / cell, tile).astype(np.float32)
    # Interpolated linearly, as a morph's (0.63): each grid sample repeated over its cell (0.62) made the
    # outlines a staircase of cell-sized steps, which the join straightened into long horizontal and
    # vertical edges.
    field = _upsample(_upsample(field, cell, h, 0, tile), cell, w, 1, tile)
    cuts = np.quantile(field, np.linspace(0.0, 1.0, n_models + 1)[1:-1])
    labels = np.searchsorted(cuts, field).astype(np.int64)
    _merge_islands(labels, n_models, REMIX_ISLAND * scale ** 2, tile)
    return labels


def _merge_islands(labels, k, smallest, tile):
    """Give each region of ``labels`` (classes ``0 ... k - 1``; 4-connected, across the edges with
    ``tile``) of fewer than ``smallest`` pixels, but its class's largest, to the class most of the pixels
    around it have, in place."""
    from scipy import ndimage
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    cross = ndimage.generate_binary_structure(2, 1)
    for value in range(k):
        parts, n = ndimage.label(labels == value)
        if n < 2:
            continue
        if tile:  # parts that meet across an edge are one region
            a = np.concatenate([parts[:, 0], parts[0, :]])
            b = np.concatenate([parts[:, -1], parts[-1, :]])
            both = (a > 0) & (b > 0)
            graph = coo_matrix((np.ones(int(both.sum())), (a[both], b[both])), shape=(n + 1, n + 1))
            group = connected_components(graph, directed=False)[1]
            group = np.where(np.arange(n + 1) == 0, 0, group - (group > group[0]) + 1)  # the others' pixels 0
            parts = group[parts]
        sizes = np.bincount(parts.ravel())
        sizes[0] = 0
        small = sizes < smallest
        small[0] = False
        small[sizes.argmax()] = False
        if not small.any():
            continue
        ids = (np.cumsum(small) * small).astype(np.int32)[parts]  # 1, 2, ... on each small region, else 0
        around = ndimage.maximum_filter(ids, footprint=cross, mode="wrap" if tile else "nearest")
        ring = (around > 0) & (ids == 0)
        votes = np.bincount(around[ring].astype(np.int64) * k + labels[ring], minlength=(int(small.sum()) + 1) * k)
        best = votes.reshape(-1, k).argmax(axis=1)
        island = ids > 0
        labels[island] = best[ids[island]]
