"""The core generative model's distribution: independent-components histogram matching
(ICHM), paper section IV.C.

:class:`tghop.sdr.SpatialReduction` turns core responses ``(n, 8, 8, K2)`` into vectors ``z``
of dimension ``D_r``; ``ICHM`` learns the distribution of ``z`` and samples new vectors.

Where its parts are: this module holds ``ICHM``'s settings and its steps (``fit``; drawing,
``sample_sources`` / ``sample`` / ``mix``; inspecting, ``predict`` / ``unmix`` / ``transform``).
:mod:`tghop.ichm_clusters` holds the per-cluster work those steps call, as functions of arrays
(merging small clusters, PCA + FastICA, the residual Gaussian, histogram CDFs and their
codebook, inverse-CDF and norm matching of draws); :mod:`tghop.ichm_storage` how the fitted
state is kept (the mixing matrix quantised) and written to and read from model files.
:mod:`tghop.unsupervised` has the K-means and FastICA, :mod:`tghop.coupling` the coupled draws.

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

import numpy as np

from ._arrays import check_array, check_count, check_int, check_width, forget_fit
from ._errors import TGHopError, warn
from ._estimator import BaseEstimator, TransformerMixin, check_is_fitted, check_rng
from ._progress import report
from ._resources import one_blas_thread, usable_cores
from .coupling import coupled_uniforms, member_ranks
from .ichm_clusters import (AUTO_CLUSTERS, AUTO_FEWEST, AUTO_PER_CLUSTER, NORM_DRAWS, NORM_QUANTILES,
                            QUANTILE_STEPS, cdf_codebook, fit_cluster, histogram_cdfs, match_components, match_norms,
                            merge_small_clusters, quantile_table, residual_factors)
from .ichm_storage import ICHMStorageMixin, quantize
from .settings import BY_NAME as _SETTINGS
from .unsupervised import fast_ica, kmeans, nearest  # noqa: F401 (fast_ica: also tghop.core's)

#: The constants of :mod:`tghop.ichm_clusters` are tghop.core's too, as they were before it.
__all__ = ["ICHM", "fast_ica", "AUTO_CLUSTERS", "AUTO_PER_CLUSTER", "QUANTILE_STEPS", "NORM_QUANTILES", "NORM_DRAWS"]

#: ICHM's private caches of a fitted state, forgotten with it (:func:`tghop._arrays.forget_fit`).
_CACHES = ("_stored_mixing", "_mixing", "_mixing32", "_ranks", "_quantiles")


class ICHM(ICHMStorageMixin, TransformerMixin, BaseEstimator):
    """Independent-components histogram matching: a mixture of per-cluster ICA models.

    Parameters
    ----------
    n_clusters : int or None, default=None
        N, the number of K-means clusters (paper: 50 in Table 4; quality improves up to
        about 100). None: :meth:`clusters_for` the training vectors, one per
        ``AUTO_PER_CLUSTER`` of them, at least 50 and at most 100; from fewer than 50 x
        ``min_cluster_size`` vectors, one per ``min_cluster_size``, at least ``AUTO_FEWEST`` (4).
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
        FastICA's convergence tolerance (``--paper``: scikit-learn's default, 1e-4; the paper names none).
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
    n_features_in_ : int
        D_r, the width of the ``Z`` it was fitted on (scikit-learn's name).
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
    n_iter_ : int
        The most FastICA iterations any cluster ran (scikit-learn's ``FastICA.n_iter_``; 0.61: a model
        file of 0.60 or older does not record it, 0).
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
        vectors, 100 from 4,000: a 256x256 exemplar at stride 2 gives 12,769); from fewer than
        50 x ``min_cluster_size`` vectors, one per ``min_cluster_size``, at least ``AUTO_FEWEST`` (4: from
        fewer vectors the fit is refused, naming the smallest exemplar; 44x44 at stride 2).

        Parameters
        ----------
        n_samples : int
            Training vectors.

        Returns
        -------
        n_clusters : int
            K-means's N (clusters under ``min_cluster_size`` are merged after it).
        """
        if self.n_clusters is not None:
            return self.n_clusters
        n = int(min(AUTO_CLUSTERS[1], max(AUTO_CLUSTERS[0], n_samples // AUTO_PER_CLUSTER)))
        # Fewer than 50 x min_cluster_size vectors (a small exemplar's: under 76x76 at stride 2): as many
        # clusters as they fill, at least AUTO_FEWEST (0.58; 0.57 refused them all; docs/choices.md, ICHM "0.58").
        if n * self.min_cluster_size > n_samples:
            n = max(AUTO_FEWEST, int(n_samples) // self.min_cluster_size)
        return n

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
        """Learn the mixture from vectors ``Z``. A failed fit leaves the model unfitted.

        Parameters
        ----------
        Z : array_like, shape (n, D_r)
            Training vectors (:class:`tghop.sdr.SpatialReduction`'s of the core's patches),
            at least ``min_cluster_size`` per cluster.
        y : None
            Ignored (scikit-learn's signature).
        groups : array_like of int, shape (D_r,), optional
            With ``residual``: dimensions of one group share a Gaussian and groups are
            independent (None: one Gaussian over all dimensions).
        progress : callable, optional
            ``progress(stage, done, total)``, with stages "clusters" (K-means), "ICA" (per
            cluster) and "CDF codebook".

        Returns
        -------
        self : ICHM
        """
        forget_fit(self, _CACHES)
        try:
            with one_blas_thread():  # the same model on any number of cores, alone as inside TGHop.fit
                return self._fit(Z, groups, progress)
        except BaseException:
            forget_fit(self, _CACHES)
            raise

    def _fit(self, Z, groups, progress):
        Z = check_array(Z, "Z", "(n_samples, D_r)", ndim=2, min_rows=0)
        # In the words scikit-learn's checks look for too (0.61), as Saab's
        if Z.shape[1] < 1:
            raise TGHopError(f"ICHM needs vectors of dimension D_r >= 1: found 0 feature(s) (shape={Z.shape}) while a "
                             "minimum of 1 is required; give Z of shape (n_samples, D_r) with D_r >= 1")
        if Z.shape[0] == 1:
            raise TGHopError(f"ICHM needs more than one vector: found 1 sample(s) (shape={Z.shape}); give Z at least "
                             f"min_cluster_size ({self.min_cluster_size}) rows per cluster")
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
            return (mean, *self._fit_cluster(members - mean, np.random.default_rng(seeds[i]), return_n_iter=True))

        from concurrent.futures import ThreadPoolExecutor  # not at module level: loading a model needs none

        residuals = [] if self.residual else None

        # One BLAS thread each (the clusters' results do not depend on how many run at
        # once); as many at once as there are idle cores: on a busy machine more only compete.
        workers = max(1, min(n_clusters, usable_cores()))
        with one_blas_thread(), ThreadPoolExecutor(max_workers=workers) as pool:
            fitted, n_iters = [], []
            for i, result in enumerate(pool.map(one, range(n_clusters))):
                report(progress, "ICA", i, n_clusters)
                fitted.append(result[:4])
                n_iters.append(result[-1])
                if residuals is not None:
                    residuals.append(result[4])
        self.means_ = np.array([mean for mean, _, _, _ in fitted])
        mixing = [m for _, m, _, _ in fitted]
        sources = [s for _, _, s, _ in fitted]
        n_comp = [m.shape[0] for m in mixing]
        self.n_ica_unconverged_ = sum(not ok for _, _, _, ok in fitted)
        self.n_iter_ = max(n_iters, default=0)  # scikit-learn's FastICA's (deflation): the most any cluster ran
        self._fit_residual(residuals, Z.shape[1], groups)
        # Model files store the mixing matrix (most of the model) as float16 rows with a
        # float32 scale each (a quarter of float64's size); rounding here keeps a fitted
        # model and its saved copy generating the same patches.
        self._set_stored_mixing(*quantize(np.vstack(mixing)))
        self.n_components_ = np.asarray(n_comp, dtype=np.int64)
        report(progress, "ICA", n_clusters, n_clusters)  # after the mixing's rounding: no work between stages
        report(progress, "CDF codebook", 0, 1)
        self._fit_cdfs(sources, rng)
        self._fit_ranks(sources)
        self._fit_norms(sources, rng)
        report(progress, "CDF codebook", 1, 1)
        return self

    def _cluster(self, Z, rng):
        """K-means labels (n,) of ``Z``, small clusters merged (:func:`merge_small_clusters`)."""
        labels, centres = kmeans(Z, self.clusters_for(len(Z)), rng)  # float32: it only routes samples
        return merge_small_clusters(Z, labels, centres, self.min_cluster_size)

    def _fit_cluster(self, centred, rng, return_n_iter=False):
        """:func:`tghop.ichm_clusters.fit_cluster` with this model's settings."""
        return fit_cluster(centred, rng, energy=self.cluster_energy, max_components=self.max_cluster_components,
                           max_ratio=self.max_component_ratio, max_iter=self.max_iter, tol=self.tol,
                           residual=self.residual, return_n_iter=return_n_iter)

    def _fit_residual(self, residuals, d_r, groups):
        """The Gaussian of the residuals ``(n_i, D_r)`` of all clusters (empty without ``residual``)."""
        if residuals is None:
            self.residual_group_, self.residual_factor_ = np.zeros(0, dtype=np.int64), np.zeros(0)
        else:
            self.residual_group_, self.residual_factor_ = residual_factors(residuals, d_r, groups)

    def residual_draws(self, n, *, rng=None):
        """Standard normals for ``n`` residual draws, group by group (an iterator).

        The fit and ``n`` are checked at the call, before the first draw.

        Parameters
        ----------
        n : int
            Draws, at least 0.
        rng : int or numpy.random.Generator, optional

        Yields
        ------
        dims : ndarray of int, shape (k,)
            The group's dimensions.
        normals : ndarray, shape (n, k)
        factor : ndarray, shape (k, k)
            The group's residuals are ``normals @ factor.T``.
        """
        check_is_fitted(self, "means_")  # checked at the call, not at the first draw
        n = check_count(n)
        rng = check_rng(rng)
        groups = getattr(self, "residual_group_", np.zeros(0, dtype=np.int64))

        def draws():
            start = 0
            for g in np.unique(groups):
                dims = np.flatnonzero(groups == g)
                k = dims.size
                factor = self.residual_factor_[start: start + k * k].reshape(k, k)
                start += k * k
                yield dims, rng.standard_normal((int(n), k)), factor

        return draws()

    def sample_residual(self, n, *, rng=None):
        """Draw ``n`` residual vectors from the Gaussian (zeros without ``residual``).

        Parameters
        ----------
        n : int
            Draws, at least 0.
        rng : int or numpy.random.Generator, optional

        Returns
        -------
        residuals : ndarray, shape (n, D_r)
        """
        check_is_fitted(self, "means_")
        out = np.zeros((check_count(n), self.means_.shape[1]))
        for dims, normals, factor in self.residual_draws(n, rng=rng):
            out[:, dims] = normals @ factor.T
        return out

    def _fit_cdfs(self, sources, rng):
        """Histogram CDFs of all components, vector-quantised into the codebook."""
        cdfs, self.cdf_min_, self.cdf_max_ = histogram_cdfs(sources, self.n_bins)
        self.codebook_, self.cdf_index_ = cdf_codebook(cdfs, self.n_codewords, rng)

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
        """Cluster ``i``'s drawn sources ``s`` (m, k) rescaled towards the training norms in place
        (:func:`tghop.ichm_clusters.match_norms`; as drawn without ``norm_match``)."""
        if self.norm_quantiles_.shape[1] == 0 or not self.norm_match:
            return s
        return match_norms(s, self.norm_quantiles_[i], self.sampled_norm_quantiles_[i], self.norm_match)

    @property
    def p_(self):
        """Alias of :attr:`weights_` (the paper's cluster probabilities p)."""
        check_is_fitted(self, "weights_")
        return self.weights_

    # ------------------------------------------------------------------ sampling
    def _blocks(self):
        """Each cluster's components: its slice of the F rows of the mixing matrix and CDFs."""
        ends = np.cumsum(self.n_components_)
        return [slice(int(e - k), int(e)) for e, k in zip(ends, self.n_components_)]

    @property
    def n_features_in_(self) -> int:
        """D_r, the width of the vectors it was fitted on (scikit-learn's name for it)."""
        check_is_fitted(self, "means_")
        return int(self.means_.shape[1])

    @property
    def n_cdfs_(self) -> int:
        """F, the number of CDFs (independent components over all clusters)."""
        check_is_fitted(self, "means_")
        return int(self.n_components_.sum())

    def _quantile_table(self):
        """:func:`tghop.ichm_clusters.quantile_table` of the codebook, made once."""
        if getattr(self, "_quantiles", None) is None:
            self._quantiles = quantile_table(self.codebook_)
        return self._quantiles

    def sample_sources(self, n, *, rng=None):
        """Draw clusters and matched independent components (steps i-iv; with ``coupling``
        each vector's probabilities coupled to a random training member's ranks, with
        ``norm_match`` each vector rescaled towards the training norms, before step iv).

        Parameters
        ----------
        n : int
            Samples to draw, at least 0.
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
        warn(f"ICHM: {int(sum((~(s > self.reject_threshold).any(axis=1)).sum() for s in sources))} samples "
             f"still have no component above reject_threshold={self.reject_threshold:g} after 100 redraws; "
             "kept as drawn (lower the threshold)")
        return labels, sources

    def _match(self, uniform, comp, table):
        """(ii-iii) Probabilities (m, k) -> the values of the components ``comp`` (a slice of F)
        through their inverse CDFs (:func:`tghop.ichm_clusters.match_components`)."""
        return match_components(uniform, self.cdf_index_[comp], self.cdf_min_[comp], self.cdf_max_[comp], table)

    def sample(self, n, *, rng=None):
        """Draw ``n`` new vectors (steps i-v).

        Parameters
        ----------
        n : int
            Samples to draw, at least 0.
        rng : int or numpy.random.Generator, optional

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

        Parameters
        ----------
        labels : array_like of int, shape (n,)
            The cluster of each vector, in [0, N).
        sources : list of ndarray
            ``sources[i]`` has shape (count of label i, n_components_[i]), cluster ``i``'s
            vectors in their order in ``labels`` (as :meth:`sample_sources` and
            :meth:`unmix` return them).
        mixing : ndarray, shape (F, D_r), optional
            Default :attr:`mixing_`; a caller may pass it in another dtype (float32 for
            generation, :meth:`mixing_as`).
        means : ndarray, shape (N, D_r), optional
            Default :attr:`means_`.

        Returns
        -------
        Z : ndarray, shape (n, D_r)
            In ``mixing``'s dtype, in the order of ``labels``.
        """
        z, position = self.mix_by_cluster(labels, sources, mixing=mixing, means=means)
        return z[position]

    def mix_by_cluster(self, labels, sources, *, mixing=None, means=None):
        """:meth:`mix` with the vectors grouped by cluster, as the matrix products make them.

        Each cluster's block is written by one product straight into its rows (no scatter
        into the samples' order, a pass over the whole output saved), at one BLAS thread.

        Parameters
        ----------
        labels, sources, mixing, means
            As for :meth:`mix`.

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
        labels = self._check_labels(labels, None, "mix")
        n_clusters = len(self.means_)
        if not isinstance(sources, (list, tuple)) or len(sources) != n_clusters:
            got = f"a {type(sources).__name__} of {len(sources)}" if hasattr(sources, "__len__") else repr(sources)
            raise TGHopError(f"mix: sources must be a list of {n_clusters} arrays, one per cluster (as unmix and "
                             f"sample_sources return them), got {got}")
        counts = np.bincount(labels, minlength=n_clusters)
        for i, (s, k, c) in enumerate(zip(sources, counts, self.n_components_)):
            if np.shape(s) != (k, c):  # a wrong width failed in the matrix product, in NumPy's words (0.58)
                raise TGHopError(f"mix: sources[{i}] must have shape ({k}, {c}): cluster {i}'s {k} vectors in labels "
                                 f"by its {c} components (n_components_[{i}]), got {np.shape(s)}")
            kind = np.asarray(s).dtype.kind  # text, objects, complex failed in the product, in NumPy's words (0.61)
            if kind not in "biuf" or (kind == "f" and not np.isfinite(s).all()):
                got = "NaN or infinite values" if kind == "f" else f"values of type {np.asarray(s).dtype}"
                raise TGHopError(f"mix: sources[{i}] must hold finite real numbers (as unmix and sample_sources give "
                                 f"them), got {got}")
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
        if Z.shape[1] != d:  # in scikit-learn's words too, whose X is Z here (0.61)
            raise TGHopError(f"Z must have shape (n, D_r) = (n, {d}) for this fitted model, got {Z.shape} (in "
                             f"scikit-learn's words, X has {Z.shape[1]} features, but ICHM is expecting {d} features "
                             "as input)")
        return Z

    def _check_labels(self, labels, n, where):
        """``labels`` as int64 cluster indices in [0, N), ``n`` of them (None: any number); else one line."""
        labels, n_clusters = np.asarray(labels), len(self.means_)
        if labels.size == 0 and labels.ndim == 1:  # [] is float64: no index, and none is wrong
            labels = labels.astype(np.int64)
        if labels.ndim != 1 or (n is not None and len(labels) != n) or labels.dtype.kind not in "iu" or (
                len(labels) and not 0 <= labels.min() <= labels.max() < n_clusters):
            count = "a 1-D array of" if n is None else n
            got = f"an array of shape {labels.shape} and type {labels.dtype}"
            if labels.ndim == 1 and labels.dtype.kind in "iu" and (n is None or len(labels) == n):
                got = f"indices from {labels.min()} to {labels.max()}"  # the range is what is wrong: said (0.61)
            raise TGHopError(f"{where}: labels must be {count} cluster indices from 0 to {n_clusters - 1} (integers), "
                             f"got {got}")
        return labels.astype(np.int64, copy=False)

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
        Z = self._check_vectors(Z)
        chunk = check_int(chunk, "chunk", 1, where="ICHM.predict")
        with one_blas_thread():  # the same labels on any number of cores (OpenBLAS rounds by its threads)
            return nearest(Z, self.means_, chunk=chunk)

    def unmix(self, Z, *, labels=None):
        """The independent components of each vector in its cluster: the inverse of :meth:`mix`
        (0.61; 0.60's :meth:`transform` gave these).

        Cluster ``i``'s components of ``z`` are ``(z - means_[i]) @ pinv(mixing_[block i])``
        (through a QR decomposition of the block), so ``mix(*unmix(Z))`` is each ``z``
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
        labels = self._check_labels(self.predict(Z) if labels is None else labels, len(Z), "unmix")
        mixing, sources = self._mixing_uncached(), []
        with one_blas_thread():  # as in fit: threaded BLAS only slows many small matrices
            for i, comp in enumerate(self._blocks()):  # a cluster of no components gives (m, 0) sources
                # mixing[comp].T = Q R: the least-squares s of s @ mixing[comp] = z - mean is ((z - mean) Q) R^-T
                # (the rows are independent as fit makes them: R is invertible).
                q, r = np.linalg.qr(mixing[comp].T)
                sources.append(np.linalg.solve(r, ((Z[labels == i] - self.means_[i]) @ q).T).T)
        return labels.astype(np.int64, copy=False), sources

    def transform(self, Z, *, labels=None):
        """Each vector as one row of numbers (scikit-learn's transform; 0.61): its cluster, one-hot, in the
        first N columns, then its independent components (:meth:`unmix`'s) in the F columns of the
        components, its own cluster's block (column ``N + f`` is the component whose CDF is ``cdf_index_[f]``),
        zeros in the other clusters' blocks. :meth:`inverse_transform` of it is :meth:`mix` of :meth:`unmix`'s.

        0.60's ``transform`` returned ``(labels, sources)``, which :meth:`unmix` returns now (scikit-learn's
        checks and pipelines take a transformer's output to be one array).

        Parameters
        ----------
        Z : array_like, shape (n, D_r)
        labels : array_like of int, shape (n,), optional
            The cluster of each vector; None: :meth:`predict`'s.

        Returns
        -------
        codes : ndarray of float64, shape (n, N + F)
            Float64: (N + F) x 8 bytes a vector (51 KB for N = 100, F = 6,289); :meth:`unmix` keeps only its own.
        """
        labels, sources = self.unmix(Z, labels=labels)
        n_clusters = len(self.means_)
        codes = np.zeros((len(labels), n_clusters + self.n_cdfs_))
        codes[np.arange(len(labels)), labels] = 1.0
        for i, (s, comp) in enumerate(zip(sources, self._blocks())):
            codes[np.flatnonzero(labels == i), n_clusters + comp.start:n_clusters + comp.stop] = s
        return codes

    def inverse_transform(self, X, sources=None):
        """:meth:`transform`'s rows back to vectors: ``X[:, :N] @ means_ + X[:, N:] @ mixing_``, one
        matrix product (:meth:`mix` of the same labels and components, to float precision).

        Parameters
        ----------
        X : array_like, shape (n, N + F)
            As :meth:`transform` returns it.
        sources : list of ndarray, optional
            Deprecated (a FutureWarning; 0.60's call): ``inverse_transform(labels, sources)``, :meth:`mix`'s.

        Returns
        -------
        Z : ndarray of float64, shape (n, D_r)
        """
        check_is_fitted(self, "means_")
        if sources is not None:
            warn("ICHM.inverse_transform(labels, sources) is mix(labels, sources) since 0.61 (inverse_transform "
                 "takes transform's one array); call mix", FutureWarning)
            return self.mix(X, sources)
        n_clusters = len(self.means_)
        X = check_array(X, "X", f"(n, N + F) = (n, {n_clusters + self.n_cdfs_})", ndim=2, min_rows=0)
        check_width(X, "X", f"(n, N + F) = (n, {n_clusters + self.n_cdfs_}) (transform's rows)",
                    (n_clusters + self.n_cdfs_,))
        with one_blas_thread():  # the same vectors on any number of cores
            return X[:, :n_clusters] @ self.means_ + X[:, n_clusters:] @ self._mixing_uncached()
