"""``tghop fit``, ``synth``, ``patches``, ``clusters`` and ``info``: TGHop models and the textures they make."""

from __future__ import annotations

import json
import os
import re
import time
from pathlib import Path

import click

from .._errors import TGHopError
from .._formats import OUTPUT_HELP, model_file_kind
from ..fit_options import build_model
from .help_sections import COMMON, SectionedCommand
from .lines import say
from .common import (HINT_DOWNSCALE_OPTION, Progress, check_model_output, check_output, check_outputs, check_stdout,
                     is_builtin, is_model_file, load_exemplar, load_mask, map_names, count_outputs, quiet_tifffile,
                     refuse_albedo_as_map, refuse_colour_map_out_of_place, read_image, summary,
                     draw_seed, tell_steps, tell_seed, user_errors, warn_written_with_8, write_materials, examples,
                     stage_paths, MATERIAL_STAGES, save_with_stages)
from .guided import BLOB_HELP, DEFAULT_TRANSITION, GUIDE_HELP, MAX_TRANSITION, TRANSITION_HELP
from .options import (DOWNSCALE_HELP, EXCLUDE_HELP, FIT_OPTION_PARAMS, MAX_COUNT, QUIET_OPTION, Size,
                      depth_option, generation_options, generation_params, given_options, model_options,
                      refuse_patch_refine_of_saved, refuse_patch_refine_without_statistics, refuse_split_size)

__all__ = ["fit", "synth", "patches", "clusters", "info"]


def fit_exemplar(spec, options, *, exclude, downscale, progress, deep_warning=None, output=None, depth=None):
    """A TGHop fitted on exemplar ``spec`` (a file or builtin:NAME) with the fit options,
    leaving out the white pixels of the ``--exclude`` mask (``fit`` and ``synth``); with
    ``deep_warning`` (a label), a warning when the exemplar has more than 8 bits a channel (written to
    ``output``). With ``output`` and ``depth`` (synth's), an image of the exemplar's channels that
    ``output`` cannot take at ``depth`` is refused before the fit (:func:`tghop.imageio.check_depth`).
    The model records the exemplar's bits per channel (``exemplar_depth_``: its file keeps them)."""
    from ..imageio import check_depth
    from ..synthesis import prepare_exemplar

    started = time.monotonic()  # stage "reading": the exemplar read (a built-in one drawn) and its mask
    raw, bits = load_exemplar(spec, downscale=downscale, dtype=None, has_downscale=True, with_depth=True)
    if deep_warning and not is_builtin(spec) and raw.dtype.name != "uint8":  # 16-bit or float: floats
        warn_written_with_8(deep_warning, spec, output)
    image = prepare_exemplar(raw)
    if output is not None and depth is not None:
        check_depth(output, depth, channels=image.shape[2])
    model = build_model(options, n_colours=image.shape[2])
    model.check_exemplar_size(image.shape)  # before the mask is read
    mask = None if exclude is None else load_mask(exclude, image.shape, label="--exclude", image_label="the exemplar",
                                                    what="part left out")
    progress.took("reading", started)
    return model.fit(image, exclude=mask, depth=bits, progress=progress)


