"""Inpainting (tghop.inpaint, ``tghop inpaint``) and sample masks (``TGHop.fit(exclude=)``,
``--exclude``), on textures made in code."""


import warnings

import numpy as np
import pytest
from PIL import Image

from tghop import TGHopError, data
from tghop.imageio import save_image, to_uint8
from tghop.inpaint import check_hole, extend, inpaint
from tghop.modelfile import save_model
from tghop.period import match_band
from tghop.synthesis import TGHop

from conftest import assert_user_error, cli

#: A small model, fast to fit.
FAST = dict(n_clusters=10, n_codewords=40, max_patches=1200, layout_factor=None)
POOL = dict(n_patches=600, refine=2)


@pytest.fixture(scope="module")
def cells():
    return to_uint8(data.cells(96, rng=3))  # (96, 96, 3) uint8


@pytest.fixture(scope="module")
def square(cells):
    hole = np.zeros(cells.shape[:2], dtype=bool)
    hole[30:62, 34:66] = True
    return hole


@pytest.fixture(scope="module")
def model(cells, square):
    return TGHop(rng=0, **FAST).fit(cells, exclude=square)


def _red(x):
    x = np.asarray(x, dtype=np.float64)
    x = x / 255.0 if x.max() > 1 else x
    return float((x[..., 0] - np.maximum(x[..., 1], x[..., 2]) > 0.3).mean())


def test_known_pixels_are_kept_bit_for_bit_and_the_hole_looks_like_its_surroundings(model, cells, square):
    out = inpaint(model, cells, square, rng=1, **POOL)
    assert out.dtype == np.uint8 and out.shape == cells.shape
    assert np.array_equal(out[~square], cells[~square])
    ring = np.zeros_like(square)
    ring[14:78, 18:82] = True
    ring &= ~square
    filled, around = out[square] / 255.0, cells[ring] / 255.0
    assert np.all(np.abs(filled.mean(axis=0) - around.mean(axis=0)) < 0.08)
    assert np.all(filled.std(axis=0) > 0.5 * around.std(axis=0))
    # Float images: the known values are the same floats.
    image = data.cells(96, rng=3)
    out = inpaint(model, image, square, rng=1, **POOL)
    assert out.dtype == np.float64 and np.array_equal(out[~square], image[~square])


def test_the_same_seed_gives_the_same_image(model, cells, square):
    a = inpaint(model, cells, square, rng=5, **POOL)
    b = inpaint(model, cells, square, rng=5, **POOL)
    c = inpaint(model, cells, square, rng=6, **POOL)
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_a_fill_is_stitched_to_its_surroundings_by_default(model, cells, square):
    # inpaint's seam removal (seam_window, 9 as synthesize's; 0: none, as up to 0.49.1) is on by default
    # and makes the steps across the hole's edge smaller; the known pixels stay.
    plain = inpaint(model, cells, square, rng=1, seam_window=0, refine=0, patch_refine=0, n_patches=600)
    stitched = inpaint(model, cells, square, rng=1, refine=0, patch_refine=0, n_patches=600)
    assert np.array_equal(stitched[~square], cells[~square]) and not np.array_equal(stitched, plain)

    def edge_steps(img):  # the tone steps across the hole's left and right edges: means over 8 rows
        img = img.astype(np.float64)
        return np.abs((img[30:62, [33, 65]] - img[30:62, [34, 66]]).reshape(4, 8, 2, 3).mean(axis=1)).mean()

    assert edge_steps(stitched) < 0.9 * edge_steps(plain)  # 0.80 here


@pytest.mark.parametrize("tile", [False, True])
def test_stitching_removes_the_fills_tone_steps_and_keeps_the_known_pixels(tile, monkeypatch):
    # A fill's blocks differ in tone from each other and from the image around the hole: its
    # seams showed as a patchwork and the hole's outline (a game artist's audit, 0.49.1).
    from tghop.inpaint import stitch_hole

    canvas = np.full((40, 48, 2), 0.5, dtype=np.float32)
    hole = np.zeros((40, 48), bool)
    hole[10:30, 12:36] = True
    owner = np.full((40, 48), -1)
    owner[10:30, 12:24], owner[10:30, 24:36] = 1, 2
    canvas[10:30, 12:24] = 0.6  # tone steps: 0.1 at the hole's left edge, 0.15 between the blocks
    canvas[10:30, 24:36] = 0.45
    canvas[10:30, 12:36, 1] += np.linspace(0, 0.1, 24, dtype=np.float32)  # detail: a ramp, kept
    out = stitch_hole(canvas, hole, owner, tile=tile)
    assert out.dtype == np.float32 and np.array_equal(out[~hole], canvas[~hole])  # the known pixels, exactly
    steps = np.abs(np.diff(out[..., 0], axis=1))
    assert steps[20, 11] < 0.02 and steps[20, 23] < 0.04 and steps[20, 35] < 0.02  # were 0.1, 0.15, 0.05
    inner = np.diff(out[20, 13:23, 1]) - np.diff(canvas[20, 13:23, 1])
    assert np.abs(inner).max() < 0.01  # inside a block its own differences stay
    same = np.where(hole, 1, -1)  # one block: no seam inside, only the hole's edge
    flat = np.where(hole[..., None], np.float32(0.5), canvas)
    assert np.array_equal(stitch_hole(flat, hole, same, tile=tile), flat)  # nothing to remove
    # A content edge at the hole's edge (a white label beside the fill) is no tone step: the fill keeps
    # its own tone there instead of taking the label's colour along the seam.
    label = canvas.copy()
    label[4:36, 4:12] = 1.0
    kept = stitch_hole(label, hole, owner, tile=tile)
    assert np.array_equal(kept[~hole], label[~hole]) and 0.5 < kept[20, 12, 0] < 0.65  # near 1 if pulled
    import tghop.hole_refine

    monkeypatch.setattr(tghop.hole_refine, "STITCH_LU", 0)  # a large hole's conjugate gradients: the same, nearly
    np.testing.assert_allclose(stitch_hole(canvas, hole, owner, tile=tile), out, atol=2e-3)


