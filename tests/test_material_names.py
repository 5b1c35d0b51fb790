"""A material's maps named as the common libraries name them (ambientCG, Poly Haven, Unreal,
Substance): each read as its kind, a normal map as one, and a set that does not fit together told in
one line."""

import numpy as np
import pytest

from tghop import TGHop, TGHopError, data
from tghop.material import Material, example_maps, is_normal_name, map_kind, normal_convention

#: A small, fast joint model (as tests/test_material.py's).
FAST = dict(max_patches=1500, n_clusters=10, layout_factor=None)


@pytest.fixture(scope="module")
def exemplar():
    return data.bricks()[:96, :96]


@pytest.fixture(scope="module")
def maps(exemplar):
    return example_maps(exemplar)


@pytest.mark.parametrize("name, kind", [
    ("Rock023_2K_Color.jpg", "albedo"), ("Rock023_2K_NormalGL.png", "normal"), ("Rock023_2K_NormalDX.png", "normal"),
    ("Rock023_2K_Displacement.png", "height"), ("Rock023_2K_AmbientOcclusion.jpg", "ao"),
    ("Rock023_2K_Metalness.jpg", "metallic"), ("Rock023_2K_Opacity.jpg", "opacity"),
    ("rock_wall_diff_2k.jpg", "albedo"), ("rock_wall_nor_gl_2k.png", "normal"), ("rock_wall_nor_dx_4k.exr", "normal"),
    ("rock_wall_rough_2k.jpg", "roughness"), ("rock_wall_arm_2k.jpg", "packed"),
    ("rock-wall-nor-gl-1024.png", "normal"),
    ("T_Rock_BC.png", "albedo"), ("T_Rock_N.png", "normal"), ("T_Rock_ORM.png", "packed"),
    ("Rock_BaseColor.png", "albedo"), ("ROCK_NORMAL_OPENGL.PNG", "normal"), ("bricks.jpg", None), ("gl.png", None)])
def test_the_libraries_map_names_are_read_as_their_kind(name, kind):
    # Poly Haven's rock_wall_nor_gl_2k and Unreal's T_Rock_N were no kind: a remix of them was not warned of.
    assert map_kind(name) == kind
    stem = name.rsplit(".", 1)[0]
    assert is_normal_name(stem) == (kind == "normal")


def test_a_normal_maps_convention_is_read_from_its_name():
    for name, convention in (("Rock023_2K_NormalGL", "OpenGL"), ("Rock023_2K_NormalDX", "DirectX"),
                             ("rock_wall_nor_gl_2k", "OpenGL"), ("rock_wall_nor_dx_2k", "DirectX"),
                             ("Rock_Normal_DirectX", "DirectX"), ("T_Rock_N", None), ("Rock_Normal", None)):
        assert normal_convention(name) == convention, name


def test_a_poly_haven_normal_map_is_a_normal_map_and_comes_out_unit(exemplar, maps):
    # rock_wall_nor_gl_2k was fitted as a colour map: not checked, and not renormalised after synthesis.
    mat = Material(model=TGHop(**FAST), rng=0).fit(exemplar, {"rock_wall_nor_gl_2k": maps["normal"],
                                                              "T_Rock_N": maps["normal"][:, ::-1]})
    assert mat.normal_ == [False, True, True]
    out = mat.synthesize((64, 64), rng=1, n_patches=800, refine=1)
    for name in ("rock_wall_nor_gl_2k", "T_Rock_N"):
        np.testing.assert_allclose(np.linalg.norm(out[name] * 2 - 1, axis=2), 1.0, atol=1e-6)
