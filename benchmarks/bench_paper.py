"""Reproduce the TGHop paper's tables and figures (Lei, Zhao, Zhang, Kuo 2021) in one command.

    python benchmarks/bench_paper.py            # everything: about 20 min on 2 idle cores (14 with
                                                # --tghop paper); more on a machine busy with other jobs
    python benchmarks/bench_paper.py --quick    # 3 textures, smaller sweeps, Table 2's Ustyuzhaninov run
                                                # not timed: 8 min on 2 cores busy with other jobs
                                                # (5 with --ust-textures ""; 12.5 at a load average
                                                # of 50-85)

Options:

  --out DIR            output folder (default benchmarks/results/paper/; with --only,
                       benchmarks/results/paper-KEYS/, e.g. paper-stages/)
  --quick              3 textures in the quality table (--textures), fewer sweep points
                       (Table 1: settings a, d; Fig. 11: N = 50, 110; Table 5: gamma 0,
                       0.01, 0.1), Ustyuzhaninov in the quality table on brick_wall only at
                       20 iterations, and Table 2's timed 256x256 Ustyuzhaninov run skipped
                       (--time-ust-iters 0; that run alone took 7 min of a loaded 2-core
                       machine at 5 iterations). Explicit options below still win.
  --textures a,b,...   exemplars of the quality table (file stems in ../shared/textures
                       or TGHOP_TEXTURES; default: all of them)
  --ust-textures a,b   exemplars on which the Ustyuzhaninov et al. baseline runs in the
                       quality table (default brick_wall,red_peppers,grass_lawn; brick_wall
                       with --quick; "" skips those runs, not Table 2's timed one)
  --ust-size S         output side of those runs (default 128)
  --ust-iters N        L-BFGS iterations of those runs (default 100, 20 with --quick)
  --time-ust-iters N   iterations of the timed 256x256 Ustyuzhaninov run of Table 2 (default
                       10; 0 skips it, the default with --quick: Table 2 then says "not timed");
                       the paper's 100 are extrapolated by loss evaluations: the measured ones,
                       and the rest at the rate of the iterations after the first two
  --workers N          processes for everything after the timing section (default 2)
  --threads N          BLAS / PyTorch threads of the timing section (default 1: on this
                       shared 2-core machine one thread was faster for both methods)
  --only a,b,...       only these sections (default: all), by their key or the paper's name:
                       time (table2, table3), params (table4), stages (fig6), settings (table1,
                       fig8), clusters (fig11), gamma (table5, fig12), fig3, fig7, quality (fig9,
                       fig10); e.g. --only fig6 reproduces Fig. 6 alone in under a minute (the
                       paper-setting brick_wall model is fitted, untimed, without "time")
  --tghop MODES        TGHop variants of the quality table (default "paper,default"):
                       "paper" = the paper's Table 4 setting (tghop.synthesis.PAPER_TABLE4)
                       and pipeline (as tghop synth --paper: none of tghop's additions;
                       until 0.37 they were all on but the colour matching and the band
                       refinement), "default" = tghop's own defaults; "paper"
                       alone saves about a third of the quality table's time

Sections (each a Markdown table in DIR/report.md, data in DIR/<section>.json, images PNG):

1. Table 2/3 -- time of one 256x256 brick_wall image: analysis, generation of the
   10,000-patch pool, quilting (Table 3: wall and CPU time, 0.60); Ustyuzhaninov et al. timed in
   the same run (measured and extrapolated to the paper's 100 iterations; not with --quick or
   --time-ust-iters 0);
   ratios next to the paper's.
2. Table 1 / Fig. 8 -- four (K1, K2) dimension settings: dims, patches, metrics.
3. Fig. 11 -- N = 50, 80, 110, 200 clusters: patches, metrics, fit time, parameters.
4. Table 5 / Fig. 12 -- gamma sweep: D_r and model size against the paper's, patches.
5. Table 4 -- parameter count by module against the paper's.
6. Fig. 6 -- stage views (core DC -> S1 DC -> S0) of generated patches.
7. Fig. 7 -- 32x32 and 64x64 (three hops) patches and stitched 256x256 images.
   Fig. 3 -- grass_lawn without and with SDR (gamma 0: every component kept, against 0.01), in the paper's order.
8. Quality -- every metric for TGHop (paper setting and tghop's defaults), quilting, crop,
   blurred crop and colour noise on every exemplar, diversity of two TGHop seeds, medians;
   Ustyuzhaninov on a subset; one image sheet per texture.

Timing of section 1 runs alone in the main process; the rest runs in ``--workers``
single-threaded processes. Seeds are fixed (fit 0, images 1 and 2, baselines 0). An
exemplar larger than 512 pixels on a side is replaced by its centre 256x256 crop.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import shlex
import sys
import time
import traceback
import warnings
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (  # noqa: E402
    RESULTS,
    StageTimer,
    image_sheet,
    markdown_table,
    peak_rss_mb,
    stack_rows,
    texture,
    texture_names,
    write_results_to,
)

# ---------------------------------------------------------------------------- paper numbers
PAPER_TABLE2 = {"Ustyuzhaninov et al. [25]": 949.64, "Gatys et al. [20]": 513.98,
                "TGHop with analysis overhead": 291.25, "TGHop w/o analysis overhead": 205.50}
PAPER_TABLE3 = {"analysis": 85.75, "generation": 197.42, "quilting": 8.08}
PAPER_TABLE4 = {"transform stage 1": 109, "transform stage 2": 801, "core SDR": 58_176, "core ICHM (i)": 50,
                "core ICHM (ii)": 2_288_862, "core ICHM (iii)": 58_754, "total": 2_406_752}
PAPER_TABLE5 = {0: (1408, 3.72), 0.0005: (1226, 3.26), 0.005: (1030, 2.74), 0.01: (909, 2.41), 0.02: (718, 1.88),
                0.03: (553, 1.43), 0.04: (399, 1.00), 0.05: (289, 0.69), 0.1: (102, 0.19)}
#: Table 1 / Fig. 8: setting -> (K1, K2); D1 = 256 K1, D2 = 64 K2 for 32x32 RGB patches.
SETTINGS = {"a": (10, 32), "b": (6, 12), "c": (5, 8), "d": (3, 3)}
CLUSTERS = (50, 80, 110, 200)
#: The sections (``--only``), in the report's order, and the paper's names for each.
SECTION_NAMES = {"time": ("table2", "table3"), "settings": ("table1", "fig8"), "clusters": ("fig11",),
                 "gamma": ("table5", "fig12"), "params": ("table4",), "stages": ("fig6",), "fig3": (), "fig7": (),
                 "quality": ("fig9", "fig10")}

BASELINE_KEYS = {"quilting": "quilting", "crop": "crop", "blurred crop": "blurred-crop", "colour noise": "colour-noise"}
METRIC_NAMES = ["sifid", "gram", "swd", "cooccurrence", "novelty"]
#: Channels for greyscale exemplars: hop 1 has only 4 channels on 1 input channel, so the
#: paper's K1 = 9 cannot be; keep all 4 and K2 = 10 (about the paper's K2 / K1).
GREY_CHANNELS = (4, 10)
EXEMPLAR_MAX = 512   # larger exemplars are replaced by their centre crop
CENTRE_CROP = 256
OUT_SIZE = (256, 256)
BRICK = "brick_wall"
GRASS = "grass_lawn"  # the paper's Fig. 3

_T0 = time.perf_counter()


def log(msg: str) -> None:
    print(f"[{time.perf_counter() - _T0:7.1f} s] {msg}", file=sys.stderr, flush=True)


def u8(img) -> np.ndarray:
    return np.round(np.clip(np.asarray(img, dtype=np.float64), 0, 1) * 255).astype(np.uint8)


def f64(img) -> np.ndarray:
    return np.asarray(img, dtype=np.float64) / 255.0


def save_png(img, path: Path) -> str:
    from tghop.imageio import save_image

    path.parent.mkdir(parents=True, exist_ok=True)
    save_image(np.clip(img, 0, 1), path)
    return str(path)


def prepare(name: str):
    """Exemplar ``name`` and a note; exemplars over EXEMPLAR_MAX px become a centre crop."""
    try:
        img = texture(name)
    except SystemExit as exc:  # _common.texture exits on a missing name
        raise ValueError(str(exc)) from None
    h, w = img.shape[:2]
    if max(h, w) > EXEMPLAR_MAX:
        y, x = (h - CENTRE_CROP) // 2, (w - CENTRE_CROP) // 2
        return img[y:y + CENTRE_CROP, x:x + CENTRE_CROP].copy(), f"centre {CENTRE_CROP}^2 of {h}x{w}"
    return img, f"{h}x{w}"


def scores(exemplar, result) -> dict:
    from tghop.metrics import evaluate

    return dict(evaluate(exemplar, result))


def setting(mode="paper") -> dict:
    """TGHop parameters: the paper's Table 4 setting (``tghop.synthesis.PAPER_TABLE4``) or tghop's defaults."""
    from tghop.synthesis import PAPER_TABLE4 as SETTING

    return dict(SETTING) if mode == "paper" else {}


def fit(img, mode="paper", **kw):
    from tghop import TGHop

    params = {**setting(mode), **kw}
    t = time.perf_counter()
    model = TGHop(**params, rng=0).fit(img)
    return model, time.perf_counter() - t


def synth(model, size, rng, mode="paper", **kw):
    """``model.synthesize``; in paper mode with the paper's generation settings (``tghop.settings``: no
    colour matching, refinement, patch refinement, seam removal, ... -- none of them in the paper), as
    ``tghop synth --paper`` and ``bench_quality.py``'s "paper" variant."""
    import inspect

    if mode == "paper":
        from tghop.settings import generate_settings

        params = inspect.signature(model.synthesize).parameters
        paper = {s.name: s.paper for s in generate_settings() if s.has_paper and s.name in params}
        kw = {**paper, **kw}
    return model.synthesize(size, rng=rng, **kw)


