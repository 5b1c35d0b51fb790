"""The co-occurrence cGAN (Darzi et al., tghop.cooc) on this machine: training, speed, the paper's checks.

    python benchmarks/bench_cooc.py train brick_wall grass_lawn red_peppers   # ~15 min each
    python benchmarks/bench_cooc.py report brick_wall grass_lawn red_peppers

``train NAME...`` trains the small configuration (tghop.cooc.SMALL) on each exemplar, one
process per texture (so its peak memory is its own), and writes
``results/cooc/NAME.pt`` and ``NAME_train.json`` (wall time, steps, peak RSS, load
average before and after, loss history).

``report NAME...`` loads those checkpoints and writes ``results/cooc/report.md`` with:

1. training time and peak memory of each run;
2. generation speed (images/second at 256x256 and 1024x1024, CPU, torch threads as set);
3. the stability loop (Sec. 4.2): a held-out crop's tensor -> generate -> its tensor ->
   generate ... 10 rounds, with one noise tensor; L1 between each round's input and
   output tensor, drift of that in % against round 1 (paper: within 2 %);
4. the nearest-neighbour novelty check (Sec. 4.2, Fig. 5): for generated crops, the
   nearest training crop in RGB L1 and in co-occurrence L1, against the distance
   between two real crops;
5. the quality table: SIFID, SWD, co-occurrence distance, novelty and "copied" of
   128x128, 256x256 and 512x512 cGAN results (quilted, the default, and at 256 and 512
   also the paper's one pass) next to TGHop (tghop defaults) and Ustyuzhaninov et al.
   (100 L-BFGS iterations at 128x128, as bench_paper.py) on the same textures;
6. image sheets: samples, a morph strip, a Fig. 2 grid, an edit (two crops' statistics
   painted left/right) and the stability sequence.

``seeds RUN...`` (``RUN``: ``NAME`` or ``NAME-seedS``, trained with ``train --seed S
--extra-ema D...``) compares the raw and the averaged generators of each run (``ema``:
the model's own average, the ``--extra-ema`` decays, and the model's average with its
batch-norm statistics recomputed): four 256 px samples each (one generator pass, as the
GPU sweeps), the same conditions and noise for every variant, scored against the
exemplar; writes ``results/cooc/seeds.md`` (per run and the median over seeds) and
``seeds-RUN.png`` sheets.

Options: ``--threads N`` (torch threads, default 2), ``--steps N`` (train: override
n_steps), ``--max-minutes M`` (train: stop each run after M minutes of training and
report the steps done), ``--out DIR``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (  # noqa: E402
    RESULTS,
    image_sheet,
    markdown_table,
    peak_rss_mb,
    stack_rows,
    texture,
    write_results_to,
)

OUT = RESULTS / "cooc"


def load_average() -> float:
    return os.getloadavg()[0]


# ----------------------------------------------------------------------------- training
def run_name(name: str, seed: int) -> str:
    """File stem of a run: ``NAME`` for seed 0 (the report's), ``NAME-seedS`` otherwise."""
    return name if seed == 0 else f"{name}-seed{seed}"


def train_one(name: str, out: Path, threads: int, steps, max_seconds, seed: int = 0, extra_ema=()) -> dict:
    """Train the small configuration on ``name`` in this process (called in a child).

    ``extra_ema``: further generator-average decays kept beside the model's own (same
    update, :meth:`CoocGAN._update_average`), saved as ``RUN_ema.pt`` (decay -> state dict)
    so that they can be compared at no extra training cost.
    """
    import copy

    import torch

    from tghop.cooc import CoocGAN
    from tghop.cooc.networks import average_step
    from tghop.cooc.training import keep_mmap_threshold

    torch.set_num_threads(threads)
    img = texture(name)
    if max(img.shape[:2]) > 512:  # as bench_paper.py: the centre 256x256 of a large exemplar
        y, x = (img.shape[0] - 256) // 2, (img.shape[1] - 256) // 2
        img = img[y : y + 256, x : x + 256]
    model = CoocGAN(rng=seed)
    if steps is not None:
        model.set_params(n_steps=int(steps))
    load_before = load_average()
    stages = {}
    last = {"t": time.perf_counter(), "stage": None}

    def progress(stage, done, total):
        now = time.perf_counter()
        if last["stage"] is not None:
            stages[last["stage"]] = stages.get(last["stage"], 0.0) + now - last["t"]
        last.update(t=now, stage=stage)
        if stage == "training" and done % 50 == 0:
            print(f"{name}: step {done}/{total} at {now - t0:.0f} s, load {load_average():.1f}", flush=True)

    averages = {}

    def log(step, losses):
        gen = model.generator_
        for decay in extra_ema:
            if decay not in averages:
                averages[decay] = copy.deepcopy(gen).requires_grad_(False)
            average_step(torch, averages[decay], gen, decay, step)

    if not torch.cuda.is_available():  # the model's device is "auto": a CPU training, as tghop cooc train
        keep_mmap_threshold()
    t0, c0 = time.perf_counter(), time.process_time()
    model.fit(img, progress=progress, max_seconds=max_seconds, log=log if extra_ema else None)
    seconds = time.perf_counter() - t0
    cpu_seconds = time.process_time() - c0  # all threads; the machine is shared, wall time alone misleads
    progress(None, 0, 0)
    stem = run_name(name, seed)
    model.save(out / f"{stem}.pt")
    if averages:
        torch.save({f"{decay}": {k: v.contiguous() for k, v in avg.state_dict().items()}
                    for decay, avg in averages.items()}, out / f"{stem}_ema.pt")
    entry = {"texture": name, "seed": seed, "exemplar_shape": list(img.shape), "seconds": seconds,
             "cpu_seconds": cpu_seconds,
             "stages": stages,
             "steps": model.step_, "settings": model.settings_, "threads": threads,
             "peak_rss_mb": peak_rss_mb(), "load_before": load_before, "load_after": load_average(),
             "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY"),
             "history": model.history_.tolist()}
    write_results_to(out, f"{stem}_train", entry)
    return entry


