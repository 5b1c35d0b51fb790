"""Whole materials: do the maps stay aligned? Cross-correlations of the maps, exemplar against output.

For each texture, a material is made from it (:func:`tghop.material.example_maps`: albedo
= the exemplar, height = its luminance blurred, normal = the height's slope, roughness =
1 - the luminance blurred more; the height is stored as 16 bits) and synthesised at
``--size`` with ``--seeds`` seeds by several ways of keeping maps together:

* ``joint``: one model of the stacked channels, each map refined and colour-matched on its
  own (the default of :class:`tghop.material.Material`);
* ``joint, albedo refined only``: the same, the other maps only colour-matched;
* ``joint, unrefined``: no refinement of any map;
* ``albedo decides``: the same joint pool, but quilting chooses patches and cuts by the
  albedo's channels only (the maps' channels weighted 1e-3 in every error and in the
  coarse guide), the albedo's layout carried to the maps;
* ``one model per map``: a model fitted on each map alone, generated with the same seed
  (nothing ties the maps together: the control).

Per way: each cross-correlation of the exemplar in the output (luminance-roughness,
luminance-height, height-roughness, and the height's slope against the normal map's x
and y, both blurred by 1 px, their mean; the same pixel by pixel, which a quilting seam
breaks where it runs), and the largest relative difference from the exemplar's of the
first four; the albedo's SIFID against the
exemplar (with ``--sifid``); fit and generation times (in process, noisy on a shared
machine). A sheet of every map (exemplar and the joint output of the first seed) is
written to benchmarks/results/material_sheet.png (not committed).

    python benchmarks/bench_material.py brick_wall knit bark hexagon_tiles --seeds 3

``--albedo-refine`` (0.59) measures the albedo's patch refinement instead (docs/choices.md, Whole
materials, "The albedo patch-refined"): per texture a plain texture model and a material of the crop
(both ``rng=0``, default settings), and for each seed the texture's image, the material's albedo
without the patch refinement (``patch_refine=0``: 0.58's output, the joint model being the same) and
with it (the default); the albedo's SIFID against the crop, the height's correlation with the albedo's
brightness (the crop's too), the normal map's largest length error, generation times; means over the
seeds, and a mean row. Written to benchmarks/results/material_albedo.json and .md. The docs' table:

    python benchmarks/bench_material.py brick_wall knit bark hexagon_tiles stone_wall_256 grass_lawn \
        leopard --albedo-refine --seeds 2

``--painted`` (0.60) measures it in painted materials: the textures taken in pairs (A B C D: A beside B,
C beside D), each a material as above (``rng=0``), painted half and half (A left, B right,
``synthesize_guided``, the default transition) at ``--size``; for each seed the image without the patch
refinement (``patch_refine=0``), with the default (None: by the size, what 0.59 painted already) and with
``--quality best``'s (0.59 refused it for painted materials); each region's albedo, the columns more than
half the transition from the edge, scored against its own material's crop (SIFID), the normal map's largest
length error, whether the other maps are those without the refinement on those columns, bit for bit, and the
share of the band's pixels where they are not (the one join follows every map, the albedo too). Written to
benchmarks/results/material_painted.json and .md:

    python benchmarks/bench_material.py brick_wall knit bark stone_wall_256 grass_lawn leopard --painted \
        --seeds 2
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _common import RESULTS, image_sheet, markdown_table, texture, write_results

#: The cross-correlations held to 5 %: map values, and the height's slope against the
#: normal map at the scale of 1 px (both blurred by sigma 1: a quilting seam is one pixel wide).
PAIRS = ("lum-rough", "lum-height", "height-rough", "slope-normal")
#: Reported too: the slope against the normal pixel by pixel (a seam breaks it there).
EXTRA = ("slope-normal, per pixel",)


def cross_correlations(maps) -> dict:
    """The cross-correlations of a material's maps (dict of name -> (H, W, c))."""
    from tghop.material import _blur

    lum = maps["albedo"].mean(axis=2)
    h, r, n = maps["height"][..., 0], maps["roughness"][..., 0], maps["normal"] * 2 - 1
    gy, gx = np.gradient(h)

    def corr(a, b, sigma=0):
        if sigma:
            a, b = _blur(a, sigma), _blur(b, sigma)
        return float(np.corrcoef(a.ravel(), b.ravel())[0, 1])

    return {"lum-rough": corr(lum, r), "lum-height": corr(lum, h), "height-rough": corr(h, r),
            "slope-normal": (corr(gx, n[..., 0], 1) + corr(gy, n[..., 1], 1)) / 2,
            "slope-normal, per pixel": (corr(gx, n[..., 0]) + corr(gy, n[..., 1])) / 2}


