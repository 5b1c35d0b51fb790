"""The ``tghop`` command line: synth, fit, patches, info, evaluate, baseline.

Every command reports bad input as one line on stderr and a non-zero exit status, never
a traceback, and never leaves a half-written output file. Progress bars go to stderr.
"""

from __future__ import annotations

import json
import re
import sys
import warnings
from contextlib import contextmanager
from pathlib import Path

import click
import numpy as np

from . import __version__
from ._common import TGHopError
from .synthesis import prepare_exemplar

#: Largest accepted --count.
MAX_COUNT = 1000


# ------------------------------------------------------------------ helpers
class Progress:
    """Renders the library's ``progress(stage, done, total)`` calls as click progress bars."""

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.bar = None
        self.stage = None
        self.done = 0

    def __call__(self, stage, done, total):
        if not self.enabled:
            return
        if stage != self.stage:
            self.close()
            self.stage, self.done = stage, 0
            self.bar = click.progressbar(length=max(total, 1), label=f"{stage:<14}", file=sys.stderr,
                                         show_eta=False, show_percent=True)
            self.bar.__enter__()
        if done > self.done:
            self.bar.update(done - self.done)
            self.done = done

    def close(self):
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None
            self.stage = None


def fail(message: str, code: int = 1):
    click.echo(f"Error: {message}", err=True)
    sys.exit(code)


