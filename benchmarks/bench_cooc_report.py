"""Evaluation half of bench_cooc.py: baselines, speed, stability, novelty, quality, sheets.

    python benchmarks/bench_cooc_report.py baselines brick_wall grass_lawn red_peppers
    python benchmarks/bench_cooc.py report brick_wall grass_lawn red_peppers

``baselines`` makes (and caches as PNG in results/cooc/) the TGHop (tghop defaults, seed
0, 128x128 and 256x256) and Ustyuzhaninov (100 L-BFGS iterations, 128x128, seed 0) images
the quality table compares with; ``report`` (run through bench_cooc.py) makes them too
if missing.
"""

from __future__ import annotations

import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, image_sheet, markdown_table, stack_rows, texture, write_results_to  # noqa: E402

OUT = RESULTS / "cooc"
METRICS = ("sifid", "swd", "cooccurrence", "copied")
UST_SIZE, UST_ITERS = 128, 100


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def prepare(name):
    img = texture(name)
    if max(img.shape[:2]) > 512:
        y, x = (img.shape[0] - 256) // 2, (img.shape[1] - 256) // 2
        img = img[y : y + 256, x : x + 256]
    return img


def score(exemplar, result) -> dict:
    from tghop import metrics as M

    return {m: float(M.METRICS[m].function(exemplar, result)) for m in METRICS}


def cached(path: Path, make):
    from tghop.imageio import load_image, save_image

    if path.exists():
        return load_image(path), None
    t = time.perf_counter()
    img = make()
    seconds = time.perf_counter() - t
    save_image(img, path)
    (path.with_suffix(".json")).write_text(json.dumps({"seconds": seconds}))
    return img, seconds


def baselines(name, out: Path) -> dict:
    """TGHop (defaults) at 128 and 256, Ustyuzhaninov at 128: images cached in ``out``."""
    from tghop import TGHop
    from tghop.baselines import ustyuzhaninov

    img = prepare(name)
    model = {}

    def tg(size):
        if "m" not in model:
            model["m"] = TGHop(rng=0).fit(img)
        return model["m"].synthesize((size, size), rng=0)

    images = {
        "TGHop 128": cached(out / f"tghop-{name}-128.png", lambda: tg(128))[0],
        "TGHop 256": cached(out / f"tghop-{name}-256.png", lambda: tg(256))[0],
        "Ustyuzhaninov 128": cached(out / f"ust-{name}-{UST_SIZE}-{UST_ITERS}.png",
                                    lambda: ustyuzhaninov(img, UST_SIZE, n_iter=UST_ITERS, rng=0))[0],
    }
    log(f"baselines {name}: done")
    return images


# ----------------------------------------------------------------------------- checks
def stability(model, img, *, n_rounds=10, n_crops=8, seed=0) -> dict:
    """Sec. 4.2: tensor of a held-out crop -> generate -> its tensor -> generate ..., one noise per crop.

    L1 of round r = mean over crops of sum |input tensor - tensor of the output| per cell.
    """
    rng = np.random.default_rng(seed)
    n = model.settings_["crop_size"]
    l1 = np.zeros((n_rounds, n_crops))
    first_seq = []
    for j in range(n_crops):
        y, x = rng.integers(img.shape[0] - n + 1), rng.integers(img.shape[1] - n + 1)
        crop = img[y : y + n, x : x + n]
        cond = model.cooccurrence(crop)
        z = model.noise(cond.shape[1:], rng=rng)
        seq = [crop]
        for r in range(n_rounds):
            out = model.generate(cond, noise=z)
            new = model.cooccurrence(out)
            l1[r, j] = np.abs(new - cond / cond.sum(0)).sum(0).mean()
            cond = new
            seq.append(out)
        if j == 0:
            first_seq = seq
    per_round = l1.mean(axis=1)
    drift = 100.0 * (per_round - per_round[0]) / per_round[0]
    return {"l1": per_round.tolist(), "drift_pct": drift.tolist(), "max_abs_drift_pct": float(np.abs(drift).max()),
            "sequence": first_seq}


