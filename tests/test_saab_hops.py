import numpy as np
import pytest

from tghop import TGHopError
from tghop.hops import Hop, HopStack
from tghop.patches import count_patches, depth_to_space, extract_patches, space_to_depth
from tghop.saab import Saab, knee_point, select_channels
from tghop.sdr import _channel_major
from tghop import NotFittedError


def test_extract_patches_count_and_content(bricks96):
    p = extract_patches(bricks96, 32, stride=2)
    assert p.shape == (count_patches(bricks96.shape, 32, 2), 32, 32, 3) == (33 * 33, 32, 32, 3)
    assert np.array_equal(p[0], bricks96[:32, :32])
    assert np.array_equal(p[34], bricks96[2:34, 2:34])  # second row, second column
    assert extract_patches(np.zeros((256, 256, 3)), 32, stride=2).shape[0] == 12769  # the paper's count


def test_extract_patches_subsample_and_grey(bricks96):
    p = extract_patches(bricks96[..., 0], 32, stride=1, max_patches=100, rng=0)
    assert p.shape == (100, 32, 32, 1)
    q = extract_patches(bricks96[..., 0], 32, stride=1, max_patches=100, rng=0)
    assert np.array_equal(p, q)


def test_extract_patches_too_small():
    with pytest.raises(TGHopError, match="at least 32x32"):
        extract_patches(np.zeros((20, 40, 3)), 32)


def test_count_patches_of_an_image_smaller_than_the_patch_is_zero():
    assert count_patches((10, 10), 32, 2) == 0 and count_patches((10, 40), 32, 2) == 0
    assert count_patches((40, 10, 3), 32, 2) == 0 and count_patches((32, 33), 32, 2) == 1
    assert count_patches((256, 256), 32, 2) == 12769


@pytest.mark.parametrize("name, args, kwargs, message", [
    ("extract_patches", (32,), dict(max_patches=-1), "max_patches must be an integer >= 1, got -1"),
    ("extract_patches", (32,), dict(max_patches=0), "max_patches must be an integer >= 1, got 0"),
    ("extract_patches", (32,), dict(max_patches=2.5), "max_patches must be an integer >= 1, got 2.5"),
    ("extract_patches", (32,), dict(stride=1.5), "stride must be an integer >= 1, got 1.5"),
    ("extract_patches", (2.5,), {}, "patch_size must be an integer >= 2, got 2.5"),
    ("extract_patches", (1,), {}, "patch_size must be an integer >= 2, got 1"),
    ("patch_origins", ((96, 96, 3), 32), dict(stride=0), "stride must be an integer >= 1, got 0"),
    ("patch_origins", ((96, 96, 3), 32), dict(max_patches="9"), "max_patches must be an integer >= 1, got '9'"),
    ("count_patches", ((96, 96, 3), 32, 0), {}, "stride must be an integer >= 1, got 0"),
    ("downsample_mask", (np.zeros((8, 8), bool), 0), {}, "factor must be an integer >= 1, got 0"),
    ("patch_grid", (np.zeros((0, 8, 8, 3)),), {},
     r"patches must be a non-empty \(n, P, P\) or \(n, P, P, C\) array, got shape \(0, 8, 8, 3\)"),
    ("patch_grid", (np.zeros((2, 8, 8, 3)),), dict(gap=-1), "gap must be an integer >= 0, got -1"),
])
def test_patch_helpers_check_their_parameters(name, args, kwargs, message, bricks96):
    from tghop import patches

    if name == "extract_patches":
        args = (bricks96,) + args
    with pytest.raises(TGHopError, match=f"^{message}$"):
        getattr(patches, name)(*args, **kwargs)


def test_patch_helpers_keep_their_results_for_valid_parameters(bricks96):
    from tghop.patches import downsample_mask, patch_grid, patch_origins

    assert patch_origins(bricks96.shape, 32, stride=np.int64(4), max_patches=np.int64(10), rng=0).shape == (10, 2)
    assert patch_origins((10, 10), 32).shape == (0, 2)
    assert downsample_mask(np.eye(8, dtype=bool), 2).tolist() == np.eye(4, dtype=bool).tolist()
    assert patch_grid(np.zeros((3, 4, 4)), gap=0).shape == (8, 8, 1)


def test_space_to_depth_roundtrip(rng):
    x = rng.random((3, 8, 6, 5))
    y = space_to_depth(x)
    assert y.shape == (3, 4, 3, 20)
    assert np.array_equal(y[0, 1, 2, :5], x[0, 2, 4])  # block (1, 2), top-left pixel
    assert np.array_equal(depth_to_space(y), x)


