"""The image formats tghop writes, by the output's file extension: the one list that
:mod:`tghop.imageio` writes by and every message and ``--help`` text names (no imports:
the command line's help is made from it without loading NumPy); and the extensions of the
files it reads (:data:`READ_SUFFIXES`: what a batch takes from a folder)."""

__all__ = ["FORMATS", "DEPTHS", "READ_SUFFIXES", "OTHER_IMAGE_SUFFIXES", "extensions", "OUTPUT_HELP", "is_model_file",
           "model_file_kind", "COOC_CHECKPOINT", "checkpoint_note", "TIFF_HINT", "check_tifffile",
           "why_unreadable", "unreadable", "unread_format", "missing_decoder", "warn_frames", "read_as_it_stands"]

#: Output formats chosen by file extension.
FORMATS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG", ".tif": "TIFF", ".tiff": "TIFF"}
#: Bits per channel each output format can be written with (32: float32 TIFF).
DEPTHS = {"PNG": (8, 16), "JPEG": (8,), "TIFF": (8, 16, 32)}
#: The image files tghop reads, by extension (any case): what ``tghop fit`` and every reader
#: (:func:`tghop.imageio.load_image`: Pillow's formats) read of textures and a material's maps, and so
#: what a batch takes from a folder (:data:`tghop.batch.IMAGE_SUFFIXES` is this list). .jfif and .jpe:
#: JPEG files by other names, as a browser saves them; .pbm: the bilevel one of .ppm, .pgm, .pnm; .tga
#: (Unreal's and many studios' maps), .psd (its merged image), .dds, JPEG 2000 and .ico: Pillow reads
#: them (a batch skipped them, though fit read them); .qoi, .sgi and .pcx (0.58: Pillow 10 reads them;
#: SGI's other extensions, .rgb, .rgba and .bw, are left out: other tools' raw pixel dumps take them too);
#: .avif from Pillow 11.2 (an earlier one, as fit, refuses it in one line: upgrade Pillow,
#: :func:`missing_decoder`).
READ_SUFFIXES = (".png", ".jpg", ".jpeg", ".jfif", ".jpe", ".bmp", ".gif", ".tif", ".tiff", ".webp", ".ppm",
                 ".pgm", ".pbm", ".pnm", ".tga", ".psd", ".dds", ".jp2", ".j2k", ".avif", ".ico", ".qoi", ".sgi",
                 ".pcx")
#: Other images' extensions, of formats tghop does not read: a batch folder's files of these are
#: skipped, and said; fit refuses them in one line (:func:`unread_format`).
OTHER_IMAGE_SUFFIXES = (".exr", ".hdr", ".heic", ".heif", ".jxl", ".raw", ".dng", ".cr2", ".nef", ".arw")
#: What to install for 16-bit colour and float TIFF files (Pillow reads and writes only grey ones).
TIFF_HINT = "pip install 'tghop[tiff]'"


def extensions(formats=None) -> str:
    """The extensions of ``formats`` (format names; default every one) in words:
    ``.png, .jpg, .jpeg, .tif or .tiff``."""
    names = [ext for ext, fmt in FORMATS.items() if formats is None or fmt in formats]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


#: The start of an image output's ``-o`` help: ``Image to write (EXTENSIONS``; each command ends it.
OUTPUT_HELP = f"Image to write ({extensions()}"


def is_model_file(path) -> bool:
    """True if ``path`` (or a binary file object, from its start) starts like a zip archive (an
    ``.npz``), which only a model can be among tghop's inputs; a truncated model file still counts
    (and is then reported as truncated)."""
    try:
        if hasattr(path, "read"):
            path.seek(0)
            return path.read(4) in (b"PK\x03\x04", b"PK\x05\x06")
        with open(path, "rb") as fh:
            return fh.read(4) in (b"PK\x03\x04", b"PK\x05\x06")
    except (OSError, ValueError):
        return False


