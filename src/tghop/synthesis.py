"""TGHop end to end: fit one exemplar, generate patches, synthesize images.

The data flows one way::

    exemplar --patches--> S0 --hops--> S1 --> ... --> Sn (core)
             --sdr.SpatialReduction--> z --core.ICHM--> p(z)

and back for generation (:meth:`TGHop.synthesize`, whose steps :func:`tghop.generation.synthesize`
takes in order; the words on the arrows are tghop's modules)::

    CoarseLayout (a small TGHop of the downsampled exemplar) --> layout guide
    ICHM.sample -> z -> inverse SDR -> inverse hops -> patches (pool)
        --quilting, following the guide--> image --seams--> seams removed
        --refine (regions, by region, for a large image)--> band statistics matched
        --patch_refine (images of up to 1280x1280), else colour--> image

Here: the estimator :class:`TGHop` (settings, fit, model-file state, sizes) and
:class:`CoarseLayout`, the small TGHop a fine one owns. Elsewhere: TGHop's methods between
patches and core vectors (``encode``, ``decode``, ``sample_vectors``, ``sample_patches``,
``stage_views``: :mod:`tghop.codec`, which it inherits), the generation steps
(:mod:`tghop.generation`), the exemplar's checks and the default channels per hop
(:mod:`tghop.exemplar`; :func:`prepare_exemplar` and :func:`default_channels` are imported
from here too).

Example
-------
>>> from tghop import TGHop, data
>>> model = TGHop(rng=0).fit(data.bricks())                     # doctest: +SKIP
>>> image = model.synthesize((512, 512), rng=7)                 # doctest: +SKIP
"""

from __future__ import annotations

import textwrap

import numpy as np

from . import generation, settings
from ._errors import TGHopError, check_progress
from ._estimator import (NOT_FITTED_MODEL_HINT, BaseEstimator, ImageInputMixin, check_is_fitted, check_keywords,
                         check_rng, fit_part, fitted_settings, named_keywords)
from ._images import check_image, grey_as_rgb
from ._progress import report
from ._resources import one_blas_thread
from ._arrays import forget_fit
from .codec import PatchCodec
from .depths import exemplar_depth
from .masks import mask_levels, snap_to_levels
from .core import ICHM
from .sdr import SpatialReduction
from .hops import Hop, HopStack
from .colour import ColourClasses, channel_quantiles
from .exemplar import default_channels, drop_alpha, prepare_exemplar
from .patches import check_exclude, check_exemplar_size, downsample_mask, enough_patches, patch_origins
from . import layout
from .parameter_count import parameter_groups, table4
from .patch_refine import PatchStatistics, fit_patch_statistics
from .refine import BandStatistics
from .scale import rescale, rescale_mask

__all__ = ["TGHop", "CoarseLayout", "default_channels", "grey_as_rgb", "prepare_exemplar", "PAPER_TABLE4"]

#: The paper's Table 4 setting (brick_wall): K1=9, K2=22, gamma=0.01, N=50, W=200, with the
#: per-cluster PCA size that reproduces its F = 2,518 CDFs (95 % of the variance, at most 50
#: components). Our default keeps more (99 %, at most 100): sharper patches, about twice
#: the model size (docs/choices.md). From the ``paper`` column of the settings table.
PAPER_TABLE4 = {"n_channels": (9, 22), **{s.name: s.paper for s in settings.fit_settings() if s.has_paper}}

#: Pool of generated patches quilted into one image (paper: 5,000-10,000).
DEFAULT_POOL = settings.BY_NAME["n_patches"].default

#: Largest uint8 exemplar (pixels) :meth:`TGHop.fit` turns into floats ``x / 255`` first: the model of its
#: pixels as floats, bit for bit (larger ones stay uint8, memory bounded: docs/choices.md, "Patches").
FLOAT_EXEMPLAR_PIXELS = 1024 * 1024


