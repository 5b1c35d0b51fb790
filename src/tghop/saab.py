"""The Saab transform (subspace approximation with adjusted bias) on flat vectors.

A Saab transform of ``d``-dimensional vectors has one DC kernel, the constant vector of
unit norm ``1/sqrt(d)``, and ``d - 1`` AC kernels, the principal components of the
DC-removed vectors. All ``d`` kernels are orthonormal, so keeping them all gives an exact
inverse (``x = y @ kernels``). A single shared bias, the largest input norm, is added to
the AC responses so that they are non-negative (the "adjusted bias"); it is subtracted on
the way back. Between TGHop's hops there is no nonlinearity, so the bias only shifts
responses and does not change what is generated; it is kept for faithfulness to the
paper's parameter count.

Choices not fixed by the paper (documented here and in the notes):

* The DC kernel is unit-norm (not divided by its energy) so that the kernels are
  orthonormal and the inverse is exact.
* Eigenvector signs are fixed: the entry of largest magnitude of each kernel is positive.
* Channel energy is the mean squared response (not the variance), so DC and AC channels
  are comparable; the DC channel always comes first.
* Rank deficiency (e.g. a grey image stored as RGB) gives zero-energy channels; they are
  never kept, whatever ``n_components`` asks for.
"""

from __future__ import annotations

import math

import numpy as np

from ._arrays import check_array, check_number, check_width, forget_fit
from ._errors import TGHopError
from ._estimator import BaseEstimator, TransformerMixin, check_is_fitted
from .settings import check_channel_rule

__all__ = ["Saab", "select_channels", "knee_point"]

#: Channels whose energy is below this fraction of the total are treated as empty.
ZERO_ENERGY = 1e-12


def knee_point(energy) -> int:
    """Number of leading channels up to the knee of a decreasing energy curve.

    The knee is where the curve "becomes flat" (paper, section V.A): the point farthest
    below the straight line joining the first and last points of ``log10(energy)``
    (Kneedle). The log scale keeps one dominant channel from hiding the rest.

    Parameters
    ----------
    energy : array_like, shape (m,)
        Energies in decreasing order, all positive.

    Returns
    -------
    int
        Count of channels to keep, in ``[1, m]``.
    """
    e = np.log10(np.maximum(np.asarray(energy, dtype=np.float64), 1e-300))
    m = e.size
    if m <= 2:
        return m
    x = np.linspace(0.0, 1.0, m)
    y = (e - e[-1]) / max(e[0] - e[-1], 1e-300)
    # Distance below the chord y = 1 - x of a decreasing convex curve.
    return int(np.argmax((1.0 - x) - y)) + 1


def select_channels(energy, rule, *, n_fixed=0) -> np.ndarray:
    """Choose AC channels by energy, strongest first.

    Parameters
    ----------
    energy : array_like, shape (m,)
        Energy of each candidate AC channel.
    rule : None, int, float or "knee"
        None keeps every non-empty channel; an int is the total channel count including
        the ``n_fixed`` DC channels that are always kept (so ``rule - n_fixed`` AC
        channels); a float in (0, 1] keeps the fewest AC channels whose energy reaches
        that fraction of the total AC energy; "knee" cuts at the knee of the curve.
    n_fixed : int
        DC channels kept regardless of the rule.

    Returns
    -------
    ndarray of int, shape (k,)
        Indices into ``energy``; empty channels (energy below ``1e-12`` of the total) are
        never chosen.
    """
    energy = np.asarray(energy, dtype=np.float64)
    rule = check_channel_rule(rule, none_ok=True)
    order = np.argsort(-energy, kind="stable")
    total = energy.sum()
    nonzero = int(np.count_nonzero(energy[order] > ZERO_ENERGY * max(total, 1e-300)))
    if nonzero == 0:
        return order[:0]
    if rule is None:
        k = nonzero
    elif rule == "knee":
        k = knee_point(energy[order[:nonzero]])
    elif isinstance(rule, int):
        k = min(max(rule - n_fixed, 0), nonzero)
    else:
        cum = np.cumsum(energy[order]) / total
        k = min(int(np.searchsorted(cum, rule - 1e-12)) + 1, nonzero)
    return order[:k]


