"""Spatial dimension reduction (SDR), paper section IV.C: the first step of the core model.

``SpatialReduction`` turns core responses ``(n, 8, 8, K2)`` into vectors ``z`` of dimension
``D_r`` by a PCA of each core channel's spatial map; :class:`tghop.core.ICHM` then learns the
distribution of ``z``.

``gamma`` is an absolute variance threshold on each channel's spatial PCA components, for
images scaled to [0, 1] (``gamma_mode="absolute"``, the paper's wording "variances lower than
threshold gamma"); ``gamma_mode="relative"`` instead compares with the channel's total variance.
"""

from __future__ import annotations

import numpy as np

from ._arrays import check_array, check_width, forget_fit
from ._errors import TGHopError
from ._estimator import BaseEstimator, FourDInputMixin, TransformerMixin, check_is_fitted
from .settings import BY_NAME as _SETTINGS

__all__ = ["SpatialReduction", "flip_signs"]


def flip_signs(components):
    """Make the entry of largest magnitude of each row positive (deterministic PCA).

    Parameters
    ----------
    components : ndarray, shape (k, d)
        PCA components, one a row.

    Returns
    -------
    ndarray, shape (k, d)
        A new array: each row times the sign of its entry of largest magnitude.
    """
    pivot = np.argmax(np.abs(components), axis=1)
    return components * np.sign(components[np.arange(len(components)), pivot])[:, None]


def _channel_major(Y, chunk=64):
    """(n, h, w, K) -> contiguous (K, n, h * w): one channel's maps side by side.

    A view when ``Y`` is one already (the core :meth:`tghop.hops.HopStack.fit_image` returns);
    otherwise copied ``chunk`` samples at a time: the source rows of a chunk stay in cache while
    they are scattered over the K channels (faster than one transposing copy of a large
    core, whose strided accesses miss the cache)."""
    n, h, w, k = Y.shape
    if Y.transpose(3, 0, 1, 2).flags.c_contiguous:
        return Y.transpose(3, 0, 1, 2).reshape(k, n, h * w)
    src = Y.reshape(n, h * w, k)
    out = np.empty((k, n, h * w), dtype=Y.dtype)
    for a in range(0, n, chunk):
        out[:, a : a + chunk] = src[a : a + chunk].transpose(2, 0, 1)
    return out


