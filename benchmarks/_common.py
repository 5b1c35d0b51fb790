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
    """Peak resident memory of this process so far, in MB.

    Linux's ``VmHWM`` (this program's own peak): ``getrusage``'s ``ru_maxrss`` keeps the
    peak of the process that started this one (it survives ``fork`` + ``exec``), so a child
    of a large process would report its parent's peak, not its own.
    """
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024  # kB
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def image_sheet(columns, labels=None, *, height=256, gap=6):
    """Images side by side at one height (nearest-neighbour scaled), labels underneath.

    Parameters
    ----------
    columns : list of ndarray (H, W, C) in [0, 1]
    labels : list of str, optional

    Returns
    -------
    ndarray (h, w, 3) in [0, 1]
    """
    import numpy as np
    from PIL import Image, ImageDraw

    tiles = []
    for img in columns:
        arr = np.asarray(img, dtype=np.float64)
        if arr.ndim == 2:
            arr = arr[..., None]
        if arr.shape[2] == 1:
            arr = np.repeat(arr, 3, axis=2)
        pil = Image.fromarray(np.round(np.clip(arr, 0, 1) * 255).astype(np.uint8))
        width = max(1, round(pil.width * height / pil.height))
        tiles.append(pil.resize((width, height), Image.NEAREST))
    label_h = 16 if labels else 0
    total_w = sum(t.width for t in tiles) + gap * (len(tiles) - 1)
    sheet = Image.new("RGB", (total_w, height + label_h), "white")
    draw = ImageDraw.Draw(sheet)
    x = 0
    for i, t in enumerate(tiles):
        sheet.paste(t, (x, 0))
        if labels:
            draw.text((x + 2, height + 2), labels[i], fill="black")
        x += t.width + gap
    return np.asarray(sheet) / 255.0


def stack_rows(rows, gap=6):
    """Stack sheets vertically (padded to the widest)."""
    import numpy as np

    width = max(r.shape[1] for r in rows)
    padded = [np.pad(r, ((0, gap), (0, width - r.shape[1]), (0, 0)), constant_values=1.0) for r in rows]
    return np.concatenate(padded, axis=0)


#: File extensions of exemplar images among the shared textures (MANIFEST.tsv etc. are skipped).
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".pgm", ".ppm", ".pnm", ".bmp", ".tif", ".tiff", ".webp")


def texture_names() -> list:
    """Names (file stems) of every exemplar image in the shared textures folder, sorted."""
    if not TEXTURES.is_dir():
        return []
    return sorted(p.stem for p in TEXTURES.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)


def write_results_to(folder, name: str, payload, markdown: str | None = None):
    """:func:`write_results` into another folder: ``folder/name.json`` (and ``.md``)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.json").write_text(json.dumps(payload, indent=2, default=str))
    if markdown is not None:
        (folder / f"{name}.md").write_text(markdown + "\n")
    return folder / f"{name}.json"