def nearest_neighbours(model, img, *, n_gen=8, n_train=400, seed=0) -> dict:
    """Sec. 4.2 / Fig. 5: generated crops against their nearest training crop, in RGB L1 and in co-occurrence L1.

    Reference: the same distances for real held-out crops (a real crop is near other real
    crops that overlap it; a generated crop that copies would be as near).
    """
    rng = np.random.default_rng(seed)
    n = model.settings_["crop_size"]

    def crops(k):
        ys, xs = rng.integers(img.shape[0] - n + 1, size=k), rng.integers(img.shape[1] - n + 1, size=k)
        return np.stack([img[y : y + n, x : x + n] for y, x in zip(ys, xs)])

    train = crops(n_train)
    train_c = np.stack([model.cooccurrence(c) for c in train])
    held = crops(n_gen)
    gen = np.stack([model.generate(model.cooccurrence(c), rng=rng) for c in held])

    def nn(batch):
        rgb = np.abs(batch[:, None] - train[None]).mean(axis=(2, 3, 4))  # (b, n_train)
        bc = np.stack([model.cooccurrence(c) for c in batch])
        co = np.abs(bc[:, None] - train_c[None]).sum(axis=2).mean(axis=(2, 3))
        return rgb.min(1), co.min(1), rgb.argmin(1)

    g_rgb, g_co, g_idx = nn(gen)
    r_rgb, r_co, _ = nn(held)
    return {"gen_rgb_l1": float(g_rgb.mean()), "gen_cooc_l1": float(g_co.mean()), "real_rgb_l1": float(r_rgb.mean()),
            "real_cooc_l1": float(r_co.mean()), "pairs": [gen[:4], train[g_idx[:4]]]}


def gen_speed(model, size, n=3, assembly="quilt") -> float:
    """Images per second of :meth:`sample` at ``size`` x ``size`` (after one warm-up)."""
    model.sample((size, size), rng=0, assembly=assembly)
    t = time.perf_counter()
    for i in range(n):
        model.sample((size, size), rng=i + 1, assembly=assembly)
    return n / (time.perf_counter() - t)


# ----------------------------------------------------------------------------- seeds: raw vs averaged generator
def _with_average(model, state=None, *, recompute=True):
    """``model`` generating with an average of the same run (``state``: a state dict of
    ``RUN_ema.pt``; default the model's own), its batch-norm statistics recomputed for the
    averaged weights (as ``fit`` does since this session) or, ``recompute=False``, as
    stored (checkpoints of the first version: copied from the raw generator)."""
    import copy

    import torch

    other = copy.copy(model)
    other.generator_ema_ = copy.deepcopy(model.generator_ema_)
    if state is not None:
        other.generator_ema_.load_state_dict(state)
    if recompute:
        other._recompute_average_statistics(torch, model._conds)
    return other


def _raw_recomputed(model):
    """The raw generator with its batch-norm statistics recomputed the same way (a control:
    is a gain the average's or the recomputation's?)."""
    import copy

    import torch

    other = copy.copy(model)
    other.generator_ema_ = copy.deepcopy(model.generator_)
    other._recompute_average_statistics(torch, model._conds)
    return other