def fit_material(spec, map_paths, options, *, exclude, downscale, progress):
    """A :class:`tghop.material.Material` fitted on exemplar ``spec`` (the albedo) and the
    maps in ``map_paths`` (named by their file stems)."""
    from ..material import Material
    from ..material_files import read_map
    from ..synthesis import TGHop
    from ..fit_options import fit_params

    refuse_albedo_as_map(map_paths, spec, label="--maps", albedo="EXEMPLAR")
    names = map_names(map_paths, label="--maps", albedo="EXEMPLAR")
    refuse_colour_map_out_of_place(spec, map_paths, label="--maps", albedo="EXEMPLAR")
    started = time.monotonic()  # stage "reading": every map read
    if is_builtin(spec):
        albedo, depth = load_exemplar(spec, dtype=None), 8
    elif is_model_file(spec):
        raise TGHopError(f"EXEMPLAR {spec} is {model_file_kind(spec)}, not an image; give the material's colour map "
                         "(albedo) image first, its other maps after --maps")
    else:  # the albedo's alpha is transparency (warned of, as for a texture)
        albedo, depth = read_image(spec, dtype=None, downscale=downscale, with_depth=True,
                                   too_large_hint=HINT_DOWNSCALE_OPTION)
    quiet_tifffile()
    maps, depths = {}, {"albedo": depth}
    for path, name in zip(map_paths, names):
        maps[name], depths[name] = read_map(path, name, label=f"--maps {path}", downscale=downscale,
                                            too_large_hint=HINT_DOWNSCALE_OPTION)
        if maps[name].shape[:2] != albedo.shape[:2]:  # said here with the files, and the resolutions they are named
            (h, w), (ah, aw) = maps[name].shape[:2], albedo.shape[:2]
            said, own = _resolution_word(path), _resolution_word(spec)
            hint = f" (named {said}, EXEMPLAR {own}: take every map from one download)" if said and own and \
                said != own else ""
            raise TGHopError(f"--maps {path} is {h}x{w} but EXEMPLAR {spec} is {ah}x{aw}{hint}; give every map at "
                             "the albedo's size")
    mask = None if exclude is None else load_mask(exclude, albedo.shape, label="--exclude", image_label="the exemplar",
                                                    what="part left out")
    progress.took("reading", started)
    params = fit_params(options)
    material = Material(model=TGHop(**params), rng=params["rng"]).fit(albedo, maps, exclude=mask, depths=depths,
                                                                      progress=progress)
    return material


def _resolution_word(path):
    """The resolution a material's file is named with (``Rock023_2K_Color.jpg``: ``2K``; ``rock-1024.png``:
    ``1024``), upper case, or None."""
    words = re.findall(r"[a-z0-9]+", os.path.basename(str(path)).rsplit(".", 1)[0].lower())
    found = [w for w in words if re.fullmatch(r"\d{1,2}k|\d{3,5}", w)]
    return found[-1].upper() if found else None


@click.command(short_help='Learn a model from an exemplar and save it (.npz) to reuse', epilog=examples(
    "# learn the built-in bricks exemplar's model once; synth, info ... reuse it",
    "tghop fit builtin:bricks -o bricks.npz",
    "# your own image with the paper's settings (Table 4)",
    "tghop fit texture.jpg -o paper.npz --paper",
    "# a whole material: the colour map first, then its maps, kept aligned",
    "tghop fit albedo.png --maps normal.png roughness.png -o mat.npz"), cls=SectionedCommand, common=COMMON["fit"])
@click.argument("exemplar")
@click.argument("map_paths", metavar="[MAP]...", nargs=-1)
@click.option("-o", "--output", required=True, help="Model file to write (NAME.npz).")
@click.option("--maps", "with_maps", is_flag=True,
              help="Fit a whole material: the images after EXEMPLAR (the albedo) are its maps, of its size "
                   "(normal, roughness, height, ...: any depth, 1 or 3 channels; _MaskMap, _Metallic, _ORM keep an "
                   "alpha that holds data), each named by its file stem; "
                   "a map named *normal* or *nrm*, or ending in _nor_gl, _nor_dx or _N, is a normal map (unit "
                   "vectors, kept so, in its own convention: DirectX stays DirectX). The colour map comes first.")
