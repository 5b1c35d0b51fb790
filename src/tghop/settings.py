"""One table of every TGHop setting: the estimator, the model file and the CLI read it.

Each :class:`Setting` says once: its name, default, type and allowed range, its help
text, its command-line option, whether it is a fit-time setting (a :class:`TGHop`
constructor parameter, stored in the model file) or a generation-time one (a keyword of
:meth:`TGHop.synthesize`, a ``tghop synth`` option, not stored), which fitted component
receives it, and its value under ``--paper``. From the table come:

* the "Parameters" section of ``TGHop``'s docstring (its ``__init__`` is written out,
  with the table's names, order and defaults, and ``tests/test_settings.py`` checks that
  the two agree, as scikit-learn checks ``_parameter_constraints``);
* checks of every value (one-line :class:`~tghop.TGHopError`; non-finite numbers are
  always refused) before any work starts, in ``TGHop.fit``, ``TGHop.synthesize``, when a
  model file is read, and on the command line;
* the forwarding of fit settings to the components (``ICHM``, ``SpatialReduction``), at
  fit and when a model file is loaded;
* the ``tghop fit`` / ``tghop synth`` options, their help and defaults, ``--paper``, and
  the refusal of fit options when ``synth`` reads a saved model.

How to add a setting
--------------------
Append one :class:`Setting` to :data:`SETTINGS`, then use it where it acts:

* fit time (``when="fit"``): read ``self.<name>`` in ``TGHop.fit`` (or give
  ``target="ichm"`` / ``"ichm.<parameter>"`` / ``"sdr"`` and the component receives it);
  add it, with the same default, to ``TGHop.__init__`` (the test checks the two agree);
  it is saved in and restored from model files (older files get the default), and
  appears as a ``fit``/``synth`` option;
* generation time (``when="generate"``): add the keyword, with the same default, to
  ``TGHop.synthesize`` (``tests/test_settings.py`` checks the two agree); it appears as a
  ``synth`` option and is checked on every call.

One setting (:class:`Setting`, its check and parse; :func:`check_channel_rule`) is
:mod:`tghop.setting`'s; what a model file records of the fit's ``rng`` (:func:`recorded_seed`,
:func:`generator_record`, ...) is :mod:`tghop.rng_records`'. Both are re-exported here, where they
were up to 0.63. Nothing here imports scikit-learn or SciPy.
"""

from __future__ import annotations

import math
from typing import Tuple

from ._errors import TGHopError
from .rng_records import (BIT_GENERATORS, fit_seed, generator_from_record, generator_record, generator_records,
                          generators_given, recorded_seed, set_generators)
from .setting import Setting, check_channel_rule

__all__ = ["Setting", "SETTINGS", "BY_NAME", "PAPER", "QUALITY", "fit_settings", "generate_settings", "check_settings",
           "component_params", "numpydoc_parameters", "check_channel_rule", "recorded_seed", "fit_seed",
           "generator_record", "generator_from_record", "generators_given", "generator_records", "set_generators",
           "BIT_GENERATORS"]


