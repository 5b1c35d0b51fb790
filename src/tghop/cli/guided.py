"""``tghop synth A B ... [--guide MAP]`` (several sources in one image) and ``tghop morph``: the commands over
:mod:`tghop.guided`."""

from __future__ import annotations

import os

import click

from .._errors import HINT_DOWNSCALE_YOURSELF, TGHopError
from .._formats import OUTPUT_HELP, model_file_kind
from .lines import say
from .common import (Progress, check_output, check_outputs, is_builtin, is_model_file, load_exemplar, count_outputs,
                     draw_seed, tell_steps, read_image, tell_seed, user_errors, warn_written_with_8, write_materials,
                     examples, stage_paths, save_with_stages, STAGES, MATERIAL_STAGES)
from ..fit_options import build_model
from .options import QUIET_OPTION, Size, depth_option

__all__ = ["synth_several", "morph", "GUIDE_HELP", "TRANSITION_HELP", "BLOB_HELP", "DEFAULT_TRANSITION",
           "MAX_TRANSITION"]

#: The steps ``synth --stages`` writes of a painted or remixed image (``synthesize_guided(return_stages=True)``);
#: each layer's own between the regions and the layers (0.62): :func:`guided_stages`.
GUIDED_STAGES = ("regions", "layers", "join")


def guided_stages(k):
    """--stages' names for ``k`` layers (:data:`GUIDED_STAGES` with each layer's steps, ``layer<i>_<step>``, after
    the regions, as ``synthesize_guided(return_stages=True)`` orders them; a texture's steps and a material's)."""
    steps = dict.fromkeys(STAGES + MATERIAL_STAGES)
    return ("regions", *(f"layer{i}_{s}" for i in range(1, k + 1) for s in steps), "layers", "join")


#: :data:`tghop.guided.DEFAULT_TRANSITION`, here so that ``tghop --help`` imports no NumPy
#: (tests/test_guided.py checks that the two agree).
DEFAULT_TRANSITION = 32
#: :data:`tghop.guided.MAX_TRANSITION`, likewise.
MAX_TRANSITION = 4096

GUIDE_HELP = ("With several SOURCEs: a painted map with one flat grey level (or colour) per SOURCE, the darkest "
              "for the first, the next darker for the second, ... (colours by their channels' mean, then R, G, B: "
              "a Note line says which colour is which SOURCE); each region becomes that SOURCE's texture "
              "(or material: every map), made as one SOURCE's image with the same options. Soft (antialiased) or "
              "JPEG edges are taken. The output takes its size; with --size, a map of the output's shape (aspect "
              "ratio within 2 %) is scaled to it, nearest neighbour (a warning says so). Without --guide "
              "several SOURCEs make one texture of random regions of each (a remix).")
TRANSITION_HELP = ("Width in pixels of the band around each painted edge in which the join between two regions "
                   "follows the textures (with several SOURCEs); 0: the painted edge itself.")
BLOB_HELP = ("Size in pixels of a remix's random regions (several SOURCEs without --guide): the blur of its random "
             "field, the regions about 2.3 times as wide. Default (0.64): 7 times the coarser SOURCE's element size "
             "as its model's band statistics measure it, within 32-256 (beach gravel and leopard spots: about 155; "
             "grass and denim: 45-57); 0.63 took 64 for all.")


def _read(spec, downscale=None):
    """A saved model (.npz), or an exemplar (a file or builtin:NAME) read and checked, to fit
    with :func:`_fitted`; reading every SOURCE first refuses a bad one before anything is fitted.
    ``downscale``: the command's ``--downscale`` (None: it has none)."""
    from ..synthesis import prepare_exemplar

    if not is_builtin(spec) and (spec.lower().endswith(".npz") or is_model_file(spec)):
        from ..modelfile import load_model

        return load_model(spec, material=True)  # a material is refused where it cannot go, in the inputs' words
    return prepare_exemplar(load_exemplar(spec, downscale=bool(downscale), dtype=None,
                                          has_downscale=downscale is not None))


