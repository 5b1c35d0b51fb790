"""Hostile and broken image files made in code (a header declaring 100000x100000 pixels over a few
bytes of data, a TIFF whose tags disagree): every command gives one ``Error:`` line that names the
fix, a non-zero exit status, nothing else on the terminal and no output file."""

import io
import struct
import zlib

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from tghop.cli import main


def png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_declaring(width: int, height: int) -> bytes:
    """A PNG whose header declares ``width`` x ``height`` RGB pixels, with 1000 bytes of pixel data."""
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", header) + png_chunk(b"IDAT", zlib.compress(b"\0" * 1000))
            + png_chunk(b"IEND", b""))


def jpeg_declaring(side: int) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.zeros((16, 16, 3), np.uint8)).save(buf, format="JPEG")
    data = bytearray(buf.getvalue())
    frame = data.find(b"\xff\xc0")  # baseline start of frame: length, precision, height, width
    data[frame + 5:frame + 9] = struct.pack(">HH", side, side)
    return bytes(data)


def gif_declaring(side: int) -> bytes:
    buf = io.BytesIO()
    Image.new("P", (16, 16)).save(buf, format="GIF")
    data = bytearray(buf.getvalue())
    data[6:10] = struct.pack("<HH", side, side)  # the logical screen
    return bytes(data)


def tiff_declaring(tmp_path, side: int) -> bytes:
    """A TIFF of one pixel whose ImageWidth and ImageLength tags say ``side``: its strip tags then
    disagree with them, which tifffile logs as warnings."""
    tifffile = pytest.importorskip("tifffile")
    path = tmp_path / "one.tif"
    tifffile.imwrite(path, np.zeros((1, 1), np.uint8))
    data = bytearray(path.read_bytes())
    first = struct.unpack("<I", data[4:8])[0]
    for k in range(struct.unpack("<H", data[first:first + 2])[0]):
        entry = first + 2 + 12 * k
        tag, kind = struct.unpack("<HH", data[entry:entry + 4])
        if tag in (256, 257):
            data[entry + 8:entry + 12] = struct.pack("<HH", side, 0) if kind == 3 else struct.pack("<I", side)
    return bytes(data)


BOMBS = {"bomb.png": lambda tmp: png_declaring(100_000, 100_000), "bomb.jpg": lambda tmp: jpeg_declaring(65_000),
         "bomb.gif": lambda tmp: gif_declaring(65_535), "bomb.tif": lambda tmp: tiff_declaring(tmp, 60_000)}


def one_error_line(result, *fragments):
    assert result.exit_code not in (0, None) and not isinstance(result.exception, (AssertionError, TypeError))
    lines = result.output.splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), result.output
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    return lines[0]


@pytest.fixture(scope="module")
def small_model(tmp_path_factory):
    from tghop import TGHop, data
    from tghop.modelfile import save_model

    path = tmp_path_factory.mktemp("model") / "m.npz"
    save_model(TGHop(n_clusters=2, n_codewords=5, stride=4, max_patches=300, rng=0).fit(data.bricks(64, rng=3)), path)
    return path


@pytest.mark.parametrize("name", sorted(BOMBS))
@pytest.mark.parametrize("command", ["fit", "synth", "inpaint-image", "inpaint-mask"])
def test_a_header_declaring_too_many_pixels_is_one_line_naming_the_fix(tmp_path, small_model, monkeypatch, name,
                                                                      command):
    """0.56 ended the line at "tghop reads at most 67,108,864 pixels" (no fix), and printed
    tifffile's logged warnings of the TIFF (``incorrect StripOffsets count``) as lines of their own:
    with no logging set up (as in a shell; pytest's own handlers taken away), Python's last resort
    prints them to stderr."""
    import logging

    monkeypatch.setattr(logging.root, "handlers", [])
    bomb = tmp_path / name
    bomb.write_bytes(BOMBS[name](tmp_path))
    good = tmp_path / "good.png"
    Image.fromarray((np.random.default_rng(0).random((64, 64, 3)) * 255).astype(np.uint8)).save(good)
    out = tmp_path / ("out.npz" if command == "fit" else "out.png")
    args = {"fit": ["fit", str(bomb), "-o", str(out)],
            "synth": ["synth", str(bomb), "-o", str(out), "--size", "32x32"],
            "inpaint-image": ["inpaint", str(bomb), str(good), "-o", str(out), "--source", str(small_model)],
            "inpaint-mask": ["inpaint", str(good), str(bomb), "-o", str(out), "--source", str(small_model)]}[command]
    result = CliRunner().invoke(main, args + ["-q"])
    one_error_line(result, f"{name}: the image header declares too many pixels", "downscale it first")
    assert not out.exists()


