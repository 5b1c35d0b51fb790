"""``tghop evaluate`` and ``tghop baseline``: texture metrics, and the reference points
tghop is compared with."""

from __future__ import annotations

import json

import click

from .._formats import OUTPUT_HELP
from .lines import say
from .common import (Progress, check_output, check_outputs, check_stdout, fail, load_exemplar, stop_message,
                     user_errors, warn_written_with_8, examples)
from .options import QUIET_OPTION, Size, depth_option, scale_option

__all__ = ["evaluate", "baseline"]


@click.command(short_help='Score result images against their exemplar (texture metrics)', epilog=examples(
    "# two results scored against the exemplar, and their diversity",
    "tghop evaluate builtin:bricks out_1.png out_2.png",
    "# many results: a JSON line each, without the pairwise diversity",
    "tghop evaluate texture.jpg out_*.png --no-diversity --json > scores.jsonl"))
@click.argument("exemplar")
@click.argument("results", nargs=-1, required=True)
@click.option("--json", "as_json", is_flag=True,
              help="One JSON object per result (JSON lines), then with several results one of their diversity; "
                   "a score that is not a finite number is null.")
@click.option("--csv", "as_csv", is_flag=True,
              help="CSV: a header (exemplar, result, the metrics), then one row per result; with several results "
                   "a diversity column, filled on a last row whose result is empty. A score that is not a finite "
                   "number is an empty cell.")
@click.option("--metrics", "names", default=None,
              help="Comma-separated subset of: sifid, gram, swd, cooccurrence, novelty, copied, copied_textured "
                   "(default all of these), and self_repetition (only when named).")
@click.option("--no-diversity", "no_diversity", is_flag=True,
              help="Leave out the diversity of several results: it compares every pair of them, so its time grows "
                   "with the square of their number (190 pairs for 20 results, 4,950 for 100).")
@click.option("--repetition", is_flag=True,
              help="Also score each result's self_repetition (added to --metrics or to the default set).")
@scale_option("Score against EXEMPLAR resampled by this factor: the working scale the results were made at "
              "(tghop synth --scale).")
