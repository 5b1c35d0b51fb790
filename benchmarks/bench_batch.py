"""`tghop batch` over the shared textures: how well the default local Dask cluster uses the
cores, measured against the serial work (issue #29).

    python benchmarks/bench_batch.py                 # the full run: all 44 exemplars, 2 images each at 512x512
                                                     # (about 15 min on an idle 2-core machine; run it alone)
    python benchmarks/bench_batch.py --limit 8       # the first 8 (what fits a shared 2-core machine)
    python benchmarks/bench_batch.py --limit 6 --crop 128 --size 128 --scheduler-workers 4
                                                     # centre crops, plus a 4-process cluster via --scheduler
    python benchmarks/bench_batch.py --limit 4 --no-all-threads --repeat 3
                                                     # a busy machine: 3 pairs (one thread, cluster) alternated,
                                                     # each cluster against its own pair's serial pass; medians

Modes, each a `tghop.batch.run` on the same manifest:

* in process, one thread (`--workers 1`, each exemplar's task with `threads=1`: BLAS and
  tghop's own threads limited to one, `tghop._common.limit_cores`): the serial work, what
  one core does. Its per-exemplar task times are the single-exemplar times;
* in process, all threads (`--workers 1` as `tghop batch` runs it: a fit's clusters on
  every core); `--no-all-threads` skips it;
* the default local cluster (`--workers`: its size; default one worker process per core,
  one thread each); its wall time includes starting the cluster;
* optionally (`--scheduler-workers N`) a cluster of N worker processes started first and
  used by address, as `tghop batch --scheduler ADDRESS` does.

The in-process passes run with a cluster worker's glibc malloc settings
(`tghop.batch.tune_malloc`; `--serial-malloc default`: glibc's own), so that the serial work
and the cluster's tasks differ only in running side by side.

Reported: each mode's wall time; the serial work S (the sum of the one-thread
single-exemplar times); efficiency = S / (cores x wall), the standard parallel efficiency
(1.0: every core busy with useful work all the time); the per-exemplar overhead of the
cluster: each exemplar's task time on a cluster worker against its one-thread time in
process (median and total), and (cores x wall - task times) / exemplars (scheduling,
start-up, the driver's hashing and ledger, idle cores in the tail); peak memory per worker
(VmHWM); and, first, the machine's own ceiling: a kernel that stays in a core's cache, one
whose working set fits the shared last-level cache alone but not twice over, and a
memory-streaming one, each run alone and as one process per core at once (no tghop, no
Dask). The old comparison (in-process wall with all threads against the cluster's wall,
and the efficiency against the all-thread in-process sum, which counts every core twice)
is kept, labelled as such. Timings on a shared machine are noisy: the load average before
and after is recorded, and the CPU seconds of each task beside its wall time.

Writes benchmarks/results/batch-efficiency[-limitN][-cropN][-TAG].{json,md}.
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

from _common import TEXTURES, markdown_table, texture_names, write_results  # noqa: E402


def one_thread(job):
    """The batch task with every thread limit at one (in process: the serial work)."""
    from tghop import batch

    return batch.process_exemplar({**job, "threads": 1})


def machine_busy_s() -> float:
    """CPU seconds the whole machine has spent busy (every process; /proc/stat)."""
    with open("/proc/stat") as fh:
        fields = [int(v) for v in fh.readline().split()[1:]]
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)  # idle, iowait
    return (sum(fields[:8]) - idle) / os.sysconf("SC_CLK_TCK")


def own_cpu_s() -> float:
    """CPU seconds of this process and its finished children (the cluster's workers)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


#: Kernels that say what running tasks side by side costs on this machine by itself,
#: without tghop or Dask: a product of small matrices that stays in a core's cache; passes
#: over 24 MB, which the shared last-level cache holds for one process but not for two
#: (32 MB here); and passes over 256 MB, which stream through memory (each one thread,
#: about a second alone).
KERNELS = {
    "compute (in cache)": "a = np.random.rand(128, 128).astype(np.float32)\n"
                          "t = time.perf_counter()\nfor _ in range(30000): a @ a\n",
    "shared cache (24 MB)": "a = np.ones(3 << 20, dtype=np.float32); b = np.empty_like(a); b += a\n"
                            "t = time.perf_counter()\nfor _ in range(3500): np.multiply(a, 1.0001, out=b)\n",
    "memory (streaming)": "a = np.ones(64 << 20, dtype=np.float32); b = np.empty_like(a); b += a\n"
                          "t = time.perf_counter()\nfor _ in range(40): np.multiply(a, 1.0001, out=b)\n",
}


def kernel_seconds(code, copies):
    """Each of ``copies`` processes' time for ``code`` run at once (one BLAS thread each)."""
    import subprocess

    script = ("import time, numpy as np\nfrom threadpoolctl import threadpool_limits\nwith threadpool_limits(1):\n"
              + "".join("    " + line + "\n" for line in code.splitlines())
              + "print(time.perf_counter() - t)\n")
    procs = [subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
             for _ in range(copies)]
    return [float(p.communicate()[0]) for p in procs]


def machine_ceiling(cores, repeats=3):
    """How much slower each kernel runs as ``cores`` processes at once than alone (medians
    of ``repeats`` alternating runs): the most a batch of tasks like it can get from the
    cores. Returns {kernel: {"alone_s", "together_s", "slowdown", "efficiency"}}."""
    out = {}
    for name, code in KERNELS.items():
        alone, together = [], []
        for _ in range(repeats):
            alone += kernel_seconds(code, 1)
            together += kernel_seconds(code, cores)
        a, b = statistics.median(alone), statistics.median(together)
        out[name] = {"alone_s": a, "together_s": b, "slowdown": b / a, "efficiency": a / b}
    return out


def one_mode(manifest, outdir, *, workers, count, size, seed, scheduler=None, task=None):
    from tghop import batch

    busy, own, t = machine_busy_s(), own_cpu_s(), time.perf_counter()
    results = batch.run(manifest, outdir, count=count, size=size, seed=seed, workers=workers, scheduler=scheduler,
                        task=task, contact_sheet=True)
    wall = time.perf_counter() - t
    # Cores that other programs kept busy meanwhile (a cluster given by address: its
    # workers are not children of this process and count as others).
    others = max(0.0, (machine_busy_s() - busy) - (own_cpu_s() - own)) / wall
    failed = [r["name"] for r in results if r["status"] != "ok"]
    if len(failed) == len(results):
        raise SystemExit(f"every exemplar failed, e.g. {results[0]['name']}: {results[0]['error']}")
    per_worker = {}
    for r in results:
        per_worker[r["worker"]] = max(per_worker.get(r["worker"], 0.0), r.get("peak_rss_mb") or 0.0)
    ok = [r for r in results if r["status"] == "ok"]
    return {"wall_s": wall, "other_load": others, "task_s": sum(r["seconds"] or 0.0 for r in results),
            "cpu_s": sum(r.get("cpu_seconds") or 0.0 for r in results), "failed": failed, "n": len(results),
            "workers": len(per_worker), "peak_rss_mb_per_worker": per_worker,
            "fit_s_median": statistics.median(r["fit_seconds"] for r in ok),
            "synth_s_median": statistics.median(r["synth_seconds"] for r in ok),
            "sys_s_median": statistics.median(r.get("sys_seconds") or 0.0 for r in ok),
            "page_faults_median": statistics.median(r.get("page_faults") or 0 for r in ok),
            "task_s_by_exemplar": {r["name"]: r["seconds"] for r in results},
            "cpu_s_by_exemplar": {r["name"]: r.get("cpu_seconds") for r in results},
            "order": [r["name"] for r in sorted(results, key=lambda r: r.get("started") or 0)]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=int, default=None, help="first N exemplars only")
    ap.add_argument("--count", type=int, default=2)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--workers", type=int, default=None, help="local cluster size (default: one per core)")
    ap.add_argument("--crop", type=int, default=None, help="centre crops of CROPxCROP as the exemplars")
    ap.add_argument("--no-all-threads", action="store_true",
                    help="skip the in-process run with all threads (the old comparison)")
    ap.add_argument("--scheduler-workers", type=int, default=0,
                    help="also: start a local cluster of this many worker processes and run on it by address")
    ap.add_argument("--tag", default="", help="suffix of the result files")
    ap.add_argument("--no-ceiling", action="store_true", help="skip the kernels that measure the machine alone")
    ap.add_argument("--cluster-config", choices=("quiet", "dask"), default="quiet",
                    help="Dask's own periodic work in the local cluster: made rarer (tghop.batch.QUIET_CLUSTER, "
                         "0.57) or as Dask sets it (before)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="run the one-thread pass and the cluster this many times, alternated (a shared machine's "
                         "load changes by the minute): each cluster is compared with the serial pass just before "
                         "it, and the medians over the pairs are reported")
    ap.add_argument("--serial-malloc", choices=("worker", "default"), default="worker",
                    help="glibc malloc settings of the in-process passes: a worker's (tghop.batch.tune_malloc, "
                         "like for like with the cluster) or glibc's defaults")
    args = ap.parse_args()
    if args.serial_malloc == "worker":
        # The serial work is measured under the settings the cluster's workers run with, so
        # that the efficiency compares two tasks side by side with one alone, not two mallocs.
        from tghop import batch

        batch.tune_malloc()
    if args.cluster_config == "dask":
        from tghop import batch_dask

        batch_dask.QUIET_CLUSTER.clear()  # local_cluster reads it when it starts the cluster
    names = texture_names()[: args.limit]
    if not names:
        raise SystemExit(f"no textures in {TEXTURES}; set TGHOP_TEXTURES")
    files = {p.stem: p for p in TEXTURES.iterdir() if p.stem in names}
    cores = len(os.sched_getaffinity(0))
    n_workers = args.workers or cores
    load_before = os.getloadavg()
    ceiling = machine_ceiling(cores) if cores > 1 and not args.no_ceiling else {}
    modes = []
    with tempfile.TemporaryDirectory() as tmp:
        if args.crop:
            files = {n: centre_crop(f, args.crop, Path(tmp) / "crops") for n, f in files.items()}
        manifest = Path(tmp) / "manifest.csv"
        manifest.write_text("path,name\n" + "".join(f"{files[n]},{n}\n" for n in names))
        kw = dict(count=args.count, size=(args.size, args.size), seed=0)
        pairs = []
        for i in range(max(1, args.repeat)):
            pair = f" (pair {i + 1})" if args.repeat > 1 else ""
            serial = one_mode(manifest, Path(tmp) / f"one_thread{i}", workers=1, task=one_thread, **kw)
            modes.append((f"in process, one thread (the serial work){pair}", serial, 1, serial))
            all_threads = None
            if not args.no_all_threads:
                all_threads = one_mode(manifest, Path(tmp) / f"in_process{i}", workers=1, **kw)
                modes.append((f"in process, all threads (`--workers 1`){pair}", all_threads, cores, serial))
            cluster = one_mode(manifest, Path(tmp) / f"cluster{i}", workers=args.workers, **kw)
            modes.append((f"local cluster, {n_workers} workers x 1 thread (the default){pair}", cluster, n_workers,
                          serial))
            pairs.append((serial, cluster))
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
                          scheduled, args.scheduler_workers, serial))
    load_after = os.getloadavg()

    work = serial["task_s"]  # S: the sum of one-thread single-exemplar times (the last pair's)
    rows = []
    for label, m, w, ref in modes:  # ref: the serial pass of m's pair
        used = min(w, cores)  # more processes than cores: they share the cores
        m["cores_used"] = used
        m["efficiency"] = ref["task_s"] / (used * m["wall_s"])
        m["speedup_vs_serial"] = ref["wall_s"] / m["wall_s"]
        for key, by, total in (("task", "task_s_by_exemplar", "task_s"), ("cpu", "cpu_s_by_exemplar", "cpu_s")):
            base = ref[by]
            ratios = [m[by][n] / base[n] - 1 for n in base if base[n] and m[by].get(n) and n not in m["failed"]]
            m[f"{key}_overhead_median"] = statistics.median(ratios) if ratios else float("nan")
            m[f"{key}_overhead_total"] = m[total] / ref[total] - 1
        m["core_share"] = m["cpu_s"] / m["task_s"]
        m["idle_s_per_exemplar"] = (used * m["wall_s"] - m["task_s"]) / m["n"]
        rows.append([label, m["wall_s"], m["wall_s"] / m["n"], m["efficiency"],
                     f"{m['task_overhead_median']:+.0%} / {m['task_overhead_total']:+.0%}",
                     f"{m['cpu_overhead_median']:+.0%} / {m['cpu_overhead_total']:+.0%}", m["core_share"],
                     m["other_load"], m["idle_s_per_exemplar"], max(m["peak_rss_mb_per_worker"].values()),
                     m["fit_s_median"], m["synth_s_median"], m["sys_s_median"], m["page_faults_median"],
                     len(m["failed"])])
    header = ["mode", "wall s", "wall s / exemplar", "efficiency", "task time vs one thread (median / total)",
              "task CPU vs one thread (median / total)", "task CPU / task time", "other programs (cores busy)",
              "idle core-s / exemplar", "peak MB / worker", "fit s (median)", "synth s (median)",
              "kernel CPU s / task (median)", "page faults / task (median)", "failed"]
    crop = f" (centre crops {args.crop}x{args.crop})" if args.crop else ""
    medians = None
    if len(pairs) > 1:
        medians = {key: statistics.median(c[key] for _, c in pairs) for key in
                   ("efficiency", "task_overhead_median", "cpu_overhead_median", "other_load", "wall_s")}
        medians["serial_work_s"] = statistics.median(s["task_s"] for s, _ in pairs)
        medians["serial_other_load"] = statistics.median(s["other_load"] for s, _ in pairs)
    old = ""
    if all_threads is not None:
        old_eff = all_threads["task_s"] / (n_workers * cluster["wall_s"])
        old = (f"\n\nThe old comparison (before issue #29's efficiency was defined against one thread): in "
               f"process with all threads {all_threads['wall_s']:.1f} s against the local cluster's "
               f"{cluster['wall_s']:.1f} s, a speedup of {all_threads['wall_s'] / cluster['wall_s']:.2f}; "
               f"'efficiency' against the all-thread in-process sum ({all_threads['task_s']:.1f} s / "
               f"({n_workers} x wall)) {old_eff:.2f}: that sum already used every core, so it counts them twice.")
    md = (f"# bench_batch: {len(names)} exemplars{crop}, {args.count} images each at {args.size}x{args.size}, "
          f"{cores} cores\n\nLoad average before {load_before[0]:.1f}, after {load_after[0]:.1f} (a shared "
          f"machine: other sessions' work competes with these runs; timings are noisy).\n\n"
          f"Serial work S (sum of the one-thread single-exemplar times, in process, malloc settings: "
          f"{args.serial_malloc}): {work:.1f} s ({work / len(names):.2f} s per exemplar). Dask's periodic work in "
          f"the local cluster: {args.cluster_config}.\n\n"
          + markdown_table(header, rows)
          + (f"\n\nMedians over the {len(pairs)} pairs (each cluster against the serial pass just before it): "
             f"S {medians['serial_work_s']:.1f} s, cluster wall {medians['wall_s']:.1f} s, **efficiency "
             f"{medians['efficiency']:.3f}**, a cluster task {medians['task_overhead_median']:+.1%} time "
             f"({medians['cpu_overhead_median']:+.1%} CPU) against one thread alone (the median exemplar's); "
             f"other programs {medians['serial_other_load']:.2f} cores during the serial passes, "
             f"{medians['other_load']:.2f} during the clusters." if medians else "")
          + "\n\nefficiency = S / (cores x wall), cores capped at the machine's; task time vs one thread: each "
            "exemplar's task time in this mode against its one-thread in-process time (the cluster's overhead "
            "per exemplar: serialisation, result transfer, image writes in a worker, two workers sharing memory "
            "bandwidth; goal <= 5 %); task CPU: the same with the CPU seconds of the task's process (all its "
            "threads), which other programs disturb less than wall time; task CPU / task time: the share of a "
            "core (or cores) a task got (about 1 for a one-thread task that had its core); other programs: cores "
            "kept busy by other processes during the mode (/proc/stat less this process and its workers; "
            "efficiency needs them near 0); idle core-s / exemplar = (cores x wall - task times) / exemplars: "
            "start-up, scheduling, the driver's hashing and ledger, idle cores in the tail; peak MB: each worker "
            "process's peak resident memory (VmHWM); kernel CPU and page faults: the task's "
            "process's system time and page faults (getrusage), mostly the kernel mapping fresh memory in. Cluster "
            "walls include starting the cluster."
          + (f" The --scheduler cluster took {scheduled['cluster_start_s']:.1f} s to start (not in its wall time)."
             if scheduled else "")
          + old
          + ("\n\nThe machine alone (no tghop, no Dask): each kernel run as one process, then as "
             f"{cores} at once (one thread each; medians of 3):\n\n" + markdown_table(
                 ["kernel", "alone s", f"{cores} at once s", "slowdown", "efficiency it allows"],
                 [[k, v["alone_s"], v["together_s"], v["slowdown"], v["efficiency"]] for k, v in ceiling.items()])
             + "\n\nA task's phases whose arrays share the last-level cache or stream through memory (large "
               "arrays, FFTs) are slowed like the second or third kernel when the workers run them at the same "
               "time, whatever runs the tasks." if ceiling else "")
          + f"\n\nCommand: `python benchmarks/bench_batch.py {' '.join(sys.argv[1:])}`".rstrip() + "")
    print(md)
    name = ("batch-efficiency" + (f"-limit{args.limit}" if args.limit else "")
            + (f"-crop{args.crop}" if args.crop else "") + (f"-{args.tag}" if args.tag else ""))
    write_results(name, {"exemplars": names, "crop": args.crop, "count": args.count, "size": args.size, "cores": cores,
                         "serial_work_s": work, "serial_malloc": args.serial_malloc,
                         "cluster_config": args.cluster_config,
                         "load_before": load_before, "load_after": load_after,
                         "argv": sys.argv[1:], "one_thread": serial, "all_threads": all_threads, "cluster": cluster,
                         "pairs": [{"one_thread": a, "cluster": b} for a, b in pairs] if len(pairs) > 1 else None,
                         "medians": medians,
                         "scheduler": scheduled, "machine_ceiling": ceiling}, md)


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
