"""A material's files: one map read from its file (:func:`read_map`: as data or colours by its
name, at its depth, its alpha and turn seen to), and the output files a material's maps are written to
(:func:`map_files`; what an input map's file name says is :mod:`tghop.map_names`'s): the albedo at the output
itself, ``OUT``, each other map at ``OUT_<suffix>``, its name without the material's name and
resolution that the maps' names share, as an importer (Blender's Node Wrangler, a game
engine's) reads a material's files: ``-o Rock.png`` of ``Rock023_2K_NormalGL`` and
``Rock023_2K_Roughness`` is ``Rock_NormalGL.png`` and ``Rock_Roughness.png``.
``tghop synth``, ``paint``, ``remix``, ``inpaint`` and ``extend --maps``, ``tghop batch`` and the
web page's downloads all name a material's files by it, and ``tghop fit``, ``inpaint`` and ``extend
--maps``, a batch manifest's row and the web server's fit and fill read each map by :func:`read_map`.

Example
-------
>>> from tghop.material_files import map_files
>>> map_files("Rock.png", ["albedo", "Rock023_2K_NormalGL", "Rock023_2K_Roughness"])
['Rock.png', 'Rock_NormalGL.png', 'Rock_Roughness.png']
>>> map_files("out.png", ["albedo", "normal", "height"])
['out.png', 'out_normal.png', 'out_height.png']
"""

from __future__ import annotations

import re
from pathlib import Path

from .map_names import kind_key, name_kind, normal_convention

__all__ = ["read_map", "map_files", "map_suffixes", "map_keys", "maps_compared", "maps_refused", "RESOLUTION",
           "NORMAL_BY_NAME"]

#: A word of a map's name that is a resolution (``2K``, ``4k``, ``1024``, ``2048x2048``): dropped at
#: either end of a map's suffix (Poly Haven's ``rock_wall_nor_gl_2k`` is ``nor_gl``).
RESOLUTION = re.compile(r"\d+[kK]?|\d+[xX]\d+")
#: The words of a map's name: runs between ``.``, ``_`` and ``-``.
WORD = re.compile(r"[^._-]+")


def read_map(path, name, *, normal=None, label=None, downscale=False, too_large_hint=None) -> tuple:
    """One map of a material read from its file, as every reader of a material's maps reads it
    (``tghop fit``, ``inpaint`` and ``extend --maps``, a batch manifest's row, the web server's fit
    and fill): a model file refused; the values as stored where the map's name says data, converted
    to sRGB as any colour image where it says colours (:func:`tghop.map_names.is_data_map`); 8-bit
    kept as uint8, 16-bit and float files as floats, and their depth returned; an alpha channel
    dropped where every pixel is opaque and refused where it holds data, unless the name says a packing
    with a map in A (Unity's metallic-smoothness, HDRP's mask map: kept;
    :func:`tghop.material.drop_opaque_alpha`); a normal map stored turned (an EXIF orientation) read
    upright with its vectors turned too (:func:`tghop.normals.upright_normal_map`, in the
    convention its name says, else its content's). Its size and whether a normal map holds unit
    vectors are the caller's to check (against the albedo: :meth:`tghop.material.Material.fit`).

    Parameters
    ----------
    path : str or os.PathLike
        The map's image file.
    name : str
        The map's name (:func:`tghop.map_names.map_name`, or the name a manifest, a saved material or a
        request gives it): it says whether the map holds data or colours, and a normal map's convention.
    normal : bool or None
        Whether the map is a normal map; None: as its name says (:func:`tghop.map_names.is_normal_name`).
        A saved material's maps are normal maps as it says (:attr:`tghop.material.Material.normal_`).
    label : str or None
        How a message names the map (``"--maps Rock_N.png"``); None: ``"the map NAME (PATH)"``.
    downscale : bool
        As :func:`tghop.imageio.load_image`'s: an image over the pixel limit reduced, with a warning.
    too_large_hint : str or None
        As :func:`tghop.imageio.load_image`'s; None: its default.

    Returns
    -------
    image : ndarray, shape (H, W, C)
        uint8 for an 8-bit file, else float64 in [0, 1]; ``C`` 1 or 3 (the alpha dropped), or 4 where the
        alpha holds data and the name says a packing with a map in A (:func:`tghop.map_names.keeps_alpha`, 0.59).
    depth : int
        The file's bits per channel: 8, 16 or 32 (float).

    Raises
    ------
    TGHopError
        One line starting with ``label``: a model file, an alpha channel that holds data, a turned
        normal map of no convention said or seen; :func:`tghop.imageio.load_image`'s errors (not an
        image, too large, a decoder missing) name the file.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from tghop import data
    >>> from tghop.imageio import save_image
    >>> from tghop.material_files import read_map
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "Rock_Roughness.png"
    >>> save_image(data.bricks(64)[..., :1], path, depth=16)
    >>> image, depth = read_map(path, "Rock_Roughness")
    >>> image.shape, image.dtype.name, depth
    ((64, 64, 1), 'float64', 16)
    """
    from ._errors import TGHopError
    from ._formats import is_model_file, model_file_kind
    from .imageio import load_image
    from .map_names import is_data_map, is_normal_name, keeps_alpha, normal_convention
    from .material import drop_opaque_alpha
    from .normals import upright_normal_map

    label = f"the map {name} ({path})" if label is None else label
    if is_model_file(path):  # by its first bytes: a zip archive
        raise TGHopError(f"{label} is {model_file_kind(path)}, not an image; give the map's image")
    hint = {} if too_large_hint is None else {"too_large_hint": too_large_hint}
    image, depth = load_image(path, dtype=None, downscale=downscale, with_depth=True, keep_alpha=True,
                              as_data=is_data_map(name), **hint)
    image = drop_opaque_alpha(image, label, keep=keeps_alpha(name))  # a packing's map in A kept (0.59)
    if is_normal_name(name) if normal is None else normal:  # stored turned (EXIF): its vectors turned with its pixels
        image = upright_normal_map(image, path, convention=normal_convention(name), label=label)
    return image, depth


