"""Repetition of large outputs: self-repetition, copied textured windows, SIFID of crops, time.

For each texture, a model (fitted here, or read from ``--models DIR/NAME.npz`` made by
``tghop fit``) synthesises a 256x256 image and images of each ``--sizes`` with the
default settings ("new") and, with ``--old``, without the reuse penalty and pool growth
(``reuse=0, pool_per_block=0``: the pipeline before them). Per image: self-repetition
(:func:`tghop.metrics.self_repetition`), :func:`tghop.metrics.copied_textured` against
the exemplar, the median SIFID of four 256x256 crops (the 256x256 output's own SIFID in
its row) and the synthesis time in process (noisy on a shared machine).

    python benchmarks/bench_repetition.py --models /tmp/models --old brick_wall knit
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from _common import markdown_table, texture, write_results

OLD = dict(reuse=0.0, pool_per_block=0.0)


def crops(img, n=4, size=256, seed=0):
    rng = np.random.default_rng(seed)
    h, w = img.shape[:2]
    return [img[y : y + size, x : x + size] for y, x in
            zip(rng.integers(0, h - size + 1, n).tolist(), rng.integers(0, w - size + 1, n).tolist())]


def main():
    from tghop import TGHop, metrics
    from tghop.modelfile import load_model

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("textures", nargs="+")
    ap.add_argument("--sizes", default="2048", help="comma-separated sides (default 2048)")
    ap.add_argument("--models", help="directory of NAME.npz model files (default: fit here)")
    ap.add_argument("--old", action="store_true", help="also without the reuse penalty and pool growth")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tag", default="", help="suffix of the result files (repetition-TAG.{json,md})")
    ap.add_argument("--no-sifid", action="store_true")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    rows, payload = [], []
    for name in args.textures:
        ex = texture(name)
        model = load_model(Path(args.models) / f"{name}.npz") if args.models else TGHop().fit(ex)
        variants = [("new", {})] + ([("old", OLD)] if args.old else [])
        for size in [256] + sizes:
            for label, kw in (variants if size != 256 else [("", {})]):
                t = time.perf_counter()
                img = model.synthesize((size, size), rng=args.seed, **kw)
                seconds = time.perf_counter() - t
                rep = metrics.self_repetition(img)
                cop = metrics.copied_textured(ex, img)
                sif = None
                if not args.no_sifid:
                    parts = [img] if size == 256 else crops(img)
                    sif = float(np.median([metrics.sifid(ex, c) for c in parts]))
                row = dict(texture=name, size=size, variant=label or "-", self_repetition=rep,
                           copied_textured=cop, sifid_256=sif, seconds=seconds)
                payload.append(row)
                rows.append([name, f"{size}x{size}", row["variant"], rep, cop, "-" if sif is None else sif, seconds])
                print(markdown_table(["texture", "size", "variant", "self-repetition", "copied_textured",
                                      "SIFID of 256 crops", "time s"], rows[-1:]).splitlines()[-1], flush=True)
    header = ["texture", "size", "variant", "self-repetition", "copied_textured", "SIFID of 256 crops", "time s"]
    table = markdown_table(header, rows)
    print(table)
    write_results("repetition" + (f"-{args.tag}" if args.tag else ""), payload, "# Repetition of large outputs (bench_repetition.py)\n\n" + table)


if __name__ == "__main__":
    main()