def read_as_it_stands(source, read):
    """``read(fh, name)`` on ``source``: a path (opened, and closed after), or a binary file object from where it
    stands (put back there after; ``name`` its ``name`` or "the image"); None for anything else. The one
    dispatch of the readers that look into an image file before Pillow does (:func:`tghop.tiff_tags.quiet_copy`,
    the damaged EXIF block's check of :mod:`tghop.image_decode`); each catches its own errors."""
    import os

    if isinstance(source, (str, bytes, os.PathLike)):
        with open(source, "rb") as fh:
            return read(fh, source)
    if hasattr(source, "read") and hasattr(source, "seek"):
        start = source.tell()
        try:
            return read(source, getattr(source, "name", None) or "the image")
        finally:
            source.seek(start)
    return None


#: :func:`model_file_kind`'s words for a checkpoint of ``tghop cooc train``.
COOC_CHECKPOINT = "a co-occurrence cGAN checkpoint"


def model_file_kind(path) -> str:
    """What the zip archive at ``path`` (:func:`is_model_file`) is, in words for "PATH is ...,
    not an image": :data:`COOC_CHECKPOINT` (``torch.save``'s layout naming the checkpoint's
    ``settings_json``, also in the first bytes of a checkpoint cut short: 0.57), "a PyTorch file"
    (that layout otherwise), "a model file" (a tghop ``.npz``, or another archive cut short) or, for one
    of too many members, :func:`tghop._archives.too_many_members`' words (0.58)."""
    import zipfile

    from ._archives import too_many_members

    crowded = too_many_members(path)
    if crowded:  # its directory not parsed (many seconds)
        return crowded
    try:
        with zipfile.ZipFile(path) as archive:
            pickles = [info for info in archive.infolist() if info.filename.endswith("/data.pkl")]
            if not pickles:
                return _other_archive(archive.namelist()) or "a model file"
            small = pickles[0].file_size < 2**20  # the tensors' names and shapes only
            return COOC_CHECKPOINT if small and b"settings_json" in archive.read(pickles[0]) else "a PyTorch file"
    except (zipfile.BadZipFile, OSError, EOFError, NotImplementedError, ValueError):
        pass
    try:  # cut short (no zip directory): torch.save stores its pickle, naming settings_json, near the start
        if hasattr(path, "read"):
            path.seek(0)
            head = path.read(2**20)
        else:
            with open(path, "rb") as fh:
                head = fh.read(2**20)
    except (OSError, ValueError):
        return "a model file"
    if head.startswith(b"PK") and b"/data.pkl" in head[:400]:  # the first member's name
        return COOC_CHECKPOINT if b"settings_json" in head else "a PyTorch file"
    return "a model file"


def _other_archive(names) -> str | None:
    """:func:`model_file_kind`'s words for a zip archive of no NumPy arrays (``names``: its members'), else None:
    one of images, as the web page's "Download all maps" saves a material's (0.59 called it "a model file", and
    the model readers "a NumPy archive"), or of other files."""
    import os

    files = [n for n in names if not n.endswith("/")]
    if any(n.endswith(".npy") for n in files):
        return None
    images = [n for n in files if os.path.splitext(n)[1].lower() in READ_SUFFIXES]
    if images and len(images) == len(files):
        shown = ", ".join(os.path.basename(n)[:60] for n in images[:2]) + (", ..." if len(images) > 2 else "")
        return (f"a ZIP archive of {len(images)} image{'s' if len(images) > 1 else ''} ({shown}; the page's "
                "'Download all maps' saves one: unzip it and give its images)")
    return "a ZIP archive of other files than a model's arrays" if files else "an empty ZIP archive"


#: The suffixes of PyTorch's files, which a co-occurrence cGAN checkpoint is named by.
TORCH_SUFFIXES = (".pt", ".pth")


def checkpoint_note(path) -> str:
    """For "PATH: not a readable image (...)" and "PATH: ... not a tghop model file": where a
    co-occurrence cGAN checkpoint goes, in words to append ("; ..."), when ``path`` is or looks
    like one (:func:`model_file_kind`, a checkpoint cut short included) or is named ``.pt``/``.pth``;
    "" otherwise (0.56 named no ``tghop cooc`` command: "give a PNG, JPEG ..." or "fit the model again")."""
    import os

    where = "'tghop cooc morph' and 'tghop cooc edit' take those, not this command"
    kind = model_file_kind(path) if is_model_file(path) else None
    name = path if isinstance(path, (str, bytes, os.PathLike)) else getattr(path, "name", "")  # a file object's
    name = os.fsdecode(name) if isinstance(name, (str, bytes, os.PathLike)) else ""
    if kind == COOC_CHECKPOINT:
        return f"; it looks like a co-occurrence cGAN checkpoint ('tghop cooc train' writes them): {where}"
    if kind != "a PyTorch file" and name.lower().endswith(TORCH_SUFFIXES):  # another's: no note
        return f"; a .pt or .pth name is a co-occurrence cGAN checkpoint's: {where}"
    return ""