@pytest.mark.parametrize("width", [4, 10])
def test_stitching_continues_the_known_detail_across_the_holes_rim(width):
    # A thin stripe's fill showed hard edges at its borders (an artist's audit): the steps of detail across
    # the rim (a known pixel beside a filled one) were left, only their tone (mean over 9 x 9) was removed.
    from tghop.inpaint import stitch_hole

    rng = np.random.default_rng(0)
    smooth = np.cumsum(rng.normal(0, 0.03, (48, 1, 1)), axis=0)  # detail that changes along the rim, not across
    canvas = np.clip(0.5 + smooth - smooth.mean() + rng.normal(0, 0.01, (48, 40, 1)), 0, 1).astype(np.float32)
    hole = np.zeros((48, 40), bool)
    hole[:, 18:18 + width] = True
    owner = np.where(hole, 1, -1)
    canvas[hole] = np.clip(0.5 + rng.normal(0, 0.01, (48 * width, 1)), 0, 1)  # a fill blind to that detail
    out = stitch_hole(canvas, hole, owner)
    assert np.array_equal(out[~hole], canvas[~hole])

    def rim_step(img):  # mean absolute step across the stripe's two borders, over the known area's median
        across = np.abs(img[:, [17, 18 + width], 0] - img[:, [18, 17 + width], 0]).mean()
        return across / np.median(np.abs(np.diff(img[:, :16, 0], axis=1)))

    assert rim_step(out) < 0.25 * rim_step(canvas)  # 0.10-0.12 here; the rim's tone alone: 1.0 (4 px), 0.38 (10 px)


class _TwoPatches:
    """A stand-in for a fitted model whose pool is two given patches (``inpaint`` without refinements)."""

    def __init__(self, *patches):
        self.patches = np.stack(patches).astype(np.float32)
        self.patch_size, self.exemplar_shape_, self.ichm_ = self.patches.shape[1], self.patches.shape[1:], True

    def sample_patches(self, n, *, rng=None, dtype=np.float32):
        return self.patches.astype(dtype)


def test_a_block_is_matched_most_on_the_pixels_beside_the_hole():
    # red_bricks_512's thin stripe kept a mortar joint's edge on the known side of its rim and filled the
    # stripe from a patch that matched the block's far pixels but not that edge: a thin stripe at the rim
    # (docs/choices.md, Inpainting "the rim in the matching"). The pixels beside the hole now count more.
    image = np.full((32, 32, 1), 0.5, np.float32)
    image[:, 10:12] = 0.0  # a dark line beside the hole's left rim
    hole = np.zeros((32, 32), bool)
    hole[:, 12:20] = True
    blind = image.copy()
    blind[:, 10:12] = 0.5  # the far pixels exactly, not the line
    blind[hole] = 0.9
    continues = np.full((32, 32, 1), 0.7, np.float32)  # the far pixels 0.2 off, the line carried into the hole
    continues[:, 10:14] = 0.0
    out = inpaint(_TwoPatches(blind, continues), image, hole, rng=0, detail=0.0, flat_share=0.0, tolerance=0.0,
                  seam_window=0, refine=0, patch_refine=0)
    assert np.array_equal(out[~hole], image[~hole])
    assert out[:, 12:14].max() == 0.0 and np.allclose(out[:, 14:20], 0.7)


@pytest.mark.parametrize("order, fill", [("edge", 0.1), ("raster", 0.5)])
def test_a_block_is_matched_on_the_known_pixels_near_those_it_fills(order, fill):
    # 0.60 matched a block over all its known pixels: beside a hole's edge up to 27 of its 32 columns, which a
    # blended patch matches loosely everywhere better than a sharp one matches them, so fills of stones came out
    # as a quilt of faint blocks (docs/choices.md, Inpainting "the known pixels matched in a band"). Now only the
    # known pixels within an overlap of those to fill count, as quilting matches its overlap strips. Row by row
    # (extend's order) a block still matches all its known pixels: half a block on a grown picture's edge (0.60).
    image = np.zeros((32, 40, 1), np.float32)
    image[:, 0:27:2], image[:, 1:27:2] = 0.2, 0.8  # far from the hole: stripes
    image[:, 27:32] = 0.1  # beside it: a dark element that should carry on into it
    hole = np.zeros((32, 40), bool)
    hole[:, 32:] = True  # its one block holds columns 8 to 39: 24 known columns, 8 to fill
    blend = np.full((32, 32, 1), 0.5, np.float32)  # 0.3 off every stripe, 0.4 off the element
    sharp = np.full((32, 32, 1), 0.1, np.float32)  # the element exactly, the stripes in the other phase
    sharp[:, 0:19:2], sharp[:, 1:19:2] = 0.8, 0.2
    out = inpaint(_TwoPatches(blend, sharp), image, hole, rng=0, detail=0.0, flat_share=0.0, tolerance=0.0,
                  seam_window=0, refine=0, patch_refine=0, order=order)
    assert np.array_equal(out[~hole], image[~hole])
    assert np.allclose(out[hole], fill)  # a hole's in 0.60: the blend's 0.5


def test_a_regular_picture_is_matched_over_its_period():
    # 0.61 matched every hole's block within an overlap (5 px) of the pixels it fills: beside a hole between two
    # mortar lines those are all brick, so a patch whose mortar fell in the hole matched as well as the right one,
    # and builtin bricks' courses broke (docs/choices.md, Inpainting "0.62"). A regular picture's blocks are matched
    # within its period (here 24 rows), which holds a mortar line on each side.
    rows = np.where(np.arange(128 + 32) % 24 < 3, 0.2, 0.7).astype(np.float32)  # a mortar line every 24 rows
    image = np.repeat(rows[:128, None, None], 128, axis=1)
    hole = np.zeros((128, 128), bool)
    hole[57:63] = True  # rows 9 to 14 of a period: brick within 5 px on both sides, mortar 7 and 10 px away
    phases = [np.repeat(rows[k:k + 32, None, None], 32, axis=1) for k in range(24)]  # the stripes at every phase
    assert match_band(image, hole, 5, 32) == 24
    for seed in range(4):  # 0.61 put mortar in the hole with seeds 2 and 3
        out = inpaint(_TwoPatches(*phases), image, hole, rng=seed, detail=0.0, flat_share=0.0, tolerance=0.0,
                      seam_window=0, refine=0, patch_refine=0)
        assert np.array_equal(out, image), seed


