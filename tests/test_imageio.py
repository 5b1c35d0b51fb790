"""Image conversion for writing."""

import io
import os

import numpy as np
import pytest
from PIL import Image

from tghop.imageio import load_image, to_uint8


def test_to_uint8_rounds_clips_and_works_in_row_blocks():
    rng = np.random.default_rng(0)
    for shape in ((700, 600, 3), (3, 5), (40, 30, 1)):  # the first spans two row blocks
        img = rng.uniform(-0.2, 1.2, shape)
        img.flat[:4] = [0.5 / 255, 1.5 / 255, np.nextafter(0.5 / 255, 0), 254.5 / 255]
        expected = np.round(np.clip(img, 0.0, 1.0) * 255.0).astype(np.uint8)
        out = to_uint8(img)
        assert out.dtype == np.uint8
        assert np.array_equal(out, expected[..., 0] if shape[-1:] == (1,) else expected)
    assert to_uint8(np.float32([[0.0, 1.0]])).tolist() == [[0, 255]]


def test_uint8_images_are_written_as_they_are(tmp_path):
    from tghop.imageio import save_image

    pixels = np.random.default_rng(1).integers(0, 256, (9, 7, 3), dtype=np.uint8)
    assert to_uint8(pixels) is pixels
    np.testing.assert_array_equal(to_uint8(pixels[..., :1]), pixels[..., 0])  # as for floats
    save_image(pixels, tmp_path / "a.png")
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "a.png")), pixels)


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (6, 1), (37, 53), (37, 53, 1), (40, 29, 3), (1, 5, 3)])
@pytest.mark.parametrize("part", [1 << 20, 64])
def test_png_writer_gives_pillow_the_same_pixels(monkeypatch, shape, part):
    # One part, or several compressed on threads (small parts, more "cores" than parts):
    # Pillow reads back every pixel, from a file that passes its checks.
    from tghop import imageio, png

    monkeypatch.setattr(png, "_PNG_PART", part)
    monkeypatch.setattr(png, "usable_cores", lambda: 5)
    pixels = np.random.default_rng(sum(shape)).integers(0, 256, shape, dtype=np.uint8)
    pixels[:, : shape[1] // 2] = 255 - pixels[:, : shape[1] // 2] // 7  # runs that compress
    buf = io.BytesIO()
    imageio.write_png(buf, pixels)
    Image.open(io.BytesIO(buf.getvalue())).verify()
    back = np.asarray(Image.open(io.BytesIO(buf.getvalue())))
    np.testing.assert_array_equal(back, pixels[..., 0] if pixels.ndim == 3 and shape[2] == 1 else pixels)


def test_png_writer_gives_the_same_bytes_on_any_number_of_cores(monkeypatch):
    # The parts are set by the image alone, not the cores: a batch worker's one core, tghop
    # synth's two and a server's many write the same file (1, 2 and 5 "cores" gave 1, 2 and 5
    # deflate streams: files of one image that differed in their bytes).
    from tghop import imageio, png

    monkeypatch.setattr(png, "_PNG_PART", 64)
    pixels = np.random.default_rng(3).integers(0, 256, (40, 30, 3), dtype=np.uint8)
    files = []
    for cores in (1, 2, 5):
        monkeypatch.setattr(png, "usable_cores", lambda: cores)
        buf = io.BytesIO()
        imageio.write_png(buf, pixels)
        files.append(buf.getvalue())
    assert files[0] == files[1] == files[2]
    np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(files[0]))), pixels)