def grid(model, n=25, seed=3, n_cols=5):
    from tghop.patches import patch_grid

    return patch_grid(model.sample_patches(n, rng=seed), n_cols=n_cols)


def _init_worker(t0):
    global _T0
    _T0 = t0
    warnings.filterwarnings("ignore")
    from threadpoolctl import threadpool_limits

    global _LIMITS
    _LIMITS = threadpool_limits(1)  # keep the object: the limit lasts while it lives
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass


def _call(fn, *args):
    """Run task ``fn`` in a worker; on failure return the error instead of raising."""
    try:
        return fn(*args)
    except Exception as exc:  # noqa: BLE001 -- report and go on
        return {"error": f"{exc.__class__.__name__}: {exc}", "traceback": traceback.format_exc()}


# ---------------------------------------------------------------------------- worker tasks
def _task_settings(keys, out):
    img = texture(BRICK)
    rows, grids, images = [], [], []
    for key in keys:
        k1, k2 = SETTINGS[key]
        model, fit_s = fit(img, n_channels=(k1, k2))
        synth_img = synth(model, OUT_SIZE, 1)
        rows.append({"setting": key, "K1": k1, "K2": k2, "dims": model.dims_, "fit_s": fit_s,
                     "K2_kept": int((model.sdr_.kept_per_channel_ > 0).sum()),  # hop-2 channels SDR keeps any of
                     "scores": scores(img, synth_img)})
        grids.append(grid(model))
        images.append(synth_img)
        log(f"Table 1 setting ({key}) K1={k1} K2={k2}: fit {fit_s:.1f} s")
    labels = [f"({r['setting']}) {r['dims']['D0']}->{r['dims']['D1']}->{r['dims']['D2']}" for r in rows]
    sheet = stack_rows([image_sheet(grids, labels, height=336), image_sheet(images, [f"({k}) 256x256" for k in keys])])
    return {"rows": rows, "sheet": save_png(sheet, out / "fig8_settings.png")}


def _task_clusters(ns, out):
    from tghop.parameter_count import PAPER_MODULES

    img = texture(BRICK)
    rows, grids, images = [], [], []
    for n in ns:
        model, fit_s = fit(img, n_clusters=n)
        synth_img = synth(model, OUT_SIZE, 1)
        p = model.n_parameters()[PAPER_MODULES]  # stored: our additions left out
        rows.append({"N": n, "fit_s": fit_s, "dims": model.dims_, "params_paper": p["paper"],
                     "params_stored": p["stored"], "scores": scores(img, synth_img)})
        grids.append(grid(model))
        images.append(synth_img)
        log(f"Fig. 11 N={n}: fit {fit_s:.1f} s")
    sheet = stack_rows([image_sheet(grids, [f"N={n}" for n in ns], height=336),
                        image_sheet(images, [f"N={n} 256x256" for n in ns])])
    return {"rows": rows, "sheet": save_png(sheet, out / "fig11_clusters.png")}


def _task_gamma(gammas, out):
    from tghop.parameter_count import PAPER_MODULES

    img = texture(BRICK)
    rows, grids = [], []
    for g in gammas:
        model, fit_s = fit(img, gamma=g)
        p = model.n_parameters()[PAPER_MODULES]  # stored: our additions left out
        rows.append({"gamma": g, "dims": model.dims_, "fit_s": fit_s, "params_paper": p["paper"],
                     "params_stored": p["stored"]})
        grids.append(grid(model, n=16, n_cols=4))
        log(f"Table 5 gamma={g}: D_r {model.dims_['D_r']}, fit {fit_s:.1f} s")
    labels = [f"g={g} D_r={r['dims']['D_r']}" for g, r in zip(gammas, rows)]
    half = (len(grids) + 1) // 2  # two rows
    sheet = stack_rows([image_sheet(grids[i:i + half], labels[i:i + half], height=268)
                        for i in range(0, len(grids), half)])
    return {"rows": rows, "sheet": save_png(sheet, out / "fig12_gamma.png")}