def seed_study(stems, out: Path, threads: int, n_images: int = 4):
    """Each run ``STEM`` (``NAME`` or ``NAME-seedS``): raw and averaged generators of the same
    training, ``n_images`` 256 px samples each (``sample(rng=i)``: the same conditions and
    noise for every variant), scored against the exemplar. Writes ``seeds.json/.md`` and
    ``seeds-STEM.png`` (exemplar | raw | average, two samples each)."""
    import torch

    from tghop.cooc import load
    from tghop.imageio import save_image

    warnings.filterwarnings("ignore")
    torch.set_num_threads(threads)
    path = out / "seeds.json"
    payload = json.loads(path.read_text()) if path.exists() else {"runs": {}}
    for stem in stems:
        name = stem.split("-seed")[0]
        model = load(out / f"{stem}.pt", device="cpu")
        train = json.loads((out / f"{stem}_train.json").read_text())
        img = prepare(name)
        model._rebuild_crops(torch, img, None)  # the training tensors, for the batch-norm passes
        variants = {"raw": model.raw(), "raw, bn recomputed": _raw_recomputed(model)}
        if hasattr(model, "generator_ema_"):
            variants[f"ema {model.settings_['ema']:g}, bn copied"] = _with_average(model, recompute=False)
            variants[f"ema {model.settings_['ema']:g}"] = _with_average(model)
        extra = out / f"{stem}_ema.pt"
        if extra.exists():
            for decay, state in torch.load(extra, weights_only=True).items():
                variants[f"ema {float(decay):g}"] = _with_average(model, state)
        variants = dict(sorted(variants.items(), key=lambda kv: (kv[0] != "raw", "bn" not in kv[0], kv[0])))
        run = {"texture": name, "seed": train.get("seed", 0), "steps": train["steps"],
               "s_per_step": train["seconds"] / max(train["steps"], 1),
               "load": [train.get("load_before"), train.get("load_after")],
               "variants": {}}
        shown = {}
        for label, v in variants.items():
            # One generator pass (the paper's assembly), as the GPU sweeps in docs/choices.md.
            images = [v.sample((256, 256), rng=i, assembly="pass") for i in range(n_images)]
            scores = [score(img, im) for im in images]
            run["variants"][label] = {m: [sc[m] for sc in scores] for m in METRICS}
            shown[label] = images[:2]
            log(f"{stem} {label}: SIFID {np.round(run['variants'][label]['sifid'], 2).tolist()}")
        payload["runs"][stem] = run
        from tghop.cooc import SMALL

        # the sheet shows the default average (SMALL's decay) where the run kept it, else the model's own
        ema_label = next((k for k in (f"ema {SMALL['ema']:g}", f"ema {model.settings_['ema']:g}")
                          if k in variants), None)
        cols = [img] + shown["raw"] + (shown[ema_label] if ema_label else [])
        labels = ["exemplar", "raw rng 0", "raw rng 1"] + ([f"{ema_label} rng 0", f"{ema_label} rng 1"]
                                                           if ema_label else [])
        save_image(image_sheet(cols, labels, height=256), out / f"seeds-{stem}.png")
        for label, ims in shown.items():
            save_image(ims[0], out / f"seeds-{stem}-{label.replace(' ', '_')}.png")
        path.write_text(json.dumps(payload, indent=1))
    write_results_to(out, "seeds", payload, seeds_markdown(payload))
    merge_seeds_into_report(out, payload)
    print(seeds_markdown(payload))
    return payload


def merge_seeds_into_report(out: Path, payload) -> None:
    """Put the seeds section into an existing ``report.md`` / ``report.json`` (replacing an
    earlier seeds section; the rest of the report is left as it is)."""
    md, js = out / "report.md", out / "report.json"
    if md.exists():
        text = md.read_text()
        head = text.split("\n## Seeds:")[0].rstrip("\n")
        md.write_text(head + "\n\n" + seeds_markdown(payload) + "\n")
    if js.exists():
        data = json.loads(js.read_text())
        data["seeds"] = payload
        js.write_text(json.dumps(data, indent=2))


def seeds_markdown(payload) -> str:
    """Per run: the mean over its samples of each metric, per variant; then per texture the
    median over runs."""
    rows, per_texture = [], {}
    for stem, run in payload["runs"].items():
        for label, sc in run["variants"].items():
            means = [float(np.mean(sc[m])) for m in METRICS]
            rows.append([run["texture"], run["seed"], label] + means
                        + [f"{min(sc['sifid']):.2f}-{max(sc['sifid']):.2f}"])
            per_texture.setdefault((run["texture"], label), []).append(means)
    med = [[t, label, len(v)] + [float(np.median([r[i] for r in v])) for i in range(len(METRICS))]
           for (t, label), v in per_texture.items()]
    return "\n".join([
        "## Seeds: raw and averaged generator of the same runs (256 px, lower is better)\n",
        "SMALL runs, one per seed, steps as `seeds.json` records them (3,000 of batch 16 before issue 9's session 14, "
        "5,500 of batch 8 since; `bench_cooc.py train NAME --seed S --extra-ema ...`, "
        "then `bench_cooc.py seeds`; the sections above are earlier runs without an average). Generators of one "
        "run: raw (the last weights), the raw one with its batch-norm statistics recomputed (a control), the "
        "model's own average with the statistics copied from the raw generator (the first version) and, for "
        "every decay, the average with its statistics recomputed (as `fit` does now). "
        "Each run: mean over its samples (`sample((256, 256), rng=i)`, the same condition and noise for every "
        "variant) of each metric; the SIFID range over the samples.\n",
        markdown_table(["texture", "seed", "generator", *METRICS, "SIFID range"], rows),
        "\nMedian over the runs (seeds) of each texture:\n",
        markdown_table(["texture", "generator", "runs", *METRICS], med)])