def deflated_bomb(path, unpacked: int, arrays=None):
    """An .npz archive of ``arrays`` (stored) and one more member, ``bomb``: a float32 array of
    ``unpacked`` bytes of zeros, deflated (about a thousandth of that in the file)."""
    import zipfile

    with zipfile.ZipFile(path, "w") as archive:
        for name, value in (arrays or {}).items():
            buf = io.BytesIO()
            np.save(buf, value)
            archive.writestr(name + ".npy", buf.getvalue())
        header = f"{{'descr': '<f4', 'fortran_order': False, 'shape': ({unpacked // 4},), }}"
        header = header + " " * (118 - len(header)) + "\n"
        info = zipfile.ZipInfo("bomb.npy")
        info.compress_type = zipfile.ZIP_DEFLATED
        with archive.open(info, "w", force_zip64=True) as member:
            member.write(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode())
            chunk = b"\0" * (1 << 22)
            for _ in range(unpacked // len(chunk)):
                member.write(chunk)
    return path


@pytest.mark.parametrize("command", ["info", "synth", "inpaint"])
def test_a_model_file_that_unpacks_to_far_more_than_its_size_is_refused_before_it_is_unpacked(
        tmp_path, small_model, monkeypatch, command):
    """A 200 MB array of zeros deflated into 200 KB: 0.56 unpacked all of it (50 MB of such a file
    would be 50 GB) before it found an array tghop does not know. save_model stores its arrays
    uncompressed, so its own files are never near the bound."""
    with np.load(small_model) as data:
        arrays = {name: data[name] for name in data.files}
    bomb = deflated_bomb(tmp_path / "bomb.npz", 200 * 1024**2, arrays)
    assert bomb.stat().st_size < small_model.stat().st_size + 1024**2

    def unpacked(*args, **kwargs):
        raise AssertionError("np.load was called on the bomb")

    monkeypatch.setattr(np, "load", unpacked)
    out = tmp_path / "out.png"
    good = tmp_path / "good.png"
    Image.fromarray((np.random.default_rng(0).random((64, 64, 3)) * 255).astype(np.uint8)).save(good)
    hole = np.zeros((64, 64), np.uint8)
    hole[20:40, 20:40] = 255
    Image.fromarray(hole).save(tmp_path / "mask.png")
    args = {"info": ["info", str(bomb)], "synth": ["synth", str(bomb), "-o", str(out), "--size", "32x32", "-q"],
            "inpaint": ["inpaint", str(good), str(tmp_path / "mask.png"), "-o", str(out), "--source", str(bomb),
                        "-q"]}[command]
    one_error_line(CliRunner().invoke(main, args), "bomb.npz: its contents unpack to 2",
                   "(a decompression bomb?), not a model file tghop wrote; give a model file tghop wrote, or fit the "
                   "model again")
    assert not out.exists()


def test_a_model_file_deflated_by_another_program_still_loads(tmp_path, small_model):
    """The bound is on unpacked size over the file's: a model zipped again with deflate (savez_compressed)
    unpacks to a few times its size and is read as before."""
    from tghop.modelfile import load_model

    with np.load(small_model) as data:
        arrays = {name: data[name] for name in data.files}
    again = tmp_path / "deflated.npz"
    np.savez_compressed(again, **arrays)
    assert again.stat().st_size < small_model.stat().st_size
    model, plain = load_model(again), load_model(small_model)
    assert model.n_clusters == plain.n_clusters
    small = deflated_bomb(tmp_path / "small_bomb.npz", 8 * 1024**2)  # under UNPACK_SLACK: NumPy reads it
    with pytest.raises(Exception, match="not a tghop model file"):
        load_model(small)


@pytest.mark.parametrize("verb", ["morph", "edit"])
def test_a_checkpoint_that_unpacks_to_far_more_than_its_size_is_refused_before_it_is_unpacked(tmp_path, monkeypatch,
                                                                                             verb):
    """As a model file: torch.save stores its tensors uncompressed; 0.56 handed such an archive to
    torch.load, which unpacked what it read of it."""
    torch = pytest.importorskip("torch")
    bomb = deflated_bomb(tmp_path / "bomb.pt", 200 * 1024**2)

    def unpacked(*args, **kwargs):
        raise AssertionError("torch.load was called on the bomb")

    monkeypatch.setattr(torch, "load", unpacked)
    out = tmp_path / "out.png"
    args = {"morph": ["cooc", "morph", str(bomb), "crop:0,0", "crop:0,8", "-o", str(out)],
            "edit": ["cooc", "edit", str(bomb), "-o", str(out)]}[verb]
    one_error_line(CliRunner().invoke(main, args), "bomb.pt: its contents unpack to 2",
                   "(a decompression bomb?), not a checkpoint tghop wrote; give a checkpoint 'tghop cooc train' "
                   "wrote, or train it again")
    assert not out.exists()


@pytest.mark.parametrize("name", ["", " "])
@pytest.mark.parametrize("command", ["info", "patches", "clusters", "library"])
def test_an_empty_model_file_name_is_one_line_saying_so(tmp_path, small_model, name, command):
    """As an empty image or checkpoint name is; 0.56 said "load_model: path must be a file name (str or
    os.PathLike) to read the model from, got ''", the library's words, naming no fix (and read " " as a file)."""
    from tghop import ModelFileError
    from tghop.modelfile import load_model, save_model

    if command == "library":
        for call in (lambda: load_model(name), lambda: save_model(load_model(small_model), name)):
            with pytest.raises(ModelFileError, match="^the model's file name is empty; give one$"):
                call()
        return
    out = tmp_path / "out.png"
    good = tmp_path / "good.png"
    Image.fromarray((np.random.default_rng(0).random((64, 64, 3)) * 255).astype(np.uint8)).save(good)
    args = {"info": ["info", name], "patches": ["patches", name, "-o", str(out)],
            "clusters": ["clusters", name, str(good), "-o", str(out)]}[command]
    one_error_line(CliRunner().invoke(main, args), "the model's file name is empty; give one")
    assert not out.exists()


def complex_tiff(tmp_path) -> bytes:
    tifffile = pytest.importorskip("tifffile")
    tifffile.imwrite(tmp_path / "c.tif", np.ones((16, 16), np.complex64))
    return (tmp_path / "c.tif").read_bytes()


def png_with_bad_header_checksum(tmp_path) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.zeros((16, 16, 3), np.uint8)).save(buf, format="PNG")
    data = bytearray(buf.getvalue())
    data[29] ^= 0xFF  # the IHDR chunk's CRC
    return bytes(data)


