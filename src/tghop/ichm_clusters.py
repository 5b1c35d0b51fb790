"""The clusters of the core model (ICHM) and the model of each: how :class:`tghop.core.ICHM`
fits and draws one cluster's independent components.

Fitting (``ICHM.fit``), in order:

1. :func:`merge_small_clusters`: K-means clusters with fewer than ``min_cluster_size``
   members join their nearest larger cluster.
2. :func:`fit_cluster`: each cluster's PCA (the components that reach its energy) and
   FastICA of the whitened members give its mixing rows and its members' sources.
3. :func:`residual_factors` (setting ``residual``): the Gaussian of what the clusters'
   PCAs drop, one per group of dimensions.
4. :func:`histogram_cdfs` and :func:`cdf_codebook`: a histogram CDF per component,
   vector-quantised into a codebook of shapes.

Drawing (``ICHM.sample_sources``): :func:`quantile_table` inverts the codebook's CDFs once,
:func:`match_components` turns probabilities into component values through them, and
:func:`match_norms` (setting ``norm_match``) rescales each drawn vector towards the
training norms.

Functions of arrays only: the model's settings come in as arguments, and nothing here
keeps state.
"""

from __future__ import annotations

import numpy as np

from ._errors import TGHopError
from .sdr import flip_signs
from .unsupervised import fast_ica, kmeans

__all__ = ["merge_small_clusters", "fit_cluster", "residual_factors", "histogram_cdfs", "cdf_codebook",
           "quantile_table", "match_components", "match_norms", "AUTO_CLUSTERS", "AUTO_PER_CLUSTER", "AUTO_FEWEST",
           "QUANTILE_STEPS", "NORM_QUANTILES", "NORM_DRAWS"]

#: ``n_clusters=None``: one cluster per AUTO_PER_CLUSTER training vectors, within these bounds
#: (docs/choices.md, ICHM "0.27").
AUTO_CLUSTERS = (50, 100)
AUTO_PER_CLUSTER = 40
#: ... and from fewer than AUTO_CLUSTERS[0] x min_cluster_size vectors (a small exemplar's), one cluster per
#: min_cluster_size of them, at least AUTO_FEWEST: fewer vectors are refused (0.58; ICHM "0.58").
AUTO_FEWEST = 4
#: Resolution of the tabulated inverse CDFs used for sampling.
QUANTILE_STEPS = 1024
#: ``norm_match``: quantiles of the source norms stored per cluster (evenly spaced levels),
#: and the draws per cluster at fit that give the quantiles of the sampled norms.
NORM_QUANTILES = 33
NORM_DRAWS = 1000


# ------------------------------------------------------------------ fitting
def merge_small_clusters(Z, labels, centres, min_size):
    """Move the members of clusters under ``min_size`` to the nearest larger cluster's centre,
    and number the clusters left 0, 1, ... in order.

    Parameters
    ----------
    Z : ndarray, shape (n, D_r)
        The clustered vectors.
    labels : ndarray of int, shape (n,)
        Each vector's K-means cluster, in ``[0, k)``; changed in place.
    centres : ndarray, shape (k, D_r)
        The K-means centres.
    min_size : int
        The least members a cluster keeps (at most the largest cluster's count).

    Returns
    -------
    labels : ndarray of int, shape (n,)
        In ``[0, N)`` for the N clusters kept, renumbered in the order of the kept clusters'
        K-means numbers.
    """
    counts = np.bincount(labels, minlength=len(centres))
    small = counts < min_size
    if small.any():
        big = np.flatnonzero(~small)
        moved = small[labels]
        d = ((Z[moved, None, :] - centres[None, big, :]) ** 2).sum(-1)
        labels[moved] = big[np.argmin(d, axis=1)]
    _, labels = np.unique(labels, return_inverse=True)
    return labels