#: Fig. 7's channels: the "typical setting" of the paper's section IV.B (K1=10, K2=27: a core of 8 x 8 x 27 =
#: 1,728) for 32x32 patches, and a third hop of 63 for 64x64 ones (8 x 8 x 63 = 4,032, the paper's figure).
FIG7_CHANNELS = {32: (10, 27), 64: (10, 27, 63)}
FIG7_PAPER_CORE = {32: 1728, 64: 4032}
#: L-BFGS iterations whose line searches take several evaluations (Table 2's extrapolation).
EARLY_ITERS = 2


#: Fig. 3's panels in the paper's order: (a) without SDR, (b) with SDR; each a label and its fit settings.
FIG3_PANELS = (("(a) without SDR (gamma 0: every component)", {"gamma": 0.0}),
               ("(b) with SDR (the paper's gamma 0.01)", {}))


def _task_fig3(out):
    img = texture(GRASS)
    rows, images = [], []
    for label, kw in FIG3_PANELS:
        model, fit_s = fit(img, **kw)
        images.append(synth(model, OUT_SIZE, 1))
        rows.append({"label": label, "dims": model.dims_, "fit_s": fit_s, "scores": scores(img, images[-1])})
    sheet = image_sheet([img] + images, ["exemplar"] + [label.split(" (")[0] for label, _ in FIG3_PANELS])
    return {"rows": rows, "sheet": save_png(sheet, out / "fig3_sdr.png")}


def md_fig3(res) -> str:
    rows = [[r["label"], r["dims"]["D2"], r["dims"]["D_r"], r["fit_s"]] + fmt_scores(r["scores"]) for r in res["rows"]]
    text = (f"## Fig. 3: {GRASS} without and with SDR (the paper's setting and pipeline)\n\n"
            "The paper (section IV.C): \"The quality with SDR significantly improves\" (its Fig. 9 finds little "
            "degradation with SDR on other textures). Metrics of the seed-1 image.\n\n")
    text += markdown_table(["", "D2", "D_r", "fit (s)"] + METRIC_NAMES, rows)
    return text + f"\n\nSheet: `{Path(res['sheet']).name}`"


def _task_fig7(out):
    from tghop.patches import patch_grid

    img = texture(BRICK)
    rows, sheet_rows = [], []
    for p, channels in FIG7_CHANNELS.items():  # the paper's "core subspace dimensions" 1,728 and 4,032
        model, fit_s = fit(img, patch_size=p, n_channels=channels)
        patches = model.sample_patches(16, rng=3)
        stitched = [synth(model, OUT_SIZE, s, n_patches=5000) for s in (1, 2)]  # paper: 5,000 patches
        rows.append({"patch_size": p, "channels": model.channels_, "dims": model.dims_, "fit_s": fit_s,
                     "scores": scores(img, stitched[0])})
        sheet_rows.append(image_sheet([img, patch_grid(patches, n_cols=4)] + stitched,
                                      ["exemplar", f"{p}x{p} patches", f"stitched ({p}), seed 1",
                                       f"stitched ({p}), seed 2"]))
        log(f"Fig. 7 patch {p}: fit {fit_s:.1f} s")
    return {"rows": rows, "sheet": save_png(stack_rows(sheet_rows), out / "fig7_patch_sizes.png")}


def fit_any(img, mode):
    """:func:`fit`, with :data:`GREY_CHANNELS` where the setting's K1 = 9 cannot be.

    A greyscale exemplar has 4 hop-1 channels; so does a grey image stored as RGB (the other
    8 directions are empty and tghop drops them, but then K2 = 22 > 4 * 4 fails). Returns
    ``(model, fit seconds, note)``; the note says when and why the channels were changed.
    """
    from tghop._errors import TGHopError

    if img.shape[2] == 1:
        return (*fit(img, mode, n_channels=GREY_CHANNELS), f"greyscale: K1, K2 = {GREY_CHANNELS}")
    try:
        return (*fit(img, mode), "")
    except TGHopError as exc:
        if "channels" not in str(exc):
            raise
        return (*fit(img, mode, n_channels=GREY_CHANNELS), f"near-grey RGB (hop 1 has 4 non-empty channels): "
                f"K1, K2 = {GREY_CHANNELS}")


def tghop_label(mode: str) -> str:
    return f"TGHop ({mode})"


def _task_quality(name, modes):
    from tghop import baselines as B
    from tghop.metrics import diversity

    t = time.perf_counter()
    img, note = prepare(name)
    results, divs, fit_s, notes = {}, {}, {}, set()
    for mode in modes:
        model, fit_s[mode], why = fit_any(img, mode)
        if why:
            notes.add(why)
        a = synth(model, OUT_SIZE, 1, mode)
        b = synth(model, OUT_SIZE, 2, mode)
        results[tghop_label(mode)] = a
        divs[tghop_label(mode)] = diversity(a, b)
    side = (min(OUT_SIZE[0], img.shape[0]), min(OUT_SIZE[1], img.shape[1]))  # crops cannot exceed the exemplar
    for label, key in BASELINE_KEYS.items():
        size = side if key in ("crop", "blurred-crop") else OUT_SIZE
        results[label] = B.BASELINES[key](img, size, rng=0)
    entry = {"texture": name, "exemplar": note, "channels": img.shape[2], "fit_s": fit_s,
             "channel_note": "; ".join(notes),
             "scores": {k: scores(img, v) for k, v in results.items()}, "diversity": divs,
             "images": {"exemplar": u8(img), **{k: u8(v) for k, v in results.items()}},
             "crop_size": f"{side[0]}x{side[1]}", "seconds": time.perf_counter() - t}
    log(f"quality {name}: done in {entry['seconds']:.0f} s")
    return entry


def _task_ust(name, size, n_iter):
    from tghop.baselines import ustyuzhaninov

    img, note = prepare(name)
    tg = {m: synth(fit_any(img, m)[0], (size, size), 1, m) for m in ("paper", "default")}
    marks = []
    t = time.perf_counter()
    ust, info = ustyuzhaninov(img, size, n_iter=n_iter, rng=0, return_info=True,
                              progress=lambda s, d, n: marks.append(time.perf_counter()))
    total = time.perf_counter() - t
    loop = marks[-1] - marks[0] if len(marks) > 1 else total
    entry = {"texture": name, "exemplar": note, "size": size, "iterations_asked": n_iter, "info": info,
             "seconds": total, "s_per_iter": loop / max(info["n_iter"], 1), "scores_ust": scores(img, ust),
             "scores_tghop": {m: scores(img, v) for m, v in tg.items()}, "image": u8(ust)}
    log(f"Ustyuzhaninov {name} {size}x{size}: {info['n_iter']} iterations in {total:.0f} s")
    return entry


# ---------------------------------------------------------------------------- formatting
def fmt_scores(s: dict) -> list:
    return [s.get(m, "-") for m in METRIC_NAMES]


