"""The files a material's maps are written to (:func:`tghop.material_files.map_files`): ``OUT_<suffix>``,
the material's name and resolution the maps' names share dropped, as the common libraries' sets
(ambientCG, Poly Haven, Substance, Unreal) are named; names that share nothing as they were; no two
maps one file. And the command line's files so named, their pixels as before."""

import numpy as np
import pytest

from tghop import data
from tghop.imageio import load_image, save_image
from tghop.material import example_maps
from tghop.material_files import map_files, map_suffixes


@pytest.mark.parametrize("maps, want", [
    # ambientCG: the material's name and its resolution shared
    (["Rock023_2K_NormalGL", "Rock023_2K_Roughness", "Rock023_2K_Displacement"],
     ["NormalGL", "Roughness", "Displacement"]),
    # Poly Haven: the resolution at the end of each
    (["rock_wall_nor_gl_2k", "rock_wall_rough_2k", "rock_wall_disp_4k"], ["nor_gl", "rough", "disp"]),
    # Substance and Unreal
    (["Mat_Normal", "Mat_Roughness", "Mat_Height"], ["Normal", "Roughness", "Height"]),
    (["T_Rock_N", "T_Rock_ORM"], ["N", "ORM"]),
    # words compared without case, each suffix as written; a 1K map beside 2K ones (the resolution dropped)
    (["rock_NormalGL", "Rock_Roughness"], ["NormalGL", "Roughness"]),
    (["Rock023_2K_NormalGL", "Rock023_1K_Roughness"], ["NormalGL", "Roughness"]),
    (["Rock-2048x2048-Normal", "Rock-2048x2048-Rough"], ["Normal", "Rough"]),
    # no common prefix: the whole names, as before
    (["normal", "height"], ["normal", "height"]),
    (["bricks_normal", "height"], ["bricks_normal", "height"]),
    (["rock_n", "stone_h"], ["rock_n", "stone_h"]),
    # a name that is all the others share is no prefix: each keeps a word of its own
    (["normal", "normal_dx"], ["normal", "normal_dx"]),
    # only a resolution left: the whole name
    (["Rock_1K", "Rock_2K_Normal"], ["Rock_1K", "Normal"]),
    # a kind's word all share stays: GL and DX alone would be no normal maps to an importer
    (["Rock_Normal_GL", "Rock_Normal_DX"], ["Normal_GL", "Normal_DX"]),
    (["rock_wall_nor_gl_2k", "rock_wall_nor_dx_2k"], ["nor_gl", "nor_dx"]),
])
def test_each_map_is_named_by_what_follows_the_prefix_the_maps_share(maps, want):
    # ambientCG's Rock023_2K_NormalGL was written as Rock_Rock023_2K_NormalGL.png: the stale 2K and the source's name
    assert map_suffixes(["albedo", *maps]) == [None, *want]
    assert map_files("out/Rock.png", ["albedo", *maps]) == ["out/Rock.png", *(f"out/Rock_{w}.png" for w in want)]


@pytest.mark.parametrize("name, want", [
    ("Rock023_2K_NormalGL", "NormalGL"), ("rock_wall_nor_gl_2k", "nor_gl"), ("T_Rock_N", "N"),
    ("Mat_Normal", "Normal"), ("Mat_BaseColor_Normal", "Normal"), ("Rock_Normal_DX", "Normal_DX"),
    # no kind read, or nothing before its word: the whole name
    ("rock_mask", "rock_mask"), ("normal", "normal"), ("RockNormal", "RockNormal"), ("Rock_2K", "Rock_2K"),
])
def test_a_single_map_drops_what_comes_before_its_kinds_word(name, want):
    # One map has no other to share a prefix with: the albedo and a normal map is the usual material
    assert map_suffixes(["albedo", name]) == [None, want]


@pytest.mark.parametrize("maps, want", [
    # the same suffix twice (two resolutions of one map): those keep their whole names
    (["Rock_1K_Normal", "Rock_2K_Normal", "Rock_2K_Height"], ["Rock_1K_Normal", "Rock_2K_Normal", "Height"]),
    (["Rock_2K_Normal", "Rock_4K_normal"], ["Rock_2K_Normal", "Rock_4K_normal"]),  # in any case
    # a whole name kept becomes another's suffix: that one keeps its whole name too
    (["a_b", "a_1k_b", "a_a_b"], ["a_b", "a_1k_b", "a_a_b"]),
])
def test_no_two_maps_are_one_file(maps, want):
    got = map_suffixes(["albedo", *maps])[1:]
    assert got == want
    assert len({s.lower() for s in got}) == len(got)


def test_the_albedo_is_the_output_itself_and_the_extension_is_the_outputs():
    assert map_files("Rock.jpg", ["albedo", "Rock023_2K_NormalGL", "Rock023_2K_Roughness"]) == [
        "Rock.jpg", "Rock_NormalGL.jpg", "Rock_Roughness.jpg"]
    assert map_files("x/Rock.v2.png", ["albedo"]) == ["x/Rock.v2.png"]


# ------------------------------------------------------------------ the command line's files
FAST_CLI = ["--max-patches", "1500", "--clusters", "10", "--layout", "none", "-q"]
AMBIENTCG = ("Rock023_2K_Color.png", "Rock023_2K_NormalGL.png", "Rock023_2K_Roughness.png")


def _cli(*args, cwd):
    import os

    from click.testing import CliRunner

    from tghop.cli import main

    old = os.getcwd()
    os.chdir(cwd)
    try:
        result = CliRunner().invoke(main, list(args))
    finally:
        os.chdir(old)
    assert result.exit_code == 0, result.output
    return result