# ----------------------------------------------------------------------------- report
def report(names, out: Path, threads: int):
    import torch

    from tghop.cooc import load
    from tghop.imageio import save_image

    warnings.filterwarnings("ignore")
    torch.set_num_threads(threads)
    rows_train, rows_speed, rows_stab, rows_nn, rows_q = [], [], [], [], []
    payload = {"textures": {}}
    sheets = []
    for name in names:
        ck = out / f"{name}.pt"
        if not ck.exists():
            log(f"{name}: no checkpoint {ck}; run bench_cooc.py train {name} first")
            continue
        train = json.loads((out / f"{name}_train.json").read_text())
        model = load(ck, device="cpu")
        img = prepare(name)
        cpu = train.get("cpu_seconds")
        loads = (f"{train['load_before']:.1f} / {train['load_after']:.1f}" if "load_before" in train else "-")
        rows_train.append([name, train["steps"], train["seconds"] / 60, "-" if cpu is None else cpu / 60,
                           train.get("stages", {}).get("co-occurrences", "-"),
                           train["seconds"] / max(train["steps"], 1), train.get("peak_rss_mb", "-"), loads])
        log(f"{name}: speed")
        speed = {s: gen_speed(model, s, n=3 if s == 256 else 1) for s in (256, 1024)}
        speed.update({f"{s} pass": gen_speed(model, s, n=3 if s == 256 else 1, assembly="pass") for s in (256, 1024)})
        rows_speed.append([name, speed[256], speed[1024], speed["256 pass"], speed["1024 pass"]])
        log(f"{name}: stability")
        stab = stability(model, img)
        rows_stab.append([name] + [f"{v:.3f}" for v in stab["l1"][:1]] + [f"{d:+.1f}" for d in stab["drift_pct"][1:]]
                         + [stab["max_abs_drift_pct"]])
        log(f"{name}: nearest neighbours")
        nn = nearest_neighbours(model, img)
        rows_nn.append([name, nn["gen_rgb_l1"], nn["real_rgb_l1"], nn["gen_cooc_l1"], nn["real_cooc_l1"]])
        log(f"{name}: baselines and quality")
        base = baselines(name, out)
        ours = {"cooc 128": model.sample((128, 128), rng=0), "cooc 256": model.sample((256, 256), rng=0),
                "cooc 256 pass": model.sample((256, 256), rng=0, assembly="pass"),
                "cooc 512": model.sample((512, 512), rng=0),
                "cooc 512 pass": model.sample((512, 512), rng=0, assembly="pass")}
        for label, im in ours.items():
            save_image(im, out / f"{label.replace(' ', '-')}-{name}.png")
        crop128 = img[:128, :128]
        results = {"crop 128": crop128, **base, **ours}
        scores = {label: score(img, im) for label, im in results.items()}
        for label, sc in scores.items():
            rows_q.append([name, label] + [sc[m] for m in METRICS])
        # sheets: exemplar | samples; morph strip; grid; edit; stability sequence
        a, b = model.crop_condition(0, 0), model.crop_condition(img.shape[0] - model.settings_["crop_size"],
                                                                img.shape[1] - model.settings_["crop_size"])
        strip = model.morph_strip(a, b, length=16, rng=0)
        grid = model.morph_grid(a, b, n_cols=5, n_rows=3, rng=0)
        from tghop.cooc import paint_condition
        from tghop.patches import patch_grid

        labels = np.zeros((8, 16), dtype=int)
        labels[:, 8:] = 1
        edit = model.generate(paint_condition([a, b], labels), rng=0)
        save_image(strip, out / f"morph-{name}.png")
        save_image(patch_grid(grid.reshape((-1,) + grid.shape[2:]), n_cols=5), out / f"grid-{name}.png")
        save_image(edit, out / f"edit-{name}.png")
        sheet = stack_rows([
            # 128 px results in one row; the larger cooc samples (all of ``ours`` but the first) in the next.
            image_sheet([img] + [v for k, v in results.items() if k not in list(ours)[1:]],
                        ["exemplar"] + [k for k in results if k not in list(ours)[1:]], height=160),
            image_sheet([img] + list(ours.values())[1:], ["exemplar"] + list(ours)[1:], height=256),
            image_sheet([strip], [f"morph crop(0,0) -> crop(bottom right), {strip.shape[1]} px"], height=96),
            image_sheet([edit], ["edit: the two crops' statistics painted left | right"], height=128),
            image_sheet(stab["sequence"], ["crop"] + [f"round {i + 1}" for i in range(len(stab["sequence"]) - 1)],
                        height=64),
            image_sheet(nn["pairs"][0].tolist() and list(nn["pairs"][0]) + list(nn["pairs"][1]),
                        ["generated"] * 4 + ["nearest train crop"] * 4, height=64),
        ])
        save_image(sheet, out / f"sheet-{name}.png")
        sheets.append(sheet)
        payload["textures"][name] = {"train": {k: v for k, v in train.items() if k != "history"},
                                     "speed_images_per_s": speed,
                                     "stability": {k: v for k, v in stab.items() if k != "sequence"},
                                     "nearest": {k: v for k, v in nn.items() if k != "pairs"}, "scores": scores}
        log(f"{name}: done")
    md = ["# Co-occurrence cGAN (Darzi et al.), small configuration, on this machine\n",
          f"torch threads: {threads}. Peak RSS is the training process's own.\n",
          "## Training\n",
          markdown_table(["texture", "steps", "minutes", "CPU minutes", "co-occurrence setup s", "s / step",
                          "peak RSS MB", "load avg before / after"], rows_train),
          "\n## Generation speed (CPU, images per second)\n",
          "Default: generated training-size crops quilted together (ours, `assembly=\"quilt\"`); "
          "pass: one generator pass over the whole condition (the paper's).\n",
          markdown_table(["texture", "256x256", "1024x1024", "256 pass", "1024 pass"], rows_speed),
          "\n## Stability loop (paper: within 2 % of round 1 over 10 rounds)\n",
          "L1 = mean over 8 held-out crops and cells of sum |input - output co-occurrence|; "
          "drift of rounds 2-10 in % of round 1.\n",
          markdown_table(["texture", "L1 round 1"] + [f"r{i}" for i in range(2, 11)] + ["max |drift| %"], rows_stab),
          "\n## Nearest training crop (paper Fig. 5)\n",
          "Mean over 8 crops of the distance to the nearest of 400 training crops: generated "
          "(from held-out crops' tensors) vs the held-out real crops themselves.\n",
          markdown_table(["texture", "RGB L1 generated", "RGB L1 real", "cooc L1 generated", "cooc L1 real"], rows_nn),
          "\n## Quality (lower is better; copied: fraction of verbatim 16x16 patches)\n",
          "cooc N: sample((N, N), rng=0): generated training-size crops quilted together (the default, "
          "ours); cooc N pass: one generator pass over the exemplar's mirror-tiled tensor (the paper's way, "
          "assembly=\"pass\").\n",
          markdown_table(["texture", "method"] + list(METRICS), rows_q)]
    if (out / "seeds.json").exists():  # bench_cooc.py seeds: raw vs averaged generator over seeds
        md += ["", seeds_markdown(json.loads((out / "seeds.json").read_text()))]
    text = "\n".join(md)
    write_results_to(out, "report", payload, text)
    print(text)


if __name__ == "__main__":
    if sys.argv[1:2] in (["-h"], ["--help"]):
        print("usage: bench_cooc_report.py baselines NAME...\n\n" + __doc__)
        raise SystemExit(0)
    if len(sys.argv) < 3 or sys.argv[1] != "baselines":
        raise SystemExit("usage: bench_cooc_report.py baselines NAME...")
    warnings.filterwarnings("ignore")
    import torch

    torch.set_num_threads(1)
    OUT.mkdir(parents=True, exist_ok=True)
    for texture_name in sys.argv[2:]:
        baselines(texture_name, OUT)
