"""The command a user types, timed as whole processes: the table of issue #8.

Each row runs ``python -m tghop ...`` in a fresh process several times (after one
warm-up) and reports the median wall time and the largest peak resident memory (from
the operating system's accounting of each finished child, ``os.wait4``). Model-file
sizes are read from disk. Large exemplars are made by tiling a shared texture.

    python benchmarks/bench_cli.py                 # all rows, 5 runs each
    python benchmarks/bench_cli.py --quick         # 3 runs, no 8192^2 synthesis, no 8000^2 / 12000^2 fits
    python benchmarks/bench_cli.py --src /path/to/other/checkout/src   # time another version
    python benchmarks/bench_cli.py --only 15,16,17 --runs 1               # the evaluate rows only

Writes benchmarks/results/bench_cli.{json,md} (or bench_cli_<label>.* with --label).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import TEXTURES, markdown_table, write_results  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def run(args, src, cwd):
    """One whole process: (wall seconds, CPU seconds, peak RSS in MB, exit code, stderr tail)."""
    # As after `pip install`: byte-code compiled once and used (not recompiled every run).
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(PYTHONPATH=str(src), PYTHONWARNINGS="ignore")
    start = time.perf_counter()
    p = subprocess.Popen([sys.executable, "-m", "tghop", *map(str, args)], cwd=cwd, env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    err = p.stderr.read()
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - start
    p.returncode = os.waitstatus_to_exitcode(status)
    cpu = usage.ru_utime + usage.ru_stime
    return wall, cpu, usage.ru_maxrss / 1024, p.returncode, err.decode(errors="replace")[-300:]


def measure(label, args, src, cwd, runs, warmup=1):
    for _ in range(warmup):
        run(args, src, cwd)
    walls, cpus, peaks, codes, tail = [], [], [], set(), ""
    for _ in range(runs):
        wall, cpu, peak, code, tail = run(args, src, cwd)
        walls.append(wall)
        cpus.append(cpu)
        peaks.append(peak)
        codes.add(code)
    row = {"command": label, "median_s": statistics.median(walls), "min_s": min(walls), "max_s": max(walls),
           "cpu_s": statistics.median(cpus), "peak_mb": max(peaks), "runs": runs, "exit": sorted(codes)}
    if codes != {0}:
        row["stderr"] = tail.strip().splitlines()[-1] if tail.strip() else ""
    print(f"{label:<58} {row['median_s']:7.2f} s  (min {row['min_s']:.2f}, max {row['max_s']:.2f}, "
          f"CPU {row['cpu_s']:.2f} s)  "
          f"{row['peak_mb']:7.0f} MB  exit {row['exit']}", file=sys.stderr)
    return row


def measure_together(label, args, src, cwd, runs, copies=2):
    """``copies`` processes of the same command started at once (a machine busy with other
    work): the median over ``runs`` of the slowest one's wall time, and its CPU time.
    ``tghop fit``'s one BLAS / OpenMP thread and its idle-core count of ICA threads should
    keep each no slower than alone on a machine with ``copies`` cores."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(PYTHONPATH=str(src), PYTHONWARNINGS="ignore")
    walls, cpus, peaks, codes = [], [], [], set()
    for _ in range(runs):
        start = time.perf_counter()
        procs = [subprocess.Popen([sys.executable, "-m", "tghop", *map(str, args), "-o", f"together{i}.npz"],
                                  cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                 for i in range(copies)]
        slowest = cpu = peak = 0.0
        for p in procs:
            _, status, usage = os.wait4(p.pid, 0)
            slowest = time.perf_counter() - start
            cpu = max(cpu, usage.ru_utime + usage.ru_stime)
            peak = max(peak, usage.ru_maxrss / 1024)
            codes.add(os.waitstatus_to_exitcode(status))
        walls.append(slowest)
        cpus.append(cpu)
        peaks.append(peak)
    row = {"command": label, "median_s": statistics.median(walls), "min_s": min(walls), "max_s": max(walls),
           "cpu_s": statistics.median(cpus), "peak_mb": max(peaks), "runs": runs, "exit": sorted(codes)}
    print(f"{label:<58} {row['median_s']:7.2f} s  (min {row['min_s']:.2f}, max {row['max_s']:.2f})", file=sys.stderr)
    return row


BIG = """
import sys
from PIL import Image
Image.MAX_IMAGE_PIXELS = None
tile = Image.open(sys.argv[1]).convert("RGB")
width, height = int(sys.argv[3]), int(sys.argv[4])
big = Image.new("RGB", (width, height))
for y in range(0, height, tile.height):
    for x in range(0, width, tile.width):
        big.paste(tile, (x, y))
if len(sys.argv) > 5:  # crop LEFT TOP off: the same texture at another offset
    left, top = int(sys.argv[5]), int(sys.argv[6])
    big = big.crop((left, top, width, height))
big.save(sys.argv[2], quality=90)
"""


def big_exemplar(folder, name, width, height, crop=None):
    """A ``width`` x ``height`` JPEG tiled from brick_wall, made in a separate process (a
    child inherits its parent's peak memory in the accounting, so this process stays small).
    ``crop=(left, top)`` cuts that much off the top-left corner."""
    path = Path(folder) / f"{name}.jpg"
    if not path.exists():
        extra = [] if crop is None else [str(crop[0]), str(crop[1])]
        subprocess.run([sys.executable, "-c", BIG, TEXTURES / "brick_wall.jpg", path, str(width), str(height),
                        *extra], check=True)
    return path


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--quick", action="store_true",
                        help="3 runs; skip the 8192^2 synthesis and the 8000^2 / 12000^2 fits")
    parser.add_argument("--src", default=str(ROOT / "src"), help="the tghop source folder to time")
    parser.add_argument("--label", default="", help="suffix of the result files (e.g. 'before')")
    parser.add_argument("--only", default=None, help="comma-separated row numbers to run (1-based)")
    args = parser.parse_args()
    runs = 3 if args.quick else args.runs
    src = Path(args.src).resolve()
    # pip compiles a package's byte-code at install; do the same for the source timed here.
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(src)], check=True)
    exemplar = TEXTURES / "brick_wall.jpg"
    if not exemplar.exists():
        raise SystemExit(f"{exemplar} not found; set TGHOP_TEXTURES")
    load = os.getloadavg()[0]
    print(f"tghop from {src}; load average {load:.1f} on {os.cpu_count()} cores", file=sys.stderr)

    with tempfile.TemporaryDirectory() as work:
        w = Path(work)
        # Models used by the generation rows (fitted once, not timed here).
        subprocess.run([sys.executable, "-m", "tghop", "fit", exemplar, "-o", w / "m.npz", "-q"], check=True,
                       env={**os.environ, "PYTHONPATH": str(src)}, cwd=w)
        subprocess.run([sys.executable, "-m", "tghop", "fit", exemplar, "-o", w / "paper.npz", "-q", "--paper"],
                       check=True, env={**os.environ, "PYTHONPATH": str(src)}, cwd=w)
        rows = [
            ("tghop --help", ["--help"], runs),
            ("tghop --version", ["--version"], runs),
            ("tghop info m.npz", ["info", "m.npz"], runs),
            ("tghop synth m.npz --size 256x256", ["synth", "m.npz", "-o", "o.png", "--size", "256x256", "-q"], runs),
            ("tghop synth m.npz --size 1024x1024", ["synth", "m.npz", "-o", "o.png", "--size", "1024x1024", "-q"],
             runs),
            ("tghop synth m.npz --size 2048x2048", ["synth", "m.npz", "-o", "o.png", "--size", "2048x2048", "-q"],
             runs),
            ("tghop synth m.npz --size 8192x8192", ["synth", "m.npz", "-o", "o.png", "--size", "8192x8192", "-q"],
             1),
            ("tghop fit brick_wall.jpg (defaults)", ["fit", exemplar, "-o", "f.npz", "-q"], runs),
            ("tghop fit builtin:bricks, alone", ["fit", "builtin:bricks", "-o", "f.npz", "-q"], runs),
            ("tghop fit builtin:bricks, two at once (slower one)", ["fit", "builtin:bricks", "-q"], runs),
            ("tghop fit 3000x4000 photo", ["fit", "big3000x4000.jpg", "-o", "f.npz", "-q"], 1),
            ("tghop fit 8000x8000 photo", ["fit", "big8000x8000.jpg", "-o", "f.npz", "-q"], 1),
            ("tghop fit 12000x12000 photo", ["fit", "big12000x12000.jpg", "-o", "f.npz", "-q"], 1),
            ("tghop fit 12000x12000 photo --downscale",
             ["fit", "big12000x12000.jpg", "-o", "f.npz", "-q", "--downscale"], 1),
            # Issue #26: evaluate's memory (one result against an exemplar of the same size;
            # the result is the exemplar tiled at another offset).
            ("tghop evaluate 512x512 vs 512x512", ["evaluate", "big512x512.jpg", "res512x512.jpg", "-q"], 1),
            ("tghop evaluate 1024x1024 vs 1024x1024", ["evaluate", "big1024x1024.jpg", "res1024x1024.jpg", "-q"],
             1),
            ("tghop evaluate 2048x2048 vs 2048x2048", ["evaluate", "big2048x2048.jpg", "res2048x2048.jpg", "-q"],
             1),
        ]
        only = None if args.only is None else {int(i) for i in args.only.split(",")}
        results = []
        for i, (label, cmd, n) in enumerate(rows, start=1):
            if only is not None and i not in only:
                continue
            if args.quick and "8192x8192" in label:
                continue
            if label.startswith("tghop evaluate"):
                size = label.split()[2]
                height, width = map(int, size.split("x"))
                big_exemplar(w, f"big{size}", width, height)
                big_exemplar(w, f"res{size}", width + 37, height + 23, crop=(37, 23))
                results.append(measure(label, cmd, src, w, n, warmup=0))
                continue
            size = label.split("fit ")[-1].split(" ")[0]
            if "x" in size and size[0].isdigit():
                if args.quick and size != "3000x4000":
                    continue
                height, width = map(int, size.split("x"))  # HEIGHTxWIDTH, as --size
                big_exemplar(w, f"big{size}", width, height)
            if "at once" in label:
                results.append(measure_together(label, cmd, src, w, n))
                continue
            results.append(measure(label, cmd, src, w, n, warmup=1 if n > 1 else 0))
        sizes = {"model file, brick_wall defaults (MB)": (w / "m.npz").stat().st_size / 1e6,
                 "model file, brick_wall --paper (MB)": (w / "paper.npz").stat().st_size / 1e6}
    for k, v in sizes.items():
        print(f"{k:<58} {v:7.1f} MB", file=sys.stderr)
    table = markdown_table(
        ["command", "median (s)", "min-max (s)", "CPU (s)", "peak memory (MB)", "runs", "exit"],
        [[r["command"], r["median_s"], f"{r['min_s']:.2f}-{r['max_s']:.2f}", r["cpu_s"], r["peak_mb"], r["runs"],
          ",".join(map(str, r["exit"])) + (f" ({r['stderr']})" if "stderr" in r else "")] for r in results]
        + [[k, "", "", "", f"{v:.1f} MB file", "", ""] for k, v in sizes.items()],
    )
    note = f"Load average {load:.1f} on {os.cpu_count()} cores at the start (timings are noisy when it is high)."
    print(table + "\n\n" + note)
    name = "bench_cli" + (f"_{args.label}" if args.label else "")
    write_results(name, {"src": str(src), "load_average": load, "rows": results, "model_file_mb": sizes},
                  table + "\n\n" + note)


if __name__ == "__main__":
    main()