def map_suffixes(names) -> list:
    """What each map's file adds to the material's output name (:func:`map_files`): None for the
    albedo (the first name: the output itself), else the map's name without the words it shares
    with every other map's name at its start (the material's name, and a resolution such as
    ``2K``), and without a resolution at the start or end of what is left. The words shared leave
    at least one word of each name. A single map (no other to share with) drops the words before
    its kind's word (:func:`tghop.map_names.name_kind`: ``T_Rock_N`` is ``N``, ``rock_nor_gl_2k``
    ``nor_gl``). Fewer words are dropped where a map's suffix would lose the kind its name has
    (``Rock_Normal_GL`` beside ``Rock_Normal_DX`` is ``Normal_GL``, not ``GL``). A map of which no
    word is dropped (names that share no word at their start, a single map of no kind read) keeps
    its whole name, as do a map whose suffix would be empty and maps whose suffixes would be the
    same in any case.

    Parameters
    ----------
    names : sequence of str
        The material's map names, the albedo's first (:attr:`tghop.material.Material.names_`);
        each of :data:`tghop.map_names.MAP_NAME`'s form, no two alike in any case
        (:func:`tghop.map_names.check_map_names`).

    Returns
    -------
    list
        None, then a str per map, in ``names``' order.

    Examples
    --------
    >>> from tghop.material_files import map_suffixes
    >>> map_suffixes(["albedo", "rock_wall_nor_gl_2k", "rock_wall_rough_2k"])
    [None, 'nor_gl', 'rough']
    >>> map_suffixes(["albedo", "T_Rock_N"])
    [None, 'N']
    >>> map_suffixes(["albedo", "Rock_1K_Normal", "Rock_2K_Normal"])  # the same suffix: whole names
    [None, 'Rock_1K_Normal', 'Rock_2K_Normal']
    """
    maps = [str(n) for n in list(names)[1:]]
    words = [list(WORD.finditer(n)) for n in maps]
    if len(maps) == 1:
        out = [_suffix(maps[0], words[0], _kind_start(maps[0], words[0]))]
    else:
        kinds = [name_kind(n) for n in maps]
        shared = _shared_words(words)
        while True:  # fewer words dropped where a map would lose its kind's word (Rock_Normal_GL, Rock_Normal_DX)
            out = [_suffix(n, w, w[shared].start() if shared else 0) for n, w in zip(maps, words)]
            if not shared or all(k is None or name_kind(s) == k for s, k in zip(out, kinds)):
                break
            shared -= 1
    while True:  # a suffix taken twice: those maps keep their whole names (which check_map_names made distinct)
        seen = {}
        for i, s in enumerate(out):
            seen.setdefault(s.lower(), []).append(i)
        clash = [i for group in seen.values() if len(group) > 1 for i in group if out[i] != maps[i]]
        if not clash:
            return [None, *out]
        for i in clash:
            out[i] = maps[i]