@pytest.mark.parametrize("name, make, kind", [
    ("zero_width.png", lambda tmp: png_declaring(0, 64), "PNG"),
    ("bad_crc.png", png_with_bad_header_checksum, "PNG"),
    ("garbage.jpg", lambda tmp: b"\xff\xd8\xff" + bytes(range(256)) * 8, "JPEG"),
    ("complex.tif", complex_tiff, "TIFF"),
])
def test_a_file_of_a_format_tghop_reads_that_pillow_cannot_identify_is_called_corrupt(tmp_path, name, make, kind):
    """0.56 told "not an image format tghop reads" of a PNG whose width is 0 or whose header's checksum
    fails: the format is one tghop reads, the file is what is wrong."""
    path = tmp_path / name
    path.write_bytes(make(tmp_path))
    out = tmp_path / "out.npz"
    one_error_line(CliRunner().invoke(main, ["fit", str(path), "-o", str(out), "-q"]),
                   f"{name}: not a readable image (a {kind} file, but its header is corrupt or of a kind tghop "
                   "does not read)")
    assert not out.exists()


@pytest.mark.parametrize("route, field", [("/api/models", "image"), ("/api/models/upload", "model")])
@pytest.mark.parametrize("filename, long_field, words", [
    ("", False, "a form field over 1 MB (Part exceeded maximum size of 1024KB.): a file sent without a file name? "
                "Send each file with its file name, as a browser or curl -F NAME=@FILE does"),
    ("x" * 5000 + ".png", False, "a file name of 5,004 characters is too long (a multipart part's header holds about "
                                 "4,000 characters); rename the file shorter and send it again"),
    ("x.png", True, "a field name of 5,000 characters is too long (a multipart part's header holds about 4,000 "
                    "characters); name each field as docs/serve.md does ('image', 'model', ...)"),
])
def test_an_upload_the_multipart_parser_refuses_is_400_naming_what_to_do(live_server, route, field, filename,
                                                                          long_field, words):
    """0.56 answered "malformed multipart request (Part exceeded maximum size of 1024KB.)" of a 2 MB file
    sent with an empty file name (a field to the parser), naming no fix; 0.62 "malformed multipart request (Invalid
    multipart data.) ... send the form as a browser or curl -F NAME=@FILE sends it" of a file name or a field name of
    5,000 characters, which a browser sends as they are."""
    httpx = pytest.importorskip("httpx")
    with httpx.Client(base_url=live_server.url, timeout=60) as client:
        r = client.post(route, files={"f" * 5000 if long_field else field: (filename, b"\x89PNG" + bytes(2 * 1024**2))})
    assert r.status_code == 400, r.text
    message = r.json()["error"]
    assert message == words, message