@model_options
@click.option("--exclude", metavar="MASK", default=None, help=EXCLUDE_HELP)
@click.option("--downscale", is_flag=True, help=DOWNSCALE_HELP)
@QUIET_OPTION
def fit(exemplar, map_paths, output, with_maps, exclude, downscale, quiet, **options):
    """Learn a model from EXEMPLAR (an image file or builtin:NAME) and save it; with
    --maps, a material from EXEMPLAR and its MAPs."""
    progress = Progress(not quiet)
    with user_errors(progress):
        from ..modelfile import save_model

        if map_paths and not with_maps:
            raise click.UsageError(f"more than one EXEMPLAR ({map_paths[0]}, ...); to fit a material give its maps "
                                   "after --maps, e.g. tghop fit albedo.png --maps normal.png height.png -o mat.npz")
        if with_maps and not map_paths:
            raise click.UsageError("--maps without maps; give the map images after it")
        check_model_output(output, "-o")  # before any work
        check_outputs([("-o", output)], [("EXEMPLAR", exemplar), ("--exclude", exclude)]
                      + [("--maps", m) for m in map_paths])
        if with_maps:
            material = fit_material(exemplar, map_paths, options, exclude=exclude, downscale=downscale,
                                    progress=progress)
            model = material.model_
        else:
            model = material = fit_exemplar(exemplar, options, exclude=exclude, downscale=downscale,
                                            progress=progress)
        started = time.monotonic()
        save_model(material, output)
        progress.took("saving", started)
        progress.close()
    if with_maps:
        say(f"material: {material_summary(material)}")
    say(*summary(model).split("\n"))
    say(f"{'material' if with_maps else 'model'} written to {output}")


def material_summary(material) -> str:
    """The maps of ``material``, one line, each normal map with the convention it comes out in
    (:attr:`tghop.material.Material.conventions_`: its content's, else its name's)."""
    from ..map_names import normal_convention

    kept = getattr(material, "conventions_", None) or [None] * len(material.names_)

    def normal(name, is_normal, seen):  # the convention is the output's too: tghop keeps it
        named = normal_convention(name)
        if seen and named and seen != named:  # what comes out, as fit's warning says (0.59 said the name's here)
            said = f", {seen} by its content (its name says {named}), kept"
        else:
            said = f", {named} convention kept" if named else f", {seen} by its content, kept" if seen else ""
        return ", normal map" + said if is_normal else ""

    return ", ".join(f"{n} ({c} channel{'s' if c > 1 else ''}, {d}-bit{normal(n, nm, cv)})"
                     for n, c, d, nm, cv in zip(material.names_, material.map_channels_, material.depths_,
                                                material.normal_, kept))


@click.command(short_help='Write a grid of patches generated from a saved model', epilog=examples(
    "# 64 generated patches in a grid, and the paper's Fig. 6 views of them",
    "tghop patches bricks.npz -n 64 -o patches.png --stages"))
@click.argument("model_file", metavar="MODEL")
@click.option("-n", "--count", "n", type=click.IntRange(min=1, max=10000), default=64, show_default=True,
              help="Patches to generate.")
@click.option("-o", "--output", required=True, help=f"Grid i{OUTPUT_HELP[1:]}; - for PNG on stdout).")
@click.option("--seed", type=click.IntRange(min=0), default=None, help="Seed (same seed, same patches).")
@click.option("--stages", is_flag=True,
              help="Also write OUTPUT_stages: per sample the core DC map, the S1 DC map (64x64 patches: S2's "
                   "between them) and the patch (paper Fig. 6).")
@QUIET_OPTION
def patches(model_file, n, output, seed, stages, quiet):
    """Generate N patches from a saved MODEL and write them as a grid image."""
    del quiet  # taken as every command takes it: nothing here draws a progress bar
    from ..imageio import save_image
    from ..modelfile import load_model
    from ..patches import patch_grid, stage_sheet

    with user_errors():
        if stages and output == "-":
            raise click.UsageError("--stages needs a file name: it writes OUTPUT_stages next to -o's image, "
                                   "so give -o a file name (e.g. -o patches.png) or drop --stages")
        check_output(output, allow_stdout=True)
        stage_path = None
        if stages:  # checked with the grid, before anything is generated or written
            path = Path(output)
            stage_path = str(path.with_name(f"{path.stem}_stages{path.suffix}"))
            check_output(stage_path, made=True)
        check_outputs([("-o", output), ("--stages", stage_path)], [("MODEL", model_file)])
        model = load_model(model_file)
        if stages:
            samples, views = model.sample_patches(n, rng=seed, return_stages=True)
        else:
            samples = model.sample_patches(n, rng=seed)
        if stages:  # the grid and its views: both or neither (0.62)
            save_with_stages(patch_grid(samples), output, 8, {"stages": stage_sheet(views, model.patch_size)},
                             {"stages": stage_path})
        else:
            save_image(patch_grid(samples), output)
    if output != "-":  # the output first, then its views, as every command says its steps (0.63; 0.62: views first)
        say(f"{n} patch{'es' if n != 1 else ''} written to {output}")
    if stage_path:
        say(f"stage views written beside it: {Path(stage_path).name}")