def md_settings(res) -> str:
    rows = [[f"({r['setting']})", r["K1"], r["K2"], r.get("K2_kept", "-"),
             f"{r['dims']['D0']}->{r['dims']['D1']}->{r['dims']['D2']}", r["dims"]["D_r"], r["dims"]["F"], r["fit_s"]]
            + fmt_scores(r["scores"]) for r in res["rows"]]
    text = ("## Table 1 / Fig. 8: four dimension settings (brick_wall, gamma=0.01, N=50, W=200)\n\n"
            "Paper: (a) 3072->2560->2048, (b) 3072->1536->768, (c) 3072->1280->512, (d) 3072->768->192; "
            "quality drops from (a) to (d). Metrics of one 256x256 image per setting (lower is better, "
            "novelty: higher is more novel). \"K2 kept\": the hop-2 channels of which SDR keeps any component; a "
            "channel whose every spatial component's variance is below gamma adds nothing to the core model, so "
            "settings that differ only in such channels make the same model and images (with gamma 0.01, (a)'s "
            "K2 = 32 and Fig. 7's K2 = 27 on brick_wall).\n\n")
    text += markdown_table(["setting", "K1", "K2", "K2 kept", "D0->D1->D2", "D_r", "F", "fit (s)"] + METRIC_NAMES,
                           rows)
    return text + f"\n\nSheet (patches, then 256x256 images): `{Path(res['sheet']).name}`"


def md_clusters(res) -> str:
    rows = [[r["N"], r["dims"]["F"], r["fit_s"], r["params_paper"], r["params_stored"]] + fmt_scores(r["scores"])
            for r in res["rows"]]
    text = ("## Fig. 11: number of clusters N (brick_wall, K1=9, K2=22, gamma=0.01)\n\n"
            "Paper: N=50 over-saturates, N=80 less so, ~100-110 good, little change to 200.\n\n")
    text += markdown_table(["N", "F", "fit (s)", "parameters (paper formula)",
                            "parameters (stored, the paper's modules)"] + METRIC_NAMES, rows)
    return text + f"\n\nSheet: `{Path(res['sheet']).name}`"


def md_gamma(res) -> str:
    rows = []
    for r in res["rows"]:
        paper_dr, paper_m = PAPER_TABLE5.get(r["gamma"], ("-", "-"))
        rows.append([r["gamma"], r["dims"]["D_r"], paper_dr, r["dims"]["N"], r["dims"]["F"],
                     round(r["params_paper"] / 1e6, 2), round(r["params_stored"] / 1e6, 2), paper_m, r["fit_s"]])
    text = ("## Table 5 / Fig. 12: SDR threshold gamma (brick_wall, K1=9, K2=22, N=50)\n\n")
    text += markdown_table(["gamma", "D_r", "D_r paper", "N", "F", "size, paper formula (M)",
                            "size, stored (M; the paper's modules)", "size paper (M)", "fit (s)"], rows)
    text += ("\n\nThe paper says N also shrinks with gamma but gives no N per row; we keep N=50, so at large gamma "
             "our F (and size) stays higher than the paper's. Sheet: `" + Path(res["sheet"]).name + "`")
    return text


def md_fig7(res) -> str:
    rows = [[r["patch_size"], ",".join(map(str, r["channels"])),
             "->".join(str(r["dims"][f"D{i}"]) for i in range(len(r["channels"]) + 1)),
             FIG7_PAPER_CORE.get(r["patch_size"], ""), r["dims"]["D_r"], r["fit_s"]] + fmt_scores(r["scores"])
            for r in res["rows"]]
    text = ("## Fig. 7: 32x32 (two hops) vs 64x64 (three hops) patches on brick_wall\n\n"
            "The paper's channels: K1=10, K2=27 (its section IV.B) and K3=63, so that the cores are its 1,728 and "
            "4,032 dimensions. Stitched from a 5,000-patch pool as in the paper; metrics of the seed-1 image.\n\n")
    text += markdown_table(["patch", "K per hop", "dims", "paper's core", "D_r", "fit (s)"] + METRIC_NAMES, rows)
    return text + f"\n\nSheet: `{Path(res['sheet']).name}`"


def md_error(title, res) -> str:
    return f"## {title}\n\nFAILED: {res['error']}\n"


# ---------------------------------------------------------------------------- section 1, 5, 6
def section_time(args, out):
    """Table 2/3 in this process; returns (markdown, payload, model)."""
    import torch
    from threadpoolctl import threadpool_limits

    from tghop import TGHop
    from tghop.baselines import ustyuzhaninov
    from tghop.quilting import quilt

    torch.set_num_threads(args.threads)
    img = texture(BRICK)
    with threadpool_limits(args.threads):
        timer = StageTimer()
        t, c = time.perf_counter(), time.process_time()
        model = TGHop(**setting("paper"), rng=0).fit(img, progress=timer)
        fit_s, fit_cpu = time.perf_counter() - t, time.process_time() - c
        stages = timer.finish()
        log(f"Table 3: analysis {fit_s:.1f} s")
        gens, quilts, gens_cpu, quilts_cpu = [], [], [], []
        for seed in range(4):  # the first image pays for the float32 mixing matrix and the inverse-CDF table
            rng = np.random.default_rng(seed)
            t, c = time.perf_counter(), time.process_time()
            pool = model.sample_patches(10_000, rng=rng, dtype=np.float32)
            t1, c1 = time.perf_counter(), time.process_time()
            quilt(pool, OUT_SIZE, rng=rng)
            gens.append(t1 - t)
            quilts.append(time.perf_counter() - t1)
            gens_cpu.append(c1 - c)
            quilts_cpu.append(time.process_time() - c1)
        log(f"Table 3: generation {gens[0]:.2f} s (first) / {np.median(gens[1:]):.2f} s, "
            f"quilting {np.median(quilts):.2f} s")
        ust = None
        if args.time_ust_iters > 0:
            marks = []  # (time, iterations begun) at each loss evaluation (and at the start and chunk ends)
            t = time.perf_counter()
            _, info = ustyuzhaninov(img, OUT_SIZE, n_iter=args.time_ust_iters, rng=0, return_info=True,
                                    progress=lambda s, d, n: marks.append((time.perf_counter(), d)))
            total = time.perf_counter() - t
            setup = marks[0][0] - t
            per_eval = (marks[-1][0] - marks[0][0]) / max(info["n_evals"], 1)
            # The line search takes several evaluations in L-BFGS's first iterations and about one later:
            # the 100 iterations' evaluations are the measured ones plus the rest at the later rate.
            early = sum(1 for _, d in marks if d <= EARLY_ITERS) - 1  # less the start's report (no evaluation)
            later = (info["n_evals"] - early) / max(info["n_iter"] - EARLY_ITERS, 1)
            if info["n_iter"] <= EARLY_ITERS:
                later = info["n_evals"] / max(info["n_iter"], 1)  # no later iteration measured: an upper bound
            evals_100 = info["n_evals"] + later * max(100 - info["n_iter"], 0)
            ust = {"iterations": info["n_iter"], "evaluations": info["n_evals"], "measured_s": total, "setup_s": setup,
                   "s_per_eval": per_eval, "later_evals_per_iter": later, "evaluations_100": evals_100,
                   "extrapolated_100_s": setup + per_eval * evals_100, "loss": info["loss"]}
            log(f"Table 2: Ustyuzhaninov 256x256 {info['n_iter']} iterations in {total:.0f} s")
    gen_first, gen_warm, q = gens[0], float(np.median(gens[1:])), float(np.median(quilts))
    with_a, without = fit_s + gen_first + q, gen_warm + q
    payload = {"threads": args.threads, "fit_s": fit_s, "fit_stages_s": stages, "generation_s": gens,
               "quilting_s": quilts, "fit_cpu_s": fit_cpu, "generation_cpu_s": gens_cpu, "quilting_cpu_s": quilts_cpu,
               "tghop_with_analysis_s": with_a, "tghop_without_analysis_s": without,
               "ustyuzhaninov": ust, "peak_rss_mb": peak_rss_mb()}

    rows2 = table2_rows(args, ust, with_a, without)
    text = (f"## Table 2: time of one 256x256 brick_wall image (this machine, {args.threads} thread(s); "
            "paper: the 12 CPUs (6 cores, 12 threads) of an i7-5930K + a GTX Titan X GPU for the DL methods)\n\n")
    text += markdown_table(["method", "time here (s)", "factor here", "paper (s)", "factor paper"], rows2)
    if ust:
        text += (f"\n\nUstyuzhaninov measured: {ust['iterations']} L-BFGS iterations ({ust['evaluations']} loss "
                 f"evaluations) at 256x256 in {ust['measured_s']:.1f} s = setup {ust['setup_s']:.1f} s + "
                 f"{ust['s_per_eval']:.2f} s per evaluation (CPU, PyTorch); the 100-iteration row counts "
                 f"{ust['evaluations_100']:.0f} evaluations: the measured ones and "
                 f"{ust['later_evals_per_iter']:.2f} per later iteration (as measured after the first "
                 f"{EARLY_ITERS}, whose line searches take more; with no later one measured, the first ones' rate, "
                 f"an upper bound). The paper ran it on a GPU. Ratio Ustyuzhaninov (100 it.) / TGHop: "
                 f"{ust['extrapolated_100_s'] / without:.0f}x without analysis, "
                 f"{ust['extrapolated_100_s'] / with_a:.1f}x with analysis (paper: 4.62x and 3.26x).")
    text += "\n\n## Table 3: the three processes of TGHop\n\n"
    text += markdown_table(["process", "time here (s)", "CPU here (s)", "paper (s)"],
                           table3_rows((fit_s, fit_cpu), (gens, gens_cpu), (quilts, quilts_cpu)))
    text += ("\n\nTimes are wall-clock; \"CPU here\" is this process's CPU time over the same span, the steadier "
             "figure on a machine busy with other jobs (a wall time many times its CPU time waited for a core).")
    text += "\n\nFit stages (s): " + ", ".join(f"{k} {v:.2f}" for k, v in stages.items())
    return text, payload, model


