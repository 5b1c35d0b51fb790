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

import os
import re
from pathlib import Path

from ._errors import TGHopError

__all__ = ["ALBEDO", "MAP_NAME", "MAP_NAME_MAX", "MAP_KINDS", "NORMAL_WORDS", "CONVENTION_WORDS", "map_kind",
           "name_kind", "kind_key", "map_name", "colour_map_out_of_place", "check_colour_map_order",
           "COLOUR_MAP_WORDS", "MapNameClashError", "check_map_names",
           "is_normal_name", "normal_convention", "is_data_map", "COLOUR_KINDS", "SCALAR_KINDS", "ALPHA_KINDS",
           "keeps_alpha"]

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
    "packed": ("orm", "arm", "rma", "mra", "maskmap", "metallicsmoothness"),
}
#: The kinds of map (:data:`MAP_KINDS`) whose alpha channel holds a map of its own by their packing, kept as a
#: 4th channel where it holds data (0.59): a packed map (HDRP's ``_MaskMap``: metallic, AO, detail mask and
#: smoothness in R, G, B, A; an ORM or ARM with a 4th map) and a metallic map (Unity's metallic-smoothness:
#: ``_Metallic`` or ``_MetallicSmoothness``, metalness in R, smoothness in A). Every other map's alpha that holds
#: data is refused (:func:`tghop.material.drop_opaque_alpha`).
ALPHA_KINDS = ("packed", "metallic")
#: The kinds of map (:data:`MAP_KINDS`) that hold colours, read as the albedo is (an ICC profile or a
#: PNG's gamma converted to sRGB, :mod:`tghop.profiles`): the albedo's and an emission map's, as
#: Blender's Node Wrangler sets every other map's colour space to Non-Color.
COLOUR_KINDS = (ALBEDO, "emission")
#: The kinds of map (:data:`MAP_KINDS`) that hold one value a pixel (grey, stored as 1 channel or as 3 equal
#: ones): :meth:`tghop.material.Material.fit` warns of one whose channels differ as a colour image's (0.58).
#: Not a specular map (a metal's specular colour is a colour), a packed map or a map of no kind.
SCALAR_KINDS = ("roughness", "height", "ao", "metallic", "opacity")
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
    return _kind_word(name)[0]


def _kind_word(name):
    """``(kind, word)``: :func:`name_kind`'s kind and the word of :data:`MAP_KINDS` it read, or (None, None)."""
    words = _kind_words(name)
    if len(words) > 1 and words[-1] in CONVENTION_WORDS:  # rock_nor_gl_2k, Rock_Normal_DX
        words.pop()
    if not words:
        return None, None
    last = words[-1]
    for kind, names in MAP_KINDS.items():
        if last in names:
            return kind, last
        word = next((word for word in names if len(word) >= 5 and last.endswith(word)), None)
        if word is not None:
            return kind, word
    return None, None


#: Words of one kind (:data:`MAP_KINDS`) whose maps hold other values, each matched apart by :func:`kind_key`
#: (a packing's other words are each their own): glossiness is not a specular colour, and Poly Haven's ARM is an
#: ORM (occlusion, roughness, metalness in R, G, B) where an RMA or HDRP's mask map packs others.
KIND_SENSES = {"gloss": "glossiness", "glossiness": "glossiness", "arm": "orm"}


def kind_key(name):
    """What a map of this name holds, as two materials' maps are matched by their kinds when they are
    painted or remixed together (:func:`tghop.material_files.map_keys`, 0.59): its kind (:func:`name_kind`:
    ``Stone_NormalGL`` and Poly Haven's ``gravel_nor_gl_2k`` are both ``"normal"``, ``_Rough`` and
    ``_Roughness`` both ``"roughness"``), a packed map's packing after it (``"packed orm"``: ORM and ARM
    alike) and a glossiness map apart from a specular one (:data:`KIND_SENSES`); None for a name of no kind.

    Parameters
    ----------
    name : str
        A map's name (:func:`map_name`).

    Returns
    -------
    str or None

    Examples
    --------
    >>> from tghop.map_names import kind_key
    >>> kind_key("Rock_NormalGL"), kind_key("rock_arm_2k"), kind_key("T_Rock_ORM"), kind_key("Rock_Gloss")
    ('normal', 'packed orm', 'packed orm', 'glossiness')
    """
    kind, word = _kind_word(name)
    sense = KIND_SENSES.get(word, word)
    if kind == "packed":
        return f"packed {sense}"
    return sense if kind == "specular" and sense == "glossiness" else kind


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
    return _whole_name(path)[:MAP_NAME_MAX] or "map"


def _whole_name(path) -> str:
    """:func:`map_name` before it is cut to :data:`MAP_NAME_MAX` characters (and without its "map")."""
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", Path(path).stem)
    return re.sub(r"^[^A-Za-z0-9]+", "", stem)


