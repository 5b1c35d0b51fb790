"""Painted regions joined along the content: a minimum cut through each edge's band (ours; quilting's cuts
between blocks are :mod:`tghop.quilting`'s).

:func:`tghop.synthesize_guided` makes one *layer* per model, the model's own synthesis over
the box its region reaches, and :func:`cut_regions` says which layer each pixel shows. A
pixel further than ``transition / 2`` pixels from a painted edge (Chebyshev distance) shows
its own region's layer. In the band around an edge a pixel shows one of the two layers that
meet there: its own or the nearest other region's. The choice is one minimum s-t cut over all
the band's pixels, the graph-cut textures of Kwatra et al. (2003):

* neighbouring pixels ``s, t`` that show layers ``a, b`` cost
  ``|L_a(s) - L_b(s)| + |L_a(t) - L_b(t)|`` (mean over channels; 0 when ``a = b``), so the
  join runs where the two layers look alike, along their elements' outlines rather than
  through them; the diagonal neighbours too (:data:`NEIGHBOURS`, 0.63), each pair weighted so
  that a join costs its Euclidean length: on 4 neighbours its Manhattan length made a chord
  along a row or a column the cheapest way across a curved outline;
* showing the other region's layer costs :data:`STRAY_COST` times how far the pixel is into
  its own region (the difference of the two regions' weights, 0 on the painted edge, 1 at the
  band's border; since 0.64 at least its distance from the other regions over the band's reach,
  the same on a straight edge: round a convex corner the weights' difference fell to 0 up to
  7 px in, and the join cut the other region's inner corner across), so the join stays near the
  paint where the layers are alike everywhere.

A region narrower than the band keeps its middle: a band pixel further from the painted edge
than half its region's thickness there shows its own layer whatever the cut (without it, a
painted line, a dot or a stripe narrower than ``transition`` vanished whole: removing it
shortened the join).

Each pixel's choice is binary (the lower or the higher of its two labels), which makes the
cost of two neighbours of the same pair of regions submodular, so the cut is exact for two
regions. Where three regions meet, a pair of neighbours may see different pairs; the few
non-submodular costs there are truncated (the usual approximation).

The result has no block staircase along the painted edge (quilting one image from all the
models' pools gave each block to one model, so a circle came out as a blocky polygon), and
no patch of one texture stranded inside another's region.
"""

from __future__ import annotations

import numpy as np

from ._errors import TGHopError

__all__ = ["cut_regions", "join_layers", "layer_boxes", "band_boxes", "in_band", "wraps", "STRAY_COST", "NEIGHBOURS"]

#: Cost of showing the other region's layer at the band's border (in the units of the
#: neighbour cost: a mean absolute difference of values in [0, 1], summed over two pixels).
STRAY_COST = 0.1
#: The neighbours whose pairs the cut weighs (0.63): the four of each pixel's 3x3 block after it, the
#: diagonals too. On 4 neighbours (0.62) a cut's length was its Manhattan length, so where two layers
#: were unlike everywhere it took the chord across a curved outline as a straight row or column.
NEIGHBOURS = ((0, 1), (1, 0), (1, 1), (1, -1))
#: Pair costs along the axes and the diagonals: a cut's cost its Euclidean length (Boykov and Kolmogorov
#: 2003: pi / 8 and pi / (8 sqrt 2) on 8 neighbours), about the 4-neighbour cost of a row or a column.
_AXIS = np.pi / 8
_DIAGONAL = np.pi / (8 * np.sqrt(2))
#: Costs are whole numbers for the max-flow solver: this many per unit.
_UNITS = 1000
#: Band pixels of separate parts solved together at least (several small parts: one maximum flow).
_PIECE = 4096


