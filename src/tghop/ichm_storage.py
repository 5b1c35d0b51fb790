"""How the core model (ICHM) keeps its fitted state: the mixing matrix quantised, and the
arrays of a model file.

The mixing matrix is most of a model. It is kept as a model file stores it (format version
3): float16 rows in [-1, 1] with a float32 scale each (:func:`quantize`), a quarter of
float64's size. ``ICHM.fit`` rounds it so at once, so a fitted model and its saved copy
generate the same patches. ``mixing_`` (float64) is made from the rows on first use, and
generation takes a float32 copy made straight from them (:meth:`ICHMStorageMixin.mixing_as`):
a model loaded for generation never holds the float64 matrix, which would raise the peak
memory of a small synthesis.

:class:`ICHMStorageMixin` gives :class:`tghop.core.ICHM` these, and the arrays it writes to
and reads from a model file (:mod:`tghop.modelfile`) with the checks of their shapes.
"""

from __future__ import annotations

import numpy as np

from ._errors import TGHopError
from ._estimator import check_is_fitted
from .coupling import RANK_LEVELS
from .ichm_clusters import AUTO_CLUSTERS, NORM_QUANTILES

__all__ = ["ICHMStorageMixin", "quantize", "dequantize"]


def quantize(mixing):
    """Rows of ``mixing`` as float16 in [-1, 1] and a float32 scale per row (the row's
    largest magnitude): relative rounding error at most 2**-11 of the row's largest entry,
    far below the spread of the sampled sources.

    Parameters
    ----------
    mixing : ndarray, shape (F, D_r)

    Returns
    -------
    rows : ndarray of float16, shape (F, D_r)
    scale : ndarray of float32, shape (F,)
        Positive (1 for a row of zeros).
    """
    scale = np.abs(mixing).max(axis=1).astype(np.float32)
    scale[scale == 0] = 1.0
    return (mixing / scale[:, None].astype(np.float64)).astype(np.float16), scale


def dequantize(rows, scale):
    """Inverse of :func:`quantize`, in float64 (the same numbers at fit and after loading).

    Parameters
    ----------
    rows : ndarray of float16, shape (F, D_r)
    scale : array_like of float32, shape (F,)

    Returns
    -------
    mixing : ndarray of float64, shape (F, D_r)
        Exactly ``rows * scale[:, None]`` (a float16 times a float32 is exact in float64).
    """
    out = rows.astype(np.float64)
    out *= np.asarray(scale, dtype=np.float32).astype(np.float64)[:, None]  # in place: no second matrix
    return out


class ICHMStorageMixin:
    """Mixin of :class:`tghop.core.ICHM`: its mixing matrix kept quantised, and its arrays of
    a model file.

    Keeps ``_stored_mixing`` (the float16 rows and float32 scales), and from them the caches
    ``_mixing`` (float64, :attr:`mixing_`) and ``_mixing32`` (:meth:`mixing_as`). Restoring a
    fitted state (``_from_arrays``) also drops ICHM's sampling caches made from the arrays
    (``_ranks``, ``_quantiles``).
    """

    def _set_stored_mixing(self, rows, scale):
        self._stored_mixing = (rows, scale)
        self._mixing = self._mixing32 = None

    @property
    def mixing_(self):
        """The mixing matrices of every cluster, stacked: ndarray, shape (F, D_r), float64 (the inverse
        PCA and ICA of step v; made from the stored float16 rows and float32 scales on first use)."""
        mixing = vars(self).get("_mixing")
        if mixing is None:
            stored = vars(self).get("_stored_mixing")
            if stored is None:
                check_is_fitted(self, "means_")  # NotFittedError before fit
                raise AttributeError(f"this {type(self).__name__} has no mixing_")
            mixing = self._mixing = dequantize(*stored)
        return mixing

    def _mixing_uncached(self):
        """:attr:`mixing_` without keeping it (the inspecting methods: scikit-learn's checks hold ``transform``
        to leaving the estimator's ``__dict__`` as it was, and a made cache is a change)."""
        mixing, stored = vars(self).get("_mixing"), vars(self).get("_stored_mixing")
        return mixing if mixing is not None or stored is None else dequantize(*stored)

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
        either way), without making the float64 matrix.

        Parameters
        ----------
        dtype : numpy dtype or type
            float32 or float64 (another float dtype: ``mixing_`` converted).

        Returns
        -------
        mixing : ndarray, shape (F, D_r)
            In ``dtype``; the model's own array (kept for later calls): do not write to it.
        """
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

    # ------------------------------------------------------------------ model files
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
            stored = quantize(self.mixing_)
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
