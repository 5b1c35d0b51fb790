"""``tghop batch`` at the scale of issue #29, "thousands of exemplars", on small counts: what a
rerun reads again, how the summary lists many failures, how the contact sheet loads. The tasks are
stand-ins (no fit): what is tested is the driver's work around them."""

import json
import os
import re
from pathlib import Path

import pytest

from tghop import batch, batch_plan

from test_cli_failures import invoke


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


def test_a_folder_where_the_hashes_go_is_said_with_the_fix(tmp_path, monkeypatch, counted_reads):
    # A folder named .batch-hashes.json: the cache cannot be written, so every rerun reads every input again;
    # 0.62 said nothing. 0.63 warns in one line with the fix; the run goes on (the cache is no part of its result).
    monkeypatch.setattr(batch_plan, "STAT_MARGIN", 0.0)
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    (src / "x.png").write_bytes(b"exemplar")
    (out / batch_plan.HASHES).mkdir(parents=True)
    for _ in range(2):
        with pytest.warns(UserWarning, match=r"^.*out/\.batch-hashes\.json is a folder, where the inputs' hashes "
                                             r"go: this run and every rerun read every input whole again; remove "
                                             r"that folder$"):
            (result,) = batch.run(src, out, workers=1, task=quick_task, seed=1)
        assert result["status"] == "ok"
    assert counted_reads == ["x.png", "x.png"]
    _, _, err, _ = invoke("batch", "src", "-o", "out", "--workers", "1", "-q", cwd=tmp_path)  # x.png: no image
    assert [line for line in err.splitlines() if line.startswith("Warning: ")] == [
        f"Warning: {out / batch_plan.HASHES} is a folder, where the inputs' hashes go: this run and every rerun read "
        "every input whole again; remove that folder"], err
    (out / batch_plan.HASHES).rmdir()  # the fix: the next run writes the file, and the one after reads nothing
    batch.run(src, out, workers=1, task=quick_task, seed=1)
    counted_reads.clear()
    batch.run(src, out, workers=1, task=quick_task, seed=1)
    assert counted_reads == []


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


def test_the_summary_says_many_failures_and_warnings_alike_on_one_line(tmp_path, monkeypatch):
    # The summary of 3,000 exemplars listed its 314 failures a line each (three kinds of them), and a
    # warning every exemplar gave (an alpha channel dropped) would have been 3,000 lines. Now those alike
    # (the same but for the exemplar's path and numbers) are one line, naming a few of the others.
    src = tmp_path / "src"
    for i in range(14):
        (src / f"d{i % 3}").mkdir(parents=True, exist_ok=True)
        (src / f"d{i % 3}" / f"x{i:02d}.png").write_bytes(b"x")

    def stand_in(job):
        i = int(job["name"][-2:])
        if i < 9:  # "PATH: not a readable image" and "exemplar is 40x40 pixels ..." by turns
            error = f"{job['source']}: not a readable image" if i % 2 else f"exemplar is {40 + i}x{40 + i} pixels"
            return {"status": "failed", "error": error, "cause": "input", "outputs": [], "model": None,
                    "thumbnail": None, "warnings": []}
        return {**quick_task(job), "warnings": [f"{job['source']}: its alpha channel dropped"]}

    monkeypatch.setattr(batch, "process_exemplar", stand_in)
    code, _, err, _ = invoke("batch", "src", "-o", "out", "--workers", "1", "-q", cwd=tmp_path)
    lines = err.splitlines()
    warned = [line for line in lines if line.startswith("Warning: ")]
    assert warned == [f"Warning: d0__x09: {src / 'd0' / 'x09.png'}: its alpha channel dropped (and 4 more like it: "
                      "d0__x12, d1__x10, d1__x13, d2__x11)"], err  # in the batch's order, d0/ first
    failed = [line for line in lines if line.startswith("failed: ")]
    assert failed == ["failed: d0__x00: exemplar is 40x40 pixels (and 4 more like it: d0__x06, d1__x04, d2__x02, "
                      "d2__x08)", f"failed: d0__x03: {src / 'd0' / 'x03.png'}: not a readable image (and 3 more "
                      "like it: d1__x01, d1__x07, d2__x05)"], err
    assert code == 1 and lines[-1].startswith("Error: 9 of 14 exemplars failed: d0__x00, d0__x03, "), err
    from tghop.cli.batch import alike_lines

    many = [({"name": f"n{i}", "source": f"/s/n{i}.png"}, f"/s/n{i}.png: bad") for i in range(8)]
    assert list(alike_lines(many)) == ["n0: /s/n0.png: bad (and 7 more like it: n1, n2, n3, n4, n5, ...)"]
    assert list(alike_lines(many[:3])) == ["n0: /s/n0.png: bad", "n1: /s/n1.png: bad", "n2: /s/n2.png: bad"]


def test_the_progress_lines_of_a_log_count_in_thousands(capsys):
    from tghop.cli.batch import BatchProgress

    progress = BatchProgress(True)
    progress.lines = True  # as into a log
    progress.result({}, {"failed": 31, "running": 2})
    progress("exemplars", 300, 3000)
    # 0.57: "exemplars: 300 of 3000 finished", beside the summary's "2,686 of 3,000 exemplars done"
    assert capsys.readouterr().err == "exemplars: 300 of 3,000 finished (269 done, 31 failed), 2 running\n"


def test_the_contact_sheet_links_its_failures_from_the_top(tmp_path):
    # Among 3,000 rows the 314 failed ones were found only by scrolling through them all: a folded list of
    # links above the table now leads to each.
    from tghop.contact_sheet import write_contact_sheet

    records = [{"name": f"x{i}", "source": f"x{i}.png", "status": "failed" if i % 4 == 1 else "ok",
                "error": "not an image" if i % 4 == 1 else None} for i in range(1200)]
    page = write_contact_sheet(tmp_path, records, total=1250).read_text()
    top = page.split("<table>")[0]
    assert "<details><summary>The 300 not done</summary>" in top
    assert re.findall(r'href="#([^"]+)"', top) == [f"x-x{i}" for i in range(1, 1200, 4)]
    assert all(f'<tr id="x-x{i}" class="failed">' in page for i in range(1, 1200, 4))
    assert "900 of 1,200 exemplars done, 300 failed. 50 not finished yet" in top  # 0.57: "900 of 1200"
    assert "<details>" not in write_contact_sheet(tmp_path, records[:1]).read_text()
