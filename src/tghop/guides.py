"""Painted guide maps read into labels, the region of every pixel (ours): what :func:`tghop.synthesize_guided`
(:mod:`tghop.guided`, which paints with the labels), the web server's painted guides and the co-occurrence
model's painted crops read. Not the coarse guide that quilting follows (:mod:`tghop.layout`).

A guide holds one grey level (or colour) per model, the darkest for the first. A map with
soft (antialiased) or JPEG edges is read as its flat levels: each pixel of an edge's blend
takes the nearest level's region (:func:`guide_labels`, :func:`_snap_levels`). A guide of
another size than the output, of its shape, is scaled to it (:func:`scale_labels`: its regions,
nearest neighbour, so that no label is blended into another).
"""

from __future__ import annotations

import numpy as np

from ._arrays import check_int, check_not_path
from ._errors import TGHopError, warn
from ._images import check_size

__all__ = ["guide_labels", "label_colours", "same_shape", "scale_labels", "scaled_message",
           "LostRegionError", "ASPECT_TOLERANCE",
           "FEW_LEVELS", "RESHAPE",
           "SNAP_DISTANCE", "SNAP_SHARE", "SNAP_BLOCK", "SNAP_FLAT", "SNAP_FLAT_SHARE", "SNAP_TIE"]

#: A guide with more distinct levels than inputs (not soft edges of its levels) and at most
#: this many was painted with one level per texture (more inputs wanted); more is a picture.
FEW_LEVELS = 8
#: A guide with more distinct values than inputs whose pixels lie, but for a few, within this
#: (the largest channel difference, in 0-1 units) of as many flat levels as inputs, at least
#: SNAP_SHARE of them and each level painted as a SNAP_BLOCK x SNAP_BLOCK block somewhere, is a
#: guide of those levels with soft or JPEG edges (:func:`guide_labels`).
SNAP_DISTANCE = 0.1
SNAP_SHARE = 0.9
SNAP_BLOCK = 5
#: And its flat areas are its levels: of the pixels whose 3x3 neighbourhood varies by at most
#: SNAP_FLAT (the largest channel difference, 0-1 units), at least SNAP_FLAT_SHARE lie within
#: SNAP_FLAT of their level's commonest value (a JPEG file's flat areas within 3 levels of 255;
#: a photograph's smooth areas take any value: at most 64 % of them on the 44 exemplars).
SNAP_FLAT = 0.02
SNAP_FLAT_SHARE = 0.8
#: The levels of such a guide whose means (then R, G or B) lie within this of each other (0-1 units,
#: about 2 of 255) are ranked as equal there: a JPEG file moves a level's commonest value by a
#: level or two (pure red, green and blue, of equal means, read as 254, 0, 2 and 1, 254, 0).
SNAP_TIE = 0.008
#: A guide of another size than the output is scaled to it when their aspect ratios (width over
#: height) differ by at most this share (the larger over the smaller, less 1: a 100x150 map for a
#: 256x385 output); more is refused, as the regions would be stretched out of the shape painted.
ASPECT_TOLERANCE = 0.02


class LostRegionError(TGHopError):
    """A guide scaled to the output's size lost a region: one thinner than a pixel of the output
    (:func:`guide_labels`). A usage error on the command line (its --size), 400 on the web server."""


def same_shape(shape, size) -> bool:
    """Whether a guide of ``shape`` (H, W, ...) has the shape of an output of ``size`` (H, W):
    their aspect ratios within :data:`ASPECT_TOLERANCE` of each other, so that it is scaled to it
    (:func:`guide_labels`); ``tghop synth --guide`` and ``tghop cooc edit --mask`` ask it first.

    Parameters
    ----------
    shape : tuple of int
        The guide's ``(H, W, ...)``.
    size : (int, int)
        The output's (height, width).

    Returns
    -------
    bool
    """
    h, w = int(shape[0]), int(shape[1])
    return max(w * size[0], size[1] * h) <= (1 + ASPECT_TOLERANCE) * min(w * size[0], size[1] * h)


