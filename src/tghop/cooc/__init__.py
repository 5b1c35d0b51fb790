"""Co-occurrence based texture synthesis (Darzi et al.): a conditional GAN and its controls.

After A. Darzi, I. Lang, A. Taklikar, H. Averbuch-Elor, S. Avidan, "Co-occurrence based
texture synthesis" (``../shared/papers/003_db2109f0a38f9c15.txt``). A texture is
described locally by soft colour co-occurrence matrices; a generator turns a grid of
them (a *co-occurrence tensor*) plus noise into texture, so the user controls the local
statistics: morph between two textures by interpolating their tensors, walk through
variations by interpolating the noise, paint statistics where they are wanted.

Co-occurrence (NumPy or PyTorch; in :mod:`tghop.cooccurrence`, re-exported here; this is
also what :func:`tghop.metrics.cooccurrence_distance` measures, with the same functions):

* :func:`fit_colour_clusters` -- k-means colour centres ``tau_l`` and per-cluster,
  per-channel spreads ``sigma_l`` (Eq. 2);
* :func:`soft_assign` -- ``K(I_p, tau_l)`` for every pixel and cluster (Eq. 2);
* :func:`cooccurrence_matrix` -- one ``k x k`` matrix of a whole image (Eq. 1);
* :func:`cooccurrence_tensor` -- a matrix per pixel over a patch around it, row-stacked
  to ``k*k`` channels and average-pooled by ``s`` (Sec. 3): ``(k*k, H/s, W/s)``.

All are vectorised (separable convolutions and integral images) and, on tensors,
differentiable -- the generator is trained through them.

The cGAN (needs PyTorch: ``pip install 'tghop[metrics]'``):

* :class:`CoocGAN` -- ``fit(exemplar)`` trains it (WGAN-GP plus the paper's co-occurrence
  consistency loss); ``sample``, ``generate``, ``morph_strip``, ``morph_grid`` and
  :func:`paint_condition` and :func:`boost_condition` are the controls; ``save`` / :func:`load` write and read a
  ``.pt`` checkpoint of tensors only (JSON settings inside), and ``fit(..., resume=True)``
  continues a loaded one.
* ``sample`` quilts generated training-size crops by default (``assembly="quilt"``,
  :meth:`CoocGAN.crop_pool` and :func:`tghop.quilting.quilt`; ours: the generator never
  runs at a size it was not trained at); ``assembly="pass"`` is the paper's one pass.
* ``generate(..., windows=True)`` (:meth:`CoocGAN.generate_windows`) generates a large
  condition in overlapping training-size windows, and ``tiles=2`` trains the generator on
  2 x 2 training crops at once; both are options (docs/choices.md: neither was clearly
  better on the small configuration).
* ``ema`` keeps an exponential moving average of the generator's weights while training
  and generates with it (:data:`SMALL`: on; :data:`PAPER`: off, as the paper).
* :data:`SMALL` (the default: made to train on a 2-core CPU) and :data:`PAPER` (the
  paper's setting, for a GPU) are the two configurations; ``CoocGAN(**PAPER)`` selects
  the latter.

The modules, in the order data flows through them (none imports this package's
``__init__``):

* :mod:`tghop.cooccurrence` (outside the package, shared with :mod:`tghop.metrics`) -- the
  co-occurrence statistics;
* :mod:`tghop.cooc.config` -- :data:`SMALL`, :data:`PAPER` and the check of the settings;
* :mod:`tghop.cooc.networks` -- the generator, the critic, the weight average, tiles;
* :mod:`tghop.cooc.assembly` -- tiling conditions, windows, :func:`paint_condition`, :func:`boost_condition`;
* :mod:`tghop.cooc.training` -- ``fit`` and its steps (mixed into :class:`CoocGAN`), and
  :func:`tghop.cooc.training.keep_mmap_threshold` for programs that train on a CPU;
* :mod:`tghop.cooc.generation` -- ``generate``, ``sample``, the morphs and the other controls
  (mixed into :class:`CoocGAN`);
* :mod:`tghop.cooc.checkpoints` -- the ``.pt`` file (:data:`KIND`, :data:`FORMAT`);
* :mod:`tghop.cooc.model` -- :class:`CoocGAN`, :func:`load`, :func:`baseline`.
"""

from __future__ import annotations

from ..cooccurrence import cooccurrence_matrix, cooccurrence_tensor, fit_colour_clusters, soft_assign
from .assembly import (ASSEMBLIES, FEATHER, QUILT_DETAIL, QUILT_POOL, QUILT_TOLERANCE, boost_condition, cell_labels,
                       paint_condition)
from .checkpoints import FORMAT, KIND
from .config import PAPER, SMALL
from .model import CoocGAN, baseline, load
from .networks import average_step

__all__ = [
    "SMALL",
    "PAPER",
    "KIND",
    "FORMAT",
    "CoocGAN",
    "fit_colour_clusters",
    "soft_assign",
    "cooccurrence_matrix",
    "cooccurrence_tensor",
    "paint_condition",
    "cell_labels",
    "boost_condition",
    "load",
    "baseline",
    # also public before the split into modules
    "average_step",
    "ASSEMBLIES",
    "FEATHER",
    "QUILT_POOL",
    "QUILT_TOLERANCE",
    "QUILT_DETAIL",
]
