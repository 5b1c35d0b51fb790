"""Inpainting (tghop.inpaint) against classic quilting in the hole and a blurred fill.

For each exemplar: its centre ``CROP x CROP`` crop, and a centred square hole of 10 %,
30 % and 60 % of the area (the 60 % square leaves a 57 px frame at 512: patches of 32
still fit in it; at 256 it would leave 29 px, no whole patch). Three fills of the same
hole, each seeing only the pixels outside it:

* **tghop**: what ``tghop inpaint IMAGE MASK`` does without ``--source``: ``TGHop`` fitted
  on the crop with ``exclude=hole``, then :func:`tghop.inpaint.inpaint` (defaults);
* **quilting**: classic exemplar inpainting (Efros & Freeman style, as Embark's
  ``--inpaint``): ``tghop baseline quilting`` makes whole images and cannot fill a hole,
  so this script runs the same block filler (:func:`tghop.inpaint.inpaint`, refinement
  off, no preference for detailed patches: Efros-Freeman's rule) on a pool of 5,000 *real*
  32x32 patches of the crop that do not touch the hole, instead of generated ones. The
  fill order, matching and boundary cuts are the same, so the pair isolates the patches;
* **blur**: diffusion (the hole starts at the known pixels' mean colour; 150 rounds of a
  sigma 4 Gaussian, known pixels put back after each, about sigma 50 in all).

Measured, per fill: SIFID (:func:`tghop.metrics.sifid`) of the hole's bounding box (the
square) against the whole crop (lower is better), and the seam energy: the mean gradient
energy (squared forward differences, summed over channels) in a 3 px band across the
hole's border (1 px outside, 2 px inside) divided by the mean over the whole original
crop (1: as busy as the texture; above 1: a visible seam; below 1: smooth). The original
pixels' own value is listed as the reference. Then the time of ``tghop inpaint`` from a
fitted model (``--source model.npz``): in process and the whole ``tghop inpaint``
process, at 512x512 (the crop) and 2048x2048 (an image synthesised by the model), a 30 %
hole. Times are wall clock on whatever machine runs it (noisy on a shared one).

Seeds (``--seeds 1,2,3`` or ``--seeds 1-5``; ``--seed 1``, the default, is the single seed of
the results before seeds): each exemplar and hole is fitted once (the expensive part; rng 0)
and filled with every seed (tghop and quilting); the tables give the mean over the seeds, the
JSON each seed's values too (``per_seed``; files without it are read as their ``meta.seed``'s).
A fill's path is random: one exemplar's 10 % hole moved its SIFID ratio between two settings
from 0.74 to 1.16 from seed to seed (docs/choices.md, Inpainting), so compare over seeds.

``--against NAME`` (a results name or a .json path, either format): per hole size, the
geometric mean of this run's tghop SIFID over NAME's, paired by exemplar, hole and seed,
with its standard error across seeds (the spread of each seed's geometric mean) and a 95 %
interval (Student's t): "beyond noise" when it leaves out 1. Seeds in neither both files
are compared unpaired (the means over each file's seeds).

``--extend``: the grown-picture probe (docs/choices.md, Inpainting "0.46"): each exemplar's
centre ``CROP x CROP`` crop (256) grown to ``SIZE x SIZE`` (512) by :func:`tghop.inpaint.extend`
(centre anchor, defaults) with a model of the crop (rng 0); the median SIFID of the four
corners of side ``(SIZE - CROP) / 2``, all new, against the crop (lower is better), per seed
(``--synth``: the same of a ``synthesize`` image of the model, for reference). Its results
go to ``results/inpaint-extend.json`` and ``.md`` unless ``--name`` says otherwise.

``--models DIR`` keeps each fit as a tghop model file (``DIR/EXEMPLAR-CROP-HOLE.npz``) and
fills from the file, so that runs of two fill variants share the fits (the fit is most of
the time). A loaded model generates what the fitted one does (docs/choices.md, Model files):
the same figures as without the folder. The file names do not know the code: empty the
folder when the fit changes.

    python benchmarks/bench_inpaint.py                       # 9 exemplars, 512 crops (about 15 min on 2 busy cores)
    python benchmarks/bench_inpaint.py red_bricks_512 --crop 512 --timing red_bricks_512
    python benchmarks/bench_inpaint.py --holes 0.1 --seeds 1-5 --timing --name inpaint-new --against inpaint-old
    python benchmarks/bench_inpaint.py --extend --seeds 1,2      # 13 exemplars grown 256 -> 512
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import RESULTS, markdown_table, texture, write_results

EXEMPLARS = ["red_bricks_512", "stone_wall", "herringbone_bricks", "multicolor_bricks", "waffle",
             "leaf_veins_autumn", "gravel_gray", "denim_large", "blue_bubbles"]
FRACTIONS = (0.1, 0.3, 0.6)
#: The grown-picture probe's 13 exemplars (docs/choices.md, Inpainting "0.46").
EXTEND_EXEMPLARS = ["fur", "woven_metal", "hexagon_tiles", "knit", "lettuce", "paving_tiles", "stone_wall",
                    "brick_wall", "grass_lawn", "red_peppers", "beach_gravel", "plaid", "bark"]


def centre_crop(img, n):
    h, w = img.shape[:2]
    if h < n or w < n:
        raise SystemExit(f"exemplar {img.shape[:2]} is smaller than the {n}x{n} crop")
    y, x = (h - n) // 2, (w - n) // 2
    return np.ascontiguousarray(img[y:y + n, x:x + n])


def square_hole(n, fraction):
    """A centred square of ``fraction`` of an ``n x n`` image; returns the mask and its slices."""
    s = int(round(np.sqrt(fraction) * n))
    o = (n - s) // 2
    hole = np.zeros((n, n), dtype=bool)
    hole[o:o + s, o:o + s] = True
    return hole, (slice(o, o + s), slice(o, o + s))


class KnownPatches:
    """Duck-typed stand-in for a fitted TGHop whose "generated" patches are real patches of
    the image outside the hole (for :func:`tghop.inpaint.inpaint` with ``refine=0``)."""

    def __init__(self, image, hole, patch_size=32):
        from numpy.lib.stride_tricks import sliding_window_view

        self.patch_size = patch_size
        self.exemplar_shape_ = image.shape
        self.ichm_ = True  # what check_is_fitted looks for
        touches = sliding_window_view(hole, (patch_size, patch_size)).any(axis=(2, 3))
        self._windows = sliding_window_view(image, (patch_size, patch_size), axis=(0, 1))  # (nh, nw, C, P, P)
        self._free = np.argwhere(~touches)
        if not len(self._free):
            raise SystemExit("no whole patch outside the hole; use a larger crop")

    def sample_patches(self, n, *, rng=None, dtype=np.float32):
        rng = np.random.default_rng(rng)
        pick = self._free[rng.choice(len(self._free), size=min(n, len(self._free)), replace=False)]
        return np.ascontiguousarray(self._windows[pick[:, 0], pick[:, 1]].transpose(0, 2, 3, 1)).astype(dtype)


def blur_fill(image, hole, *, sigma=4.0, rounds=150):
    """Diffusion into the hole: Gaussian rounds with the known pixels put back each time."""
    from scipy.ndimage import gaussian_filter

    out = image.astype(np.float32).copy()
    out[hole] = image[~hole].mean(axis=0)
    keep = image[~hole].astype(np.float32)
    for _ in range(rounds):
        out = gaussian_filter(out, sigma=(sigma, sigma, 0), mode="reflect")
        out[~hole] = keep
    return np.clip(out, 0.0, 1.0)


def gradient_energy(img):
    """Per-pixel squared forward differences summed over channels, shape (H, W)."""
    img = np.asarray(img, dtype=np.float64)
    e = np.zeros(img.shape[:2])
    e[:, :-1] += np.square(np.diff(img, axis=1)).sum(axis=2)
    e[:-1, :] += np.square(np.diff(img, axis=0)).sum(axis=2)
    return e


def seam_energy(img, hole, reference_mean):
    """Mean gradient energy in the 3 px band across the hole's border over ``reference_mean``."""
    from scipy.ndimage import binary_dilation, binary_erosion

    band = binary_dilation(hole, iterations=1) & ~binary_erosion(hole, iterations=2)
    return float(gradient_energy(img)[band].mean() / reference_mean)


