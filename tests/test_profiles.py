"""Colour profiles (tghop.profiles): images with an ICC profile other than sRGB are read as sRGB."""

import io
import struct
import warnings

import numpy as np
import pytest
from PIL import Image, ImageCms

from tghop.imageio import load_image


def _s15(x):
    return struct.pack(">i", round(x * 65536))


def _tag(kind, body):
    data = kind + b"\0\0\0\0" + body
    return data + b"\0" * (-len(data) % 4)


def matrix_profile(name, red, green, blue, gamma=2.2):
    """The bytes of a minimal ICC v2 RGB display profile: D50-adapted colorants and one gamma,
    as a camera's Adobe RGB or a phone's Display P3 profile is built."""
    text = name.encode() + b"\0"
    desc = struct.pack(">I", len(text)) + text + struct.pack(">II", 0, 0) + struct.pack(">HB", 0, 0) + b"\0" * 67
    xyz = [_tag(b"XYZ ", b"".join(_s15(v) for v in c)) for c in (red, green, blue, (0.9642, 1.0, 0.8249))]
    curve = _tag(b"curv", struct.pack(">IH", 1, round(gamma * 256)))
    tags = [(b"desc", _tag(b"desc", desc)), (b"rXYZ", xyz[0]), (b"gXYZ", xyz[1]), (b"bXYZ", xyz[2]),
            (b"wtpt", xyz[3]), (b"rTRC", curve), (b"gTRC", curve), (b"bTRC", curve)]
    offset = 128 + 4 + 12 * len(tags)
    table, blobs = b"", b""
    for sig, blob in tags:
        table += sig + struct.pack(">II", offset + len(blobs), len(blob))
        blobs += blob
    size = offset + len(blobs)
    header = (struct.pack(">I", size) + b"\0" * 4 + struct.pack(">I", 0x02100000) + b"mntrRGB XYZ " + b"\0" * 12
              + b"acsp" + b"\0" * 24 + struct.pack(">I", 0) + b"".join(_s15(v) for v in (0.9642, 1.0, 0.8249)))
    header += b"\0" * (128 - len(header))
    return header + struct.pack(">I", len(tags)) + table + blobs


#: A Display P3-like profile: wider primaries than sRGB's.
P3 = matrix_profile("Test P3", (0.5151, 0.2412, -0.0011), (0.2920, 0.6922, 0.0419), (0.1571, 0.0666, 0.7841))
SRGB = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()


@pytest.fixture()
def colours():
    """Muted colours, inside both gamuts."""
    rng = np.random.default_rng(0)
    return (rng.integers(90, 180, size=(24, 32, 1)) + rng.integers(-25, 26, size=(24, 32, 3))).astype(np.uint8)


def test_a_wide_gamut_photo_is_read_in_srgb(tmp_path, colours):
    Image.fromarray(colours).save(tmp_path / "p3.png", icc_profile=P3)
    with pytest.warns(UserWarning, match=r"p3.png: colours converted to sRGB from its colour profile 'Test P3'"):
        read = load_image(tmp_path / "p3.png", dtype=None)
    assert np.abs(read.astype(int) - colours).max() > 10  # other values for the same colours
    back = ImageCms.profileToProfile(Image.fromarray(read), ImageCms.createProfile("sRGB"),
                                     ImageCms.ImageCmsProfile(io.BytesIO(P3)))
    assert np.abs(np.asarray(back).astype(int) - colours).max() <= 2  # the same colours, in sRGB's values
    grey = np.full((8, 8, 3), 128, dtype=np.uint8)
    Image.fromarray(grey).save(tmp_path / "grey.jpg", icc_profile=P3, quality=100)
    with pytest.warns(UserWarning):
        read = load_image(tmp_path / "grey.jpg", dtype=None)
    assert np.ptp(read.astype(int), axis=2).max() <= 1  # neutral stays neutral


def test_srgb_under_any_name_and_no_profile_leave_the_pixels_as_they_are(tmp_path, colours):
    Image.fromarray(colours).save(tmp_path / "srgb.png", icc_profile=SRGB)
    Image.fromarray(colours).save(tmp_path / "plain.png")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.array_equal(load_image(tmp_path / "srgb.png", dtype=None), colours)
        assert np.array_equal(load_image(tmp_path / "plain.png", dtype=None), colours)


