"""TGHop end to end: fit one exemplar, generate patches, synthesize images.

The data flows one way::

    exemplar --patches--> S0 --hops--> S1 --> ... --> Sn (core)
             --core.SpatialReduction--> z --core.ICHM--> p(z)

and back for generation::

    ICHM.sample -> z -> inverse SDR -> inverse hops -> patches --quilting--> image

Example
-------
>>> from tghop import TGHop, data
>>> model = TGHop(rng=0).fit(data.bricks())                     # doctest: +SKIP
>>> image = model.synthesize((512, 512), rng=7)                 # doctest: +SKIP
"""

from __future__ import annotations

import numbers

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted

from ._common import TGHopError, check_image, check_rng, report
from .core import ICHM, SpatialReduction
from .hops import HopStack
from .colour import channel_quantiles, match_histograms
from .patches import depth_to_space, patch_origins
from .quilting import quilt

__all__ = ["TGHop", "default_channels", "prepare_exemplar", "PAPER_TABLE4"]

#: The paper's Table 4 setting (brick_wall): K1=9, K2=22, gamma=0.01, N=50, W=200, with the
#: per-cluster PCA size that reproduces its F = 2,518 CDFs (95 % of the variance, at most 50
#: components). Our default keeps more (99 %, at most 100): sharper patches, about twice
#: the model size (docs/choices.md).
PAPER_TABLE4 = dict(patch_size=32, n_channels=(9, 22), gamma=0.01, n_clusters=50, n_codewords=200,
                    cluster_energy=0.95, max_cluster_components=50, residual=False, detail=0.0)

#: Pool of generated patches quilted into one image (paper: 5,000-10,000).
DEFAULT_POOL = 10_000

#: Quilting's default ``detail`` quantile (ours; the paper's uniform choice is 0).
DEFAULT_DETAIL = 0.5


def default_channels(patch_size: int, n_colours: int = 3):
    """Channels kept per hop when none are given.

    Colour: the paper's K1=9, K2=22 for 32x32 patches; for 64x64 patches a third hop keeps
    40 channels (our choice: the paper gives no K3), so the core is 8x8 spatially in both
    cases. Grey (one channel, 4 hop-1 channels in all): K1=4, K2=10 (, K3=20), our choice
    in the same proportions.
    """
    if patch_size not in (32, 64):
        raise TGHopError(f"patch_size must be 32 or 64 unless n_channels is given, got {patch_size}")
    channels = (9, 22, 40) if n_colours == 3 else (4, 10, 20)
    return channels[: 2 if patch_size == 32 else 3]


def prepare_exemplar(image, *, min_size: int = 1) -> np.ndarray:
    """A validated float exemplar; a grey image stored as RGB becomes single-channel.

    Three equal channels would leave 8 of the 12 hop-1 directions empty; modelling one
    channel is the same texture at a third of the cost, and the output is grey.

    Returns
    -------
    ndarray, shape (H, W, C), float64 in [0, 1], C in {1, 3}
    """
    img = check_image(image, min_size=min_size, name="exemplar")
    if img.shape[2] == 3 and np.abs(img[..., 1:] - img[..., :1]).max() < 1 / 512:
        img = np.ascontiguousarray(img[..., :1])
    return img


