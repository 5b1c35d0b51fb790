"""Odd and damaged image files written byte by byte in code: 32-bit BMP files whose 4th byte is alpha
or padding as their header says (:mod:`tghop.bmp`), image files cut short named by their format, and
manifests and model files whose JSON repeats a key."""

import struct
import warnings

import numpy as np
import pytest

from tghop import InvalidImageError
from tghop.imageio import load_image


def bmp_bytes(rgba, *, header=40, compression=0, masks=None, bits=32, top_down=False):
    """A BMP of ``rgba`` (H, W, 4 uint8) written byte by byte: each pixel packed by ``masks`` (r, g, b, a;
    BI_RGB's layout, blue lowest and the 4th byte highest, where None), in a ``header``-byte info header
    (its masks at 40-56 when it is that long, else, for BI_BITFIELDS or BI_ALPHABITFIELDS, after it)."""
    height, width, _ = rgba.shape
    masks = masks or (0xFF0000, 0xFF00, 0xFF, 0xFF000000)
    pixels = np.zeros((height, width), np.uint64)
    for channel, mask in enumerate(masks):
        if mask:
            shift = (mask & -mask).bit_length() - 1
            top = mask >> shift
            pixels |= ((rgba[..., channel].astype(np.uint64) * top + 127) // 255) << np.uint64(shift)
    rows = pixels.astype("<u4" if bits == 32 else "<u2")
    stride = (bits * width + 31) // 32 * 4
    data = b"".join(row.tobytes().ljust(stride, b"\0") for row in (rows if top_down else rows[::-1]))
    info = struct.pack("<IiiHHIIiiII", header, width, -height if top_down else height, 1, bits, compression,
                       len(data), 2835, 2835, 0, 0)
    if header > 40:
        info = (info + struct.pack("<IIII", *masks))[:header].ljust(header, b"\0")
    elif compression in (3, 6):
        info += struct.pack("<IIII" if compression == 6 else "<III", *masks[:4 if compression == 6 else 3])
    offset = 14 + len(info)
    return b"BM" + struct.pack("<IHHI", offset + len(data), 0, 0, offset) + info + data


def texture(alpha_top=255, alpha_bottom=0):
    """A 4x5 RGBA image: distinct colours, its top two rows ``alpha_top``, the others ``alpha_bottom``."""
    rgba = np.zeros((4, 5, 4), np.uint8)
    rgba[..., 0] = 200
    rgba[..., 1] = np.arange(5) * 40
    rgba[..., 2] = np.arange(4)[:, None] * 60
    rgba[..., 3] = alpha_bottom
    rgba[:2, :, 3] = alpha_top
    return rgba


def read(path, **options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        arr = load_image(path, dtype=None, **options)
    return arr, [str(w.message) for w in caught]


V5_ALPHA = (0xFF0000, 0xFF00, 0xFF, 0xFF000000)


@pytest.mark.parametrize("header, compression, masks, alpha", [
    (40, 0, None, False),  # BI_RGB: "the high byte in each DWORD is not used"
    (124, 0, (0xFF0000, 0xFF00, 0xFF, 0), False),  # a V5 header whose alpha mask is 0
    (124, 0, V5_ALPHA, True),  # a V5 header's alpha mask names it (Pillow ignored it)
    (108, 3, V5_ALPHA, True),  # BI_BITFIELDS, alpha in the mask
    (40, 3, (0xFF0000, 0xFF00, 0xFF, 0), False),  # BI_BITFIELDS after a 40-byte header: no alpha mask
    (124, 3, (0xFF, 0xFF00, 0xFF0000, 0xFF000000), True),  # R, G, B, A in byte order
    (108, 3, (0xFF00, 0xFF0000, 0xFF000000, 0xFF), True),  # A, R, G, B: Pillow "Unsupported BMP bitfields layout"
    (40, 6, V5_ALPHA, True),  # BI_ALPHABITFIELDS: Pillow "Unsupported BMP compression (6)"
    (124, 3, (0x3FF00000, 0xFFC00, 0x3FF, 0xC0000000), True),  # 10-10-10-2
])
def test_a_32_bit_bmp_s_4th_byte_is_alpha_only_where_its_header_s_mask_says_so(tmp_path, header, compression, masks,
                                                                              alpha):
    path = tmp_path / "t.bmp"
    rgba = texture()
    path.write_bytes(bmp_bytes(rgba, header=header, compression=compression, masks=masks))
    arr, said = read(path, keep_alpha=True)
    if arr.dtype == np.uint8:
        arr = arr.astype(np.float64) / 255.0
    assert arr.shape == (4, 5, 4 if alpha else 3)
    np.testing.assert_allclose(arr[..., :3], rgba[..., :3] / 255.0, atol=0.002)
    if alpha:
        np.testing.assert_allclose(arr[..., 3], rgba[..., 3] / 255.0, atol=0.34)
    assert not said
    arr, said = read(path)  # without keep_alpha: dropped and said, as for a PNG
    assert arr.shape[2] == 3
    assert [s for s in said if "alpha channel dropped" in s] == (["t.bmp: alpha channel dropped, though 50% of its "
                                                                  "pixels are transparent: the colours under them are "
                                                                  "taken as texture; crop it to its opaque part, or "
                                                                  "leave that part out with an exclude mask "
                                                                  "(--exclude MASK, white where it is transparent)"]
                                                                 if alpha else [])


@pytest.mark.parametrize("top_down", [False, True])
def test_an_alpha_mask_whose_bytes_are_0_everywhere_is_padding_and_said(tmp_path, top_down):
    path = tmp_path / "pad.bmp"
    rgba = texture(0, 0)
    path.write_bytes(bmp_bytes(rgba, header=124, compression=3, masks=V5_ALPHA, top_down=top_down))
    arr, said = read(path, keep_alpha=True)
    np.testing.assert_array_equal(arr, rgba[..., :3])
    assert said == ["pad.bmp: its 4th byte, marked as alpha by the header's alpha mask, is 0 everywhere: taken as "
                    "padding and ignored, as browsers read it (as alpha it would hide every pixel)"]


def test_an_os2_header_s_fields_after_40_bytes_are_no_masks(tmp_path):
    """OS/2's 64-byte BITMAPCOREHEADER2 holds halftoning fields where a V3 header's alpha mask lies."""
    path = tmp_path / "os2.bmp"
    rgba = texture()
    blob = bytearray(bmp_bytes(rgba, header=64))
    blob[66:70] = struct.pack("<I", 0x12345)  # its halftoning sizes: no mask
    path.write_bytes(bytes(blob))
    from PIL import Image

    with Image.open(path) as im:
        expected = np.asarray(im.convert("RGB"))
    arr, said = read(path, keep_alpha=True)
    np.testing.assert_array_equal(arr, expected)
    assert not said


def test_a_16_bit_bmp_with_an_alpha_mask_keeps_its_alpha(tmp_path):
    path = tmp_path / "argb4444.bmp"
    rgba = texture()
    path.write_bytes(bmp_bytes(rgba, header=124, compression=3, masks=(0xF00, 0xF0, 0xF, 0xF000), bits=16))
    arr, said = read(path, keep_alpha=True)
    assert arr.shape == (4, 5, 4) and not said
    np.testing.assert_allclose(arr / 255.0, rgba / 255.0, atol=1 / 30)


@pytest.mark.parametrize("masks", [(0xFF0000, 0xFF00, 0xF0F, 0), (0xFF0000, 0xFFFF00, 0xFF, 0), (0, 0xFF00, 0xFF, 0)])
def test_bmp_masks_that_are_no_separate_runs_of_bits_are_one_line(tmp_path, masks):
    path = tmp_path / "odd.bmp"
    path.write_bytes(bmp_bytes(texture(), header=124, compression=3, masks=masks))
    with pytest.raises(InvalidImageError, match=r"odd\.bmp: a BMP whose colour masks .* are not separate runs of "
                                                r"bits; save it again"):
        load_image(path)


def test_a_32_bit_bmp_cut_short_is_named_a_damaged_bmp(tmp_path):
    path = tmp_path / "cut.bmp"
    path.write_bytes(bmp_bytes(texture(), header=124, compression=3, masks=V5_ALPHA)[:-30])
    with pytest.raises(InvalidImageError, match=r"cut\.bmp: a damaged BMP: its pixels are cut short \(50 of 80 "
                                                r"bytes\); save or download it again"):
        load_image(path)


def saved(fmt, **options):
    """A 48x40 noise image in Pillow's ``fmt``, as bytes."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    rgb = (np.random.default_rng(0).random((40, 48, 3)) * 255).astype(np.uint8)
    Image.fromarray(rgb).save(buf, format=fmt, **options)
    return buf.getvalue()


@pytest.mark.parametrize("suffix, fmt, name", [
    ("png", "PNG", "a PNG"), ("jpg", "JPEG", "a JPEG"), ("tif", "TIFF", "a TIFF"), ("webp", "WEBP", "a WebP"),
    ("qoi", "QOI", "a QOI"), ("tga", "TGA", "a TGA"), ("bmp", "BMP", "a BMP"), ("gif", "GIF", "a GIF"),
    ("ppm", "PPM", "a PNM"), ("sgi", "SGI", "an SGI"), ("pcx", "PCX", "a PCX"), ("dds", "DDS", "a DDS"),
])
def test_an_image_cut_short_is_named_a_damaged_file_of_its_format(tmp_path, suffix, fmt, name):
    """0.58: "not a readable image (truncated or corrupt: OSError: image file is truncated ...); give a PNG, JPEG
    or other common image file", no format named, and another file asked for."""
    if fmt == "WEBP":
        from PIL import features

        if not features.check_module("webp"):
            pytest.skip("this Pillow reads no WebP")
    path = tmp_path / f"cut.{suffix}"
    blob = saved(fmt)
    path.write_bytes(blob[: len(blob) // 2])
    with pytest.raises(InvalidImageError) as error:
        load_image(path)
    said = str(error.value)
    assert said.startswith(f"{path}: not a readable image ({name} file, ") and "\n" not in said, said
    assert said.endswith("; save or download it again"), said


def test_a_tga_whose_header_is_damaged_is_named_by_its_extension(tmp_path):
    """TGA has no signature: 0.58 said "not an image format tghop reads" of one whose header Pillow refused."""
    path = tmp_path / "damaged.tga"
    blob = bytearray(saved("TGA"))
    blob[1] = 7  # a colour map type no TGA has
    path.write_bytes(bytes(blob))
    with pytest.raises(InvalidImageError) as error:
        load_image(path)
    assert str(error.value) == (f"{path}: not a readable image (named as a TGA file, but Pillow cannot read its "
                                "header as one: damaged, or another kind of file renamed); save or download it "
                                "again, or give a PNG, JPEG or other common image file")


@pytest.mark.parametrize("line, key", [
    ('{"path": "a.png", "size": "512x512", "size": "64x64"}', "'size'"),
    ('{"path": "a.png", "maps": {"normal": "n.png", "normal": "m.png"}}', "'normal'"),  # at any depth
])
def test_a_manifest_row_that_repeats_a_key_is_refused_naming_it(tmp_path, line, key):
    """0.58 kept the last value of a repeated key without a word (json.loads)."""
    from tghop import TGHopError
    from tghop.manifest import read_manifest

    (tmp_path / "a.png").write_bytes(saved("PNG"))
    manifest = tmp_path / "m.jsonl"
    manifest.write_text('{"path": "a.png"}\n' + line + "\n")
    with pytest.raises(TGHopError) as error:
        read_manifest(manifest)
    assert str(error.value) == (f"{manifest} line 2: the key {key} is given twice; keep one (a JSON reader keeps "
                                "the last without a word)")


@pytest.mark.parametrize("maps, said", [
    # 0.59 took it, fitted the material, then failed writing its file: "... cannot write the image there (File name
    # too long)" (300), or wrote a map's file named longer than the command line and the page ever name one (100)
    ({"n" * 300: "n.png"}, "is 300 characters, more than the 64 a map's name may have (it names the map's file); "
                           "shorten it"),
    ({"n" * 100: "n.png"}, "is 100 characters, more than the 64"),
    # 0.59: "the map 'normal' has no path", of an object holding one
    ({"normal": {"path": "n.png"}}, "the file of the map 'normal' must be a path (a string), not a JSON object"),
    ({"normal": 3}, "the file of the map 'normal' must be a path (a string), not a number"),
])
def test_a_manifest_row_s_map_name_too_long_or_file_not_a_path_is_refused_before_any_fit(tmp_path, maps, said):
    import json

    from tghop import TGHopError
    from tghop.manifest import read_manifest

    (tmp_path / "a.png").write_bytes(saved("PNG"))
    (tmp_path / "n.png").write_bytes(saved("PNG"))
    manifest = tmp_path / "m.jsonl"
    manifest.write_text(json.dumps({"path": "a.png", "maps": maps}) + "\n")
    with pytest.raises(TGHopError) as error:
        read_manifest(manifest)
    assert str(error.value).startswith(f"{manifest} line 1: ") and said in str(error.value), str(error.value)


def test_a_model_file_whose_metadata_repeats_a_key_is_refused_naming_it(tmp_path):
    from tghop import ModelFileError
    from tghop.modelfile import load_model

    path = tmp_path / "m.npz"
    np.savez(path, __meta__=np.array('{"format": "tghop-model", "format_version": 9, "format_version": 1}'))
    with pytest.raises(ModelFileError) as error:
        load_model(path)
    assert str(error.value) == f"{path}: this model file was edited, damaged or written by another program, so " \
        f"tghop cannot use it; fit the model again from its exemplar: tghop fit EXEMPLAR -o {path} (what is wrong: " \
        "the metadata gives the key 'format_version' twice)"


def test_a_model_file_whose_array_header_declares_far_more_than_it_holds_names_that_array(tmp_path):
    """A member's .npy header declaring 49 TB (an edited or hostile file) made NumPy fail to allocate it: 0.59 said
    "cannot read it: MemoryError", which reads as the machine's shortage, not the file's damage."""
    import io
    import zipfile

    from tghop import ModelFileError
    from tghop.modelfile import load_model

    header = "{'descr': '<f4', 'fortran_order': False, 'shape': (3, 32, 32, 4000000000), }".ljust(117) + "\n"
    meta = io.BytesIO()
    np.lib.format.write_array(meta, np.array('{"format": "tghop-model", "format_version": 11}'))
    path = tmp_path / "m.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("__meta__.npy", meta.getvalue())
        archive.writestr("material_patch.patch.directions.npy", b"\x93NUMPY\x01\x00" + struct.pack("<H", 118)
                         + header.encode() + b"\0" * 1000)
    with pytest.raises(ModelFileError) as error:
        load_model(path)
    assert str(error.value) == (f"{path}: truncated, corrupt or not a tghop model file (its array "
                                "'material_patch.patch.directions' declares shape (3, 32, 32, 4000000000) of float32, "
                                "49 TB, but holds 1,000 bytes); fit the model again")


def test_a_checkpoint_whose_settings_repeat_a_key_is_refused_naming_it(tiny_cooc_checkpoint, tmp_path):
    """0.59 read a co-occurrence checkpoint's settings with json.loads: the last value of a repeated key, without a
    word (here a crop size the networks were not built for, then the real one)."""
    import json

    import torch

    from tghop import ModelFileError, cooc

    tensors = torch.load(tiny_cooc_checkpoint, map_location="cpu", weights_only=True)
    text = bytes(tensors["settings_json"].numpy().tobytes()).decode()
    assert text.startswith("{") and '"kind"' in text
    text = '{"kind": "another", ' + text[1:]  # the real "kind" after it
    json.loads(text)  # a JSON reader takes it, the last "kind" winning
    tensors["settings_json"] = torch.frombuffer(bytearray(text.encode()), dtype=torch.uint8)
    path = tmp_path / "edited.pt"
    torch.save(tensors, path)
    with pytest.raises(ModelFileError) as error:
        cooc.load(path)
    assert str(error.value) == f"{path}: corrupt checkpoint settings (the key 'kind' is given twice); train it again"


#: An EXIF block whose first directory says it holds 5 entries and holds 1 (the orientation, 6): Pillow stops
#: at the second and warns "Corrupt EXIF data. Expecting to read 12 bytes but only got 0."
DAMAGED_EXIF = (b"Exif\x00\x00MM\x00*" + struct.pack(">IH", 8, 5) + b"\x01\x12\x00\x03\x00\x00\x00\x01\x00\x06\x00\x00")


@pytest.mark.parametrize("fmt, suffix", [("JPEG", "jpg"), ("PNG", "png"), ("WEBP", "webp")])
@pytest.mark.parametrize("where", ["main thread", "another thread"])
def test_a_damaged_exif_block_is_said_in_tghop_s_words_on_every_thread(tmp_path, fmt, suffix, where):
    """0.58 said it in tghop's words on the main thread alone, and of a JPEG alone: a server's upload or a batch
    worker's exemplar (read on other threads) and a PNG's eXIf chunk gave Pillow's "Corrupt EXIF data. ...", naming
    no file. No filter or handler of the process may change (``warnings.catch_warnings`` is process-wide)."""
    import threading

    from PIL import features

    from tghop._errors import collect_warnings

    if fmt == "WEBP" and not features.check_module("webp"):
        pytest.skip("this Pillow reads no WebP")
    path = tmp_path / f"damaged.{suffix}"
    path.write_bytes(saved(fmt, exif=DAMAGED_EXIF))
    kept, shown = [], []

    def read():
        with collect_warnings() as collected:  # as the server and a batch worker read
            load_image(path)
        kept.extend(str(w) for w in collected)

    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = lambda message, *args, **kwargs: shown.append(str(message))
        before = (list(warnings.filters), warnings.showwarning)
        if where == "main thread":
            read()
        else:
            reader = threading.Thread(target=read)
            reader.start()
            reader.join()
        after = (list(warnings.filters), warnings.showwarning)
    assert kept == ["damaged.%s: its EXIF data is damaged (Expecting to read 12 bytes but only got 0); its "
                    "orientation is not read: the pixels are taken as stored" % suffix]
    assert shown == [] and before == after


def zero_width_bmp(tmp_path):
    blob = bytearray(saved("BMP"))
    blob[18:22] = struct.pack("<i", 0)
    return bytes(blob)


def tiff_cut_in_its_directory(tmp_path):
    blob = saved("TIFF")
    first = struct.unpack("<I", blob[4:8])[0]
    return blob[:first + 20]  # its first directory's count and a few entries: Pillow warned "Corrupt EXIF data"


def one_pixel_png(tmp_path):
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (1, 1), (200, 30, 40)).save(buf, format="PNG")
    return buf.getvalue()


@pytest.mark.parametrize("name, make, said", [
    ("zero_width.bmp", zero_width_bmp, "zero_width.bmp: not a readable image (a BMP file, but its header is corrupt "
                                       "or of a kind tghop does not read); save or download it again, or give a PNG"),
    ("cut.tif", tiff_cut_in_its_directory, "cut.tif: not a readable image (a TIFF file, cut short: its first "
                                           "directory ends past the file's end); save or download it again"),
    ("dot.png", one_pixel_png, "the exemplar is 1x1 pixels, too small to hold a texture; give a larger image"),
])
def test_the_fuzz_round_s_odd_files_are_one_line_naming_their_problem(tmp_path, name, make, said):
    """The 0.59 fuzz round's findings: 0.58 said "named ... not a readable image" of a BMP whose width is 0
    (its signature said BMP), warned "Corrupt EXIF data" (Pillow's words, as a damaged EXIF block on the main
    thread) of a TIFF cut short in its tags, and called a 1x1 image flat. Every one: one line, exit status 1,
    no warning, no file written."""
    from click.testing import CliRunner

    from tghop.cli import main

    path, out = tmp_path / name, tmp_path / "out.npz"
    path.write_bytes(make(tmp_path))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = CliRunner().invoke(main, ["fit", str(path), "-o", str(out), "-q"])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 1 and len(lines) == 1 and said in lines[0], result.output
    assert not caught and not out.exists()


def test_is_image_says_nothing_of_a_damaged_exif_block_on_any_thread(tmp_path):
    """The server asks is_image of an upload it could not read as a model (from memory, on a thread): 0.58 let
    Pillow's "Corrupt EXIF data" reach the console."""
    import io
    import threading

    from tghop.imageio import is_image

    blob = saved("JPEG", exif=DAMAGED_EXIF)
    (tmp_path / "d.jpg").write_bytes(blob)
    answers, shown = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = lambda message, *args, **kwargs: shown.append(str(message))
        reader = threading.Thread(target=lambda: answers.extend([is_image(io.BytesIO(blob)),
                                                                 is_image(tmp_path / "d.jpg")]))
        reader.start()
        reader.join()
    assert answers == [True, True] and shown == []


@pytest.mark.parametrize("fmt, suffix, name", [("AVIF", "avif", "an AVIF"), ("JPEG2000", "jp2", "a JPEG 2000")])
def test_an_avif_or_jpeg_2000_cut_in_its_header_is_named_by_its_signature(tmp_path, fmt, suffix, name):
    """0.58 said "not an image format tghop reads" of them (a format it reads) where Pillow has the decoder."""
    from PIL import features

    if not (features.check_module("avif") if fmt == "AVIF" else features.check_codec("jpg_2000")):
        pytest.skip(f"this Pillow reads no {fmt}")
    path = tmp_path / f"cut.{suffix}"
    path.write_bytes(saved(fmt)[:40])
    with pytest.raises(InvalidImageError) as error:
        load_image(path)
    assert str(error.value).startswith(f"{path}: not a readable image ({name} file, "), str(error.value)
    assert str(error.value).endswith("; save or download it again") or "save or download it again, or" in \
        str(error.value), str(error.value)


#: An EXIF block whose first directory is whole, the orientation (6) first, then a description whose value lies
#: past the block's end: Pillow skips it warning "Truncated File Read" (or "Tag data larger than file").
VALUE_PAST_END = (b"Exif\x00\x00MM\x00*" + struct.pack(">IH", 8, 2)
                  + b"\x01\x12\x00\x03\x00\x00\x00\x01\x00\x06\x00\x00"
                  + struct.pack(">HHII", 0x010E, 2, 40, 4000) + b"\x00\x00\x00\x00")


@pytest.mark.parametrize("fmt, suffix", [("JPEG", "jpg"), ("PNG", "png"), ("WEBP", "webp")])
@pytest.mark.parametrize("where", ["main thread", "another thread"])
def test_an_exif_value_past_the_block_s_end_is_passed_over_without_pillow_s_warning(tmp_path, fmt, suffix, where):
    """0.58 passed Pillow's warning on (main thread) or let it reach the console (other threads); the value is of
    no use to tghop, and the orientation beside it is still applied."""
    import threading

    from PIL import features

    if fmt == "WEBP" and not features.check_module("webp"):
        pytest.skip("this Pillow reads no WebP")
    path = tmp_path / f"past.{suffix}"
    path.write_bytes(saved(fmt, exif=VALUE_PAST_END))
    shapes, shown = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = lambda message, *args, **kwargs: shown.append(str(message))
        if where == "main thread":
            shapes.append(load_image(path).shape)
        else:
            reader = threading.Thread(target=lambda: shapes.append(load_image(path).shape))
            reader.start()
            reader.join()
    assert shapes == [(48, 40, 3)] and shown == []  # 40x48 stored, orientation 6: turned


@pytest.mark.parametrize("kind", [5, 17, 18])
@pytest.mark.parametrize("fmt, suffix", [("JPEG", "jpg"), ("PNG", "png")])
def test_an_exif_value_past_the_end_of_a_type_pillow_reads_or_not_keeps_the_orientation_without_a_word(
        tmp_path, fmt, suffix, kind):
    """The check of an EXIF block's values counts the field types Pillow reads, as the TIFF reader does (0.61: one
    table, tghop.tiff_tags.FIELD_BYTES; 0.60's own copy also counted 17 and 18, which Pillow passes over without a
    word): whatever the type, the orientation is applied and nothing is said, as in 0.60."""
    from tghop import image_decode, tiff_tags

    assert kind in image_decode.FIELD_BYTES or kind in (17, 18)
    assert image_decode.FIELD_BYTES is tiff_tags.FIELD_BYTES
    exif = bytearray(VALUE_PAST_END)
    exif[6 + 10 + 12 + 2:6 + 10 + 12 + 4] = struct.pack(">H", kind)  # the description's field type
    path = tmp_path / f"past.{suffix}"
    path.write_bytes(saved(fmt, exif=bytes(exif)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert load_image(path).shape == (48, 40, 3)
    assert [str(w.message) for w in caught] == []


def test_a_file_object_is_looked_into_from_where_it_stands_and_put_back(tmp_path):
    """A TIFF's tags and a JPEG's EXIF block are looked into before Pillow opens a file object (0.61: one dispatch,
    _formats.read_as_it_stands, where quiet_copy and the EXIF check had a copy each): from where it stands, put
    back there, named by its name."""
    import io

    from tghop.image_decode import open_image
    from tghop.tiff_tags import quiet_copy

    jpeg = bytearray(saved("JPEG", exif=b"Exif\x00\x00MM\x00*" + struct.pack(">IH", 8, 9)))  # 9 entries, none there
    stream = io.BytesIO(b"junk" + bytes(jpeg))
    stream.seek(4)
    stream.name = "streamed.jpg"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with open_image(stream) as im:
            assert im.size == (48, 40)
    assert [str(w.message)[:44] for w in caught] == ["streamed.jpg: its EXIF data is damaged (Expe"]
    tiff = io.BytesIO(b"junk" + saved("TIFF"))
    tiff.seek(4)
    assert quiet_copy(tiff) is None and tiff.tell() == 4
    assert quiet_copy(123) is None  # neither a path nor a file object: left to Pillow


@pytest.mark.parametrize("members, kind", [
    (["tghop-rock-64x64-seed3.png", "tghop-rock-64x64-seed3_normal.png", "tghop-rock-64x64-seed3_height.png"],
     "a ZIP archive of 3 images (tghop-rock-64x64-seed3.png, tghop-rock-64x64-seed3_normal.png, ...; the page's "
     "'Download all maps' saves one: unzip it and give its images)"),
    ([], "an empty ZIP archive"),
])
def test_a_zip_of_images_given_as_a_model_or_an_image_is_named_as_one(tmp_path, members, kind):
    """The page's "Download all maps" ZIP given back: 0.59 called it "a NumPy archive but not a tghop model file" as
    a model and "a model file, not an image" as an exemplar."""
    import zipfile

    from click.testing import CliRunner

    from tghop import ModelFileError
    from tghop.cli import main
    from tghop.modelfile import load_model

    path = tmp_path / "maps.zip"
    with zipfile.ZipFile(path, "w") as archive:
        for name in members:
            archive.writestr(name, saved("PNG"))
    with pytest.raises(ModelFileError) as error:
        load_model(path)
    assert str(error.value) == f"{path}: {kind}, not a tghop model file; give a model file tghop wrote"
    result = CliRunner().invoke(main, ["fit", str(path), "-o", str(tmp_path / "m.npz"), "-q"])
    assert result.exit_code == 1 and result.output.strip() == (f"Error: {path} is {kind}, not an image; this command "
                                                               "needs an image"), result.output
