"""The hole quilted with generated patches (:func:`quilt_hole`, step 2 of :mod:`tghop.inpaint`): the
``P x P`` blocks on the quilting grid that touch the hole, filled from its edge inwards (or row by
row), each with a pool patch matched to the block's known pixels near those to fill
(:data:`MATCH_BAND`; a regular picture's period, :func:`tghop.period.match_band`), the image's
pixels beside the hole counting more (:data:`RIM_MATCH_WEIGHT`), and pasted along minimum-error
boundary cuts (:func:`tghop.quilting.boundary_cut_mask`); :func:`distance_to_known` orders the
blocks and ramps the coarse guide and the refinements' fades.

Up to 0.63 this was part of :mod:`tghop.inpaint` (``_fill``, ``_distance_to_known``).
"""

from __future__ import annotations

import numpy as np

from ._progress import report
from .period import match_band
from .quilting import GUIDE_SCALE, boundary_cut_mask, default_overlap

__all__ = ["quilt_hole", "distance_to_known", "MATCH_BAND", "RIM_MATCH_WIDTH", "RIM_MATCH_WEIGHT"]

#: The image's known pixels within ``RIM_MATCH_WIDTH`` pixels of the hole (4-neighbour steps) count
#: ``RIM_MATCH_WEIGHT`` times in a block's error: the pixels beside the hole decide the step at its rim, where a
#: fill's pixels meet the image's without a cut (docs/choices.md, Inpainting "the rim in the matching").
RIM_MATCH_WIDTH = 3
RIM_MATCH_WEIGHT = 4.0


#: A hole's block (``order`` "edge") counts its known pixels only within ``MATCH_BAND`` overlaps (8-neighbour steps) of
#: its pixels still to fill, as quilting matches its overlap strips; 0: all its known pixels (0.60). Matched over a
#: block's whole known part (up to 27 of 32 columns beside a hole's edge), the best patches were the blended ones,
#: and a fill of large elements came out as a quilt of faint blocks (0.61; docs/choices.md, Inpainting "matched in a
#: band"). A regular picture's blocks are matched within its period instead (:func:`tghop.period.match_band`: brick
#: courses broke in the narrow band, 0.62). Row by row (:func:`tghop.inpaint.extend`) a block is matched on all of
#: them (0.60).
MATCH_BAND = 1


