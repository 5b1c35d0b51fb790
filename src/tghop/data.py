"""Built-in exemplar textures, made by code (no image files ship with tghop).

They let the CLI, the tests and the README gallery run on any machine. Each function
returns a float ``(H, W, 3)`` image in [0, 1] and is deterministic for a given ``rng``.
:func:`example_maps` makes a material's maps (normal, roughness, height) from an albedo for the
same uses (also ``tghop.material.example_maps``).
"""

from __future__ import annotations

import numpy as np

from ._arrays import check_int
from ._errors import TGHopError
from ._estimator import check_rng
from ._images import check_image, check_size

__all__ = ["bricks", "cells", "builtin", "BUILTIN", "example_maps"]


def _smooth_noise(rng, shape, sigma):
    """Gaussian-filtered white noise scaled to unit standard deviation."""
    from scipy import ndimage  # only when a built-in exemplar is made

    noise = ndimage.gaussian_filter(rng.standard_normal(shape), sigma, mode="wrap")
    return noise / (noise.std() + 1e-12)


def _check_side(size) -> int:
    """``size`` as an int of at least 32 (:func:`tghop._arrays.check_int`) within
    :data:`tghop._images.MAX_PIXELS` (:func:`tghop._images.check_size`), or a one-line
    :class:`TGHopError` before any work."""
    return check_size(check_int(size, "size", 32))[0]


def bricks(size: int = 256, *, rng=0) -> np.ndarray:
    """A running-bond red brick wall with mortar lines, per-brick colour and fine grain.

    Parameters
    ----------
    size : int
        Height and width in pixels (at least 32; at most 8192, :func:`tghop._images.check_size`).
    rng : int or numpy.random.Generator

    Returns
    -------
    ndarray, shape (size, size, 3), float64 in [0, 1]
    """
    size = _check_side(size)
    rng = check_rng(rng)
    brick_h, brick_w, mortar = 20, 44, 4
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    # Slightly wavy courses so that no two bricks are identical.
    yy_w = yy + 1.2 * _smooth_noise(rng, (size, size), 12)
    row = np.floor(yy_w / brick_h).astype(int)
    xx_w = xx + (row % 2) * (brick_w / 2) + 1.2 * _smooth_noise(rng, (size, size), 12)
    col = np.floor(xx_w / brick_w).astype(int)
    in_y = yy_w - row * brick_h
    in_x = xx_w - col * brick_w
    # Distance to the brick edge gives mortar and a bevel.
    edge = np.minimum.reduce([in_y, brick_h - in_y, in_x, brick_w - in_x])
    is_mortar = edge < mortar / 2
    # Per-brick colour: hash of (row, col) into a table of random tints.
    n_ids = 4096
    tints = rng.normal(0.0, 1.0, size=(n_ids, 3))
    brick_id = (row * 131 + col * 17) % n_ids
    tint = tints[brick_id]
    base = np.array([0.62, 0.28, 0.20])
    colour = base + tint * np.array([0.07, 0.04, 0.03]) + 0.05 * tint[:, :, :1]
    grain = 0.045 * _smooth_noise(rng, (size, size), 0.8)[..., None]
    blotch = 0.04 * _smooth_noise(rng, (size, size), 5)[..., None]
    bevel = np.clip(edge / 3.0, 0, 1)[..., None]
    img = colour * (0.75 + 0.25 * bevel) + grain + blotch
    mortar_col = np.array([0.70, 0.68, 0.63]) + 0.05 * _smooth_noise(rng, (size, size), 1.0)[..., None]
    img = np.where(is_mortar[..., None], mortar_col, img)
    return np.clip(img, 0.0, 1.0)