class TGHop(ImageInputMixin, PatchCodec, BaseEstimator):
    """Texture generation by successive subspace learning (Lei, Zhao, Zhang, Kuo 2021).

    Fit it on one exemplar (an ``(H, W, 3)`` or grey ``(H, W)`` array, float in [0, 1], uint8 or
    uint16), then make images of any size; keep it in a model file (:func:`tghop.modelfile.save_model`,
    ``load_model``):

    >>> from tghop import TGHop, data
    >>> model = TGHop(rng=0).fit(data.bricks())                     # doctest: +SKIP
    >>> image = model.synthesize((512, 768), rng=7)                 # doctest: +SKIP
    >>> image, steps = model.synthesize((256, 256), rng=7, return_stages=True)  # doctest: +SKIP

    ``image`` is float ``(512, 768, 3)`` in [0, 1] (``tghop.imageio.save_image`` writes it); ``steps``
    holds each step's image and the patch pool. The parameters are the fit-time settings of
    :data:`tghop.settings.SETTINGS` (one table for the estimator, the model file and the CLI; the
    defaults are tghop's, ``TGHop(**PAPER_TABLE4)`` the paper's); generation-time settings are
    keywords of :meth:`synthesize`.

    Parameters
    ----------
{parameters}

    Attributes
    ----------
    hops_ : HopStack
    sdr_ : SpatialReduction
    ichm_ : ICHM
        Its ``rng``: a copy of the fit's generator as it was before this part's fit (what refits it;
        a loaded model's holds it too, from the model file; None in files of tghop 0.56 and older).
    exemplar_shape_ : tuple
    exemplar_depth_ : int or None
        Bits per channel of the exemplar's file: 8, 16 or 32 (float), as ``fit``'s ``depth`` says
        or its dtype (uint8, uint16); None when not known (a float array, a file of tghop 0.55 or
        older). Kept in the model file, so that ``tghop synth MODEL`` warns, as from the exemplar,
        that an image written with 8 bits loses some.
    exemplar_levels_ : ndarray, shape (2, C), or None
        The exemplar's two pixel values where it holds no others (a 1-bit scan, line art, a
        stencil: its pixels left out by ``exclude`` not counted), in [0, 1]; :meth:`synthesize`
        moves each pixel of its image to the nearer of them, as a material's mask maps are
        (:mod:`tghop.masks`), so that a black-and-white texture comes out black and white. None
        for any other exemplar (and in a file of tghop 0.56 or older). Kept in the model file.
    colour_quantiles_ : ndarray, shape (C, 257)
        The exemplar's per-channel quantiles, for colour matching after quilting.
    classes_ : tghop.colour.ColourClasses or None
        The exemplar's colour classes and their histograms (``colour_classes``).
    bands_ : tghop.refine.BandStatistics
        The exemplar's band and pixel distributions in its decorrelated colour space, for
        the refinement after stitching.
    patches_ : tghop.patch_refine.PatchStatistics or None
        The exemplar's patch distributions per pyramid level (quantiles of projections on
        fixed directions), for the patch refinement (``patch_levels``; None with 0). Not
        training patches: :meth:`sample_patches` draws new ones.
    n_patches_ : int
        Training patches used.
    layout_ : tghop.synthesis.CoarseLayout or None
        The coarse layout model (``layout_factor`` set and the exemplar large enough; its
        ``factor`` is the one used: :func:`tghop.layout.usable_factor`); its ``rng`` as ``ichm_``'s.
    """

    # The fit settings of tghop.settings.SETTINGS, in its order and with its defaults
    # (tests/test_settings.py checks that they agree). Nothing is checked until ``fit``.
    def __init__(self, patch_size=32, stride=2, n_channels=None, gamma=0.003, gamma_mode="absolute",
                 n_clusters=None, n_codewords=200, n_bins=256, cluster_energy=0.99, max_cluster_components=100,
                 max_component_ratio=0.5, norm_match=1.0, coupling=0.95, min_cluster_size=10, reject_threshold=None,
                 ica_max_iter=200, ica_tol=1e-3, residual=False, max_patches=20000, band_levels=4, band_orientations=4,
                 colour_classes=4, patch_levels=4, patch_whitening=0.0, layout_factor=3, scale=1.0, rng=None):
        self.patch_size, self.stride, self.n_channels = patch_size, stride, n_channels
        self.gamma, self.gamma_mode = gamma, gamma_mode
        self.n_clusters, self.n_codewords, self.n_bins = n_clusters, n_codewords, n_bins
        self.cluster_energy, self.max_cluster_components = cluster_energy, max_cluster_components
        self.max_component_ratio = max_component_ratio
        self.norm_match, self.coupling = norm_match, coupling
        self.min_cluster_size, self.reject_threshold = min_cluster_size, reject_threshold
        self.ica_max_iter, self.ica_tol = ica_max_iter, ica_tol
        self.residual, self.max_patches, self.band_levels = residual, max_patches, band_levels
        self.band_orientations, self.colour_classes, self.patch_levels = band_orientations, colour_classes, patch_levels
        self.patch_whitening, self.layout_factor, self.scale = patch_whitening, layout_factor, scale
        self.rng = rng

    _not_fitted_hint = NOT_FITTED_MODEL_HINT  # a model file holds one

    def _unknown_param_hint(self, name):
        """A command line's name for a parameter (``k1``, ``clusters``, ``fit_seed``) or a generation setting, which
        is a keyword of ``synthesize``, given to :meth:`set_params`: the name to use (0.63; 0.62 listed the valid
        ones alone)."""
        option = "--" + name.replace("_", "-")
        if option in ("--k1", "--k2", "--k3"):
            return f"; the command line's {option} is n_channels=(K1, K2[, K3]) here"
        if option == "--fit-seed":
            return "; the command line's --fit-seed is rng here"
        for setting in settings.SETTINGS:
            if setting.name == name or option in setting.option_names:
                if setting.when == "generate":
                    said = setting.name if setting.name == name else f"the command line's {option}"
                    return (f"; {said} is synthesize()'s {setting.name}, given per image: "
                            f"model.synthesize(size, {setting.name}=...)")
                return f"; the command line's {option} is {setting.name} here"
        return super()._unknown_param_hint(name)

    def _unknown_keyword_hint(self, name):
        """A name given to :meth:`synthesize` that it does not take (0.64): a generation setting's command-line name,
        its keyword; a fit setting, the constructor's, and a fit again."""
        option = "--" + name.replace("_", "-")
        if option in ("--k1", "--k2", "--k3", "--fit-seed"):
            said = "rng=..." if option == "--fit-seed" else "n_channels=(K1, K2[, K3])"
            return f"; the command line's {option} is a fit setting: TGHop({said}), fitted again"
        for setting in settings.SETTINGS:
            if setting.name == name or option in setting.option_names:
                if setting.when == "generate":
                    return f"; the command line's {option} is {setting.name} here"
                said = name if setting.name == name else f"the command line's {option}"
                return f"; {said} is a fit setting: TGHop({setting.name}=...), fitted again"
        return ""

    # ---------------------------------------------------------------- fitting
    def check_settings(self):
        """Raise the :class:`TGHopError` :meth:`fit` would raise for a bad setting, fitting nothing (every
        setting against the settings table, then the patch size against the hops).

        Returns
        -------
        None

        Raises
        ------
        tghop.TGHopError
            One line naming the setting and what it accepts.
        """
        settings.check_settings({s.name: getattr(self, s.name) for s in settings.fit_settings()})
        self.check_channels()

    def check_channels(self, n_colours=None):
        """The hops' channel rules for an exemplar of ``n_colours`` channels (None: any), or a one-line TGHopError
        before any work: a patch size the hops cannot halve, or a hop-1 count above 4 C (its 2x2 blocks).

        Parameters
        ----------
        n_colours : int, optional
            The exemplar's channels C (None: not known yet; the colour defaults then).

        Returns
        -------
        tuple
            The channels kept per hop: ``n_channels`` as given (counts, energy fractions or "knee"),
            or :func:`default_channels` of the patch size and C.
        """
        for name in ("patch_size", "stride"):
            settings.BY_NAME[name].check(getattr(self, name))
        rules = default_channels(self.patch_size, n_colours or 3) if self.n_channels is None else tuple(self.n_channels)
        if not rules or self.patch_size % (2 ** len(rules)) or self.patch_size // 2 ** len(rules) < 2:
            raise TGHopError(f"{len(rules)} hop{'s need' if len(rules) != 1 else ' needs'} a patch size divisible by "
                             f"{2 ** len(rules)} leaving a core of at least 2x2, got patch_size={self.patch_size}")
        if n_colours and isinstance(rules[0], (int, np.integer)) and rules[0] > 4 * n_colours:
            raise TGHopError(f"K1 (n_channels[0], --k1) is {rules[0]}, but hop 1 of an exemplar of {n_colours} "
                             f"channel{'s' * (n_colours != 1)} has {4 * n_colours}; choose at most {4 * n_colours}")
        return rules

    def check_exemplar_size(self, shape, ichm=None):
        """Raise :func:`tghop.patches.check_exemplar_size`'s error for an exemplar of ``shape`` (H, W, ...),
        as given (before the working ``scale``).

        Parameters
        ----------
        shape : tuple
            (H, W, ...) of the exemplar.
        ichm : tghop.core.ICHM, optional
            The core model of these settings (None: made from them, after :meth:`check_settings`).

        Returns
        -------
        None

        Raises
        ------
        tghop.patches.ExemplarTooSmallError
            A :class:`TGHopError` of one line naming the smallest square exemplar that works.
        """
        if ichm is None:
            self.check_settings()
            ichm = ICHM(**settings.component_params(self, "ichm"))
        check_exemplar_size(shape, ichm, patch_size=self.patch_size, stride=self.stride, max_patches=self.max_patches,
                            scale=self.scale)

    def fit(self, image, y=None, *, exclude=None, depth=None, progress=None, stacked=False):
        """Learn the model from one exemplar.

        Parameters
        ----------
        image : ndarray, shape (H, W) or (H, W, C)
            Float in [0, 1], uint8 or uint16, ``H, W >= patch_size``; C is 1 or 3 (or more: the
            stacked maps of a material, :mod:`tghop.material`). A grey image stored as RGB
            is modelled as one channel (see :func:`prepare_exemplar`). C = 2 or 4 is grey or
            RGB with alpha (an RGBA PNG as ``numpy.asarray(PIL.Image.open(path))`` gives it): the
            alpha is dropped, with a :class:`~tghop.OpaqueAlphaWarning` (none of it transparent) or
            a :class:`~tghop.TransparencyWarning` (the colours under the transparent part are learnt
            as texture: crop them away, or leave them out with ``exclude``), as ``tghop fit`` and
            :func:`tghop.imageio.load_image` read such a file (0.58; 0.57 learnt the alpha as a
            colour, without a word; :func:`tghop.exemplar.drop_alpha`).
            A uint8 exemplar of up to :data:`FLOAT_EXEMPLAR_PIXELS` (1024x1024) gives the model
            of its pixels / 255 as floats. Memory depends on the training patches used
            (``max_patches``), not on the exemplar's size: the hops see the image tile by tile,
            and a larger uint8 image is never converted whole (its model then differs a little
            from the float image's: the coarse layout is fitted on box means rounded to 8 bits).
        y : None
            Ignored (scikit-learn's signature).
        exclude : array_like of bool, shape (H, W), optional
            A sample mask: True where the model must not learn (a logo, a label, a stain,
            a hole to inpaint). Training patches that overlap it are dropped, and the
            colour and band statistics come from the other pixels (the coarse layout's
            model too; it is left out when too few of its patches remain). Too few
            training patches left is a :class:`TGHopError` naming the minimum.
        depth : {8, 16, 32}, optional
            Bits per channel of the exemplar's file (32: float), recorded as ``exemplar_depth_``;
            by default the dtype's (8 for uint8, 16 for uint16; a float array: not known). It
            changes nothing learned.
        progress : callable, optional
            ``progress(stage, done, total)``; stages "exemplar" (its checks and statistics), "hop 1",
            "hop 2", ..., "core" (the training patches' core responses), "SDR", "clusters", "ICA",
            "CDF codebook", and "layout" with a ``layout_factor``: one after another, each from its
            first call to its last (``done == total``) covering the fit's work, nothing left between them.
        stacked : bool
            The channels are stacked maps, none of them alpha (a :class:`~tghop.material.Material`'s
            joint model): 2 or 4 channels are modelled as they are.

        Returns
        -------
        self
        """
        check_progress(progress)
        image = drop_alpha(image, stacked=stacked)
        from threadpoolctl import threadpool_limits

        started = settings.generators_given(self)  # a Generator given as rng, as the fit begins: the model file's

        depth = exemplar_depth(depth, image)
        # One BLAS / OpenMP thread: the model is the same bit for bit on every machine (OpenBLAS's
        # results change with its thread count) and a busy machine is not oversubscribed; ICHM.fit
        # runs its clusters in threads of its own (usable_cores). The BLAS limit is one_blas_thread's, counted
        # process-wide (fits and generation in other threads at once: the same bytes); OpenMP's is the thread's.
        with one_blas_thread(), threadpool_limits(limits=1, user_api="openmp"):
            try:
                self._fit(image, exclude=exclude, progress=progress)
            except BaseException:  # a failure once learning began leaves no half-fitted model
                if "_fitted_params" not in self.__dict__:
                    forget_fit(self)
                raise
        self.exemplar_depth_ = depth
        self._fitted_params = fitted_settings(self)  # what check_is_fitted holds the settings to
        self._fitted_params.update(started)  # rng: where the fit began (a Generator's state; its settings' copies)
        return self

    def _fit(self, image, *, exclude=None, progress=None):
        self.check_settings()  # parameter errors before touching the image
        # Stage "exemplar": its checks, working scale, training patches' origins and the colour, band and patch
        # statistics, work before the hops that no stage reported (0.56: missing from the stage lines).
        report(progress, "exemplar", 0, 1)
        rng = check_rng(self.rng)
        ichm = ICHM(**settings.component_params(self, "ichm"))  # rng: fit_part's copy of the fit's, at its fit
        image = prepare_exemplar(image, channels=None)
        self.check_exemplar_size(image.shape, ichm)  # names the smallest exemplar that works
        exclude = check_exclude(exclude, image.shape)
        levels = mask_levels(image, exclude, most=2)  # a two-level exemplar's, before any resampling
        levels = levels / 255.0 if levels is not None and image.dtype == np.uint8 else levels
        if self.scale != 1:  # the working scale: the model sees only the resampled exemplar from here on
            image, exclude = rescale(image, self.scale), rescale_mask(exclude, self.scale)
            image = prepare_exemplar(image, channels=None)  # and checks it again (flat, grey)
        if image.dtype == np.uint8 and image.shape[0] * image.shape[1] <= FLOAT_EXEMPLAR_PIXELS:
            image = image / 255.0  # the floats of the same pixels: the same model (0.32: another one)
        rules = self.check_channels(image.shape[2])
        sdr = SpatialReduction(**settings.component_params(self, "sdr"))
        origins = patch_origins(image.shape, self.patch_size, stride=self.stride,
                                max_patches=self.max_patches, rng=rng, exclude=exclude)
        if exclude is not None:
            enough_patches(len(origins), ichm.clusters_for(len(origins)) * ichm.min_cluster_size, self.patch_size,
                           ichm.min_cluster_size)
        ichm._check_params(len(origins))  # fail before the expensive stages
        forget_fit(self, private=("_fitted_params",))  # an earlier fit's state goes now, not on a bad setting
        self.exemplar_shape_ = image.shape
        self.exemplar_levels_ = levels
        self.n_patches_ = len(origins)
        # Colour quantiles of the pixels kept only (a (n, 1, C) "image" of them).
        self.colour_quantiles_ = channel_quantiles(image if exclude is None else image[~exclude][:, None, :])
        self.bands_ = BandStatistics(n_levels=self.band_levels,
                                     n_orientations=self.band_orientations).fit(image, exclude=exclude)
        self.classes_ = ColourClasses(self.colour_classes).fit(image, self.bands_, exclude=exclude) \
            if self.colour_classes else None
        self.patches_ = fit_patch_statistics(self.patch_levels, image, whitening=self.patch_whitening, exclude=exclude)
        report(progress, "exemplar", 1, 1)
        # Same result as hops.fit_transform(extract_patches(...)) without cutting patches out.
        self.hops_ = HopStack(n_channels=rules)
        core = self.hops_.fit_image(image, self.patch_size, origins, progress=progress)
        report(progress, "SDR", 0, 1)
        z, self.sdr_ = sdr.fit_transform(core), sdr
        report(progress, "SDR", 1, 1)
        del core
        self.ichm_ = fit_part(ichm, rng, z, groups=sdr.channel_, progress=progress)
        self.layout_ = None
        factor = self.layout_factor and CoarseLayout(factor=self.layout_factor).usable_factor(image.shape, exclude)
        if factor:
            report(progress, "layout", 0, 1)
            levels = min(int(self.patch_levels), layout.PATCH_LEVELS)
            self.layout_ = fit_part(CoarseLayout(factor=factor, patch_levels=levels), rng, image, exclude=exclude)
            report(progress, "layout", 1, 1)
        return self

    # ------------------------------------------------------------- state (model files)
    def _to_arrays(self) -> dict:
        """Every learned array by file name; each part names its own (see :mod:`tghop.modelfile`)."""
        check_is_fitted(self, "ichm_")
        out = {}
        for i, hop in enumerate(self.hops_.hops_, start=1):
            out.update(hop._to_arrays(i))
        out.update(self.sdr_._to_arrays())
        out.update(self.ichm_._to_arrays())
        out["colour.quantiles"] = self.colour_quantiles_
        out.update(self.classes_._to_arrays() if getattr(self, "classes_", None) is not None else {})
        out.update(self.bands_._to_arrays())
        out.update(self.patches_._to_arrays() if getattr(self, "patches_", None) is not None else {})
        if self.layout_ is not None:  # the coarse model's arrays, prefixed
            out.update({f"layout.{k}": v for k, v in self.layout_.model_._to_arrays().items()})
        return out

    def _state_meta(self) -> dict:
        """JSON-ready settings and shapes needed, with :meth:`_to_arrays`, to rebuild the model."""
        params = {s.name: getattr(self, s.name) for s in settings.fit_settings()}
        params["rng"] = settings.fit_seed(self)  # an int seed; a Generator: fit_rngs
        records = settings.generator_records(vars(self).get("_fitted_params"))
        if params["n_channels"] is not None:
            params["n_channels"] = list(params["n_channels"])
        return {
            "params": params,
            "exemplar_shape": list(self.exemplar_shape_),
            "n_patches": self.n_patches_,
            "hops": [hop._state_meta() for hop in self.hops_.hops_],
            "hop_dims": self.hops_.dims_,
            "sdr_shape": list(self.sdr_.shape_),
            "ica_unconverged": int(self.ichm_.n_ica_unconverged_), "ica_n_iter": int(self.ichm_.n_iter_),
            # The fitted parts' copies of the fit's generator, as they were before their fits (0.57): a loaded
            # model's parts hold them too (get_params, clone, repr as the fitted one's); older files: None.
            "ichm_rng": settings.generator_record(self.ichm_.rng),
            # A Generator given as rng, in the state the fit began in (0.58): clone(loaded).fit(x) fits it again.
            **({"fit_rngs": records} if records else {}),
            "layout": None if self.layout_ is None else {
                "params": {**self.layout_.get_params(), "rng": None},
                "model": {k: v for k, v in self.layout_.model_._state_meta().items() if k != "fit_rngs"},  # model_rng
                "rng": settings.generator_record(self.layout_.rng),
                "model_rng": settings.generator_record(self.layout_.model_.rng)},
            # Metadata, not an array (as a hop's saab_energy): the same format version; left out when not known.
            **({} if getattr(self, "exemplar_depth_", None) is None else {"exemplar_depth": self.exemplar_depth_}),
            **({} if getattr(self, "exemplar_levels_", None) is None
               else {"exemplar_levels": self.exemplar_levels_.tolist()}),
        }

    @classmethod
    def _from_state(cls, meta, arrays):
        """Inverse of :meth:`_state_meta` and :meth:`_to_arrays`.

        Settings missing from ``meta`` (files written before they existed) take their
        defaults, or the value such files were fitted with (:data:`tghop.settings.BEFORE_ADDED`);
        unknown or invalid ones raise :class:`TGHopError`.
        """
        model = cls(**settings.file_settings(meta["params"]))
        model.exemplar_shape_ = tuple(int(v) for v in meta["exemplar_shape"])
        model.n_patches_ = int(meta["n_patches"])
        stack = HopStack(n_channels=model.check_channels(model.exemplar_shape_[2]))
        rules = [settings.check_channel_rule(r, "n_channels", none_ok=True) for r in stack.n_channels]  # as fit
        stack.hops_ = [Hop._from_arrays(i, info, arrays, rules[i - 1] if i <= len(rules) else None)
                       for i, info in enumerate(meta["hops"], start=1)]
        stack.dims_ = [int(d) for d in meta["hop_dims"]]
        model.hops_ = stack
        model.sdr_ = SpatialReduction(**settings.component_params(model, "sdr"))._from_arrays(
            arrays, tuple(int(v) for v in meta["sdr_shape"]))
        model.ichm_ = ICHM(**settings.component_params(model, "ichm"))._from_arrays(arrays)
        model.ichm_.n_ica_unconverged_ = int(meta.get("ica_unconverged", 0))
        model.ichm_.n_iter_ = int(meta.get("ica_n_iter", 0))  # 0.61
        model.ichm_.rng = settings.generator_from_record(meta.get("ichm_rng"), "ichm_rng")
        model.exemplar_depth_ = exemplar_depth(meta.get("exemplar_depth"), what="the metadata's exemplar_depth")
        model.exemplar_levels_ = _levels(meta.get("exemplar_levels"), model.exemplar_shape_[2])
        model.colour_quantiles_ = arrays["colour.quantiles"].astype(np.float64, copy=False)
        model.classes_ = ColourClasses(model.colour_classes)._from_arrays(arrays) if model.colour_classes else None
        model.bands_ = BandStatistics(n_levels=model.band_levels,
                                      n_orientations=model.band_orientations)._from_arrays(arrays)
        model.patches_ = (PatchStatistics(model.patch_levels, model.patch_whitening)._from_arrays(arrays)
                          if model.patch_levels else None)
        model.layout_ = None
        if meta.get("layout") is not None:
            params = {**meta["layout"]["params"], "rng": settings.generator_from_record(meta["layout"].get("rng"),
                                                                                      "layout's rng")}
            model.layout_ = CoarseLayout(**{"patch_levels": 0, **params})  # 0.47 and older: 0
            sub = {k[len("layout."):]: v for k, v in arrays.items() if k.startswith("layout.")}
            model.layout_.model_ = cls._from_state(meta["layout"]["model"], sub)
            model.layout_.model_.rng = settings.generator_from_record(meta["layout"].get("model_rng"),
                                                                      "layout's model_rng")
        started = settings.set_generators(model, meta.get("fit_rngs"))  # a Generator given as rng (0.58)
        model._check_consistent()
        model._fitted_params = {**fitted_settings(model), **started}
        return model

    @classmethod
    def _array_specs(cls, meta, *, quantised=True, prefix=""):
        """The arrays a model file with metadata ``meta`` holds, for the checks of
        :mod:`tghop.modelfile`: ``[(prefix, specs), ...]``, this model's and its coarse
        layout model's (prefixed "layout."). The metadata is checked first: the numbers
        it gives must agree with each other (:class:`TGHopError` naming them).
        ``quantised``: whether the mixing rows come with scales (format version 3), or
        the set of prefixes whose do (version 2 files: float32 rows, no scales)."""
        model = cls(**settings.file_settings(meta["params"]))
        where = f"the {prefix or 'model'} metadata's"

        def count(value, what, low=1):
            if not isinstance(value, int) or isinstance(value, bool) or value < low:
                raise TGHopError(f"{where} {what} is {value!r}, not an integer of at least {low}")
            return value

        shape = meta["exemplar_shape"]
        if not isinstance(shape, list) or len(shape) != 3:
            raise TGHopError(f"{where} exemplar_shape {shape!r} is not [height, width, channels]")
        h, w, c = (count(v, "exemplar_shape") for v in shape)
        count(meta["n_patches"], "n_patches")
        p = model.patch_size
        n = len(model.check_channels(c))
        hops, dims = meta["hops"], meta["hop_dims"]
        if not isinstance(hops, list) or len(hops) != n or not isinstance(dims, list) or len(dims) != n + 1:
            raise TGHopError(f"{where} hops and hop_dims do not describe {n} hops")
        if count(dims[0], "hop_dims") != p * p * c:
            raise TGHopError(f"{where} hop_dims[0] is {dims[0]}, not {p * p * c} for {p}x{p}x{c} patches "
                             f"(exemplar_shape {shape!r})")
        specs, c_in = [], c
        for i, info in enumerate(hops, start=1):
            side = p >> i
            k = count(dims[i], "hop_dims") // (side * side)
            channelwise = info["channelwise"]
            if (channelwise is not (i > 1) or count(info["n_channels_in"], "n_channels_in") != c_in
                    or dims[i] != k * side * side or not (c_in if channelwise else 1) <= k <= 4 * c_in):
                shown = {k: info[k] for k in ("channelwise", "n_channels_in")}  # not its energies
                raise TGHopError(f"{where} hop {i} ({shown!r}, hop_dims {dims[i]}) does not follow from "
                                 f"{c_in} input channels and {side}x{side} outputs")
            specs += Hop._array_specs(i, channelwise, c_in, k)
            c_in = k
        side = p >> n
        if meta["sdr_shape"] != [side, side, c_in]:
            raise TGHopError(f"{where} sdr_shape {meta['sdr_shape']!r} is not [{side}, {side}, {c_in}] "
                             "(the last hop's output)")
        specs += SpatialReduction._array_specs((side, side, c_in))
        specs += ICHM(**settings.component_params(model, "ichm"))._array_specs(
            quantised if isinstance(quantised, bool) else prefix in quantised)
        specs.append(("colour.quantiles", (c, "Qc"), "f", f"the metadata says {c} colour channels",
                      (("dim", 1, 2, None), ("range", 0.0, 1.0), ("nondecreasing",))))
        specs += BandStatistics(n_levels=model.band_levels, n_orientations=model.band_orientations)._array_specs(c)
        specs += ColourClasses(model.colour_classes)._array_specs(c) if model.colour_classes else ()
        specs += PatchStatistics(model.patch_levels)._array_specs(c, meta) if model.patch_levels else ()
        groups = [(prefix, tuple(specs))]
        layout_meta = meta.get("layout")
        if layout_meta is not None:
            if prefix:
                raise TGHopError("a coarse layout model has a layout of its own")
            sub = layout_meta["model"]
            CoarseLayout(**layout_meta["params"])  # unknown parameters: TypeError
            settings.BY_NAME["layout_factor"].check(layout_meta["params"].get("factor"), label="layout factor")
            if not isinstance(sub, dict) or sub.get("exemplar_shape", [None] * 3)[2:] != [c]:
                raise TGHopError(f"the coarse layout model's exemplar_shape is not of {c} channels")
            groups += cls._array_specs(sub, quantised=quantised, prefix="layout.")
        return groups

    def _check_consistent(self):
        """Shapes that must agree; a mismatch means a damaged or hand-edited file."""
        ichm, sdr = self.ichm_, self.sdr_
        d_r = sdr.components_.shape[0]
        f = int(ichm.n_components_.sum())
        checks = [
            ichm.mixing_shape_ == (f, d_r),
            ichm.means_.shape == (len(ichm.weights_), d_r),
            len(ichm.n_components_) == len(ichm.weights_),
            ichm.cdf_index_.shape == (f,) and ichm.cdf_min_.shape == (f,) and ichm.cdf_max_.shape == (f,),
            ichm.cdf_index_.size == 0 or (0 <= ichm.cdf_index_.min() and ichm.cdf_index_.max() < len(ichm.codebook_)),
            self.hops_.hops_[-1].n_channels_out_ == sdr.shape_[2],
            bool(np.all(np.diff(sdr.channel_) >= 0)),  # components in channel order
            abs(float(ichm.weights_.sum()) - 1.0) < 1e-6,
            self.colour_quantiles_.shape[0] == self.exemplar_shape_[2],
            self.bands_.colour_basis_.shape == (self.exemplar_shape_[2],) * 2,
        ]
        if not all(checks):
            raise ValueError("array shapes disagree")

    # ------------------------------------------------------------- dimensions
    @property
    def dims_(self) -> dict:
        """dict of str to int: dimensions of every space, D0 (P x P x C), D1, ..., Dn, D_r (the core
        vectors), and N (clusters), F (CDFs) and W (codewords) of the core model (the paper's Table 4)."""
        check_is_fitted(self, "ichm_")
        out = {f"D{i}": d for i, d in enumerate(self.hops_.dims_)}
        out.update(D_r=self.sdr_.n_components_, N=len(self.ichm_.weights_), F=self.ichm_.n_cdfs_,
                   W=self.ichm_.codebook_.shape[0])
        return out

    @property
    def channels_(self) -> list:
        """list of int: kept channels per hop (K1, K2, ...), as fitted."""
        check_is_fitted(self, "hops_")
        return [hop.n_channels_out_ for hop in self.hops_.hops_]

    def n_parameters(self) -> dict:
        """Parameter count broken down as in the paper's Table 4.

        Returns
        -------
        dict
            ``{module: {"formula": str, "paper": int, "stored": int}}`` for the paper's modules
            "transform stage 1", "transform stage 2", "core SDR", "core ICHM (i)", "(ii)" and
            "(iii)", then ours (their names end in "(ours)"; 0 where the model has none): "colour
            matching", "residual Gaussian", "core norm quantiles", "core member ranks", "coarse
            layout", "refinement" and "patch refinement"; then "the paper's modules" (the rows
            before ours: what the paper's pipeline, ``--paper``, uses) and "total". "paper"
            applies the paper's formula to this model's dimensions; "stored" counts the numbers
            this model actually stores
            (the arrays of its model file, index bookkeeping excluded). They differ where
            the paper's formula does: stage 2 stores ``4 K2 + K1`` numbers (each kept
            channel is one 4-tap kernel; the paper writes ``4 K1 K2 + K1``), SDR also
            stores each channel's mean map (``64 K2``), and ICHM (ii) also stores each
            cluster's mean (``N D_r``).
        """
        return table4(self.dims_, self.channels_, self.exemplar_shape_[2], self.ichm_.codebook_.shape[1],
                      self.sdr_.shape_, parameter_groups(self._to_arrays()),
                      n_classes=getattr(getattr(self, "classes_", None), "n_classes", 0))

    @one_blas_thread()  # the same image with any number of threads or concurrent callers
    @named_keywords
    def synthesize(self, size, *, rng=None, n_patches=DEFAULT_POOL, tile=False, overlap=None,
                   tolerance=0.1, detail=0.8, flat_share=0.25, match_colours=True, layout_weight=3.0, refine=5,
                   layout_refine=3, layout_patch_refine=None, patch_refine=None, patch_stride=2, reuse=1.0,
                   pool_per_block=1.5, seam_window=9, region=1024, own_shares=1.0, progress=None, dtype=np.float64,
                   return_stages=False):
        """Generate a texture image of any size: a patch pool quilted together.

        Parameters
        ----------
        size : (int, int)
            Output (height, width).
        rng : int or numpy.random.Generator, optional
{settings}
        progress : callable, optional
            Stages "layout" (with a coarse layout: its guide's steps, from the thread that makes
            it, as ``done`` of 1000), "patch pool", "quilting", "seams" (the seam
            removal, with ``seam_window``), "refine", "colour" (without the patch refinement) and
            "patch refine".
        dtype : {numpy.float64, numpy.float32, numpy.uint8}
            Of the image. float32 holds the same values as float64 rounded to float32;
            uint8 the 8-bit values 0-255 that :func:`tghop.imageio.to_uint8` makes of the
            float64 image (what ``tghop synth`` writes), without making that image (an
            8192x8192 RGB image is 1.6 GB in float64, 0.2 GB in uint8).
        return_stages : bool
            Also return each step's image, to look at: a dict of float32 (H, W, C) arrays in [0, 1]
            in the order made: "guide" (the coarse layout's, with one), "quilt" (as quilted),
            "seams" (seam removal), "refine" (the band refinement; regions too), then "patch
            refine" or "colour", the last step's (float32; the image itself is ``dtype``), and after it,
            for a two-level exemplar (:attr:`exemplar_levels_`), "levels": the image snapped to them (0.60); and,
            after "guide", "pool" (0.58): the patch pool quilting chose from, float32 (n, P, P, C)
            in [0, 1], P the patch size and n ``n_patches`` (more from 2048x2048 on, up to
            30,000: ``pool_per_block``), in the order drawn; not an image (``ndim`` 4). Without
            ``return_stages`` a small image's pool is never made whole (its patches decoded as
            quilting reads them): nothing of this costs the default path.

        Returns
        -------
        ndarray, shape (H, W, C), ``dtype``, in [0, 1] (uint8: 0 to 255)
            And the dict of stages with ``return_stages``.
        """
        check_progress(progress)
        check_is_fitted(self, "ichm_")
        made = generation.synthesize(
            self, size, rng=rng, n_patches=n_patches, tile=tile, overlap=overlap, tolerance=tolerance, detail=detail,
            flat_share=flat_share, match_colours=match_colours, layout_weight=layout_weight, refine=refine,
            layout_refine=layout_refine, layout_patch_refine=layout_patch_refine, patch_refine=patch_refine,
            patch_stride=patch_stride, reuse=reuse, pool_per_block=pool_per_block, seam_window=seam_window,
            region=region, own_shares=own_shares, progress=progress, dtype=dtype, return_stages=return_stages)
        levels = getattr(self, "exemplar_levels_", None)
        if levels is not None:  # a two-level exemplar's image: its two levels (exemplar_levels_)
            image = made[0] if return_stages else made
            snap_levels(image, levels)
            if return_stages:  # a step too, the last (0.60): the image returned, as float32 in [0, 1]
                made[1]["levels"] = (image / 255 if image.dtype == np.uint8 else image).astype(np.float32)
        return made