def albedo_decides(material, weight=1e-3):
    """A copy of ``material`` whose quilting is led by the albedo alone (see the module notes)."""
    import copy

    from tghop.pool import GeneratedPool
    from tghop.quilting import prepare_pool
    from tghop.synthesis import TGHop

    c0 = material.map_channels_[0]

    class AlbedoLed(TGHop):
        def _prepared_pool(self, n_patches, rng, size, overlap, tile, detail, guide_scale):
            pool = GeneratedPool(self, *self.sample_vectors(n_patches, rng, np.dtype(np.float32))).all()
            pool[..., c0:] *= weight
            return prepare_pool(pool, size, overlap=overlap, tile=tile, detail=detail, guide_scale=guide_scale)

        def synthesize(self, size, **kw):
            out = super().synthesize(size, **kw)
            out[..., c0:] /= weight
            return np.clip(out, 0, 1, out=out)

    class Guide:
        def __init__(self, layout):
            self.layout = layout

        def __getattr__(self, name):  # factor, patch_size, ... (tghop.layout.follows_guide reads them)
            return getattr(self.__dict__["layout"], name)

        def guide(self, *args, **kw):
            g = self.layout.guide(*args, **kw)
            g[..., c0:] *= weight
            return g

    alt = copy.copy(material)
    model = AlbedoLed.__new__(AlbedoLed)
    model.__dict__.update(material.model_.__dict__)
    if model.layout_ is not None:
        model.layout_ = Guide(model.layout_)
    alt.model_ = model
    return alt


def per_map(material_maps, size, seed, fit_kw):
    """'one model per map': each map fitted alone, generated with the same seed."""
    from tghop import TGHop

    out = {}
    for name, img in material_maps.items():
        model = TGHop(rng=0, **fit_kw).fit(img)
        out[name] = model.synthesize(size, rng=seed)
        if name == "normal":
            from tghop.material import renormalise

            out[name] = renormalise(out[name])
    return out


#: The columns of ``--albedo-refine``'s rows: the albedo's SIFID of each output.
ALBEDO_WAYS = ("texture (plain)", "material 0.58", "material 0.59")


def height_brightness(maps) -> float:
    """The correlation of a material's height with its albedo's brightness (the channels' mean)."""
    return float(np.corrcoef(maps["albedo"].mean(axis=2).ravel(), maps["height"][..., 0].ravel())[0, 1])


def albedo_refine_row(ex, size, seeds, *, fit=None, score=None) -> dict:
    """``--albedo-refine`` for one exemplar ``ex`` (the crop): a plain texture model and a material of
    :func:`tghop.material.example_maps` (height as 16 bits), both ``rng=0`` with the settings ``fit``
    (None: the defaults), each seed's texture image, material albedo with ``patch_refine=0`` (0.58's) and
    with the default patch refinement (0.59), scored by ``score(exemplar, image)`` (None:
    :func:`tghop.metrics.sifid`). Returns the means over ``seeds`` of each way's score
    (:data:`ALBEDO_WAYS`), the height-brightness correlations (``corr 0.58``, ``corr 0.59`` and the crop's
    ``corr crop``), the normal map's largest length error of the refined output (``normal error``), the
    generation seconds (``synth 0.58``, ``synth 0.59``) and the fit seconds (``fit plain``, ``fit material``)."""
    from tghop import TGHop
    from tghop.material import Material, example_maps

    if score is None:
        from tghop.metrics import sifid as score
    fit = fit or {}
    maps = example_maps(ex)
    maps["height"] = np.round(maps["height"] * 65535).astype(np.uint16)  # a 16-bit map
    crop = {"albedo": ex, "height": maps["height"] / 65535.0}
    t = time.perf_counter()
    plain = TGHop(rng=0, **fit).fit(ex)
    fit_plain = time.perf_counter() - t
    t = time.perf_counter()
    material = Material(model=TGHop(rng=0, **fit) if fit else None, rng=0).fit(ex, maps)
    fit_material = time.perf_counter() - t
    got = {}
    for seed in seeds:
        texture_image = plain.synthesize(size, rng=seed)
        t = time.perf_counter()
        before = material.synthesize(size, rng=seed, patch_refine=0)
        t_before = time.perf_counter() - t
        t = time.perf_counter()
        after = material.synthesize(size, rng=seed)
        t_after = time.perf_counter() - t
        for way, image in zip(ALBEDO_WAYS, (texture_image, before["albedo"], after["albedo"])):
            got.setdefault(way, []).append(float(score(ex, image)))
        got.setdefault("corr 0.58", []).append(height_brightness(before))
        got.setdefault("corr 0.59", []).append(height_brightness(after))
        got.setdefault("normal error", []).append(
            float(np.abs(np.linalg.norm(after["normal"] * 2 - 1, axis=2) - 1).max()))
        got.setdefault("synth 0.58", []).append(t_before)
        got.setdefault("synth 0.59", []).append(t_after)
    row = {k: float(np.mean(v)) for k, v in got.items()}
    row["normal error"] = float(np.max(got["normal error"]))
    row.update({"corr crop": height_brightness(crop), "fit plain": fit_plain, "fit material": fit_material})
    return row


