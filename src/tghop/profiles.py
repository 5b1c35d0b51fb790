"""Colour profiles: an image read with an embedded ICC profile other than sRGB becomes sRGB.

tghop learns and writes pixel values; its outputs carry no colour profile, so viewers show
them as sRGB, the web's and most tools' default. A photograph from a phone (Display P3) or
a camera set to Adobe RGB stores other values for the same colours: read as they are, its
texture came out duller or shifted beside the exemplar in any colour-managed viewer.
:func:`to_srgb` converts such an image with LittleCMS (Pillow's ``ImageCms``, relative
colorimetric: colours outside sRGB are clipped to its gamut) and says so in a warning that
names the profile.

Converted: 8-bit RGB, RGBA (alpha kept as it is), palette and CMYK images whose profile is
not sRGB. Left as they are: images without a profile, with an sRGB one under any name
(a profile that maps a grid of colours onto themselves within one level), grey ones, and
16-bit and float files (which tghop decodes itself; :func:`say_unapplied` warns where their
colour profile is not sRGB).
"""

from __future__ import annotations

import functools
import io
import warnings

import numpy as np

__all__ = ["to_srgb", "say_unapplied"]

#: Levels per channel of the grid of colours that tells an sRGB profile by what it does.
_GRID = 17


def _description(profile) -> str:
    from PIL import ImageCms

    try:
        return ImageCms.getProfileDescription(profile).strip() or "unnamed"
    except Exception:  # noqa: BLE001 - a profile without a readable description
        return "unnamed"


@functools.lru_cache(maxsize=8)
def _transform(data: bytes, mode: str):
    """(transform to sRGB or None where the profile is sRGB, the profile's description) for an
    image of ``mode`` ("RGB" or "CMYK") with the ICC profile ``data``; raises where LittleCMS
    cannot read the profile or it does not fit the mode."""
    from PIL import Image, ImageCms

    source = ImageCms.ImageCmsProfile(io.BytesIO(data))
    transform = ImageCms.buildTransform(source, ImageCms.createProfile("sRGB"), mode, "RGB",
                                        renderingIntent=ImageCms.Intent.RELATIVE_COLORIMETRIC)
    if mode == "RGB":
        levels = np.linspace(0, 255, _GRID).round().astype(np.uint8)
        grid = np.stack(np.meshgrid(levels, levels, levels, indexing="ij"), axis=-1).reshape(_GRID, _GRID ** 2, 3)
        mapped = np.asarray(ImageCms.applyTransform(Image.fromarray(grid, "RGB"), transform))
        if np.abs(mapped.astype(int) - grid).max() <= 1:
            return None, _description(source)
    return transform, _description(source)


def to_srgb(im, name: str):
    """An open Pillow image in sRGB (see the module's notes); ``name`` names it in the warnings."""
    data = im.info.get("icc_profile")
    if not data or im.mode not in ("RGB", "RGBA", "P", "CMYK"):
        return im
    from PIL import Image, ImageCms

    if im.mode == "P":
        im = im.convert("RGBA" if "transparency" in im.info else "RGB")
    colours = im.convert("RGB") if im.mode == "RGBA" else im
    try:
        transform, what = _transform(bytes(data), "CMYK" if im.mode == "CMYK" else "RGB")
    except Exception:  # noqa: BLE001 - a damaged profile, or one for other colours than the image's
        warnings.warn(f"{name}: its colour profile could not be read; colours taken as sRGB", UserWarning,
                      stacklevel=4)
        return im
    if transform is None:
        return im
    out = ImageCms.applyTransform(colours, transform)
    if im.mode == "RGBA":
        out = Image.merge("RGBA", (*out.split(), im.getchannel("A")))
    warnings.warn(f"{name}: colours converted to sRGB from its colour profile {what!r}", UserWarning, stacklevel=4)
    return out


def say_unapplied(data, name: str) -> None:
    """Warn where the ICC profile ``data`` (bytes or None) of a 16-bit or float file, whose pixels
    tghop decodes itself without converting them, is of other colours than sRGB."""
    if not data:
        return
    try:
        transform, what = _transform(bytes(data), "RGB")
    except Exception:  # noqa: BLE001 - a grey or unreadable profile: nothing to say of colours
        return
    if transform is not None:
        warnings.warn(f"{name}: its colour profile {what!r} is not applied to 16-bit and float images; "
                      "colours taken as sRGB", UserWarning, stacklevel=4)
