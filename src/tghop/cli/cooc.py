"""``tghop cooc ...``: train the co-occurrence cGAN (Darzi et al.) and use its controls.

Registered on the main group by :mod:`tghop.cli.group`; torch is imported only when a
command runs (through :mod:`tghop.cooc`), and NumPy only inside the commands, so
``tghop --help`` stays fast and torch-free.
"""

from __future__ import annotations

import json
import re

import click

from .._errors import TGHopError
from .._formats import OUTPUT_HELP
from .._limits import MAX_BOOST
from .lines import say
from .common import Progress, check_model_output, check_output, check_outputs, load_exemplar, user_errors
from .options import QUIET_OPTION, FloatRange, Size, refuse_split_size

#: Longest morph strip, in condition cells.
MAX_CELLS = 4096


class Grid(click.ParamType):
    """``COLSxROWS`` of morph's grid, 1 to 32 each: a usage error (exit status 2) otherwise."""

    name = "COLSxROWS"

    def get_metavar(self, param, ctx=None):
        return self.name  # as written (click would upper-case it)

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", value)
        if not m or not (1 <= int(m.group(1)) <= 32 and 1 <= int(m.group(2)) <= 32):
            self.fail(f"{value!r}: write COLSxROWS with 1 to 32 each, e.g. 5x3", param, ctx)
        return int(m.group(1)), int(m.group(2))


class Boost(click.ParamType):
    """``A,B,FACTOR`` of edit's boost: two cluster numbers and a factor from 0 to :data:`MAX_BOOST`
    (a usage error otherwise: more changes next to nothing, and 1e308 overflowed)."""

    name = "A,B,FACTOR"

    def get_metavar(self, param, ctx=None):
        return self.name  # as written (click would upper-case it)

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            ia, ib, factor = value.split(",")
            ia, ib, factor = int(ia), int(ib), float(factor)
        except ValueError:
            self.fail(f"{value!r}: write A,B,FACTOR, e.g. 0,0,2", param, ctx)
        if not 0 <= factor <= MAX_BOOST:  # NaN too
            self.fail(f"{value!r}: FACTOR must be from 0 to {MAX_BOOST:,.0f}, got {factor:g}", param, ctx)
        return ia, ib, factor


class LossProgress(Progress):
    """A progress bar that also shows the latest training losses."""

    def __init__(self, enabled: bool):
        super().__init__(enabled, show_eta=True)
        self.note = ""

    def log(self, step, losses):
        self.note = (f"D {losses['critic']:+.3f}  G {losses['adversarial']:+.3f}  "
                     f"cooc {losses['consistency']:.3f}")


def value_form(key: str) -> str:
    """What ``--set KEY=VALUE`` takes for setting ``key`` (by its default's type), with an example."""
    from ..cooc import SMALL

    default = SMALL[key]
    if isinstance(default, str):
        return f"one of zeros, reflect, replicate, e.g. {key}=reflect"
    if isinstance(default, bool):
        return f"true or false, e.g. {key}=true"
    if isinstance(default, (list, tuple)):
        return f"a JSON list of integers, e.g. {key}={json.dumps(list(default), separators=(',', ':'))}"
    if isinstance(default, int):
        return f"an integer, e.g. {key}={default}"
    return f"a number, e.g. {key}={default:g}"


def parse_settings(pairs) -> dict:
    """``KEY=VALUE`` strings -> dict (VALUE parsed as JSON: numbers, lists, true and false;
    padding's words as they are). The values are checked when the model trains
    (:func:`tghop.cooc.config.check_settings`)."""
    from ..cooc import SMALL

    out = {}
    for item in pairs:
        key, sep, value = item.partition("=")
        key = key.strip().replace("-", "_")
        if not sep or key not in SMALL:
            raise TGHopError(f"--set {item!r}: write KEY=VALUE with KEY one of {', '.join(SMALL)}")
        try:
            out[key] = json.loads(value)
        except ValueError:
            if isinstance(SMALL[key], str):  # a word setting: padding=replicate
                out[key] = value.strip()
                continue
            raise TGHopError(f"--set {item!r}: {key} takes {value_form(key)}") from None
    return out


def usage_settings(pairs, base) -> dict:
    """:func:`parse_settings` of ``--set``'s ``pairs``, checked over the configuration ``base``
    (:func:`tghop.cooc.config.check_settings`) before anything is read: a bad one is a usage
    error (exit status 2), one line naming it, as click's own option errors are."""
    from ..cooc.config import check_settings

    try:
        overrides = parse_settings(pairs)
    except TGHopError as exc:  # its words name the --set item already
        raise click.UsageError(str(exc)) from None
    try:
        check_settings({**base, **overrides})
    except TGHopError as exc:
        raise click.BadParameter(str(exc), param_hint="'--set'") from None
    return overrides


