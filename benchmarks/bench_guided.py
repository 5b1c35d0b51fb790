"""Several models in one image: time and SIFID of each region (tghop.guided).

For each pair ``A:B`` of textures (models fitted here with the defaults, or read from
``--models DIR/NAME.npz``):

* guided ``SIZE x SIZE`` from a map whose left half is A and right half B
  (``--transition`` px): the time in process (models loaded) and of the whole
  ``tghop synth A.npz B.npz --guide MAP`` process, next to the whole ``tghop synth
  A.npz`` process at the same size (the same machine, its load at that moment); the median SIFID of four 256x256 crops
  of each region (away from the transition) against its own exemplar and against the
  other one, next to the same crops of a plain ``synthesize`` of that model alone;
* remix ``SIZE x SIZE`` (no guide): time;
* morph 256 x 1024: time, and the SIFID of its left, middle and right 256x256 against A
  and B; with ``--morph-only``, only the morph: its time in process and of the whole ``tghop morph
  A.npz B.npz --size 256x1024`` process, next to a whole ``tghop synth A.npz`` process of that size,
  ``--repeat`` times each, in turn (the ranges).

Timings are wall clock on whatever machine runs it (noisy on a shared one).

    python benchmarks/bench_guided.py brick_wall:grass_lawn red_bricks_512:brick_wall --models /tmp/models
    python benchmarks/bench_guided.py brick_wall:grass_lawn bricks:cells --morph-only --repeat 3 --no-sifid
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import markdown_table, texture, write_results


def region_crops(img, x0, x1, size=256):
    """Four ``size`` crops inside columns [x0, x1): two rows, two columns."""
    h = img.shape[0]
    ys = [h // 4 - size // 2, 3 * h // 4 - size // 2] if h >= 2 * size else [0, max(0, h - size)]
    xs = [x0, x1 - size]
    return [img[y:y + size, x:x + size] for y in ys for x in xs]


def median_sifid(ex, crops):
    from tghop import metrics

    return float(np.median([metrics.sifid(ex, c) for c in crops]))


def fitted(names, models_dir, tmp):
    """Each name's exemplar and saved model (fitted here with the defaults unless ``models_dir`` has it)."""
    from tghop import TGHop
    from tghop.modelfile import save_model

    exemplars, paths = [texture(name) for name in names], []
    for name, ex in zip(names, exemplars):
        path = Path(models_dir) / f"{name}.npz" if models_dir else Path(tmp) / f"{name}.npz"
        if not models_dir:
            save_model(TGHop(rng=0).fit(ex), path)
        paths.append(str(path))
    return exemplars, paths


def morph_only(args):
    """The morph 256x1024 of each pair, timed in process and as a whole ``tghop morph`` process, in turn."""
    from tghop import morph
    from tghop.modelfile import load_model

    rows, payload = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for pair in args.pairs:
            exemplars, paths = fitted(pair.split(":"), args.models, tmp)
            models = [load_model(p) for p in paths]
            inside, whole, plain = [], [], []
            for _ in range(args.repeat):
                t = time.perf_counter()
                strip = morph(models[0], models[1], (256, 1024), rng=args.seed)
                inside.append(time.perf_counter() - t)
                t = time.perf_counter()
                subprocess.run([sys.executable, "-m", "tghop", "morph", *paths, "--size", "256x1024", "-o",
                                os.path.join(tmp, "strip.png"), "--seed", str(args.seed), "-q"], check=True,
                               capture_output=True)
                whole.append(time.perf_counter() - t)
                t = time.perf_counter()  # the same machine's plain synth of A at the strip's size, for comparison
                subprocess.run([sys.executable, "-m", "tghop", "synth", paths[0], "--size", "256x1024", "-o",
                                os.path.join(tmp, "plain.png"), "--seed", str(args.seed), "-q"], check=True,
                               capture_output=True)
                plain.append(time.perf_counter() - t)
            row = dict(pair=pair, morph_s=inside, morph_process_s=whole, plain_process_s=plain)
            if not args.no_sifid:
                for label, x in (("left", 0), ("middle", 384), ("right", 768)):
                    for k, e in zip("ab", exemplars):
                        row[f"morph_{label}_sifid_{k}"] = median_sifid(e, [strip[:, x:x + 256]])
            payload.append(row)
            rows.append([pair, *[f"{min(x):.2f}-{max(x):.2f}" for x in (inside, whole, plain)],
                         *[row.get(f"morph_{p}_sifid_{e}", "-") for p in ("left", "middle", "right") for e in "ab"]])
            print(rows[-1], flush=True)
    text = (f"# Morph 256x1024 (bench_guided.py --morph-only)\n\nSeed {args.seed}, {args.repeat} run(s) of each in "
            "turn (min-max).\n\n" + markdown_table(["A:B", "in process s", "whole process s",
                                                      "plain synth A 256x1024 s (whole process)", "left vs A",
                                                      "left vs B", "middle vs A", "middle vs B", "right vs A",
                                                      "right vs B"], rows))
    print(text)
    write_results(args.name, payload, text)