def check_tifffile(path, depth):
    """A one-line :class:`~tghop.MissingExtraError` unless :mod:`tifffile` (the tiff extra)
    imports: Pillow writes no colour TIFF of ``depth`` (16 or 32) bits."""
    try:
        import tifffile  # noqa: F401
    except ImportError:
        from ._errors import MissingExtraError

        raise MissingExtraError(f"{path}: writing a {depth}-bit colour TIFF needs tifffile: {TIFF_HINT}") from None


def why_unreadable(path, exc, found=None) -> str:
    """Why Pillow could not read the image at ``path`` (raising ``exc``), in a few words: the
    exception's class name alone ("OSError") did not say that a download was cut short. ``found``: the
    format Pillow found in its header (``Image.format``), where it opened it."""
    return _unreadable(path, exc, found)[0]


def unreadable(path, exc, found=None) -> str:
    """What follows "PATH: " where Pillow could not read the image at ``path`` (raising ``exc``; ``found``:
    the format Pillow found in its header, where it opened it):
    "not a readable image (WHY); FIX", WHY as :func:`why_unreadable` says it, FIX another file for one
    that is no image, the file again for a damaged one (0.58: "give a PNG, JPEG or other common image
    file" of a PNG cut short). A file of a format tghop reads that Pillow gave up on partway is named
    a damaged file of the format Pillow found in its header ("a TGA file, cut short (...)"; 0.58:
    "truncated or corrupt: OSError: ...", no format named), one whose header Pillow could not read a
    file of that format by its signature, or, with none (TGA), by its extension."""
    why, fix = _unreadable(path, exc, found)
    return f"not a readable image ({why}); {fix}"


_AGAIN, _OTHER = "save or download it again", "give a PNG, JPEG or other common image file"
_EITHER = f"{_AGAIN}, or {_OTHER}"


def _unreadable(path, exc, found):
    """``(why, fix)`` for :func:`unreadable`."""
    from PIL import UnidentifiedImageError

    if not isinstance(exc, UnidentifiedImageError):
        words = " ".join(str(exc).split())[:100] or exc.__class__.__name__
        name = _PILLOW_NAMES.get(found, found) or _signature_format(path) or _SUFFIX_FORMATS.get(_suffix(path))
        if name is None:
            return f"truncated or corrupt: {exc.__class__.__name__}: {words}", _EITHER
        cut = isinstance(exc, EOFError) or any(sign in words.lower() for sign in _CUT_SHORT)
        return f"{_a(name)} file, {'cut short' if cut else 'damaged'} ({words})", _AGAIN
    head = _file_head(path) or b""
    if not head:
        return "the file is empty", _OTHER
    if head.startswith(b"\x93NUMPY"):
        return "a NumPy array file (.npy), not an image", _OTHER
    bits = _jpeg_bits(path) if head.startswith(b"\xff\xd8\xff") else None
    if bits not in (None, 8):  # 0.57: "a JPEG file, but its header is corrupt or of a kind tghop does not read"
        return (f"a {bits}-bit JPEG, which Pillow does not read, only 8-bit ones: convert it to a 16-bit PNG or "
                "TIFF"), _OTHER
    for matches, name, _ in _READ_HEADS:  # 0.56: "not an image format tghop reads" of a PNG of width 0
        if matches(head):  # a decoder Pillow lacks was said before (missing_decoder): the file is at fault
            return f"{_a(name)} file, but its header is corrupt or of a kind tghop does not read", _EITHER
    named = _SUFFIX_FORMATS.get(_suffix(path))
    if named and named == next((name for start, name in _MORE_HEADS if head.startswith(start)), None):
        return f"{_a(named)} file, but its header is corrupt or of a kind tghop does not read", _EITHER  # a BMP's
    if named:  # 0.58: "not an image format tghop reads" of a damaged TGA (no signature: its name alone says it)
        return (f"named as {_a(named)} file, but Pillow cannot read its header as one: damaged, or another kind of "
                "file renamed"), _EITHER
    return "not an image format tghop reads", _OTHER


