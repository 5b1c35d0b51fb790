"""A normal map's convention read from its content: OpenGL's (green up: Blender, Unity, glTF) or
DirectX's (green down: Unreal), for telling an artist which one a file holds when its name does not
say, or says the other (:mod:`tghop.material` keeps a normal map's convention, whichever it is, and
checks and renormalises its vectors; what a map's name says is :mod:`tghop.map_names`').

A tangent-space normal map drawn from a height field holds its slopes: ``n_x / n_z = -dh/dx`` and
``n_y / n_z = -dh/dy`` with ``y`` down the rows (DirectX) or ``+dh/dy`` (OpenGL). A height field's
mixed slopes agree (``d/dy dh/dx = d/dx dh/dy``), so ``d/dy (n_x / n_z)`` and ``d/dx (n_y / n_z)``
correlate by +1 for DirectX's encoding and -1 for OpenGL's; a photographed or painted map less, and
noise not at all. Measured: builtin bricks' and cells' example maps +-1.00; an ambientCG-style set
synthesised at 1024x1024, +0.69 (DirectX) and -0.80 (OpenGL); noise -0.01.

That cue cannot tell a map mirrored left to right (its pixels, red not negated) from the other convention's
map of the surface turned inside out: both hold ``(+dh/dx, -dh/dy)``, and both read +-1.00. A material's
height map is a second cue (0.60): ``n_x / n_z = -dh/dx`` in either convention, so where the normal map's
slopes across the rows run against the height's (a mirrored map, a half turn, a height inverted), the
content says no convention (None: the name's is kept, and a paint flips nothing); where the height's slopes
down the rows say the other convention than the mixed slopes, neither. A height the normal map does not
follow (correlations under :data:`CONVENTION_CORRELATION`) says nothing; without a height map, the ambient
occlusion (dark in the creases) is the cue (:func:`surface_map`). A mirrored map with neither is still read
as the other convention: nothing in it tells the two apart.

A normal map stored turned, with an EXIF orientation (a viewer's "rotate" of a JPEG often only
sets the tag), is read upright like any image (:func:`tghop.imageio.load_image`); its vectors are
then turned with its pixels (:func:`upright_normal_map`): a slope to the right of a map turned a
quarter is a slope down the rows. Mirrors and the half turn negate red or green whatever the
convention; the quarter turns and transpositions swap red and green, whose signs depend on it (the
name's, else the stored pixels' :func:`convention_of`; neither: refused in one line).

Here too, what a normal map is to tghop (0.61; :mod:`tghop.material` gives the same names): its content told
from a photograph's (:func:`looks_like_normal_map`), the check of its unit vectors (:func:`check_normal_map`)
and their renormalisation after synthesis (:func:`renormalise`).
"""

from __future__ import annotations

import numpy as np

from ._errors import TGHopError
from .image_decode import file_header, upright
from .map_names import kind_key

__all__ = ["CONVENTION_CORRELATION", "SAMPLE_PIXELS", "AO_CHANNEL", "convention_of", "surface_map", "upright_vectors",
           "upright_normal_map", "convention_flips", "flip_green", "NORMAL_TOLERANCE", "NORMAL_LOOK_SHARE",
           "NORMAL_LOOK_MEAN", "looks_like_normal_map", "check_normal_map", "renormalise"]

#: The least correlation, either sign, that decides a normal map's convention by its content.
CONVENTION_CORRELATION = 0.3
#: At most this many pixels are read (a larger map every few pixels in each direction).
SAMPLE_PIXELS = 1 << 20


