"""How much of ``copied_textured`` is copying: tghop's outputs against an unseen piece of the same texture.

``copied_textured`` counts a textured 16x16 window of an output as copied when some exemplar
window is within RMS 0.03 of it. On smooth or strictly regular exemplars a texture's own
unseen parts score that way too. For each exemplar (as ``bench_quality.py`` prepares it:
larger than 512 px, its centre 256x256) this script splits it into a top half A and a bottom
half B and reports:

- **natural**: B's windows found in A and A's in B (the mean): what a new piece of the same
  texture, which nobody copied, scores against a reference of that size;
- **natural, blurred**: the same with the scored half smoothed (Gaussian, ``--blur`` pixels):
  a smooth window matches more easily, so a smoother output scores higher without copying;
- **tghop / half**: tghop's 256x256 outputs (seeds 0, 1, ...; the model fitted on the whole
  exemplar, or read from ``--models DIR/NAME.npz``) scored against A and against B (the mean):
  the same reference as "natural";
- **tghop / whole**: the outputs against the whole exemplar (``bench_quality.py``'s number).

An output that pastes exemplar pieces scores far above "natural"; one that makes new texture
scores about as its own exemplar's halves do. ``--threshold`` and ``--patch-size`` score at
other settings than the metric's defaults (RMS 0.03, 16x16): a verbatim piece still counts at
RMS 0.015, or over 32x32 windows (a quilting block), where a smooth window's natural twins no
longer do (0.59, docs/choices.md, Metrics and baselines).

    python benchmarks/bench_copies.py --tag s50
    python benchmarks/bench_copies.py --models /tmp/models clouds_192 blue_bubbles leopard
    python benchmarks/bench_copies.py --threshold 0.015 --tag strict clouds_192 orange_blobs
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path

import numpy as np

from _common import markdown_table, texture_names, write_results

HEADER = ["texture", "natural", "natural, blurred", "tghop / half", "tghop / whole", "tghop / half over natural"]


def score(name, models, seeds, blur, fit_seed, threshold=0.03, patch_size=16):
    from scipy.ndimage import gaussian_filter

    from bench_quality import prepare
    from tghop import TGHop
    from tghop.metrics import copied_textured
    from tghop.modelfile import load_model

    ex = prepare(name)
    h = ex.shape[0] // 2
    a, b = ex[:h], ex[h:2 * h]
    path = Path(models) / f"{name}.npz" if models else None
    model = load_model(path) if path and path.exists() else TGHop(rng=fit_seed).fit(ex)
    outputs = [model.synthesize((256, 256), rng=s) for s in range(seeds)]
    smooth = (lambda img: gaussian_filter(img, (blur, blur, 0))) if blur > 0 else (lambda img: img)
    copied = partial(copied_textured, threshold=threshold, patch_size=patch_size)
    return name, {
        "natural": float(np.mean([copied(a, b), copied(b, a)])),
        "natural_blurred": float(np.mean([copied(a, smooth(b)), copied(b, smooth(a))])),
        "tghop_half": float(np.mean([copied(ref, out) for ref in (a, b) for out in outputs])),
        "tghop_whole": float(np.mean([copied(ex, out) for out in outputs])),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("textures", nargs="*", help="exemplar names (default: every shared texture)")
    ap.add_argument("--models", default=None, help="folder of NAME.npz model files (fitted here where absent)")
    ap.add_argument("--fit-seed", type=int, default=0)
    ap.add_argument("--seeds", type=int, default=2, help="outputs per exemplar (seeds 0, 1, ...)")
    ap.add_argument("--blur", type=float, default=0.8, help="Gaussian sigma of 'natural, blurred' in pixels")
    ap.add_argument("--threshold", type=float, default=0.03, help="RMS below which a window is a copy")
    ap.add_argument("--patch-size", type=int, default=16, help="window side in pixels")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--tag", default="")
    args = ap.parse_args(argv)
    names = args.textures or texture_names()
    if not names:
        raise SystemExit("no textures: pass names or put exemplars in ../shared/textures (TGHOP_TEXTURES)")
    t = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        one = partial(score, models=args.models, seeds=args.seeds, blur=args.blur, fit_seed=args.fit_seed,
                      threshold=args.threshold, patch_size=args.patch_size)
        rows = dict(pool.map(one, names))
    table = []
    for name in names:
        r = rows[name]
        ratio = r["tghop_half"] / r["natural"] if r["natural"] > 0 else (float("inf") if r["tghop_half"] else 1.0)
        table.append([name, r["natural"], r["natural_blurred"], r["tghop_half"], r["tghop_whole"], ratio])
    md = (f"## copied_textured: tghop against its exemplar's halves ({args.seeds} outputs of 256x256 each, "
          f"blur sigma {args.blur:g}, {args.patch_size}x{args.patch_size} windows within RMS {args.threshold:g})"
          f"\n\n" + markdown_table(HEADER, table))
    print(md)
    print(f"\n{time.perf_counter() - t:.0f} s")
    write_results(f"copies{'-' + args.tag if args.tag else ''}", {"args": vars(args), "rows": rows}, md)


if __name__ == "__main__":
    main()
