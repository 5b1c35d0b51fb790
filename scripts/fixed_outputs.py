"""Write tghop's outputs for 17 fixed settings into a folder, to compare two versions.

    python scripts/fixed_outputs.py OUTDIR
    cmp OUTDIR_a/x.png OUTDIR_b/x.png     # or: diff -r OUTDIR_a OUTDIR_b

A refactor must leave every file the same, byte for byte. Everything comes from the
built-in exemplars through the ``tghop`` command (as ``python -m tghop``), so the check
needs no other images. Model files are compared by their arrays and metadata (see
``--models``), images byte for byte.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

#: name -> (command words after ``tghop``); ``{out}`` is the output folder.
RUNS = {
    "fit_bricks": "fit builtin:bricks -o {out}/bricks.npz -q",
    "fit_cells": "fit builtin:cells -o {out}/cells.npz -q",
    "fit_paper": "fit builtin:bricks -o {out}/paper.npz --paper -q",
    "s01_default": "synth {out}/bricks.npz -o {out}/s01.png --seed 1",
    "s02_512": "synth {out}/bricks.npz -o {out}/s02.png --seed 2 --size 512x384",
    "s03_tile": "synth {out}/bricks.npz -o {out}/s03.png --seed 3 --tile --size 192",
    "s04_refine0": "synth {out}/bricks.npz -o {out}/s04.png --seed 4 --refine 0",
    "s05_nomatch": "synth {out}/bricks.npz -o {out}/s05.png --seed 5 --no-match-colours",
    "s06_noguide": "synth {out}/bricks.npz -o {out}/s06.png --seed 6 --layout-weight 0",
    "s07_detail0": "synth {out}/bricks.npz -o {out}/s07.png --seed 7 --detail 0 --tolerance 0.3",
    "s08_pool": "synth {out}/bricks.npz -o {out}/s08.png --seed 8 --pool 800 --overlap 8",
    "s09_cells": "synth {out}/cells.npz -o {out}/s09.png --seed 9 --size 300x200",
    "s10_paper": "synth {out}/paper.npz -o {out}/s10.png --seed 10 --refine 0 --detail 0 --no-match-colours",
    "s11_count": "synth {out}/cells.npz -o {out}/s11.png --seed 11 --count 2 --size 128",
    "s12_fit_synth": "synth builtin:cells -o {out}/s12.png --seed 12 --layout none --refine 1",
    "s13_large": "synth {out}/bricks.npz -o {out}/s13.png --seed 13 --size 1100x700",
    "s14_tile_large": "synth {out}/bricks.npz -o {out}/s14.png --seed 14 --tile --size 640x512",
    "s15_patches": "patches {out}/bricks.npz -n 16 -o {out}/s15.png --seed 15 --stages",
    "s16_jpg": "synth {out}/cells.npz -o {out}/s16.jpg --seed 16 --layout-refine 0",
    "s17_p64": "synth builtin:bricks -o {out}/s17.png --seed 17 --patch-size 64 --layout none --max-patches 3000",
}


def main(argv):
    if len(argv) != 1:
        sys.exit(__doc__)
    out = Path(argv[0])
    out.mkdir(parents=True, exist_ok=True)
    for name, words in RUNS.items():
        cmd = [sys.executable, "-m", "tghop", *words.format(out=out).split()]
        subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
        print(name, flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
