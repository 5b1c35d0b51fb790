"""Colour profiles: an image read with an embedded ICC profile other than sRGB becomes sRGB.

tghop learns and writes pixel values; its outputs carry no colour profile, so viewers show
them as sRGB, the web's and most tools' default. A photograph from a phone (Display P3) or
a camera set to Adobe RGB stores other values for the same colours: read as they are, its
texture came out duller or shifted beside the exemplar in any colour-managed viewer.
:func:`to_srgb` converts such an image with LittleCMS (Pillow's ``ImageCms``, relative
colorimetric: colours outside sRGB are clipped to its gamut) and says so in a warning that
names the profile.

A PNG that says its gamma (a gAMA chunk) and has neither an sRGB chunk nor an ICC profile, as some
tools write a linear PNG (gamma 1.0), is converted by that gamma (:func:`gamma_to_srgb`), grey ones
too, with a warning; a gamma within :data:`GAMMA_TOLERANCE` of sRGB's 1/2.2 is taken as sRGB.

Converted: 8-bit RGB, RGBA (alpha kept as it is), palette and CMYK images whose profile is
not sRGB, and 16-bit and float colour files, which tghop decodes itself, by the same transform
sampled on a grid and interpolated (:func:`deep_to_srgb`). Left as they are: images without a
profile, with an sRGB one under any name (a profile that maps a grid of colours onto themselves
within one level), and grey ones. Not converted either: a material's maps other than its colours
(normal, height, roughness...: data, read as stored, :func:`tghop.imageio.load_image`'s ``as_data``).
"""

from __future__ import annotations

import functools
import io

import numpy as np

from ._errors import warn

__all__ = ["to_srgb", "deep_to_srgb", "tiff_profile", "png_gamma", "gamma_to_srgb", "GAMMA_TOLERANCE", "CLIP_DELTA_E",
           "CLIP_SHARE"]

#: Levels per channel of the grid of colours that tells an sRGB profile by what it does.
_GRID = 17
#: Levels per channel of the table that converts 16-bit and float images: every fifth 8-bit level.
_TABLE = 52
#: A colour the conversion to sRGB moves by more than this (CIE76 Delta E, in Lab) counts as clipped:
#: a difference seen at a glance (one of 1-2 takes a close look side by side), well above the 8-bit
#: rounding of the measure itself (at most 1.5 on colours inside both gamuts).
CLIP_DELTA_E = 5.0
#: The share of an image's pixels clipped (:data:`CLIP_DELTA_E`) from which its conversion's warning
#: says so: 1 % of a 256x256 output is a 25x25 patch, whole elements (a petal, a stripe) rather than
#: scattered pixels.
CLIP_SHARE = 0.01
#: At most about this many pixels (every k-th row and column) are measured for the share clipped.
_CLIP_SAMPLE = 1 << 16


def _description(profile) -> str:
    from PIL import ImageCms

    try:
        return ImageCms.getProfileDescription(profile).strip() or "unnamed"
    except Exception:  # noqa: BLE001 - a profile without a readable description
        return "unnamed"


def _mapped(transform, nodes):
    """The ``transform``'s image of every colour whose channels are among ``nodes`` (uint8, n of
    them): (n^3, 3) uint8, the colour ``(r, g, b)`` of node indices in row ``(r * n + g) * n + b``;
    and the colours themselves, alike."""
    from PIL import Image, ImageCms

    n = len(nodes)
    grid = np.stack(np.meshgrid(nodes, nodes, nodes, indexing="ij"), axis=-1).reshape(n, n * n, 3)
    mapped = np.asarray(ImageCms.applyTransform(Image.fromarray(grid, "RGB"), transform))
    return mapped.reshape(-1, 3), grid.reshape(-1, 3)


@functools.lru_cache(maxsize=8)
def _transform(data: bytes, mode: str):
    """(transform to sRGB or None where the profile is sRGB, the profile's description) for an
    image of ``mode`` ("RGB" or "CMYK") with the ICC profile ``data``; raises where LittleCMS
    cannot read the profile or it does not fit the mode."""
    from PIL import ImageCms

    source = ImageCms.ImageCmsProfile(io.BytesIO(data))
    transform = ImageCms.buildTransform(source, ImageCms.createProfile("sRGB"), mode, "RGB",
                                        renderingIntent=ImageCms.Intent.RELATIVE_COLORIMETRIC)
    if mode == "RGB":
        mapped, grid = _mapped(transform, np.linspace(0, 255, _GRID).round().astype(np.uint8))
        if np.abs(mapped.astype(int) - grid).max() <= 1:
            return None, _description(source)
    return transform, _description(source)


