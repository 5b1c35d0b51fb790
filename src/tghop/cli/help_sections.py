"""The ``--help`` of the commands with many options (``synth``, ``fit``, ``batch``): what most users need first.

:class:`SectionedCommand` writes the command's common options with their help, then the others by name only, under
headings (:data:`SECTIONS`: what each group of options changes), then the examples; ``--help-all`` writes every
option's help under the same headings. Every option stays named in ``--help`` (a user who read one in the docs
finds it there, and its heading), and ``--help-all`` holds each one's words (0.64: ``synth --help`` was 356 lines,
its output and seed options among 60 others in the pipeline's order).
"""

from __future__ import annotations

import click

__all__ = ["SectionedCommand", "SECTIONS", "COMMON", "HELP_ALL"]

#: The option that shows every option's help.
HELP_ALL = "--help-all"

#: The headings the options that are not a command's common ones are listed under, in this order, with the options
#: (their parameters' names) each holds; a command lists those it has. Those of no heading: "Other options".
SECTIONS = (
    ("Several SOURCEs", ("guide", "transition", "blob")),
    ("What is written", ("depth", "stages")),
    ("Batch runs", ("workers", "scheduler", "retries", "task_timeout", "max_depth", "retry_failed", "force",
                    "prune")),
    ("Quilting (the patches' placement)", ("n_patches", "overlap", "tolerance", "detail", "flat_share", "reuse",
                                           "pool_per_block", "layout_weight")),
    ("After quilting (seams, refinement, colours)", ("seam_window", "refine", "patch_refine", "patch_stride",
                                                     "region", "match_colours", "own_shares", "layout_refine",
                                                     "layout_patch_refine")),
    ("Fitting (an exemplar's model; fixed in a saved model)", ("paper", "exclude", "downscale", "rng", "patch_size",
                                                                "stride", "layout_factor", "max_patches")),
    ("The model's parts (the paper's Table 4, and ours)", (
        "k1", "k2", "k3", "gamma", "gamma_mode", "n_clusters", "n_codewords", "n_bins", "cluster_energy",
        "max_cluster_components", "max_component_ratio", "norm_match", "coupling", "min_cluster_size",
        "reject_threshold", "ica_max_iter", "ica_tol", "residual", "band_levels", "band_orientations",
        "colour_classes", "patch_levels", "patch_whitening")),
)


#: Each sectioned command's common options (parameters' names), in the order its --help lists them.
COMMON = {
    "synth": ("output", "size", "count", "seed", "tile", "quality", "save_model", "scale", "quiet"),
    "fit": ("output", "with_maps", "scale", "paper", "exclude", "downscale", "quiet"),
    "batch": ("outdir", "count", "size", "seed", "tile", "quality", "scale", "workers", "quiet"),
}


def _show_all(ctx, param, value):
    if not value or ctx.resilient_parsing:
        return
    ctx.meta[HELP_ALL] = True
    click.echo(ctx.get_help(), color=ctx.color)
    ctx.exit()


class SectionedCommand(click.Command):
    """A :class:`click.Command` whose ``--help`` leads with ``common`` (parameter names, in their order: the options
    most users need, with their help), then names the others under the :data:`SECTIONS` headings, and takes
    ``--help-all``: every option's help, under those headings."""

    def __init__(self, *args, common=(), **kwargs):
        super().__init__(*args, **kwargs)
        self.common = tuple(common)
        self.params.append(click.Option([HELP_ALL], is_flag=True, expose_value=False, is_eager=True,
                                        callback=_show_all, help="Show every option's help, under its heading."))

    def sections(self, ctx):
        """``[(heading, [option, ...]), ...]``: the common options (heading "Options"), then each heading's that the
        command has, then "Other options"; the help options last of the first."""
        options = [p for p in self.get_params(ctx) if isinstance(p, click.Option) and not p.hidden]
        by_name = {p.name: p for p in options}
        common = [by_name[n] for n in self.common if n in by_name]
        helps = [p for p in options if p.name == "help_all" or p is self.get_help_option(ctx)]
        out, placed = [("Options", common + helps)], {p.name for p in common + helps}
        for heading, names in SECTIONS:  # each in the command's own order (the pipeline's)
            these = [p for p in options if p.name in names and p.name not in placed]
            placed.update(p.name for p in these)
            if these:
                out.append((heading, these))
        rest = [p for p in options if p.name not in placed]
        if rest:
            out.append(("Other options", rest))
        return out

    def format_options(self, ctx, formatter):
        every = ctx.meta.get(HELP_ALL, False)
        sections = self.sections(ctx)
        for i, (heading, options) in enumerate(sections):
            if every or i == 0:
                with formatter.section(heading):
                    formatter.write_dl([p.get_help_record(ctx) for p in options])
                continue
            with formatter.section(heading):
                _write_names(formatter, [_names(p) for p in options])
        if not every and len(sections) > 1:
            formatter.write_paragraph()
            with formatter.indentation():
                formatter.write_text(f"Each option's help: {ctx.command_path} {HELP_ALL}")


def _names(option) -> str:
    """An option as the short --help names it: its flags (``-N/--clusters``, ``--tile/--no-tile``), no value."""
    return "/".join([*sorted(option.opts, key=len), *option.secondary_opts])


def _write_names(formatter, names):
    """``names`` comma-separated, wrapped at the help's width between names (never inside one, as click's text
    wrapping breaks at a hyphen: ``--flat-`` / ``share``)."""
    indent = " " * formatter.current_indent
    width = max(formatter.width - formatter.current_indent, 20)
    line = ""
    for i, name in enumerate(names):
        word = name + ("," if i < len(names) - 1 else "")
        if line and len(line) + 1 + len(word) > width:
            formatter.write(f"{indent}{line}\n")
            line = word
        else:
            line = f"{line} {word}" if line else word
    if line:
        formatter.write(f"{indent}{line}\n")
