"""The block grid: how much the quilting seams show, with and without the seam removal.

For each texture a model (fitted here on the exemplar as ``bench_quality.py`` prepares it,
or read from ``--models DIR/NAME.npz``) synthesises ``--size`` images (seeds 0 and 1) at each
``--windows`` value of ``seam_window`` (0: quilting's plain minimum-error cuts, tghop 0.15;
9: the default; 1: every seam edge on its own; :mod:`tghop.seams`). The *grid contrast*
of an image is the mean absolute difference between neighbouring pixels across the
quilting grid's overlap bands (where the cuts run), over the same mean elsewhere, averaged
over the two axes: about 1 where no grid shows (the exemplar measured at the same places
gives the reference), above 1 where block edges stand out. Also the in-process time of
each synthesis (noisy on a shared machine).

    python benchmarks/bench_seams.py                      # the default ten textures
    python benchmarks/bench_seams.py blue_bubbles knit --size 1024 --windows 0,9,1 --sheet
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _common import RESULTS, image_sheet, markdown_table, write_results
from bench_quality import prepare

DEFAULT = ["blue_bubbles", "orange_blobs", "clouds_192", "water_caustics", "beach_gravel", "brick_wall", "knit",
           "burl_wood", "grass_lawn", "stone_wall"]


def grid_contrast(img, plan) -> float:
    """Mean |difference| across the overlap bands of ``plan`` over the mean elsewhere."""
    ratios = []
    for axis, starts in ((1, plan.xs), (0, plan.ys)):
        d = np.abs(np.diff(img, axis=axis)).mean(axis=(1 - axis, 2))  # one value per edge line
        band = np.zeros(d.size, dtype=bool)
        for s in starts[1:]:
            band[max(s - 1, 0) : s + plan.overlap - 1] = True  # a cut at c separates c - 1 and c
        if band.any() and (~band).any():
            ratios.append(d[band].mean() / d[~band].mean())
    return float(np.mean(ratios))


def main():
    from tghop import TGHop
    from tghop.modelfile import load_model
    from tghop.quilting import quilting_plan

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("textures", nargs="*", default=DEFAULT)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--models", default=None, help="read DIR/NAME.npz instead of fitting")
    ap.add_argument("--windows", default="0,9,1", help="seam_window values, comma-separated (default 0,9,1)")
    ap.add_argument("--sheet", action="store_true", help="a sheet per texture: exemplar | each window")
    ap.add_argument("--tag", default="")
    args = ap.parse_args()
    windows = [int(v) for v in args.windows.split(",")]

    rows, entries = [], []
    for name in args.textures:
        exemplar = prepare(name)
        model = load_model(f"{args.models}/{name}.npz") if args.models else TGHop().fit(exemplar)
        plan = quilting_plan((args.size, args.size), model.patch_size)
        ref_plan = quilting_plan(exemplar.shape[:2], model.patch_size)
        entry = {"texture": name, "exemplar": grid_contrast(exemplar, ref_plan), "windows": {}}
        images = []
        for window in windows:
            contrast, seconds = [], []
            for seed in (0, 1):
                t0 = time.perf_counter()
                img = model.synthesize((args.size, args.size), rng=seed, seam_window=window, dtype=np.float32)
                seconds.append(time.perf_counter() - t0)
                contrast.append(grid_contrast(img, plan))
                if seed == 0:
                    images.append(img)
            entry["windows"][window] = {"grid_contrast": float(np.mean(contrast)), "seconds": float(np.median(seconds))}
        entries.append(entry)
        rows.append([name, entry["exemplar"]] + [entry["windows"][v]["grid_contrast"] for v in windows]
                    + [entry["windows"][v]["seconds"] for v in windows])
        print(name, " ".join(f"w{v} {entry['windows'][v]['grid_contrast']:.3f}" for v in windows),
              f"(exemplar {entry['exemplar']:.3f})", flush=True)
        if args.sheet:
            from tghop.imageio import save_image

            sheet = image_sheet([exemplar, *images], ["exemplar"] + [f"seam_window {v}" for v in windows],
                                height=args.size)
            save_image(sheet, RESULTS / f"seams-{name}{args.tag}.png")
    header = (["texture", "exemplar"] + [f"window {v}" for v in windows] + [f"window {v} s" for v in windows])
    med = ["median"] + [float(np.median([r[i] for r in rows])) for i in range(1, len(header))]
    md = (f"## Grid contrast at {args.size}x{args.size}, seeds 0 and 1 (1: no grid), by seam_window\n\n"
          + markdown_table(header, rows + [med]))
    print(md)
    write_results(f"seams{args.tag}", {"size": args.size, "windows": windows, "entries": entries}, md)


if __name__ == "__main__":
    main()