def map_files(path, names) -> list:
    """Where each map of a material written to ``path`` goes: ``path`` itself for the albedo (the
    first name), else ``<stem>_<suffix><ext>`` beside it (:func:`map_suffixes`: ``Rock.png`` of the
    maps ``Rock023_2K_NormalGL`` and ``Rock023_2K_Roughness`` is ``Rock_NormalGL.png`` and
    ``Rock_Roughness.png``; of maps named ``normal`` and ``height``, ``Rock_normal.png`` and
    ``Rock_height.png``; ``Rock_Color.png``'s, ``Rock_NormalGL.png``: a colour map's word at the
    end of ``path``'s stem, or before a number or resolution, is left out of its maps' names, 0.59).
    The one naming of a material's files: ``tghop synth`` (and ``paint``, ``remix``), ``inpaint``
    and ``extend --maps``, ``tghop batch`` and the web page's downloads.

    Parameters
    ----------
    path : str or os.PathLike
        The material's output file (its albedo's).
    names : sequence of str
        The material's map names, the albedo's first (:attr:`tghop.material.Material.names_`).

    Returns
    -------
    list of str
        A file path per name, in ``names``' order (nothing is created or checked).
    """
    p = Path(path)
    suffixes = map_suffixes(names)
    for stem in (_without_colour_word(p.stem), p.stem):  # -o Rock_Color.png: Rock_NormalGL.png (0.59)
        files = [str(path) if suffix is None else str(p.with_name(f"{stem}_{suffix}{p.suffix}")) for suffix in suffixes]
        if str(path) not in files[1:]:
            return files
    return files


def _without_colour_word(stem) -> str:
    """An output name without the colour map's word at its end (``Rock_Color``, ``T_Rock_BC``,
    ``rock_albedo``: ``Rock``, ``T_Rock``, ``rock``; before a number, as ``--count`` numbers the
    files, or a resolution: ``Rock_Color_2`` is ``Rock_2``, ``rock_diff_2k`` ``rock_2k``), which its
    maps' files leave out (0.58 wrote ``Rock_Color_NormalGL.png``, a name an importer reads as a
    colour map and a normal map); a name of one word, or without such a word there, as it is."""
    words = list(WORD.finditer(stem))
    at = len(words) - (2 if len(words) > 2 and RESOLUTION.fullmatch(words[-1].group()) else 1)
    if at < 1 or name_kind(words[at].group()) != "albedo":
        return stem
    return stem[:words[at - 1].end()] + stem[words[at].end():]


def map_keys(names) -> list:
    """Which maps a material has, as painted and remixed materials are matched (``tghop synth A.npz
    B.npz``, :func:`tghop.synthesize_guided`, the web page's paint): each map's kind where its name says
    one that no other map of the material has (:func:`tghop.map_names.kind_key`: ``kind normal``), else a
    normal map's kind and the convention its name says where that is the material's only one of both
    (ambientCG's ``NormalGL`` beside ``NormalDX``: ``kind normal opengl``), else its suffix
    (:func:`map_suffixes`, what its output file adds to the name) in lower case; the albedo left out. Two
    sets of one library's naming are then the same maps (0.59): ``Stone_NormalGL`` and ``Gravel_NormalGL``
    are both ``normalgl``, where their whole names (0.58) never matched; and so are two libraries' namings
    (0.59): ``Stone_NormalGL`` and Poly Haven's ``gravel_nor_gl_2k`` are both a normal map, ``_Roughness``
    and ``_rough`` a roughness map (a map's name has no space, so a kind is no suffix).

    Parameters
    ----------
    names : sequence of str
        The material's map names, the albedo's first (:attr:`tghop.material.Material.names_`).

    Returns
    -------
    list of str
        A key per map but the albedo, in ``names``' order.

    Examples
    --------
    >>> from tghop.material_files import map_keys
    >>> map_keys(["albedo", "Stone_NormalGL", "Stone_Roughness"]) == map_keys(["albedo", "gravel_nor_gl_2k",
    ...                                                                        "gravel_rough_2k"])
    True
    >>> map_keys(["albedo", "Rock_NormalGL", "Rock_NormalDX", "Rock_Mask"])
    ['kind normal opengl', 'kind normal directx', 'mask']
    """
    maps = list(names)[1:]
    kinds = [kind_key(n) for n in maps]
    said = [(k, normal_convention(n)) if k == "normal" else (k, None) for k, n in zip(kinds, maps)]
    keys = []
    for suffix, kind, (_, convention) in zip(map_suffixes(names)[1:], kinds, said):
        if kind is not None and kinds.count(kind) == 1:
            keys.append(f"kind {kind}")
        elif convention is not None and said.count((kind, convention)) == 1:
            keys.append(f"kind {kind} {convention.lower()}")
        else:
            keys.append(suffix.lower())
    return keys