def _check_channels(output, depth, read):
    """Refuse, before anything is fitted, a colour TIFF of 16 or 32 bits that cannot be written
    (no tifffile): the output has the most channels of the sources ``read`` (:func:`_read`);
    a material's maps are checked where they are written."""
    import numpy as np

    from ..imageio import check_depth

    channels = [source.shape[2] if isinstance(source, np.ndarray) else source.exemplar_shape_[2]
                for source in read if not hasattr(source, "names_")]
    if channels:
        check_depth(output, depth or 8, channels=max(channels))


def _warn_deep(specs, read, labels, output, depth):
    """Without ``depth``, one warning naming the 16-bit or float exemplars among the sources ``read``
    (:func:`_read`, read as floats), and the models fitted on one (their ``exemplar_depth_``), that the
    image is written with 8 bits, as one such SOURCE of ``synth`` is warned of; ``labels``: "SOURCE"
    (numbered) or one label per source ("A", "B")."""
    import numpy as np

    names = [f"{labels} {i}" for i in range(1, len(specs) + 1)] if isinstance(labels, str) else list(labels)
    deep = [(name if isinstance(source, np.ndarray) else f"the exemplar of {name}", spec)
            for name, spec, source in zip(names, specs, read)
            if (isinstance(source, np.ndarray) and source.dtype != np.uint8 and not is_builtin(spec))
            or (getattr(source, "exemplar_depth_", None) or 8) > 8]
    if deep and not depth:
        warn_written_with_8(None, None, output, several=deep)


def _warn_material_maps(specs, read):
    """One warning where the exemplar images among a remix's SOURCEs (``read``: :func:`_read`'s)
    look like maps of one material: two kinds or more by their names (:func:`tghop.map_names.map_kind`:
    ``rock_albedo.png rock_normal.png``), an image of no such name taken as a normal map by its
    content (:func:`tghop.material.looks_like_normal_map`: ``rock.png`` of blue-violet unit vectors),
    or a normal map with one other image of no kind (its albedo, by elimination). The remix makes
    them one texture of random regions of each, not a material's aligned maps; the warning names
    the commands that make the material. A remix of such files is allowed (it may be what was meant)."""
    import shlex
    import warnings

    import numpy as np

    from ..map_names import ALBEDO, map_kind
    from ..material import looks_like_normal_map

    images = [(i, spec, source) for i, (spec, source) in enumerate(zip(specs, read), start=1)
              if isinstance(source, np.ndarray) and not is_builtin(spec)]
    named = [(i, spec, map_kind(spec)) for i, spec, _ in images]
    by_content = {i for (i, _, kind), (_, _, source) in zip(named, images)
                  if kind is None and looks_like_normal_map(source)}
    maps = [(i, spec, "normal" if i in by_content else kind) for i, spec, kind in named]
    kinds = {kind for _, _, kind in maps if kind is not None}
    plain = [m for m in maps if m[2] is None]  # one with a normal map and no albedo: the albedo, by elimination
    stand_in = plain[0] if len(plain) == 1 and "normal" in kinds and ALBEDO not in kinds else None
    if len(kinds) < 2 and stand_in is None:
        return
    maps = [m for m in maps if m[2] is not None or m is stand_in]
    albedo = next((m for m in maps if m[2] == ALBEDO), stand_in or maps[0])
    others = " ".join(shlex.quote(spec) for _, spec, _ in maps if spec != albedo[1])
    said = ", ".join(f"SOURCE {i} ({spec})" if kind is None else
                     f"SOURCE {i} ({spec}: {'normal, by its colours' if i in by_content else kind})"
                     for i, spec, kind in maps)
    rename = [spec for i, spec, _ in maps if i in by_content]
    hint = (f" (name {' and '.join(rename)} *_normal* first: --maps takes a map as a normal map by its name)"
            if rename else "")
    warnings.warn(f"{said} look like maps of one material, but several SOURCEs without --guide remix them as "
                  f"separate textures into one image; to make the material (every map, aligned), run 'tghop fit "
                  f"{shlex.quote(albedo[1])} --maps {others} -o material.npz'{hint}, then 'tghop synth material.npz "
                  "-o OUT'")