def convention_of(values, height=None):
    """The convention a normal map's content is in: ``"DirectX"``, ``"OpenGL"`` or None (not clear:
    a correlation below :data:`CONVENTION_CORRELATION`, a flat map; or, with ``height``, slopes that run
    against the height's: see the module's notes, 0.60).

    Parameters
    ----------
    values : array_like, shape (H, W, 3)
        Unit vectors encoded as ``(n + 1) / 2``: floats in [0, 1], or unsigned integers at their
        full range (8 or 16 bits).
    height : array_like, shape (H, W) or (H, W, 1), optional
        The material's height map (white high; floats or unsigned integers), or its ambient occlusion
        (:func:`surface_map`), the second cue; another shape is refused (:class:`TGHopError`).

    Returns
    -------
    str or None
    """
    arr = np.asarray(values)
    if arr.ndim != 3 or arr.shape[2] != 3 or min(arr.shape[:2]) < 3:
        return None
    h = None if height is None else np.asarray(height)
    if h is not None and (h.shape[:2] != arr.shape[:2] or h.ndim not in (2, 3) or h.shape[2:] not in ((), (1,))):
        raise TGHopError(f"height must be the normal map's {arr.shape[0]}x{arr.shape[1]} pixels of one channel, "
                         f"got shape {h.shape}")
    step = max(1, int(np.ceil(np.sqrt(arr.shape[0] * arr.shape[1] / SAMPLE_PIXELS))))
    scale = np.iinfo(arr.dtype).max if arr.dtype.kind == "u" else 1.0
    n = arr[::step, ::step].astype(np.float64) * (2.0 / scale) - 1.0  # a large map read every step-th pixel
    if min(n.shape[:2]) < 3:
        return None
    nz = np.maximum(n[..., 2], 0.05)  # a slope's steepness bounded: a few sideways vectors do not decide
    sx, sy = n[..., 0] / nz, n[..., 1] / nz
    r = _correlation(np.gradient(sx, axis=0), np.gradient(sy, axis=1))
    found = None if r is None or abs(r) < CONVENTION_CORRELATION else "DirectX" if r > 0 else "OpenGL"
    if found is None or h is None:
        return found
    h = h.reshape(h.shape[:2])[::step, ::step].astype(np.float64)  # its scale and offset change no correlation
    rx = _correlation(sx, -np.gradient(h, axis=1))  # +1 in either convention
    ry = _correlation(sy, -np.gradient(h, axis=0))  # +1 DirectX's (y down the rows), -1 OpenGL's
    if rx is not None and rx <= -CONVENTION_CORRELATION:  # mirrored, turned a half, or the height inverted
        return None
    if ry is not None and abs(ry) >= CONVENTION_CORRELATION and (ry > 0) != (found == "DirectX"):
        return None
    return found


#: The channel of each packing (:func:`tghop.map_names.kind_key`) that holds the ambient occlusion: an ORM's (and
#: Poly Haven's ARM's) red, HDRP's mask map's green, an RMA's and an MRA's blue.
AO_CHANNEL = {"packed orm": 0, "packed maskmap": 1, "packed rma": 2, "packed mra": 2}


def surface_map(maps):
    """A material's map that shows its surface's shape, the second cue of :func:`convention_of` (0.60): its
    height map (white high), else its ambient occlusion (dark in the creases: its slopes follow the height's; an
    occlusion made from builtin bricks' and cells' example heights read 0.64-0.85), else a packing's occlusion
    (:data:`AO_CHANNEL`).

    Parameters
    ----------
    maps : iterable of (str, ndarray)
        Each map's name and pixels (H, W, C), the normal maps left out; a height or occlusion map of more
        than one channel is passed over.

    Returns
    -------
    ndarray, shape (H, W), or None
    """
    maps = list(maps)
    for want in ("height", "ao"):
        for name, img in maps:
            if kind_key(name) == want and img.shape[2] == 1:
                return img[..., 0]
    for name, img in maps:
        channel = AO_CHANNEL.get(kind_key(name))
        if channel is not None and img.shape[2] > channel:
            return img[..., channel]
    return None


def _correlation(a, b):
    """The correlation of two arrays' values, or None where either is constant."""
    a, b = a.ravel(), b.ravel()
    if a.std() == 0 or b.std() == 0:
        return None
    return float(np.corrcoef(a, b)[0, 1])


#: EXIF orientations whose quarter turn or transposition swaps a normal map's red and green.
TRANSPOSING = (5, 6, 7, 8)
#: The orientation that turns an upright image back as it was stored (the quarter turns swap).
STORED = {6: 8, 8: 6}