def fit_cluster(centred, rng, *, energy, max_components, max_ratio, max_iter, tol, residual=False, return_n_iter=False):
    """PCA-whiten one cluster's members and run FastICA on them.

    PCA keeps the fewest components that reach ``energy`` of the variance, at most
    ``max_components``, at most ``max_ratio`` of the members and fewer than them (and none
    of zero variance); it goes through the smaller of the n x n Gram matrix (a patch
    model's clusters have fewer members than dimensions) and the d x d scatter matrix.

    Parameters
    ----------
    centred : ndarray, shape (n, D_r)
        The cluster's members less their mean, n >= 2.
    rng : int or numpy.random.Generator
        FastICA's initial rotation.
    energy : float
        ``cluster_energy`` of :class:`tghop.core.ICHM`.
    max_components : int
        ``max_cluster_components``.
    max_ratio : float
        ``max_component_ratio``.
    max_iter : int
        FastICA's iterations.
    tol : float
        FastICA's tolerance.
    residual : bool, default=False
        Also return what the kept components miss of each member.
    return_n_iter : bool, default=False
        Also return FastICA's iterations, last (0.61).

    Returns
    -------
    mixing : ndarray, shape (k, D_r)
        ``centred``, within the kept components, is ``sources @ mixing``.
    sources : ndarray, shape (n, k)
        The members' independent components.
    converged : bool
        Whether FastICA converged within ``max_iter``.
    residual : ndarray of float32, shape (n, D_r)
        Only with ``residual``: ``centred`` less its projection on the kept components.
    n_iter : int
        Only with ``return_n_iter``: FastICA's iterations.
    """
    n, d = centred.shape
    gram = n <= d
    vals, vecs = np.linalg.eigh(centred @ centred.T if gram else centred.T @ centred)
    vals, vecs = np.maximum(vals[::-1], 0), vecs[:, ::-1]
    var = vals / n
    cum = np.cumsum(var) / max(var.sum(), 1e-300)
    k = int(np.searchsorted(cum, energy - 1e-12)) + 1
    k = max(1, min(k, max_components, int(max_ratio * n), n - 1, int(np.count_nonzero(var > 1e-12 * var[0]))))
    std = np.sqrt(var[:k])
    basis = flip_signs((vecs[:, :k].T @ centred) / np.sqrt(vals[:k])[:, None] if gram else vecs[:, :k].T)
    white = centred @ basis.T / std
    unmix, converged, n_iter = fast_ica(white, max_iter=max_iter, tol=tol, rng=rng, return_n_iter=True)
    sources = white @ unmix.T
    # z - mean = white * std @ basis = sources @ inv(unmix).T * std @ basis
    mixing = np.linalg.inv(unmix).T @ (std[:, None] * basis)
    out = (mixing, sources, converged)
    if residual:  # what the kept components miss (basis rows are orthonormal)
        out += ((centred - (centred @ basis.T) @ basis).astype(np.float32),)
    return out + (n_iter,) if return_n_iter else out


def residual_factors(residuals, d_r, groups=None):
    """The Gaussian of the residuals of all clusters, block-diagonal by group of dimensions.

    Parameters
    ----------
    residuals : list of ndarray, shape (n_i, D_r) each
        :func:`fit_cluster`'s residuals of each cluster.
    d_r : int
        D_r, the vectors' dimension.
    groups : array_like of int, shape (D_r,), optional
        The group of each dimension (None: one group of all).

    Returns
    -------
    groups : ndarray of int, shape (D_r,)
    factors : ndarray, shape (sum of squared group sizes,)
        For each group in increasing order, ``L`` row-major with ``L @ L.T`` the covariance of
        the group's residuals.
    """
    groups = np.zeros(d_r, dtype=np.int64) if groups is None else np.asarray(groups, dtype=np.int64)
    if groups.shape != (d_r,):
        raise TGHopError(f"groups must have one entry per dimension ({d_r}), got shape {groups.shape}")
    R = np.vstack(residuals)
    factors = []
    for g in np.unique(groups):
        block = R[:, groups == g]
        vals, vecs = np.linalg.eigh(block.T.astype(np.float64) @ block / len(R))
        factors.append((vecs * np.sqrt(np.maximum(vals, 0.0))).ravel())
    return groups, np.concatenate(factors)


def histogram_cdfs(sources, n_bins):
    """A histogram CDF of every component of every cluster, between its minimum and maximum.

    Parameters
    ----------
    sources : list of ndarray, shape (n_i, k_i) each
        Each cluster's members' independent components.
    n_bins : int
        Bins per histogram.

    Returns
    -------
    cdfs : ndarray, shape (F, n_bins)
        The CDF at the right edge of each bin, for the F = sum of k_i components in order.
    lo, hi : ndarray, shape (F,)
        Each component's least and greatest value (the bins span them).
    """
    cdfs, lo, hi = [], [], []
    for s in sources:
        smin, smax = s.min(axis=0), s.max(axis=0)
        width = np.where(smax > smin, smax - smin, 1.0)
        idx = np.clip(((s - smin) / width * n_bins).astype(np.int64), 0, n_bins - 1)
        k = s.shape[1]
        hist = np.bincount((idx + n_bins * np.arange(k)).ravel(), minlength=k * n_bins).reshape(k, n_bins)
        cdfs.append(np.cumsum(hist, axis=1) / s.shape[0])
        lo.append(smin)
        hi.append(smax)
    return np.vstack(cdfs), np.concatenate(lo), np.concatenate(hi)


