"""The names of a material's maps, read from their input files' names (the output files' names are
:mod:`tghop.material_files`'s): the kind of map a file's name says (:func:`map_kind`: albedo,
normal, roughness, ... by :data:`MAP_KINDS`), a map's name made from its file's (:func:`map_name`),
the check that no two maps are named alike (:func:`check_map_names`), and what a normal map's name
says (:func:`is_normal_name`, :func:`normal_convention`). Names only: no image is read here (a map's
content is :mod:`tghop.material`'s and :mod:`tghop.normals`' to read).

Example
-------
>>> from tghop.map_names import map_kind, map_name
>>> map_kind("Rock023_2K_NormalGL.png"), map_name("Rock Normal.png")
('normal', 'Rock_Normal')
"""

from __future__ import annotations

import re
from pathlib import Path

from ._common import TGHopError

__all__ = ["ALBEDO", "MAP_NAME", "MAP_NAME_MAX", "MAP_KINDS", "NORMAL_WORDS", "CONVENTION_WORDS", "map_kind",
           "name_kind", "map_name", "colour_map_out_of_place", "MapNameClashError", "check_map_names",
           "is_normal_name", "normal_convention", "is_data_map", "COLOUR_KINDS"]

#: The name of the first map (the exemplar itself, written to ``-o``'s file).
ALBEDO = "albedo"
#: Words in a map's name that make it a normal map.
NORMAL_WORDS = ("normal", "nrm")
#: Map names: what a file name can hold (they name the maps' files: :func:`tghop.material_files.map_files`).
MAP_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
#: Longest name :func:`map_name` gives a map's file (and the web server takes in a request).
MAP_NAME_MAX = 64
#: The words a material's map files are commonly named with (the last word of the file's stem, any
#: case, or its end when it has five letters or more: ``RockNormal``), by the kind of map they name:
#: what :func:`map_kind` reads. Not a limit on a material's maps (any name is one); ``tghop synth``
#: warns by them that a remix of such files is no material.
MAP_KINDS = {
    ALBEDO: ("albedo", "basecolor", "basecolour", "diffuse", "diff", "color", "colour", "col", "bc"),
    "normal": ("normal", "normalgl", "normaldx", "nrm", "nrml", "nor", "norm", "n"),
    "roughness": ("roughness", "rough", "rgh"),
    "height": ("height", "displacement", "disp", "bump"),
    "ao": ("ao", "occlusion", "ambientocclusion"),
    "metallic": ("metallic", "metalness", "metal"),
    "specular": ("specular", "spec", "glossiness", "gloss"),
    "opacity": ("opacity",),
    "emission": ("emission", "emissive"),
    "packed": ("orm", "arm", "rma", "mra"),
}
#: The kinds of map (:data:`MAP_KINDS`) that hold colours, read as the albedo is (an ICC profile or a
#: PNG's gamma converted to sRGB, :mod:`tghop.profiles`): the albedo's and an emission map's, as
#: Blender's Node Wrangler sets every other map's colour space to Non-Color.
COLOUR_KINDS = (ALBEDO, "emission")
#: Words after a normal map's name that say its convention (Poly Haven's ``rock_nor_gl_2k``): passed over.
CONVENTION_WORDS = {"gl": "OpenGL", "ogl": "OpenGL", "opengl": "OpenGL", "dx": "DirectX", "directx": "DirectX"}


def _kind_words(stem):
    """The words of a file's stem, lower case, without a trailing resolution (``2K``, ``1024``)."""
    words = [w for w in re.split(r"[^a-z0-9]+", stem.lower()) if w]
    while len(words) > 1 and re.fullmatch(r"\d+k?", words[-1]):  # rock_diff_2k, Rock_Color_1024
        words.pop()
    return words


