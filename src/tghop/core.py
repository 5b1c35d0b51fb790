"""The core generative model's distribution: independent-components histogram matching
(ICHM), paper section IV.C.

:class:`tghop.sdr.SpatialReduction` turns core responses ``(n, 8, 8, K2)`` into vectors ``z``
of dimension ``D_r``; ``ICHM`` learns the distribution of ``z`` and samples new vectors.

Choices the paper leaves open (see also the notes in the docs):

* Per-cluster PCA keeps the fewest components that reach ``cluster_energy`` of the
  cluster's variance, at most ``max_cluster_components``, at most ``max_component_ratio``
  of the cluster's samples and fewer than it has. The paper's Table 4 (F = 2,518 CDFs for
  N = 50, about 50 per cluster) is 0.95 and 50; the default 0.99 and 100 gives sharper
  patches; with N = 100 clusters the cap of half the samples keeps each component's
  histogram from being fitted on too few of them (0.4 until 0.39; docs/choices.md).
* Clusters with fewer than ``min_cluster_size`` members are merged into the nearest
  larger cluster before modelling (ICA of a handful of points is meaningless).
* Each CDF is a 256-bin histogram between the component's training minimum and maximum,
  so a sampled value never leaves the range seen in training. The inverse CDF is linear
  between bin edges.
* ``norm_match`` (ours, 0 in the paper's pipeline): independently drawn components add
  up to patches whose overall strength (the norm of the source vector) spreads about twice
  as widely as the training patches' do, and many weak components drawn at once make
  streaks that no training patch has. Each cluster stores the quantiles of its training
  vectors' source norms and of its own draws' (simulated at fit); a drawn vector is
  rescaled towards the training norm at its draw's rank, by this power of the ratio
  (docs/choices.md, ICHM "0.28").
* ``coupling`` (ours, 0 in the paper's pipeline): a draw's components follow a random
  training member's ranks with this correlation of their normal scores, so that components
  that act together in the exemplar's patches are drawn together (:mod:`tghop.coupling`).
* The rejection step (iv) is off by default (``reject_threshold=None``; the paper gives no
  threshold); when set, a draw whose matched independent components are all <= the threshold
  is drawn again, its cluster too ("repeat steps 1-3"), up to 100 times (then a warning).
* ``residual=True`` (ours, off in the paper's pipeline) also models what each cluster's
  PCA drops: the residual ``z - mean - projection`` of every training vector, pooled over
  clusters, as a zero-mean Gaussian per group of dimensions (per core channel: the SDR
  outputs of one channel), and adds a draw of it to every sample. The per-cluster PCA
  keeps the shapes but drops the fine grain (on brick_wall the kept part of a training
  patch has 0.6 of its gradient energy; with the residual, pool patches have 0.85).
"""

from __future__ import annotations

import warnings

import numpy as np

from ._arrays import check_array, check_count, check_int, check_width, forget_fit
from ._common import BaseEstimator, TGHopError, check_is_fitted, check_rng, one_blas_thread, usable_cores, report
from .coupling import RANK_LEVELS, coupled_uniforms, member_ranks
from .sdr import flip_signs
from .settings import BY_NAME as _SETTINGS
from .unsupervised import fast_ica, kmeans, nearest  # noqa: F401 (fast_ica: also tghop.core's)

__all__ = ["ICHM", "fast_ica"]

#: ICHM's private caches of a fitted state, forgotten with it (:func:`tghop._arrays.forget_fit`).
_CACHES = ("_stored_mixing", "_mixing", "_mixing32", "_ranks", "_quantiles")

#: Resolution of the tabulated inverse CDFs used for sampling.
QUANTILE_STEPS = 1024


#: ``n_clusters=None``: one cluster per AUTO_PER_CLUSTER training vectors, within these bounds
#: (docs/choices.md, ICHM "0.27").
AUTO_CLUSTERS = (50, 100)
AUTO_PER_CLUSTER = 40
#: ``norm_match``: quantiles of the source norms stored per cluster (evenly spaced levels),
#: and the draws per cluster at fit that give the quantiles of the sampled norms.
NORM_QUANTILES = 33
NORM_DRAWS = 1000


def _quantize(mixing):
    """Rows of ``mixing`` as float16 in [-1, 1] and a float32 scale per row (the row's
    largest magnitude): relative rounding error at most 2**-11 of the row's largest entry,
    far below the spread of the sampled sources."""
    scale = np.abs(mixing).max(axis=1).astype(np.float32)
    scale[scale == 0] = 1.0
    return (mixing / scale[:, None].astype(np.float64)).astype(np.float16), scale


def _dequantize(rows, scale):
    """Inverse of :func:`_quantize`, in float64 (the same numbers at fit and after loading)."""
    out = rows.astype(np.float64)
    out *= np.asarray(scale, dtype=np.float32).astype(np.float64)[:, None]  # in place: no second matrix
    return out