def _grid(n, p, step, tile, edges=()):
    """Block positions along one axis: every ``step`` from 0, the last one at ``n - p``
    (inside the image); with ``tile`` evenly around the torus, at most ``step`` apart (every
    ``step`` left the block across the edge overlapping the first by up to ``p - 1`` pixels,
    where the seams are cut in ``p - step``). ``edges`` (without ``tile``): positions of a grown
    picture's edges along this axis (:func:`_picture_edges`): a block is centred on each, half of it
    on the picture, and the blocks between are spread evenly, at most ``step`` apart (0.60;
    docs/choices.md, Inpainting "the blocks across a grown picture's edge")."""
    if tile:
        k = -(-n // step)
        return np.unique(np.round(np.arange(k) * (n / k)).astype(np.int64))
    centred = {e - p // 2 for e in edges if 0 < e - p // 2 < n - p}
    if not centred:
        return np.unique(np.minimum(np.arange(0, max(n - p, 0) + step, step), n - p))
    fixed = sorted({0, n - p} | centred)
    out = [np.array(fixed[:1])]
    for a, b in zip(fixed[:-1], fixed[1:]):
        k = -(-(b - a) // step)
        out.append(a + np.round(np.arange(1, k + 1) * ((b - a) / k)).astype(np.int64))
    return np.unique(np.concatenate(out))


def _picture_edges(hole, axis):
    """The edges along ``axis`` (0: rows, 1: columns) of the known pixels' extent that lie inside the image: a
    grown picture's (:func:`tghop.inpaint.extend`); none where the known pixels reach both ends of the axis (a hole
    inside them)."""
    inside = np.flatnonzero((~hole).any(axis=1 - axis))
    if not inside.size:
        return ()
    return tuple(e for e in (int(inside[0]), int(inside[-1]) + 1) if 0 < e < hole.shape[axis])


def distance_to_known(hole, tile):
    """Euclidean distance of each pixel to the nearest known one (0 on known pixels);
    on a torus with ``tile``. All hole: inf."""
    from scipy.ndimage import distance_transform_edt

    if hole.all():
        return np.full(hole.shape, np.inf)
    if not tile:
        return distance_transform_edt(hole)
    h, w = hole.shape
    return distance_transform_edt(np.tile(hole, (3, 3)))[h:2 * h, w:2 * w]


def _rim_weights(hole, tile):
    """(H, W) float32: ``RIM_MATCH_WEIGHT`` on the known pixels within ``RIM_MATCH_WIDTH`` 4-neighbour steps of
    ``hole`` (around a periodic image's edges with ``tile``), 1 elsewhere."""
    from scipy.ndimage import binary_dilation

    r = RIM_MATCH_WIDTH
    if r <= 0 or RIM_MATCH_WEIGHT == 1.0:
        return np.ones(hole.shape, dtype=np.float32)
    grown = binary_dilation(np.pad(hole, r, mode="wrap" if tile else "constant"), iterations=r)[r:-r, r:-r]
    return np.where(grown & ~hole, np.float32(RIM_MATCH_WEIGHT), np.float32(1.0))


def _fill_order(hole, p, step, tile, order="edge", distance=None):
    """The (y, x) of the ``p x p`` blocks that touch the hole, in the order they are filled:
    from the hole's edge inwards (then in raster order), those that see no known pixel after
    all the others (a block next to the hole's edge but not across it, such as the first
    block of a hole at a periodic image's edge: filled before its neighbours, at random, it
    set them a second border to match, and the fill there was chopped). ``order`` "raster":
    row by row instead, as quilting does (:func:`tghop.inpaint.extend`). ``distance``: the hole's
    :func:`distance_to_known`, where the caller has it."""
    h, w = hole.shape
    offsets = np.arange(p)
    distance = distance_to_known(hole, tile) if distance is None else distance
    blocks = []
    # Row by row (extend's order), a block centred on each edge of the picture (0.60)
    edges = (_picture_edges(hole, 0), _picture_edges(hole, 1)) if order == "raster" and not tile else ((), ())
    for y in _grid(h, p, step, tile, edges[0]).tolist():
        rows = (y + offsets) % h
        for x in _grid(w, p, step, tile, edges[1]).tolist():
            cols = (x + offsets) % w
            inside = hole[np.ix_(rows, cols)]
            if inside.any():
                blocks.append((bool(inside.all()), distance[np.ix_(rows, cols)][inside].min(), y, x))
    if order == "raster":
        return [(y, x) for _, _, y, x in blocks]  # made row by row
    return [(y, x) for _, _, y, x in sorted(blocks)]


def quilt_hole(work, hole, distance, pool, tables, p, tile, tolerance, detail, guide, order, rng, progress):
    """Quilt generated patches into the hole of ``work`` (float32, (H, W, C)); returns the canvas and
    the block each pixel came from ((H, W) int, -1 where it is the image's own).
    ``distance``: the hole's :func:`distance_to_known`. ``tables``: the pool's rows (n, P*P*C),
    their squared norms per pixel (n, P*P), gradient energies (n,) and error factors (n,) or None.
    ``guide``: None, or an (H, W, C) coarse fill and its weight (:func:`tghop.inpaint.inpaint`'s ``layout_weight``)."""
    from scipy.ndimage import maximum_filter

    h, w, c = work.shape
    flat, squares, energy, factor = tables
    overlap = default_overlap(p)
    step = p - overlap
    canvas = work.copy()
    canvas[hole] = 0.0
    known = ~hole
    owner = np.full((h, w), -1, dtype=np.int32)  # the block each hole pixel was pasted from last
    offsets = np.arange(p)
    rim = _rim_weights(hole, tile)
    band = match_band(work, hole, MATCH_BAND * overlap, p) if order == "edge" else 0  # a regular picture's period
    if guide is not None:  # the pool's box means, as quilting compares them with its guide
        guide, guide_weight = guide
        # The guide counts from nothing at the hole's edge to whole a patch side inside it:
        # next to the known pixels the fill follows them (a coarse fill is a few pixels off).
        reach = np.clip(distance / p, 0.0, 1.0).astype(np.float32)
        s = GUIDE_SCALE if p % GUIDE_SCALE == 0 else 1
        q = p // s
        low = pool.reshape(len(pool), q, s, q, s, c).mean(axis=(2, 4), dtype=np.float32).reshape(len(pool), -1)
        low_squares = low * low
    blocks = _fill_order(hole, p, step, tile, order, distance)
    report(progress, "inpainting", 0, len(blocks))
    for done, (y, x) in enumerate(blocks, start=1):
        window = np.ix_((y + offsets) % h, (x + offsets) % w)
        old = canvas[window]  # (P, P, C)
        have = known[window]  # pixels with a value: the image's and those filled before
        weight = np.where(have, rim[window], np.float32(0.0))
        if band and not have.all():  # the known pixels near those to fill, as quilting's overlap strips (0.61)
            weight = np.where(maximum_filter(~have, size=2 * band + 1, mode="constant"), weight, np.float32(0.0))
        err = None
        if weight.any():
            target = (old * weight[..., None]).ravel()
            # ||p||^2 over the known pixels - 2 p.o + ||o||^2 (each pixel weighted), for every pool patch at once.
            err = squares @ weight.ravel() - 2.0 * (flat @ target) + float(target @ old.ravel())
        if guide is not None and not have.all():
            # The same over the guide's box means, each box weighted by its share of pixels not
            # yet filled, per pixel as the known pixels' error (quilting's guide term).
            share = np.where(have, np.float32(0.0), reach[window]).reshape(q, s, q, s).mean(axis=(1, 3))
            share = np.repeat(share[..., None], c, axis=2)
            boxes = guide[window].reshape(q, s, q, s, c).mean(axis=(1, 3), dtype=np.float32)
            term = (low_squares @ share.ravel() - 2.0 * (low @ (share * boxes).ravel())
                    + float((share * boxes * boxes).sum()))
            scale = guide_weight * max(float(np.count_nonzero(weight)), p * overlap) / (q * q)
            err = scale * term if err is None else err + scale * term
        if err is not None and factor is not None:
            err = err * factor
        if err is not None:
            best = max(float(err.min()), 0.0)
            candidates = np.flatnonzero(err <= best * (1.0 + tolerance) + 1e-4 * (1.0 + best))
        else:
            candidates = np.arange(len(pool))
        if detail > 0 and candidates.size > 1:
            ranked = candidates[np.argsort(energy[candidates], kind="stable")]
            skip = min(int(detail * ranked.size), ranked.size - 1)
            candidates = ranked[skip:]
        new = pool[candidates[rng.integers(candidates.size)]]
        pixel_err = np.square(old - new).sum(axis=2)
        pixel_err[~have] = 0.0
        sides = {side: overlap if strip.any() else 0 for side, strip in (
            ("left", have[:, :overlap]), ("top", have[:overlap]), ("right", have[:, -overlap:]),
            ("bottom", have[-overlap:]))}
        paste = (boundary_cut_mask(pixel_err, **sides) | ~have) & hole[window]
        canvas[window] = np.where(paste[..., None], new, old)
        owner[window] = np.where(paste, done, owner[window])
        known[window] |= hole[window]
        report(progress, "inpainting", done, len(blocks))
    return canvas, owner