def cells(size: int = 256, *, rng=0) -> np.ndarray:
    """Irregular green cells (a Voronoi pattern with dark walls), a stochastic texture.

    Parameters
    ----------
    size : int
        Height and width in pixels (at least 32; at most 8192, :func:`tghop._images.check_size`).
    rng : int or numpy.random.Generator

    Returns
    -------
    ndarray, shape (size, size, 3), float64 in [0, 1]
    """
    size = _check_side(size)
    rng = check_rng(rng)
    n_seeds = max(8, (size * size) // 500)
    seeds = rng.uniform(0, size, size=(n_seeds, 2))
    from scipy.spatial import cKDTree

    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    pts = np.stack([yy.ravel(), xx.ravel()], axis=1)
    # The two nearest seeds of every pixel, at periodic distances so that the exemplar itself
    # tiles (a tree: every pixel against every seed took size ** 4 / 250 numbers of memory).
    two, nearest = cKDTree(seeds, boxsize=size).query(pts, k=2)
    wall = np.clip((two[:, 1] - two[:, 0]) / 3.0, 0, 1).reshape(size, size)
    owner = nearest[:, 0].reshape(size, size)
    shade = rng.uniform(0.8, 1.2, n_seeds)[owner][..., None]
    base = np.array([0.35, 0.62, 0.25]) * shade
    grain = 0.03 * _smooth_noise(rng, (size, size), 1.0)[..., None]
    img = base * (0.25 + 0.75 * wall[..., None]) + grain
    return np.clip(img, 0.0, 1.0)


#: name -> function(size, rng) of the built-in exemplars.
BUILTIN = {"bricks": bricks, "cells": cells}


def builtin(name: str, size: int = 256, *, rng=0) -> np.ndarray:
    """A built-in exemplar by name (see :data:`BUILTIN`).

    Parameters
    ----------
    name : {"bricks", "cells"}
        As ``builtin:NAME`` names it on the command line.
    size : int
        Height and width in pixels, as :func:`bricks` takes it.
    rng : int or numpy.random.Generator
        Same seed, same image.

    Returns
    -------
    ndarray, shape (size, size, 3), float64 in [0, 1]
    """
    if name not in BUILTIN:
        shown = repr(name) if len(repr(name)) <= 60 else repr(name)[:57] + "..."  # 0.57: a 900 KB field whole
        raise TGHopError(f"unknown built-in exemplar {shown}; choose one of {', '.join(sorted(BUILTIN))}")
    return BUILTIN[name](size, rng=rng)


def _blur(x, sigma):
    """A separable Gaussian blur of an (H, W) array (reflecting edges), without SciPy."""
    r = max(1, int(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    for axis in (0, 1):
        pad = [(r, r) if a == axis else (0, 0) for a in range(2)]
        x = np.apply_along_axis(lambda v: np.convolve(v, k, mode="valid"), axis, np.pad(x, pad, mode="reflect"))
    return x


def example_maps(albedo, *, strength=8.0, convention="DirectX"):
    """Maps made from an albedo's luminance, for tests, benchmarks and demonstrations:
    ``{"normal": (H, W, 3), "roughness": (H, W, 1), "height": (H, W, 1)}``, float in [0, 1].

    The height is the luminance blurred (sigma 1.5 px), the normal map its slope
    (``(-strength dh/dx, -strength dh/dy, 1)`` normalised, encoded as ``(n + 1) / 2``, ``y`` down
    the rows: the DirectX convention, green down; ``convention="OpenGL"``: green up, the map for
    Blender, Unity and glTF), the roughness one minus the luminance blurred more (sigma 3 px).

    Parameters
    ----------
    albedo : array_like, shape (H, W) or (H, W, C), C in {1, 3}
        Float in [0, 1], or uint8 / uint16 (rescaled); a bad shape, dtype or range raises
        :class:`~tghop.InvalidImageError`.
    strength : float
        Slope of the normal map per unit of height (larger: steeper normals).
    convention : {"DirectX", "OpenGL"}
        The normal map's: green down (a bump's upper edge dark in green; Unreal) or up (Blender,
        Unity). DirectX by default, as tghop made them before this choice was given.

    Returns
    -------
    dict of str to ndarray
        ``"normal"`` (H, W, 3), ``"roughness"`` (H, W, 1), ``"height"`` (H, W, 1), float64 in [0, 1].
    """
    if convention not in ("DirectX", "OpenGL"):
        raise TGHopError(f"convention must be 'DirectX' or 'OpenGL' (a normal map's green down or up), "
                         f"got {convention!r}")
    img = check_image(albedo, name="albedo")
    lum = img.mean(axis=2)
    height = _blur(lum, 1.5)
    gy, gx = np.gradient(height)
    if convention == "OpenGL":
        gy = -gy
    n = np.stack([-strength * gx, -strength * gy, np.ones_like(height)], axis=2)
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    return {"normal": (n + 1.0) / 2.0, "roughness": np.clip(1.0 - _blur(lum, 3.0), 0.0, 1.0)[..., None],
            "height": np.clip(height, 0.0, 1.0)[..., None]}