def test_odd_shapes_holes_at_the_border_and_nearly_everything(model, cells):
    yy, xx = np.mgrid[:96, :96]
    shapes = {
        "ring": (np.hypot(yy - 48, xx - 48) > 20) & (np.hypot(yy - 48, xx - 48) < 28),
        "corner": (yy < 20) & (xx > 70),
        "line": np.abs(yy - xx) < 2,
        "pixel": (yy == 95) & (xx == 0),
        "almost all": ~((yy < 8) & (xx < 8)),
    }
    for name, hole in shapes.items():
        out = inpaint(model, cells, hole, rng=2, **POOL)
        assert np.array_equal(out[~hole], cells[~hole]), name
        assert out[hole].std() > 5, name  # texture, not a flat colour


def test_tile_fills_across_the_edges(model, cells):
    image = np.roll(cells, 48, axis=(0, 1))  # a tileable image
    hole = np.zeros((96, 96), dtype=bool)
    hole[:, :12] = hole[:, -12:] = True  # straddles the left and right edges
    out = inpaint(model, image, hole, rng=3, tile=True, **POOL).astype(np.float64)
    assert np.array_equal(out[~hole], image[~hole])
    seam = np.abs(out[:, 0] - out[:, -1]).mean()
    inside = np.abs(np.diff(out[:, 20:76], axis=1)).mean()
    assert seam < 2.0 * inside


def test_a_greyscale_model_fills_a_grey_rgb_image(cells):
    grey = np.repeat(cells.mean(axis=2, keepdims=True).astype(np.uint8), 3, axis=2)
    hole = np.zeros((96, 96), dtype=bool)
    hole[40:60, 40:60] = True
    model = TGHop(rng=0, **FAST).fit(grey, exclude=hole)
    out = inpaint(model, grey, hole, rng=1, **POOL)
    assert np.array_equal(out[~hole], grey[~hole])
    assert np.array_equal(out[..., 0], out[..., 1]) and np.array_equal(out[..., 0], out[..., 2])


def test_a_16_bit_picture_is_filled_at_16_bits(model, cells, square):
    deep = cells.astype(np.uint16) * np.uint16(257) ^ np.uint16(5)  # low bits an 8-bit picture cannot hold
    out = inpaint(model, deep, square, rng=1, **POOL)
    assert out.dtype == np.uint16
    assert np.array_equal(out[~square], deep[~square])  # the same levels
    assert not np.array_equal(out[square], deep[square])
    # The fill of the same picture as floats (levels / 65535, as a 16-bit file is read), at 16 bits
    floats = inpaint(model, deep / 65535.0, square, rng=1, **POOL)
    assert np.abs(out.astype(np.int64) - np.round(floats * 65535).astype(np.int64)).max() <= 1
    # A 16-bit mask's hole is above half its levels
    assert np.array_equal(check_hole(np.where(square, 40000, 30000).astype(np.uint16), square.shape), square)
    grown = extend(model, deep, (96, 128), anchor="left", rng=1, **POOL)
    assert grown.dtype == np.uint16 and np.array_equal(grown[:, :96], deep)


def test_bad_input_is_one_line(model, cells, square):
    with pytest.raises(TGHopError, match="the mask is 10x10 but the image is 96x96"):
        inpaint(model, cells, np.zeros((10, 10), bool))
    with pytest.raises(TGHopError, match="greyscale"):
        inpaint(model, cells[..., :1], square)
    with pytest.raises(TGHopError, match="at least 32x32"):
        inpaint(model, cells[:20, :20], square[:20, :20])
    assert check_hole(np.full((4, 4, 3), 200, np.uint8), (4, 4)).all()


def test_masks_and_arguments_are_checked_as_documented(model, cells, square):
    fast = dict(rng=1, n_patches=100, refine=0)
    # an (H, W, C) bool mask is documented: the same hole as its (H, W) one
    assert np.array_equal(inpaint(model, cells, np.dstack([square] * 3), **fast), inpaint(model, cells, square, **fast))
    assert check_hole(np.dstack([square] * 3), (96, 96)).sum() == square.sum()
    for mask in (np.where(square, np.nan, 0.0), np.where(square, np.inf, 0.0)):
        with pytest.raises(TGHopError, match="the mask has NaN or infinite values"):
            inpaint(model, cells, mask, **fast)
    with pytest.raises(TGHopError, match=r"the mask is 96x96x3x1 but the image is 96x96"):
        check_hole(np.zeros((96, 96, 3, 1), bool), (96, 96))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a mask of no channels warned "Mean of empty slice" first
        with pytest.raises(TGHopError, match=r"the mask is 96x96x0 but the image is 96x96"):
            check_hole(np.zeros((96, 96, 0)), (96, 96))
    # an empty image was grown to a canvas all hole: a texture with nothing of the image kept
    for empty in (cells[:0], cells[:, :0], cells[..., :0]):
        with pytest.raises(TGHopError, match=r"the image is empty \(shape"):
            extend(model, empty, (120, 120), **fast)
    for tile in ("no", 2, None):  # synthesize's rule (the settings table): 0 and 1 are taken
        with pytest.raises(TGHopError, match="tile must be True or False"):
            inpaint(model, cells, square, tile=tile, **fast)
    with pytest.raises(TGHopError, match="the image is empty"):
        inpaint(model, cells[:0].astype(np.float64), square[:0])
    with pytest.raises(TGHopError, match=r"^inpaint: image must be an \(H, W, C\) float array in \[0, 1\] or "
                       "uint8 or uint16, got int64"):
        inpaint(model, cells.astype(np.int64), square, **fast)
    with pytest.raises(TGHopError, match=r"^inpaint: image values must lie in \[0, 1\], got \["):
        inpaint(model, cells.astype(np.float64), square, **fast)
    with pytest.raises(TGHopError, match="n_patches must be an integer >= 1 and <= 10,000,000, got 1000000000"):
        inpaint(model, cells, square, rng=1, n_patches=10**9)
    with pytest.raises(TGHopError, match=r"^blend must be an integer >= 0, got -1$"):
        inpaint(model, cells, square, blend=-1, **fast)
    for weight in (-1, float("inf"), True):
        with pytest.raises(TGHopError, match=r"^layout_weight must be a finite number >= 0 and <= 1,000,000, got "):
            inpaint(model, cells, square, layout_weight=weight, **fast)
    for steps in (-1, 2.5, "10", 501):
        with pytest.raises(TGHopError, match=r"^patch_refine must be an integer >= 0 and <= 500 or None, got "):
            inpaint(model, cells, square, patch_refine=steps, **fast)
    # The rest of the settings it shares with synthesize: the same table, the same words.
    for name, value in (("tolerance", -0.5), ("detail", 1.0), ("flat_share", -0.1), ("refine", 21)):
        with pytest.raises(TGHopError, match=f"^{name} must be .*, got {value}$"):
            inpaint(model, cells, square, **{**fast, name: value})
    with pytest.raises(TGHopError, match="rng"):
        inpaint(model, cells, np.zeros((96, 96), bool), rng="x")