def checkpoint_cut_short(path):
    """A torch.save layout (archive/data.pkl naming settings_json, then a tensor) without its zip directory."""
    import zipfile

    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as archive:
        archive.writestr("archive/data.pkl", b"\x80\x02}q\x00X\r\x00\x00\x00settings_jsonq\x01" + b"." * 200)
        archive.writestr("archive/data/0", bytes(4000))
    path.write_bytes(path.read_bytes()[:3000])
    return path


@pytest.mark.parametrize("command", ["synth", "info", "fit"])
def test_a_pt_file_that_is_no_image_or_model_names_the_cooc_commands(tmp_path, command):
    """0.56 said "not a readable image ... give a PNG" or "not a tghop model file ... fit the model
    again" of random bytes named .pt and of a checkpoint cut short, naming no 'tghop cooc' command."""
    noise = tmp_path / "x.pt"
    noise.write_bytes(np.random.default_rng(0).bytes(5000))
    cut = checkpoint_cut_short(tmp_path / "cut.bin")
    out = tmp_path / ("o.npz" if command == "fit" else "o.png")
    for path, said in ((noise, "a .pt or .pth name is a co-occurrence cGAN checkpoint's"),
                       (cut, "co-occurrence cGAN checkpoint")):
        args = {"synth": ["synth", str(path), "-o", str(out)], "info": ["info", str(path)],
                "fit": ["fit", str(path), "-o", str(out)]}[command]
        result = CliRunner().invoke(main, args)
        one_error_line(result, path.name, said, "'tghop cooc morph'")
        assert "fit the model again" not in result.output or path is noise
        assert not out.exists()


@pytest.mark.parametrize("case", ["grey and 4 unspecified", "rgb, alpha and 2 unspecified", "rgb and alpha",
                                  "rgb and 1 unspecified", "rgb and 2 unspecified"])
def test_a_tiff_s_extra_channels_that_are_not_alpha_are_said_dropped(tmp_path, case):
    """0.56 dropped them without a word (a multispectral file read as its first band)."""
    import warnings

    from tghop.imageio import load_image

    tifffile = pytest.importorskip("tifffile")
    samples, photometric, extras, said = {
        "grey and 4 unspecified": (5, "minisblack", [0, 0, 0, 0], "4 extra channels that are not alpha dropped; "
                                   "tghop reads its grey channel only"),
        "rgb, alpha and 2 unspecified": (6, "rgb", [2, 0, 0], "2 extra channels that are not alpha dropped; tghop "
                                         "reads its RGB channels and alpha only"),
        "rgb and alpha": (4, "rgb", [2], None),
        "rgb and 1 unspecified": (4, "rgb", [0], None),  # read as alpha (0.58), said: test_an_unmarked_4th_...
        "rgb and 2 unspecified": (5, "rgb", [0, 0], "2 extra channels that are not alpha dropped; tghop "
                                  "reads its RGB channels only")}[case]
    path = tmp_path / "many.tif"
    tifffile.imwrite(path, np.full((16, 16, samples), 200, np.uint8), photometric=photometric, extrasamples=extras)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        image = load_image(path)
    assert image.shape == (16, 16, 1 if photometric == "minisblack" else 3)
    dropped = [str(w.message) for w in caught if "extra channel" in str(w.message)]
    assert dropped == ([f"many.tif: {said}"] if said else []), dropped


