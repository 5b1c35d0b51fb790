"""The pool of generated patches that quilting reads, made from core-model vectors as it is read.

A 256x256 image places about 100 of a 5,000-patch pool; :class:`GeneratedPool` decodes
the pool a chunk at a time while quilting prepares its tables, and again for the few
patches it places, so the pool itself never takes memory.
"""

from __future__ import annotations

import math

import numpy as np

from .patches import depth_to_space
from .quilting import POOL_CHUNK, block_count

__all__ = ["GeneratedPool", "DECODE_CHUNK", "ON_DEMAND_BLOCKS", "MAX_GROWN_POOL", "block_decoder", "on_demand",
           "patch_decoder", "pool_size"]

#: Patches decoded per step (the intermediate arrays stay in cache).
DECODE_CHUNK = 64
#: Pools are generated on demand (:class:`GeneratedPool`) for images of at most this many
#: blocks per pool patch (256x256 and 512x512 images from a pool of 5,000). Larger images
#: place more patches, decoded again one wavefront at a time on quilting's path, which
#: then costs more than it saves (measured: docs/choices.md).
ON_DEMAND_BLOCKS = 0.125
#: Largest pool that ``pool_per_block`` grows to (a 4096x4096 image has 23,104 blocks).
MAX_GROWN_POOL = 30_000


def on_demand(size, patch_size, n_patches, *, overlap=None, tile=False) -> bool:
    """Whether an image of ``size`` places few enough blocks (at most
    :data:`ON_DEMAND_BLOCKS` per pool patch) for its pool to be generated on demand."""
    return block_count(size, patch_size, overlap=overlap, tile=tile) <= ON_DEMAND_BLOCKS * n_patches


def pool_size(size, patch_size, *, n_patches, pool_per_block, reuse, overlap=None, tile=False):
    """The pool and the reuse penalty quilting uses for an image of ``size``.

    The pool grows to ``pool_per_block`` patches per block when that is more than
    ``n_patches`` (up to :data:`MAX_GROWN_POOL`). Small images (:func:`on_demand`: 256x256
    and 512x512 from 5,000) hardly reuse a patch (100 blocks: 81 patches, at most 3 uses):
    no penalty, the same images as without it.

    Returns
    -------
    n_patches : int
    reuse : float
    """
    if pool_per_block:
        blocks = block_count(size, patch_size, overlap=overlap, tile=tile)
        n_patches = max(n_patches, min(MAX_GROWN_POOL, int(math.ceil(pool_per_block * blocks))))
    if on_demand(size, patch_size, n_patches, overlap=overlap, tile=tile):
        reuse = 0.0
    return n_patches, reuse


def block_decoder(model):
    """The inverse hops of a fitted :class:`~tghop.TGHop` as one affine map per core position.

    The hops act on non-overlapping 2x2 blocks, so the whole inverse c/w Saab path
    maps each core position's K-vector to its own ``b x b`` pixel block (b = 2 ** hops):
    ``block = v @ linear + constant``. Returns ``linear`` (K, b*b*C) and ``constant``
    (b*b*C,), in float64.
    """
    k = model.sdr_.shape_[2]
    linear = np.eye(k).reshape(k, 1, 1, k)
    constant = np.zeros((1, 1, 1, k))
    for hop in reversed(model.hops_.hops_):
        linear = depth_to_space(linear @ hop.kernels_)
        constant = depth_to_space((constant - hop.bias_) @ hop.kernels_)
    return linear.reshape(k, -1), constant.reshape(-1)