class ICHM(BaseEstimator):
    """Independent-components histogram matching: a mixture of per-cluster ICA models.

    Parameters
    ----------
    n_clusters : int or None, default=None
        N, the number of K-means clusters (paper: 50 in Table 4; quality improves up to
        about 100). None: :meth:`clusters_for` the training vectors, one per
        ``AUTO_PER_CLUSTER`` of them, at least 50 and at most 100.
    n_codewords : int, default=200
        W, the size of the vector-quantised codebook of CDF shapes.
    n_bins : int, default=256
        Histogram bins per CDF.
    cluster_energy : float, default=0.99
        Fraction of a cluster's variance its PCA keeps before FastICA (the paper's
        F = 2,518 for N = 50 corresponds to 0.95 with at most 50 components).
    max_cluster_components : int, default=100
        Upper bound of components per cluster.
    max_component_ratio : float, default=0.5
        Components per cluster at most this fraction of its members (1: one fewer than
        the members, the paper's only bound): FastICA and 256-bin histograms of fewer
        members per component fit the members rather than their distribution.
    min_cluster_size : int, default=10
        Smaller clusters are merged into their nearest larger one.
    reject_threshold : float or None, default=None
        Sampling step (iv): redraw a sample none of whose matched components exceeds it.
    max_iter : int, default=200
        FastICA iterations per cluster.
    tol : float, default=1e-3
        FastICA's convergence tolerance (scikit-learn's default and the paper's: 1e-4).
    residual : bool, default=False
        Model the residual of the per-cluster PCA by a Gaussian per group of dimensions
        (``groups`` of :meth:`fit`) and add a draw of it to every sample (ours).
    norm_match : float in [0, 1], default=1.0
        Rescale each drawn source vector towards the training norm at its rank: by the
        ratio of the two to this power (ours; 0: off, the paper's independent draws).
    coupling : float in [0, 0.99], default=0.95
        Correlation of each draw's normal scores with a random training member's
        (:mod:`tghop.coupling`; ours; 0: the paper's independent draws).
    rng : int or numpy.random.Generator, optional
        For K-means and FastICA initialisation.

    Attributes
    ----------
    weights_ : ndarray, shape (N,)
        Cluster probabilities (the paper's interval representation; the name of
        scikit-learn's ``GaussianMixture.weights_``). ``p_`` is an alias.
    means_ : ndarray, shape (N, D_r)
    mixing_ : ndarray, shape (F, D_r)
        Row block ``i`` maps cluster ``i``'s independent components back to ``z``
        (inverse ICA and inverse PCA in one matrix). This is the transpose of
        scikit-learn's ``FastICA.mixing_`` (n_features, n_components), kept on purpose:
        it stacks N per-cluster models by rows, so a cluster's block is one contiguous
        slice and generation is ``sources @ mixing_[block]`` (the convention of
        ``PCA.components_``, which is (n_components, n_features)).
    n_components_ : ndarray of int, shape (N,)
        Independent components per cluster; ``F = n_components_.sum()``.
    cdf_index_ : ndarray of int, shape (F,)
        Codeword of each component's CDF.
    cdf_min_, cdf_max_ : ndarray, shape (F,)
        Range of each component (the CDF's bin structure spans it).
    codebook_ : ndarray, shape (W, n_bins)
        Quantised CDF shapes: the CDF at the right edge of each bin (last value 1).
    n_ica_unconverged_ : int
        Clusters whose FastICA hit ``max_iter`` (sampling stays exact for them; the
        components are just less independent).
    residual_group_ : ndarray of int, shape (D_r,) or (0,)
        Group of each dimension of the residual Gaussian (empty without ``residual``).
    residual_factor_ : ndarray, shape (sum of squared group sizes,)
        For each group in order, the square root ``L`` (row-major, ``L @ L.T`` = the
        group's residual covariance) of its Gaussian; empty without ``residual``.
    norm_quantiles_, sampled_norm_quantiles_ : ndarray, shape (N, NORM_QUANTILES) or (N, 0)
        Quantiles (at evenly spaced levels) of the source norms of each cluster's training
        vectors and of its draws; (N, 0) with ``norm_match`` 0.
    member_counts_ : ndarray of int, shape (N,) or (0,)
        Training members per cluster; empty with ``coupling`` 0.
    member_ranks_ : ndarray of uint8, shape (sum of members x components,)
        :func:`tghop.coupling.member_ranks` of each cluster, flattened in cluster order.
    """

    def __init__(
        self,
        n_clusters=None,
        n_codewords=200,
        n_bins=256,
        cluster_energy=0.99,
        max_cluster_components=100,
        max_component_ratio=0.5,
        min_cluster_size=10,
        reject_threshold=None,
        max_iter=200,
        tol=1e-3,
        residual=False,
        norm_match=1.0,
        coupling=0.95,
        rng=None,
    ):
        self.n_clusters = n_clusters
        self.n_codewords = n_codewords
        self.n_bins = n_bins
        self.cluster_energy = cluster_energy
        self.max_cluster_components = max_cluster_components
        self.max_component_ratio = max_component_ratio
        self.min_cluster_size = min_cluster_size
        self.reject_threshold = reject_threshold
        self.max_iter = max_iter
        self.tol = tol
        self.residual = residual
        self.norm_match = norm_match
        self.coupling = coupling
        self.rng = rng

    #: (parameter, label in messages, setting of the table that defines its type and range)
    _CHECKS = (("n_clusters", "n_clusters (N)", "n_clusters"), ("n_codewords", "n_codewords (W)", "n_codewords"),
               ("n_bins", "n_bins", "n_bins"), ("cluster_energy", "cluster_energy", "cluster_energy"),
               ("max_cluster_components", "max_cluster_components", "max_cluster_components"),
               ("max_component_ratio", "max_component_ratio", "max_component_ratio"),
               ("min_cluster_size", "min_cluster_size", "min_cluster_size"),
               ("reject_threshold", "reject_threshold", "reject_threshold"),
               ("max_iter", "max_iter", "ica_max_iter"), ("tol", "tol", "ica_tol"),
               ("norm_match", "norm_match", "norm_match"), ("coupling", "coupling", "coupling"))

    def clusters_for(self, n_samples) -> int:
        """N for ``n_samples`` training vectors: ``n_clusters``, or with None one per
        ``AUTO_PER_CLUSTER`` vectors within ``AUTO_CLUSTERS`` (the paper's 50 up to 2,000
        vectors, 100 from 4,000: a 256x256 exemplar at stride 2 gives 12,769)."""
        if self.n_clusters is not None:
            return self.n_clusters
        return int(min(AUTO_CLUSTERS[1], max(AUTO_CLUSTERS[0], n_samples // AUTO_PER_CLUSTER)))

    def _check_params(self, n_samples):
        for param, label, setting in self._CHECKS:
            _SETTINGS[setting].check(getattr(self, param), label=label)
        n_clusters = self.clusters_for(n_samples)
        if n_clusters * self.min_cluster_size > n_samples:
            raise TGHopError(
                f"n_clusters={n_clusters}{' (auto)' if self.n_clusters is None else ''} needs at least "
                f"{n_clusters * self.min_cluster_size} training patches (min_cluster_size={self.min_cluster_size} "
                f"each) but there are {n_samples}; lower N (n_clusters, --clusters) or the least cluster "
                "size (min_cluster_size, --min-cluster-size), take more training patches (a smaller stride, --stride, "
                "or a larger max_patches, --max-patches) or use a larger exemplar"
            )

    def fit(self, Z, y=None, *, groups=None, progress=None):
        """Learn the mixture from vectors ``Z`` of shape (n, D_r).

        ``groups`` (D_r,) ints: with ``residual``, dimensions of one group share a
        Gaussian and groups are independent (None: one Gaussian over all dimensions).

        ``progress(stage, done, total)`` reports "clusters" (K-means), "ICA" (per
        cluster) and "CDF codebook". A failed fit leaves the model unfitted.

        Returns
        -------
        self
        """
        forget_fit(self, _CACHES)
        try:
            return self._fit(Z, groups, progress)
        except BaseException:
            forget_fit(self, _CACHES)
            raise

    def _fit(self, Z, groups, progress):
        Z = check_array(Z, "Z", "(n_samples, D_r)", ndim=2, min_rows=0)
        if Z.shape[1] < 1:
            raise TGHopError(f"Z must have shape (n_samples, D_r) with D_r >= 1, got {Z.shape}")
        self._check_params(Z.shape[0])
        self._quantiles = None  # derived from the codebook: never reuse a previous fit's
        rng = check_rng(self.rng)
        report(progress, "clusters", 0, 1)
        labels = self._cluster(Z, rng)
        report(progress, "clusters", 1, 1)
        n_clusters = labels.max() + 1
        counts = np.bincount(labels, minlength=n_clusters)
        self.weights_ = counts / counts.sum()
        # Clusters are independent: fit them on all cores (LAPACK releases the GIL), one
        # BLAS thread each (many small matrices). Seeds are drawn in cluster order, so the
        # result does not depend on scheduling.
        seeds = rng.integers(0, 2**63 - 1, size=n_clusters)

        def one(i):
            members = Z[labels == i]
            mean = members.mean(axis=0)
            return (mean, *self._fit_cluster(members - mean, np.random.default_rng(seeds[i])))

        from concurrent.futures import ThreadPoolExecutor  # not at module level: loading a model needs none

        residuals = [] if self.residual else None

        # One BLAS thread each (the clusters' results do not depend on how many run at
        # once); as many at once as there are idle cores: on a busy machine more only compete.
        workers = max(1, min(n_clusters, usable_cores()))
        with one_blas_thread(), ThreadPoolExecutor(max_workers=workers) as pool:
            fitted = []
            for i, result in enumerate(pool.map(one, range(n_clusters))):
                report(progress, "ICA", i, n_clusters)
                fitted.append(result[:4])
                if residuals is not None:
                    residuals.append(result[4])
        self.means_ = np.array([mean for mean, _, _, _ in fitted])
        mixing = [m for _, m, _, _ in fitted]
        sources = [s for _, _, s, _ in fitted]
        n_comp = [m.shape[0] for m in mixing]
        self.n_ica_unconverged_ = sum(not ok for _, _, _, ok in fitted)
        self._fit_residual(residuals, Z.shape[1], groups)
        report(progress, "ICA", n_clusters, n_clusters)
        # Model files store the mixing matrix (most of the model) as float16 rows with a
        # float32 scale each (a quarter of float64's size); rounding here keeps a fitted
        # model and its saved copy generating the same patches.
        self._set_stored_mixing(*_quantize(np.vstack(mixing)))
        self.n_components_ = np.asarray(n_comp, dtype=np.int64)
        report(progress, "CDF codebook", 0, 1)
        self._fit_cdfs(sources, rng)
        self._fit_ranks(sources)
        self._fit_norms(sources, rng)
        report(progress, "CDF codebook", 1, 1)
        return self

    def _cluster(self, Z, rng):
        # float32 halves K-means time; the clustering only routes samples to clusters.
        n_clusters = self.clusters_for(len(Z))
        labels, centres = kmeans(Z, n_clusters, rng)
        counts = np.bincount(labels, minlength=n_clusters)
        small = counts < self.min_cluster_size
        if small.any():
            big = np.flatnonzero(~small)
            moved = small[labels]
            d = ((Z[moved, None, :] - centres[None, big, :]) ** 2).sum(-1)
            labels[moved] = big[np.argmin(d, axis=1)]
        # Renumber 0..N'-1 in order of first appearance of the kept clusters.
        _, labels = np.unique(labels, return_inverse=True)
        return labels

    def _fit_cluster(self, centred, rng):
        """PCA-whiten one cluster, run FastICA; return (mixing (k, D_r), sources (n_i, k), converged)."""
        n, d = centred.shape
        # PCA through the smaller of the n x n Gram matrix (a patch model's clusters have
        # fewer members than dimensions) and the d x d scatter matrix.
        gram = n <= d
        vals, vecs = np.linalg.eigh(centred @ centred.T if gram else centred.T @ centred)
        vals, vecs = np.maximum(vals[::-1], 0), vecs[:, ::-1]
        var = vals / n
        cum = np.cumsum(var) / max(var.sum(), 1e-300)
        k = int(np.searchsorted(cum, self.cluster_energy - 1e-12)) + 1
        k = max(1, min(k, self.max_cluster_components, int(self.max_component_ratio * n), n - 1,
                       int(np.count_nonzero(var > 1e-12 * var[0]))))
        std = np.sqrt(var[:k])
        basis = flip_signs((vecs[:, :k].T @ centred) / np.sqrt(vals[:k])[:, None] if gram else vecs[:, :k].T)
        white = centred @ basis.T / std
        unmix, converged = fast_ica(white, max_iter=self.max_iter, tol=self.tol, rng=rng)
        sources = white @ unmix.T
        # z - mean = white * std @ basis = sources @ inv(unmix).T * std @ basis
        mixing = np.linalg.inv(unmix).T @ (std[:, None] * basis)
        if self.residual:  # what the kept components miss (basis rows are orthonormal)
            return mixing, sources, converged, (centred - (centred @ basis.T) @ basis).astype(np.float32)
        return mixing, sources, converged

    def _fit_residual(self, residuals, d_r, groups):
        """Gaussian of the residuals ``(n_i, D_r)`` of all clusters, block-diagonal by group."""
        if residuals is None:
            self.residual_group_ = np.zeros(0, dtype=np.int64)
            self.residual_factor_ = np.zeros(0)
            return
        groups = np.zeros(d_r, dtype=np.int64) if groups is None else np.asarray(groups, dtype=np.int64)
        if groups.shape != (d_r,):
            raise TGHopError(f"groups must have one entry per dimension ({d_r}), got shape {groups.shape}")
        R = np.vstack(residuals)
        factors = []
        for g in np.unique(groups):
            block = R[:, groups == g]
            vals, vecs = np.linalg.eigh(block.T.astype(np.float64) @ block / len(R))
            factors.append((vecs * np.sqrt(np.maximum(vals, 0.0))).ravel())
        self.residual_group_ = groups
        self.residual_factor_ = np.concatenate(factors)

    def residual_draws(self, n, *, rng=None):
        """Standard normals for ``n`` residual draws, group by group.

        Yields ``(dims, normals, factor)``: the group's dimensions (k,), normals (n, k)
        and its factor (k, k); the group's residuals are ``normals @ factor.T``.
        """
        check_is_fitted(self, "means_")
        n = check_count(n)
        rng = check_rng(rng)
        groups = getattr(self, "residual_group_", np.zeros(0, dtype=np.int64))
        start = 0
        for g in np.unique(groups):
            dims = np.flatnonzero(groups == g)
            k = dims.size
            factor = self.residual_factor_[start: start + k * k].reshape(k, k)
            start += k * k
            yield dims, rng.standard_normal((int(n), k)), factor

    def sample_residual(self, n, *, rng=None):
        """Draw ``n`` residual vectors (n, D_r) from the Gaussian (zeros without ``residual``)."""
        check_is_fitted(self, "means_")
        out = np.zeros((check_count(n), self.means_.shape[1]))
        for dims, normals, factor in self.residual_draws(n, rng=rng):
            out[:, dims] = normals @ factor.T
        return out

    def _fit_cdfs(self, sources, rng):
        """Histogram CDFs of all components, vector-quantised into the codebook."""
        nb = self.n_bins
        cdfs, lo, hi = [], [], []
        for s in sources:
            smin, smax = s.min(axis=0), s.max(axis=0)
            width = np.where(smax > smin, smax - smin, 1.0)
            idx = np.clip(((s - smin) / width * nb).astype(np.int64), 0, nb - 1)
            k = s.shape[1]
            hist = np.bincount((idx + nb * np.arange(k)).ravel(), minlength=k * nb).reshape(k, nb)
            cdfs.append(np.cumsum(hist, axis=1) / s.shape[0])
            lo.append(smin)
            hi.append(smax)
        cdfs = np.vstack(cdfs)
        self.cdf_min_ = np.concatenate(lo)
        self.cdf_max_ = np.concatenate(hi)
        if cdfs.shape[0] <= self.n_codewords:
            self.codebook_ = cdfs
            self.cdf_index_ = np.arange(cdfs.shape[0], dtype=np.int64)
        else:
            labels, centres = kmeans(cdfs, self.n_codewords, rng)
            self.cdf_index_ = labels.astype(np.int64)
            self.codebook_ = np.maximum.accumulate(np.clip(centres, 0.0, 1.0), axis=1)
            self.codebook_[:, -1] = 1.0

    def _fit_norms(self, sources, rng):
        """Quantiles of each cluster's training source norms, and of the norms of
        NORM_DRAWS draws from its fitted CDFs, as :meth:`sample_sources` makes them (empty
        without ``norm_match``)."""
        n = len(sources)
        if not self.norm_match:
            self.norm_quantiles_ = self.sampled_norm_quantiles_ = np.zeros((n, 0))
            return
        levels = np.linspace(0.0, 1.0, NORM_QUANTILES)
        table = self._quantile_table()
        real, drawn = np.empty((n, NORM_QUANTILES)), np.empty((n, NORM_QUANTILES))
        for i, (s, comp) in enumerate(zip(sources, self._blocks(), strict=True)):
            draws = self._match(self._uniforms(i, NORM_DRAWS, rng), comp, table)
            real[i] = np.quantile(np.linalg.norm(s, axis=1), levels)
            drawn[i] = np.quantile(np.linalg.norm(draws, axis=1), levels)
        self.norm_quantiles_, self.sampled_norm_quantiles_ = real, drawn

    def _fit_ranks(self, sources):
        """Each cluster's members' ranks for coupled draws (empty without ``coupling``)."""
        ranks = [member_ranks(s) for s in sources] if self.coupling else []
        self.member_counts_ = np.array([len(r) for r in ranks], dtype=np.int64)
        self.member_ranks_ = np.concatenate([r.ravel() for r in ranks] or [np.zeros(0)]).astype(np.uint8)
        self._ranks = ranks or None  # per cluster, as _uniforms splits them from the file's flat array

    def _uniforms(self, i, m, rng):
        """Probabilities (m, components of cluster ``i``) for its inverse CDFs: independent, or
        with ``coupling`` coupled to its members' ranks (:func:`tghop.coupling.coupled_uniforms`)."""
        if not self.coupling or not self.member_counts_.size:
            return rng.random((int(m), int(self.n_components_[i])))
        if getattr(self, "_ranks", None) is None:
            sizes = self.member_counts_ * self.n_components_
            self._ranks = [r.reshape(n, -1) for r, n in zip(np.split(self.member_ranks_, np.cumsum(sizes)[:-1]),
                                                             self.member_counts_, strict=True)]
        return coupled_uniforms(self._ranks[i], float(self.coupling), m, rng)

    def _match_norm(self, s, i):
        """Cluster ``i``'s drawn sources ``s`` (m, k), each row rescaled by (training norm at
        its norm's rank among the draws / its norm) ** ``norm_match``, in place."""
        if self.norm_quantiles_.shape[1] == 0 or not self.norm_match or not len(s):
            return s
        levels = np.linspace(0.0, 1.0, self.norm_quantiles_.shape[1])
        r = np.linalg.norm(s, axis=1)
        target = np.interp(np.interp(r, self.sampled_norm_quantiles_[i], levels), levels, self.norm_quantiles_[i])
        s *= ((target / np.maximum(r, 1e-300)) ** self.norm_match)[:, None]
        return s

    # ------------------------------------------------------------------ mixing matrix
    # The fitted (or loaded) mixing matrix is kept as what the model file stores: float16
    # rows and a float32 scale per row. ``mixing_`` (float64) is made from them on first
    # use and generation takes a float32 copy made straight from them: a model loaded for
    # generation never holds the float64 matrix, which would raise the peak memory of a
    # small synthesis.
    def _set_stored_mixing(self, rows, scale):
        self._stored_mixing = (rows, scale)
        self._mixing = self._mixing32 = None

    @property
    def mixing_(self):
        mixing = vars(self).get("_mixing")
        if mixing is None:
            stored = vars(self).get("_stored_mixing")
            if stored is None:
                check_is_fitted(self, "means_")  # NotFittedError before fit
                raise AttributeError(f"this {type(self).__name__} has no mixing_")
            mixing = self._mixing = _dequantize(*stored)
        return mixing

    @mixing_.setter
    def mixing_(self, value):
        # Set by hand (or from a version 2 file): saved by quantising it again.
        self._mixing = np.asarray(value)
        self._stored_mixing = self._mixing32 = None

    @property
    def mixing_shape_(self):
        """``mixing_.shape`` (F, D_r), without making the float64 matrix."""
        check_is_fitted(self, "means_")
        stored = vars(self).get("_stored_mixing")
        return tuple(stored[0].shape) if stored is not None else self.mixing_.shape

    def mixing_as(self, dtype):
        """:attr:`mixing_` in ``dtype`` (float32 or float64).

        float32 is made straight from the stored float16 rows and float32 scales, and kept
        for later calls: the same numbers as ``mixing_.astype(float32)`` (a float16 times a
        float32 is exact in float64, so rounding the product to float32 once is the same
        either way), without making the float64 matrix."""
        check_is_fitted(self, "means_")
        dtype = np.dtype(dtype)
        if dtype != np.float32:
            return self.mixing_.astype(dtype, copy=False)
        if vars(self).get("_mixing32") is None:
            stored = vars(self).get("_stored_mixing")
            if stored is None:
                self._mixing32 = self.mixing_.astype(np.float32)
            else:
                rows, scale = stored
                self._mixing32 = np.multiply(rows, np.asarray(scale, dtype=np.float32)[:, None], dtype=np.float32)
        return self._mixing32

    @property
    def p_(self):
        """Alias of :attr:`weights_` (the paper's cluster probabilities p)."""
        check_is_fitted(self, "weights_")
        return self.weights_

    #: (file name, attribute, dtype): the arrays of a model file that belong to ICHM.
    _ARRAYS = (
        ("ichm_i.p", "weights_", np.float64),
        ("ichm_ii.mixing", "mixing_", np.float64),
        ("ichm_ii.means", "means_", np.float64),
        ("index.ichm_n_components", "n_components_", np.int64),
        ("ichm_iii.cdf_index", "cdf_index_", np.int64),
        ("ichm_iii.cdf_min", "cdf_min_", np.float64),
        ("ichm_iii.cdf_max", "cdf_max_", np.float64),
        ("ichm_iii.codebook", "codebook_", np.float64),
        ("index.ichm_residual_group", "residual_group_", np.int64),
        ("residual.factor", "residual_factor_", np.float64),
    )
    #: The same for ``norm_match``: written only where it is on (format version 7).
    _NORM_ARRAYS = (
        ("ichm_iv.norm_quantiles", "norm_quantiles_", np.float64),
        ("ichm_iv.sampled_norm_quantiles", "sampled_norm_quantiles_", np.float64),
    )
    #: And for ``coupling`` (format version 8).
    _RANK_ARRAYS = (("index.ichm_member_counts", "member_counts_", np.int64),
                    ("ichm_coupling.member_ranks", "member_ranks_", np.uint8))

    def _to_arrays(self) -> dict:
        out = {name: getattr(self, attr) for name, attr, _ in self._ARRAYS if attr != "mixing_"}
        if self.norm_match and self.norm_quantiles_.size:  # what the metadata's setting says is there
            out.update({name: getattr(self, attr) for name, attr, _ in self._NORM_ARRAYS})
        if self.coupling and self.member_counts_.size:
            out.update({name: getattr(self, attr) for name, attr, _ in self._RANK_ARRAYS})
        # The float16 rows as fitted or loaded (mixing_ is made from them), unless mixing_ was
        # set since; quantising again gives the same numbers, it only costs time.
        stored = vars(self).get("_stored_mixing")
        if stored is None:
            stored = _quantize(self.mixing_)
        out["ichm_ii.mixing"], out["index.ichm_mixing_scale"] = stored
        return out

    def _from_arrays(self, arrays):
        """Restore the fitted state from :meth:`_to_arrays` output; returns self.

        Files of format version 2 hold the mixing matrix in float32 and no scale."""
        quantised = "index.ichm_mixing_scale" in arrays
        for name, attr, dtype in self._ARRAYS:
            if not (quantised and attr == "mixing_"):
                setattr(self, attr, arrays[name].astype(dtype, copy=False))
        for name, attr, dtype in self._NORM_ARRAYS:  # absent where norm_match is 0 (and before version 7)
            setattr(self, attr, arrays[name].astype(dtype, copy=False) if name in arrays
                    else np.zeros((len(self.weights_), 0)))
        for name, attr, dtype in self._RANK_ARRAYS:  # absent where coupling is 0 (and before version 8)
            setattr(self, attr, arrays[name].astype(dtype, copy=False) if name in arrays else np.zeros(0, dtype))
        self._ranks = None
        if quantised:
            scale, rows = arrays["index.ichm_mixing_scale"], arrays["ichm_ii.mixing"]
            if rows.ndim != 2 or scale.shape != rows.shape[:1] or scale.dtype.kind != "f":
                raise TGHopError(f"mixing scales of shape {scale.shape} and type {scale.dtype} for "
                                 f"mixing rows of shape {rows.shape}")
            self._set_stored_mixing(rows, scale)
        self._quantiles = None
        return self

    def _array_specs(self, quantised=True):
        """ICHM's arrays for the checks of :mod:`tghop.modelfile` (``quantised``: float16
        mixing rows with a scale each, format version 3): ``(name, shape, kind, says,
        rules)`` each; needs D_r, sets N, F, W."""
        n_codewords = self.n_codewords

        def codewords(arr, dims):
            w = min(dims["F"], n_codewords)
            return None if len(arr) == w else f"has {len(arr)} CDFs, not {w} (the smaller of F and n_codewords)"

        specs = [
            ("ichm_i.p", ("N",), "f", "one probability per cluster",
             (("dim", 0, 1, self.n_clusters or AUTO_CLUSTERS[1]), ("positive",), ("sum", 1.0, 1e-6))),
            ("ichm_ii.means", ("N", "D_r"), "f", "a mean per cluster of ichm_i.p, of D_r values", ()),
            ("index.ichm_n_components", ("N",), "i", "a component count per cluster of ichm_i.p",
             (("range", 1, self.max_cluster_components), ("sum_defines", "F"))),
            ("ichm_ii.mixing", ("F", "D_r"), "f", "F = the sum of index.ichm_n_components rows of D_r values", ()),
        ]
        if quantised:
            specs.append(("index.ichm_mixing_scale", ("F",), "f", "one of the mixing scales per row of ichm_ii.mixing",
                          (("positive",),)))
        specs += [
            ("ichm_iii.codebook", ("W", self.n_bins), "f", f"the metadata says CDFs of n_bins={self.n_bins}",
             (("range", 0.0, 1.0), ("nondecreasing",), ("last", 1.0, 1e-6), codewords)),
            ("ichm_iii.cdf_index", ("F",), "i", "one codeword per component", (("index", "W"),)),
            ("ichm_iii.cdf_min", ("F",), "f", "one minimum per component", ()),
            ("ichm_iii.cdf_max", ("F",), "f", "one maximum per component", (("not_below", "ichm_iii.cdf_min"),)),
        ]

        def group_sizes(arr, dims):
            _, counts = np.unique(arr, return_counts=True)
            dims["R"] = int((counts.astype(np.int64) ** 2).sum())

        if self.residual:
            specs += [("index.ichm_residual_group", ("D_r",), "i",
                       "the metadata says residual: one group per dimension", (("range", 0, None), group_sizes)),
                      ("residual.factor", ("R",), "f", "the squared sizes of the groups of index.ichm_residual_group",
                       ())]
        else:
            specs += [("index.ichm_residual_group", (0,), "i", "the metadata says no residual", ()),
                      ("residual.factor", (0,), "f", "the metadata says no residual", ())]
        if self.norm_match:
            says = f"the metadata says norm_match={self.norm_match}: {NORM_QUANTILES} quantiles per cluster"
            specs += [(name, ("N", NORM_QUANTILES), "f", says, (("range", 0.0, None), ("nondecreasing",)))
                      for name, _, _ in self._NORM_ARRAYS]
        if self.coupling:
            says = f"the metadata says coupling={self.coupling}"
            # M, the ranks stored: each cluster's members times its components.
            specs += [("index.ichm_member_counts", ("N",), "i", f"{says}: a member count per cluster",
                       (("range", 1, None), ("products_define", "M", "index.ichm_n_components"))),
                      ("ichm_coupling.member_ranks", ("M",), "i", f"{says}: a rank per member and component",
                       (("range", 0, RANK_LEVELS - 1),))]
        return tuple(specs)

    # ------------------------------------------------------------------ sampling
    def _blocks(self):
        """Each cluster's components: its slice of the F rows of the mixing matrix and CDFs."""
        ends = np.cumsum(self.n_components_)
        return [slice(int(e - k), int(e)) for e, k in zip(ends, self.n_components_)]

    @property
    def n_cdfs_(self) -> int:
        """F, the number of CDFs (independent components over all clusters)."""
        check_is_fitted(self, "means_")
        return int(self.n_components_.sum())

    def _quantile_table(self):
        """Inverse CDF of each codeword on a regular grid of probabilities, in [0, 1]."""
        if getattr(self, "_quantiles", None) is None:
            nb = self.codebook_.shape[1]
            edges = np.linspace(0.0, 1.0, nb + 1)
            grid = np.linspace(0.0, 1.0, QUANTILE_STEPS + 1)
            cdf = np.hstack([np.zeros((len(self.codebook_), 1)), self.codebook_])
            self._quantiles = np.vstack([np.interp(grid, c, edges) for c in cdf])
        return self._quantiles

    def sample_sources(self, n, *, rng=None):
        """Draw clusters and matched independent components (steps i-iv; with ``coupling``
        each vector's probabilities coupled to a random training member's ranks, with
        ``norm_match`` each vector rescaled towards the training norms, before step iv).

        Parameters
        ----------
        n : int
        rng : int or numpy.random.Generator, optional

        Returns
        -------
        labels : ndarray of int, shape (n,)
            Cluster of each sample.
        sources : list of ndarray
            ``sources[i]`` has shape (count of label i, n_components_[i]): the samples
            of cluster ``i`` in order of their position in ``labels``.
        """
        check_is_fitted(self, "means_")
        n = check_count(n)
        rng = check_rng(rng)
        table, blocks = self._quantile_table(), self._blocks()

        def draw(m):  # steps (i)-(iii) for m samples: their clusters and matched components
            # (i) the interval representation: a uniform number picks the segment.
            labels = np.minimum(np.searchsorted(np.cumsum(self.weights_), rng.random(m), side="right"),
                                len(self.weights_) - 1)
            return labels, [self._match_norm(self._match(self._uniforms(i, int(np.count_nonzero(labels == i)), rng),
                                                         comp, table), i) for i, comp in enumerate(blocks)]

        labels, sources = draw(n)
        if self.reject_threshold is None:
            return labels, sources
        for _ in range(100):  # (iv) "repeat steps 1-3" for the samples with no value above the threshold
            bad = [~(s > self.reject_threshold).any(axis=1) for s in sources]
            where = np.concatenate([np.flatnonzero(labels == i)[b] for i, b in enumerate(bad)])
            if not where.size:
                return labels, sources
            new_labels, new_sources = draw(where.size)
            where.sort()
            labels[where] = new_labels
            for i, (s, b, new) in enumerate(zip(sources, bad, new_sources)):  # kept rows and new ones, by position
                fresh = np.isin(np.flatnonzero(labels == i), where[new_labels == i])
                sources[i] = np.empty((fresh.size,) + s.shape[1:], dtype=s.dtype)
                sources[i][fresh], sources[i][~fresh] = new, s[~b]
        warnings.warn(f"ICHM: {int(sum((~(s > self.reject_threshold).any(axis=1)).sum() for s in sources))} samples "
                      f"still have no component above reject_threshold={self.reject_threshold:g} after 100 redraws; "
                      "kept as drawn (lower the threshold)")
        return labels, sources

    def _match(self, uniform, comp, table):
        """(ii-iii) Map probabilities through each component's inverse CDF.

        The paper draws standard normals and maps them through Phi; Phi of a standard
        normal is uniform on [0, 1), so we draw the uniform numbers directly (the same
        distribution, without SciPy's ``ndtr`` on the generation path).
        """
        u = uniform * QUANTILE_STEPS
        lo = np.minimum(u.astype(np.int64), QUANTILE_STEPS - 1)
        frac = u - lo
        codes = self.cdf_index_[comp]
        t = table[codes, lo] * (1.0 - frac) + table[codes, lo + 1] * frac
        return self.cdf_min_[comp] + (self.cdf_max_[comp] - self.cdf_min_[comp]) * t

    def sample(self, n, *, rng=None):
        """Draw ``n`` new vectors (steps i-v).

        Returns
        -------
        Z : ndarray, shape (n, D_r)
        labels : ndarray of int, shape (n,)
            The cluster of each sample (as scikit-learn's ``GaussianMixture.sample``).
        """
        labels, sources = self.sample_sources(n, rng=rng)
        return self.mix(labels, sources), labels

    def mix(self, labels, sources, *, mixing=None, means=None):
        """(v) Inverse ICA and PCA: independent components -> vectors.

        ``mixing`` and ``means`` default to :attr:`mixing_` and :attr:`means_`; a caller
        may pass them in another dtype (float32 for generation).
        """
        z, position = self.mix_by_cluster(labels, sources, mixing=mixing, means=means)
        return z[position]

    def mix_by_cluster(self, labels, sources, *, mixing=None, means=None):
        """:meth:`mix` with the vectors grouped by cluster, as the matrix products make them.

        Each cluster's block is written by one product straight into its rows (no scatter
        into the samples' order, a pass over the whole output saved).

        Returns
        -------
        Z : ndarray, shape (n, D_r)
            Cluster 0's samples first, each cluster's in the order of ``labels``.
        position : ndarray of int, shape (n,)
            ``Z[position]`` is :meth:`mix`'s result: the row of ``Z`` of each sample.
        """
        check_is_fitted(self, "means_")
        mixing = self.mixing_ if mixing is None else mixing
        means = self.means_ if means is None else means
        labels = np.asarray(labels)
        counts = np.bincount(labels, minlength=len(sources)) if len(labels) else np.zeros(len(sources), dtype=int)
        if len(counts) != len(sources) or any(len(s) != k for s, k in zip(sources, counts)):
            raise TGHopError(f"mix: source rows per cluster {[len(s) for s in sources]} do not match the "
                             f"labels' counts {counts.tolist()}")
        out = np.empty((len(labels), mixing.shape[1]), dtype=mixing.dtype)
        start = 0
        with one_blas_thread():  # the same vectors for a seed on any number of cores (OpenBLAS rounds by its threads)
            for i, (s, comp) in enumerate(zip(sources, self._blocks(), strict=True)):
                stop = start + len(s)
                if stop > start:
                    block = out[start:stop]
                    np.matmul(s, mixing[comp], out=block)
                    block += means[i]
                start = stop
        position = np.empty(len(labels), dtype=np.intp)
        position[np.argsort(labels, kind="stable")] = np.arange(len(labels))
        return out, position

    # ------------------------------------------------------------------ inspection
    def _check_vectors(self, Z):
        check_is_fitted(self, "means_")
        Z = check_array(Z, "Z", "(n, D_r)", ndim=2, min_rows=0)
        d = self.means_.shape[1]
        check_width(Z, "Z", f"(n, D_r) = (n, {d})", (d,))
        return Z

    def predict(self, Z, *, chunk=4096):
        """The cluster of each vector: the nearest of :attr:`means_` in Euclidean distance.

        The fit's clusters are K-means's (float32, Lloyd stopped when at most 0.1 % of the
        points change cluster) with clusters under ``min_cluster_size`` merged into the nearest
        larger one, and :attr:`means_` are their members' means; the K-means centres are not
        stored. The nearest mean is the assignment those clusters converge to: on the
        training vectors it gives the fit's clusters except for the few points K-means left
        at a boundary (docs/choices.md, "Inspecting the core model").

        Parameters
        ----------
        Z : array_like, shape (n, D_r)
            Core vectors (``TGHop.encode`` of patches, or :meth:`sample`'s).
        chunk : int
            Vectors per matrix product (memory ``chunk x N``), at least 1.

        Returns
        -------
        labels : ndarray of int, shape (n,)
        """
        return nearest(self._check_vectors(Z), self.means_, chunk=check_int(chunk, "chunk", 1, where="ICHM.predict"))

    def transform(self, Z, *, labels=None):
        """The independent components of each vector in its cluster: the inverse of :meth:`mix`.

        Cluster ``i``'s components of ``z`` are ``(z - means_[i]) @ pinv(mixing_[block i])``
        (through a QR decomposition of the block), so ``mix(*transform(Z))`` is each ``z``
        projected orthogonally onto its cluster's affine subspace (its mean plus the row
        space of its mixing rows: its kept PCA components): ``Z`` itself, to float
        precision, for vectors in that subspace, such as :meth:`sample`'s with their own
        labels (without ``residual``); for a training vector, the part its cluster's PCA keeps.

        Parameters
        ----------
        Z : array_like, shape (n, D_r)
        labels : array_like of int, shape (n,), optional
            The cluster of each vector; None: :meth:`predict`'s.

        Returns
        -------
        labels : ndarray of int, shape (n,)
        sources : list of ndarray
            ``sources[i]`` has shape (count of label i, n_components_[i]): the vectors of
            cluster ``i`` in their order in ``labels``, as :meth:`sample_sources` returns them.
        """
        Z = self._check_vectors(Z)
        n_clusters = len(self.means_)
        if labels is None:
            labels = self.predict(Z)
        labels = np.asarray(labels)
        if labels.size == 0 and labels.ndim == 1:  # [] is float64: no index, and none is wrong
            labels = labels.astype(np.int64)
        if labels.shape != (len(Z),) or labels.dtype.kind not in "iu" or (
                len(labels) and not 0 <= labels.min() <= labels.max() < n_clusters):
            raise TGHopError(f"labels must be {len(Z)} cluster indices from 0 to {n_clusters - 1}, got an array of "
                             f"shape {labels.shape} and type {labels.dtype}")
        mixing, sources = self.mixing_, []
        with one_blas_thread():  # as in fit: threaded BLAS only slows many small matrices
            for i, comp in enumerate(self._blocks()):  # a cluster of no components gives (m, 0) sources
                # mixing[comp].T = Q R: the least-squares s of s @ mixing[comp] = z - mean is ((z - mean) Q) R^-T
                # (the rows are independent as fit makes them: R is invertible).
                q, r = np.linalg.qr(mixing[comp].T)
                sources.append(np.linalg.solve(r, ((Z[labels == i] - self.means_[i]) @ q).T).T)
        return labels.astype(np.int64, copy=False), sources

