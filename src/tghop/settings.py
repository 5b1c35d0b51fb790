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

Nothing here imports scikit-learn or SciPy.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Any, Optional, Tuple

from ._errors import TGHopError

__all__ = ["Setting", "SETTINGS", "BY_NAME", "PAPER", "QUALITY", "fit_settings", "generate_settings", "check_settings",
           "component_params", "numpydoc_parameters", "check_channel_rule", "recorded_seed", "fit_seed",
           "generator_record", "generator_from_record", "generators_given", "generator_records", "set_generators"]

_MISSING = object()


def _number(value) -> str:
    """A bound as people write it: 10,000,000 rather than 1e+07; 0.5 stays 0.5."""
    if float(value).is_integer() and abs(value) >= 1000:
        return f"{int(value):,}"
    return f"{value:g}"


@dataclass(frozen=True)
class Setting:
    """One setting of TGHop.

    Parameters
    ----------
    name : str
        Python name: a ``TGHop`` constructor parameter (fit) or ``synthesize`` keyword
        (generate).
    default : object
    kind : {"int", "float", "bool", "choice", "channels", "rng"}
    help : str
        One or two sentences; used for the docstring and ``--help``.
    when : {"fit", "generate"}
        "fit": part of the model (constructor parameter, stored in model files, needs a
        refit to change). "generate": a ``synthesize`` keyword, given per call.
    low, high : float, optional
        Allowed range (inclusive unless ``low_open`` / ``high_open``).
    low_open, high_open : bool
        The bound itself is not allowed.
    none_ok : bool
        None is allowed (meaning "off" or "automatic", see the help).
    auto : bool
        None means "automatic": the command line's word for it is ``auto`` (else ``none``
        or ``off``).
    choices : tuple
        Allowed values of a "choice" setting.
    cli : tuple of str or None
        Command-line option names; ``()`` gives ``--name-with-dashes``; None keeps the
        setting off the command line (or handled specially there, as ``n_channels``).
    cli_high : float, optional
        A tighter upper bound on the command line only.
    paper : object, optional
        Value under ``--paper`` (the paper's Table 4 setting) where it differs from or
        pins the default.
    target : str, optional
        ``"ichm"`` or ``"sdr"`` (same parameter name) or ``"ichm.max_iter"``: the
        fitted component that receives this setting.
    """

    name: str
    default: Any
    kind: str
    help: str
    when: str = "fit"
    low: Optional[float] = None
    high: Optional[float] = None
    low_open: bool = False
    high_open: bool = False
    none_ok: bool = False
    auto: bool = False
    choices: Tuple = ()
    cli: Optional[Tuple[str, ...]] = ()
    cli_high: Optional[float] = None
    paper: Any = field(default=_MISSING)
    target: Optional[str] = None

    # ------------------------------------------------------------ checking
    @property
    def has_paper(self) -> bool:
        return self.paper is not _MISSING

    def range_text(self, *, cli: bool = False, json: bool = False) -> str:
        """The values the setting takes, in words; ``cli``: None as the command line writes it,
        ``json``: as JSON does (``null``).

        Parameters
        ----------
        cli : bool
            Name None ``auto`` or ``none``, as the command line takes it.
        json : bool
            Name None ``null`` (when not ``cli``).

        Returns
        -------
        str
            E.g. ``"an integer >= 1 or None"``, ``"one of 'a', 'b'"``.
        """
        if self.kind == "choice":
            return "one of " + ", ".join(repr(c) for c in self.choices)
        parts = []
        if self.low is not None:
            parts.append(f"{'>' if self.low_open else '>='} {_number(self.low)}")
        if self.high is not None:
            parts.append(f"{'<' if self.high_open else '<='} {_number(self.high)}")
        noun = {"int": "an integer", "float": "a finite number", "bool": "True or False"}.get(self.kind, "")
        text = noun + (" " + " and ".join(parts) if parts else "")
        none = ("auto" if self.auto else "none") if cli else "null" if json else "None"
        return text + (f" or {none}" if self.none_ok else "")

    def check(self, value, *, label=None, cli=False, json=False):
        """Return ``value`` (normalised) or raise a one-line :class:`TGHopError`; an ``"int"``
        setting takes integers only (Python or NumPy, not a float such as 2.0); ``cli``: the
        message names None as the command line writes it (``auto`` or ``none``), ``json`` as
        JSON does (``null``).

        Parameters
        ----------
        value : object
            The value given.
        label : str, optional
            The name in the message (default the setting's name).
        cli, json : bool
            How the message writes None (:meth:`range_text`).

        Returns
        -------
        object
            ``value`` normalised: an ``int`` or ``float`` for numbers, ``bool``, a tuple of
            rules for ``"channels"``, None where allowed; an ``"rng"`` setting's value as given.
        """
        label = label or self.name
        words = self.range_text(cli=cli, json=json)
        if self.kind == "rng":
            return value  # checked where it is used (check_rng)
        if value is None:
            if self.none_ok:
                return None
            raise TGHopError(f"{label} must be {words}, got {'null' if json else None}")
        if self.kind == "channels":
            return _check_channels(value, label)
        if self.kind == "choice":
            if value not in self.choices:
                raise TGHopError(f"{label} must be {words}, got {value!r}")
            return value
        if self.kind == "bool":
            if type(value).__name__ not in ("bool", "bool_") and not (
                    isinstance(value, numbers.Integral) and value in (0, 1)):
                raise TGHopError(f"{label} must be True or False, got {value!r}")
            return bool(value)
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise TGHopError(f"{label} must be {words}, got {value!r}")
        if self.kind == "int":
            if not isinstance(value, numbers.Integral):  # 2.0 too, as the server and the other entry points
                whole = math.isfinite(value) and float(value).is_integer()
                raise TGHopError(f"{label} must be {words}, got {value!r}"
                                 + (f"; write {int(value)}" if whole else ""))
            value = int(value)
        else:
            value = float(value)
            if not math.isfinite(value):
                raise TGHopError(f"{label} must be {words}, got {value!r}")
        bad_low = self.low is not None and (value <= self.low if self.low_open else value < self.low)
        bad_high = self.high is not None and (value >= self.high if self.high_open else value > self.high)
        if bad_low or bad_high:
            raise TGHopError(f"{label} must be {words}, got {value!r}")
        return value

    def parse(self, text: str):
        """A command-line string -> value (then :meth:`check`); raises TGHopError, whose line names
        the word for None where the setting takes it (``'abc' is not an integer (or auto)``).

        Parameters
        ----------
        text : str
            An option's value (spaces around ignored); ``auto`` (or ``none``, ``off``) is
            None where the setting takes None.

        Returns
        -------
        int, float, object or None
            The value, not yet checked against the range (:meth:`check`); a ``"choice"``
            setting's choice whose text is ``text``.
        """
        text = str(text).strip()
        if self.none_ok and text.lower() in (("auto",) if self.auto else ("none", "off")):
            return None
        word = f" (or {'auto' if self.auto else 'none'})" if self.none_ok else ""
        if self.kind == "int":
            try:
                return int(text)
            except ValueError:
                raise TGHopError(f"{text!r} is not an integer{word}") from None
        if self.kind == "float":
            try:
                return float(text)
            except ValueError:
                raise TGHopError(f"{text!r} is not a number{word}") from None
        if self.kind == "choice":
            for c in self.choices:
                if str(c) == text:
                    return c
            raise TGHopError(f"{text!r} is not {self.range_text()}")
        raise TGHopError(f"{self.name} cannot be parsed from text")

    # ------------------------------------------------------------ presentation
    @property
    def option_names(self) -> Tuple[str, ...]:
        if self.cli is None:
            return ()
        return self.cli or ("--" + self.name.replace("_", "-"),)

    def doc_type(self) -> str:
        """The setting's type line in numpydoc form.

        Returns
        -------
        str
            E.g. ``"int, default=32"``, ``"float or None, default=None"``; the ``rng``
            setting's without a default.
        """
        kinds = {"int": "int", "float": "float", "bool": "bool", "channels": "sequence or None",
                 "rng": "int or numpy.random.Generator, optional",
                 "choice": "{" + ", ".join(repr(c) for c in self.choices) + "}"}
        text = kinds[self.kind]
        if self.kind == "rng":
            return text
        if self.none_ok and self.kind != "channels":
            text += " or None"
        return f"{text}, default={self.default!r}"