def scaled_message(shape, size) -> str:
    """What :func:`guide_labels` warns of a guide of ``shape`` (H, W, ...) scaled to ``size``
    (h, w); the web server tells its clients the same words (docs/serve.md).

    Parameters
    ----------
    shape : tuple of int
        The guide's ``(H, W, ...)``.
    size : (int, int)
        The output's (height, width).

    Returns
    -------
    str
    """
    return (f"the guide was scaled from {shape[0]}x{shape[1]} to {size[0]}x{size[1]}, the output's size (nearest "
            "neighbour: its regions kept as painted)")


def scale_labels(labels, size) -> np.ndarray:
    """A label map (H, W) scaled to ``size`` (h, w) by nearest neighbour: each pixel takes the
    label under its centre, so that the labels stay the ones painted (no blend of two regions
    becomes a third) and a map scaled by whole factors keeps every edge where it was painted.

    Parameters
    ----------
    labels : ndarray, shape (H, W) or (H, W, C)
    size : (int, int)
        The result's (height, width).

    Returns
    -------
    ndarray, shape (h, w) or (h, w, C)
        ``labels``' dtype.
    """
    h, w = labels.shape[:2]
    rows = (2 * np.arange(size[0], dtype=np.int64) + 1) * h // (2 * size[0])
    cols = (2 * np.arange(size[1], dtype=np.int64) + 1) * w // (2 * size[1])
    return labels[rows[:, None], cols[None, :]]


#: What :func:`guide_labels` says to do about a guide of another shape than the output, by default.
RESHAPE = "paint the guide at the output's shape, it is scaled to its size (or leave the size out to take the guide's)"


