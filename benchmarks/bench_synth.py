"""Issue: texture images of any size. Time of one image from a fitted model, split into
pool generation and quilting, at 256x256 and 2048x2048, on brick_wall and three more
textures; a sheet of the images next to each exemplar.

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
from _common import RESULTS, image_sheet, markdown_table, peak_rss_mb, stack_rows, texture, write_results  # noqa: E402

DEFAULT = "brick_wall,grass_lawn,knit,red_peppers"


def one_image(model, size, seed, tile=False):
    """What ``model.synthesize`` does, timed stage by stage: (image, pool s, quilting s, colour s)."""
    from tghop.colour import match_histograms
    from tghop.quilting import quilt

    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    pool = model.sample_patches(10_000, rng=rng, dtype=np.float32)
    t1 = time.perf_counter()
    img = quilt(pool, size, rng=rng, tile=tile)
    t2 = time.perf_counter()
    img = match_histograms(img, model.colour_quantiles_, out=img)
    t3 = time.perf_counter()
    return img, t1 - t0, t2 - t1, t3 - t2


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
        model.sample_patches(model.ichm_.n_cdfs_ + 1, rng=0, dtype=np.float32)  # builds the folded decoder once
        best = None
        for r in range(args.repeats):
            img, pool_s, quilt_s, colour_s = one_image(model, (256, 256), seed=r)
            if best is None or pool_s + quilt_s + colour_s < sum(best[1:]):
                best = (img, pool_s, quilt_s, colour_s)
        tiled, tp, tq, tc = one_image(model, (256, 256), seed=99, tile=True)
        entry = {"texture": name, "fit_s": fit_s, "pool_s": best[1], "quilt_s": best[2], "colour_s": best[3],
                 "total_256_s": sum(best[1:]), "tiled_256_s": tp + tq + tc}
        if args.big:
            rss0 = peak_rss_mb()
            big, bp, bq, bc = one_image(model, (args.big, args.big), seed=7)
            entry.update(big_side=args.big, big_pool_s=bp, big_quilt_s=bq, big_colour_s=bc, big_total_s=bp + bq + bc,
                         big_image_mb=big.nbytes / 2**20, peak_rss_growth_mb=peak_rss_mb() - rss0)
            crop = big[:512, :512]
        else:
            crop = None
        payload.append(entry)
        rows.append([name, fit_s, best[1], best[2], best[3], sum(best[1:]), tp + tq + tc]
                    + ([bp, bq, bc, bp + bq + bc] if args.big else []))
        cols = [exemplar, best[0], tiled, np.tile(tiled, (2, 2, 1))[:384, :384]] + ([crop] if crop is not None else [])
        labels = ["exemplar", "256x256", "tileable", "tileable 2x2"] + ([f"{args.big}^2 crop"] if crop is not None else [])
        sheet_rows.append(image_sheet(cols, labels))
    header = ["texture", "fit (s)", "pool 10k (s)", "quilting (s)", "colour (s)", "256x256 total (s)",
              "256x256 tiled (s)"]
    if args.big:
        header += [f"{args.big}^2 pool (s)", f"{args.big}^2 quilting (s)", f"{args.big}^2 colour (s)",
                   f"{args.big}^2 total (s)"]
    text = "## One image from a fitted model (targets: 256x256 <= 1 s, 2048x2048 <= 15 s)\n\n"
    text += markdown_table(header, rows)
    text += "\n\nPaper (12-core i7, 2015): 205.5 s per 256x256 image, of which quilting 8.08 s.\n"
    if args.big:
        text += "\nMemory growth during the large image (peak RSS, MB): " + ", ".join(
            f"{e['texture']} {e['peak_rss_growth_mb']:.0f} (image {e['big_image_mb']:.0f})" for e in payload)
    print(text)
    write_results("synth", payload, text)
    save_image(stack_rows(sheet_rows), RESULTS / "synth_sheet.png")
    print(f"\nsheet: {RESULTS / 'synth_sheet.png'}")


if __name__ == "__main__":
    main()