class Saab(TransformerMixin, BaseEstimator):
    """Saab transform of flat vectors: a unit DC kernel plus PCA AC kernels.

    Parameters
    ----------
    n_components : None, int, float or "knee", default=None
        Channels to keep, the DC channel always among them; see :func:`select_channels`.
        None keeps all non-empty channels, which makes :meth:`inverse_transform` exact.
        An int above the dimension ``d`` of the vectors is an error at fit.

    Attributes
    ----------
    kernels_ : ndarray, shape (k, d)
        Orthonormal rows; row 0 is the DC kernel ``ones(d) / sqrt(d)``.
    channels_ : ndarray of int, shape (k,)
        Index of each kept kernel among all ``d`` (0 is DC, then AC by decreasing energy).
    energy_ : ndarray, shape (d,)
        Mean squared response (bias excluded) of all ``d`` channels, kept or not, in the
        same order: the squared error per vector that dropping the channel costs. A loaded
        model's Saabs have it from the model file's metadata; files of tghop 0.55 and before keep
        the kept channels' energies only (:attr:`tghop.hops.Hop.energy_`), and reading it then is
        an AttributeError saying so.
    bias_ : float
        Added to AC responses: the largest norm of the fitting vectors.
    n_features_in_ : int
    """

    def __init__(self, n_components=None):
        self.n_components = n_components

    def __getattr__(self, name):
        # Only for attributes not found: a loaded Saab without every channel's energy says why it has none.
        if name == "energy_" and self.__dict__.get("_energy_unknown_"):
            raise AttributeError("this Saab was loaded from a model file of tghop 0.55 or before, which keeps the kept "
                                 "channels' energies only (its Hop's energy_); fit the model again for every channel's")
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @staticmethod
    def _all_kernels(mean, second_moment):
        """DC kernel plus the d - 1 PCA directions of the DC-free subspace, by variance."""
        d = mean.size
        dc = np.full(d, 1.0 / np.sqrt(d))
        # Orthonormal basis Q of the complement of the DC direction.
        q, _ = np.linalg.qr(np.column_stack([dc, np.eye(d)[:, : d - 1]]))
        comp = q[:, 1:]
        cov = comp.T @ (second_moment - np.outer(mean, mean)) @ comp
        _, vecs = np.linalg.eigh((cov + cov.T) / 2)
        ac = (comp @ vecs[:, ::-1]).T
        pivot = np.argmax(np.abs(ac), axis=1)
        ac *= np.sign(ac[np.arange(d - 1), pivot])[:, None]
        return np.vstack([dc, ac])

    def fit(self, X, y=None):
        """Learn the kernels from vectors ``X`` of shape (n_samples, d).

        Parameters
        ----------
        X : array_like, shape (n_samples, d)
            At least 2 vectors of dimension d >= 2, finite (else :class:`~tghop.TGHopError`).
        y : None
            Ignored (scikit-learn's signature).

        Returns
        -------
        self
        """
        X = check_array(X, "X", "(n_samples, d)", ndim=2, finite=False)
        # In scikit-learn's words too ("found 1 sample(s) (shape=(1, 10)) while a minimum of 2 is required").
        if X.shape[1] < 2:
            raise TGHopError(f"Saab needs vectors of dimension d >= 2: found {X.shape[1]} feature(s) (shape={X.shape}) "
                             "while a minimum of 2 is required; give X of shape (n_samples, d) with d >= 2")
        if X.shape[0] < 2:
            raise TGHopError(f"Saab needs at least 2 vectors: found {X.shape[0]} sample(s) (shape={X.shape}) "
                             "while a minimum of 2 is required; give X at least 2 rows")
        if not np.isfinite(X).all():
            raise TGHopError("X contains NaN or infinite values; clean it first")
        return self.fit_moments(
            X.mean(axis=0), X.T @ X / X.shape[0], float(np.max(np.einsum("nd,nd->n", X, X)))
        )

    def fit_moments(self, mean, second_moment, max_sq_norm):
        """Learn the kernels from the statistics of the vectors instead of the vectors.

        Parameters
        ----------
        mean : ndarray, shape (d,)
        second_moment : ndarray, shape (d, d)
            ``X.T @ X / n``.
        max_sq_norm : float
            Largest squared norm of a vector (sets the bias).

        Returns
        -------
        self
        """
        forget_fit(self)
        rule = check_channel_rule(self.n_components, "n_components", none_ok=True)
        mean = check_array(mean, "mean", "(d,)", ndim=1)
        d = mean.size
        if d < 2:
            raise TGHopError(f"Saab needs vectors of dimension >= 2, got a mean of shape {mean.shape}")
        second_moment = check_array(second_moment, "second_moment", f"(d, d) = ({d}, {d})", ndim=2, samples=False)
        if second_moment.shape != (d, d):
            raise TGHopError(f"second_moment must have shape (d, d) = ({d}, {d}), got {second_moment.shape}")
        max_sq_norm = check_number(max_sq_norm, "max_sq_norm")
        if isinstance(rule, int) and rule > d:
            raise TGHopError(f"a Saab transform of {d}-dimensional vectors has at most {d} components, "
                             f"got n_components={rule}; choose at most {d}")
        kernels = self._all_kernels(mean, second_moment)
        energy = np.einsum("kd,de,ke->k", kernels, second_moment, kernels)
        # AC kernels by decreasing energy (mean square, i.e. variance plus squared mean).
        order = np.concatenate([[0], 1 + np.argsort(-energy[1:], kind="stable")])
        ac = 1 + select_channels(energy[order][1:], rule, n_fixed=1)
        self.energy_ = energy[order]
        self.n_features_in_ = mean.size
        self.bias_ = math.sqrt(max_sq_norm)
        self._all_kernels_ = kernels[order]
        self._set_channels(np.concatenate([[0], np.sort(ac)]))
        return self

    def _set_channels(self, channels):
        self.channels_ = np.asarray(channels, dtype=np.int64)
        self.kernels_ = self._all_kernels_[self.channels_]

    def keep(self, channels):
        """Keep only the given channels (indices among all ``d``, as in :attr:`energy_`).

        Channel-wise hops use this to choose channels across several Saab transforms. A loaded
        Saab cannot (a model file keeps the kept channels' kernels only): :class:`~tghop.TGHopError`.

        Parameters
        ----------
        channels : array_like of int
            Indices in ``[0, d)`` (0: the DC kernel); sorted and made unique. An empty list keeps none.

        Returns
        -------
        self
        """
        check_is_fitted(self, "kernels_")
        if "_all_kernels_" not in vars(self):
            raise TGHopError("this Saab was loaded from a model file, which keeps the kept channels' kernels only; "
                             "fit it again (or the model) to keep other channels")
        channels = np.unique(np.asarray(channels, dtype=np.int64))
        if channels.size and (channels.min() < 0 or channels.max() >= self.n_features_in_):
            raise TGHopError(f"channel indices must lie in [0, {self.n_features_in_}), got {channels.tolist()}")
        self._set_channels(channels)
        return self

    def _ac_bias(self):
        return self.bias_ * (self.channels_ != 0)

    def transform(self, X):
        """Responses of ``X`` (n, d) to the kept kernels: shape (n, k).

        Parameters
        ----------
        X : array_like, shape (n, d)
            Finite numbers; n may be 0.

        Returns
        -------
        ndarray of float64, shape (n, k)
            ``X @ kernels_.T`` plus the bias on the AC channels (not on the DC one).
        """
        check_is_fitted(self, "kernels_")
        X = check_array(X, "X", f"(n, d) = (n, {self.n_features_in_})", ndim=2, min_rows=0)  # numbers, finite
        check_width(X, "X", f"(n, d) = (n, {self.n_features_in_})", (self.n_features_in_,),
                    who=type(self).__name__)
        return X @ self.kernels_.T + self._ac_bias()

    def inverse_transform(self, Y):
        """Vectors (n, d) from responses (n, k); discarded channels count as zero.

        Parameters
        ----------
        Y : array_like, shape (n, k)
            One column per kept channel, as :meth:`transform` gives them.

        Returns
        -------
        ndarray of float64, shape (n, d)
            Exact for vectors whose discarded responses are zero (the kernels are orthonormal).
        """
        check_is_fitted(self, "kernels_")
        k = len(self.channels_)
        Y = check_array(Y, "Y", f"(n, k) = (n, {k})", ndim=2, min_rows=0)
        check_width(Y, "Y", f"(n, k) = (n, {k}), one column per kept channel", (k,))
        return (Y - self._ac_bias()) @ self.kernels_