def upright_vectors(values, orientation, convention):
    """A normal map's vectors turned as :func:`tghop.image_decode.upright` turned its pixels.

    Parameters
    ----------
    values : ndarray, shape (H, W, 3)
        The upright pixels: vectors encoded as ``(n + 1) / 2``, floats in [0, 1] or unsigned
        integers at their full range.
    orientation : int
        The EXIF orientation the pixels were turned by (1-8; another value: none).
    convention : {"OpenGL", "DirectX"} or None
        The map's (y up or down the rows); needed only for orientations 5 to 8.

    Returns
    -------
    ndarray, the shape and dtype of ``values`` (``values`` itself for orientation 1)
    """
    if orientation not in range(2, 9):
        return values
    if orientation in TRANSPOSING and convention not in ("OpenGL", "DirectX"):
        raise TGHopError(f"a normal map turned by EXIF orientation {orientation} needs its convention, 'OpenGL' or "
                         f"'DirectX', got {convention!r}")
    full = values.dtype.type(np.iinfo(values.dtype).max if values.dtype.kind == "u" else 1.0)
    gl = convention == "OpenGL"
    x, y = (0, False), (1, gl)  # (channel, negated): worked in DirectX's frame, y down the rows as the pixels'
    if orientation in TRANSPOSING:  # as upright turns the pixels: rows and columns swapped first, then as 1-4
        x, y = y, x
        orientation -= 4
    if orientation in (2, 3):  # columns mirrored
        x = (x[0], not x[1])
    if orientation in (3, 4):  # rows mirrored
        y = (y[0], not y[1])
    y = (y[0], y[1] != gl)  # back to the map's convention
    out = values.copy()
    for i, (c, negated) in enumerate((x, y)):
        out[..., i] = full - values[..., c] if negated else values[..., c]
    return out


def upright_normal_map(values, path, *, convention=None, label="the normal map"):
    """A normal map read from ``path`` (:func:`tghop.imageio.load_image`: its pixels turned upright
    by its EXIF orientation), its vectors turned with them (:func:`upright_vectors`).

    Parameters
    ----------
    values : ndarray, shape (H, W, C)
        As read; a map of other than 3 channels is returned as it is (refused as a normal map later).
    path : str or os.PathLike
        The file, whose orientation is read (its header only).
    convention : {"OpenGL", "DirectX"} or None
        The map's by its name (:func:`tghop.map_names.normal_convention`); None: read from its stored
        pixels' content (:func:`convention_of`) where a quarter turn needs it.
    label : str
        How a message names the map (``"--maps rock_nrm.jpg"``).

    Returns
    -------
    ndarray

    Raises
    ------
    TGHopError
        A map turned a quarter (orientations 5-8) whose convention neither its name nor its content says.
    """
    if values.ndim != 3 or values.shape[2] != 3:
        return values
    orientation = file_header(path)[0]
    if orientation in TRANSPOSING and convention is None:
        convention = convention_of(upright(values, STORED.get(orientation, orientation)))
        if convention is None:
            raise TGHopError(f"{label} is stored turned (EXIF orientation {orientation}) and neither its name nor its "
                             "content says its convention, so its vectors cannot be turned with its pixels; save it "
                             "upright, or name it *_NormalGL (green up) or *_NormalDX (green down)")
    return upright_vectors(values, orientation, convention)


def convention_flips(materials):
    """Which normal maps of painted or remixed materials are flipped to the first one's convention (0.59):
    ``{id(material): [map names]}`` for every one of ``materials`` whose normal map is recorded in the other
    convention than the first material's map in its place (:attr:`tghop.material.Material.conventions_`, from
    its content or name; a map of no convention known is left as it is), with one warning for each saying
    which and how to paint in the other. 0.58 painted an OpenGL map beside a DirectX one silently, the
    slopes of one region upside down in the result."""
    import warnings

    first = materials[0]
    theirs = getattr(first, "conventions_", None) or [None] * len(first.names_)
    out = {}
    for i, mat in enumerate(materials[1:], start=2):
        mine = getattr(mat, "conventions_", None) or [None] * len(mat.names_)
        flipped = [(name, own, want) for name, own, want, normal in zip(mat.names_, mine, theirs, mat.normal_)
                   if normal and own and want and own != want]
        if flipped and id(mat) not in out:
            said = ", ".join(f"{name!r} ({own})" for name, own, _ in flipped)
            warnings.warn(f"input {i}'s normal map {said} is in the other convention than input 1's "
                          f"({flipped[0][2]}); its green is flipped, so that the painted map is "
                          f"{flipped[0][2]}'s throughout (give a {flipped[0][1]} material first to paint in "
                          f"{flipped[0][1]}'s)", UserWarning, stacklevel=3)
        out.setdefault(id(mat), [name for name, _, _ in flipped])
    return out


def flip_green(values):
    """A normal map's pixels (H, W, 3) in [0, 1] in the other convention: green (y) inverted, a new array."""
    out = np.array(values, copy=True)
    out[..., 1] = 1 - out[..., 1]
    return out