def test_alpha_and_palette_images_are_converted_too(tmp_path, colours):
    alpha = np.linspace(0, 255, 24 * 32).astype(np.uint8).reshape(24, 32, 1)
    Image.fromarray(np.concatenate([colours, alpha], axis=2), "RGBA").save(tmp_path / "rgba.png", icc_profile=P3)
    with pytest.warns(UserWarning, match="converted to sRGB"):
        read = load_image(tmp_path / "rgba.png", dtype=None, keep_alpha=True)
    assert read.shape == (24, 32, 4) and np.array_equal(read[..., 3:], alpha)
    with pytest.warns(UserWarning) as said:
        assert np.array_equal(load_image(tmp_path / "rgba.png", dtype=None), read[..., :3])
    assert sorted(str(w.message).split(": ")[1][:20] for w in said) == ["alpha channel droppe", "colours converted to"]
    Image.fromarray(colours).quantize(16).save(tmp_path / "palette.png", icc_profile=P3)
    with pytest.warns(UserWarning, match="converted to sRGB"):
        assert load_image(tmp_path / "palette.png", dtype=None).shape == (24, 32, 3)


def test_a_damaged_profile_is_said_and_ignored(tmp_path, colours):
    Image.fromarray(colours).save(tmp_path / "bad.png", icc_profile=b"not a profile at all" * 8)
    with pytest.warns(UserWarning, match="bad.png: its colour profile could not be read; colours taken as sRGB"):
        assert np.array_equal(load_image(tmp_path / "bad.png", dtype=None), colours)


def test_a_deep_file_is_converted_as_an_8_bit_one_is(tmp_path, colours):
    import zlib

    from tghop.imageio import write_png

    def with_profile(png):  # an iCCP chunk after the signature and IHDR
        body = b"P3\0\0" + zlib.compress(P3)
        return png[:33] + struct.pack(">I", len(body)) + b"iCCP" + body + struct.pack(
            ">I", zlib.crc32(b"iCCP" + body)) + png[33:]

    buffer = io.BytesIO()
    write_png(buffer, colours.astype(np.uint16) * 257)  # 16-bit colour: decoded by tghop itself
    (tmp_path / "deep.png").write_bytes(with_profile(buffer.getvalue()))
    Image.fromarray(colours).save(tmp_path / "eight.png", icc_profile=P3)
    with pytest.warns(UserWarning, match="deep.png: colours converted to sRGB from its colour profile 'Test P3'"):
        deep = load_image(tmp_path / "deep.png")
    with pytest.warns(UserWarning, match="converted to sRGB"):
        eight = load_image(tmp_path / "eight.png")
    assert np.abs(deep - colours / 255).max() > 10 / 255  # converted
    assert np.abs(deep - eight).max() <= 1.5 / 255  # as the 8-bit file of the same values is
    buffer = io.BytesIO()
    alpha = np.full((24, 32, 1), 40000, dtype=np.uint16)
    write_png(buffer, np.concatenate([colours.astype(np.uint16) * 257, alpha], axis=2))
    (tmp_path / "deep_rgba.png").write_bytes(with_profile(buffer.getvalue()))
    with pytest.warns(UserWarning, match="converted to sRGB"):
        rgba = load_image(tmp_path / "deep_rgba.png", keep_alpha=True)
    assert np.allclose(rgba[..., :3], deep) and np.allclose(rgba[..., 3], 40000 / 65535)


def test_a_float_colour_tiff_is_converted_too(tmp_path, colours):
    tifffile = pytest.importorskip("tifffile")
    tifffile.imwrite(tmp_path / "deep.tif", (colours / 255).astype(np.float32), iccprofile=P3, photometric="rgb")
    tifffile.imwrite(tmp_path / "plain.tif", (colours / 255).astype(np.float32), photometric="rgb")
    Image.fromarray(colours).save(tmp_path / "eight.png", icc_profile=P3)
    with pytest.warns(UserWarning, match="deep.tif: colours converted to sRGB from its colour profile 'Test P3'"):
        deep = load_image(tmp_path / "deep.tif")
    with pytest.warns(UserWarning):
        eight = load_image(tmp_path / "eight.png")
    assert np.abs(deep - eight).max() <= 1.5 / 255
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.allclose(load_image(tmp_path / "plain.tif"), colours / 255, atol=1e-6)


def _with_chunk(png, kind, body):
    """A PNG file's bytes with a chunk inserted after the signature and IHDR."""
    import zlib

    return png[:33] + struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body)) + png[33:]


def _srgb_of_linear(levels):
    linear = levels / 255.0
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)


