"""Speed and memory of :func:`tghop.quilting.quilt`.

Pool: 10,000 patches of 32x32x3, random crops of ``tghop.data.bricks(256)`` (float32, as
TGHop hands them over). Prints a table and writes ``benchmarks/results/quilting.json`` and a
Markdown table beside it (``quilting.md``).

    python benchmarks/bench_quilting.py            # 256x256 and 2048x2048 (plain and tiled)
    python benchmarks/bench_quilting.py --quick    # small sizes only
    python benchmarks/bench_quilting.py --raster   # also the one-block-at-a-time reference
    python benchmarks/bench_quilting.py --blas-threads default   # only BLAS's own thread count

Targets (2-core machine): 256x256 well under 0.5 s, 2048x2048 under ~12 s.
Time is the best of ``--repeat`` runs; peak memory is measured in a separate run with
``tracemalloc`` (numpy reports its buffers to it) and excludes the pool itself.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import sys
import time
import tracemalloc
from dataclasses import replace
from pathlib import Path

import numpy as np

from tghop import quilting
from tghop.data import bricks

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _common import markdown_table  # noqa: E402


def make_pool(n=10_000, patch=32, seed=0):
    tex = bricks(256).astype(np.float32)
    rng = np.random.default_rng(seed)
    ys = rng.integers(0, tex.shape[0] - patch + 1, n)
    xs = rng.integers(0, tex.shape[1] - patch + 1, n)
    rows = ys[:, None] + np.arange(patch)
    cols = xs[:, None] + np.arange(patch)
    return tex[rows[:, :, None], cols[:, None, :]]  # (n, patch, patch, 3)


def raster_plan(plan):
    """The same plan, one block per step (matrix-vector products): the reference the
    wavefront batching is measured against. Blocks keep their order, so the image is
    the same."""
    ny, nx = plan.level.shape
    ii, jj = np.mgrid[0:ny, 0:nx]
    order = np.lexsort((jj.ravel(), ii.ravel(), plan.level.ravel()))
    level = np.empty(ny * nx, dtype=np.int32)
    level[order] = np.arange(ny * nx, dtype=np.int32)
    return replace(plan, level=level.reshape(ny, nx), n_levels=ny * nx)


def run(pool, size, tile, repeat, raster=False):
    quilt_kwargs = dict(tile=tile, rng=0)
    original = quilting.quilting_plan
    if raster:
        quilting.quilting_plan = lambda *a, **k: raster_plan(original(*a, **k))
    try:
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            out = quilting.quilt(pool, size, **quilt_kwargs)
            times.append(time.perf_counter() - t0)
        del out
        tracemalloc.start()
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        out = quilting.quilt(pool, size, **quilt_kwargs)
        peak = tracemalloc.get_traced_memory()[1] - base
        tracemalloc.stop()
    finally:
        quilting.quilting_plan = original
    plan = quilting.quilting_plan(size, pool.shape[1], tile=tile)
    return {
        "size": f"{size[0]}x{size[1]}",
        "tile": tile,
        "mode": "raster (1 block/GEMV)" if raster else "wavefront (GEMM)",
        "blocks": plan.n_blocks,
        "steps": plan.n_levels if not raster else plan.n_blocks,
        "seconds_best": round(min(times), 3),
        "seconds_all": [round(t, 3) for t in times],
        "peak_mib": round(peak / 2**20, 1),
        "output_mib": round(out.nbytes / 2**20, 1),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="256x256 and 512x512 only")
    ap.add_argument("--raster", action="store_true", help="also time the one-block-at-a-time reference")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument(
        "--blas-threads", default="default,1",
        help="comma-separated BLAS thread counts to run each case with ('default': BLAS's own); "
        "on a busy machine 1 thread can be faster",
    )
    ap.add_argument("--out", default=str(HERE / "results" / "quilting.json"))
    args = ap.parse_args(argv)

    from threadpoolctl import threadpool_info, threadpool_limits

    settings = [None if t.strip() == "default" else int(t) for t in args.blas_threads.split(",")]
    blas = [p.get("num_threads", 1) for p in threadpool_info() if p.get("user_api") == "blas"]
    default_threads = max(blas, default=1)
    t0 = time.perf_counter()
    pool = make_pool()
    print(f"pool {pool.shape} {pool.dtype} ({pool.nbytes / 2**20:.0f} MiB) made in {time.perf_counter() - t0:.1f} s")
    cases = [((256, 256), False), ((512, 512), False), ((256, 256), True)]
    if not args.quick:
        cases += [((2048, 2048), False), ((2048, 2048), True)]
    load_start = os.getloadavg()
    rows = []
    for size, tile in cases:
        for threads in settings:
            with threadpool_limits(threads):
                rows.append(dict(run(pool, size, tile, args.repeat), blas_threads=threads or default_threads))
                if args.raster and size[0] <= 512:
                    rows.append(dict(run(pool, size, tile, 1, raster=True), blas_threads=threads or default_threads))
            print(f"  done {rows[-1]['size']} tile={tile} threads={threads or 'default'}", file=sys.stderr)

    header = (
        f"{'size':>10} {'tile':>5} {'threads':>7} {'mode':>22} {'blocks':>7} {'steps':>6} "
        f"{'best s':>8} {'peak MiB':>9} {'out MiB':>8}"
    )
    print(header)
    print("-" * len(header))
    for r in rows:
        print(
            f"{r['size']:>10} {str(r['tile']):>5} {r['blas_threads']:>7} {r['mode']:>22} "
            f"{r['blocks']:>7} {r['steps']:>6} "
            f"{r['seconds_best']:>8.3f} {r['peak_mib']:>9.1f} {r['output_mib']:>8.1f}"
        )
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    print(f"process max RSS {maxrss:.0f} MiB (includes the {pool.nbytes / 2**20:.0f} MiB pool)")
    load = os.getloadavg()
    print(f"load average at start {load_start[0]:.1f}, at end {load[0]:.1f} (other processes slow BLAS down)")
    result = {
        "benchmark": "quilting",
        "pool": {"n": pool.shape[0], "patch": pool.shape[1], "channels": pool.shape[3], "dtype": str(pool.dtype)},
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(), "loadavg_at_end": load},
        "numpy": np.__version__,
        "blas_threads_default": default_threads,
        "loadavg_at_start": load_start,
        "max_rss_mib": round(maxrss, 1),
        "results": rows,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    table = markdown_table(["size", "tile", "BLAS threads", "mode", "blocks", "steps", "best s", "peak MiB", "out MiB"],
                           [[r["size"], str(r["tile"]), r["blas_threads"], r["mode"], r["blocks"], r["steps"],
                             r["seconds_best"], r["peak_mib"], r["output_mib"]] for r in rows])
    out.with_suffix(".md").write_text(
        f"# Quilting alone (bench_quilting.py)\n\n{table}\n\nPool: {pool.shape[0]:,} patches of "
        f"{pool.shape[1]}x{pool.shape[2]}x{pool.shape[3]} ({pool.dtype}); process max RSS {maxrss:.0f} MiB; "
        f"load average {load_start[0]:.1f} at start, {load[0]:.1f} at end.\n")
    print(f"wrote {out} and {out.with_suffix('.md')}")


if __name__ == "__main__":
    main()
