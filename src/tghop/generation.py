"""The image pipeline of :meth:`TGHop.synthesize <tghop.synthesis.TGHop.synthesize>`, step by step: from
a fitted model to an image (new patches are drawn by :mod:`tghop.codec` and decoded by :mod:`tghop.pool`; the
co-occurrence cGAN's generation is :mod:`tghop.cooc.generation`).

From a fitted model to an image, in order (each step in its own module)::

    coarse guide (tghop.layout, in a second thread)   patch pool (tghop.pool)
        --> quilting, following the guide (tghop.quilting) --> seams removed (tghop.seams)
        --> band refinement (tghop.refine; large images region by region: tghop.regions)
        --> patch refinement (tghop.patch_refine) or colour matching (tghop.colour)

:meth:`TGHop.synthesize <tghop.synthesis.TGHop.synthesize>` holds the settings' defaults and
their documentation (from :data:`tghop.settings.SETTINGS`) and calls :func:`synthesize`.
"""

from __future__ import annotations

import numpy as np

from . import layout, settings
from ._arrays import check_dtype
from ._errors import TGHopError
from ._estimator import check_is_fitted, check_rng
from ._images import check_size
from ._progress import report
from ._resources import in_thread
from .colour import match_histograms
from .patch_refine import refine_image, steps_for
from .pool import GeneratedPool, pool_size, prepared_pool
from .quilting import GUIDE_SCALE, quilt_prepared
from .refine import refine as refine_bands
from .regions import match_regions, n_regions, prepare as prepare_regions
from .seams import remove_seams

__all__ = ["synthesize"]


