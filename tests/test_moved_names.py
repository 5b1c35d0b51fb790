"""Names that 0.64 moved out of a module at the 850-line limit still import from where they were.

tghop.settings, tghop.inpaint and tghop.cli.common were split by what their parts do (docs/choices.md, "0.64"
in Settings, Inpainting and The command line); a program, a test or a command that imports a moved name from
its old module gets the same object as from its new one. These read nothing of ../shared/ and fit nothing.
"""

import importlib

import pytest

MOVED = {
    "tghop.settings": {
        "tghop.setting": ["Setting", "check_channel_rule"],
        "tghop.rng_records": ["recorded_seed", "fit_seed", "BIT_GENERATORS", "generator_record",
                              "generator_from_record", "generators_given", "generator_records", "set_generators"],
    },
    "tghop.inpaint": {
        "tghop.holes": ["LEVELS", "check_hole", "require_hole", "grey_share", "MASK_BLACK_WHITE",
                        "MASK_PICTURE_SHARE", "split_alpha", "with_alpha", "channel_mismatch"],
    },
    "tghop.cli.common": {
        "tghop.cli.errors": ["Terminated", "stop_message", "fail", "drop_stdout", "output_gone", "os_error_message",
                             "user_errors"],
        "tghop.cli.progress": ["Progress"],
        "tghop.cli.inputs": ["HINT_DOWNSCALE_OPTION", "is_builtin", "quiet_tifffile", "read_image", "load_exemplar",
                             "load_mask"],
        "tghop.cli.outputs": ["check_stdout", "check_output", "check_outputs", "check_model_output", "count_outputs",
                              "numbered", "STAGES", "MATERIAL_STAGES", "stage_paths", "save_with_stages",
                              "tell_steps", "warn_written_with_8", "warn_lost_depth"],
        "tghop.cli.materials": ["refuse_albedo_as_map", "refuse_colour_map_out_of_place", "map_names",
                                "material_outputs", "material_stage_files", "write_materials"],
    },
}


@pytest.mark.parametrize("old", sorted(MOVED))
def test_a_moved_name_imports_from_its_old_module_as_the_same_object(old):
    was = importlib.import_module(old)
    missing = [f"{old}.{name} (now {new})" for new, names in MOVED[old].items() for name in names
               if getattr(was, name, None) is not getattr(importlib.import_module(new), name)]
    assert not missing, missing


@pytest.mark.parametrize("old", sorted(MOVED))
def test_a_moved_name_is_defined_in_its_new_module(old):
    # Where a reader is sent: the new module defines each (its functions and classes name it as theirs).
    elsewhere = [f"{new}.{name}" for new, names in MOVED[old].items() for name in names
                 if getattr(getattr(importlib.import_module(new), name), "__module__", new) not in (new, None)
                 and callable(getattr(importlib.import_module(new), name))]
    assert not elsewhere, elsewhere