@QUIET_OPTION
def evaluate(exemplar, results, as_json, as_csv, names, no_diversity, repetition, scale, quiet):
    """Score RESULTS against EXEMPLAR with texture metrics: lower is better, except novelty (the
    distance to the nearest exemplar patch: higher is newer).

    copied: the fraction of 16x16 result patches nearly equal to an exemplar patch (0: all new).

    copied_textured: the same over the result's textured 16x16 windows only (the root mean
    square of the colour channels' standard deviations over the window at least 0.06): a flat
    window, of any colour, matches any flat window of its colour and says nothing of copying.

    self_repetition (opt-in: --repetition or --metrics self_repetition): the fraction of a
    result's textured 16x16 windows that recur elsewhere in the same result (about 1 for a
    tiling of one crop, 0 for no repetition). It looks at the result alone, not the exemplar:
    asked alone, it takes an exemplar of any size.

    With two or more results, also their diversity (higher: more different from each other):
    every pair of results is compared, so with many results it takes longer than the scores
    themselves; --no-diversity leaves it out.
    SIFID and the Gram distance need the metrics extra: pip install 'tghop[metrics]'.

    Each result's row is written as soon as it is scored (the diversity last): Ctrl-C keeps
    the rows written, whole lines, and says how many; running the command again scores every
    result again.

    Large images: memory stays bounded. Images above 512x512 pixels are scored in strips
    (sifid, cooccurrence) or tiles of 256x256 positions (gram, above 310x310), which gives
    the same scores up to float rounding; smaller images are scored in one piece. swd,
    novelty, copied, copied_textured and diversity sample a fixed number of patches
    (seed 0) at any size; novelty, copied, copied_textured and diversity search every
    exemplar patch, so their time grows with the exemplar. self_repetition samples 500
    windows and searches the central 1024x1024 of the result (seconds at any size).
    Images over 8192x8192 pixels are refused.
    """
    from .. import metrics as M
    from ..scale import rescale

    progress = Progress(not quiet)
    with user_errors(progress):
        if as_json and as_csv:
            raise click.UsageError("--json and --csv: give one (the scores are written in one format)")
        check_stdout("the scores (JSON lines)" if as_json else "the scores (CSV)" if as_csv else "the table of scores")
        chosen = None if names is None else [n.strip() for n in names.split(",") if n.strip()]
        if chosen == []:
            raise click.UsageError(f"--metrics is empty; give one or more of: "
                                   f"{', '.join([*M.METRICS, *M.RESULT_METRICS])}")
        if chosen is not None:
            M.check_sizes({}, chosen)  # unknown names: refused before any image is read
        checked = None if chosen is None and not repetition else [*(chosen or M.METRICS)]
        if repetition and "self_repetition" not in checked:
            checked.append("self_repetition")
        ex = rescale(load_exemplar(exemplar), scale)
        # 8-bit results held as uint8 (an eighth of float64): converted one at a time as they are scored
        images = [load_exemplar(r, dtype=None) for r in results]
        scaled = exemplar if scale == 1 else f"{exemplar} at --scale {scale:g}"
        M.check_sizes({scaled: ex.shape}, checked, exemplar=scaled)  # as large as the metrics that use it need
        with_diversity = len(images) > 1 and not no_diversity
        M.check_sizes({r: img.shape for r, img in zip(results, images)}, checked, diversity=with_diversity,
                      exemplar=None)
        out = ScoreWriter(exemplar, results, "csv" if as_csv else "json" if as_json else "table",
                          with_diversity=with_diversity)
        scored = 0
        try:
            for i, (path, img) in enumerate(zip(results, images), start=1):
                if len(images) > 1:
                    def step(stage, done, total, _i=i):
                        progress(f"{stage} {_i}/{len(images)}", done, total)
                else:
                    step = progress
                scores = M.evaluate(ex, img, metrics=chosen, repetition=repetition, progress=step)
                progress.close()  # the bar's line ends before the row (both on one terminal)
                out.row(path, scores)
                scored = i
            div = M.diversity(*images, progress=progress) if with_diversity else None
            progress.close()
        except KeyboardInterrupt as exc:
            progress.close()
            message, code = stop_message(exc)
            n = len(results)
            during = " (during their diversity)" if scored == n and with_diversity else ""
            written = ", their rows written" if scored else ""
            fail(f"{message} after {scored} of {n} result{'s' if n != 1 else ''} scored{during}{written}; "
                 "running the same command again scores them all again", code)
        out.end(div)
    for name, why in out.skipped.items():
        say(f"Note: {name} skipped: {why}")


