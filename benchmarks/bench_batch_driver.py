"""The batch driver's own cost per exemplar on Dask (`tghop.batch.run`, issue #29): many tiny exemplars
whose task returns at once, on a given client's cluster with more threads than the driver can keep
busy, so that the wall time per exemplar is the driver's (getting each result, asking the workers,
the ledger line, the exemplar's `.batch-running` file) and the scheduler's.

    python benchmarks/bench_batch_driver.py                  # 300 exemplars, 2 workers x 16 threads
    python benchmarks/bench_batch_driver.py -n 600 --profile # and the driver thread's cProfile (top 15)

Reported: the time from the first result to the last, per exemplar after the first; the calls of the
driver's thread that cost most (`--profile`). A shared machine is noisy: compare runs made side by side.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image


def instant(job):
    """A stand-in task: a failed record at once (no model, no files), as a bad exemplar's."""
    return {"status": "failed", "error": "stand-in", "cause": "run", "outputs": [], "model": None,
            "thumbnail": None, "seed_used": job.get("seed"), "started": time.time(), "seconds": 0.0}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-n", type=int, default=300, help="exemplars (default 300)")
    ap.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--threads", type=int, default=16, help="threads per worker (default 16)")
    ap.add_argument("--profile", action="store_true", help="print the driver thread's costliest calls")
    args = ap.parse_args(argv)

    import distributed

    from tghop.batch import run

    with tempfile.TemporaryDirectory(prefix="bench-driver-") as tmp:
        src = Path(tmp, "src")
        src.mkdir()
        rng = np.random.default_rng(0)
        for i in range(args.n):
            Image.fromarray(rng.integers(0, 255, (8, 8, 3), dtype=np.uint8)).save(src / f"e{i:05d}.png")
        cluster = distributed.LocalCluster(n_workers=args.workers, threads_per_worker=args.threads,
                                           processes=True, dashboard_address=":0", silence_logs=50)
        client = distributed.Client(cluster)
        times = []
        prof = cProfile.Profile() if args.profile else None
        try:
            if prof:
                prof.enable()
            run(src, Path(tmp, "out"), client=client, task=instant, contact_sheet=False,
                on_result=lambda rec, counts: times.append(time.perf_counter()))
            if prof:
                prof.disable()
        finally:
            client.close()
            cluster.close()
    per = (times[-1] - times[0]) / max(1, len(times) - 1)
    print(f"{len(times)} exemplars, {args.workers} workers x {args.threads} threads: first to last result "
          f"{times[-1] - times[0]:.2f} s, {per * 1000:.1f} ms per exemplar ({1 / per:.0f} a second)")
    if prof:
        out = io.StringIO()
        stats = pstats.Stats(prof, stream=out)
        stats.sort_stats("tottime").print_stats(8)
        stats.sort_stats("cumulative").print_stats(
            r"\((result|gather|nthreads|scheduler_info|submit|map|append_ledger|sync_ledger|mark_running|finish|"
            r"hand_out|remove_stale|_cost|run_distributed|_next_group|get)\)")
        print(out.getvalue())
    return 0


if __name__ == "__main__":
    sys.exit(main())