@click.command(short_help="Map which of a model's clusters each part of an exemplar falls in", epilog=examples(
    "# the bricks exemplar beside its map of the model's clusters",
    "tghop clusters bricks.npz builtin:bricks -o clusters.png"))
@click.argument("model_file", metavar="MODEL")
@click.argument("exemplar")
@click.option("-o", "--output", required=True,
              help=f"I{OUTPUT_HELP[1:]}): EXEMPLAR on the left, its cluster map on the right.")
@click.option("--stride", type=click.IntRange(min=1, max=4096), default=None,
              help="Step between the patches mapped, in pixels; default the model's fit stride.")
@QUIET_OPTION
def clusters(model_file, exemplar, output, stride, quiet):
    """Show which of MODEL's clusters each part of EXEMPLAR (an image file or builtin:NAME,
    with the model's channel count) falls in: the cluster of the patch centred nearest each
    pixel, one colour per cluster, beside the exemplar (resampled by the model's --scale, as
    the model saw it)."""
    import numpy as np

    from ..explain import cluster_image, cluster_map
    from ..imageio import save_image
    from ..modelfile import load_model
    from ..scale import rescale

    progress = Progress(not quiet)
    with user_errors(progress):
        check_output(output)
        check_outputs([("-o", output)], [("MODEL", model_file), ("EXEMPLAR", exemplar)])
        model = load_model(model_file)  # a material: one line, fit a plain model from its albedo
        image = rescale(load_exemplar(exemplar), model.scale)
        labels = cluster_map(model, image, stride=stride, progress=progress)
        progress.close()
        painted = cluster_image(labels, model.patch_size, stride or model.stride, image.shape)
        left = np.repeat(image, 3, axis=2) if image.shape[2] == 1 else image
        save_image(np.concatenate([left, painted], axis=1), output)
        used, total = len(np.unique(labels)), len(model.ichm_.means_)
    say(f"{used} cluster{'s' if used != 1 else ''} used of {total}; map written to {output}")


@click.command(short_help='Make texture images from an image, builtin:NAME or saved model(s)', epilog=examples(
    "# a 512x512 texture of the built-in bricks exemplar; same seed, same image",
    "tghop synth builtin:bricks -o bricks.png --size 512x512 --seed 1",
    "# 2 images from a saved model, 256 high and 512 wide: out_1.png, out_2.png",
    "tghop synth bricks.npz -o out.png --size 256x512 --count 2 --seed 7",
    "# your own image: a seamless tile, its model kept to make more",
    "tghop synth texture.jpg -o tile.png --tile --save-model texture.npz",
    "# two textures painted by map.png: one grey level each, the darkest first",
    "tghop synth bricks.npz texture.npz --guide map.png -o painted.png"), cls=SectionedCommand, common=COMMON["synth"])
@click.argument("sources", nargs=-1, required=True, metavar="SOURCE...")
@click.option("-o", "--output", required=True,
              help=f"{OUTPUT_HELP}); with --count > 1 numbered name_1.png, ...; - writes PNG "
                   "to stdout.")
@click.option("--size", type=Size(), default="256x256", show_default=True,
              help="Output HEIGHTxWIDTH, height first (1024x768 is 768 pixels wide), or one number for a square. "
                   "At most 8192x8192 pixels in all (4096x16384 too). Cost on 2 cores (0.39; 8192x8192: 0.14): "
                   "about 0.8 s and 0.2 GB at 256x256, 3.8 s and 0.6 GB at 2048x2048, 2.7 minutes and 4.3 GB at "
                   "8192x8192.")
