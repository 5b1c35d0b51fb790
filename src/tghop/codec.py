"""Between patches and the core model's vectors: the methods of :class:`~tghop.synthesis.TGHop`
that go forward (patches to core vectors, as the fit does) and back (core vectors to patches,
as generation does), and that draw new ones.

The paper's analysis and generation paths (section IV) on a fitted model::

    patches (n, P, P, C) --hops--> S1 ... Sn --SDR--> z (n, D_r)      encode
    z --inverse SDR--> Sn --inverse hops--> ... S0 --clip--> patches   decode
    ICHM steps i-v --> z (grouped by cluster)                          sample_vectors
    sample_vectors, then decode (chunked: tghop.pool)                 sample_patches

:class:`PatchCodec` holds them for :class:`~tghop.synthesis.TGHop`, which inherits them: they use
its fitted ``hops_``, ``sdr_``, ``ichm_``, ``exemplar_shape_``, ``patch_size`` and ``dims_``.
"""

from __future__ import annotations

import numpy as np

from . import settings
from ._arrays import LEVELS, check_array, check_dtype, check_width, from_levels
from ._errors import TGHopError
from ._estimator import check_is_fitted, check_rng
from ._resources import one_blas_thread
from .hops import stage_views
from .pool import GeneratedPool

__all__ = ["PatchCodec"]