def test_a_mask_with_no_hole_gives_the_image_back_with_a_warning(model, cells):
    # 0.61 gave it back without a word, where tghop inpaint and the page refuse such a mask; a library call over
    # many masks, some empty, still gets its pictures (and the stages, empty): told, not stopped
    with pytest.warns(UserWarning, match=r"^inpaint: the mask has no hole \(no pixel True, or white\), so the image is "
                                         r"returned as it is; mark the pixels to fill True") as said:
        out, stages = inpaint(model, cells, np.zeros((96, 96), bool), rng=0, return_stages=True)
    assert np.array_equal(out, cells) and stages == {} and said[0].filename == __file__


def test_too_large_a_hole_is_refused_naming_the_minimum(cells):
    hole = np.ones((96, 96), dtype=bool)
    hole[:40, :40] = False
    with pytest.raises(TGHopError, match=r"too little texture outside the mask: 25 training patches .* at least "
                                         r"100 are needed; use a smaller mask or a larger image, or N of at most 2 "
                                         r"\(n_clusters, "):
        TGHop(rng=0, **FAST).fit(cells, exclude=hole)
    TGHop(rng=0, **{**FAST, "n_clusters": 2}).fit(cells, exclude=hole)  # the N it names fits


def test_an_excluded_red_label_is_not_learnt():
    image = data.cells(128, rng=1)
    image[30:70, 40:80] = (1.0, 0.0, 0.0)
    label = np.zeros((128, 128), dtype=bool)
    label[30:70, 40:80] = True
    plain = TGHop(rng=0, **FAST).fit(image)
    assert _red(plain.sample_patches(200, rng=1)) > 0.01  # learnt without the mask
    model = TGHop(rng=0, **FAST).fit(image, exclude=label)
    assert _red(model.sample_patches(300, rng=1)) == 0.0
    assert _red(model.synthesize((96, 96), rng=1, n_patches=600)) == 0.0
    assert model.colour_quantiles_[0, -1] < 0.9  # no red in the colour statistics either


def test_an_empty_exclude_mask_gives_the_same_model(cells):
    a = TGHop(rng=0, **FAST).fit(cells)
    b = TGHop(rng=0, **FAST).fit(cells, exclude=np.zeros((96, 96), bool))
    assert np.array_equal(a.synthesize((64, 64), rng=1, n_patches=300), b.synthesize((64, 64), rng=1, n_patches=300))
    with pytest.raises(TGHopError, match="exclude must be a boolean"):
        TGHop(rng=0, **FAST).fit(cells, exclude=np.zeros((5, 5), bool))


def test_return_stages_gives_each_steps_picture_and_the_last_is_the_result(model, cells, square, small_model,
                                                                           bricks96):
    # 0.60: synthesize(return_stages=True) showed each step of a synthesis, but an inpainting's steps (its coarse
    # fill, quilt, seams, refinements) could not be looked at.
    laid = small_model  # with a coarse layout: its fill is the step "guide"
    assert laid.layout_ is not None
    for m, picture in ((laid, to_uint8(bricks96)), (model, cells.astype(np.uint16) * np.uint16(257)),
                       (model, cells / 255.0)):
        out, stages = inpaint(m, picture, square, rng=1, return_stages=True, **POOL)
        assert np.array_equal(out, inpaint(m, picture, square, rng=1, **POOL))  # the same fill
        names = [k for k in stages if k != "pool"]
        want = ["quilt", "seams", "refine", "patch refine"]
        assert names == (["guide"] if m is laid else []) + want
        top = {np.uint8: 255, np.uint16: 65535}.get(picture.dtype.type, 1)
        known = (picture[~square] / top).astype(np.float32)
        for name in names:
            assert stages[name].dtype == np.float32 and stages[name].shape == picture.shape
            assert np.array_equal(stages[name][~square], known)  # the picture's own pixels in every step
        assert np.array_equal(stages[names[-1]], (out / top).astype(np.float32))  # the last step is the result
        assert not np.array_equal(stages["quilt"], stages["seams"]) and not np.array_equal(stages["seams"],
                                                                                          stages["refine"])
        assert stages["pool"].shape == (POOL["n_patches"], m.patch_size, m.patch_size, 3)
    no_steps = inpaint(model, cells, square, rng=1, seam_window=0, refine=0, patch_refine=0, n_patches=600,
                       return_stages=True)[1]
    assert [k for k in no_steps if k != "pool"] == ["quilt"]
    grown, steps = extend(model, cells, (96, 128), anchor="left", rng=1, return_stages=True, **POOL)
    assert np.array_equal(steps["patch refine"], grown / np.float32(255)) and steps["quilt"].shape == (96, 128, 3)


def test_a_deferred_pool_decoded_twice_says_so(small_model):
    # 0.63's second decode() raised "IndexError: pop from empty list" (its vectors are let go after the first).
    from tghop._errors import TGHopError
    from tghop.pool import deferred_pool

    decode = deferred_pool(small_model, 20, np.random.default_rng(4), np.float32)
    assert decode().shape[0] == 20
    with pytest.raises(TGHopError, match=r"^deferred_pool: this pool was decoded already \(its vectors are let go "
                                         r"after the first decode\(\)\); draw another with deferred_pool$"):
        decode()