def layer_boxes(weights, *, tile=False):
    """The box each model's layer must cover: where its weight is above 0, one pixel more.

    Parameters
    ----------
    weights : ndarray, shape (K, H, W)
        Region weights (:func:`tghop.guided.region_weights`).
    tile : bool
        Regions wrap around: the whole image for a model whose weight reaches the image's edge
        (its layer must tile), its own box for one that stays inside (:func:`wraps`).

    Returns
    -------
    list of (slice, slice)
        One box per model (empty slices for a model with no weight anywhere).
    """
    k, h, w = weights.shape
    boxes = []
    for share in weights:
        some = share > 0
        rows, cols = np.flatnonzero(some.any(axis=1)), np.flatnonzero(some.any(axis=0))
        if rows.size == 0:
            boxes.append((slice(0, 0), slice(0, 0)))
            continue
        if tile and (some[0].any() or some[-1].any() or some[:, 0].any() or some[:, -1].any()):
            boxes.append((slice(0, h), slice(0, w)))
            continue
        boxes.append((slice(max(int(rows[0]) - 1, 0), min(int(rows[-1]) + 2, h)),
                      slice(max(int(cols[0]) - 1, 0), min(int(cols[-1]) + 2, w))))
    return boxes


def wraps(box, shape, tile):
    """Whether the layer over ``box`` of an image of ``shape`` (H, W) must tile: with ``tile``, a
    box of the whole image (:func:`layer_boxes` gives one to a region that reaches the edge)."""
    return bool(tile) and (box[0].start, box[0].stop, box[1].start, box[1].stop) == (0, shape[0], 0, shape[1])


def in_band(weights):
    """The pixels of the edges' bands, (H, W) bool: those whose largest weight (``weights`` (K, H, W),
    :func:`tghop.guided.region_weights`) is below 1."""
    return weights.max(axis=0) < 1.0 - 1e-6


def band_boxes(weights, *, tile=False, band=None):
    """The part of each model's layer that :func:`cut_regions` and :func:`join_layers` read:
    the box of the band pixels where its weight is above 0, one pixel more (without a band,
    ``transition`` below 2: of the pixels next to a painted edge).

    Every other pixel of the image shows its own region's layer, so a caller can write those
    as each layer is made and keep only these boxes of the layers (a disc in a large
    background keeps the disc's box of the background, not the whole image).

    Parameters
    ----------
    weights : ndarray, shape (K, H, W)
        Region weights (:func:`tghop.guided.region_weights`).
    tile : bool
        The band wraps around (its boxes are then the whole image where it reaches an edge).
    band : ndarray of bool, shape (H, W), optional
        :func:`in_band` of ``weights``, where the caller has it.

    Returns
    -------
    list of (slice, slice)
        One box per model, inside its :func:`layer_boxes` box (empty where it meets no band).
    """
    k, h, w = weights.shape
    band = in_band(weights) if band is None else band
    if not band.any():  # transition 0 or 1: no band, but join_layers still antialiases each painted edge
        band = _next_to_another(np.argmax(weights, axis=0), tile)
    boxes = []
    for share in weights:
        near = _grown(band & (share > 0), tile)
        rows, cols = np.flatnonzero(near.any(axis=1)), np.flatnonzero(near.any(axis=0))
        if rows.size == 0:
            boxes.append((slice(0, 0), slice(0, 0)))
        elif tile and (near[:, 0].any() or near[:, -1].any() or near[0].any() or near[-1].any()):
            boxes.append((slice(0, h), slice(0, w)))
        else:
            boxes.append((slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1)))
    return boxes


def _next_to_another(labels, tile):
    """The pixels with another label in their 3x3 neighbourhood (wrapping with ``tile``, else the
    edge's pixels repeated): the pixels :func:`join_layers` antialiases (but for those of a region
    1-2 px wide)."""
    padded = np.pad(labels, 1, mode="wrap" if tile else "edge")
    h, w = labels.shape
    out = np.zeros((h, w), dtype=bool)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            out |= padded[dy:dy + h, dx:dx + w] != labels
    return out