@click.option("--count", type=click.IntRange(min=1, max=MAX_COUNT), default=1, show_default=True,
              help="Number of images, drawn one after another from --seed's stream: image k is the same in any "
                   "--count of k or more with that seed (--count 2 --seed 5's name_2.png is --count 3's).")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed of generation: the same seed gives the same image; without it every run differs (the seed "
                   "drawn is said after it, to make the image again).")
@click.option("--save-model", type=click.Path(dir_okay=False), default=None,
              help="When SOURCE is an image, also save the fitted model here (NAME.npz).")
@click.option("--guide", metavar="MAP", default=None, help=GUIDE_HELP)
@click.option("--transition", type=click.IntRange(min=0, max=MAX_TRANSITION), default=DEFAULT_TRANSITION,
              show_default=True, help=TRANSITION_HELP)
@click.option("--blob", type=click.IntRange(min=1, max=MAX_TRANSITION), default=None, metavar="PX", help=BLOB_HELP)
@depth_option("8; a material's maps: each at its file's depth, as far as the format holds it")
@generation_options
@model_options
@click.option("--exclude", metavar="MASK", default=None, help=EXCLUDE_HELP)
@click.option("--downscale", is_flag=True, help=DOWNSCALE_HELP)
@click.option("--stages", is_flag=True,
              help="Also write each step's image beside OUTPUT, at its depth: OUTPUT_guide (the coarse layout's), "
                   "_quilt, _seams, _refine, then _patch-refine or _colour (the last step's: the image itself; "
                   "a two-level exemplar's: then _levels, snapped to them). A material's (0.61): each step's maps "
                   "(OUTPUT_guide, OUTPUT_guide_<map>, where it has a layout, OUTPUT_quilt, OUTPUT_quilt_<map>, ...), "
                   "_colour after _patch-refine, its last _maps (the maps written). Several SOURCEs or "
                   "--guide (0.61): _regions (the labels as grey levels), each layer's own steps (0.62: "
                   "_layer1_quilt, ..., _layer2_quilt, ...: layer i is the i-th SOURCE, one given twice one layer; "
                   "black outside the box it was made over), _layers (each region its own texture) and _join (the "
                   "image).")