def synthesize(model, size, *, rng, n_patches, tile, overlap, tolerance, detail, flat_share, match_colours,
               layout_weight, refine, layout_refine, layout_patch_refine, patch_refine, patch_stride, reuse,
               pool_per_block, seam_window, region, own_shares, progress, dtype, return_stages):
    """Generate a texture image of ``size`` from a fitted model: the pipeline's steps in order.

    Parameters
    ----------
    model : tghop.synthesis.TGHop
        Fitted (:class:`~tghop.NotFittedError` before).
    size : int or (int, int)
        Output (height, width).
    rng : int, numpy.random.Generator or None
    n_patches, pool_per_block, reuse, overlap, detail, flat_share
        The patch pool and how quilting draws from it (:mod:`tghop.pool`, :mod:`tghop.quilting`).
    tile, tolerance, layout_weight
        Quilting; ``layout_weight``: how far it follows the coarse guide.
    layout_refine, layout_patch_refine
        The coarse guide's refinements (:func:`tghop.layout.coarse_guide`).
    seam_window
        The seam removal (:mod:`tghop.seams`).
    refine, region, own_shares
        The band refinement (:mod:`tghop.refine`; by region: :mod:`tghop.regions`) and the
        histograms it gives (the colour classes' shares).
    match_colours
        The colour matching (:mod:`tghop.colour`), where no patch refinement follows.
    patch_refine, patch_stride
        The patch refinement (:mod:`tghop.patch_refine`).
    progress, dtype, return_stages
        As :meth:`TGHop.synthesize <tghop.synthesis.TGHop.synthesize>`, which documents every
        setting and holds their defaults (the settings table's): here all are given.

    Returns
    -------
    ndarray, shape (H, W, C), ``dtype``, in [0, 1] (uint8: 0 to 255)
        And the dict of each step's float32 image with ``return_stages`` (and the pool's patches).
    """
    check_is_fitted(model, "ichm_")
    dtype = check_dtype(dtype, (np.float64, np.float32, np.uint8), "float64, float32 or uint8")
    checked = settings.check_settings(dict(
        n_patches=n_patches, tile=tile, overlap=overlap, tolerance=tolerance, detail=detail,
        flat_share=flat_share, match_colours=match_colours, layout_weight=layout_weight, refine=refine,
        layout_refine=layout_refine, layout_patch_refine=layout_patch_refine, patch_refine=patch_refine,
        patch_stride=patch_stride, reuse=reuse,
        pool_per_block=pool_per_block, seam_window=seam_window, region=region, own_shares=own_shares))
    if checked["patch_refine"] and getattr(model, "patches_", None) is None:  # None (auto) skips it quietly
        raise TGHopError(f"patch_refine={checked['patch_refine']} needs the patch statistics this model lacks "
                         "(fitted with patch_levels=0, or by tghop 0.14 or older); fit it again, or leave "
                         "patch_refine at None or 0")
    # Where the patch refinement follows, it gives the image the exemplar's colours with its patches:
    # no per-channel colour matching before it (docs/choices.md, Colour matching, "0.41").
    n_steps = steps_for(checked["patch_refine"], check_size(size, limit=None))
    patches = bool(n_steps) and getattr(model, "patches_", None) is not None
    match_colours = match_colours and not patches
    regions = (refine or match_colours) and n_regions(size, checked["region"], tile=tile) != (1, 1)
    n_patches, reuse = pool_size(size, model.patch_size, n_patches=checked["n_patches"], overlap=overlap,
                                 tile=tile, pool_per_block=checked["pool_per_block"], reuse=checked["reuse"])
    rng = check_rng(rng)
    stages = {}

    def keep(name, img):  # a copy of this step's image (return_stages), in [0, 1] (a uint8 one's levels / 255)
        if return_stages and img is not None:
            stages[name] = np.array(img, dtype=np.float32)
            if img.dtype == np.uint8:  # the colour matching's 8-bit image (dtype uint8: tghop synth's)
                stages[name] /= 255

    guide = None
    if layout_weight and layout.follows_guide(model.layout_, size, tile=tile):
        # The coarse guide and the pool are independent: the guide is made in a second thread (its
        # own random stream) while the pool is generated and made ready for quilting.
        layout_rng = np.random.default_rng(rng.integers(0, 2**63 - 1))
        # Its steps are told as "layout" done of 1000 (from its thread; this one reports nothing until it has
        # the guide), so its start and end here are in the same units: a bar made at the first report keeps them.
        report(progress, "layout", 0, 1000)
        pending = in_thread(model.layout_.guide, size, rng=layout_rng, tile=tile, refine=layout_refine,
                            seam_window=checked["seam_window"], flat_share=checked["flat_share"],
                            patch_refine=checked["layout_patch_refine"], progress=progress)
        if refine:  # SciPy's FFT module and the windows for a large image, here, not on the guide's path
            prepare_regions(size, model.bands_, region=checked["region"] if regions else None, tile=tile)
        prepared = prepared_pool(model, n_patches, rng, size, overlap=overlap, tile=tile, detail=detail,
                                 flat_share=checked["flat_share"], guide_scale=GUIDE_SCALE)
        guide = pending()
        report(progress, "layout", 1000, 1000)
        report(progress, "patch pool", 0, 1)
    else:
        report(progress, "patch pool", 0, 1)
        prepared = prepared_pool(model, n_patches, rng, size, overlap=overlap, tile=tile, detail=detail,
                                 flat_share=checked["flat_share"], guide_scale=None)
    report(progress, "patch pool", 1, 1)
    keep("guide", guide)
    if return_stages:  # the pool quilting drew from, whole (a pool generated as it is read: decoded again)
        pool = prepared.patches
        stages["pool"] = pool.all() if isinstance(pool, GeneratedPool) else np.asarray(pool, dtype=np.float32)
    # float32 unless a float64 image is wanted unrefined and unsmoothed (the refinement
    # and the seam removal work in float32; so does quilting's canvas): half the memory.
    wide = np.float64 if dtype == np.float64 and not (refine or checked["seam_window"]) else np.float32
    image = quilt_prepared(prepared, tolerance=tolerance, rng=rng, progress=progress, guide=guide,
                           guide_weight=layout_weight, dtype=wide, reuse=reuse,
                           return_seams=checked["seam_window"] > 0)
    del prepared, guide  # the pool, its tables and the guide: not needed from here on
    keep("quilt", image[0] if checked["seam_window"] else image)
    if checked["seam_window"]:  # (image, steps)
        image = remove_seams(*image, window=checked["seam_window"], out=image[0], progress=progress)
        keep("seams", image)
    # The histograms to match: of the exemplar's colour classes in shares towards the quilt's.
    classes = getattr(model, "classes_", None) if refine or match_colours else None
    classes = classes if classes is not None and classes.weight(checked["own_shares"]) else None
    pixel_q, colour_q = (model.bands_.pixel_quantiles_, model.colour_quantiles_) if classes is None else \
        classes.targets(image, own_shares=checked["own_shares"])
    if regions:  # refined and colour-matched here; float32
        image = match_regions(image, bands=model.bands_ if refine else None, n_iter=refine, tile=tile,
                              colour_quantiles=colour_q if match_colours else None, pixel_quantiles=pixel_q,
                              region=checked["region"], progress=progress)
        refine = match_colours = 0
        keep("refine", image)
    if refine:  # float64 only for a float64 image, whose colours are then matched in place
        image = refine_bands(image, model.bands_, n_iter=refine, tile=tile, progress=progress,
                             dtype=np.float64 if dtype == np.float64 else np.float32, pixel_quantiles=pixel_q)
        keep("refine", image)
    if patches:  # ours, the last step: in float32, then the asked dtype (below, as refine_image makes it)
        image = refine_image(image.astype(np.float32, copy=False), model.patches_, n_steps=n_steps,
                             stride=checked["patch_stride"], tile=tile,
                             dtype=np.float32 if return_stages else dtype, progress=progress)
        if not return_stages:
            return image
        keep("patch refine", image)
    elif match_colours:
        report(progress, "colour", 0, 1)
        out = image if image.dtype == dtype else np.empty(image.shape, dtype=dtype)
        out = match_histograms(image, colour_q, out=out)
        keep("colour", out)
        return (out, stages) if return_stages else out
    if dtype == np.uint8:
        from .imageio import to_uint8

        out = to_uint8(image).reshape(image.shape)  # (H, W, 1) stays so
    else:
        out = image.astype(dtype, copy=False)
    return (out, stages) if return_stages else out