def colour_map_out_of_place(albedo, maps, names=None):
    """Whether a material's files, by their names (:func:`map_kind`), give its colour map out of
    place: the albedo's file (the exemplar, first) named as another kind of map (``Rock_Roughness.png``).
    :func:`check_colour_map_order` says what it means (refused or warned of), for ``tghop fit --maps``,
    ``inpaint``/``extend --maps``, a batch manifest's row and the web server's fit with maps.

    Parameters
    ----------
    albedo : str or os.PathLike
        The albedo's file (only its name is read).
    maps : sequence of str or os.PathLike
        The maps' files, in the order given.
    names : sequence of str or None
        The maps' names where they are given apart from their files (a manifest's ``color=Rock_C.png``,
        the web server's ``map:<name>`` fields): a map's kind is its name's (:func:`name_kind`), else, for
        a name of no kind, its file's. None: the files' names alone.

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
    >>> colour_map_out_of_place("Rock_Roughness.png", ["Rock_C.png"], names=["color"])
    ('roughness', 'Rock_C.png')
    >>> colour_map_out_of_place("Rock_Color.png", ["Rock_NormalGL.png"]) is None
    True
    """
    kind = map_kind(albedo)
    if kind in (None, ALBEDO):
        return None
    names = [None] * len(maps) if names is None else list(names)
    return kind, next((path for path, name in zip(maps, names)
                       if ((name_kind(name) if name else None) or map_kind(path)) == ALBEDO), None)


#: The words of :func:`check_colour_map_order`'s messages that a caller may give in its user's terms
#: (format strings of ``{albedo}``, ``{colour}``, ``{maps}`` and ``{others}``: the albedo's file, the map
#: named as the colour map, every map, and every file but that map, as the caller shows them): how the
#: albedo and a map are named, what "no map" is, the fix of each refusal, where the albedo is written and
#: where the colour map goes (``expected``), and what follows the expected names in a warning (``then``).
COLOUR_MAP_WORDS = {
    "albedo": "the exemplar {albedo}",
    "map": "the map {colour}",
    "none": "no map",
    "swap": "give {colour} as the exemplar and {albedo} as a map",
    "first": "give the material's colour map as the exemplar (e.g. Rock_Color.png) and {albedo} as a map",
    "written": "its images' albedo",
    "expected": "as the exemplar",
    "then": "",
}


def check_colour_map_order(albedo_path, maps, /, *, names=None, shown=None, **words):
    """Refuse a material whose colour map is out of place by its files' names, or word what to warn
    of: the one reading (:func:`colour_map_out_of_place`) and the one wording of ``tghop fit --maps``,
    ``inpaint``/``extend --maps``, a batch manifest's row and the web server's fit, each naming the files
    and the fix in its user's terms (``words``). Refused, as one line: a map named as the colour map
    while the albedo's file is named as another kind (the two swapped), and the albedo's file named as a
    normal map with no map named as the colour map (its vectors would be modelled as the albedo's
    colours, not kept unit vectors). Warned of: the albedo's file named as another kind
    (``Rock_Roughness.png``) and no map as the colour map; it is fitted as the colour map, as asked (a
    material may have none, and a file may be misnamed).

    Parameters
    ----------
    albedo_path : str or os.PathLike
        The albedo's file, as the message shows it (only its name is read).
    maps : sequence of str or os.PathLike
        The maps' files, in the order given.
    names : sequence of str or None
        As :func:`colour_map_out_of_place`'s: the maps' names where given apart from their files.
    shown : sequence of str or None
        How the message shows each map (a file's name without its folder, a request's field); None: ``maps``.
    **words : str
        Any of :data:`COLOUR_MAP_WORDS`, in the caller's terms (``albedo="EXEMPLAR {albedo}"``).

    Returns
    -------
    str or None
        The warning's one line (the caller warns, or notes it, in its way), or None: nothing to say.

    Raises
    ------
    TGHopError
        The colour map among the maps, or a normal map as the albedo with no colour map: one line
        naming the fix.

    Examples
    --------
    >>> from tghop.map_names import check_colour_map_order
    >>> print(check_colour_map_order("Rock_Roughness.png", ["Rock_NormalGL.png"]))  # fitted, with this warning
    the exemplar Rock_Roughness.png is named as a roughness map and no map as the colour map; it is ...
    >>> check_colour_map_order("Rock_Roughness.png", ["Rock_Color.png"])
    Traceback (most recent call last):
    ...
    tghop._errors.TGHopError: the exemplar Rock_Roughness.png is named as a roughness map and ... as a map
    >>> check_colour_map_order("Rock_Color.png", ["Rock_Roughness.png"]) is None
    True
    """
    unknown = set(words) - set(COLOUR_MAP_WORDS)
    if unknown:
        raise TypeError(f"check_colour_map_order() got unknown words {sorted(unknown)}; it takes "
                        f"{', '.join(COLOUR_MAP_WORDS)}")
    maps = list(maps)
    found = colour_map_out_of_place(albedo_path, maps, names)
    if found is None:
        return None
    kind, colour = found
    shown = [str(m) for m in (maps if shown is None else shown)]
    at = None if colour is None else next(i for i, m in enumerate(maps) if m is colour)
    values = {"albedo": str(albedo_path), "colour": None if at is None else shown[at], "maps": " ".join(shown),
              "others": " ".join([str(albedo_path), *(m for i, m in enumerate(shown) if i != at)])}
    said = {key: text.format(**values) for key, text in {**COLOUR_MAP_WORDS, **words}.items()}
    if colour is not None:
        raise TGHopError(f"{said['albedo']} is named as a {kind} map and {said['map']} as the colour map; the albedo "
                         f"comes first: {said['swap']}")
    if kind == "normal":
        raise TGHopError(f"{said['albedo']} is named as a normal map and {said['none']} as the colour map (a normal "
                         f"map fitted as the albedo is modelled as colours, not unit vectors); {said['first']}")
    return (f"{said['albedo']} is named as a {kind} map and {said['none']} as the colour map; it is fitted as the "
            f"colour map ({said['written']}); tghop expects the colour map {said['expected']} (named *_Color, "
            f"*_BaseColor, *_Albedo, *_diff, ...){said['then']}, or rename the file if it is the colour map")