def test_saab_exact_inverse_and_orthonormal(rng):
    x = rng.random((500, 12))
    s = Saab().fit(x)
    assert s.kernels_.shape == (12, 12)
    np.testing.assert_allclose(s.kernels_ @ s.kernels_.T, np.eye(12), atol=1e-12)
    np.testing.assert_allclose(s.kernels_[0], np.full(12, 1 / np.sqrt(12)))
    np.testing.assert_allclose(s.inverse_transform(s.transform(x)), x, atol=1e-10)
    assert np.all(s.transform(x)[:, 1:] >= 0)  # the adjusted bias makes AC responses non-negative


def test_saab_energy_order_and_meaning(rng):
    x = rng.random((800, 12)) * np.linspace(2, 0.1, 12)
    s = Saab().fit(x)
    assert np.all(np.diff(s.energy_[1:]) <= 1e-12)  # AC by decreasing energy
    y = s.transform(x) - s._ac_bias()
    np.testing.assert_allclose(np.mean(y**2, axis=0), s.energy_[s.channels_], rtol=1e-9)
    # Dropping channel j costs exactly its energy in mean squared error.
    part = Saab(n_components=6).fit(x)
    err = np.mean(np.sum((part.inverse_transform(part.transform(x)) - x) ** 2, axis=1))
    assert err == pytest.approx(s.energy_[6:].sum(), rel=1e-9)


def test_saab_deterministic_signs(rng):
    x = rng.random((300, 12))
    a = Saab().fit(x).kernels_
    b = Saab().fit(x[::-1].copy()).kernels_  # same data, other order
    np.testing.assert_allclose(a, b, atol=1e-10)


def test_saab_rank_deficient_grey_as_rgb(rng):
    grey = rng.random((400, 4))
    x = np.repeat(grey, 3, axis=1)  # a grey image stored as RGB: 8 of 12 directions are empty
    s = Saab(n_components=10).fit(x)
    assert len(s.channels_) == 4  # empty channels are never kept
    np.testing.assert_allclose(s.inverse_transform(s.transform(x)), x, atol=1e-10)


def test_saab_not_fitted():
    with pytest.raises(NotFittedError):
        Saab().transform(np.zeros((2, 4)))


def test_select_channels_rules():
    e = np.array([5.0, 3.0, 1.0, 0.5, 0.0])
    assert select_channels(e, 3, n_fixed=1).tolist() == [0, 1]
    assert select_channels(e, None).tolist() == [0, 1, 2, 3]  # the empty channel is dropped
    assert select_channels(e, 0.85).tolist() == [0, 1, 2]  # 9/9.5 >= 0.85 > 8/9.5
    assert knee_point([100, 10, 1, 0.9, 0.8, 0.7]) == 3
    with pytest.raises(TGHopError):
        select_channels(e, 0)
    with pytest.raises(TGHopError):
        select_channels(e, "elbow")


@pytest.mark.parametrize("channels", [(None, None), (None, None, None)])
def test_hop_stack_exact_inverse_all_channels(bricks96, channels):
    p = extract_patches(bricks96, 32, stride=8)
    stack = HopStack(n_channels=channels).fit(p)
    core = stack.transform(p)
    assert core.shape[1] == 32 // 2 ** len(channels)
    np.testing.assert_allclose(stack.inverse_transform(core), p, atol=1e-10)


def test_hop_stack_dims_and_channel_record(bricks96):
    p = extract_patches(bricks96, 32, stride=4)
    stack = HopStack(n_channels=(9, 22)).fit(p)
    assert stack.dims_ == [3072, 16 * 16 * 9, 8 * 8 * 22]
    hop2 = stack.hops_[1]
    assert hop2.channels_.shape == (22, 2)
    # Every parent keeps its DC child; channels are grouped by parent.
    assert set(hop2.channels_[hop2.channels_[:, 1] == 0, 0]) == set(range(9))
    assert np.all(np.diff(hop2.channels_[:, 0]) >= 0)
    # The kept AC children are the strongest ones over all parents.
    kept = {tuple(c) for c in hop2.channels_ if c[1] > 0}
    all_ac = [(k, j, s.energy_[j]) for k, s in enumerate(hop2.saabs_) for j in range(1, 4)]
    dropped = [e for k, j, e in all_ac if (k, j) not in kept]
    kept_e = [e for k, j, e in all_ac if (k, j) in kept]
    assert min(kept_e) >= max(dropped)