@QUIET_OPTION
@click.option("--maps", "maps_given", is_flag=True, hidden=True)  # fit's: said so (click offered --gamma, --paper)
@click.pass_context
def synth(ctx, sources, output, size, count, seed, save_model, guide, transition, blob, exclude, downscale, stages,
          quiet, depth, maps_given, **options):
    """Synthesize texture images from SOURCE: an exemplar image, builtin:NAME, or a saved model.

    Several SOURCEs make one image: with --guide MAP each painted region is one SOURCE's
    texture; without it, random regions of each (a remix). A saved material (tghop fit
    EXEMPLAR --maps ...) writes OUTPUT and OUTPUT_<map> for each of its maps, aligned (the
    material's name and resolution its maps' names share dropped: Rock023_2K_NormalGL as
    OUTPUT_NormalGL); several materials with the same maps (by their kinds: Stone_NormalGL and
    gravel_nor_gl_2k are both a normal map; else by those names) are painted or remixed alike.
    """
    from ..imageio import check_depth

    progress = Progress(not quiet)
    seed, drawn = draw_seed(seed)
    with user_errors(progress):
        refuse_split_size(ctx, sources[1:])  # --size 512 512: before any work (0.63)
        if maps_given:
            raise click.UsageError("synth takes no --maps: fit the material first ('tghop fit ALBEDO --maps MAP... "
                                   "-o MAT.npz'), then 'tghop synth MAT.npz -o OUT' writes OUT and OUT_<map> for "
                                   "each map")
        # The files written are checked (0.61): with --count above 1 the numbered ones, not -o's own name (a
        # folder named out.png refused out_1.png, out_2.png), as inpaint and extend check them; -o - refused.
        first = count_outputs(output, count)[0]
        check_output(first, allow_stdout=True, depth=depth, made=first != output)
        check_depth(first, depth or 8)
        if stages and output == "-":  # several SOURCEs' steps are OUTPUT_regions, _layers, _join (0.61)
            first_step = "OUTPUT_regions" if len(sources) > 1 or guide is not None else "OUTPUT_quilt"
            raise click.UsageError(f"--stages needs a file name: it writes {first_step} and the others next to -o's "
                                   "image, so give -o a file name (e.g. -o out.png) or drop --stages")
        if blob is not None and (len(sources) < 2 or guide is not None):
            raise click.UsageError("--blob sizes a remix's regions (several SOURCEs without --guide); drop it")
        if len(sources) > 1 or guide is not None:
            from .guided import synth_several

            outputs, size, steps = synth_several(ctx, sources, output, size, count, seed, guide, transition,
                                                 save_model, exclude, downscale, progress, generation_params(options),
                                                 options, depth, stages=stages, blob=blob)
            if outputs is None:  # materials: it said what it wrote
                tell_seed(seed, drawn, "the same material" if count == 1 else "the same materials")
                return
            from_model = True  # nothing saved
        elif given_options(ctx, ["transition"]):
            raise click.UsageError("--transition applies to several SOURCEs or --guide; drop it")
        else:
            outputs, from_model, steps = _synth_one(ctx, sources[0], output, size, count, seed, save_model,
                                                    exclude, downscale, progress, options, depth, stages)
            if outputs is None:  # a material: it said what it wrote
                tell_seed(seed, drawn, "the same material" if count == 1 else "the same materials")
                return
    if output != "-":
        where = outputs[0] if count == 1 else f"{outputs[0]} ... {outputs[-1]}"
        say(f"{count} image{'s' if count > 1 else ''} of {size[0]}x{size[1]} written to {where}")
        if save_model is not None and not from_model:
            say(f"model written to {save_model}")
        tell_steps(steps, count)  # after the output, as for materials (0.62)
    tell_seed(seed, drawn, "the same image" if count == 1 else "the same images")