def _source(data, mode, name, stacklevel):
    """(transform to sRGB, description) of the ICC profile ``data`` for an image of ``mode``, or
    None where there is nothing to convert: no profile, an sRGB one, or one LittleCMS cannot use
    (said in a warning; ``stacklevel``: the caller's own, as it would give :func:`warnings.warn`)."""
    if not data:
        return None
    try:
        transform, what = _transform(bytes(data), mode)
    except Exception:  # noqa: BLE001 - a damaged profile, or one for other colours than the image's
        warn(f"{name}: {_unusable(data, mode)}; colours taken as sRGB", UserWarning, stacklevel=stacklevel + 1)
        return None
    return None if transform is None else (transform, what)


def _unusable(data, mode) -> str:
    """Why the ICC profile ``data`` cannot convert an image of ``mode`` to sRGB, in words: damaged, or
    made for other colours than the image's (0.58 said "could not be read" of a Lab profile too)."""
    from PIL import ImageCms

    try:
        space = ImageCms.ImageCmsProfile(io.BytesIO(bytes(data))).profile.xcolor_space.strip()
    except Exception:  # noqa: BLE001 - LittleCMS cannot read it
        return "its colour profile could not be read"
    if space and space.upper() != mode.upper():
        return f"its colour profile is for {space} colours, not {mode} ones as the image's"
    return "its colour profile could not be used"


@functools.lru_cache(maxsize=8)
def _lab_transforms(data: bytes, mode: str):
    """(the ICC profile ``data``'s colours to Lab, sRGB's to Lab): LittleCMS transforms, relative
    colorimetric as :func:`_transform`'s."""
    from PIL import ImageCms

    lab, intent = ImageCms.createProfile("LAB"), ImageCms.Intent.RELATIVE_COLORIMETRIC
    source = ImageCms.ImageCmsProfile(io.BytesIO(data))
    return (ImageCms.buildTransform(source, lab, mode, "LAB", renderingIntent=intent),
            ImageCms.buildTransform(ImageCms.createProfile("sRGB"), lab, "RGB", "LAB", renderingIntent=intent))


def _lab(im, transform):
    """An 8-bit image's colours in Lab (float: L in [0, 100], a and b signed), by ``transform``."""
    from PIL import ImageCms

    arr = np.asarray(ImageCms.applyTransform(im, transform)).astype(np.float64)
    arr[..., 0] *= 100 / 255
    arr[..., 1:] -= np.where(arr[..., 1:] > 127, 256, 0)  # Pillow's LAB: a and b as signed bytes
    return arr