def guide_labels(guide, n_models, *, size=None, input_name="input", no_guide="give no guide", names=None,
                 guide_name="the guide", size_name="size", reshape=RESHAPE, enlarge=None) -> np.ndarray:
    """The region of every pixel of a painted guide, as (H, W) int labels in ``[0, n_models)``.

    The rule: the guide's distinct values (grey levels, or colours) sorted from dark to
    light (by their mean over the channels, then by R, G, B) are the models in the order
    given: the darkest is the first model. An integer label map 0, 1, ... follows the same
    rule. A guide with more distinct values than models whose pixels lie, but for a few, near
    as many flat levels as models is such a map with soft (antialiased) or JPEG edges: its
    levels are those, and a pixel of an edge's blend takes the nearest level's region
    (:data:`SNAP_DISTANCE`); its levels' means (then R, G, B) within :data:`SNAP_TIE` of each
    other count as equal (a JPEG file's noise), the exact values deciding only after. Any other
    guide with more distinct values than models (a smooth picture, or too few models given) or
    fewer is refused, naming the counts and the likely fix.

    Parameters
    ----------
    guide : array_like, shape (H, W) or (H, W, C)
        uint8, uint16, integers or floats. Soft or JPEG edges are judged in 0-255 (8 bits),
        0-65535 (16 bits), 0-1 (floats; floats above 1 in 0-255, above 255 in 0-65535) and,
        for other integers, in label units.
    n_models : int
    size : (int, int), optional
        The output size. A guide of another size but its shape (aspect ratios within
        :data:`ASPECT_TOLERANCE`: :func:`same_shape`) is read at its own size and its labels
        scaled to ``size`` by nearest neighbour (:func:`scale_labels`), with a warning saying
        so; one of another shape is refused (paint it at the output's shape). None: the
        guide's. The guide's own size is refused above :data:`tghop._images.MAX_PIXELS`.
    input_name, no_guide : str
        What the messages call a model and the fix of leaving the guide out (the CLI's
        "SOURCE" and "drop --guide").
    names : sequence of str, optional
        Each model's name in the message of a region lost by the scaling (the CLI's "SOURCE 2",
        the server's "models[1]"); default ``input_name`` numbered from 1.
    guide_name, size_name : str
        What that message calls the guide and the size (the CLI's "--guide map.png" and "--size").
    reshape : str
        The fix named when the guide is of another shape than ``size`` (:data:`RESHAPE`: paint it at the
        output's shape, or leave the size out); ``{h}`` and ``{w}`` in it are the guide's height and width
        (the web page's: set its height and width to the guide's shape).
    enlarge : str, optional
        The fix named when the scaling loses a region; default "paint it wider or give a larger
        ``size_name``".

    Returns
    -------
    ndarray of int64, shape (H, W)
        ``size``, or the guide's size without it.

    Raises
    ------
    LostRegionError
        A guide scaled to ``size`` whose region of a model is gone (thinner than a pixel of the
        output), naming the model and the fix (paint it wider, or a larger size).

    Warns
    -----
    UserWarning
        A guide of another size than ``size``, scaled to it: from which size to which.
    """
    n_models = check_int(n_models, "n_models", 1)
    size = None if size is None else check_size(size, limit=None)
    check_not_path(guide, "the guide")
    try:
        arr = np.asarray(guide)
    except ValueError:  # ragged nested lists
        raise TGHopError("the guide must be an (H, W) or (H, W, C) image of numbers, got ragged rows") from None
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if arr.ndim not in (2, 3) or arr.dtype.kind not in "biuf" or arr.size == 0:
        raise TGHopError(f"the guide must be an (H, W) or (H, W, C) image of numbers, got {arr.dtype} {arr.shape}")
    if arr.dtype.kind == "f" and not np.isfinite(arr).all():
        raise TGHopError("the guide has NaN or infinite values")
    scaled = size is not None and tuple(arr.shape[:2]) != tuple(size)
    if scaled and not same_shape(arr.shape, size):
        raise TGHopError(f"the guide is {arr.shape[0]}x{arr.shape[1]} but the output is {size[0]}x{size[1]}, of "
                         f"another shape (width/height {arr.shape[1] / arr.shape[0]:.3g} against "
                         f"{size[1] / size[0]:.3g}); {reshape.format(h=arr.shape[0], w=arr.shape[1])}")
    if size is None or scaled:  # the labels are made at the guide's own size: within the limit
        check_size(arr.shape[:2], name="the guide's size")
    values, labels = _distinct(arr)
    n = len(values)
    tie, smooth = 0.0, None  # a flat map's levels: ranked by their exact values
    if n > n_models:  # antialiased or JPEG edges: each pixel to the nearest of the guide's flat levels
        full = _full_scale(arr)
        smooth = _smooth(values.astype(np.float64) / full, labels)  # once: each count reads it
        snapped = _snap_levels(values, labels, n_models, full, smooth)
        if snapped is not None:
            values, labels = snapped
            n = len(values)
            tie = SNAP_TIE * full  # their values moved by a JPEG file's noise
    if n != n_models:
        soft = n > n_models and next((m for m in range(2, min(n, FEW_LEVELS + 1)) if m != n_models and
                                      _snap_levels(values, labels, m, full, smooth) is not None), None)
        if soft:  # levels with soft or JPEG edges, as many as that: named, not the blends' values
            n = soft
        if n > FEW_LEVELS:
            hint = (f"paint one flat level per {input_name} (soft or JPEG edges are taken, "
                    "a smooth picture is not)")
        elif n > n_models:
            hint = f"give one {input_name} per level ({n} {input_name}s for {n} levels) or {no_guide}"
        else:
            hint = f"paint one level per {input_name}"
        levels = "one grey level/colour" if n == 1 else f"{n} distinct grey levels/colours"
        if soft:
            levels = f"{n} grey levels/colours with soft or JPEG edges"
        inputs = f"one {input_name} was" if n_models == 1 else f"{n_models} {input_name}s were"
        raise TGHopError(f"the guide has {levels} but {inputs} given; {hint}: the darkest is the first {input_name}")
    rank = np.empty(n, dtype=np.int64)
    rank[_dark_to_light(values, tie)] = np.arange(n)
    if not scaled:
        return rank[labels]
    scaled = rank[scale_labels(labels, size)]
    gone = np.flatnonzero(np.bincount(scaled.ravel(), minlength=n_models) == 0)
    if len(gone):  # read again, it would be "one grey level but 2 inputs were given"
        name = names[gone[0]] if names is not None else f"{input_name} {gone[0] + 1}"
        raise LostRegionError(f"{guide_name}: {name}'s region is gone once the map is scaled from {arr.shape[0]}x"
                              f"{arr.shape[1]} to {size_name} {size[0]}x{size[1]} (it is thinner than a pixel of the "
                              f"output); {enlarge or f'paint it wider or give a larger {size_name}'}")
    warn(scaled_message(arr.shape, size))
    return scaled