def _synth_one(ctx, source, output, size, count, seed, save_model, exclude, downscale, progress, options, depth,
               stages=False):
    """``tghop synth`` from one SOURCE (inside the command's user_errors): the outputs
    written (None for a material, which says what it wrote), whether SOURCE was a saved model and --stages' files
    written beside the first."""
    from ..imageio import check_depth, generation_dtype, save_image
    from ..modelfile import load_model, save_model as write_model
    from ..settings import BY_NAME

    # A .npz SOURCE is read as a model whatever its bytes ("not a tghop model file", not
    # "not a readable image"); other names as a model when they start like one.
    from_model = not is_builtin(source) and (source.lower().endswith(".npz") or is_model_file(source))
    if from_model:
        fit_only = ([s.name for s in BY_NAME.values() if s.when == "fit"] + list(FIT_OPTION_PARAMS)
                    + ["save_model", "downscale"])
        refused = given_options(ctx, fit_only)
        if refused:
            several = len(refused) > 1
            raise click.UsageError(f"{', '.join(refused)}: fitting option{'s' if several else ''} but SOURCE is a "
                                   f"saved model; refit with 'tghop fit' or drop {'them' if several else 'it'}")
    generation = generation_params(options)
    # Every output checked before the fit and before the first image is written.
    outputs = count_outputs(output, count)
    staged = [stage_paths(path) for path in outputs] if stages else []
    if count > 1:
        for path in outputs:
            check_output(path, made=True)
    for path in (p for paths in staged for p in paths.values()):
        check_output(path, made=True)
    if save_model is not None and not from_model:
        check_model_output(save_model, "--save-model")
    check_outputs([("-o", path) for path in outputs] + [("--stages", p) for paths in staged for p in paths.values()]
                  + [("--save-model", save_model)], [("SOURCE", source), ("--exclude", exclude)])
    if from_model:
        model = load_model(source, material=True)
        if hasattr(model, "names_"):  # a whole material: every map, written together
            stride = given_options(ctx, ["patch_stride"])  # would be ignored without the albedo's patch statistics
            # refused here by the options typed, not the library's keyword: a material fitted by 0.58 or with
            # --patch-levels 0 (0.59 patch-refines a material's albedo)
            if (generation["patch_refine"] or stride) and model.albedo_patches() is None:
                refuse_patch_refine_of_saved(ctx, "this material", material=True)
            _synth_material(model, output, outputs, size, depth, rng=seed, progress=progress, generation=generation,
                            source=source, stages=stages)
            return None, True, []
        check_depth(output, depth or 8, channels=model.exemplar_shape_[2])
        if not depth and (getattr(model, "exemplar_depth_", None) or 8) > 8:  # as from the exemplar (fit_exemplar)
            warn_written_with_8("the exemplar of SOURCE", source, output)
        if generation["patch_refine"] and model.patches_ is None:
            refuse_patch_refine_of_saved(ctx, "this model", material=False)
    else:
        from ..quilting import block_count

        # The output's blocks at the fit's patch size, before the fit: a --size or --overlap
        # that quilting refuses is refused at once, not after the fit.
        planned = build_model(dict(options))
        block_count(size, planned.patch_size, overlap=generation["overlap"], tile=generation["tile"])
        refuse_patch_refine_without_statistics(ctx, generation, planned)
        model = fit_exemplar(source, options, exclude=exclude, downscale=downscale, progress=progress,
                             deep_warning=None if depth else "SOURCE", output=output, depth=depth or 8)
        if save_model is not None:
            write_model(model, save_model)
    import warnings

    if (given_options(ctx, ["own_shares"]) and generation["own_shares"] != BY_NAME["own_shares"].default
            and getattr(model, "classes_", None) is None):
        warnings.warn(f"--own-shares {generation['own_shares']:g} has no effect: the model has no colour classes "
                      "(fitted with --colour-classes 0); fit it with --colour-classes above 0, or drop --own-shares")
    unused = given_options(ctx, ["layout_weight", "layout_refine", "layout_patch_refine"])
    if unused and getattr(model, "layout_", None) is None:
        warnings.warn(f"{', '.join(unused)} {'has' if len(unused) == 1 else 'have'} no effect: the model has no "
                      "coarse layout (fitted with --layout none); fit it with a layout factor, or drop "
                      f"{'it' if len(unused) == 1 else 'them'}")
    import numpy as np

    rng = np.random.default_rng(seed)
    for i, path in enumerate(outputs):
        # 8-bit straight from the colour matching: no float64 image (1.6 GB at 8192x8192).
        image = model.synthesize(size, rng=rng, progress=progress, return_stages=stages,
                                 dtype=generation_dtype(depth), **generation)
        progress.close()
        if stages:  # the images (not the patch pool, 0.58) and the result: all or none (0.62)
            image, steps = image
            save_with_stages(image, path, depth or 8, steps, staged[i], progress=progress)
        else:
            save_image(image, path, depth=depth or 8, progress=progress)
        progress.close()
    return outputs, from_model, [p for p in staged[0].values() if Path(p).exists()] if stages else []


def _synth_material(material, output, outputs, size, depth, *, rng, progress, generation, source, stages=False):
    """``synth`` from a material: OUT, OUT_<suffix>, ... for each image (:func:`~tghop.cli.common.write_materials`);
    with ``stages`` each step's maps too (0.61)."""
    import numpy as np

    rng = np.random.default_rng(rng)

    def make():
        maps = material.synthesize(size, rng=rng, progress=progress, dtype=np.float32, return_stages=stages,
                                   **generation)
        progress.close()
        return maps

    write_materials(material, output, outputs, size, depth, make, [("SOURCE", source)], progress, stages=stages)
    if stages:
        tell_steps([p for p in stage_paths(outputs[0], MATERIAL_STAGES).values() if Path(p).exists()], len(outputs),
                   maps=True)