def load_checkpoint(path):
    from ..cooc import load

    return load(path)


def condition(model, spec: str):
    """A co-occurrence tensor of a training crop's size from ``crop:Y,X`` (a crop of the
    training exemplar) or an image (its whole tensor averaged down, or up, to that size:
    :meth:`~tghop.cooc.CoocGAN.image_condition`)."""
    m = re.fullmatch(r"crop:(\d+),(\d+)", spec.strip())
    if m:
        return model.crop_condition(int(m.group(1)), int(m.group(2)))
    if spec.startswith("crop:"):
        raise click.UsageError(f"{spec!r}: write crop:ROW,COL (pixel position of a crop in the training exemplar)")
    return model.image_condition(load_exemplar(spec))


#: ``--windows`` of morph and edit.
WINDOWS_OPTION = click.option(
    "--windows", is_flag=True,
    help="Generate in overlapping training-size windows instead of one generator pass over the whole condition "
         "(the paper's way).")


def _mask_labels(mask, n_sources, size):
    """``--mask``'s region of every pixel of the output, (H, W) labels in ``[0, n_sources)``: one flat grey
    level (or colour) per SOURCE, the darkest for the first (:func:`tghop.guides.guide_labels`, as ``synth
    --guide`` reads its map); one of --size's shape but another size scaled to it, nearest neighbour, saying
    so in the command's words; another shape refused, and a region the scaling loses (a usage error, of
    --size)."""
    import warnings

    from .._errors import collect_warnings
    from ..guides import LostRegionError, guide_labels, same_shape

    painted = load_exemplar(mask, dtype=None)
    if not same_shape(painted.shape, size):
        raise click.UsageError(f"--mask {mask} is {painted.shape[0]}x{painted.shape[1]} but --size is "
                               f"{size[0]}x{size[1]}, another shape; give a mask of the output's shape, it is scaled "
                               f"to its size (or --size {painted.shape[0]}x{painted.shape[1]})")
    try:
        with collect_warnings() as said:  # the library's words name a guide
            pixels = guide_labels(painted, n_sources, size=size, input_name="SOURCE", no_guide="drop --mask",
                                  names=[f"SOURCE {i}" for i in range(1, n_sources + 1)], guide_name=f"--mask {mask}",
                                  size_name="--size")
    except LostRegionError as exc:
        raise click.UsageError(str(exc)) from None
    except TGHopError as exc:
        raise TGHopError(f"--mask {mask}: {str(exc).replace('the guide', 'the mask')}") from None
    if said:
        warnings.warn(f"--mask {mask} was scaled from {painted.shape[0]}x{painted.shape[1]} to {size[0]}x{size[1]}, "
                      "--size (nearest neighbour: its regions kept as painted)")
    return pixels


class _InOrder(click.Group):
    """Lists its commands in the order they are used (train first), not by name."""

    def list_commands(self, ctx):
        return list(self.commands)


@click.group("cooc", cls=_InOrder, short_help="The co-occurrence cGAN (needs PyTorch): train, morph, edit")
def cooc():
    """Co-occurrence cGAN (Darzi et al.): train, morph, edit. Needs: pip install 'tghop[metrics]'.

    \b
    Examples:
      # the small config: about 15 min on a 2-core CPU (0.13)
      tghop cooc train texture.jpg -o model.pt
      tghop cooc morph model.pt crop:0,0 crop:128,128 -o strip.png
      tghop cooc morph model.pt crop:0,0 crop:128,128 --grid 5x3 -o grid.png
      tghop cooc edit model.pt crop:0,0 crop:128,128 --size 256x512 -o edit.png
      tghop baseline cooc texture.jpg --model model.pt -o out.png --size 512x512
    """


@cooc.command(short_help='Train the cGAN on an exemplar and save a checkpoint (.pt)')
@click.argument("exemplar")
@click.option("-o", "--output", required=True, help="Checkpoint to write (.pt).")
@click.option("--paper", is_flag=True,
              help="The paper's configuration (128 px crops, s = 32, 2,000 crops; ~10 min on an H100 GPU, "
                   "far too slow for a CPU).")
@click.option("--steps", type=click.IntRange(min=0), default=None,
              help="Generator steps, at most 150,000 (--max-minutes bounds the time). "
                   "[default: the configuration's: 5,500 small, 3,750 with --paper]")
