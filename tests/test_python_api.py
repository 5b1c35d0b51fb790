"""The library as a Python user in a script or a notebook meets it (0.57): what a slip of theirs is told."""

import pathlib

import numpy as np
import pytest

import tghop
from tghop import metrics
from tghop.inpaint import extend, inpaint
from tghop.material import Material


@pytest.mark.parametrize("call, name", [
    (lambda m, b, hole: tghop.TGHop().fit("texture.png"), "exemplar"),
    (lambda m, b, hole: tghop.TGHop().fit(pathlib.Path("texture.png")), "exemplar"),
    (lambda m, b, hole: inpaint(m, "texture.png", hole), "the image"),
    (lambda m, b, hole: inpaint(m, b, "texture.png"), "the mask"),
    (lambda m, b, hole: extend(m, "texture.png", (96, 160)), "the image"),
    (lambda m, b, hole: tghop.synthesize_guided([m, m], "texture.png"), "the guide"),
    (lambda m, b, hole: metrics.sliced_wasserstein(b, "texture.png"), "result"),
    (lambda m, b, hole: Material().fit(b, {"height": "texture.png"}), "map 'height'"),
])
def test_a_file_name_where_an_image_belongs_is_told_to_read_it_first(call, name, small_model, bricks96):
    # NumPy reads a name as a 0-d array of text: 0.56 said "must have shape (H, W) ..., got ()" or
    # "the mask must be numbers or booleans, got dtype <U11".
    hole = np.zeros(bricks96.shape[:2], dtype=bool)
    hole[30:60, 30:60] = True
    with pytest.raises(tghop.InvalidImageError) as caught:
        call(small_model, bricks96, hole)
    assert str(caught.value) == (f"{name} is a file name ('texture.png'), not an image array; read it first: "
                                 "tghop.imageio.load_image(path)")


def test_tghops_warnings_are_told_at_the_callers_line(small_model, bricks96):
    # 0.56 told these at guides.py and core.py, the library's own lines: a notebook showed tghop's source
    # line under the warning, and filterwarnings(module=...) of the caller's module missed them.
    import warnings

    from conftest import SMALL

    guide = np.zeros((33, 33))
    guide[:, 16:] = 1
    picky = tghop.TGHop(**{**SMALL, "reject_threshold": 50.0}).fit(bricks96)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tghop.synthesize_guided([small_model, small_model], guide, size=(48, 48), rng=0, refine=0, patch_refine=0)
        picky.sample_patches(4, rng=0)
    assert [str(w.message)[:24] for w in caught] == ["the guide was scaled fro", "ICHM: 4 samples still ha"]
    assert [w.filename for w in caught] == [__file__, __file__]
    with warnings.catch_warnings():
        warnings.filterwarnings("error", module=__name__)
        with pytest.raises(UserWarning, match="samples still have no component"):
            picky.sample_patches(4, rng=0)


def test_inpaint_takes_nan_in_the_hole_and_refuses_it_elsewhere(small_model, bricks96):
    # image[mask] = np.nan is how a NumPy user marks a hole; 0.56 refused it ("contains NaN or
    # infinite values; clean it first"), though the hole's values are never read.
    hole = np.zeros(bricks96.shape[:2], dtype=bool)
    hole[30:60, 25:70] = True
    marked = bricks96.astype(np.float32)
    marked[hole] = np.nan
    marked[hole.nonzero()[0][0], hole.nonzero()[1][0], 1] = np.inf
    plain = inpaint(small_model, bricks96.astype(np.float32), hole, rng=0, n_patches=300)
    filled = inpaint(small_model, marked, hole, rng=0, n_patches=300)
    np.testing.assert_array_equal(filled, plain)
    assert not np.isfinite(marked[hole]).any()  # the caller's image untouched
    marked[0, 0, 0] = np.nan  # outside the hole: still refused
    with pytest.raises(tghop.InvalidImageError, match="contains NaN or infinite values"):
        inpaint(small_model, marked, hole, rng=0, n_patches=300)


def _rgba(image, alpha_value=None):
    """``image`` (uint8 RGB) with an alpha channel: a ramp (partly transparent), or ``alpha_value`` everywhere."""
    h, w = image.shape[:2]
    alpha = ((np.arange(h)[:, None] * 3 + np.arange(w)) % 256).astype(np.uint8) if alpha_value in (None, "ramp") else \
        np.full((h, w), alpha_value, dtype=np.uint8)
    return np.concatenate([image, alpha[..., None]], axis=2)


