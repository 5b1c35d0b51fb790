"""Server side of "the result appears within a second of the click at 512x512": a real
``tghop serve`` (uvicorn, in this process, on a free port) fits builtin:bricks (the
default fit settings, and the browser tests' fast ones), then answers ``POST
/api/models/{id}/images`` for 512x512 images with the page's default generation
settings, one request at a time. Per request: the client's wall time (HTTP on localhost
included) and the server's Server-Timing (generation and PNG encoding); and the model
file's size (what ``--cache-size`` counts).

    python benchmarks/bench_serve_click.py [--repeats 10] [--size 512]

The browser's part (click to image shown) is measured by tests/test_server_firefox.py
and tests/test_server_browser.py (run with ``-s`` to see it). Writes
benchmarks/results/serve_click.{json,md}.
"""

from __future__ import annotations

import argparse
import os
import socket
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import markdown_table, write_results  # noqa: E402

FAST_FIT = {"n_clusters": "8", "n_codewords": "40", "stride": "4", "max_patches": "1500", "layout_factor": "none"}


def start_server(cache):
    import uvicorn

    from tghop.server.app import create_app

    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(64)
    server = uvicorn.Server(uvicorn.Config(create_app(cache), log_level="warning", lifespan="on"))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.02)
    return server, thread, f"http://127.0.0.1:{sock.getsockname()[1]}"


def fit(client, fields):
    t = time.perf_counter()
    answer = client.post("/api/models",
                         files={"builtin": (None, "bricks"), **{k: (None, v) for k, v in fields.items()}})
    answer.raise_for_status()
    job = answer.json()
    while (state := client.get(f"/api/jobs/{job['job']}").json())["state"] not in ("done", "failed", "cancelled"):
        time.sleep(0.1)
    assert state["state"] == "done", state
    return job["id"], time.perf_counter() - t


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--size", type=int, default=512)
    args = parser.parse_args(argv)
    import httpx

    rows, payload = [], {"size": args.size, "repeats": args.repeats, "cores": len(os.sched_getaffinity(0)),
                         "load_before": os.getloadavg(), "models": {}}
    with tempfile.TemporaryDirectory() as cache:
        server, thread, url = start_server(cache)
        try:
            with httpx.Client(base_url=url, timeout=300) as client:
                for name, fields in (("default fit", {}), ("fast fit (browser tests)", FAST_FIT)):
                    model_id, fit_s = fit(client, fields)
                    file_mb = (Path(cache) / "models" / f"{model_id}.npz").stat().st_size / 1e6
                    client.post(f"/api/models/{model_id}/images", json={"size": [64, 64], "seed": 0})  # load it
                    wall, server_s = [], []
                    for seed in range(1, args.repeats + 1):
                        t = time.perf_counter()
                        r = client.post(f"/api/models/{model_id}/images",
                                        json={"size": [args.size, args.size], "seed": seed, "tile": False})
                        wall.append(time.perf_counter() - t)
                        r.raise_for_status()
                        server_s.append(float(r.headers["server-timing"].split("dur=")[1]) / 1000)
                    payload["models"][name] = {"fit_s": fit_s, "file_mb": file_mb, "wall_s": wall, "server_s": server_s}
                    rows.append([name, fit_s, file_mb, statistics.median(server_s), min(server_s), max(server_s),
                                 statistics.median(wall)])
        finally:
            server.should_exit = True
            thread.join(timeout=30)
    payload["load_after"] = os.getloadavg()
    table = markdown_table(["model (builtin:bricks)", "fit s", "file MB", f"server s, median of {args.repeats}",
                            "min", "max", "client s, median"], rows)
    note = (f"{args.size}x{args.size}, the page's default generation settings; {payload['cores']} cores, "
            f"load average {payload['load_before'][0]:.1f} before, {payload['load_after'][0]:.1f} after")
    print(table + "\n\n" + note)
    write_results("serve_click", payload, table + "\n\n" + note)


if __name__ == "__main__":
    main()
