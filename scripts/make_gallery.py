"""Make the README gallery from the built-in exemplars (the only images committed).

    python scripts/make_gallery.py

    python scripts/make_gallery.py control        # only some sheets: bricks, cells, control, serve

Writes docs/gallery/{bricks,cells}.png: exemplar | 256x256 result | the same with
``--quality best`` | tileable result 2x2 |
generated 32x32 patches | Fig. 6 stage views; docs/gallery/control.png: an inpainted
image (hole outlined) | a picture grown by ``tghop extend`` | a guide map and the image it
paints from two models | a morph strip;
and docs/gallery/serve.png: a screenshot of ``tghop serve``'s page (the web extra and
headless Chromium through Playwright, as tests/test_server_browser.py drives it) after
fitting builtin:bricks and generating; the last two with a 256-colour palette to keep them small.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(1, str(ROOT / "tests"))  # chromium.py: the browser tests' launch of Chromium
from _common import image_sheet  # noqa: E402

from tghop import data, morph, synthesize_guided  # noqa: E402
from tghop.inpaint import expand_canvas, extend, inpaint  # noqa: E402
from tghop.patches import patch_grid, stage_sheet  # noqa: E402
from tghop.imageio import save_image  # noqa: E402
from tghop.settings import QUALITY  # noqa: E402
from tghop.synthesis import TGHop  # noqa: E402


def outline(image, hole, colour=(1.0, 0.85, 0.0)):
    """``image`` (H, W, 3) with the 1 px border just outside ``hole`` (H, W) drawn in ``colour``."""
    from scipy.ndimage import binary_dilation

    out = np.array(image, dtype=np.float64)
    out[binary_dilation(hole) & ~hole] = colour
    return out


def control_sheet():
    """Inpainting, guided synthesis and morph from the built-in exemplars, one row."""
    bricks, cells = TGHop(rng=0).fit(data.builtin("bricks")), TGHop(rng=0).fit(data.builtin("cells"))
    # Inpainting: another draw of the built-in bricks, an irregular hole (two overlapping discs, 27 %).
    n = 192
    image = data.builtin("bricks", n, rng=5)
    yy, xx = np.mgrid[:n, :n]
    hole = ((yy - 90) ** 2 + (xx - 80) ** 2 < 50 ** 2) | ((yy - 115) ** 2 + (xx - 125) ** 2 < 35 ** 2)
    model = TGHop(rng=0).fit(image, exclude=hole)  # what `tghop inpaint` does without --source
    filled = inpaint(model, image, hole, rng=1)
    holed = image.copy()
    holed[hole] = 0.5
    # Extend: a 128x128 picture of cells grown to 192x320 around it (its model fitted on it).
    picture = data.builtin("cells", 128, rng=5)
    grown = extend(TGHop(rng=0).fit(picture), picture, (n, 320), rng=1)
    new_area = expand_canvas(picture, (n, 320))[1]
    # Guided: bricks everywhere but a disc of cells (map: dark = first model).
    guide = np.where((yy - n // 2) ** 2 + (xx - n // 2) ** 2 < 60 ** 2, 255, 0).astype(np.uint8)
    painted = synthesize_guided([bricks, cells], guide, rng=1)
    strip = morph(bricks, cells, (n, 4 * n), rng=1)
    return image_sheet(
        [outline(holed, hole), outline(filled, hole), outline(grown, ~new_area), guide.astype(np.float64) / 255,
         painted, strip],
        ["tghop inpaint: hole", "filled (outlined)", "tghop extend (picture outlined)", "--guide map",
         "synth bricks cells --guide", "tghop morph bricks cells"],
        height=n,
    )


def save_small(sheet, path):
    """``sheet`` (H, W, 3) float in [0, 1], or a PIL image, as a PNG with a 256-colour palette
    (about a third of the RGB file)."""
    from PIL import Image

    img = sheet if isinstance(sheet, Image.Image) else Image.fromarray(
        np.round(np.clip(sheet, 0, 1) * 255).astype(np.uint8))
    img.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT,
                                dither=Image.Dither.NONE).save(path, optimize=True)


def serve_page(width=900):
    """A screenshot (PIL image, ``width`` wide) of ``tghop serve``'s whole page in a
    1200-pixel-wide window: the command started on a free port with a temporary model
    cache, builtin:bricks picked and fitted (default settings), a tileable 160x240 image
    generated, its tiled preview and 8 seeds."""
    import io
    import subprocess
    import tempfile

    from PIL import Image
    from playwright.sync_api import sync_playwright

    import chromium

    if chromium.missing():
        raise SystemExit(chromium.missing())
    with tempfile.TemporaryDirectory() as cache:
        server = subprocess.Popen([sys.executable, "-m", "tghop", "serve", "--port", "0", "--cache", cache],
                                  stdout=subprocess.PIPE, text=True)
        try:
            line = server.stdout.readline()  # "tghop serving on http://127.0.0.1:PORT/ (...)"
            if not line.startswith("tghop serving on "):
                raise SystemExit(f"tghop serve did not start: {line!r}")
            url = line.split()[3]
            with sync_playwright() as p:
                browser = chromium.launch(p)
                page = browser.new_page(viewport={"width": 1200, "height": 800})
                page.goto(url)
                page.wait_for_selector("body[data-ready='1']", timeout=30_000)
                page.select_option("#builtin", "bricks")
                page.wait_for_function("document.getElementById('fit-status').dataset.state === 'done'",
                                       timeout=300_000)
                page.wait_for_selector("#summary:not([hidden])")
                page.fill("#height", "160")
                page.fill("#width", "240")
                page.check("#tile")  # the tiled preview without seams
                page.click("#go")
                page.wait_for_selector("#tiled[data-ready='1']", timeout=60_000)
                page.click("#strip-go")
                page.wait_for_function("[...document.querySelectorAll('#strip img')].filter("
                                       "i => i.complete && i.naturalWidth).length === 8", timeout=120_000)
                png = page.screenshot(full_page=True)
                browser.close()
        finally:
            server.terminate()
            server.wait(timeout=30)
    shot = Image.open(io.BytesIO(png))
    return shot.resize((width, round(shot.height * width / shot.width)), Image.Resampling.LANCZOS)


def main():
    out = ROOT / "docs" / "gallery"
    out.mkdir(parents=True, exist_ok=True)
    names = sys.argv[1:] or ["bricks", "cells", "control", "serve"]
    unknown = sorted(set(names) - {"bricks", "cells", "control", "serve"})
    if unknown:
        raise SystemExit(f"unknown sheet {unknown[0]!r}; choose from bricks, cells, control, serve")
    if "serve" in names:
        save_small(serve_page(), out / "serve.png")
        print(out / "serve.png")
    if "control" in names:
        save_small(control_sheet(), out / "control.png")
        print(out / "control.png")
    for name in [n for n in names if n in ("bricks", "cells")]:
        exemplar = data.builtin(name)
        model = TGHop(rng=0).fit(exemplar)
        image = model.synthesize((256, 256), rng=1)
        best = model.synthesize((256, 256), rng=1, **QUALITY["best"])
        tiled = model.synthesize((192, 192), rng=2, tile=True)
        patches, views = model.sample_patches(16, rng=3, return_stages=True)
        sheet = image_sheet(
            [exemplar, image, best, np.tile(tiled, (2, 2, 1)), patch_grid(patches, n_cols=4), stage_sheet(
                {k: v[:6] for k, v in views.items()}, model.patch_size)],
            ["exemplar (built in)", "tghop synth 256x256", "--quality best", "--tile, repeated 2x2",
             "generated patches", "core | hop 1 | patch"],
            height=200,
        )
        save_image(sheet, out / f"{name}.png")
        print(out / f"{name}.png")


if __name__ == "__main__":
    main()