def test_inpaint_and_extend_keep_an_arrays_alpha_as_tghop_inpaint_keeps_a_files(small_model, bricks96):
    # 0.58 refused an RGBA array ("drop its alpha channel first") where fit drops one with a warning and
    # tghop inpaint keeps a file's: the one rule now (0.59): the colours filled, the alpha kept outside the
    # hole, opaque in it (extend: where the image grew).
    rgb = np.round(bricks96 * 255).astype(np.uint8)
    image = _rgba(rgb)
    hole = np.zeros(rgb.shape[:2], dtype=bool)
    hole[30:60, 25:70] = True
    filled = inpaint(small_model, image, hole, rng=0, n_patches=300)
    assert filled.shape == image.shape and filled.dtype == np.uint8
    np.testing.assert_array_equal(filled[..., :3], inpaint(small_model, rgb, hole, rng=0, n_patches=300))
    np.testing.assert_array_equal(filled[~hole][:, 3], image[~hole][:, 3])
    assert (filled[hole][:, 3] == 255).all()
    grown = extend(small_model, image, (96, 128), rng=0, n_patches=300)
    assert grown.shape == (96, 128, 4)
    np.testing.assert_array_equal(grown[..., :3], extend(small_model, rgb, (96, 128), rng=0, n_patches=300))
    np.testing.assert_array_equal(grown[:, 16:112, 3], image[..., 3])
    assert (grown[:, :16, 3] == 255).all() and (grown[:, 112:, 3] == 255).all()
    with pytest.raises(tghop.TGHopError) as caught:  # still refused: 5 channels, grey+alpha to a colour model
        inpaint(small_model, np.ones(rgb.shape[:2] + (5,)), hole)
    assert str(caught.value).endswith("got (96, 96, 5); convert it to greyscale or RGB first")
    with pytest.raises(tghop.TGHopError, match="^the model is in colour but the image is greyscale"):
        inpaint(small_model, image[..., 2:], hole)


@pytest.mark.parametrize("where", ["Material.fit", "synthesize_guided", "metrics"])
def test_an_arrays_alpha_is_dropped_with_fits_warnings_wherever_an_image_enters(where, small_model, bricks96):
    # 0.58: fit dropped an RGBA array's alpha with a warning, but Material.fit and the metrics refused one ("must
    # have shape ... (H, W, 3)") and synthesize_guided read a guide's alpha as a colour of its own. Now each drops
    # it as fit does: OpaqueAlphaWarning, or TransparencyWarning with its share, naming the image; the same result.
    import warnings

    rgb = np.round(bricks96 * 255).astype(np.uint8)
    guide = np.zeros((48, 48, 3), dtype=np.uint8)
    guide[:, 24:] = 255

    def run(alpha):
        if where == "Material.fit":
            given = rgb if alpha is None else _rgba(rgb, alpha)
            mat = Material(model=tghop.TGHop(**{**SMALL, "layout_factor": None})).fit(given, {"height": rgb[..., :1]})
            return mat.synthesize((40, 40), rng=1)["albedo"]
        if where == "synthesize_guided":
            given = guide if alpha is None else _rgba(guide, alpha)
            return tghop.synthesize_guided([small_model, small_model], given, rng=0, refine=0, patch_refine=0)
        given = rgb if alpha is None else _rgba(rgb, alpha)
        return metrics.sliced_wasserstein(given, rgb[::-1], seed=0)

    from conftest import SMALL

    plain = run(None)
    name = {"Material.fit": "albedo", "synthesize_guided": "the guide", "metrics": "exemplar"}[where]
    for alpha, category in [(255, tghop.OpaqueAlphaWarning), ("ramp", tghop.TransparencyWarning)]:
        if where == "synthesize_guided" and alpha == "ramp":
            alpha = 0  # a guide's alpha ramp would be two colours' worth of regions: transparent everywhere
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            got = run(alpha)
        said = [w for w in caught if issubclass(w.category, (tghop.OpaqueAlphaWarning, tghop.TransparencyWarning))]
        assert len(said) == 1 and issubclass(said[0].category, category), [str(w.message) for w in caught]
        assert str(said[0].message).startswith(f"{name}: alpha channel dropped (an array of 4 channels is read as RGBA")
        assert said[0].filename == __file__
        np.testing.assert_array_equal(got, plain)


@pytest.mark.parametrize("call", [
    lambda m, b, hole, p: tghop.TGHop(n_clusters=4).fit(b, progress=p),
    lambda m, b, hole, p: m.synthesize((48, 48), rng=0, progress=p),
    lambda m, b, hole, p: inpaint(m, b, hole, rng=0, progress=p),
    lambda m, b, hole, p: extend(m, b, (96, 128), rng=0, progress=p),
    lambda m, b, hole, p: tghop.synthesize_guided([m, m], size=(48, 48), rng=0, progress=p),
    lambda m, b, hole, p: tghop.morph(m, m, (48, 96), rng=0, progress=p),
    lambda m, b, hole, p: Material().fit(b, {"height": b[..., :1]}, progress=p),
], ids=["fit", "synthesize", "inpaint", "extend", "synthesize_guided", "morph", "Material.fit"])
def test_a_progress_callback_of_the_wrong_arguments_is_refused_before_any_work(call, small_model, bricks96):
    # 0.56 let Python's own TypeError ("<lambda>() takes 2 positional arguments but 3 were given") out of
    # the first report, deep in tghop, after the work before it.
    hole = np.zeros(bricks96.shape[:2], dtype=bool)
    hole[30:60, 30:60] = True
    calls = []

    def two(stage, done):
        calls.append(stage)

    with pytest.raises(TypeError) as caught:
        call(small_model, bricks96, hole, two)
    assert str(caught.value) == ("progress must take three arguments, progress(stage, done, total); "
                                 "two(stage, done) does not")
    assert calls == []


