"""16-bit and float images (issue #27, item 6): read without loss, written with a depth."""

import struct
import zlib

import numpy as np
import pytest

from tghop import InvalidImageError
from tghop.imageio import check_depth, load_image, save_image


def _levels(shape, seed=0):
    return np.random.default_rng(seed).integers(0, 65536, shape).astype(np.uint16)


@pytest.mark.parametrize("shape", [(17, 23, 3), (17, 23)])
def test_16bit_png_round_trip_is_exact(tmp_path, shape):
    levels = _levels(shape)
    save_image(levels / 65535.0, tmp_path / "a.png", depth=16)
    image, depth = load_image(tmp_path / "a.png", with_depth=True)
    assert depth == 16 and image.dtype == np.float64
    assert np.array_equal(np.round(image * 65535).astype(np.uint16).reshape(shape), levels)
    save_image(image, tmp_path / "b.png", depth=16)  # written again: the same file
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()


def _png16_filtered(levels):
    """A 16-bit PNG whose rows use every filter type (0-4 in turn), encoded byte by byte
    as the PNG specification says (another writer's file, not tghop's)."""
    h, w, c = levels.shape
    data = levels.astype(">u2").view(np.uint8).reshape(h, w * c * 2).astype(int)
    bpp, out, prev = 2 * c, b"", [0] * (w * c * 2)
    for y in range(h):
        kind, row, enc = y % 5, data[y].tolist(), []
        for i, x in enumerate(row):
            a = row[i - bpp] if i >= bpp else 0
            b, cc = prev[i], (prev[i - bpp] if i >= bpp else 0)
            p = a + b - cc
            pa, pb, pc = abs(p - a), abs(p - b), abs(p - cc)
            paeth = a if pa <= pb and pa <= pc else b if pb <= pc else cc
            enc.append((x - [0, a, b, (a + b) // 2, paeth][kind]) % 256)
        out += bytes([kind] + enc)
        prev = row

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 2 if c == 3 else 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(out)) + chunk(b"IEND", b""))


def test_16bit_png_of_every_filter_type_is_read_exactly(tmp_path):
    levels = _levels((11, 9, 3), seed=1)
    (tmp_path / "f.png").write_bytes(_png16_filtered(levels))
    image = load_image(tmp_path / "f.png")
    assert np.array_equal(np.round(image * 65535).astype(np.uint16), levels)


def test_16bit_and_float_tiff_round_trips(tmp_path):
    pytest.importorskip("tifffile")
    levels = _levels((13, 10, 3), seed=2)
    save_image(levels / 65535.0, tmp_path / "a.tif", depth=16)
    image, depth = load_image(tmp_path / "a.tif", with_depth=True)
    assert depth == 16 and np.array_equal(np.round(image * 65535).astype(np.uint16), levels)
    values = np.random.default_rng(3).random((13, 10, 3))
    save_image(values, tmp_path / "f.tif", depth=32)
    image, depth = load_image(tmp_path / "f.tif", with_depth=True)
    assert depth == 32 and image.dtype == np.float64
    np.testing.assert_array_equal(image, values.astype(np.float32))  # float32 in the file, nothing else lost


def test_a_float_depth_and_a_path_of_the_wrong_kind_are_one_line():
    from tghop import TGHopError
    from tghop.imageio import output_format

    with pytest.raises(InvalidImageError, match=r"^depth 8.0 is not 8, 16 or 32 bits per channel; write 8"):
        check_depth("a.png", 8.0)
    with pytest.raises(InvalidImageError, match="depth '8' is not 8, 16 or 32"):
        check_depth("a.png", "8")
    assert check_depth("a.png", np.int64(16)) == 16
    for call in (lambda: output_format(None), lambda: check_depth(None, 8)):
        with pytest.raises(TGHopError, match=r"^the output path must be a str or os.PathLike, got NoneType$"):
            call()


@pytest.mark.parametrize("name, depth", [("a.png", 32), ("a.jpg", 16), ("a.jpg", 32), ("a.png", 12)])
def test_depth_a_format_cannot_hold_is_one_line(name, depth):
    with pytest.raises(InvalidImageError) as err:
        check_depth(name, depth)
    assert "\n" not in str(err.value)
    with pytest.raises(InvalidImageError):
        save_image(np.zeros((4, 4, 3)), name, depth=depth)


def test_cli_synth_depth(tmp_path):
    from click.testing import CliRunner

    from tghop.cli import main

    runner = CliRunner()
    out = tmp_path / "t.png"
    res = runner.invoke(main, ["synth", "builtin:bricks", "-o", str(out), "--size", "64", "--seed", "1",
                               "--depth", "16", "-q", "--max-patches", "1500", "--clusters", "10"])
    assert res.exit_code == 0, res.output
    image, depth = load_image(out, with_depth=True)
    assert depth == 16 and image.shape == (64, 64, 3)
    assert len(np.unique(image)) > 256  # more levels than 8 bits hold
    bad = runner.invoke(main, ["synth", "builtin:bricks", "-o", str(tmp_path / "u.jpg"), "--depth", "16", "-q"])
    assert bad.exit_code != 0 and "Traceback" not in bad.output and not (tmp_path / "u.jpg").exists()
    assert bad.output.strip().count("\n") == 0 and "JPEG" in bad.output


def test_colour_tiff_without_tifffile_is_refused_before_the_work(tmp_path, monkeypatch):
    # A core-only install (no tiff extra): synth -o x.tif --depth 16 fitted and generated the whole image,
    # then said that tifffile was missing. Now every command says so before the fit, in one line.
    from click.testing import CliRunner

    from tghop import MissingExtraError
    from tghop.cli import main
    from tghop.synthesis import TGHop

    monkeypatch.setitem(__import__("sys").modules, "tifffile", None)  # as if not installed

    def reached(*args, **kwargs):
        raise AssertionError("the work started before the missing tifffile was told")

    monkeypatch.setattr(TGHop, "fit", reached)
    assert check_depth(tmp_path / "g.tif", 16, channels=1) == 16  # grey: Pillow writes it
    assert check_depth(tmp_path / "c.tif", 8, channels=3) == 8
    with pytest.raises(MissingExtraError, match=r"tghop\[tiff\]"):
        check_depth(tmp_path / "c.tif", 32, channels=3)
    picture = tmp_path / "p.png"
    save_image(np.random.default_rng(0).random((64, 64, 3)), picture)
    hole = tmp_path / "h.png"
    save_image(np.pad(np.ones((8, 8)), 28), hole)
    runner = CliRunner()
    out = str(tmp_path / "o.tif")
    for command in (["synth", "builtin:bricks", "--size", "64"], ["synth", "builtin:bricks", "builtin:cells"],
                    ["morph", "builtin:bricks", "builtin:cells", "--size", "64x128"],
                    ["inpaint", str(picture), str(hole)], ["extend", str(picture), "--size", "64x96"]):
        res = runner.invoke(main, [*command, "-o", out, "--depth", "16", "-q"])
        assert res.exit_code == 1 and "Traceback" not in res.output, (command, res.output)
        assert res.output.strip().count("\n") == 0 and "pip install 'tghop[tiff]'" in res.output, command
        assert not (tmp_path / "o.tif").exists()


def test_cli_synth_warns_that_a_16bit_exemplar_is_written_8bit(tmp_path):
    # synth writes 8 bits unless --depth (as documented): a height map artist's 16-bit exemplar lost its
    # depth without a word, where inpaint and extend keep it.
    from click.testing import CliRunner

    from tghop import data
    from tghop.cli import main

    save_image(data.bricks()[:96, :96], tmp_path / "deep.png", depth=16)
    fast = ["--size", "48", "--seed", "1", "-q", "--max-patches", "1000", "--clusters", "10", "--layout", "none"]
    runner = CliRunner()
    res = runner.invoke(main, ["synth", str(tmp_path / "deep.png"), "-o", str(tmp_path / "o.png"), *fast])
    assert res.exit_code == 0 and "has more than 8 bits a channel" in res.output and "--depth 16" in res.output
    assert load_image(tmp_path / "o.png", with_depth=True)[1] == 8
    res = runner.invoke(main, ["synth", str(tmp_path / "deep.png"), "-o", str(tmp_path / "d.png"), "--depth", "16",
                               *fast])
    assert res.exit_code == 0 and "Warning" not in res.output
    res = runner.invoke(main, ["synth", "builtin:bricks", "-o", str(tmp_path / "b.png"), *fast])
    assert res.exit_code == 0 and "Warning" not in res.output  # the built-ins are 8-bit


def test_cli_synth_of_several_sources_warns_once_naming_the_deep_ones(tmp_path):
    # A remix or a painted --guide of 16-bit (or float) exemplars wrote 8 bits without the warning one
    # deep exemplar gets: one warning naming each deep SOURCE, none with --depth.
    from click.testing import CliRunner

    from tghop import data
    from tghop.cli import main

    save_image(data.bricks()[:64, :64], tmp_path / "a.png", depth=16)
    save_image(data.cells(64, rng=0), tmp_path / "b.png")
    save_image(data.cells(64, rng=1), tmp_path / "c.tif", depth=32)
    fast = ["--size", "48", "--seed", "1", "-q", "--max-patches", "1000", "--clusters", "10", "--pool", "400",
            "--refine", "1"]
    sources = [str(tmp_path / n) for n in ("a.png", "b.png", "c.tif")]
    runner = CliRunner()
    res = runner.invoke(main, ["synth", *sources, "-o", str(tmp_path / "o.png"), *fast])
    assert res.exit_code == 0, res.output
    assert [line for line in res.output.splitlines() if line.startswith("Warning")] == [
        f"Warning: SOURCE 1 ({sources[0]}) and SOURCE 3 ({sources[2]}) have more than 8 bits a channel, but the "
        "image is written with 8; pass --depth 16 to keep them"]
    assert load_image(tmp_path / "o.png", with_depth=True)[1] == 8
    res = runner.invoke(main, ["synth", *sources[:2], "-o", str(tmp_path / "o.jpg"), *fast])
    assert res.exit_code == 0, res.output
    assert [line for line in res.output.splitlines() if line.startswith("Warning")] == [
        f"Warning: SOURCE 1 ({sources[0]}) has more than 8 bits a channel, but the image is written with 8; "
        "name the output .png, .tif or .tiff and pass --depth 16 to keep them"]
    res = runner.invoke(main, ["synth", *sources, "-o", str(tmp_path / "d.png"), "--depth", "16", *fast])
    assert res.exit_code == 0 and "Warning" not in res.output, res.output
    res = runner.invoke(main, ["synth", "builtin:bricks", sources[1], "-o", str(tmp_path / "e.png"), *fast])
    assert res.exit_code == 0 and "Warning" not in res.output, res.output  # 8-bit and built-in sources
    # A morph of them likewise names its A and B.
    res = runner.invoke(main, ["morph", sources[1], sources[0], "-o", str(tmp_path / "m.png"), "--size", "48x96",
                               "--seed", "1", "-q"])
    assert res.exit_code == 0, res.output
    assert [line for line in res.output.splitlines() if line.startswith("Warning")] == [
        f"Warning: B ({sources[0]}) has more than 8 bits a channel, but the image is written with 8; "
        "pass --depth 16 to keep them"]


def test_a_model_of_a_16bit_exemplar_warns_as_the_exemplar_does(tmp_path):
    # tghop synth EXEMPLAR16.png warned that the image is written with 8 bits; tghop fit EXEMPLAR16.png, then
    # tghop synth MODEL.npz wrote 8 bits without a word. The model file's metadata records the exemplar's depth
    # (no array: the format version stays); files without it (tghop 0.55 and older) stay silent.
    import json

    from click.testing import CliRunner

    from tghop import TGHop, data
    from tghop.cli import main
    from tghop.modelfile import ModelFileError, load_model, save_model

    save_image(data.bricks(72, rng=2), tmp_path / "deep.png", depth=16)
    save_image(data.bricks(72, rng=2), tmp_path / "flat.png")
    fast = ["--clusters", "6", "--codewords", "30", "--stride", "4", "--layout", "none", "-q"]
    runner = CliRunner()

    def run(*args):
        res = runner.invoke(main, [str(a) for a in args])
        assert res.exit_code == 0, res.output
        return [line for line in res.output.splitlines() if line.startswith("Warning")]

    def meta(path):
        return json.loads(str(np.load(path)["__meta__"]))

    deep, flat = tmp_path / "deep.npz", tmp_path / "flat.npz"
    assert run("fit", tmp_path / "deep.png", "-o", deep, *fast) == []
    assert run("fit", tmp_path / "flat.png", "-o", flat, *fast) == []
    assert meta(deep)["exemplar_depth"] == 16 and meta(flat)["exemplar_depth"] == 8
    assert load_model(deep).exemplar_depth_ == 16
    said = ("has more than 8 bits a channel, but the image is written with 8; pass --depth 16 to keep them")
    assert run("synth", deep, "-o", tmp_path / "o.png", "--size", "48") == [
        f"Warning: the exemplar of SOURCE {deep} {said}"]
    assert load_image(tmp_path / "o.png", with_depth=True)[1] == 8
    assert run("synth", deep, "-o", tmp_path / "o.jpg", "--size", "48") == [
        f"Warning: the exemplar of SOURCE {deep} has more than 8 bits a channel, but the image is written with 8; "
        "name the output .png, .tif or .tiff and pass --depth 16 to keep them"]
    assert run("synth", deep, "-o", tmp_path / "d.png", "--size", "48", "--depth", "16") == []
    assert run("synth", flat, "-o", tmp_path / "f.png", "--size", "48") == []
    # Several sources and a morph name the model's exemplar, as they name a deep exemplar.
    assert run("synth", deep, flat, "-o", tmp_path / "r.png", "--size", "48") == [
        f"Warning: the exemplar of SOURCE 1 ({deep}) {said}"]
    assert run("morph", flat, deep, "-o", tmp_path / "m.png", "--size", "48x96", "--seed", "1", "-q") == [
        f"Warning: the exemplar of B ({deep}) {said}"]
    # synth --save-model records it too; the info says it.
    assert run("synth", tmp_path / "deep.png", "-o", tmp_path / "s.png", "--size", "48", "--depth", "16",
               "--save-model", tmp_path / "s.npz", *fast) == []
    assert meta(tmp_path / "s.npz")["exemplar_depth"] == 16
    assert "3 channels, 16-bit;" in runner.invoke(main, ["info", str(deep)]).output
    assert json.loads(runner.invoke(main, ["info", "--json", str(flat)]).output)["exemplar_depth"] == 8
    # The depth changes nothing learned: the arrays of a float fit of the same pixels (depth not known).
    arrays = np.load(deep)
    refit = TGHop(**load_model(deep).get_params()).fit(load_image(tmp_path / "deep.png"))
    assert refit.exemplar_depth_ is None and "exemplar_depth" not in refit._state_meta()
    save_model(refit, tmp_path / "float.npz")
    other = np.load(tmp_path / "float.npz")
    assert sorted(other.files) == sorted(arrays.files)
    assert meta(deep)["format_version"] == meta(tmp_path / "float.npz")["format_version"]
    assert all(np.array_equal(arrays[k], other[k]) for k in arrays.files if k != "__meta__")
    # A file without it (tghop 0.55) loads and stays silent; an edited one is one line.
    old = meta(deep)
    del old["exemplar_depth"]
    np.savez(tmp_path / "old.npz", **{**{k: arrays[k] for k in arrays.files}, "__meta__": np.array(json.dumps(old))})
    assert load_model(tmp_path / "old.npz").exemplar_depth_ is None
    assert run("synth", tmp_path / "old.npz", "-o", tmp_path / "p.png", "--size", "48") == []
    for bad in (12, "16", True, 16.0):
        old["exemplar_depth"] = bad
        np.savez(tmp_path / "bad.npz", **{**{k: arrays[k] for k in arrays.files},
                                          "__meta__": np.array(json.dumps(old))})
        with pytest.raises(ModelFileError,
                           match=r"fit the model again.*the metadata's exemplar_depth must be 8, 16 or 32 "):
            load_model(tmp_path / "bad.npz")


def test_fit_records_the_depth_it_is_told_or_its_dtypes():
    from tghop import TGHop, TGHopError, data

    image = data.bricks(64, rng=1)
    fast = dict(rng=0, max_patches=600, n_clusters=4, layout_factor=None, patch_levels=0)
    assert TGHop(**fast).fit(image).exemplar_depth_ is None  # floats: any file's levels
    assert TGHop(**fast).fit(np.round(image * 65535).astype(np.uint16)).exemplar_depth_ == 16
    assert TGHop(**fast).fit(np.round(image * 255).astype(np.uint8)).exemplar_depth_ == 8
    assert TGHop(**fast).fit(image, depth=32).exemplar_depth_ == 32
    for bad in (12, True, 16.0, "16"):
        with pytest.raises(TGHopError, match=r"^depth must be 8, 16 or 32 \(bits per channel of the exemplar's"):
            TGHop(**fast).fit(image, depth=bad)


@pytest.fixture(scope="module")
def bricks_model(tmp_path_factory):
    """(96x96 bricks, the path of a small model fitted on them), saved once for the CLI tests that read it."""
    from tghop import TGHop, data
    from tghop.modelfile import save_model

    exemplar = data.bricks()[:96, :96]
    path = tmp_path_factory.mktemp("depth") / "m.npz"
    save_model(TGHop(max_patches=1000, n_clusters=10, layout_factor=None, rng=0).fit(exemplar), path)
    return exemplar, path


def test_cli_inpaint_keeps_a_16bit_image_16bit(tmp_path, bricks_model):
    from click.testing import CliRunner

    from tghop.cli import main

    exemplar, model = bricks_model
    levels = np.round(exemplar * 65535).astype(np.uint16) ^ np.uint16(5)  # low bits an 8-bit file cannot hold
    save_image(levels / 65535.0, tmp_path / "in.png", depth=16)
    hole = np.zeros((96, 96))
    hole[30:60, 30:60] = 1
    save_image(hole, tmp_path / "hole.png")
    res = CliRunner().invoke(main, ["inpaint", str(tmp_path / "in.png"), str(tmp_path / "hole.png"),
                                    "-o", str(tmp_path / "out.png"), "--source", str(model),
                                    "--seed", "1", "-q"])
    assert res.exit_code == 0, res.output
    image, depth = load_image(tmp_path / "out.png", with_depth=True)
    out = np.round(image * 65535).astype(np.uint16)
    keep = hole == 0
    assert depth == 16 and np.array_equal(out[keep], levels[keep])  # every known pixel, all 16 bits


def test_cli_inpaint_and_extend_warn_that_a_16bit_image_is_written_8bit_as_jpeg(tmp_path, bricks_model):
    # They keep IMAGE's depth as far as the output's format holds it: a JPEG output lost it without a word.
    from click.testing import CliRunner

    from tghop.cli import main

    exemplar, model = bricks_model
    save_image(exemplar, tmp_path / "in.png", depth=16)
    hole = np.zeros((96, 96))
    hole[30:60, 30:60] = 1
    save_image(hole, tmp_path / "hole.png")
    warning = (f"Warning: IMAGE {tmp_path / 'in.png'} (16-bit) has more bits a channel than JPEG holds, but is "
               "written with 8; name the output .png, .tif or .tiff to keep them")
    for command in (["inpaint", str(tmp_path / "in.png"), str(tmp_path / "hole.png")],
                    ["extend", str(tmp_path / "in.png"), "--size", "96x128"]):
        for name, warned in (("o.jpg", [warning]), ("o.png", []), ("d.jpg", [])):
            depth = ["--depth", "8"] if name == "d.jpg" else []  # asked for: no warning
            res = CliRunner().invoke(main, [*command, "-o", str(tmp_path / name), "--source", str(model),
                                            "--seed", "1", "-q", *depth])
            assert res.exit_code == 0, res.output
            assert [line for line in res.output.splitlines() if line.startswith("Warning")] == warned, command


def test_colour_tiff_without_tifffile_is_one_line(tmp_path, monkeypatch):
    pytest.importorskip("tifffile")
    from tghop import MissingExtraError

    save_image(_levels((9, 8, 3)) / 65535.0, tmp_path / "c.tif", depth=16)
    monkeypatch.setitem(__import__("sys").modules, "tifffile", None)  # as if not installed
    with pytest.raises(MissingExtraError, match=r"tghop\[tiff\]"):
        load_image(tmp_path / "c.tif")
    with pytest.raises(MissingExtraError, match=r"tghop\[tiff\]"):
        save_image(np.zeros((4, 4, 3)), tmp_path / "d.tif", depth=16)
    assert not (tmp_path / "d.tif").exists()
    grey = np.random.default_rng(0).random((6, 7))
    save_image(grey, tmp_path / "g.tif", depth=32)  # grey float TIFF: Pillow suffices
    np.testing.assert_allclose(load_image(tmp_path / "g.tif")[..., 0], grey, atol=1e-7)
    save_image(grey, tmp_path / "g16.tif", depth=16)
    assert np.array_equal(np.round(load_image(tmp_path / "g16.tif")[..., 0] * 65535), np.round(grey * 65535))