@click.option("--set", "settings", multiple=True, metavar="KEY=VALUE",
              help="Override a setting, e.g. --set crop_size=32 --set g_widths=[32,16] (repeatable).")
@click.option("--resume", is_flag=True, help="Continue the checkpoint at OUTPUT (same exemplar) up to --steps.")
@click.option("--max-minutes", type=FloatRange(min=0, min_open=True, max=1e6), default=None, metavar="M",
              help="Stop training after M minutes and write the checkpoint (--resume continues it).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the training (initial weights, batches).")
@QUIET_OPTION
def train(exemplar, output, paper, steps, settings, resume, max_minutes, seed, quiet):
    """Train the co-occurrence cGAN on EXEMPLAR (an image file or builtin:NAME).

    The small configuration (the default) trains 5,500 steps in about 15 minutes on a
    2-core CPU (0.13); --max-minutes bounds that, --resume continues a stopped training.
    """
    progress = LossProgress(not quiet)
    with user_errors(progress):
        from .._resources import import_torch
        from ..cooc import PAPER, SMALL, CoocGAN

        from ..cooc.config import MAX_STEPS

        if steps is not None and steps > MAX_STEPS:
            raise click.BadParameter(f"at most {MAX_STEPS:,}, got {steps:,}; give fewer steps (and --max-minutes "
                                     "to bound the time)", param_hint="'--steps'")
        overrides = usage_settings(settings, PAPER if paper else SMALL)
        if resume and (paper or overrides):
            raise click.UsageError("--resume continues a checkpoint with its own settings; drop --paper and --set")
        import_torch("the co-occurrence cGAN")  # the one-line hint before the exemplar is read
        check_model_output(output, "-o", suffix=".pt", what="checkpoint")
        check_outputs([("-o", output)], [("EXEMPLAR", exemplar)])  # (--resume reads and rewrites -o on purpose)
        image = load_exemplar(exemplar)
        from ..cooc.training import keep_mmap_threshold

        keep_mmap_threshold()  # the command's process only: a long CPU training's memory stays flat
        max_seconds = None if max_minutes is None else 60.0 * max_minutes
        if resume:
            model = load_checkpoint(output)
            if steps is not None:
                model.set_params(n_steps=steps)
            model.fit(image, resume=True, max_seconds=max_seconds, progress=progress, log=progress.log)
        else:
            model = CoocGAN(**(PAPER if paper else {}), rng=seed).set_params(**overrides)
            if steps is not None:
                model.set_params(n_steps=steps)
            model.fit(image, max_seconds=max_seconds, progress=progress, log=progress.log)
        progress.close()
        model.save(output)
    total = model.settings_["n_steps"]
    if model.step_ < total:
        say(f"stopped early after {max_minutes:g} minutes, at step {model.step_} of {total}; checkpoint "
            f"written to {output} (continue it with: tghop cooc train {exemplar} -o {output} --resume)")
    else:
        say(f"{model.step_} step{'s' if model.step_ != 1 else ''} trained; checkpoint written to {output}")


@cooc.command(short_help="A strip (or grid) whose co-occurrence moves from A's to B's")
@click.argument("model_file", metavar="MODEL")
@click.argument("a")
@click.argument("b")
@click.option("-o", "--output", required=True, help=f"{OUTPUT_HELP}; - writes PNG to stdout).")
@click.option("--length", type=click.IntRange(min=2, max=MAX_CELLS), default=8, show_default=True,
              help="Strip length in co-occurrence cells (s pixels each).")
@click.option("--grid", type=Grid(), default=None,
              help="Write the paper's Fig. 2 grid instead: co-occurrence A->B across, noise down, e.g. 5x3.")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed of the noise: the same seed gives the same image; without it every run differs.")