# The table. Order = order of the constructor's parameters and of the options in --help.
SETTINGS: Tuple[Setting, ...] = (
    # ---------------------------------------------------------------- fit time
    Setting("patch_size", 32, "int", "Side of the generated patches (paper: 32; 64 uses three hops).",
            low=4, paper=32),
    Setting("stride", 2, "int", "Step between training patches (paper: 2).", low=1),
    Setting("n_channels", None, "channels",
            "Channels kept per hop, e.g. ``(9, 22)`` for (K1, K2); each entry an int (a count, DC "
            "included), a float in (0, 1] (a fraction of the AC energy), or \"knee\" (the knee of the "
            "energy curve). None: :func:`default_channels` (the paper's (9, 22) for colour, (4, 10) "
            "for grey exemplars).", none_ok=True, cli=None),
    Setting("gamma", 0.003, "float",
            "SDR threshold on the variance of spatial PCA components (absolute, for images in [0, 1]); "
            "the paper's 0.01 drops most of the patches' oblique fine detail (docs/choices.md).",
            low=0, target="sdr", paper=0.01),
    Setting("gamma_mode", "absolute", "choice",
            "Compare gamma with each component's variance (absolute) or its share of the channel's.",
            choices=("absolute", "relative"), target="sdr"),
    Setting("n_clusters", None, "int",
            "N, K-means clusters in ICHM. auto (None in Python): one per 40 training patches, at least 50 "
            "(the paper's) and at most 100 (from 4,000 patches; a 256x256 exemplar has 12,769); under 500 "
            "patches (an exemplar under 76x76) one per min_cluster_size, at least 4 (44x44; 0.58).",
            low=1, none_ok=True, auto=True, cli=("--clusters", "-N"), cli_high=5000, target="ichm", paper=50),
    Setting("n_codewords", 200, "int", "W, size of the CDF codebook.", low=1, cli=("--codewords", "-W"),
            cli_high=100000, target="ichm", paper=200),
    Setting("n_bins", 256, "int", "Histogram bins per CDF.", low=2, high=65536, cli=("--bins",),
            target="ichm"),
    Setting("cluster_energy", 0.99, "float",
            "Variance fraction each cluster's PCA keeps before FastICA (the paper's F = 2,518 for "
            "N = 50 corresponds to 0.95 with at most 50 components).",
            low=0, high=1, low_open=True, target="ichm", paper=0.95),
    Setting("max_cluster_components", 100, "int", "Components per cluster at most.", low=1,
            target="ichm", paper=50),
    Setting("max_component_ratio", 0.5, "float",
            "Components per cluster at most this fraction of its training patches (ours: with fewer "
            "patches per dimension, FastICA and the histograms fit the patches, not their distribution; "
            "1: up to one fewer than the patches, as the paper).",
            low=0, high=1, low_open=True, target="ichm", paper=1.0),
    Setting("norm_match", 1.0, "float",
            "Rescale each drawn vector's independent components towards the exemplar's norm at the draw's "
            "rank, by this power of the ratio (ours: independent draws spread twice as widely in overall "
            "strength as the exemplar's patches and streak; 0: off, as the paper).",
            low=0, high=1, target="ichm", paper=0.0),
    Setting("coupling", 0.95, "float",
            "Draw each vector's independent components together: their normal scores follow a random training "
            "patch's with this correlation, plus fresh noise (ours: keeps which components act together, which "
            "independent draws lose; 0: independent draws, as the paper; below 1, so never a training patch).",
            low=0, high=0.99, target="ichm", paper=0.0),
    Setting("min_cluster_size", 10, "int", "Clusters with fewer training patches are merged into the nearest one.",
            low=2, target="ichm"),
    Setting("reject_threshold", None, "float",
            "Sampling step (iv): draw again (cluster and components) the samples with no independent "
            "component above this (None: off; the paper gives no value).",
            none_ok=True, target="ichm"),
    Setting("ica_max_iter", 200, "int", "FastICA iterations per cluster at most.", low=1,
            cli=("--ica-iterations",), target="ichm.max_iter"),
    Setting("ica_tol", 1e-3, "float",
            "FastICA stops when no unmixing direction changes by more than this (--paper: scikit-learn's "
            "default 1e-4; the paper names none; 1e-3 halves ICA's fitting time at the same measured quality).",
            low=0, low_open=True, cli=("--ica-tol",), target="ichm.tol", paper=1e-4),
    Setting("residual", False, "bool",
            "Also model the detail each cluster's PCA drops, as a Gaussian per core channel, and add a "
            "draw of it to every generated patch (ours; restores fine grain without the refinement, "
            "but adds noise on top of it, so off by default).", target="ichm", paper=False),
    Setting("max_patches", 20000, "int",
            "Training patches beyond this are subsampled at random (a 256x256 exemplar at stride 2 has "
            "12,769).", low=1, none_ok=True),
    Setting("band_levels", 4, "int",
            "Laplacian bands whose distributions are learned for the refinement after stitching "
            "(:mod:`tghop.refine`, ours).", low=1, high=8),
    Setting("band_orientations", 4, "int",
            "Oriented parts per band for the refinement (0: whole Laplacian bands).", low=0, high=8),
    Setting("colour_classes", 4, "int",
            "Classes of the exemplar's colours (K-means), each with its own histograms, so that an output "
            "holding them in other proportions keeps them (ours, with own_shares; 0: none stored, one "
            "histogram per channel as up to tghop 0.32).", low=0, high=16, paper=0),
    Setting("patch_levels", 4, "int",
            "Pyramid levels whose 5x5 patch distributions (quantiles of their projections on fixed "
            "random directions) are learned for the patch refinement (:mod:`tghop.patch_refine`, ours; "
            "0: none stored).", low=0, high=6, paper=0),
    Setting("patch_whitening", 0.0, "float",
            "The patch refinement's directions are drawn in patch space whitened to this power "
            "(0: uniform random directions; 0.5: uniform in whitened space, where edges and grain "
            "weigh as much as a patch's mean). 0.35: sharper edges, colour patches less exact "
            "(docs/choices.md; :mod:`tghop.patch_refine`).", low=0, high=1),
    Setting("layout_factor", 3, "int",
            "Coarse to fine (ours, :mod:`tghop.layout`): also model the layout on the exemplar "
            "downsampled by this factor, and quilt guided by a coarse synthesis (None: off). An exemplar "
            "smaller than 48 times the factor gets the largest smaller one it allows (at least 2), or none.",
            low=2, high=16, none_ok=True,
            cli=("--layout",), paper=None),
    Setting("scale", 1.0, "float",
            "Working scale (ours, :mod:`tghop.scale`): the exemplar is resampled by this factor before "
            "anything is learned, so every output is a texture at that scale (0.5: elements half as large "
            "in pixels). Below 1 for photographs whose elements are larger than about 100 pixels, which "
            "the patches cannot hold whole at 1.", low=0, low_open=True, high=4, paper=1.0),
    Setting("rng", None, "rng", "Randomness of fitting (patch subsampling, K-means, FastICA); model files "
            "record an int seed, and a Generator as the fit began (0.58: a loaded model's rng then refits it).",
            cli=("--fit-seed",)),
    # ---------------------------------------------------------------- generation time
    Setting("n_patches", 5000, "int", "Generated patches quilted into each image (paper: 5,000-10,000).",
            when="generate", low=1, high=10_000_000, cli=("--pool",), cli_high=200_000),
    Setting("tile", False, "bool", "Make the output wrap around seamlessly (tileable; under 94 px a side at layout "
            "factor 3, 63 at 2, without the layout's guide: tghop.layout.guide_fits).", when="generate"),
    Setting("overlap", None, "int", "Quilting overlap in pixels (None: patch_size / 6, rounded: 5 at 32, 11 at 64).",
            when="generate", low=1, none_ok=True),
    Setting("tolerance", 0.1, "float",
            "Quilting picks among pool patches within (1 + tolerance) of the best match.",
            when="generate", low=0, high=1e6),
    Setting("detail", 0.8, "float",
            "Quilting chooses only among the near-best candidates whose gradient energy is at or above "
            "this quantile of theirs, against the overlap error's preference for smooth patches (ours; "
            "0: the paper's uniform choice).", when="generate", low=0, high=1, high_open=True, paper=0.0),
    Setting("flat_share", 0.25, "float",
            "Quilting counts the errors of this share of the pool, its flattest patches by gradient energy, "
            "twice: generated patches are blurrier than the exemplar's and the overlap error prefers them, "
            "which leaves smeared blocks (ours; 0: off, the paper's rule).",
            when="generate", low=0, high=1, high_open=True, paper=0.0),
    Setting("match_colours", True, "bool",
            "Match each channel's histogram to the exemplar's after the refinement, where the patch "
            "refinement does not follow (it matches the colours with the patches; ours; False: the "
            "paper's pipeline).", when="generate", paper=False),
    Setting("layout_weight", 3.0, "float",
            "Weight of the coarse layout's guide in quilting, per pixel relative to the overlap error "
            "(models fitted with a layout factor; 0 ignores the guide, as the paper's quilting).",
            when="generate", low=0, high=1e6, paper=0.0),
    Setting("refine", 5, "int",
            "Rounds of multi-scale histogram matching after quilting (Heeger-Bergen style, ours; "
            ":mod:`tghop.refine`; each but the last over-relaxed): restores the contrast of fine detail; "
            "0 is off, as in the paper.",
            when="generate", low=0, high=20, paper=0),
    Setting("patch_refine", None, "int",
            "Adam steps per pyramid level of sliced Wasserstein matching of the image's 5x5 patches to "
            "the exemplar's, the last step (ours, :mod:`tghop.patch_refine`; models fitted with "
            "patch_levels; 0: off). auto (None in Python): 52 on images of up to 512x512 pixels, 24 on "
            "images of up to 1024x1024, then fewer in proportion to the pixels (15 at 1280x1280), none on "
            "larger ones (the cost grows with the image; give a number to refine them too).",
            when="generate", low=0, high=500, none_ok=True, auto=True, paper=0),
    Setting("patch_stride", 2, "int",
            "The patch refinement's steps take every patch_stride-th patch each way at each level, "
            "the grid shifted every step (larger images take more, levels of up to 8,192 pixels every "
            "patch; :mod:`tghop.patch_refine`).",
            when="generate", low=1, high=5),  # at most the patch side
    Setting("reuse", 1.0, "float",
            "Quilting multiplies the error of a pool patch already placed u times by (1 + reuse * u), "
            "against repeating the same patches in large images (ours; not applied where there are 8 "
            "pool patches per block or more, e.g. 256x256; 0: the paper's rule).",
            when="generate", low=0, high=1e6, paper=0.0),
    Setting("pool_per_block", 1.5, "float",
            "Grow the pool to this many patches per quilted block when that is more than n_patches, up "
            "to 30,000 (ours, for large images; 0: the pool is n_patches).", when="generate", low=0,
            high=1e6, paper=0.0),
    Setting("seam_window", 9, "int",
            "Remove the steps in tone and colour across quilting seams by gradient-domain stitching "
            "(ours, :mod:`tghop.seams`): each seam edge's step is averaged over the seam edges within "
            "a square of this side (1: each on its own, no grid left but smoother seams; 0: off, the "
            "paper's plain minimum-error cuts).", when="generate", low=0, high=255, paper=0),
    Setting("region", 1024, "int",
            "Refine and colour-match images larger than about 1.5 times this side region by region, "
            "cross-faded (ours, :mod:`tghop.regions`): every part of a large image keeps the "
            "exemplar's statistics (None: the whole image at once, as up to tghop 0.16).",
            when="generate", low=256, none_ok=True, paper=None),
    Setting("own_shares", 1.0, "float",
            "How far the histograms the refinement and the colour matching give an image follow its own "
            "shares of the exemplar's colour classes rather than the exemplar's, times how distinct the "
            "classes are, and only as far as the exemplar's own crops vary (ours; models fitted with "
            "colour_classes): forcing the exemplar's shares turns the extra pixels of a colour the image "
            "has too much of into flecks of another; 0: the exemplar's histograms, as up to tghop 0.32.",
            when="generate", low=0, high=1, paper=0.0),
    Setting("layout_refine", 3, "int",
            "Rounds of the refinement after quilting (as ``refine``) of the coarse layout's guide "
            "(models fitted with a layout factor).", when="generate", low=0, high=20),
    Setting("layout_patch_refine", None, "int",
            "Steps per pyramid level of the patch refinement (as patch_refine, every patch) of the coarse "
            "layout's guide, after its refinement: the coarse image's patches take the downsampled "
            "exemplar's statistics, so the fine level follows sharper large shapes (ours; models fitted "
            "by tghop 0.48 or newer; 0: off). auto (None in Python): 20 on images of up to 512x512 "
            "pixels, none on larger ones (tghop.layout.guide_steps).",
            when="generate", low=0, high=500, none_ok=True, auto=True),
)