class TGHop(BaseEstimator):
    """Texture generation by successive subspace learning (Lei, Zhao, Zhang, Kuo 2021).

    Parameters
    ----------
    patch_size : int, default=32
        Side of the generated patches (paper: 32; 64 with three hops).
    stride : int, default=2
        Step between training patches (paper: 2).
    n_channels : sequence or None, default=None
        Channels kept per hop, e.g. ``(9, 22)`` for (K1, K2); each entry an int (a count,
        DC included), a float in (0, 1] (a fraction of the AC energy), or "knee" (the
        knee of the energy curve, texture-dependent). None: :func:`default_channels`
        (the paper's (9, 22) for colour, (4, 10) for grey exemplars).
    gamma : float, default=0.01
        SDR threshold on the variance of spatial PCA components (absolute, for images in
        [0, 1]; reproduces the paper's Table 5 D_r values on brick_wall).
    gamma_mode : {"absolute", "relative"}, default="absolute"
    n_clusters : int, default=50
        N, K-means clusters in ICHM.
    n_codewords : int, default=200
        W, size of the CDF codebook.
    n_bins : int, default=256
        Histogram bins per CDF.
    cluster_energy : float, default=0.99
        Variance fraction each cluster's PCA keeps before FastICA.
    max_cluster_components : int, default=100
        Cap on components per cluster. The paper's F = 2,518 for N = 50 corresponds to
        0.95 and 50 (:data:`PAPER_TABLE4`); our default halves the median SIFID on six
        test textures at about twice the model size and fit time.
    min_cluster_size : int, default=10
    reject_threshold : float or None, default=None
        Sampling step (iv), off by default.
    max_patches : int or None, default=20000
        Training patches beyond this are subsampled at random (bounds memory for large
        exemplars; a 256x256 exemplar at stride 2 has 12,769).
    residual : bool, default=True
        Also model the detail each cluster's PCA drops, as a Gaussian per core channel,
        and add a draw of it to every generated patch (ours; off in the paper's
        pipeline, :data:`PAPER_TABLE4`). Restores the fine grain: on brick_wall the pool
        patches' gradient energy goes from 0.5 to 0.85 of the exemplar's.
    detail : float in [0, 1), default=DEFAULT_DETAIL
        Quilting default of :meth:`synthesize`: choose among the near-best candidates
        only those whose gradient energy is at or above this quantile of theirs, against
        the overlap error's preference for smooth patches (ours; the paper's 0 in
        :data:`PAPER_TABLE4`).
    rng : int or numpy.random.Generator, optional
        Randomness of fitting (patch subsampling, K-means, FastICA).

    Attributes
    ----------
    hops_ : HopStack
    sdr_ : SpatialReduction
    ichm_ : ICHM
    exemplar_shape_ : tuple
    colour_quantiles_ : ndarray, shape (C, 257)
        The exemplar's per-channel quantiles, for colour matching after quilting.
    n_patches_ : int
        Training patches used.
    """

    def __init__(
        self,
        patch_size=32,
        stride=2,
        n_channels=None,
        gamma=0.01,
        gamma_mode="absolute",
        n_clusters=50,
        n_codewords=200,
        n_bins=256,
        cluster_energy=0.99,
        max_cluster_components=100,
        min_cluster_size=10,
        reject_threshold=None,
        max_patches=20000,
        residual=True,
        detail=DEFAULT_DETAIL,
        rng=None,
    ):
        self.patch_size = patch_size
        self.stride = stride
        self.n_channels = n_channels
        self.gamma = gamma
        self.gamma_mode = gamma_mode
        self.n_clusters = n_clusters
        self.n_codewords = n_codewords
        self.n_bins = n_bins
        self.cluster_energy = cluster_energy
        self.max_cluster_components = max_cluster_components
        self.min_cluster_size = min_cluster_size
        self.reject_threshold = reject_threshold
        self.max_patches = max_patches
        self.residual = residual
        self.detail = detail
        self.rng = rng

    # ---------------------------------------------------------------- fitting
    def _channel_rules(self, n_colours=3):
        for name in ("patch_size", "stride"):
            value = getattr(self, name)
            if not isinstance(value, numbers.Integral) or isinstance(value, bool) or value < 1:
                raise TGHopError(f"{name} must be a positive integer, got {value!r}")
        if self.n_channels is None:
            rules = default_channels(self.patch_size, n_colours)
        else:
            rules = tuple(self.n_channels)
        if not rules or self.patch_size % (2 ** len(rules)) or self.patch_size // 2 ** len(rules) < 2:
            raise TGHopError(
                f"{len(rules)} hops need a patch size divisible by {2 ** len(rules)} leaving a core of at "
                f"least 2x2, got patch_size={self.patch_size}"
            )
        return rules

    def fit(self, image, y=None, *, progress=None):
        """Learn the model from one exemplar.

        Parameters
        ----------
        image : ndarray, shape (H, W) or (H, W, C)
            Float in [0, 1] (or uint8), ``H, W >= patch_size``; C is 1 or 3. A grey
            image stored as RGB is modelled as one channel (see :func:`prepare_exemplar`).
        progress : callable, optional
            ``progress(stage, done, total)``; stages "hop 1", "hop 2", ...,
            "SDR", "clusters", "ICA", "CDF codebook".

        Returns
        -------
        self
        """
        self._channel_rules()  # parameter errors before touching the image
        image = prepare_exemplar(image, min_size=self.patch_size)
        rules = self._channel_rules(image.shape[2])
        rng = check_rng(self.rng)
        ichm = ICHM(
            n_clusters=self.n_clusters,
            n_codewords=self.n_codewords,
            n_bins=self.n_bins,
            cluster_energy=self.cluster_energy,
            max_cluster_components=self.max_cluster_components,
            min_cluster_size=self.min_cluster_size,
            reject_threshold=self.reject_threshold,
            residual=bool(self.residual),
            rng=rng,
        )
        sdr = SpatialReduction(gamma=self.gamma, gamma_mode=self.gamma_mode)
        origins = patch_origins(image.shape, self.patch_size, stride=self.stride,
                                max_patches=self.max_patches, rng=rng)
        ichm._check_params(len(origins))  # fail before the expensive stages
        self.exemplar_shape_ = image.shape
        self.n_patches_ = len(origins)
        self.colour_quantiles_ = channel_quantiles(image)
        # Same result as hops.fit_transform(extract_patches(...)) without cutting patches out.
        self.hops_ = HopStack(n_channels=rules)
        core = self.hops_.fit_image(image, self.patch_size, origins, progress=progress)
        report(progress, "SDR", 0, 1)
        z = sdr.fit_transform(core)
        self.sdr_ = sdr
        report(progress, "SDR", 1, 1)
        del core
        self.ichm_ = ichm.fit(z, groups=sdr.channel_, progress=progress)
        self._decoder = None
        return self

    # ------------------------------------------------------------- dimensions
    @property
    def dims_(self) -> dict:
        """Dimensions of every space: D0, D1, ..., Dn, D_r, and N, F, W of the core model."""
        check_is_fitted(self, "ichm_")
        out = {f"D{i}": d for i, d in enumerate(self.hops_.dims_)}
        out.update(
            D_r=self.sdr_.n_components_,
            N=len(self.ichm_.p_),
            F=self.ichm_.n_cdfs_,
            W=self.ichm_.codebook_.shape[0],
        )
        return out

    @property
    def channels_(self) -> list:
        """Kept channels per hop (K1, K2, ...)."""
        check_is_fitted(self, "hops_")
        return [hop.n_channels_out_ for hop in self.hops_.hops_]

    def n_parameters(self) -> dict:
        """Parameter count broken down as in the paper's Table 4.

        Returns
        -------
        dict
            ``{module: {"formula": str, "paper": int, "stored": int}}`` for the modules
            "transform stage 1", "transform stage 2", "core SDR", "core ICHM (i)",
            "(ii)", "(iii)", "colour matching (ours)" and "total". "paper" applies the paper's formula to this
            model's dimensions; "stored" counts the numbers this model actually stores
            (the arrays of its model file, index bookkeeping excluded). They differ where
            the paper's formula does: stage 2 stores ``4 K2 + K1`` numbers (each kept
            channel is one 4-tap kernel; the paper writes ``4 K1 K2 + K1``), SDR also
            stores each channel's mean map (``64 K2``), and ICHM (ii) also stores each
            cluster's mean (``N D_r``).
        """
        from .modelfile import model_arrays, parameter_groups  # no cycle at import time

        d = self.dims_
        k = self.channels_
        c_in = self.exemplar_shape_[2]
        k1, d_r, n, f, w = k[0], d["D_r"], d["N"], d["F"], d["W"]
        nb = self.ichm_.codebook_.shape[1]
        block = (self.sdr_.shape_[0] * self.sdr_.shape_[1])
        paper = {
            "transform stage 1": (f"{4 * c_in}*K1 + 1", 4 * c_in * k1 + 1),
            # Per c/w hop, the paper's 4 * K_parent * K_child + K_parent (two hops: 4 K1 K2 + K1).
            "transform stage 2": ("4*K1*K2 + K1", sum(4 * a * b + a for a, b in zip(k[:-1], k[1:]))),
            "core SDR": (f"{block}*D_r", block * d_r),
            "core ICHM (i)": ("N", n),
            "core ICHM (ii)": ("F*D_r", f * d_r),
            "core ICHM (iii)": (f"3*F + {nb}*W", 3 * f + nb * w),
        }
        paper["colour matching (ours)"] = ("C*257 (not in the paper)", 0)
        stored = parameter_groups(model_arrays(self))
        out = {m: {"formula": fm, "paper": int(p), "stored": int(stored.get(m, 0))} for m, (fm, p) in paper.items()}
        out["total"] = {
            "formula": "sum",
            "paper": sum(v["paper"] for v in out.values()),
            "stored": sum(v["stored"] for v in out.values()),
        }
        return out

    # ------------------------------------------------------------- generation
    def _check_n(self, n, name="n"):
        if not isinstance(n, numbers.Integral) or isinstance(n, bool) or n < 1:
            raise TGHopError(f"{name} must be a positive integer, got {n!r}")
        if n > 10_000_000:
            raise TGHopError(f"{name}={n} is too many; generate at most 10,000,000 patches per call")
        return int(n)

    def decode(self, z, *, return_stages=False):
        """Core-model vectors ``z`` (n, D_r) -> patches (n, P, P, C), clipped to [0, 1].

        With ``return_stages``, also the list of spaces ``[Sn, ..., S1, S0]`` before
        clipping (the inverse c/w Saab path of the paper, section IV.D).
        """
        check_is_fitted(self, "ichm_")
        spaces = self.hops_.inverse_transform(self.sdr_.inverse_transform(z), return_all=True)
        patches = np.clip(spaces[-1], 0.0, 1.0)
        return (patches, spaces) if return_stages else patches

    def _affine_decoder(self, dtype=np.float64):
        """The generation path from ICHM sources to pixels is affine; fold it per cluster.

        Returns ``(mixing, means)`` so that a cluster-``i`` sample with components ``s``
        is the patch ``means[i] + s @ mixing[rows of i]`` (flattened), exactly what the
        step-by-step inverse gives, at one matrix product per cluster. Cached per dtype.
        """
        dtype = np.dtype(dtype)
        if getattr(self, "_decoder", None) is None:
            d_r = self.sdr_.n_components_
            origin = self.hops_.inverse_transform(self.sdr_.inverse_transform(np.zeros((1, d_r))))
            basis = self.hops_.inverse_transform(self.sdr_.inverse_transform(np.eye(d_r)))
            shift = origin.reshape(1, -1)
            linear = basis.reshape(d_r, -1) - shift
            self._decoder = {np.dtype(np.float64): (self.ichm_.mixing_ @ linear, self.ichm_.means_ @ linear + shift)}
        if dtype not in self._decoder:
            self._decoder[dtype] = tuple(a.astype(dtype) for a in self._decoder[np.dtype(np.float64)])
        return self._decoder[dtype]

    def sample_patches(self, n, *, rng=None, return_stages=False, dtype=np.float64):
        """Generate new patches.

        Parameters
        ----------
        n : int
        rng : int or numpy.random.Generator, optional
            Same seed, same patches (on the same machine).
        return_stages : bool
            Also return the stage views of the paper's Fig. 6 (see :meth:`stage_views`).
        dtype : {numpy.float64, numpy.float32}
            float32 halves memory and time for large pools (quilting works in float32).

        Returns
        -------
        patches : ndarray, shape (n, P, P, C), in [0, 1]
        stages : dict, only with ``return_stages``
        """
        check_is_fitted(self, "ichm_")
        n = self._check_n(n)
        dtype = np.dtype(dtype)
        if dtype not in (np.float32, np.float64):
            raise TGHopError(f"dtype must be float32 or float64, got {dtype}")
        rng = check_rng(rng)
        labels, sources = self.ichm_.sample_sources(n, rng=rng)
        residual = self.ichm_.residual_factor_.size > 0
        if return_stages or n <= self.ichm_.n_cdfs_:
            z = self.ichm_.mix(labels, sources)
            if residual:
                z += self.ichm_.sample_residual(n, rng=rng)
            if return_stages:
                patches, spaces = self.decode(z, return_stages=True)
                return patches.astype(dtype, copy=False), self.stage_views(spaces)
            return self.decode(z).astype(dtype, copy=False)
        # Folding the decoder pays off for large batches.
        shape = (n, self.patch_size, self.patch_size, self.exemplar_shape_[2])
        mixing, means = self._affine_decoder(dtype)
        flat = self.ichm_.mix(labels, [s.astype(dtype, copy=False) for s in sources], mixing=mixing, means=means)
        if residual:
            self._add_residual(flat, rng)
        return np.clip(flat, 0.0, 1.0, out=flat).reshape(shape)

    def _add_residual(self, flat, rng):
        """Add residual draws, decoded, to flattened patches ``flat`` (n, P * P * C), in place.

        The residual is decoded through the linear parts of the inverse SDR (one product
        per core channel) and of the inverse hops (one ``K x (2^hops)^2 C`` map from a core
        position to its pixel block, applied at every position), in ``flat``'s dtype: far
        fewer operations than the dense ``D_r x P*P*C`` map of :meth:`_affine_decoder`.
        Same draws as :meth:`ICHM.sample_residual` (the decode path of small batches).
        """
        n, dtype = len(flat), flat.dtype
        h, w, k = self.sdr_.shape_
        maps = np.empty((k, n, h * w), dtype=dtype)
        filled = np.zeros(k, dtype=bool)
        for dims, normals, factor in self.ichm_.residual_draws(n, rng=rng):
            channels = np.unique(self.sdr_.channel_[dims])
            if channels.size != 1 or filled[channels[0]]:
                raise TGHopError("each residual group must be one whole core channel")
            fold = (factor.T @ self.sdr_.components_[dims]).astype(dtype)  # (k_g, h * w)
            np.matmul(normals.astype(dtype), fold, out=maps[channels[0]])
            filled[channels[0]] = True
        maps[~filled] = 0.0
        # Linear part of the inverse hops for one core position: (K, b, b, C).
        y = np.eye(k).reshape(k, 1, 1, k)
        for hop in reversed(self.hops_.hops_):
            y = depth_to_space(y @ hop.kernels_)
        b, c = y.shape[1], y.shape[3]
        blocks = y.reshape(k, -1).T.astype(dtype) @ maps.reshape(k, -1)  # (b * b * C, n * h * w)
        out = flat.reshape(n, h, b, w, b, c)
        out += blocks.reshape(b, b, c, n, h, w).transpose(3, 4, 0, 5, 1, 2)

    def stage_views(self, spaces):
        """The three views of the paper's Fig. 6 for generated samples.

        Parameters
        ----------
        spaces : list of ndarray
            ``[Sn, ..., S1, S0]`` as returned by :meth:`decode` with ``return_stages``.

        Returns
        -------
        dict of ndarray
            ``"core_dc"`` (n, h, w): the DC map in the core (the channel that descends
            from the DC of every hop, a grey low-resolution pattern); ``"S1_dc"`` (n, 2h,
            2w) etc.: the DC map in each intermediate space; ``"S0"`` (n, P, P, C): the
            patch. DC maps are divided by their DC gain, so they are in pixel units.
        """
        views = {}
        n_hops = len(self.hops_.hops_)
        c_in = self.exemplar_shape_[2]
        for level, space in zip(range(n_hops, 0, -1), spaces[:-1]):
            # DC channel of the hop: index 0 (DC is kept first in every group).
            gain = np.sqrt(4.0 ** level * c_in)  # a DC kernel has entries 1/sqrt(block size)
            name = "core_dc" if level == n_hops else f"S{level}_dc"
            views[name] = space[..., 0] / gain
        views["S0"] = np.clip(spaces[-1], 0.0, 1.0)
        return views

    def synthesize(self, size, *, rng=None, n_patches=DEFAULT_POOL, tile=False, overlap=None,
                   tolerance=0.1, detail=None, match_colours=True, progress=None):
        """Generate a texture image of any size: a patch pool quilted together.

        Parameters
        ----------
        size : (int, int)
            Output (height, width).
        rng : int or numpy.random.Generator, optional
        n_patches : int
            Pool size (paper: 5,000-10,000).
        tile : bool
            Make the output wrap around seamlessly.
        overlap : int, optional
            Quilting overlap (default ``patch_size // 6``).
        tolerance : float
            Quilting picks among pool patches within ``(1 + tolerance)`` of the best error.
        detail : float in [0, 1), optional
            Quilting picks only among those candidates whose gradient energy is at or
            above this quantile of theirs (0: the paper's uniform choice; see
            :func:`tghop.quilting.quilt`). None: the model's ``detail`` parameter.
        match_colours : bool
            Match each channel's histogram to the exemplar's after quilting (our
            addition, see :mod:`tghop.colour`); False reproduces the paper's pipeline.
        progress : callable, optional
            Stages "patch pool" and "quilting".

        Returns
        -------
        ndarray, shape (H, W, C), float64 in [0, 1]
        """
        check_is_fitted(self, "ichm_")
        rng = check_rng(rng)
        n_patches = self._check_n(n_patches, "n_patches")
        report(progress, "patch pool", 0, 1)
        pool = self.sample_patches(n_patches, rng=rng, dtype=np.float32)
        report(progress, "patch pool", 1, 1)
        detail = self.detail if detail is None else detail
        image = quilt(pool, size, overlap=overlap, tolerance=tolerance, tile=tile, detail=detail, rng=rng,
                      progress=progress)
        return match_histograms(image, self.colour_quantiles_, out=image) if match_colours else image