def _suffix(path) -> str:
    """The extension of ``path`` in lower case (".tga")."""
    import os

    return os.path.splitext(os.fsdecode(path))[1].lower()


#: The signatures of formats tghop reads beyond :data:`_READ_HEADS`, for a file Pillow stopped reading in its header.
_MORE_HEADS = ((b"BM", "BMP"), (b"8BPS", "PSD"), (b"DDS ", "DDS"), (b"\x00\x00\x01\x00", "ICO"), (b"\x01\xda", "SGI"),
               (b"P1", "PNM"), (b"P2", "PNM"), (b"P3", "PNM"), (b"P4", "PNM"), (b"P5", "PNM"), (b"P6", "PNM"))


def _signature_format(path):
    """The format whose signature starts the file at ``path`` ("JPEG"), of those tghop reads; None for none."""
    head = _file_head(path) or b""
    for matches, name, _ in _READ_HEADS:
        if matches(head):
            return name
    return next((name for start, name in _MORE_HEADS if head.startswith(start)), None)


#: Pillow's words (lower case) for a file whose data ends early.
_CUT_SHORT = ("truncated", "not enough image data", "incomplete", "expected to read", "broken data stream",
              "buffer is not large enough", "ran out of data", "premature end")

#: Pillow's format names that read better otherwise.
_PILLOW_NAMES = {"WEBP": "WebP", "JPEG2000": "JPEG 2000", "PPM": "PNM", "MPO": "JPEG"}

#: The formats of :data:`READ_SUFFIXES` by extension, for a file whose first bytes no signature of theirs
#: matches (TGA has none).
_SUFFIX_FORMATS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG", ".jfif": "JPEG", ".jpe": "JPEG", ".bmp": "BMP",
                   ".gif": "GIF", ".tif": "TIFF", ".tiff": "TIFF", ".webp": "WebP", ".ppm": "PNM", ".pgm": "PNM",
                   ".pbm": "PNM", ".pnm": "PNM", ".tga": "TGA", ".psd": "PSD", ".dds": "DDS", ".jp2": "JPEG 2000",
                   ".j2k": "JPEG 2000", ".avif": "AVIF", ".ico": "ICO", ".qoi": "QOI", ".sgi": "SGI", ".pcx": "PCX"}


