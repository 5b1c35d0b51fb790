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