class MapNameClashError(TGHopError):
    """Two maps of a material named alike (in any case), or a map named as the albedo
    (:func:`check_map_names`). Its ``name`` (as given), ``index`` (that name's place in the names
    checked), ``albedo`` (True: the name is the albedo's, else an earlier map's), ``other`` (the
    earlier name, or "albedo"), ``clash`` (the clash in words: "two maps are named 'n' and 'N', which
    differ only in case ...", 0.61; 0.60 said "two maps are named 'N'" of those), ``fix`` and ``cut`` (two
    files' stems alike in the first :data:`MAP_NAME_MAX` characters, the names cut from them) let a
    caller word the message its user reads, naming what was given (a manifest's line, a command's
    files, a request's fields)."""


def check_map_names(names, files=None) -> None:
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
    files : sequence of (str, os.PathLike or None), optional
        Each map's file where its name is the file's (:func:`map_name`; None where it was named otherwise):
        two files whose stems differ only past :data:`MAP_NAME_MAX` characters are said so (``cut``; 0.61).

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
    tghop.map_names.MapNameClashError: two maps are named 'normal' and 'Normal', which differ only in case (one \
file name where case is ignored); give each map its own name, not only in case
    """
    seen = {}
    for index, name in enumerate(names):
        key = name.lower()
        if key == ALBEDO or key in seen:
            albedo = key == ALBEDO
            other, at = (ALBEDO, None) if albedo else seen[key]
            pair = [files[i] for i in (at, index)] if files is not None and at is not None else [None, None]
            cut = None not in pair and len({_whole_name(f).lower() for f in pair}) == 2
            if cut:  # 0.60: "two maps are named 'X'" of two files whose stems differ past the 64th character
                clash = (f"the maps' files {os.fsdecode(pair[0])} and {os.fsdecode(pair[1])} give one name, {name!r} "
                         f"(a map's name is its file stem's first {MAP_NAME_MAX} characters)")
                fix = f"give files whose stems differ in their first {MAP_NAME_MAX} characters"
            elif albedo:  # a name kept for the albedo (OUT's own file), in any case
                clash = f"a map is named {name!r}, the albedo's name{'' if name == ALBEDO else ' in another case'}"
                fix = "give each map its own name"
            elif other == name:
                clash, fix = f"two maps are named {name!r}", "give each map its own name"
            else:
                clash = (f"two maps are named {other!r} and {name!r}, which differ only in case (one file name "
                         "where case is ignored)")
                fix = "give each map its own name, not only in case"
            exc = MapNameClashError(f"{clash}; {fix}")
            exc.name, exc.index, exc.albedo, exc.other, exc.clash, exc.fix = name, index, albedo, other, clash, fix
            exc.cut = cut
            raise exc
        seen[key] = (name, index)


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


def keeps_alpha(name: str) -> bool:
    """Whether a material's map of this name keeps an alpha channel that holds data as a channel of its own
    (:data:`ALPHA_KINDS`: Unity's metallic-smoothness, HDRP's mask map, a packed map; 0.59), where any other
    map's is refused (:func:`tghop.material.drop_opaque_alpha`). A normal map's never.

    Parameters
    ----------
    name : str
        A map's name (:func:`map_name`).

    Returns
    -------
    bool

    Examples
    --------
    >>> from tghop.map_names import keeps_alpha
    >>> [keeps_alpha(n) for n in ("Rock_Metallic", "Rock_MaskMap", "T_Rock_ORM", "Rock_Roughness")]
    [True, True, True, False]
    """
    return not is_normal_name(name) and name_kind(name) in ALPHA_KINDS


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
