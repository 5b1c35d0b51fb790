"""Repetition and quality of large outputs: self-repetition, copied textured windows, SIFID of crops, time.

For each texture, a model (fitted here, or read from ``--models DIR/NAME.npz`` made by
``tghop fit``) synthesises ``--refs`` 256x256 images (seeds 0, 1, ...) and ``--large-seeds``
images of each ``--sizes`` per variant (seeds 0, 1, ...): the default settings ("new"), with
``--old`` without the reuse penalty and pool growth (``reuse=0, pool_per_block=0``: the
pipeline before them), and each ``--variant LABEL:KEY=VALUE,...`` (synthesize keywords;
VALUE a Python literal or ``none``). Per size and variant: self-repetition
(:func:`tghop.metrics.self_repetition`) and :func:`tghop.metrics.copied_textured` against the
exemplar (means over the images), the median SIFID of ``--crops`` random 256x256 crops of
each image, all images' crops together (of the 256x256 rows: the median of the images' own
SIFIDs). One image's crops are noisy: beach_gravel at 4096x4096 gave 2.36 from 8 crops of
the seed-0 image and 2.01 from 16 crops of each of two images; compare variants with
``--crops 16 --large-seeds 2`` at least. Then that median over the 256x256 images' ("crops /
256": the issue's goal is at most 1.10) and the synthesis time in process (noisy on a shared
machine). A first row per texture gives the exemplar's own self-repetition: what a periodic
texture scores by itself. With ``--unrefined`` the 256x256 images are made again without the
patch refinement (``patch_refine=0``, which images over 1280x1280 pixels do not get), a row of
their own, and each large row's median also over theirs ("crops / unrefined 256"): near 1, a
large image's crops lack only that step; above it, something of the large image's own
(docs/choices.md, Patch refinement "0.59").

    python benchmarks/bench_repetition.py --models /tmp/models --old brick_wall knit
    python benchmarks/bench_repetition.py --variant 'whole:region=none' --sizes 2048,4096 brick_wall
    python benchmarks/bench_repetition.py --models /tmp/models --unrefined --crops 8 fur grass_lawn
"""

from __future__ import annotations

import argparse
import ast
import time
from pathlib import Path

import numpy as np

from _common import markdown_table, texture, write_results

OLD = dict(reuse=0.0, pool_per_block=0.0)
HEADER = ["texture", "size", "variant", "self-repetition", "copied_textured", "SIFID of 256 crops", "crops / 256",
          "time s"]


def crops(img, n=4, size=256, seed=0):
    rng = np.random.default_rng(seed)
    h, w = img.shape[:2]
    return [img[y : y + size, x : x + size] for y, x in
            zip(rng.integers(0, h - size + 1, n).tolist(), rng.integers(0, w - size + 1, n).tolist())]


def parse_variant(spec: str):
    """``LABEL:KEY=VALUE,...`` -> (label, synthesize keywords)."""
    label, _, items = spec.partition(":")
    kw = {}
    for item in filter(None, items.split(",")):
        key, _, value = item.partition("=")
        kw[key.strip()] = None if value.strip().lower() == "none" else ast.literal_eval(value.strip())
    return label, kw