def test_the_pool_is_drawn_before_the_coarse_fill_decoded_after_it_and_let_go_before_the_refinements(
        small_model, bricks96, square, monkeypatch):
    # 0.62 decoded the fill's pool before its coarse fill, which holds a pool of its own, and kept it through the
    # refinements: both pools at once (80-200 MB). 0.63 draws its vectors first (the same draws: the same fill)
    # and decodes them after the coarse fill.
    import weakref

    import tghop.inpaint as module
    from tghop.pool import GeneratedPool, deferred_pool

    m = small_model
    assert m.layout_ is not None
    assert np.array_equal(deferred_pool(m, 300, np.random.default_rng(4), np.float32)(),
                          m.sample_patches(300, rng=4, dtype=np.float32))  # bit for bit
    events, pools, alive = [], [], []
    decode, draw, refine = GeneratedPool.all, TGHop.sample_vectors, module.refine_hole

    def spy_decode(self):
        out = decode(self)
        events.append(("decode", len(out)))
        pools.append(weakref.ref(out))
        return out

    def spy_draw(self, n, *args, **kwargs):
        events.append(("draw", n))
        return draw(self, n, *args, **kwargs)

    def spy_refine(*args, **kwargs):
        alive.append([p() is not None for p in pools])
        return refine(*args, **kwargs)

    monkeypatch.setattr(GeneratedPool, "all", spy_decode)
    monkeypatch.setattr(TGHop, "sample_vectors", spy_draw)
    monkeypatch.setattr(module, "refine_hole", spy_refine)
    inpaint(m, to_uint8(bricks96), square, rng=1, **POOL)
    c = module.COARSE_PATCHES
    assert events == [("draw", POOL["n_patches"]), ("draw", c), ("decode", c), ("decode", POOL["n_patches"])]
    assert alive[-1] == [False, False]  # the fine fill's refinements: neither pool held


# ---------------------------------------------------------------- command line
def run(*args):
    return cli(*args)  # in this process: the same exit status and output, no interpreter to start


@pytest.fixture(scope="module")
def files(tmp_path_factory, cells, square, model):
    d = tmp_path_factory.mktemp("inpaint")
    save_image(cells, d / "cells.png")
    mask = np.zeros((96, 96), dtype=np.uint8)
    mask[40:52, 40:52] = 255
    Image.fromarray(mask).save(d / "mask.png")
    Image.fromarray(np.zeros((50, 96), np.uint8)).save(d / "small_mask.png")
    Image.fromarray(np.full((96, 96), 127, np.uint8)).save(d / "grey_mask.png")  # just below mid-grey: no hole
    (d / "notes.txt").write_text("not an image")
    save_model(model, d / "model.npz")
    return d


def test_cli_without_source_fits_on_the_image(files):
    r = run("inpaint", files / "cells.png", files / "mask.png", "-o", files / "out.png", "--seed", "1", "-q")
    assert r.returncode == 0, r.stderr.decode()
    src, out = (np.asarray(Image.open(files / n)) for n in ("cells.png", "out.png"))
    hole = np.asarray(Image.open(files / "mask.png")) > 127
    assert np.array_equal(out[~hole], src[~hole]) and not np.array_equal(out[hole], src[hole])


def test_cli_stages_writes_each_steps_picture_the_last_the_output(files):
    # 0.60: synth --stages wrote each step's image; inpaint and extend had no such option.
    src = np.asarray(Image.open(files / "cells.png"))
    for command, args in (("inpaint", (files / "mask.png",)), ("extend", ("--size", "96x128", "--anchor", "left"))):
        out = files / f"st_{command}.png"
        r = run(command, files / "cells.png", *args, "--source", files / "model.npz", "-o", out, "--seed", "3",
                "--stages", "-q")
        assert r.returncode == 0, r.stderr.decode()
        steps = ["quilt", "seams", "refine", "patch-refine"]
        said = f"steps written beside it: {', '.join(f'st_{command}_{s}.png' for s in steps)}\n"
        assert said in r.stderr.decode()
        assert f"written to {out}\n{said}" in r.stderr.decode(), r.stderr.decode()  # the output first (0.62)
        pictures = [np.asarray(Image.open(files / f"st_{command}_{s}.png")) for s in steps]
        result = np.asarray(Image.open(out))
        assert np.array_equal(pictures[-1], result) and not np.array_equal(pictures[0], result)
        kept = (slice(None), slice(0, 96)) if command == "extend" else ~(np.asarray(Image.open(files / "mask.png"))
                                                                         > 127)
        assert all(np.array_equal(p[kept], src[kept] if command == "inpaint" else src) for p in pictures)
        again = files / f"plain_{command}.png"  # the same fill without --stages
        assert run(command, files / "cells.png", *args, "--source", files / "model.npz", "-o", again, "--seed", "3",
                   "-q").returncode == 0
        assert np.array_equal(np.asarray(Image.open(again)), result)
    r = run("inpaint", files / "cells.png", files / "mask.png", "-o", "-", "--stages", "-q")
    assert_user_error(r, "--stages needs a file name", status=2)
    # with --maps: each step's maps (0.61; 0.60 refused it), tests/test_material_fill.py


def test_cli_with_a_model_and_tile(files):
    args = ("inpaint", files / "cells.png", files / "mask.png", "--source", files / "model.npz", "--seed", "2", "-q")
    r = run(*args, "-o", files / "a.png", "--tile")
    assert r.returncode == 0, r.stderr.decode()
    r = run(*args, "-o", files / "b.png", "--tile")
    src, a, b = (np.asarray(Image.open(files / n)) for n in ("cells.png", "a.png", "b.png"))
    hole = np.asarray(Image.open(files / "mask.png")) > 127
    assert np.array_equal(a[~hole], src[~hole]) and np.array_equal(a, b)


@pytest.mark.parametrize("mask, words", [("small_mask.png", "is 50x96 but IMAGE"), ("notes.txt", "notes.txt"),
                                         ("model.npz", "is a model file"),
                                         ("grey_mask.png", "grey_mask.png has no white pixel, so there is nothing")])
def test_cli_bad_masks_are_one_line(files, mask, words):
    r = run("inpaint", files / "cells.png", files / mask, "-o", files / "bad.png", "--source", files / "model.npz")
    assert_user_error(r, words)
    assert not (files / "bad.png").exists()


@pytest.mark.parametrize("command", ["inpaint", "extend"])
def test_cli_a_built_in_exemplar_as_image_is_sent_to_source(files, command):
    # It said "builtin:bricks: no such file; check the path"; then exit status 1, though the command line alone is
    # wrong (a usage error, 2, as builtin:NAME of no built-in exemplar is; 0.57).
    more = [files / "mask.png"] if command == "inpaint" else ["--size", "128x128"]
    r = run(command, "builtin:bricks", *more, "-o", files / "bad.png")
    assert_user_error(r, "IMAGE builtin:bricks is a built-in exemplar, not a picture file",
                      "a built-in exemplar goes to --source", status=2)
    assert not (files / "bad.png").exists()