TGHop.__doc__ = TGHop.__doc__.replace("{parameters}", settings.numpydoc_parameters(settings.fit_settings()))
TGHop.synthesize.__doc__ = TGHop.synthesize.__doc__.replace(  # the generation settings, from the table
    "{settings}", textwrap.indent(settings.numpydoc_parameters(settings.generate_settings()), "    "))


class CoarseLayout(ImageInputMixin, BaseEstimator):
    """The coarse layout of :class:`TGHop` (ours): a small TGHop model of the exemplar
    downsampled by ``factor``, whose quilted images guide the fine level above patch scale.

    A fine model owns its coarse one (``TGHop.layout_``); the scales, the coarse model's
    training settings and the guide are the plain functions of :mod:`tghop.layout`.

    Parameters
    ----------
    factor : int, default=3
        Downsampling of the exemplar (3: coarse patches cover 96x96 exemplar pixels).
    patch_size : int, default=32
        Patch size of the coarse model.
    n_clusters : int, default=50
        ICHM clusters of the coarse model (fewer if it has few training patches: at least
        about 40 patches per cluster).
    min_patches : int, default=2000
        Below this many training patches at stride 2, the coarse model uses stride 1.
    max_patches : int, default=4000
        Training patches of the coarse model (a random subset beyond this): it only needs
        the low-pass layout, so it is kept cheap (with the two settings below, about a
        third of the fine model's fit time).
    cluster_energy, max_cluster_components : float, int, default=0.95, 50
        Per-cluster PCA of the coarse model (the paper's Table 4 values).
    gamma : float, default=0.01
        SDR threshold of the coarse model (the paper's value: the layout needs no fine
        detail, so it keeps the smaller core of the paper, unlike the fine model's 0.003).
    patch_levels : int, default=3
        Pyramid levels of the coarse model's patch statistics, for the guide's patch
        refinement (0: none, as up to tghop 0.47).
    rng : int or numpy.random.Generator, optional
        A Generator is drawn from (advanced); the coarse model keeps a copy of it as it was.

    Attributes
    ----------
    model_ : TGHop
        The coarse model (fitted on the downsampled exemplar; its ``rng`` the int seed given, or
        a copy of the generator as it was before the fit).

    Example
    -------
    >>> from tghop import data
    >>> from tghop.synthesis import CoarseLayout
    >>> coarse = CoarseLayout(rng=0).fit(data.bricks())                     # doctest: +SKIP
    >>> guide = coarse.guide((256, 256), rng=1)                             # doctest: +SKIP
    """

    def __init__(self, factor=3, patch_size=32, n_clusters=50, min_patches=2000, max_patches=4000,
                 cluster_energy=0.95, max_cluster_components=50, gamma=0.01, patch_levels=layout.PATCH_LEVELS,
                 rng=None):
        self.factor = factor
        self.patch_size = patch_size
        self.n_clusters = n_clusters
        self.min_patches = min_patches
        self.max_patches = max_patches
        self.cluster_energy = cluster_energy
        self.max_cluster_components = max_cluster_components
        self.gamma = gamma
        self.patch_levels = patch_levels
        self.rng = rng

    def fits(self, shape) -> bool:
        """Whether an exemplar of ``shape`` is large enough for this layout (:func:`tghop.layout.fits`).

        Parameters
        ----------
        shape : tuple of int
            The exemplar's (H, W, ...).

        Returns
        -------
        bool
        """
        return layout.fits(shape, self.factor, self.patch_size)

    def usable_factor(self, shape, exclude=None):
        """:func:`tghop.layout.usable_factor` with these settings: ``factor`` or smaller, or None.

        Parameters
        ----------
        shape : tuple of int
            The exemplar's (H, W, ...).
        exclude : ndarray of bool, shape (H, W), optional
            Pixels left out of training (True: excluded).

        Returns
        -------
        int or None
            The largest factor in ``[2, factor]`` the exemplar is large enough for; None: none is.
        """
        return layout.usable_factor(shape, self.factor, patch_size=self.patch_size, exclude=exclude,
                                    n_clusters=self.n_clusters, min_patches=self.min_patches,
                                    max_patches=self.max_patches)

    def fit(self, image, y=None, *, exclude=None):
        """Fit the coarse model on ``image`` downsampled by ``factor``.

        Parameters
        ----------
        image : ndarray, shape (H, W) or (H, W, C)
            The exemplar: float in [0, 1], or uint8 (downsampled without a float copy).
        y : None
            Ignored (scikit-learn's signature).
        exclude : array_like of bool, shape (H, W), optional
            Pixels to leave out (:meth:`TGHop.fit`); a coarse pixel is left out when any of
            its pixels is.

        Returns
        -------
        self
        """
        img = np.asarray(image)
        if img.dtype != np.uint8:  # uint8 (a large exemplar) is downsampled without a float copy
            img = check_image(image, name="exemplar", channels=None)
        elif img.ndim == 2:
            img = img[:, :, None]
        training = layout.coarse_training(img.shape, self.factor, patch_size=self.patch_size,
                                          n_clusters=self.n_clusters, min_patches=self.min_patches,
                                          max_patches=self.max_patches)
        small = layout.downsample(img, int(self.factor))  # 8-bit stays 8-bit: a byte per value
        small_exclude = None if exclude is None else downsample_mask(np.asarray(exclude, dtype=bool), int(self.factor))
        model = TGHop(
            patch_size=int(self.patch_size), cluster_energy=self.cluster_energy,
            max_cluster_components=self.max_cluster_components, gamma=self.gamma, layout_factor=None,
            patch_levels=self.patch_levels, colour_classes=0, rng=self.rng, **training,
        )
        # An int seed stays one (the model file records it); a Generator (or None's fresh one) is drawn
        # from as before, the model keeping a copy of it as it was (fit_part).
        if settings.recorded_seed(self.rng) is None:
            self.model_ = fit_part(model, check_rng(self.rng), small, exclude=small_exclude, stacked=True)
        else:
            self.model_ = model.fit(small, exclude=small_exclude, stacked=True)  # the fine model's channels
        return self

    def guide(self, size, **options):
        """A coarse synthesis upsampled to ``size``: the layout the fine level follows.

        Parameters
        ----------
        size : int or (int, int)
            Output (H, W).
        **options
            The keywords of :func:`tghop.layout.coarse_guide` (``rng``, ``n_patches``, ``tile``,
            ``refine``, ``seam_window``, ``flat_share``, ``patch_refine``); others are a
            :class:`TGHopError`.

        Returns
        -------
        ndarray, shape (H, W, C), float32 in [0, 1]
        """
        check_is_fitted(self, "model_")
        check_keywords(options, layout.coarse_guide, where="guide", exclude=("model", "factor", "size"))
        return layout.coarse_guide(self.model_, self.factor, size, **options)


def snap_levels(image, levels):
    """Move each pixel of ``image`` (H, W, C; floats in [0, 1] or uint8 levels) to the nearer of a
    two-level exemplar's ``levels`` (:attr:`TGHop.exemplar_levels_`, floats), in place."""
    if image.dtype == np.uint8:
        image[...] = snap_to_levels(image.astype(np.float32), np.round(levels * 255))
    else:
        snap_to_levels(image, levels, out=image)


def _levels(value, channels):
    """A model file's ``exemplar_levels`` (None, or two lists of ``channels`` values in [0, 1]) as
    :attr:`TGHop.exemplar_levels_`, or a one-line :class:`TGHopError`."""
    if value is None:
        return None
    try:
        levels = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        levels = None
    if levels is None or levels.shape != (2, channels) or not np.all((levels >= 0) & (levels <= 1)):
        raise TGHopError(f"the metadata's exemplar_levels must be two lists of {channels} values in [0, 1], "
                         f"got {value!r:.80}; the model file is damaged")
    return levels
