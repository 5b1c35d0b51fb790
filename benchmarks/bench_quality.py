"""Picture quality over many exemplars: TGHop variants side by side, medians, ablations.

Every exemplar (``../shared/textures``; larger than 512 px: its centre 256x256, as in
``bench_paper.py``; with ``--whole`` the whole exemplar, as a user gives it) is fitted once
per distinct fit setting; each variant then makes a 256x256 image with seed 0 and one with
seed 1 (``--seeds``: others, or more), and ``tghop.metrics`` scores each against the
exemplar (SIFID, SWD, co-occurrence, copied, copied_textured) plus the diversity between
them. The table gives medians over exemplars (of the seeds' mean), the maxima of ``copied``
and ``copied_textured`` (issue #25: median <= 0.02, maximum <= 0.10), and the fit and per-
image times; a second table compares each variant with the first, exemplar by exemplar
(geometric mean of the ratios, how many got better, the largest changes): a variant that
changes the layout moves single exemplars by 10-20 % by chance with two seeds, so look there
before at the medians.

    python benchmarks/bench_quality.py                                 # all exemplars, paper + default
    python benchmarks/bench_quality.py --textures knit,brick_wall --variants default
    python benchmarks/bench_quality.py --variant 'n100:fit.n_clusters=100'  # an ad-hoc variant
    python benchmarks/bench_quality.py --variants default --variant 'o8:synth.overlap=8' --seeds 0,1,2,3
    python benchmarks/bench_quality.py --ust knit,brick_wall --ust-size 128 --ust-iterations 100

A variant is ``name:fit.KEY=VALUE,synth.KEY=VALUE,...`` (VALUE a Python literal), or one
of the named VARIANTS below. Its settings reach the fine model and the fine level's
synthesis only: the coarse layout model (``CoarseLayout``) is fitted with TGHop's *defaults*
for every setting it does not set itself (``max_component_ratio``, ``coupling``, ...), and the
guide is quilted with its own ``detail`` (``layout.GUIDE_DETAIL``). So a variant measures a
new default of such a setting with the old coarse model; once the default is changed, run
``--variants default`` again (0.40's ``max_component_ratio`` changed the coarse model too).
A variant with ``fit.scale`` (the working scale, :mod:`tghop.scale`) is scored against the
exemplar resampled by it: the texture it was asked to make. ``--sheets`` writes one image per
exemplar (exemplar | each variant, seed 0). With
``--ust``, the Ustyuzhaninov baseline runs on those exemplars at ``--ust-size`` next to
every variant at the same size (slow: minutes per exemplar; its images are kept in
``results/ust-cache/`` and reused, since they do not depend on tghop).

``--against RESULTS.json[:VARIANT]`` compares the variants with a variant of an earlier
run instead of with the first (exemplar by exemplar, as above): a change that no variant
can express (a module constant, a worktree of other code run with ``PYTHONPATH``) against
the saved default, without running the default again. The runs are deterministic on one
machine, so this is only fair with the same size, seeds and fit seed (checked where the
saved run records them; older results do not) and the same exemplars (compared on those
in both).

    python benchmarks/bench_quality.py --variants '' --variant 'r6:fit.max_component_ratio=0.6' \
        --against benchmarks/results/quality-base.json:default

Writes ``benchmarks/results/quality[-TAG].{json,md}`` (and ``quality[-TAG]/*.png``).
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import re
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, image_sheet, markdown_table, texture, texture_names, write_results  # noqa: E402

EXEMPLAR_MAX = 512  # larger exemplars are replaced by their centre crop (as bench_paper.py)
CENTRE_CROP = 256
METRICS = ("sifid", "swd", "cooccurrence", "copied", "copied_textured")
#: Metrics whose maximum over exemplars is reported too.
MAXIMA = ("copied", "copied_textured")

#: Named variants: (fit keyword arguments of TGHop, synthesize keyword arguments).
VARIANTS = {
    "paper": ("PAPER", "PAPER"),  # the paper values of tghop.settings (fit and generation)
    "default": ({}, {}),
    # Ablation: each step of tghop's pipeline beyond the paper switched off (or on) alone.
    "no-layout": ({"layout_factor": None}, {}),
    "no-refine": ({}, {"refine": 0}),
    "no-detail": ({}, {"detail": 0.0}),
    "no-colour": ({}, {"match_colours": False}),
    "no-patch-refine": ({}, {"patch_refine": 0}),  # the default until tghop 0.20
    "no-seams": ({}, {"seam_window": 0}),  # quilting's plain cuts (tghop 0.15's default)
    "no-norm-match": ({"norm_match": 0.0}, {}),  # the core model's draws not rescaled to its norms (before 0.28)
    "no-coupling": ({"coupling": 0.0}, {}),  # the core model's components drawn independently (before 0.29)
    "best": ({}, "BEST"),  # tghop synth --quality best
    "pool10k": ({}, {"n_patches": 10000}),
    "residual": ({"residual": True}, {}),
    # The defaults of tghop 0.1: colour matching and the larger per-cluster model only.
    "tghop-0.1": ({"layout_factor": None}, {"detail": 0.0, "refine": 0, "n_patches": 10000}),
}


def log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def parse_variant(spec: str):
    """``name:fit.k=v,synth.k=v`` -> (name, fit kwargs, synth kwargs); a bare name looks up VARIANTS."""
    if ":" not in spec:
        if spec not in VARIANTS:
            raise SystemExit(f"unknown variant {spec!r}; named ones: {', '.join(VARIANTS)} (or name:fit.k=v,...)")
        return (spec, *VARIANTS[spec])
    name, _, body = spec.partition(":")
    fit_kw, synth_kw = {}, {}
    # Items are split at commas that start a new item, so a value may be a tuple: fit.n_channels=(12,30).
    for item in filter(None, (s.strip() for s in re.split(r",(?=\s*(?:fit|synth)\.)", body))):
        key, _, value = item.partition("=")
        where, _, key = key.partition(".")
        if where not in ("fit", "synth") or not key:
            raise SystemExit(f"bad variant item {item!r}: use fit.KEY=VALUE or synth.KEY=VALUE")
        try:
            value = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            pass  # a bare word stays a string
        (fit_kw if where == "fit" else synth_kw)[key] = value
    return name, fit_kw, synth_kw


def prepare(name: str, whole: bool = False):
    img = texture(name)
    h, w = img.shape[:2]
    if max(h, w) > EXEMPLAR_MAX and not whole:
        y, x = (h - CENTRE_CROP) // 2, (w - CENTRE_CROP) // 2
        return img[y:y + CENTRE_CROP, x:x + CENTRE_CROP].copy()
    return img


def fit_kwargs(fit_kw, exemplar):
    from tghop.synthesis import PAPER_TABLE4, prepare_exemplar

    kw = dict(PAPER_TABLE4) if fit_kw == "PAPER" else dict(fit_kw)
    if kw.get("n_channels") and prepare_exemplar(exemplar).shape[2] == 1:
        kw.pop("n_channels")  # K1 = 9 cannot be on one channel: the default grey channels
    return kw


def synth_kwargs(synth_kw):
    from tghop.settings import QUALITY, generate_settings

    if synth_kw == "PAPER":
        return {s.name: s.paper for s in generate_settings() if s.has_paper}
    return dict(QUALITY["best"]) if synth_kw == "BEST" else dict(synth_kw)


def score(exemplar, image, metrics):
    from tghop.metrics import evaluate

    return dict(evaluate(exemplar, image, metrics=list(metrics)))


def _init_worker():
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass


def task(name, variants, size, metrics, sheets, fit_seed=0, seeds=(0, 1), whole=False):
    """Fit ``name`` (``whole``: not cropped) once per distinct fit setting (seed ``fit_seed``), run every
    variant with ``seeds``, score."""
    from tghop import TGHop
    from tghop.metrics import diversity

    from tghop.scale import rescale

    exemplar = prepare(name, whole)
    models, out, images = {}, {}, {}
    for vname, fit_kw, synth_kw in variants:
        kw = fit_kwargs(fit_kw, exemplar)
        key = repr(sorted(kw.items()))
        if key not in models:
            t = time.perf_counter()
            models[key] = (TGHop(**kw, rng=fit_seed).fit(exemplar), time.perf_counter() - t)
        model, fit_s = models[key]
        results, synth_s = [], []
        for seed in seeds:
            t = time.perf_counter()
            results.append(model.synthesize(size, rng=seed, **synth_kwargs(synth_kw)))
            synth_s.append(time.perf_counter() - t)
        reference = rescale(exemplar, model.scale)  # what the model was asked to reproduce (fit.scale)
        per_seed = [score(reference, r, metrics) for r in results]
        out[vname] = {
            **{m: float(np.mean([s[m] for s in per_seed])) for m in metrics},
            "diversity": diversity(*results),
            "fit_s": fit_s,
            "synth_s": float(np.median(synth_s)),
        }
        images[vname] = results[0]
    sheet = None
    if sheets:
        from tghop.imageio import save_image

        folder = Path(sheets)
        folder.mkdir(parents=True, exist_ok=True)
        sheet = folder / f"{name}.png"
        save_image(image_sheet([exemplar, *images.values()], ["exemplar", *images]), sheet)
    return {"texture": name, "shape": list(exemplar.shape), "variants": out, "sheet": str(sheet) if sheet else None}


def ust_task(name, variants, size, n_iter, metrics, whole=False):
    """The Ustyuzhaninov baseline next to each variant, all at ``size`` x ``size``, seed 0."""
    from tghop import TGHop
    from tghop.baselines import ustyuzhaninov

    from tghop.imageio import load_image, save_image

    exemplar = prepare(name, whole)
    # The baseline does not change with tghop.
    cached = RESULTS / "ust-cache" / f"{name}{'-whole' if whole else ''}-{size}-{n_iter}.png"
    t = time.perf_counter()
    if cached.exists():
        ust = load_image(cached)
    else:
        ust = ustyuzhaninov(exemplar, size, n_iter=n_iter, rng=0)
        cached.parent.mkdir(parents=True, exist_ok=True)
        save_image(ust, cached)
    row = {"texture": name, "ust_s": time.perf_counter() - t, "Ustyuzhaninov": score(exemplar, ust, metrics)}
    for vname, fit_kw, synth_kw in variants:
        model = TGHop(**fit_kwargs(fit_kw, exemplar), rng=0).fit(exemplar)
        row[vname] = score(exemplar, model.synthesize((size, size), rng=0, **synth_kwargs(synth_kw)), metrics)
    return row


def medians(entries, vname, metrics):
    rows = [e["variants"][vname] for e in entries if vname in e["variants"]]
    med = {k: float(np.median([r[k] for r in rows])) for k in (*metrics, "diversity", "fit_s", "synth_s")}
    for m in MAXIMA:
        if m in metrics:
            med[m + "_max"] = float(np.max([r[m] for r in rows]))
    return med


def _seeds(text):
    try:
        seeds = tuple(int(s) for s in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"seeds must be comma-separated integers, got {text!r}")
    if len(seeds) < 2 or len(set(seeds)) < len(seeds) or min(seeds) < 0:
        raise argparse.ArgumentTypeError(f"give at least two distinct seeds of at least 0, got {text!r}")
    return seeds


def against_first(entries, names, metrics, n_named=3):
    """Rows comparing each variant after the first with the first, exemplar by exemplar, in the
    metrics where lower is better (SIFID, SWD, co-occurrence): the geometric mean of the ratios,
    how many exemplars got better, and the ``n_named`` largest gains and losses."""
    rows = []
    for vname in names[1:]:
        for m in (m for m in ("sifid", "swd", "cooccurrence") if m in metrics):
            pairs = [(e["texture"], e["variants"][names[0]][m], e["variants"][vname][m]) for e in entries
                     if names[0] in e["variants"] and vname in e["variants"]]
            pairs = [(t, a, b) for t, a, b in pairs if a > 0 and b > 0]
            if not pairs:
                continue
            ratio = sorted((b / a, t, a, b) for t, a, b in pairs)
            geo = float(np.exp(np.mean([np.log(r[0]) for r in ratio])))
            better = sum(r[0] < 1 for r in ratio)

            def named(rs):
                return ", ".join(f"{t} {a:.3g} -> {b:.3g}" for _, t, a, b in rs)

            rows.append([vname, m, geo, f"{better} of {len(ratio)}", named([r for r in ratio[:n_named] if r[0] < 1]),
                         named([r for r in ratio[::-1][:n_named] if r[0] > 1])])
    return rows


def load_against(spec, args):
    """``PATH[:VARIANT]`` of ``--against`` -> (label, its fit and synth settings, texture -> its
    scores), or exit with one line: a missing file, an unknown variant, another size, seeds or
    fit seed."""
    path, _, vname = spec.partition(":")
    try:
        saved = json.loads(Path(path).read_text())
        names = [v["name"] for v in saved["variants"]]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SystemExit(f"--against: cannot read {path} as bench_quality.py results ({exc})")
    vname = vname or names[0]
    if vname not in names:
        raise SystemExit(f"--against: {path} has no variant {vname!r}; it has {', '.join(names)}")
    for key, ours in (("size", args.size), ("seeds", list(args.seeds)), ("fit_seed", args.fit_seed),
                      ("whole", args.whole)):
        theirs = saved.get(key, False if key == "whole" else ours)  # runs before --whole cropped
        if theirs != ours:
            raise SystemExit(f"--against: {path} was run with {key} {theirs}, this run with {ours}")
    if "seeds" not in saved:
        log(f"--against: {path} does not record its seeds and fit seed; it must have used these ones")
    settings = next(v for v in saved["variants"] if v["name"] == vname)
    scores = {e["texture"]: e["variants"][vname] for e in saved["entries"] if vname in e["variants"]}
    return f"{vname} ({Path(path).stem})", settings.get("fit", {}), settings.get("synth", {}), scores


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--textures", default=None, help="comma-separated exemplar names (default: all)")
    ap.add_argument("--variants", default="paper,default", help="comma-separated named variants")
    ap.add_argument("--variant", action="append", default=[],
                    help="an ad-hoc variant name:fit.k=v,synth.k=v (repeatable)")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--metrics", default=",".join(METRICS))
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--fit-seed", type=int, default=0,
                    help="the models' seed (default 0); another shows a refit's spread (large on a few exemplars)")
    ap.add_argument("--seeds", default="0,1", type=_seeds,
                    help="comma-separated generation seeds, at least two (default 0,1); more lower the noise")
    ap.add_argument("--sheets", action="store_true", help="one sheet per exemplar")
    ap.add_argument("--whole", action="store_true",
                    help="fit and score exemplars over 512 px whole, not their centre 256x256")
    ap.add_argument("--tag", default="", help="suffix of the result files")
    ap.add_argument("--against", default=None, metavar="RESULTS.json[:VARIANT]",
                    help="compare with VARIANT (default: its first) of an earlier run's results")
    ap.add_argument("--ust", default="", help="exemplars for the Ustyuzhaninov comparison (comma-separated)")
    ap.add_argument("--ust-size", type=int, default=128)
    ap.add_argument("--ust-iterations", type=int, default=100)
    args = ap.parse_args(argv)

    names = args.textures.split(",") if args.textures else texture_names()
    variants = ([parse_variant(v) for v in filter(None, args.variants.split(","))]
                + [parse_variant(v) for v in args.variant])
    metrics = tuple(m for m in args.metrics.split(",") if m)
    if not variants:
        ap.error("no variants: give --variants or --variant")
    saved = load_against(args.against, args) if args.against else None
    stem = "quality" + (f"-{args.tag}" if args.tag else "")
    sheets = str(RESULTS / stem) if args.sheets else None
    size = (args.size, args.size)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{stem}.partial.jsonl").unlink(missing_ok=True)
    log(f"{len(names)} exemplars x {len(variants)} variants ({', '.join(v[0] for v in variants)}), "
        f"{args.jobs} workers")

    entries, ust_rows, failed = [], [], {}
    with ProcessPoolExecutor(max_workers=args.jobs, initializer=_init_worker) as pool:
        futures = {pool.submit(task, n, variants, size, metrics, sheets, args.fit_seed, args.seeds,
                               args.whole): n for n in names}
        futures.update({pool.submit(ust_task, n, variants, args.ust_size, args.ust_iterations, metrics,
                                    args.whole): f"ust:{n}"
                        for n in filter(None, args.ust.split(","))})
        for fut in as_completed(futures):
            label = futures[fut]
            try:
                res = fut.result()
            except Exception as exc:  # one bad exemplar must not lose the others
                failed[label] = f"{type(exc).__name__}: {exc}"
                log(f"{label} FAILED: {failed[label]}")
                continue
            (ust_rows if label.startswith("ust:") else entries).append(res)
            with open(RESULTS / f"{stem}.partial.jsonl", "a") as fh:  # survives a crash of the run
                fh.write(json.dumps(res, default=str) + "\n")
            log(f"{label} done")

    entries.sort(key=lambda e: e["texture"])
    if saved is not None:  # the saved variant first: every variant of this run is compared with it
        label, fit_kw, synth_kw, scores = saved
        for e in entries:
            if e["texture"] in scores:
                e["variants"] = {label: scores[e["texture"]], **e["variants"]}
        variants = [(label, fit_kw, synth_kw), *variants]
    cols = [*metrics, "diversity", "fit_s", "synth_s"]
    maxima = [m for m in MAXIMA if m in metrics]
    head = ["variant", *("median " + m for m in metrics), *("max " + m for m in maxima)]
    head += ["median diversity", "fit (s)", "image (s)"]
    table_rows, summary = [], {}
    for vname, *_ in variants:
        med = medians(entries, vname, metrics)
        summary[vname] = med
        table_rows.append([vname, *(med[m] for m in metrics), *(med[m + "_max"] for m in maxima),
                           med["diversity"], med["fit_s"], med["synth_s"]])
    seeds_text = ", ".join(map(str, args.seeds[:-1])) + f" and {args.seeds[-1]}"
    text = (f"## Quality, {args.size}x{args.size}, seeds {seeds_text} (models: seed {args.fit_seed}), "
            f"medians over {len(entries)} {'whole ' if args.whole else ''}exemplars\n\n"
            + markdown_table(head, table_rows))
    against = against_first(entries, [v[0] for v in variants], metrics)
    if against:
        text += (f"\n\n### Against {variants[0][0]}, exemplar by exemplar\n\n"
                 + markdown_table(["variant", "metric", "geometric mean of ratios", "better on", "largest gains",
                                   "largest losses"], against))
    per_tex = [[e["texture"], vname, *(e["variants"][vname][c] for c in cols)]
               for e in entries for vname in e["variants"]]
    text += "\n\n### Per exemplar\n\n" + markdown_table(["exemplar", "variant", *cols], per_tex)
    if ust_rows:
        names_v = ["Ustyuzhaninov", *(v[0] for v in variants)]
        rows = []
        for m in metrics:
            rows.append([m, *(float(np.median([r[n][m] for r in ust_rows])) for n in names_v)])
        text += (f"\n\n### Against Ustyuzhaninov et al. ({args.ust_size}x{args.ust_size}, {args.ust_iterations} "
                 f"L-BFGS iterations, seed 0), medians over {len(ust_rows)} exemplars "
                 f"({', '.join(sorted(r['texture'] for r in ust_rows))})\n\n"
                 + markdown_table(["metric", *names_v], rows))
    if failed:
        text += "\n\nFailed: " + "; ".join(f"{k}: {v}" for k, v in failed.items())
    print(text)
    variants_json = [{"name": n, "fit": f, "synth": s} for n, f, s in variants]
    path = write_results(stem, {"size": args.size, "seeds": list(args.seeds), "fit_seed": args.fit_seed,
                                "whole": args.whole,
                                "against": args.against, "variants": variants_json, "summary": summary,
                                "entries": entries, "ust": ust_rows, "failed": failed}, text)
    (RESULTS / f"{stem}.partial.jsonl").unlink(missing_ok=True)  # the whole run is in the results now
    log(f"wrote {path}")


if __name__ == "__main__":
    main()
