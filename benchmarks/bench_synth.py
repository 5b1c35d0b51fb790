"""Time of one image from a fitted model (tghop's default pipeline), split into its stages
(coarse layout, patch pool, quilting, refinement, colour matching, patch refinement), at 256x256 and
2048x2048, on brick_wall and three more textures; a sheet of the images next to each
exemplar.

    python benchmarks/bench_synth.py [--textures brick_wall,...] [--big 2048] [--repeats 3]

Writes benchmarks/results/synth.{json,md} and synth_sheet.png.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (RESULTS, StageTimer, image_sheet, markdown_table, peak_rss_mb, stack_rows, texture,  # noqa: E402
                     write_results)

DEFAULT = "brick_wall,grass_lawn,knit,red_peppers"


def one_image(model, size, seed, tile=False):
    """``model.synthesize`` timed stage by stage (its progress stages): (image, {stage: s}, total s)."""
    timer = StageTimer()
    t = time.perf_counter()
    img = model.synthesize(size, rng=seed, tile=tile, progress=timer)
    total = time.perf_counter() - t
    return img, timer.finish(), total


#: ``synthesize``'s progress stages in the order they run ("patch refine" last: after the colours).
STAGES = ("layout", "patch pool", "quilting", "refine", "colour", "patch refine")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--textures", default=DEFAULT)
    ap.add_argument("--big", type=int, default=2048, help="side of the large image (0 skips it)")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()

    from tghop.imageio import save_image
    from tghop.synthesis import TGHop

    rows, payload, sheet_rows = [], [], []
    for name in args.textures.split(","):
        exemplar = texture(name)
        t = time.perf_counter()
        model = TGHop(rng=0).fit(exemplar)
        fit_s = time.perf_counter() - t
        runs = [one_image(model, (256, 256), seed=r) for r in range(args.repeats)]
        img, stages, total = min(runs, key=lambda r: r[2])
        tiled, _, tiled_s = one_image(model, (256, 256), seed=99, tile=True)
        entry = {"texture": name, "fit_s": fit_s, "stages_256_s": stages, "total_256_s": total, "tiled_256_s": tiled_s}
        row = [name, fit_s, *(stages.get(k, 0.0) for k in STAGES), total, tiled_s]
        crop = None
        if args.big:
            rss0 = peak_rss_mb()
            big, big_stages, big_s = one_image(model, (args.big, args.big), seed=7)
            entry.update(big_side=args.big, big_stages_s=big_stages, big_total_s=big_s,
                         big_image_mb=big.nbytes / 2**20, peak_rss_growth_mb=peak_rss_mb() - rss0)
            row.append(big_s)
            crop = big[:512, :512]
        payload.append(entry)
        rows.append(row)
        cols = [exemplar, img, tiled, np.tile(tiled, (2, 2, 1))[:384, :384]] + ([crop] if crop is not None else [])
        labels = (["exemplar", "256x256", "tileable", "tileable 2x2"]
                  + ([f"{args.big}^2 crop"] if crop is not None else []))
        sheet_rows.append(image_sheet(cols, labels))
    header = ["texture", "fit (s)", *(f"{k} (s)" for k in STAGES), "256x256 total (s)", "256x256 tiled (s)"]
    if args.big:
        header.append(f"{args.big}^2 total (s)")
    text = ("## One image from a fitted model, default pipeline (targets: 256x256 <= 1 s, 2048x2048 <= 20 s; "
            f"best of {args.repeats} at 256x256)\n\n")
    text += markdown_table(header, rows)
    text += ("\n\nPaper (12 CPUs of an i7-5930K: 6 cores, 12 threads): 205.5 s per 256x256 image, of which quilting "
             "8.08 s.\n")
    if args.big:
        text += "\nMemory growth during the large image (peak RSS, MB): " + ", ".join(
            f"{e['texture']} {e['peak_rss_growth_mb']:.0f} (image {e['big_image_mb']:.0f})" for e in payload)
    print(text)
    write_results("synth", payload, text)
    save_image(stack_rows(sheet_rows), RESULTS / "synth_sheet.png")
    print(f"\nsheet: {RESULTS / 'synth_sheet.png'}")


if __name__ == "__main__":
    main()
