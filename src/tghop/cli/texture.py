"""``tghop fit``, ``synth``, ``patches`` and ``info``: TGHop models and the textures they make."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .._errors import TGHopError
from ..fit_options import build_model
from .common import (Progress, check_model_output, check_output, check_outputs, is_model_file,
                     load_exemplar, load_mask, numbered, summary, user_errors)
from .options import (DOWNSCALE_HELP, EXCLUDE_HELP, FIT_OPTION_PARAMS, MAX_COUNT, Size, depth_option,
                      generation_options, generation_params, given_options, model_options)

__all__ = ["fit", "synth", "patches", "info"]


def fit_exemplar(spec, options, *, exclude, downscale, progress):
    """A TGHop fitted on exemplar ``spec`` (a file or builtin:NAME) with the fit options,
    leaving out the white pixels of the ``--exclude`` mask (``fit`` and ``synth``)."""
    from ..synthesis import prepare_exemplar

    image = prepare_exemplar(load_exemplar(spec, downscale=downscale, dtype=None, has_downscale=True),
                             min_size=options.get("patch_size") or 32)
    mask = None if exclude is None else load_mask(exclude, image.shape, label="--exclude", image_label="the exemplar")
    model = build_model(options, n_colours=image.shape[2])
    return model.fit(image, exclude=mask, progress=progress)


@click.command()
@click.argument("exemplar")
@click.option("-o", "--output", required=True, help="Model file to write (NAME.npz).")
@model_options
@click.option("--exclude", metavar="MASK", default=None, help=EXCLUDE_HELP)
@click.option("--downscale", is_flag=True, help=DOWNSCALE_HELP)
@click.option("-q", "--quiet", is_flag=True, help="No progress bars.")
def fit(exemplar, output, exclude, downscale, quiet, **options):
    """Learn a model from EXEMPLAR (an image file or builtin:NAME) and save it."""
    progress = Progress(not quiet)
    with user_errors(progress):
        from ..modelfile import save_model

        check_model_output(output, "-o")  # before any work
        check_outputs([("-o", output)], [("EXEMPLAR", exemplar), ("--exclude", exclude)])
        model = fit_exemplar(exemplar, options, exclude=exclude, downscale=downscale, progress=progress)
        progress.close()
        save_model(model, output)
    click.echo(summary(model), err=True)
    click.echo(f"model written to {output}", err=True)


@click.command()
@click.argument("model_file", metavar="MODEL")
@click.option("-n", "--count", "n", type=click.IntRange(min=1, max=10000), default=64, show_default=True,
              help="Patches to generate.")
@click.option("-o", "--output", required=True, help="Grid image to write (.png or .jpg; - for stdout).")
@click.option("--seed", type=click.IntRange(min=0), default=None, help="Seed (same seed, same patches).")
@click.option("--stages", is_flag=True,
              help="Also write OUTPUT_stages: per sample the core DC map, the S1 DC map and the patch (paper Fig. 6).")
def patches(model_file, n, output, seed, stages):
    """Generate N patches from a saved MODEL and write them as a grid image."""
    from ..imageio import save_image
    from ..modelfile import load_model
    from ..patches import patch_grid, stage_sheet

    with user_errors():
        if stages and output == "-":
            raise TGHopError("--stages needs a file name: it writes OUTPUT_stages next to -o's image, "
                             "so give -o a file name (e.g. -o patches.png) or drop --stages")
        check_output(output, allow_stdout=True)
        stage_path = None
        if stages:  # checked with the grid, before anything is generated or written
            path = Path(output)
            stage_path = str(path.with_name(f"{path.stem}_stages{path.suffix}"))
            check_output(stage_path)
        check_outputs([("-o", output), ("--stages", stage_path)], [("MODEL", model_file)])
        model = load_model(model_file)
        if stages:
            samples, views = model.sample_patches(n, rng=seed, return_stages=True)
        else:
            samples = model.sample_patches(n, rng=seed)
        save_image(patch_grid(samples), output)
        if stages:
            save_image(stage_sheet(views, model.patch_size), stage_path)
            click.echo(f"stage views written to {stage_path}", err=True)
    if output != "-":
        click.echo(f"{n} patches written to {output}", err=True)


@click.command()
@click.argument("source")
@click.option("-o", "--output", required=True,
              help="Image to write (.png/.jpg); with --count > 1 numbered name_1.png, ...; - writes PNG to stdout.")
@click.option("--size", type=Size(), default="256x256", show_default=True,
              help="Output HEIGHTxWIDTH, height first (1024x768 is 768 pixels wide), or one number for a square. "
                   "At most 8192x8192. Cost on 2 cores: about 0.5 s and 0.2 GB at 256x256, 3.6 s and 0.6 GB "
                   "at 2048x2048, 2.7 minutes and 4.3 GB at 8192x8192.")
@click.option("--count", type=click.IntRange(min=1, max=MAX_COUNT), default=1, show_default=True,
              help="Number of images.")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed of generation: the same seed gives the same image; without it every run differs.")
@click.option("--save-model", type=click.Path(dir_okay=False), default=None,
              help="When SOURCE is an image, also save the fitted model here (NAME.npz).")
@depth_option
@generation_options
@model_options
@click.option("--exclude", metavar="MASK", default=None, help=EXCLUDE_HELP)
@click.option("--downscale", is_flag=True, help=DOWNSCALE_HELP)
@click.option("-q", "--quiet", is_flag=True, help="No progress bars.")
@click.pass_context
def synth(ctx, source, output, size, count, seed, save_model, exclude, downscale, quiet, depth, **options):
    """Synthesize texture images from SOURCE: an exemplar image, builtin:NAME, or a saved model."""
    from ..imageio import check_depth, save_image
    from ..modelfile import load_model, save_model as write_model
    from ..settings import BY_NAME

    progress = Progress(not quiet)
    with user_errors(progress):
        check_output(output, allow_stdout=True)
        check_depth(output, depth or 8)
        if output == "-" and count > 1:
            raise TGHopError("--count > 1 cannot write to stdout; give a file name with -o")
        # A .npz SOURCE is read as a model whatever its bytes ("not a tghop model file", not
        # "not a readable image"); other names as a model when they start like one.
        from_model = not source.startswith("builtin:") and (source.lower().endswith(".npz") or is_model_file(source))
        if from_model:
            fit_only = ([s.name for s in BY_NAME.values() if s.when == "fit"] + list(FIT_OPTION_PARAMS)
                        + ["save_model", "downscale"])
            refused = given_options(ctx, fit_only)
            if refused:
                raise TGHopError(f"{', '.join(refused)}: fitting option{'s' if len(refused) > 1 else ''} but SOURCE "
                                 f"is a saved model; refit with 'tghop fit' or drop {'them' if len(refused) > 1 else 'it'}")
        generation = generation_params(options)
        # Every output checked before the fit and before the first image is written.
        outputs = [output] if count == 1 else numbered(output, count)
        if count > 1:
            for path in outputs:
                check_output(path)
        if save_model and not from_model:
            check_model_output(save_model, "--save-model")
        check_outputs([("-o", path) for path in outputs] + [("--save-model", save_model)],
                      [("SOURCE", source), ("--exclude", exclude)])
        if from_model:
            model = load_model(source)
        else:
            model = fit_exemplar(source, options, exclude=exclude, downscale=downscale, progress=progress)
            if save_model:
                write_model(model, save_model)
        import numpy as np

        rng = np.random.default_rng(seed)
        for path in outputs:
            # 8-bit straight from the colour matching: no float64 image (1.6 GB at 8192x8192).
            image = model.synthesize(size, rng=rng, progress=progress,
                                     dtype=np.float32 if (depth or 8) > 8 else np.uint8, **generation)
            progress.close()
            save_image(image, path, depth=depth or 8)
    if output != "-":
        where = outputs[0] if count == 1 else f"{outputs[0]} ... {outputs[-1]}"
        click.echo(f"{count} image{'s' if count > 1 else ''} of {size[0]}x{size[1]} written to {where}", err=True)
        if save_model and not from_model:
            click.echo(f"model written to {save_model}", err=True)


@click.command()
@click.argument("model_file", metavar="MODEL")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def info(model_file, as_json):
    """Describe a saved MODEL: settings, dimensions and parameter count (paper Table 4)."""
    from ..modelfile import info_dict, load_model

    with user_errors():
        model = load_model(model_file)
        params = model.n_parameters()
    if as_json:
        click.echo(json.dumps(info_dict(model, params), indent=2, default=str, allow_nan=False))
        return
    h, w, c = model.exemplar_shape_
    click.echo(f"tghop model {model_file}")
    click.echo(f"exemplar: {h}x{w}, {c} channel{'s' if c > 1 else ''}; {model.n_patches_:,} training patches "
               f"of {model.patch_size}x{model.patch_size} at stride {model.stride}")
    click.echo(summary(model, params))
    click.echo("\nparameters (paper Table 4):")
    rows = [("module", "formula", "paper formula", "stored")] + [
        (name, row["formula"], f"{row['paper']:,}", f"{row['stored']:,}") for name, row in params.items()]
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    for r in rows:
        click.echo(f"  {r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]:>{widths[2]}}  {r[3]:>{widths[3]}}")
