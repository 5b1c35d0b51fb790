"""K-means and FastICA in NumPy: the unsupervised steps of the core model (ICHM).

NumPy only, so that fitting never imports scikit-learn's estimators (their import alone
is a large part of a fit's time) and generation never imports scikit-learn at all.
:class:`tghop.core.ICHM` clusters the core vectors with :func:`kmeans` and finds each
cluster's independent components with :func:`fast_ica`.
"""

from __future__ import annotations

import numpy as np

from ._estimator import check_rng

__all__ = ["kmeans", "kmeans_plusplus", "lloyd", "nearest", "fast_ica"]


def kmeans_plusplus(X, n_clusters, rng, n_trials=None):
    """Greedy k-means++ seeding (Arthur & Vassilvitskii 2007), vectorised over candidates.

    Parameters
    ----------
    X : ndarray, shape (n, d)
        Points, at least one.
    n_clusters : int
        Centres to pick.
    rng : int or numpy.random.Generator
        The picks' random stream.
    n_trials : int, optional
        Candidates tried per centre (default ``2 + log(n_clusters)``, scikit-learn's).

    Returns
    -------
    centres : ndarray, shape (n_clusters, d), ``X``'s dtype
        Rows of ``X`` (repeated where ``X`` has fewer distinct points).
    """
    rng = check_rng(rng)
    n = len(X)
    n_trials = n_trials or 2 + int(np.log(n_clusters))
    sq = np.einsum("nd,nd->n", X, X)
    centres = np.empty((n_clusters, X.shape[1]), dtype=X.dtype)
    centres[0] = X[rng.integers(n)]
    closest = np.maximum(sq - 2 * X @ centres[0] + centres[0] @ centres[0], 0)
    for k in range(1, n_clusters):
        total = closest.sum()
        if total <= 0:  # fewer distinct points than clusters: repeat points
            centres[k:] = X[rng.integers(n, size=n_clusters - k)]
            break
        cand = np.searchsorted(np.cumsum(closest), rng.random(n_trials) * total)
        cand = np.minimum(cand, n - 1)
        d = np.maximum(sq[cand, None] - 2 * X[cand] @ X.T + sq[None, :], 0)
        d = np.minimum(d, closest)
        best = np.argmin(d.sum(axis=1))
        centres[k] = X[cand[best]]
        closest = d[best]
    return centres


def lloyd(X, centres, max_iter=100, tol=1e-4, settled=1e-3):
    """Lloyd iterations from ``centres`` (float32 points, one matrix product per step).

    Stops when the centres move less than ``tol`` times the mean per-dimension variance
    of ``X`` (scikit-learn's criterion) or when at most a fraction ``settled`` of the
    points changed cluster in a step (cutting the long tail of steps that move a handful
    of points, at a negligible rise in inertia; measured: docs/choices.md), after
    ``max_iter`` steps at the latest. The cluster sums are updated with the points that
    changed cluster only (few after the first steps). An emptied cluster is re-seeded with
    the point farthest from its centre.

    Parameters
    ----------
    X : ndarray, shape (n, d), float32
        Points.
    centres : ndarray, shape (k, d)
        Initial centres (:func:`kmeans_plusplus`).
    max_iter : int
        Steps at most.
    tol : float
        Centre movement below which it stops, relative to the points' mean variance.
    settled : float
        Fraction of points changing cluster at or below which it stops.

    Returns
    -------
    labels : ndarray of int, shape (n,)
    centres : ndarray, shape (k, d), float32
    """
    n, k = len(X), len(centres)
    threshold = tol * _mean_variance(X)
    few = int(settled * n)
    labels = np.full(n, -1)
    sums = np.zeros((k, X.shape[1]))
    counts = np.zeros(k, dtype=np.int64)
    for _ in range(int(max_iter)):
        # argmin_j |x - c_j|^2 = argmin_j (|c_j|^2 - 2 x.c_j): |x|^2 is the same for all j.
        d = np.einsum("kd,kd->k", centres, centres)[None, :] - 2.0 * (X @ centres.T)
        new = np.argmin(d, axis=1)
        changed = np.flatnonzero(new != labels)
        if changed.size == 0:
            break
        # +1 where a point joins a cluster, -1 where it leaves one: one product updates the sums.
        moves = np.zeros((k, changed.size), dtype=X.dtype)
        moves[new[changed], np.arange(changed.size)] = 1.0
        old = labels[changed]
        was = np.flatnonzero(old >= 0)
        moves[old[was], was] = -1.0
        sums += moves @ X[changed]
        counts += np.bincount(new[changed], minlength=k) - np.bincount(old[was], minlength=k)
        labels = new
        moved = centres.astype(np.float64)
        full = counts > 0
        moved[full] = sums[full] / counts[full, None]
        empty = np.flatnonzero(~full)
        if empty.size:  # re-seed with the points farthest from their centres
            far = np.argsort(d[np.arange(n), labels] + np.einsum("nd,nd->n", X, X))[::-1][: empty.size]
            moved[empty] = X[far]
        shift = float(((moved - centres) ** 2).sum())
        centres = moved.astype(np.float32)
        if shift <= threshold or changed.size <= few:
            break
    return nearest(X, centres), centres