def tiff_without_extrasamples(samples) -> bytes:
    """A little-endian, uncompressed, one-strip RGB TIFF of ``samples`` (H, W, 4) uint8 whose header has
    no ExtraSamples tag at all (as some writers leave it out: tifffile and Pillow always write it)."""
    height, width, spp = samples.shape
    data = samples.tobytes()
    entries = [(256, 3, 1, width), (257, 3, 1, height), (258, 3, spp, None), (259, 3, 1, 1), (262, 3, 1, 2),
               (273, 4, 1, None), (277, 3, 1, spp), (278, 3, 1, height), (279, 4, 1, len(data))]
    ifd_at = 8
    extra_at = ifd_at + 2 + 12 * len(entries) + 4
    bits_at, data_at = extra_at, extra_at + 2 * spp
    out = bytearray(b"II*\x00" + struct.pack("<I", ifd_at) + struct.pack("<H", len(entries)))
    for tag, kind, count, value in entries:
        value = bits_at if tag == 258 else data_at if tag == 273 else value
        packed = struct.pack("<HI", value, 0)[:4] if kind == 3 and count == 1 else struct.pack("<I", value)
        out += struct.pack("<HHI", tag, kind, count) + packed
    out += struct.pack("<I", 0) + struct.pack(f"<{spp}H", *([8] * spp)) + data
    return bytes(out)


