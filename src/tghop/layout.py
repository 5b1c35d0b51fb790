"""Coarse-to-fine layout: a TGHop model of the exemplar at a coarser scale guides quilting.

32x32 patches cannot hold structures larger than themselves (brick courses, knit cables,
large cells), and quilting alone only matches overlaps, so nothing keeps the arrangement
above the patch scale. :class:`~tghop.synthesis.CoarseLayout` fits a second, small TGHop model on the
exemplar downsampled by ``factor`` (box means): its 32x32 patches then cover
``32 * factor`` exemplar pixels. At generation, :func:`coarse_guide` quilts a coarse
image from that model (new content, not a copy) and upsamples it to the output size; the
fine level is quilted from the fine model's pool *guided* by it
(:func:`tghop.quilting.quilt` with ``guide``: each candidate's overlap error plus the
distance between its low-pass version and the guide there, Efros & Freeman's texture
transfer).

This module holds the layout's plain functions: the scales (:func:`downsample`,
:func:`upsample`), the coarse model's training settings (:func:`coarse_training`) and
the guide made from a fitted coarse model (:func:`coarse_guide`). The coarse model is a
:class:`~tghop.TGHop`, owned by the fine one (:class:`tghop.synthesis.CoarseLayout`), so
this module never builds one.

Example
-------
>>> from tghop import TGHop, data
>>> model = TGHop(layout_factor=2, rng=0).fit(data.bricks())         # doctest: +SKIP
>>> guide = model.layout_.guide((256, 256), rng=1)                    # doctest: +SKIP
"""

from __future__ import annotations

import math

import numpy as np

from ._arrays import check_int
from ._errors import TGHopError
from ._images import check_size, checked_image
from ._progress import report
from ._resources import usable_cores

#: Quilting's detail preference in the coarse guide: 0.5, the fine level's until 0.38. 0.39 raised
#: the fine level's to 0.8, measured with the guide at 0.5 (docs/choices.md, Quilting).
GUIDE_DETAIL = 0.5
#: Pyramid levels of the coarse model's patch statistics (0.48), at most the fine model's: its
#: guide is patch-refined (``layout_patch_refine``). A coarse exemplar is often under 100 px a side.
PATCH_LEVELS = 3
#: The guide's patch refinement by default (``layout_patch_refine`` None, :func:`guide_steps`):
#: GUIDE_STEPS steps per level for images of at most GUIDE_PIXELS pixels, none on larger ones,
#: where it was measured no better at twice the time (docs/choices.md, Coarse-to-fine layout).
GUIDE_STEPS = 20
GUIDE_PIXELS = 512 * 512
#: The guide's patch refinement takes steps GUIDE_RATE times the fine level's at every level (0.49):
#: its 20 steps then do about what 80 of the fine level's size did, at the cost of 20
#: (docs/choices.md, Coarse-to-fine layout, "0.49").
GUIDE_RATE = 8.0

__all__ = ["PATCH_LEVELS", "GUIDE_STEPS", "GUIDE_PIXELS", "GUIDE_RATE", "guide_steps", "downsample", "upsample", "fits",
           "guide_fits", "follows_guide", "usable_factor", "coarse_training", "coarse_guide"]