def test_cli_exclude_on_fit_and_synth(files):
    r = run("fit", files / "cells.png", "-o", files / "ex.npz", "--exclude", files / "small_mask.png", "-q")
    assert_user_error(r, "--exclude", "is 50x96 but the exemplar is 96x96")
    r = run("synth", files / "model.npz", "-o", files / "s.png", "--exclude", files / "mask.png")
    assert_user_error(r, "--exclude")
    r = run("synth", files / "cells.png", "-o", files / "s.png", "--exclude", files / "mask.png", "--size", "64",
            "--clusters", "10", "--max-patches", "1000", "--layout", "none", "--seed", "1", "-q")
    assert r.returncode == 0, r.stderr.decode()


def test_cli_masks_that_leave_too_little_name_the_fix_of_each_command(files):
    # An all-white MASK: inpaint names --source; fit --exclude is not inpainting (both said
    # "or, to inpaint, fit on another exemplar").
    Image.fromarray(np.full((96, 96), 255, np.uint8)).save(files / "white.png")
    r = run("inpaint", files / "cells.png", files / "white.png", "-o", files / "w.png", "-q")
    assert_user_error(r, "MASK", "white.png", "0 training patches", "give --source")
    r = run("fit", files / "cells.png", "--exclude", files / "white.png", "-o", files / "w.npz", "-q")
    assert_user_error(r, "too little texture outside the mask", "a smaller mask or a larger image")
    assert "inpaint" not in r.stderr.decode() and not (files / "w.npz").exists()


def test_cli_a_hole_painted_as_transparency_is_told_to_be_painted_white(files):
    # The mask's alpha was dropped: a hole painted as transparency gave "no white pixel" or "leaves too
    # little" without a word why. The pixels that are the hole stay the same: its colours' white ones.
    clear = np.zeros((96, 96, 4), np.uint8)
    clear[..., 3] = 255
    clear[40:52, 40:52, 3] = 0  # the hole, transparent black
    Image.fromarray(clear, "RGBA").save(files / "clear.png")
    r = run("inpaint", files / "cells.png", files / "clear.png", "-o", files / "c.png", "--source", files / "model.npz")
    assert_user_error(r, "clear.png has no white pixel")
    warned = [line for line in r.stderr.decode().splitlines() if line.startswith("Warning")]
    assert warned == [f"Warning: MASK {files / 'clear.png'} has transparent pixels, but transparency is not read as "
                      "the hole (its alpha channel is ignored; its white pixels are the hole); paint the hole white "
                      "on black"] and not (files / "c.png").exists()
    clear[..., :3] = 255  # white and transparent all round: the whole picture is the hole
    Image.fromarray(clear, "RGBA").save(files / "clear_white.png")
    r = run("inpaint", files / "cells.png", files / "clear_white.png", "-o", files / "c.png", "-q")
    assert_user_error(r, "leaves too little")
    assert "transparency is not read as the hole" in r.stderr.decode()
    r = run("fit", files / "cells.png", "--exclude", files / "clear.png", "-o", files / "c.npz", "-q", "--clusters",
            "10", "--max-patches", "1000", "--layout", "none")
    assert r.returncode == 0 and "paint the part left out white on black" in r.stderr.decode()
    opaque = np.zeros((96, 96, 4), np.uint8)
    opaque[..., 3] = 255
    opaque[40:52, 40:52, :3] = 255
    Image.fromarray(opaque, "RGBA").save(files / "opaque.png")  # white on black, an alpha that changes nothing
    r = run("inpaint", files / "cells.png", files / "opaque.png", "-o", files / "o.png", "--source",
            files / "model.npz", "--seed", "2", "-q")
    assert r.returncode == 0 and "Warning" not in r.stderr.decode(), r.stderr.decode()


@pytest.mark.parametrize("mode, channels, bits", [("RGBA", 4, 8), ("LA", 2, 8), ("RGBA", 4, 16), ("P", 1, 8)])
def test_a_masks_hole_is_its_white_pixels_whatever_its_alpha(tmp_path, mode, channels, bits):
    import warnings

    from tghop.cli.common import load_mask
    from tghop.imageio import load_image

    rng = np.random.default_rng(bits + channels)
    if mode == "P":  # a palette with a transparent entry
        image = Image.fromarray(rng.integers(0, 4, (20, 30)).astype(np.uint8), "P")
        image.putpalette([0, 0, 0, 255, 255, 255, 200, 90, 30, 250, 250, 250])
        image.info["transparency"] = 3
        image.save(tmp_path / "m.png", transparency=3)
    elif bits == 16:
        save_image(rng.random((20, 30, channels)), tmp_path / "m.png", depth=16)
    else:
        Image.fromarray(rng.integers(0, 256, (20, 30, channels)).astype(np.uint8), mode).save(tmp_path / "m.png")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        before = load_image(tmp_path / "m.png").mean(axis=2) > 0.5  # the alpha dropped, as the mask was read
    # Its masks are noise, which is rightly said too: both warnings are expected (each pytest.warns passes on
    # what it does not match), and no other.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.warns(UserWarning, match=r"^MASK .*m\.png is not black and white: \d+% of its pixels are "
                                             "grey or coloured"), \
                pytest.warns(UserWarning, match="transparency is not read as the hole"):
            hole = load_mask(str(tmp_path / "m.png"), (20, 30))
    assert np.array_equal(hole, before) and 0 < hole.sum() < hole.size


def test_cli_a_mask_that_leaves_one_patch_says_so_in_the_singular(files):
    # "1 training patches of 32x32 avoid the hole"
    corner = np.full((96, 96), 255, np.uint8)
    corner[:32, :32] = 0  # one patch position outside the hole
    Image.fromarray(corner).save(files / "corner.png")
    r = run("inpaint", files / "cells.png", files / "corner.png", "-o", files / "k.png", "-q")
    assert_user_error(r, "leaves too little", ": 1 training patch of 32x32 avoids the hole, at least")
    r = run("fit", files / "cells.png", "--exclude", files / "corner.png", "-o", files / "k.npz", "-q")
    assert_user_error(r, "mask: 1 training patch of 32x32 avoids it, at least")
    assert not (files / "k.png").exists() and not (files / "k.npz").exists()


