"""Coupled draws of the core model's independent components (ICHM, ours; setting ``coupling``).

The paper draws each cluster's independent components independently, each from its own
histogram. Training patches are not made that way: which components act together (a
tile's face with its joint, a leaf's edge with its vein) is what independent draws lose,
and the patches they make are streaked and smeared (docs/choices.md, ICHM "0.29").

Here each cluster keeps its training members' ranks, component by component (a fraction
in [0, 1) per member and component, quantised to ``RANK_LEVELS``). A draw picks a member
at random, turns its ranks into normal scores ``z``, and takes

    u = Phi(rho * z + sqrt(1 - rho^2) * e),   e ~ N(0, 1) independently per component,

as the probabilities that the histograms' inverse CDFs turn into components. Each ``u`` is
uniform whatever ``rho`` is, so every component keeps its fitted histogram exactly (up to
the quantised ranks); ``rho`` = 0 is the paper's independent draw, and the larger ``rho``,
the more of the members' joint behaviour the draws keep. ``rho`` < 1 always adds fresh
noise to every component, so a draw is never a training patch (bounded by the setting).

NumPy only: the normal CDF and its inverse are tabulated once from :func:`math.erfc`.
"""

from __future__ import annotations

import functools
import math
import numbers

import numpy as np

from ._arrays import check_int
from ._errors import TGHopError
from ._estimator import check_rng

__all__ = ["RANK_LEVELS", "member_ranks", "coupled_uniforms", "normal_cdf", "normal_ppf"]

#: Levels a member's rank fraction is stored at (uint8).
RANK_LEVELS = 256
#: Normal scores tabulated on [-_Z_MAX, _Z_MAX] (beyond it the CDF is 0 or 1 in float64 sums).
_Z_MAX = 8.0
_Z_STEPS = 4096


@functools.cache
def _table():
    """(grid, Phi(grid), the steps between its values): the standard normal CDF on an even grid."""
    grid = np.linspace(-_Z_MAX, _Z_MAX, _Z_STEPS + 1)
    cdf = np.array([0.5 * math.erfc(-x / math.sqrt(2.0)) for x in grid])
    return grid, cdf, np.diff(cdf)


def normal_cdf(z):
    """Phi(z), the standard normal CDF (linear between tabulated points; error below 1e-6).

    The grid is even, so each value's interval is found by arithmetic, not searched for.

    Parameters
    ----------
    z : float or array_like of float

    Returns
    -------
    float64 or ndarray of float64, the shape of ``z``
        In [0, 1]; NaN where ``z`` is NaN (as :func:`normal_ppf`); beyond the table
        (``|z| > 8``, infinities included) the CDF at its end, within 1e-15 of 0 or 1.
    """
    _, cdf, step = _table()
    pos = np.clip(np.asarray(z, dtype=np.float64) + _Z_MAX, 0.0, 2 * _Z_MAX)
    nan = np.isnan(pos)
    has_nan = bool(nan.any())
    if has_nan:
        pos = np.where(nan, 0.0, pos)  # a valid table index; NaN again below
    pos *= _Z_STEPS / (2 * _Z_MAX)
    i = np.minimum(pos.astype(np.intp), _Z_STEPS - 1)
    pos -= i
    pos *= step[i]
    pos += cdf[i]
    return np.where(nan, np.nan, pos)[()] if has_nan else pos


def normal_ppf(u):
    """Phi^-1(u) for u in (0, 1), the inverse of :func:`normal_cdf` (NaN where ``u`` is NaN)."""
    grid, cdf, _ = _table()
    return np.interp(u, cdf, grid)


@functools.cache
def _rank_scores():
    """The normal score of each of the RANK_LEVELS stored ranks: Phi^-1((q + 0.5) / RANK_LEVELS)."""
    return normal_ppf((np.arange(RANK_LEVELS) + 0.5) / RANK_LEVELS)


def member_ranks(sources):
    """Each member's rank among its cluster's members, component by component.

    Parameters
    ----------
    sources : ndarray, shape (n, k)
        One cluster's training members in its independent components.

    Returns
    -------
    ndarray of uint8, shape (n, k)
        ``floor(RANK_LEVELS * (rank + 0.5) / n)``, the mid-rank fraction quantised.
    """
    s = np.asarray(sources)
    if s.ndim != 2:
        raise TGHopError(f"sources must be a 2-D (members, components) array, got shape {s.shape}")
    n = s.shape[0]
    ranks = np.empty(s.shape, dtype=np.int64)
    np.put_along_axis(ranks, np.argsort(s, axis=0, kind="stable"), np.arange(n)[:, None], axis=0)
    return ((ranks + 0.5) * (RANK_LEVELS / max(n, 1))).astype(np.uint8)


def coupled_uniforms(ranks, rho, m, rng):
    """``m`` draws of probabilities for one cluster's components, coupled to its members.

    Parameters
    ----------
    ranks : ndarray of uint8, shape (n, k)
        :func:`member_ranks` of the cluster (n >= 1).
    rho : float in [0, 1)
        Correlation of each draw's normal scores with its member's.
    m : int
        Draws, at least 0.
    rng : None, int or numpy.random.Generator
        As everywhere in tghop (:func:`tghop._estimator.check_rng`): a Generator is advanced,
        an int seed gives the same draws every time, None fresh ones.

    Returns
    -------
    ndarray, shape (m, k)
        Probabilities in [0, 1], each uniform on its own.

    Raises
    ------
    TGHopError
        ``ranks`` not 2-D or without a member, ``rho`` outside [0, 1), ``m`` not an
        integer >= 0, or ``rng`` of another type.
    """
    ranks = np.asarray(ranks)
    if ranks.ndim != 2 or len(ranks) == 0:
        raise TGHopError(f"ranks must be a 2-D (members, components) array with at least one member, "
                         f"got shape {ranks.shape}")
    if isinstance(rho, (bool, np.bool_)) or not isinstance(rho, (numbers.Real, np.floating, np.integer)) \
            or not 0.0 <= rho < 1.0:
        raise TGHopError(f"rho must be a number in [0, 1), got {rho!r}")
    m = check_int(m, "m", 0)
    rng = check_rng(rng)
    z = _rank_scores()[ranks[rng.integers(0, len(ranks), int(m))]]
    z *= rho
    z += math.sqrt(1.0 - rho * rho) * rng.standard_normal(z.shape)
    return normal_cdf(z)