def maps_compared(material, first) -> str:
    """How ``material``'s maps compare with ``first``'s (two fitted materials), as painted, remixed and morphed
    materials are matched (:func:`map_keys`, each map's channels and its normal flag, in order; the albedo's
    channels): "same", "order" (the same maps in another order, which the command line and the server say so:
    0.60's server said "has the maps ... but ... has ...", naming the same maps twice) or "other". The one
    comparison of the library (:func:`tghop.synthesize_guided`, :func:`tghop.morph`), the command line and the
    server (0.61: the last two did not compare the normal flags, which the library refused after them)."""
    def maps(m):
        return list(zip(map_keys(m.names_), m.map_channels_[1:], m.normal_[1:]))

    mine, theirs = maps(material), maps(first)
    if material.map_channels_[0] != first.map_channels_[0]:
        return "other"
    return "same" if mine == theirs else "order" if sorted(mine) == sorted(theirs) else "other"


NORMAL_BY_NAME = "a map named *normal* or *nrm*, or ending in _nor_gl, _nor_dx or _N, is a normal map"


def maps_refused(material, first, label, label1, given="after --maps", normal_by=NORMAL_BY_NAME) -> str:
    """Why ``material`` cannot be painted, remixed or morphed with ``first`` (:func:`maps_compared`), one line
    naming the two as the caller does (``label``, ``label1``: "SOURCE 2 (b.npz)", "input 2") and the fix, in one
    wording for the library, the command line and the server; "" where their maps are the same. ``given``: where the
    caller's user gives a material's maps ("after --maps", "as the fields map:NAME"); ``normal_by``: what makes a
    map a normal map there. A map that is a normal map in one material alone, or of other channels, is named (0.60
    named every map of both, the same lists twice: "has the maps swirl but ... has swirl")."""
    if maps_compared(material, first) == "same":
        return ""

    def say(m):
        return "in colour" if m.map_channels_[0] > 1 else "greyscale"

    if material.map_channels_[0] != first.map_channels_[0]:
        return (f"{label}'s albedo is {say(material)} but {label1}'s is {say(first)}; give materials whose albedos "
                "are all in colour or all greyscale")
    mine, theirs = map_keys(material.names_), map_keys(first.names_)
    names, names1 = ", ".join(material.names_[1:]), ", ".join(first.names_[1:])
    if sorted(mine) != sorted(theirs):
        return (f"{label} has the maps {names} but {label1} has {names1}; give materials with the same maps, matched "
                "by their kinds (NormalGL and nor_gl are both a normal map) or else by the names after the name "
                "their maps share")
    for i, key in enumerate(mine, start=1):
        j = theirs.index(key) + 1
        a, b = material.names_[i], first.names_[j]
        if material.normal_[i] != first.normal_[j]:
            said = ("is a normal map but", "is not") if material.normal_[i] else ("is not a normal map but", "is")
            return (f"{label}'s map {a} {said[0]} {label1}'s {b} {said[1]}; fit them with the same normal maps "
                    f"({normal_by})")
        if material.map_channels_[i] != first.map_channels_[j]:
            c, c1 = material.map_channels_[i], first.map_channels_[j]
            return (f"{label}'s map {a} has {c} channel{'s' if c > 1 else ''} but {label1}'s {b} has {c1}; give "
                    "materials whose maps have the same channels")
    return (f"{label} has its maps in another order ({names}) than {label1} ({names1}); fit it again with its maps "
            f"{given} in that order: {names1}")


def _shared_words(words) -> int:
    """How many words (without case) every name starts with, leaving each at least one."""
    most = min((len(w) for w in words), default=1) - 1
    n = 0
    while n < most and len({w[n].group().lower() for w in words}) == 1:
        n += 1
    return n


def _kind_start(name, words) -> int:
    """Where a single map's kind word starts in ``name`` (the shortest end of it, at a word, that
    :func:`~tghop.map_names.name_kind` reads as the whole name's kind), else 0 (the whole name)."""
    kind = name_kind(name)
    if kind is None:
        return 0
    for w in reversed(words[1:]):
        if name_kind(name[w.start():]) == kind:
            return w.start()
    return 0


def _suffix(name, words, start) -> str:
    """``name`` from ``start``, without resolution words at either end; the whole name where
    ``start`` is 0 or only resolutions are left."""
    kept = [w for w in words if w.start() >= start]
    while kept and RESOLUTION.fullmatch(kept[0].group()):
        kept.pop(0)
    while kept and RESOLUTION.fullmatch(kept[-1].group()):
        kept.pop()
    return name[kept[0].start():kept[-1].end()] if start and kept else name