def test_cli_an_image_smaller_than_the_patches_names_a_model_of_smaller_ones(files):
    # inpaint has no --patch-size and IMAGE is no exemplar ("use a larger exemplar or a smaller
    # patch size"); with --source the message named no fix at all.
    save_image(np.full((20, 20, 3), 0.5), files / "tiny.png")
    hole = np.zeros((20, 20), np.uint8)
    hole[5:10, 5:10] = 255
    Image.fromarray(hole).save(files / "tiny_hole.png")
    for source in ([], ["--source", files / "model.npz"], ["--source", "builtin:bricks"]):
        r = run("inpaint", files / "tiny.png", files / "tiny_hole.png", "-o", files / "t.png", "-q", *source)
        assert_user_error(r, "IMAGE", "20x20", "32x32 patches", "give --source a model of smaller patches",
                          "--patch-size 16")
        assert "exemplar" not in r.stderr.decode().split(";")[0]


def test_cli_a_source_exemplar_too_small_names_the_smallest_that_works(files):
    # `--source small.png` (31x31) said "at least 32x32", though 32x32 is still too small.
    save_image(np.random.default_rng(0).random((31, 31, 3)), files / "small.png")
    r = run("inpaint", files / "cells.png", files / "mask.png", "-o", files / "s.png", "-q",
            "--source", files / "small.png")
    assert_user_error(r, "31x31 pixels", "at least 44x44")


def test_a_layout_left_out_for_the_mask_says_so():
    # `fit rgb.png --exclude hole.png` said "(asked 3: the exemplar is too small for it)".
    from types import SimpleNamespace

    from tghop.cli.common import layout_summary

    def model(shape, factor):
        return SimpleNamespace(exemplar_shape_=shape, layout_factor=3,
                               layout_=None if factor is None else SimpleNamespace(factor=factor, patch_size=32))

    assert layout_summary(model((200, 200, 3), 3)) == "a coarse model at 1/3 scale"
    assert layout_summary(model((200, 200, 3), 2)).endswith("(asked 3: too little of the exemplar lies outside "
                                                            "the mask for it)")
    assert layout_summary(model((120, 120, 3), 2)).endswith("(asked 3: the exemplar is too small for it)")
    assert layout_summary(model((200, 200, 3), None)) == "none (too little of the exemplar lies outside the mask " \
                                                          "for one)"
    assert layout_summary(model((80, 80, 3), None)) == "none (the exemplar is too small for one)"


@pytest.fixture(scope="module")
def grey_model(files, cells):
    path = files / "grey_model.npz"
    save_model(TGHop(rng=0, **FAST).fit(cells[..., :1]), path)
    return path


@pytest.mark.parametrize("kind", ["RGBA", "LA"])
@pytest.mark.parametrize("depth", [8, 16])
def test_cli_keeps_the_alpha_channel_outside_the_hole_and_makes_the_hole_opaque(files, cells, grey_model, kind,
                                                                              depth):
    # It said "Warning: ...: alpha channel dropped" and wrote RGB, though .png keeps every pixel outside the hole.
    from click.testing import CliRunner

    from tghop.cli import main
    from tghop.imageio import load_image

    colour = cells if kind == "RGBA" else cells[..., :1]
    alpha = ((np.arange(96)[:, None] * 3 + np.arange(96)) % 256).astype(np.uint8)[..., None]
    pixels = np.concatenate([colour, alpha], axis=2)
    if depth == 16:  # low bits an 8-bit file cannot hold (Pillow writes no 16-bit RGBA: tghop's writer)
        pixels = pixels.astype(np.uint16) * np.uint16(257) ^ np.uint16(5)
        save_image(pixels / 65535.0, files / "alpha.png", depth=16)
    else:
        Image.fromarray(pixels, kind).save(files / "alpha.png")
    source = files / "model.npz" if kind == "RGBA" else grey_model
    res = CliRunner().invoke(main, ["inpaint", str(files / "alpha.png"), str(files / "mask.png"), "-o",
                                    str(files / "alpha_out.png"), "--source", str(source), "--seed", "1", "-q",
                                    "--stages"])
    assert res.exit_code == 0 and "Warning" not in res.stderr, res.stderr
    out, out_depth = load_image(files / "alpha_out.png", dtype=None, with_depth=True, keep_alpha=True)
    out = np.round(out * 65535).astype(np.uint16) if depth == 16 else out
    hole = np.asarray(Image.open(files / "mask.png")) > 127
    assert out_depth == depth and out.shape == pixels.shape
    assert np.array_equal(out[~hole], pixels[~hole])  # every channel, alpha too, bit for bit
    assert (out[hole][:, -1] == (255 if depth == 8 else 65535)).all()  # the filled texture covers the hole
    assert not np.array_equal(out[hole][:, :-1], pixels[hole][:, :-1])
    # --stages' pictures keep the alpha channel as the output does (0.62; 0.61 wrote them without it)
    for step in ("quilt", "refine", "patch-refine"):
        staged = load_image(files / f"alpha_out_{step}.png", dtype=None, keep_alpha=True)
        staged = np.round(staged * 65535).astype(np.uint16) if depth == 16 else staged
        assert staged.shape == out.shape and np.array_equal(staged[..., -1], out[..., -1]), step


def test_cli_a_jpeg_output_drops_the_alpha_channel_with_a_warning(files, cells):
    from click.testing import CliRunner

    from tghop.cli import main

    alpha = np.full((96, 96, 1), 128, np.uint8)
    Image.fromarray(np.concatenate([cells, alpha], axis=2), "RGBA").save(files / "alpha8.png")
    res = CliRunner().invoke(main, ["inpaint", str(files / "alpha8.png"), str(files / "mask.png"), "-o",
                                    str(files / "alpha_out.jpg"), "--source", str(files / "model.npz"), "-q",
                                    "--stages"])
    assert res.exit_code == 0, res.stderr
    warning = [line for line in res.stderr.splitlines() if line.startswith("Warning:")]
    assert len(warning) == 1 and "alpha channel dropped (JPEG holds none" in warning[0]  # once, with --stages too
    assert Image.open(files / "alpha_out.jpg").mode == "RGB" and Image.open(files / "alpha_out_quilt.jpg").mode == "RGB"