BY_NAME = {s.name: s for s in SETTINGS}


def fit_settings():
    """Settings that are constructor parameters of TGHop (stored in model files).

    Returns
    -------
    list of Setting
        In :data:`SETTINGS`' order (the constructor's).
    """
    return [s for s in SETTINGS if s.when == "fit"]


def generate_settings():
    """Settings that are keywords of ``TGHop.synthesize``.

    Returns
    -------
    list of Setting
        In :data:`SETTINGS`' order.
    """
    return [s for s in SETTINGS if s.when == "generate"]


#: The paper's pipeline (Table 4 on brick_wall, no colour matching): the ``paper`` values.
PAPER = {s.name: s.paper for s in SETTINGS if s.has_paper}

#: Generation presets (``tghop synth --quality``): settings that differ from the defaults.
#: "best" takes 90 Adam steps per level of the patch refinement, every patch at full
#: resolution, at any size (its cost and gain against the default's steps at stride 2:
#: docs/choices.md, "Patch refinement", "0.26").
QUALITY = {"default": {}, "best": {"patch_refine": 90, "patch_stride": 1}}


def check_settings(values: dict, *, prefix: str = "") -> dict:
    """Check every ``name: value`` against the table; unknown names are refused.

    Parameters
    ----------
    values : dict
        Setting name -> value (fit or generation settings, any subset).
    prefix : str
        Put before each name in messages (``"setting "``: ``setting 'x'``).

    Returns
    -------
    dict
        The same names, each value normalised by :meth:`Setting.check`.

    Raises
    ------
    TGHopError
        One line for the first unknown name or bad value.
    """
    out = {}
    for name, value in values.items():
        if name not in BY_NAME:
            raise TGHopError(f"unknown {prefix or 'setting '}{name!r}")  # not "unknown setting setting 'x'"
        out[name] = BY_NAME[name].check(value, label=prefix + name)
    return out