def table3_rows(fit, gens, quilts) -> list:
    """Table 3's rows: each process's wall time, CPU time and the paper's; ``fit`` is (wall, CPU) seconds,
    ``gens`` and ``quilts`` (wall list, CPU list) over the images (0.59's table gave the wall times alone)."""
    (gen_wall, gen_cpu), (q_wall, q_cpu) = gens, quilts
    return [
        ["analysis (fit, forward path)", fit[0], fit[1], PAPER_TABLE3["analysis"]],
        ["generation of 10,000 patches, first image (includes the float32 mixing matrix and inverse-CDF table, "
         "made once)", gen_wall[0], gen_cpu[0], PAPER_TABLE3["generation"]],
        [f"generation of 10,000 patches, later images (median of {len(gen_wall) - 1})", float(np.median(gen_wall[1:])),
         float(np.median(gen_cpu[1:])), PAPER_TABLE3["generation"]],
        [f"quilting 256x256 (median of {len(q_wall)})", float(np.median(q_wall)), float(np.median(q_cpu)),
         PAPER_TABLE3["quilting"]]]


def table2_rows(args, ust, with_a, without) -> list:
    """Table 2's rows: Ustyuzhaninov et al. (timed, or why not), Gatys et al., TGHop with and without analysis."""
    rows = []
    if not ust:
        rows.append([f"Ustyuzhaninov et al. [25]: not timed (skipped by {args.time_ust_skipped}; "
                     "--time-ust-iters N times N iterations)", "-", "-",
                     PAPER_TABLE2["Ustyuzhaninov et al. [25]"], "4.62x"])
    else:
        rows.append([f"Ustyuzhaninov et al. [25], {ust['iterations']} iterations (measured)", ust["measured_s"],
                     f"{ust['measured_s'] / without:.0f}x", "-", "-"])
        rows.append(["Ustyuzhaninov et al. [25], 100 iterations (extrapolated by loss evaluations)",
                     ust["extrapolated_100_s"], f"{ust['extrapolated_100_s'] / without:.0f}x",
                     PAPER_TABLE2["Ustyuzhaninov et al. [25]"], "4.62x"])
    rows.append(["Gatys et al. [20]", "not run", "-", PAPER_TABLE2["Gatys et al. [20]"], "2.50x"])
    rows.append(["TGHop with analysis overhead (fit + first image)", with_a, f"{with_a / without:.0f}x",
                 PAPER_TABLE2["TGHop with analysis overhead"], "1.42x"])
    rows.append(["TGHop w/o analysis overhead (pool + quilting)", without, "1x",
                 PAPER_TABLE2["TGHop w/o analysis overhead"], "1x"])
    return rows


def section_params(model):
    params = model.n_parameters()
    d = model.dims_
    rows = [[k, v["formula"], PAPER_TABLE4.get(k, "-"), v["paper"], v["stored"]] for k, v in params.items()]
    text = ("## Table 4: parameters (brick_wall, K1=9, K2=22, gamma=0.01, N=50, W=200)\n\n"
            f"Our dimensions: D_r={d['D_r']} (paper 909), F={d['F']} (paper 2,518), N={d['N']}, W={d['W']}.\n\n")
    text += markdown_table(["module", "formula", "paper", "paper formula on our dims", "stored by tghop"], rows)
    text += ("\n\nThe paper-formula column differs from the paper's numbers only through our D_r and F. "
             "What tghop stores differs from the paper's formulas in three rows (docs/choices.md, 'Parameter count'): "
             "stage 2 stores 4*K2 + K1 numbers (each kept channel of a channel-wise hop is one 4-tap kernel; the "
             "paper writes 4*K1*K2 + K1), SDR also stores each channel's 8x8 mean map (64*K2 more), and ICHM (ii) "
             "also stores each cluster's mean (N*D_r more). Note the paper's own SDR entry (58,176 = 64*909) and "
             "ICHM (ii) entry (2,288,862 = 909*2,518) follow its formulas. The rows marked (ours) are our additions, "
             "stored even in a model fitted with --paper (whose generation does not use them): compare the paper's "
             "total with the row 'the paper's modules', not with 'total'.")
    return text, {"dims": d, "parameters": params}