@pytest.mark.parametrize("how", ["unspecified", "no tag", "unspecified, 0 everywhere", "unspecified, 16-bit"])
def test_an_unmarked_4th_sample_of_an_rgb_tiff_is_read_as_alpha_and_said(tmp_path, how):
    """0.57 dropped it without a word, its transparency untold: it is nearly always an alpha channel whose
    writer left it unmarked (GIMP, libtiff and ImageMagick read it as alpha); 0 everywhere, it is padding."""
    import warnings

    from tghop.imageio import load_image

    tifffile = pytest.importorskip("tifffile")
    rng = np.random.default_rng(1)
    deep = how.endswith("16-bit")
    samples = rng.integers(0, 65536 if deep else 256, (6, 5, 4)).astype(np.uint16 if deep else np.uint8)
    samples[..., 3] = 0 if "0 everywhere" in how else samples[..., 3] | 1
    path = tmp_path / "rgbx.tif"
    if how == "no tag":
        path.write_bytes(tiff_without_extrasamples(samples))
    else:
        tifffile.imwrite(path, samples, photometric="rgb", extrasamples=["unspecified"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        kept = load_image(path, keep_alpha=True, dtype=None)
    said = [str(w.message) for w in caught]
    tag = "no ExtraSamples tag" if how == "no tag" else "ExtraSamples unspecified"
    expected = samples / 65535.0 if deep else samples
    if "0 everywhere" in how:
        assert said == [f"rgbx.tif: its 4th sample, not marked as alpha ({tag}), is 0 everywhere: taken as padding "
                        "and dropped; tghop reads its RGB channels only"]
        np.testing.assert_array_equal(kept, samples[..., :3])
        return
    assert said == [f"rgbx.tif: its 4th sample, not marked as alpha ({tag}), is read as straight alpha, as GIMP and "
                    "libtiff read it; save the file with its alpha marked (or without it) to be sure"]
    np.testing.assert_array_equal(kept, expected)  # straight: colours as stored
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        colours = load_image(path, dtype=None)
    np.testing.assert_array_equal(colours, expected[..., :3])
    assert [str(w.message).split(",")[0] for w in caught][-1] == "rgbx.tif: alpha channel dropped"


def test_an_unspecified_4th_sample_pillow_drops_is_said_without_tifffile(tmp_path, monkeypatch):
    """Without tifffile, Pillow reads an RGB TIFF's "unspecified" 4th sample as RGBX padding: said (0.57: silent)."""
    import sys
    import warnings

    from tghop.imageio import load_image

    tifffile = pytest.importorskip("tifffile")
    samples = np.random.default_rng(2).integers(1, 256, (6, 5, 4)).astype(np.uint8)
    tifffile.imwrite(tmp_path / "rgbx.tif", samples, photometric="rgb", extrasamples=["unspecified"])
    monkeypatch.setitem(sys.modules, "tifffile", None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got = load_image(tmp_path / "rgbx.tif", dtype=None)
    np.testing.assert_array_equal(got, samples[..., :3])
    assert [str(w.message) for w in caught] == [
        "rgbx.tif: its 4th sample, not marked as alpha (ExtraSamples unspecified), dropped; tghop reads it as alpha "
        "with tifffile (pip install 'tghop[tiff]')"]


def test_an_upload_s_unicode_name_stays_readable_and_safe(live_server, small_model):
    """0.57 made every character outside ASCII "_" in messages and notes ("дом.png" was "___.png") and "-" or
    nothing in downloads' names. Letters and digits of any script stay; path separators, spaces, control and
    format characters (a right-to-left override) do not; a download names it in RFC 6266's ``filename*``."""
    import urllib.parse

    from conftest import FAST_FIT

    httpx = pytest.importorskip("httpx")
    rgba = np.full((96, 96, 4), 200, np.uint8)
    rgba[:40, :40, 3] = 0  # transparent: a note naming the file
    rgba[..., 0] = np.arange(96, dtype=np.uint8)[None, :] * 2
    buf = io.BytesIO()
    Image.fromarray(rgba).save(buf, format="PNG")
    evil = "C:\\x/../Дом\u202e \x07 e\u0301té_01.png"  # Windows and POSIX paths, RLO, BEL, NFD accent
    with httpx.Client(base_url=live_server.url, timeout=60) as client:
        r = client.post("/api/models", files={"image": ("дом.png", b"", "image/png")})
        assert (r.status_code, r.json()["error"]) == (400, "дом.png is empty; send an image file"), r.text
        form = {k: (None, v) for k, v in FAST_FIT.items()}
        r = client.post("/api/models", files={"image": (evil, buf.getvalue(), "image/png"), **form})
        assert r.status_code == 202, r.text
        client.delete(f"/api/jobs/{r.json()['job']}")
        notes = [n.split(" of its")[0] for n in r.json()["notes"]]  # httpx sends BEL as %07
        assert notes == ["Дом___07_été_01.png: 17%"], r.text
        r = client.post("/api/models/upload", files={"model": ("мой.npz", small_model.read_bytes())})
        assert r.status_code == 200, r.text
        model_id = r.json()["id"]
        for name, plain, utf8 in [("Дом 01", "tghop-01", "tghop-Дом-01"), ("crème brûlée", "tghop-creme-brulee", None),
                                  ("a\u202eb/../\x00c", "tghop-a-b-..-c", None), ("🙂", "tghop", None)]:
            got = client.get(f"/api/models/{model_id}/file", params={"name": name})
            header = got.headers["content-disposition"]
            expected = f'attachment; filename="{plain}-{model_id[:12]}.npz"'
            if utf8:
                expected += f"; filename*=UTF-8''{urllib.parse.quote(utf8, safe='')}-{model_id[:12]}.npz"
            elif name == "crème brûlée":
                expected += f"; filename*=UTF-8''tghop-cr%C3%A8me-br%C3%BBl%C3%A9e-{model_id[:12]}.npz"
            assert header == expected, header


def zip_of_empty_members(count: int, *, name: bytes = b"a.npy", zip64: bool = False) -> bytes:
    """A zip archive of ``count`` empty stored members (one name, one local header), made from bytes at once;
    with ``zip64`` its end record defers to ZIP64's (as one of 65,535 members or more must)."""
    local = struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 0, 0, 0, 0, 0, 0, len(name), 0) + name
    entry = struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, 0, 0, 0, 0, 0, 0, len(name), 0, 0, 0, 0, 0, 0)
    directory = (entry + name) * count
    if zip64:
        at = len(local) + len(directory)
        end = (struct.pack("<IQHHIIQQQQ", 0x06064B50, 44, 45, 45, 0, 0, count, count, len(directory), len(local))
               + struct.pack("<IIQI", 0x07064B50, 0, at, 1)
               + struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, 0xFFFF, 0xFFFF, 0xFFFFFFFF, 0xFFFFFFFF, 0))
    else:
        end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, count, count, len(directory), len(local), 0)
    return local + directory + end


