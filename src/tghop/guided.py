"""Several TGHop models in one image: painted regions, a remix, a morph (ours).

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
   of about 150 px).
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
1. **Weights.** ``W_k(x)``: a linear ramp across the width.
2. **Quilting** from the union of the models' pools (``n_patches`` shared out by area,
   at least a quarter each, grown with the blocks as :meth:`tghop.TGHop.synthesize` grows
   its pool). Each block draws the model whose patches it takes, with probabilities
   ``W_k`` at its centre, through a smooth random field made uniform by its ranks in each
   column of blocks (the models come in blobs of a few blocks, each column in its
   proportions); the other models' patches cost :data:`MIXED_COST` per overlap value more
   (:func:`tghop.quilting.quilt_prepared`'s ``group_cost``; more than any overlap error, so
   each block takes its drawn model's patches), and the boundary cuts join the models along
   the content. The quilt tells which model's patch each pixel shows (``group_map``): its
   *owner*, blurred by a box of :data:`OWNER_BLUR` pixels (``o_k``). The coarse layout
   guide is each model's own blended by ``W``.
3. **Refinement by stations.** A *station* is a weight map ``w_s`` (the stations'
   weights sum to 1 at every pixel; hat functions at evenly spaced ``t`` across the
   width). Each round, every station's bounding box is refined once per model that owns
   pixels there as :func:`tghop.refine.refine` does (the model's decorrelated colour
   space, Laplacian bands and oriented parts given its quantiles, then the pixels),
   except that each monotone map is estimated from the pixels the model owns where the
   station dominates (``w_s >= 0.5``) and applied to the whole box; the image becomes
   ``sum_s w_s sum_k o_k refined_sk``. The colours likewise (each model's colour
   quantiles, RGB). So each region keeps its own model's statistics and colours, and the
   columns go from A to B by the share of each model's regions. (Up to 0.54 every station
   mixed both models' maps over all its pixels, ``(1 - t, t)``, the interpolated
   quantiles: both textures in the middle were greyed into a colour of neither.)

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

import numpy as np

from . import settings
from ._arrays import check_dtype, check_int, check_number
from ._common import (TGHopError, check_is_fitted, check_rng, check_size, in_thread, one_blas_thread, report,
                      usable_cores)
from .composite import band_boxes, cut_regions, in_band, join_layers, layer_boxes, wraps
from .guides import guide_labels
from .layout import follows_guide
from .material import Material, renormalise
from .oriented import iter_oriented_parts
from .pool import MAX_GROWN_POOL, on_demand
from .quilting import GUIDE_SCALE, block_count, prepare_pool, quilt_prepared
from .pyramid import downsample, laplacian_pyramid, reconstruct
from .quantiles import tailed_band_quantiles
from .refine import prepare as prepare_refinement
from .seams import remove_seams

__all__ = ["synthesize_guided", "morph", "guide_labels", "region_weights", "random_labels", "DEFAULT_TRANSITION",
           "MAX_TRANSITION", "REGION_COST", "MIXED_COST"]

#: Default width in pixels of the band around a painted edge where the join follows the textures.
DEFAULT_TRANSITION = 32
#: The widest band (the command line's ``--transition`` range): wider took memory for nothing.
MAX_TRANSITION = 4096
#: The morph's quilting: extra error per overlap value (a squared difference, in [0, 1]
#: units) of a patch of a model other than the one a block drew where that model has all the
#: weight: more than any overlap error (at most 1 per value).
REGION_COST = 1.0
#: The same in blocks where several models have a share. Strict as :data:`REGION_COST` (it was
#: 0.003, a preference): the smoother model's patches fit the overlaps better and took most of
#: the middle (grass to bark: grass up to three quarters of the width), so the share of each
#: model's pixels now follows the ramp (each block its drawn model, in blobs).
MIXED_COST = 1.0
#: Length scale in pixels of the random regions of a remix.
_BLOB = 64
#: Values ranked to estimate each monotone map of the refinement.
_SAMPLES = 1 << 14
#: Fewer pixels of a model than this where a station dominates: its maps are estimated from the
#: model's pixels over the station's whole box.
_FEW_SAMPLES = 256
#: The morph's share of each model in a pixel: which model's patch the quilt shows there (the
#: boundary cuts decide), blurred by a box of this many pixels (antialiased where they meet).
OWNER_BLUR = 3
#: Images from this many pixels on are refined a station per thread.
_THREADED_PIXELS = 512 * 512
#: Entries of the lookup table that applies a monotone map.
_TABLE = 4096


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
        for i, m in enumerate(models[1:], start=2):
            if (m.names_, m.map_channels_, m.normal_) != (models[0].names_, models[0].map_channels_, models[0].normal_):
                raise TGHopError(f"input {i}'s maps are {', '.join(m.names_)} but input 1's are "
                                 f"{', '.join(models[0].names_)} (or their channels differ); give materials with the "
                                 "same maps")
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
def synthesize_guided(models, guide=None, *, size=None, transition=DEFAULT_TRANSITION, rng=None,
                      n_patches=settings.BY_NAME["n_patches"].default, tile=False, overlap=None, tolerance=0.1,
                      detail=0.8, flat_share=0.25, refine=5, match_colours=True, reuse=1.0, pool_per_block=1.5,
                      layout_weight=3.0, layout_refine=3, layout_patch_refine=None, patch_refine=None, patch_stride=2,
                      region=1024, own_shares=1.0, seam_window=9, progress=None, dtype=np.float64):
    """One image from several fitted models: painted regions, or a remix without a guide.

    Parameters
    ----------
    models : sequence of tghop.TGHop, or of tghop.material.Material
        Fitted, with the same patch size and colour channels; materials with the same maps
        (every map is painted alike: the join follows all of them). A model given more than
        once (the same object) paints its regions as one synthesis, with no join between them.
    guide : array_like, shape (H, W) or (H, W, C), optional
        One grey level (or colour) per model, the darkest for the first
        (:func:`guide_labels`). None: a remix (``size`` needed) of the models' textures.
    size : (int, int), optional
        Output (height, width); default the guide's size. A guide of another size but the
        output's shape (aspect ratios within 2 %) is scaled to it by nearest neighbour, with a
        warning; one of another shape is refused (:func:`guide_labels`).
    transition : int
        Width in pixels of the band around each painted edge in which the join between two
        regions follows the content (:mod:`tghop.composite`); 0: the join is the painted
        edge itself. At most :data:`MAX_TRANSITION`.
    rng : int or numpy.random.Generator, optional
        Same seed, same image (on the same machine).
    n_patches, tile, overlap, tolerance, detail, flat_share, refine, match_colours, reuse, pool_per_block
        As :meth:`tghop.TGHop.synthesize`, for each model's layer (its synthesis over the
        box its region reaches).
    layout_weight, layout_refine, layout_patch_refine, patch_refine, patch_stride, region, own_shares, seam_window
        As :meth:`tghop.TGHop.synthesize`, for each layer.
    progress : callable, optional
        Each layer's stages of :meth:`tghop.TGHop.synthesize` named with the layer's
        number, e.g. "quilting 2/3"; then "join".
    dtype : {numpy.float64, numpy.float32, numpy.uint8}

    Returns
    -------
    ndarray, shape (H, W, C), ``dtype``, in [0, 1] (uint8: 0 to 255)
        For materials a dict ``name -> (H, W, c)`` array as
        :meth:`tghop.material.Material.synthesize` gives, each map of that ``dtype``.
    """
    models = _check_models(models, 1 if guide is not None else 2, materials=True)
    transition = check_int(transition, "transition", 0, MAX_TRANSITION)
    k = len(models)
    rng = check_rng(rng)
    if guide is None:
        if size is None:
            raise TGHopError("a remix without a guide needs a size")
        size = check_size(size)
    else:
        size = None if size is None else check_size(size)
        labels = guide_labels(guide, k, size=size)
        size = labels.shape
    # The quilt's checks (a size, tile or overlap it refuses) before any work: the random regions and their
    # weights took 45 s at 33554432x2, whose canvas quilting refuses.
    block_count(size, (models[0].model_ if isinstance(models[0], Material) else models[0]).patch_size,
                overlap=overlap, tile=tile)
    if guide is None:
        labels = random_labels(size, k, rng=rng, tile=tile)
    models, labels = _one_region_per_model(models, labels)
    weights = region_weights(labels, len(models), transition, tile=tile)
    return _layered(models, labels, weights, rng=rng, progress=progress, dtype=dtype, n_patches=n_patches, tile=tile,
                    overlap=overlap, tolerance=tolerance, detail=detail, flat_share=flat_share, refine=refine,
                    match_colours=match_colours, reuse=reuse, pool_per_block=pool_per_block,
                    layout_weight=layout_weight, layout_refine=layout_refine, layout_patch_refine=layout_patch_refine,
                    patch_refine=patch_refine, patch_stride=patch_stride, region=region, own_shares=own_shares,
                    seam_window=seam_window)


@one_blas_thread()  # the same image with any number of threads or concurrent callers
def morph(model_a, model_b, size=(256, 1024), *, rng=None, stations=None,
          n_patches=settings.BY_NAME["n_patches"].default, overlap=None, tolerance=0.1, detail=0.8,
          flat_share=0.25, refine=5, match_colours=True, reuse=1.0, pool_per_block=1.5, layout_weight=3.0,
          layout_refine=3, layout_patch_refine=None, seam_window=9, progress=None, dtype=np.float64):
    """A strip from ``model_a``'s texture on the left to ``model_b``'s on the right.

    Column ``x`` is at ``t = x / (W - 1)`` of the way: a share ``t`` of its blocks take B's
    patches, the others A's (in blobs of a few blocks), and each region is refined to its
    own model's band, pixel and colour statistics, estimated locally (``stations`` evenly
    spaced stations with hat-function weights, see the module's notes).

    Parameters
    ----------
    model_a, model_b : tghop.TGHop
    size : (int, int)
        (height, width) of the strip.
    stations : int, optional
        Windows across the width in which each model's statistics are matched (at least 2);
        default one per 128 columns, at least 3.
    rng, n_patches, overlap, tolerance, detail, flat_share, refine, match_colours, reuse, pool_per_block, seam_window
        As :meth:`tghop.TGHop.synthesize`; ``n_patches`` is shared out between the models in
        proportion to their areas (each at least a quarter of it), ``pool_per_block`` counts
        each model's share of the blocks, ``flat_share`` is taken of each model's pool.
    layout_weight, layout_refine, layout_patch_refine
        As :meth:`tghop.TGHop.synthesize`. The coarse layout guide is each model's blended by
        the ramp; off unless both models have a coarse layout.
    progress : callable, optional
        Stages "layout" (with the coarse guides: their steps, done of 1000), "patch pool", "quilting",
        "seams" (with ``seam_window``), "refine", "colour".
    dtype : {numpy.float64, numpy.float32, numpy.uint8}

    Returns
    -------
    ndarray, shape (H, W, C), ``dtype``
    """
    models = _check_models([model_a, model_b], 2)
    h, w = check_size(size)
    n = max(3, int(math.ceil(w / 128)) + 1) if stations is None else check_int(stations, "stations", 2)
    t = np.linspace(0.0, 1.0, w) if w > 1 else np.zeros(1)
    centres = np.linspace(0.0, 1.0, n)
    ramp = np.broadcast_to(np.stack([1.0 - t, t]).astype(np.float32)[:, None, :], (2, h, w))
    return _synthesize(models, (h, w), _hat_stations(h, t, centres), ramp, rng=rng, n_patches=n_patches,
                       tile=False, overlap=overlap, tolerance=tolerance, detail=detail, flat_share=flat_share,
                       refine=refine, match_colours=match_colours, reuse=reuse, pool_per_block=pool_per_block,
                       layout_weight=layout_weight, layout_refine=layout_refine,
                       layout_patch_refine=layout_patch_refine, seam_window=seam_window,
                       progress=progress, dtype=dtype)


def _hat_stations(h, t, centres):
    """Each station's box and hat weights over it (None where it has none), for :class:`_Stations`:
    the hat of centre ``c`` is ``1 - |t - c| (n - 1)``, clipped to [0, 1] (they sum to 1), the same
    in every row. Only its own columns are computed: an (n, W) table of them took n * W * 12 bytes
    and every station a pass over the whole image (a 64x1048576 strip, 8,193 stations: 100 GB)."""
    n, w = centres.size, t.size
    for c in centres:
        lo, hi = np.searchsorted(t, [c - 1.0 / (n - 1), c + 1.0 / (n - 1)])
        lo, hi = max(int(lo) - 1, 0), min(int(hi) + 1, w)  # a column more each side: the hat is 0 beyond
        hat = np.clip(1.0 - np.abs(t[lo:hi] - c) * (n - 1), 0.0, 1.0).astype(np.float32)
        on = np.flatnonzero(hat > 1e-3)
        if on.size == 0:
            yield None
            continue
        part = hat[on[0]:on[-1] + 1]
        yield ((slice(0, h), slice(lo + int(on[0]), lo + int(on[-1]) + 1)),
               np.ascontiguousarray(np.broadcast_to(part, (h, part.size))))


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


def _layered(models, labels, weights, *, rng, progress, dtype, tile, **generation):
    """Painted regions: each model's own synthesis over the box its region reaches (a layer),
    joined by :func:`tghop.composite.cut_regions`; (H, W, C) ``dtype``."""
    dtype = check_dtype(dtype, (np.float64, np.float32, np.uint8), "float64, float32 or uint8")
    checked = settings.check_settings(dict(generation, tile=tile))  # refused before any layer is made
    materials = isinstance(models[0], Material)
    if materials and checked["patch_refine"]:
        raise TGHopError("patch_refine does not apply to materials (their joint models have no patch statistics); "
                         "leave it at 0 or None")
    for i, model in enumerate(models, start=1):
        if checked["patch_refine"] and getattr(model, "patches_", None) is None:
            raise TGHopError(f"patch_refine={checked['patch_refine']} needs the patch statistics input {i} lacks "
                             "(fitted with patch_levels=0, or by tghop 0.14 or older); fit it again, or leave "
                             "patch_refine at None or 0")
    k = len(models)
    boxes = layer_boxes(weights, tile=tile)
    # Each layer's pixels of its own region go to the image as it is made; only the part the join
    # reads is kept (one layer in memory at a time besides the bands).
    band = in_band(weights)
    keep = band_boxes(weights, tile=tile, band=band)
    image, kept = None, []
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
                                 **generation)
        if materials:  # the maps stacked: the join follows them all and is the same in every map
            layer = np.concatenate(list(layer.values()), axis=2)
        if image is None:
            image = np.empty(labels.shape + layer.shape[2:], dtype=layer.dtype)
        np.copyto(image[rows, cols], layer, where=(labels[rows, cols] == i - 1)[..., None])
        inside = (slice(near[0].start - rows.start, near[0].stop - rows.start),
                  slice(near[1].start - cols.start, near[1].stop - cols.start))
        kept.append(layer[inside].copy() if near[0].stop > near[0].start else layer[:0, :0].copy())
        del layer
    kept = [np.zeros((0, 0) + image.shape[2:], image.dtype) if layer is None else layer for layer in kept]
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
        return {name: _as_dtype(m, dtype) for name, m in maps.items()}
    return _as_dtype(image, dtype, scratch=True)


def _as_dtype(image, dtype, scratch=False):
    """A float image in [0, 1] as a contiguous array of ``dtype`` (uint8: rounded to 0-255; with
    ``scratch``, in ``image`` itself on the way)."""
    if dtype == np.uint8:
        if not scratch:
            return np.round(image * np.float32(255.0)).astype(np.uint8)
        image *= np.float32(255.0)
        return np.round(image, out=image).astype(np.uint8)
    return np.ascontiguousarray(image, dtype=dtype)


def _synthesize(models, size, stations, shares, *, rng, n_patches, tile, overlap, tolerance, detail, flat_share,
                refine, match_colours, reuse, pool_per_block, layout_weight, layout_refine, layout_patch_refine,
                seam_window, progress, dtype):
    """Quilt the union of the models' pools (each block its drawn model's patches, drawn
    from the models' ``shares`` (K, H, W)), refine and colour-match by the ``stations`` (each
    one's box and weights over it, as :func:`_hat_stations` gives them), each pixel by the
    model whose patch it shows."""
    dtype = check_dtype(dtype, (np.float64, np.float32, np.uint8), "float64, float32 or uint8")
    checked = settings.check_settings(dict(n_patches=n_patches, tile=tile, overlap=overlap, tolerance=tolerance,
                                           detail=detail, flat_share=flat_share, match_colours=match_colours,
                                           refine=refine, reuse=reuse, pool_per_block=pool_per_block,
                                           layout_weight=layout_weight, layout_refine=layout_refine,
                                           layout_patch_refine=layout_patch_refine, seam_window=seam_window))
    rng = check_rng(rng)
    k = len(models)
    p = int(models[0].patch_size)
    blocks = block_count(size, p, overlap=overlap, tile=tile)
    area = shares.reshape(k, -1).mean(axis=1)
    # Each model's pool in proportion to its area (the pool of one image shared out), at
    # least a quarter of n_patches (a small region still has choice), grown with the
    # region's blocks as TGHop.synthesize grows its pool.
    n_min = checked["n_patches"]
    counts = [max(int(math.ceil(n_min * max(a, 0.25))),
                  min(MAX_GROWN_POOL, int(math.ceil(checked["pool_per_block"] * blocks * a)))) for a in area]
    guided = bool(checked["layout_weight"]) and all(  # a tileable image too small for a guide goes without
        follows_guide(m.layout_, size, tile=tile) for m in models)
    pending = None
    # The coarse guides are made in a second thread (their own random stream) while the
    # pools are generated and prepared (one BLAS thread, as everything here). Their steps are
    # told as "layout" done of 1000 (from their thread), and this one is silent until it has
    # them (the CLI's bar is of one stage at a time); its start and end in the same units.
    if guided:
        layout_rng = np.random.default_rng(rng.integers(0, 2**63 - 1))
        report(progress, "layout", 0, 1000)
        pending = in_thread(_layout_guide, models, shares, layout_rng, tile, checked["layout_refine"],
                            checked["seam_window"], checked["flat_share"], checked["layout_patch_refine"],
                            progress=progress)
    pool_progress = None if guided else progress
    report(pool_progress, "patch pool", 0, k)
    pool = np.empty((sum(counts), p, p, models[0].exemplar_shape_[2]), dtype=np.float32)
    start = 0
    for i, (model, n) in enumerate(zip(models, counts), start=1):
        pool[start:start + n] = model.sample_patches(n, rng=rng, dtype=np.float32)
        start += n
        report(pool_progress, "patch pool", i, k)
    groups = np.repeat(np.arange(k), counts)
    prepared = prepare_pool(pool, size, overlap=overlap, tile=tile, detail=checked["detail"],
                            guide_scale=GUIDE_SCALE if guided else None, flat_share=checked["flat_share"],
                            groups=groups)
    if checked["refine"]:
        prepare_refinement(size, models[0].bands_)
    guide = None
    if guided:
        guide = pending()
        report(progress, "layout", 1000, 1000)
        report(progress, "patch pool", 0, k)
        report(progress, "patch pool", k, k)
    group_cost = _group_cost(shares, prepared.plan, p, pool.shape[3], rng)
    reuse = 0.0 if on_demand(size, p, len(pool), overlap=overlap, tile=tile) else checked["reuse"]
    shown = np.zeros(size, dtype=np.uint8)  # the model whose patch each pixel shows
    image = quilt_prepared(prepared, tolerance=tolerance, rng=rng, progress=progress, dtype=np.float32, reuse=reuse,
                           guide=guide, guide_weight=checked["layout_weight"], groups=groups, group_cost=group_cost,
                           return_seams=checked["seam_window"] > 0, group_map=shown)
    del prepared, pool
    if checked["seam_window"]:  # (image, steps)
        image = remove_seams(*image, window=checked["seam_window"], out=image[0], progress=progress)
    stations = _Stations(stations, region_weights(shown, k, OWNER_BLUR), models)
    if checked["refine"]:
        image = stations.refine(image, n_iter=checked["refine"], tile=tile, progress=progress)
    if checked["match_colours"]:
        report(progress, "colour", 0, 1)
        image = stations.match_colours(image)
        report(progress, "colour", 1, 1)
    return _as_dtype(np.clip(image, 0.0, 1.0), dtype)


def _layout_guide(models, shares, rng, tile, refine, seam_window, flat_share, patch_refine, progress=None):
    """``sum_k W_k guide_k``: each model's coarse layout guide over the bounding box of its
    share (the whole image with ``tile``), weighted by its share; (H, W, C) float32.
    ``progress("layout", done, 1000)``: the guides' steps, each guide an equal part."""
    k, h, w = shares.shape
    guide = np.zeros((h, w, models[0].exemplar_shape_[2]), dtype=np.float32)
    for i, (model, share) in enumerate(zip(models, shares)):
        box = (slice(0, h), slice(0, w))
        if not tile:
            rows, cols = np.flatnonzero((share > 1e-3).any(axis=1)), np.flatnonzero((share > 1e-3).any(axis=0))
            if rows.size == 0:
                continue
            box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
        part = model.layout_.guide((box[0].stop - box[0].start, box[1].stop - box[1].start), rng=rng, tile=tile,
                                   refine=refine, seam_window=seam_window, flat_share=flat_share,
                                   patch_refine=patch_refine, progress=_one_of(progress, i, k))
        guide[box] += part * share[box][..., None]
    return guide


