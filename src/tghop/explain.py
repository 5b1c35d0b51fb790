"""The core model on an image: which of a fitted model's clusters each part of it falls in.

After :mod:`tghop.synthesis` in the data flow (it needs a fitted :class:`~tghop.synthesis.TGHop`):
each patch of the image at a grid of origins is taken through :meth:`TGHop.encode
<tghop.synthesis.TGHop.encode>` to a core vector and :meth:`ICHM.predict
<tghop.core.ICHM.predict>` to its cluster (:func:`cluster_map`), and the labels are painted
as an image in a fixed palette (:func:`cluster_image`). ``tghop clusters`` writes the two
side by side.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ._arrays import check_int
from ._errors import TGHopError
from ._estimator import check_is_fitted
from ._images import check_image
from ._progress import report
from ._resources import one_blas_thread
from .synthesis import TGHop, grey_as_rgb

__all__ = ["cluster_map", "cluster_image", "cluster_colours", "CHUNK", "PALETTE_LEVELS"]

#: Patches encoded at a time by :func:`cluster_map` (memory: a few tens of MB at 32x32x3).
CHUNK = 512

#: Levels per channel of the grid :func:`cluster_colours` picks its colours from.
PALETTE_LEVELS = 13


def _model_image(model, image):
    """``image`` as float64 (H, W, C) with the model's channel count C (a grey image stored
    as RGB is taken as one channel for a grey model, as :func:`~tghop.synthesis.prepare_exemplar`
    does); one :class:`TGHopError` line for any other count, or for a model not a TGHop."""
    if hasattr(model, "__dict__") and not isinstance(model, TGHop):  # else check_is_fitted: "not fitted yet"
        hint = {"Material": "give its model_ (the TGHop fitted on its albedo), or fit a plain TGHop",
                "ICHM": "give the TGHop whose ichm_ it is"}.get(type(model).__name__, "fit a TGHop on an exemplar")
        raise TGHopError(f"cluster_map expects a fitted TGHop, got {type(model).__name__}; {hint}")
    check_is_fitted(model, "ichm_")
    want = model.exemplar_shape_[2]
    img = check_image(image, min_size=model.patch_size, name="image", channels=None)
    have = img.shape[2]
    if want == 1 and grey_as_rgb(img):
        return np.ascontiguousarray(img[..., :1])
    if have != want:
        def words(c):
            return f"{c} channel{'s' if c != 1 else ''}"
        raise TGHopError(f"the image has {words(have)} but the model was fitted on {words(want)}; give an image "
                         f"with {words(want)}, or fit a model on this image")
    return img


@one_blas_thread()  # the same clusters on any number of cores (the hops' products round by BLAS's threads)
def cluster_map(model, image, *, stride=None, progress=None) -> np.ndarray:
    """The cluster of the model's core model that each patch of ``image`` falls in.

    Every ``model.patch_size`` patch with its top-left corner on a grid of ``stride`` pixels
    (the origins of :func:`tghop.patches.patch_origins`, in raster order) goes through
    :meth:`TGHop.encode <tghop.synthesis.TGHop.encode>` and :meth:`ICHM.predict
    <tghop.core.ICHM.predict>` (the nearest cluster mean), :data:`CHUNK` patches at a time
    from a sliding-window view: memory does not grow with the image beyond the image itself.

    Parameters
    ----------
    model : tghop.synthesis.TGHop
        Fitted.
    image : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1] or integer (uint8, uint16), with the model's channel count C (an RGB
        image with three equal channels is read as grey for a grey model); ``H, W >= P``. Taken
        at the model's scale: an exemplar of a model fitted with ``scale`` goes through
        :func:`tghop.scale.rescale` first, as ``tghop clusters`` does.
    stride : int, optional
        Step between patch origins, at least 1; default the model's fit stride
        (``model.stride``: at it the exemplar's patches are the fit's training patches).
    progress : callable, optional
        ``progress(stage, done, total)``, called with stage ``"cluster map"`` and the patches
        mapped so far, before the first chunk and after each.

    Returns
    -------
    labels : ndarray of int, shape (rows, cols)
        ``rows = (H - P) // stride + 1``, ``cols = (W - P) // stride + 1``; the cluster of the
        patch with origin ``(i * stride, j * stride)`` at ``[i, j]``, in ``[0, N)`` for the
        model's N clusters.

    Raises
    ------
    NotFittedError
        Before :meth:`TGHop.fit <tghop.synthesis.TGHop.fit>`.
    TGHopError
        An image of another channel count, smaller than a patch, or not an image; a model
        that is not a :class:`~tghop.synthesis.TGHop` (a material: its ``model_``).

    Examples
    --------
    >>> from tghop import data
    >>> from tghop.synthesis import TGHop
    >>> from tghop.explain import cluster_map
    >>> image = data.bricks(64, rng=0)
    >>> model = TGHop(n_channels=(9, 22), n_clusters=4, stride=4, rng=0).fit(image)
    >>> cluster_map(model, image).shape
    (9, 9)
    """
    img = _model_image(model, image)
    p = model.patch_size
    s = model.stride if stride is None else check_int(stride, "stride", 1)
    windows = sliding_window_view(img, (p, p), axis=(0, 1))[::s, ::s]  # (rows, cols, C, P, P): no copy
    rows, cols = windows.shape[:2]
    labels = np.empty(rows * cols, dtype=np.int64)
    step = check_int(CHUNK, "CHUNK", 1)
    report(progress, "cluster map", 0, labels.size)
    for a in range(0, labels.size, step):
        i, j = np.divmod(np.arange(a, min(a + step, labels.size)), cols)
        patches = windows[i, j].transpose(0, 2, 3, 1)  # (n, P, P, C), a copy of this chunk only
        labels[a: a + step] = model.ichm_.predict(model.encode(patches))
        report(progress, "cluster map", min(a + step, labels.size), labels.size)
    return labels.reshape(rows, cols)


def cluster_colours(n: int) -> np.ndarray:
    """The palette of :func:`cluster_image`: cluster ``k``'s colour, the same for every model.

    A farthest-point order of the RGB cube's colours on a grid of ``PALETTE_LEVELS`` levels
    per channel: colour 0 is a red, and each next colour is the grid colour farthest (in RGB
    distance) from all earlier ones, the first such in raster order on a tie (integer
    distances: the same order everywhere). Colour ``k`` does not depend on ``n``; any two of
    the first 50 are at least 0.27 apart in RGB, of the first 100 at least 0.20 (the cube's
    diagonal is 1.73). Past the grid's 2,197 colours the order repeats.

    Parameters
    ----------
    n : int
        Number of colours, at least 0.

    Returns
    -------
    ndarray, shape (n, 3), float64 in [0, 1]
        RGB of clusters 0 .. n - 1.
    """
    n = check_int(n, "n", 0)
    levels = PALETTE_LEVELS - 1
    grid = np.stack(np.meshgrid(*[np.arange(levels + 1)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    order = np.empty(min(n, len(grid)), dtype=np.intp)
    far = np.full(len(grid), np.iinfo(np.int64).max)
    pick = int(np.flatnonzero((grid == (levels - 1, 1, 1)).all(axis=1))[0])
    for k in range(len(order)):
        order[k] = pick
        far = np.minimum(far, ((grid - grid[pick]) ** 2).sum(axis=1))
        pick = int(np.argmax(far))
    return (grid[order[np.arange(n) % max(len(order), 1)]] / levels).astype(np.float64).reshape(n, 3)


def _nearest_cells(n_pixels, n_cells, patch_size, stride):
    """For each pixel index along one axis, the grid index of the patch whose centre (origin
    + (P - 1) / 2: its middle pixel, or halfway between its two middle ones for an even P) is
    nearest (ties to the earlier patch), clipped to the grid."""
    y = np.arange(n_pixels)
    # ceil((2y - P + 1 - s) / 2s): the patch i with |y - (i s + (P - 1) / 2)| smallest.
    return np.clip(-((stride + patch_size - 1 - 2 * y) // (2 * stride)), 0, n_cells - 1)


def cluster_image(labels, patch_size: int, stride: int, shape) -> np.ndarray:
    """Paint a :func:`cluster_map` as an image of the size it was computed on.

    Each pixel takes the colour of the patch whose centre is nearest along each axis: the
    ``stride`` x ``stride`` cell around each patch's centre (origin + ``(patch_size - 1) / 2``,
    between its two middle pixels for an even size; a pixel as near two centres takes the
    earlier patch's) has that patch's cluster colour, and the border no patch centre
    reaches (about ``patch_size / 2`` pixels each side) takes the nearest cell's.

    Parameters
    ----------
    labels : array_like of int, shape (rows, cols)
        Clusters, at least 0, as :func:`cluster_map` returns them.
    patch_size, stride : int
        Those the map was computed with (``model.patch_size``; the ``stride`` given, or
        ``model.stride``).
    shape : tuple of int
        (H, W) or (H, W, C) of the image the map was computed on (positive integers):
        ``rows == (H - P) // stride + 1`` and ``cols == (W - P) // stride + 1``.

    Returns
    -------
    ndarray, shape (H, W, 3), float64 in [0, 1]
        Colours of :func:`cluster_colours`, by cluster index.
    """
    p = check_int(patch_size, "patch_size", 1)
    s = check_int(stride, "stride", 1)
    lab = np.asarray(labels)
    if lab.ndim != 2 or lab.size == 0 or not np.issubdtype(lab.dtype, np.integer) or lab.min() < 0:
        raise TGHopError(f"labels must be a non-empty (rows, cols) array of cluster indices (integers, at least 0), "
                         f"got {lab.dtype} of shape {lab.shape}; give cluster_map's result")
    if isinstance(shape, (str, bytes)) or not hasattr(shape, "__len__") or len(shape) < 2:
        raise TGHopError(f"cluster_image: shape must be the image's (H, W) or (H, W, C), got {shape!r:.60}; "
                         "give image.shape")
    h, w = (check_int(v, f"shape[{k}]", 1, where="cluster_image") for k, v in enumerate(shape[:2]))
    grid = ((h - p) // s + 1, (w - p) // s + 1) if h >= p and w >= p else (0, 0)
    if lab.shape != grid:
        raise TGHopError(f"labels of shape {lab.shape} are not the grid of {p}x{p} patches at stride {s} of a "
                         f"{h}x{w} image ({grid[0]}x{grid[1]}); give the patch size, stride and shape the map "
                         "was computed with")
    palette = cluster_colours(int(lab.max()) + 1)
    return palette[lab[_nearest_cells(h, lab.shape[0], p, s)[:, None], _nearest_cells(w, lab.shape[1], p, s)[None, :]]]