def test_a_png_gamma_alone_is_converted_to_srgb(tmp_path, colours):
    # 0.57: a linear PNG (gAMA 1.0, no sRGB chunk or profile) was read as sRGB, darker than viewers show it
    from tghop.imageio import write_png

    def png(pixels, *chunks):
        buffer = io.BytesIO()
        write_png(buffer, pixels)
        data = buffer.getvalue()
        for kind, body in chunks:
            data = _with_chunk(data, kind, body)
        return data

    linear = (b"gAMA", struct.pack(">I", 100000))
    (tmp_path / "linear.png").write_bytes(png(colours, linear))
    with pytest.warns(UserWarning, match=r"linear.png: colours converted to sRGB from its PNG gamma 1 "):
        read = load_image(tmp_path / "linear.png", dtype=None)
    assert np.array_equal(read, np.round(255 * _srgb_of_linear(colours)).astype(np.uint8))
    grey = colours[..., :1]
    alpha = np.full_like(grey, 77)
    (tmp_path / "grey_alpha.png").write_bytes(png(np.concatenate([grey, alpha], axis=2), linear))
    with pytest.warns(UserWarning, match="PNG gamma 1 "):
        read = load_image(tmp_path / "grey_alpha.png", dtype=None, keep_alpha=True)
    assert np.array_equal(read[..., 0], np.round(255 * _srgb_of_linear(grey[..., 0])))
    assert np.all(read[..., 1] == 77)  # alpha is linear in PNG: kept
    (tmp_path / "deep.png").write_bytes(png(colours.astype(np.uint16) * 257, linear))  # decoded by tghop itself
    with pytest.warns(UserWarning, match="deep.png: colours converted to sRGB from its PNG gamma 1 "):
        assert np.allclose(load_image(tmp_path / "deep.png"), _srgb_of_linear(colours), atol=1e-9)
    mac = (b"gAMA", struct.pack(">I", 55556))  # an old Mac's 1/1.8
    (tmp_path / "mac.png").write_bytes(png(colours, mac))
    with pytest.warns(UserWarning, match="PNG gamma 0.55556 "):
        assert load_image(tmp_path / "mac.png", dtype=None).mean() > colours.mean() + 5  # lighter, as shown


def test_a_png_gamma_of_srgb_or_beside_srgb_leaves_the_pixels_as_they_are(tmp_path, colours):
    import zlib

    from tghop.imageio import save_image, write_png

    buffer = io.BytesIO()
    write_png(buffer, colours)
    plain = buffer.getvalue()
    cases = {"near.png": [(b"gAMA", struct.pack(">I", 45455))],  # sRGB's, alone (as many writers store it)
             "old.png": [(b"gAMA", struct.pack(">I", 45000))],  # within libpng's 5 % of it
             "srgb.png": [(b"gAMA", struct.pack(">I", 100000)), (b"sRGB", b"\0")],  # sRGB's chunk comes first
             "icc.png": [(b"gAMA", struct.pack(">I", 100000)), (b"iCCP", b"s\0\0" + zlib.compress(SRGB))]}
    for name, chunks in cases.items():
        data = plain
        for kind, body in chunks:
            data = _with_chunk(data, kind, body)
        (tmp_path / name).write_bytes(data)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert np.array_equal(load_image(tmp_path / name, dtype=None), colours), name
    save_image(colours / 255, tmp_path / "own.png")  # tghop's own outputs carry no gAMA: read as written
    with Image.open(tmp_path / "own.png") as im:
        assert "gamma" not in im.info
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.array_equal(load_image(tmp_path / "own.png", dtype=None), colours)


def test_a_cmyk_jpeg_without_a_profile_is_said_and_not_inverted(tmp_path):
    # 0.57: converted by Pillow's formula without a word; Adobe's inverted CMYK JPEGs (Photoshop's, and
    # Pillow's own: an APP14 marker) come out the right way round
    cmyk = np.zeros((16, 16, 4), dtype=np.uint8)
    cmyk[:8, :, 0] = 255  # cyan over white
    cmyk[8:, 8:, 3] = 128  # half black
    Image.fromarray(cmyk, "CMYK").save(tmp_path / "print.jpg", quality=95)
    with Image.open(tmp_path / "print.jpg") as im:
        assert "adobe" in im.info
    with pytest.warns(UserWarning, match=r"print.jpg: a CMYK image without a usable colour profile; .* approximate; "
                                         r"export it as RGB"):
        read = load_image(tmp_path / "print.jpg", dtype=None).astype(int)
    assert np.abs(read[2, 2] - (0, 255, 255)).max() <= 3 and np.abs(read[12, 2] - 255).max() <= 3
    assert np.abs(read[12, 12] - 127).max() <= 3