def cdf_codebook(cdfs, n_codewords, rng):
    """Vector-quantise CDFs into at most ``n_codewords`` shapes (K-means), each a CDF again.

    Parameters
    ----------
    cdfs : ndarray, shape (F, n_bins)
        :func:`histogram_cdfs`'s.
    n_codewords : int
        W at most; with F <= W every CDF is its own codeword.
    rng : int or numpy.random.Generator
        For K-means (not drawn from with F <= W).

    Returns
    -------
    codebook : ndarray, shape (min(F, W), n_bins)
        Non-decreasing in [0, 1], last value 1.
    index : ndarray of int, shape (F,)
        Each CDF's codeword.
    """
    if cdfs.shape[0] <= n_codewords:
        return cdfs, np.arange(cdfs.shape[0], dtype=np.int64)
    labels, centres = kmeans(cdfs, n_codewords, rng)
    codebook = np.maximum.accumulate(np.clip(centres, 0.0, 1.0), axis=1)
    codebook[:, -1] = 1.0
    return codebook, labels.astype(np.int64)


# ------------------------------------------------------------------ drawing
def quantile_table(codebook):
    """The inverse CDF of each codeword, tabulated at ``QUANTILE_STEPS + 1`` even probabilities.

    Parameters
    ----------
    codebook : ndarray, shape (W, n_bins)
        CDFs at the right edges of ``n_bins`` even bins of [0, 1] (linear between edges).

    Returns
    -------
    table : ndarray, shape (W, QUANTILE_STEPS + 1)
        In [0, 1]: the fraction of a component's range at each probability.
    """
    nb = codebook.shape[1]
    edges = np.linspace(0.0, 1.0, nb + 1)
    grid = np.linspace(0.0, 1.0, QUANTILE_STEPS + 1)
    cdf = np.hstack([np.zeros((len(codebook), 1)), codebook])
    return np.vstack([np.interp(grid, c, edges) for c in cdf])


def match_components(uniform, codes, lo, hi, table):
    """(ii-iii) Map probabilities through each component's inverse CDF.

    The paper draws standard normals and maps them through Phi; Phi of a standard normal is
    uniform on [0, 1), so the uniform numbers are drawn directly (the same distribution,
    without SciPy's ``ndtr`` on the generation path).

    Parameters
    ----------
    uniform : ndarray, shape (m, k)
        Probabilities in [0, 1], a column per component.
    codes : ndarray of int, shape (k,)
        Each component's codeword (a row of ``table``).
    lo, hi : ndarray, shape (k,)
        Each component's range.
    table : ndarray, shape (W, QUANTILE_STEPS + 1)
        :func:`quantile_table`'s.

    Returns
    -------
    values : ndarray, shape (m, k)
        In ``[lo, hi]``, linear between the table's steps.
    """
    u = uniform * QUANTILE_STEPS
    step = np.minimum(u.astype(np.int64), QUANTILE_STEPS - 1)
    frac = u - step
    t = table[codes, step] * (1.0 - frac) + table[codes, step + 1] * frac
    return lo + (hi - lo) * t


def match_norms(s, norm_quantiles, sampled_quantiles, power):
    """Rescale each drawn vector of one cluster towards the training norm at its norm's rank
    among the draws: by (that norm / its own) ** ``power``, in place.

    Parameters
    ----------
    s : ndarray, shape (m, k)
        One cluster's drawn sources; rescaled in place.
    norm_quantiles, sampled_quantiles : ndarray, shape (q,)
        The cluster's training source norms and its fit-time draws' norms at ``q`` evenly
        spaced levels.
    power : float
        ``norm_match``, in [0, 1].

    Returns
    -------
    s : ndarray, shape (m, k)
        The same array.
    """
    if not len(s):
        return s
    levels = np.linspace(0.0, 1.0, len(norm_quantiles))
    r = np.linalg.norm(s, axis=1)
    target = np.interp(np.interp(r, sampled_quantiles, levels), levels, norm_quantiles)
    s *= ((target / np.maximum(r, 1e-300)) ** power)[:, None]
    return s