def label_colours(guide, labels) -> list:
    """The colour painted for each label of :func:`guide_labels`, as 8-bit ``(r, g, b)`` (a grey
    guide's ``(v, v, v)``): the median of its pixels, so that a soft or JPEG edge's blends do not move
    it; None for a label no pixel has. What ``tghop synth --guide`` tells of a colour guide (0.59):
    which colour is which SOURCE, where "dark to light" (mean, then R, G, B) is no order a painter sees.

    Parameters
    ----------
    guide : array_like, shape (H, W) or (H, W, C)
        The guide as read (uint8, uint16 or floats, as :func:`guide_labels` takes it).
    labels : ndarray of int, shape (h, w)
        Its labels, at its size or scaled to another (:func:`scale_labels`: each pixel's under its centre).

    Returns
    -------
    list
        ``(r, g, b)`` ints in 0-255 or None, one per label from 0 to ``labels.max()``.
    """
    arr = np.asarray(guide)
    arr = arr.reshape(arr.shape[0], arr.shape[1], -1)[..., :3]
    if arr.shape[2] < 3:
        arr = np.repeat(arr[..., :1], 3, axis=2)
    labels = np.asarray(labels)
    if labels.shape != arr.shape[:2]:  # the guide's pixel under each label's centre
        arr = scale_labels(arr, labels.shape)
    step = max(1, int(np.sqrt(labels.size / 1e6)))  # about a million pixels are enough for a median
    arr, labels = arr[::step, ::step].reshape(-1, 3), labels[::step, ::step].ravel()
    full = _full_scale(arr)
    out = []
    for k in range(int(labels.max()) + 1):
        mine = arr[labels == k]
        out.append(tuple(int(round(float(v) / full * 255)) for v in np.median(mine, axis=0)) if len(mine) else None)
    return out


def _dark_to_light(values, tie):
    """The order of the levels ``values`` (n, C) from dark to light: by their mean over the channels,
    then by R, G, B; values within ``tie`` of each other (chained, in the values' units) count as
    equal first, so that a JPEG file's noise (pure red, green and blue, of equal means, read as
    254, 0, 2 and 1, 254, 0) does not decide, and exact values only after (a flat map: ``tie`` 0)."""
    keys = [values.astype(np.float64).mean(axis=1)] + list(values.astype(np.float64).T)
    if tie > 0:
        keys = [_tied(key, tie) for key in keys] + keys
    return np.lexsort(tuple(reversed(keys)))


def _tied(key, tie):
    """Each value's group among ``key`` (n,): sorted, a new group where the next lies more than ``tie``
    above the last."""
    order = np.argsort(key, kind="stable")
    group = np.empty(key.size, dtype=np.int64)
    group[order] = np.concatenate([[0], np.cumsum(np.diff(key[order]) > tie)])
    return group


def _snap_levels(values, labels, k, full, smooth):
    """``(levels (k, C), labels (H, W))`` of a guide whose pixels lie, all but a few, near ``k``
    flat levels (a soft brush's or a JPEG file's edges); None where they do not (another count
    of levels painted, or a smooth picture).

    The levels: k-means of the distinct values weighted by their counts, started from the
    commonest value and each next the farthest (by count times squared distance); where those
    fail the checks, k-means again weighted by the counts of ``smooth``'s pixels (:func:`_smooth`,
    the flat areas: a rare level's blends outnumber its own pixels, so the first took a blend
    for a level, or the level's mean far from its value). Near: within :data:`SNAP_DISTANCE`
    (the largest channel difference, 0-1 units) of the k-means' mean for at least
    :data:`SNAP_SHARE` of the pixels, and every level painted somewhere as a block of
    :data:`SNAP_BLOCK` pixels a side (the blend across an edge between two levels is no level of
    its own, however near a third level's value it passes), no such block of one value near
    none of them (another level painted), the levels' values more than :data:`SNAP_FLAT` apart,
    twice that in the second k-means (not one level's noise split in two; a label map 0-3 of
    8 bits given two inputs was taken as two levels), and the flat areas on the levels
    (:func:`_flat_areas_are_levels`: not a photograph). A pixel near a level that no other's blends
    or noise reach (:func:`_reached`; thin strokes, small dots), or in a level's block, is painted;
    any other (on an edge's blend, or a stray one) takes the level of the nearest painted pixel.
    Each level is given as its commonest value (of the flat pixels, in the second k-means: the
    painted one; the k-means' mean is pulled by the blends).
    """
    points = values.astype(np.float64) / full  # (n, C)
    counts = np.bincount(labels.ravel(), minlength=len(values)).astype(np.float64)
    for weights in (counts, None):
        split = weights is None  # the levels again, of the flat pixels' values only (no blends pulling them)
        if split:
            weights = np.bincount(labels[smooth], minlength=len(values)).astype(np.float64)
            if np.count_nonzero(weights) < k:
                return None
        centres, nearest = _kmeans(points, weights, k)
        snapped = _levels_of(points, counts, weights, labels, centres, nearest, smooth, (1 + split) * SNAP_FLAT)
        if snapped is not None:
            modes, level = snapped
            return values[modes], level
    return None