def _grown(mask, tile):
    """``mask`` grown by one pixel in each of the eight directions (wrapping with ``tile``)."""
    padded = np.pad(mask, 1, mode="wrap" if tile else "constant")
    h, w = mask.shape
    out = np.zeros_like(mask)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            out |= padded[dy:dy + h, dx:dx + w]
    return out


def cut_regions(labels, weights, layers, boxes, *, tile=False, stray_cost=STRAY_COST, band=None):
    """Which layer each pixel shows: its region's, or across a minimum cut in an edge's band.

    Parameters
    ----------
    labels : ndarray of int, shape (H, W)
        The painted region of each pixel, in ``[0, K)``.
    weights : ndarray, shape (K, H, W)
        The regions' weights (:func:`tghop.guided.region_weights` of ``labels``): a pixel
        is in a band where its largest weight is below 1.
    layers : sequence of K ndarrays, each shape (h_k, w_k, C)
        Model ``k``'s texture over ``boxes[k]``, float in [0, 1].
    boxes : sequence of K (slice, slice)
        Where each layer lies in the image (:func:`layer_boxes`).
    tile : bool
        Edges wrap around (a tileable image).
    stray_cost : float
        Cost of showing the other region's layer at the band's border.
    band : ndarray of bool, shape (H, W), optional
        :func:`in_band` of ``weights``, where the caller has it (not changed).

    Returns
    -------
    ndarray of int64, shape (H, W)
        The layer each pixel shows.
    """
    labels = np.asarray(labels)
    k = weights.shape[0]
    _check_labels(labels, "labels", weights.shape[1:], k)
    labels = labels.astype(np.int64, copy=False)
    if len(layers) != k:
        raise TGHopError(f"{k} regions' weights but {len(layers)} layers")
    h, w = labels.shape
    band = in_band(weights) if band is None else band
    if k < 2 or not band.any():
        return labels.copy()
    depth = _depth(labels, band, tile)
    reach = int(depth[band].max())
    band = band & ~_cores(labels, band, tile, depth)
    if not band.any():
        return labels.copy()
    ys, xs = np.nonzero(band)
    own = labels[ys, xs]
    w_at = weights[:, ys, xs]  # (K, n)
    own_weight = w_at[own, np.arange(own.size)]
    w_at[own, np.arange(own.size)] = -1.0
    other = np.argmax(w_at, axis=0)
    other_weight = w_at[other, np.arange(own.size)]
    del w_at
    lo, hi = np.minimum(own, other), np.maximum(own, other)
    n = own.size
    node = np.full((h, w), -1, dtype=np.int64)
    node[ys, xs] = np.arange(n)
    # Cost of each node's two choices: x = 0 shows ``lo``, x = 1 shows ``hi``.
    # How far into its own region: the weights' difference, or the pixel's distance from the other regions
    # where that is more (0.64; round a region's convex corner its box is mostly the other region's, so the
    # weights' difference fell to 0 up to 7 px into it and the join cut the other region's concave corner
    # across for nothing). On a straight edge the two are the same, (2 d + 1) / (2 reach + 1).
    far = (depth[ys, xs] - 0.5) / (reach + 0.5)
    stray = stray_cost * np.maximum(np.clip(own_weight - other_weight, 0.0, 1.0), far)
    cost = np.zeros((2, n))
    cost[0] = np.where(own == hi, stray, 0.0)
    cost[1] = np.where(own == lo, stray, 0.0)
    value = _Values(layers, boxes)
    heads, tails, caps = [], [], []
    for dy, dx in NEIGHBOURS:
        s_y, s_x, t_y, t_x = _pairs(band, dy, dx, tile)
        weight = _AXIS if dy == 0 or dx == 0 else _DIAGONAL
        s_node, t_node = node[s_y, s_x], node[t_y, t_x]
        s_in, t_in = s_node >= 0, t_node >= 0
        s_opts = _options(s_node, s_in, labels[s_y, s_x], lo, hi)
        t_opts = _options(t_node, t_in, labels[t_y, t_x], lo, hi)
        (e00, e01), (e10, e11) = value.differences(s_opts, t_opts, (s_y, s_x), (t_y, t_x), weight)
        only_s = s_in & ~t_in  # t shows its own layer: a cost for each of s's choices
        np.add.at(cost[0], s_node[only_s], e00[only_s])
        np.add.at(cost[1], s_node[only_s], e10[only_s])
        only_t = t_in & ~s_in
        np.add.at(cost[0], t_node[only_t], e00[only_t])
        np.add.at(cost[1], t_node[only_t], e01[only_t])
        both = s_in & t_in  # E(x_s, x_t) = A + (C - A) x_s + (D - C) x_t + (B + C - A - D)(1 - x_s) x_t
        a, b, c, d = e00[both], e01[both], e10[both], e11[both]
        np.add.at(cost[1], s_node[both], c - a)
        np.add.at(cost[1], t_node[both], d - c)
        heads.append(s_node[both])
        tails.append(t_node[both])
        caps.append(np.maximum(b + c - a - d, 0.0))  # 0 below: truncated where three regions meet
    out = labels.copy()
    out[ys, xs] = np.where(_min_cut(cost, np.concatenate(heads), np.concatenate(tails), np.concatenate(caps)), hi, lo)
    return out