def timing(name, crop, seed, tmp):
    """Times of inpainting a 30 % hole from a saved model, at 512x512 and 2048x2048."""
    from tghop import TGHop
    from tghop.imageio import save_image
    from tghop.inpaint import inpaint
    from tghop.modelfile import load_model, save_model

    path = os.path.join(tmp, f"{name}.npz")
    save_model(TGHop(rng=0).fit(crop), path)
    model = load_model(path)
    rows = []
    for n in (crop.shape[0], 2048):
        img = crop if n == crop.shape[0] else model.synthesize((n, n), rng=seed)
        hole, _ = square_hole(n, 0.3)
        t = time.perf_counter()
        inpaint(model, img, hole, rng=seed)
        in_process = time.perf_counter() - t
        save_image(img, os.path.join(tmp, "img.png"))
        save_image(hole.astype(np.uint8) * 255, os.path.join(tmp, "hole.png"))
        t = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "tghop", "inpaint", os.path.join(tmp, "img.png"),
                            os.path.join(tmp, "hole.png"), "-o", os.path.join(tmp, "out.png"), "--source", path,
                            "--seed", str(seed), "-q"], capture_output=True)
        process = time.perf_counter() - t
        if r.returncode:
            raise SystemExit(r.stderr.decode())
        rows.append(dict(exemplar=name, size=n, hole=0.3, in_process_s=in_process, process_s=process))
        print(rows[-1], flush=True)
    return rows


