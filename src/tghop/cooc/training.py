"""Training of the co-occurrence cGAN: WGAN-GP with the paper's consistency loss, and the
weight average.

:class:`TrainingMixin` holds :meth:`~TrainingMixin.fit` and the steps it is made of; it is
mixed into :class:`tghop.cooc.model.CoocGAN`, whose statistics methods it uses (``_cooc``,
``_cooc_context``, ``_exemplar_tensor``, ``_normalise``, ``_noise``, ``_to_device``,
``_settings``, ``_check_fitted`` and the property ``s``). One generator step
(:meth:`~TrainingMixin.fit`'s loop):

1. ``n_critic`` critic steps (:meth:`~TrainingMixin._critic_step`) on random batches of
   training crops (:meth:`~TrainingMixin._batch`), the gradient penalty on every
   ``gp_every``-th;
2. a generator step (:meth:`~TrainingMixin._generator_step`): the adversarial loss plus
   ``lambda_cooc`` times the L1 distance between the generated crops' co-occurrence tensors
   and their conditions (Eq. 3);
3. the weight average (``ema``) moves (:meth:`~TrainingMixin._update_average`); after the
   last step its batch-norm statistics are recomputed
   (:meth:`~TrainingMixin._recompute_average_statistics`).

:func:`keep_mmap_threshold` is for the program that trains (``tghop cooc train`` calls it):
a process-wide allocator setting that a library does not make on its own.
"""

from __future__ import annotations

import copy
import hashlib
import math
import numbers
import time
from typing import Callable, Optional, TypeVar

import numpy as np

from .._errors import TGHopError
from .._estimator import check_rng
from .._images import check_image, check_texture
from .._progress import ProgressCallback, report
from .._resources import available_memory, import_torch
from ..cooccurrence import fit_colour_clusters
from .networks import average_step, build_networks, join_tiles, split_tiles

__all__ = ["TrainingMixin", "keep_mmap_threshold"]

#: The class ``fit`` is called on (a :class:`tghop.cooc.model.CoocGAN`), which it returns: named by a
#: bound type variable, as this module cannot import the model that imports it (``typing.Self`` is 3.11+).
_Self = TypeVar("_Self", bound="TrainingMixin")


def keep_mmap_threshold() -> None:
    """Keep glibc's mmap threshold at its initial 128 KiB for the rest of the process.

    For long CPU trainings (``tghop cooc train`` calls it before training; :meth:`CoocGAN.fit
    <TrainingMixin.fit>` does not, since it changes the whole process). glibc raises the
    threshold whenever a large mmapped block is freed; from then on a training step's large
    temporary tensors come from the heap, whose free pieces are not given back, and the
    resident memory of a CPU training grows step after step. With the threshold fixed it
    stays flat. The same as ``MALLOC_MMAP_THRESHOLD_=131072`` in the environment; does
    nothing where there is no glibc ``mallopt``.
    """
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.mallopt(-3, 128 * 1024)  # M_MMAP_THRESHOLD
    except (OSError, AttributeError):
        pass


def _exemplar_hash(img: np.ndarray) -> str:
    """Identifies the exemplar a model was trained on (``fit(..., resume=True)`` checks it)."""
    return hashlib.sha1(np.round(img * 255).astype(np.uint8).tobytes()).hexdigest()[:16]


