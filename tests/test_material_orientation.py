"""A normal map stored turned (an EXIF orientation other than 1) is read upright with its vectors turned
with its pixels (tghop.normals.upright_normal_map): the material lit as the upright map would be."""

import numpy as np
import pytest
from PIL import Image

from tghop import TGHopError, data
from tghop.image_decode import upright
from tghop.imageio import load_image, save_image
from tghop.material import example_maps
from tghop.normals import STORED, upright_normal_map, upright_vectors

#: A small, fast joint model (as tests/test_material.py's).
FAST_CLI = ["--max-patches", "1500", "--clusters", "10", "--layout", "none", "-q"]


@pytest.fixture(scope="module")
def height():
    return data.bricks()[:80, :96].mean(axis=2)  # not square: a quarter turn shows


def _stored(path, height, orientation, convention):
    """A normal map of ``height`` as a camera or viewer stores it turned: the pixels as they were before
    the turn that ``orientation`` records, written with that EXIF tag (a JPEG at quality 95)."""
    raw = upright(height, STORED.get(orientation, orientation))
    img = Image.fromarray(np.round(example_maps(raw, convention=convention)["normal"] * 255).astype(np.uint8))
    exif = Image.Exif()
    exif[274] = orientation
    img.save(path, exif=exif, **({"quality": 95} if str(path).endswith(".jpg") else {}))


def _read_upright(path, height, orientation, convention, named):
    """The normal map of ``height`` stored at ``path`` turned by EXIF ``orientation``, read and turned upright
    (its convention given where ``named``, else read from its content), in [0, 1], and the map it should be."""
    _stored(path, height, orientation, convention)
    read = load_image(path, dtype=None)
    want = example_maps(height, convention=convention)["normal"]
    assert read.shape == want.shape
    return upright_normal_map(read, path, convention=convention if named else None) / 255.0, want


@pytest.mark.parametrize("orientation", range(1, 9))
@pytest.mark.parametrize("convention", ["DirectX", "OpenGL"])
@pytest.mark.parametrize("named", [True, False])
def test_a_turned_normal_maps_vectors_turn_with_its_pixels(tmp_path, height, orientation, convention, named):
    # The pixels were turned upright but red and green (the x and y slopes) were not: lit wrong.
    got, want = _read_upright(tmp_path / "rock_normal.png", height, orientation, convention, named)
    assert np.abs(got - want).max() <= 1 / 255 + 1e-9, (orientation, convention)


@pytest.mark.parametrize("orientation", range(1, 9))
@pytest.mark.parametrize("convention", ["DirectX", "OpenGL"])
@pytest.mark.parametrize("named", [True, False])
def test_a_turned_jpeg_normal_maps_vectors_turn_with_its_pixels(tmp_path, height, orientation, convention, named):
    # Normal maps are often JPEG (ambientCG's, a viewer's "rotate" of one sets only the EXIF tag): the orientation
    # of its APP1 segment, as a PNG's eXIf chunk, and its convention read from content JPEG's blocks have blurred.
    got, want = _read_upright(tmp_path / "rock_normal.jpg", height, orientation, convention, named)
    # JPEG's own loss (4:2:0 chroma at quality 95): 0.013 on average, up to 0.094 at the bricks' edges, at each
    # orientation alike; vectors left unturned were off by 0.041 to 0.093 on average (red or green mirrored, swapped)
    error = np.abs(got - want)
    assert error.mean() <= 0.02 and error.max() <= 0.12, (orientation, convention, error.mean(), error.max())


def test_a_quarter_turned_normal_map_of_no_clear_convention_is_refused_in_one_line(tmp_path):
    flat = np.zeros((40, 50, 3), np.uint8)
    flat[...] = (128, 128, 255)
    img = Image.fromarray(flat)
    exif = Image.Exif()
    exif[274] = 6
    img.save(tmp_path / "wall_nrm.png", exif=exif)
    read = load_image(tmp_path / "wall_nrm.png", dtype=None)
    with pytest.raises(TGHopError, match=r"^MAP x is stored turned \(EXIF orientation 6\) and neither its name nor "
                                         r"its content says its convention, .*name it \*_NormalGL \(green up\)"):
        upright_normal_map(read, tmp_path / "wall_nrm.png", label="MAP x")
    assert upright_normal_map(read, tmp_path / "wall_nrm.png", convention="DirectX").shape == (50, 40, 3)
    with pytest.raises(TGHopError, match="needs its convention"):
        upright_vectors(read, 8, None)
    np.testing.assert_array_equal(upright_vectors(read, 3, None)[..., :2], 255 - read[..., :2])


def test_fit_maps_turns_a_turned_normal_maps_vectors(tmp_path, height):
    from click.testing import CliRunner

    from tghop.cli import main
    from tghop.modelfile import load_model
    from tghop.normals import convention_of

    albedo = np.repeat(height[..., None], 3, axis=2)
    save_image(albedo, tmp_path / "Rock_Color.png")
    _stored(tmp_path / "Rock_NormalGL.png", height, 6, "OpenGL")
    res = CliRunner().invoke(main, ["fit", str(tmp_path / "Rock_Color.png"), "--maps",
                                    str(tmp_path / "Rock_NormalGL.png"), "-o", str(tmp_path / "m.npz"), *FAST_CLI])
    assert res.exit_code == 0, res.output
    assert "is named as OpenGL's but its content is DirectX's" not in res.output  # turned as OpenGL's, it stays one
    out = load_model(tmp_path / "m.npz", material=True).synthesize((96, 96), rng=1, n_patches=800)["Rock_NormalGL"]
    assert convention_of(out) == "OpenGL"
    # Lit as the upright map: its green follows the height's slope up the rows, as the albedo's brightness
    albedo_out = load_model(tmp_path / "m.npz", material=True).synthesize((96, 96), rng=1, n_patches=800)["albedo"]
    slope = np.gradient(albedo_out.mean(axis=2), axis=0)
    assert np.corrcoef(slope.ravel(), out[..., 1].ravel())[0, 1] > 0.5


def test_inpaint_and_a_batch_row_turn_a_turned_normal_maps_vectors(tmp_path):
    from click.testing import CliRunner

    from tghop.batch_task import _read_maps
    from tghop.cli import main

    height = data.bricks()[:176, :200].mean(axis=2)  # enough patches around the hole to fit on
    save_image(np.repeat(height[..., None], 3, axis=2), tmp_path / "Rock_Color.png")
    _stored(tmp_path / "Rock_NormalDX.png", height, 8, "DirectX")
    want = np.round(example_maps(height)["normal"] * 255)
    hole = np.zeros(height.shape)
    hole[70:90, 80:100] = 1
    save_image(hole, tmp_path / "hole.png")
    res = CliRunner().invoke(main, ["inpaint", str(tmp_path / "Rock_Color.png"), str(tmp_path / "hole.png"), "--maps",
                                    str(tmp_path / "Rock_NormalDX.png"), "-o", str(tmp_path / "o.png"), "-q"])
    assert res.exit_code == 0, res.output
    (normal,) = [p for p in tmp_path.glob("o*.png") if p.name != "o.png"]
    kept = load_image(normal, dtype=None)[hole == 0].astype(float)
    assert np.abs(kept - want[hole == 0]).max() <= 1, "the known pixels: the upright map's, turned"
    (image, _), = _read_maps([("Rock_NormalDX", tmp_path / "Rock_NormalDX.png")]).values()
    assert np.abs(image - want).max() <= 1