class PatchCodec:
    """The patch methods of :class:`~tghop.synthesis.TGHop` (a mixin: it has no state of its own).

    Before :meth:`TGHop.fit <tghop.synthesis.TGHop.fit>`, each raises :class:`~tghop.NotFittedError`.
    """

    def encode(self, patches):
        """Patches (n, P, P, C) -> core-model vectors ``z`` (n, D_r): the hops, then SDR, as
        :meth:`fit` takes its training patches (the counterpart of :meth:`decode`).

        Every hop and SDR is an affine map with orthonormal rows and :meth:`decode` applies
        their transposes, so ``encode`` inverts ``decode`` before its clip: for ``z`` of
        :meth:`sample_vectors` (or any ``z``), ``encode(decode(z, return_stages=True)[1][-1])``
        is ``z`` to float precision, and ``encode(decode(z))`` too where no pixel was clipped.
        The other way round, ``decode(encode(x))`` is ``x`` projected orthogonally onto the
        model's patch space (the channels and spatial components kept), clipped to [0, 1].

        Parameters
        ----------
        patches : array_like, shape (n, P, P, C)
            Patches as :meth:`sample_patches` returns them (in [0, 1]; other values are projected
            all the same); uint8 and uint16 are read as x / 255 and x / 65535, as :meth:`fit` reads them.

        Returns
        -------
        z : ndarray, shape (n, D_r)
            :meth:`ICHM.predict <tghop.core.ICHM.predict>` gives their clusters and
            :meth:`ICHM.transform <tghop.core.ICHM.transform>` their independent components.
        """
        check_is_fitted(self, "ichm_")
        if isinstance(getattr(patches, "dtype", None), np.dtype) and patches.dtype in LEVELS:  # any array type
            patches = from_levels(np.asarray(patches))  # as fit reads them
        x = check_array(patches, "patches", "(n, P, P, C)", ndim=4, min_rows=0)
        shape = (self.patch_size, self.patch_size, self.exemplar_shape_[2])
        check_width(x, "patches", "(n, {}, {}, {})".format(*shape), shape)
        return self.sdr_.transform(self.hops_.transform(x))

    def decode(self, z, *, return_stages=False):
        """Core-model vectors ``z`` (n, D_r) -> patches (n, P, P, C), clipped to [0, 1].

        Parameters
        ----------
        z : array_like, shape (n, D_r)
            Core vectors (:meth:`sample_vectors`, :meth:`ICHM.sample <tghop.core.ICHM.sample>`,
            :meth:`encode`), finite numbers.
        return_stages : bool
            Also return every space of the way back, before clipping (the inverse c/w Saab path
            of the paper, section IV.D).

        Returns
        -------
        patches : ndarray, shape (n, P, P, C), float64 in [0, 1]
        spaces : list of ndarray, only with ``return_stages``
            ``[Sn, ..., S1, S0]``: the core (n, P / 2**n, P / 2**n, Kn) after the inverse SDR, each
            hop's input, and the unclipped patches (n, P, P, C) last (:meth:`stage_views` shows them).
        """
        check_is_fitted(self, "ichm_")
        z, d = np.asarray(z), self.dims_["D_r"]
        if z.dtype.kind not in "iuf":
            raise TGHopError(f"z must be numbers, got an array of {z.dtype}")
        if z.ndim != 2 or z.shape[1] != d:
            raise TGHopError(f"z must have shape (n, D_r) = (n, {d}) for this model, got {z.shape}")
        if not np.isfinite(z).all():
            raise TGHopError("z holds NaN or infinite values")
        spaces = self.hops_.inverse_transform(self.sdr_.inverse_transform(z), return_all=True)
        patches = np.clip(spaces[-1], 0.0, 1.0)
        return (patches, spaces) if return_stages else patches

    def sample_vectors(self, n, rng, dtype, *, return_labels=False):
        """Steps i-v of the core model: ``n`` vectors ``z`` (n, D_r) in ``dtype``, grouped by
        cluster as mixed (:meth:`ICHM.mix_by_cluster <tghop.core.ICHM.mix_by_cluster>`), and
        ``position``: ``z[position]`` are the samples in order (and, with ``return_labels``, each
        sample's cluster, in order).

        Parameters
        ----------
        n : int
            Samples.
        rng : int or numpy.random.Generator
            Their random stream: a Generator is advanced; an int seed gives the draws of
            ``numpy.random.default_rng(seed)``, one stream for the sources and the residual alike.
        dtype : {numpy.float32, numpy.float64}
            Of ``z``.
        return_labels : bool
            Also return each sample's cluster.

        Returns
        -------
        z : ndarray, shape (n, D_r), float32 or float64 as ``dtype`` (a :class:`~tghop.TGHopError` for others)
        position : ndarray of intp, shape (n,)
        labels : ndarray of int, shape (n,), only with ``return_labels``
        """
        check_is_fitted(self, "ichm_")
        dtype = check_dtype(dtype, (np.float32, np.float64), "float32 or float64")
        rng = check_rng(rng)  # one stream: an int given to each draw below restarted it for the residual
        ichm = self.ichm_
        labels, sources = ichm.sample_sources(n, rng=rng)
        z, position = ichm.mix_by_cluster(labels, [s.astype(dtype, copy=False) for s in sources],
                                          mixing=ichm.mixing_as(dtype), means=ichm.means_.astype(dtype, copy=False))
        if ichm.residual_factor_.size > 0:
            z[position] += ichm.sample_residual(n, rng=rng).astype(dtype, copy=False)
        return (z, position, labels) if return_labels else (z, position)

    @one_blas_thread()  # the same patches on any number of cores (OpenBLAS's products round by its threads)
    def sample_patches(self, n, *, rng=None, return_stages=False, dtype=np.float64):
        """Generate new patches.

        Parameters
        ----------
        n : int
        rng : int or numpy.random.Generator, optional
            Same seed, same patches (on the same machine).
        return_stages : bool
            Also return the stage views of the paper's Fig. 6 (see :meth:`stage_views`), and
            ``"cluster"``: (n,) the cluster each patch was drawn from (step i).
        dtype : {numpy.float64, numpy.float32}
            float32 halves memory and time for large pools (quilting works in float32).

        Returns
        -------
        patches : ndarray, shape (n, P, P, C), in [0, 1]
        stages : dict, only with ``return_stages``
        """
        check_is_fitted(self, "ichm_")
        n = settings.BY_NAME["n_patches"].check(n, label="n")
        dtype = check_dtype(dtype, (np.float32, np.float64), "float32 or float64")
        rng = check_rng(rng)
        if return_stages:  # the paper's step-by-step inverse, keeping every space (in float64)
            z, position, labels = self.sample_vectors(n, rng, np.dtype(np.float64), return_labels=True)
            patches, spaces = self.decode(z[position], return_stages=True)
            return patches.astype(dtype, copy=False), {**self.stage_views(spaces), "cluster": labels}
        return GeneratedPool(self, *self.sample_vectors(n, rng, dtype)).all()

    def stage_views(self, spaces):
        """The three views of the paper's Fig. 6 for generated samples: :func:`tghop.hops.stage_views`
        of ``spaces``; before :meth:`fit`, :class:`~tghop.NotFittedError`.

        Parameters
        ----------
        spaces : list of ndarray
            ``[Sn, ..., S1, S0]`` from :meth:`decode` with ``return_stages``: the core
            (n, h, w, Kn), each hop's input, and the patches (n, P, P, C).

        Returns
        -------
        dict of ndarray
            ``"core_dc"`` (n, h, w), ``"S1_dc"`` (n, 2h, 2w), ..., ``"S0"`` (n, P, P, C) in [0, 1].
        """
        check_is_fitted(self, "ichm_")
        return stage_views(spaces, self.exemplar_shape_[2], n_hops=len(self.hops_.hops_))
