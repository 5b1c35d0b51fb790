"""How 8-bit and 16-bit levels become floats in [0, 1] (``_arrays.from_levels``), the one
rule behind ``check_image``, the quilting pool's check and ``TGHop.encode``."""

import numpy as np
import pytest

from tghop._arrays import from_levels
from tghop._images import check_image


@pytest.mark.parametrize("dtype, full", [(np.uint8, 255), (np.uint16, 65535)])
@pytest.mark.parametrize("out", [np.float64, np.float32])
def test_levels_are_divided_by_their_full_scale(dtype, full, out):
    levels = np.array([[0, 1, full // 2, full]], dtype=dtype)
    floats = from_levels(levels, out)
    assert floats.dtype == out and floats.shape == levels.shape
    assert floats[0, 0] == 0 and floats[0, -1] == 1
    np.testing.assert_array_equal(floats, levels.astype(out) / out(full))


@pytest.mark.parametrize("arr", [np.array([0.25, 1.0]), np.array([0.5], np.float32), np.array([3, 200], np.int32),
                                 np.array([True, False])])
def test_other_arrays_are_returned_as_they_are(arr):
    assert from_levels(arr) is arr  # an int32 array is not read as levels: the caller's checks refuse it


def test_check_image_reads_16_bit_levels_as_from_levels():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 65536, size=(40, 40, 3), dtype=np.uint16)
    np.testing.assert_array_equal(check_image(img, min_size=8), from_levels(img))
    np.testing.assert_array_equal(check_image(img, min_size=8, dtype=np.float32), from_levels(img, np.float32))
