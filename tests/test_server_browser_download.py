"""The page's ZIP of a material's maps (``download.js``'s ``zipOf``), made in a real browser (Chromium through
Playwright) and read back with Python's :mod:`zipfile`, as an unzip program reads it."""

import io
import struct
import zipfile

import chromium

chromium.require()


def zip_of(page, files):
    """The bytes ``zipOf`` makes of ``files`` ({name: bytes})."""
    return bytes(page.evaluate("""async (files) => {
        const zip = await zipOf(files.map(([name, bytes]) => ({ name, blob: new Blob([new Uint8Array(bytes)]) })));
        return Array.from(new Uint8Array(await zip.arrayBuffer()));
    }""", [[name, list(data)] for name, data in files.items()]))


def test_a_zip_of_maps_named_after_a_non_ascii_exemplar_keeps_its_letters(page):
    # A model's stem keeps letters of any script (fileStem: "Ziegelwand_Größe.jpg" gives "Ziegelwand_Größe"), and
    # zipOf wrote its UTF-8 bytes without the flag that says so (bit 11): unzip programs and Python's zipfile
    # read them as code page 437, "tghop-Ziegelwand_Gr├╢├ƒe-64x64-seed3.png".
    names = ["tghop-Ziegelwand_Größe-64x64-seed3.png", "tghop-Ziegelwand_Größe-64x64-seed3_normal.png",
             "tghop-岩-64x64-seed3.png"]
    blob = zip_of(page, {name: bytes([i]) * (10 + i) for i, name in enumerate(names)})
    with zipfile.ZipFile(io.BytesIO(blob)) as archive:
        assert archive.testzip() is None
        assert archive.namelist() == names
        assert [archive.read(name) for name in names] == [bytes([i]) * (10 + i) for i in range(3)]
    assert struct.unpack("<H", blob[6:8])[0] & 0x800  # the local header's flag too (readers of the stream)
    assert page.errors == []