def test_an_images_write_is_a_progress_stage_of_the_same_bytes(monkeypatch, tmp_path):
    # A 4096x4096 PNG took seconds to write with the progress bar showing nothing: its parts are now told as
    # they are compressed (on threads), then the file's write; the bytes are the same with a progress or without.
    from tghop import TGHopError, png
    from tghop.imageio import save_image, save_images

    monkeypatch.setattr(png, "_PNG_PART", 64)
    monkeypatch.setattr(png, "usable_cores", lambda: 3)
    rng = np.random.default_rng(4)
    for pixels in (rng.integers(0, 256, (40, 30, 3), dtype=np.uint8), rng.integers(0, 65536, (9, 8), dtype=np.uint16)):
        calls, plain, told = [], io.BytesIO(), io.BytesIO()
        png.write_png(plain, pixels)
        png.write_png(told, pixels, progress=lambda *a: calls.append(a))
        assert told.getvalue() == plain.getvalue()
        parts = max(1, min(pixels.shape[0] * (1 + pixels[0].nbytes) // 64, pixels.shape[0]))
        assert parts > 1 and calls == [("writing", i, parts + 1) for i in range(parts + 2)], calls
    calls = []
    save_image(np.full((6, 5, 3), 0.5), tmp_path / "a.jpg", progress=lambda *a: calls.append(a))
    assert calls == [("writing", 0, 1), ("writing", 1, 1)]
    calls = []
    save_images([(np.zeros((6, 5, 3)), tmp_path / "b.png", 8), (np.ones((6, 5)), tmp_path / "c.tif", 8)],
                progress=lambda *a: calls.append(a))
    done = [c[1] for c in calls]
    assert {c[0] for c in calls} == {"writing"} and {c[2] for c in calls} == {2000}
    assert done[0] == 0 and done[-1] == 2000 and done == sorted(done), calls
    with pytest.raises(TGHopError, match="progress must be a function"):  # refused before a file is written
        save_image(np.zeros((6, 5, 3)), tmp_path / "d.png", progress="bar")
    assert not (tmp_path / "d.png").exists()


def test_png_writer_refuses_what_png_cannot_hold():
    # (2 and 4 channels are grey and RGB with alpha: PNG holds them.)
    from tghop.imageio import write_png

    for bad in (np.zeros((4, 4), dtype=np.float32), np.zeros((4, 4, 5), dtype=np.uint8), np.zeros(4, dtype=np.uint8)):
        with pytest.raises(ValueError, match="write_png takes"):
            write_png(io.BytesIO(), bad)


def test_png_writer_raises_a_parts_error(monkeypatch):
    # A part compressed on another thread that fails (e.g. out of memory) fails the write:
    # no PNG with a part missing.
    from tghop import imageio, png

    def boom(*args):
        raise MemoryError("no memory for this part")

    monkeypatch.setattr(png, "_PNG_PART", 64)
    monkeypatch.setattr(png, "usable_cores", lambda: 4)
    monkeypatch.setattr(png.zlib, "compressobj", boom)
    with pytest.raises(MemoryError, match="this part"):
        imageio.write_png(io.BytesIO(), np.zeros((40, 30, 3), dtype=np.uint8))


def test_float_tiff_in_unit_range_is_read_as_is(tmp_path):
    # A float32 TIFF with values in [0, 1] (issue #26, item 9) keeps its values: it was
    # divided by 255 and then refused as "no texture".
    from PIL import Image

    from tghop.imageio import load_image

    values = np.random.default_rng(0).random((40, 30)).astype(np.float32)
    Image.fromarray(values, mode="F").save(tmp_path / "f.tif")
    got = load_image(tmp_path / "f.tif")
    assert got.shape == (40, 30, 1)
    np.testing.assert_allclose(got[..., 0], values, atol=1e-7)
    levels = (values * 255).round().astype(np.float32)  # a float image of 8-bit levels: scaled as before
    Image.fromarray(levels, mode="F").save(tmp_path / "g.tif")
    np.testing.assert_allclose(load_image(tmp_path / "g.tif")[..., 0], levels / 255.0, atol=1e-7)


def test_a_float_image_outside_the_unit_range_is_clipped_within_rounding_or_refused(tmp_path):
    # tghop 0.49.0 took any float image outside [0, 1] for 8-bit levels: one pixel at 1.0001
    # made the whole exemplar nearly black, and heights of 0-3 came out as 0-0.012.
    from PIL import Image

    from tghop._errors import InvalidImageError
    from tghop.imageio import load_image

    tifffile = pytest.importorskip("tifffile")
    values = np.random.default_rng(0).random((40, 30)).astype(np.float32)
    over, heights, nan = values.copy(), values * 3 + 0.25, values.copy()
    over[0, 0], nan[3, 4] = 1.0004, np.nan
    for name, write in (("grey", lambda a, f: Image.fromarray(a, mode="F").save(f)),  # Pillow's path
                        ("rgb", lambda a, f: tifffile.imwrite(f, np.repeat(a[..., None], 3, 2), photometric="rgb"))):
        write(over, tmp_path / f"{name}_over.tif")
        got = load_image(tmp_path / f"{name}_over.tif")
        assert got.max() == 1.0 and np.allclose(got[..., 0].ravel()[1:], values.ravel()[1:], atol=1e-7)
        write(heights, tmp_path / f"{name}_heights.tif")
        with pytest.raises(InvalidImageError, match=rf"^\S*{name}_heights.tif: float pixel values from 0\.25\d* to "
                                                    r"3\.2\d*; tghop reads float images with values in \[0, 1\]; "
                                                    r"rescale it"):
            load_image(tmp_path / f"{name}_heights.tif")
        write(nan, tmp_path / f"{name}_nan.tif")
        with pytest.raises(InvalidImageError, match=rf"{name}_nan.tif: NaN or infinite pixel values"):
            load_image(tmp_path / f"{name}_nan.tif")


def test_save_image_refuses_pixels_it_would_write_wrong(tmp_path, monkeypatch):
    import sys

    from tghop._errors import InvalidImageError
    from tghop.imageio import save_image

    levels = np.arange(256, dtype=np.int64).reshape(16, 16)
    with pytest.raises(InvalidImageError, match="floats in \\[0, 1\\] or uint8, not int64.*image / 255"):
        save_image(levels, tmp_path / "a.png")  # would clip to black and white
    with pytest.raises(InvalidImageError, match="not uint16"):
        save_image(levels.astype(np.uint16), tmp_path / "a.png", depth=16)
    with pytest.raises(InvalidImageError, match="not bool"):
        save_image(levels > 100, tmp_path / "a.png")
    bad = np.full((8, 8, 3), 0.5)
    bad[3, 4, 1] = np.nan
    for depth, name in ((8, "a.png"), (16, "a.png")):
        with pytest.raises(InvalidImageError, match="NaN or infinite"):
            save_image(bad, tmp_path / name, depth=depth)
    assert not list(tmp_path.iterdir())  # nothing written
    save_image(levels.astype(np.uint8), tmp_path / "ok.png")
    assert np.array_equal(np.asarray(Image.open(tmp_path / "ok.png")), levels)
    monkeypatch.setattr(sys, "stdout", None)  # `-o - >&-`
    with pytest.raises(InvalidImageError, match="standard output is closed"):
        save_image(levels.astype(np.uint8), "-")


@pytest.mark.parametrize("depth", [8, 16])
@pytest.mark.parametrize("channels", [2, 4])
def test_dropped_alpha_warning_says_how_much_was_transparent(tmp_path, depth, channels):
    # An artist's cut-out (a texture on a transparent background) read without its alpha: the
    # colours under the transparent part (black here) were learnt as texture, and the warning said
    # only "alpha channel dropped". It now says how much was transparent and how to leave it out;
    # an opaque image keeps the plain warning; the colours read are the same either way.
    import warnings

    from tghop.imageio import save_image

    rgba = np.zeros((20, 10, channels))
    rgba[:, :4, :-1], rgba[:, :4, -1] = 0.6, 1.0  # the left 4 of 10 columns opaque: 60 % transparent
    save_image(rgba, tmp_path / "cut.png", depth=depth)
    with pytest.warns(UserWarning) as said:
        cut = load_image(tmp_path / "cut.png")
    assert len(said) == 1 and str(said[0].message).startswith("cut.png: alpha channel dropped, though 60% of its "
                                                              "pixels are transparent")
    assert "--exclude MASK" in str(said[0].message)
    assert np.array_equal(cut, rgba[..., :-1] if channels == 4 else rgba[..., :1])
    rgba[..., -1] = 1.0
    save_image(rgba, tmp_path / "opaque.png", depth=depth)
    with pytest.warns(UserWarning) as said:
        load_image(tmp_path / "opaque.png")
    assert [str(w.message) for w in said] == ["opaque.png: alpha channel dropped"]
    # Its own class (0.57), told apart from a transparent one's without reading its words (the web server did).
    from tghop import OpaqueAlphaWarning, TransparencyWarning

    assert said[0].category is OpaqueAlphaWarning and said[0].message.name == "opaque.png"
    with pytest.warns(TransparencyWarning):
        load_image(tmp_path / "cut.png")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_image(tmp_path / "cut.png", keep_alpha=True).shape == (20, 10, channels)


@pytest.mark.parametrize("channels, mode", [(2, "LA"), (4, "RGBA")])
@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_alpha_is_written_and_read_back_with_keep_alpha(tmp_path, channels, mode, suffix):
    # PNG and TIFF take an alpha channel last (what `tghop inpaint` writes back); load_image
    # keeps it with keep_alpha (else drops it with a warning, as before).
    from tghop.imageio import load_image, save_image

    rng = np.random.default_rng(channels)
    eight = rng.integers(0, 256, (9, 7, channels), dtype=np.uint8)
    save_image(eight, tmp_path / f"a{suffix}")
    with Image.open(tmp_path / f"a{suffix}") as im:
        assert im.mode == mode and np.array_equal(np.asarray(im), eight)
    back, depth = load_image(tmp_path / f"a{suffix}", dtype=None, with_depth=True, keep_alpha=True)
    assert depth == 8 and np.array_equal(back, eight)
    with pytest.warns(UserWarning, match="alpha channel dropped"):
        assert load_image(tmp_path / f"a{suffix}").shape == (9, 7, channels - 1)
    levels = rng.integers(0, 65536, (9, 7, channels), dtype=np.uint16)
    save_image(levels / 65535.0, tmp_path / f"b{suffix}", depth=16)
    back, depth = load_image(tmp_path / f"b{suffix}", with_depth=True, keep_alpha=True)
    assert depth == 16 and np.array_equal(np.round(back * 65535).astype(np.uint16), levels)


def test_a_palette_with_transparency_is_rgba_with_keep_alpha_and_jpeg_refuses_alpha(tmp_path):
    from tghop import InvalidImageError
    from tghop.imageio import load_image, save_image

    im = Image.new("P", (4, 3), 1)
    im.putpalette([0, 0, 0, 200, 100, 50] + [0] * 762)
    im.info["transparency"] = 0
    im.putpixel((0, 0), 0)
    im.save(tmp_path / "p.png", transparency=0)
    rgba = load_image(tmp_path / "p.png", dtype=None, keep_alpha=True)
    assert rgba.shape == (3, 4, 4) and rgba[0, 0, 3] == 0 and rgba[1, 1].tolist() == [200, 100, 50, 255]
    with pytest.raises(InvalidImageError, match="JPEG holds no alpha channel; name the output .png"):
        save_image(rgba, tmp_path / "p.jpg")
    assert not (tmp_path / "p.jpg").exists()


def test_a_palette_with_transparency_bytes_is_read_in_its_colours_without_pillows_warning(tmp_path):
    # Pillow warns "Palette images with Transparency expressed in bytes should be converted to RGBA images"
    # as such an image (tRNS with several entries) is converted to RGB: its words reached the command line
    # and the web server's console beside tghop's own (the alpha dropped, how much of it shows through).
    # Read through RGBA: the same colours, tghop's warning alone.
    import warnings

    indices = (np.arange(12 * 10).reshape(12, 10) % 3).astype(np.uint8)
    palette = [0, 0, 0, 200, 100, 50, 10, 220, 30]
    im = Image.fromarray(indices, "P")
    im.putpalette(palette + [0] * (768 - len(palette)))
    im.save(tmp_path / "p.png", transparency=bytes([255, 0, 128]))
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        image = load_image(tmp_path / "p.png", dtype=None)
    assert image.tolist() == np.array(palette, np.uint8).reshape(3, 3)[indices].tolist()
    assert [str(w.message) for w in shown] == [
        "p.png: alpha channel dropped, though 33% of its pixels are transparent: the colours under them are taken "
        "as texture; crop it to its opaque part, or leave that part out with an exclude mask (--exclude MASK, "
        "white where it is transparent)"]


@pytest.mark.parametrize("colour", [False, True])
@pytest.mark.parametrize("bits", [8, 16])
def test_a_png_transparent_colour_is_an_alpha_channel(tmp_path, colour, bits):
    # A grey or RGB PNG may mark one colour transparent (a tRNS chunk) instead of storing alpha:
    # its pixels are transparent as a palette's transparent entry is (0.55 took them as texture
    # without a word, while a palette's was warned of and kept by keep_alpha).
    import struct
    import zlib

    from tghop.imageio import write_png

    levels = (np.arange(12 * 10).reshape(12, 10) * 523 % 60000 + 1000).astype(np.uint16)
    if colour:
        levels = np.stack([levels, levels[::-1], levels[:, ::-1]], axis=2)
    levels[:3, :4] = 0  # 12 of 120 pixels: the transparent colour
    buffer = io.BytesIO()
    write_png(buffer, levels if bits == 16 else (levels >> 8).astype(np.uint8))
    key = struct.pack(">3H" if colour else ">H", *([0] * (3 if colour else 1)))
    png = buffer.getvalue()  # a tRNS chunk after the signature and IHDR
    (tmp_path / "key.png").write_bytes(png[:33] + struct.pack(">I", len(key)) + b"tRNS" + key
                                       + struct.pack(">I", zlib.crc32(b"tRNS" + key)) + png[33:])
    with pytest.warns(UserWarning, match="key.png: alpha channel dropped, though 10% of its pixels are transparent"):
        flat = load_image(tmp_path / "key.png")
    assert flat.shape == (12, 10, 3 if colour else 1)
    kept = load_image(tmp_path / "key.png", keep_alpha=True)
    assert kept.shape == (12, 10, 4 if colour else 2)
    np.testing.assert_array_equal(kept[..., :-1], flat)
    opaque = np.ones((12, 10))
    opaque[:3, :4] = 0
    np.testing.assert_array_equal(kept[..., -1], opaque)


@pytest.mark.parametrize("suffix", [".png", ".tif", ".jpg"])
@pytest.mark.parametrize("orientation", range(1, 9))
def test_exif_orientation_is_applied(tmp_path, suffix, orientation):
    # Cameras store JPEG pixels sideways and record how to show them: the image is read as shown,
    # by Pillow's path and by tghop's own readers (TIFF through tifffile, 16-bit PNG) alike.
    from PIL import ImageOps

    y, x = np.mgrid[:20, :30]
    pixels = np.stack([y * 12, x * 8, (x + y) * 4], axis=2).astype(np.uint8)  # smooth: JPEG keeps it
    exif = Image.Exif()
    exif[0x0112] = orientation
    path = tmp_path / f"turned{suffix}"
    Image.fromarray(pixels).save(path, exif=exif, **({"quality": 95} if suffix == ".jpg" else {}))
    with Image.open(path) as im:
        shown = np.asarray(ImageOps.exif_transpose(im)).astype(float)
    got = load_image(path, dtype=None).astype(float)
    assert got.shape == shown.shape == ((30, 20, 3) if orientation >= 5 else (20, 30, 3))
    assert np.abs(got - shown).max() <= 1
    if orientation != 1:  # not the pixels as stored
        assert got.shape != pixels.shape or np.abs(got - pixels).mean() > 5


def test_exif_orientation_of_a_16_bit_png(tmp_path):
    levels = (np.arange(20 * 30).reshape(20, 30) * 97 % 65536).astype(np.uint16)
    exif = Image.Exif()
    exif[0x0112] = 6  # shown turned a quarter clockwise
    Image.fromarray(levels).save(tmp_path / "deep.png", exif=exif)
    got = load_image(tmp_path / "deep.png")
    np.testing.assert_array_equal(np.round(got[:, :, 0] * 65535).astype(np.uint16), np.rot90(levels, -1))


@pytest.mark.parametrize("orientation", [3, 6, 8])
def test_exif_orientation_of_a_float_colour_tiff(tmp_path, orientation):
    # Pillow cannot open a float RGB TIFF; its Orientation tag is read by tifffile (0.55 read
    # the pixels as stored: a texture learnt sideways of what every viewer shows).
    tifffile = pytest.importorskip("tifffile")
    from PIL import ImageOps

    pixels = _colourful(20, 30)
    tifffile.imwrite(tmp_path / "turned.tif", (pixels / 255).astype(np.float32), photometric="rgb",
                     extratags=[(274, 3, 1, orientation, True)])
    Image.fromarray(pixels).save(tmp_path / "eight.tif", tiffinfo={274: orientation})
    with Image.open(tmp_path / "eight.tif") as im:
        shown = np.asarray(ImageOps.exif_transpose(im))
    got = load_image(tmp_path / "turned.tif")
    assert got.shape == shown.shape
    np.testing.assert_allclose(got * 255, shown, atol=0.01)


def _colourful(h=24, w=32):
    """A smooth colour image (uint8): JPEG compression keeps it close."""
    y, x = np.mgrid[:h, :w]
    return np.stack([40 + y * 6, 200 - x * 5, 60 + (x + y) * 2], axis=2).astype(np.uint8)


@pytest.mark.parametrize("kind", ["CMYK", "P", "YCbCr", "LAB", "1", "jpeg", "tiff_lzw"])
def test_tiffs_of_other_colour_kinds_are_converted_as_pillow_converts_them(tmp_path, kind):
    # review 58 item 1: with tifffile installed, CMYK was read as RGBA (K dropped, "alpha channel
    # dropped", colours inverted), palette as grey indices, YCbCr and LAB as raw RGB; bilevel and
    # JPEG (or LZW) compressed files, which tifffile cannot decode without imagecodecs, were refused.
    import warnings

    rgb = Image.fromarray(_colourful())
    path = tmp_path / f"{kind}.tif"
    if kind in ("jpeg", "tiff_lzw"):
        rgb.save(path, compression=kind)
    else:
        rgb.convert(kind).save(path)
    with Image.open(path) as im:
        expected = np.asarray(im.convert("L" if kind == "1" else "RGB"))
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")  # no "alpha channel dropped"; CMYK's approximate colours said (0.57)
        got, depth = load_image(path, dtype=None, with_depth=True)
    assert [str(w.message).split(";")[0] for w in said] == (
        [f"{kind}.tif: a CMYK image without a usable colour profile"] if kind == "CMYK" else [])
    assert depth == 8
    assert got.shape == expected.shape[:2] + (1 if kind == "1" else 3,)
    np.testing.assert_array_equal(got.reshape(expected.shape), expected)
    if kind not in ("P", "1"):  # the colours of the image saved, not raw samples
        assert np.abs(got.astype(float) - _colourful()).mean() < 3


def test_deep_tiffs_alpha_only_where_extrasamples_says_and_refused_kinds(tmp_path, monkeypatch):
    tifffile = pytest.importorskip("tifffile")
    from tghop import InvalidImageError

    rng = np.random.default_rng(5)
    levels = rng.integers(0, 65536, (9, 7, 4), dtype=np.uint16)
    tifffile.imwrite(tmp_path / "x.tif", levels, photometric="rgb", extrasamples=["unspecified"])
    tifffile.imwrite(tmp_path / "a.tif", levels, photometric="rgb", extrasamples=["unassalpha"])
    with pytest.warns(UserWarning, match="its 4th sample, not marked as alpha .*read as straight alpha"):
        got = load_image(tmp_path / "x.tif", keep_alpha=True)  # 0.58: an unmarked 4th sample is alpha, said
    np.testing.assert_array_equal(np.round(got * 65535).astype(np.uint16), levels)
    np.testing.assert_array_equal(np.round(load_image(tmp_path / "a.tif", keep_alpha=True) * 65535), levels)
    # min-is-white levels are inverted (Pillow reads a 16-bit one as min-is-black)
    tifffile.imwrite(tmp_path / "w.tif", levels[..., 0], photometric="miniswhite")
    np.testing.assert_array_equal(np.round(load_image(tmp_path / "w.tif")[..., 0] * 65535), 65535 - levels[..., 0])
    # 16-bit kinds tghop cannot turn into RGB without loss: one line naming the fix
    tifffile.imwrite(tmp_path / "c.tif", levels, photometric="separated")
    tifffile.imwrite(tmp_path / "y.tif", levels[..., :3], photometric="ycbcr")
    for name, kind in (("c.tif", "CMYK"), ("y.tif", "YCbCr")):
        with pytest.raises(InvalidImageError, match=f"a 16-bit {kind} TIFF; .*convert it to RGB"):
            load_image(tmp_path / name)
    # a deep colour TIFF tifffile cannot decode (compression without imagecodecs) is refused, not
    # reduced to 8 bits by Pillow; an 8-bit one goes to Pillow
    tifffile.imwrite(tmp_path / "e.tif", _colourful())

    def no_codec(self, *args, **kwargs):
        raise ValueError("<COMPRESSION.LZW: 5> requires the 'imagecodecs' package")

    monkeypatch.setattr(tifffile.TiffPage, "asarray", no_codec)
    with pytest.raises(InvalidImageError, match="cannot decode this 16-bit colour TIFF .*pip install imagecodecs"):
        load_image(tmp_path / "a.tif")
    np.testing.assert_array_equal(load_image(tmp_path / "e.tif", dtype=None), _colourful())


@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
def test_deep_tiffs_with_premultiplied_alpha_are_divided_out(tmp_path, dtype):
    # 0.36 read a 16-bit or float TIFF with associated alpha as plain colours: every
    # semi-transparent pixel darkened by its alpha (Pillow divides an 8-bit one out).
    tifffile = pytest.importorskip("tifffile")
    rng = np.random.default_rng(2)
    colours = rng.random((6, 5, 3))
    alpha = rng.uniform(0.2, 1.0, (6, 5, 1))
    alpha[0, 0] = 0.0  # fully transparent: no colour to recover, read as 0
    stored = np.concatenate([colours * alpha, alpha], axis=2)
    samples = np.round(stored * 65535).astype(np.uint16) if dtype == np.uint16 else stored.astype(np.float32)
    tifffile.imwrite(tmp_path / "p.tif", samples, photometric="rgb", extrasamples=["assocalpha"])
    with pytest.warns(UserWarning, match="alpha"):
        got = load_image(tmp_path / "p.tif")
    expected = colours.copy()
    expected[0, 0] = 0.0
    tol = 1e-6 if dtype == np.float32 else 2.0 / (65535 * 0.2)  # 16-bit levels, divided by alpha >= 0.2
    np.testing.assert_allclose(got, expected, atol=tol)
    kept = load_image(tmp_path / "p.tif", keep_alpha=True)
    np.testing.assert_allclose(kept[..., 3:], alpha, atol=1e-6 if dtype == np.float32 else 1 / 65535)
    if dtype == np.float32:  # a colour a rounding above its alpha: 1, not the whole image read as 0-255 levels
        samples[1, 1, :3] = samples[1, 1, 3] * np.float32(1 + 1e-6)
        tifffile.imwrite(tmp_path / "q.tif", samples, photometric="rgb", extrasamples=["assocalpha"])
        with pytest.warns(UserWarning, match="alpha"):
            over = load_image(tmp_path / "q.tif")
        np.testing.assert_allclose(over[1, 1], 1.0)
        np.testing.assert_allclose(np.delete(over.reshape(-1, 3), 6, axis=0), np.delete(got.reshape(-1, 3), 6, axis=0))


@pytest.mark.parametrize("compression", ["lzw", "zlib", "zstd", "packbits"])
@pytest.mark.parametrize("kind", ["uint16 rgb", "uint16 grey", "float32 rgb"])
def test_compressed_deep_tiffs_are_read_exactly(tmp_path, compression, kind):
    # 0.36 refused LZW-compressed 16-bit colour TIFFs (what image editors write) with "pip install
    # imagecodecs": the tiff extra now installs it.
    tifffile = pytest.importorskip("tifffile")
    pytest.importorskip("imagecodecs")
    dtype, colour = kind.split()
    rng = np.random.default_rng(3)
    shape = (13, 11, 3) if colour == "rgb" else (13, 11)
    if dtype == "uint16":
        levels = rng.integers(0, 65536, shape, dtype=np.uint16)
        expected = levels / 65535.0
    else:
        levels = rng.random(shape, dtype=np.float32)
        expected = levels.astype(np.float64)
    path = tmp_path / "x.tif"
    tifffile.imwrite(path, levels, compression=compression, photometric="rgb" if colour == "rgb" else "minisblack")
    got, depth = load_image(path, with_depth=True)
    assert depth == (16 if dtype == "uint16" else 32)
    np.testing.assert_array_equal(got.reshape(expected.shape), expected)


def test_save_image_refuses_empty_wrong_channels_and_out_of_range_images(tmp_path):
    # review 58 item 11: an empty image made an unreadable PNG, 5 channels an internal ValueError,
    # floats outside [0, 1] were clipped without a word.
    from tghop import InvalidImageError
    from tghop.imageio import save_image

    rgb = np.random.default_rng(2).random((16, 16, 3))
    cases = [(rgb[:0], "no pixels"), (np.zeros((16, 16, 5)), "C 1 to 4.*not of shape \\(16, 16, 5\\)"),
             (np.zeros((2, 4, 4, 3)), "not of shape"), (np.zeros((16, 16, 5), np.uint8), "C 1 to 4"),
             (np.full((8, 8, 3), 2.0), "values run from 2 to 2; scale it to \\[0, 1\\]"),
             (np.full((8, 8, 3), -1.0), "values run from -1 to -1; scale it")]
    for image, match in cases:
        for name, depth in (("a.png", 8), ("a.tif", 16), ("a.tif", 32)):
            with pytest.raises(InvalidImageError, match=match):
                save_image(image, tmp_path / name, depth=depth)
    nan = rgb.copy()
    nan[0, 0, 0] = np.nan
    with pytest.raises(InvalidImageError, match="NaN or infinite"):
        save_image(nan, tmp_path / "a.tif", depth=32)  # load_image refuses such a float TIFF
    assert not list(tmp_path.iterdir())
    # float rounding a hair outside [0, 1] is clipped, as before
    hair = rgb.copy()
    hair[0, 0] = [1 + 1e-4, -1e-4, 0.5]  # within imageio.RANGE_TOLERANCE
    save_image(hair, tmp_path / "ok.png")
    assert np.asarray(Image.open(tmp_path / "ok.png"))[0, 0].tolist() == [255, 0, 128]


def test_load_image_refuses_a_dtype_it_does_not_give(tmp_path):
    # review 58 item 12: dtype=np.int32 failed deep in NumPy
    from tghop import TGHopError

    Image.fromarray(_colourful()).save(tmp_path / "a.png")
    for dtype in (np.int32, np.uint8, np.float16, "bogus"):
        with pytest.raises(TGHopError, match="dtype must be numpy.float64, numpy.float32 or None"):
            load_image(tmp_path / "a.png", dtype=dtype)
    assert load_image(tmp_path / "a.png", dtype="float32").dtype == np.float32


def test_save_images_checks_every_path_before_moving_any(tmp_path, monkeypatch):
    from tghop import InvalidImageError, TGHopError
    from tghop.imageio import save_images

    monkeypatch.chdir(tmp_path)
    img = np.random.default_rng(0).random((8, 8, 3))
    (tmp_path / "isdir.png").mkdir()
    with pytest.raises(InvalidImageError, match=r"^isdir\.png is a folder"):
        save_images([(img, "w1.png", 8), (img, "isdir.png", 8)])
    with pytest.raises(InvalidImageError, match=r"^t2\.jpg: JPEG cannot hold 16-bit"):
        save_images([(img, "t1.png", 8), (img, "t2.jpg", 16)])
    with pytest.raises(InvalidImageError, match="standard output"):
        save_images([(img, "-", 8)])
    with pytest.raises(TGHopError, match=r"item 0 must be an \(image, path, depth\) triple"):
        save_images([(img, "a.png")])
    with pytest.raises(TGHopError, match="sequence of"):
        save_images(None)
    with pytest.raises(InvalidImageError, match="given twice"):
        save_images([(img, "a.png", 8), (img, "./a.png", 8)])
    with pytest.raises(InvalidImageError, match=r"^an image to save") as info:
        save_images([(img, "ok.png", 8), (img * 5, "b.png", 8)])
    assert ".part" not in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["isdir.png"]


def _replace_failing_on(monkeypatch, name):
    """``os.replace`` made to fail (permission denied) for a destination named ``name``; returns
    the real one, to put back."""
    real = os.replace

    def failing(src, dst):
        if str(dst).endswith(name):
            raise PermissionError(13, "Permission denied")
        return real(src, dst)

    monkeypatch.setattr(os, "replace", failing)
    return real


def test_save_images_rolls_back_when_a_move_fails(tmp_path, monkeypatch):
    from tghop import InvalidImageError
    from tghop.imageio import save_images

    img = np.random.default_rng(0).random((8, 8, 3))
    (tmp_path / "old.png").write_bytes(b"old")
    real = _replace_failing_on(monkeypatch, "second.png")
    with pytest.raises(InvalidImageError, match=r"second\.png: writing the image failed .*none of the images"):
        save_images([(img, tmp_path / "old.png", 8), (img, tmp_path / "new.png", 8), (img, tmp_path / "second.png", 8)])
    monkeypatch.setattr(os, "replace", real)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.png"]
    assert (tmp_path / "old.png").read_bytes() == b"old"


def test_helpers_refuse_nan_empty_and_bad_level():
    from tghop import InvalidImageError, TGHopError
    from tghop.imageio import to_uint16, write_png

    for convert in (to_uint8, to_uint16):
        with pytest.raises(InvalidImageError, match="NaN values"):
            convert(np.full((2, 2), np.nan))
    with pytest.raises(InvalidImageError, match="no pixels"):
        write_png(io.BytesIO(), np.zeros((0, 0), np.uint8))
    for level in (10, -1, 1.5):
        with pytest.raises(TGHopError, match="level must be a zlib level"):
            write_png(io.BytesIO(), np.zeros((2, 2), np.uint8), level=level)


def test_writing_a_symbolic_link_writes_its_target(tmp_path, monkeypatch):
    # An atomic write replaced the link itself with a file; now the link stays and its target
    # (through a chain of links) gets the content, written in the target's folder.
    from tghop.imageio import save_image, write_atomic

    monkeypatch.chdir(tmp_path)
    img = np.random.default_rng(0).random((8, 8, 3))
    (tmp_path / "real").mkdir()
    save_image(np.zeros((8, 8, 3)), "real/t.png")
    os.symlink("real/t.png", "hop.png")
    os.symlink("hop.png", "link.png")
    save_image(img, "link.png")
    assert os.path.islink("link.png") and os.path.islink("hop.png")
    np.testing.assert_array_equal(load_image("real/t.png"), to_uint8(img) / 255.0)
    write_atomic("link.png", lambda fh: fh.write(b"new"))
    assert os.path.islink("link.png") and (tmp_path / "real" / "t.png").read_bytes() == b"new"
    assert sorted(os.listdir("real")) == ["t.png"] and sorted(os.listdir(".")) == ["hop.png", "link.png", "real"]
    # a relative link in another folder points from its own folder
    (tmp_path / "other").mkdir()
    os.symlink("../real/t.png", "other/rel.png")
    save_image(img * 0, "other/rel.png")
    assert os.path.islink("other/rel.png") and load_image("real/t.png").max() == 0


def test_a_dangling_link_writes_its_target_where_its_folder_exists(tmp_path, monkeypatch):
    # Written as a shell's `>` would: the target is made. A target whose folder is missing, and
    # a loop of links, are one line each, before anything is written.
    from tghop import InvalidImageError
    from tghop.imageio import check_output_path, save_image

    monkeypatch.chdir(tmp_path)
    img = np.random.default_rng(1).random((8, 8, 3))
    (tmp_path / "real").mkdir()
    os.symlink("real/new.png", "dangling.png")
    save_image(img, "dangling.png")
    assert os.path.islink("dangling.png") and os.listdir("real") == ["new.png"]
    np.testing.assert_array_equal(load_image("dangling.png"), to_uint8(img) / 255.0)
    os.symlink("missing/x.png", "nowhere.png")
    with pytest.raises(InvalidImageError, match=r"^nowhere\.png is a symbolic link to .*missing.x\.png, whose folder "
                                                r".*missing does not exist; create that folder or point the link"):
        save_image(img, "nowhere.png")
    os.symlink("real/new.png/x.png", "under_a_file.png")
    with pytest.raises(InvalidImageError, match=r"whose folder .*new\.png is a file; point the link elsewhere"):
        check_output_path("under_a_file.png")
    os.symlink("loop_b.png", "loop_a.png")
    os.symlink("loop_a.png", "loop_b.png")
    with pytest.raises(InvalidImageError, match=r"^loop_a\.png is a loop of symbolic links"):
        save_image(img, "loop_a.png")
    assert sorted(os.listdir(".")) == ["dangling.png", "loop_a.png", "loop_b.png", "nowhere.png", "real",
                                       "under_a_file.png"]
    assert not os.path.exists("missing") and os.listdir("real") == ["new.png"]


def test_save_images_writes_through_links_and_rolls_them_back(tmp_path, monkeypatch):
    from tghop import InvalidImageError
    from tghop.imageio import save_images

    img = np.random.default_rng(0).random((8, 8, 3))
    (tmp_path / "real").mkdir()
    (tmp_path / "real" / "old.png").write_bytes(b"old")
    os.symlink(tmp_path / "real" / "old.png", tmp_path / "link.png")
    with pytest.raises(InvalidImageError, match="given twice"):  # the link and its target are one file
        save_images([(img, tmp_path / "link.png", 8), (img, tmp_path / "real" / "old.png", 8)])
    real = _replace_failing_on(monkeypatch, "second.png")
    with pytest.raises(InvalidImageError, match=r"second\.png: writing the image failed .*none of the images"):
        save_images([(img, tmp_path / "link.png", 8), (img, tmp_path / "second.png", 8)])
    monkeypatch.setattr(os, "replace", real)
    assert os.path.islink(tmp_path / "link.png") and (tmp_path / "real" / "old.png").read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.png", "real"] and os.listdir(tmp_path / "real") == [
        "old.png"]
    save_images([(img, tmp_path / "link.png", 8), (img, tmp_path / "second.png", 8)])
    assert os.path.islink(tmp_path / "link.png") and os.listdir(tmp_path / "real") == ["old.png"]
    np.testing.assert_array_equal(load_image(tmp_path / "real" / "old.png"), to_uint8(img) / 255.0)


def test_an_unreadable_image_says_why_in_words(tmp_path):
    # Each said only the class name of Pillow's exception: "(OSError)" for a download cut short,
    # "(UnidentifiedImageError)" for an empty file and for a NumPy array file alike.
    from tghop import InvalidImageError
    from tghop.imageio import save_image

    save_image(np.random.default_rng(0).random((40, 40, 3)), tmp_path / "whole.png")
    blob = (tmp_path / "whole.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(blob[: len(blob) // 2])
    (tmp_path / "empty.png").write_bytes(b"")
    np.save(tmp_path / "array.npy", np.zeros((4, 4)))
    (tmp_path / "notes.png").write_text("hello")
    other = "give a PNG, JPEG or other common image file"
    (tmp_path / "notes.txt").write_text("hello")
    for name, why in (("cut.png", "(a PNG file, cut short (image file is truncated)); save or download it again"),
                      ("empty.png", f"(the file is empty); {other}"),
                      ("array.npy", f"(a NumPy array file (.npy), not an image); {other}"),
                      ("notes.png", "(named as a PNG file, but Pillow cannot read its header as one: damaged, or "
                                    f"another kind of file renamed); save or download it again, or {other}"),
                      ("notes.txt", f"(not an image format tghop reads); {other}")):
        with pytest.raises(InvalidImageError) as error:
            load_image(tmp_path / name)
        assert str(error.value) == f"{tmp_path / name}: not a readable image {why}", str(error.value)


@pytest.mark.parametrize("name, head, said", [
    ("phone.heic", b"\x00\x00\x00\x18ftypheic\x00\x00\x00\x00mif1heic", "a HEIC/HEIF image"),
    ("photo.HEIF", b"\x00\x00\x00\x18ftypmif1\x00\x00\x00\x00mif1heic", "a HEIC/HEIF image"),
    ("new.jxl", b"\xff\x0a\xfa\x7f\x01\x90\x08", "a JPEG XL image"),
    ("boxed.jxl", b"\x00\x00\x00\x0cJXL \r\n\x87\n\x00\x00\x00\x14ftypjxl ", "a JPEG XL image"),
    ("render.exr", b"\x76\x2f\x31\x01\x02\x00\x00\x00channels", "an OpenEXR image"),
    ("sky.hdr", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n", "a Radiance HDR image"),
    ("scan.pdf", b"%PDF-1.7\n", "a PDF document"),
    ("logo.svg", b'<svg xmlns="http://www.w3.org/2000/svg"/>', "an SVG or other XML file")])
def test_a_common_format_pillow_does_not_read_is_named(tmp_path, name, head, said):
    # A phone's HEIC photo or an artist's EXR texture was "not an image format tghop reads", as a
    # text file is: the user could not tell that converting it would do.
    from tghop import InvalidImageError

    (tmp_path / name).write_bytes(head + bytes(200))
    with pytest.raises(InvalidImageError) as error:
        load_image(tmp_path / name)
    assert str(error.value) == f"{tmp_path / name}: {said}, a format tghop does not read; convert it to PNG, " \
                               "TIFF or JPEG first"


@pytest.mark.parametrize("name", ["moving.gif", "pages.tif"])
def test_a_file_of_several_frames_warns_that_the_first_is_read(tmp_path, name):
    # An animated GIF and a TIFF of several pages were read (the first frame) without a word.
    import warnings

    frames = [Image.fromarray(np.full((8, 8, 3), v, np.uint8)) for v in (10, 200, 90)]
    frames[0].save(tmp_path / name, save_all=True, append_images=frames[1:])
    frames[0].save(tmp_path / ("one" + name[-4:]))
    with pytest.warns(UserWarning, match=rf"^{name}: 3 frames \(or pages\); only the first is read$"):
        image = load_image(tmp_path / name, dtype=None)
    assert (image == 10).all()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_image(tmp_path / ("one" + name[-4:]))


@pytest.mark.parametrize("tifffile_installed", [True, False])
@pytest.mark.parametrize("dtype, low, high", [(np.int16, -12700, 12300), (np.uint32, 0, 3_900_000_000),
                                               (np.int32, -5, 200)])
def test_integer_levels_outside_16_bits_are_refused(tmp_path, monkeypatch, tifffile_installed, dtype, low, high):
    # A signed or 32-bit integer TIFF (a height map, a scientific camera's frame) whose values are
    # outside 0-65535: 0.55 clipped them to black and white (unsigned 32-bit ones wrapped to negative
    # by Pillow first) without a word. In range they are levels, as 16-bit ones.
    import sys

    tifffile = pytest.importorskip("tifffile")
    from tghop import InvalidImageError

    values = np.linspace(low, high, 12 * 10).reshape(12, 10).astype(dtype)
    tifffile.imwrite(tmp_path / "wide.tif", values)
    tifffile.imwrite(tmp_path / "fits.tif", ((values.astype(np.int64) - low) * 40000 // (high - low)).astype(np.int32))
    if not tifffile_installed:
        monkeypatch.setitem(sys.modules, "tifffile", None)  # Pillow's path alone
    said = f"wide.tif: integer pixel values from {low} to {high}; tghop reads integer images as levels from 0 to 65535"
    with pytest.raises(InvalidImageError, match=said if tifffile_installed or dtype != np.uint32 else "levels from 0"):
        load_image(tmp_path / "wide.tif")
    got = load_image(tmp_path / "fits.tif")
    assert got.shape == (12, 10, 1) and got.min() == 0 and got.max() == 40000 / 65535


@pytest.mark.parametrize("shape", [(13, 11, 3), (3, 2, 1), (9, 17, 2)])
def test_an_interlaced_16_bit_png_is_read_whole(tmp_path, shape):
    # Adam7-interlaced 16-bit PNG files went to Pillow, which reduces colour ones to 8 bits: read
    # as 8-bit, without a word, and `tghop inpaint` wrote them back 8-bit.
    import struct
    import zlib

    levels = np.random.default_rng(shape[0]).integers(0, 65536, shape, dtype=np.uint16)
    rows = b""
    for x0, y0, dx, dy in ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2),
                           (0, 1, 1, 2)):
        part = levels[y0::dy, x0::dx]
        if part.size:
            for k, row in enumerate(part):  # filter Sub on odd rows: unfiltered per pass
                data = np.frombuffer(row.astype(">u2").tobytes(), np.uint8).copy()
                if k % 2:
                    data[2 * shape[2]:] -= np.frombuffer(row.astype(">u2").tobytes(), np.uint8)[: -2 * shape[2]]
                rows += (b"\x01" if k % 2 else b"\x00") + data.tobytes()

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    header = struct.pack(">IIBBBBB", shape[1], shape[0], 16, {1: 0, 2: 4, 3: 2}[shape[2]], 0, 0, 1)
    (tmp_path / "adam7.png").write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                                         + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
    got, depth = load_image(tmp_path / "adam7.png", with_depth=True, keep_alpha=True)
    assert depth == 16
    np.testing.assert_array_equal(np.round(got * 65535).astype(np.uint16), levels)


@pytest.mark.parametrize("tifffile_installed", [True, False])
def test_a_camera_raw_file_s_preview_is_not_learnt(tmp_path, monkeypatch, tifffile_installed):
    # A DNG's first image is a small preview (NewSubfileType 1), its raw data in a SubIFD: the
    # preview was read as the exemplar, a few hundred pixels of it, without a word.
    import sys

    tifffile = pytest.importorskip("tifffile")
    from tghop import InvalidImageError

    with tifffile.TiffWriter(tmp_path / "camera.dng") as tif:
        tif.write(_colourful(24, 32), photometric="rgb", subfiletype=1, subifds=1)
        tif.write(np.zeros((96, 128), np.uint16), photometric="minisblack")
    tifffile.imwrite(tmp_path / "whole.tif", _colourful(24, 32), photometric="rgb", subfiletype=0)
    if not tifffile_installed:
        monkeypatch.setitem(sys.modules, "tifffile", None)  # Pillow's path alone
    with pytest.raises(InvalidImageError, match="camera.dng: its first image is a reduced-resolution preview "
                                                r"\(a camera raw file, such as DNG\?\); .* export it as TIFF"):
        load_image(tmp_path / "camera.dng")
    np.testing.assert_array_equal(load_image(tmp_path / "whole.tif", dtype=None), _colourful(24, 32))


@pytest.mark.parametrize("ext, mode", [(".qoi", "RGB"), (".sgi", "RGB"), (".sgi", "L"), (".pcx", "RGB"), (".pcx", "L")])
def test_qoi_sgi_and_pcx_are_read_and_taken_from_a_batch_folder(tmp_path, ext, mode):
    # Pillow 10 (pyproject's lower bound) reads them, and tghop fit did; a batch folder skipped them without a word
    # (0.57: "no image files in this folder"), as they were in neither read list.
    from tghop import batch, data
    from tghop._formats import READ_SUFFIXES

    rgb = (data.bricks(48, rng=7) * 255).round().astype(np.uint8)
    pixels = rgb if mode == "RGB" else rgb[..., 0]
    path = tmp_path / "src" / f"Wall{ext.upper() if mode == 'L' else ext}"  # any case, as every read extension
    path.parent.mkdir()
    try:
        Image.fromarray(pixels, mode).save(path, format={".qoi": "QOI", ".sgi": "SGI", ".pcx": "PCX"}[ext])
    except (KeyError, OSError, ValueError) as exc:  # QOI is written from Pillow 11.3 on
        pytest.skip(f"this Pillow does not write {ext}: {exc}")
    assert ext in READ_SUFFIXES
    image = load_image(path, dtype=None)
    want = pixels[..., None] if mode == "L" else pixels
    np.testing.assert_array_equal(image, want)
    (item,) = batch.find_work(tmp_path / "src", tmp_path / "out")
    assert item["path"].name == path.name


def test_an_avif_file_and_a_pillow_older_than_11_2_is_one_line_naming_the_upgrade(tmp_path, monkeypatch):
    # pyproject allows Pillow 10, which has no AVIF plugin: an AVIF exemplar was "not a readable image (not an image
    # format tghop reads)", though tghop lists .avif among what it reads.
    from PIL import features

    from tghop._errors import MissingExtraError

    if not features.check("avif"):
        pytest.skip("this Pillow writes no AVIF")
    path = tmp_path / "wall.avif"
    Image.fromarray(np.full((16, 16, 3), 100, np.uint8)).save(path)
    Image.init()
    monkeypatch.delitem(Image.OPEN, "AVIF")  # what Pillow 10 and 11.1 have: no plugin, no module named avif
    monkeypatch.setattr(Image, "ID", [i for i in Image.ID if i != "AVIF"])
    monkeypatch.delitem(features.modules, "avif")
    monkeypatch.setattr("PIL.__version__", "11.1.0")
    with pytest.raises(MissingExtraError) as caught:
        load_image(path)
    said = str(caught.value)
    assert said == (f"{path}: an AVIF image, which Pillow reads from version 11.2 on, and this is Pillow 11.1.0; "
                    "install a Pillow that reads it (pip install --upgrade pillow) or convert the file to PNG"), said


@pytest.mark.parametrize("size", [240, 250, 255])
def test_a_name_the_file_system_takes_is_written(tmp_path, size):
    # 0.62's probe and temporary files were the whole name and 14-16 more: a name of 240 to 255 bytes, which the file
    # system takes, was refused as "File name too long" (tghop synth -o, and a --stages step named after it).
    from tghop.imageio import check_output_path, save_image, save_images

    img = np.full((4, 4, 3), 0.5)
    name = "é" * ((size - 4) // 2) + "a" * ((size - 4) % 2) + ".png"
    assert len(name.encode()) == size
    check_output_path(tmp_path / name)
    save_image(img, tmp_path / name)
    save_images([(img, tmp_path / name, 8), (img, tmp_path / "b.png", 8)])
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([name, "b.png"])


def test_a_name_over_the_file_systems_limit_is_refused_in_its_words(tmp_path):
    from tghop._errors import InvalidImageError
    from tghop.imageio import check_output_path

    # 0.62: the path's first 80 characters, "cannot write the image there (File name too long)": a step's or map's
    # name, its end, cut off
    path = tmp_path / ("a" * 240 + "_patch-refine.png")
    with pytest.raises(InvalidImageError) as said:
        check_output_path(path)
    assert str(said.value) == (f"{str(path)[:60]}...{'a' * 23}_patch-refine.png: the file's name is 257 bytes, more "
                               "than a name may have (File name too long); give a shorter name for the image")
    assert list(tmp_path.iterdir()) == []


def test_save_images_writes_a_long_name_that_its_check_passes(tmp_path):
    # check_output_path's probe is the name and 16 characters; save_images' temporary file, of the whole name, and
    # save_image's own beside it were the name and 29: a name of 227 to 239 characters passed the check and failed
    # at the write (0.61: a material's maps, OUT_height.png, after every map was made; and 0.62's --stages sets).
    from tghop.imageio import check_output_path, save_images

    img = np.full((4, 4, 3), 0.5)
    long = tmp_path / ("a" * 231 + ".png")
    check_output_path(long)
    save_images([(img, long, 8), (img, tmp_path / "b.png", 16)])
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([long.name, "b.png"])
    np.testing.assert_allclose(load_image(long), img, atol=1 / 255)
