"""Growing an image (tghop.inpaint.extend, ``tghop extend``): outpainting, on textures made in code."""


import numpy as np
import pytest
from PIL import Image

from tghop import TGHopError, data
from tghop.imageio import save_image
from tghop.inpaint import ANCHORS, expand_canvas, extend
from tghop.modelfile import save_model
from tghop.synthesis import TGHop

from conftest import assert_user_error, cli
from test_inpaint import FAST, POOL, cells  # noqa: F401 (cells: the fixture of a 96x96 uint8 texture)


@pytest.fixture(scope="module")
def model(cells):
    return TGHop(rng=0, **FAST).fit(cells)


@pytest.mark.parametrize("anchor, offset", [
    ("center", (7, 20)), ("top", (0, 20)), ("bottom", (15, 20)), ("left", (7, 0)), ("right", (7, 41)),
    ("top-left", (0, 0)), ("top-right", (0, 41)), ("bottom-left", (15, 0)), ("bottom-right", (15, 41))])
def test_the_canvas_holds_the_image_at_its_anchor_and_the_hole_is_the_rest(anchor, offset):
    image = np.arange(6 * 9 * 2, dtype=np.uint16).reshape(6, 9, 2) + 1
    canvas, hole, at = expand_canvas(image, (21, 50), anchor=anchor)
    y, x = offset
    assert at == offset and canvas.dtype == np.uint16 and canvas.shape == (21, 50, 2) and hole.shape == (21, 50)
    assert np.array_equal(canvas[y:y + 6, x:x + 9], image)
    assert not hole[y:y + 6, x:x + 9].any() and hole.sum() == 21 * 50 - 6 * 9
    assert (canvas[hole] == 0).all()
    grey, _, _ = expand_canvas(image[..., 0], (6, 10), anchor=anchor)  # (H, W) stays (H, W)
    assert grey.shape == (6, 10)


def test_extend_keeps_the_image_bit_for_bit_and_fills_the_rest_with_its_texture(model, cells):
    out = extend(model, cells, (120, 200), anchor="left", rng=1, **POOL)
    assert out.shape == (120, 200, 3) and out.dtype == np.uint8
    assert np.array_equal(out[12:108, :96], cells)
    new = np.ones((120, 200), bool)
    new[12:108, :96] = False
    filled, own = out[new] / 255.0, cells.reshape(-1, 3) / 255.0
    assert np.all(np.abs(filled.mean(axis=0) - own.mean(axis=0)) < 0.08)
    assert np.all(filled.std(axis=0) > 0.5 * own.std(axis=0))  # texture, not a flat colour
    far = out[:, 160:] / 255.0  # 64 px from the image: texture there too
    assert np.all(far.reshape(-1, 3).std(axis=0) > 0.5 * own.std(axis=0))
    floats = data.cells(96, rng=3)
    out = extend(model, floats, 128, rng=1, **POOL)  # float: the same values, float64
    assert out.dtype == np.float64 and np.array_equal(out[16:112, 16:112], floats)



def test_extend_of_a_canvas_thinner_than_a_patch_names_extending_the_image(model, cells):
    # extend(model, 8x50 image, (8, 400)) said "the image is 8x400; inpainting with 32x32 patches ...": the
    # canvas, and inpainting, where the caller extended an 8x50 image (`tghop extend` named it already).
    for size, least in (((8, 400), "32x400"), ((20, 60), "32x60")):
        with pytest.raises(TGHopError) as err:
            extend(model, cells[:8, :50], size, rng=0)
        message = str(err.value)
        assert f"the image (8x50) extended to {size[0]}x{size[1]} is thinner than the 32x32 patches" in message
        assert f"give a size of at least {least}" in message and "smaller patch_size" in message
        assert "inpainting" not in message
    out = extend(model, cells[:8, :50], (40, 100), anchor="top-left", rng=0, **POOL)  # a canvas a patch fits
    assert out.shape == (40, 100, 3) and np.array_equal(out[:8, :50], cells[:8, :50])

