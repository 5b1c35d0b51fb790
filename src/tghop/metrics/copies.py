"""How new a result is: nearest-patch distances to the exemplar (novelty, copied,
copied_textured), between results (diversity), and within one image (self_repetition)."""

from __future__ import annotations

import itertools

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .._errors import TGHopError
from .._images import check_image
from .._arrays import check_int, check_number
from .common import pair, counter, check_patch_size, check_seed, sample_patches, without_alpha

__all__ = ["novelty", "copied", "diversity", "TEXTURED_STD", "copied_textured", "self_repetition"]

# ---------------------------------------------------------------------------------------
# Novelty and diversity: nearest-patch distances
# ---------------------------------------------------------------------------------------


_NEAREST_CHUNK = 8192  # reference patches compared at once: a (max_patches, 8192) float32 block


def _nearest_chunks(shape, patch_size: int) -> int:
    """How many chunks :func:`_nearest_patch_rms` searches a reference of ``shape`` (H, W, ...) in."""
    nh, nw = shape[0] - patch_size + 1, shape[1] - patch_size + 1
    return -(-nh // max(1, _NEAREST_CHUNK // nw))


def _nearest_patch_rms(reference: np.ndarray, query: np.ndarray, patch_size: int, max_patches: int, seed: int,
                       tick=None, within=None):
    """RMS distance of sampled ``query`` patches to their nearest ``reference`` patch
    (:func:`_nearest_rms` of up to ``max_patches`` random patches of ``query``, seeded;
    ``within`` as there).

    Returns
    -------
    ndarray, shape (n_query,), float64
    """
    n_total = (query.shape[0] - patch_size + 1) * (query.shape[1] - patch_size + 1)
    rng = np.random.default_rng((int(seed), 2))
    q = sample_patches(query, patch_size, min(int(max_patches), n_total), rng)  # (n, d) float64
    return _nearest_rms(reference, q, patch_size, tick, within)


def _block_means(x: np.ndarray, block: int) -> np.ndarray:
    """``block`` x ``block`` means of windows ``x`` (n, C, P, P): (n, C * (P / block)^2) float32."""
    n, c, p = x.shape[0], x.shape[1], x.shape[2]
    k = p // block
    return x.reshape(n, c, k, block, k, block).mean(axis=(3, 5)).reshape(n, -1).astype(np.float32)


def _box_sums(x: np.ndarray, size: int) -> np.ndarray:
    """Sum of every stride-1 ``size`` x ``size`` window over the first two axes of ``x``
    (a float64 summed-area table): shape ``(H - size + 1, W - size + 1, ...)``."""
    s = np.zeros((x.shape[0] + 1, x.shape[1] + 1) + x.shape[2:])
    np.cumsum(x, axis=0, dtype=np.float64, out=s[1:, 1:])
    np.cumsum(s[1:, 1:], axis=1, out=s[1:, 1:])
    return s[size:, size:] - s[:-size, size:] - s[size:, :-size] + s[:-size, :-size]


def _strip_block_means(strip: np.ndarray, p: int, block: int, nw: int) -> np.ndarray:
    """:func:`_block_means` of every ``p`` x ``p`` window of ``strip`` (h, W, C) whose
    rows lie in it (``h - p + 1`` rows of ``nw`` windows), from one box-mean image:
    ((h - p + 1) * nw, C * (p / block)^2) float32."""
    rows, k = strip.shape[0] - p + 1, p // block
    boxes = _box_sums(strip, block) / (block * block)
    parts = [boxes[a * block: a * block + rows, b * block: b * block + nw] for a in range(k) for b in range(k)]
    return np.stack(parts, axis=-1).reshape(rows * nw, -1).astype(np.float32)  # (C, a, b) as _block_means


#: Block sides of the lower bound that lets :func:`_nearest_rms` skip queries far from a chunk.
_BOUND_BLOCKS = (4, 2)


def _nearest_rms(reference: np.ndarray, q: np.ndarray, patch_size: int, tick=None, within=None) -> np.ndarray:
    """RMS distance of each window ``q`` (n, P * P * C), float64 in the order of
    :func:`~numpy.lib.stride_tricks.sliding_window_view`'s (C, P, P), to its nearest
    ``patch_size`` window of ``reference`` (H, W, C).

    Every stride-1 window of ``reference`` is a candidate. Neighbours are found with
    float32 matrix products (``|q|^2 - 2 q.r + |r|^2``, chunked over the reference rows
    to bound memory: about ``n x 8192`` floats at a time, whatever the image sizes; each
    chunk's rows of pixels are made float32 before their windows are cut, which copies a
    quarter of the bytes of cutting them in float64 first) and their distances recomputed
    exactly in float64, so a verbatim copy scores exactly 0. ``tick()``, if given, is
    called once after each chunk (:func:`_nearest_chunks` of them).

    With ``within`` (an RMS distance), only whether a window lies nearer than ``within``
    matters: a window's 4 x 4 (or 2 x 2) block means give a lower bound of its distance
    (``|q - r|^2 >= block^2 |means(q) - means(r)|^2``, each block's mean being its
    projection on the constant vectors), and a query is compared with a chunk's windows
    only where the bound of one of them is below ``within``, and then only with the windows
    whose bound is below ``within`` for some such query. Distances of ``within`` or
    more may then be reported as ``inf``; those below are the same as without it.

    Returns
    -------
    ndarray, shape (n,), float64
    """
    n, p = q.shape[0], patch_size
    d = q.shape[1]
    q32 = q.astype(np.float32)
    q_norm = (q32 * q32).sum(axis=1)
    q_m2 = -2.0 * q32  # (-2 q).r is exactly -2 (q.r): scaling by a power of two rounds nothing
    block = next((b for b in _BOUND_BLOCKS if p % b == 0 and b < p), None) if within is not None else None
    if block is not None:
        fq = _block_means(q.reshape(n, -1, p, p), block)
        # The bound in the block means' units; the margin is far above float32 rounding, so no
        # window within ``within`` is ever skipped (the exact distances decide).
        limit = float(within) ** 2 * d / block ** 2 + 1e-3
        half_gap = (0.5 * ((fq * fq).sum(axis=1) - np.float32(limit)))[:, None]
        fq_aug = np.concatenate([fq, np.ones((n, 1), np.float32)], axis=1)  # [fq | 1]
    nh, nw = reference.shape[0] - p + 1, reference.shape[1] - p + 1
    best = np.full(n, np.inf, dtype=np.float32)
    best_index = np.full(n, -1, dtype=np.int64)
    rows_per_chunk = max(1, _NEAREST_CHUNK // nw)
    for r0 in range(0, nh, rows_per_chunk):
        r1 = min(nh, r0 + rows_per_chunk)
        strip = reference[r0:r1 + p - 1].astype(np.float32)
        sel, cols = slice(None), None
        if block is not None:
            fr = _strip_block_means(strip, p, block, nw)
            # |fq|^2 - 2 fq.fr + |fr|^2 < limit, as fq.fr - |fr|^2 / 2 > (|fq|^2 - limit) / 2: one
            # product of [fq | 1] and [fr | -|fr|^2 / 2], no pass over it but the comparison.
            fr_aug = np.empty((fr.shape[0], fr.shape[1] + 1), dtype=np.float32)
            fr_aug[:, :-1] = fr
            fr_aug[:, -1] = -0.5 * (fr * fr).sum(axis=1)
            passes = np.matmul(fq_aug, fr_aug.T) > half_gap  # (n, windows of the chunk)
            sel = np.flatnonzero(passes.any(axis=1))
            # Only the windows that pass for some kept query: every window within ``within`` of a
            # query passes for it, so its nearest one, if within, is among them (the first of ties too).
            cols = np.flatnonzero(passes[sel].any(axis=0)) if sel.size else None
            del passes
        if block is None or sel.size:
            if cols is None:
                ref = sliding_window_view(strip, (p, p), axis=(0, 1)).reshape((r1 - r0) * nw, -1)
            else:
                ref = sliding_window_view(strip, (p, p), axis=(0, 1))[cols // nw, cols % nw].reshape(cols.size, -1)
            d2 = np.matmul(q_m2[sel], ref.T)
            d2 += (ref * ref).sum(axis=1)[None, :]
            local = d2.argmin(axis=1)
            value = d2[np.arange(d2.shape[0]), local] + q_norm[sel]
            better = value < best[sel]
            chosen = np.arange(n)[sel][better]
            best[chosen] = value[better]
            best_index[chosen] = (local[better] if cols is None else cols[local[better]]) + r0 * nw
        if tick is not None:
            tick()
    found = best_index >= 0
    rms = np.full(n, np.inf)
    rows, cols = np.divmod(best_index[found], nw)
    nearest = sliding_window_view(reference, (p, p), axis=(0, 1))[rows, cols].reshape(rows.size, d)
    rms[found] = np.sqrt(np.mean((q[found] - nearest) ** 2, axis=1))
    return rms


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
        Float in [0, 1], or uint8 / uint16 (scored as x / 255, x / 65535), at least ``patch_size`` on each side.
    patch_size : int
        Side of the compared patches (default 8).
    max_patches : int
        Result patches sampled, at least 1 (default 2,048); every exemplar patch is searched.
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
    with the exemplar's pixels times ``max_patches`` times the patch's values
    (``benchmarks/bench_cli.py`` times ``tghop evaluate``).
    """
    patch_size, seed = check_patch_size(patch_size), check_seed(seed)
    max_patches = check_int(max_patches, "max_patches")
    ex, res = pair(exemplar, result, min_size=patch_size)
    tick = counter(progress, "novelty", _nearest_chunks(ex.shape, patch_size))
    return float(_nearest_patch_rms(ex, res, patch_size, max_patches, int(seed), tick).mean())


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
        Float in [0, 1], or uint8 / uint16 (scored as x / 255, x / 65535), at least ``patch_size`` on each side.
    patch_size : int
        Side of the compared patches (default 16).
    threshold : float
        RMS difference (intensity units, 0 to 1) below which a patch is a copy
        (default 0.03, about 8 grey levels of 255).
    max_patches : int
        Result patches sampled, at least 1 (default 1,024); every exemplar patch is searched.
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
    patch_size, seed = check_patch_size(patch_size), check_seed(seed)
    threshold = check_number(threshold, "threshold", positive=True)
    max_patches = check_int(max_patches, "max_patches")
    ex, res = pair(exemplar, result, min_size=patch_size)
    tick = counter(progress, "copied", _nearest_chunks(ex.shape, patch_size))
    rms = _nearest_patch_rms(ex, res, patch_size, max_patches, int(seed), tick, within=threshold)
    return float(np.mean(rms < threshold))


def diversity(*results, patch_size: int = 8, max_patches: int = 2048, seed: int = 0, progress=None) -> float:
    """How different results of different seeds are; HIGHER means more diverse.

    Pixel-aligned differences say nothing for textures (two good samples differ
    everywhere; a shifted copy differs too), so this is the symmetric :func:`novelty` of
    one result with respect to another -- the mean RMS distance of each result's patches
    to their nearest patch in the other -- averaged over all pairs. Identical results
    score 0; a result and a crop of it, or two overlapping crops of one image, score above
    0 (each has patches the other lacks; about 0.01 for 64 x 64 crops of ``bricks`` 10 pixels apart).

    Parameters
    ----------
    *results : array_like, shape (H, W) or (H, W, C)
        Two or more results, or a single sequence of them: ``diversity(a, b)`` or
        ``diversity([a, b, c])``; each float in [0, 1], or uint8 / uint16 (scored as x / 255, x / 65535).
    patch_size, max_patches, seed
        As for :func:`novelty`.
    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"diversity"``, one unit per chunk of
        patches searched, over all pairs. Memory is bounded as for :func:`novelty`, and at
        most two results are held as float64 at a time (uint8 results stay uint8 until a pair
        needs them).

    Returns
    -------
    float
        Mean RMS distance in intensity units, >= 0.
    """
    if len(results) == 1 and not (isinstance(results[0], np.ndarray) and results[0].ndim <= 3):
        results = tuple(results[0])
    if len(results) < 2:
        raise TGHopError(f"diversity needs at least two results, got {len(results)}")
    patch_size, seed = check_patch_size(patch_size), check_seed(seed)
    max_patches = check_int(max_patches, "max_patches")
    # Each result is checked here, before any long work, and converted to float64 again when a pair
    # needs it: at most two converted results are held at once, not all of them (many large results).
    names = [f"result {i + 1}" for i in range(len(results))]
    results = [without_alpha(r, name) for r, name in zip(results, names)]  # RGBA: the alpha dropped, told (0.59)
    shapes = [check_image(r, min_size=patch_size, name=name).shape for r, name in zip(results, names)]
    to_rgb = len({shape[2] for shape in shapes}) > 1

    def image(i):
        img = check_image(results[i], min_size=patch_size, name=names[i])
        return np.repeat(img, 3, axis=2) if to_rgb and img.shape[2] == 1 else img

    pairs = list(itertools.combinations(range(len(results)), 2))
    tick = counter(progress, "diversity",
                   sum(_nearest_chunks(shapes[i], patch_size) + _nearest_chunks(shapes[j], patch_size)
                       for i, j in pairs))
    values = []
    for i in range(len(results) - 1):
        a = image(i)
        for j in range(i + 1, len(results)):
            b = image(j)
            values.append(_nearest_patch_rms(a, b, patch_size, max_patches, int(seed), tick).mean())
            values.append(_nearest_patch_rms(b, a, patch_size, max_patches, int(seed), tick).mean())
            del b
    return float(np.mean(values))



# ---------------------------------------------------------------------------------------
# Copies and repetition of textured windows
# ---------------------------------------------------------------------------------------

#: Standard deviation within a window (:func:`_window_std`) from which it counts as
#: textured in :func:`copied_textured` and :func:`self_repetition`: a flat window nearly
#: equals any flat window of its colour, which says nothing about copying.
TEXTURED_STD = 0.06


def _window_std(img: np.ndarray, size: int) -> np.ndarray:
    """``(H - size + 1, W - size + 1)`` standard deviation of every stride-1 ``size`` x
    ``size`` window: the root of the mean over channels of each channel's variance over the
    window's pixels (float64 summed-area tables). A flat window of any colour scores 0; a
    grey image, or one whose channels are equal, scores its pixels' standard deviation.
    (Before 0.20 the deviation was over pixels and channels together, so the spread between
    a colour's channels counted as texture: every window of an orange fur or a blue sky
    was "textured", docs/choices.md.)"""
    c = img.shape[2]
    n = float(size * size)
    x = np.asarray(img, dtype=np.float64)
    var = np.zeros((x.shape[0] - size + 1, x.shape[1] - size + 1))
    for k in range(c):
        mean = _box_sums(x[..., k], size) / n
        var += np.maximum(_box_sums(x[..., k] * x[..., k], size) / n - mean * mean, 0.0)
    return np.sqrt(var / c)


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
                    max_patches: int = 1024, seed: int = 0, progress=None) -> float:
    """:func:`copied` over the result's *textured* windows only; LOWER is better.

    A flat window (a smooth sky, a mortar line) nearly equals any flat exemplar window,
    so :func:`copied` counts it as copied whatever the method. Here only the result's
    ``patch_size`` x ``patch_size`` windows whose own standard deviation (each channel's
    over the window, root-mean-squared over the channels: a flat window of any colour has
    none) is at least ``min_std`` are sampled (up to ``max_patches``, seeded), and each
    counts as copied when some exemplar window (stride 1) is within RMS ``threshold``.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C), float in [0, 1] (or uint8 / uint16 as x / 255, x / 65535)
        Both at least ``patch_size`` a side; grey and colour are matched as :func:`pair` does.
    patch_size : int
        Window side in pixels.
    threshold : float
        RMS difference (in [0, 1] units) below which a window is a copy; positive.
    min_std : float
        Smallest standard deviation of a textured window.
    max_patches : int
        Most textured windows sampled from the result.
    seed : int
        Seed of the sample (an int, not a Generator: :func:`check_seed`).
    progress : callable, optional

    Returns
    -------
    float
        The fraction of sampled textured windows that are copies, in [0, 1]; **0 when the
        result has no textured window** (nothing textured was copied).

    Notes
    -----
    ``progress(stage, done, total)``: stage ``"copied_textured"``, one unit per chunk of
    exemplar rows searched. Memory is bounded as for :func:`copied`.
    """
    patch_size, seed = check_patch_size(patch_size), check_seed(seed)
    threshold = check_number(threshold, "threshold", positive=True)
    max_patches, min_std = check_int(max_patches, "max_patches"), check_number(min_std, "min_std")
    ex, res = pair(exemplar, result, min_size=patch_size)
    rng = np.random.default_rng((int(seed), 3))
    pos = _textured_positions(res, patch_size, min_std, max_patches, rng)
    n_chunks = _nearest_chunks(ex.shape, patch_size)
    tick = counter(progress, "copied_textured", n_chunks)
    if len(pos) == 0:
        for _ in range(n_chunks):
            tick()
        return 0.0
    rms = _nearest_rms(ex, _windows_at(res, pos, patch_size), patch_size, tick, within=threshold)
    return float(np.mean(rms < threshold))


def _box_features(img: np.ndarray) -> np.ndarray:
    """``(H - 3, W - 3, C)`` float32 means of every stride-1 4 x 4 box of ``img``."""
    return (_box_sums(img, 4) / 16.0).astype(np.float32)


def self_repetition(image, *, patch_size: int = 16, threshold: float = 0.03, min_std: float = TEXTURED_STD,
                    region: int = 1024, search: int = 1024, max_windows: int = 500, seed: int = 0,
                    progress=None) -> float:
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
    ``progress(stage, done, total)``: stage ``"self_repetition"``, one unit per chunk of
    search rows.

    It looks at one image only (no exemplar): :func:`tghop.metrics.evaluate` computes it
    for the result when asked by name (``metrics=[..., "self_repetition"]``, ``tghop
    evaluate --repetition``).

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C), float in [0, 1] (or uint8 / uint16 as x / 255, x / 65535)
        At least ``patch_size`` a side; scored in float32.
    patch_size : int
        Window side in pixels, a multiple of 4 (else :class:`~tghop.TGHopError`).
    threshold : float
        RMS difference (in [0, 1] units) below which two windows are the same; positive.
    min_std : float
        Smallest standard deviation of a textured (sampled) window.
    region : int
        Side of the central square the windows are sampled from (at most ``search``).
    search : int
        Side of the central square searched for repeats.
    max_windows : int
        Most windows sampled.
    seed : int
        Seed of the sample (:func:`check_seed`).
    progress : callable, optional

    Returns
    -------
    float
        The fraction of sampled windows that repeat, in [0, 1].
    """
    patch_size, seed = check_patch_size(patch_size), check_seed(seed)
    if patch_size % 4:
        raise TGHopError(f"patch_size must be a multiple of 4, got {patch_size}")
    threshold = check_number(threshold, "threshold", positive=True)
    max_windows, min_std = check_int(max_windows, "max_windows"), check_number(min_std, "min_std")
    region, search = check_int(region, "region"), check_int(search, "search")
    img = check_image(without_alpha(image, "image"), min_size=patch_size, name="image", dtype=np.float32)
    h, w = img.shape[:2]
    region = min(region, search)  # the sampled windows lie in the search area

    def centre(length, size):
        size = max(patch_size, min(length, int(size)))
        start = (length - size) // 2
        return start, start + size

    (qy0, qy1), (qx0, qx1) = centre(h, region), centre(w, region)
    (sy0, sy1), (sx0, sx1) = centre(h, search), centre(w, search)
    rng = np.random.default_rng((int(seed), 4))
    pos = _textured_positions(img[qy0:qy1, qx0:qx1], patch_size, min_std, max_windows, rng)
    nh, nw = sy1 - sy0 - patch_size + 1, sx1 - sx0 - patch_size + 1
    rows_per_chunk = max(1, 8192 // nw)
    n_chunks = -(-nh // rows_per_chunk)
    tick = counter(progress, "self_repetition", n_chunks)
    if len(pos) == 0:
        for _ in range(n_chunks):
            tick()
        return 0.0
    pos = pos + [qy0, qx0]  # image coordinates
    area = img[sy0:sy1, sx0:sx1]
    box = _box_features(area)
    offsets = [(4 * i, 4 * j) for i in range(patch_size // 4) for j in range(patch_size // 4)]
    nb = len(offsets) * img.shape[2]
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
    for r0 in range(0, nh, rows_per_chunk):
        tick()
        live = np.flatnonzero(~found)
        if live.size == 0:
            continue  # every window already repeats: the remaining chunks are only counted
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