@WINDOWS_OPTION
@QUIET_OPTION
def morph(model_file, a, b, output, length, grid, seed, windows, quiet):
    """Morph from A to B: a strip (or a grid) whose co-occurrence moves from A to B.

    A and B are crop:ROW,COL (the training exemplar's training-size crop at that pixel) or
    images. An image (a file or builtin:NAME, any size of at least s pixels a side) stands
    for its statistics: its whole co-occurrence tensor, measured with the model's colours
    and scale, averaged down (or up) to a training crop's grid of cells.
    """
    from ..imageio import save_image
    from ..patches import patch_grid

    del quiet  # taken as every command takes it: nothing here draws a progress bar
    with user_errors():
        check_output(output, allow_stdout=True)
        check_outputs([("-o", output)], [("MODEL", model_file), *[(label, spec) for label, spec in (("A", a), ("B", b))
                                                                   if not spec.startswith("crop:")]])
        cols, rows = grid or (None, None)
        model = load_checkpoint(model_file)
        ca, cb = condition(model, a), condition(model, b)
        if grid is None:
            image = model.morph_strip(ca, cb, length=length, rng=seed, windows=windows)
        else:
            h = min(ca.shape[1], cb.shape[1])
            w = min(ca.shape[2], cb.shape[2])
            tiles = model.morph_grid(ca[:, :h, :w], cb[:, :h, :w], n_cols=cols, n_rows=rows, rng=seed)
            image = patch_grid(tiles.reshape((-1,) + tiles.shape[2:]), n_cols=cols)
        save_image(image, output)
    if output != "-":  # as tghop morph says it
        what = "1 strip" if grid is None else f"a {cols}x{rows} grid"
        say(f"{what} of {image.shape[0]}x{image.shape[1]} written to {output}")


@cooc.command(short_help='Generate from edited co-occurrence: statistics painted where wanted')
@click.argument("model_file", metavar="MODEL")
@click.argument("sources", nargs=-1)
@click.option("-o", "--output", required=True, help=f"{OUTPUT_HELP}; - writes PNG to stdout).")
@click.option("--size", type=Size(), default="256x256", show_default=True, help="Output HEIGHTxWIDTH.")
@click.option("--mask", default=None, metavar="IMAGE",
              help="Image of --size's shape (scaled to it, nearest neighbour) painted with one flat grey level (or "
                   "colour) per SOURCE, the darkest for the first, as synth's --guide: each SOURCE goes to its "
                   "region (default: SOURCES side by side, left to right).")
@click.option("--boost", type=Boost(), default=None,
              help="Multiply bin M(A, B) (and M(B, A)) by FACTOR (0 to 1,000) everywhere, then re-normalise "
                   "(paper Fig. 11).")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed of the noise: the same seed gives the same image; without it every run differs.")
@WINDOWS_OPTION
@QUIET_OPTION
def edit(model_file, sources, output, size, mask, boost, seed, windows, quiet):
    """Generate from edited co-occurrence: SOURCES' statistics painted where you want them.

    SOURCES are crop:ROW,COL or images, as for morph (an image: its whole co-occurrence
    tensor averaged to a training crop's grid of cells); each is repeated over its region.
    None: the exemplar's own tensor.
    """
    import numpy as np

    from ..cooc import boost_condition, cell_labels, paint_condition
    from ..imageio import save_image

    del quiet  # taken as every command takes it: nothing here draws a progress bar
    with user_errors():
        refuse_split_size(click.get_current_context(), sources)  # --size 512 512: before the checkpoint is read
        check_output(output, allow_stdout=True)
        check_outputs([("-o", output)], [("MODEL", model_file), ("--mask", mask),
                                         *[("SOURCE", spec) for spec in sources if not spec.startswith("crop:")]])
        if mask is not None and not sources:
            raise click.UsageError("--mask says which SOURCE goes where; give the SOURCES (crop:ROW,COL or images) "
                                   "too")
        pixels = None
        if mask is not None:  # read and refused before the checkpoint is read, as synth reads a --guide
            pixels = _mask_labels(mask, len(sources), size)
        model = load_checkpoint(model_file)
        s = model.s
        hh, ww = -(-size[0] // s), -(-size[1] // s)
        if not sources:
            cond = model.condition_for(size, rng=seed)
        else:
            tensors = [condition(model, spec) for spec in sources]
            if pixels is None:
                labels = np.minimum(np.arange(ww) * len(tensors) // ww, len(tensors) - 1)
                labels = np.broadcast_to(labels[None], (hh, ww))
            else:  # each cell its centre pixel's region, as the web server's edit
                labels = cell_labels(pixels, s)
            cond = paint_condition(tensors, labels)
        if boost is not None:
            try:
                cond = boost_condition(cond, *boost)
            except TGHopError as exc:  # a cluster the model has not: a usage error too
                raise click.BadParameter(f"{','.join(map(str, boost[:2]))}: {exc}", param_hint="'--boost'") from None
        image = model.generate(cond, rng=seed, windows=windows)[: size[0], : size[1]]
        save_image(image, output)
    if output != "-":
        say(f"edited texture of {image.shape[0]}x{image.shape[1]} written to {output}")