def _fitted(source, options, progress, label):
    """``source`` from :func:`_read` as a model: a saved one as it is, an exemplar fitted with the fit
    ``options`` (None: the command has none, and a too small exemplar is told so in its own words).
    ``label``: the input, for the message (``SOURCE 2 (x.png)``)."""
    import numpy as np

    from ..patches import ExemplarTooSmallError

    if not isinstance(source, np.ndarray):
        return source
    try:
        return build_model(options or {}, n_colours=source.shape[2]).fit(source, progress=progress)
    except ExemplarTooSmallError as exc:
        if options is not None:
            raise TGHopError(f"{label}: {exc}") from None
        raise TGHopError(f"{label} is {source.shape[0]}x{source.shape[1]} pixels, too small to fit a model on (at "
                         f"least {exc.least_side}x{exc.least_side} pixels); give a larger exemplar or a saved model "
                         "fitted with other settings ('tghop fit')") from None


def _load_guide(path, size, size_given):
    """The guide map as an array, refused when it has not --size's shape (one line); of another
    size, it is scaled to --size when its labels are read (:func:`tghop.guides.guide_labels`)."""
    from ..guides import same_shape

    if is_model_file(path):
        raise TGHopError(f"--guide {path} is {model_file_kind(path)}, not an image; give a painted map")
    guide = read_image(path, dtype=None, too_large_hint=HINT_DOWNSCALE_YOURSELF)
    if size_given and not same_shape(guide.shape, size):
        raise click.UsageError(f"--guide {path} is {guide.shape[0]}x{guide.shape[1]} but --size is "
                               f"{size[0]}x{size[1]}, another shape; paint the map at the output's shape (it is "
                               "scaled to --size) or drop --size (the map's size is taken)")
    return guide


def _tell_colours(path, guide, labels, sources):
    """One line naming each colour of a colour guide's SOURCE (0.59): the rule, dark to light by the
    channels' mean, then R, G, B, puts pure red, green and blue (of one mean) in an order no painter sees."""
    import numpy as np

    from ..guides import label_colours

    if guide.ndim < 3 or guide.shape[2] < 3 or np.ptp(guide[..., :3], axis=2).max() == 0:
        return  # grey: darkest first, as the help says
    colours = label_colours(guide, labels)
    if all(colour is None or max(colour) - min(colour) <= 2 for colour in colours):
        return  # grey levels saved in colour (a JPEG's chroma noise)
    told = ", ".join(f"SOURCE {i} ({spec}) where it is #{r:02x}{g:02x}{b:02x}" for i, (spec, colour) in
                     enumerate(zip(sources, colours), start=1) if colour is not None for r, g, b in [colour])
    say(f"Note: --guide {path} paints {told} (its colours ranked dark to light by their mean, then R, G, B)")