@pytest.mark.parametrize("case", ["4,097 members", "ZIP64, 70,000 members", "a 5 MB directory of 90 members"])
@pytest.mark.parametrize("command", ["info", "synth", "fit", "cooc morph"])
def test_an_archive_of_too_many_members_is_refused_from_its_end_record(tmp_path, monkeypatch, case, command):
    """0.57 listed every member of such a file before refusing it (zipfile parses the whole directory: a million
    empty members, 51 MB, took 29-55 s and 470 MB on a loaded machine): refused now from the few bytes at its end."""
    import zipfile

    if command == "cooc morph":
        pytest.importorskip("torch")
    path = tmp_path / "many.npz"
    if case.startswith("a 5 MB"):  # few members of long names: the directory's size says it
        data = zip_of_empty_members(90, name=b"x" * 60_000)
        size = "5 MB"
    else:
        count = 4097 if case.startswith("4,097") else 70_000
        data = zip_of_empty_members(count, zip64=case.startswith("ZIP64"))
    path.write_bytes(data)

    def parsed(*args, **kwargs):
        raise AssertionError("the whole zip directory was parsed")

    monkeypatch.setattr(zipfile, "ZipFile", parsed)
    args = {"info": ["info", str(path)], "synth": ["synth", str(path), "-o", str(tmp_path / "o.png")],
            "fit": ["fit", str(path), "-o", str(tmp_path / "o.npz")],
            "cooc morph": ["cooc", "morph", str(path), "crop:0,0", "crop:1,1", "-o", str(tmp_path / "o.png")]}[command]
    result = CliRunner().invoke(main, args)
    what = (f"a zip archive whose directory takes {size} (a model file's or checkpoint's takes at most 4 MB)"
            if case.startswith("a 5 MB") else f"a zip archive of {count:,} members (a model file or checkpoint has "
            "at most 4,096)")
    if command == "fit":
        one_error_line(result, f"{path} is {what}, not an image; this command needs an image")
    elif command == "cooc morph":
        one_error_line(result, f"{path}: {what}, not a checkpoint tghop wrote; give a checkpoint 'tghop cooc train' "
                       "wrote, or train it again")
    else:
        one_error_line(result, f"{path}: {what}, not a model file tghop wrote; give a model file tghop wrote, or fit "
                       "the model again")
    assert not list(tmp_path.glob("o.*"))


@pytest.mark.parametrize("command", ["synth", "info"])
def test_an_intact_checkpoint_given_as_a_model_names_cooc_edit_and_morph_with_it(tiny_cooc_checkpoint, tmp_path,
                                                                                 command):
    """0.57 said "a co-occurrence cGAN checkpoint is read by tghop.cooc.load and the 'tghop cooc' commands":
    which command, and how, was left to find."""
    import shutil

    path = tmp_path / "my model.pt"
    shutil.copy(tiny_cooc_checkpoint, path)
    out = tmp_path / "o.png"
    args = ["synth", str(path), "-o", str(out)] if command == "synth" else ["info", str(path)]
    one_error_line(CliRunner().invoke(main, args),
                   f"{path}: a co-occurrence cGAN checkpoint, not a tghop model file; generate from it with 'tghop "
                   f"cooc edit '{path}' -o OUT.png' (a texture, as synth makes) or 'tghop cooc morph '{path}' A B -o "
                   "OUT.png' (a morph), in Python with tghop.cooc.load")
    assert not out.exists()


@pytest.mark.parametrize("chunk", [b"iCCP", b"zTXt", b"iCCP 16-bit"])
def test_a_png_whose_metadata_unpacks_too_far_says_so(tmp_path, chunk):
    """0.57 said "not a readable image (truncated or corrupt: ValueError: Decompressed data too large for
    PngImagePlugin.MAX_TEXT_CHUNK); give a PNG, JPEG or other common image file" of a PNG, and read a 16-bit one
    (tghop's own decoder) with its profile dropped without a word."""
    buf = io.BytesIO()
    deep = chunk.endswith(b"16-bit")
    chunk = chunk[:4]
    pixels = np.zeros((16, 16), np.uint16) if deep else np.zeros((16, 16, 3), np.uint8)
    Image.fromarray(pixels).save(buf, format="PNG")
    data = buf.getvalue()
    bomb = png_chunk(chunk, b"name\x00\x00" + zlib.compress(b"\x00" * 3_000_000, 9))
    path, out = tmp_path / "meta.png", tmp_path / "o.npz"
    path.write_bytes(data[:33] + bomb + data[33:])  # after IHDR
    one_error_line(CliRunner().invoke(main, ["fit", str(path), "-o", str(out)]),
                   f"{path}: its metadata (a colour profile, iCCP, or text, zTXt/iTXt) unpacks to more than Pillow "
                   "reads (a decompression bomb, or an outsized profile); save the image again without its metadata")
    assert not out.exists()