def name_kind(name):
    """The kind of a material's map (a key of :data:`MAP_KINDS`) that a map's name, or a file's
    stem, ends in, or None: :func:`map_kind` of a name that is not a file's, read whole (a map's
    name may hold a ``.``: ``Rock.Normal`` -> ``"normal"``, where ``map_kind("Rock.Normal")``
    reads ``.Normal`` as the file's extension and the stem ``Rock`` as no kind).

    Parameters
    ----------
    name : str
        A map's name (:func:`map_name`) or a file's stem.

    Returns
    -------
    str or None

    Examples
    --------
    >>> from tghop.map_names import name_kind
    >>> name_kind("rock_wall_nor_gl_2k"), name_kind("Rock.Normal"), name_kind("bricks")
    ('normal', 'normal', None)
    """
    words = _kind_words(name)
    if len(words) > 1 and words[-1] in CONVENTION_WORDS:  # rock_nor_gl_2k, Rock_Normal_DX
        words.pop()
    if not words:
        return None
    last = words[-1]
    for kind, names in MAP_KINDS.items():
        if last in names or any(len(word) >= 5 and last.endswith(word) for word in names):
            return kind
    return None


def map_kind(path):
    """The kind of a material's map (a key of :data:`MAP_KINDS`) that file ``path``'s name ends
    in, or None: ``rock_albedo.png`` -> ``"albedo"``, ``Rock_NormalGL_2K.jpg`` -> ``"normal"``
    (a trailing resolution, ``2K`` or ``1024``, is passed over, and so is a normal map's convention
    after its name: Poly Haven's ``rock_nor_gl_2k.png``), Unreal's ``T_Rock_N.png`` -> ``"normal"``,
    ``T_Rock_ORM.png`` -> ``"packed"`` (occlusion, roughness and metalness in R, G, B), ``bricks.jpg``
    -> None. A map's name, which is no file's, is read by :func:`name_kind`.

    Parameters
    ----------
    path : str or os.PathLike
        A file; only its name is read (the file need not exist).

    Returns
    -------
    str or None
    """
    return name_kind(Path(path).stem)


def map_name(path) -> str:
    """The name of the map in file ``path``: its stem, other characters than letters, digits,
    ``.``, ``_`` and ``-`` as ``_``, without a leading ``.``, ``_`` or ``-``, at most 64
    characters ("map" when nothing is left): ``Rock Normal.png`` -> ``Rock_Normal``. What
    ``tghop fit --maps``, ``inpaint --maps``, a batch manifest and the web page name a map by.

    Parameters
    ----------
    path : str or os.PathLike
        A map's file; only its name is read (the file need not exist).

    Returns
    -------
    str
        The map's name, 1 to 64 characters of ``[A-Za-z0-9._-]``, starting with a letter or digit.
    """
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", Path(path).stem)
    return re.sub(r"^[^A-Za-z0-9]+", "", stem)[:MAP_NAME_MAX] or "map"


def colour_map_out_of_place(albedo, maps):
    """Whether a material's files, by their names (:func:`map_kind`), give its colour map out of
    place: the albedo's file (the exemplar, first) named as another kind of map (``Rock_Roughness.png``).
    ``tghop fit --maps``, ``inpaint``/``extend --maps``, a batch manifest's row and the web server's
    fit with maps each word what they say of it (refused or warned of).

    Parameters
    ----------
    albedo : str or os.PathLike
        The albedo's file (only its name is read).
    maps : sequence of str or os.PathLike
        The maps' files, in the order given.

    Returns
    -------
    tuple (str, path or None) or None
        None where the albedo's file is named as the colour map or as no kind; else the kind it is
        named as and the first of ``maps`` named as the colour map (None: none is).

    Examples
    --------
    >>> from tghop.map_names import colour_map_out_of_place
    >>> colour_map_out_of_place("Rock_Roughness.png", ["Rock_NormalGL.png"])
    ('roughness', None)
    >>> colour_map_out_of_place("Rock_Color.png", ["Rock_NormalGL.png"]) is None
    True
    """
    kind = map_kind(albedo)
    if kind in (None, ALBEDO):
        return None
    return kind, next((path for path in maps if map_kind(path) == ALBEDO), None)


class MapNameClashError(TGHopError):
    """Two maps of a material named alike (in any case), or a map named as the albedo
    (:func:`check_map_names`). Its ``name`` (as given), ``index`` (that name's place in the names
    checked) and ``albedo`` (True: the name is the albedo's, else an earlier map's) let a caller
    word the message its user reads, naming what was given (a manifest's line, a command's
    files, a request's fields)."""