def _min_cut(cost, heads, tails, caps):
    """The binary choice of ``n`` nodes of least total cost: ``cost`` (2, n) of each node's
    x = 0 and x = 1, and ``caps[i]`` paid where node ``heads[i]`` has x = 0 and ``tails[i]`` x = 1.
    One maximum flow (SciPy's, whole-number capacities) and the nodes the source still reaches
    after it (x = 0); (n,) bool, True for x = 1.

    Nodes joined by no pair cost (the bands of separate shapes, the blobs of a remix) are cut
    apart: the same nodes are reached, and a maximum flow's time grows faster than its graph."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    n = cost.shape[1]
    cost = cost - cost.min(axis=0)
    # A node on the sink's side (x = 1) cuts its edge from the source; on the source's side its edge to the sink.
    up, down, caps = (np.minimum(np.round(c * _UNITS), np.iinfo(np.int32).max).astype(np.int32)
                      for c in (cost[1], cost[0], caps))
    keep = caps > 0
    heads, tails, caps = heads[keep], tails[keep], caps[keep]
    n_parts, part = connected_components(csr_matrix((np.ones(caps.size, dtype=np.int8), (heads, tails)),
                                                    shape=(n, n)), directed=False)
    if n_parts == 1:
        return _sink_side(up, down, heads, tails, caps)
    # Parts in order, put together into pieces of at least _PIECE nodes (a small one's flow costs more to set up
    # than to run); each piece's nodes and pairs in order, numbered from 0.
    piece = (np.cumsum(np.bincount(part, minlength=n_parts)) // _PIECE)[part]
    nodes = np.argsort(piece, kind="stable")
    counts = np.bincount(piece)
    local = np.empty(n, dtype=np.int64)
    local[nodes] = np.arange(n) - np.repeat(np.cumsum(counts) - counts, counts)
    pairs = np.argsort(piece[heads], kind="stable")
    pair_counts = np.bincount(piece[heads], minlength=counts.size)
    ones = np.empty(n, dtype=bool)
    node_end, pair_end = np.cumsum(counts), np.cumsum(pair_counts)
    for p in np.flatnonzero(counts):
        mine = nodes[node_end[p] - counts[p]:node_end[p]]
        e = pairs[pair_end[p] - pair_counts[p]:pair_end[p]]
        ones[mine] = _sink_side(up[mine], down[mine], local[heads[e]], local[tails[e]], caps[e])
    return ones


def _sink_side(up, down, heads, tails, caps):
    """:func:`_min_cut` of ``n`` nodes in whole units: ``up`` (n,) the capacities from the source
    (paid at x = 1), ``down`` to the sink (paid at x = 0), ``caps`` of the pairs ``heads -> tails``."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import breadth_first_order, maximum_flow

    n = up.size
    source, sink = n, n + 1
    heads = np.concatenate([heads, np.full(n, source), np.arange(n)])
    tails = np.concatenate([tails, np.arange(n), np.full(n, sink)])
    caps = np.concatenate([caps, up, down])
    keep = caps > 0
    graph = csr_matrix((caps[keep], (heads[keep], tails[keep])), shape=(n + 2, n + 2))
    graph.sum_duplicates()
    flow = maximum_flow(graph, source, sink).flow
    residual = (graph - flow).tocsr()
    residual.data[residual.data < 0] = 0
    residual.eliminate_zeros()
    reached = breadth_first_order(residual, source, directed=True, return_predecessors=False)
    ones = np.ones(n, dtype=bool)
    ones[reached[reached < n]] = False
    return ones