def synth_several(ctx, sources, output, size, count, seed, guide, transition, save_model, exclude, downscale,
                  progress, generation, options, depth=None, stages=False, blob=None):
    """``tghop synth`` with several SOURCEs or a --guide, as its only caller calls it (inside the command's
    user_errors; 0.62 dropped a check of one SOURCE without --guide, "a remix needs at least two SOURCEs", that
    could not be met); ``stages``: --stages, OUT_regions, OUT_layers and OUT_join beside each image (0.61;
    materials': OUT_layers_<map>, ... too). Returns the outputs (None for materials, which say what they
    wrote), the size and the first output's step files."""
    import numpy as np

    from ..guided import guide_labels, synthesize_guided
    from ..imageio import generation_dtype, save_image
    from .options import FIT_OPTION_PARAMS, given_options

    if save_model is not None:
        raise click.UsageError("--save-model takes one exemplar; save each model with 'tghop fit' and give the "
                               ".npz files")
    if exclude:
        raise click.UsageError("--exclude takes one exemplar; fit each with 'tghop fit --exclude' and give the "
                               ".npz files")
    size_given = ctx.get_parameter_source("size").name == "COMMANDLINE"
    outputs = count_outputs(output, count)
    staged = [stage_paths(path, guided_stages(len(sources))) for path in outputs] if stages else []
    for path in (outputs if count > 1 else []) + [p for paths in staged for p in paths.values()]:
        check_output(path, made=True)
    check_outputs([("-o", path) for path in outputs] + [("--stages", p) for paths in staged for p in paths.values()],
                  [(f"SOURCE {i}", s) for i, s in enumerate(sources, start=1)] + [("--guide", guide)])
    for spec in sources:  # a SOURCE that is no file is named first (0.58 counted the guide's levels against it)
        if not is_builtin(spec) and not os.path.lexists(spec):
            _read(spec, downscale)
    painted = None
    if guide is not None:  # read and checked (size, levels) before anything is fitted
        painted = _load_guide(guide, size, size_given)
        from ..guides import LostRegionError

        try:  # scaled to --size, saying so; a region it loses refused, a usage error (of --size)
            labels = guide_labels(painted, len(sources), size=size if size_given else None, input_name="SOURCE",
                                  no_guide="drop --guide", names=[f"SOURCE {i}" for i in range(1, len(sources) + 1)],
                                  guide_name=f"--guide {guide}", size_name="--size")
        except LostRegionError as exc:
            raise click.UsageError(str(exc)) from None
        _tell_colours(guide, painted, labels, sources)
        # its regions as grey levels 0, 1, ...: the same regions, read again at once (a soft map's levels took
        # seconds at 4096x4096)
        painted = labels.astype(np.uint8) if len(sources) < 256 else labels
        size = painted.shape[:2]
    from ..settings import BY_NAME

    fit_only = [s.name for s in BY_NAME.values() if s.when == "fit"] + list(FIT_OPTION_PARAMS) + ["downscale"]
    fitting = given_options(ctx, fit_only)
    read = [_read(spec, downscale) for spec in sources]
    for i, (spec, source) in enumerate(zip(sources, read), start=1):
        if fitting and not isinstance(source, np.ndarray):
            one = len(fitting) == 1
            raise click.UsageError(f"{', '.join(fitting)}: fitting option{'' if one else 's'} but SOURCE {i} ({spec}) "
                                   f"is a saved model; fit the exemplars with 'tghop fit' or drop "
                                   f"{'it' if one else 'them'}")
    _same_kind(sources, read, "SOURCE")
    if guide is None:  # before _check_mixable: a grey map among them is refused there
        _warn_material_maps(sources, read)
    _check_mixable([f"SOURCE {i} ({spec})" for i, spec in enumerate(sources, start=1)], read, options)
    _check_channels(output, depth, read)
    _warn_deep(sources, read, "SOURCE", output, depth)
    if generation["patch_refine"] and hasattr(read[0], "names_"):  # each albedo by its own statistics (0.60)
        from .options import refuse_patch_refine_of_saved

        for i, (spec, source) in enumerate(zip(sources, read), start=1):
            if source.albedo_patches() is None:
                refuse_patch_refine_of_saved(ctx, f"SOURCE {i} ({spec})", material=True)
    elif generation["patch_refine"]:  # before any fit
        from .options import refuse_patch_refine_of_saved, refuse_patch_refine_without_statistics

        for i, (spec, source) in enumerate(zip(sources, read), start=1):
            if not isinstance(source, np.ndarray) and source.patches_ is None:
                refuse_patch_refine_of_saved(ctx, f"SOURCE {i} ({spec})", material=False)
        if any(isinstance(source, np.ndarray) for source in read):
            refuse_patch_refine_without_statistics(ctx, generation, build_model(dict(options)))

    same, models = {}, []  # a file given twice is one model (fitted once): its regions are one synthesis
    for i, (spec, source) in enumerate(zip(sources, read), start=1):
        key = spec if is_builtin(spec) else os.path.realpath(spec)
        if key not in same:
            same[key] = _fitted(source, options, progress, f"SOURCE {i} ({spec})")
        models.append(same[key])
    rng = np.random.default_rng(seed)
    if hasattr(models[0], "names_"):  # materials: every map painted alike, OUT, OUT_<suffix>, ...
        def make():
            maps = synthesize_guided(models, painted, size=size, transition=transition, blob=blob, rng=rng,
                                     progress=progress, dtype=np.float32, return_stages=stages, **generation)
            progress.close()
            return maps

        steps = write_materials(models[0], output, outputs, size, depth, make,
                                [(f"SOURCE {i}", s) for i, s in enumerate(sources, start=1)] + [("--guide", guide)],
                                progress, stages=guided_stages(len(sources)) if stages else False)
        tell_steps(steps, count, maps=True)
        return None, size, []
    first = []  # the steps written beside the first output
    for i, path in enumerate(outputs):
        image = synthesize_guided(models, painted, size=size, transition=transition, blob=blob, rng=rng,
                                  progress=progress, dtype=generation_dtype(depth), return_stages=stages, **generation)
        progress.close()
        if stages:  # the steps and the result: all or none (0.62)
            image, steps = image
            steps = {name: step for name, step in steps.items() if name in staged[i]}
            first = first or list(steps)
            save_with_stages(image, path, depth or 8, steps, staged[i], progress=progress)
        else:
            save_image(image, path, depth=depth or 8, progress=progress)
        progress.close()
    return outputs, size, [staged[0][name] for name in first] if stages else []


