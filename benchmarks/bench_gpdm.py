"""GPDM (Elnekave & Weiss 2022) next to tghop's default output, same exemplars, same size.

Each exemplar is the centre 256x256 of a shared texture. tghop: ``tghop fit`` (defaults)
then ``tghop synth --seed 0`` at SIZE, and the same with ``--quality best``;
GPDM: :func:`tghop.baselines.gpdm` (seed 0) at
SIZE with STEPS Adam steps per level (the paper's 300 by default). Both are scored
against the exemplar with SIFID, SWD, copied and copied_textured (``tghop.metrics``),
and timed (wall clock, on whatever the machine is also running).

    python benchmarks/bench_gpdm.py                                   # 3 textures, 128x128, 300 steps
    python benchmarks/bench_gpdm.py --textures knit --size 256 --tag 256
    python benchmarks/bench_gpdm.py --steps 100 --tag s100
    python benchmarks/bench_gpdm.py --size 256 --tag 256x10 --resume --textures a,b,...  # add to a run

``--resume`` keeps the rows of an earlier run with the same tag and computes only the
missing ones (GPDM takes minutes per exemplar).

Writes ``benchmarks/results/gpdm[-TAG].{json,md}`` and the images in ``results/gpdm[-TAG]/``.
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, markdown_table, texture, write_results  # noqa: E402

TEXTURES = ("beach_gravel", "brick_wall", "knit")
METRICS = ("sifid", "swd", "copied", "copied_textured")


def log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def centre(img, side=256):
    h, w = img.shape[:2]
    if h < side or w < side:
        return img
    y, x = (h - side) // 2, (w - side) // 2
    return img[y : y + side, x : x + side]


def tghop_cli(*args):
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parent.parent / "src"))
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "tghop", *map(str, args), "-q"], check=True, env=env)
    return time.perf_counter() - t


def scores(ex, img):
    from tghop import metrics as M

    out = {}
    for name in METRICS:
        fn = M.copied_textured if name == "copied_textured" else M.METRICS[name].function
        out[name] = float(fn(ex, img))
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--textures", default=",".join(TEXTURES))
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--steps", type=int, default=300, help="GPDM Adam steps per level (paper: 300)")
    parser.add_argument("--tag", default="")
    parser.add_argument("--render", action="store_true", help="only rewrite the .md from the .json of a run")
    parser.add_argument("--resume", action="store_true", help="keep an earlier run's rows; compute the missing ones")
    args = parser.parse_args(argv)
    if args.render:
        import json

        name = "gpdm" + (f"-{args.tag}" if args.tag else "")
        payload = json.loads((RESULTS / f"{name}.json").read_text())
        write_results(name, payload, render(payload))
        print(render(payload))
        return

    from tghop.baselines import gpdm
    from tghop.imageio import save_image

    name = "gpdm" + (f"-{args.tag}" if args.tag else "")
    images = RESULTS / name
    images.mkdir(parents=True, exist_ok=True)
    payload = []
    if args.resume and (RESULTS / f"{name}.json").exists():
        import json

        payload = json.loads((RESULTS / f"{name}.json").read_text())
    have = {(p["texture"], p["method"]) for p in payload}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for tex in filter(None, args.textures.split(",")):
            from tghop.imageio import load_image

            ex = centre(texture(tex))
            runs = []  # (method, image, seconds, detail)
            if (tex, "tghop") not in have or (tex, "tghop-best") not in have:
                save_image(ex, tmp / f"{tex}.png")
                log(f"{tex}: tghop fit + synth at {args.size}")
                fit_s = tghop_cli("fit", tmp / f"{tex}.png", "-o", tmp / f"{tex}.npz")
                for method, extra in (("tghop", ()), ("tghop-best", ("--quality", "best"))):
                    if (tex, method) in have:
                        continue
                    out = images / f"{tex}-{method}.png"
                    synth_s = tghop_cli("synth", tmp / f"{tex}.npz", "-o", out, "--size", args.size, "--seed", 0,
                                        *extra)
                    runs.append((method, load_image(out), fit_s + synth_s,
                                 f"fit {fit_s:.0f} s + synth {synth_s:.1f} s"))
            if (tex, "gpdm") not in have:
                log(f"{tex}: gpdm at {args.size}, {args.steps} steps per level")
                t = time.perf_counter()
                theirs, info = gpdm(ex, args.size, rng=0, n_steps=args.steps, return_info=True)
                gpdm_s = time.perf_counter() - t
                save_image(theirs, images / f"{tex}-gpdm.png")
                runs.append(("gpdm", theirs, gpdm_s, f"{len(info['levels'])} levels x {args.steps} steps"))
            for method, img, seconds, detail in runs:
                s = scores(ex, img)
                log(f"{tex} {method}: {seconds:.1f} s {s}")
                payload.append({"texture": tex, "method": method, "seconds": seconds, "detail": detail, **s,
                                "size": args.size, "steps": args.steps if method == "gpdm" else None})
            order = {"tghop": 0, "tghop-best": 1, "gpdm": 2}
            payload.sort(key=lambda p: (p["texture"], order.get(p["method"], 3)))
            write_results(name, payload, render(payload))  # after every texture: a partial table survives
    print(render(payload))


def render(payload) -> str:
    """The markdown table of a (possibly partial) list of rows."""
    size, steps = payload[0]["size"], max(p["steps"] or 0 for p in payload)
    rows = [[p["texture"], p["method"], round(p["seconds"], 1), p["detail"], *(p[m] for m in METRICS)] for p in payload]
    return (
        f"# GPDM vs tghop ({size}x{size} from the centre 256x256 of each exemplar)\n\n"
        f"GPDM: `tghop.baselines.gpdm`, seed 0, {steps} Adam steps per level (paper: 300), 64 projections, "
        "7x7 patches, scale factor 0.85, coarsest side 21. tghop: `tghop fit` (defaults), `tghop synth --seed 0` "
        "(tghop-best: with `--quality best`). "
        "Seconds: wall clock on a shared 2-core machine (tghop: fit + synth). Lower is better for every metric; "
        "copied and copied_textured are fractions of 16x16 result windows within RMS 0.03 of an exemplar window.\n\n"
        + markdown_table(["texture", "method", "seconds", "detail", *METRICS], rows)
        + "\n\nMedians over the exemplars that have all three rows:\n\n" + medians(payload)
    )


def medians(payload) -> str:
    """Per method, the medians over the textures that every method reached."""
    methods = sorted({p["method"] for p in payload}, key=("tghop", "tghop-best", "gpdm").index)
    done = [t for t in sorted({p["texture"] for p in payload})
            if all(any(p["texture"] == t and p["method"] == m for p in payload) for m in methods)]
    rows = []
    for m in methods:
        sel = [p for p in payload if p["method"] == m and p["texture"] in done]
        rows.append([m, len(sel), *(float(np.median([p[k] for p in sel])) for k in ("seconds", *METRICS))])
    return markdown_table(["method", "textures", "seconds", *METRICS], rows)


if __name__ == "__main__":
    main()
