"""How images and conditions are put together from pieces (NumPy only).

* conditions: :func:`tile` and :func:`reflect_tile` repeat a co-occurrence tensor
  periodically or mirrored to any size; :func:`paint_condition` composes one from several,
  cell by cell (the paper's Sec. 5.2 control); :func:`boost_condition` scales one bin of
  every cell's matrix (the paper's Fig. 11 edit);
* windows (:meth:`tghop.cooc.model.CoocGAN.generate_windows`): :func:`window_layout` places
  overlapping training-size windows along an axis, :func:`mirror_pad` pads a condition for
  them, :func:`blend_weights` cross-fades neighbouring windows;
* :data:`ASSEMBLIES`, the ways :meth:`~tghop.cooc.model.CoocGAN.sample` makes an image, and
  the settings of its default, quilting.
"""

from __future__ import annotations

import numpy as np

from .._arrays import check_number
from .._errors import TGHopError
from .._limits import MAX_BOOST

__all__ = [
    "FEATHER",
    "ASSEMBLIES",
    "QUILT_POOL",
    "QUILT_TOLERANCE",
    "QUILT_DETAIL",
    "check_assembly",
    "paint_condition",
    "cell_labels",
    "boost_condition",
    "MAX_BOOST",
    "tile",
    "reflect_tile",
    "window_layout",
    "blend_weights",
    "mirror_pad",
]

#: Default blend width of :meth:`~tghop.cooc.model.CoocGAN.generate_windows`, as a fraction
#: of the windows' stride (1: the whole overlap, a sin^2 window; 0: hard seams).
FEATHER = 0.5

#: How :meth:`~tghop.cooc.model.CoocGAN.sample` makes an image from the generator.
ASSEMBLIES = ("quilt", "pass", "windows")

#: Generated crops quilted by :meth:`~tghop.cooc.model.CoocGAN.sample` (``assembly="quilt"``)
#: for crops of up to 64 px (:data:`~tghop.cooc.config.SMALL`); larger crops get
#: proportionally fewer, the same 4 Mpx of generator work, and at least 100
#: (:data:`~tghop.cooc.config.PAPER`'s 128 px crops: 250).
QUILT_POOL = 1000

#: Quilting's tolerance and detail preference for that assembly (see
#: :func:`tghop.quilting.quilt`; the values TGHop generates with).
QUILT_TOLERANCE = 0.1
QUILT_DETAIL = 0.5


def check_assembly(assembly) -> None:
    """A one-line :class:`TGHopError` unless ``assembly`` is one of :data:`ASSEMBLIES`.

    Parameters
    ----------
    assembly : str
        ``"quilt"``, ``"pass"`` or ``"windows"`` (anything else is refused).

    Raises
    ------
    TGHopError
        Naming the allowed values and the one given.
    """
    if assembly not in ASSEMBLIES:
        raise TGHopError(f"assembly must be one of {', '.join(ASSEMBLIES)}, got {assembly!r}")


def paint_condition(tensors, labels):
    """Compose a co-occurrence tensor from several, cell by cell: ``out[:, y, x] = tensors[labels[y, x]][:, y, x]``.

    Each source is tiled (repeated periodically) to the label map's size first, so a
    source may be one crop's tensor. This is the paper's Sec. 5.2 / Fig. 14 control:
    spatially varying statistics for one generated image.

    Parameters
    ----------
    tensors : sequence of ndarray, each shape (k*k, h_i, w_i)
    labels : array_like of int, shape (h, w)
        Index of the source of each cell.

    Returns
    -------
    ndarray, shape (k*k, h, w), float64
    """
    labels = np.asarray(labels)
    if labels.ndim != 2 or labels.dtype.kind not in "iu":
        raise TGHopError(f"labels must be a 2-D integer array, got shape {labels.shape} and dtype {labels.dtype}")
    srcs = [np.asarray(t, dtype=np.float64) for t in tensors]
    if not srcs or any(t.ndim != 3 for t in srcs) or len({t.shape[0] for t in srcs}) > 1:
        raise TGHopError("tensors must be one or more (k*k, h, w) co-occurrence tensors with the same k")
    if labels.min() < 0 or labels.max() >= len(srcs):
        raise TGHopError(f"labels must lie in 0..{len(srcs) - 1}, got {labels.min()}..{labels.max()}")
    h, w = labels.shape
    tiled = np.stack([tile(t, h, w) for t in srcs])  # (n, k*k, h, w)
    return np.take_along_axis(tiled, labels[None, None], axis=0)[0]