def section_stages(model, out):
    from tghop.patches import stage_sheet

    _, views = model.sample_patches(8, rng=5, return_stages=True)
    halves = [{k: v[i:i + 4] for k, v in views.items()} for i in (0, 4)]
    grids = [stage_sheet(h, model.patch_size) for h in halves]
    sheet = image_sheet(grids, ["core DC | S1 DC | S0", "core DC | S1 DC | S0"], height=3 * grids[0].shape[0])
    path = save_png(sheet, out / "fig6_stages.png")
    text = ("## Fig. 6: stage views of 8 generated brick_wall patches\n\n"
            f"Each row: the DC map in the core (8x8, grey), the DC map of S1 (16x16), the patch in S0 (32x32). "
            f"Sheet: `{Path(path).name}`")
    return text, {"sheet": path, "views": list(views)}


# ---------------------------------------------------------------------------- section 8
def md_quality(entries, failed, ust_entries, modes) -> tuple[str, dict]:
    ok = sorted(entries, key=lambda e: e["texture"])
    tg = [tghop_label(m) for m in modes]
    methods = tg + list(BASELINE_KEYS)
    which = "; ".join(
        f"{tghop_label(m)} = the paper's Table 4 setting (" + ", ".join(f"{k}={v}" for k, v in setting("paper").items())
        + "), the paper's generation (as tghop synth --paper: none of tghop's additions)" if m == "paper"
        else f"{tghop_label(m)} = tghop's defaults" for m in modes)
    parts = [f"## Quality: {len(ok)} exemplars, 256x256 results\n", f"{which}.\n",
             "Lower is better for sifid, gram, swd, cooccurrence; novelty (RMS distance of 8x8 patches to the nearest "
             "exemplar patch) and diversity (the same between two TGHop seeds) are higher for more new content. "
             "Crop and blurred crop (sigma=1) are reference points (a crop is the best a metric can see), colour "
             "noise the worst case; quilting copies exemplar patches (novelty ~0).\n"]
    cropped = [f"{e['texture']} ({e['exemplar']})" for e in ok if e["exemplar"].startswith("centre")]
    small = [f"{e['texture']} ({e['crop_size']})" for e in ok if e["crop_size"] != f"{OUT_SIZE[0]}x{OUT_SIZE[1]}"]
    changed = [f"{e['texture']} ({e['channel_note']})" for e in ok if e.get("channel_note")]
    if cropped:
        parts.append(f"Exemplars larger than {EXEMPLAR_MAX} px on a side replaced by their centre "
                     f"{CENTRE_CROP}x{CENTRE_CROP} crop (everything else used whole): {', '.join(cropped)}.\n")
    if small:
        parts.append(f"Exemplars smaller than 256 px: crop / blurred crop at the exemplar's size: "
                     f"{', '.join(small)}.\n")
    if changed:
        parts.append(f"K1 = 9 is impossible with 4 hop-1 channels, so these use K1, K2 = {GREY_CHANNELS}: "
                     f"{', '.join(changed)}.\n")
    if failed:
        parts.append("Skipped (failed): " + "; ".join(f"{n}: {e}" for n, e in failed) + "\n")
    medians = {}
    for metric in METRIC_NAMES:
        extra = [f"{t} diversity" for t in tg] if metric == "novelty" else []
        cols = {m: [] for m in methods + extra}
        rows = []
        for e in ok:
            vals = [e["scores"][m].get(metric, float("nan")) for m in methods]
            vals += [e["diversity"][t] for t in tg] if extra else []
            for m, v in zip(methods + extra, vals):
                cols[m].append(v)
            rows.append([e["texture"]] + vals)
        med = {m: float(np.nanmedian(v)) if v else float("nan") for m, v in cols.items()}
        medians[metric] = med
        rows.append(["**median**"] + [med[m] for m in methods + extra])
        parts.append(f"### {metric}\n\n" + markdown_table(["texture"] + methods + extra, rows) + "\n")

    # Scale-free summaries.
    summary = []
    for t in tg:
        for metric in METRIC_NAMES[:4]:
            sc = [e["scores"] for e in ok if metric in e["scores"][t]]
            pos = [(s[t][metric] - s["crop"][metric]) / (s["colour noise"][metric] - s["crop"][metric])
                   for s in sc if s["colour noise"][metric] != s["crop"][metric]]
            ratios = [[s[t][metric] / s[ref][metric] for s in sc if s[ref][metric] > 0]
                      for ref in ("quilting", "blurred crop", "colour noise")]
            wins = [s[t][metric] < s["blurred crop"][metric] for s in sc]
            summary.append([t, metric] + [float(np.median(v)) if v else "-" for v in [pos] + ratios]
                           + [f"{sum(wins)}/{len(wins)}"])
    parts.append("### TGHop vs references (medians over exemplars)\n\n" + markdown_table(
        ["method", "metric", "position between crop (0) and colour noise (1)", "TGHop / quilting",
         "TGHop / blurred crop", "TGHop / colour noise", "TGHop better than blurred crop"], summary) + "\n")

    ust_payload = []
    if ust_entries:
        rows = []
        ratio = {}
        for u in sorted(ust_entries, key=lambda u: u.get("texture", "")):
            if "error" in u:
                rows.append([u.get("texture", "?"), "Ustyuzhaninov: FAILED " + u["error"]] + ["-"] * 6)
                continue
            rows.append([u["texture"], f"Ustyuzhaninov, {u['size']}x{u['size']}, {u['info']['n_iter']} iterations",
                         u["seconds"]] + fmt_scores(u["scores_ust"]))
            for mode, sc in u["scores_tghop"].items():
                rows.append([u["texture"], f"{tghop_label(mode)}, {u['size']}x{u['size']}", "-"] + fmt_scores(sc))
                for m in METRIC_NAMES[:4]:
                    if m in sc and u["scores_ust"].get(m, 0) > 0:
                        ratio.setdefault(mode, {}).setdefault(m, []).append(sc[m] / u["scores_ust"][m])
        parts.append("### Ustyuzhaninov et al. [25] on a subset (CPU, PyTorch L-BFGS, 1,024 random filters at 8 "
                     "scales; TGHop images synthesised at the same size, both TGHop settings)\n\n"
                     + markdown_table(["texture", "method", "time (s)"] + METRIC_NAMES, rows) + "\n")
        for mode, r in ratio.items():
            line = ", ".join(f"{m} {np.median(v):.2f}" for m, v in r.items())
            parts.append(f"**{tghop_label(mode)} / Ustyuzhaninov, median ratio over the subset** "
                         f"(below 1: TGHop better): {line}.\n")
        ust_payload = [{k: v for k, v in u.items() if k != "image"} for u in ust_entries]
    payload = {"entries": [{k: v for k, v in e.items() if k != "images"} for e in ok], "failed": failed,
               "medians": medians, "summary": summary, "ustyuzhaninov": ust_payload}
    return "\n".join(parts), payload


