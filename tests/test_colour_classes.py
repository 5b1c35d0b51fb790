"""Colour classes (tghop.colour.ColourClasses): histograms that keep an image's own share of each colour."""

from __future__ import annotations

import numpy as np
import pytest

from tghop.colour import (ColourClasses, channel_quantiles, class_separation, class_shares, colour_classes,
                          match_histograms, mixed_quantiles, share_spread)
from tghop.refine import BandStatistics
from tghop._errors import TGHopError


def two_colours(rng, grey_share, shape=(64, 64), stripes=True):
    """Grey (0.5) and white (0.9) pixels with a little noise, ``grey_share`` of them grey: in
    two wide stripes (crops of it hold other shares) or, ``stripes`` False, pixel by pixel."""
    if stripes:
        rows = np.arange(shape[0]) < shape[0] * grey_share
        grey = np.repeat(rows[:, None], shape[1], axis=1)
    else:
        grey = rng.random(shape) < grey_share
    img = np.where(grey[..., None], 0.5, 0.9) + rng.normal(0, 0.03, shape + (3,))
    return np.clip(img, 0, 1), grey


def test_classes_are_found_the_same_every_time_and_in_order(rng):
    centres = np.array([[0.1, 0.2, 0.3], [0.5, 0.5, 0.5], [0.9, 0.8, 0.7]])
    pixels = centres[rng.integers(0, 3, 5000)] + rng.normal(0, 0.02, (5000, 3))
    found = colour_classes(pixels, 3)
    np.testing.assert_allclose(found, centres, atol=0.01)  # sorted along the first principal axis
    np.testing.assert_array_equal(colour_classes(pixels, 3), found)
    with pytest.raises(Exception, match="2 pixels for 3 classes"):
        colour_classes(pixels[:2], 3)


def test_separate_colours_are_told_from_a_continuum(rng):
    # A continuum cut into classes: its shares are an image's tone, which matching corrects.
    continuum = rng.random((20000, 3))
    assert class_separation(continuum, colour_classes(continuum, 4)) == 0.0
    grey = rng.normal(0.5, 0.15, (20000, 1)) * np.ones(3)
    assert class_separation(grey, colour_classes(grey, 4)) == 0.0
    separate, _ = two_colours(rng, 0.4)
    pixels = separate.reshape(-1, 3)
    assert class_separation(pixels, colour_classes(pixels, 2)) == 1.0
    four = np.array([[0.1] * 3, [0.4] * 3, [0.7, 0.2, 0.2], [0.9] * 3])[rng.integers(0, 4, 20000)]
    four += rng.normal(0, 0.02, four.shape)
    assert class_separation(four, colour_classes(four, 4)) == 1.0


def test_the_exemplars_own_shares_give_its_histograms(rng):
    exemplar, _ = two_colours(rng, 0.4)
    classes = ColourClasses(2).fit(exemplar, BandStatistics().fit(exemplar))
    np.testing.assert_allclose(classes.shares_, [0.4, 0.6], atol=0.02)
    assert classes.separation_[0] == 1.0
    np.testing.assert_allclose(class_shares(exemplar, classes.centres_), classes.shares_, atol=1e-9)
    # The mixture in the exemplar's shares is the exemplar's overall distribution: it maps an
    # image as the exemplar's own quantiles do (but for the odd pixel at the jump between colours).
    mixed = mixed_quantiles(classes.quantiles_, classes.shares_)
    image, _ = two_colours(rng, 0.7)
    difference = np.abs(match_histograms(image, mixed) - match_histograms(image, channel_quantiles(exemplar)))
    assert np.median(difference) < 0.002 and np.mean(difference > 0.05) < 0.01


@pytest.mark.parametrize("own_shares, most_turned", [(0.0, 1.0), (0.5, 0.6), (1.0, 0.05)])
def test_an_image_with_too_much_grey_keeps_its_grey(rng, own_shares, most_turned):
    # Matching the whole histogram of an image with 70 % grey to an exemplar with 40 % turns
    # its brightest greys white (the flecks); the classes' histograms in the image's own
    # shares leave them grey.
    exemplar, _ = two_colours(rng, 0.4)
    classes = ColourClasses(2).fit(exemplar, BandStatistics().fit(exemplar))
    image, grey = two_colours(rng, 0.7)
    matched = match_histograms(image, classes.targets(image, own_shares=own_shares)[1])
    turned = (matched[grey].mean(axis=1) > 0.7).mean()  # greys made white, of all greys
    assert turned <= most_turned * (0.7 - 0.4) / 0.7 + 0.01
    if own_shares == 0:  # the exemplar's histograms: 30 of the 70 % grey become white
        difference = np.abs(matched - match_histograms(image, channel_quantiles(exemplar)))
        assert np.median(difference) < 0.002 and np.mean(difference > 0.05) < 0.01
        assert turned > 0.25  # each channel on its own: some greys get one or two white channels only