def _jpeg_bits(path):
    """The sample precision (bits) a JPEG file's frame header (SOF) declares, from its first 256 KiB; None where
    none is found there (the markers walked by their lengths)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read(256 * 1024)
    except OSError:
        return None
    at = 2
    while at + 5 <= len(data) and data[at] == 0xFF:
        marker = data[at + 1]
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):  # a start of frame
            return data[at + 4]
        if marker == 0xFF:  # fill byte
            at += 1
            continue
        at += 2 + int.from_bytes(data[at + 2:at + 4], "big")
    return None


def _file_head(path):
    """The first 16 bytes of the file at ``path`` (fewer in a shorter one), or None where it cannot be read."""
    try:
        with open(path, "rb") as fh:
            return fh.read(16)
    except OSError:
        return None


#: The first bytes of formats tghop reads, each row: whether a file of them is that format
#: (``matches(head)``), its name (:func:`unreadable` calls a file Pillow cannot identify that starts
#: so one of that format with a corrupt header: a width of 0, a checksum that fails, complex TIFF
#: samples, an AVIF or JPEG 2000 cut short, which 0.58 called "not an image format tghop reads"); and,
#: for a format Pillow reads only where it was built with its library, the module or codec
#: :mod:`PIL.features` checks for it (:func:`missing_decoder`, asked first).
#: :data:`_PILLOW_FROM` names the first Pillow that knows a format at all.
_READ_HEADS = (
    (lambda head: head.startswith(b"\x89PNG\r\n\x1a\n"), "PNG", None),
    (lambda head: head.startswith(b"\xff\xd8\xff"), "JPEG", ("codec", "jpg")),
    (lambda head: head.startswith((b"GIF87a", b"GIF89a")), "GIF", None),
    (lambda head: head.startswith((b"II*\x00", b"MM\x00*")), "TIFF", None),
    (lambda head: head[:4] == b"RIFF" and head[8:12] == b"WEBP", "WebP", ("module", "webp")),
    (lambda head: head[4:8] == b"ftyp" and head[8:12] in (b"avif", b"avis"), "AVIF", ("module", "avif")),
    (lambda head: head.startswith((b"\x00\x00\x00\x0cjP  \r\n\x87\n", b"\xff\x4f\xff\x51")), "JPEG 2000",
     ("codec", "jpg_2000")),
    (lambda head: head.startswith(b"qoif"), "QOI", None),
)


#: The first Pillow version that reads a format of :data:`_READ_HEADS` (by name) that pyproject's lower
#: bound (``pillow>=10``) does not: an older one has no plugin for it, and :mod:`PIL.features` does not
#: know its module (AVIF: Pillow 11.2).
_PILLOW_FROM = {"AVIF": "11.2"}


#: ISO base media brands of HEIF images (a phone's photos: .heic, .heif); AVIF ones Pillow reads.
_HEIF_BRANDS = (b"heic", b"heix", b"hevc", b"hevx", b"heim", b"heis", b"hevm", b"hevs", b"mif1", b"msf1")


def unread_format(path):
    """The name of a common image format that Pillow does not read ("a HEIC/HEIF image"), from
    the first bytes of the file at ``path`` (a phone's HEIC photo, a texture artist's EXR or JPEG
    XL were only "not an image format tghop reads"), or None."""
    head = _file_head(path)
    if head is None:
        return None
    if head[4:8] == b"ftyp" and head[8:12] in _HEIF_BRANDS:
        return "a HEIC/HEIF image"
    if head.startswith((b"\xff\x0a", b"\x00\x00\x00\x0cJXL ")):
        return "a JPEG XL image"
    if head.startswith(b"\x76\x2f\x31\x01"):
        return "an OpenEXR image"
    if head.startswith((b"#?RADIANCE", b"#?RGBE")):
        return "a Radiance HDR image"
    if head.startswith(b"%PDF"):
        return "a PDF document"
    if head.lstrip().startswith((b"<svg", b"<?xml")):
        return "an SVG or other XML file"
    return None


def missing_decoder(path, exc=None):
    """Why this Python cannot read the image at ``path`` though the file may be sound: the name of
    its format where the installed Pillow was built without that format's library ("WebP": a file
    of a format tghop reads, told "not an image format tghop reads") or is older than the first that
    reads it (an AVIF file and Pillow 10 or 11.1: 0.57 said "not an image format tghop reads"), or
    Pillow's own words for a decoder it lacks (``exc``: ``OSError("decoder jpeg2k not available")``);
    else None. The cause is outside the file: the same file reads once Pillow has the library."""
    import re

    if isinstance(exc, OSError) and re.fullmatch(r"decoder \S+ not available", str(exc)):
        return str(exc)
    head = _file_head(path)
    if head is None:
        return None
    from PIL import features

    for matches, name, built_with in _READ_HEADS:
        if not matches(head):
            continue
        if built_with is None:
            return None
        kind, feature = built_with
        known = features.modules if kind == "module" else features.codecs
        if feature not in known and name in _PILLOW_FROM:  # a Pillow from before the format's plugin
            import PIL

            return f"{_a(name)} image, which Pillow reads from version {_PILLOW_FROM[name]} on, and this is Pillow " \
                   f"{PIL.__version__}"
        if feature in known and not (features.check_module if kind == "module" else features.check_codec)(feature):
            return f"{_a(name)} image, and this Pillow was built without {name} support"
        return None
    return None


def _a(name) -> str:
    """``name`` (a format's) with its article: "an AVIF", "a WebP"."""
    return f"{'an' if name[0] in 'AEFHILMNORSX' else 'a'} {name}"


def warn_frames(path, count) -> None:
    """Warn that only the first of an image file's ``count`` frames is read (an animated GIF, a
    TIFF of several pages: each was read without a word)."""
    if count > 1:
        import os

        from ._errors import warn

        warn(f"{os.path.basename(path)}: {count} frames (or pages); only the first is read", UserWarning,
             stacklevel=4)