def downsample(image, factor: int) -> np.ndarray:
    """Box-mean downsampling by an integer ``factor`` (trailing rows/columns dropped).

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Float in [0, 1], or uint8 (0-255).
    factor : int
        At least 1, at most the image's shorter side.

    Returns
    -------
    ndarray, shape (H // factor, W // factor, C)
        float64, or uint8 (rounded box means) for a uint8 image.
    """
    img = checked_image(image, "downsample")
    factor = check_int(factor, "downsample: factor")
    h, w, c = img.shape
    if factor > min(h, w):
        raise TGHopError(f"downsample: factor {factor} is larger than the {h}x{w} image; "
                         f"use at most {max(1, min(h, w))}")
    hs, ws = h // factor, w // factor
    eight_bit = img.dtype == np.uint8
    out = np.empty((hs, ws, c), dtype=np.uint8 if eight_bit else np.float64)
    rows = max(1, (1 << 22) // max(1, factor * ws * factor * c))  # bands of about 4 M values: no whole-image copy
    for y in range(0, hs, rows):
        band = img[y * factor: min(hs, y + rows) * factor, : ws * factor].astype(np.float64)
        mean = band.reshape(-1, factor, ws, factor, c).mean(axis=(1, 3))
        out[y: y + rows] = np.round(mean) if eight_bit else mean
    return out


def upsample(image, factor: int | None, size, *, wrap: bool = False) -> np.ndarray:
    """Bilinear upsampling by ``factor`` (pixel-centre aligned), cropped to ``size``.

    Parameters
    ----------
    image : ndarray, shape (h, w, C)
        Float in [0, 1].
    factor : int or None
        None: each axis by its own ratio ``H / h``, ``W / w`` (no crop): with ``wrap``, one
        period of the image becomes one period of the output (a tileable 256x256 guide
        from an 86x86 coarse image).
    size : int or (int, int)
        Output (H, W), at most ``(h * factor, w * factor)`` (:func:`tghop._images.check_size`).
    wrap : bool
        Treat the image as periodic (for tileable output).

    Returns
    -------
    ndarray, shape (H, W, C), in [0, 1]
        float32 for a float32 image, else float64.
    """
    img = checked_image(image, "upsample")
    if img.dtype.kind != "f":
        raise TGHopError(f"upsample: image must be a float array in [0, 1], got {img.dtype}")
    img = img.astype(np.float32 if img.dtype == np.float32 else np.float64, copy=False)
    h, w = check_size(size, name="upsample: size")
    if factor is not None:
        factor = check_int(factor, "upsample: factor")
        if h > img.shape[0] * factor or w > img.shape[1] * factor:
            raise TGHopError(f"upsample: size {h}x{w} is larger than the {img.shape[0]}x{img.shape[1]} image "
                             f"times factor {factor}")
    elif min(img.shape[:2]) < 1:
        raise TGHopError(f"upsample: the image is empty ({img.shape[0]}x{img.shape[1]} pixels)")
    out = np.empty((h, w, *img.shape[2:]), dtype=img.dtype)

    def rows(start, stop):  # output rows [start, stop)
        part = img
        for axis, index in ((0, np.arange(start, stop)), (1, np.arange(w))):
            # Output sample i sits at input coordinate (i + 0.5) / factor - 0.5 (pixel centres).
            if factor is None:
                pos = (index + 0.5) * (img.shape[axis] / (h, w)[axis]) - 0.5
            else:
                pos = (index + 0.5) / factor - 0.5
            lo = np.floor(pos).astype(np.int64)
            frac = (pos - lo).astype(img.dtype).reshape([-1 if a == axis else 1 for a in range(img.ndim)])
            m = img.shape[axis]
            hi = lo + 1
            lo, hi = (np.mod(lo, m), np.mod(hi, m)) if wrap else (np.clip(lo, 0, m - 1), np.clip(hi, 0, m - 1))
            part = (1.0 - frac) * np.take(part, lo, axis=axis) + frac * np.take(part, hi, axis=axis)
        np.clip(part, 0.0, 1.0, out=out[start:stop])

    # A large guide: the two halves of the rows on two threads (it is made while the
    # other thread waits for it; docs/choices.md).
    if h * w >= 1 << 20 and h > 1 and usable_cores() > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=1) as worker:
            lower = worker.submit(rows, h // 2, h)
            rows(0, h // 2)
            lower.result()  # its error, if any, is raised here
    else:
        rows(0, h)
    return out



def fits(shape, factor, patch_size=32) -> bool:
    """Whether an exemplar of ``shape`` (H, W, ...) is large enough for a coarse layout:
    at least ``(p/2 + 1)**2`` coarse training patches of side ``p`` at stride 1.

    Parameters
    ----------
    shape : tuple of int
        The exemplar's (H, W, ...); only H and W are read.
    factor : int
        The layout factor, at least 2 (else :class:`~tghop.TGHopError`).
    patch_size : int
        The coarse model's patch side ``p``, at least 4.

    Returns
    -------
    bool
        Whether ``min(H, W) // factor >= p + p // 2``.
    """
    f = check_int(factor, "factor", 2)
    p = check_int(patch_size, "patch_size", 4)
    return min(shape[0] // f, shape[1] // f) >= p + p // 2


def coarse_training(shape, factor, *, patch_size=32, n_clusters=50, min_patches=2000, max_patches=4000) -> dict:
    """The coarse model's training settings for an exemplar of ``shape`` (H, W, ...).

    Stride 2 unless that gives fewer than ``min_patches`` training patches (then 1), at
    most ``max_patches`` of them, and at most one cluster per 40 patches (at least 2).

    Parameters
    ----------
    shape : tuple of int
        The exemplar's (H, W, ...), at full resolution.
    factor : int
        The layout factor, at least 2.
    patch_size : int
        The coarse patches' side, at least 4.
    n_clusters : int
        Most clusters (at least 2).
    min_patches : int
        Fewest training patches at stride 2 before stride 1 is used.
    max_patches : int
        Most training patches (at least 100).

    Returns
    -------
    dict
        ``stride``, ``max_patches`` and ``n_clusters`` of the coarse :class:`~tghop.TGHop`.

    Raises
    ------
    TGHopError
        The exemplar is too small for ``factor`` (see :func:`fits`).
    """
    f = check_int(factor, "factor", 2)
    p = check_int(patch_size, "patch_size", 4)
    hs, ws = shape[0] // f, shape[1] // f
    if not fits(shape, f, p):
        raise TGHopError(
            f"a coarse layout at factor {f} needs an exemplar of at least {(p + p // 2) * f}x{(p + p // 2) * f} "
            f"pixels, got {shape[0]}x{shape[1]}; use a smaller layout factor or none"
        )
    count = lambda s: ((hs - p) // s + 1) * ((ws - p) // s + 1)  # noqa: E731
    stride = 2 if count(2) >= min_patches else 1
    n_train = min(count(stride), check_int(max_patches, "max_patches", 100))
    n_clusters = max(2, min(check_int(n_clusters, "n_clusters", 2), n_train // 40))
    return {"stride": stride, "max_patches": n_train, "n_clusters": n_clusters}


def guide_fits(size, factor, patch_size=32, *, tile=False) -> bool:
    """Whether an output of ``size`` (H, W) can have a coarse guide at ``factor``: always,
    unless it is tileable and its coarse image (``ceil(H / factor)`` a side) is smaller
    than a patch, which cannot wrap around (:meth:`tghop.TGHop.synthesize` then quilts
    without the guide).

    Parameters
    ----------
    size : int or (int, int)
        The output's (H, W) (checked as every output size: :class:`~tghop.TGHopError`).
    factor : int
        The layout factor.
    patch_size : int
        The coarse model's patch side.
    tile : bool
        Whether the output is tileable.

    Returns
    -------
    bool
    """
    h, w = check_size(size)
    return not tile or min(math.ceil(h / factor), math.ceil(w / factor)) >= patch_size


def follows_guide(coarse, size, *, tile=False) -> bool:
    """Whether an output of ``size`` gets the guide of ``coarse``: a fitted
    :class:`tghop.synthesis.CoarseLayout`, or None (a model without a layout: never).

    Parameters
    ----------
    coarse : tghop.synthesis.CoarseLayout or None
        Its ``factor`` and ``patch_size`` are read.
    size : int or (int, int)
        The output's (H, W).
    tile : bool
        Whether the output is tileable (:func:`guide_fits`).

    Returns
    -------
    bool
    """
    return coarse is not None and guide_fits(size, coarse.factor, coarse.patch_size, tile=tile)


def usable_factor(shape, factor, *, patch_size=32, exclude=None, **training):
    """The layout factor an exemplar of ``shape`` gets for the setting ``factor``: the
    largest of ``factor``, ``factor - 1``, ..., 2 that it is large enough for (:func:`fits`;
    with ``exclude``, also :func:`fits_excluding`), or None when none is. A 128x128
    exemplar gets 2 from the default 3: a coarser layout than asked beats none.

    Parameters
    ----------
    shape : tuple of int
        The exemplar's (H, W, ...).
    factor : int
        The layout factor asked for, at least 2 (else :class:`~tghop.TGHopError`).
    patch_size : int
        The coarse model's patch side.
    exclude : ndarray of bool, shape (H, W), optional
        Pixels left out of training (True: excluded).
    **training
        ``n_clusters``, ``min_patches``, ``max_patches``, as :func:`coarse_training` takes them.

    Returns
    -------
    int or None
        A factor in ``[2, factor]``.
    """
    f = check_int(factor, "factor", 2)
    for g in range(f, 1, -1):
        if fits(shape, g, patch_size) and fits_excluding(exclude, g, patch_size=patch_size, **training):
            return g
    return None


def fits_excluding(exclude, factor, *, patch_size=32, n_clusters=50, min_patches=2000, max_patches=4000) -> bool:
    """Whether enough coarse training patches avoid ``exclude`` ((H, W) bool or None): at
    least ``min_cluster_size`` per cluster of :func:`coarse_training`."""
    from .patches import downsample_mask, patch_origins
    from .settings import BY_NAME

    if exclude is None:
        return True
    training = coarse_training(exclude.shape + (1,), factor, patch_size=patch_size, n_clusters=n_clusters,
                               min_patches=min_patches, max_patches=max_patches)
    small = downsample_mask(exclude, int(factor))
    n = len(patch_origins(small.shape, int(patch_size), stride=training["stride"], exclude=small))
    return n >= training["n_clusters"] * BY_NAME["min_cluster_size"].default


def guide_steps(n_steps, size) -> int:
    """``layout_patch_refine`` for an image of ``size`` (H, W): ``n_steps``, or for None
    :data:`GUIDE_STEPS` on images of at most :data:`GUIDE_PIXELS` pixels and 0 on larger ones.

    Parameters
    ----------
    n_steps : int or None
        The setting (an int is returned as it is, unchecked).
    size : (int, int)
        The image's (H, W).

    Returns
    -------
    int
    """
    if n_steps is not None:
        return int(n_steps)
    return GUIDE_STEPS if size[0] * size[1] <= GUIDE_PIXELS else 0


#: The coarse image's steps that report their progress, in order: each an equal part of one "layout" stage
#: (:func:`coarse_guide`'s ``progress``).
GUIDE_PARTS = ("quilting", "seams", "refine", "patch refine")


def as_layout_progress(progress, parts=GUIDE_PARTS):
    """``progress`` told the coarse image's steps (``parts``, :data:`GUIDE_PARTS` by default, each an equal
    part of it) as one stage "layout", ``done`` of 1000 (None for None); other stages are not passed on."""
    if progress is None:
        return None

    def inner(stage, done, total):
        if stage in parts:
            share = min(done, total) / total if total > 0 else 0.0
            report(progress, "layout", round(1000 * (parts.index(stage) + share) / len(parts)), 1000)

    return inner


def coarse_guide(model, factor, size, *, rng=None, n_patches=4000, tile=False, refine=3,
                 seam_window=9, flat_share=0.25, patch_refine=0, progress=None) -> np.ndarray:
    """A coarse synthesis from ``model`` upsampled by ``factor`` to ``size``: the layout
    the fine level follows.

    Parameters
    ----------
    model : tghop.TGHop
        The coarse model, fitted on the exemplar downsampled by ``factor``.
    factor : int
    size : (int, int) or int
        Output (H, W).
    rng : int or numpy.random.Generator, optional
    n_patches : int
        Pool of coarse patches.
    tile : bool
        Make the coarse image wrap around (for tileable output).
    refine : int
        Rounds (>= 0) of the refinement after quilting (:mod:`tghop.refine`) of the coarse image
        (at factor 2 without its finest band, which the fine level's comparison by box
        means hardly sees).
    seam_window : int
        Remove the steps across the coarse image's quilting seams (:mod:`tghop.seams`),
        averaged over squares of this side (0: off).
    flat_share : float in [0, 1)
        The coarse quilt's share of its pool passed over (:func:`tghop.quilting.quilt`).
    patch_refine : int or None
        Steps per level of the patch refinement of the coarse image, after its colours are
        matched (:func:`tghop.patch_refine.refine_image`, every patch, with the coarse
        model's statistics, steps :data:`GUIDE_RATE` times the fine level's; a model without
        them is left as it is); 0: off; None:
        :func:`guide_steps` for ``size``.
    progress : callable, optional
        ``progress("layout", done, 1000)`` as the coarse image is quilted, its seams removed,
        refined and patch-refined (:data:`GUIDE_PARTS`, a quarter each).

    Returns
    -------
    ndarray, shape (H, W, C), float32 in [0, 1]
        (float32: quilting compares it in float32; half the memory of a large guide.)
    """
    f = int(factor)
    refine = check_int(refine, "refine", 0)
    h, w = check_size(size)
    patch_refine = guide_steps(None if patch_refine is None else check_int(patch_refine, "patch_refine", 0), (h, w))
    small = (math.ceil(h / f), math.ceil(w / f))  # tileable: stretched to (h, w) when not divisible
    if not guide_fits((h, w), f, model.patch_size, tile=tile):
        raise TGHopError(f"a tileable output with a coarse layout at factor {f} needs at least "
                         f"{(model.patch_size - 1) * f + 1} pixels a side, got {h}x{w}")
    from .colour import match_histograms
    from .quilting import GUIDE_SCALE
    from .refine import refine as refine_bands

    # What the coarse model's synthesize does, except that the refinement leaves the
    # finest band when the fine level cannot see it: quilting compares the guide by
    # GUIDE_SCALE x GUIDE_SCALE box means, which at factor 2 average 2x2 coarse pixels
    # of the bilinear upsampling and pass at most half of that band (none at its top).
    # Measured better on 20 exemplars in SIFID, SWD and co-occurrence, and faster
    # (docs/choices.md). Its patch refinement comes last, after the colours (0.48).
    progress = as_layout_progress(progress)
    coarse = model.synthesize(small, rng=rng, n_patches=n_patches, tile=tile, refine=0, match_colours=False,
                              seam_window=seam_window, detail=GUIDE_DETAIL, flat_share=flat_share, patch_refine=0,
                              dtype=np.float32, progress=progress)
    coarse = refine_bands(coarse, model.bands_, n_iter=int(refine), tile=tile,
                          first_level=1 if GUIDE_SCALE // f >= 2 else 0, dtype=np.float32, progress=progress)
    coarse = match_histograms(coarse, model.colour_quantiles_, out=coarse)
    if patch_refine and getattr(model, "patches_", None) is not None:
        from .patch_refine import refine_image

        coarse = refine_image(coarse, model.patches_, n_steps=patch_refine, stride=1, tile=tile, dtype=np.float32,
                              rate=GUIDE_RATE, progress=progress)
    return upsample(coarse, None if tile and (h % f or w % f) else f, (h, w), wrap=tile)