def test_extend_fills_row_by_row_and_inpaint_from_the_edge_inwards(model, cells):
    # Row by row measured better around a picture, from the edge inwards better for holes
    # (docs/choices.md, Inpainting "0.46"); either can be asked for.
    from tghop.inpaint import inpaint

    canvas, hole, _ = expand_canvas(cells, (96, 160), anchor="left")
    grown = extend(model, cells, (96, 160), anchor="left", rng=3, **POOL)
    assert np.array_equal(grown, inpaint(model, canvas, hole, rng=3, order="raster", **POOL))
    edge = extend(model, cells, (96, 160), anchor="left", rng=3, order="edge", **POOL)
    assert np.array_equal(edge, inpaint(model, canvas, hole, rng=3, **POOL)) and not np.array_equal(edge, grown)
    with pytest.raises(TGHopError, match="order must be 'edge' or 'raster', got 'spiral'"):
        inpaint(model, canvas, hole, order="spiral", **POOL)
    # An unknown keyword was Python's TypeError, naming inpaint
    with pytest.raises(TGHopError, match=r"^extend: unknown keyword 'orde'; the keywords are n_patches, "):
        extend(model, cells, (96, 160), orde="raster")


def test_the_same_seed_gives_the_same_image(model, cells):
    a, b, c = (extend(model, cells, (96, 160), rng=seed, **POOL) for seed in (4, 4, 5))
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def _patch_distance(model, img, hole):
    """Mean distance of the quantiles of the full-resolution 5x5 patches wholly inside ``hole``,
    projected on each of the model's stored direction sets, to the stored quantiles."""
    stats = model.patches_
    x = (np.asarray(img, np.float32) / 255).transpose(2, 0, 1)  # channel-first, as the directions
    c, p = x.shape[0], int(round(np.sqrt(stats.directions_[0].shape[-1] / x.shape[0])))
    windows = np.lib.stride_tricks.sliding_window_view(x, (p, p), axis=(1, 2))  # (C, h, w, p, p)
    inside = np.lib.stride_tricks.sliding_window_view(hole, (p, p)).all(axis=(2, 3))
    cols = windows[:, inside].transpose(0, 2, 3, 1).reshape(c * p * p, -1)
    return np.mean([np.abs(np.quantile(dirs @ cols, stats.levels_, axis=1).T - target).mean()
                    for dirs, target in zip(stats.directions_[0], stats.quantiles_[0])])


def test_the_patch_refinement_moves_the_new_areas_patches_towards_the_models(model, cells):
    # A 64x64 image grown to 160x160: the new area is most of the canvas the patch refinement
    # sees. Measured (seeds 1-4): 0.64-0.69 of the distance without it.
    canvas, hole, _ = expand_canvas(cells[16:80, 16:80], 160)
    plain = extend(model, cells[16:80, 16:80], 160, rng=1, patch_refine=0, **POOL)
    refined = extend(model, cells[16:80, 16:80], 160, rng=1, **POOL)
    assert np.array_equal(refined[~hole], canvas[~hole]) and not np.array_equal(refined, plain)
    assert _patch_distance(model, refined, hole) < 0.8 * _patch_distance(model, plain, hole)