class TrainingMixin:
    """:meth:`fit` and its parts, for :class:`tghop.cooc.model.CoocGAN` (see the module's docstring).

    State made here: ``centres_``, ``spreads_``, ``cond_mean_``, ``cond_std_``,
    ``exemplar_cooc_``, ``generator_``, ``critic_``, ``generator_ema_`` (with ``ema > 0``),
    ``step_``, ``history_``, ``exemplar_shape_``, ``exemplar_hash_``, ``settings_``, and the
    private training state: ``_seed_``, ``_crops``, ``_conds``, ``_targets``, ``_opt_g``,
    ``_opt_d`` and ``_torch_gen`` (the random numbers of training).
    """

    def _check_exemplar(self, img: np.ndarray, what: str, fix: str) -> None:
        """Refuse ``img`` (a checked exemplar) unless it is the one this trained model was
        trained on: "``what``: this exemplar is not the one ...; ``fix``"."""
        self._check_fitted()
        if tuple(img.shape) != tuple(self.exemplar_shape_) or _exemplar_hash(img) != self.exemplar_hash_:
            raise TGHopError(f"{what}: this exemplar is not the one the model was trained on; {fix}")

    # ------------------------------------------------------------------ the loop
    def fit(self: _Self, exemplar, y=None, *, resume: bool = False, max_seconds: Optional[float] = None,
            progress: Optional[ProgressCallback] = None,
            log: Optional[Callable[[int, dict], None]] = None) -> _Self:
        """Train on one exemplar.

        Parameters
        ----------
        exemplar : array_like, shape (H, W) or (H, W, C)
            Float in [0, 1], at least ``crop_size`` on each side, not flat
            (:func:`tghop._images.check_texture`).
        y : None
            Ignored (scikit-learn's signature: a Pipeline passes it; 0.59 took the image alone).
        resume : bool
            Continue a loaded checkpoint (or an earlier fit) up to ``n_steps`` instead of
            starting afresh; the exemplar must be the one it was trained on. Crops are cut
            again from the same seed; optimiser and random-number states come from the
            checkpoint.
        max_seconds : float, optional
            Stop after this much training time (the steps done are in ``step_``).
        progress : callable, optional
            ``progress("co-occurrences", done, total)`` then ``progress("training", step, n_steps)``.
        log : callable, optional
            ``log(step, losses)`` after every generator step, ``losses`` a dict with
            ``critic``, ``adversarial``, ``consistency`` and ``gp``.

        Returns
        -------
        self

        Notes
        -----
        A long training on a CPU should call :func:`keep_mmap_threshold` first (``tghop
        cooc train`` does): without it the process's memory can grow step after step.
        ``fit`` leaves that process-wide setting to its caller.
        """
        if max_seconds is not None and not (isinstance(max_seconds, numbers.Real) and max_seconds > 0):
            raise TGHopError(f"max_seconds must be a number of seconds above 0, or None, got {max_seconds!r}")
        torch = import_torch("the co-occurrence cGAN")
        img = check_image(exemplar, name="exemplar")
        check_texture(img)  # a flat image has nothing to learn: refused before any training, as fit's
        if resume:
            self._check_exemplar(img, "resume", "give the same image, or train afresh")
            self.settings_ = {**self.settings_, "n_steps": self._settings()["n_steps"]}
            self._rebuild_crops(torch, img, progress)
        else:
            self.settings_ = self._settings()
            self.exemplar_shape_ = tuple(int(v) for v in img.shape)
            self.exemplar_hash_ = _exemplar_hash(img)
            self._seed_ = int(check_rng(self.rng).integers(2**31))
            self._build(torch, img, np.random.default_rng(self._seed_), progress)
        total = self.settings_["n_steps"]
        self._memory_format(torch, train=True)
        self.generator_.train()
        self.critic_.train()
        history = [self.history_]
        start = time.perf_counter()
        report(progress, "training", self.step_, max(total, self.step_))
        n_critic, gp_every = self.settings_["n_critic"], self.settings_["gp_every"]
        gp = float("nan")
        while self.step_ < total:
            self._set_learning_rate(total)
            for i in range(n_critic):
                real, cond = self._batch(torch)
                # critic steps are counted from the start (so resume keeps the schedule)
                d_loss, gp_now = self._critic_step(torch, real, cond, (self.step_ * n_critic + i) % gp_every == 0)
                gp = gp_now if math.isfinite(gp_now) else gp
            _, cond, target = self._batch(torch, targets=True)
            adv, cooc = self._generator_step(torch, cond, target=target)
            self.step_ += 1
            self._update_average(torch)
            history.append(np.array([[self.step_, d_loss, adv, cooc, gp]]))
            if log is not None:
                log(self.step_, {"critic": d_loss, "adversarial": adv, "consistency": cooc, "gp": gp})
            report(progress, "training", self.step_, total)
            if not all(math.isfinite(v) for v in (d_loss, adv, cooc)):
                raise TGHopError(f"training diverged at step {self.step_} (a loss is not finite); "
                                 "train again with a lower lr or another seed")
            if max_seconds is not None and time.perf_counter() - start > max_seconds:
                break
        if self.step_ < total:
            report(progress, "training", total, total)
        self.history_ = np.concatenate(history)
        self._memory_format(torch, train=False)
        self.generator_.eval()
        self.critic_.eval()
        if hasattr(self, "generator_ema_"):
            self._recompute_average_statistics(torch)
        return self

    # ------------------------------------------------------------------ setting up
    def _build(self, torch, img: np.ndarray, rng: np.random.Generator, progress):
        """Clusters, training crops and their tensors, networks and optimisers (a fresh fit)."""
        p = self.settings_
        seed = int(rng.integers(2**31))
        self.centres_, self.spreads_ = fit_colour_clusters(img, n_clusters=p["n_clusters"], seed=seed)
        self._to_device(torch)
        self._cut_crops(torch, img, rng, progress)
        flat = self._conds.double().transpose(0, 1).reshape(self._conds.shape[1], -1)
        self.cond_mean_ = flat.mean(1).cpu().numpy()
        self.cond_std_ = np.maximum(flat.std(1).cpu().numpy(), 1e-4)
        self._to_device(torch)
        self.exemplar_cooc_ = self._exemplar_tensor(torch, img)
        # The networks are made on the CPU, their initial weights drawn from torch's global CPU generator, seeded here
        # (torch.manual_seed seeded every device's too); fork_rng puts its state back after, so that a fit leaves the
        # caller's torch.rand & co. as they were. The weights are those torch.manual_seed gave.
        with torch.random.fork_rng(devices=[]):
            torch.default_generator.manual_seed(seed)
            self.generator_, self.critic_ = build_networks(torch, img.shape[2], self._conds.shape[1], p)
        self.generator_.to(self._device)
        self.critic_.to(self._device)
        self._make_averaged()
        self._make_optimisers(torch)
        self.step_ = 0
        self.history_ = np.zeros((0, 5))
        self._torch_gen = torch.Generator(device=self._device).manual_seed(seed + 1)

    def _cut_crops(self, torch, img, rng, progress):
        """``n_crops`` random crops of ``tiles x tiles`` training crops each, cut into their
        ``crop_size`` tiles, and each tile's own co-occurrence tensor.

        ``_crops`` is ``(n_crops * tiles**2, C, n, n)`` and ``_conds`` ``(n_crops * tiles**2, k*k, n/s, n/s)``,
        crop by crop, each crop's tiles row by row (the order of :func:`~tghop.cooc.networks.split_tiles`);
        ``_targets`` (the consistency targets, the crops' own tensors) is ``_conds`` unless
        ``context``, where ``_conds`` are computed with the pixels around each crop.
        """
        p = self.settings_
        n, t = p["crop_size"], p["tiles"]
        if img.shape[0] < n * t or img.shape[1] < n * t:
            raise TGHopError(f"the exemplar is {img.shape[0]}x{img.shape[1]} pixels but the training crops are "
                             f"{n * t} (crop_size {n} x tiles {t}); use a larger exemplar or a smaller crop_size")
        self._check_crops_memory(img.shape[2])
        ys = rng.integers(img.shape[0] - n * t + 1, size=p["n_crops"])
        xs = rng.integers(img.shape[1] - n * t + 1, size=p["n_crops"])
        crops = np.stack([img[y + i * n : y + (i + 1) * n, x + j * n : x + (j + 1) * n]
                          for y, x in zip(ys, xs) for i in range(t) for j in range(t)]).transpose(0, 3, 1, 2)
        self._crops = torch.as_tensor(crops, dtype=torch.float32, device=self._device)
        conds = []
        chunk = 64
        with torch.no_grad():
            for i in range(0, len(crops), chunk):
                conds.append(self._cooc(self._crops[i : i + chunk]))
                report(progress, "co-occurrences", min(i + chunk, len(crops)), len(crops))
        self._targets = self._conds = torch.cat(conds)
        if p["context"]:  # each t x t block with one cell of the (mirror-padded) exemplar around it
            s, cells = self.s, n * t // self.s
            padded = np.pad(img, ((s, s), (s, s), (0, 0)), mode="symmetric")
            side = n * t + 2 * s
            ctx = []
            with torch.no_grad():
                for i in range(0, len(ys), chunk):
                    block = np.stack([padded[y : y + side, x : x + side]
                                      for y, x in zip(ys[i : i + chunk], xs[i : i + chunk])])
                    block = torch.as_tensor(block.transpose(0, 3, 1, 2), dtype=torch.float32, device=self._device)
                    ctx.append(split_tiles(self._cooc_context(block, cells, cells), t))
            self._conds = torch.cat(ctx)

    def _check_crops_memory(self, channels: int) -> None:
        """A one-line :class:`TGHopError` naming ``n_crops`` where the training crops and their
        co-occurrence tensors would not fit in the available memory (``n_crops=1000000000``
        grew a list of views until the machine ran out of memory)."""
        p = self.settings_
        n, t, k = p["crop_size"], p["tiles"], p["n_clusters"]
        # per tile: its pixels as float64 (the stack) and float32 (the tensor), its condition
        # and target (float32; k*k cells of (n / s)**2 each), and the view that cut it
        per_crop = t * t * (12.0 * channels * n * n + 8.0 * k * k * (n // self.s) ** 2 + 200.0)
        avail = available_memory()
        if avail is not None and p["n_crops"] * per_crop > avail:
            raise TGHopError(f"n_crops={p['n_crops']:,} training crops need about {p['n_crops'] * per_crop / 1e9:,.1f} "
                             f"GB but only {avail / 1e9:,.1f} GB is available; use at most "
                             f"n_crops={max(1, int(avail // per_crop)):,}")

    def _rebuild_crops(self, torch, img, progress):
        """The training crops of a fresh fit with this seed (a resumed fit needs them again)."""
        rng = np.random.default_rng(self._seed_)
        rng.integers(2**31)  # the clustering seed of _build
        self._cut_crops(torch, img, rng, progress)

    def _make_optimisers(self, torch):
        p = self.settings_
        betas = (p["beta1"], p["beta2"])
        self._opt_g = torch.optim.Adam(self.generator_.parameters(), lr=p["lr"], betas=betas)
        self._opt_d = torch.optim.Adam(self.critic_.parameters(), lr=p["lr"], betas=betas)

    def _make_averaged(self):
        """The averaged generator (``ema > 0``): a copy of the generator, outside autograd."""
        if self.settings_["ema"] > 0:
            self.generator_ema_ = copy.deepcopy(self.generator_).requires_grad_(False).eval()
        elif hasattr(self, "generator_ema_"):
            del self.generator_ema_

    # ------------------------------------------------------------------ one step
    def _set_learning_rate(self, total: int) -> None:
        """``lr`` until the last ``lr_decay`` share of ``total`` steps, then linearly down to
        0 at step ``total`` (both networks); a function of the step, so resume continues it."""
        p = self.settings_
        span = p["lr_decay"] * total
        lr = p["lr"] if span <= 0 else p["lr"] * min(1.0, max(0.0, (total - self.step_) / span))
        for opt in (self._opt_g, self._opt_d):
            for group in opt.param_groups:
                group["lr"] = lr

    def _batch(self, torch, targets: bool = False):
        """Real tiles in [-1, 1] and the generator's conditions: ``max(1, batch_size // tiles**2)``
        crops, i.e. their ``tiles**2`` tiles each and their tiles' tensors joined into one grid;
        ``targets=True`` adds the consistency targets (joined likewise)."""
        t = self.settings_["tiles"]
        m = max(1, self.settings_["batch_size"] // (t * t))
        idx = torch.randint(len(self._crops) // (t * t), (m,), generator=self._torch_gen, device=self._device)
        if t > 1:
            idx = (idx[:, None] * (t * t) + torch.arange(t * t, device=self._device)).reshape(-1)
        if targets:
            return self._crops[idx] * 2.0 - 1.0, join_tiles(self._conds[idx], t), join_tiles(self._targets[idx], t)
        return self._crops[idx] * 2.0 - 1.0, join_tiles(self._conds[idx], t)

    def _critic_step(self, torch, real, cond, with_gp: bool = True):
        """One critic update; ``with_gp=False`` leaves the gradient penalty out (lazy
        regularisation, ``gp_every > 1``: the penalty, weighted ``gp_every`` times, only on
        every ``gp_every``-th critic step) and returns NaN for it."""
        p = self.settings_
        t = p["tiles"]
        cn = self._normalise(cond)
        with torch.no_grad():
            fake = split_tiles(self.generator_(cn, self._noise(torch, len(cn), cn.shape[2], cn.shape[3])), t)
        cn = split_tiles(cn, t)
        d_real, d_fake = self.critic_(real, cn), self.critic_(fake, cn)
        # Eq. 4 as written is E[D(x_r)] - E[D(x_g)]: a critic that scores real crops high
        # must *maximise* it, so its loss is the negative (Gulrajani et al.'s sign).
        loss = d_fake.mean() - d_real.mean()
        gp = None
        if with_gp:
            u = torch.rand((len(real), 1, 1, 1), generator=self._torch_gen, device=self._device)
            mix = (u * real + (1 - u) * fake).requires_grad_(True)
            (grad,) = torch.autograd.grad(self.critic_(mix, cn).sum(), mix, create_graph=True)
            gp = ((grad.flatten(1).norm(dim=1) - 1.0) ** 2).mean()
            loss = loss + p["lambda_gp"] * p["gp_every"] * gp
        self._opt_d.zero_grad(set_to_none=True)
        loss.backward()
        self._opt_d.step()
        return float(loss.detach()), (float(gp.detach()) if gp is not None else float("nan"))

    def _generator_loss(self, cond, noise, target=None):
        """Eq. 3: ``-E[D(G(z, C), C)] + lambda_M |M_g - M_r|_1``; returns (total, adversarial, consistency).

        ``target``: the crop-only tensors ``M_r`` (default ``cond``; they differ with ``context``).

        With ``tiles > 1`` the generator draws whole ``tiles x tiles``-crop conditions and
        the critic and the consistency loss see the generated image's training-size tiles,
        each with its own part of the condition.
        """
        t = self.settings_["tiles"]
        cn = self._normalise(cond)
        fake = split_tiles(self.generator_(cn, noise), t)
        cn, target = split_tiles(cn, t), split_tiles(cond if target is None else target, t)
        adv = -self.critic_(fake, cn).mean()
        cooc = (self._cooc((fake + 1.0) * 0.5) - target).abs().sum(1).mean()  # L1 per cell, averaged
        return adv + self.settings_["lambda_cooc"] * cooc, adv, cooc

    def _generator_step(self, torch, cond, noise=None, target=None):
        if noise is None:
            noise = self._noise(torch, len(cond), cond.shape[2], cond.shape[3])
        for q in self.critic_.parameters():
            q.requires_grad_(False)
        total, adv, cooc = self._generator_loss(cond, noise, target)
        self._opt_g.zero_grad(set_to_none=True)
        total.backward()
        self._opt_g.step()
        for q in self.critic_.parameters():
            q.requires_grad_(True)
        return float(adv.detach()), float(cooc.detach())

    # ------------------------------------------------------------------ the weight average
    def _update_average(self, torch):
        """After generator step ``t = step_``: ``avg <- beta_t avg + (1 - beta_t) theta_t``.

        ``beta_t = ema (1 - ema**(t-1)) / (1 - ema**t)`` makes the average exactly the
        normalised exponentially weighted mean of the weights after steps 1..t (weights
        ``ema**(t-i)``; Adam's bias correction): no share of the random initialisation is
        left in it, and ``t = 1`` gives the weights themselves. Batch-norm buffers (running
        statistics) are copied from the generator while training; :meth:`fit` recomputes
        them for the averaged weights at its end (:meth:`_recompute_average_statistics`).
        """
        if hasattr(self, "generator_ema_"):
            average_step(torch, self.generator_ema_, self.generator_, self.settings_["ema"], self.step_)

    def _recompute_average_statistics(self, torch, conds=None):
        """Batch-norm running statistics of the averaged generator, recomputed for its own weights.

        The raw generator's statistics (which :meth:`_update_average` copies) belong to
        other weights: on brick_wall the averaged generator with them gave SIFID 10-22
        against 4-5 for the raw one (docs/choices.md). So, as for stochastic weight
        averaging (Izmailov et al. 2018, ``update_bn``), one train-mode pass over the
        training conditions (``conds``, default the training crops' tensors, in
        generator batches, tiles joined as in training) with fresh noise sets them to the
        plain average of the batch statistics. The noise comes from its own seeded
        generator, so training's random numbers are untouched and the result is repeatable.
        """
        gen = self.generator_ema_
        conds = self._conds if conds is None else conds
        t = int(self.settings_["tiles"])
        per = max(1, int(self.settings_["batch_size"]) // (t * t)) * t * t
        noise_gen = torch.Generator(device=self._device).manual_seed(int(self._seed_) + 2)
        norms = [m for m in gen.modules() if isinstance(m, torch.nn.BatchNorm2d)]
        momenta = [m.momentum for m in norms]
        for m in norms:
            m.reset_running_stats()
            m.momentum = None  # cumulative: the mean over the batches
        gen.train()
        with torch.no_grad():
            for i in range(0, len(conds) - t * t + 1, per):
                cn = self._normalise(join_tiles(conds[i : i + per], t))
                gen(cn, self._noise(torch, len(cn), cn.shape[2], cn.shape[3], generator=noise_gen))
        for m, momentum in zip(norms, momenta):
            m.momentum = momentum
        gen.eval()

    # ------------------------------------------------------------------ memory layout
    def _memory_format(self, torch, *, train: bool):
        """Channels-last networks on a CPU, where oneDNN's convolutions run faster in it.

        While training (``train=True``): every network and the crops (each step is faster).
        Afterwards and after :func:`~tghop.cooc.model.load`: the generators stay
        channels-last (generation, too, is faster in it), the critic and the crops go back
        to the default one. A trained model and one loaded from its checkpoint therefore
        generate identically.
        """
        if self._device.type != "cpu":
            return
        fmt = torch.channels_last if train else torch.contiguous_format
        for module in (self.generator_, getattr(self, "generator_ema_", None)):
            if module is not None:
                module.to(memory_format=torch.channels_last)
        self.critic_.to(memory_format=fmt)
        if getattr(self, "_crops", None) is not None:
            self._crops = self._crops.contiguous(memory_format=fmt)
