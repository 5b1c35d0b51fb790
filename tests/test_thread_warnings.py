"""Warnings on threads: the web server reads uploads (and a batch worker may run exemplars) on
threads, and ``warnings.catch_warnings`` is process-wide in Python < 3.14: a thread inside it
swapped the filters and ``showwarning`` of every thread, swallowed or recorded their warnings,
and two at once could leave the process with the wrong ones for good. tghop's own warnings are
collected per thread instead (:func:`tghop._errors.collect_warnings`)."""

import io
import sys
import threading
import warnings

import numpy as np
from PIL import Image

from tghop import data
from tghop.imageio import load_image, to_uint8


def _cut_out() -> bytes:
    """A PNG whose right half is transparent (a TransparencyWarning when read without alpha)."""
    rgba = np.zeros((48, 48, 4), np.uint8)
    rgba[:, :24, :3], rgba[:, :24, 3] = to_uint8(data.bricks(48, rng=3))[:, :24], 255
    buf = io.BytesIO()
    Image.fromarray(rgba, "RGBA").save(buf, format="PNG")
    return buf.getvalue()


def _run_with_a_speaker(readers, work):
    """Run ``work(i)`` on ``readers`` threads while another thread warns without pause: (what
    reached this thread's ``showwarning``, what the speaker said, the filters and ``showwarning``
    before and after)."""
    shown, spoken, stop = [], [], threading.Event()

    def speaker():
        while not stop.is_set():
            spoken.append(f"the speaker's warning {len(spoken)}")
            warnings.warn(spoken[-1], UserWarning)

    switching = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)  # threads interleaved often: a race seen on every run, not one in three
    try:
        with warnings.catch_warnings():  # this test's own handler, set before any thread starts
            warnings.simplefilter("always")
            warnings.showwarning = lambda message, *args, **kwargs: shown.append(str(message))
            before = (list(warnings.filters), warnings.showwarning)
            talking = threading.Thread(target=speaker)
            talking.start()
            threads = [threading.Thread(target=work, args=(i,)) for i in range(readers)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            stop.set()
            talking.join()
            after = (list(warnings.filters), warnings.showwarning)
    finally:
        sys.setswitchinterval(switching)
    return shown, spoken, before, after


def test_the_servers_upload_reading_on_threads_leaves_other_threads_warnings_alone():
    from tghop._errors import HINT_DOWNSCALE_YOURSELF
    from tghop.server.uploads import read_notes
    from tghop.server.uploads import read_image

    content, rounds = _cut_out(), 60
    notes = {i: [] for i in range(6)}
    images = {i: [] for i in range(6)}

    def reader(i):
        for _ in range(rounds):  # prepare_fit's read: the upload's transparency told in its notes
            def read(path):
                with read_notes(notes[i]):
                    return load_image(path, dtype=None, too_large_hint=HINT_DOWNSCALE_YOURSELF, with_depth=True)

            images[i].append(read_image(content, f"cut_{i}.png", read))

    shown, spoken, before, after = _run_with_a_speaker(6, reader)
    assert after == before  # the filters and showwarning as they were
    assert spoken and set(spoken) <= set(shown)  # none of the other thread's warnings swallowed or recorded
    assert not [s for s in shown if "alpha channel" in s]  # the uploads' warnings are the page's notes
    for i in range(6):  # each read told its own upload's transparency, once
        assert notes[i] == [f"cut_{i}.png: 50% of its pixels are transparent, and the colours under them are "
                            "learnt as texture; to leave them out, crop the image to its opaque part"] * rounds
        assert all(depth == 8 and np.array_equal(image, images[0][0][0]) for image, depth in images[i])


def _png_header(width, height):
    """A PNG whose header declares ``width`` x ``height`` (with almost no pixel data)."""
    import struct
    import zlib

    def chunk(kind, payload):
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\x00" * 10)) + chunk(b"IEND", b""))


def test_an_image_over_pillows_bomb_limit_is_refused_without_its_warning(tmp_path):
    # Pillow warns (DecompressionBombWarning) as it opens a header over its 89 Mpx; tghop's own
    # limit applies, and the warning was hidden by a process-wide catch_warnings. Opened without it now.
    import pytest

    from tghop import InvalidImageError
    from tghop._errors import ImageTooLargeError

    (tmp_path / "big.png").write_bytes(_png_header(10000, 10000))  # 100 Mpx: Pillow's warning
    (tmp_path / "bomb.png").write_bytes(_png_header(20000, 20000))  # over twice its limit: its error
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        with pytest.raises(ImageTooLargeError, match="big.png: the image is 10000x10000 pixels"):
            load_image(tmp_path / "big.png")
        with pytest.raises(InvalidImageError, match="downscaled|not a readable image"):
            load_image(tmp_path / "big.png", downscale=True)  # no pixels to downscale, but opened as before
        with pytest.raises(InvalidImageError, match="bomb.png: the image header declares too many pixels"):
            load_image(tmp_path / "bomb.png", downscale=True)
    assert not [w for w in said if issubclass(w.category, Image.DecompressionBombWarning)], said


def test_open_image_reads_what_pillows_open_reads(tmp_path):
    from PIL import UnidentifiedImageError

    from tghop.image_decode import open_image

    rgb = to_uint8(data.bricks(40, rng=1))
    pictures = {"a.png": Image.fromarray(rgb), "a.jpg": Image.fromarray(rgb), "a.gif": Image.fromarray(rgb).quantize(),
                "a.bmp": Image.fromarray(rgb), "a.webp": Image.fromarray(rgb), "a.tif": Image.fromarray(rgb),
                "a.tga": Image.fromarray(rgb).convert("RGBA")}
    for name, picture in pictures.items():
        picture.save(tmp_path / name)
        with open_image(tmp_path / name) as ours, Image.open(tmp_path / name) as theirs:
            assert (ours.format, ours.mode, ours.size) == (theirs.format, theirs.mode, theirs.size), name
            assert np.array_equal(np.asarray(ours), np.asarray(theirs)), name
        assert ours.fp is None  # the file closed with the image
    (tmp_path / "a.txt").write_bytes(b"not an image at all")
    import pytest

    with pytest.raises(UnidentifiedImageError):
        open_image(tmp_path / "a.txt")


def test_collect_warnings_keeps_this_threads_alone():
    # The primitive: a thread collecting while another warns (a catch_warnings(record=True) took both).
    from tghop._errors import collect_warnings, warn

    inside, said, kept = threading.Barrier(2), threading.Barrier(2), []

    def collector():
        with collect_warnings() as mine:
            inside.wait()
            said.wait()  # the other thread has warned meanwhile
            warn("the collector's own")
        kept.extend(str(w) for w in mine)

    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        before = list(warnings.filters)
        t = threading.Thread(target=collector)
        t.start()
        inside.wait()
        warn("this thread's")
        said.wait()
        t.join()
        assert list(warnings.filters) == before
    assert kept == ["the collector's own"]
    assert [str(w.message) for w in shown] == ["this thread's"]


def test_a_batch_workers_tasks_on_threads_record_their_own_warnings(tmp_path):
    # A Dask worker started with --nthreads 2 (or a client of a threaded cluster) runs two
    # exemplars at once in one process: each ledger line had the other's warnings (or none).
    from tghop import batch
    from tghop.imageio import save_image

    src = tmp_path / "src"
    src.mkdir()
    save_image(np.concatenate([data.bricks(64, rng=3), np.ones((64, 64, 1))], axis=2), src / "a.png")  # alpha
    save_image(data.cells(64, rng=4), src / "b.png")
    jobs = []
    batch.run(src, tmp_path / "first", size=(32, 32), seed=1, fit=dict(n_clusters=6, n_codewords=30, stride=4),
              generate=dict(n_patches=300), workers=1, contact_sheet=False,
              task=lambda job: jobs.append(job) or batch.process_exemplar(job))
    assert sorted(j["name"] for j in jobs) == ["a", "b"]
    records = {}

    def task(i):
        # claim None: a run's claim is checked against its own folders' .batch-running files (0.62), not these
        job = dict(jobs[i % 2], folder=str(tmp_path / "again" / f"{i}"), threads=1, claim=None)
        records[i] = (job["name"], batch.process_exemplar(job))

    shown, spoken, before, after = _run_with_a_speaker(4, task)
    assert after == before
    assert spoken and set(spoken) <= set(shown)
    for name, record in records.values():
        assert record["status"] == "ok", record
        assert record["warnings"] == (["a.png: alpha channel dropped"] if name == "a" else []), (name, record)


def test_a_helper_thread_of_tghops_own_warns_into_its_callers_collector(monkeypatch):
    # synthesize lays its layout out on a thread of its own (_resources.in_thread): a warning there
    # was the caller's (catch_warnings took every thread's); collected per thread, it went astray.
    from tghop import _resources
    from tghop._errors import collect_warnings, warn

    monkeypatch.setattr(_resources, "usable_cores", lambda: 2)  # a thread, not the caller's own
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        with collect_warnings() as said:
            _resources.in_thread(lambda: warn("from the helper") or threading.get_ident())()
    assert [str(w) for w in said] == ["from the helper"] and not shown