def test_the_coarse_fill_keeps_structures_larger_than_a_patch():
    # Stripes 48 px wide, wider than the 32 px patches: the fill alone cannot tell where one
    # ends (runs of 19-36 px to the right of the picture); the coarse model sees two of them in
    # a patch, and its fill of the hole at 1/3 scale guides the fine one (46-51 px). Measured
    # with seeds 0-3: medians of the runs 33 / 34 / 33 / 38 without, 46 / 50 / 45 / 49 with.
    rng = np.random.default_rng(0)
    colours = np.where(((np.arange(288) // 48) % 2 == 1)[:, None], [0.8, 0.3, 0.2], [0.2, 0.4, 0.7])
    image = np.clip(colours[None].repeat(192, axis=0) + rng.normal(0, 0.05, (192, 288, 3)), 0, 1)
    model = TGHop(rng=0, n_clusters=10, n_codewords=40, max_patches=2000).fit(image)
    assert model.layout_ is not None

    def runs(out):  # widths of the stripes in the new area's middle rows, flickers of a few pixels left out
        red = out[76:116, 288:, 0].mean(axis=0) > 0.5
        widths = np.diff(np.flatnonzero(np.diff(red.astype(int)) != 0))
        return float(np.median(widths[widths >= 8]))

    plain = extend(model, image, (192, 576), anchor="left", rng=1, layout_weight=0)
    guided = extend(model, image, (192, 576), anchor="left", rng=1)
    assert np.array_equal(guided[:, :288], image)
    assert abs(runs(guided) - 48) < 6 and abs(runs(plain) - 48) > abs(runs(guided) - 48) + 4


def _edge_step(img, axis):
    """Mean absolute step across the image's wrapped edge along ``axis`` over the mean step between
    neighbouring rows (or columns) inside it."""
    img = np.asarray(img, dtype=np.float64)
    inner = np.abs(np.diff(img, axis=axis)).mean()
    first, last = np.take(img, 0, axis=axis), np.take(img, -1, axis=axis)
    return np.abs(first - last).mean() / inner


def test_tile_makes_a_result_that_wraps_around(model, cells):
    # The image at the bottom-left: without tile, its bottom row meets the canvas's top row at
    # the wrap only by chance; with tile, the fill continues it across the edge.
    # (The whole pool: with the small one the last blocks often find no patch that fits both
    # sides. Measured: plain 2.9 and 3.4, tiled 1.6 and 1.6; the image itself 0.7 and 0.6.)
    plain = extend(model, cells, (160, 160), anchor="bottom-left", rng=2, refine=2)
    tiled = extend(model, cells, (160, 160), anchor="bottom-left", rng=2, tile=True, refine=2)
    assert np.array_equal(tiled[64:, :96], cells)
    steps = [_edge_step(tiled, 0), _edge_step(tiled, 1)]
    assert max(steps) < 2.0 and sum(steps) < 0.75 * (_edge_step(plain, 0) + _edge_step(plain, 1))


@pytest.mark.parametrize("size, anchor, words", [
    ((80, 200), "center", "the size 80x200 is smaller than the image (96x96) in height; give a size at least 96x96"),
    ((96, 90), "center", "smaller than the image (96x96) in width"),
    ((96, 96), "center", "the size 96x96 is the image's own, so there is nothing to extend"),
    ((128, 128), "middle", "anchor must be one of center, top, bottom"),
    ((0, 128), "center", "size"),
])
def test_bad_sizes_and_anchors_are_refused(model, cells, size, anchor, words):
    with pytest.raises(TGHopError, match=words.replace("(", r"\(").replace(")", r"\)")):
        extend(model, cells, size, anchor=anchor, **POOL)


def test_the_command_lines_anchors_are_the_librarys():
    from tghop.cli.inpaint import ANCHOR_CHOICES

    assert ANCHOR_CHOICES == ANCHORS


@pytest.fixture(scope="module")
def files(tmp_path_factory, cells, model):
    d = tmp_path_factory.mktemp("extend")
    save_image(cells, d / "cells.png")
    save_model(model, d / "model.npz")
    return d


def test_cli_grows_the_image_fitting_on_it(files, cells):
    r = cli("extend", files / "cells.png", "-o", files / "out.png", "--size", "96x200", "--anchor", "right",
            "--seed", "1", "-q")
    assert r.returncode == 0, r.stderr.decode()
    assert "96x96 extended to 96x200, written to" in r.stderr.decode()
    out = np.asarray(Image.open(files / "out.png"))
    assert out.shape == (96, 200, 3) and np.array_equal(out[:, 104:], cells)
    assert out[:, :104].reshape(-1, 3).std(axis=0).min() > 10


def test_cli_with_a_model_gives_the_same_image_for_the_same_seed(files, cells):
    args = ("extend", files / "cells.png", "--source", files / "model.npz", "--size", "128", "--seed", "3", "-q")
    for name in ("a.png", "b.png"):
        r = cli(*args, "-o", files / name)
        assert r.returncode == 0, r.stderr.decode()
    a, b = (np.asarray(Image.open(files / n)) for n in ("a.png", "b.png"))
    assert np.array_equal(a, b) and np.array_equal(a[16:112, 16:112], cells)


def test_cli_grows_the_image_as_the_librarys_extend_does(files, cells):
    # 0.59's tghop extend filled a texture's new area from the edge inwards, as a hole (tghop.inpaint.inpaint's
    # default), not row by row as tghop.inpaint.extend does: another, worse image for the same model and seed
    from tghop.modelfile import load_model

    r = cli("extend", files / "cells.png", "--source", files / "model.npz", "--size", "128x160", "--seed", "3", "-q",
            "-o", files / "lib.png")
    assert r.returncode == 0, r.stderr.decode()
    ours = extend(load_model(files / "model.npz"), cells, (128, 160), rng=3)
    assert np.array_equal(np.asarray(Image.open(files / "lib.png")), ours)


def test_cli_keeps_the_alpha_channel_and_makes_the_new_area_opaque(files, cells):
    alpha = ((np.arange(96)[:, None] + 2 * np.arange(96)) % 256).astype(np.uint8)[..., None]
    pixels = np.concatenate([cells, alpha], axis=2)
    Image.fromarray(pixels, "RGBA").save(files / "alpha.png")
    r = cli("extend", files / "alpha.png", "-o", files / "alpha_out.png", "--source", files / "model.npz",
            "--size", "96x130", "--anchor", "left", "--seed", "1", "-q")
    assert r.returncode == 0, r.stderr.decode()
    out = np.asarray(Image.open(files / "alpha_out.png"))
    assert out.shape == (96, 130, 4) and np.array_equal(out[:, :96], pixels) and (out[:, 96:, 3] == 255).all()


@pytest.mark.parametrize("args, words, status", [
    # --size's bad value: a usage error, 2, in the options' words (0.61: 1, "the size 64x200 ... the image")
    (["--size", "64x200"], ["--size 64x200 is smaller than IMAGE", "cells.png (96x96) in height; give --size at "
                                                                   "least 96x96"], 2),
    (["--size", "96x96"], ["--size 96x96 is IMAGE", "cells.png's own size, so there is nothing to extend; give a "
                                                    "larger --size"], 2),
    (["--size", "128", "--anchor", "middle"], ["--anchor", "middle"], 2),
    # a usage error, 2 (it exited 1, as a bad file does)
    (["--size", "128", "--scale", "0.5"], ["--scale applies to an exemplar given as --source", "extend --help"], 2),
    (["--size", "wide"], ["--size", "write HEIGHTxWIDTH"], 2),
])
def test_cli_bad_options_are_one_line_and_write_nothing(files, args, words, status):
    r = cli("extend", files / "cells.png", "-o", files / "bad.png", "-q", *args)
    assert_user_error(r, *words, status=status)
    assert not (files / "bad.png").exists()


def test_cli_an_image_too_small_to_fit_on_names_the_least_size_and_source(files, cells):
    # It said "use an exemplar of at least 76x76 pixels, or N of at most 10 (n_clusters, --clusters)":
    # extend and inpaint have no --clusters, and IMAGE is no exemplar.
    save_image(cells[:40, :40], files / "small.png")  # 0.57 refused 50x50 too (at least 76x76)
    small = files / "small.png"
    for args in (["extend", small, "--size", "100"], ["inpaint", small, small]):  # its light cells: the hole
        r = cli(*args, "-o", files / "bad.png", "-q")
        assert_user_error(r, "IMAGE", "small.png is 40x40 pixels, too small to fit a model on (at least 44x44 "
                             "pixels); give --source")
        assert "--clusters" not in r.stderr.decode() and not (files / "bad.png").exists()


def test_cli_a_strip_thinner_than_a_patch_names_image_the_size_asked_and_extend(files, cells):
    # `extend small.png --size 8x400` said "the image is 8x400; inpainting with 32x32 patches ...", naming the
    # canvas and inpainting where the user gave an 8x50 IMAGE to extend (or, with --source, refused IMAGE
    # itself, though the canvas is what the patches fill: an 8x50 IMAGE grown to 40x400 is filled).
    save_image(cells[:8, :50], files / "strip.png")
    for source in ([], ["--source", files / "model.npz"], ["--source", "builtin:bricks"]):
        r = cli("extend", files / "strip.png", "-o", files / "bad.png", "--size", "8x400", "-q", *source)
        assert_user_error(r, "extend", "IMAGE", "strip.png (8x50)", "--size 8x400", "32x32 patches",
                          "ask for a --size of at least 32x400")
        assert "inpainting" not in r.stderr.decode() and "the image is" not in r.stderr.decode()
        assert not (files / "bad.png").exists()
    r = cli("extend", files / "strip.png", "-o", files / "thin.png", "--size", "20x400", "-q", "--source",
            files / "model.npz")  # a model of 16x16 patches: named where it can fill the strip
    assert_user_error(r, "--size 20x400", "ask for a --size of at least 32x400",
                      "or give --source a model of smaller patches", "--patch-size 16")
    r = cli("extend", files / "strip.png", "-o", files / "wide.png", "--size", "40x400", "--source",
            files / "model.npz", "--seed", "1", "-q")
    assert r.returncode == 0, r.stderr.decode()
    assert np.asarray(Image.open(files / "wide.png")).shape == (40, 400, 3)
    r = cli("extend", files / "strip.png", "-o", files / "fit.png", "--size", "40x400", "-q")  # fitted on IMAGE
    assert_user_error(r, "IMAGE", "strip.png is 8x50 pixels, too small to fit a model on", "give --source")


def test_cli_an_image_that_is_no_image_or_a_model_is_one_line(files):
    (files / "notes.txt").write_text("not an image")
    r = cli("extend", files / "notes.txt", "-o", files / "bad.png", "--size", "128")
    assert_user_error(r, "notes.txt")
    r = cli("extend", files / "model.npz", "-o", files / "bad.png", "--size", "128")
    assert_user_error(r, "is a model file")
    assert not (files / "bad.png").exists()


def test_cli_tile_warns_where_the_image_spans_the_whole_height_or_width(files):
    # 'extend --tile' promises a result that tiles, but IMAGE is kept as it is: where it spans the whole height
    # (or width) of --size its own top and bottom rows meet at the wrap, and the result tiled only as IMAGE did.
    args = ("extend", files / "cells.png", "--source", files / "model.npz", "--tile", "--seed", "1", "-q")
    for size, words in (("96x160", "spans the whole height of --size 96x160 and is kept as it is, so the result "
                                    "tiles top to bottom only if IMAGE does; give a --size larger in height too"),
                        ("160x160", None)):
        r = cli(*args, "-o", files / "tiled.png", "--size", size)
        assert r.returncode == 0, r.stderr.decode()
        lines = [line for line in r.stderr.decode().splitlines() if line.startswith("Warning")]
        assert lines == ([f"Warning: --tile: IMAGE {files / 'cells.png'} {words}"] if words else []), lines


def test_a_block_is_centred_on_each_edge_of_the_grown_picture():
    # 0.59 put extend's blocks every step from 0: a 256 px picture at 64 of a 384 px canvas met the block at 54
    # (10 of its columns on the picture), and the cut between it and the block before lay 6-10 px outside the old
    # edge, a band busier than the fill around it (the seam an artist saw on stone). Now a block is centred on each
    # of the picture's edges, half on it, and the blocks between are spread evenly at most a step apart. A hole
    # inside the picture (inpaint's order) keeps 0.59's grid.
    from tghop.hole_quilting import _fill_order

    p, step = 32, 27
    hole = np.ones((384, 384), dtype=bool)
    hole[64:320, 64:320] = False
    blocks = _fill_order(hole, p, step, tile=False, order="raster")
    xs, ys = sorted({x for _, x in blocks}), sorted({y for y, _ in blocks})
    for grid in (xs, ys):
        assert {64 - p // 2, 320 - p // 2} <= set(grid), grid
        assert grid[0] == 0 and grid[-1] == 384 - p and max(np.diff(grid)) <= step
    covered = np.zeros_like(hole)
    for y, x in blocks:
        covered[y:y + p, x:x + p] = True
    assert covered[hole].all()
    square = np.zeros((256, 256), dtype=bool)
    square[64:192, 64:192] = True
    assert {x for _, x in _fill_order(square, p, step, tile=False)} == {54, 81, 108, 135, 162, 189}
    left = np.ones((128, 384), dtype=bool)
    left[:, :256] = False  # grown to the right (anchor "left"): one edge, at 256
    assert 256 - p // 2 in {x for _, x in _fill_order(left, p, step, tile=False, order="raster")}