def _same_kind(specs, read, label):
    """Refuse materials mixed with textures (or with exemplar images, which fit texture models), in one
    line (``label`` "A"/"B": a morph's, two materials since 0.59, "SOURCE": a paint's or remix's): a usage error,
    exit status 2 (0.62; 0.61 exited 1, as for a file it could not use)."""
    import numpy as np

    whole = [hasattr(r, "names_") for r in read]
    if not any(whole) or all(whole):
        return
    first = whole.index(True)
    if label != "SOURCE":
        other = "B" if label == "A" else "A"
        raise click.UsageError(f"{label} {specs[first]} is a material but {other} {specs[1 - first]} is not; morph two "
                               "materials (fit each with 'tghop fit ALBEDO --maps ...') or two textures")
    for i, (spec, r, w) in enumerate(zip(specs, read, whole), start=1):
        if not w:
            what = "an exemplar image" if isinstance(r, np.ndarray) else "a texture model"
            raise click.UsageError(f"SOURCE {i} ({spec}) is {what} but SOURCE {first + 1} ({specs[first]}) is a "
                                   "material; paint with all materials (fit each with 'tghop fit ALBEDO --maps ...') "
                                   "or all textures")


def _check_mixable(labels, read, options):
    """Refuse, before anything is fitted, sources that cannot share an image, naming them
    (``labels``: "SOURCE 2 (x.png)", "B x.npz"): grey with colour, other patch sizes (an
    exemplar's: the fit ``options``' or the default), or materials of other maps (the library
    refuses them too, but after every exemplar's fit and as "input 2")."""
    import numpy as np

    def shape(source):  # an exemplar's or texture model's (channels, patch size)
        if isinstance(source, np.ndarray):
            return source.shape[2], build_model(options or {}, n_colours=source.shape[2]).patch_size
        return source.exemplar_shape_[2], source.patch_size

    first, label1 = read[0], labels[0]
    if hasattr(first, "names_"):  # all materials (_same_kind): the same maps (by their kinds or suffixes), in order
        from ..material_files import maps_refused

        for label, source in zip(labels[1:], read[1:]):
            refused = maps_refused(source, first, label, label1, given="after --maps")
            if refused:
                raise TGHopError(refused)
        return
    channels1, patch1 = shape(first)
    for label, source in zip(labels[1:], read[1:]):
        channels, patch = shape(source)
        if channels != channels1:
            kind = {1: "greyscale"}
            raise TGHopError(f"{label} is {kind.get(channels, 'in colour')} but {label1} is "
                             f"{kind.get(channels1, 'in colour')}; give all colour or all greyscale exemplars or "
                             "models")
        if patch != patch1:
            raise TGHopError(f"{label} has {patch}x{patch} patches but {label1} has {patch1}x{patch1}; fit them with "
                             "the same --patch-size")


