"""Stages 1..n: the hops, successive (channel-wise) Saab transforms on 2x2 blocks.

Hop 1 is a joint Saab transform of each 2x2xC block (12 values for RGB). Every later hop
is *channel-wise* (c/w Saab): each kept channel of the previous hop gets its own Saab
transform of its 2x2 blocks (4 values), and the hop keeps a chosen number of channels in
total over all parents. Each hop halves the spatial size: 32x32x3 -> 16x16xK1 -> 8x8xK2.

Channel choice in a c/w hop: the DC child of every parent is always kept (paper, Fig. 5:
"each group of channels is composed of one DC channel and several low-frequency AC
channels"); the AC children of all parents compete by energy, the mean squared response,
which is the squared error per block that dropping the channel would cost. The count
rule therefore counts the DC children too, so ``K2 >= K1``.
"""

from __future__ import annotations

import numpy as np

from ._arrays import check_array, forget_fit
from ._errors import TGHopError
from ._estimator import BaseEstimator, FourDInputMixin, TransformerMixin, check_is_fitted
from ._images import checked_image
from ._progress import report
from .patches import depth_to_space, space_to_depth
from .saab import Saab, select_channels
from .settings import check_channel_rule

__all__ = ["Hop", "HopStack", "stage_views"]


class Hop(FourDInputMixin, TransformerMixin, BaseEstimator):
    """One hop: a (channel-wise) Saab transform of non-overlapping 2x2 blocks.

    Parameters
    ----------
    n_channels : None, int, float or "knee", default=None
        Output channels to keep (see :func:`tghop.saab.select_channels`); None keeps all,
        which makes the hop exactly invertible.
    channelwise : bool, default=False
        False: one Saab transform of whole 2x2xC blocks (hop 1). True: one Saab transform
        per input channel on its 2x2 blocks (hops 2, 3, ...).

    Attributes
    ----------
    saabs_ : list of Saab
        One transform (joint) or one per input channel (channel-wise).
    kernels_ : ndarray, shape (K, 4 * C)
        All kept kernels of the hop as one matrix (block-structured for a c/w hop), acting
        on 2x2 blocks flattened as (row, column, channel).
    bias_ : ndarray, shape (K,)
        Bias of each output channel (zero for DC channels).
    channels_ : ndarray of int, shape (K, 2)
        For each output channel: (parent input channel, kernel index in that parent's
        Saab transform; 0 is DC). Parent is 0 for a joint hop. Grouped by parent.
    energy_ : ndarray, shape (K,)
        Energy of each output channel.
    n_channels_in_ : int
    """

    def __init__(self, n_channels=None, channelwise=False):
        self.n_channels = n_channels
        self.channelwise = channelwise

    def fit(self, X, y=None):
        """Learn the hop from ``X`` of shape (n, H, W, C), ``H`` and ``W`` even.

        Parameters
        ----------
        X : array_like, shape (n, H, W, C)
            Finite numbers (patches or spaces), ``H`` and ``W`` even, ``C >= 1``; its 2x2 blocks
            (stride 2) are the training vectors. Another shape raises :class:`~tghop.TGHopError`.
        y : None
            Ignored (scikit-learn's signature).

        Returns
        -------
        self
        """
        X = check_array(X, "X", "(n, H, W, C) with H and W even", ndim=4)
        if min(X.shape[1:]) < 1 or X.shape[1] % 2 or X.shape[2] % 2:
            raise TGHopError(f"X must have shape (n, H, W, C) with H and W even and C >= 1, got {X.shape}")
        blocks = space_to_depth(X).reshape(-1, 4 * X.shape[3])
        return self.fit_sums(_block_sums(blocks, 1 if self.channelwise else X.shape[3]))

    def fit_sums(self, sums):
        """Learn the hop from block statistics accumulated by :func:`_block_sums` (summed
        over any number of image tiles: the fit is the same as on all blocks at once).

        A failed fit leaves the hop unfitted.

        Parameters
        ----------
        sums : tuple
            ``(total, moment, max_sq, count)``: weighted sum (4C,) and sum of outer products (4C, 4C)
            of the blocks, the largest squared norm of each channel group, and the total weight (> 0).

        Returns
        -------
        self
        """
        forget_fit(self)
        try:
            return self._fit_sums(sums)
        except BaseException:
            forget_fit(self)
            raise

    def _fit_sums(self, sums):
        total, moment_sum, max_sq, count = sums
        rule = check_channel_rule(self.n_channels, "n_channels", none_ok=True)
        if not count > 0:
            raise TGHopError(f"a hop needs at least one block of weight > 0 to fit, got a total weight of {count}")
        c = self.n_channels_in_ = len(total) // 4
        if isinstance(rule, int) and rule > 4 * c:
            raise TGHopError(
                f"a hop on {c} input channel{'s' if c != 1 else ''} has at most {4 * c} channels, {rule} were "
                f"asked for; choose at most {4 * c}"
            )
        if isinstance(rule, int) and self.channelwise and rule < c:
            raise TGHopError(
                f"a channel-wise hop on {c} channel{'s' if c != 1 else ''} keeps at least {c} (one DC child "
                f"each), {rule} {'was' if rule == 1 else 'were'} asked for; choose at least {c}"
            )
        mean, moment = total / count, moment_sum / count
        if not self.channelwise:
            saab = Saab(n_components=rule).fit_moments(mean, moment, max_sq[0])
            self.saabs_ = [saab]
            self.channels_ = np.column_stack([np.zeros_like(saab.channels_), saab.channels_])
        else:
            # Parent k's 2x2 block is at positions k, c + k, 2c + k, 3c + k of a block row.
            self.saabs_ = [
                Saab().fit_moments(mean[k::c], moment[k::c, k::c], max_sq[k]) for k in range(c)
            ]
            # Candidates: every AC child of every parent; DC children are always kept.
            parent = np.repeat(np.arange(c), 3)
            child = np.tile(np.arange(1, 4), c)
            energy = np.concatenate([s.energy_[1:4] for s in self.saabs_])
            chosen = select_channels(energy, rule, n_fixed=c)
            for k, saab in enumerate(self.saabs_):
                saab.keep([0] + child[chosen][parent[chosen] == k].tolist())
            self.channels_ = np.array(
                [(k, j) for k, s in enumerate(self.saabs_) for j in s.channels_], dtype=np.int64
            )
        self.energy_ = np.array([self.saabs_[k].energy_[j] for k, j in self.channels_])
        self._build_matrix()
        return self

    def _build_matrix(self):
        """One (K, 4C) kernel matrix and (K,) bias for the whole hop (block-diagonal if c/w)."""
        c = self.n_channels_in_
        if not self.channelwise:
            self.kernels_ = self.saabs_[0].kernels_
            self.bias_ = self.saabs_[0].bias_ * (self.channels_[:, 1] != 0)
            return
        kernels = np.zeros((len(self.channels_), 4 * c))
        row = 0
        for k, saab in enumerate(self.saabs_):
            kept = saab.kernels_.shape[0]
            kernels[row: row + kept, k::c] = saab.kernels_
            row += kept
        self.kernels_ = kernels
        self.bias_ = np.array([self.saabs_[k].bias_ * (j != 0) for k, j in self.channels_])

    def _to_arrays(self, i) -> dict:
        """This hop's learned arrays, named ``hop<i>.*`` (parameters) and ``index.hop<i>_*``."""
        if self.channelwise:
            # Each kept channel: one 4-tap kernel of its parent's Saab transform.
            kernels = np.array([self.saabs_[p].kernels_[list(self.saabs_[p].channels_).index(j)]
                                for p, j in self.channels_])
            bias = np.array([s.bias_ for s in self.saabs_])
        else:
            kernels, bias = self.saabs_[0].kernels_, np.array([self.saabs_[0].bias_])
        return {f"hop{i}.kernels": kernels, f"hop{i}.bias": bias,
                f"index.hop{i}_channels": self.channels_, f"index.hop{i}_energy": self.energy_}

    def _state_meta(self) -> dict:
        """This hop's part of a model file's metadata: "channelwise", "n_channels_in" and "saab_energy", each
        Saab's :attr:`~tghop.saab.Saab.energy_` (every channel's, kept or not: a few numbers per input channel;
        left out when a loaded hop has none). Metadata, not an array: a new array would need a new format version,
        which older tghop refuses, for numbers generation never uses."""
        out = {"channelwise": self.channelwise, "n_channels_in": self.n_channels_in_}
        if all("energy_" in vars(s) for s in self.saabs_):
            out["saab_energy"] = [s.energy_.tolist() for s in self.saabs_]
        return out

    def _saab_energy(self, info, d):
        """The Saabs' energies of the metadata ``info`` (:meth:`_state_meta`), checked: (n_saabs, ``d``), or None
        (files of tghop 0.55 and before)."""
        energy = info.get("saab_energy")
        if energy is None:
            return None
        n = len(self.saabs_)
        if (not isinstance(energy, list) or len(energy) != n
                or not all(isinstance(row, list) and len(row) == d for row in energy)
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for row in energy for v in row)):
            raise TGHopError(f"the metadata's saab_energy of a hop is not {n} list(s) of {d} numbers")
        out = np.array(energy, dtype=np.float64)
        if not np.isfinite(out).all():  # not its sign: an empty channel's energy is 0 to rounding, either way
            raise TGHopError("the metadata's saab_energy of a hop holds NaN or infinite energies")
        return out

    @classmethod
    def _from_arrays(cls, i, info, arrays, n_channels=None):
        """Inverse of :meth:`_to_arrays`; ``info`` holds "channelwise", "n_channels_in" and (since 0.56)
        "saab_energy" (:meth:`_state_meta`); ``n_channels``: the rule it was fitted with (its stack's), a
        parameter as after ``fit``."""
        hop = cls(n_channels=n_channels, channelwise=bool(info["channelwise"]))
        c = hop.n_channels_in_ = int(info["n_channels_in"])
        hop.channels_ = arrays[f"index.hop{i}_channels"].astype(np.int64)
        hop.energy_ = arrays[f"index.hop{i}_energy"].astype(np.float64)
        kernels = arrays[f"hop{i}.kernels"].astype(np.float64)
        bias = arrays[f"hop{i}.bias"].astype(np.float64)
        hop.saabs_ = []
        for p in (range(c) if hop.channelwise else [0]):
            saab = Saab() if hop.channelwise else Saab(n_components=n_channels)  # as fit makes them
            rows = hop.channels_[:, 0] == p
            saab.channels_ = hop.channels_[rows, 1]
            saab.kernels_ = kernels[rows]
            saab.bias_ = float(bias[p])
            saab.n_features_in_ = kernels.shape[1]
            hop.saabs_.append(saab)
        energy = hop._saab_energy(info, kernels.shape[1])
        for saab, row in zip(hop.saabs_, energy if energy is not None else [None] * len(hop.saabs_)):
            if row is None:
                saab._energy_unknown_ = True
            else:
                saab.energy_ = row
        hop._build_matrix()
        return hop

    @staticmethod
    def _array_specs(i, channelwise, c, k):
        """The arrays of hop ``i`` (``c`` input, ``k`` output channels) for the checks of
        :mod:`tghop.modelfile`: ``(name, shape, kind, says, rules)`` each."""
        inputs = 4 if channelwise else 4 * c
        says = f"the metadata says {k} channels"
        return (
            (f"hop{i}.kernels", (k, inputs), "f", f"{says} of {inputs} inputs", ()),
            (f"hop{i}.bias", (c if channelwise else 1,), "f",
             f"the metadata says one bias per input channel, {c}" if channelwise else "one bias", ()),
            (f"index.hop{i}_channels", (k, 2), "i", f"{says}, each (parent, kernel)",
             (("index", c if channelwise else 1, 0), ("index", inputs, 1), ("nondecreasing", 0))),
            (f"index.hop{i}_energy", (k,), "f", f"{says}, one energy each", (("unbounded",),)),
        )

    @property
    def n_channels_out_(self) -> int:
        """Number of output channels K."""
        check_is_fitted(self, "channels_")
        return len(self.channels_)

    def transform(self, X):
        """``(n, H, W, C)`` -> ``(n, H/2, W/2, K)``.

        Parameters
        ----------
        X : array_like, shape (n, H, W, C)
            Finite numbers, ``H`` and ``W`` even, ``C`` the fit's (else :class:`~tghop.TGHopError`).

        Returns
        -------
        ndarray of float64, shape (n, H/2, W/2, K)
            Each 2x2 block's responses to the kept kernels, plus their biases.
        """
        check_is_fitted(self, "kernels_")
        X = check_array(X, "X", f"(n, H, W, {self.n_channels_in_})", ndim=4, min_rows=0)  # numbers, finite
        if X.shape[3] != self.n_channels_in_:
            raise TGHopError(f"this hop takes (n, H, W, {self.n_channels_in_}) arrays, got shape {X.shape}")
        blocks = space_to_depth(X)
        return blocks @ self.kernels_.T + self.bias_

    def inverse_transform(self, Y):
        """``(n, h, w, K)`` -> ``(n, 2h, 2w, C)``; discarded channels are zero.

        Parameters
        ----------
        Y : array_like, shape (n, h, w, K)
            Finite numbers, one channel per kept kernel (as :meth:`transform` gives them).

        Returns
        -------
        ndarray of float64, shape (n, 2h, 2w, C)
        """
        check_is_fitted(self, "kernels_")
        Y = check_array(Y, "Y", f"(n, h, w, {self.n_channels_out_})", ndim=4, min_rows=0)  # numbers, finite
        if Y.shape[3] != self.n_channels_out_:
            raise TGHopError(f"this hop inverts (n, h, w, {self.n_channels_out_}) arrays, got shape {Y.shape}")
        return depth_to_space((Y - self.bias_) @ self.kernels_)