def test_a_progress_callback_of_star_args_or_defaults_is_taken(small_model):
    seen = []
    small_model.synthesize((32, 32), rng=0, progress=lambda *args: seen.append(args))
    small_model.synthesize((32, 32), rng=0, progress=lambda stage, done, total, extra=None: seen.append(stage))
    assert {len(args) for args in seen if isinstance(args, tuple)} == {3}
    assert any(isinstance(stage, str) for stage in seen)


@pytest.mark.parametrize("dtype", [np.float64, np.uint8])
def test_an_rgba_exemplar_loses_its_alpha_as_tghop_fit_reads_a_png_with_alpha(dtype, small_model, bricks96):
    # 0.57 learnt an RGBA array's alpha as a fourth colour channel, without a word, where the command line
    # drops it (OpaqueAlphaWarning, TransparencyWarning): an (H, W, 4) array is now read as the CLI reads the file.
    import warnings

    from conftest import SMALL

    from tghop.imageio import to_uint8

    rgb = bricks96 if dtype == np.float64 else to_uint8(bricks96).reshape(bricks96.shape)
    opaque = np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 1 if dtype == np.float64 else 255, dtype)], axis=2)
    with pytest.warns(tghop.OpaqueAlphaWarning, match=r"^exemplar: alpha channel dropped \(an array of 4 channels is "
                                                      r"read as RGBA; stacked=True models every channel\)$"):
        model = tghop.TGHop(**SMALL).fit(opaque)
    plain = small_model if dtype == np.float64 else tghop.TGHop(**SMALL).fit(rgb)
    assert model.exemplar_shape_ == (96, 96, 3) and model.exemplar_depth_ == plain.exemplar_depth_
    assert all(np.array_equal(a, plain._to_arrays()[k]) for k, a in model._to_arrays().items())
    holed = opaque.copy()
    holed[:48, :, 3] = 0  # half of it transparent
    with pytest.warns(tghop.TransparencyWarning, match=r"though 50% of its pixels are transparent: .* leave that "
                                                       rf"part out with exclude=image\[\.\.\., -1\] < "
                                                       rf"{0.5 if dtype == np.float64 else 128}$") as caught:
        tghop.TGHop(**{**SMALL, "layout_factor": None}).fit(holed)
    assert caught[0].message.share == 0.5 and caught[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stacked = tghop.TGHop(**{**SMALL, "layout_factor": None}).fit(opaque, stacked=True)  # as 0.57: 4 channels
    assert stacked.exemplar_shape_ == (96, 96, 4)


def test_a_grey_and_alpha_exemplar_is_grey_and_a_materials_two_channels_stay(bricks96):
    import warnings

    from conftest import SMALL

    grey = bricks96.mean(axis=2)
    with pytest.warns(tghop.OpaqueAlphaWarning, match=r"an array of 2 channels is read as grey\+alpha"):
        model = tghop.TGHop(**{**SMALL, "n_channels": None, "layout_factor": None}).fit(
            np.stack([grey, np.ones_like(grey)], axis=2))
    assert model.exemplar_shape_ == (96, 96, 1)
    with warnings.catch_warnings():  # a grey albedo and a grey map: two channels of data, no alpha
        warnings.simplefilter("error")
        mat = Material(tghop.TGHop(**{**SMALL, "n_channels": None})).fit(grey, {"height": bricks96[..., 0]})
    assert mat.model_.exemplar_shape_ == (96, 96, 2) and mat.model_.layout_.model_.exemplar_shape_[2] == 2


def test_inpaint_material_keeps_an_albedos_alpha_as_inpaint_does(bricks96):
    # 0.58: "map albedo: image must have shape ...; drop its alpha channel first"; tghop inpaint --maps keeps it.
    from conftest import SMALL
    from tghop.inpaint import inpaint_material

    rgb = np.round(bricks96 * 255).astype(np.uint8)
    height = rgb[..., :1]
    mat = Material(model=tghop.TGHop(**{**SMALL, "layout_factor": None})).fit(rgb, {"height": height})
    hole = np.zeros(rgb.shape[:2], dtype=bool)
    hole[30:60, 25:70] = True
    image = _rgba(rgb)
    filled = inpaint_material(mat, {"albedo": image, "height": height}, hole, rng=0, n_patches=300)
    plain = inpaint_material(mat, {"albedo": rgb, "height": height}, hole, rng=0, n_patches=300)
    assert filled["albedo"].shape == image.shape
    np.testing.assert_array_equal(filled["albedo"][..., :3], plain["albedo"])
    np.testing.assert_array_equal(filled["height"], plain["height"])
    np.testing.assert_array_equal(filled["albedo"][~hole][:, 3], image[~hole][:, 3])
    assert (filled["albedo"][hole][:, 3] == 255).all()
