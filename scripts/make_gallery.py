"""Make the README gallery from the built-in exemplars (the only images committed).

    python scripts/make_gallery.py

Writes docs/gallery/{bricks,cells}.png: exemplar | 256x256 result | tileable result 2x2 |
generated 32x32 patches | Fig. 6 stage views.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import image_sheet  # noqa: E402

from tghop import data  # noqa: E402
from tghop.patches import patch_grid, stage_sheet  # noqa: E402
from tghop.imageio import save_image  # noqa: E402
from tghop.synthesis import TGHop  # noqa: E402


def main():
    out = ROOT / "docs" / "gallery"
    out.mkdir(parents=True, exist_ok=True)
    for name in ("bricks", "cells"):
        exemplar = data.builtin(name)
        model = TGHop(rng=0).fit(exemplar)
        image = model.synthesize((256, 256), rng=1)
        tiled = model.synthesize((192, 192), rng=2, tile=True)
        patches, views = model.sample_patches(16, rng=3, return_stages=True)
        sheet = image_sheet(
            [exemplar, image, np.tile(tiled, (2, 2, 1)), patch_grid(patches, n_cols=4), stage_sheet(
                {k: v[:6] for k, v in views.items()}, model.patch_size)],
            ["exemplar (built in)", "tghop synth 256x256", "--tile, repeated 2x2", "generated patches",
             "core DC | S1 DC | patch"],
            height=200,
        )
        save_image(sheet, out / f"{name}.png")
        print(out / f"{name}.png")


if __name__ == "__main__":
    main()