#: A normal map's vectors (``2 v - 1``) must have a median length within this of 1.
NORMAL_TOLERANCE = 0.1
#: An image whose pixels, all but this share, are unit vectors facing up (``2 v - 1`` of length
#: within 0.15 of 1, blue at least 0.5) and whose mean red and green lie within
#: NORMAL_LOOK_MEAN of 0.5 (its slopes cancel out) is a normal map by its content
#: (:func:`looks_like_normal_map`). Of the 44 exemplars, the closest photograph had 95 % of such
#: pixels (water_caustics: mean red 0.04); the next 71 %.
NORMAL_LOOK_SHARE = 0.9
NORMAL_LOOK_MEAN = 0.1


def looks_like_normal_map(image) -> bool:
    """Whether an image's content is a tangent-space normal map (whatever its name): at least
    :data:`NORMAL_LOOK_SHARE` of its pixels unit vectors encoded as ``(n + 1) / 2`` facing up
    (blue at least 0.5), and its mean red and green within :data:`NORMAL_LOOK_MEAN` of 0.5: the
    blue-violet of a normal map, mean about (0.5, 0.5, 1). ``tghop synth`` warns by it, as by
    :func:`tghop.map_names.map_kind`, of a remix of a material's maps.

    Parameters
    ----------
    image : array_like, shape (H, W, C)
        Floats in [0, 1], or unsigned integers at their full range (8 or 16 bits); only an image of
        3 channels can be one (every other pixel of every other row is read).

    Returns
    -------
    bool
    """
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.size == 0 or arr.dtype.kind not in "uf":
        return False
    v = arr[::2, ::2].reshape(-1, 3).astype(np.float64)
    if arr.dtype.kind == "u":
        v /= np.iinfo(arr.dtype).max
    length = np.linalg.norm(v * 2.0 - 1.0, axis=1)
    unit_up = (np.abs(length - 1.0) <= 0.15) & (v[:, 2] >= 0.5)
    mean = v.mean(axis=0)
    return bool(unit_up.mean() >= NORMAL_LOOK_SHARE and np.abs(mean[:2] - 0.5).max() <= NORMAL_LOOK_MEAN)


def check_normal_map(values, name: str = "normal map"):
    """Refuse a "normal map" that does not hold unit vectors (one-line :class:`TGHopError`).

    Parameters
    ----------
    values : ndarray, shape (H, W, 3), float in [0, 1]
        Vectors encoded as ``(n + 1) / 2``.
    name : str
    """
    if values.shape[2] != 3:
        raise TGHopError(f"map {name!r} is a normal map by its name but has {values.shape[2]} channel"
                         f"{'s' if values.shape[2] != 1 else ''}, not 3; rename it if it is not a normal map")
    length = np.linalg.norm(values[::2, ::2].reshape(-1, 3) * 2.0 - 1.0, axis=1)
    median = float(np.median(length))
    if abs(median - 1.0) > NORMAL_TOLERANCE:
        raise TGHopError(f"map {name!r} is a normal map by its name but its pixels are not unit vectors "
                         f"(median length {median:.2f}, not 1 +- {NORMAL_TOLERANCE}); give a normal map encoded "
                         "as (n + 1) / 2, or rename it if it is not one")


def renormalise(values, out=None):
    """Normal map values (H, W, 3) in [0, 1] -> the same directions as unit vectors, encoded
    as ``(n + 1) / 2`` (a zero vector becomes (0, 0, 1), straight up).

    Parameters
    ----------
    values : array_like, shape (H, W, 3), float in [0, 1]
        Vectors encoded as ``(n + 1) / 2``, of any length (computed in float64).
    out : ndarray, shape (H, W, 3), optional
        Where to write the result (it may be ``values`` itself); None: a new float64 array.

    Returns
    -------
    ndarray, shape (H, W, 3), float in [0, 1]
        ``out`` when given, else a new float64 array.
    """
    n = np.asarray(values, dtype=np.float64) * 2.0 - 1.0
    length = np.linalg.norm(n, axis=2, keepdims=True)
    flat = length[..., 0] < 1e-6
    n[flat] = (0.0, 0.0, 1.0)
    length[flat] = 1.0
    n /= length
    n += 1.0
    n *= 0.5
    if out is None:
        return np.clip(n, 0.0, 1.0)
    out[...] = np.clip(n, 0.0, 1.0)
    return out
