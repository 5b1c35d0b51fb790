"""Texture quality metrics: how close a synthesised texture is to its exemplar, and how new.

Every fidelity metric is a function ``metric(exemplar, result, **options) -> float``
where both images are ``(H, W, C)`` or ``(H, W)`` arrays, float in [0, 1] or uint8 / uint16
(scored as x / 255 and x / 65535: an 8-bit image and its floats score alike; C = 1 or 3; a greyscale
image compared with a colour one is repeated to three channels, so a colour result is
fairly penalised for colour the exemplar does not have, and vice versa). The two images
may have different sizes: every metric compares distributions of local statistics, never
pixels at the same place. **Lower is better** for all of them, 0 for identical images:

========================  =================================================  =========
name                      what it compares                                   needs
========================  =================================================  =========
``sifid``                 InceptionV3 first-pool features (Shaham et al.)   PyTorch
``gram``                  Gram matrices of a random multiscale CNN           PyTorch
``swd``                   7 x 7 patch distributions at 3 scales              numpy
``cooccurrence``          soft colour co-occurrence (Darzi et al.)           numpy
========================  =================================================  =========

Two more say how *new* the results are, and **higher means more novel / diverse**:

* :func:`novelty` -- distance of the result's patches to their nearest exemplar patch
  (0 for a verbatim crop or for quilting the exemplar itself);
* :func:`diversity` -- the same nearest-patch distance between results of different seeds.

And two say how much of a result is *copied* (lower is better): :func:`copied`, the
fraction of the result's 16 x 16 patches that nearly equal some exemplar patch (1 for a
crop, about 0.4 for image quilting of the exemplar, 0 for a texture made anew), and
:func:`copied_textured`, the same over the result's textured windows only (a flat window
nearly equals any flat window). :func:`self_repetition` looks at the result alone: the
fraction of its textured windows that recur elsewhere in it (1 for a tiling of a crop).

:func:`evaluate` computes the fidelity metrics, novelty, copied and copied_textured at
once (``tghop evaluate``), and self_repetition of the result when named.
All metrics are deterministic: randomness (projections, sampled patches, filters,
k-means) comes from a fixed ``seed`` argument, so scores of different results computed
with the same seed are comparable. Compare a result with reference points of the same
texture (:mod:`tghop.baselines`: a crop, a blurred crop, colour noise) rather than by
absolute value: the scale of every metric depends on the texture. They disagree about
blur: on photographs SIFID, ``gram`` and ``cooccurrence`` rank even a slightly blurred
crop below colour noise (they weigh fine grain and exact colours heavily), while ``swd``
keeps blur between a crop and noise.
"""

from .._errors import MissingExtraError
from .common import PLAIN_MAX_PIXELS
from .copies import TEXTURED_STD, copied, copied_textured, diversity, novelty, self_repetition
from .distributions import cooccurrence_distance, sliced_wasserstein
from .evaluation import DIVERSITY_MIN_SIZE, METRICS, RESULT_METRICS, MetricInfo, Scores, check_sizes, evaluate
from .networks import GRAM_N_MAPS, GRAM_TILE, gram_distance, sifid

__all__ = [
    "MissingExtraError",
    "Scores",
    "MetricInfo",
    "METRICS",
    "RESULT_METRICS",
    "DIVERSITY_MIN_SIZE",
    "check_sizes",
    "GRAM_N_MAPS",
    "PLAIN_MAX_PIXELS",
    "GRAM_TILE",
    "sifid",
    "gram_distance",
    "sliced_wasserstein",
    "cooccurrence_distance",
    "novelty",
    "copied",
    "diversity",
    "evaluate",
    "TEXTURED_STD",
    "copied_textured",
    "self_repetition",
]