@pytest.fixture(scope="module")
def material_set(tmp_path_factory):
    """An ambientCG-style set (albedo, OpenGL normal map, roughness) and a material fitted on it."""
    d = tmp_path_factory.mktemp("rock")
    albedo = data.bricks()[:96, :96]
    maps = example_maps(albedo, convention="OpenGL")
    for name, image in zip(AMBIENTCG, (albedo, maps["normal"], maps["height"])):
        save_image(image, d / name)
    mask = np.zeros((96, 96))
    mask[30:60, 30:60] = 1
    save_image(mask, d / "mask.png")
    _cli("fit", AMBIENTCG[0], "--maps", *AMBIENTCG[1:], "-o", "mat.npz", "--fit-seed", "0", *FAST_CLI, cwd=d)
    return d


def test_synth_writes_a_materials_maps_as_an_importer_reads_them(material_set):
    d = material_set
    (d / "out").mkdir()
    result = _cli("synth", "mat.npz", "-o", "out/Rock.png", "--size", "64x64", "--seed", "1", *FAST_CLI[-1:], cwd=d)
    assert sorted(p.name for p in (d / "out").iterdir()) == ["Rock.png", "Rock_NormalGL.png", "Rock_Roughness.png"]
    assert "written to out/Rock.png, out/Rock_NormalGL.png, out/Rock_Roughness.png" in result.output
    # The pixels are the library's (only the names changed)
    from tghop.modelfile import load_model

    material = load_model(d / "mat.npz", material=True)
    want = material.synthesize((64, 64), rng=np.random.default_rng(1), dtype=np.float32)
    for name, file in zip(material.names_, ("Rock.png", "Rock_NormalGL.png", "Rock_Roughness.png")):
        got = load_image(d / "out" / file)
        np.testing.assert_allclose(got, np.squeeze(want[name]) if got.ndim == 2 else want[name], atol=0.5 / 255)


def test_an_output_named_as_the_colour_map_leaves_its_colour_word_out_of_the_maps(material_set):
    # 0.58: -o Rock_Color.png wrote Rock_Color_NormalGL.png, a name an importer reads as both a colour map and
    # a normal map; the maps now leave the colour word out (0.59), --count's numbered sets too.
    d = material_set
    (d / "colour").mkdir()
    _cli("synth", "mat.npz", "-o", "colour/Rock_Color.png", "--size", "48x48", "--seed", "1", "--count", "2",
         *FAST_CLI[-1:], cwd=d)
    assert sorted(p.name for p in (d / "colour").iterdir()) == [
        "Rock_1_NormalGL.png", "Rock_1_Roughness.png", "Rock_2_NormalGL.png", "Rock_2_Roughness.png",
        "Rock_Color_1.png", "Rock_Color_2.png"]
    names = ["albedo", "Rock023_2K_NormalGL", "Rock023_2K_Roughness"]
    assert map_files("T_Rock_BC.tga", names)[1:] == ["T_Rock_NormalGL.tga", "T_Rock_Roughness.tga"]
    assert map_files("x/rock_diff_2k.png", names)[1:] == ["x/rock_2k_NormalGL.png", "x/rock_2k_Roughness.png"]
    assert map_files("color.png", names)[1:] == ["color_NormalGL.png", "color_Roughness.png"]  # one word: kept
    # a map whose file would then be the albedo's own keeps the whole output name
    assert map_files("Rock_Color.png", ["albedo", "a_Color", "a_Height"]) == [
        "Rock_Color.png", "Rock_Color_Color.png", "Rock_Color_Height.png"]


@pytest.mark.parametrize("command", [["inpaint", AMBIENTCG[0], "mask.png"],
                                     ["extend", AMBIENTCG[0], "--size", "96x112"]])
def test_inpaint_and_extend_with_maps_name_the_files_alike(material_set, command):
    d = material_set
    folder = command[0]
    (d / folder).mkdir()
    _cli(*command, "--maps", *AMBIENTCG[1:], "--source", "mat.npz", "-o", f"{folder}/Fill.png", "--seed", "2",
         *FAST_CLI[-1:], cwd=d)
    assert sorted(p.name for p in (d / folder).iterdir()) == ["Fill.png", "Fill_NormalGL.png", "Fill_Roughness.png"]


@pytest.mark.parametrize("one, other, same", [
    # 0.58 (and 0.59 before this) matched by suffixes alone: ambientCG's NormalGL beside Poly Haven's nor_gl was refused
    (["Stone_NormalGL", "Stone_Roughness"], ["gravel_nor_gl_2k", "gravel_rough_2k"], True),
    (["Stone_Normal", "Stone_Displacement"], ["T_Gravel_N", "T_Gravel_Height"], True),
    (["T_Rock_ORM"], ["rock_arm_2k"], True),  # the same packing
    # two normal maps each: matched by the convention each name says
    (["Rock_NormalGL", "Rock_NormalDX"], ["rock_nor_gl_2k", "rock_nor_dx_2k"], True),
    (["Rock_NormalGL", "Rock_NormalDX"], ["rock_nor_dx_2k", "rock_nor_gl_2k"], False),  # another order
    # other kinds, or kinds a material has twice (no one map of the kind to match), stay apart
    (["Rock_Normal", "Rock_Roughness"], ["Rock_Normal", "Rock_Height"], False),
    (["Rock_Specular"], ["Rock_Gloss"], False),
    (["T_Rock_ORM"], ["T_Rock_RMA"], False),
    (["Rock_Height", "Rock_Displacement"], ["Gravel_Height", "Gravel_Bump"], False),
    (["Rock_Height", "Rock_Displacement"], ["Gravel_Height", "Gravel_Displacement"], True),  # by their suffixes
])
def test_map_keys_match_maps_by_kind_across_namings(one, other, same):
    from tghop.material_files import map_keys

    assert (map_keys(["albedo", *one]) == map_keys(["albedo", *other])) is same