def join_layers(shows, layers, boxes, *, tile=False, out=None):
    """The image: each pixel from the layer ``shows`` names, the join antialiased.

    A pixel next to a join (a pixel of its 3x3 neighbourhood shows another layer) is the mean
    of its neighbourhood's layers at it, weighted by how many of the nine show each, so the join
    is softened over about a pixel on each side rather than a staircase of pixels. A pixel in no
    3x3 block of its own layer (a line or a stroke 1-2 px wide, a dot; the image's edge, without
    ``tile``, ends a block) shows its own layer: the mean faded a 1 px line to a third of its
    contrast (its neighbours still take their share of it).

    Parameters
    ----------
    shows : ndarray of int, shape (H, W)
        The layer each pixel shows (:func:`cut_regions`).
    layers, boxes
        As :func:`cut_regions`; every layer of a pixel's neighbourhood must cover the pixel
        (as :func:`layer_boxes`'s do).
    tile : bool
        Neighbourhoods wrap around.
    out : ndarray, shape (H, W, C), optional
        The image with every pixel outside the layers' boxes already its own region's layer
        (then the boxes need to cover only the bands, :func:`band_boxes`); written in place.

    Returns
    -------
    ndarray, shape (H, W, C)
        ``out``, or a new array of the layers' dtype.
    """
    shows = np.asarray(shows)
    _check_labels(shows, "shows", shows.shape, len(layers))
    h, w = shows.shape
    if out is None:
        out = np.empty((h, w, layers[0].shape[2]), dtype=layers[0].dtype)
    for which, (layer, box) in enumerate(zip(layers, boxes)):
        mine = shows[box] == which
        out[box][mine] = layer[mine]
    small = shows.astype(np.min_scalar_type(len(layers)))
    padded = np.pad(small, 1, mode="wrap" if tile else "edge")
    offsets = [(dy, dx) for dy in (0, 1, 2) for dx in (0, 1, 2)]
    edge_y, edge_x = np.nonzero(_next_to_another(small, tile))
    thick = _in_a_block(small, edge_y, edge_x, tile, len(layers))
    edge_y, edge_x = edge_y[thick], edge_x[thick]  # a region 1-2 px wide keeps its own layer
    if edge_y.size == 0:
        return out
    near = np.stack([padded[edge_y + dy, edge_x + dx] for dy, dx in offsets])  # (9, n)
    values = _Values(layers, boxes)
    mean = np.zeros((edge_y.size, out.shape[2]), dtype=out.dtype)
    for which in range(len(layers)):
        count = (near == which).sum(axis=0)
        some = count > 0
        if some.any():
            labels = np.full(int(some.sum()), which)
            mean[some] += values.at(labels, edge_y[some], edge_x[some]) * (count[some, None] / out.dtype.type(9))
    out[edge_y, edge_x] = mean
    return out