# ----------------------------------------------------------------------------- report
def main(argv=None):
    warnings.filterwarnings("ignore")
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("command", choices=["train", "train-one", "report", "seeds"])
    ap.add_argument("textures", nargs="+")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--steps", type=int, default=None)
    ap.add_argument("--max-minutes", type=float, default=None,
                    help="train: stop each training after this many minutes (its steps are reported)")
    ap.add_argument("--seed", type=int, default=0, help="train: the model's rng (files NAME-seedS.* unless 0)")
    ap.add_argument("--extra-ema", type=float, nargs="*", default=[],
                    help="train: further generator-average decays kept beside the model's own (RUN_ema.pt)")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.command == "train-one":
        max_s = None if args.max_minutes is None else 60 * args.max_minutes
        train_one(args.textures[0], args.out, args.threads, args.steps, max_s, args.seed, tuple(args.extra_ema))
        return
    if args.command == "train":
        for name in args.textures:
            cmd = [sys.executable, __file__, "train-one", name, "--threads", str(args.threads), "--out", str(args.out)]
            if args.steps is not None:
                cmd += ["--steps", str(args.steps)]
            if args.max_minutes is not None:
                cmd += ["--max-minutes", str(args.max_minutes)]
            cmd += ["--seed", str(args.seed)] + (["--extra-ema"] + [str(d) for d in args.extra_ema]
                                                 if args.extra_ema else [])
            # Passive OpenMP waiting: with the default spinning, 2 torch threads on a machine
            # that is busy with other work ran a training step up to 20 times slower than 1.
            env = {**os.environ, "OMP_WAIT_POLICY": os.environ.get("OMP_WAIT_POLICY", "PASSIVE")}
            subprocess.run(cmd, check=True, env=env)
        return
    from bench_cooc_report import report, seed_study  # the evaluation half lives beside this file

    if args.command == "seeds":
        seed_study([run_name(t, args.seed) if "-seed" not in t else t for t in args.textures], args.out, args.threads)
        return
    report(args.textures, args.out, args.threads)


if __name__ == "__main__":
    main()