def check_map_names(names) -> None:
    """Refuse names of a material's maps that name two maps alike, or a map as the albedo, in
    any case: each name names its map's file (:func:`tghop.material_files.map_files`; the albedo's
    is ``OUT`` itself), so two would be one file, on a file system that ignores case too.
    The one check of ``tghop fit/inpaint/extend --maps``, a batch manifest's ``maps``, the web
    server's ``map:<name>`` fields and :meth:`tghop.material.Material.fit`, each wording it for its user.

    Parameters
    ----------
    names : sequence of str
        The maps' names (the albedo's not among them), in the order given; their form is
        not checked here (:data:`MAP_NAME`).

    Raises
    ------
    MapNameClashError
        At the first name that is the albedo's or an earlier one's (``index``: its place).

    Examples
    --------
    >>> from tghop.map_names import check_map_names
    >>> check_map_names(["normal", "Normal"])
    Traceback (most recent call last):
    ...
    tghop.map_names.MapNameClashError: two maps are named 'Normal' (in any case); give each map its own name
    """
    seen = set()
    for index, name in enumerate(names):
        key = name.lower()
        if key == ALBEDO or key in seen:
            albedo = key == ALBEDO
            exc = MapNameClashError(f"a map is named {name!r}, the albedo's name; give each map its own name" if albedo
                                    else f"two maps are named {name!r} (in any case); give each map its own name")
            exc.name, exc.index, exc.albedo = name, index, albedo
            raise exc
        seen.add(key)


def is_normal_name(name: str) -> bool:
    """Whether a map's name says it is a normal map: "normal" or "nrm" anywhere (any case), or a
    normal map's word at its end as :func:`map_kind` reads it (``rock_nor_gl_2k``, ``T_Rock_N``).

    Parameters
    ----------
    name : str
        A map's name (:func:`map_name`).

    Returns
    -------
    bool
        True when ``name`` contains one of the words, anywhere (``"RockNormalGL"`` is one), or ends
        in a normal map's word (``"rock_nor_dx_2k"``, ``"T_Rock_N"``).
    """
    return any(word in name.lower() for word in NORMAL_WORDS) or name_kind(name) == "normal"


def is_data_map(name: str) -> bool:
    """Whether a material's map of this name holds data rather than colours, and is read with its
    values as stored (:func:`tghop.imageio.load_image`'s ``as_data``: no ICC profile or PNG gamma
    applied): every map but one whose name :func:`name_kind` reads as one of :data:`COLOUR_KINDS`
    (a name of no kind is data too; a normal map's, :func:`is_normal_name`, always). Converted as
    colours, a normal map's vectors were no longer unit length, and a roughness's, metalness's or
    height's values no longer what they measure (0.57).

    Parameters
    ----------
    name : str
        A map's name (:func:`map_name`).

    Returns
    -------
    bool

    Examples
    --------
    >>> from tghop.map_names import is_data_map
    >>> [is_data_map(n) for n in ("Rock_NormalGL", "rock_rough_2k", "mask", "Rock_Emission")]
    [True, True, True, False]
    """
    return is_normal_name(name) or name_kind(name) not in COLOUR_KINDS


def normal_convention(name: str):
    """The convention a normal map's name says it is in: ``"OpenGL"`` (green up: Blender, Unity,
    ambientCG's ``NormalGL``, Poly Haven's ``nor_gl``), ``"DirectX"`` (green down: Unreal,
    ``NormalDX``, ``nor_dx``) or None (not said). tghop keeps a normal map's convention: its
    output is in the convention of its input, whatever this says.

    Parameters
    ----------
    name : str
        A map's name (:func:`map_name`).

    Returns
    -------
    str or None
    """
    words = _kind_words(name)
    if len(words) > 1 and words[-1] in CONVENTION_WORDS:
        return CONVENTION_WORDS[words[-1]]
    last = words[-1] if words else ""
    return "OpenGL" if last.endswith("normalgl") else "DirectX" if last.endswith("normaldx") else None
