"""All metrics at once: the table of metrics (:data:`METRICS`), the size check before any
work, and :func:`evaluate` (``tghop evaluate``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._errors import InvalidImageError, MissingExtraError, TGHopError
from .._images import MAX_PIXELS, check_texture
from .._random_cnn import USTYUZHANINOV_SCALES
from .common import pair
from .copies import copied, copied_textured, novelty, self_repetition
from .distributions import cooccurrence_distance, sliced_wasserstein
from .networks import gram_distance, sifid

__all__ = ["MetricInfo", "METRICS", "RESULT_METRICS", "DIVERSITY_MIN_SIZE", "check_sizes", "Scores", "evaluate"]

# ---------------------------------------------------------------------------------------
# All at once
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MetricInfo:
    """A metric of :func:`evaluate`: its function, direction and optional dependency."""

    function: Callable[..., float]
    higher_is_better: bool
    needs_torch: bool
    description: str
    #: Smallest height and width (pixels) it accepts with its default options.
    min_size: int = 1


#: name -> :class:`MetricInfo`, in the order :func:`evaluate` reports them.
METRICS = {
    "sifid": MetricInfo(sifid, False, True, "single-image FID, InceptionV3 first-pool features", 16),
    "gram": MetricInfo(gram_distance, False, True, "relative Gram distance, random multiscale CNN",
                       2 * min(USTYUZHANINOV_SCALES)),
    "swd": MetricInfo(sliced_wasserstein, False, False, "sliced Wasserstein distance of 7x7 patches, 3 scales", 7 * 4),
    "cooccurrence": MetricInfo(cooccurrence_distance, False, False, "L1 of soft colour co-occurrences"),
    "novelty": MetricInfo(novelty, True, False, "RMS distance to the nearest exemplar patch (higher: more novel)", 8),
    "copied": MetricInfo(copied, False, False, "fraction of 16x16 patches within RMSE 0.03 of an exemplar patch",
                         16),
    "copied_textured": MetricInfo(copied_textured, False, False,
                                  "copied, over the result's textured 16x16 windows only (std >= 0.06)", 16),
}


def _result_self_repetition(exemplar, result, *, progress=None) -> float:
    """:func:`self_repetition` of the result; the exemplar is not looked at."""
    return self_repetition(result, progress=progress)


#: Metrics of the result alone (no comparison with the exemplar), computed by
#: :func:`evaluate` only when named: name -> :class:`MetricInfo` (its function takes
#: ``(exemplar, result)`` like the others and ignores the exemplar).
RESULT_METRICS = {
    "self_repetition": MetricInfo(_result_self_repetition, False, False,
                                  "fraction of the result's textured 16x16 windows that recur elsewhere in it", 16),
}

#: Smallest side :func:`diversity` accepts with its default patch size.
DIVERSITY_MIN_SIZE = 8


def _metric_names(metrics) -> list:
    """The chosen metric names (all for None), or a one-line :class:`TGHopError`."""
    if metrics is None:
        return list(METRICS)
    if isinstance(metrics, str):
        metrics = [metrics]
    names = [str(m) for m in metrics]
    known = [*METRICS, *RESULT_METRICS]
    if not names:
        raise TGHopError(f"no metrics chosen; choose one or more of {', '.join(known)}")
    unknown = [m for m in names if m not in known]
    if unknown:
        raise TGHopError(f"unknown metric {unknown[0]!r}; choose from {', '.join(known)}")
    return names


def _info(name: str) -> MetricInfo:
    return METRICS[name] if name in METRICS else RESULT_METRICS[name]


def check_sizes(shapes, metrics=None, *, diversity: bool = False, exemplar: str | None = "exemplar") -> None:
    """Check image sizes for :func:`evaluate` before any work; a one-line :class:`TGHopError` if not.

    Parameters
    ----------
    shapes : dict of str to tuple
        ``name -> shape`` of each image (``"exemplar"``, ``"result"``, or file names).
    metrics : sequence of str, optional
        The metrics that will be computed (default all).
    diversity : bool
        Whether :func:`diversity` will be computed too (of the results alone).
    exemplar : str or None
        The name in ``shapes`` of the exemplar (None: none of them is), held only to the
        sizes of the chosen metrics that compare with it (:data:`METRICS`): those of
        :data:`RESULT_METRICS` (``self_repetition``) and diversity look at the results alone,
        so with them alone any exemplar size will do.

    Raises
    ------
    InvalidImageError
        If an image is not of shape (H, W) or (H, W, C), has more than
        :data:`~tghop._images.MAX_PIXELS` pixels (8192 x 8192), or is smaller than a chosen
        metric needs (saying how large it must be).
    """
    names = _metric_names(metrics)
    needs = [(_info(n).min_size, n) for n in names]
    if diversity:
        needs.append((DIVERSITY_MIN_SIZE, "diversity"))
    exemplar_needs = [(METRICS[n].min_size, n) for n in names if n in METRICS]
    for name, shape in shapes.items():
        need, which = max(exemplar_needs, default=(1, None)) if name == exemplar else max(needs)
        if len(shape) not in (2, 3):
            raise InvalidImageError(f"{name} must have shape (H, W) or (H, W, C), got {tuple(shape)}")
        h, w = int(shape[0]), int(shape[1])
        if h * w > MAX_PIXELS:
            side = math.isqrt(MAX_PIXELS)
            raise InvalidImageError(
                f"{name} is {h}x{w} = {h * w:,} pixels, above the {MAX_PIXELS:,} ({side}x{side}) that evaluation "
                "supports; crop or downscale it"
            )
        if h < need or w < need:
            raise InvalidImageError(
                f"{name} is {h}x{w} pixels but {which} needs at least {need}x{need}; "
                f"give images of at least {need}x{need} pixels or leave {which} out of the metrics"
            )


class Scores(dict):
    """``name -> value`` of the metrics :func:`evaluate` computed, plus what it skipped.

    Attributes
    ----------
    skipped : dict of str to str
        Metrics left out and why (e.g. PyTorch missing), each a one-line message.
    """

    def __init__(self, *args, skipped=None, **kwargs):
        super().__init__(*args, **kwargs)
        self.skipped = dict(skipped or {})


def evaluate(exemplar, result, *, metrics=None, repetition: bool = False, progress=None) -> Scores:
    """Compute several metrics of one result against its exemplar.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C)
        Float in [0, 1], or uint8 / uint16 (scored as x / 255, x / 65535); sizes may differ.
    metrics : sequence of str, optional
        Names from :data:`METRICS` (``sifid``, ``gram``, ``swd``, ``cooccurrence``,
        ``novelty``, ``copied``, ``copied_textured``) or :data:`RESULT_METRICS`
        (``self_repetition``: of the result alone, never computed unless named).
        Default: all of :data:`METRICS`; then the PyTorch ones are *skipped* (recorded
        in ``Scores.skipped`` with the install hint) if PyTorch is missing. Metrics named
        explicitly are never skipped: a missing dependency raises
        :class:`MissingExtraError`. An empty sequence is refused.
    repetition : bool
        Also compute ``self_repetition`` of the result (as if named in ``metrics``; with
        ``metrics=None``, added to the default set, whose PyTorch metrics may still be
        skipped).
    progress : callable, optional
        ``progress(stage, done, total)``: one stage per metric, named after it, counting
        the pieces (strips, tiles, chunks or scales) it is computed in.

    Notes
    -----
    Every metric's memory is bounded whatever the image sizes (see each metric's Notes:
    images above 512 x 512 pixels are scored in strips or tiles, which gives the same
    value up to float rounding; the results of smaller images are unchanged). Images of
    more than :data:`~tghop._images.MAX_PIXELS` pixels (8192 x 8192) are refused, and so
    are images smaller than a chosen metric needs, before any work (:func:`check_sizes`).

    Returns
    -------
    Scores
        A dict ``name -> float`` in :data:`METRICS` then :data:`RESULT_METRICS` order,
        with a ``skipped`` attribute. Lower is better for all but ``novelty``.
    """
    explicit = metrics is not None
    names = _metric_names(metrics)
    if repetition and "self_repetition" not in names:
        names.append("self_repetition")
    shapes = {"exemplar": np.shape(exemplar), "result": np.shape(result)}
    if all(len(shape) >= 2 for shape in shapes.values()):  # before any copy of a huge array
        check_sizes(shapes, names)
    ex, res = pair(exemplar, result)
    check_sizes({"exemplar": ex.shape, "result": res.shape}, names)
    if any(name in METRICS for name in names):  # a flat exemplar: no statistics to compare (gram was 1e23)
        check_texture(ex, name="exemplar")
    scores = Scores()
    for name in [*METRICS, *RESULT_METRICS]:
        if name not in names:
            continue
        try:
            scores[name] = float(_info(name).function(ex, res, progress=progress))
        except MissingExtraError as exc:
            if explicit:
                raise
            scores.skipped[name] = str(exc)
    return scores