def parse_seeds(text):
    """``"1,2,3"`` or ``"1-5"`` (or both, ``"1,4-6"``) as a list of distinct seeds (argparse's ``type``)."""
    seeds = []
    try:
        for part in text.split(","):
            first, dash, last = part.strip().partition("-")
            seeds += range(int(first), int(last) + 1) if dash else [int(first)]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a list of seeds; write e.g. 1,2,3 or 1-5") from None
    if not seeds or min(seeds) < 0 or len(set(seeds)) != len(seeds):
        raise argparse.ArgumentTypeError(f"{text!r}: give distinct seeds of 0 or more, e.g. 1,2,3 or 1-5")
    return seeds


def seed_values(payload, value):
    """``{(exemplar, hole): {seed: value}}`` of a results payload.

    Rows with ``per_seed`` give each seed's value; rows without (results written before seeds)
    give theirs as the value of ``meta["seed"]``. Rows or seeds without ``value`` (a failed fill)
    are left out.
    """
    out = {}
    single = payload.get("meta", {}).get("seed")
    for r in payload["results"]:
        if "per_seed" in r:
            vals = {int(s): v[value] for s, v in r["per_seed"].items() if value in v}
        else:
            vals = {int(single): r[value]} if value in r and single is not None else {}
        if vals:
            out[(r["exemplar"], r["hole"])] = vals
    return out


def ratio_summary(new, old):
    """The geometric mean of ``new / old`` and its noise across seeds.

    ``new`` and ``old`` map the same keys (exemplar, hole) to ``{seed: value}``. Paired where
    the two share seeds: each shared seed's mean log ratio over the keys having it in both,
    their mean and its standard error across those seeds. Unpaired otherwise: each file's
    per-seed mean logs, the difference of their means and its standard error from their
    pooled spread. The 95 % interval uses Student's t (few seeds give a wide one); no noise
    estimate from a single seed a side.

    Returns
    -------
    dict
        ``gmean``, ``se`` (of the mean log, about the ratio's relative error; nan without one),
        ``low``, ``high`` (the interval of the ratio; nan without one), ``seeds`` (how many seeds
        gave the estimate: a count paired, ``"this + that"`` unpaired), ``paired``, ``better`` and
        ``pairs`` (new below old, of how many comparisons: key and seed when paired, key's means over
        seeds when not), ``verdict``.
    """
    from scipy.stats import t as student

    keys = sorted(set(new) & set(old))
    shared = sorted(set().union(*[set(new[k]) & set(old[k]) for k in keys])) if keys else []
    if shared:
        pairs = [(k, s) for s in shared for k in keys if s in new[k] and s in old[k]]
        logs = [float(np.mean([np.log(new[k][s] / old[k][s]) for k, q in pairs if q == s])) for s in shared]
        mean, n, df = float(np.mean(logs)), len(logs), len(logs) - 1
        var = float(np.var(logs, ddof=1)) / n if n > 1 else float("nan")
        better = sum(new[k][s] < old[k][s] for k, s in pairs)
        count = len(pairs)
    elif keys:
        def per_seed(side):
            seeds = sorted(set().union(*[set(side[k]) for k in keys]))
            return [float(np.mean([np.log(side[k][s]) for k in keys if s in side[k]])) for s in seeds]

        a, b = per_seed(new), per_seed(old)
        mean, n, df = float(np.mean(a) - np.mean(b)), f"{len(a)} + {len(b)}", len(a) + len(b) - 2
        spread = sum(float(np.var(x, ddof=1)) * (len(x) - 1) for x in (a, b) if len(x) > 1)
        var = spread / df * (1 / len(a) + 1 / len(b)) if df > 0 else float("nan")
        means = {k: (np.mean(list(new[k].values())), np.mean(list(old[k].values()))) for k in keys}
        better, count = sum(x < y for x, y in means.values()), len(keys)
    else:
        return dict(gmean=float("nan"), se=float("nan"), low=float("nan"), high=float("nan"), seeds=0,
                    paired=False, better=0, pairs=0, verdict="nothing in common")
    se = float(np.sqrt(var)) if var == var else float("nan")
    half = float(student.ppf(0.975, df)) * se if se == se and df > 0 else float("nan")
    low, high = float(np.exp(mean - half)), float(np.exp(mean + half))
    if half != half:
        verdict = "one seed: no noise estimate"
    else:
        verdict = "beyond noise" if low > 1 or high < 1 else "within noise"
    return dict(gmean=float(np.exp(mean)), se=se, low=low, high=high, seeds=n, paired=bool(shared),
                better=int(better), pairs=int(count), verdict=verdict)


