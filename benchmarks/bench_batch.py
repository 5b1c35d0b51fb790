"""`tghop batch` over the shared textures: in process (--workers 1) against the default
local Dask cluster (one worker process per core), and optionally against a cluster the
script starts first and hands over by address (`--scheduler`: the path to an existing
cluster, end to end).

    python benchmarks/bench_batch.py                 # all 44 exemplars, 2 images each at 512x512
    python benchmarks/bench_batch.py --limit 6       # the first 6 (what fits a shared 2-core machine)
    python benchmarks/bench_batch.py --limit 6 --crop 128 --size 128 --scheduler-workers 4
                                                     # centre crops, plus a 4-process cluster via --scheduler

Reports the wall time of each mode, the sum of the single-exemplar times (each exemplar's
task time in process, all cores to itself), the cluster's efficiency against that sum
(sum / (wall x workers)), the peak memory per worker process, and the overhead per
exemplar (wall x workers - task times, per exemplar: scheduling, start-up, hashing, the
ledger and the contact sheet); with more worker processes than cores the efficiency is
taken against the cores. Writes benchmarks/results/bench_batch[-cropN].{json,md}.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import TEXTURES, markdown_table, peak_rss_mb, texture_names, write_results  # noqa: E402


def one_mode(manifest, outdir, *, workers, count, size, seed, scheduler=None):
    from tghop import batch

    t = time.perf_counter()
    results = batch.run(manifest, outdir, count=count, size=size, seed=seed, workers=workers, scheduler=scheduler)
    wall = time.perf_counter() - t
    failed = [r["name"] for r in results if r["status"] != "ok"]
    if len(failed) == len(results):
        raise SystemExit(f"every exemplar failed, e.g. {results[0]['name']}: {results[0]['error']}")
    task = sum(r["seconds"] or 0.0 for r in results)
    per_worker = {}
    for r in results:
        per_worker[r["worker"]] = max(per_worker.get(r["worker"], 0.0), r.get("peak_rss_mb") or 0.0)
    return {"wall_s": wall, "task_s": task, "failed": failed, "n": len(results), "workers": len(per_worker),
            "peak_rss_mb_per_worker": per_worker,
            "fit_s_median": statistics.median(r["fit_seconds"] for r in results if r["fit_seconds"]),
            "synth_s_median": statistics.median(r["synth_seconds"] for r in results if r["synth_seconds"]),
            "single_s": {r["name"]: r["seconds"] for r in results}}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=int, default=None, help="first N exemplars only")
    ap.add_argument("--count", type=int, default=2)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--workers", type=int, default=None, help="local cluster size (default: one per core)")
    ap.add_argument("--crop", type=int, default=None, help="centre crops of CROPxCROP as the exemplars")
    ap.add_argument("--scheduler-workers", type=int, default=0,
                    help="also: start a local cluster of this many worker processes and run on it by address")
    args = ap.parse_args()
    names = texture_names()[: args.limit]
    if not names:
        raise SystemExit(f"no textures in {TEXTURES}; set TGHOP_TEXTURES")
    files = {p.stem: p for p in TEXTURES.iterdir() if p.stem in names}
    cores = len(os.sched_getaffinity(0))
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        if args.crop:
            files = {n: centre_crop(f, args.crop, Path(tmp) / "crops") for n, f in files.items()}
        manifest = Path(tmp) / "manifest.csv"
        manifest.write_text("path,name\n" + "".join(f"{files[n]},{n}\n" for n in names))
        kw = dict(count=args.count, size=(args.size, args.size), seed=0)
        single = one_mode(manifest, Path(tmp) / "in_process", workers=1, **kw)
        single["peak_rss_mb_per_worker"] = {"this process": peak_rss_mb()}
        cluster = one_mode(manifest, Path(tmp) / "cluster", workers=args.workers, **kw)
        modes = [("--workers 1 (in process)", single, 1), (f"local cluster, {args.workers or cores} workers",
                                                           cluster, args.workers or cores)]
        scheduled = None
        if args.scheduler_workers:
            from tghop import batch

            t = time.perf_counter()
            started = batch.local_cluster(args.scheduler_workers)  # what a user starts by hand
            start_s = time.perf_counter() - t
            try:
                scheduled = one_mode(manifest, Path(tmp) / "scheduler", workers=None,
                                     scheduler=started.scheduler_address, **kw)
            finally:
                started.close()
            scheduled["cluster_start_s"] = start_s
            modes.append((f"--scheduler ADDRESS, {args.scheduler_workers} worker processes (started first)",
                          scheduled, args.scheduler_workers))
    load_after = os.getloadavg()
    sum_single = single["task_s"]
    rows = []
    for label, m, w in modes:
        shared = w > cores  # more processes than cores: their task times include waiting for a core
        w = min(w, cores)
        m["efficiency"] = sum_single / (m["wall_s"] * w)
        m["overhead_s_per_exemplar"] = None if shared else (m["wall_s"] * w - m["task_s"]) / m["n"]
        m["speedup"] = single["wall_s"] / m["wall_s"]
        rows.append([label, m["wall_s"], m["wall_s"] / m["n"], m["speedup"], m["efficiency"],
                     "n/a" if m["overhead_s_per_exemplar"] is None else m["overhead_s_per_exemplar"], max(m["peak_rss_mb_per_worker"].values()),
                     m["fit_s_median"], m["synth_s_median"], len(m["failed"])])
    header = ["mode", "wall s", "s / exemplar", "speedup", "efficiency", "overhead s / exemplar",
              "peak MB / worker", "fit s (median)", "synth s (median)", "failed"]
    crop = f" (centre crops {args.crop}x{args.crop})" if args.crop else ""
    md = (f"# bench_batch: {len(names)} exemplars{crop}, {args.count} images each at {args.size}x{args.size}, "
          f"{cores} cores\n\nLoad average before {load_before[0]:.1f}, after {load_after[0]:.1f} (a shared "
          f"machine: other sessions' work competes with these runs).\n\nSum of single-exemplar task times (in process): {sum_single:.1f} s.\n\n"
          + markdown_table(header, rows)
          + "\n\nefficiency = sum of single-exemplar times / (wall x workers); overhead = (wall x workers - "
            "task times) / exemplars, with workers capped at the cores (n/a with more workers than cores, whose task "
            "times include waiting for a core); peak MB: the worker process's peak resident "
            "memory." + (f" The --scheduler cluster took {scheduled['cluster_start_s']:.1f} s to start (not in its "
                         "wall time)." if scheduled else ""))
    print(md)
    write_results("bench_batch" + (f"-crop{args.crop}" if args.crop else ""),
                  {"exemplars": names, "crop": args.crop, "count": args.count, "size": args.size, "cores": cores,
                   "sum_single_s": sum_single, "load_before": load_before, "load_after": load_after,
                   "in_process": single, "cluster": cluster, "scheduler": scheduled}, md)


def centre_crop(path, side, folder):
    """The central SIDExSIDE of an image file, written as PNG into ``folder``."""
    from PIL import Image

    folder.mkdir(parents=True, exist_ok=True)
    img = Image.open(path).convert("RGB")
    w, h = img.size
    s = min(side, w, h)
    left, top = (w - s) // 2, (h - s) // 2
    out = folder / f"{Path(path).stem}.png"
    img.crop((left, top, left + s, top + s)).save(out)
    return out


if __name__ == "__main__":
    main()