def test_discarded_channels_are_zero_on_the_way_back(bricks96):
    p = extract_patches(bricks96, 32, stride=8)
    hop = Hop(n_channels=4).fit(p)
    full = Hop().fit(p)
    y = full.transform(p)
    y[..., 4:] = full.bias_[4:]  # response zero (bias only) in the dropped channels
    np.testing.assert_allclose(hop.inverse_transform(hop.transform(p)), full.inverse_transform(y), atol=1e-10)


def test_hop_channel_limits(bricks96):
    p = extract_patches(bricks96, 32, stride=8)
    with pytest.raises(TGHopError, match="K1.*at most 12"):
        HopStack(n_channels=(13, 22)).fit(p)
    with pytest.raises(TGHopError, match="K2.*at least 9"):
        HopStack(n_channels=(9, 5)).fit(p)


def test_knee_selection_is_texture_dependent(bricks96):
    p = extract_patches(bricks96, 32, stride=4)
    stack = HopStack(n_channels=("knee", "knee")).fit(p)
    k1, k2 = (h.n_channels_out_ for h in stack.hops_)
    assert 2 <= k1 <= 12 and k1 <= k2 <= 4 * k1


@pytest.mark.parametrize("stride, channels, size, tile", [(2, (9, 22), 32, 1024), (3, (6, 14), 32, 1024),
                                                         (4, (9, 22, 40), 64, 1024), (2, (9, 22), 32, 20),
                                                         (3, (6, 14), 32, 40), (4, (9, 22, 40), 64, 8)])
