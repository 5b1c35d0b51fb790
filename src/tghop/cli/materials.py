"""A whole material on the command line: its maps' files named and checked (:func:`map_names`,
:func:`refuse_albedo_as_map`, :func:`refuse_colour_map_out_of_place`), and its maps written, OUT and
OUT_<suffix> for each set, with ``--stages``' (:func:`material_outputs`, :func:`material_stage_files`,
:func:`write_materials`).

It stands on :mod:`tghop.cli.outputs` and on the library (0.64: part of :mod:`tghop.cli.common`, which
re-exports its names).
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import click

from .._errors import TGHopError, terminal_line
from .outputs import MATERIAL_STAGES, check_output, check_outputs, stage_paths, warn_lost_depth

__all__ = ["refuse_albedo_as_map", "refuse_colour_map_out_of_place", "map_names", "material_outputs",
           "material_stage_files", "write_materials"]


def refuse_albedo_as_map(paths, albedo_path, *, label: str = "MAP", albedo: str = "IMAGE") -> None:
    """A one-line error where a map's file is the albedo's own (the manifest of ``tghop batch``
    refuses it too): the material had the albedo twice, one copy as a map."""
    for path in paths:
        try:
            same = os.path.samefile(path, albedo_path)
        except OSError:  # a missing file: said where it is read
            continue
        if same:
            raise TGHopError(f"{label} {path} is {albedo} itself, the albedo; give the map's own file")


def refuse_colour_map_out_of_place(albedo_path, paths, *, label: str = "MAP", albedo: str = "IMAGE",
                                   command: str = "tghop fit {} --maps") -> None:
    """The colour map out of place by the files' names (:func:`tghop.map_names.check_colour_map_order`,
    in the command line's words): a one-line error where the albedo's file is named as another kind of map
    and one of the maps as the colour map (the two swapped), or the albedo's file as a normal map and no map
    as the colour map; a one-line warning where the albedo's file is named as another kind
    (``Rock_Roughness.png``) and no map as the colour map (fitted as the colour map, as asked: a material
    may have none). ``command``: the command line up to the maps, ``{}`` where the colour map goes."""
    from ..map_names import check_colour_map_order

    example = command.format("Rock_Color.png")
    said = check_colour_map_order(
        albedo_path, paths, albedo=f"{albedo} {{albedo}}", map=f"{label} {{colour}}", none=f"no {label}",
        swap=command.format("{colour}") + " {others} ...",
        first=f"give the material's colour map first ({example} {{albedo}} ...)", written="written to OUT",
        expected="first", then=f": {example} {{albedo}} {{maps}}")
    if said is not None:
        warnings.warn(said, UserWarning, stacklevel=2)


def map_names(paths, *, label: str = "MAP", albedo: str = "IMAGE") -> list:
    """The names of the maps in files ``paths`` (:func:`tghop.map_names.map_name`), or a one-line
    error where two are one name (in any case) or one is the albedo's (``label``: what the
    command calls a map, ``albedo``: what it calls the albedo)."""
    from ..map_names import MapNameClashError, check_map_names, map_name

    names = [map_name(path) for path in paths]
    try:
        check_map_names(names, paths)
    except MapNameClashError as exc:
        name = exc.name
        if exc.albedo:
            raise TGHopError(f"{label} {paths[exc.index]} is named {name!r}, the name of {albedo} itself (written to "
                             "OUT, the other maps beside it); rename the file") from None
        if exc.cut:
            raise TGHopError(f"{exc.clash}; {exc.fix}") from None
        raise TGHopError(f"{exc.clash}: the file stem names the map and its output file; rename one") from None
    return names


def material_outputs(material, output, depth):
    """``[(name, path, depth)]`` of a material's maps for output ``output``: the albedo at
    ``output``, each other map at ``OUT_<suffix>.EXT`` (:func:`tghop.material_files.map_files`);
    each at ``depth``, or without it at the depth its file had (as far as the format holds it)."""
    from ..imageio import check_depth, deepest
    from ..material_files import map_files

    out = []
    for name, path, own in zip(material.names_, map_files(output, material.names_), material.depths_):
        out.append((name, path, check_depth(path, depth or deepest(path, own))))
    return out


def material_stage_files(output, plan, names):
    """``{step: [(name, path, depth)]}`` of --stages for a material written to ``output`` (``plan``:
    :func:`material_outputs`', ``(name, path, depth)`` of each map, the albedo first): OUT_<step>.EXT for the albedo,
    OUT_<step>_<suffix>.EXT for each other map, at ``plan``'s depths (not :func:`tghop.material_files.map_files`,
    whose colour word would take OUT_colour's maps for OUT's); ``names``: the steps."""
    from ..material_files import map_suffixes

    out = {}
    for step, path in stage_paths(output, names).items():
        p = Path(path)
        out[step] = [(name, path if suffix is None else str(p.with_name(f"{p.stem}_{suffix}{p.suffix}")), d)
                     for (name, _, d), suffix in zip(plan, map_suffixes([name for name, _, _ in plan]))]
    written = {path: name for name, path, _ in plan}  # a map named as a step (Rock_quilt: OUT_quilt): said so
    for step, files in out.items():
        for name, path, _ in files:
            if path in written:
                raise TGHopError(f"map {written[path]} is written as {path}, the name --stages gives the {step} "
                                 f"step's {name}; drop --stages, or give that map's file another name (a saved "
                                 "material's: fit it again)")
    return out


def write_materials(material, output, outputs, size, depth, make, inputs, progress=None, stages=False):
    """Materials' maps, OUT, OUT_<suffix>, ... for each path of ``outputs``: all checked before any
    work (``inputs``: ``(label, path)`` pairs that no output may be), each set made by ``make()``
    (a dict of maps, ``material``'s names) and written together (all or none); then one line
    says what was written. ``material`` names the maps and their depths; ``progress`` (a
    :class:`~tghop.cli.progress.Progress`) shows each set's write. ``stages`` (0.61): ``make()`` gives
    ``(maps, steps)`` (``Material.synthesize(return_stages=True)``'s), each step's maps written as OUT_<step>,
    OUT_<step>_<suffix>; True: the steps :data:`~tghop.cli.outputs.MATERIAL_STAGES`, or a tuple of others (a
    painting's). Returns the first set's step files written (the albedo's; for
    :func:`~tghop.cli.outputs.tell_steps`), none without ``stages``."""
    from ..imageio import save_images

    if output == "-":
        raise click.UsageError("a material writes a file per map; give -o a file name (e.g. -o out.png)")
    plans = [material_outputs(material, path, depth) for path in outputs]
    names = stages if isinstance(stages, tuple) else MATERIAL_STAGES
    staged = [material_stage_files(path, plan, names) for path, plan in zip(outputs, plans)] if stages else [
        {}] * len(outputs)
    steps_planned = [("--stages", path) for steps in staged for plan in steps.values() for _, path, _ in plan]
    for plan in plans:
        for _, path, _ in plan:
            check_output(path, made=path != output)
    for _, path in steps_planned:
        check_output(path, made=True)
    check_outputs([("-o", path) for plan in plans for _, path, _ in plan] + steps_planned, inputs)
    warn_lost_depth([(name, own, d) for (name, _, d), own in zip(plans[0], material.depths_)], output, depth, "map")
    first = []  # the first set's step files written (the albedo's)
    for plan, steps_plan in zip(plans, staged):
        maps, steps = make() if stages else (make(), {})
        if stages:
            first = first or [step_plan[0][1] for step, step_plan in steps_plan.items() if step in steps]
        # each step's maps (a step of one image, a painting's regions: at OUT_<step> alone) and the maps: all or
        # none (0.62; 0.61 wrote the steps first, and kept them where the maps failed)
        save_images([(steps[step][name] if isinstance(steps[step], dict) else steps[step], path, d)
                     for step, step_plan in steps_plan.items() if step in steps
                     for name, path, d in (step_plan if isinstance(steps[step], dict) else step_plan[:1])]
                    + [(maps[name], path, d) for name, path, d in plan], progress=progress)
        if progress is not None:
            progress.close()
    written = ", ".join(path for _, path, _ in plans[0])
    more = f" (and {len(plans) - 1} more set{'s' if len(plans) > 2 else ''})" if len(plans) > 1 else ""
    click.echo(terminal_line(f"{len(plans)} material{'s' if len(plans) > 1 else ''} of {size[0]}x{size[1]} written "
                             f"to {written}{more}"), err=True)
    return first