def _check_grid(size, grid):
    """The stacked strips within the output size limit (each strip's --size is checked alone)."""
    import math

    from .._images import MAX_PIXELS

    height, width = size[0] * grid, size[1]
    if height * width > MAX_PIXELS:
        side = math.isqrt(MAX_PIXELS)
        raise click.UsageError(f"--grid {grid} strips of {size[0]}x{size[1]} make a {height}x{width} image, "
                               f"{height * width:,} pixels, above the limit of {MAX_PIXELS:,} ({side}x{side}); "
                               "ask for fewer strips or a smaller --size")


def _check_height(size, source):
    """A strip at least a patch tall (``source``: A, an exemplar or a texture model), refused as a usage
    error before anything is fitted: the library refuses it too, after the fits."""
    import numpy as np

    patch = build_model({}, n_colours=source.shape[2]).patch_size if isinstance(source, np.ndarray) \
        else getattr(source, "model_", source).patch_size  # a material's: its joint model's (0.59)
    if size[0] < patch:
        raise click.UsageError(f"--size {size[0]}x{size[1]}: a morph strip must be at least {patch} px tall (the "
                               "patch size; a lower one cannot mix the two textures by position); give "
                               f"--size {patch}x{size[1]} or taller")


@click.command(short_help='A strip from texture A on the left to texture B on the right', epilog=examples(
    "# the bricks model (see tghop fit --help) turning into the built-in cells",
    "tghop morph bricks.npz builtin:cells -o strip.png --seed 1",
    "# from saved models: 4 strips of 256x1024, consecutive seeds, stacked",
    "tghop morph bricks.npz cells.npz -o grid.png --size 256x1024 --grid 4"))
@click.argument("source_a", metavar="A")
@click.argument("source_b", metavar="B")
@click.option("-o", "--output", required=True, help=f"{OUTPUT_HELP}; - writes PNG to stdout).")
@click.option("--size", type=Size(), default="256x1024", show_default=True,
              help="HEIGHTxWIDTH of one strip, at least a patch (32 px by default) tall.")
@click.option("--grid", type=click.IntRange(min=1, max=64), default=1, show_default=True,
              help="Strips of consecutive seeds stacked top to bottom (a grid of seeds).")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed: the same seed gives the same strip; without it every run differs (the seed drawn is "
                   "said after it).")
@click.option("--stations", type=click.IntRange(min=2, max=256), default=None,
              help="No longer applies (accepted with a warning, and ignored).")
@click.option("--stages", is_flag=True,
              help="Also write each step's picture beside OUTPUT: OUTPUT_regions (A's black, B's white), A's "
                   "and B's own steps (0.62: OUTPUT_layer1_quilt, ..., OUTPUT_layer2_quilt, ...), "
                   "OUTPUT_layers (each region its own texture, before the join) and OUTPUT_join (OUTPUT itself); "
                   "of materials each map's too (OUTPUT_layers_<map>, ...); with --grid, each step's strips stacked.")