def test_shares_move_only_as_far_as_the_exemplars_crops_vary(rng):
    # Pixel by pixel the exemplar's crops all hold 40 % grey: an image with 70 % (a blur's
    # bias, as on text) is given the exemplar's histograms; a striped one's crops vary by
    # a stripe, and an image of it keeps its own shares.
    image, _ = two_colours(rng, 0.7, stripes=False)
    for stripes, moved in ((False, (0.0, 0.06)), (True, (0.25, 0.31))):
        exemplar, _ = two_colours(rng, 0.4, stripes=stripes)
        classes = ColourClasses(2).fit(exemplar, BandStatistics().fit(exemplar))
        assert classes.spread_[-1] == 32  # crops of half the side
        colour_q = classes.targets(image)[1]
        grey_share = np.mean(match_histograms(image, colour_q).mean(axis=2) < 0.7)
        assert moved[0] <= grey_share - 0.4 <= moved[1], (stripes, grey_share)


def test_the_spread_is_over_crops_at_every_position_not_a_grid_in_step_with_the_stripes():
    # Stripes of period 32 and crops of 48x48 on a 144x96 exemplar: crops started every 32
    # rows (tghop 0.49.0's 4x4 grid) all hold the same shares, and measured no spread at all.
    rows = (np.arange(144) // 16) % 2
    exemplar = np.repeat(np.repeat(rows[:, None, None], 96, axis=1), 3, axis=2).astype(float)
    centres = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    every = np.array([class_shares(exemplar[y:y + 48, :48], centres) for y in range(97)])
    spread = share_spread(exemplar, centres)
    assert spread[-1] == 48 and every.std(axis=0)[0] > 0.09
    np.testing.assert_allclose(spread[:-1], every.std(axis=0), rtol=0.02)
    # A mask: each crop's shares over its pixels outside it, crops mostly under it left out.
    exclude = np.zeros((144, 96), dtype=bool)
    exclude[:, :60] = True
    kept = [class_shares(exemplar[y:y + 48, x:x + 48][~exclude[y:y + 48, x:x + 48]], centres)
            for y in range(97) for x in range(49) if (~exclude[y:y + 48, x:x + 48]).sum() * 2 >= 48 * 48]
    np.testing.assert_allclose(share_spread(exemplar, centres, exclude)[:-1], np.std(kept, axis=0), rtol=0.02)


def test_a_sample_mask_is_checked_as_patch_statistics_checks_it(rng):
    exemplar, _ = two_colours(rng, 0.4)
    bands = BandStatistics().fit(exemplar)
    h, w = exemplar.shape[:2]
    for fit, where in ((lambda m: BandStatistics().fit(exemplar, exclude=m), "BandStatistics.fit"),
                       (lambda m: ColourClasses(2).fit(exemplar, bands, exclude=m), "ColourClasses.fit")):
        with pytest.raises(TGHopError, match=rf"^{where}: exclude must be an \(H, W\) mask of the image's "
                                             rf"{h}x{w} pixels, got shape \(5, 5\)$"):
            fit(np.zeros((5, 5), bool))
    # A 0/1 integer mask is the boolean one (it was used as indices by ColourClasses).
    exclude = np.zeros((h, w), dtype=bool)
    exclude[40:50, 5:20] = True
    a = ColourClasses(2).fit(exemplar, bands, exclude=exclude)
    b = ColourClasses(2).fit(exemplar, bands, exclude=exclude.astype(np.uint8))
    np.testing.assert_array_equal(a.centres_, b.centres_)


def test_a_sample_mask_keeps_the_spread_of_the_pixels_outside_it(rng):
    # An exemplar fitted with a mask measures its crops' shares on the pixels outside the mask
    # (tghop 0.33 stored no spread for it, so its images kept the exemplar's shares).
    exemplar, _ = two_colours(rng, 0.4)
    whole = ColourClasses(2).fit(exemplar, BandStatistics().fit(exemplar))
    exclude = np.zeros(exemplar.shape[:2], dtype=bool)
    exclude[40:50, 5:20] = True  # a blemish
    masked = ColourClasses(2).fit(exemplar, BandStatistics().fit(exemplar, exclude=exclude), exclude=exclude)
    assert masked.spread_[-1] == 32 and masked.spread_[0] > 0.1
    np.testing.assert_allclose(masked.spread_[:-1], whole.spread_[:-1], atol=0.05)
    image, grey = two_colours(rng, 0.7, stripes=False)
    kept = match_histograms(image, masked.targets(image)[1])
    assert np.mean(kept.mean(axis=2) < 0.7) - 0.4 > 0.2  # the image keeps more of its grey
    # Crops mostly under the mask are left out; too few left: no spread.
    exclude[:, 10:] = True
    assert not ColourClasses(2).fit(exemplar, BandStatistics().fit(exemplar, exclude=exclude),
                                    exclude=exclude).spread_.any()


def test_refine_takes_the_classes_targets(rng):
    from tghop.refine import refine

    exemplar, _ = two_colours(rng, 0.4)
    bands = BandStatistics().fit(exemplar)
    classes = ColourClasses(2).fit(exemplar, bands)
    image, grey = two_colours(rng, 0.7)
    pixel_q = classes.targets(image, own_shares=1.0)[0]
    kept = refine(image, bands, n_iter=2, pixel_quantiles=pixel_q)
    forced = refine(image, bands, n_iter=2)
    assert (kept[grey].mean(axis=1) > 0.7).mean() < 0.05 < 0.3 < (forced[grey].mean(axis=1) > 0.7).mean()
    with pytest.raises(Exception, match="pixel_quantiles of shape"):
        refine(image, bands, n_iter=1, pixel_quantiles=pixel_q[:2])


def test_a_model_uses_its_classes_only_with_own_shares(small_model):
    assert small_model.classes_.centres_.shape == (4, 3)
    a = small_model.synthesize((48, 48), rng=3, n_patches=200)
    assert np.array_equal(a, small_model.synthesize((48, 48), rng=3, n_patches=200))
    saved = small_model.classes_
    try:
        small_model.classes_ = None  # a model without classes: the exemplar's histograms
        plain = small_model.synthesize((48, 48), rng=3, n_patches=200)
    finally:
        small_model.classes_ = saved
    assert np.array_equal(small_model.synthesize((48, 48), rng=3, n_patches=200, own_shares=0.0), plain)
    assert not np.array_equal(a, plain)


# ------------------------------------------------------------------ input checks
def _bad(img):
    nan = img.copy()
    nan[1, 2, 0] = np.nan
    return [(img * 255, r"values must lie in \[0, 1\]"), (nan, "NaN"), (img[..., 0], r"\(H, W, C\)")]


def test_colour_functions_check_their_images(rng):
    from tghop._errors import InvalidImageError, NotFittedError
    from tghop.colour import match_histograms

    img = rng.random((24, 20, 3))
    q = channel_quantiles(img)
    bands = BandStatistics(n_levels=1, n_quantiles=17).fit(img)
    cc = ColourClasses(2).fit(img, bands)
    for bad, message in _bad(img):
        for where, call in (("match_histograms", lambda: match_histograms(bad, q)),
                            ("channel_quantiles", lambda: channel_quantiles(bad)),
                            ("ColourClasses.fit", lambda: ColourClasses(2).fit(bad, bands)),
                            ("ColourClasses.targets", lambda: cc.targets(bad))):
            with pytest.raises(InvalidImageError, match=f"^{where}: image.*{message}"):
                call()
    with pytest.raises(InvalidImageError, match="match_histograms: image has 3 channels where 1 is expected"):
        match_histograms(img, q[:1])
    with pytest.raises(InvalidImageError, match="ColourClasses.targets: image has 1 channel where 3 are expected"):
        cc.targets(img[..., :1])
    with pytest.raises(TGHopError, match="match_histograms: quantiles must be a"):
        match_histograms(img, q[0])
    assert np.array_equal(match_histograms(img, q.tolist()), match_histograms(img, q))
    with pytest.raises(NotFittedError):
        ColourClasses(2).fit(img, BandStatistics())
    for n in (1, 2.0, True):
        with pytest.raises(TGHopError, match=rf"^channel_quantiles: n must be an integer >= 2, got {n!r}$"):
            channel_quantiles(img, n)


@pytest.mark.parametrize("n_classes", [0, -2, 2.7, "3", None])
def test_colour_classes_refuse_a_bad_n_classes(rng, n_classes):
    img = rng.random((24, 20, 3))
    bands = BandStatistics(n_levels=1, n_quantiles=17).fit(img)
    with pytest.raises(TGHopError, match="n_classes must be an integer >= 1"):
        ColourClasses(n_classes).fit(img, bands)


def test_colour_classes_of_an_8_bit_exemplar_are_those_of_its_floats(rng):
    u8 = (rng.random((40, 30, 3)) * 255).round().astype(np.uint8)
    bands = BandStatistics(n_levels=1, n_quantiles=17).fit(u8 / 255.0)
    a, b = ColourClasses(3).fit(u8, bands), ColourClasses(3).fit(u8 / 255.0, bands)
    for name in ("centres_", "shares_", "quantiles_", "refine_quantiles_", "spread_"):
        assert np.allclose(getattr(a, name), getattr(b, name), atol=1e-12), name
