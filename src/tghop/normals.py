"""A normal map's convention read from its content: OpenGL's (green up: Blender, Unity, glTF) or
DirectX's (green down: Unreal), for telling an artist which one a file holds when its name does not
say, or says the other (:mod:`tghop.material` keeps a normal map's convention, whichever it is).

A tangent-space normal map drawn from a height field holds its slopes: ``n_x / n_z = -dh/dx`` and
``n_y / n_z = -dh/dy`` with ``y`` down the rows (DirectX) or ``+dh/dy`` (OpenGL). A height field's
mixed slopes agree (``d/dy dh/dx = d/dx dh/dy``), so ``d/dy (n_x / n_z)`` and ``d/dx (n_y / n_z)``
correlate by +1 for DirectX's encoding and -1 for OpenGL's; a photographed or painted map less, and
noise not at all. Measured: builtin bricks' and cells' example maps +-1.00; an ambientCG-style set
synthesised at 1024x1024, +0.69 (DirectX) and -0.80 (OpenGL); noise -0.01.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CONVENTION_CORRELATION", "SAMPLE_PIXELS", "convention_of"]

#: The least correlation, either sign, that decides a normal map's convention by its content.
CONVENTION_CORRELATION = 0.3
#: At most this many pixels are read (a larger map every few pixels in each direction).
SAMPLE_PIXELS = 1 << 20


def convention_of(values):
    """The convention a normal map's content is in: ``"DirectX"``, ``"OpenGL"`` or None (not clear:
    a correlation below :data:`CONVENTION_CORRELATION`, a flat map).

    Parameters
    ----------
    values : array_like, shape (H, W, 3)
        Unit vectors encoded as ``(n + 1) / 2``: floats in [0, 1], or unsigned integers at their
        full range (8 or 16 bits).

    Returns
    -------
    str or None
    """
    arr = np.asarray(values)
    if arr.ndim != 3 or arr.shape[2] != 3 or min(arr.shape[:2]) < 3:
        return None
    step = max(1, int(np.ceil(np.sqrt(arr.shape[0] * arr.shape[1] / SAMPLE_PIXELS))))
    scale = np.iinfo(arr.dtype).max if arr.dtype.kind == "u" else 1.0
    n = arr[::step, ::step].astype(np.float64) * (2.0 / scale) - 1.0  # a large map read every step-th pixel
    if min(n.shape[:2]) < 3:
        return None
    nz = np.maximum(n[..., 2], 0.05)  # a slope's steepness bounded: a few sideways vectors do not decide
    across = np.gradient(n[..., 0] / nz, axis=0).ravel()
    down = np.gradient(n[..., 1] / nz, axis=1).ravel()
    if across.std() == 0 or down.std() == 0:
        return None
    r = float(np.corrcoef(across, down)[0, 1])
    return None if abs(r) < CONVENTION_CORRELATION else "DirectX" if r > 0 else "OpenGL"