def check_channel_rule(rule, name: str = "channel count", *, none_ok: bool = False):
    """One hop's channel rule: an int count >= 1, a fraction in (0, 1], or "knee".

    The one check of a channel rule (the settings table, :mod:`tghop.saab` and the
    command line's ``--k1``/``--k2``/``--k3`` call it). ``none_ok``: None ("keep every
    non-empty channel") is allowed too.

    Parameters
    ----------
    rule : int, float, str or None
        The rule given.
    name : str
        What the message calls it (``"n_channels: K1"``).
    none_ok : bool
        Allow None.

    Returns
    -------
    int, float, str or None
        ``rule`` as an ``int`` count, a ``float`` fraction, ``"knee"`` or None.

    Raises
    ------
    TGHopError
        One line naming ``name`` and the rules allowed.
    """
    if rule is None and none_ok:
        return None
    if isinstance(rule, str) and rule == "knee":
        return rule
    if isinstance(rule, numbers.Integral) and not isinstance(rule, bool):
        if rule < 1:
            raise TGHopError(f"{name} must be at least 1 (or a fraction in (0, 1], or 'knee'), got {rule}")
        return int(rule)
    if isinstance(rule, numbers.Real) and not isinstance(rule, bool) and 0.0 < rule <= 1.0:
        return float(rule)
    raise TGHopError(f"{name} must be an integer >= 1, a fraction in (0, 1] or 'knee', got {rule!r}")


