"""`tghop batch` over the shared textures: in process (--workers 1) against the default
local Dask cluster (one worker process per core).

    python benchmarks/bench_batch.py                 # all 44 exemplars, 2 images each at 512x512
    python benchmarks/bench_batch.py --limit 6       # the first 6 (what fits a shared 2-core machine)

Reports the wall time of each mode, the sum of the single-exemplar times (each exemplar's
task time in process, all cores to itself), the cluster's efficiency against that sum
(sum / (wall x workers)), the peak memory per worker process, and the overhead per
exemplar (wall x workers - task times, per exemplar: scheduling, start-up, hashing, the
ledger and the contact sheet). Writes benchmarks/results/bench_batch.{json,md}.
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


def one_mode(manifest, outdir, *, workers, count, size, seed):
    from tghop import batch

    t = time.perf_counter()
    results = batch.run(manifest, outdir, count=count, size=size, seed=seed, workers=workers)
    wall = time.perf_counter() - t
    failed = [r["name"] for r in results if r["status"] != "ok"]
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
    args = ap.parse_args()
    names = texture_names()[: args.limit]
    if not names:
        raise SystemExit(f"no textures in {TEXTURES}; set TGHOP_TEXTURES")
    files = {p.stem: p for p in TEXTURES.iterdir() if p.stem in names}
    cores = len(os.sched_getaffinity(0))
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        manifest = Path(tmp) / "manifest.csv"
        manifest.write_text("path\n" + "".join(f"{files[n]}\n" for n in names))
        kw = dict(count=args.count, size=(args.size, args.size), seed=0)
        single = one_mode(manifest, Path(tmp) / "in_process", workers=1, **kw)
        single["peak_rss_mb_per_worker"] = {"this process": peak_rss_mb()}
        cluster = one_mode(manifest, Path(tmp) / "cluster", workers=args.workers, **kw)
    load_after = os.getloadavg()
    n_workers = args.workers or cores
    sum_single = single["task_s"]
    rows = []
    for label, m, w in (("--workers 1 (in process)", single, 1), (f"local cluster, {n_workers} workers", cluster,
                                                                   n_workers)):
        m["efficiency"] = sum_single / (m["wall_s"] * w)
        m["overhead_s_per_exemplar"] = (m["wall_s"] * w - m["task_s"]) / m["n"]
        m["speedup"] = single["wall_s"] / m["wall_s"]
        rows.append([label, m["wall_s"], m["wall_s"] / m["n"], m["speedup"], m["efficiency"],
                     m["overhead_s_per_exemplar"], max(m["peak_rss_mb_per_worker"].values()),
                     m["fit_s_median"], m["synth_s_median"], len(m["failed"])])
    header = ["mode", "wall s", "s / exemplar", "speedup", "efficiency", "overhead s / exemplar",
              "peak MB / worker", "fit s (median)", "synth s (median)", "failed"]
    md = (f"# bench_batch: {len(names)} exemplars, {args.count} images each at {args.size}x{args.size}, "
          f"{cores} cores\n\nSum of single-exemplar task times (in process): {sum_single:.1f} s.\n\n"
          + markdown_table(header, rows)
          + "\n\nefficiency = sum of single-exemplar times / (wall x workers); overhead = (wall x workers - "
            "task times) / exemplars; peak MB: the worker process's peak resident memory.")
    print(md)
    write_results("bench_batch", {"exemplars": names, "count": args.count, "size": args.size, "cores": cores,
                                  "sum_single_s": sum_single, "load_before": load_before, "load_after": load_after, "in_process": single, "cluster": cluster}, md)


if __name__ == "__main__":
    main()