def test_fit_image_equals_fit_on_cut_patches(stride, channels, size, tile):
    """The phase-map shortcut gives exactly the patch-based fit and core, whole or in tiles."""
    from tghop.data import bricks
    from tghop.patches import patch_origins

    img = bricks(128, rng=5)
    origins = patch_origins(img.shape, size, stride=stride, max_patches=1500, rng=1)
    patches = extract_patches(img, size, stride=stride, max_patches=1500, rng=1)
    a = HopStack(n_channels=channels)
    core_a = a.fit_transform(patches)
    b = HopStack(n_channels=channels)
    core_b = b.fit_image(img, size, origins, tile=tile)
    assert a.dims_ == b.dims_
    for ha, hb in zip(a.hops_, b.hops_):
        assert np.array_equal(ha.channels_, hb.channels_)
        np.testing.assert_allclose(ha.kernels_, hb.kernels_, atol=1e-8)
        np.testing.assert_allclose(ha.bias_, hb.bias_, rtol=1e-12)
    np.testing.assert_allclose(core_a, core_b, atol=1e-8)
    # The core is held channel-major, so SDR reads each channel's maps without another copy.
    maps = _channel_major(core_b)
    assert np.shares_memory(maps, core_b)
    assert np.array_equal(maps, _channel_major(np.ascontiguousarray(core_b)))
    if tile == 1024:  # a uint8 image gives the fit of its float version
        img8 = np.round(img * 255).astype(np.uint8)
        c = HopStack(n_channels=channels)
        core_c = c.fit_image(img8, size, origins, tile=tile // 16)
        d = HopStack(n_channels=channels)
        np.testing.assert_allclose(core_c, d.fit_image(img8 / 255.0, size, origins), atol=1e-8)


def test_hop_channel_errors_count_in_the_singular_too():
    # A grey exemplar's first hop has one input channel ("a hop on 1 input channels").
    from tghop import TGHop, data

    grey = data.cells(64, rng=1)[..., :1]
    with pytest.raises(TGHopError, match="a hop on 1 input channel has at most 4 channels, 5 were asked for"):
        Hop(n_channels=5).fit(np.random.default_rng(0).random((20, 8, 8, 1)))
    with pytest.raises(TGHopError, match="hop 1 of an exemplar of 1 channel has 4"):  # TGHop says it before any work
        TGHop(n_channels=(5, 10), n_clusters=5, max_patches=200, layout_factor=None, rng=0).fit(grey)
    with pytest.raises(TGHopError, match="1 hop needs a patch size divisible by 2"):
        TGHop(n_channels=(4,), patch_size=5, rng=0).fit(grey)


# ------------------------------------------------------------------ input checks
@pytest.fixture(scope="module")
def small_patches(bricks96):
    return extract_patches(bricks96, 32, stride=8)


def _nan(a, value=np.nan):
    a = np.array(a, dtype=np.float64)
    a.flat[0] = value
    return a


@pytest.mark.parametrize("call, message", [
    (lambda p: Saab().fit(_nan(p.reshape(len(p), -1)[:, :12])), "X contains NaN or infinite values"),
    (lambda p: Saab().fit(_nan(p.reshape(len(p), -1)[:, :12], np.inf)), "X contains NaN or infinite values"),
    (lambda p: Hop().fit(p[:0]), r"X must have at least 1 row"),
    (lambda p: HopStack().fit(p[:0]), r"X must have at least 1 row"),
    (lambda p: Hop().fit(_nan(p)), "X contains NaN or infinite values"),
    (lambda p: HopStack().fit(_nan(p)), "X contains NaN or infinite values"),
    (lambda p: HopStack().fit(np.zeros(5)), r"X must have shape \(n_patches, P, P, C\), got \(5,\)"),
    (lambda p: HopStack(n_channels=9).fit(p), r"n_channels must be a sequence of one rule per hop.*got 9"),
    (lambda p: HopStack(n_channels=()).fit(p), "n_channels must name at least one hop"),
    (lambda p: HopStack(n_channels=(0, 22)).fit(p), "n_channels: K1 must be at least 1"),
    (lambda p: Hop(n_channels=0).fit(p), "n_channels must be at least 1"),
    (lambda p: Hop().fit_sums((np.zeros(4), np.zeros((4, 4)), np.zeros(1), 0.0)), "at least one block of weight > 0"),
    (lambda p: Saab(n_components=100).fit(p.reshape(len(p), -1)[:, :12]),
     r"at most 12 components, got n_components=100; choose at most 12"),
    (lambda p: Saab(n_components=0).fit(p.reshape(len(p), -1)[:, :12]), "n_components must be at least 1"),
    # complex numbers lost their imaginary parts with a NumPy warning; a sparse matrix was "not an array"
    (lambda p: Saab().fit(p.reshape(len(p), -1)[:, :12] + 1j), r"^X holds complex numbers; give real ones"),
    (lambda p: Hop().fit(p.astype(complex)), r"^X holds complex numbers"),
    (lambda p: Saab().fit(__import__("scipy.sparse").sparse.csr_matrix(p.reshape(len(p), -1)[:, :12])),
     r"^X is a sparse csr_matrix; give a dense array of shape \(n_samples, d\) \(X.toarray\(\)\)"),
])
def test_saab_and_hops_refuse_bad_input_with_one_line_errors(small_patches, call, message):
    with pytest.raises(TGHopError, match=message) as info:
        call(small_patches)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("max_sq_norm", [True, np.bool_(True), -1.0, np.inf, np.nan, "4", None])
def test_saab_from_moments_refuses_a_largest_norm_that_is_not_a_finite_number(max_sq_norm):
    mean, second = np.zeros(4), np.eye(4)
    with pytest.raises(TGHopError, match=r"^max_sq_norm must be a finite number >= 0, got "):
        Saab().fit_moments(mean, second, max_sq_norm)
    assert Saab().fit_moments(mean, second, np.float32(4.0)).bias_ == 2.0


def test_saab_transforms_check_the_fitted_width(rng):
    X = rng.random((200, 12))
    s = Saab().fit(X)
    Y = s.transform(X)
    with pytest.raises(TGHopError, match=r"X must have shape \(n, d\) = \(n, 12\) for this fitted model, got \(200, 5"):
        s.transform(X[:, :5])
    with pytest.raises(TGHopError, match=r"Y must have shape \(n, k\) = \(n, 12\).*got \(200, 3\)"):
        s.inverse_transform(Y[:, :3])
    with pytest.raises(TGHopError, match="X must have shape"):
        s.transform(X[0])


def test_a_failed_fit_leaves_saab_hop_and_stack_unfitted(small_patches, rng):
    X = rng.random((200, 12))
    s = Saab().fit(X)
    with pytest.raises(TGHopError):
        s.set_params(n_components=100).fit(X)
    with pytest.raises(NotFittedError):
        s.transform(X)
    stack = HopStack(n_channels=(9, 22)).fit(small_patches)
    with pytest.raises(TGHopError, match="K2.*at least 9"):
        stack.set_params(n_channels=(9, 5)).fit(small_patches)
    with pytest.raises(NotFittedError):
        stack.transform(small_patches)
    hop = Hop(n_channels=4, channelwise=True).fit(small_patches)
    with pytest.raises(TGHopError, match="keeps at least 3"):
        hop.set_params(n_channels=2).fit(small_patches)
    with pytest.raises(NotFittedError):
        hop.transform(small_patches)


def test_a_fitted_stack_keeps_no_training_output(bricks96):
    import pickle

    p = extract_patches(bricks96, 32, stride=4)
    stack = HopStack().fit(p)
    assert not [name for name in vars(stack) if name.startswith("_fit")]
    assert len(pickle.dumps(stack)) < p.nbytes // 20  # the hops only, not the patches' core responses
    core = HopStack().fit_transform(p)
    assert np.array_equal(core, stack.transform(p))


@pytest.mark.parametrize("image, origins, error, message", [
    (lambda img: img * 255, [[0, 0]], "image", r"image values must lie in \[0, 1\], got \[0, 2"),
    (lambda img: _nan(img), [[0, 0]], "image", "image contains NaN or infinite values"),
    (lambda img: img[..., 0], [[0, 0]], "image",
     r"^HopStack.fit_image: image must be an \(H, W, C\) float array in \[0, 1\] or uint8, got float64 of shape "
     r"\(96, 96\)$"),
    (lambda img: img.astype(np.int32), [[0, 0]], "image", r"image must be an \(H, W, C\) float array in \[0, 1\] or "
     "uint8, got int32"),
    (lambda img: img.astype(np.uint16), [[0, 0]], "image", "or uint8, got uint16 of shape"),
    (lambda img: img[:0], [[0, 0]], "image", r"^HopStack.fit_image: the image is empty \(shape \(0, 96, 3\)\)"),
    (lambda img: img, [[90, 90]], "origins", r"origins must put every 32x32 patch inside the 96x96 image "
     r"\(rows in \[0, 64\], columns in \[0, 64\]\), got rows in \[90, 90\]"),
    (lambda img: img, [[-4, 0]], "origins", "origins must put every 32x32 patch inside"),
    (lambda img: img, np.zeros((0, 2), int), "origins", r"origins must have shape \(n, 2\), n >= 1"),
    (lambda img: img, [[0.5, 0]], "origins", "origins must be integers"),
])
def test_fit_image_checks_image_and_origins(bricks96, image, origins, error, message):
    from tghop import InvalidImageError

    kind = InvalidImageError if error == "image" else TGHopError
    stack = HopStack()
    with pytest.raises(kind, match=message):
        stack.fit_image(image(bricks96), 32, np.asarray(origins))
    with pytest.raises(NotFittedError):
        stack.transform(extract_patches(bricks96, 32, stride=32))


def test_saab_transform_refuses_what_is_not_finite_numbers(rng):
    # Strings reached NumPy's ValueError, and NaN went through to a NaN response (ICHM and
    # SpatialReduction refused both).
    saab = Saab().fit(rng.random((50, 12)))
    for bad, message in (([["a"] * 12], r"^X must be an array of numbers"), (np.full((2, 12), np.nan), "NaN")):
        with pytest.raises(TGHopError, match=message):
            saab.transform(bad)
    with pytest.raises(TGHopError, match="NaN"):
        saab.inverse_transform(np.full((2, len(saab.channels_)), np.inf))
    assert saab.transform(np.zeros((0, 12))).shape == (0, len(saab.channels_))


def test_hop_transforms_refuse_what_is_not_finite_numbers(small_patches):
    # A NaN went through a hop and its inverse to NaN responses and patches without a word.
    hop = Hop().fit(small_patches)
    core = hop.transform(small_patches[:2])
    for call, arg, name in ((hop.transform, small_patches[:2], "X"), (hop.inverse_transform, core, "Y")):
        with pytest.raises(TGHopError, match=rf"^{name} contains NaN or infinite values"):
            call(_nan(arg))
        with pytest.raises(TGHopError, match=rf"^{name} must be an array of numbers"):
            call(np.full(arg.shape, "a"))
    stack = HopStack().fit(small_patches)
    with pytest.raises(TGHopError, match=r"^Y contains NaN"):
        stack.inverse_transform(_nan(stack.transform(small_patches[:2])))
    assert hop.transform(small_patches[:0]).shape == (0,) + core.shape[1:]


def test_hop_stack_transforms_refuse_complex_and_sparse_input_in_one_line(small_patches):
    # HopStack's transform and inverse_transform read X with numpy.asarray: complex numbers lost their
    # imaginary parts with only NumPy's ComplexWarning (Saab and Hop refuse them).
    stack = HopStack().fit(small_patches)
    core = stack.transform(small_patches[:2])
    for call, arg, name in ((stack.transform, small_patches[:2], "X"), (stack.inverse_transform, core, "Y")):
        with pytest.raises(TGHopError, match=rf"^{name} holds complex numbers") as info:
            call(arg + 1j)
        assert "\n" not in str(info.value)
        with pytest.raises(TGHopError, match=rf"^{name} must be an array of numbers"):
            call(np.full(arg.shape, "a"))
    with pytest.raises(TGHopError, match=r"^X must have shape \(n, P, P, 3\), got \(32, 32, 3\)"):
        stack.transform(small_patches[0])
    np.testing.assert_array_equal(stack.transform(small_patches[:2].tolist()), core)