class ScoreWriter:
    """Writes ``tghop evaluate``'s scores as each result is scored, one whole line at a time,
    flushed (``click.echo``): the rows of a run stopped by Ctrl-C or a crash stay.

    ``fmt``: ``"table"`` (the header with the first row: its columns are the first result's
    scores, the metrics not skipped), ``"json"`` (JSON lines) or ``"csv"`` (a header, one row a
    result; with the diversity, a ``diversity`` column filled on a last row whose ``result`` is
    empty). A score that is not a finite number is ``null`` in JSON, an empty cell in CSV.
    """

    def __init__(self, exemplar, results, fmt, *, with_diversity):
        self.exemplar, self.results, self.fmt, self.with_diversity = exemplar, list(results), fmt, with_diversity
        self.cols = None
        self.skipped = {}
        self.width = max(len("result"), *(len(p) for p in self.results))

    def row(self, path, scores):
        """The row of the result at ``path``; before the first, the header."""
        if self.cols is None:
            self.cols = list(scores)
            self.skipped = scores.skipped
            self.sides = [max(14, len(c) + 2) for c in self.cols]  # a long name (copied_textured) keeps a gap
            if self.fmt == "table":
                say(f"{'result':<{self.width}}" + "".join(f"{c:>{n}}" for c, n in zip(self.cols, self.sides)),
                    err=False)
            elif self.fmt == "csv":
                self._csv(["exemplar", "result", *self.cols, *(["diversity"] if self.with_diversity else [])])
        if self.fmt == "json":
            click.echo(json.dumps({"exemplar": self.exemplar, "result": path, **_finite(scores)}, allow_nan=False))
        elif self.fmt == "csv":
            self._csv([self.exemplar, path, *(_csv_number(scores[c]) for c in self.cols),
                       *([""] if self.with_diversity else [])])
        else:
            say(f"{path:<{self.width}}" + "".join(f"{scores[c]:>{n}.4g}" for c, n in zip(self.cols, self.sides)),
                err=False)

    @staticmethod
    def _csv(cells):
        import csv
        import io

        line = io.StringIO()
        csv.writer(line, lineterminator="\n").writerow(cells)
        click.echo(line.getvalue(), nl=False)  # the whole line in one write

    def end(self, div):
        """The rows after every result's: their diversity (``div``, None without it)."""
        if div is None:
            return
        if self.fmt == "json":
            click.echo(json.dumps({"exemplar": self.exemplar, "results": self.results, "diversity": div}))
        elif self.fmt == "csv":
            self._csv([self.exemplar, "", *([""] * len(self.cols)), _csv_number(div)])
        else:
            say(f"diversity of the {len(self.results)} results: {div:.4g}", err=False)


def _finite(scores):
    """JSON has no Infinity or NaN (json.dumps wrote them, which parsers refuse): null instead."""
    return {k: v if v == v and abs(v) != float("inf") else None for k, v in scores.items()}


def _csv_number(value) -> str:
    """A score in a CSV cell: the shortest text that reads back as the same float (as JSON
    writes it); empty when it is not a finite number."""
    return repr(float(value)) if value == value and abs(value) != float("inf") else ""


def check_iterations(name, iterations):
    """Refuse (a usage error, exit status 2) more ``--iterations`` than baseline ``name`` runs."""
    from ..baselines import USTYUZHANINOV_MAX_ITER
    from ..cooc.config import MAX_STEPS
    from ..gpdm import GPDM_MAX_STEPS

    high = {"ustyuzhaninov": USTYUZHANINOV_MAX_ITER, "cooc": MAX_STEPS, "gpdm": GPDM_MAX_STEPS}.get(name)
    if iterations is not None and high is not None and iterations > high:
        raise click.BadParameter(f"the {name} baseline runs at most {high:,}, got {iterations:,}; give a smaller "
                                 "count", param_hint="'--iterations'")


@click.command(short_help='Make a reference texture with another method, to compare', epilog=examples(
    "# classic image quilting of the exemplar's own patches",
    "tghop baseline quilting builtin:bricks -o quilted.png --seed 0",
    "# a random crop of the exemplar: the best case a method can reach",
    "tghop baseline crop texture.jpg -o crop.png --size 128"))
@click.argument("name", type=click.Choice(["crop", "blurred-crop", "colour-noise", "quilting", "ustyuzhaninov",
                                           "cooc", "gpdm"]))
@click.argument("exemplar")
@click.option("-o", "--output", required=True, help=f"{OUTPUT_HELP}; - for PNG on stdout).")
@click.option("--size", type=Size(), default=None, help="Output HEIGHTxWIDTH (default: the exemplar's).")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed: the same seed gives the same image; without it every run differs.")
@click.option("--iterations", type=click.IntRange(min=1), default=None,
              help="ustyuzhaninov: L-BFGS iterations (default 500, at most 20,000; the paper used 2000). "
                   "cooc: training steps (default 5500, at most 150,000; not with --model). "
                   "gpdm: Adam steps per pyramid level (default 300, at most 3,000).")
@click.option("--model", "model_file", default=None, metavar="CHECKPOINT",
              help="cooc: a checkpoint from 'tghop cooc train' on this EXEMPLAR to generate from instead of training.")
