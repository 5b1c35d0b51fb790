"""tghop.period: a picture's strongest repeat, and the band a hole's block is matched on (0.62)."""

import numpy as np

from tghop import data
from tghop.period import REGULAR, match_band, repeat


def test_a_repeat_is_found_at_its_period_not_its_multiples():
    columns = np.tile(np.repeat([0.2, 0.8], 9), 8)[:128]  # a period of 18 columns; peaks at 18, 36 and 54 too
    image = np.repeat(columns[None, :, None], 96, axis=0)
    strength, lag = repeat(image, np.zeros((96, 128), bool), 32)
    assert strength > 0.95 and lag == 18


def test_the_hole_is_not_read():
    rows = np.where(np.arange(128) % 20 < 4, 0.1, 0.6)[:, None, None].repeat(128, axis=1)
    hole = np.zeros((128, 128), bool)
    hole[40:90, 30:100] = True
    noisy = rows.copy()
    noisy[hole] = np.random.default_rng(0).random(int(hole.sum()))[:, None]
    assert repeat(noisy, hole, 32)[1] == 20
    assert match_band(noisy, hole, 5, 32) == 20


def test_irregular_pictures_and_too_few_pixels_keep_the_overlap():
    rng = np.random.default_rng(1)
    noise = rng.random((128, 128, 3))
    hole = np.zeros((128, 128), bool)
    hole[32:96, 32:96] = True
    assert repeat(noise, hole, 32)[0] < REGULAR
    assert match_band(noise, hole, 5, 32) == 5
    assert match_band(data.cells(128), hole, 5, 32) == 5  # cells: irregular
    assert repeat(noise[:40, :40], np.zeros((40, 40), bool), 32) == (0.0, 0)  # under 4 patches of known pixels
    assert match_band(np.full((128, 128, 3), 0.5), hole, 5, 32) == 5  # flat: no repeat


def test_a_long_period_is_matched_on_the_whole_block():
    rows = np.where(np.arange(160) % 48 < 6, 0.2, 0.7)[:, None, None].repeat(128, axis=1)
    hole = np.zeros((160, 128), bool)
    hole[60:100, 40:90] = True
    assert match_band(rows, hole, 5, 32) == 32
    bricks = data.bricks(192, rng=5)  # the gallery's picture: courses of running bond
    band = match_band(bricks, np.pad(hole, ((0, 32), (0, 64))), 5, 32)
    assert 16 <= band <= 32


def test_peaks_of_negative_correlation_are_no_repeat():
    """A hole of scattered pixels over most of a picture can leave only peaks of negative correlation, none of
    them a repeat: no period (0.62 raised ValueError from ``min()``, a traceback from ``tghop inpaint``)."""
    rng = np.random.default_rng(347)
    h, w = rng.integers(64, 256, 2)
    picture = data.bricks(256, rng=0)[:h, :w]
    hole = rng.random((h, w)) < rng.uniform(0.3, 0.95)
    strength, lag = repeat(picture, hole, 32)
    assert (strength, lag) == (0.0, 0)
    assert match_band(picture, hole, 5, 32) == 5


def test_bad_arguments_are_told_in_one_line_not_numpys_errors():
    # 0.63: a 2-D picture raised NumPy's AxisError, a hole of another shape was read as one of too few pixels ((0.0, 0),
    # or NumPy's IndexError at a smaller patch), a negative patch NumPy's "negative dimensions", a float one
    # "'float' object cannot be interpreted as an integer", and match_band's hole as a list "no attribute 'any'".
    import pytest

    from tghop._errors import TGHopError

    image, hole = data.bricks(96), np.zeros((96, 96), bool)
    hole[40:50, 40:50] = True
    cases = [(repeat, image[..., 0], hole, 32, r"image must be an \(H, W, C\) array, got shape \(96, 96\); give "
                                              r"a grey picture as image\[\.\.\., None\]"),
             (repeat, image, np.zeros((50, 50), bool), 32,
              r"hole must be an \(H, W\) mask of the image's 96x96 pixels"),
             (repeat, image, np.zeros((50, 50), bool), 8, r"hole must be an \(H, W\) mask"),
             (repeat, image, None, 32, r"hole must be an \(H, W\) mask"),
             (repeat, image, hole, -3, r"patch_size must be an integer >= 1, got -3"),
             (repeat, image, hole, 2.5, r"patch_size must be an integer >= 1, got 2.5"),
             (match_band, image, np.ones((10, 10), bool), 32, r"hole must be an \(H, W\) mask")]
    for f, *args, message in cases:
        with pytest.raises(TGHopError, match=rf"^{f.__name__}: {message}"):
            f(*args) if f is repeat else f(args[0], args[1], 5, args[2])
    assert match_band(image, hole.tolist(), 5, 32) == match_band(image, hole, 5, 32)
    assert repeat(image, hole.astype(np.uint8) * 255, 32) == repeat(image, hole, 32)