@click.command(short_help='Describe a saved model: settings, dimensions, parameter count', epilog=examples(
    "tghop info bricks.npz",
    "tghop info bricks.npz --json"))
@click.argument("model_file", metavar="MODEL")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def info(model_file, as_json):
    """Describe a saved MODEL: settings, dimensions and parameter count (paper Table 4)."""
    from ..modelfile import info_dict, load_model

    with user_errors():
        check_stdout("the model's description" + (" (JSON)" if as_json else ""))
        material = load_model(model_file, material=True)
        model = getattr(material, "model_", material)
        params = model.n_parameters()
    if as_json:
        out = info_dict(model, params)
        if material is not model:
            out["material"] = {"maps": material.map_info(), **_mask_levels(material, as_json=True),
                               "conventions": {n: c for n, c in zip(material.names_, material.conventions_) if c}}
        click.echo(json.dumps(out, indent=2, default=str, allow_nan=False))
        return
    h, w, c = model.exemplar_shape_
    say(f"tghop model {model_file}", err=False)
    if material is not model:
        say(f"material: {material_summary(material)}", err=False)
        for line in _mask_levels(material):
            say(line, err=False)
    scaled = "" if model.scale == 1 else f" (resampled by --scale {model.scale:g})"
    bits = getattr(model, "exemplar_depth_", None)
    bits = "" if bits is None else ", float" if bits == 32 else f", {bits}-bit"
    say(f"exemplar: {h}x{w}{scaled}, {c} channel{'s' if c > 1 else ''}{bits}; {model.n_patches_:,} training "
        f"patches of {model.patch_size}x{model.patch_size} at stride {model.stride}", err=False)
    levels = getattr(model, "exemplar_levels_", None)
    if levels is not None:  # a two-level exemplar (line art, a 1-bit file): its images hold these two only
        low, high = (f"{v[0]:.4g}" if len(v) == 1 else "(" + ", ".join(f"{x:.4g}" for x in v) + ")" for v in levels)
        say(f"exemplar levels: two only, {low} and {high} (its images are snapped to them)", err=False)
    seed = info_dict(model, params)["fit_seed"]
    say(f"fit seed: {seed}" if seed is not None else
        "fit seed: not recorded (fitted with a Generator, or by tghop 0.32 or older)", err=False)
    say(*summary(model, params).split("\n"), err=False)
    say("", "parameters (paper Table 4):", err=False)
    rows = [("module", "formula", "paper formula", "stored")] + [
        (name, row["formula"], f"{row['paper']:,}", f"{row['stored']:,}") for name, row in params.items()]
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    for r in rows:
        say(f"  {r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]:>{widths[2]}}  {r[3]:>{widths[3]}}", err=False)


def _mask_levels(material, as_json=False):
    """A material's mask levels (0.57; 0.56's ``tghop info`` showed none): each mask map's pixel values
    (``levels_``) and each packed map's mask channels' (``channel_levels_``), to which its images are snapped;
    as text lines, or (``as_json``) the model file's "levels" and "channel_levels" where there are any."""
    levels = {n: lv for n, lv in zip(material.names_, material.levels_) if lv is not None}
    packed = {n: lv for n, lv in zip(material.names_, material.channel_levels_) if lv is not None}
    if as_json:
        return {**({"levels": {n: lv.tolist() for n, lv in levels.items()}} if levels else {}),
                **({"channel_levels": {n: [None if c is None else c.tolist() for c in lv] for n, lv in packed.items()}}
                   if packed else {})}

    def values(rows):
        return ", ".join(f"{v[0]:.4g}" if len(v) == 1 else "(" + ", ".join(f"{x:.4g}" for x in v) + ")" for v in rows)

    lines = [f"mask levels of {n}: {values(lv)} (its images are snapped to them)" for n, lv in levels.items()]
    for n, lv in packed.items():
        lines += [f"mask levels of {n}, channel {i + 1}: {values([[x] for x in c])} (snapped to them)"
                  for i, c in enumerate(lv) if c is not None]
    return lines
