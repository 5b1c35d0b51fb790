"""Load benchmark of ``tghop serve``: many clients generating from one model at once.

Starts a real server (``python -m tghop serve --port 0``, its own process, so its memory
is its own), fits builtin:bricks through ``POST /api/models``, then ``--clients`` threads
(one httpx client each) repeatedly ``POST /api/models/{id}/images`` at ``--size`` (a new
seed every request) for ``--seconds`` (requests still in flight then are waited for and
counted; the wall time includes them). Reports throughput, latency (p50, p99, max), errors
(with their bodies), the server's CPU time (per image, and cores busy on average) and its
resident memory, sampled every 0.5 s: the peak in the first and the last 10 s of the load
(flat means no leak).

    python benchmarks/bench_serve.py [--seconds 60] [--clients 20] [--size 256] [--fit default|fast]

Writes benchmarks/results/{--name}.{json,md} (default ``serve``).
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import markdown_table, write_results  # noqa: E402

FITS = {
    "default": {},
    "fast": {"n_clusters": "8", "n_codewords": "40", "stride": "4", "max_patches": "1500", "layout_factor": "none"},
}


def rss_bytes(pid: int) -> int:
    """Resident set size of process ``pid`` (psutil when installed, else /proc)."""
    try:
        import psutil
    except ImportError:
        with open(f"/proc/{pid}/status") as f:
            return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmRSS:"))
    return psutil.Process(pid).memory_info().rss


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` so far (its threads included)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class Sampler(threading.Thread):
    """Samples the RSS of ``pid`` every ``every`` seconds: ``samples`` as (time, bytes)."""

    def __init__(self, pid: int, every: float = 0.5):
        super().__init__(daemon=True)
        self.pid, self.every, self.samples = pid, every, []
        self.stop = threading.Event()

    def run(self):
        while not self.stop.is_set():
            try:
                self.samples.append((time.perf_counter(), rss_bytes(self.pid)))
            except Exception:  # the process has gone (psutil.NoSuchProcess, OSError)
                return
            self.stop.wait(self.every)


def start_server(cache: str):
    """``python -m tghop serve --port 0 --cache CACHE`` in a new process: (process, url)."""
    proc = subprocess.Popen([sys.executable, "-m", "tghop", "serve", "--port", "0", "--cache", cache],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    line = proc.stdout.readline()
    m = re.search(r"(http://\S+?)/? ", line)
    if not m:
        proc.kill()
        raise SystemExit(f"tghop serve did not start: {line}{proc.stdout.read()}")
    threading.Thread(target=proc.stdout.read, daemon=True).start()  # keep draining its output
    return proc, m.group(1)


def fit(client, fields: dict):
    t = time.perf_counter()
    answer = client.post("/api/models",
                         files={"builtin": (None, "bricks"), **{k: (None, v) for k, v in fields.items()}})
    answer.raise_for_status()
    job = answer.json()
    while (state := client.get(f"/api/jobs/{job['job']}").json())["state"] not in ("done", "failed", "cancelled"):
        time.sleep(0.2)
    if state["state"] != "done":
        raise SystemExit(f"the fit did not finish: {state}")
    return job["id"], time.perf_counter() - t


def client_loop(url, model_id, index, size, deadline, records, errors):
    """Generate with seeds index*10**6 + 0, 1, ... until ``deadline``: (start, latency) to ``records``."""
    import httpx

    with httpx.Client(base_url=url, timeout=600) as client:
        n = 0
        while time.perf_counter() < deadline:
            seed = index * 10**6 + n
            n += 1
            t = time.perf_counter()
            try:
                r = client.post(f"/api/models/{model_id}/images", json={"size": [size, size], "seed": seed})
                ok = r.status_code == 200 and r.content[:8] == b"\x89PNG\r\n\x1a\n"
                if not ok:
                    errors.append(f"client {index} seed {seed}: {r.status_code} {r.text[:300]}")
            except httpx.HTTPError as exc:
                ok = False
                errors.append(f"client {index} seed {seed}: {type(exc).__name__}: {exc}")
            if ok:
                records.append((t, time.perf_counter() - t))


def percentile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, max(0, round(q / 100 * len(values) + 0.5) - 1))]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60)
    parser.add_argument("--clients", type=int, default=20)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--fit", choices=sorted(FITS), default="default",
                        help="builtin:bricks with the default fit settings, or the browser tests' fast ones")
    parser.add_argument("--name", default="serve", help="results file name (benchmarks/results/NAME.{json,md})")
    args = parser.parse_args(argv)
    import httpx

    cores = len(os.sched_getaffinity(0))
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as cache:
        proc, url = start_server(cache)
        try:
            with httpx.Client(base_url=url, timeout=600) as client:
                model_id, fit_s = fit(client, FITS[args.fit])
                warm = client.post(f"/api/models/{model_id}/images", json={"size": [64, 64], "seed": 0})
                warm.raise_for_status()  # the model is in the server's memory from here
            sampler = Sampler(proc.pid)
            sampler.start()
            time.sleep(1.0)  # a few samples before the load
            records, errors = [], []
            cpu0, start = cpu_seconds(proc.pid), time.perf_counter()
            deadline = start + args.seconds
            threads = [threading.Thread(target=client_loop,
                                        args=(url, model_id, i, args.size, deadline, records, errors))
                       for i in range(args.clients)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            end = time.perf_counter()
            cpu = cpu_seconds(proc.pid) - cpu0
            time.sleep(0.6)
            sampler.stop.set()
            sampler.join()
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
    load_after = os.getloadavg()

    wall = end - start
    latencies = [lat for _, lat in records]
    window = min(10.0, args.seconds / 2)
    mib = 1024**2
    before = [b for t, b in sampler.samples if t < start]
    during = [(t - start, b) for t, b in sampler.samples if start <= t <= end]
    first = max((b for t, b in during if t < window), default=0)
    last = max((b for t, b in during if t >= wall - window), default=0)
    peak = max((b for _, b in during), default=0)
    stats = {
        "images": len(records), "errors": len(errors), "wall_s": wall, "images_per_s": len(records) / wall,
        "p50_s": percentile(latencies, 50) if latencies else None,
        "p99_s": percentile(latencies, 99) if latencies else None,
        "max_s": max(latencies, default=None), "mean_s": statistics.fmean(latencies) if latencies else None,
        "server_cpu_s": cpu, "server_cores_busy": cpu / wall,
        "server_cpu_s_per_image": cpu / len(records) if records else None,
        "rss_before_mib": max(before, default=0) / mib, "rss_peak_first_mib": first / mib,
        "rss_peak_last_mib": last / mib, "rss_peak_mib": peak / mib, "rss_window_s": window,
    }
    payload = {"clients": args.clients, "seconds": args.seconds, "size": args.size, "fit": args.fit,
               "fit_s": fit_s, "cores": cores, "load_before": load_before, "load_after": load_after,
               **stats, "error_bodies": errors,
               "rss_samples": [(round(t - start, 2), b) for t, b in sampler.samples],
               "latencies_s": latencies}
    table = markdown_table(
        ["clients", "s", f"{args.size}x{args.size} images", "images/s", "p50 s", "p99 s", "max s", "errors",
         "server CPU s/image", "server cores busy", "RSS before MiB", f"RSS peak, first {window:g} s",
         f"last {window:g} s", "peak"],
        [[args.clients, round(wall, 1), len(records), stats["images_per_s"], stats["p50_s"], stats["p99_s"],
          stats["max_s"], len(errors), stats["server_cpu_s_per_image"], stats["server_cores_busy"],
          stats["rss_before_mib"], stats["rss_peak_first_mib"], stats["rss_peak_last_mib"], stats["rss_peak_mib"]]])
    note = (f"`tghop serve` in its own process, builtin:bricks with the {args.fit} fit "
            f"({fit_s:.1f} s through the API); "
            f"each client a thread with one httpx connection, a new seed per request, the page's default generation "
            f"settings. {cores} cores shared with other sessions (clients and server on the same machine), "
            f"load average {load_before[0]:.1f} before, {load_after[0]:.1f} after: timings are noisy upper bounds.")
    print(table + "\n\n" + note)
    for body in errors:
        print("error:", body)
    write_results(args.name, payload, table + "\n\n" + note)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