def _check_channels(value, label):
    """A sequence of per-hop rules (:func:`check_channel_rule`)."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise TGHopError(f"{label} must be a sequence of per-hop rules, e.g. (9, 22), got {value!r}")
    rules = tuple(value)
    if not rules:
        raise TGHopError(f"{label} must name at least one hop, got {value!r}")
    return tuple(check_channel_rule(rule, f"{label}: K{i}") for i, rule in enumerate(rules, start=1))


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


def recorded_seed(rng):
    """What a model file records of the fit's ``rng``: an int seed as it is, anything else
    (a Generator, None: no seed to give again) as None.

    Parameters
    ----------
    rng : int, numpy.random.Generator or None
        A ``rng`` argument as given to ``TGHop``.

    Returns
    -------
    int or None
        ``rng`` as an int where it is an integer >= 0 (a NumPy integer too), else None.
    """
    if isinstance(rng, numbers.Integral) and not isinstance(rng, bool) and rng >= 0:
        return int(rng)
    return None


def fit_seed(model):
    """:func:`recorded_seed` of the ``rng`` a fitted model was fitted with (its ``rng`` now may
    have been changed by ``set_params`` since, which changes nothing learned).

    Parameters
    ----------
    model : TGHop
        A fitted (or loaded) model.

    Returns
    -------
    int or None
        The seed the model was fitted with, or None (fitted from a Generator or None).
    """
    return recorded_seed(vars(model).get("_fitted_params", {}).get("rng", model.rng))


#: The bit generators whose state a model file may record (:func:`generator_record`): NumPy's own.
BIT_GENERATORS = ("PCG64", "PCG64DXSM", "MT19937", "Philox", "SFC64")


def generator_record(rng):
    """A fitted part's ``rng`` as a model file records it (JSON data): a Generator as its bit
    generator's name, its seed where :func:`tghop._estimator.generator_text` shows one, and its state;
    anything else (an int seed, None) as None (an int seed is in the settings already).

    Parameters
    ----------
    rng : numpy.random.Generator, int or None
        A fitted part's copy of the fit's generator, as it was before the part's fit.

    Returns
    -------
    dict or None
        ``{"bit_generator": name, "seed": int or None, "state": ...}`` (arrays in the state as
        ``{"dtype": ..., "values": [...]}``), or None.
    """
    import numpy as np  # here: the command line reads this table without NumPy

    if not isinstance(rng, np.random.Generator) or type(rng.bit_generator).__name__ not in BIT_GENERATORS:
        return None
    bits = rng.bit_generator
    seeds = getattr(bits, "seed_seq", None)
    entropy = getattr(seeds, "entropy", None)
    seed = entropy if isinstance(entropy, int) and 0 <= entropy < 2**64 and not tuple(
        getattr(seeds, "spawn_key", ())) else None

    def data(value):
        if isinstance(value, dict):
            return {k: data(v) for k, v in value.items()}
        if isinstance(value, np.ndarray):
            return {"dtype": value.dtype.str, "values": value.tolist()}
        return value.item() if isinstance(value, np.generic) else value

    return {"bit_generator": type(bits).__name__, "seed": seed, "state": data(bits.state)}


def generator_from_record(record, what: str = "rng"):
    """The Generator of :func:`generator_record`'s ``record`` (None: None), in the state it records.

    Parameters
    ----------
    record : dict or None
        As :func:`generator_record` made it (read from a model file's metadata).
    what : str
        How the record is named in the error message.

    Returns
    -------
    numpy.random.Generator or None

    Raises
    ------
    TGHopError
        A record that is not one (another bit generator, a state NumPy does not take).
    """
    import numpy as np

    if record is None:
        return None
    if not isinstance(record, dict) or set(record) != {"bit_generator", "seed", "state"} or \
            record["bit_generator"] not in BIT_GENERATORS or not isinstance(record["state"], dict):
        raise TGHopError(f"the metadata's {what} is not a generator's record (bit_generator, seed, state)")

    def value(v):
        if isinstance(v, dict) and set(v) == {"dtype", "values"}:
            return np.asarray(v["values"], dtype=np.dtype(v["dtype"]))
        return {k: value(x) for k, x in v.items()} if isinstance(v, dict) else v

    try:
        kind = getattr(np.random, record["bit_generator"])
        seed = record["seed"]
        bits = kind(np.random.SeedSequence(seed) if isinstance(seed, int) and not isinstance(seed, bool) else None)
        bits.state = value(record["state"])
    except (TypeError, ValueError, KeyError, OverflowError) as exc:
        raise TGHopError(f"the metadata's {what} holds a state NumPy does not take ({exc})") from None
    return np.random.Generator(bits)


def generators_given(estimator) -> dict:
    """Copies of the Generators among ``estimator``'s own parameters as they are now (``rng``; a
    Material's ``model__rng`` too): what a fit that starts now draws from, kept in its
    ``_fitted_params`` so that :func:`generator_records` writes them to the model file (0.58).

    Parameters
    ----------
    estimator : TGHop or Material

    Returns
    -------
    dict
        Parameter name (as ``get_params(deep=True)`` names it) -> a copy of its Generator.
    """
    import copy

    import numpy as np

    return {name: copy.deepcopy(value) for name, value in estimator.get_params(deep=True).items()
            if name.split("__")[-1] == "rng" and isinstance(value, np.random.Generator)}


def generator_records(fitted) -> dict:
    """What a model file records of the Generators a fit started from (0.58; ``fit_rngs``): each of a
    fitted estimator's own ``rng`` settings (its ``_fitted_params``: ``rng``, a Material's ``model__rng``)
    that was a Generator, as :func:`generator_record` makes it, as it was when the fit began. Its parts'
    copies (``ichm_rng``, ...) are recorded by them.

    Parameters
    ----------
    fitted : dict or None
        The estimator's ``_fitted_params``.

    Returns
    -------
    dict
        Parameter name -> record; empty where none was a Generator (an int seed: in the settings).
    """
    out = {}
    for name, value in (fitted or {}).items():
        record = generator_record(value) if "." not in name and name.split("__")[-1] == "rng" else None
        if record is not None:
            out[name] = record
    return out


def set_generators(estimator, records, what: str = "fit_rngs") -> dict:
    """Give a loaded ``estimator`` the Generators a model file records for its ``rng`` settings
    (:func:`generator_records`' ``records``; None: none recorded), each in the state its fit began in,
    so that ``clone(loaded).fit(x)`` fits it again as it was fitted.

    Parameters
    ----------
    estimator : TGHop or Material
        Loaded, not yet given its ``_fitted_params``.
    records : dict or None
    what : str
        How the records are named in an error.

    Returns
    -------
    dict
        Parameter name -> a copy of the Generator set, for the estimator's ``_fitted_params``.

    Raises
    ------
    TGHopError
        Records that are not a dict of ``rng`` settings' generator records.
    """
    import copy

    if records is None:
        return {}
    params = estimator.get_params(deep=True)
    if not isinstance(records, dict) or not all(isinstance(n, str) and n in params and n.split("__")[-1] == "rng"
                                                for n in records):
        raise TGHopError(f"the metadata's {what} is not a record of the estimator's rng settings")
    given = {name: generator_from_record(record, f"{what}[{name!r}]") for name, record in records.items()}
    estimator.set_params(**given)
    return {name: copy.deepcopy(value) for name, value in given.items()}


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