def main():
    from tghop import TGHop, morph, synthesize_guided
    from tghop.imageio import save_image
    from tghop.modelfile import load_model, save_model

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("pairs", nargs="+", help="A:B texture names")
    ap.add_argument("--models", help="directory of NAME.npz model files (default: fit here)")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--transition", type=int, default=32)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-sifid", action="store_true")
    ap.add_argument("--name", default="guided", help="results/NAME.json and .md")
    ap.add_argument("--morph-only", action="store_true", help="time the morph alone (in process and whole process)")
    ap.add_argument("--repeat", type=int, default=1, help="timings of each kind with --morph-only, in turn")
    args = ap.parse_args()
    if args.morph_only:
        return morph_only(args)
    n = args.size
    if not args.no_sifid and n // 2 - (args.transition + 32) < 256:  # region_crops: 256x256 crops in each half
        ap.error(f"--size {n} leaves no 256x256 crop in a region (at least transition + 32 px from the middle): "
                 f"give --size {2 * (256 + args.transition + 32)} or more, or --no-sifid")
    guide = np.zeros((n, n), dtype=np.uint8)
    guide[:, n // 2:] = 255
    rows, morph_rows, payload = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        save_image(guide, os.path.join(tmp, "map.png"))
        for pair in args.pairs:
            names = pair.split(":")
            exemplars = [texture(name) for name in names]
            paths, models = [], []
            for name, ex in zip(names, exemplars):
                path = Path(args.models) / f"{name}.npz" if args.models else Path(tmp) / f"{name}.npz"
                if not args.models:
                    save_model(TGHop(rng=0).fit(ex), path)
                paths.append(str(path))
                models.append(load_model(path))
            row = dict(pair=pair, size=n, transition=args.transition)
            t = time.perf_counter()
            img = synthesize_guided(models, guide, transition=args.transition, rng=args.seed)
            row["guided_s"] = time.perf_counter() - t
            t = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "tghop", "synth", *paths, "--guide", os.path.join(tmp, "map.png"),
                                "-o", os.path.join(tmp, "out.png"), "--seed", str(args.seed), "-q",
                                "--transition", str(args.transition)], capture_output=True)
            row["guided_process_s"] = time.perf_counter() - t
            if r.returncode:
                raise SystemExit(r.stderr.decode())
            t = time.perf_counter()  # the same machine's plain synth of A, for comparison
            subprocess.run([sys.executable, "-m", "tghop", "synth", paths[0], "--size", f"{n}x{n}", "-o",
                            os.path.join(tmp, "plain.png"), "--seed", str(args.seed), "-q"], check=True,
                           capture_output=True)
            row["plain_process_s"] = time.perf_counter() - t
            t = time.perf_counter()
            synthesize_guided(models, size=(n, n), rng=args.seed)
            row["remix_s"] = time.perf_counter() - t
            t = time.perf_counter()
            strip = morph(models[0], models[1], (256, 1024), rng=args.seed)
            row["morph_s"] = time.perf_counter() - t
            if not args.no_sifid:
                margin = args.transition + 32
                regions = [(0, n // 2 - margin), (n // 2 + margin, n)]
                for k, (x0, x1) in enumerate(regions):
                    own, other = exemplars[k], exemplars[1 - k]
                    crops = region_crops(img, x0, x1)
                    plain = region_crops(models[k].synthesize((n, n), rng=args.seed), x0, x1)
                    row[f"region{k}_sifid_own"] = median_sifid(own, crops)
                    row[f"region{k}_sifid_other"] = median_sifid(other, crops)
                    row[f"region{k}_sifid_plain"] = median_sifid(own, plain)
                for label, x in (("left", 0), ("middle", 384), ("right", 768)):
                    crop = strip[:, x:x + 256]
                    row[f"morph_{label}_sifid_a"] = median_sifid(exemplars[0], [crop])
                    row[f"morph_{label}_sifid_b"] = median_sifid(exemplars[1], [crop])
            payload.append(row)
            g = row.get
            rows.append([pair, f"{n}x{n}", row["guided_s"], row["guided_process_s"], row["plain_process_s"],
                         row["remix_s"],
                         *[g(f"region{k}_sifid_{w}", "-") for k in (0, 1) for w in ("own", "other", "plain")]])
            morph_rows.append([pair, row["morph_s"],
                               *[g(f"morph_{p}_sifid_{e}", "-") for p in ("left", "middle", "right") for e in "ab"]])
            print(rows[-1], morph_rows[-1], flush=True)
    header = ["A:B", "size", "guided s (in process)", "guided s (whole process)", "plain synth A s (whole process)",
              "remix s",
              "A region: SIFID vs A", "vs B", "plain A", "B region: SIFID vs B", "vs A", "plain B"]
    table = markdown_table(header, rows)
    morph_table = markdown_table(["A:B", "morph 256x1024 s", "left vs A", "left vs B", "middle vs A",
                                  "middle vs B", "right vs A", "right vs B"], morph_rows)
    text = (f"# Guided synthesis, remix and morph (bench_guided.py)\n\n"
            f"Guide: left half A, right half B, transition {args.transition} px, seed {args.seed}. SIFID: median "
            "of four 256x256 crops of each region (at least transition + 32 px from the middle) against the "
            "exemplar; 'plain': the same crops of the model's own synthesize.\n\n"
            f"{table}\n\nMorph strips (SIFID of 256x256 at the left, middle and right):\n\n{morph_table}")
    print(text)
    write_results(args.name, payload, text)


if __name__ == "__main__":
    main()