@contextmanager
def user_errors(progress=None):
    """Turn library errors into one line on stderr; show warnings as one line each."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield
        except TGHopError as exc:
            if progress:
                progress.close()
            fail(str(exc))
        except MemoryError:
            if progress:
                progress.close()
            fail("out of memory; use a smaller output size, pool or exemplar")
        except KeyboardInterrupt:
            if progress:
                progress.close()
            fail("interrupted", 130)
        finally:
            if progress:
                progress.close()
            for w in caught:
                if issubclass(w.category, (UserWarning, RuntimeWarning)):
                    click.echo(f"Warning: {w.message}", err=True)


class ChannelRule(click.ParamType):
    """An int count, a fraction in (0, 1], or 'knee'."""

    name = "COUNT|FRACTION|knee"

    def convert(self, value, param, ctx):
        if isinstance(value, (int, float)) or value is None:
            return value
        text = str(value).strip().lower()
        if text == "knee":
            return "knee"
        try:
            number = int(text)
            if number < 1:
                self.fail(f"{value!r} must be at least 1 (or a fraction in (0, 1], or 'knee')", param, ctx)
            return number
        except ValueError:
            pass
        try:
            frac = float(text)
        except ValueError:
            self.fail(f"{value!r} is not a channel count, a fraction in (0, 1] or 'knee'", param, ctx)
        if not 0 < frac <= 1:
            self.fail(f"{value!r}: a fraction must lie in (0, 1]", param, ctx)
        return frac


class Size(click.ParamType):
    """``HxW`` or a single number for a square."""

    name = "HxW"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        m = re.fullmatch(r"\s*(-?\d+)\s*(?:[xX*,]\s*(-?\d+)\s*)?", str(value))
        if not m:
            self.fail(f"{value!r} is not a size; write HEIGHTxWIDTH, e.g. 512x512", param, ctx)
        h = int(m.group(1))
        w = int(m.group(2)) if m.group(2) else h
        if h < 1 or w < 1:
            self.fail(f"{value!r}: height and width must be positive", param, ctx)
        return (h, w)


def model_options(func):
    """The fitting options shared by ``fit`` and ``synth`` (paper defaults)."""
    options = [
        click.option("--patch-size", type=click.Choice(["32", "64"]), default="32", show_default=True,
                     help="Patch side (64 uses three hops)."),
        click.option("--stride", type=click.IntRange(min=1), default=2, show_default=True,
                     help="Step between training patches."),
        click.option("--k1", type=ChannelRule(), default=None, help="Hop-1 channels (paper: 9): count, energy fraction or 'knee'."),
        click.option("--k2", type=ChannelRule(), default=None, help="Hop-2 channels in total (paper: 22)."),
        click.option("--k3", type=ChannelRule(), default=None, help="Hop-3 channels (64x64 patches; default 40)."),
        click.option("--gamma", type=click.FloatRange(min=0), default=0.01, show_default=True,
                     help="SDR variance threshold."),
        click.option("--clusters", "-N", "n_clusters", type=click.IntRange(min=1, max=5000), default=50,
                     show_default=True, help="K-means clusters in ICHM."),
        click.option("--codewords", "-W", "n_codewords", type=click.IntRange(min=1, max=100000), default=200,
                     show_default=True, help="CDF codebook size."),
        click.option("--cluster-energy", type=click.FloatRange(min=0, max=1, min_open=True), default=None,
                     help="Variance fraction kept by each cluster's PCA [default: 0.99; --paper: 0.95]."),
        click.option("--max-cluster-components", type=click.IntRange(min=1), default=None,
                     help="Components per cluster at most [default: 100; --paper: 50]."),
        click.option("--paper", is_flag=True,
                     help="The paper's pipeline exactly: Table 4 core model (F about 2,500) and no colour matching."),
        click.option("--reject-threshold", type=float, default=None,
                     help="Sampling step (iv): redraw samples with no component above this."),
        click.option("--max-patches", type=click.IntRange(min=1), default=20000, show_default=True,
                     help="Subsample training patches beyond this many."),
        click.option("--residual/--no-residual", default=None,
                     help="Model the detail each cluster's PCA drops (a Gaussian per core channel) and add it "
                          "to every patch [default: on; off with --paper]."),
        click.option("--fit-seed", type=click.IntRange(min=0), default=0, show_default=True,
                     help="Seed of fitting (K-means, FastICA)."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


def build_model(patch_size, stride, k1, k2, k3, gamma, n_clusters, n_codewords, cluster_energy,
                max_cluster_components, paper, reject_threshold, max_patches, fit_seed, residual=None, n_colours=3):
    from .synthesis import PAPER_TABLE4, TGHop, default_channels

    defaults_from = PAPER_TABLE4 if paper else TGHop().get_params()
    if cluster_energy is None:
        cluster_energy = defaults_from["cluster_energy"]
    if max_cluster_components is None:
        max_cluster_components = defaults_from["max_cluster_components"]
    if residual is None:
        residual = defaults_from["residual"]

    patch_size = int(patch_size)
    defaults = default_channels(patch_size, n_colours)
    given = [k1, k2, k3][: len(defaults)]
    if patch_size == 32 and k3 is not None:
        raise TGHopError("--k3 applies to --patch-size 64 only (three hops)")
    channels = tuple(d if g is None else g for g, d in zip(given, defaults))
    return TGHop(
        patch_size=patch_size, stride=stride, n_channels=channels, gamma=gamma, n_clusters=n_clusters,
        n_codewords=n_codewords, cluster_energy=cluster_energy, max_cluster_components=max_cluster_components,
        reject_threshold=reject_threshold, max_patches=max_patches, residual=residual,
        detail=defaults_from["detail"], rng=fit_seed,
    )


def load_exemplar(spec: str):
    """An image file, or ``builtin:NAME`` for a built-in exemplar."""
    from .data import builtin
    from .imageio import load_image

    if spec.startswith("builtin:"):
        return builtin(spec.split(":", 1)[1])
    return load_image(spec)


def is_model_file(path: str) -> bool:
    """True if ``path`` is a zip archive (an ``.npz``), which only a model can be here."""
    import zipfile

    p = Path(path)
    return p.is_file() and zipfile.is_zipfile(p)


def summary(model) -> str:
    d = model.dims_
    params = model.n_parameters()
    dims = " -> ".join(f"D{i}={d[f'D{i}']}" for i in range(len(model.channels_) + 1))
    ks = ", ".join(f"K{i + 1}={k}" for i, k in enumerate(model.channels_))
    return (
        f"dimensions: {dims}, D_r={d['D_r']}  ({ks})\n"
        f"core model: N={d['N']} clusters, F={d['F']} CDFs, W={d['W']} codewords\n"
        f"parameters: {params['total']['stored']:,} stored ({params['total']['paper']:,} by the paper's formulas)"
    )


def check_output(path: str, allow_stdout=False):
    from .imageio import check_output_path, output_format

    if path == "-" and not allow_stdout:
        raise TGHopError("this command cannot write to stdout; give a file name with -o")
    output_format(path)
    if path != "-":
        check_output_path(path)


# ------------------------------------------------------------------ commands
@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="tghop")
def main():
    """tghop: explainable, fast texture synthesis from one exemplar (TGHop).

    \b
    Quick start:
      tghop synth builtin:bricks -o bricks.png --size 512x512
      tghop synth my_texture.jpg -o out.png --count 4 --seed 7 --tile
    """


@main.command()
@click.argument("exemplar")
@click.option("-o", "--output", required=True, help="Model file to write (any name, e.g. model.npz).")
@model_options
@click.option("-q", "--quiet", is_flag=True, help="No progress bars.")
def fit(exemplar, output, quiet, **options):
    """Learn a model from EXEMPLAR (an image file or builtin:NAME) and save it."""
    from .imageio import check_output_path
    from ._common import ModelFileError
    from .modelfile import save_model

    progress = Progress(not quiet)
    with user_errors(progress):
        image = prepare_exemplar(load_exemplar(exemplar))
        model = build_model(**options, n_colours=image.shape[2])
        check_output_path(output, what="model", error=ModelFileError)  # before the fit, not after
        model.fit(image, progress=progress)
        progress.close()
        save_model(model, output)
    click.echo(summary(model), err=True)
    click.echo(f"model written to {output}", err=True)


@main.command()
@click.argument("model_file", metavar="MODEL")
@click.option("-n", "--count", "n", type=click.IntRange(min=1, max=10000), default=64, show_default=True,
              help="Patches to generate.")
@click.option("-o", "--output", required=True, help="Grid image to write (.png or .jpg; - for stdout).")
@click.option("--seed", type=click.IntRange(min=0), default=None, help="Seed (same seed, same patches).")
@click.option("--stages", is_flag=True,
              help="Also write OUTPUT_stages: per sample the core DC map, the S1 DC map and the patch (paper Fig. 6).")
def patches(model_file, n, output, seed, stages):
    """Generate N patches from a saved MODEL and write them as a grid image."""
    from .imageio import save_image
    from .modelfile import load_model
    from .patches import patch_grid

    with user_errors():
        check_output(output, allow_stdout=not stages)
        model = load_model(model_file)
        if stages:
            samples, views = model.sample_patches(n, rng=seed, return_stages=True)
        else:
            samples = model.sample_patches(n, rng=seed)
        save_image(patch_grid(samples), output)
        if stages:
            path = Path(output)
            stage_path = path.with_name(f"{path.stem}_stages{path.suffix}")
            save_image(stage_sheet(views, model.patch_size), stage_path)
            click.echo(f"stage views written to {stage_path}", err=True)
    if output != "-":
        click.echo(f"{n} patches written to {output}", err=True)


def stage_sheet(views, patch_size):
    """One row per sample: each DC map (grey, enlarged to the patch size) then the patch."""
    from .patches import patch_grid

    columns = []
    for name, maps in views.items():
        if name == "S0":
            columns.append(maps)
            continue
        scale = patch_size // maps.shape[1]
        big = np.repeat(np.repeat(maps, scale, axis=1), scale, axis=2)
        grey = np.clip(big, 0.0, 1.0)[..., None]
        columns.append(np.repeat(grey, views["S0"].shape[3], axis=3))
    rows = np.stack(columns, axis=1).reshape((-1,) + views["S0"].shape[1:])
    return patch_grid(rows, n_cols=len(columns))


@main.command()
@click.argument("source")
@click.option("-o", "--output", required=True,
              help="Image to write (.png/.jpg); with --count > 1 numbered name_1.png, ...; - writes PNG to stdout.")
@click.option("--size", type=Size(), default="256x256", show_default=True, help="Output HEIGHTxWIDTH.")
@click.option("--count", type=click.IntRange(min=1, max=MAX_COUNT), default=1, show_default=True,
              help="Number of images.")
@click.option("--seed", type=click.IntRange(min=0), default=None, help="Seed of generation.")
@click.option("--tile", is_flag=True, help="Make the images wrap around seamlessly (tileable).")
@click.option("--pool", type=click.IntRange(min=1, max=200000), default=10000, show_default=True,
              help="Generated patches quilted into each image.")
@click.option("--overlap", type=click.IntRange(min=1), default=None, help="Quilting overlap (default patch/6).")
@click.option("--tolerance", type=click.FloatRange(min=0), default=0.1, show_default=True,
              help="Quilting: choose among patches within (1+tolerance) of the best match.")
@click.option("--detail", type=click.FloatRange(min=0, max=1, max_open=True), default=None,
              help="Quilting: choose only among candidates whose gradient energy is at or above this quantile "
                   "of theirs [default: the model's, 0.5; 0 (the paper's uniform choice) with --paper].")
@click.option("--match-colours/--no-match-colours", default=None,
              help="Match the result's colour histograms to the exemplar's [default: on; off with --paper].")
@click.option("--save-model", type=click.Path(dir_okay=False), default=None,
              help="When SOURCE is an image, also save the fitted model here.")
@model_options
@click.option("-q", "--quiet", is_flag=True, help="No progress bars.")
def synth(source, output, size, count, seed, tile, pool, overlap, tolerance, detail, match_colours, save_model,
          quiet, **options):
    """Synthesize texture images from SOURCE: an exemplar image, builtin:NAME, or a saved model."""
    from .imageio import save_image
    from .modelfile import load_model, save_model as write_model
    from .quilting import MAX_PIXELS

    progress = Progress(not quiet)
    with user_errors(progress):
        check_output(output, allow_stdout=True)
        if output == "-" and count > 1:
            raise TGHopError("--count > 1 cannot write to stdout; give a file name with -o")
        if size[0] * size[1] > MAX_PIXELS:
            raise TGHopError(f"--size {size[0]}x{size[1]} exceeds the limit of {MAX_PIXELS:,} pixels; choose a smaller size")
        if not source.startswith("builtin:") and is_model_file(source):
            model = load_model(source)
        else:
            image = prepare_exemplar(load_exemplar(source))
            model = build_model(**options, n_colours=image.shape[2])
            model.fit(image, progress=progress)
            if save_model:
                write_model(model, save_model)
        if match_colours is None:
            match_colours = not options["paper"]
        if detail is None and options["paper"]:
            detail = 0.0
        rng = np.random.default_rng(seed)
        outputs = [output] if count == 1 else numbered(output, count)
        for path in outputs:
            image = model.synthesize(size, rng=rng, n_patches=pool, tile=tile, overlap=overlap,
                                     tolerance=tolerance, detail=detail, match_colours=match_colours,
                                     progress=progress)
            progress.close()
            save_image(image, path)
    if output != "-":
        where = outputs[0] if count == 1 else f"{outputs[0]} ... {outputs[-1]}"
        click.echo(f"{count} image{'s' if count > 1 else ''} of {size[0]}x{size[1]} written to {where}", err=True)
        if save_model and not is_model_file(source):
            click.echo(f"model written to {save_model}", err=True)


def numbered(path: str, count: int):
    p = Path(path)
    width = len(str(count))
    return [str(p.with_name(f"{p.stem}_{i:0{width}d}{p.suffix}")) for i in range(1, count + 1)]


@main.command()
@click.argument("model_file", metavar="MODEL")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def info(model_file, as_json):
    """Describe a saved MODEL: settings, dimensions and parameter count (paper Table 4)."""
    from .modelfile import load_model

    with user_errors():
        model = load_model(model_file)
        params = model.n_parameters()
    if as_json:
        click.echo(json.dumps({"params": {k: v for k, v in model.get_params().items() if k != "rng"},
                               "dims": model.dims_, "channels": model.channels_,
                               "exemplar_shape": list(model.exemplar_shape_),
                               "n_parameters": params}, indent=2, default=str))
        return
    h, w, c = model.exemplar_shape_
    click.echo(f"tghop model {model_file}")
    click.echo(f"exemplar: {h}x{w}, {c} channel{'s' if c > 1 else ''}; {model.n_patches_:,} training patches "
               f"of {model.patch_size}x{model.patch_size} at stride {model.stride}")
    click.echo(summary(model))
    click.echo("\nparameters (paper Table 4):")
    click.echo(f"  {'module':<20}{'formula':<16}{'paper formula':>14}{'stored':>12}")
    for name, row in params.items():
        click.echo(f"  {name:<20}{row['formula']:<16}{row['paper']:>14,}{row['stored']:>12,}")


@main.command()
@click.argument("exemplar")
@click.argument("results", nargs=-1, required=True)
@click.option("--json", "as_json", is_flag=True, help="One JSON object per result (JSON lines).")
@click.option("--metrics", "names", default=None,
              help="Comma-separated subset of: sifid, gram, swd, cooccurrence, novelty, copied (default all).")
def evaluate(exemplar, results, as_json, names):
    """Score RESULT images against EXEMPLAR with texture metrics (lower is better but novelty).

    copied: the fraction of 16x16 result patches nearly equal to an exemplar patch (0: all new).

    With two or more results, also their diversity (higher: more different from each other).
    SIFID and the Gram distance need the metrics extra: pip install 'tghop[metrics]'.
    """
    from . import metrics as M

    with user_errors():
        chosen = None if names is None else [n.strip() for n in names.split(",") if n.strip()]
        ex = load_exemplar(exemplar)
        images = [load_exemplar(r) for r in results]
        rows = [(path, M.evaluate(ex, img, metrics=chosen)) for path, img in zip(results, images)]
        div = M.diversity(*images) if len(images) > 1 else None
    skipped = rows[0][1].skipped if rows else {}
    if as_json:
        for path, scores in rows:
            click.echo(json.dumps({"exemplar": exemplar, "result": path, **scores}))
        if div is not None:
            click.echo(json.dumps({"exemplar": exemplar, "results": list(results), "diversity": div}))
    else:
        cols = list(rows[0][1])
        width = max(len("result"), *(len(p) for p, _ in rows))
        click.echo(f"{'result':<{width}}" + "".join(f"{c:>14}" for c in cols))
        for path, scores in rows:
            click.echo(f"{path:<{width}}" + "".join(f"{scores[c]:>14.4g}" for c in cols))
        if div is not None:
            click.echo(f"diversity of the {len(images)} results: {div:.4g}")
    for name, why in skipped.items():
        click.echo(f"Note: {name} skipped: {why}", err=True)


@main.command()
@click.argument("name", type=click.Choice(["crop", "blurred-crop", "colour-noise", "quilting", "ustyuzhaninov"]))
@click.argument("exemplar")
@click.option("-o", "--output", required=True, help="Image to write (.png/.jpg; - for PNG on stdout).")
@click.option("--size", type=Size(), default=None, help="Output HEIGHTxWIDTH (default: the exemplar's).")
@click.option("--seed", type=click.IntRange(min=0), default=None)
@click.option("--iterations", type=click.IntRange(min=1), default=None,
              help="ustyuzhaninov: L-BFGS iterations (default 500; the paper used 2000).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bars.")
def baseline(name, exemplar, output, size, seed, iterations, quiet):
    """Make a reference texture from EXEMPLAR with baseline NAME.

    \b
    crop           a random crop of the exemplar (best case)
    blurred-crop   a blurred crop
    colour-noise   noise with the exemplar's colour mean and covariance (worst case)
    quilting       classic image quilting of the exemplar's own patches
    ustyuzhaninov  single-layer random CNN, Gram loss, L-BFGS (needs the metrics extra)
    """
    from .baselines import BASELINES
    from .imageio import save_image

    progress = Progress(not quiet)
    with user_errors(progress):
        check_output(output, allow_stdout=True)
        if iterations is not None and name != "ustyuzhaninov":
            raise TGHopError("--iterations applies to the ustyuzhaninov baseline only")
        ex = load_exemplar(exemplar)
        kwargs = {"n_iter": iterations} if iterations is not None else {}
        image = BASELINES[name](ex, size, rng=seed, progress=progress, **kwargs)
        progress.close()
        save_image(image, output)
    if output != "-":
        click.echo(f"{name} result written to {output}", err=True)


if __name__ == "__main__":  # pragma: no cover
    main()