@depth_option("8")
@QUIET_OPTION
def morph(source_a, source_b, output, size, grid, seed, stations, stages, depth, quiet):
    """A strip from texture A on the left to texture B on the right (A and B: exemplars,
    builtin:NAME or saved models); every column mixes regions of the two, with organic outlines, in its
    proportion. Two saved materials with the same maps (tghop fit ALBEDO --maps ...) morph every map
    alike: OUTPUT and OUTPUT_<map>, as synth writes a material."""
    import numpy as np

    from ..guided import STATIONS_GONE
    from ..guided import morph as make_strip
    from ..imageio import check_depth, generation_dtype, save_image

    progress = Progress(not quiet)
    seed, drawn = draw_seed(seed)
    with user_errors(progress):
        if stages and output == "-":
            raise click.UsageError("--stages needs a file name: it writes OUTPUT_regions and the others next to -o's "
                                   "image, so give -o a file name (e.g. -o strip.png) or drop --stages")
        check_output(output, allow_stdout=True, depth=depth)
        check_depth(output, depth or 8)
        staged = stage_paths(output, guided_stages(2)) if stages else {}
        for path in staged.values():
            check_output(path, made=True)
        check_outputs([("-o", output)] + [("--stages", path) for path in staged.values()],
                      [("A", source_a), ("B", source_b)])
        _check_grid(size, grid)
        read_a, read_b = _read(source_a), _read(source_b)
        _same_kind([source_a, source_b], [read_a, read_b], "A" if hasattr(read_a, "names_") else "B")
        _check_mixable([f"A {source_a}", f"B {source_b}"], [read_a, read_b], None)
        _check_height(size, read_a)
        _check_channels(output, depth, [read_a, read_b])
        _warn_deep([source_a, source_b], [read_a, read_b], ("A", "B"), output, depth)
        model_a, model_b = _fitted(read_a, None, progress, f"A {source_a}"), _fitted(read_b, None, progress,
                                                                                     f"B {source_b}")
        if stations is not None:  # (the library's FutureWarning is not among the warnings shown)
            say(f"Warning: --{STATIONS_GONE}")
        if hasattr(model_a, "names_"):  # two materials (0.59): every map morphed alike, OUT and OUT_<suffix>
            steps = _morph_materials(model_a, model_b, output, size, grid, seed, depth, progress,
                                     [("A", source_a), ("B", source_b)], stages)
            tell_steps(steps, 1, maps=True)
            tell_seed(seed, drawn, "the same strip" if grid == 1 else "the same strips")
            return
        rows = []
        for row in range(grid):
            rng = np.random.default_rng(seed + row)
            rows.append(make_strip(model_a, model_b, size, rng=rng, progress=progress, dtype=generation_dtype(depth),
                                   return_stages=stages))
            progress.close()
        image, steps = _stacked(rows, stages)
        steps = {name: step for name, step in steps.items() if name in staged}
        if stages:  # the steps and the strips: all or none (0.62)
            save_with_stages(image, output, depth or 8, steps, staged, progress=progress)
        else:
            save_image(image, output, depth=depth or 8, progress=progress)
    if output != "-":
        say(f"{grid} strip{'s' if grid > 1 else ''} of {size[0]}x{size[1]} written to {output}")
    tell_steps([staged[name] for name in steps], 1)
    tell_seed(seed, drawn, "the same strip" if grid == 1 else "the same strips")


def _stacked(rows, stages):
    """``grid`` strips (``rows``: :func:`tghop.guided.morph`'s results; with ``stages``, ``(strip, steps)`` pairs)
    stacked top to bottom: ``(strips, steps)``, each step stacked alike (a material's step and result: dicts of
    maps); steps ``{}`` without ``stages``."""
    import numpy as np

    def stack(parts):
        if isinstance(parts[0], dict):
            return {name: np.concatenate([p[name] for p in parts], axis=0) for name in parts[0]}
        return np.concatenate(parts, axis=0)

    if not stages:
        return stack(rows), {}
    # a step every strip has (a layer's box too small for a coarse guide in one strip has no layer<i>_guide there)
    return stack([r[0] for r in rows]), {name: stack([r[1][name] for r in rows]) for name in rows[0][1]
                                         if all(name in r[1] for r in rows)}


def _morph_materials(model_a, model_b, output, size, grid, seed, depth, progress, inputs, stages=False):
    """``morph`` of two materials: ``grid`` strips of every map, stacked, written as ``synth`` writes a
    material (:func:`~tghop.cli.common.write_materials`: OUT and OUT_<suffix> for each of A's maps); with
    ``stages`` (0.61) each step's maps too, OUT_<step> and OUT_<step>_<suffix>."""
    import numpy as np

    from ..guided import morph as make_strip

    def make():
        rows = []
        for row in range(grid):
            rows.append(make_strip(model_a, model_b, size, rng=np.random.default_rng(seed + row), progress=progress,
                                   dtype=np.float32, return_stages=stages))
            progress.close()
        maps, steps = _stacked(rows, stages)
        return (maps, steps) if stages else maps

    return write_materials(model_a, output, [output], (size[0] * grid, size[1]), depth, make, inputs, progress,
                           stages=guided_stages(2) if stages else False)
