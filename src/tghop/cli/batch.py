"""``tghop batch``: a model and N images for every exemplar of a folder or manifest
(:func:`tghop.batch.run`), in this process or on Dask."""

from __future__ import annotations

import contextlib
import math
import os
import re
import sys

import click

from .._errors import TGHopError
from ..fit_options import fit_params
from .help_sections import COMMON, SectionedCommand
from .lines import say
from .common import Progress, examples, fail, quiet_tifffile, stop_message, user_errors
from .options import MAX_COUNT, QUIET_OPTION, Size, generation_options, generation_params, model_options

__all__ = ["batch"]

#: The exit status of a run whose Dask scheduler went away mid-run (0.58; 0.57: 1, as for failed exemplars):
#: nothing to fix in the exemplars, run the same command again once the scheduler is back.
SCHEDULER_LOST = 3
#: How to try the known failures again, said wherever they are skipped.
RETRY_HINT = "--retry-failed tries them again"
#: The summary's failures (and warnings) alike: up to APART a line each, more on one line naming SHOWN of the
#: others (:func:`alike_lines`).
ALIKE_APART, ALIKE_SHOWN = 3, 5


class BatchProgress(Progress):
    """The bar over exemplars, with how many failed and are running, and the time left; where
    stderr is no terminal (a log), a line at each tenth of the exemplars instead."""

    def __init__(self, enabled):
        super().__init__(enabled, show_eta=True)
        self.note = ""
        self.lines = enabled and not sys.stderr.isatty()  # click draws no bar there: a log showed nothing for hours
        self.last = self.planned = None
        self.failed = self.running = 0

    def __call__(self, stage, done, total):
        self.last = {"done": done, "total": total}  # for the line after Ctrl-C, with or without a bar
        if not self.lines:  # into a log click's bar wrote its label alone on a line ("exemplars     ") and no more
            super().__call__(stage, done, total)
        elif done and (done == total or done % -(-total // 10) == 0):
            # "finished", the failed among them: "306 of 306 done, 49 failed" read as 306 made, where the
            # summary's "257 of 306 exemplars done" counts those that succeeded
            say(f"{stage}: {done:,} of {total:,} finished ({done - self.failed:,} done, {self.failed:,} "
                f"failed), {self.running} running")

    def result(self, record, counts):
        self.failed, self.running = counts["failed"], counts["running"]
        self.note = f"{self.failed} failed, {self.running} running"

    def plan(self, plan):
        """Before the bar, what an earlier run did (the bar counts this run's exemplars alone: a rerun's
        bar of 50 read as the whole batch of 1,250)."""
        self.planned = plan  # for the line after Ctrl-C, -q too
        if self.enabled and (plan["done_before"] or plan["failed_before"]):
            say(plan_line(plan))


def plan_line(plan) -> str:
    """``1,200 of 1,250 exemplars already done; 50 to make`` (and the known failures skipped)."""
    before = f"{plan['done_before']:,} of {_exemplars(plan['exemplars'])} already done"
    if plan["failed_before"]:
        before += f", {plan['failed_before']:,} skipped as failed before ({RETRY_HINT})"
    to_make = f"{plan['to_do']:,} to make" if plan["to_do"] else "nothing to make"
    return f"{before}; {to_make}"


def stopped_line(plan, last, failed) -> str:
    """Where a stopped run got to, for the line after Ctrl-C: `` after 3 of 50 exemplars`` (this
    run's ``last`` progress), and where an earlier run did some the whole batch's too: `` after 3
    made in this run (50 to make); 1,203 of 1,250 exemplars done in all`` (``failed``: how many of
    this run's failed, said apart); "" before any work."""
    if not last:
        return ""
    if not plan or not (plan["done_before"] or plan["failed_before"]):
        return f" after {last['done']:,} of {_exemplars(last['total'])}"
    made = last["done"] - failed
    failures = f" and {failed:,} failed" if failed else ""
    return (f" after {made:,} made{failures} in this run ({last['total']:,} to make); "
            f"{plan['done_before'] + made:,} of {_exemplars(plan['exemplars'])} done in all")


@click.command(short_help='Fit many exemplars (a folder or a manifest) and make their images', epilog=examples(
    "# every image under textures/: its model and two 512x512 images, all cores",
    "tghop batch textures/ -o results --count 2 --size 512 --seed 1",
    "# a manifest (CSV with a path column), in this process, without Dask",
    "tghop batch list.csv -o results --workers 1",
    "# then open results/index.html: every exemplar's thumbnail and images"), cls=SectionedCommand,
    common=COMMON["batch"])
@click.argument("source")
@click.option("-o", "--outdir", required=True,
              help="Folder for the results: OUTDIR/NAME/ per exemplar, the ledger batch.jsonl, the contact "
                   "sheet index.html.")
@click.option("--count", type=click.IntRange(min=1, max=MAX_COUNT), default=1, show_default=True,
              help="Images per exemplar (a manifest row may give its own).")
@click.option("--size", type=Size(), default="256x256", show_default=True,
              help="Output HEIGHTxWIDTH (a manifest row may give its own).")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed of generation for every exemplar; without it each gets a fresh one, recorded in the ledger.")
@generation_options
@model_options
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Worker processes of the local Dask cluster [default: one per core; at most 4 per core]; 1 runs "
                   "in this process, without Dask.")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run on an existing dask.distributed scheduler (e.g. tcp://host:8786) instead.")
@click.option("--retries", type=click.IntRange(min=0, max=20), default=3, show_default=True,
              help="Times a task whose worker died (killed, out of memory) runs again on another worker of the "
                   "local cluster before it is recorded as failed.")
@click.option("--prune", is_flag=True,
              help="Delete the folders an earlier run made in OUTDIR for exemplars no longer in SOURCE (only the files "
                   "its ledger lists; a folder holding other files stays), but not those whose source folder is "
                   "missing (see --force) or unreadable. Without it they are kept and named.")
@click.option("--force", is_flag=True,
              help="With --prune: also the folders of exemplars whose source folder is missing (a share down keeps "
                   "them without it), however many; never those whose source folder cannot be read.")
@click.option("--max-depth", type=click.IntRange(min=0), default=None, metavar="N",
              help="Levels of subfolders of a folder SOURCE searched for exemplars: 0 its own images only, 1 its "
                   "subfolders' too, ... [default: every level]")
@click.option("--retry-failed", is_flag=True,
              help="Try again the exemplars that failed before for a cause in their input (not an image, flat, too "
                   "small; a worker dead on every try in 3 runs in a row; stopped by --task-timeout) although their "
                   "files and settings are unchanged; without it a rerun skips them.")
@click.option("--task-timeout", type=click.FloatRange(min=0, min_open=True), default=None, metavar="SECONDS",
              help="Stop an exemplar's task after SECONDS and record it as that exemplar's failure (a rerun skips it "
                   "until it changes, a longer timeout or --retry-failed); on Dask its worker is restarted, and the "
                   "run goes on [default: no limit].")
@QUIET_OPTION
def batch(source, outdir, count, size, seed, workers, scheduler, retries, prune, force, max_depth, retry_failed,
          task_timeout, quiet, **options):
    """Fit every exemplar of SOURCE and write its model and COUNT images to OUTDIR.

    SOURCE is a folder (every image in it, recursively) or a manifest: a CSV file with a
    'path' column, or JSON lines {"path": ...}; optional per-exemplar size, count, seed,
    tile, scale (the working scale, as --scale) and name. --max-depth limits how deep a
    folder is searched. A row's 'maps' make it a whole
    material whose albedo is 'path' (as tghop fit --maps): in CSV the maps' files separated
    by ';', each optionally name=file (normal=rock_n.png;rock_h.png), in JSON an object
    {"normal": "rock_n.png"} or a list; each image is then NAME.png and NAME_<map>.png (the
    prefix the maps' names share dropped, as tghop synth names them). A
    rerun skips exemplars already done with the same input (maps too) and settings, and
    those whose input failed (not an image, flat, too small) unless it changed or
    --retry-failed is given. Exit status 1 when any exemplar failed, now or before (the
    ledger and the summary say why); 3 when the Dask scheduler (--scheduler) went away
    mid-run: run the same command again once it is back.
    """
    from .. import batch as library
    from ..batch_plan import check_outdir

    progress = BatchProgress(not quiet)
    orphans = []
    with user_errors(progress):
        if scheduler is not None and workers is not None:
            raise click.UsageError("--workers and --scheduler: the scheduler's cluster has its own workers; give one")
        if force and not prune:
            raise click.UsageError("--force is for --prune (it removes the folders --prune keeps for a source folder "
                                   "missing); give both, or neither")
        if max_depth is not None and os.path.isfile(source):
            raise click.UsageError(f"--max-depth is for a folder SOURCE; the manifest {source} lists its files: drop "
                                   "--max-depth (the manifest's rows are the exemplars)")
        try:  # options that do not go together, as --max-depth with a manifest (0.63; 0.62: exit status 1)
            check_outdir(source, outdir)
        except TGHopError as exc:
            raise click.UsageError(str(exc)) from None
        if task_timeout is not None and not math.isfinite(task_timeout):
            raise click.UsageError(f"--task-timeout {task_timeout}: give a number of seconds (e.g. 3600), or leave it "
                                   "out for no limit")
        generate = generation_params(options)
        fit = fit_params(options)
        quiet_tifffile()  # the exemplars read in this process (one worker); a local cluster's workers: worker_setup
        if workers != 1 or scheduler is not None:
            import logging

            with contextlib.suppress(ImportError):  # first: its import sets its loggers' levels (dask's config)
                import distributed  # noqa: F401
            logging.getLogger("distributed").setLevel(logging.ERROR)  # workers' deaths are in the ledger
            # its "Failed to reconnect to scheduler ..., closing client": the run's one line says the scheduler lost
            logging.getLogger("distributed.client").setLevel(logging.CRITICAL)
        try:
            results = library.run(source, outdir, count=count, size=size, seed=seed, tile=generate.pop("tile"),
                                  fit=fit, generate=generate, workers=workers, scheduler=scheduler, retries=retries,
                                  progress=progress, on_result=progress.result, prune=prune, force=force,
                                  on_orphans=orphans.extend, retry_failed=retry_failed, max_depth=max_depth,
                                  on_plan=progress.plan, worker_setup=quiet_tifffile, task_timeout=task_timeout)
        except library.SchedulerLostError as exc:  # its own status: "run it again", not "look at the failures"
            progress.close()
            fail(str(exc), SCHEDULER_LOST)
        except KeyboardInterrupt as exc:
            progress.close()
            message, code = stop_message(exc)
            # this run's count alone read as the whole batch's ("after 3 of 50" of a batch of 1,250 nearly done)
            where = stopped_line(progress.planned, progress.last, progress.failed)
            fail(f"{message}{where}; run the same command again to finish the rest", code)
    # what the workers warned of (an alpha channel dropped), by exemplar as the failures below (a/x.png and
    # b/x.png: "x.png: ..."), those alike on one line
    warned = [(r, message) for r in results if not r.get("skipped") for message in r.get("warnings") or []]
    for line in alike_lines(warned):
        say(f"Warning: {line}")
    failed = [r for r in results if r["status"] != "ok"]
    known = [r for r in failed if r.get("skipped")]  # failed before, input unchanged: not tried, not listed again
    skipped = sum(bool(r.get("skipped")) for r in results) - len(known)
    ok = len(results) - len(failed)
    earlier = f" ({skipped:,} by an earlier run)" if skipped else ""
    for o in orphans:  # one line each: a log of thousands says which
        said = "removed" if o["pruned"] and not o["kept"] else "kept, not pruned (above)" if o.get("held") else \
            "kept" if not o["pruned"] else \
            f"its files removed, the folder kept for what tghop did not make ({', '.join(o['kept'][:3])})"
        say(f"no longer in SOURCE: {o['name']}: {said}")
    for r in results:  # 0.62: made again under the new name, the old folder kept as no longer in SOURCE (0.61)
        if r.get("renamed"):
            say(f"renamed: {r['renamed_from']} is now {r['name']}: its files moved, not made again")
    say(f"{ok:,} of {_exemplars(len(results))} done{earlier}; results in {outdir}, "
        f"contact sheet {outdir}/index.html{_orphans(orphans)}")
    if known:
        say(f"{len(known):,} skipped as failed before, their input and settings unchanged "
            f"({', '.join(r['name'] for r in known[:3])}{' ...' if len(known) > 3 else ''}; their errors are in "
            f"{outdir}/batch.jsonl); fix or remove them, or {RETRY_HINT}")
    if failed:
        for line in alike_lines([(r, r["error"]) for r in failed if not r.get("skipped")]):
            say(f"failed: {line}")
        said = f"; {len(known):,} of them before" if known else ""
        fail(f"{len(failed):,} of {_exemplars(len(results))} failed{said}: {', '.join(r['name'] for r in failed[:10])}"
             f"{' ...' if len(failed) > 10 else ''} (see {outdir}/batch.jsonl)", 1)


def alike_lines(said, apart=ALIKE_APART, shown=ALIKE_SHOWN):
    """``NAME: MESSAGE`` for each exemplar's message (``said``: ``[(record, message)]``, in the batch's
    order); where more than ``apart`` are alike, one line for them, the first's: ``a: MESSAGE (and 168 more
    like it: b, c, d, e, f, ...)``, at most ``shown`` names. Alike: the same message but for the exemplar's
    own path and the numbers (a size, a count). The summary of 3,000 exemplars listed its 314 failures a line
    each (0.57), of three kinds."""
    groups = {}
    for record, message in said:
        text = str(message)
        source = str(record.get("source") or "")
        key = re.sub(r"\d+", "#", text.replace(source, "\0") if source else text)
        groups.setdefault(key, []).append((record["name"], text))
    for group in groups.values():
        if len(group) <= apart:
            yield from (f"{name}: {text}" for name, text in group)
            continue
        (name, text), *others = group
        more = ", ".join(n for n, _ in others[:shown]) + (", ..." if len(others) > shown else "")
        yield f"{name}: {text} (and {len(others):,} more like it: {more})"


def _orphans(orphans) -> str:
    """The summary's part on the folders of exemplars no longer in SOURCE."""
    if not orphans:
        return ""
    folders = f"{len(orphans)} folder{'s' if len(orphans) != 1 else ''} of exemplars no longer in SOURCE"
    held = sum(bool(o.get("held")) for o in orphans)
    if not any(o["pruned"] for o in orphans) and not held:
        return f"; {folders} kept (--prune removes them)"
    left = sum(bool(o["kept"]) for o in orphans)
    if held:  # 0.62: a source folder missing or unreadable, too many at once (the warnings above say which and why)
        return f"; {folders}: {len(orphans) - left - held} removed, {held} kept, not pruned (above)" + \
            (f", {left} kept for files tghop did not make" if left else "")
    return f"; {folders}: {len(orphans) - left} removed, {left} kept for files tghop did not make" if left else \
        f"; {folders} removed"


def _exemplars(n: int) -> str:
    return f"{n:,} exemplar{'s' if n != 1 else ''}"
