"""A material's maps other than its colours (normal, height, roughness, packed...) are read as data:
their values as stored, a linear gAMA chunk or an ICC profile not applied (0.57: converted as colours,
a normal map's vectors were no longer unit length and fit --maps refused it), in fit --maps, inpaint
--maps and a batch row; the albedo is still converted to sRGB. The server's: tests/test_server_materials.py."""

import struct

import numpy as np
import pytest
from PIL import Image, PngImagePlugin
from test_profiles import P3

from tghop import data
from tghop.imageio import load_image, save_image
from tghop.material import example_maps

#: A small, fast joint model (as tests/test_material.py's).
FAST_CLI = ["--max-patches", "1500", "--clusters", "10", "--layout", "none", "-q"]


def _linear(path, pixels):
    """``pixels`` (uint8) saved by Pillow as a PNG whose gAMA chunk says 1.0 (linear), as tools write data maps."""
    info = PngImagePlugin.PngInfo()
    info.add(b"gAMA", struct.pack(">I", 100000))
    Image.fromarray(pixels).save(path, pnginfo=info)


@pytest.fixture(scope="module")
def height():
    return data.bricks()[:176, :200].mean(axis=2)  # enough patches around a hole to fit on


def _material(folder, height):
    """An albedo with a P3 profile (converted), a linear normal map and a height map: their stored levels."""
    levels = {"normal": np.round(example_maps(height)["normal"] * 255).astype(np.uint8),
              "height": np.round(height * 255).astype(np.uint8)}
    Image.fromarray(np.round(np.repeat(height[..., None], 3, axis=2) * 255).astype(np.uint8)).save(
        folder / "Rock_Color.png", icc_profile=P3)
    _linear(folder / "Rock_NormalDX.png", levels["normal"])
    _linear(folder / "Rock_Height.png", levels["height"])
    return levels


def test_fit_maps_reads_a_linear_normal_map_as_data(tmp_path, height):
    from click.testing import CliRunner

    from tghop.cli import main

    _material(tmp_path, height[:80, :96])
    res = CliRunner().invoke(main, ["fit", str(tmp_path / "Rock_Color.png"), "--maps",
                                    str(tmp_path / "Rock_NormalDX.png"), str(tmp_path / "Rock_Height.png"),
                                    "-o", str(tmp_path / "m.npz"), *FAST_CLI])
    assert res.exit_code == 0, res.output  # 0.56: "its pixels are not unit vectors (median length 1.20)"
    assert "Rock_Color.png: colours converted to sRGB from its colour profile 'Test P3'" in res.output
    assert "Rock_NormalDX.png: colours converted" not in res.output
    assert "Rock_Height.png: colours converted" not in res.output


def test_inpaint_maps_and_a_batch_row_keep_a_maps_stored_values(tmp_path, height):
    from click.testing import CliRunner

    from tghop.batch_task import _read_maps
    from tghop.cli import main

    levels = _material(tmp_path, height)
    hole = np.zeros(height.shape)
    hole[70:90, 80:100] = 1
    save_image(hole, tmp_path / "hole.png")
    res = CliRunner().invoke(main, ["inpaint", str(tmp_path / "Rock_Color.png"), str(tmp_path / "hole.png"), "--maps",
                                    str(tmp_path / "Rock_NormalDX.png"), str(tmp_path / "Rock_Height.png"),
                                    "-o", str(tmp_path / "o.png"), "-q"])
    assert res.exit_code == 0, res.output
    for name in ("normal", "height"):
        out = load_image(next(p for p in tmp_path.glob("o_*.png") if name in p.name.lower()), dtype=None)
        want = levels[name] if levels[name].ndim == 3 else levels[name][..., None]
        np.testing.assert_array_equal(out[hole == 0], want[hole == 0])  # the known pixels: as stored
    Image.fromarray(levels["normal"]).save(tmp_path / "T_Rock_ORM.png", icc_profile=P3)  # a packed map, P3-tagged
    Image.fromarray(levels["normal"]).save(tmp_path / "Rock_Emission.png", icc_profile=P3)  # colours: converted
    rows = [(n, tmp_path / f"{n}.png") for n in ("Rock_NormalDX", "Rock_Height", "T_Rock_ORM", "Rock_Emission")]
    with pytest.warns(UserWarning, match="Rock_Emission.png: colours converted") as caught:
        read = _read_maps(rows)
    assert len(caught) == 1, [str(w.message) for w in caught]
    np.testing.assert_array_equal(read["Rock_NormalDX"][0], levels["normal"])
    np.testing.assert_array_equal(read["Rock_Height"][0][..., 0], levels["height"])
    np.testing.assert_array_equal(read["T_Rock_ORM"][0], levels["normal"])
    assert np.abs(read["Rock_Emission"][0].astype(int) - levels["normal"]).max() > 10
