"""Image conversion for writing."""

import numpy as np

from tghop.imageio import to_uint8


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