def main():
    from tghop import TGHop, metrics
    from tghop.modelfile import load_model

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("textures", nargs="+")
    ap.add_argument("--sizes", default="2048", help="comma-separated sides (default 2048)")
    ap.add_argument("--models", help="directory of NAME.npz model files (default: fit here)")
    ap.add_argument("--fit-seed", type=int, default=0, help="the seed of the models fitted here (default 0)")
    ap.add_argument("--old", action="store_true", help="also without the reuse penalty and pool growth")
    ap.add_argument("--variant", action="append", default=[], help="LABEL:KEY=VALUE,... (repeatable)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--refs", type=int, default=1, help="256x256 images per texture (seeds seed, seed+1, ...)")
    ap.add_argument("--crops", type=int, default=4, help="random 256x256 crops per large image")
    ap.add_argument("--large-seeds", type=int, default=1, help="large images per size and variant (seeds seed, ...)")
    ap.add_argument("--tag", default="", help="suffix of the result files (repetition-TAG.{json,md})")
    ap.add_argument("--no-sifid", action="store_true")
    ap.add_argument("--unrefined", action="store_true",
                    help="also 256x256 images without the patch refinement, and the crops over theirs")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    variants = [("new", {})] + ([("old", OLD)] if args.old else []) + [parse_variant(v) for v in args.variant]
    rows, payload = [], []
    header = HEADER + (["crops / unrefined 256"] if args.unrefined and not args.no_sifid else [])

    def record(name, size, label, images, seconds, ex, ref, unrefined=(), own=None):
        rep = float(np.mean([metrics.self_repetition(img) for img in images]))
        cop = float(np.mean([metrics.copied_textured(ex, img) for img in images]))
        sif = None
        if not args.no_sifid:
            small = ref if own is None else own
            sif = float(np.median(small if size == 256 else [metrics.sifid(ex, c) for k, img in enumerate(images)
                                                             for c in crops(img, n=args.crops, seed=k)]))
        ratio = None if sif is None or not ref else sif / float(np.median(ref))
        row = dict(texture=name, size=size, variant=label, self_repetition=rep, copied_textured=cop, sifid_256=sif,
                   ratio_to_256=ratio, seconds=seconds, images=len(images))
        rows.append([name, f"{size}x{size}", label, rep, cop, "-" if sif is None else sif,
                     "-" if ratio is None else ratio, seconds])
        if len(header) > len(HEADER):
            row["ratio_to_unrefined_256"] = plain = None if size == 256 else sif / float(np.median(unrefined))
            rows[-1].append("-" if plain is None else plain)
        payload.append(row)
        print(markdown_table(header, rows[-1:]).splitlines()[-1], flush=True)

    for name in args.textures:
        ex = texture(name)
        # The exemplar's own figure: a periodic texture repeats itself (hexagon_tiles 0.21, stripes 0.82).
        own = float(metrics.self_repetition(ex))
        payload.append(dict(texture=name, size=list(ex.shape[:2]), variant="exemplar", self_repetition=own))
        rows.append([name, "x".join(map(str, ex.shape[:2])), "exemplar", own] + ["-"] * (len(header) - 4))
        model = load_model(Path(args.models) / f"{name}.npz") if args.models else TGHop(rng=args.fit_seed).fit(ex)
        t = time.perf_counter()
        smalls = [model.synthesize((256, 256), rng=args.seed + k) for k in range(args.refs)]
        seconds = (time.perf_counter() - t) / args.refs
        ref = [] if args.no_sifid else [metrics.sifid(ex, img) for img in smalls]
        record(name, 256, "-", smalls, seconds, ex, ref)  # every reference image, as the large rows
        unrefined = []
        if len(header) > len(HEADER):  # the same seeds without the one step large images lack
            t = time.perf_counter()
            plain = [model.synthesize((256, 256), rng=args.seed + k, patch_refine=0) for k in range(args.refs)]
            unrefined = [metrics.sifid(ex, img) for img in plain]
            record(name, 256, "unrefined", plain, (time.perf_counter() - t) / args.refs, ex, ref, own=unrefined)
        for size in sizes:
            for label, kw in variants:
                t = time.perf_counter()
                images = [model.synthesize((size, size), rng=args.seed + k, **kw) for k in range(args.large_seeds)]
                record(name, size, label, images, (time.perf_counter() - t) / len(images), ex, ref, unrefined)
    table = markdown_table(header, rows)
    print(table)
    command = "python benchmarks/bench_repetition.py " + " ".join(__import__("sys").argv[1:])
    write_results("repetition" + (f"-{args.tag}" if args.tag else ""), payload,
                  "# Repetition of large outputs (bench_repetition.py)\n\n" + table + f"\n\nCommand: `{command}`\n")


if __name__ == "__main__":
    main()