def _in_a_block(labels, ys, xs, tile, outside):
    """Whether each pixel ``(ys[i], xs[i])`` of ``labels`` (H, W) lies in a 3x3 block of its own
    label (wrapping with ``tile``; else ``outside``, a label none has, beyond the image's edge)."""
    padded = np.pad(labels, 2, mode="wrap") if tile else np.pad(labels, 2, constant_values=outside)
    own = labels[ys, xs]
    same = [[padded[ys + dy, xs + dx] == own for dx in range(5)] for dy in range(5)]
    out = np.zeros(ys.size, dtype=bool)
    for cy in (1, 2, 3):
        for cx in (1, 2, 3):
            block = np.ones(ys.size, dtype=bool)
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    block &= same[cy + dy][cx + dx]
            out |= block
    return out


def _cores(labels, band, tile, depth=None):
    """The band's pixels that show their own region's layer: those further from the painted edge than
    half their region's thickness there. A pixel at distance ``d`` from the edge is one where no pixel
    of its region within ``r`` of it is ``2 d`` from the edge, ``r`` the power of two from ``2 d`` to
    ``4 d`` (the image's edge, without ``tile``, ends a region). A region narrower than the band
    keeps its middle (a line or a dot all of it); where a region runs on across the band from its
    edge none is."""
    from scipy.ndimage import maximum_filter

    depth = _depth(labels, band, tile) if depth is None else depth  # capped in place, above twice the band's
    # Only whether a depth reaches twice a band pixel's counts: capped there, 16 bits are enough (and
    # the maximum filters, most of the time, read half the bytes).
    np.minimum(depth, min(2 * int(depth[band].max()) + 1, np.iinfo(np.uint16).max), out=depth)
    depth = depth.astype(np.uint16)
    ys, xs = np.nonzero(band)
    at_depth = depth[ys, xs]
    scale = np.zeros(at_depth.shape, dtype=np.int8)  # log2 of each band pixel's r / 2
    np.ceil(np.log2(at_depth, out=np.zeros(at_depth.shape)), out=scale, casting="unsafe")
    mine = labels[ys, xs]
    cores = np.zeros_like(band)
    for k in np.unique(mine):
        region = labels == k
        own = np.where(region, depth, 0) if tile else None
        if not tile:  # the region's bounding box: outside it no pixel of the region counts
            rows, cols = np.flatnonzero(region.any(axis=1)), np.flatnonzero(region.any(axis=0))
        for j in np.unique(scale[mine == k]):
            at = np.flatnonzero((mine == k) & (scale == j))
            ay, ax, reach = ys[at], xs[at], 2 << int(j)
            if tile:
                thick = maximum_filter(own, size=2 * reach + 1, mode="wrap")[ay, ax]
            else:  # the filter over the part of that box its pixels' windows reach
                box = (slice(max(int(ay.min()) - reach, int(rows[0])), min(int(ay.max()) + reach, int(rows[-1])) + 1),
                       slice(max(int(ax.min()) - reach, int(cols[0])), min(int(ax.max()) + reach, int(cols[-1])) + 1))
                thick = maximum_filter(np.where(region[box], depth[box], 0), size=2 * reach + 1,
                                       mode="constant")[ay - box[0].start, ax - box[1].start]
            cores[ay, ax] = 2 * at_depth[at] > thick
    return cores


def _depth(labels, band, tile):
    """Each pixel's Chebyshev distance to the nearest pixel of another region (1 next to one),
    int32; wrapping with ``tile``, exact up to twice the ``band`` pixels' largest."""
    from scipy.ndimage import distance_transform_cdt

    far = ~_next_to_another(labels, tile)  # the distance to the others, plus one
    if not tile:
        return distance_transform_cdt(far, metric="chessboard") + 1
    h, w = far.shape
    pad = 64
    while True:  # the wrap as a margin wide enough for the distances read
        py, px = min(pad, h), min(pad, w)
        depth = distance_transform_cdt(np.pad(far, ((py, py), (px, px)), mode="wrap"),
                                       metric="chessboard")[py:py + h, px:px + w] + 1
        need = 2 * int(depth[band].max())
        if (need <= py or py == h) and (need <= px or px == w):  # or a whole period: all exact
            return depth
        pad = max(need, 2 * pad)