def _clipped(im, data, transform):
    """The share of the 8-bit RGB or CMYK image ``im``'s pixels (about :data:`_CLIP_SAMPLE` of them,
    evenly spread) that ``transform`` to sRGB moves by more than :data:`CLIP_DELTA_E` in Lab: colours
    outside sRGB, clipped to it; 0 where LittleCMS cannot build the transforms to Lab."""
    from PIL import Image

    step = max(1, int(np.ceil((im.width * im.height / _CLIP_SAMPLE) ** 0.5)))
    if step > 1:
        im = im.resize((max(1, im.width // step), max(1, im.height // step)), Image.Resampling.NEAREST)
    try:
        to_lab, srgb_lab = _lab_transforms(bytes(data), im.mode)
    except Exception:  # noqa: BLE001 - a profile LittleCMS converts to sRGB but not to Lab: not measured
        return 0.0
    from PIL import ImageCms

    moved = np.sqrt(((_lab(im, to_lab) - _lab(ImageCms.applyTransform(im, transform), srgb_lab)) ** 2).sum(axis=-1))
    return float(np.mean(moved > CLIP_DELTA_E))


def _said(name, what, stacklevel, clipped=0.0):
    """The warning that ``name``'s colours were converted (``stacklevel``: as for :func:`_source`), and
    how many were clipped to sRGB where they are :data:`CLIP_SHARE` or more."""
    told = "" if clipped < CLIP_SHARE else (
        f"; {clipped:.0%} of its pixels hold colours outside sRGB, clipped to it: duller in the outputs than "
        "the file shows (tghop writes sRGB)")
    warn(f"{name}: colours converted to sRGB from its colour profile {what!r}{told}", UserWarning,
         stacklevel=stacklevel + 1)


def to_srgb(im, name: str):
    """An open Pillow image in sRGB (see the module's notes); ``name`` names it in the warnings.

    Parameters
    ----------
    im : PIL.Image.Image
        An open image; its ``info["icc_profile"]`` is read.
    name : str
        The image's name in the warnings (its file).

    Returns
    -------
    PIL.Image.Image
        ``im`` itself where there is nothing to convert (no profile, an sRGB one, one
        LittleCMS cannot read, a grey or other mode); else a new ``"RGB"`` image (``"RGBA"``
        with the alpha kept), after a :class:`UserWarning` naming the profile. A palette
        image with a profile comes back as RGB (RGBA with transparency) even when sRGB.
    """
    data = im.info.get("icc_profile")
    if not data or im.mode not in ("RGB", "RGBA", "P", "CMYK"):
        return im
    from PIL import Image, ImageCms

    if im.mode == "P":
        im = im.convert("RGBA" if "transparency" in im.info else "RGB")
    found = _source(data, "CMYK" if im.mode == "CMYK" else "RGB", name, stacklevel=4)
    if found is None:
        return im
    colours = im.convert("RGB") if im.mode == "RGBA" else im
    out = ImageCms.applyTransform(colours, found[0])
    if im.mode == "RGBA":
        out = Image.merge("RGBA", (*out.split(), im.getchannel("A")))
    _said(name, found[1], stacklevel=4, clipped=_clipped(colours, data, found[0]))
    return out


@functools.lru_cache(maxsize=4)
def _table(data: bytes):
    """The sRGB colour (float32 in [0, 1]) of each of _TABLE^3 evenly spaced 8-bit colours, by the
    same LittleCMS transform as 8-bit images (:func:`_transform`): (_TABLE^3, 3), the colour of
    nodes ``(r, g, b)`` in row ``(r * _TABLE + g) * _TABLE + b``."""
    mapped, _ = _mapped(_transform(data, "RGB")[0], (np.arange(_TABLE) * (255 // (_TABLE - 1))).astype(np.uint8))
    return (mapped / np.float32(255)).astype(np.float32)


def _trilinear(table, rgb):
    """``table`` (_TABLE^3, 3) at the colours ``rgb`` (n, 3) in [0, 1], trilinearly interpolated."""
    pos = np.clip(rgb, 0.0, 1.0) * (_TABLE - 1)
    low = np.minimum(pos.astype(np.intp), _TABLE - 2)
    frac = (pos - low).astype(np.float32)
    base = (low[:, 0] * _TABLE + low[:, 1]) * _TABLE + low[:, 2]
    out = np.zeros((len(rgb), 3), dtype=np.float32)
    for dr in (0, 1):
        for dg in (0, 1):
            for db in (0, 1):
                weight = ((frac[:, 0] if dr else 1 - frac[:, 0]) * (frac[:, 1] if dg else 1 - frac[:, 1])
                          * (frac[:, 2] if db else 1 - frac[:, 2]))
                out += weight[:, None] * table[base + (dr * _TABLE + dg) * _TABLE + db]
    return out


def deep_to_srgb(arr, data, name: str):
    """A 16-bit or float colour image (H, W, 3 or 4; float in [0, 1]) whose ICC profile ``data``
    (bytes or None) is not sRGB, in sRGB: Pillow's colour management takes 8-bit images only, so
    the same transform is sampled on a grid of _TABLE^3 colours and interpolated trilinearly (on
    average within half an 8-bit level of the 8-bit conversion; up to several levels for colours
    outside sRGB, whose clipping the grid smooths); alpha as it is. Others as they are.

    Parameters
    ----------
    arr : ndarray, shape (H, W, C)
        Float in [0, 1], decoded from a 16-bit or float file; only C = 3 or 4 is converted.
    data : bytes or None
        The file's ICC profile.
    name : str
        The image's name in the warnings.

    Returns
    -------
    ndarray, shape (H, W, C)
        ``arr`` itself where there is nothing to convert; else a new float64 array in
        [0, 1], after a :class:`UserWarning` naming the profile.
    """
    if arr.ndim != 3 or arr.shape[2] not in (3, 4):
        return arr
    found = _source(data, "RGB", name, stacklevel=3)
    if found is None:
        return arr
    table = _table(bytes(data))
    out = np.array(arr, dtype=np.float64)
    rows = max(1, (1 << 18) // max(1, arr.shape[1]))  # about a quarter of a million colours at a time
    for y in range(0, arr.shape[0], rows):
        part = out[y: y + rows, :, :3]
        part[...] = _trilinear(table, part.reshape(-1, 3)).reshape(part.shape)
    from PIL import Image

    step = max(1, int(np.ceil((arr.shape[0] * arr.shape[1] / _CLIP_SAMPLE) ** 0.5)))
    sample = np.round(np.clip(arr[::step, ::step, :3], 0.0, 1.0) * 255).astype(np.uint8)
    _said(name, found[1], stacklevel=3, clipped=_clipped(Image.fromarray(sample, "RGB"), data, found[0]))
    return np.clip(out, 0.0, 1.0)


def tiff_profile(path):
    """The ICC profile (bytes) of a TIFF file's first page, read by :mod:`tifffile` from its
    header (a float colour TIFF, which Pillow cannot open); None where there is none.

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    bytes or None
        None also where the file is not a TIFF or :mod:`tifffile` is not installed.
    """
    try:
        import tifffile

        with tifffile.TiffFile(path) as tif:
            tag = tif.pages[0].tags.get(34675)  # InterColorProfile
            return None if tag is None else bytes(tag.value)
    except Exception:  # noqa: BLE001 - not a TIFF, or no tifffile: no profile to apply
        return None


#: A PNG gamma (gAMA) whose product with 2.2 is within this of 1 is taken as sRGB, as libpng takes a
#: gamma correction within 5 % of none as none (its PNG_GAMMA_THRESHOLD): the 0.45455 that most
#: writers store, beside an sRGB chunk or alone, and the nearby values of older ones.
GAMMA_TOLERANCE = 0.05


def png_gamma(info):
    """The encoding gamma of a PNG whose gAMA chunk is the only word on its colours (no sRGB chunk, no
    ICC profile, which the PNG standard puts first) and is not sRGB's (:data:`GAMMA_TOLERANCE`); else
    None (also for a gamma of 0, which the standard calls an error and libpng ignores).

    Parameters
    ----------
    info : dict
        An open Pillow image's ``info`` (its ``"gamma"``, ``"srgb"`` and ``"icc_profile"``).

    Returns
    -------
    float or None
    """
    gamma = info.get("gamma")
    if gamma is None or "srgb" in info or info.get("icc_profile"):
        return None
    gamma = float(gamma)
    return gamma if gamma > 0 and abs(gamma * 2.2 - 1) > GAMMA_TOLERANCE else None


def _srgb_encoded(linear):
    """sRGB's transfer function (IEC 61966-2-1) of linear light in [0, 1]."""
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)


def gamma_to_srgb(arr, gamma, name: str, *, alpha: bool = False):
    """Pixels stored with the encoding ``gamma`` (``stored = linear ** gamma``; :func:`png_gamma`) in
    sRGB, as a colour-managed viewer shows them, after a :class:`UserWarning` naming the gamma.

    Parameters
    ----------
    arr : ndarray, shape (H, W) or (H, W, C)
        uint8 levels, or floats in [0, 1].
    gamma : float or None
        None: ``arr`` itself, no warning.
    name : str
        The image's name in the warning (its file).
    alpha : bool
        The last channel is alpha, kept as it is (the PNG standard stores alpha linear).

    Returns
    -------
    ndarray of ``arr``'s shape and dtype (float64 for floats)
    """
    if gamma is None:
        return arr
    warn(f"{name}: colours converted to sRGB from its PNG gamma {gamma:.5g} (a gAMA chunk without an sRGB chunk "
         f"or colour profile; {'linear light' if abs(gamma - 1) < 1e-3 else 'not sRGB'})", UserWarning, stacklevel=2)
    out = np.array(arr, dtype=np.uint8 if arr.dtype == np.uint8 else np.float64)
    colours = out[..., :-1] if alpha else out
    if out.dtype == np.uint8:
        table = np.round(255 * _srgb_encoded((np.arange(256) / 255.0) ** (1 / gamma))).astype(np.uint8)
        colours[...] = table[colours]
    else:
        colours[...] = np.clip(_srgb_encoded(np.clip(colours, 0.0, 1.0) ** (1 / gamma)), 0.0, 1.0)
    return out