def quality_sheets(entries, ust_entries, modes, out):
    ust_by = {u["texture"]: u for u in ust_entries if "error" not in u}
    methods = [tghop_label(m) for m in modes] + list(BASELINE_KEYS)
    paths = []
    for e in entries:
        cols = [f64(e["images"]["exemplar"])] + [f64(e["images"][m]) for m in methods]
        labels = ["exemplar"] + methods
        if e["texture"] in ust_by:
            u = ust_by[e["texture"]]
            cols.append(f64(u["image"]))
            labels.append(f"Ust. {u['info']['n_iter']} it")
        # Every image at its pixel size on a 256-high strip (small ones padded, not scaled).
        padded = [np.pad(c, ((0, max(0, 256 - c.shape[0])), (0, 0), (0, 0)), constant_values=1.0) if c.shape[0] < 256
                  else c for c in cols]
        paths.append(save_png(image_sheet(padded, labels, height=256), out / "quality" / f"{e['texture']}.png"))
    return paths


# ---------------------------------------------------------------------------- main
def parse_args(argv=None):
    # --help: the docstring's usage lines, each option's meaning and the sections (the docstring's "Options:"
    # list was shown only in the source; argparse printed the bare option names).
    usage, rest = __doc__.split("\nOptions:\n", 1)
    ap = argparse.ArgumentParser(description=usage, epilog="Sections" + rest.split("\nSections", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help="3 textures in the quality table, fewer sweep points, Ustyuzhaninov on brick_wall only at 20 "
                         "iterations, Table 2's timed Ustyuzhaninov run skipped (8 min on 2 cores busy with other "
                         "jobs; explicit options below still win)")
    ap.add_argument("--out", type=Path, default=None,
                    help=f"output folder (default {RESULTS / 'paper'}; with --only, {RESULTS / 'paper-KEYS'}: a full "
                         "run's report is not overwritten)")
    ap.add_argument("--textures", default=None, help="comma-separated exemplars of the quality table (file stems in "
                    "../shared/textures or TGHOP_TEXTURES; default all)")
    ap.add_argument("--ust-textures", default=None, help="exemplars on which Ustyuzhaninov et al. runs in the "
                    "quality table (default brick_wall,red_peppers,grass_lawn; brick_wall with --quick; \"\" skips "
                    "those runs, not Table 2's timed one: --time-ust-iters 0)")
    ap.add_argument("--ust-size", type=int, default=None, help="output side of those runs (default 128)")
    ap.add_argument("--ust-iters", type=int, default=None,
                    help="L-BFGS iterations of those runs (default 100, 20 with --quick)")
    ap.add_argument("--time-ust-iters", type=int, default=None,
                    help="iterations of Table 2's timed 256x256 Ustyuzhaninov run, extrapolated to the paper's 100 "
                         "(default 10; 0 skips it, the default with --quick)")
    ap.add_argument("--workers", type=int, default=2,
                    help="processes for everything after the timing section (default 2)")
    ap.add_argument("--threads", type=int, default=1, help="BLAS / PyTorch threads of the timing section (default 1)")
    ap.add_argument("--only", default=None,
                    help="only these sections, comma-separated, by key or the paper's name: "
                         + ", ".join(f"{k} ({', '.join(v)})" if v else k for k, v in SECTION_NAMES.items())
                         + "; default all (e.g. --only fig6: Fig. 6 alone, under a minute)")
    ap.add_argument("--tghop", default="paper,default",
                    help="TGHop variants of the quality table: paper, default or paper,default (both)")
    args = ap.parse_args(argv)
    quick = args.quick
    if args.textures is None:
        args.textures = "brick_wall,grass_lawn,red_peppers" if quick else ",".join(texture_names())
    if args.ust_textures is None:
        args.ust_textures = "brick_wall" if quick else "brick_wall,red_peppers,grass_lawn"
    args.ust_size = args.ust_size or (128 if quick else 128)
    args.ust_iters = args.ust_iters if args.ust_iters is not None else (20 if quick else 100)
    if args.time_ust_iters is not None and args.time_ust_iters < 0:
        ap.error(f"--time-ust-iters takes 0 (skip the timed run) or more iterations, got {args.time_ust_iters}")
    # time_ust_skipped: the option that skipped Table 2's timed Ustyuzhaninov run ("" when it runs). A few
    # iterations at 256x256 take minutes of one core, most of a quick run's budget: --quick skips it.
    if args.time_ust_iters is None:
        args.time_ust_iters = 0 if quick else 10
        args.time_ust_skipped = "--quick" if quick else ""
    else:
        args.time_ust_skipped = "" if args.time_ust_iters else "--time-ust-iters 0"
    args.sections = list(SECTION_NAMES)
    if args.only is not None:
        aliases = {alias: key for key, names in SECTION_NAMES.items() for alias in (key, *names)}
        asked = [a.strip().lower().replace(" ", "").replace(".", "") for a in args.only.split(",") if a.strip()]
        unknown = [a for a in asked if a not in aliases]
        if unknown or not asked:
            ap.error(f"--only takes sections among {', '.join(aliases)}, got {args.only!r}")
        args.sections = [k for k in SECTION_NAMES if k in {aliases[a] for a in asked}]
    if args.out is None:
        args.out = RESULTS / ("paper" if args.only is None else "paper-" + "-".join(args.sections))
    args.modes = [m for m in args.tghop.split(",") if m]
    if not args.modes or any(m not in ("paper", "default") for m in args.modes):
        ap.error(f"--tghop takes paper, default or paper,default, got {args.tghop!r}")
    args.settings = ["a", "d"] if quick else list(SETTINGS)
    args.clusters = (50, 110) if quick else CLUSTERS
    args.gammas = (0, 0.01, 0.1) if quick else tuple(PAPER_TABLE5)
    return args


def needed_exemplars(args) -> list:
    """Every exemplar a run reads: brick_wall (Tables 1-5, Figs. 6, 7, 8, 11, 12), grass_lawn (Fig. 3),
    the quality table's and the Ustyuzhaninov runs' (in that order, each once)."""
    chosen = set(getattr(args, "sections", SECTION_NAMES))
    names = ([BRICK] if chosen - {"fig3", "quality"} else []) + ([GRASS] if "fig3" in chosen else []) + (
        args.textures.split(",") + args.ust_textures.split(",") if "quality" in chosen else [])
    return [n for n in dict.fromkeys(names) if n]


def missing_exemplars(names) -> list:
    """Those of ``names`` that are neither built in nor an image in the exemplar folder (``_common.TEXTURES``)."""
    import _common
    from tghop.data import BUILTIN

    return [n for n in names if n not in BUILTIN and not any(_common.TEXTURES.glob(f"{n}.*"))]


def git_version() -> str:
    """Commit of the checkout (``+dirty`` with local changes), or "unknown"."""
    import subprocess

    here = Path(__file__).resolve().parent
    try:
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=here, capture_output=True, text=True,
                             check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "src"], cwd=here.parent, capture_output=True,
                               text=True, check=True).stdout.strip()
        return rev + ("+dirty src" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def command_line(argv) -> str:
    """The command that made a run, as a shell reads it back: each argument quoted where it must be (an empty
    ``--ust-textures ""`` was written as nothing, so the report's command took the next option for its value)."""
    return shlex.join(["python", "benchmarks/bench_paper.py", *argv])


def main(argv=None):
    warnings.filterwarnings("ignore")
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse_args(argv)
    # Every exemplar is looked for before any work or output: one missing (no ../shared/textures
    # beside a fresh checkout) stopped the run at its first fit, or a worker's, minutes in.
    missing = missing_exemplars(needed_exemplars(args))
    if missing:
        import _common

        print(f"Error: exemplar{'s' if len(missing) > 1 else ''} {', '.join(missing)} not found in "
              f"{_common.TEXTURES} (the paper's brick_wall and grass_lawn, and those of --textures and "
              "--ust-textures); set TGHOP_TEXTURES to the folder that holds them (../shared/textures beside "
              "the checkout), or name others with --textures", file=sys.stderr)
        return 2
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    chosen = set(args.sections)
    textures = [t for t in args.textures.split(",") if t] if "quality" in chosen else []
    ust_textures = [t for t in args.ust_textures.split(",") if t] if "quality" in chosen else []
    timed = ("not run" if "time" not in chosen else "skipped by " + args.time_ust_skipped if args.time_ust_skipped
             else f"{args.time_ust_iters} iterations")
    quality = (f"{len(textures)} exemplars in the quality table; Ustyuzhaninov on {ust_textures or 'none'} at "
               f"{args.ust_size}^2 x {args.ust_iters} iterations" if "quality" in chosen else "no quality table")
    log(f"output {out}; sections: {', '.join(args.sections)}; {quality}; Table 2's timed Ustyuzhaninov run: {timed}; "
        f"quick={args.quick}")

    version = git_version()
    order = ["time", "settings", "clusters", "gamma", "params", "stages", "fig3", "fig7", "quality", "runtime"]
    sections: dict[str, str] = {}

    def emit(key, text, payload):
        sections[key] = text
        print(text + "\n", flush=True)
        data = write_results_to(out, key, payload)
        images = [v for v in payload.values() if isinstance(v, str) and v.endswith(".png")]
        log(f"{key}: written to {', '.join(images + [str(data)])} and {out / 'report.md'}")
        header = (f"# TGHop paper reproduction\n\n`{command_line(argv)}` "
                  f"({'quick' if args.quick else 'default'} settings). "
                  f"tghop commit {version}. Machine: {os.cpu_count()} CPU cores, shared with other jobs. "
                  "Paper: the 12 CPUs (6 cores, 12 threads) of an i7-5930K.\n\n"
                  + (f"Sections of this run (--only): {', '.join(args.sections)}.\n\n" if args.only else "")
                  + "Here: Tables 1-5 and Figs. 3, 6, 7, 8, 11 and 12. Figs. 9 and 10 (TGHop's images beside the DL "
                  "methods'): the quality section's sheets, with Ustyuzhaninov et al. on its subset; Gatys et al. "
                  "is not run (VGG-19's weights are not shipped). Figs. 1, 2, 4 and 5 are diagrams.\n")
        body = "\n\n".join(sections[k] for k in order if k in sections)
        (out / "report.md").write_text(header + "\n" + body + "\n")

    # 1, 5, 6: in this process, timing first while nothing else of ours runs.
    model = None
    if "time" not in chosen and chosen & {"params", "stages"}:  # their model, as the timing section fits it
        from tghop import TGHop

        log("fitting the paper-setting brick_wall model (untimed: the timing section is not run)")
        model = TGHop(**setting("paper"), rng=0).fit(texture(BRICK))
    for key, title, run in [("time", "Table 2/3", lambda: section_time(args, out)),
                            ("params", "Table 4", lambda: section_params(model)),
                            ("stages", "Fig. 6", lambda: section_stages(model, out))]:
        if key not in chosen:
            continue
        try:
            if key != "time" and model is None:
                raise RuntimeError("no model: the timing section failed")
            result = run()
            if key == "time":
                text, payload, model = result
            else:
                text, payload = result
            emit(key, text, payload)
        except Exception as exc:  # noqa: BLE001 -- report the section and go on
            traceback.print_exc()
            emit(key, md_error(title, {"error": f"{exc.__class__.__name__}: {exc}"}), {"error": str(exc)})

    # Everything else in single-threaded worker processes.
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"
    ctx = multiprocessing.get_context("spawn")
    quality, failed, ust = [], [], []
    tasks = [(key, fn, args_) for key, fn, args_ in (
        ("settings", _task_settings, (args.settings, out)), ("clusters", _task_clusters, (args.clusters, out)),
        ("gamma", _task_gamma, (args.gammas, out)), ("fig7", _task_fig7, (out,)), ("fig3", _task_fig3, (out,)))
        if key in chosen]
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=ctx, initializer=_init_worker,
                             initargs=(_T0,)) as pool:
        futures = {pool.submit(_call, fn, *args_): (key, None) for key, fn, args_ in tasks}
        for name in ust_textures:  # long runs early, so that they do not finish last alone
            futures[pool.submit(_call, _task_ust, name, args.ust_size, args.ust_iters)] = ("ust", name)
        for name in textures:
            futures[pool.submit(_call, _task_quality, name, args.modes)] = ("quality", name)
        formatters = {"settings": (md_settings, "Table 1 / Fig. 8"), "clusters": (md_clusters, "Fig. 11"),
                      "gamma": (md_gamma, "Table 5 / Fig. 12"), "fig7": (md_fig7, "Fig. 7"),
                      "fig3": (md_fig3, "Fig. 3")}
        n_quality = 0
        for fut in as_completed(futures):
            kind, name = futures[fut]
            try:
                res = fut.result()
            except Exception as exc:  # noqa: BLE001 -- a worker died
                res = {"error": f"{exc.__class__.__name__}: {exc}"}
            if kind in formatters:
                fmt, title = formatters[kind]
                if "error" in res:
                    log(f"{title} FAILED: {res['error']}\n{res.get('traceback', '')}")
                    emit(kind, md_error(title, res), res)
                else:
                    emit(kind, fmt(res), res)
            elif kind == "ust":
                if "error" in res:
                    log(f"Ustyuzhaninov {name} FAILED: {res['error']}")
                ust.append({**res, "texture": name})
            else:
                n_quality += 1
                if "error" in res:
                    log(f"quality {name} SKIPPED: {res['error']}")
                    failed.append((name, res["error"]))
                else:
                    quality.append(res)
                log(f"quality {n_quality}/{len(textures)} done")

    if "quality" in chosen:
        text, payload = md_quality(quality, failed, ust, args.modes)
        payload["sheets"] = quality_sheets(sorted(quality, key=lambda e: e["texture"]), ust, args.modes, out)
        methods = [tghop_label(m) for m in args.modes] + list(BASELINE_KEYS)
        text += f"\nOne sheet per exemplar in `quality/` (exemplar | {' | '.join(methods)} [| Ustyuzhaninov])."
        emit("quality", text, payload)
    total = time.perf_counter() - _T0
    sections["runtime"] = f"Total runtime: {total / 60:.1f} min ({total:.0f} s)."
    emit("runtime", sections["runtime"], {"total_s": total})
    log(f"done in {total:.0f} s; report {out / 'report.md'}")


if __name__ == "__main__":
    sys.exit(main())
