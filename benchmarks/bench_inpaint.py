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

    python benchmarks/bench_inpaint.py                       # 9 exemplars, 512 crops (about 15 min on 2 busy cores)
    python benchmarks/bench_inpaint.py red_bricks_512 --crop 512 --timing red_bricks_512
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from _common import RESULTS, markdown_table, texture, write_results

EXEMPLARS = ["red_bricks_512", "stone_wall", "herringbone_bricks", "multicolor_bricks", "waffle",
             "leaf_veins_autumn", "gravel_gray", "denim_large", "blue_bubbles"]
FRACTIONS = (0.1, 0.3, 0.6)


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


def main():
    from tghop import TGHop, metrics
    from tghop.inpaint import inpaint

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("exemplars", nargs="*", default=EXEMPLARS)
    ap.add_argument("--crop", type=int, default=512)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timing", nargs="*", default=["red_bricks_512", "stone_wall"],
                    help="exemplars whose 512 and 2048 inpainting is timed")
    ap.add_argument("--name", default="inpaint", help="results/NAME.json and .md")
    ap.add_argument("--report", action="store_true", help="only rewrite results/NAME.md from results/NAME.json")
    args = ap.parse_args()
    if args.report:
        payload = json.loads((RESULTS / f"{args.name}.json").read_text())
        write_results(args.name, payload, report(payload))
        return
    results = []
    start = time.perf_counter()
    for name in args.exemplars:
        crop = centre_crop(texture(name), args.crop)
        if crop.ndim == 2:
            crop = crop[:, :, None]
        reference = gradient_energy(crop).mean()
        for fraction in FRACTIONS:
            hole, box = square_hole(args.crop, fraction)
            row = dict(exemplar=name, crop=args.crop, hole=fraction, hole_px=int(hole.sum()))
            t = time.perf_counter()
            model = TGHop(rng=0).fit(crop, exclude=hole)
            row["fit_s"] = time.perf_counter() - t
            fills = {}
            t = time.perf_counter()
            try:
                fills["tghop"] = inpaint(model, crop, hole, rng=args.seed)
            except Exception as exc:  # recorded, left out of the medians
                row["tghop_error"] = f"{type(exc).__name__}: {exc}"
            row["tghop_s"] = time.perf_counter() - t
            t = time.perf_counter()
            fills["quilting"] = inpaint(KnownPatches(crop, hole), crop, hole, rng=args.seed, refine=0, detail=0.0)
            row["quilting_s"] = time.perf_counter() - t
            fills["blur"] = blur_fill(crop, hole)
            fills["original"] = crop
            for method, img in fills.items():
                row[f"{method}_sifid"] = float(metrics.sifid(crop, img[box]))
                row[f"{method}_seam"] = seam_energy(img, hole, reference)
            results.append(row)
            print({k: round(v, 3) if isinstance(v, float) else v for k, v in row.items()}, flush=True)
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.timing:
            crop = centre_crop(texture(name), args.crop)
            times += timing(name, crop if crop.ndim == 3 else crop[:, :, None], args.seed, tmp)
    meta = dict(exemplars=len(args.exemplars), crop=args.crop, seed=args.seed, cpus=os.cpu_count(),
                load_average_end=os.getloadavg()[0], minutes=(time.perf_counter() - start) / 60)
    payload = dict(meta=meta, results=results, timing=times)
    text = report(payload)
    print(text)
    write_results(args.name, payload, text)


def report(payload):
    """The Markdown report of a run's ``payload`` (meta, results, timing)."""
    meta, results, times = payload["meta"], payload["results"], payload["timing"]
    methods = ("tghop", "quilting", "blur", "original")

    def off(r, m):  # how far a fill's seam is from the original's, either way
        return abs(np.log(r[f"{m}_seam"] / r["original_seam"]))

    summary = []
    for fraction in FRACTIONS:
        sel = [r for r in results if r["hole"] == fraction and "tghop_error" not in r]
        summary.append([f"{fraction:.0%}", *[float(np.median([r[f"{m}_sifid"] for r in sel])) for m in methods],
                        *[float(np.median([r[f"{m}_seam"] / r["original_seam"] for r in sel])) for m in methods[:3]],
                        f"{sum(r['tghop_sifid'] < r['quilting_sifid'] for r in sel)}/{len(sel)}",
                        f"{sum(off(r, 'tghop') < off(r, 'quilting') for r in sel)}/{len(sel)}",
                        *[float(np.median([r[f"{m}_s"] for r in sel])) for m in ("tghop", "quilting")]])
    header = ["hole", *[f"SIFID {m}" for m in methods], *[f"seam {m} / original's" for m in methods[:3]],
              "tghop better SIFID", "tghop seam nearer original's", "tghop s", "quilting s"]
    detail = [[r["exemplar"], f"{r['hole']:.0%}", *[r.get(f"{m}_sifid", "failed") for m in methods],
               *[r.get(f"{m}_seam", "failed") for m in methods], r["fit_s"], r["tghop_s"], r["quilting_s"]]
              for r in results]
    failures = "".join(f"\n- {r['exemplar']} {r['hole']:.0%}: tghop failed: {r['tghop_error']}"
                       for r in results if "tghop_error" in r)
    detail_header = ["exemplar", "hole", *[f"SIFID {m}" for m in methods], *[f"seam {m}" for m in methods],
                     "fit s", "tghop inpaint s", "quilting s"]
    time_rows = [[t["exemplar"], f"{t['size']}x{t['size']}", t["in_process_s"], t["process_s"]] for t in times]
    return (f"# Inpainting (bench_inpaint.py)\n\n"
            f"{meta['exemplars']} exemplars, centre {meta['crop']}x{meta['crop']} crops, a centred square hole of "
            f"10 / 30 / 60 % of the area, seed {meta['seed']}. Every fill sees only the pixels outside the hole. "
            "tghop: `tghop inpaint` without --source (fit with exclude=hole, then inpaint). quilting: the same "
            "block filler on 5,000 real patches of the crop outside the hole (no refinement, no detail "
            "preference: classic exemplar quilting in the hole). blur: Gaussian diffusion. original: the crop's "
            "own pixels (the reference). SIFID: the hole's square against the whole crop (lower is better). "
            "seam: gradient energy in a 3 px band across the hole's border (1 px out, 2 px in) / the crop's "
            "mean; the original pixels' own band varies with where the border falls (mortar lines), so the "
            "medians divide each fill's by the original's (1: as busy as the real pixels there; > 1 a visible "
            "seam, < 1 smoother than the texture). Times (in process; fit not included) on the loaded "
            "machine below.\n\n"
            "Medians over the exemplars (failed fills left out; the counts: on how many exemplars):\n\n"
            f"{markdown_table(header, summary)}\n\n"
            f"Each exemplar (seam: band / crop mean, not divided by the original's):\n\n"
            f"{markdown_table(detail_header, detail)}\n{failures}\n\n"
            "Time of inpainting a 30 % centred hole from a saved model (`--source model.npz`; the 2048 image "
            "is synthesised by the model), in process and the whole `tghop inpaint` process (start, reading, "
            f"writing the PNG). Wall clock on a machine of {meta['cpus']} cores shared with other sessions "
            f"(load average {meta['load_average_end']:.1f} at the end): noisy.\n\n"
            f"{markdown_table(['exemplar', 'size', 'in process s', 'whole process s'], time_rows)}\n\n"
            f"Whole benchmark: {meta['minutes']:.1f} min.")


if __name__ == "__main__":
    main()
