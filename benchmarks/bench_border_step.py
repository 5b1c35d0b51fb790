"""The step at a fill's border: how much the pixels change across the hole's edge (a known pixel and its
filled 4-neighbour) against how much neighbouring pixels change elsewhere.

For each exemplar (its centre ``CROP x CROP`` crop) and hole shape, ``tghop inpaint``'s fill (``TGHop``
fitted with ``exclude=hole``, :func:`tghop.inpaint.inpaint` defaults) or ``tghop extend``'s (the crop grown
by 64 px on every side with a model of the crop): the mean absolute difference (mean over channels) across
the border's edges, over the median of the known area's neighbouring-pixel differences (``step``). The
original crop's own value at the same edges (``orig``) is the reference for the holes (for ``extend``
there is none: the median, ~1 for a seamless border). ``step1``: the same one pixel further into the hole
(a fill whose first row is matched but the next not shows it there). ``--seeds 1,2,3``: each fit (rng 0) filled
with each seed (a fill's path is random: compare over seeds); the medians per seed and their mean.

    python benchmarks/bench_border_step.py stone_wall gravel_gray --crop 256 --out /tmp/steps
    python benchmarks/bench_border_step.py stone_wall gravel_gray red_bricks_512 --seeds 1-3
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

from _common import texture
from bench_inpaint import parse_seeds

HOLES = ("stripe10", "stripe30", "square", "extend")


def make_hole(kind, n):
    hole = np.zeros((n, n), dtype=bool)
    c = n // 2
    if kind == "stripe10":
        hole[:, c - 5:c + 5] = True
    elif kind == "stripe30":
        hole[:, c - 15:c + 15] = True
    elif kind == "square":
        s = int(round(np.sqrt(0.3) * n))
        hole[(n - s) // 2:(n - s) // 2 + s, (n - s) // 2:(n - s) // 2 + s] = True
    return hole


def border_edges(hole, inset=0):
    """(a, b) index arrays of 4-neighbour pairs across the hole's border (``inset``: the pair ``inset``
    pixels further into the hole)."""
    pairs = []
    h, w = hole.shape
    ys, xs = np.nonzero(hole)
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        oy, ox = ys - dy, xs - dx  # the neighbour on the known side
        ok = (oy >= 0) & (oy < h) & (ox >= 0) & (ox < w)
        oy, ox, y, x = oy[ok], ox[ok], ys[ok], xs[ok]
        ok = ~hole[oy, ox]
        oy, ox, y, x = oy[ok], ox[ok], y[ok], x[ok]
        if inset:
            y1, x1 = y + dy * inset, x + dx * inset
            y0, x0 = y1 - dy, x1 - dx
            ok = (y1 >= 0) & (y1 < h) & (x1 >= 0) & (x1 < w)
            ok[ok] = hole[y1[ok], x1[ok]] & hole[y0[ok], x0[ok]]
            pairs.append(((y0[ok], x0[ok]), (y1[ok], x1[ok])))
        else:
            pairs.append(((oy, ox), (y, x)))
    a = tuple(np.concatenate([p[0][i] for p in pairs]) for i in (0, 1))
    b = tuple(np.concatenate([p[1][i] for p in pairs]) for i in (0, 1))
    return a, b


def step(img, a, b):
    img = np.asarray(img, dtype=np.float64)
    return float(np.abs(img[a] - img[b]).mean())


def median_elsewhere(img, hole):
    img = np.asarray(img, dtype=np.float64)
    known = ~hole
    dx = np.abs(np.diff(img, axis=1)).mean(axis=2)[known[:, 1:] & known[:, :-1]]
    dy = np.abs(np.diff(img, axis=0)).mean(axis=2)[known[1:] & known[:-1]]
    return float(np.median(np.concatenate([dx, dy])))


def measure(name, kind, crop, seed, **options):
    """``(row, filled image)`` of one fill; ``seed`` may be a list: then ``[(row, image), ...]``, one per
    seed, of one fit."""
    from tghop import TGHop
    from tghop.canvas import expand_canvas
    from tghop.inpaint import inpaint

    seeds = seed if isinstance(seed, (list, tuple)) else [seed]
    n = crop.shape[0]
    if kind == "extend":
        model = TGHop(rng=0).fit(crop)
        canvas, hole, _ = expand_canvas(crop, (n + 128, n + 128), anchor="center")
        reference = None
    else:
        hole = make_hole(kind, n)
        model = TGHop(rng=0).fit(crop, exclude=hole)
        canvas, reference = crop, crop
    a, b = border_edges(hole)
    a1, b1 = border_edges(hole, 1)
    done = []
    for s in seeds:
        if kind == "extend":
            out = inpaint(model, canvas, hole, rng=s, order="raster", **options)
        else:
            out = inpaint(model, canvas, hole, rng=s, **options)
        base = median_elsewhere(out, hole)
        row = dict(exemplar=name, hole=kind, seed=s, step=step(out, a, b) / base, step1=step(out, a1, b1) / base)
        if reference is not None:
            row["orig"] = step(reference, a, b) / base
            row["orig1"] = step(reference, a1, b1) / base
        done.append((row, out))
    return done if isinstance(seed, (list, tuple)) else done[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("exemplars", nargs="+")
    ap.add_argument("--holes", nargs="*", default=list(HOLES))
    ap.add_argument("--crop", type=int, default=256)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--seeds", type=parse_seeds, help="several seeds, e.g. 1,2,3 or 1-5: each fit filled with each")
    ap.add_argument("--out", help="folder for the filled images (PNG)")
    args = ap.parse_args()
    if args.seeds and "--seed" in sys.argv[1:]:
        ap.error("give --seed or --seeds, not both")
    seeds = args.seeds or [args.seed]
    rows = []
    for name in args.exemplars:
        img = texture(name)
        img = img[:, :, None] if img.ndim == 2 else img
        h, w = img.shape[:2]
        crop = np.ascontiguousarray(img[(h - args.crop) // 2:(h - args.crop) // 2 + args.crop,
                                        (w - args.crop) // 2:(w - args.crop) // 2 + args.crop])
        for kind in args.holes:
            for row, out in measure(name, kind, crop, seeds):
                rows.append(row)
                print(" ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()),
                      flush=True)
                if args.out:
                    from tghop.imageio import save_image

                    os.makedirs(args.out, exist_ok=True)
                    tag = "" if len(seeds) == 1 else f"-seed{row['seed']}"
                    save_image(out, os.path.join(args.out, f"{name}-{kind}{tag}.png"))
    for key in ("step", "step1", "orig"):
        medians = [float(np.median(vals)) for s in seeds if (vals := [r[key] for r in rows if key in r
                                                                     and r["seed"] == s])]
        if len(medians) == 1:
            print(f"median {key}: {medians[0]:.3f}")
        elif medians:
            print(f"median {key}: {' / '.join(f'{m:.3f}' for m in medians)} (seeds {', '.join(map(str, seeds))}), "
                  f"mean {np.mean(medians):.3f}")
    offs = [float(np.mean([abs(np.log(r["step"] / r["orig"])) for r in rows if "orig" in r and r["seed"] == s]))
            for s in seeds if any("orig" in r and r["seed"] == s for r in rows)]
    if offs:
        print(f"mean |log(step / orig)|: {' / '.join(f'{m:.3f}' for m in offs)}"
              + (f", mean {np.mean(offs):.3f}" if len(offs) > 1 else ""))


if __name__ == "__main__":
    main()