def test_colours_clipped_to_srgb_are_counted_and_said(tmp_path, colours):
    # 0.57: a wide-gamut photo's saturated colours were clipped to sRGB without a word
    import zlib

    from tghop.imageio import write_png

    vivid = np.random.default_rng(1).integers(0, 256, size=(96, 128, 3), dtype=np.uint8)  # about 4 in 10 outside sRGB
    Image.fromarray(vivid).save(tmp_path / "vivid.png", icc_profile=P3)
    with pytest.warns(UserWarning, match=r"vivid.png: colours converted to sRGB from its colour profile 'Test P3'; "
                                         r"(3\d|4\d)% of its pixels hold colours outside sRGB, clipped to it"):
        load_image(tmp_path / "vivid.png", dtype=None)
    Image.fromarray(colours).save(tmp_path / "muted.png", icc_profile=P3)  # inside both gamuts: not said
    with pytest.warns(UserWarning) as said:
        load_image(tmp_path / "muted.png", dtype=None)
    assert [str(w.message) for w in said] == ["muted.png: colours converted to sRGB from its colour profile 'Test P3'"]
    buffer = io.BytesIO()
    write_png(buffer, vivid.astype(np.uint16) * 257)  # 16-bit: measured on 8-bit levels of it
    body = b"P3\0\0" + zlib.compress(P3)
    png = buffer.getvalue()
    (tmp_path / "deep.png").write_bytes(png[:33] + struct.pack(">I", len(body)) + b"iCCP" + body
                                        + struct.pack(">I", zlib.crc32(b"iCCP" + body)) + png[33:])
    with pytest.warns(UserWarning, match=r"deep.png: .*'Test P3'; (3\d|4\d)% of its pixels hold colours outside sRGB"):
        load_image(tmp_path / "deep.png")


def linear_png(pixels) -> bytes:
    """A PNG file's bytes (8 or 16 bits) whose only word on colour is a gAMA chunk of 1.0 (linear)."""
    from tghop.imageio import write_png

    buffer = io.BytesIO()
    write_png(buffer, pixels)
    return _with_chunk(buffer.getvalue(), b"gAMA", struct.pack(">I", 100000))


#: A linear-light profile of sRGB's primaries (gamma 1.0), as tools tag data maps.
LINEAR = matrix_profile("Linear sRGB", (0.4361, 0.2225, 0.0139), (0.3851, 0.7169, 0.0971),
                        (0.1431, 0.0606, 0.7141), gamma=1.0)


def test_a_data_map_is_read_as_stored_its_profile_and_gamma_not_applied(tmp_path, colours):
    # 0.57: a normal map with a linear gAMA or a P3 or linear profile was converted as colours: vectors off unit length
    from PIL import PngImagePlugin

    info = PngImagePlugin.PngInfo()
    info.add(b"gAMA", struct.pack(">I", 100000))
    Image.fromarray(colours).save(tmp_path / "gamma.png", pnginfo=info)  # Pillow's own gAMA chunk
    Image.fromarray(colours[..., 0]).save(tmp_path / "grey.png", pnginfo=info)
    Image.fromarray(colours).save(tmp_path / "p3.png", icc_profile=P3)
    Image.fromarray(colours).save(tmp_path / "linear.tif", icc_profile=LINEAR)
    (tmp_path / "deep.png").write_bytes(linear_png(colours.astype(np.uint16) * 257))  # decoded by tghop itself
    for name in ("gamma.png", "grey.png", "p3.png", "linear.tif", "deep.png"):
        with pytest.warns(UserWarning, match=f"{name}: colours converted to sRGB"):  # a colour image: converted
            load_image(tmp_path / name, dtype=None)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # read as data: without a word
            read = load_image(tmp_path / name, as_data=True)
        want = colours[..., :1] if name == "grey.png" else colours
        assert np.array_equal(np.round(read * 255), want), name
    cmyk = Image.fromarray(colours).convert("CMYK")  # no data as stored: converted to RGB as without as_data
    cmyk.save(tmp_path / "ink.tif")
    with pytest.warns(UserWarning, match="CMYK"):
        assert load_image(tmp_path / "ink.tif", dtype=None, as_data=True).shape == colours.shape


def test_every_map_but_a_colour_one_is_data():
    from tghop.map_names import is_data_map

    assert all(is_data_map(n) for n in ("Rock_NormalGL", "rock_nor_gl_2k", "Rock_Roughness", "T_Rock_ORM", "height",
                                        "Rock_AO", "metalness", "Rock_Specular", "mask", "dirt"))
    assert not any(is_data_map(n) for n in ("Rock_Emission", "rock_diff_2k", "T_Rock_BC", "albedo"))


def test_a_profile_for_other_colours_is_named_so(tmp_path, colours):
    """0.58 said "its colour profile could not be read" of a readable Lab profile on an RGB image."""
    from PIL import ImageCms

    lab = ImageCms.ImageCmsProfile(ImageCms.createProfile("LAB")).tobytes()
    Image.fromarray(colours).save(tmp_path / "lab.png", icc_profile=lab)
    with pytest.warns(UserWarning, match="lab.png: its colour profile is for Lab colours, not RGB ones as the "
                                         "image's; colours taken as sRGB"):
        assert np.array_equal(load_image(tmp_path / "lab.png", dtype=None), colours)