def patch_decoder(model, dtype):
    """A function ``decode(z, out)``: core-model vectors ``z`` (m, D_r) -> patches
    written into ``out`` (m, P, P, C), a C-contiguous array of ``dtype``, clipped to
    [0, 1].

    The same affine path as :meth:`tghop.TGHop.decode` (tested equal), arranged for speed: the
    inverse SDR per channel into a channel-major core, then the inverse hops as one
    matrix product from each core position to its pixel block (:func:`block_decoder`)
    and one transpose into patch order. The channel means go through the block map
    once, as one offset per core position. Given :data:`DECODE_CHUNK` patches at a time its
    intermediate arrays stay in the processor's cache. Made for each pool, not cached, so
    the first pool from a loaded model costs what every later one does.
    """
    sdr = model.sdr_
    h, w, k = sdr.shape_
    linear, constant = block_decoder(model)
    ranges = sdr.channel_ranges()  # each channel's columns of z
    comps = [sdr.components_[a:e].astype(dtype) for a, e in ranges]
    offset = (sdr.mean_.T @ linear + constant).astype(dtype)  # (h * w, b * b * C)
    linear = linear.astype(dtype)
    b = model.patch_size // h
    c_out = model.exemplar_shape_[2]
    # A block row's b * C values move as one item: the transpose into patch order
    # copies items of that size instead of runs of a few floats (fewer, larger copies).
    row = np.dtype((np.void, b * c_out * np.dtype(dtype).itemsize))

    def decode(z, out):
        m = len(z)
        z = np.asarray(z, dtype=dtype)
        core = np.empty((k, m, h * w), dtype=dtype)  # channel-major: contiguous writes
        for c, (a, stop) in enumerate(ranges):
            if a < stop:
                np.matmul(z[:, a:stop], comps[c], out=core[c])
            else:
                core[c] = 0.0
        blocks = (core.reshape(k, -1).T @ linear).reshape(m, h * w, -1)
        blocks += offset
        dst = out.reshape(m, h, b, w, b * c_out).view(row)[..., 0]  # (m, h, b, w)
        dst[...] = blocks.reshape(m, h, w, b, b * c_out).view(row)[..., 0].transpose(0, 1, 3, 2)
        np.clip(out, 0.0, 1.0, out=out)

    return decode


class GeneratedPool:
    """A pool of patches generated from core-model vectors when they are read.

    What quilting reads of a pool (:func:`tghop.quilting.prepare_pool`): ``shape``,
    ``dtype``, contiguous ranges ``pool[a:b]`` (in order, while its tables are made) and
    the chosen patches ``pool[indices]``. A range is decoded into one reused buffer, valid
    until the next read, so it is used while it is in cache and the pool never takes
    memory (5,000 patches: 61 MB in float32); the chosen patches are decoded again. Ranges
    are decoded :data:`DECODE_CHUNK` patches at a time from multiples of it, as
    :meth:`all` decodes the whole pool, so they hold the same numbers; chosen patches
    decoded in other groups can differ from them by float32 round-off (4e-7; BLAS sums
    in an order that depends on the number of rows).

    Parameters
    ----------
    model : TGHop
    z, position : ndarray
        :meth:`tghop.TGHop.sample_vectors`: patch ``i`` is decoded from ``z[position[i]]``.
    """

    ndim = 4

    def __init__(self, model, z, position):
        self._z, self._position = z, position
        self.dtype = z.dtype
        self.shape = (len(position), model.patch_size, model.patch_size, model.exemplar_shape_[2])
        self._decode = patch_decoder(model, self.dtype)
        self._buffer = None

    def __len__(self):
        return self.shape[0]

    def _fill(self, rows, out):
        """Decode the patches ``rows`` (their indices in the pool, ascending from a multiple
        of DECODE_CHUNK for ranges) into ``out``, DECODE_CHUNK at a time."""
        for a in range(0, len(rows), DECODE_CHUNK):
            e = min(len(rows), a + DECODE_CHUNK)
            self._decode(self._z[self._position[rows[a:e]]], out[a:e])
        return out

    def __getitem__(self, index):
        if isinstance(index, slice):
            start, stop, step = index.indices(self.shape[0])
            rows = np.arange(start, stop, step)
            if self._buffer is None or len(self._buffer) < len(rows):
                self._buffer = np.empty((max(len(rows), POOL_CHUNK),) + self.shape[1:], dtype=self.dtype)
            return self._fill(rows, self._buffer[: len(rows)])
        rows = np.asarray(index)
        if rows.dtype.kind not in "iu" or rows.ndim != 1:
            raise TypeError("a generated pool is read by a slice or a 1-d array of indices")
        return self._fill(rows, np.empty((len(rows),) + self.shape[1:], dtype=self.dtype))

    def all(self):
        """The whole pool as an array (n, P, P, C)."""
        return self._fill(np.arange(self.shape[0]), np.empty(self.shape, dtype=self.dtype))
