"""Small exemplars (a game artist's 64x64 or 48x48 tile): automatic settings against alternatives.

For each texture and each ``--sides`` S, the centre SxS crop is fitted and a ``--size`` image made
with each ``--variant LABEL:stride=S,per=K`` (N = the training patches // K, at least 1; ``per=auto``:
the automatic N, ``n_clusters=None``), fit and synthesis seed each of ``--seeds``, every other
setting the default. Per image: SIFID, SWD, :func:`tghop.metrics.copied_textured` against the crop
(verbatim pieces of a 64 px exemplar are a failure whatever the other scores) and the output's
:func:`tghop.metrics.self_repetition`; per side and variant: the median SIFID, the geometric mean of
the SIFID ratios against the first variant, the median SWD, the mean and largest copied_textured, the
images over 0.01 of it, the median self-repetition. ``--sheet`` writes, per side, a PNG of each
texture's crop and its first seed's images, one row per texture, to look at. docs/choices.md, ICHM
"0.58: small exemplars" (a crop that fails is listed with its error).

    python benchmarks/bench_small.py --tag small-058 --sheet
    python benchmarks/bench_small.py --sides 38,42,48,56,64,76,96 --variant auto:stride=2,per=auto --seeds 0
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from _common import RESULTS, image_sheet, markdown_table, stack_rows, texture, write_results

TEXTURES = ["brick_wall", "knit", "blue_bubbles", "grass_lawn", "red_peppers", "leopard", "stone_wall_256",
            "rust_paint", "beach_gravel", "plaid", "hexagon_tiles", "text_gray"]
VARIANTS = ["auto:stride=2,per=auto", "per20:stride=2,per=20", "per40:stride=2,per=40", "stride1:stride=1,per=auto"]
HEADER = ["side", "variant", "N", "images", "median SIFID", "SIFID ratio", "median SWD", "copied_textured mean",
          "largest", "over 0.01", "self-repetition median"]


def parse_variant(spec: str):
    """``LABEL:stride=S,per=K`` -> (label, stride, per or None)."""
    label, _, items = spec.partition(":")
    kw = dict(item.split("=") for item in filter(None, items.split(",")))
    per = kw.get("per", "auto")
    return label, int(kw.get("stride", 2)), None if per == "auto" else int(per)


def crop(image, side):
    image = image[..., :3] if image.ndim == 3 else image
    h, w = image.shape[:2]
    y, x = (h - side) // 2, (w - side) // 2
    return np.ascontiguousarray(image[y : y + side, x : x + side])


def main():
    from tghop import TGHop, TGHopError, metrics
    from tghop.imageio import save_image

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("textures", nargs="*", default=TEXTURES)
    ap.add_argument("--sides", default="64,48")
    ap.add_argument("--variant", action="append", help="LABEL:stride=S,per=K (repeatable; default: four)")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--size", type=int, default=192)
    ap.add_argument("--tag", default="small")
    ap.add_argument("--sheet", action="store_true")
    args = ap.parse_args()
    variants = [parse_variant(v) for v in args.variant or VARIANTS]
    sides, seeds = [int(s) for s in args.sides.split(",")], [int(s) for s in args.seeds.split(",")]
    rows, sheets = [], {side: [] for side in sides}
    for name in args.textures:
        image = texture(name)
        for side in sides:
            ex = crop(image, side)
            shown = [ex]
            for label, stride, per in variants:
                n = len(range(0, side - 31, stride)) ** 2
                n_clusters = None if per is None else max(1, n // per)
                for seed in seeds:
                    row = dict(texture=name, side=side, variant=label, seed=seed, patches=n)
                    try:
                        model = TGHop(stride=stride, n_clusters=n_clusters, rng=seed).fit(ex)
                        out = model.synthesize((args.size, args.size), rng=seed)
                    except TGHopError as exc:
                        print(json.dumps({**row, "error": str(exc)}), flush=True)
                        rows.append({**row, "error": str(exc)})
                        continue
                    scores = metrics.evaluate(ex, out, metrics=["sifid", "swd", "copied_textured"])
                    row.update(N=model.ichm_.clusters_for(model.n_patches_), **{k: float(v) for k, v in scores.items()},
                               self_repetition=float(metrics.self_repetition(out)))
                    print(json.dumps(row), flush=True)
                    rows.append(row)
                    if seed == seeds[0]:
                        shown.append(out)
            sheets[side].append(image_sheet(shown, [f"{name} {side}"] + [v[0] for v in variants][: len(shown) - 1],
                                            height=args.size))
    table = []
    for side in sides:
        done = [r for r in rows if r["side"] == side and "error" not in r]
        base = {(r["texture"], r["seed"]): r["sifid"] for r in done if r["variant"] == variants[0][0]}
        for label, _, _ in variants:
            rs = [r for r in done if r["variant"] == label]
            if not rs:
                continue
            ratios = [r["sifid"] / base[r["texture"], r["seed"]] for r in rs if (r["texture"], r["seed"]) in base]
            copied = [r["copied_textured"] for r in rs]
            table.append([side, label, "/".join(sorted({str(r["N"]) for r in rs})), len(rs),
                          float(np.median([r["sifid"] for r in rs])), float(np.exp(np.mean(np.log(ratios)))),
                          float(np.median([r["swd"] for r in rs])), float(np.mean(copied)), float(max(copied)),
                          sum(c > 0.01 for c in copied), float(np.median([r["self_repetition"] for r in rs]))])
    failed = [f"- {r['texture']} {r['side']} {r['variant']}: {r['error']}" for r in rows if "error" in r]
    md = markdown_table(HEADER, table) + ("\n\nFailed:\n" + "\n".join(failed) if failed else "")
    print(md)
    write_results(args.tag, rows, md)
    if args.sheet:
        for side, sheet in sheets.items():
            save_image(stack_rows(sheet), RESULTS / f"{args.tag}-{side}.png")


if __name__ == "__main__":
    main()
