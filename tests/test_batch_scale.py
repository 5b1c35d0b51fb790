"""``tghop batch`` at the scale of issue #29, "thousands of exemplars", on small counts: what a
rerun reads again, how the summary lists many failures, how the contact sheet loads. The tasks are
stand-ins (no fit): what is tested is the driver's work around them."""

import json
import os
import re
from pathlib import Path

import pytest

from tghop import batch, batch_plan


def quick_task(job):
    """A finished exemplar's files without a fit (their bytes do not matter to a rerun)."""
    folder, name = Path(job["folder"]), job["name"]
    folder.mkdir(parents=True, exist_ok=True)
    for f in (f"{name}.png", f"{name}.npz", "exemplar.png"):
        (folder / f).write_bytes(b"made")
    return {"status": "ok", "error": None, "cause": None, "outputs": [f"{name}/{name}.png"],
            "model": f"{name}/{name}.npz", "thumbnail": f"{name}/exemplar.png", "seed_used": 1, "seconds": 0.0}


def ledger(out):
    return [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]


@pytest.fixture
def counted_reads(monkeypatch):
    """The files whose bytes the run hashes (by path)."""
    reads = []
    real = batch_plan.file_sha256

    def counting(path):
        reads.append(Path(path).name)
        return real(path)

    monkeypatch.setattr(batch_plan, "file_sha256", counting)
    return reads


def test_a_rerun_reads_no_unchanged_file_again(tmp_path, monkeypatch, counted_reads):
    # 0.57 hashed every exemplar's bytes on every run, to find them unchanged: a rerun of a studio's
    # thousands, all done, read gigabytes again. Now a file whose size, times and inode are those it had
    # when a run hashed it is taken as unchanged (as git compares files with its index).
    src, out = tmp_path / "src", tmp_path / "out"
    for i in range(6):
        (src / f"d{i % 2}").mkdir(parents=True, exist_ok=True)
        (src / f"d{i % 2}" / f"x{i}.png").write_bytes(b"exemplar %d" % i)
    monkeypatch.setattr(batch_plan, "STAT_MARGIN", 0.0)  # the files were written a moment ago
    run = dict(workers=1, task=quick_task, seed=1)
    assert [r["status"] for r in batch.run(src, out, **run)] == ["ok"] * 6
    assert len(counted_reads) == 6
    counted_reads.clear()
    assert all(r["skipped"] for r in batch.run(src, out, **run))
    assert counted_reads == []
    # One file changed to the same size, its modification time put back: its change time and the
    # hash say so, and it alone is read and made again.
    changed = src / "d1" / "x3.png"
    before = changed.stat()
    changed.write_bytes(b"exemplar 9")
    os.utime(changed, ns=(before.st_atime_ns, before.st_mtime_ns))
    results = batch.run(src, out, **run)
    assert counted_reads == ["x3.png"]
    assert [r["name"] for r in results if not r["skipped"]] == ["d1__x3"]
    # The hashes are a cache: without them (removed, torn) every file is read again, and nothing redone.
    for broken in (None, "{not json", "[]"):
        if broken is None:
            (out / batch_plan.HASHES).unlink()
        else:
            (out / batch_plan.HASHES).write_text(broken)
        counted_reads.clear()
        assert all(r["skipped"] for r in batch.run(src, out, **run))
        assert len(counted_reads) == 6
    assert len(ledger(out)) == 7  # no line more for the files' hashes


def test_a_file_changed_just_before_the_run_is_read_every_time(tmp_path, monkeypatch, counted_reads):
    # Within STAT_MARGIN seconds of a change, a file's times could stay the same through another change
    # (a file system's coarse timestamps): it is hashed again by the next run.
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    monkeypatch.setattr(batch_plan, "STAT_MARGIN", 3600.0)  # "just before", however slow the machine
    (src / "x.png").write_bytes(b"exemplar")
    run = dict(workers=1, task=quick_task, seed=1)
    batch.run(src, out, **run)
    batch.run(src, out, **run)
    assert counted_reads == ["x.png", "x.png"]
    assert not (out / batch_plan.HASHES).exists()


def test_hashes_of_another_source_into_the_same_outdir_are_kept(tmp_path, monkeypatch, counted_reads):
    # Two SOURCEs into one OUTDIR (docs/batch.md): each run keeps the other's hashes, so that neither
    # reads the other's files again on its next run; a file no ledger line names is forgotten.
    monkeypatch.setattr(batch_plan, "STAT_MARGIN", 0.0)
    out = tmp_path / "out"
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        (tmp_path / name / f"{name}.png").write_bytes(name.encode())
    run = dict(workers=1, task=quick_task, seed=1, on_orphans=lambda found: None)
    batch.run(tmp_path / "a", out, **run)
    batch.run(tmp_path / "b", out, **run)
    counted_reads.clear()
    batch.run(tmp_path / "a", out, **run)
    batch.run(tmp_path / "b", out, **run)
    assert counted_reads == []
    hashes = json.loads((out / batch_plan.HASHES).read_text())
    hashes["/nowhere/x.png"] = hashes[str(tmp_path / "a" / "a.png")]
    (out / batch_plan.HASHES).write_text(json.dumps(hashes))
    (tmp_path / "a" / "a.png").write_bytes(b"A")
    batch.run(tmp_path / "a", out, **run)
    assert sorted(json.loads((out / batch_plan.HASHES).read_text())) == [str(tmp_path / n / f"{n}.png") for n in "ab"]


def test_the_contact_sheet_fetches_its_images_as_they_are_scrolled_to(tmp_path):
    # The sheet of 3,000 exemplars fetched its 5,372 images (thumbnails, and the whole outputs for their
    # 96-pixel previews) before the page was loaded. Now every image is fetched as it nears the window.
    from tghop.contact_sheet import write_contact_sheet

    records = [{"name": f"x{i}", "source": f"x{i}.png", "status": "ok", "thumbnail": f"x{i}/exemplar.png",
                "outputs": [f"x{i}/x{i}_1.png", f"x{i}/x{i}_2.png"], "model": f"x{i}/x{i}.npz", "seconds": 1.0}
               for i in range(40)]
    page = write_contact_sheet(tmp_path, records, ledger="batch.jsonl").read_text()
    images = re.findall(r"<img [^>]*>", page)
    assert len(images) == 120
    assert all(' loading="lazy"' in tag for tag in images), images[0]