def nearest(X, centres, chunk=None):
    """The index of each row of ``X`` (n, d)'s nearest row of ``centres`` (k, d) in Euclidean
    distance: ``argmin_j |c_j|^2 - 2 x.c_j`` (``|x|^2`` is the same for all j), ``chunk`` rows
    at a time (None: all at once; memory ``chunk x k``).

    Parameters
    ----------
    X : ndarray, shape (n, d)
    centres : ndarray, shape (k, d)
    chunk : int, optional
        Rows of ``X`` at a time.

    Returns
    -------
    ndarray of int, shape (n,)
    """
    sq = np.einsum("kd,kd->k", centres, centres)[None, :]
    if chunk is None:
        return np.argmin(sq - 2.0 * (X @ centres.T), axis=1)
    out = np.empty(len(X), dtype=np.int64)
    for a in range(0, len(X), chunk):
        out[a: a + chunk] = np.argmin(sq - 2.0 * (X[a: a + chunk] @ centres.T), axis=1)
    return out


def _mean_variance(X, chunk=1024):
    """The mean over columns of each column's variance, in float64, ``chunk`` rows at a
    time: ``X.var(axis=0, dtype=np.float64).mean()`` without a float64 copy of ``X``."""
    mean = X.mean(axis=0, dtype=np.float64)
    total = np.zeros(X.shape[1])
    for a in range(0, len(X), chunk):
        dev = X[a: a + chunk] - mean
        total += np.einsum("nd,nd->d", dev, dev)
    return float((total / max(len(X), 1)).mean())


def kmeans(X, n_clusters, rng, max_iter=100, init_sample=2000, fit_sample=5000, polish=10):
    """K-means: k-means++ seeding on a random subsample of ``init_sample`` points (seeding
    on all points costs several times the whole Lloyd iteration for the same inertia); with
    more than ``fit_sample`` points, Lloyd to convergence on a random ``fit_sample`` of them
    and then at most ``polish`` steps on all (from the same seeds, Lloyd on all 20,000 core
    vectors took 40-60 steps; this ends 0.05-0.6 % higher in inertia in a third to a half of the time:
    docs/choices.md); all in float32 (the clustering only routes samples to clusters; each
    step reads the points, so half the bytes is about half the time). NumPy only: importing
    scikit-learn's KMeans would add its long import time to every fit.

    Parameters
    ----------
    X : array_like, shape (n, d)
        Points, at least ``n_clusters``.
    n_clusters : int
        k.
    rng : int or numpy.random.Generator
        The subsamples' and the seeding's random stream.
    max_iter : int
        Lloyd steps at most.
    init_sample, fit_sample, polish : int
        As above.

    Returns
    -------
    labels : ndarray of int, shape (n,)
    centres : ndarray, shape (n_clusters, d), float64 (found in float32)
    """
    rng = check_rng(rng)
    centres = kmeans_plusplus(np.asarray(_sample_rows(X, init_sample, rng), dtype=np.float32), n_clusters, rng)
    X = np.asarray(X, dtype=np.float32)
    steps = max_iter
    if len(X) > fit_sample:
        _, centres = lloyd(_sample_rows(X, fit_sample, rng), centres, max_iter=max_iter)
        steps = polish
    labels, centres = lloyd(X, centres, max_iter=steps)
    return labels, centres.astype(np.float64)