def _kmeans(points, weights, k):
    """``(centres (k, C), nearest (n,))``: a k-means of the distinct values ``points`` (n, C) weighted
    by ``weights`` (n,), started from the heaviest value and each next the farthest (by weight times
    squared distance), and each value's level."""
    centres = [points[np.argmax(weights)]]
    for _ in range(k - 1):
        far = np.min([np.square(points - c).sum(axis=1) for c in centres], axis=0)
        centres.append(points[np.argmax(weights * far)])
    centres = np.array(centres)
    for _ in range(20):  # Lloyd's rounds, weighted
        nearest = np.argmin(np.square(points[:, None, :] - centres[None]).sum(axis=2), axis=1)
        moved = np.array([np.average(points[nearest == j], axis=0, weights=weights[nearest == j])
                          if weights[nearest == j].sum() else centres[j] for j in range(k)])
        if np.allclose(moved, centres):
            break
        centres = moved
    return centres, np.argmin(np.square(points[:, None, :] - centres[None]).sum(axis=2), axis=1)


def _levels_of(points, counts, weights, labels, centres, nearest, smooth, apart):
    """``(modes (k,), labels (H, W))`` of the guide's pixels given the levels' ``centres`` (k, C)
    and each distinct value's (``nearest`` (n,)): the checks and the snap of :func:`_snap_levels`;
    None where they fail. ``counts`` (n,): each value's pixels; ``weights`` (n,): the k-means',
    whose heaviest value in each level is its mode; ``smooth``: :func:`_smooth`'s mask; ``apart``:
    how far apart the levels' modes must lie, more than (0-1 units, the largest channel difference:
    not one level's noise, or a blend's flat tail, split off as a level of its own)."""
    k = len(centres)
    close = np.abs(points - centres[nearest]).max(axis=1) <= SNAP_DISTANCE
    if counts[close].sum() < SNAP_SHARE * counts.sum():
        return None
    if not all((nearest == j).any() for j in range(k)):
        return None
    # each level's commonest value (of its flat pixels, in the second k-means): the painted one (a JPEG
    # file's within a few levels of it; a rare level's commonest of all may be a blend)
    heaviest = [weights if weights[nearest == j].any() else counts for j in range(k)]
    modes = np.array([np.flatnonzero(nearest == j)[np.argmax(w[nearest == j])] for j, w in enumerate(heaviest)])
    if (np.abs(points[modes][:, None] - points[modes][None]).max(axis=2) + np.eye(k)).min() <= apart:
        return None
    if not _flat_areas_are_levels(labels, smooth, np.abs(points - points[modes][nearest]).max(axis=1)):
        return None
    level, near = nearest[labels], close[labels]
    from scipy.ndimage import distance_transform_edt, maximum_filter, minimum_filter

    flat = maximum_filter(labels, size=SNAP_BLOCK) == minimum_filter(labels, size=SNAP_BLOCK)
    if (flat & ~near).any():  # a block of one value near no level: a level of its own, not an edge
        return None
    solid = np.zeros(level.shape, dtype=bool)  # the pixels taken as painted: near a level, and not a blend
    reached = _reached(points[modes])
    for j in range(k):
        mine = (level == j) & near
        centres_j = minimum_filter(mine, size=SNAP_BLOCK, mode="nearest")  # of a block all near level j
        if not centres_j.any():
            return None
        # a level that blends or noise of others reach: only its blocks' pixels; any other: all its near
        # pixels (no other's pass near it), its thin strokes and small dots kept
        solid |= mine & maximum_filter(centres_j, size=SNAP_BLOCK, mode="nearest") if reached[j] else mine
    near = solid
    if not near.all():
        rows, cols = distance_transform_edt(~near, return_distances=False, return_indices=True)
        level = level[rows, cols]
    return modes, level