#: Settings added after model files had them fixed otherwise: a file without one was fitted
#: with this value, not the default.
BEFORE_ADDED = {"max_component_ratio": 1.0, "norm_match": 0.0, "coupling": 0.0, "colour_classes": 0}


def file_settings(params: dict) -> dict:
    """The checked constructor settings of a model file's metadata ``params`` (a JSON
    object): lists back to tuples, :data:`BEFORE_ADDED` for settings it predates, and
    ``rng`` the fit's seed where one was recorded (None in files before 0.33, and for a
    Generator).

    Parameters
    ----------
    params : dict
        The constructor settings a model file records (JSON values: lists for tuples,
        whole floats such as 2.0 from files before they were refused).

    Returns
    -------
    dict
        Setting name -> checked value (:func:`check_settings`), with the settings the file
        predates at their :data:`BEFORE_ADDED` value.

    Raises
    ------
    TGHopError
        One line naming an unknown or bad setting (``setting 'x' ...``).
    """
    params = {**BEFORE_ADDED, **params}
    for name, value in params.items():  # files written before whole floats (2.0) were refused
        if (name in BY_NAME and BY_NAME[name].kind == "int" and isinstance(value, float) and math.isfinite(value)
                and value.is_integer()):
            params[name] = int(value)
    params["rng"] = recorded_seed(params.get("rng"))
    if params.get("n_channels") is not None:
        params["n_channels"] = tuple(params["n_channels"])
    return check_settings(params, prefix="setting ")