def _add_sums(a, b):
    """Combine two :func:`_block_sums` results (None is empty)."""
    if a is None:
        return b
    return a[0] + b[0], a[1] + b[1], np.maximum(a[2], b[2]), a[3] + b[3]


def _block_sums(blocks, group, weights=None, chunk=1 << 18):
    """Weighted sum, sum of outer products, largest squared norm per channel group, and
    total weight of blocks, in one pass.

    Parameters
    ----------
    blocks : ndarray, shape (m, 4 * C)
    group : int
        1 for per-channel norms (c/w hops: norm of each channel's 4 values), ``C`` for
        the norm of the whole block (joint hop).
    weights : ndarray, shape (m,), optional
        Multiplicity of each block (default 1).

    Returns
    -------
    total : (4C,), moment : (4C, 4C), max_sq : (C // group,), count : float
    """
    m, d = blocks.shape
    c = d // 4
    total = np.zeros(d)
    moment = np.zeros((d, d))
    max_sq = np.zeros(c // group)
    count = 0.0
    for start in range(0, m, chunk):
        b = blocks[start: start + chunk]
        if weights is not None:
            w = weights[start: start + chunk]
            b = b[w > 0]
            w = w[w > 0]
            count += w.sum()
            total += w @ b
            moment += (b * w[:, None]).T @ b
        else:
            count += b.shape[0]
            total += b.sum(axis=0)
            moment += b.T @ b
        if b.shape[0]:
            sq = (b * b).reshape(-1, 4, c // group, group).sum(axis=(1, 3))
            np.maximum(max_sq, sq.max(axis=0), out=max_sq)
    return total, moment, max_sq, count


def _check_origins(origins, shape, patch_size):
    """:meth:`HopStack.fit_image`'s ``origins``: (n, 2) ints, n >= 1, every patch inside the image."""
    arr = np.asarray(origins)
    if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) == 0:
        raise TGHopError(f"origins must have shape (n, 2), n >= 1 (row, column of each patch), got {arr.shape}")
    if arr.dtype.kind not in "iu":
        if arr.dtype.kind != "f" or not np.array_equal(arr, np.round(arr)):  # NaN is never equal
            raise TGHopError(f"origins must be integers (row, column), got an array of {arr.dtype}")
    arr = arr.astype(np.int64, copy=False)
    h, w = shape[:2]
    lo, hi = arr.min(axis=0), arr.max(axis=0)
    if lo.min() < 0 or hi[0] > h - patch_size or hi[1] > w - patch_size:
        raise TGHopError(f"origins must put every {patch_size}x{patch_size} patch inside the {h}x{w} image "
                         f"(rows in [0, {h - patch_size}], columns in [0, {w - patch_size}]), got rows in "
                         f"[{lo[0]}, {hi[0]}] and columns in [{lo[1]}, {hi[1]}]")
    return arr


#: Side of the image tiles :meth:`HopStack.fit_image` works on (memory per tile: about
#: 250 bytes per pixel of a (TILE + patch)^2 square at the second hop).
TILE = 1024


def _tiles(image, origins, patch_size, tile):
    """Group patch origins by tile: a list of (crop function, local origins, rows)."""
    h, w = image.shape[:2]
    key = origins // tile
    if len(origins) == 0:
        return []
    order = np.lexsort((key[:, 1], key[:, 0]))
    bounds = np.flatnonzero(np.any(np.diff(key[order], axis=0) != 0, axis=1)) + 1
    out = []
    for rows in np.split(order, bounds):
        y0, x0 = (key[rows[0]] * tile).tolist()
        y1 = min(h, int(origins[rows, 0].max()) + patch_size)
        x1 = min(w, int(origins[rows, 1].max()) + patch_size)

        def crop(y0=y0, x0=x0, y1=y1, x1=x1):
            part = image[y0:y1, x0:x1]
            if part.dtype == np.uint8:
                return part / 255.0
            return np.asarray(part, dtype=np.float64)

        out.append((crop, origins[rows] - np.array([y0, x0]), rows))
    return out


def _phase_inputs(image, origins, hops, level):
    """Blocks at hop ``level`` of every phase map, with the block origins of the patches.

    Applies the fitted ``hops[: level - 1]``; returns ``{phase: (blocks (h, w, 4C), starts)}``.
    """
    maps = {(0, 0): image[None]}
    for lv in range(1, level + 1):
        step = 2**lv
        phase = origins % step
        inputs = {}
        for r in map(tuple, np.unique(phase, axis=0)):
            parent = (r[0] % (step // 2), r[1] % (step // 2))
            shift = (r[0] // (step // 2), r[1] // (step // 2))
            src = maps[parent][:, shift[0]:, shift[1]:]
            src = src[:, : src.shape[1] // 2 * 2, : src.shape[2] // 2 * 2]
            starts = (origins[np.all(phase == r, axis=1)] - np.array(r)) // step
            inputs[r] = (space_to_depth(src)[0], starts)
        if lv == level:
            return inputs
        hop = hops[lv - 1]
        maps = {r: (b @ hop.kernels_.T + hop.bias_)[None] for r, (b, _) in inputs.items()}


def _core_of(image, patch_size, origins, hops, out, rows):
    """Write the core responses (p, p, Kn) of the patches at ``origins`` of ``image``, through
    ``hops``, into ``out`` (N, p, p, Kn; any layout, e.g. a channel-major view): patch i's
    into row ``rows[i]``."""
    from numpy.lib.stride_tricks import sliding_window_view

    n_hops = len(hops)
    inputs = _phase_inputs(image, origins, hops, n_hops)
    hop = hops[-1]
    side = patch_size // 2**n_hops
    rows = np.asarray(rows)
    phase = origins % 2**n_hops
    for r, (blocks, starts) in inputs.items():
        m = blocks @ hop.kernels_.T + hop.bias_
        mine = np.flatnonzero(np.all(phase == np.array(r), axis=1))
        windows = sliding_window_view(m, (side, side), axis=(0, 1))
        out[rows[mine]] = windows[starts[:, 0], starts[:, 1]].transpose(0, 2, 3, 1)


def _coverage(shape, starts, side):
    """How many windows of ``side x side`` starting at ``starts`` (k, 2) cover each cell."""
    marks = np.zeros((shape[0] + 1, shape[1] + 1))
    np.add.at(marks, (starts[:, 0], starts[:, 1]), 1.0)
    cum = marks.cumsum(axis=0).cumsum(axis=1)
    # Count of starts in [u - side + 1, u] x [v - side + 1, v], from the 2-D prefix sums.
    pad = np.pad(cum, ((side, 0), (side, 0)))
    total = pad[side:, side:] - pad[:-side, side:] - pad[side:, :-side] + pad[:-side, :-side]
    return total[: shape[0], : shape[1]]


class HopStack(FourDInputMixin, TransformerMixin, BaseEstimator):
    """Successive hops from patches (S0) to the core (Sn).

    Parameters
    ----------
    n_channels : sequence of (None, int, float or "knee")
        One rule per hop, e.g. the paper's ``(9, 22)`` for 32x32 patches (K1, K2). Hop 1
        is joint, the others channel-wise. Each hop halves the patch side.

    Attributes
    ----------
    hops_ : list of Hop
    dims_ : list of int
        Dimension of each space: ``[D0, D1, ..., Dn]``.
    """

    def __init__(self, n_channels=(9, 22)):
        self.n_channels = n_channels

    def _rules(self):
        """``n_channels`` checked: a list of one rule per hop (None: keep every non-empty channel)."""
        rules = self.n_channels
        if isinstance(rules, (str, bytes)) or not hasattr(rules, "__iter__"):
            raise TGHopError(f"n_channels must be a sequence of one rule per hop, e.g. (9, 22), got {rules!r}")
        rules = list(rules)
        if not rules:
            raise TGHopError(f"n_channels must name at least one hop, got {self.n_channels!r}")
        return [check_channel_rule(rule, f"n_channels: K{i}", none_ok=True) for i, rule in enumerate(rules, start=1)]

    def fit(self, X, y=None, *, progress=None):
        """Learn every hop from patches ``X`` of shape (n, P, P, C).

        ``progress(stage, done, total)`` is called once per hop. Only the hops are kept,
        not the training patches' core responses (:meth:`fit_transform` returns those).

        Parameters
        ----------
        X : array_like, shape (n, P, P, C)
            Square patches, finite, ``P`` divisible by ``2**n_hops`` (else :class:`~tghop.TGHopError`).
        y : None
            Ignored (scikit-learn's signature).
        progress : callable, optional

        Returns
        -------
        self
        """
        self._fit(X, progress)
        return self

    def _fit(self, X, progress):
        """Fit; return the core responses of ``X``."""
        forget_fit(self)
        rules = self._rules()
        X = check_array(X, "X", "(n_patches, P, P, C)", ndim=4)
        side = X.shape[1]
        if side < 1 or side % (2 ** len(rules)) or X.shape[2] != side or X.shape[3] < 1:
            raise TGHopError(
                f"{len(rules)} hop{'s need' if len(rules) != 1 else ' needs'} square patches whose side is divisible "
                f"by {2 ** len(rules)}, "
                f"got shape {X.shape[1:]}"
            )
        hops, dims = [], [int(np.prod(X.shape[1:]))]
        for i, rule in enumerate(rules):
            report(progress, f"hop {i + 1}", 0, 1)
            try:
                hop = Hop(n_channels=rule, channelwise=i > 0).fit(X)
            except TGHopError as exc:
                raise TGHopError(f"K{i + 1} (n_channels[{i}], --k{i + 1}): {exc}") from None
            X = hop.transform(X)
            hops.append(hop)
            dims.append(int(np.prod(X.shape[1:])))
            report(progress, f"hop {i + 1}", 1, 1)
        self.hops_, self.dims_ = hops, dims  # only now: a failed fit leaves the stack unfitted
        return X

    def fit_image(self, image, patch_size, origins, *, progress=None, tile=TILE):
        """Fit on the patches of one image without cutting them out; return their core.

        Every training patch's 2x2 blocks at hop ``L`` are blocks of one of a few
        *phase maps* of the image (the image shifted by the patch origin modulo ``2**L``
        and transformed by hops 1..L). So each hop is fitted on the blocks of those
        maps, each weighted by the number of patches that contain it: exactly the
        statistics of fitting on the cut-out patches, at a fraction of the cost and
        memory. The result equals ``fit_transform(extract_patches(...))``.

        Memory is bounded by the tile, not the image: the patches are grouped by the
        ``tile`` x ``tile`` square their origin falls in, each square (plus a patch
        margin) is processed on its own and the statistics are summed, so a 64 Mpx
        exemplar costs what a few tiles do. Pixels are converted to float one tile at a
        time, so ``image`` may be uint8 (0-255).

        Parameters
        ----------
        image : ndarray, shape (H, W, C)
            Float in [0, 1], or uint8.
        patch_size : int
        origins : ndarray of int, shape (n, 2)
            Top-left corners of the training patches (see
            :func:`tghop.patches.patch_origins`).
        progress : callable, optional
            ``progress(stage, done, total)``: stages "hop 1", "hop 2", ... (each tile's sums, then
            the hop's fit on them) and "core" (the patches' core responses, tile by tile).
        tile : int
            Side of the tiles (rounded up to a multiple of ``2**n_hops``).

        Returns
        -------
        ndarray, shape (n, p, p, Kn)
            Core responses of the patches, ``p = patch_size / 2**n_hops``.
        """
        forget_fit(self)
        rules = self._rules()
        n_hops = len(rules)
        unit = 2 ** n_hops
        if (isinstance(patch_size, (bool, np.bool_)) or not isinstance(patch_size, (int, np.integer))
                or patch_size < unit or patch_size % unit):
            raise TGHopError(f"{n_hops} hop{'s need' if n_hops != 1 else ' needs'} a patch size divisible by {unit}, "
                             f"got {patch_size!r}")
        patch_size = int(patch_size)
        image = checked_image(image, "HopStack.fit_image", integers=(np.uint8,), empty=False)  # a uint8 one stays uint8
        origins = _check_origins(origins, image.shape, patch_size)
        tile = max(unit, -(-int(tile) // unit) * unit)
        tiles = _tiles(image, origins, patch_size, tile)
        hops, dims = [], [patch_size * patch_size * image.shape[2]]
        for level, rule in enumerate(rules, start=1):
            steps = len(tiles) + 1  # each tile's sums, then the hop's Saab fit on them
            report(progress, f"hop {level}", 0, steps)
            side = patch_size // 2**level
            sums = None
            for i, (crop, local, _) in enumerate(tiles):
                inputs = _phase_inputs(crop(), local, hops, level)
                group = 1 if level > 1 else image.shape[2]
                for blocks, starts in inputs.values():
                    weights = _coverage(blocks.shape[:2], starts, side).ravel()
                    sums = _add_sums(sums, _block_sums(blocks.reshape(-1, blocks.shape[-1]), group, weights))
                report(progress, f"hop {level}", i + 1, steps)
            try:
                hop = Hop(n_channels=rule, channelwise=level > 1).fit_sums(sums)
            except TGHopError as exc:
                raise TGHopError(f"K{level} (n_channels[{level - 1}], --k{level}): {exc}") from None
            report(progress, f"hop {level}", steps, steps)
            hops.append(hop)
            dims.append(side * side * hop.n_channels_out_)
        side = patch_size // unit
        # Stored channel-major and returned as an (n, p, p, Kn) view of it: SDR works on each
        # channel's maps (tghop.sdr), which then need no second, transposed copy of the core.
        k = hops[-1].n_channels_out_
        core = np.empty((k, len(origins), side, side)).transpose(1, 2, 3, 0)
        report(progress, "core", 0, len(tiles))
        for i, (crop, local, rows) in enumerate(tiles):
            _core_of(crop(), patch_size, local, hops, out=core, rows=rows)
            report(progress, "core", i + 1, len(tiles))
        self.hops_, self.dims_ = hops, dims  # only now: a failed fit leaves the stack unfitted
        return core

    def fit_transform(self, X, y=None, *, progress=None):
        """Fit and return the core responses ``(n, P / 2**n, P / 2**n, Kn)``.

        Parameters
        ----------
        X : array_like, shape (n, P, P, C)
            As :meth:`fit` takes them.
        y : None
            Ignored.
        progress : callable, optional

        Returns
        -------
        ndarray of float64, shape (n, P / 2**n, P / 2**n, Kn)
            The training patches' core responses, what :meth:`transform` gives for ``X``.
        """
        return self._fit(X, progress)

    def transform(self, X, *, return_all=False):
        """Patches -> core responses, hop by hop (each hop's :meth:`Hop.transform`).

        Parameters
        ----------
        X : array_like, shape (n, P, P, C)
            Patches (any side divisible by ``2**n_hops``; the fit's ``P`` gives the fit's core).
        return_all : bool
            Return every space, not only the core.

        Returns
        -------
        ndarray, shape (n, P / 2**n, P / 2**n, Kn)
            The core; with ``return_all`` the list ``[S0, S1, ..., Sn]``, ``S0`` the patches as float64.
        """
        check_is_fitted(self, "hops_")
        c = self.hops_[0].n_channels_in_  # numbers (not complex, sparse or strings); each hop checks the rest
        spaces = [check_array(X, "X", f"(n, P, P, {c})", ndim=4, min_rows=0, finite=False)]
        for hop in self.hops_:
            spaces.append(hop.transform(spaces[-1]))
        return spaces if return_all else spaces[-1]

    def inverse_transform(self, Y, *, return_all=False):
        """Core responses -> patches: each hop's :meth:`Hop.inverse_transform`, last hop first (the
        channels a hop dropped count as zero, so with fewer kept this is a projection, not an inverse).

        Parameters
        ----------
        Y : array_like, shape (n, p, p, Kn)
            Core responses.
        return_all : bool
            Return every intermediate space, not only the patches.

        Returns
        -------
        ndarray, shape (n, p * 2**n, p * 2**n, C)
            The patches (not clipped); with ``return_all`` the list ``[Sn, ..., S1, S0]``.
        """
        check_is_fitted(self, "hops_")
        k = self.hops_[-1].n_channels_out_
        spaces = [check_array(Y, "Y", f"(n, p, p, {k})", ndim=4, min_rows=0, finite=False)]
        for hop in reversed(self.hops_):
            spaces.append(hop.inverse_transform(spaces[-1]))
        return spaces if return_all else spaces[-1]


def stage_views(spaces, n_colours, *, n_hops=None):
    """The three views of the paper's Fig. 6 for generated samples.

    Parameters
    ----------
    spaces : list of ndarray
        ``[Sn, ..., S1, S0]`` as :meth:`tghop.TGHop.decode` returns with ``return_stages``.
    n_colours : int
        Colour channels of the exemplar.
    n_hops : int, optional
        The model's hops, when known: ``spaces`` holds one more array.

    Returns
    -------
    dict of ndarray
        ``"core_dc"`` (n, h, w): the DC map in the core (the channel that descends
        from the DC of every hop, a grey low-resolution pattern); ``"S1_dc"`` (n, 2h,
        2w) etc.: the DC map in each intermediate space; ``"S0"`` (n, P, P, C): the
        patch. DC maps are divided by their DC gain, so they are in pixel units, and every
        view is clipped to [0, 1] as the patches are (float64 images to look at; the unclipped
        values are in ``spaces``).

    Raises
    ------
    TGHopError
        If ``spaces`` is not such a list (an array of patches, one space alone, sides that do not
        halve from S0 on, another count of samples, colours or hops).
    """
    _check_spaces(spaces, n_colours, n_hops)
    views = {}
    n_hops = len(spaces) - 1
    for level, space in zip(range(n_hops, 0, -1), spaces[:-1]):
        # DC channel of the hop: index 0 (DC is kept first in every group).
        gain = np.sqrt(4.0 ** level * n_colours)  # a DC kernel has entries 1/sqrt(block size)
        name = "core_dc" if level == n_hops else f"S{level}_dc"
        views[name] = np.clip(space[..., 0] / gain, 0.0, 1.0)  # generated DC can overshoot [0, 1] a little
    views["S0"] = np.clip(spaces[-1], 0.0, 1.0)
    return views


def _check_spaces(spaces, n_colours, n_hops=None):
    """One TGHopError line unless ``spaces`` is a list ``[Sn, ..., S1, S0]`` of 4-D arrays of as many samples,
    each half the side of the next, S0 of ``n_colours`` channels (an array of patches was read as a list of
    spaces: views of nothing, without a word)."""
    want = (f"spaces must be the list [Sn, ..., S1, S0] that decode(z, return_stages=True) returns (arrays (n, side, "
            f"side, K), each half the side of the next, S0 (n, P, P, {n_colours})"
            f"{'' if n_hops is None else f'; {n_hops + 1} arrays for {n_hops} hops'})")
    if isinstance(spaces, np.ndarray):
        raise TGHopError(f"{want}, got an array of shape {spaces.shape}")
    if not isinstance(spaces, (list, tuple)) or len(spaces) < 2:
        count = f" of {len(spaces)}" if isinstance(spaces, (list, tuple)) else ""
        raise TGHopError(f"{want}, got {type(spaces).__name__}{count}")
    shapes = [np.shape(s) for s in spaces]
    p = shapes[-1][1] if len(shapes[-1]) == 4 else 0
    if any(len(s) != 4 or s[0] != shapes[0][0] or s[1] != s[2] or s[1] * 2 ** (len(shapes) - 1 - i) != p
           for i, s in enumerate(shapes)) or shapes[-1][3] != n_colours or n_hops not in (None, len(shapes) - 1):
        raise TGHopError(f"{want}, got shapes {', '.join(str(s) for s in shapes)}")