def _full_scale(arr):
    """The value of full white in the guide ``arr``: what 1 is in the snap's 0-1 units. 255 for
    8 bits, 65535 for 16; a float guide's 1, or, where its values go above 1 (a 0-255 image read
    as floats), 255, and above that 65535, then its largest; other integers' 1 (label maps)."""
    if arr.dtype == np.uint8:
        return 255.0
    if arr.dtype == np.uint16:
        return 65535.0
    top = float(np.abs(arr).max()) if arr.dtype.kind == "f" else 1.0
    return next(full for full in (1.0, 255.0, 65535.0, top) if top <= full)


def _reached(levels):
    """Whether each of the levels ``(k, C)`` (0-1 units) lies within :data:`SNAP_DISTANCE` (the
    largest channel difference) of the straight blend between two others (where a soft edge
    between those passes near it), or within twice that of another level (where that level's
    noise, a JPEG file's ringing, comes near it)."""
    gaps = np.abs(levels[:, None] - levels[None]).max(axis=2) + np.eye(len(levels)) * 2 * SNAP_DISTANCE
    out = gaps.min(axis=1) < 2 * SNAP_DISTANCE
    t = np.linspace(0.0, 1.0, 129)[:, None, None]
    for a in range(len(levels)):
        for b in range(a + 1, len(levels)):
            blend = levels[a] + t * (levels[b] - levels[a])  # (129, 1, C)
            near = np.abs(blend - levels[None]).max(axis=2).min(axis=0) <= SNAP_DISTANCE
            near[[a, b]] = False
            out |= near
    return out


def _smooth(points, labels):
    """The pixels whose 3x3 neighbourhood varies by at most :data:`SNAP_FLAT` (each channel):
    ``points`` (n, C) the distinct values in 0-1 units, ``labels`` (H, W) each pixel's."""
    from scipy.ndimage import maximum_filter, minimum_filter

    smooth = np.ones(labels.shape, dtype=bool)
    for channel in points.T.astype(np.float32):
        value = channel[labels]
        smooth &= maximum_filter(value, size=3) - minimum_filter(value, size=3) <= SNAP_FLAT + 1e-6
    return smooth


def _flat_areas_are_levels(labels, smooth, off):
    """Whether at least :data:`SNAP_FLAT_SHARE` of the pixels whose 3x3 neighbourhood varies by at
    most :data:`SNAP_FLAT` (``smooth``) lie within it of their level (``off``: each distinct value's
    distance to its level's): a painted map's flat areas are its levels, a photograph's smooth ones any
    value."""
    if not smooth.any():
        return False
    return (off <= SNAP_FLAT + 1e-6)[labels[smooth]].mean() >= SNAP_FLAT_SHARE


def _distinct(arr):
    """``(values (n, C), labels (H, W))``: the distinct pixels of an (H, W) or (H, W, C)
    image and each pixel's index among them (8-bit images by counting, in linear time)."""
    h, w = arr.shape[:2]
    c = 1 if arr.ndim == 2 else arr.shape[2]
    if arr.dtype == np.uint8 and c in (1, 3):
        code = arr.astype(np.int32) if c == 1 else (arr[..., 0].astype(np.int32) << 16) | (
            arr[..., 1].astype(np.int32) << 8) | arr[..., 2]
        if c == 1:
            present = np.flatnonzero(np.bincount(code.ravel(), minlength=256))
            index = np.zeros(256, dtype=np.int64)
            index[present] = np.arange(present.size)
            return present[:, None].astype(np.uint8), index[code]
        codes, labels = np.unique(code.ravel(), return_inverse=True)
        values = np.stack([(codes >> 16) & 255, (codes >> 8) & 255, codes & 255], axis=1).astype(np.uint8)
        return values, labels.reshape(h, w)
    if c == 1:
        values, labels = np.unique(arr.reshape(-1), return_inverse=True)
        return values[:, None], labels.reshape(h, w)
    values, labels = np.unique(arr.reshape(h * w, c), axis=0, return_inverse=True)
    return values, labels.reshape(h, w)