def _one_of(progress, i, k):
    """``progress`` told the i-th (from 0) of ``k`` equal parts of a stage: each report's ``done`` of
    ``total`` moved into its part (None for None)."""
    if progress is None:
        return None
    return lambda stage, done, total: report(progress, stage, (i * total + done) // k, total)


def random_labels(size, n_models, *, rng=None, scale=_BLOB, tile=False) -> np.ndarray:
    """Random regions for a remix: a smooth random field (Gaussian of ``scale`` pixels)
    cut at its quantiles into ``n_models`` classes of equal area; (H, W) int64.

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
        pixels, smoothed and repeated up to ``size``.
    tile : bool
        Make the field periodic, so that the regions tile.

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
    field = _smooth(rng.standard_normal(small), scale / cell, tile)
    field = np.repeat(np.repeat(field, cell, axis=0), cell, axis=1)[:h, :w]
    cuts = np.quantile(field, np.linspace(0.0, 1.0, n_models + 1)[1:-1])
    return np.searchsorted(cuts, field).astype(np.int64)


def _group_cost(shares, plan, p, c, rng):
    """(ny, nx, K) cost of each model's patches at each block: 0 for the model the block
    draws (probabilities: ``shares`` at its centre), :data:`REGION_COST` per overlap value
    for the others (:data:`MIXED_COST` in blocks where several models have a share). The draw
    thresholds a smooth random field made uniform by its ranks, so that mixed blocks come in blobs."""
    k, h, w = shares.shape
    cy = np.minimum(plan.ys + p // 2, h - 1)
    cx = np.minimum(plan.xs + p // 2, w - 1)
    at = shares[:, cy[:, None], cx[None, :]]  # (K, ny, nx)
    field = _smooth(rng.standard_normal(at.shape[1:]), 1.0, plan.tile)
    # Made uniform by its ranks in each column of blocks: every column draws each model in its share
    # (to within a block), and the blobs of the smooth field hold across the columns.
    u = (np.argsort(np.argsort(field, axis=0), axis=0) + 0.5) / field.shape[0]
    drawn = np.minimum((np.cumsum(at, axis=0) < u[None]).sum(axis=0), k - 1)  # (ny, nx)
    n_values = 2 * p * plan.overlap * c
    mixed = at.max(axis=0) < 1.0 - 1e-6  # blocks in a transition: a preference only
    per_value = np.where(mixed, MIXED_COST, REGION_COST).astype(np.float32)
    cost = np.repeat((per_value * n_values)[..., None], k, axis=2)
    np.put_along_axis(cost, drawn[..., None], 0.0, axis=2)
    return cost


class _Stations:
    """Stations (each one's box and its weights over it, or None) and each model's soft share of
    every pixel (``owners`` (K, H, W), summing to 1: which model's patch the pixel shows).

    Each station is worked on over the bounding box of its weights only; each model's monotone
    maps are estimated from the pixels (of each band level) that the model owns where the station
    dominates, and applied where the model owns the pixels."""

    def __init__(self, stations, owners, models):
        self.owners = np.asarray(owners, dtype=np.float32)
        self.stats = [m.bands_ for m in models]
        # Each model's band quantiles with exponential tails, and their levels (made once).
        self.bands = [tailed_band_quantiles(s.band_quantiles_) for s in self.stats]
        self.colours = [m.colour_quantiles_ for m in models]
        self.n_levels = min(s.band_quantiles_.shape[0] for s in self.stats)
        self.stations = []
        for station in stations:
            if station is None:
                self.stations.append(None)
                continue
            box, wb = station
            per_model = {}
            for k in range(len(models)):
                own = self.owners[k][box]
                if not (own >= 0.5).any():  # no pixel of this model here
                    continue
                samples, level, owned = [], wb, own
                for i in range(self.n_levels + 1):  # each band level's, then (last) the pixels'
                    if i == self.n_levels:
                        level, owned = wb, own
                    elif i:
                        level, owned = downsample(level, mode="reflect"), downsample(owned, mode="reflect")
                    samples.append(_dominant(level, owned))
                per_model[k] = (own, samples)
            self.stations.append((box, wb, per_model))

    def _each(self, image, one):
        """``sum_s w_s sum_k o_k one(k, crop, samples)`` over the stations' boxes (``o_k`` the
        model's share of each pixel, over the models present); (H, W, C) float32."""
        def station_value(s):
            box, wb, per_model = self.stations[s]
            crop = image[box]
            acc = total = None
            for k, (own, samples) in per_model.items():
                value = one(k, crop, samples)
                value *= own[..., None]
                acc = value if acc is None else np.add(acc, value, out=acc)
                total = own.copy() if total is None else np.add(total, own, out=total)
            if len(per_model) < len(self.owners):  # a model owns no pixel here: the others' share it
                acc /= np.maximum(total, np.float32(1e-6))[..., None]
            acc *= wb[..., None]
            return acc

        todo = [s for s, station in enumerate(self.stations) if station is not None]
        out = np.zeros(image.shape, dtype=np.float32)
        workers = min(len(todo), usable_cores(), 4)  # a batch worker's task: one (limit_cores)
        if workers > 1 and image.shape[0] * image.shape[1] >= _THREADED_PIXELS:
            # Stations in threads (NumPy and the FFTs let go of the interpreter lock),
            # added in station order: the same image as one at a time.
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(max_workers=workers) as pool:
                for s, value in zip(todo, pool.map(station_value, todo)):
                    out[self.stations[s][0]] += value
        else:
            for s in todo:
                out[self.stations[s][0]] += station_value(s)
        return out

    def refine(self, image, *, n_iter, tile, progress=None):
        """Band and pixel matching rounds (see the module's notes); (H, W, C) float32."""
        mode = "wrap" if tile else "reflect"
        n_parts = self.stats[0].band_quantiles_.shape[1]
        x = np.asarray(image, dtype=np.float32)

        def one(k, crop, samples):
            stats = self.stats[k]
            band_levels, band_q = self.bands[k]
            dec = _linear(np.moveaxis(crop, 2, 0), stats.colour_basis_, -stats.colour_basis_ @ stats.colour_mean_)
            bands = laplacian_pyramid(dec, self.n_levels, mode=mode, axes=(1, 2))
            for i in range(len(bands) - 1):
                total = None
                for j, part in enumerate(iter_oriented_parts(bands[i], n_parts, axes=(1, 2))):
                    for c in range(part.shape[0]):
                        flat = part[c].reshape(-1)
                        part[c] = _monotone_map(flat, flat[samples[i]], band_q[i, j, c],
                                                band_levels).reshape(part.shape[1:])
                    total = part if total is None else np.add(total, part, out=total)
                bands[i] = total
            dec = reconstruct(bands, mode=mode, axes=(1, 2)).astype(np.float32)
            for c in range(dec.shape[0]):
                flat = dec[c].reshape(-1)
                dec[c] = _monotone_map(flat, flat[samples[-1]], stats.pixel_quantiles_[c]).reshape(dec.shape[1:])
            return np.moveaxis(_linear(dec, stats.colour_basis_.T, stats.colour_mean_), 0, 2)

        report(progress, "refine", 0, n_iter)
        for r in range(1, n_iter + 1):
            x = self._each(x, one)
            np.clip(x, 0.0, 1.0, out=x)
            report(progress, "refine", r, n_iter)
        return x

    def match_colours(self, image):
        """Each station's colours given its models' colour quantiles (RGB), blended."""
        def one(k, crop, samples):
            out = np.empty(crop.shape, dtype=np.float32)
            for c in range(crop.shape[2]):
                flat = np.ascontiguousarray(crop[..., c]).reshape(-1)
                out[..., c] = _monotone_map(flat, flat[samples[-1]], self.colours[k][c]).reshape(crop.shape[:2])
            return out

        return self._each(np.asarray(image, dtype=np.float32), one)


def _linear(x, matrix, offset):
    """``matrix @ x + offset`` over the channels of ``x`` (C, h, w): (C, h, w) float32, a
    channel at a time (NumPy's product of (N, 3) by (3, 3) is slow)."""
    matrix, offset = np.asarray(matrix, dtype=np.float32), np.asarray(offset, dtype=np.float32)
    out = np.empty((matrix.shape[0],) + x.shape[1:], dtype=np.float32)
    tmp = np.empty(x.shape[1:], dtype=np.float32)
    for a in range(matrix.shape[0]):
        np.multiply(x[0], matrix[a, 0], out=out[a])
        for b in range(1, x.shape[0]):
            out[a] += np.multiply(x[b], matrix[a, b], out=tmp)
        out[a] += offset[a]
    return out


def _dominant(weights, owned):
    """Flat indices of at most :data:`_SAMPLES` pixels (evenly strided) that a model owns
    (``owned`` (h, w) at least 0.5) where ``weights`` (h, w) is at least 0.5; where those are
    fewer than :data:`_FEW_SAMPLES`, those it owns where ``weights`` is above zero."""
    mine = owned.ravel() >= 0.5
    where = np.flatnonzero(mine & (weights.ravel() >= 0.5))
    if where.size < _FEW_SAMPLES:
        where = np.flatnonzero(mine & (weights.ravel() > 1e-3))
    if where.size > _SAMPLES:
        where = where[:: int(math.ceil(where.size / _SAMPLES))]
    return where


def _monotone_map(values, sample, target, levels=None):
    """``values`` (1-d float32) through the monotone map that gives ``sample`` (a subset
    of them) the quantiles ``target`` (Q,) at ``levels`` (Q,; default evenly spaced from 0
    to 1): the sample's quantiles at the same levels are mapped to the target's, linearly
    between them (a lookup table of :data:`_TABLE` entries; values beyond the sample's
    range take the end values)."""
    levels = np.linspace(0.0, 1.0, target.shape[0]) if levels is None else levels
    if sample.size == 0:
        return values
    ordered = np.sort(sample)
    src = np.interp(levels * (ordered.size - 1), np.arange(ordered.size), ordered)
    lo, hi = float(src[0]), float(src[-1])
    if not hi > lo:
        return np.full_like(values, float(np.interp(0.5, levels, target)))
    scale = (_TABLE - 1) / (hi - lo)
    table = np.interp(lo + np.arange(_TABLE) / scale, src, target).astype(values.dtype)
    # The nearest entry, round((v - lo) * scale), as v * scale + (0.5 - lo * scale) truncated.
    index = np.multiply(values, np.float32(scale), dtype=np.float32)
    index += np.float32(0.5 - lo * scale)
    np.clip(index, 0, _TABLE - 1, out=index)
    return np.take(table, index.astype(np.int32), mode="clip")