def cell_labels(labels, s: int) -> np.ndarray:
    """The label of every condition cell of ``s`` x ``s`` pixels over a pixel label map: its centre
    pixel's (the last row or column's for a cell past the edge), for :func:`paint_condition`
    (``tghop cooc edit --mask`` and the web server's edit).

    Parameters
    ----------
    labels : array_like, shape (H, W)
    s : int
        The cells' side in pixels (the model's ``s``).

    Returns
    -------
    ndarray, shape (ceil(H / s), ceil(W / s))
    """
    labels = np.asarray(labels)
    h, w = labels.shape
    rows = np.minimum(np.arange(-(-h // s)) * s + s // 2, h - 1)
    cols = np.minimum(np.arange(-(-w // s)) * s + s // 2, w - 1)
    return labels[rows][:, cols]


def boost_condition(cond, a: int, b: int, factor: float) -> np.ndarray:
    """Multiply bin ``M(a, b)`` (and ``M(b, a)``) of every cell's co-occurrence matrix by
    ``factor``: more (``factor > 1``) or fewer (``< 1``) neighbouring pixels of colour
    clusters ``a`` and ``b`` (the paper's Fig. 11). :meth:`CoocGAN.generate
    <tghop.cooc.model.CoocGAN.generate>` re-normalises each cell to sum to 1.

    Parameters
    ----------
    cond : array_like, shape (k*k, h, w)
        Co-occurrence tensor (row-stacked ``k x k`` matrices).
    a, b : int
        Colour clusters, each in ``0..k-1``.
    factor : float
        From 0 to :data:`MAX_BOOST` (1000: more changes next to nothing, and near 1e308 the
        cells' sums overflowed to infinity).

    Returns
    -------
    ndarray, shape (k*k, h, w), float64
        A boosted copy.
    """
    cond = np.array(cond, dtype=np.float64)
    k = int(round(np.sqrt(cond.shape[0]))) if cond.ndim == 3 else 0
    if k == 0 or k * k != cond.shape[0]:
        raise TGHopError(f"cond must be a (k*k, h, w) co-occurrence tensor, got shape {cond.shape}")
    ok = all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and 0 <= v < k for v in (a, b))
    if not ok:
        raise TGHopError(f"the boosted clusters must lie in 0..{k - 1} (this model has {k} colour clusters), "
                         f"got {a!r} and {b!r}")
    factor = check_number(factor, "the factor")
    if factor > MAX_BOOST:
        raise TGHopError(f"the factor must be at most {MAX_BOOST:,.0f}, got {factor:g}")
    cond[a * k + b] *= factor
    if a != b:
        cond[b * k + a] *= factor
    return cond


def tile(t: np.ndarray, h: int, w: int, offset=(0, 0)) -> np.ndarray:
    """Periodic tiling of a ``(c, th, tw)`` tensor to ``(c, h, w)`` from ``offset``.

    Parameters
    ----------
    t : ndarray, shape (c, th, tw)
        A co-occurrence tensor, or any array with cells on its last two axes.
    h, w : int
        Output cells (rows, columns); larger or smaller than ``(th, tw)``.
    offset : (int, int)
        Cell of ``t`` (row, column; taken modulo ``(th, tw)``, negative allowed) placed at
        the output's ``[:, 0, 0]``.

    Returns
    -------
    ndarray, shape (c, h, w)
        ``out[:, y, x] = t[:, (y + offset[0]) % th, (x + offset[1]) % tw]``; ``t``'s dtype.
    """
    rows = (np.arange(h) + offset[0]) % t.shape[1]
    cols = (np.arange(w) + offset[1]) % t.shape[2]
    return t[:, rows][:, :, cols]


def reflect_tile(t: np.ndarray, h: int, w: int, offset=(0, 0)) -> np.ndarray:
    """Mirror tiling (..., a b c c b a a b ...) of ``(c, th, tw)`` to ``(c, h, w)``: no jumps at the joins.

    Parameters
    ----------
    t : ndarray, shape (c, th, tw)
        A co-occurrence tensor, or any array with cells on its last two axes.
    h, w : int
        Output cells (rows, columns).
    offset : (int, int)
        Position (row, column) in the mirrored period of ``2 * th`` by ``2 * tw`` cells
        placed at the output's ``[:, 0, 0]``; ``(-p, -q)`` starts ``p`` rows and ``q``
        columns before ``t`` (as :func:`mirror_pad`).

    Returns
    -------
    ndarray, shape (c, h, w)
        ``t``'s dtype; each edge cell repeated once at a join.
    """

    def index(n, size, start):
        period = 2 * size
        i = (np.arange(n) + start) % period
        return np.where(i < size, i, period - 1 - i)

    return t[:, index(h, t.shape[1], offset[0])][:, :, index(w, t.shape[2], offset[1])]


def window_layout(length: int, n: int, stride: int):
    """Windows along one axis of ``length`` cells: ``(starts, (pad_before, pad_after), window)``.

    Windows are ``n`` cells long and ``stride`` apart; window ``t`` contributes the cells
    ``[t*stride, (t+1)*stride)`` of the image (its centre), so the axis is padded by the
    margin ``(n - stride) // 2`` before and up to the last window's end after. An axis of
    at most ``n`` cells is one window of its own length, unpadded.

    Parameters
    ----------
    length : int
        Cells along the axis (of the condition to generate for).
    n : int
        Window length in cells (the training crops' condition size).
    stride : int
        Cells between window starts, at most ``n``.

    Returns
    -------
    starts : list of int
        Each window's first cell in the padded axis: ``0, stride, 2 * stride, ...``,
        ``ceil(length / stride)`` of them (``[0]`` for a short axis).
    pads : (int, int)
        Cells to pad before and after (:func:`mirror_pad`); ``(0, 0)`` for a short axis.
    window : int
        Window length: ``n``, or ``length`` for an axis of at most ``n`` cells.
    """
    if length <= n:
        return [0], (0, 0), length
    margin = (n - stride) // 2
    count = -(-length // stride)
    after = (count - 1) * stride + n - margin - length
    return [t * stride for t in range(count)], (margin, after), n


def blend_weights(size: int, lo: int, hi: int, feather: int, blend: bool) -> np.ndarray:
    """Per-pixel weight of a window along one axis: 1 on ``[lo, hi)``, raised-cosine ramps
    ``feather`` pixels wide centred on ``lo`` and ``hi``; a neighbour's ramp is the
    complement, so overlapping windows' weights sum to one. All ones if ``not blend``.

    Parameters
    ----------
    size : int
        The window's length in pixels.
    lo, hi : int
        The window's own part, ``[lo, hi)`` pixels (its centre of ``stride`` cells).
    feather : int
        Ramp width in pixels; 0 or less: hard steps at ``lo`` and ``hi``.
    blend : bool
        False for an axis of a single window: no ramps, all ones.

    Returns
    -------
    ndarray, shape (size,), float64
        Weights in [0, 1], of pixel centres ``0.5, 1.5, ...``.
    """
    if not blend:
        return np.ones(size)
    x = np.arange(size) + 0.5

    def ramp(t):
        if feather <= 0:
            return (t >= 0).astype(np.float64)
        return 0.5 - 0.5 * np.cos(np.pi * np.clip(t / feather + 0.5, 0.0, 1.0))

    return ramp(x - lo) * ramp(hi - x)


def mirror_pad(t: np.ndarray, pads_y, pads_x) -> np.ndarray:
    """Mirror padding (edge cell repeated) of a ``(c, h, w)`` array: :func:`reflect_tile`
    started ``pads_y[0]`` rows and ``pads_x[0]`` columns before the array.

    Parameters
    ----------
    t : ndarray, shape (c, h, w)
        A condition or a noise array.
    pads_y, pads_x : (int, int)
        Rows (columns) to add before and after, each at most ``h`` (``w``) for a plain
        mirror (:func:`window_layout`'s pads).

    Returns
    -------
    ndarray, shape (c, h + sum(pads_y), w + sum(pads_x))
        ``t`` itself when nothing is padded, else a new array of ``t``'s dtype.
    """
    if not any(pads_y) and not any(pads_x):
        return t
    _, h, w = t.shape
    return reflect_tile(t, h + sum(pads_y), w + sum(pads_x), offset=(-pads_y[0], -pads_x[0]))