@pytest.mark.parametrize("n", [32, 33, 64, 100, 256, 257, 1000])
def test_tiled_block_grid_is_even_around_the_torus(n):
    # With tile, the blocks wrap: every gap, the one across the edge too, at most a step and
    # within a pixel of the others (every step from 0 left a block across the edge overlapping
    # the first by up to p - 1 pixels, and the fill there was chopped).
    from tghop.hole_quilting import _grid

    p, step = 32, 27
    xs = _grid(n, p, step, tile=True)
    gaps = np.diff(np.append(xs, xs[0] + n))
    assert xs[0] == 0 and gaps.max() <= step and gaps.max() - gaps.min() <= 1, (xs, gaps)
    plain = _grid(n, p, step, tile=False)
    assert plain[0] == 0 and plain[-1] == n - p and np.diff(plain).max(initial=0) <= step


def test_blocks_that_see_no_known_pixel_are_filled_last():
    # A hole over a periodic image's left edge: the block at x=0 sees only hole; filled first
    # (at random), it set its neighbours, which do see the image, a second border to match.
    from tghop.hole_quilting import _fill_order

    hole = np.zeros((64, 256), dtype=bool)
    hole[:, :40] = True
    order = _fill_order(hole, 32, 27, tile=True)
    blind = [not (~hole[np.ix_(np.arange(y, y + 32) % 64, np.arange(x, x + 32) % 256)]).any() for y, x in order]
    assert any(blind) and blind == sorted(blind)  # every block that sees the image comes first
    assert {x for (_, x), b in zip(order, blind) if b} == {0}
    # a hole in the middle: from its edge inwards, as before
    hole = np.zeros((128, 128), dtype=bool)
    hole[40:90, 40:90] = True
    order = _fill_order(hole, 32, 27, tile=False)
    assert len(order) == len(set(order)) and not any(
        hole[y:y + 32, x:x + 32].all() for y, x in order[:4])


def test_a_float_sample_mask_excludes_above_one_half_as_a_hole_does():
    # A float mask excluded every pixel above 0: a grey picture's faint pixels took the whole image.
    from tghop.patches import check_exclude

    grey = np.full((8, 8), 0.3)
    grey[:2] = 0.7
    assert check_exclude(grey * 0 + 0.3, (8, 8)) is None
    np.testing.assert_array_equal(check_exclude(grey, (8, 8)), grey > 0.5)
    ones = np.zeros((8, 8), np.uint8)
    ones[3, 3] = 1  # 0/1 integers: the boolean mask
    np.testing.assert_array_equal(check_exclude(ones, (8, 8)), ones == 1)


def test_cli_a_source_exemplar_of_other_colours_is_refused_before_its_fit(files, monkeypatch):
    # A grey --source exemplar for a colour IMAGE (or the reverse) was fitted first, seconds to
    # minutes, and then refused as "the model is greyscale ...; fit the model on a colour exemplar".
    from tghop.synthesis import TGHop as Fitted

    def no_fit(*args, **kwargs):
        raise AssertionError("fitted before the channels were checked")

    monkeypatch.setattr(Fitted, "fit", no_fit)
    rng = np.random.default_rng(0)
    Image.fromarray((rng.random((96, 96)) * 255).astype(np.uint8)).save(files / "grey_source.png")
    r = run("inpaint", files / "cells.png", files / "mask.png", "-o", files / "g.png", "-q",
            "--source", files / "grey_source.png")
    assert_user_error(r, "--source", "grey_source.png", "is greyscale", "IMAGE", "cells.png", "has colour")
    Image.fromarray(np.asarray(Image.open(files / "cells.png").convert("L"))).save(files / "grey_cells.png")
    r = run("extend", files / "grey_cells.png", "-o", files / "g.png", "--size", "96x128", "-q",
            "--source", files / "cells.png")
    assert_user_error(r, "--source", "cells.png", "in colour", "IMAGE", "grey_cells.png", "is greyscale")
    r = run("inpaint", files / "grey_cells.png", files / "mask.png", "-o", files / "g.png", "-q",
            "--source", files / "model.npz")
    assert_user_error(r, "--source", "model.npz", "in colour", "IMAGE", "grey_cells.png", "is greyscale")
    assert not (files / "g.png").exists()


def test_cli_a_mask_whose_hole_is_most_of_the_image_warns_it_may_be_inverted(files):
    # A mask painted the other way round (what to keep white, the hole black) filled 86 % of the picture
    # without a word.
    inverted = np.full((96, 96), 255, np.uint8)
    inverted[20:80, 20:80] = 0
    Image.fromarray(inverted).save(files / "inverted.png")
    for mask, warned in (("inverted.png", True), ("mask.png", False)):
        r = run("inpaint", files / "cells.png", files / mask, "-o", files / "inv.png", "--source", files / "model.npz",
                "--seed", "1", "-q")
        assert r.returncode == 0, r.stderr.decode()
        lines = [line for line in r.stderr.decode().splitlines() if line.startswith("Warning")]
        assert lines == ([f"Warning: MASK {files / mask}: its white pixels, the hole that is filled, are 61% of IMAGE "
                          f"{files / 'cells.png'}; if you painted the part to keep white, invert the mask"]
                         if warned else []), r.stderr.decode()


def test_cli_a_picture_given_as_mask_is_warned_of_and_a_feathered_mask_is_not(files):
    # A photograph as MASK (or IMAGE and MASK swapped) had its light pixels filled, or was "leaves too little
    # ... paint a smaller hole", without a word that the mask was not a mask.
    save_image(data.bricks(96, rng=1), files / "photo.png")
    yy, xx = np.mgrid[:96, :96]
    feathered = np.clip((30 - np.hypot(yy - 48, xx - 48)) / 6 + 0.5, 0, 1)  # a 6 px soft edge
    save_image(feathered, files / "feathered.png")
    for mask, warned in (("photo.png", True), ("feathered.png", False)):
        r = run("inpaint", files / "cells.png", files / mask, "-o", files / "pic.png", "--source", files / "model.npz",
                "--seed", "1", "-q")
        assert r.returncode == 0, r.stderr.decode()
        lines = [line for line in r.stderr.decode().splitlines() if "not black and white" in line]
        assert lines == ([f"Warning: MASK {files / mask} is not black and white: 100% of its pixels are grey or "
                          "coloured (a picture?), and those lighter than mid-grey are taken as the hole; paint the "
                          "hole white on black (IMAGE comes first, then MASK)"] if warned else []), r.stderr.decode()
    r = run("fit", files / "cells.png", "--exclude", files / "photo.png", "-o", files / "pic.npz", "-q")
    assert "Warning: --exclude" in r.stderr.decode() and "taken as the part left out" in r.stderr.decode()
