"""Helpers shared by the benchmark scripts: where textures and results live, tables, timing."""

from __future__ import annotations

import json
import os
import resource
import time
from contextlib import contextmanager
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
#: Exemplars for experiments (never copied into the project): ../shared/textures beside the checkout.
TEXTURES = Path(os.environ.get("TGHOP_TEXTURES", HERE.parent.parent / "shared" / "textures"))


def texture(name: str):
    """Load ``name`` (without extension) from the shared textures, or a built-in exemplar."""
    from tghop.data import BUILTIN, builtin
    from tghop.imageio import load_image

    if name in BUILTIN:
        return builtin(name)
    matches = sorted(TEXTURES.glob(f"{name}.*"))
    if not matches:
        raise SystemExit(f"texture {name!r} not found in {TEXTURES}; set TGHOP_TEXTURES or use a built-in name")
    return load_image(matches[0])


def markdown_table(header, rows) -> str:
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.3g}" if abs(v) < 1000 else f"{v:,.0f}"
        if isinstance(v, int):
            return f"{v:,}"
        return str(v)

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def write_results(name: str, payload, markdown: str | None = None):
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{name}.json").write_text(json.dumps(payload, indent=2, default=str))
    if markdown is not None:
        (RESULTS / f"{name}.md").write_text(markdown + "\n")
    return RESULTS / f"{name}.json"


class StageTimer:
    """A progress callback that records the wall time of each stage."""

    def __init__(self):
        self.times = {}
        self._last = time.perf_counter()
        self._stage = None

    def __call__(self, stage, done, total):
        now = time.perf_counter()
        if self._stage is not None:
            self.times[self._stage] = self.times.get(self._stage, 0.0) + now - self._last
        self._stage, self._last = stage, now

    def finish(self):
        self(None, 0, 0)
        return dict(self.times)


@contextmanager
def timed(out: dict, key: str):
    t = time.perf_counter()
    yield
    out[key] = time.perf_counter() - t


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far, in MB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