def _sample_rows(X, n, rng):
    """``X``, or ``n`` of its rows drawn at random (kept in their order) when it has more."""
    return X if len(X) <= n else X[np.sort(rng.choice(len(X), n, replace=False))]


def _orthonormal(w, tol=0.01) -> bool:
    """Whether every row of ``w`` has unit length within ``tol`` (False for NaN): the
    symmetric decorrelation of a singular FastICA update blows a direction up instead."""
    return bool(np.abs(np.einsum("ij,ij->i", w, w) - 1.0).max() <= tol)


def fast_ica(white, *, max_iter=200, tol=1e-4, rng=None, return_n_iter=False):
    """Symmetric FastICA (Hyvarinen 1999) with the logcosh contrast on whitened data.

    Parameters
    ----------
    white : ndarray, shape (n, k)
        Zero-mean data with identity covariance.
    max_iter : int
    tol : float
        Stop when every unmixing direction changes by less than this.
    rng : int or numpy.random.Generator, optional
        Initial rotation.
    return_n_iter : bool, default=False
        Also return the iterations run (0.61; scikit-learn's ``fastica`` has it).

    Returns
    -------
    unmix : ndarray, shape (k, k)
        Orthogonal matrix; the independent components are ``white @ unmix.T``.
    converged : bool
    n_iter : int, only with ``return_n_iter``
        Iterations run (1 for one component: nothing to iterate).
    """
    n, k = white.shape
    if k == 1:
        return (np.ones((1, 1)), True, 1)[:3 if return_n_iter else 2]

    def decorrelate(w):
        vals, vecs = np.linalg.eigh(w @ w.T)
        return (vecs / np.sqrt(np.maximum(vals, np.finfo(vals.dtype).tiny))) @ vecs.T @ w

    # The iterations run in float32 (tanh and the products cost a fifth of float64's; the
    # tolerance is far above float32's resolution); the result is orthogonalised in float64.
    w = good = decorrelate(check_rng(rng).standard_normal((k, k))).astype(np.float32)
    x = np.asarray(white, dtype=np.float32)
    xt = np.ascontiguousarray(x.T)
    converged, n_iter = False, 0
    for n_iter in range(1, int(max_iter) + 1):
        g = np.tanh(w @ xt)
        w_new = decorrelate(g @ x / n - (1.0 - g**2).mean(axis=1)[:, None] * w)
        if not np.isfinite(w_new).all():
            break  # the decorrelation broke down: the last orthonormal iterate below
        change = np.max(np.abs(np.abs(np.einsum("ij,ij->i", w_new, w)) - 1.0))
        w = w_new
        if _orthonormal(w):
            good = w
        if change < tol:
            converged = True
            break
    out = decorrelate(w.astype(np.float64))
    if not _orthonormal(out):
        # A singular update (few samples in many dimensions) blew a direction up and the
        # iterations ended there: the last orthogonal iterate instead, unconverged.
        return (decorrelate(good.astype(np.float64)), False, n_iter)[:3 if return_n_iter else 2]
    return (out, converged, n_iter)[:3 if return_n_iter else 2]