@click.option("--assembly", type=click.Choice(["quilt", "pass", "windows"]), default=None,
              help="cooc: how the image is made from the generator: quilt (default: generated training-size "
                   "crops stitched by image quilting), pass (the paper's: one pass over the whole condition), "
                   "windows (that condition in training-size windows).")
@depth_option("8")
@QUIET_OPTION
def baseline(name, exemplar, output, size, seed, iterations, model_file, assembly, depth, quiet):
    """Make a reference texture from EXEMPLAR with baseline NAME.

    \b
    crop           a random crop of the exemplar (best case)
    blurred-crop   a blurred crop
    colour-noise   noise with the exemplar's colour mean and covariance (worst case)
    quilting       classic image quilting of the exemplar's own patches
    ustyuzhaninov  single-layer random CNN, Gram loss, L-BFGS (needs the metrics extra)
    cooc           co-occurrence cGAN (Darzi et al.): trains first (about 15 min on a 2-core CPU, 0.13),
                   or --model (a checkpoint of 'tghop cooc train'); metrics extra
    gpdm           GPDM (Elnekave & Weiss): patch sliced-Wasserstein matching, coarse to fine, Adam on the
                   pixels; 12 levels x 300 steps: ~12 min at 128x128 on 2 busy cores (0.13; metrics extra)

    Sizes whose estimated memory exceeds the memory available are refused at once.
    """
    from ..baselines import BASELINES
    from ..imageio import check_depth, save_image

    progress = Progress(not quiet)
    with user_errors(progress):
        check_output(output, allow_stdout=True, depth=depth)
        check_depth(output, depth or 8)
        check_outputs([("-o", output)], [("EXEMPLAR", exemplar), ("--model", model_file)])
        if iterations is not None and name not in ("ustyuzhaninov", "cooc", "gpdm"):
            raise click.UsageError("--iterations applies to the ustyuzhaninov, cooc and gpdm baselines only")
        for option, value in (("--model", model_file), ("--assembly", assembly)):
            if value is not None and name != "cooc":
                raise click.UsageError(f"{option} applies to the cooc baseline only")
        check_iterations(name, iterations)
        if iterations is not None and model_file is not None:
            raise click.UsageError("--iterations applies to the cooc baseline without --model only (it sets the "
                                   "training steps; the checkpoint is trained already)")
        ex, own = load_exemplar(exemplar, with_depth=True)
        if own > 8 and depth is None:
            warn_written_with_8("EXEMPLAR", exemplar, output)
        kwargs = {"n_iter": iterations} if iterations is not None else {}
        if name == "gpdm":
            kwargs = {"n_steps": iterations} if iterations is not None else {}
        if name == "cooc":
            from .._images import check_size, check_texture
            from .._resources import check_memory, import_torch
            from ..cooc import SMALL, load
            from ..cooc.model import memory_estimate

            kwargs = {"n_steps": iterations, "model": None if model_file is None else load(model_file),
                      "assembly": assembly or "quilt"}
            if model_file is None:
                # the checks baseline() makes, made here first so that the note comes only before a training
                import_torch("the co-occurrence cGAN")
                check_texture(ex)
                check_memory(memory_estimate(ex.shape, assembly=kwargs["assembly"]),
                             check_size(size, default=ex.shape[:2], name="--size"), what="the cooc baseline",
                             name="--size")
                steps = SMALL["n_steps"] if iterations is None else iterations
                minutes = 15.0 * steps / SMALL["n_steps"]
                when = f"about {minutes:.0f} minutes" if minutes >= 1.5 else "about a minute or less"
                say(f"Note: no --model: training the co-occurrence cGAN first ({steps} "
                    f"step{'s' if steps != 1 else ''}, {when} on a 2-core CPU); to reuse it, train once with "
                    "'tghop cooc train' and pass --model")
        image = BASELINES[name](ex, size, rng=seed, progress=progress, **kwargs)
        progress.close()
        save_image(image, output, depth=depth or 8, progress=progress)
    if output != "-":
        say(f"{name} result written to {output}")