def comparison(payload, against, label):
    """:func:`ratio_summary` of ``payload``'s main value over ``against``'s, per hole and over all."""
    value = "corner_sifid" if payload["meta"].get("mode") == "extend" else "tghop_sifid"
    new, old = seed_values(payload, value), seed_values(against, value)
    holes = sorted({k[1] for k in set(new) & set(old)}, key=str)
    rows = [dict(hole=h, **ratio_summary({k: v for k, v in new.items() if k[1] == h},
                                         {k: v for k, v in old.items() if k[1] == h})) for h in holes]
    if len(holes) > 1:
        rows.append(dict(hole="all", **ratio_summary(new, old)))
    return dict(against=label, value=value, rows=rows)


def usage_error(message):
    """``message`` on stderr and exit status 2 (a usage error), no traceback."""
    print(f"bench_inpaint.py: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def read_against(text, mode):
    """The payload of ``--against`` (a results name or a .json path); a usage error naming the problem."""
    path = Path(text) if text.endswith(".json") else RESULTS / f"{text}.json"
    try:
        payload = json.loads(path.read_text())
        payload["results"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        usage_error(f"--against {text}: cannot read {path} ({type(exc).__name__}); "
                    "give a results name or a bench_inpaint .json file")
    if (payload.get("meta", {}).get("mode") == "extend") != (mode == "extend"):
        usage_error(f"--against {text}: one file is an --extend run and the other not; compare like with like")
    return payload


def fitted(crop, hole, key, folder):
    """``TGHop(rng=0)`` fitted on ``crop`` (``exclude=hole``), or read from ``folder/key.npz``
    (fitted and written there first when missing)."""
    from tghop import TGHop
    from tghop.modelfile import load_model, save_model

    if folder is None:
        return TGHop(rng=0).fit(crop, exclude=hole)
    path = os.path.join(folder, f"{key}.npz")
    if not os.path.exists(path):
        os.makedirs(folder, exist_ok=True)
        save_model(TGHop(rng=0).fit(crop, exclude=hole), path)
    return load_model(path)


def seed_means(row, keys):
    """``row[key]`` = the mean of ``row["per_seed"]``'s values of ``key`` (seeds that have it)."""
    for key in keys:
        vals = [v[key] for v in row["per_seed"].values() if key in v]
        if vals:
            row[key] = float(np.mean(vals))


def inpaint_rows(args, seeds):
    from tghop import metrics
    from tghop.inpaint import inpaint

    results = []
    for name in args.exemplars:
        crop = centre_crop(texture(name), args.crop)
        if crop.ndim == 2:
            crop = crop[:, :, None]
        reference = gradient_energy(crop).mean()
        for fraction in args.holes:
            hole, box = square_hole(args.crop, fraction)
            row = dict(exemplar=name, crop=args.crop, hole=fraction, hole_px=int(hole.sum()), seeds=seeds)
            t = time.perf_counter()
            model = fitted(crop, hole, f"{name}-{args.crop}-hole{fraction:g}", args.models)
            row["fit_s"] = time.perf_counter() - t
            blurred = blur_fill(crop, hole)
            row["blur_sifid"] = float(metrics.sifid(crop, blurred[box]))
            row["blur_seam"] = seam_energy(blurred, hole, reference)
            row["original_sifid"] = float(metrics.sifid(crop, crop[box]))
            row["original_seam"] = seam_energy(crop, hole, reference)
            row["per_seed"] = {}
            for seed in seeds:
                entry = row["per_seed"][str(seed)] = {}
                t = time.perf_counter()
                try:
                    img = inpaint(model, crop, hole, rng=seed)
                    entry["tghop_sifid"] = float(metrics.sifid(crop, img[box]))
                    entry["tghop_seam"] = seam_energy(img, hole, reference)
                except Exception as exc:  # recorded, left out of the means and medians
                    entry["tghop_error"] = f"{type(exc).__name__}: {exc}"
                entry["tghop_s"] = time.perf_counter() - t
                t = time.perf_counter()
                img = inpaint(KnownPatches(crop, hole), crop, hole, rng=seed, refine=0, detail=0.0)
                entry["quilting_s"] = time.perf_counter() - t
                entry["quilting_sifid"] = float(metrics.sifid(crop, img[box]))
                entry["quilting_seam"] = seam_energy(img, hole, reference)
            seed_means(row, ("tghop_sifid", "tghop_seam", "tghop_s", "quilting_sifid", "quilting_seam", "quilting_s"))
            errors = [f"seed {s}: {v['tghop_error']}" for s, v in row["per_seed"].items() if "tghop_error" in v]
            if errors and "tghop_sifid" not in row:
                row["tghop_error"] = "; ".join(errors)
            elif errors:
                row["tghop_failed_seeds"] = "; ".join(errors)
            results.append(row)
            print({k: round(v, 3) if isinstance(v, float) else v for k, v in row.items() if k != "per_seed"},
                  flush=True)
    return results


def extend_rows(args, seeds):
    """The grown-picture probe's rows: each exemplar's crop grown to ``args.size``, per seed."""
    from tghop import metrics
    from tghop.inpaint import extend

    def corners(img, c):
        return float(np.median([metrics.sifid(crop, k) for k in (img[:c, :c], img[:c, -c:], img[-c:, :c],
                                                                  img[-c:, -c:])]))

    results = []
    side = (args.size - args.crop) // 2
    for name in args.exemplars:
        crop = centre_crop(texture(name), args.crop)
        if crop.ndim == 2:
            crop = crop[:, :, None]
        row = dict(exemplar=name, hole="extend", crop=args.crop, size=args.size, corner=side, seeds=seeds)
        t = time.perf_counter()
        model = fitted(crop, None, f"{name}-{args.crop}-whole", args.models)
        row["fit_s"] = time.perf_counter() - t
        row["per_seed"] = {}
        for seed in seeds:
            entry = row["per_seed"][str(seed)] = {}
            t = time.perf_counter()
            try:
                entry["corner_sifid"] = corners(extend(model, crop, (args.size, args.size), rng=seed), side)
            except Exception as exc:  # recorded, left out of the means and medians
                entry["error"] = f"{type(exc).__name__}: {exc}"
            entry["extend_s"] = time.perf_counter() - t
            if args.synth:
                entry["synth_sifid"] = corners(model.synthesize((args.size, args.size), rng=seed), side)
        seed_means(row, ("corner_sifid", "extend_s", "synth_sifid"))
        errors = [f"seed {s}: {v['error']}" for s, v in row["per_seed"].items() if "error" in v]
        if errors:
            row["error"] = "; ".join(errors)
        results.append(row)
        print({k: round(v, 3) if isinstance(v, float) else v for k, v in row.items() if k != "per_seed"}, flush=True)
    return results


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 epilog="Details: the module docstring (python -m pydoc benchmarks/bench_inpaint.py).")
    ap.add_argument("exemplars", nargs="*", help="default: the nine (the 13 with --extend)")
    ap.add_argument("--crop", type=int, help="the centre crop's side (512; 256 with --extend)")
    ap.add_argument("--holes", type=float, nargs="+", default=list(FRACTIONS),
                    help="hole sizes, fractions of the area (default 0.1 0.3 0.6)")
    ap.add_argument("--seed", type=int, help="one seed (the default, 1: the results before --seeds)")
    ap.add_argument("--seeds", type=parse_seeds, help="several seeds, e.g. 1,2,3 or 1-5: each fit filled with each")
    ap.add_argument("--timing", nargs="*", default=["red_bricks_512", "stone_wall"],
                    help="exemplars whose 512 and 2048 inpainting is timed (first seed; none: --timing alone)")
    ap.add_argument("--extend", action="store_true", help="the grown-picture probe instead (docstring)")
    ap.add_argument("--size", type=int, help="--extend: the grown image's side (twice the crop)")
    ap.add_argument("--synth", action="store_true", help="--extend: also a synthesised image's corners")
    ap.add_argument("--models", metavar="DIR", help="keep the fits as model files in DIR and fill from them")
    ap.add_argument("--against", metavar="NAME", help="compare with results/NAME.json (or a .json path)")
    ap.add_argument("--name", help="results/NAME.json and .md (inpaint; inpaint-extend with --extend)")
    ap.add_argument("--report", action="store_true", help="only rewrite results/NAME.md from results/NAME.json")
    args = ap.parse_args(argv)
    if args.seed is not None and args.seeds is not None:
        ap.error("give --seed or --seeds, not both")
    if args.seed is not None and args.seed < 0:
        ap.error(f"--seed {args.seed}: give a seed of 0 or more")
    args.seeds = args.seeds or [1 if args.seed is None else args.seed]
    args.name = args.name or ("inpaint-extend" if args.extend else "inpaint")
    args.exemplars = args.exemplars or (EXTEND_EXEMPLARS if args.extend else EXEMPLARS)
    args.crop = args.crop or (256 if args.extend else 512)
    args.size = args.size or 2 * args.crop
    if args.crop < 64 or (args.extend and args.size < args.crop + 64):
        ap.error("--crop must be at least 64 and --size at least --crop + 64")
    if any(not 0 < h < 1 for h in args.holes):
        ap.error("--holes: fractions of the area between 0 and 1, e.g. 0.1 0.3")
    return args


def main(argv=None):
    args = parse_args(argv)
    against = read_against(args.against, "extend" if args.extend else "inpaint") if args.against else None
    if args.report:
        try:
            payload = json.loads((RESULTS / f"{args.name}.json").read_text())
        except OSError:
            usage_error(f"no results/{args.name}.json: run the benchmark first, or give --name")
        if against is not None:
            payload["comparison"] = comparison(payload, against, args.against)
        write_results(args.name, payload, report(payload))
        return
    for name in {*args.exemplars, *([] if args.extend else args.timing)}:
        texture(name)  # a missing one stops the run now, not after the others' fits
    start = time.perf_counter()
    seeds = args.seeds
    results = extend_rows(args, seeds) if args.extend else inpaint_rows(args, seeds)
    times = []
    if not args.extend:
        with tempfile.TemporaryDirectory() as tmp:
            for name in args.timing:
                crop = centre_crop(texture(name), args.crop)
                times += timing(name, crop if crop.ndim == 3 else crop[:, :, None], seeds[0], tmp)
    import tghop

    meta = dict(format=2, tghop=tghop.__version__, mode="extend" if args.extend else "inpaint",
                exemplars=len(args.exemplars), crop=args.crop, seed=seeds[0], seeds=seeds, models=args.models,
                cpus=os.cpu_count(),
                load_average_end=os.getloadavg()[0], minutes=(time.perf_counter() - start) / 60)
    if args.extend:
        meta["size"] = args.size
    payload = dict(meta=meta, results=results, timing=times)
    if against is not None:
        payload["comparison"] = comparison(payload, against, args.against)
    text = report(payload)
    print(text)
    write_results(args.name, payload, text)


def seeds_text(meta):
    seeds = meta.get("seeds", [meta["seed"]])
    if len(seeds) == 1:
        return f"seed {seeds[0]}"
    return f"seeds {', '.join(map(str, seeds))} (each fit filled with each; the values are means over the seeds)"


def comparison_text(payload):
    """The Markdown of a payload's ``comparison`` (empty without one)."""
    comp = payload.get("comparison")
    if not comp:
        return ""
    rows = [[f"{r['hole']:.0%}" if isinstance(r["hole"], float) else r["hole"], f"{r['gmean']:.3f}",
             f"{r['se']:.3f}" if r["se"] == r["se"] else "-",
             f"{r['low']:.3f}-{r['high']:.3f}" if r["low"] == r["low"] else "-",
             f"{r['seeds']} {'paired' if r['paired'] else 'unpaired'}", f"{r['better']}/{r['pairs']}", r["verdict"]]
            for r in comp["rows"]]
    header = ["hole", "geometric mean of ratios", "SE of mean log", "95 % interval", "seeds",
              "better (lower)", "verdict"]
    what = "corner SIFID" if comp["value"] == "corner_sifid" else "tghop's hole SIFID"
    return (f"\n\n## Against {comp['against']}\n\n{what}, this run over {comp['against']}'s (below 1: this run "
            "lower, better). Paired by exemplar, hole and seed where both have the seed: the mean over the seeds of "
            "each seed's mean log ratio, its standard error across the seeds, a 95 % interval by Student's t; "
            "unpaired (no seed in common): the means over each file's seeds, the error from both files' spread "
            "across their seeds. \"better\": comparisons (exemplar and seed; exemplars when unpaired) where this "
            f"run is lower.\n\n{markdown_table(header, rows)}")


def report(payload):
    """The Markdown report of a run's ``payload`` (meta, results, timing; comparison)."""
    if payload["meta"].get("mode") == "extend":
        return extend_report(payload)
    meta, results, times = payload["meta"], payload["results"], payload["timing"]
    methods = ("tghop", "quilting", "blur", "original")
    several = len(meta.get("seeds", [meta["seed"]])) > 1

    def off(r, m):  # how far a fill's seam is from the original's, either way
        return abs(np.log(r[f"{m}_seam"] / r["original_seam"]))

    def spread(r):  # the standard deviation of tghop's SIFID over the seeds
        vals = [v["tghop_sifid"] for v in r["per_seed"].values() if "tghop_sifid" in v]
        return float(np.std(vals, ddof=1)) if len(vals) > 1 else "-"

    summary = []
    for fraction in sorted({r["hole"] for r in results}):
        sel = [r for r in results if r["hole"] == fraction and "tghop_error" not in r]
        if not sel:
            continue
        summary.append([f"{fraction:.0%}", *[float(np.median([r[f"{m}_sifid"] for r in sel])) for m in methods],
                        *[float(np.median([r[f"{m}_seam"] / r["original_seam"] for r in sel])) for m in methods[:3]],
                        f"{sum(r['tghop_sifid'] < r['quilting_sifid'] for r in sel)}/{len(sel)}",
                        f"{sum(off(r, 'tghop') < off(r, 'quilting') for r in sel)}/{len(sel)}",
                        *[float(np.median([r[f"{m}_s"] for r in sel])) for m in ("tghop", "quilting")]])
    header = ["hole", *[f"SIFID {m}" for m in methods], *[f"seam {m} / original's" for m in methods[:3]],
              "tghop better SIFID", "tghop seam nearer original's", "tghop s", "quilting s"]
    detail = [[r["exemplar"], f"{r['hole']:.0%}", *[r.get(f"{m}_sifid", "failed") for m in methods],
               *([spread(r)] if several else []), *[r.get(f"{m}_seam", "failed") for m in methods],
               r["fit_s"], r.get("tghop_s", "-"), r["quilting_s"]]
              for r in results]
    failures = "".join(f"\n- {r['exemplar']} {r['hole']:.0%}: tghop failed: {r['tghop_error']}"
                       for r in results if "tghop_error" in r)
    failures += "".join(f"\n- {r['exemplar']} {r['hole']:.0%}: tghop failed ({r['tghop_failed_seeds']}); the "
                        "mean over the other seeds" for r in results if "tghop_failed_seeds" in r)
    detail_header = ["exemplar", "hole", *[f"SIFID {m}" for m in methods], *(["tghop SIFID sd"] if several else []),
                     *[f"seam {m}" for m in methods], "fit or load s" if meta.get("models") else "fit s",
                     "tghop inpaint s", "quilting s"]
    time_rows = [[t["exemplar"], f"{t['size']}x{t['size']}", t["in_process_s"], t["process_s"]] for t in times]
    timing_text = ("\n\nTime of inpainting a 30 % centred hole from a saved model (`--source model.npz`; the 2048 "
                   "image is synthesised by the model), in process and the whole `tghop inpaint` process (start, "
                   f"reading, writing the PNG). Wall clock on a machine of {meta['cpus']} cores shared with other "
                   f"sessions (load average {meta['load_average_end']:.1f} at the end): noisy.\n\n"
                   f"{markdown_table(['exemplar', 'size', 'in process s', 'whole process s'], time_rows)}"
                   if times else "")
    holes = " / ".join(f"{h:.0%}".rstrip("%") for h in sorted({r["hole"] for r in results})) + " %"
    sd_note = "; tghop SIFID sd: the standard deviation of its SIFID over the seeds" if several else ""
    return (f"# Inpainting (bench_inpaint.py)\n\n"
            f"{meta['exemplars']} exemplars, centre {meta['crop']}x{meta['crop']} crops, a centred square hole of "
            f"{holes} of the area, {seeds_text(meta)}. Every fill sees only the pixels outside the hole. "
            "tghop: `tghop inpaint` without --source (fit with exclude=hole, then inpaint"
            f"{'; the fits kept as model files in ' + meta['models'] if meta.get('models') else ''}). quilting: "
            "the same block filler on 5,000 real patches of the crop outside the hole (no refinement, no detail "
            "preference: classic exemplar quilting in the hole). blur: Gaussian diffusion. original: the crop's "
            "own pixels (the reference). SIFID: the hole's square against the whole crop (lower is better). "
            "seam: gradient energy in a 3 px band across the hole's border (1 px out, 2 px in) / the crop's "
            "mean; the original pixels' own band varies with where the border falls (mortar lines), so the "
            "medians divide each fill's by the original's (1: as busy as the real pixels there; > 1 a visible "
            "seam, < 1 smoother than the texture). Times (in process; fit not included) on the loaded "
            "machine below.\n\n"
            "Medians over the exemplars (failed fills left out; the counts: on how many exemplars):\n\n"
            f"{markdown_table(header, summary)}\n\n"
            f"Each exemplar (seam: band / crop mean, not divided by the original's"
            f"{sd_note}):\n\n"
            f"{markdown_table(detail_header, detail)}\n{failures}"
            f"{comparison_text(payload)}{timing_text}\n\n"
            f"Whole benchmark: {meta['minutes']:.1f} min.")


def extend_report(payload):
    """The Markdown report of an ``--extend`` run's ``payload``."""
    meta, results = payload["meta"], payload["results"]
    seeds = meta["seeds"]
    synth = any("synth_sifid" in r for r in results)
    ok = [r for r in results if "corner_sifid" in r]
    per_seed = [[s, float(np.median([r["per_seed"][str(s)]["corner_sifid"] for r in ok
                                                if "corner_sifid" in r["per_seed"][str(s)]]))]
                for s in seeds if any("corner_sifid" in r["per_seed"][str(s)] for r in ok)]
    summary = [["median", float(np.median([r["corner_sifid"] for r in ok])),
                *([float(np.median([r["synth_sifid"] for r in ok]))] if synth else [])]] if ok else []
    rows = [[r["exemplar"], r.get("corner_sifid", "failed"), *([r.get("synth_sifid", "-")] if synth else []),
             *([r["per_seed"][str(s)].get("corner_sifid", "failed") for s in seeds] if len(seeds) > 1 else []),
             r["fit_s"], r["extend_s"]] for r in results]
    header = ["exemplar", "corner SIFID", *(["synth's corners"] if synth else []),
              *([f"seed {s}" for s in seeds] if len(seeds) > 1 else []),
              "fit or load s" if meta.get("models") else "fit s", "extend s"]
    failures = "".join(f"\n- {r['exemplar']}: {r['error']}" for r in results if "error" in r)
    side = (meta["size"] - meta["crop"]) // 2
    return (f"# Grown pictures (bench_inpaint.py --extend)\n\n"
            f"{meta['exemplars']} exemplars, the centre {meta['crop']}x{meta['crop']} crop grown to "
            f"{meta['size']}x{meta['size']} by `tghop.inpaint.extend` (centre anchor, defaults) with a model of the "
            f"crop (rng 0{'; kept as model files in ' + meta['models'] if meta.get('models') else ''}), "
            f"{seeds_text(meta)}. corner SIFID: the median SIFID of the four {side}x{side} corners (all new) "
            "against the crop, lower is better"
            f"{'; synth: the same of a synthesised image of the model, as large' if synth else ''}.\n\n"
            f"{markdown_table(['', 'corner SIFID', *(['synth'] if synth else [])], summary)}\n\n"
            + (f"Median per seed:\n\n{markdown_table(['seed', 'corner SIFID'], per_seed)}\n\n"
               if len(seeds) > 1 else "")
            + f"Each exemplar:\n\n{markdown_table(header, rows)}\n{failures}{comparison_text(payload)}\n\n"
            f"Whole benchmark: {meta['minutes']:.1f} min (load average {meta['load_average_end']:.1f} at the end).")


if __name__ == "__main__":
    main()