class SpatialReduction(FourDInputMixin, TransformerMixin, BaseEstimator):
    """Spatial dimension reduction: per-channel PCA of each core channel's spatial map.

    Parameters
    ----------
    gamma : float, default=0.01
        PCA components whose variance is below ``gamma`` are dropped (the same threshold
        for every channel). 0 keeps all of them.
    gamma_mode : {"absolute", "relative"}, default="absolute"
        Compare ``gamma`` with the component variance itself, or with its fraction of
        the channel's total variance.

    Attributes
    ----------
    mean_ : ndarray, shape (K, h * w)
        Mean spatial map of each channel.
    components_ : ndarray, shape (D_r, h * w)
        Kept components of all channels, grouped by channel.
    channel_ : ndarray of int, shape (D_r,)
        Channel of each kept component.
    explained_variance_ : ndarray, shape (D_r,)
    kept_per_channel_ : ndarray of int, shape (K,)
    """

    def __init__(self, gamma=0.01, gamma_mode="absolute"):
        self.gamma = gamma
        self.gamma_mode = gamma_mode

    def fit(self, Y, y=None):
        """Learn from core responses ``Y`` of shape (n, h, w, K).

        Parameters
        ----------
        Y : array_like, shape (n_samples, h, w, K)
            Core responses (:meth:`tghop.hops.HopStack.transform`), at least 2 samples.
        y : None
            Ignored (scikit-learn's signature).

        Returns
        -------
        self
        """
        self.fit_transform(Y)
        return self

    def fit_transform(self, Y, y=None):
        """Fit, then return ``z`` of shape (n, D_r).

        A failed fit leaves the estimator unfitted (a previous fit is forgotten).

        Parameters
        ----------
        Y : array_like, shape (n_samples, h, w, K)
            As :meth:`fit` takes it.
        y : None
            Ignored (scikit-learn's signature).

        Returns
        -------
        z : ndarray, shape (n_samples, D_r), float64
            :meth:`transform` of ``Y``.
        """
        forget_fit(self)
        _SETTINGS["gamma"].check(self.gamma)
        _SETTINGS["gamma_mode"].check(self.gamma_mode)
        Y = check_array(Y, "Y", "(n_samples, h, w, K) of core responses", ndim=4, min_rows=2)
        n, h, w, k = Y.shape
        if min(h, w, k) < 1:
            raise TGHopError(f"Y must have shape (n_samples, h, w, K) with h, w, K >= 1, got {Y.shape}")
        maps = _channel_major(Y)
        mean = maps.mean(axis=1)
        comps, var, chan = [], [], []
        for c in range(k):
            centred = maps[c] - mean[c]
            vals, vecs = np.linalg.eigh(centred.T @ centred / n)
            vals, vecs = vals[::-1], vecs[:, ::-1].T
            limit = self.gamma * (vals.sum() if self.gamma_mode == "relative" else 1.0)
            keep = vals > limit if self.gamma > 0 else vals > 1e-12 * max(vals.sum(), 1e-300)
            comps.append(flip_signs(vecs[keep]))
            var.append(vals[keep])
            chan.append(np.full(int(keep.sum()), c))
        if sum(len(part) for part in comps) == 0:  # before any learned attribute is set
            raise TGHopError(f"gamma={self.gamma} drops every spatial component; use a smaller gamma")
        self.shape_ = (h, w, k)
        self.mean_ = mean
        self.components_ = np.vstack(comps)
        self.explained_variance_ = np.concatenate(var)
        self.channel_ = np.concatenate(chan).astype(np.int64)
        self.kept_per_channel_ = np.bincount(self.channel_, minlength=k)
        return self._project(maps)

    #: (file name, attribute, dtype): the arrays of a model file that belong to SDR.
    _ARRAYS = (
        ("sdr.components", "components_", np.float64),
        ("sdr.mean", "mean_", np.float64),
        ("index.sdr_channel", "channel_", np.int64),
        ("index.sdr_variance", "explained_variance_", np.float64),
    )

    def _to_arrays(self) -> dict:
        return {name: getattr(self, attr) for name, attr, _ in self._ARRAYS}

    def _from_arrays(self, arrays, shape):
        """Restore the fitted state from :meth:`_to_arrays` output and ``shape_``; returns self."""
        for name, attr, dtype in self._ARRAYS:
            setattr(self, attr, arrays[name].astype(dtype, copy=False))
        self.shape_ = tuple(shape)
        self.kept_per_channel_ = np.bincount(self.channel_, minlength=self.shape_[2])
        return self

    @staticmethod
    def _array_specs(shape):
        """SDR's arrays for core maps of ``shape`` (h, w, K), for the checks of
        :mod:`tghop.modelfile`: ``(name, shape, kind, says, rules)`` each; sets D_r."""
        h, w, k = shape
        return (
            ("sdr.components", ("D_r", h * w), "f", f"the metadata says {h}x{w} core maps",
             (("dim", 0, 1, None),)),
            ("sdr.mean", (k, h * w), "f", f"the metadata says {k} core channels of {h}x{w}", ()),
            ("index.sdr_channel", ("D_r",), "i", "one channel per row of sdr.components",
             (("index", k), ("nondecreasing",))),
            ("index.sdr_variance", ("D_r",), "f", "one variance per row of sdr.components",
             (("range", 0, None), ("unbounded",))),
        )

    @property
    def n_components_(self) -> int:
        """D_r, the dimension after SDR."""
        check_is_fitted(self, "components_")
        return self.components_.shape[0]

    def transform(self, Y):
        """Core responses ``(n, h, w, K)`` -> ``z`` of shape (n, D_r).

        Parameters
        ----------
        Y : array_like, shape (n, h, w, K)
            Of the fitted ``shape_`` (h, w, K).

        Returns
        -------
        z : ndarray, shape (n, D_r), float64
            Each channel's spatial map, less its mean, on the channel's kept components, channel by channel.
        """
        check_is_fitted(self, "components_")
        # Finite real numbers of any rank here (a scalar: check_array's message), the shape just below.
        Y = check_array(Y, "Y", "(n, {}, {}, {})".format(*self.shape_), ndim=max(np.ndim(Y), 1), min_rows=0)
        check_width(Y, "Y", "(n, {}, {}, {})".format(*self.shape_), self.shape_)
        return self._project(_channel_major(Y))

    def channel_ranges(self):
        """Each core channel's rows of :attr:`components_` (and columns of ``z``): fit keeps the
        components in channel order, so each channel's are one range (empty where a channel keeps none).

        Returns
        -------
        list of tuple of int
            ``[(start, stop), ...]``, one per core channel (K of them).
        """
        check_is_fitted(self, "components_")
        bounds = np.searchsorted(self.channel_, np.arange(self.shape_[2] + 1))
        return list(zip(bounds[:-1].tolist(), bounds[1:].tolist()))

    def _project(self, maps):
        z = np.empty((maps.shape[1], self.components_.shape[0]))
        for c, (a, e) in enumerate(self.channel_ranges()):
            if a < e:
                z[:, a:e] = (maps[c] - self.mean_[c]) @ self.components_[a:e].T
        return z

    def inverse_transform(self, Z):
        """``z`` (n, D_r) -> core responses (n, h, w, K); dropped components are zero.

        Parameters
        ----------
        Z : array_like, shape (n, D_r)
            As :meth:`transform` returns it (or drawn by the core model).

        Returns
        -------
        Y : ndarray, shape (n, h, w, K), float64
            The input of :meth:`transform` projected on the kept components (about its mean): the
            input itself where they span every spatial map (``gamma`` 0 and training data of full rank).
        """
        check_is_fitted(self, "components_")
        Z = check_array(Z, "Z", f"(n, D_r) = (n, {self.components_.shape[0]})", ndim=max(np.ndim(Z), 1), min_rows=0)
        check_width(Z, "Z", f"(n, D_r) = (n, {self.components_.shape[0]})", self.components_.shape[:1])
        h, w, k = self.shape_
        out = np.repeat(self.mean_.T[None], Z.shape[0], axis=0)
        for c, (a, e) in enumerate(self.channel_ranges()):
            if a < e:
                out[:, :, c] += Z[:, a:e] @ self.components_[a:e]
        return out.reshape(Z.shape[0], h, w, k)