def component_params(estimator, component: str) -> dict:
    """The constructor arguments of fitted component ``component`` ("ichm", "sdr").

    Parameters
    ----------
    estimator : TGHop
        Its fit settings are read (the attributes of the settings whose ``target`` names
        ``component``).
    component : str
        ``"ichm"`` or ``"sdr"``.

    Returns
    -------
    dict
        The component's parameter name (the target's part after the dot, else the
        setting's name) -> the estimator's value.
    """
    out = {}
    for s in fit_settings():
        if s.target and s.target.split(".")[0] == component:
            out[s.target.split(".", 1)[1] if "." in s.target else s.name] = getattr(estimator, s.name)
    return out


def numpydoc_parameters(settings, indent: str = "    ") -> str:
    """The "Parameters" entries of ``settings`` in numpydoc form.

    Parameters
    ----------
    settings : iterable of Setting
        In the order to list them.
    indent : str
        One level of indentation: the name line gets one, its help (wrapped at 88
        characters) two.

    Returns
    -------
    str
        ``name : type`` lines (:meth:`Setting.doc_type`) each followed by its help, without
        the section's heading.
    """
    import textwrap

    lines = []
    for s in settings:
        lines.append(f"{indent}{s.name} : {s.doc_type()}")
        lines.extend(textwrap.wrap(s.help, 88, initial_indent=indent * 2, subsequent_indent=indent * 2))
    return "\n".join(lines)
