"""Whole materials: an albedo and its maps (normal, roughness, height, ...) synthesised
together, every map aligned with the others as in the exemplar. Beside it: :mod:`tghop.map_names`
(what an input map's file name says), :mod:`tghop.material_files` (the output files' names),
:mod:`tghop.normals` (a normal map's convention), :mod:`tghop.masks` (mask maps kept at their levels).

How the maps stay aligned: one :class:`~tghop.synthesis.TGHop` model is fitted on the
stacked channels of all maps (albedo RGB, normal RGB, roughness, ...: an (H, W, C) image
of C channels), so every generated patch carries all maps at once, drawn together from
one joint distribution; quilting then chooses each block's patch and its cut once, for
every map (the choice and the cuts are the same for all channels by construction). After quilting each map is refined
(band statistics of its own, :mod:`tghop.refine`) and colour-matched (each channel to its own exemplar histogram,
:mod:`tghop.colour`) on its own: a map's values are never matched to another map's. Up to a texture's sizes the albedo
is then patch-refined (:mod:`tghop.patch_refine`) with its own statistics in place of its colour matching (0.59). A
normal map is renormalised to unit vectors at the end. The measurement behind these choices (against a model per map,
and with the maps left unrefined) is in docs/choices.md, "Whole materials".

A map is a normal map when its name contains "normal" or "nrm" (any case), or when it is
named in ``normal`` (what a map's name says: :mod:`tghop.map_names`, whose names this module
gives too); it must have 3 channels holding unit vectors encoded as ``(n + 1) / 2``
(OpenGL or DirectX convention alike): anything else is refused at fit.

Example
-------
>>> from tghop import data
>>> from tghop.material import Material, example_maps
>>> albedo = data.bricks()
>>> maps = example_maps(albedo)   # made from the albedo; your own: arrays of its size (a normal map: 3 channels)
>>> mat = Material(rng=0).fit(albedo, maps={"normal": maps["normal"], "height": maps["height"]})  # doctest: +SKIP
>>> out = mat.synthesize((512, 512), rng=1)   # {"albedo": ..., "normal": ..., "height": ...}  # doctest: +SKIP
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping

import numpy as np

from . import settings
from ._arrays import check_dtype, check_not_path
from ._errors import TGHopError, check_progress, warn
from ._estimator import BaseEstimator, ImageInputMixin, check_is_fitted, check_rng, fit_part, fitted_settings
from ._images import check_image
from .data import example_maps  # made from an albedo for tests and demonstrations; tghop.material's name too
from ._progress import report
from ._resources import one_blas_thread
from .colour import match_histograms
from .depths import to_uint8
from .map_names import (ALBEDO, MAP_KINDS, MAP_NAME, MAP_NAME_MAX, SCALAR_KINDS, MapNameClashError, check_map_names,
                        is_normal_name, keeps_alpha, map_kind, map_name, name_kind, normal_convention)
from .masks import MASK_LEVELS, channel_levels, mask_levels, snap_map
from .normals import (NORMAL_LOOK_MEAN, NORMAL_LOOK_SHARE, check_normal_map, convention_of, looks_like_normal_map,
                      renormalise, surface_map)
from .patch_refine import PatchStatistics, fit_patch_statistics, refine_image, steps_for
from .refine import BandStatistics, refine as refine_bands
from .scale import rescale, rescale_mask
from .exemplar import drop_alpha
from .synthesis import TGHop, default_channels, prepare_exemplar

__all__ = ["Material", "is_normal_name", "normal_convention", "check_normal_map", "drop_opaque_alpha", "renormalise",
           "example_maps", "map_name", "check_map_names", "MapNameClashError", "map_kind",
           "looks_like_normal_map", "ALBEDO", "MAP_NAME", "MAP_NAME_MAX", "MAP_KINDS", "NORMAL_LOOK_SHARE",
           "NORMAL_LOOK_MEAN", "colour_spread", "COLOUR_SPREAD", "one_value_a_pixel", "carry_steps"]

#: Bits per channel a map's file may have (what a model file accepts).
DEPTHS = (8, 16, 32)
#: The albedo's patch statistics' arrays in a model file (0.59): no map's ``material.<name>.`` prefix.
PATCH_PREFIX = "material_patch."
#: ``Material.synthesize``'s own setting, checked as the settings table checks its booleans.
REFINE_MAPS = settings.Setting("refine_maps", True, "bool", "Refine the maps other than the albedo too.",
                               when="generate", cli=None)


#: Mean spread of a map's channels (:func:`colour_spread`) above which a map named as one value a pixel
#: (:data:`tghop.map_names.SCALAR_KINDS`: roughness, height, ...) is warned of as holding colours (0.58).
#: Measured: 0 for every grey map stored as RGB, JPEG too (bricks' and cells' example roughness and height
#: and their luminance, 20 of ../shared/textures' JPEGs made grey; quality 60-95: equal channels encode no
#: chroma), 0.061 (knit) to 0.607 for its 38 colour photographs (median 0.21); 3 more are grey photos stored
#: as RGB (0). Half the closest photograph's.
COLOUR_SPREAD = 0.03


def colour_spread(image) -> float:
    """How far an image's channels are apart: the mean, over every other pixel of every other row, of
    each pixel's largest channel less its smallest (0 for a grey image stored as RGB; a colour
    photograph's 0.06-0.6, :data:`COLOUR_SPREAD`).

    Parameters
    ----------
    image : array_like, shape (H, W, C)
        Floats in [0, 1]; fewer than 2 channels are 0.

    Returns
    -------
    float
    """
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] < 2 or arr.size == 0:
        return 0.0
    v = arr[::2, ::2].astype(np.float64, copy=False)
    return float((v.max(axis=2) - v.min(axis=2)).mean())


def drop_opaque_alpha(image, name: str, *, keep=False):
    """A map read with its alpha channel (``load_image(..., keep_alpha=True)``) without it, where
    every pixel is opaque; a map whose alpha holds data is kept whole where ``keep`` (its name says a
    packing with a map in A, :func:`tghop.map_names.keeps_alpha`: Unity's metallic-smoothness, HDRP's mask
    map; 0.59), else refused in one line (:class:`TGHopError`): a material's map has 1 or 3 channels
    (2 or 4: such a packing), and the alpha was dropped with a warning about transparency, the output without it.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        C of 2 or 4: the alpha last (uint8, uint16 or float in [0, 1]); another C is returned as it is.
    name : str
        How the message names the map (``"--maps rock_mask.png"``).
    keep : bool
        A map whose alpha holds data is a packing's channels (RGBA, or grey and alpha): returned as it is.

    Returns
    -------
    ndarray, shape (H, W, C - 1) or the image itself
    """
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] not in (2, 4):
        return arr
    alpha = arr[..., -1]
    full = np.iinfo(arr.dtype).max if arr.dtype.kind == "u" else 1.0
    share = float(np.mean(alpha < full))
    if share > 0 and keep:  # RGBA, or grey and alpha (a metalness and its smoothness saved as LA)
        return arr
    if share > 0:
        raise TGHopError(f"{name} has an alpha channel that holds data ({share:.0%} of its pixels not opaque: a "
                         "smoothness, an opacity?), and a material's map has 1 or 3 channels; name it as a packing "
                         "that holds a map in A (_MaskMap, _MetallicSmoothness, _ORM), or save the alpha as a map "
                         "of its own and the map without it")
    return arr[..., :-1]


def one_value_a_pixel(image) -> bool:
    """Whether a map's channels hold one value a pixel: every channel that varies (by 1/512 or more) equal to
    the others that do, within 1/512; a constant channel is the packing's unused one (Unity's metallic map:
    metalness in R, G and B zero or copies of it; 0.59). What :meth:`Material.fit` warns of where a map named as
    one value a pixel holds more (:func:`colour_spread`).

    Parameters
    ----------
    image : array_like, shape (H, W, C)
        Floats in [0, 1] (every other pixel of every other row is read).

    Returns
    -------
    bool

    Examples
    --------
    >>> import numpy as np
    >>> from tghop.material import one_value_a_pixel
    >>> metal = np.linspace(0, 1, 16).reshape(4, 4, 1)
    >>> one_value_a_pixel(np.concatenate([metal, 0 * metal, 0 * metal], axis=2)), one_value_a_pixel(np.dstack(
    ...     [metal, 1 - metal, metal]))
    (True, False)
    """
    arr = np.asarray(image)[::2, ::2]
    varying = [c for c in range(arr.shape[2]) if np.ptp(arr[..., c]) >= 1 / 512] if arr.size else []
    return all(np.abs(arr[..., c] - arr[..., varying[0]]).max() < 1 / 512 for c in varying[1:])


def carry_steps(steps, own):
    """A material's steps in order (:meth:`Material.synthesize`'s and :func:`tghop.inpaint.inpaint_material`'s
    ``stages``): ``steps`` (step -> ``{name: map}``, or ``"pool"`` -> its patches) with the joint model's first,
    then each map's of ``own`` in that order, each step's dict holding every map (one it left alone as before it)."""
    ordered, last = {}, {}
    for step in [k for k in steps if k not in own] + [k for k in own if k in steps]:
        ordered[step] = steps[step] if step == "pool" else (last := {**last, **steps[step]})
    return ordered


def _depth_of(arr) -> int:
    return 8 if arr.dtype == np.uint8 else 16 if arr.dtype == np.uint16 else 32


class Material(ImageInputMixin, BaseEstimator):
    """An albedo and its maps, modelled together (see the module's notes).

    Parameters
    ----------
    model : TGHop, optional
        Its settings are those of the joint model (default: ``TGHop()``'s); it is not
        changed (a copy is fitted). ``n_channels`` None, or entries of it None: the default
        for the stacked channel count (:func:`tghop.synthesis.default_channels`).
    normal : "auto", str or sequence of str
        Which maps are normal maps: by name ("auto", :func:`is_normal_name`), or the map
        of this name, or the maps of these names (``[]``: none). A single string other than
        "auto" is one map's name, not a sequence of one-letter names (``"normal"`` is read
        as ``["normal"]``, what anyone writing it means); a map named "auto" is given as
        ``["auto"]``.
    rng : int or numpy.random.Generator, optional
        Seed of fitting (overrides the model's ``rng``).

    Attributes
    ----------
    model_ : TGHop
        The joint model of the stacked channels.
    names_ : list of str
        ``"albedo"`` first, then the maps in the order given.
    map_channels_ : list of int
        Channels of each map (a grey map stored as RGB becomes one channel; a normal map
        keeps its three; a packing with a map in its alpha, four or two: :func:`tghop.map_names.keeps_alpha`).
    normal_ : list of bool
    conventions_ : list of str or None
        Each normal map's convention, ``"OpenGL"`` or ``"DirectX"``: its content's
        (:func:`tghop.normals.convention_of`; 0.60: none where its slopes run against the height map's, or the
        occlusion's, :func:`tghop.normals.surface_map`, as a mirrored map's do), else its name's
        (:func:`normal_convention`), else None (0.59; a model file of 0.58 or before: its name's); None for the
        other maps. Painted or remixed materials whose normal maps differ in it are made one
        (:func:`tghop.synthesize_guided`).
    depths_ : list of int
        Bits per channel of each map as given (8, 16, or 32 for float): what ``tghop synth``
        writes each map with unless told otherwise.
    bands_ : list of tghop.refine.BandStatistics
        Each map's own refinement statistics.
    patches_ : tghop.patch_refine.PatchStatistics or None
        The albedo's alone, for its patch refinement (0.59; None: ``patch_levels`` 0, or a file of 0.58).
    levels_ : list of ndarray or None
        Each map's mask levels (:func:`tghop.masks.mask_levels`: a map of at most 4 distinct values,
        not the albedo or a normal map), to which its output is snapped; None for the others.
    channel_levels_ : list of list or None
        Where a map of several channels has no mask levels, its channels' own
        (:func:`tghop.masks.channel_levels`: a channel of at most 4 distinct values, an ORM's
        metalness), a list of one (k,) array or None per channel, each snapped on its own; None for
        the other maps.
    """

    # what to do before fit (0.63; 0.62 said "with an exemplar", where Material.fit takes an albedo and its maps)
    _not_fitted_hint = ("call 'fit' with an albedo and its maps first (or load a fitted material with "
                        "tghop.modelfile.load_model)")

    def __init__(self, model=None, normal="auto", rng=None):
        self.model = model
        self.normal = normal
        self.rng = rng

    def _unknown_param_hint(self, name):
        """A TGHop setting (or its command line's name) given to the material (0.64): it belongs to its ``model``."""
        from .synthesis import TGHop

        own = super()._unknown_param_hint(name)  # random_state: rng, the material's own
        if not own and name in TGHop._get_param_names():
            return f"; {name} is its model's: Material(model=TGHop({name}=...))"
        if not own and TGHop()._unknown_param_hint(name):
            return f"; a setting of its model, Material(model=TGHop(...)){TGHop()._unknown_param_hint(name)}"
        return own

    # ---------------------------------------------------------------- fitting
    def _checked_params(self):
        """``model`` and ``normal``, checked (one-line :class:`TGHopError` naming each)."""
        if self.model is not None and not isinstance(self.model, TGHop):
            raise TGHopError(f"model must be a TGHop (the joint model's settings) or None, "
                             f"got {type(self.model).__name__}")
        normal = self.normal
        if isinstance(normal, str):
            return normal if normal == "auto" else [normal]
        bad = isinstance(normal, Mapping) or not isinstance(normal, (list, tuple, set, frozenset))
        if bad or not all(isinstance(name, str) for name in normal):
            raise TGHopError(f"normal must be 'auto', a map's name or a list of map names, got {normal!r}")
        return list(normal)

    @staticmethod
    def _checked_depths(depths, names):
        """``depths`` checked against the map names: ``{name: 8, 16 or 32}``."""
        if depths is None:
            return {}
        if not isinstance(depths, Mapping):
            raise TGHopError(f"depths must be a dict of map name -> 8, 16 or 32, got {type(depths).__name__}")
        out = {}
        for name, depth in depths.items():
            if name not in names:
                raise TGHopError(f"depths names {name!r}, which is not a map's name ({', '.join(names)}); give "
                                 "depths only of the albedo and the maps given")
            if isinstance(depth, bool) or not isinstance(depth, numbers.Integral) or int(depth) not in DEPTHS:
                raise TGHopError(f"depths[{name!r}] must be 8, 16 or 32 (bits per channel of the map's file), "
                                 f"got {depth!r}")
            out[name] = int(depth)
        return out

    def _maps(self, albedo, maps, depths, normal):
        """Validated maps: [(name, (H, W, c) float64 array, depth, is_normal)], the albedo first."""
        if maps is not None and not isinstance(maps, Mapping):
            raise TGHopError(f"maps must be a dict of map name -> array, got {type(maps).__name__}")
        items = [(ALBEDO, albedo)] + list((maps or {}).items())
        names = [name for name, _ in items]
        for name in names:
            if not isinstance(name, str) or not MAP_NAME.fullmatch(name):
                raise TGHopError(f"map name {name!r} cannot name a file; use letters, digits, '_', '-' and '.'")
        try:
            check_map_names(names[1:])
        except MapNameClashError as exc:
            raise TGHopError(str(exc)) from None
        depths = self._checked_depths(depths, names)
        if normal != "auto":
            unknown = set(normal) - set(names)
            if unknown:
                raise TGHopError(f"normal names {sorted(unknown)[0]!r}, which is not a map's name "
                                 f"({', '.join(names)})")
        out = []
        for name, arr in items:
            check_not_path(arr, f"map {name!r}")
            raw = np.asarray(arr)
            if name == ALBEDO and raw.ndim == 3 and raw.shape[2] in (2, 4):  # RGBA: fit warns as it drops it (0.59)
                raw = raw[..., :-1]
            depth = depths.get(name, _depth_of(raw))
            packed = name != ALBEDO and keeps_alpha(name)  # Unity's metallic-smoothness, HDRP's mask map (0.59)
            if name != ALBEDO:  # an alpha: dropped where opaque, kept by a packing, else refused (as read_map)
                raw = drop_opaque_alpha(raw, f"map {name!r}", keep=packed)
            img = check_image(raw, name=f"map {name!r}", channels=(1, 2, 3, 4) if packed else (1, 3))
            is_normal = is_normal_name(name) if normal == "auto" else name in normal
            if is_normal:  # before a grey map is made one channel: a normal map keeps its three, checked
                check_normal_map(img, name)
            if name == ALBEDO:  # the exemplar: refused if flat; a map may be (a constant metalness)
                prepared = prepare_exemplar(img)
                img = img if is_normal else prepared
            elif not is_normal and img.shape[2] == 3 and np.abs(img[..., 1:] - img[..., :1]).max() < 1 / 131072:
                img = np.ascontiguousarray(img[..., :1])  # a grey map stored as RGB (to 16 bits)
            if name == ALBEDO:
                shape = img.shape[:2]
            elif img.shape[:2] != shape:
                raise TGHopError(f"map {name!r} is {img.shape[0]}x{img.shape[1]} but the albedo is "
                                 f"{shape[0]}x{shape[1]}; give every map at the albedo's size")
            out.append((name, img.astype(np.float64, copy=False), depth, is_normal))
        return out

    def fit(self, albedo, maps=None, *, exclude=None, depths=None, progress=None):
        """Learn the joint model of an albedo and its maps.

        Parameters
        ----------
        albedo : ndarray, shape (H, W) or (H, W, C)
            The exemplar (float in [0, 1], uint8 or uint16). Of 2 or 4 channels, grey or RGB with alpha:
            the alpha is dropped with :meth:`TGHop.fit <tghop.synthesis.TGHop.fit>`'s warnings
            (:func:`tghop.exemplar.drop_alpha`; 0.58 refused it).
        maps : dict of str to ndarray, optional
            Name -> map of the same H and W (1 or 3 channels, any depth). Names
            name the maps' files (:func:`tghop.material_files.map_files`). A list or another type
            is refused. A map's alpha channel (2 or 4 channels) is dropped where every pixel is opaque;
            one that holds data is a 4th channel where the name says such a packing
            (:func:`tghop.map_names.keeps_alpha`: ``_Metallic``, ``_MetallicSmoothness``, ``_MaskMap``, ``_ORM``;
            0.59), else refused (:func:`drop_opaque_alpha`, as ``fit --maps`` reads a file).
        exclude : array_like of bool, shape (H, W), optional
            Pixels not to learn (:meth:`TGHop.fit`).
        depths : dict of str to int, optional
            Bits per channel of each map's file, 8, 16 or 32, by the name of the albedo or a
            map (default: from the arrays' dtypes: 8 for uint8, 16 for uint16, 32 for floats).
            Another depth, or a name that is not a map's, is refused.
        progress : callable, optional
            ``progress(stage, done, total)``: the joint model's stages (:meth:`TGHop.fit
            <tghop.synthesis.TGHop.fit>`), then "maps" (each map's band statistics).

        Returns
        -------
        self

        Warns
        -----
        UserWarning
            Of a normal map named as one convention (:func:`normal_convention`) whose content is the
            other's (:func:`tghop.normals.convention_of`). With ``normal="auto"``, of a map that
            looks like a normal map by its content (:func:`looks_like_normal_map`) but is not one by
            its name (:func:`is_normal_name`): it is modelled as colours, its output not renormalised.
            Of a map named as one value a pixel (:data:`tghop.map_names.SCALAR_KINDS`: roughness, height,
            ...) whose channels differ as a colour image's (:func:`colour_spread` over
            :data:`COLOUR_SPREAD`): the colour map under another name, or a packed map (0.58).
        """
        check_progress(progress)
        started = settings.generators_given(self)  # rng, model__rng: Generators as the fit begins (model file)
        normal = self._checked_params()
        check_not_path(albedo, "map 'albedo'")
        albedo = drop_alpha(albedo, name="albedo", exclude="exclude=albedo[..., -1] < {half}", keep=None)  # as fit
        items = self._maps(albedo, maps, depths, normal)
        conventions = [None]
        # a height map (or the occlusion) a second cue: a normal map whose slopes run against it has none (0.60)
        height = surface_map((name, img) for name, img, _, is_normal in items[1:] if not is_normal)
        for name, img, _, is_normal in items[1:]:
            named, found = normal_convention(name), convention_of(img, height) if is_normal else None
            conventions.append((found or named) if is_normal else None)  # what comes out: its content's (0.59)
            if named and found and named != found:
                warn(f"map {name!r} is named as {named}'s but its content is {found}'s (green "
                     f"{'down' if found == 'DirectX' else 'up'}); it comes out as it is, {found}'s: rename "
                     "it, or flip its green if the name is right", UserWarning, stacklevel=2)
        for name, img, _, is_normal in items[1:] if normal == "auto" else ():
            if not is_normal and looks_like_normal_map(img):
                warn(f"map {name!r} looks like a normal map but its name does not say so: it is modelled as "
                     "colours and not renormalised; name it *normal* or *nrm* (or give it in normal) if it "
                     "is one", UserWarning, stacklevel=2)
        for name, img, _, is_normal in items[1:]:  # a colour image under a grey map's name (0.58)
            kind, spread = name_kind(name), colour_spread(img)
            # not Unity's metallic-smoothness (4 channels) or its metalness in R alone (G, B constant or copies; 0.59)
            if not is_normal and kind in SCALAR_KINDS and spread > COLOUR_SPREAD and img.shape[2] in (1, 3) and \
                    not one_value_a_pixel(img):
                warn(f"map {name!r} is named as a {kind} map, one value a pixel, but its channels differ as a colour "
                     f"image's (mean spread {spread:.2f}; a grey map's is 0): it is modelled as {img.shape[2]} "
                     "channels, as given; if it is the colour map give it as the albedo, if it packs several maps "
                     "name it as a packed map (_ORM)", UserWarning, stacklevel=2)
        stack = np.concatenate([img for _, img, _, _ in items], axis=2)
        if stack.shape[2] == 3 and np.abs(stack[..., 1:] - stack[..., :1]).max() < 1 / 512:
            raise TGHopError("every map equals the grey albedo; there is nothing to model apart from it")
        base = TGHop() if self.model is None else self.model
        params = base.get_params()
        if self.rng is not None:
            params["rng"] = self.rng
        patch_levels, whitening = params["patch_levels"], params["patch_whitening"]  # the albedo's alone (0.59)
        params["patch_levels"] = 0  # the joint model's: none (refining all maps together did not help)
        given = params.get("n_channels")
        if given is not None and any(k is None for k in given):  # some given (--k1 alone): the rest by default
            defaults = default_channels(params["patch_size"], stack.shape[2])
            params["n_channels"] = tuple(d if k is None else k for k, d in zip(given, defaults))
        model = TGHop(**params)
        if settings.recorded_seed(params["rng"]) is None:  # an int seed stays one: the model file records it
            # A Generator (None: a fresh one) is drawn from as before; the model keeps a copy of it as it was.
            model = fit_part(model, check_rng(params["rng"]), stack, exclude=exclude, progress=progress, stacked=True)
        else:
            model.fit(stack, exclude=exclude, progress=progress, stacked=True)  # 2 or 4 channels: maps, no alpha
        scale = model.scale  # each map's bands at the joint model's working scale
        ex = None if exclude is None else rescale_mask(np.asarray(exclude, dtype=bool), scale)
        bands = []  # stage "maps": each map's own band statistics (work after the joint model's stages)
        report(progress, "maps", 0, len(items))
        for _, img, _, _ in items:
            bands.append(BandStatistics(n_levels=model.band_levels, n_orientations=model.band_orientations)
                         .fit(rescale(img, scale), exclude=ex))
            report(progress, "maps", len(bands), len(items))
        patches = fit_patch_statistics(patch_levels, rescale(items[0][1], scale), whitening=whitening, exclude=ex)
        # Only now, all together: a fit that fails leaves an earlier fit whole, not its model beside new maps.
        self.model_, self.bands_, self.patches_ = model, bands, patches
        self.names_ = [name for name, _, _, _ in items]
        self.normal_ = [is_normal for _, _, _, is_normal in items]
        self.conventions_ = conventions
        self.map_channels_ = [img.shape[2] for _, img, _, _ in items]
        self.depths_ = [depth for _, _, depth, _ in items]
        self.levels_ = [None if i == 0 or is_normal else mask_levels(img, exclude)
                        for i, (_, img, _, is_normal) in enumerate(items)]
        self.channel_levels_ = [channel_levels(img, exclude) if levels is None and i and not is_normal
                                and img.shape[2] > 1 else None
                                for i, ((_, img, _, is_normal), levels) in enumerate(zip(items, self.levels_))]
        self._fitted_params = fitted_settings(self)  # as TGHop's: set_params after fit is refused until a new fit
        self._fitted_params.update(started)
        return self

    def stacked_channels(self, albedo, maps=None) -> dict:
        """The channels each map takes in the joint model, as :meth:`fit` stacks them (a grey map
        stored as RGB: one; a normal map: three), by name, the albedo first; fitting nothing (the
        channel counts of :attr:`model` can be checked against their sum before a fit:
        :meth:`tghop.synthesis.TGHop.check_channels`). Bad maps raise :meth:`fit`'s one-line
        :class:`TGHopError`.

        Parameters
        ----------
        albedo : array_like, shape (H, W) or (H, W, C)
            As :meth:`fit` takes it.
        maps : dict of str to ndarray, optional
            As :meth:`fit` takes them.

        Returns
        -------
        dict of str to int
            Map name -> its channels in the joint model (1 or 3; 2 or 4: a packing with a map in A, 0.59),
            ``"albedo"`` first.
        """
        return {name: img.shape[2] for name, img, _, _ in self._maps(albedo, maps, None, self._checked_params())}

    def map_slices(self):
        """Each map's channels in the joint model's stacked channels, in :attr:`names_`'s order:
        a list of slices.

        Returns
        -------
        list of slice
            One per map, ``"albedo"`` first: ``stack[..., s]`` is the map's (H, W, c) part of an
            (H, W, sum(map_channels_)) stack. Before :meth:`fit`, :class:`~tghop.NotFittedError`.
        """
        check_is_fitted(self, "model_")
        bounds = np.concatenate([[0], np.cumsum(self.map_channels_)]).tolist()
        return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]

    # ------------------------------------------------------------- generation
    @one_blas_thread()  # the same image with any number of threads or concurrent callers
    def synthesize(self, size, *, rng=None, refine=5, match_colours=True, tile=False, refine_maps=True,
                   progress=None, dtype=np.float64, return_stages=False, **options):
        """Generate every map of the material, aligned.

        Parameters
        ----------
        size : (int, int)
        rng : int or numpy.random.Generator, optional
            Same seed, same maps.
        refine : int
            Rounds of each map's own refinement (:meth:`TGHop.synthesize`'s ``refine``).
        match_colours : bool
            Match each channel of each map to its own exemplar histogram.
        tile : bool
        refine_maps : bool
            Refine the maps other than the albedo too (the albedo always is, with ``refine``).
        progress : callable, optional
            ``progress(stage, done, total)``: the joint model's stages, then each map's
            refinement ("refine", as :func:`tghop.refine.refine` reports it) and a "maps" stage
            after each map (``done`` of ``total`` maps); an exception it raises stops the work.
        dtype : {numpy.float64, numpy.float32, numpy.uint8}
            uint8 (0.57; 0.56 refused it, which :func:`tghop.synthesize_guided` of materials took):
            each map's float values rounded to 0-255 as :meth:`TGHop.synthesize` rounds them, a
            16-bit map (:attr:`depths_`) too; keep a float for its 65536 levels.
        **options
            The other generation settings of :meth:`TGHop.synthesize` (``n_patches``,
            ``tolerance``, ``detail``, ``layout_weight``, ...). These, ``refine``,
            ``match_colours`` and ``tile`` are checked as :meth:`TGHop.synthesize` checks them
            (:mod:`tghop.settings`), ``refine_maps`` as a boolean. ``patch_refine`` (None: by the size, as a
            texture's) patch-refines the albedo with :attr:`patches_` in place of its colour matching (0.59;
            a material of 0.58 has none: above 0 refused, None skips it); the other maps are as in 0.58.
        return_stages : bool
            Also return each step's maps (0.61), as :meth:`TGHop.synthesize` does its image's.

        Returns
        -------
        dict of str to ndarray
            ``name -> (H, W, c)`` array in [0, 1] (uint8: 0 to 255), ``"albedo"`` first, in :attr:`names_`'s order; a
            mask map (:attr:`levels_`) holds only its exemplar's values, a mask channel
            (:attr:`channel_levels_`) its own (:mod:`tghop.masks`).
        stages : dict, only with ``return_stages``
            Step -> ``{name: (H, W, c) float32}``, every map after each step that ran, in order: the joint model's
            (``"guide"``, ``"quilt"``, ``"seams"``; ``"pool"`` its (n, P, P, channels) patches, whole), ``"refine"``,
            ``"patch refine"`` (the albedo's), ``"colour"``, ``"maps"`` (normals at unit length, masks snapped: the
            result, uint8 as levels / 255); a map a step leaves alone as the step before left it.
        """
        check_progress(progress)
        check_is_fitted(self, "model_")
        dtype = check_dtype(dtype, (np.float32, np.float64, np.uint8), "float64, float32 or uint8")
        # The checks of TGHop.synthesize (refine and match_colours are applied here, per map, not by it)
        checked = settings.check_settings(dict(refine=refine, match_colours=match_colours, tile=tile, **options))
        refine, match_colours, tile = checked.pop("refine"), checked.pop("match_colours"), checked.pop("tile")
        refine_maps = REFINE_MAPS.check(refine_maps)
        stats = self.albedo_patches(patch_refine := checked.pop("patch_refine", None))
        stride = checked.pop("patch_stride", settings.BY_NAME["patch_stride"].default)
        stack = self.model_.synthesize(size, rng=check_rng(rng), tile=tile, refine=0, match_colours=False,
                                       progress=progress, dtype=np.float32, return_stages=return_stages, **checked)
        stack, steps = stack if return_stages else (stack, {})  # the joint model's steps, then each map's (0.61)
        steps = {k: v if k == "pool" else dict(zip(self.names_, (v[..., p] for p in self.map_slices())))
                 for k, v in steps.items()}
        keep = (lambda step, name, img: steps.setdefault(step, {}).__setitem__(name, img.astype(np.float32))
                if return_stages else None)
        n_steps = steps_for(patch_refine, stack.shape[:2]) if stats is not None else 0
        quantiles = self.model_.colour_quantiles_
        out = {}
        for i, (name, part) in enumerate(zip(self.names_, self.map_slices())):
            img = np.ascontiguousarray(stack[..., part])
            if refine and (refine_maps or i == 0):
                img = refine_bands(img, self.bands_[i], n_iter=refine, tile=tile, dtype=np.float32, progress=progress)
                keep("refine", name, img)
            if i == 0 and n_steps:  # the albedo's last step, as a texture's (in place of its colour matching)
                img = refine_image(img, stats, n_steps=n_steps, stride=stride, tile=tile, progress=progress)
                keep("patch refine", name, img)
            elif match_colours:
                img = match_histograms(img, quantiles[part])
                keep("colour", name, img)
            if self.normal_[i]:
                img = renormalise(img)
            # a mask (metalness 0 and 1), or a packed map's mask channel, kept one: tghop.masks
            img = snap_map(img, self.levels_[i], self.channel_levels_[i])
            out[name] = to_uint8(img).reshape(img.shape) if dtype == np.uint8 else img.astype(dtype, copy=False)
            keep("maps", name, out[name] / np.float32(255) if dtype == np.uint8 else out[name])
            report(progress, "maps", i + 1, len(self.names_))
        return (out, carry_steps(steps, ("refine", "patch refine", "colour", "maps"))) if return_stages else out

    def albedo_patch_levels(self) -> int:
        """The levels of the albedo's patch statistics (0.59), as the file's metadata and the page's quality switch
        say them.

        Returns
        -------
        int
            0 where there are none (a material of tghop 0.58, or fitted with ``patch_levels`` 0).
        """
        stats = self.albedo_patches()
        return 0 if stats is None else len(stats.directions_)

    def albedo_patches(self, patch_refine=None):
        """The albedo's patch statistics (:attr:`patches_`), checked against ``patch_refine``.

        Parameters
        ----------
        patch_refine : int or None
            Above 0 where there are none (a material of tghop 0.58, or fitted with ``patch_levels`` 0): TGHopError.

        Returns
        -------
        tghop.patch_refine.PatchStatistics or None
        """
        check_is_fitted(self, "model_")
        stats = vars(self).get("patches_")
        if patch_refine and stats is None:
            raise TGHopError(f"patch_refine={patch_refine} needs the albedo's patch statistics, which this material "
                             "lacks (fitted by tghop 0.58 or older, or with patch_levels=0); fit it again, or leave "
                             "patch_refine at None or 0")
        return stats

    # ------------------------------------------------------------- model files
    def _to_arrays(self) -> dict:
        check_is_fitted(self, "model_")
        out = self.model_._to_arrays()
        for name, bands in zip(self.names_, self.bands_):
            out.update({f"material.{name}.{k}": v for k, v in bands._to_arrays().items()})
        if self.albedo_patches() is not None:  # 0.59
            out.update({f"{PATCH_PREFIX}{k}": v for k, v in self.patches_._to_arrays().items()})
        return out

    def map_info(self) -> list:
        """Each map's name, channels, whether it is a normal map and its depth, as
        JSON-ready dicts (what the model file's metadata and ``tghop info --json`` hold).

        Returns
        -------
        list of dict
            One per map, in :attr:`names_`'s order: ``{"name": str, "channels": int, "normal": bool,
            "depth": int}`` (depth 8, 16 or 32). Before :meth:`fit`, :class:`~tghop.NotFittedError`.
        """
        check_is_fitted(self, "model_")
        return [{"name": n, "channels": int(c), "normal": bool(nm), "depth": int(d)}
                for n, c, nm, d in zip(self.names_, self.map_channels_, self.normal_, self.depths_)]

    def _state_meta(self) -> dict:
        levels = {n: lv.tolist() for n, lv in zip(self.names_, self.levels_) if lv is not None}
        per_channel = {n: [None if c is None else c.tolist() for c in lv]
                       for n, lv in zip(self.names_, self.channel_levels_) if lv is not None}
        records = settings.generator_records(vars(self).get("_fitted_params"))  # Generators given (0.58)
        joint = {k: v for k, v in self.model_._state_meta().items() if k != "fit_rngs"}  # its: model_rng
        return {**joint, "material": {"maps": self.map_info(), "params": self._params_meta(),
                                      **({"fit_rngs": records} if records else {}),
                                      **({"levels": levels} if levels else {}),
                                      **({"channel_levels": per_channel} if per_channel else {}),
                                      "conventions": {n: c for n, c in zip(self.names_, self.conventions_) if c},
                                      **({"patch_levels": self.albedo_patch_levels()}
                                         if self.albedo_patch_levels() else {}),
                                      # the joint model's copy of the fit's generator (0.57)
                                      "model_rng": settings.generator_record(self.model_.rng)}}

    def _params_meta(self) -> dict:
        """The constructor's parameters as given (JSON-ready; rngs as :func:`tghop.settings.recorded_seed`
        of those fitted with), so that a loaded Material's ``get_params`` are the fitted one's: files of
        tghop 0.55 and before had them rebuilt from the joint model (its ``patch_levels`` 0, ``rng`` the seed
        and ``normal`` the maps found normal)."""
        fitted = vars(self).get("_fitted_params") or {}
        model = None
        if self.model is not None:
            model = {s.name: getattr(self.model, s.name) for s in settings.fit_settings()}
            model["rng"] = settings.recorded_seed(fitted.get("model__rng", self.model.rng))
            if model["n_channels"] is not None:
                model["n_channels"] = list(model["n_channels"])
        normal = self.normal if isinstance(self.normal, str) else \
            sorted(self.normal) if isinstance(self.normal, (set, frozenset)) else list(self.normal)
        return {"model": model, "normal": normal, "rng": settings.recorded_seed(fitted.get("rng", self.rng))}

    @classmethod
    def _from_params_meta(cls, given) -> "Material":
        """An unfitted Material of :meth:`_params_meta`'s parameters, checked (:class:`TGHopError`)."""
        if not isinstance(given, dict) or set(given) != {"model", "normal", "rng"}:
            raise TGHopError("the material metadata's params are not model, normal and rng")
        model = given["model"]
        if model is not None and not isinstance(model, dict):
            raise TGHopError("the material metadata's model is not null or the joint model's settings")
        if model is not None:
            rules = model.get("n_channels")
            partial = isinstance(rules, list) and None in rules  # some given (--k1 alone): the rest by default at fit
            model = settings.file_settings({**model, "n_channels": None} if partial else model)
            if partial:
                model["n_channels"] = tuple(settings.check_channel_rule(r, "n_channels", none_ok=True) for r in rules)
            model = TGHop(**model)
        mat = cls(model=model, normal=given["normal"], rng=settings.recorded_seed(given["rng"]))
        mat._checked_params()  # normal: 'auto', a name or a list of names
        return mat

    @staticmethod
    def _check_meta(meta):
        """The material part of a model file's metadata, checked: the list of maps."""
        maps = meta["material"]["maps"]
        if not isinstance(maps, list) or not maps:
            raise TGHopError("the material metadata lists no maps")
        names = []
        for i, m in enumerate(maps):
            name, c, depth = m["name"], m["channels"], m["depth"]
            # 0.60 took a name of any length (a file's map names are cut to 64)
            if not isinstance(name, str) or not MAP_NAME.fullmatch(name) or len(name) > MAP_NAME_MAX:
                shown = repr(name[:40] + "...") if isinstance(name, str) and len(name) > 40 else repr(name)[:60]
                raise TGHopError(f"the material metadata has a bad map name {shown} (letters, digits, '.', '_' or "
                                 f"'-', at most {MAP_NAME_MAX})")
            if name.lower() in names:  # 0.60: "a bad or repeated map name", not which clash
                try:
                    check_map_names([m["name"] for m in maps[1:i + 1]])
                except MapNameClashError as exc:
                    raise TGHopError(f"the material metadata's map names clash: {exc.clash}") from None
                raise TGHopError(f"the material metadata names two maps {name!r} (in any case)")
            if c not in (1, 2, 3, 4) or depth not in (8, 16, 32) or not isinstance(m["normal"], bool) or (
                    m["normal"] and c != 3):  # 2 and 4: a packing with a map in A (0.59)
                raise TGHopError(f"the material metadata's map {name!r} is not of 1 to 4 channels and 8, 16 or 32 "
                                 "bits")
            names.append(name.lower())
        if sum(m["channels"] for m in maps) != meta["exemplar_shape"][2]:
            raise TGHopError("the material's maps do not add up to the model's channels")
        return maps

    @staticmethod
    def _conventions_meta(given, maps):
        """Each normal map's convention from the metadata, checked (0.59); a file of 0.58 or before has none:
        a normal map's name's (:func:`normal_convention`), as :meth:`fit` records where its content says none."""
        if given is None:
            return [normal_convention(m["name"]) if m["normal"] else None for m in maps]
        normals = {m["name"] for m in maps if m["normal"]}
        if not isinstance(given, dict) or not set(given) <= normals or not set(given.values()) <= {"OpenGL", "DirectX"}:
            raise TGHopError("the material metadata's conventions are not a dict of its normal maps' names to 'OpenGL' "
                             "or 'DirectX'")
        return [given.get(m["name"]) for m in maps]

    @staticmethod
    def _levels_meta(given, maps, key="levels"):
        """Each map's mask levels from the metadata, checked: ``key`` "levels", a map's (k, C) pixel
        values (files of tghop 0.55 and before have none), or "channel_levels", a list of C, each a
        channel's (k,) values or None (files of 0.56 and before have none)."""
        channels = {m["name"]: m["channels"] for m in maps}
        words = key.replace("_", " ")
        if not isinstance(given, dict) or not set(given) <= {m["name"] for m in maps[1:] if not m["normal"]}:
            raise TGHopError(f"the material metadata's {words} are not a dict of its maps' names (not the albedo's "
                             "or a normal map's)")

        def values(lv, width):  # 1 to MASK_LEVELS values in [0, 1] of `width` channels, else None
            arr = np.asarray(lv, dtype=object)
            good = arr.shape[1:] == (width,) and 1 <= len(arr) <= MASK_LEVELS and all(
                isinstance(v, numbers.Real) and not isinstance(v, bool) and 0 <= v <= 1 for v in arr.flat)
            return arr.astype(np.float64) if good else None

        out = []
        for name in channels:
            lv = given.get(name)
            if lv is None:
                got = None
            elif key == "levels":
                got = values(lv, channels[name])
            elif isinstance(lv, list) and len(lv) == channels[name] and all(isinstance(e, (list, type(None)))
                                                                             for e in lv):
                got = [None if e is None else values([[v] for v in e], 1) for e in lv]
                got = None if any(g is None and e is not None for g, e in zip(got, lv)) else \
                    [None if g is None else g[:, 0] for g in got]
            else:
                got = None
            if lv is not None and got is None:
                whose = "its channels" if key == "levels" else "each of its channels, or null"
                raise TGHopError(f"the material metadata's {words} of map {name!r} are not 1 to {MASK_LEVELS} values "
                                 f"in [0, 1] of {whose}")
            out.append(got)
        return out

    @classmethod
    def _array_specs(cls, meta, *, quantised=True):
        """The checks of :mod:`tghop.modelfile`: the joint model's and each map's statistics."""
        groups = TGHop._array_specs(meta, quantised=quantised)
        params = meta["params"]
        stats = BandStatistics(n_levels=params.get("band_levels", 4), n_orientations=params.get("band_orientations", 4))
        for m in cls._check_meta(meta):
            groups.append((f"material.{m['name']}.", stats._array_specs(m["channels"])))
        levels = meta["material"].get("patch_levels")  # the albedo's patch statistics (0.59)
        if levels is not None and (not isinstance(levels, int) or isinstance(levels, bool) or not 1 <= levels <= 16):
            raise TGHopError("the material metadata's patch_levels is not a whole number from 1 to 16")
        return groups + ([(PATCH_PREFIX, PatchStatistics(levels)._array_specs(meta["material"]["maps"][0]["channels"],
                                                                              meta))] if levels else [])

    @classmethod
    def _from_state(cls, meta, arrays):
        maps = cls._check_meta(meta)
        model = TGHop._from_state(meta, arrays)
        if meta["material"].get("model_rng") is not None:  # fitted from a Generator (an int seed: in the params)
            model.rng = settings.generator_from_record(meta["material"]["model_rng"], "material's model_rng")
        given = meta["material"].get("params")
        if given is None:  # tghop 0.55 and before: rebuilt from the joint model
            mat = cls(model=TGHop(**model.get_params()), normal=[m["name"] for m in maps if m["normal"]])
        else:
            mat = cls._from_params_meta(given)
        mat.model_ = model
        mat.names_ = [m["name"] for m in maps]
        mat.map_channels_ = [m["channels"] for m in maps]
        mat.normal_ = [m["normal"] for m in maps]
        mat.conventions_ = cls._conventions_meta(meta["material"].get("conventions"), maps)
        mat.depths_ = [m["depth"] for m in maps]
        mat.levels_ = cls._levels_meta(meta["material"].get("levels", {}), maps)
        mat.channel_levels_ = cls._levels_meta(meta["material"].get("channel_levels", {}), maps, "channel_levels")
        levels = meta["material"].get("patch_levels")  # checked by _array_specs
        mat.patches_ = PatchStatistics(levels)._from_arrays(
            {k[len(PATCH_PREFIX):]: v for k, v in arrays.items() if k.startswith(PATCH_PREFIX)}) if levels else None
        mat.bands_ = []
        for m in maps:
            prefix = f"material.{m['name']}."
            sub = {k[len(prefix):]: v for k, v in arrays.items() if k.startswith(prefix)}
            mat.bands_.append(BandStatistics(n_levels=model.band_levels,
                                             n_orientations=model.band_orientations)._from_arrays(sub))
        started = settings.set_generators(mat, meta["material"].get("fit_rngs"), "material's fit_rngs")
        mat._fitted_params = {**fitted_settings(mat), **started}
        return mat