def test_a_huge_field_value_is_not_sent_back_whole(live_server):
    """0.57 answered a 900 KB 'builtin' field or a JSON seed of 500,000 digits with an error quoting it whole."""
    httpx = pytest.importorskip("httpx")
    big = "9" * 500_000
    with httpx.Client(base_url=live_server.url, timeout=60) as client:
        r = client.post("/api/models", files={"builtin": (None, "x" * 900_000)})
        assert (r.status_code, r.json()["error"]) == (400, f"unknown built-in exemplar '{'x' * 56}...; choose one of "
                                                           "bricks, cells"), r.text[:300]
        for key in ("seed", "refine"):
            r = client.post(f"/api/models/{'0' * 64}/images", json={"size": [16, 16], key: big})
            assert r.status_code == 422 and len(r.text) < 300, r.text[:300]
            assert r.json()["error"].endswith(f", got '{'9' * 57}'..."), r.text[:300]


def test_a_jpeg_with_damaged_exif_data_is_said_in_tghop_s_words(tmp_path):
    """0.57 passed Pillow's "Warning: Corrupt EXIF data.  Expecting to read 12 bytes but only got 4." on, naming
    no file and not saying that the orientation was then not applied."""
    im = Image.fromarray((np.random.default_rng(0).random((40, 56, 3)) * 255).astype(np.uint8))
    exif = im.getexif()
    exif[0x0112] = 6
    buf = io.BytesIO()
    im.save(buf, format="JPEG", exif=exif)
    data = bytearray(buf.getvalue())
    at = data.find(b"Exif")
    data[at + 14:at + 30] = np.random.default_rng(3).bytes(16)  # inside the EXIF block (APP1), the rest intact
    path = tmp_path / "damaged.jpg"
    path.write_bytes(bytes(data))
    result = CliRunner().invoke(main, ["fit", str(path), "-o", str(tmp_path / "o.npz"), "-q"])
    assert "Corrupt EXIF" not in result.output, result.output
    assert ("Warning: damaged.jpg: its EXIF data is damaged (Expecting to read 12 bytes but only got 4); its "
            "orientation is not read: the pixels are taken as stored") in result.output, result.output


def test_a_12_bit_jpeg_is_named_as_one(tmp_path):
    """0.57: "a JPEG file, but its header is corrupt or of a kind tghop does not read" of a 12-bit JPEG (a
    medical or scientific camera's), which Pillow does not read."""
    buf = io.BytesIO()
    Image.fromarray(np.zeros((16, 16, 3), np.uint8)).save(buf, format="JPEG")
    data = bytearray(buf.getvalue())
    frame = data.find(b"\xff\xc0")
    data[frame + 1], data[frame + 4] = 0xC1, 12  # extended sequential, 12-bit samples (the header of one)
    path, out = tmp_path / "deep.jpg", tmp_path / "o.npz"
    path.write_bytes(bytes(data))
    one_error_line(CliRunner().invoke(main, ["fit", str(path), "-o", str(out)]),
                   f"{path}: not a readable image (a 12-bit JPEG, which Pillow does not read, only 8-bit ones: convert "
                   "it to a 16-bit PNG or TIFF)")
    assert not out.exists()


def test_a_size_refused_or_downscaled_is_said_height_first(tmp_path):
    """Sizes are HEIGHTxWIDTH everywhere, as --size takes them: 0.60 said an image over the pixel limit, one
    downscaled to it and one too thin to hold a texture width first ("the image is 9000x8000" of one 8000
    high and 9000 wide)."""
    import warnings

    from tghop.imageio import load_image

    wide = tmp_path / "wide.png"
    wide.write_bytes(png_declaring(9000, 8000))  # 72 Mpx, over the 64 Mpx tghop reads
    result = CliRunner().invoke(main, ["fit", str(wide), "-o", str(tmp_path / "m.npz"), "-q"])
    one_error_line(result, "wide.png: the image is 8000x9000 pixels, more than the 67,108,864 tghop reads")
    photo = tmp_path / "photo.png"
    Image.fromarray(np.zeros((40, 90, 3), np.uint8)).save(photo)  # 40 high, 90 wide
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        image = load_image(photo, max_pixels=900, downscale=True)
    assert image.shape[:2] == (20, 45)
    assert "photo.png: 40x90 pixels downscaled to 20x45" in str(caught[0].message)
    line = tmp_path / "line.png"
    Image.fromarray(np.full((1, 30, 3), 128, np.uint8)).save(line)  # 1 high, 30 wide, one grey
    result = CliRunner().invoke(main, ["fit", str(line), "-o", str(tmp_path / "m.npz"), "-q"])
    one_error_line(result, "the exemplar is 1x30 pixels, too small to hold a texture")