def albedo_refine_table(rows: dict) -> str:
    """The markdown table of docs/choices.md ("The albedo patch-refined") from ``{texture: row}`` of
    :func:`albedo_refine_row`, with a mean row of the scores."""
    header = ["exemplar", *ALBEDO_WAYS, "correlation 0.58 / 0.59 (crop)", "synth s 0.58 / 0.59"]
    lines = [[name, *(f"{r[w]:.2f}" for w in ALBEDO_WAYS),
              f"{r['corr 0.58']:.3f} / {r['corr 0.59']:.3f} ({r['corr crop']:.3f})",
              f"{r['synth 0.58']:.1f} / {r['synth 0.59']:.1f}"] for name, r in rows.items()]
    lines.append(["mean", *(f"{np.mean([r[w] for r in rows.values()]):.2f}" for w in ALBEDO_WAYS), "", ""])
    return markdown_table(header, lines)


#: The columns of ``--painted``'s rows: the settings each painted image is made with (0.60).
PAINTED_WAYS = {"unrefined": {"patch_refine": 0}, "default": {}, "best": {"patch_refine": 90, "patch_stride": 1}}


def painted_row(ex_a, ex_b, size, seeds, *, fit=None, score=None, transition=32) -> dict:
    """``--painted`` for one pair of crops: materials of ``ex_a`` and ``ex_b`` (as :func:`albedo_refine_row`
    makes them, with the settings ``fit``) painted half and half at ``size`` by each of :data:`PAINTED_WAYS`,
    each region's albedo (its columns farther than ``transition / 2`` from the edge) scored against its own crop
    by ``score(exemplar, image)`` (None: :func:`tghop.metrics.sifid`). Returns the means over ``seeds`` of
    ``"<way> A"`` and ``"<way> B"``, the normal map's largest length error (``normal error``), whether every
    map but the albedo is the unrefined one's bit for bit in every way on the regions' columns (``maps kept``),
    the share of the band's pixels where they are not (``"<way> band moved"``: the one join follows the albedo
    too) and the mean seconds of each way (``"<way> s"``)."""
    from tghop import TGHop, synthesize_guided
    from tghop.material import Material, example_maps

    if score is None:
        from tghop.metrics import sifid as score
    materials = []
    for ex in (ex_a, ex_b):
        maps = example_maps(ex)
        maps["height"] = np.round(maps["height"] * 65535).astype(np.uint16)  # a 16-bit map
        materials.append(Material(model=TGHop(rng=0, **fit) if fit else None, rng=0).fit(ex, maps))
    h, w = size
    guide = np.zeros((h, w), np.uint8)
    guide[:, w // 2:] = 255
    half = transition // 2
    regions = ((ex_a, np.s_[:, :w // 2 - half]), (ex_b, np.s_[:, w // 2 + half:]))
    got, kept, error = {}, True, 0.0
    for seed in seeds:
        made = {}
        for way, settings in PAINTED_WAYS.items():
            t = time.perf_counter()
            made[way] = synthesize_guided(materials, guide, rng=seed, transition=transition, **settings)
            got.setdefault(f"{way} s", []).append(time.perf_counter() - t)
            for side, (ex, part) in zip("AB", regions):
                got.setdefault(f"{way} {side}", []).append(float(score(ex, made[way]["albedo"][part])))
            error = max(error, float(np.abs(np.linalg.norm(made[way]["normal"] * 2 - 1, axis=2) - 1).max()))
            for name in made[way]:  # the other maps: the same away from the join, which follows the albedo too
                if name != "albedo":
                    kept = kept and all(np.array_equal(made[way][name][part], made["unrefined"][name][part])
                                        for _, part in regions)
                    band = made[way][name][:, w // 2 - half:w // 2 + half] != \
                        made["unrefined"][name][:, w // 2 - half:w // 2 + half]
                    got.setdefault(f"{way} band moved", []).append(float(band.any(axis=2).mean()))
    row = {k: float(np.mean(v)) for k, v in got.items()}
    row.update({"normal error": error, "maps kept": kept})
    return row


def painted_table(rows: dict) -> str:
    """The markdown table of docs/choices.md ("Painted materials", 0.60) from ``{"A / B": row}`` of
    :func:`painted_row`, with a mean row of the scores."""
    moved = [w for w in PAINTED_WAYS if w != "unrefined"]
    header = ["A / B", *(f"{way} A / B" for way in PAINTED_WAYS), "normal error", "maps kept",
              "band moved " + " / ".join(moved), "synth s " + " / ".join(PAINTED_WAYS)]
    lines = [[pair, *(f"{r[f'{w} A']:.2f} / {r[f'{w} B']:.2f}" for w in PAINTED_WAYS), f"{r['normal error']:.1e}",
              "yes" if r["maps kept"] else "no", " / ".join(f"{r[f'{w} band moved']:.0%}" for w in moved),
              " / ".join(f"{r[f'{w} s']:.1f}" for w in PAINTED_WAYS)] for pair, r in rows.items()]
    lines.append(["mean", *(f"{np.mean([(r[f'{w} A'] + r[f'{w} B']) / 2 for r in rows.values()]):.2f}"
                            for w in PAINTED_WAYS), "", "", "", ""])
    return markdown_table(header, lines)


def table_main(args, flag, groups, row, table, name, key, title):
    """``flag``'s run (--albedo-refine, --painted): ``row(*crops, size, seeds)`` for each group of textures (one
    texture, or a pair A B) cropped to --crop, printed as it is made; then the rows written to results/``name``
    (``key``: what names a row) and printed as ``table(rows)`` under ``title`` (what comes before the seeds)."""
    size, seeds, rows = (args.size, args.size), list(range(args.seeds)), {}
    crops = {n: texture(n)[: args.crop or None, : args.crop or None] for group in groups for n in group}
    for group in groups:
        label = " / ".join(group)
        rows[label] = row(*[crops[n] for n in group], size, seeds)
        print(*group, {k: round(v, 3) for k, v in rows[label].items()}, flush=True)
    md = f"{title}, seeds 0-{args.seeds - 1}, means (benchmarks/bench_material.py {flag})\n\n" + table(rows)
    write_results(name, [{key: k, **v, "size": args.size, "seeds": seeds} for k, v in rows.items()], md)
    print(md)


def painted_main(args):
    if len(args.textures) % 2:
        raise SystemExit("--painted takes the textures in pairs (A B C D: A beside B, C beside D)")
    table_main(args, "--painted", list(zip(args.textures[::2], args.textures[1::2])), painted_row, painted_table,
               "material_painted", "pair",
               f"Painted materials' albedos patch-refined (0.60): each region's albedo SIFID against its own "
               f"{args.crop}x{args.crop} crop, A left and B right of {args.size}x{args.size}")


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("textures", nargs="+")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--crop", type=int, default=256, help="exemplar crop side (0: whole)")
    ap.add_argument("--sifid", action="store_true", help="also the albedo's SIFID (needs the metrics extra)")
    ap.add_argument("--albedo-refine", action="store_true",
                    help="the albedo's patch refinement (0.59) against 0.58's material and the plain texture: "
                         "SIFID (needs the metrics extra), seeds 0 to --seeds - 1")
    ap.add_argument("--painted", action="store_true",
                    help="the albedo's patch refinement of materials painted half and half (0.60), the textures in "
                         "pairs: each region's SIFID (needs the metrics extra), seeds 0 to --seeds - 1")
    return ap.parse_args(argv)


def albedo_refine_main(args):
    table_main(args, "--albedo-refine", [(name,) for name in args.textures], albedo_refine_row, albedo_refine_table,
               "material_albedo", "texture", f"The material albedo's patch refinement (0.59): albedo SIFID against the "
               f"{args.crop}x{args.crop} crop, {args.size}x{args.size}")


def main():
    from tghop import TGHop
    from tghop.imageio import save_image
    from tghop.material import Material, example_maps

    args = parse_args()
    if args.albedo_refine:
        return albedo_refine_main(args)
    if args.painted:
        return painted_main(args)
    size = (args.size, args.size)
    rows, payload, sheet = [], [], None
    for name in args.textures:
        ex = texture(name)
        if args.crop:
            ex = ex[: args.crop, : args.crop]
        maps = example_maps(ex)
        maps["height"] = np.round(maps["height"] * 65535).astype(np.uint16)  # a 16-bit map
        t = time.perf_counter()
        mat = Material(rng=0).fit(ex, maps)
        fit_s = time.perf_counter() - t
        exemplar = {"albedo": ex, **{k: np.asarray(v, dtype=np.float64) / (65535.0 if v.dtype == np.uint16 else 1.0)
                                     for k, v in maps.items()}}
        target = cross_correlations(exemplar)
        ways = {"joint": lambda s: mat.synthesize(size, rng=s),
                "joint, albedo refined only": lambda s: mat.synthesize(size, rng=s, refine_maps=False),
                "joint, unrefined": lambda s: mat.synthesize(size, rng=s, refine=0),
                "albedo decides": lambda s: albedo_decides(mat).synthesize(size, rng=s),
                "one model per map": lambda s: per_map(exemplar, size, s, {})}
        for way, make in ways.items():
            corrs, times, sifids = [], [], []
            for seed in range(args.seeds):
                t = time.perf_counter()
                out = make(seed)
                times.append(time.perf_counter() - t)
                corrs.append(cross_correlations(out))
                if args.sifid:
                    from tghop.metrics import sifid

                    sifids.append(float(sifid(out["albedo"], ex)))
                if sheet is None and way == "joint":
                    sheet = image_sheet([exemplar[k] for k in exemplar] + [out[k] for k in out],
                                        [f"exemplar {k}" for k in exemplar] + [f"output {k}" for k in out])
            mean = {k: float(np.mean([c[k] for c in corrs])) for k in PAIRS + EXTRA}
            rel = {k: abs(mean[k] - target[k]) / abs(target[k]) for k in PAIRS + EXTRA}
            worst = max(PAIRS, key=rel.get)
            row = [name, way] + [f"{target[k]:+.2f} / {mean[k]:+.2f}" for k in PAIRS + EXTRA] + [
                f"{100 * rel[worst]:.1f}% ({worst})", f"{np.mean(sifids):.3f}" if sifids else "-",
                f"{fit_s:.1f}" if way.startswith("joint") or way == "albedo decides" else "- (in synth s)",
                f"{np.mean(times):.2f}"]
            rows.append(row)
            payload.append({"texture": name, "way": way, "exemplar": target, "output_mean": mean,
                            "relative_difference": rel, "worst": rel[worst], "sifid_albedo": sifids,
                            "fit_s": fit_s if way != "one model per map" else None, "synth_s": times,
                            "size": args.size, "seeds": args.seeds})
            print(" | ".join(str(v) for v in row), flush=True)
    header = ["texture", "way"] + [f"{k} (ex / out)" for k in PAIRS + EXTRA] + ["worst rel. diff", "SIFID albedo",
                                                                        "fit s", "synth s"]
    md = (f"Cross-correlations of a material's maps, exemplar / output mean of {args.seeds} seeds, "
          f"{args.size}x{args.size} (benchmarks/bench_material.py)\n\n" + markdown_table(header, rows))
    write_results("material", payload, md)
    if sheet is not None:
        RESULTS.mkdir(parents=True, exist_ok=True)
        save_image(sheet, RESULTS / "material_sheet.png")
    print(md)


if __name__ == "__main__":
    main()