def _check_labels(labels, name, shape, k):
    """``labels`` an (H, W) integer map of ``shape`` with values in [0, k), or a one-line TGHopError."""
    if labels.ndim != 2 or labels.shape != tuple(shape) or labels.dtype.kind not in "iu" or labels.size == 0 \
            or labels.min() < 0 or labels.max() >= k:
        raise TGHopError(f"{name} must be an integer map of shape {tuple(shape)} with values in [0, {k}), got "
                         f"{labels.dtype} {labels.shape}")


def _pairs(band, dy, dx, tile):
    """Neighbour pairs ``(s, t = s + (dy, dx))`` with at least one pixel in ``band``, as four
    coordinate arrays (``dy`` 0 or 1, ``dx`` -1, 0 or 1); the last row or column pairs with the first
    with ``tile``."""
    h, w = band.shape
    if tile:
        shifted = np.roll(band, (-dy, -dx), axis=(0, 1))
        s_y, s_x = np.nonzero(band | shifted)
        return s_y, s_x, (s_y + dy) % h, (s_x + dx) % w
    x0 = max(0, -dx)  # the first column of s whose t lies in the image
    s_y, s_x = np.nonzero(band[:h - dy, x0:w - max(0, dx)] | band[dy:, x0 + dx:w - max(0, dx) + dx])
    s_x += x0
    return s_y, s_x, s_y + dy, s_x + dx


def _options(nodes, inside, labels, lo, hi):
    """The labels a pixel may show for x = 0 and x = 1: its pair's, or its own twice."""
    safe = np.where(inside, nodes, 0)
    return np.where(inside, lo[safe], labels), np.where(inside, hi[safe], labels)


class _Values:
    """The layers' values at pixels, each pixel from the layer its label names."""

    def __init__(self, layers, boxes):
        if len(layers) != len(boxes):
            raise TGHopError(f"{len(layers)} layers but {len(boxes)} boxes")
        self.layers, self.boxes = layers, boxes

    def at(self, which, y, x):
        """(n, C), the layers' dtype: layer ``which[i]`` at pixel ``(y[i], x[i])``."""
        c = self.layers[0].shape[2]
        out = np.empty((which.size, c), dtype=self.layers[0].dtype)
        for k, (layer, (rows, cols)) in enumerate(zip(self.layers, self.boxes)):
            m = np.flatnonzero(which == k)
            if m.size:  # flat positions in the layer: one take of whole rows of channels
                out[m] = layer.reshape(-1, c).take((y[m] - rows.start) * layer.shape[1] + (x[m] - cols.start), axis=0)
        return out

    def differences(self, s_options, t_options, s, t, weight=1.0):
        """``[[e(a, b) for b in t_options] for a in s_options]``, per pair ``e(a, b) = |L_a(s) - L_b(s)| +
        |L_a(t) - L_b(t)|``, each a mean over channels (float64; 0 where ``a = b``), times ``weight``: each
        layer's value at each pixel read once."""
        out = [[np.zeros(s[0].size) for _ in t_options] for _ in s_options]
        for y, x in (s, t):
            mine = [self.at(a, y, x) for a in s_options]
            theirs = [self.at(b, y, x) for b in t_options]
            for row, va in zip(out, mine):
                for total, vb in zip(row, theirs):
                    total += _channel_mean(np.abs(va - vb))
        if weight != 1.0:
            for row in out:
                for total in row:
                    total *= weight
        return out


def _channel_mean(values):
    """``values.mean(axis=1)`` of an (n, C) array, the same numbers: below 8 channels NumPy adds them in
    order and divides in their dtype, done here a channel at a time (a reduction over so short an axis
    is slow); from 8 on, NumPy's own."""
    c = values.shape[1]
    if c >= 8:
        return values.mean(axis=1)
    total = values[:, 0].copy()
    for i in range(1, c):
        total += values[:, i]
    total /= values.dtype.type(c)
    return total
