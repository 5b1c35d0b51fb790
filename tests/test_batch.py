"""``tghop batch`` and :func:`tghop.batch.run` (issue #29): in process and on a real local
Dask cluster of worker processes, resumable, bad exemplars recorded, dead workers retried.

Exemplars are made in code (no ../shared); fits use tiny settings. The Dask tests share
one LocalCluster(n_workers=2, processes=True, threads_per_worker=1) whose scheduler lets a
task's worker die twice (``allowed-failures`` 2).
"""

import gc
import hashlib
import json
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tghop import batch, batch_dask, batch_plan, data
from tghop._errors import TGHopError
from tghop.imageio import save_image

from test_cli_failures import assert_one_line, invoke

FIT = dict(n_clusters=6, n_codewords=30, stride=4)
GEN = dict(n_patches=300)
CLI_FAST = ["--clusters", "6", "--codewords", "30", "--stride", "4", "--pool", "300", "-q"]


def make_folder(d, *, bad=True):
    """Two good exemplars with equal stems in different folders (and a bad and a flat one)."""
    (d / "sub").mkdir(parents=True, exist_ok=True)
    save_image(data.bricks(64, rng=3), d / "a.png")
    save_image(data.cells(64, rng=4), d / "sub" / "a.png")
    if bad:
        (d / "bad.png").write_bytes(b"not an image at all")
        save_image(np.full((64, 64, 3), 0.5), d / "flat.png")
    return d


def ledger(out):
    return [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]


def leftovers(out):
    return [p for p in out.rglob("*") if p.name.endswith((".tmp", ".probe"))]


def check_sheet(out, results):
    page = (out / "index.html").read_text()
    assert "http://" not in page and "https://" not in page and "<script" not in page
    links = re.findall(r'(?:href|src)="([^"]+)"', page)
    assert links
    for link in links:
        if link.startswith("#"):  # a failed exemplar's row (0.58)
            assert f'id="{link[1:]}"' in page, link
            continue
        assert not link.startswith("/") and (out / link).is_file(), link
    for r in results:
        assert r["name"] in page


def run(src, out, **kw):
    return batch.run(src, out, size=(48, 48), seed=1, fit=FIT, generate=GEN, **kw)


# ------------------------------------------------------------------ finding work
def test_names_are_unique_and_manifest_rows_are_checked(tmp_path):
    for rel in ("a.png", "sub/a.png", "b.png", "b.jpg", "sub/.hidden.png", "notes.txt"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_bytes(b"x")
    names = sorted(it["name"] for it in batch.find_work(tmp_path))
    assert names == ["a", "b_jpg", "b_png", "sub__a"]
    assert sorted(it["name"] for it in batch.find_work(tmp_path, outdir=tmp_path / "sub")) == ["a", "b_jpg", "b_png"]
    twice = tmp_path / "twice.csv"
    twice.write_text("path,size\na.png,32\na.png,64\nsub/a.png,\n")
    first, second, third = [it["name"] for it in batch.find_work(twice)]
    assert first.startswith("a_png_") and second == first + "_2" and third == "sub__a"
    bad = tmp_path / "m.csv"
    bad.write_text("path,colour\na.png,red\n")
    with pytest.raises(TGHopError, match="m.csv line 2: unknown column colour"):
        batch.find_work(bad)
    bad.write_text("path,size\na.png,big\n")
    with pytest.raises(TGHopError, match="line 2: size 'big'"):
        batch.find_work(bad)
    bad = tmp_path / "m.jsonl"
    bad.write_text('{"path": "a.png"}\n[1, 2]\n')
    with pytest.raises(TGHopError, match="m.jsonl line 2"):
        batch.find_work(bad)
    for size, words in (([64, 64, 64], r"size \[64, 64, 64\] is not \[HEIGHT, WIDTH\]"), ([], r"size \[\] is not"),
                        (["a", "b"], "size 'a' is not a whole number"),
                        ([None, 64], "size must be an integer >= 1, got None"),
                        ([64.7, 64], "size must be an integer >= 1, got 64.7")):
        bad.write_text(json.dumps({"path": "a.png", "size": size}) + "\n")
        with pytest.raises(TGHopError, match="m.jsonl line 1: " + words):
            batch.find_work(bad)
    # names of OUTDIR's own files are kept for them; OUTDIR cannot be SOURCE itself
    (tmp_path / "batch.jsonl.png").write_bytes(b"x")
    (tmp_path / "INDEX.HTML.png").write_bytes(b"x")
    # and the thumbnail's: with --count 1 exemplar.png's image was the thumbnail's file, and
    # a name of no letters (\u7eb9\u7406.png) fell back to that name.
    (tmp_path / "Exemplar.png").write_bytes(b"x")
    (tmp_path / "\u7eb9\u7406.png").write_bytes(b"x")
    names = sorted(it["name"] for it in batch.find_work(tmp_path))
    assert names == ["Exemplar_exemplar", "INDEX.HTML_exemplar", "a", "b_jpg", "b_png", "batch.jsonl_exemplar",
                     "sub__a", "unnamed"]
    with pytest.raises(TGHopError, match="OUTDIR is the SOURCE folder"):
        batch.find_work(tmp_path, outdir=tmp_path / "sub" / "..")
    with pytest.raises(TGHopError, match="count must be an integer from 1 to 1,000, got 0"):
        batch.run(tmp_path, tmp_path / "out", count=0)
    with pytest.raises(TGHopError, match="tile must be true or false, got 'maybe'"):
        batch.run(tmp_path, tmp_path / "out", tile="maybe")
    with pytest.raises(TGHopError, match="seed must be an integer >= 0, got -5"):
        batch.run(tmp_path, tmp_path / "out", seed=-5)
    assert not (tmp_path / "out").exists()  # refused before any work


def test_folders_linked_into_source_are_scanned_once(tmp_path):
    # A library of symbolic links to asset folders: os.walk skipped them without a word.
    (tmp_path / "src").mkdir()
    (tmp_path / "assets" / "rock").mkdir(parents=True)
    for rel in ("src/a.png", "assets/rock/r.png"):
        (tmp_path / rel).write_bytes(b"x")
    try:
        (tmp_path / "src" / "rock").symlink_to(tmp_path / "assets" / "rock")
        (tmp_path / "src" / "rock_again").symlink_to(tmp_path / "assets" / "rock")
        (tmp_path / "src" / "loop").symlink_to(tmp_path / "src")
    except OSError:
        pytest.skip("no symbolic links here")
    found = sorted(str(it["rel"]) for it in batch.find_work(tmp_path / "src"))
    assert found == ["a.png", os.path.join("rock", "r.png")]


def test_max_depth_limits_how_deep_a_folder_is_searched(tmp_path):
    # A folder SOURCE was searched at every depth, with no way to take a folder's own images alone
    # (a studio's exemplars beside folders of references, renders, variants).
    src = tmp_path / "src"
    for rel in ("top.png", "a/one.png", "a/b/two.png", "a/b/c/three.png"):
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        (src / rel).write_bytes(b"x")
    found = {d: sorted(it["name"] for it in batch.find_work(src, max_depth=d)) for d in (None, 0, 1, 2, 3)}
    assert found == {None: ["a__b__c__three", "a__b__two", "a__one", "top"], 0: ["top"], 1: ["a__one", "top"],
                     2: ["a__b__two", "a__one", "top"], 3: ["a__b__c__three", "a__b__two", "a__one", "top"]}
    (tmp_path / "deep" / "x" / "y").mkdir(parents=True)
    (tmp_path / "deep" / "x" / "y" / "z.png").write_bytes(b"x")
    with pytest.raises(TGHopError, match=r"no image files in this folder or 1 level of subfolders .*--max-depth"):
        batch.find_work(tmp_path / "deep", max_depth=1)
    with pytest.raises(TGHopError, match=r"no image files in this folder itself \("):
        batch.find_work(tmp_path / "deep", max_depth=0)
    for bad in (-1, 1.5, True, "2"):
        with pytest.raises(TGHopError, match="max_depth must be an integer >= 0"):
            batch.find_work(src, max_depth=bad)
    (src / "list.csv").write_text("path\ntop.png\n")
    with pytest.raises(TGHopError, match="for a folder SOURCE; a manifest lists its files"):
        batch.find_work(src / "list.csv", max_depth=0)
    by = {r["name"]: r for r in batch.run(src, tmp_path / "out", workers=1, max_depth=0)}  # nothing to fit
    assert list(by) == ["top"] and "not a readable image" in by["top"]["error"]
    for value, said in (("-1", "-1 is not in the range x>=0"), ("x", "'x' is not a valid integer"),
                        ("", "'' is not a valid integer")):
        code, _, err, exc = invoke("batch", "src", "-o", "out", "--max-depth", value, cwd=tmp_path)
        assert_one_line(code, err, "--max-depth", said, exception=exc)
        assert code == 2
    code, _, err, exc = invoke("batch", "src/list.csv", "-o", "out", "--max-depth", "1", cwd=tmp_path)
    assert_one_line(code, err, "--max-depth is for a folder SOURCE", exception=exc)
    assert code == 2
    for other in ("--depth", "--recursive", "-r"):  # the names a user tries; --depth is a bit depth elsewhere
        code, _, err, exc = invoke("batch", "src", "-o", "out", other, "1", cwd=tmp_path)
        assert_one_line(code, err, f"No such option '{other}'", "give --max-depth N", exception=exc)
        assert code == 2


def test_a_truncated_jpeg_says_so_in_the_ledger(tmp_path):
    # A guard: it was "not a readable image (OSError)", without the words the rest of tghop gives.
    save_image(data.bricks(64, rng=3), tmp_path / "a.jpg")
    blob = (tmp_path / "a.jpg").read_bytes()
    (tmp_path / "a.jpg").write_bytes(blob[: len(blob) // 2])
    (record,) = batch.run(tmp_path, tmp_path / "out", workers=1)
    assert record["status"] == "failed" and "a.jpg: not a readable image (a JPEG file, cut short (" in record["error"]


def test_a_named_pipe_is_no_exemplar_but_a_broken_link_is_said(tmp_path):
    # A FIFO named like an image was hashed before any work: the run waited for ever on it.
    (tmp_path / "a.png").write_bytes(b"x")
    if not hasattr(os, "mkfifo"):
        pytest.skip("no named pipes here")
    os.mkfifo(tmp_path / "pipe.png")
    try:
        (tmp_path / "gone.png").symlink_to(tmp_path / "nowhere.png")
        (tmp_path / "self.png").symlink_to(tmp_path / "self.png")  # a loop
    except OSError:
        pytest.skip("no symbolic links here")
    assert sorted(it["name"] for it in batch.find_work(tmp_path)) == ["a", "gone", "self"]
    by = {r["name"]: r["error"] for r in batch.run(tmp_path, tmp_path / "out", workers=1)}  # nothing to fit
    assert "not a readable image" in by["a"], by
    assert all("a symbolic link to no file" in by[n] for n in ("gone", "self")), by  # it said "no such file"


def _no_work(job):
    raise AssertionError(f"{job['name']} was run; the settings should have been refused first")


def test_an_earlier_outdir_inside_source_is_no_exemplar(tmp_path):
    src = make_folder(tmp_path / "m", bad=False)
    inside = src / "out"
    assert [r["status"] for r in run(src, inside, workers=1)] == ["ok", "ok"]
    assert sorted(it["name"] for it in batch.find_work(src)) == ["a", "sub__a"]  # m/out/*/*.png left out
    assert sorted(it["name"] for it in batch.find_work(src, tmp_path / "other")) == ["a", "sub__a"]
    (src / "sub" / "out2").mkdir()  # OUTDIR inside SOURCE before it holds a ledger
    save_image(data.bricks(64, rng=5), src / "sub" / "out2" / "x.png")
    assert sorted(it["name"] for it in batch.find_work(src, src / "sub" / "out2")) == ["a", "sub__a"]
    assert "sub__out2__x" in [it["name"] for it in batch.find_work(src, tmp_path / "other")]


def test_bad_settings_are_refused_before_any_work(tmp_path):
    # As synth refuses them: the generation settings against the fit's patch size, the fit's own.
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    for kw, words in ((dict(generate={**GEN, "overlap": 100}), "overlap (overlap, --overlap) must be between 1 and 16 "
                                                               "(half the patch size 32), got 100"),
                      (dict(generate=GEN, fit={**FIT, "patch_size": 64}, size=(48, 48), tile=True),
                       "a tileable output (tile, --tile) needs a height of at least the patch size 64, got 48"),
                      (dict(generate={**GEN, "tolerance": -1}), "tolerance must be"),
                      (dict(generate={**GEN, "colour": 1}), "unknown setting 'colour'"),
                      (dict(generate=GEN, fit={**FIT, "n_clusters": 0}), "n_clusters must be")):
        kw = {"size": (48, 48), "seed": 1, "fit": FIT, **kw}
        with pytest.raises(TGHopError, match=re.escape(words)):
            batch.run(src, out, workers=1, task=_no_work, **kw)
        assert not out.exists()
    # a manifest row's own size or tile: named by its line
    (tmp_path / "m.csv").write_text("path,size,tile\nsrc/a.png,,\nsrc/sub/a.png,20,true\n")
    with pytest.raises(TGHopError, match=re.escape("m.csv line 3: a tileable output (tile, --tile) needs a height "
                                                   "of at least the patch size 32, got 20")):
        run(tmp_path / "m.csv", out, workers=1, task=_no_work)
    assert not out.exists()
    code, _, err, exc = invoke("batch", "src", "-o", "out", "--workers", "1", "--size", "64", "--overlap", "100",
                               *CLI_FAST, cwd=tmp_path)
    assert_one_line(code, err, "--overlap) must be between 1 and 16", exception=exc)
    assert not out.exists()


def test_bad_run_arguments_are_refused_before_any_file(tmp_path):
    # As a Python call: one TGHopError naming the argument, before OUTDIR or its ledger exists.
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    nan = float("nan")
    for kw, words in ((dict(fit={"bogus": 1}), "fit: unknown TGHop setting 'bogus'"),
                      (dict(fit={**FIT, "gamma": nan}), "fit: every number must be finite"),
                      (dict(generate={"tolerance": nan}), "generate: every number must be finite"),
                      (dict(generate={"rng": 5}), "generate: 'rng' is not a synthesize setting"),
                      (dict(generate={"dtype": "uint8"}), "unknown setting 'dtype'"),
                      (dict(fit=[1]), "fit must be a dict"), (dict(generate=[1]), "generate must be a dict"),
                      (dict(progress=5), "progress must be a callable"), (dict(on_result=5), "on_result must be a"),
                      (dict(task=5), "task must be a callable"), (dict(workers=0), "workers must be an integer >= 1"),
                      (dict(workers=-1), "workers must be"), (dict(workers="1"), "workers must be"),
                      (dict(workers=1.0), "workers must be"), (dict(workers=True), "workers must be")):
        kw = {"size": (48, 48), "seed": 1, "fit": FIT, "workers": 1, **kw}
        with pytest.raises(TGHopError, match=re.escape(words)):
            batch.run(src, out, **kw)
        assert not out.exists()
    with pytest.raises(TGHopError, match="outdir must be a folder path"):
        batch.run(src, None, workers=1)


def test_a_local_cluster_of_too_many_workers_is_refused_before_it_starts(tmp_path):
    # `--workers 1000000` (a typo) kept the run making worker processes for ever, Ctrl-C ignored
    # while a cluster starts; one line now, before any file (the most: 4 per core).
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    too_many = batch.WORKERS_PER_CORE * len(os.sched_getaffinity(0)) + 1
    with pytest.raises(TGHopError, match=rf"\(workers, --workers\): {too_many} on this machine's"):
        batch.run(src, out, workers=too_many, task=_no_work)
    assert not out.exists()
    code, _, err, exc = invoke("batch", "src", "-o", "out", "--workers", too_many, *CLI_FAST, cwd=tmp_path)
    assert_one_line(code, err, f"at most {too_many - 1} (4 per core", exception=exc)
    assert not out.exists()


def test_a_small_exemplar_is_told_the_fits_minimum(tmp_path):
    # The fit's check (the smallest exemplar that works), as synth and fit say, whatever the size.
    src = tmp_path / "src"
    src.mkdir()
    for side in (16, 33):
        save_image(data.bricks(64, rng=side)[:side, :side], src / f"s{side}.png")
    results = run(src, tmp_path / "out", workers=1)
    for r in results:
        assert r["status"] == "failed" and "use an exemplar of at least 60x60 pixels" in r["error"], r["error"]
        assert "at least 32x32" not in r["error"]


def test_outdirs_own_files_are_checked_before_any_work(tmp_path):
    # A ledger that cannot be added to (here a link to a missing folder: that holds for root too),
    # and a folder where the ledger or the contact sheet goes: refused before any exemplar is done.
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    out.mkdir()
    (out / "batch.jsonl").symlink_to(tmp_path / "missing" / "batch.jsonl")
    with pytest.raises(TGHopError, match=r"batch.jsonl is a symbolic link to .*missing.batch.jsonl, whose folder "
                                         r".*missing does not exist; create that folder or point the link elsewhere"):
        run(src, out, workers=1, task=_no_work)
    (out / "batch.jsonl").unlink()
    for name, what in (("batch.jsonl", "the ledger"), ("index.html", "the contact sheet")):
        (out / name).mkdir()
        with pytest.raises(TGHopError, match=re.escape(f"{out / name} is a folder, where {what} of the batch goes; "
                                                       "remove that folder or choose another OUTDIR")):
            run(src, out, workers=1, task=_no_work)
        (out / name).rmdir()
    assert sorted(p.name for p in out.iterdir()) == []  # nothing made
    # without a contact sheet, a folder of that name is no matter
    (out / "index.html").mkdir()
    (out / "index.html" / "x").write_text("kept")
    assert all(r["status"] == "ok" for r in run(src / "sub", out, workers=1, contact_sheet=False))


def test_an_outdir_that_cannot_be_made_is_told_what_to_do(tmp_path, monkeypatch):
    # 0.61: "OUTDIR: cannot create the output folder (Read-only file system)", and no fix
    import errno

    src = make_folder(tmp_path / "src", bad=False)
    (tmp_path / "file").write_text("x")
    with pytest.raises(TGHopError, match=r"file.out: cannot create the output folder \(.*\); a file stands where "
                                         "OUTDIR or a folder above it goes; give another OUTDIR"):
        run(src, tmp_path / "file" / "out", workers=1, task=_no_work)

    def read_only(self, *args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(Path, "mkdir", read_only)
    with pytest.raises(TGHopError, match=r"ro: cannot create the output folder \(Read-only file system\); give an "
                                         "OUTDIR on a disk and in a folder you can write to"):
        run(src, tmp_path / "ro", workers=1, task=_no_work)


def test_an_immutable_ledger_is_found_before_the_first_exemplar_is_redone(tmp_path):
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    (first, _) = run(src, out, workers=1)
    model = out / first["model"]
    before = (model.stat().st_mtime_ns, model.read_bytes())
    ledger_file = out / "batch.jsonl"
    try:
        made = subprocess.run(["chattr", "+i", str(ledger_file)], capture_output=True).returncode == 0
    except OSError:
        made = False
    if not made:
        pytest.skip("chattr +i cannot be set here (not root, or the file system has no such attribute)")
    try:
        with pytest.raises(TGHopError, match="batch.jsonl: cannot add to the ledger .*; nothing was done"):
            run(src, out, workers=1, count=2)  # changed settings: everything would be redone
    finally:
        subprocess.run(["chattr", "-i", str(ledger_file)], check=True)
    assert (model.stat().st_mtime_ns, model.read_bytes()) == before and len(ledger(out)) == 2


def test_a_second_batch_into_the_same_outdir_is_refused(tmp_path):
    # Two at once redid each other's exemplars under way and removed their files in the
    # making ("output folder does not exist"); the second is refused while the first runs.
    fcntl = pytest.importorskip("fcntl")
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    (first, _) = run(src, out, workers=1)
    before = (out / first["model"]).read_bytes()
    with open(out / "batch.jsonl", "a") as other:  # as the first batch holds it
        fcntl.flock(other.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(TGHopError, match="another tghop batch is writing to this OUTDIR .*nothing was done"):
            run(src, out, workers=1, count=2)
        # nothing to make, but its hashes and contact sheet would be written over the running batch's (0.61 did)
        with pytest.raises(TGHopError, match="another tghop batch is writing to this OUTDIR"):
            run(src, out, workers=1)
    assert all(r["skipped"] for r in run(src, out, workers=1))  # nothing to make once it ended
    assert (out / first["model"]).read_bytes() == before and len(ledger(out)) == 2
    assert [r["status"] for r in run(src, out, workers=1, count=2)] == ["ok", "ok"]


def test_a_torn_last_line_does_not_swallow_the_next_runs_first(tmp_path):
    # A crash or a full disk mid-line: the next line was appended to the torn one, and lost with it.
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    out.mkdir()
    (out / "batch.jsonl").write_text('{"name": "a", "status": "o')
    assert [r["status"] for r in run(src, out, workers=1)] == ["ok", "ok"]
    assert [r["skipped"] for r in run(src, out, workers=1)] == [True, True]
    torn, *lines = (out / "batch.jsonl").read_text().splitlines()
    assert torn == '{"name": "a", "status": "o'
    assert sorted(json.loads(line)["name"] for line in lines) == ["a", "sub__a"]


def test_a_full_disk_at_the_ledger_still_ends_the_run_tidily(tmp_path, monkeypatch):
    import errno

    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    append, calls = batch.append_ledger, []

    def full_after_one(fh, record, **kw):
        calls.append(record["status"])
        if len(calls) > 1:
            raise OSError(errno.ENOSPC, "No space left on device")
        append(fh, record, **kw)

    monkeypatch.setattr(batch, "append_ledger", full_after_one)
    with pytest.raises(TGHopError, match=r"batch\.jsonl: cannot add to the ledger \(No space left"):  # 0.60: OSError
        run(src, out, workers=1)
    assert calls == ["ok", "ok", "interrupted"]  # the second's line, then its "interrupted" one: both refused
    assert [line["name"] for line in ledger(out)] == ["a"]
    assert "1 of 1 exemplars done" in (out / "index.html").read_text()
    assert not leftovers(out)


def test_a_ctrl_c_right_after_a_line_is_written_leaves_that_exemplar_done(tmp_path, monkeypatch):
    # A Ctrl-C between the ledger line and the removal of the exemplar's RUNNING file left the file: the rerun
    # redid an exemplar its line said was done ("(0 by an earlier run)", a flaky Ctrl-C test under load).
    import signal

    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    append = batch.append_ledger

    def ctrl_c_after_the_line(fh, record, **kw):
        append(fh, record, **kw)
        signal.raise_signal(signal.SIGINT)  # Ctrl-C as the line reaches the disk

    monkeypatch.setattr(batch, "append_ledger", ctrl_c_after_the_line)
    with pytest.raises(KeyboardInterrupt):
        run(src, out, workers=1)
    monkeypatch.setattr(batch, "append_ledger", append)
    assert [line["status"] for line in ledger(out)] == ["ok"]
    assert not list(out.rglob(batch.RUNNING))
    assert [r["skipped"] for r in run(src, out, workers=1)] == [True, False]  # the first is not redone


CRASH_AT_SYNC = """
import os, signal, sys
from tghop import batch

sync, calls = batch.sync_ledger, []

def sync_then_note(fh):
    calls.append(1)
    if len(calls) == int(sys.argv[3]):
        os.kill(os.getpid(), signal.SIGKILL)  # the group's lines written, not yet synced
    sync(fh)
    with open(sys.argv[4], "a") as note:
        note.write(f"{os.path.getsize(fh.name)}\\n")  # what a power loss would keep

batch.sync_ledger = sync_then_note
batch.run(sys.argv[1], sys.argv[2], size=(48, 48), seed=1, fit=dict(n_clusters=6, n_codewords=30, stride=4),
          generate=dict(n_patches=300), workers=1)
"""


def test_a_crash_before_the_ledger_sync_leaves_exactly_those_exemplars_to_redo(tmp_path):
    # 0.59 syncs the ledger once per group of lines (the exemplars that came back together), not per line. A kill
    # of the driver loses no line written; a crash of the machine can lose the lines written since the last sync,
    # so the RUNNING files of a group are removed only once its lines are synced: the rerun redoes exactly the
    # exemplars whose lines were lost, though an earlier line of theirs, with the same settings, says done.
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    run(src, out, workers=1)
    for name in ("a", "sub__a"):  # as a killed run leaves them: this run redoes both
        (out / name / batch.RUNNING).touch()
    script, notes = tmp_path / "crash.py", tmp_path / "synced.txt"
    script.write_text(CRASH_AT_SYNC)
    p = subprocess.run([sys.executable, str(script), str(src), str(out), "2", str(notes)], capture_output=True,
                       timeout=600)
    assert p.returncode == -signal.SIGKILL, p.stderr.decode()
    lines = ledger(out)
    assert [line["name"] for line in lines] == ["a", "sub__a", "a", "sub__a"]  # the kill lost no line written
    assert not (out / "a" / batch.RUNNING).exists() and (out / "sub__a" / batch.RUNNING).exists()
    with open(out / "batch.jsonl", "r+b") as fh:  # a power loss: the lines after the last sync gone
        fh.truncate(int(notes.read_text().split()[-1]))
    assert [line["name"] for line in ledger(out)] == ["a", "sub__a", "a"]
    assert [r["skipped"] for r in run(src, out, workers=1)] == [True, False]
    assert not list(out.rglob(batch.RUNNING))


def stand_in(job):
    """A task that makes nothing: a failed record at once."""
    return {"status": "failed", "error": "a stand-in", "cause": "run", "outputs": [], "model": None,
            "thumbnail": None, "seed_used": job.get("seed"), "started": None, "seconds": None}


def test_a_run_compacts_a_ledger_of_many_superseded_lines(tmp_path, monkeypatch):
    # 0.58's ledger only grew: each exemplar made again (new settings, a retry) added a line after its old ones.
    src, out = make_folder(tmp_path / "src"), tmp_path / "out"
    monkeypatch.setattr(batch_plan, "COMPACT_MIN", 4)
    for seed in (1, 2, 3):
        batch.run(src, out, size=(48, 48), seed=seed, fit=FIT, generate=GEN, workers=1, task=stand_in)
    lines = ledger(out)
    # 12 lines: 8 superseded, at least COMPACT_MIN and as many as the 4 kept
    assert [(line["name"], line["seed_used"]) for line in lines] == [(n, 3) for n in ("a", "bad", "flat", "sub__a")]
    assert not list(out.glob(".batch.jsonl.*"))


def test_compacting_keeps_what_the_ledger_says_and_a_kill_loses_nothing(tmp_path):
    out = tmp_path / "out"
    (out / "a").mkdir(parents=True)
    recs = [{"name": "a", "status": "ok", "outputs": ["a/a_1.png", "a/a_2.png"], "model": "a/a.npz"},
            {"name": "b", "status": "ok", "outputs": ["b/b.png"], "model": "b/b.npz"},
            {"name": "a", "status": "failed", "outputs": [], "model": None},  # lists none: the files above stay
            *({"name": "b", "status": "ok", "outputs": ["b/b.png"], "model": "b/b.npz", "seed_used": i}
              for i in range(6)),
            {"name": "gone", "status": "ok", "outputs": ["gone/g.png"], "model": "gone/g.npz"}]
    text = "".join(json.dumps(r) + "\n" for r in recs) + '{"name": "a", "status": "o'  # torn by a crash
    (out / "batch.jsonl").write_text(text)
    before = batch_plan.read_ledger_files(out)
    script = tmp_path / "compact.py"
    script.write_text("import os, signal, sys\nfrom tghop import batch_plan\nreplace = os.replace\n"
                      "def killed(a, b):\n    if sys.argv[2] == 'after':\n        replace(a, b)\n"
                      "    os.kill(os.getpid(), signal.SIGKILL)\n"
                      "os.replace = killed\nbatch_plan.COMPACT_MIN = 2\nbatch_plan.compact_ledger(sys.argv[1])\n")
    # killed before its move: the old ledger, byte for byte, and a temporary file beside it
    p = subprocess.run([sys.executable, str(script), str(out), "before"], capture_output=True, timeout=120)
    assert p.returncode == -signal.SIGKILL, p.stderr.decode()
    assert (out / "batch.jsonl").read_text() == text and len(list(out.glob(".batch.jsonl.*.tmp"))) == 1
    # killed right after its move: the new ledger, whole
    p = subprocess.run([sys.executable, str(script), str(out), "after"], capture_output=True, timeout=120)
    assert p.returncode == -signal.SIGKILL, p.stderr.decode()
    assert batch_plan.read_ledger_files(out) == before and not list(out.glob(".batch.jsonl.*"))  # the temporary too
    kept = ledger(out)
    assert [(r["name"], r["status"]) for r in kept] == [("a", "ok"), ("a", "failed"), ("b", "ok"), ("gone", "ok")]
    assert kept[2]["seed_used"] == 5


# ------------------------------------------------------------------ in process
def test_in_process_run_records_bad_exemplars_and_resumes(tmp_path):
    src, out = make_folder(tmp_path / "src"), tmp_path / "out"
    seen = []
    results = run(src, out, count=2, workers=1, on_result=lambda r, c: seen.append(dict(c)))
    by = {r["name"]: r for r in results}
    assert sorted(by) == ["a", "bad", "flat", "sub__a"]
    assert seen[-1]["done"] == 4 and seen[-1]["failed"] == 2
    for name in ("a", "sub__a"):
        r = by[name]
        assert r["status"] == "ok" and r["error"] is None and not r["skipped"]
        assert r["outputs"] == [f"{name}/{name}_1.png", f"{name}/{name}_2.png"]
        for f in r["outputs"]:
            assert np.asarray(Image.open(out / f)).shape[:2] == (48, 48)
        assert (out / r["model"]).is_file()
    assert "not a readable image" in by["bad"]["error"] and "no texture" in by["flat"]["error"]
    assert not (out / "bad").exists() and not (out / "flat").exists()
    lines = ledger(out)
    assert len(lines) == 4
    a = next(line for line in lines if line["name"] == "a")
    assert a["sha256"] == hashlib.sha256((src / "a.png").read_bytes()).hexdigest()
    assert a["settings"]["size"] == [48, 48] and a["settings"]["count"] == 2 and a["seconds"] > 0
    # The kernel's part of the task's CPU time, and its page faults (none if the heap was warm).
    assert 0 <= a["sys_seconds"] <= a["cpu_seconds"] + 0.05 and isinstance(a["page_faults"], int)
    assert a["page_faults"] >= 0
    check_sheet(out, results)

    # a rerun skips what is done, and the exemplars whose input failed (unchanged: they would fail again)
    again = {r["name"]: r for r in run(src, out, count=2, workers=1)}
    assert again["a"]["skipped"] and again["sub__a"]["skipped"]
    assert again["bad"]["skipped"] and again["bad"]["status"] == "failed" and len(ledger(out)) == 4
    # a changed input is redone, the unchanged one is not
    save_image(data.bricks(64, rng=9), src / "a.png")
    again = {r["name"]: r for r in run(src, out, count=2, workers=1)}
    assert not again["a"]["skipped"] and again["sub__a"]["skipped"]
    assert again["a"]["sha256"] == hashlib.sha256((src / "a.png").read_bytes()).hexdigest()
    # changed settings redo everything
    again = {r["name"]: r for r in run(src, out, count=1, workers=1)}
    assert not again["a"]["skipped"] and not again["sub__a"]["skipped"]
    assert again["a"]["outputs"] == ["a/a.png"]
    assert sorted(p.name for p in (out / "a").iterdir()) == ["a.npz", "a.png", "exemplar.png"]  # a_1, a_2 gone
    assert not leftovers(out)
    # a deleted thumbnail (the contact sheet's) is made again
    (out / "sub__a" / "exemplar.png").unlink()
    again = {r["name"]: r for r in run(src, out, count=1, workers=1)}
    assert again["a"]["skipped"] and not again["sub__a"]["skipped"] and (out / "sub__a" / "exemplar.png").is_file()
    # a contact sheet of an unfinished batch says so
    page = batch.write_contact_sheet(out, [again["a"]], total=4).read_text()
    assert "1 of 1 exemplars done, 0 failed. 3 not finished yet: run the same command again." in page


def test_a_rerun_skips_the_failures_of_the_input_until_it_changes(tmp_path, monkeypatch):
    # A studio's rerun of thousands tried every bad exemplar again (not an image, flat, too small),
    # each failing as before, and listed them all again. Now the ledger says whose fault a failure
    # was (cause); a rerun skips the input's until its files, settings or tghop change, or retry_failed.
    import tghop
    from tghop import synthesis

    src, out = make_folder(tmp_path / "src"), tmp_path / "out"
    save_image(data.bricks(64, rng=5)[:16, :16], src / "small.png")
    bad = ("bad", "flat", "small")
    first = {r["name"]: r for r in run(src, out, workers=1)}
    assert [first[n]["cause"] for n in bad] == ["input"] * 3 and first["a"]["cause"] is None
    assert {line["version"] for line in ledger(out)} == {tghop.__version__}
    plans = []
    again = {r["name"]: r for r in run(src, out, workers=1, on_plan=plans.append)}
    assert plans == [{"exemplars": 5, "done_before": 2, "failed_before": 3, "to_do": 0}]
    assert all(again[n]["skipped"] and again[n]["status"] == "failed" for n in bad) and len(ledger(out)) == 5
    assert again["small"]["error"] == first["small"]["error"]  # the earlier record, its reason
    # a changed file is tried again (still no image: a new line), the others are not
    (src / "bad.png").write_bytes(b"still not an image")
    counts = []
    again = {r["name"]: r for r in run(src, out, workers=1, on_result=lambda r, c: counts.append(c))}
    assert [again[n]["skipped"] for n in bad] == [False, True, True] and len(ledger(out)) == 6
    # on_result's counts: those done before and those failed before apart (0.56 summed them in skipped)
    assert counts == [{"done": 1, "failed": 1, "running": 0, "total": 1, "skipped": 2, "failed_before": 2}]
    # so is every failure of the input with retry_failed, and with other settings
    again = {r["name"]: r for r in run(src, out, workers=1, retry_failed=True)}
    assert [again[n]["skipped"] for n in bad] == [False] * 3 and again["a"]["skipped"] and len(ledger(out)) == 9
    again = {r["name"]: r for r in run(src, out, workers=1, count=2)}
    assert not any(r["skipped"] for r in again.values()) and len(ledger(out)) == 14
    # a line of another tghop, or of one before causes were recorded: tried again (it may read it now)
    lines = ledger(out)
    for line in lines:
        if line["name"] == "flat":
            line["version"] = "0.54.0"
        if line["name"] == "small":
            del line["cause"]
    (out / "batch.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    again = {r["name"]: r for r in run(src, out, workers=1, count=2)}
    assert [again[n]["skipped"] for n in bad] == [True, False, False]
    # a failure of the run's (memory, a lost worker, an interruption) is always tried again
    one = tmp_path / "one"
    one.mkdir()
    save_image(data.bricks(64, rng=3), one / "a.png")

    def no_memory(*args, **kwargs):
        raise MemoryError

    with monkeypatch.context() as m:
        m.setattr(synthesis, "prepare_exemplar", no_memory)  # the task's, in the task
        (r,) = run(one, tmp_path / "out1", workers=1)
    assert r["status"] == "failed" and r["cause"] == "run" and "out of memory" in r["error"]
    (r,) = run(one, tmp_path / "out1", workers=1)
    assert r["status"] == "ok" and not r["skipped"]
    # so is too little memory to decode the image (tghop's one line for it was the input's, 0.56)
    from PIL import ImageFile

    with monkeypatch.context() as m:
        m.setattr(ImageFile.ImageFile, "load", no_memory)  # Pillow's decoding, out of memory
        (r,) = run(one, tmp_path / "out2", workers=1)
    assert r["status"] == "failed" and r["cause"] == "run" and "not enough memory to decode" in r["error"], r
    (r,) = run(one, tmp_path / "out2", workers=1)
    assert r["status"] == "ok" and not r["skipped"]


def test_a_failed_try_in_between_leaves_no_stale_images(tmp_path):
    # count 2, then the exemplar broken (a failed line, which lists no file: a_1, a_2 stay as
    # they were), then fixed with count 1: a_1 and a_2 go, as after a rerun straight away.
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    save_image(data.bricks(64, rng=3), src / "a.png")
    good = (src / "a.png").read_bytes()
    assert run(src, out, workers=1, count=2)[0]["status"] == "ok"
    (src / "a.png").write_bytes(b"not an image")
    assert run(src, out, workers=1, count=2)[0]["status"] == "failed"
    assert sorted(p.name for p in (out / "a").iterdir()) == ["a.npz", "a_1.png", "a_2.png", "exemplar.png"]
    (src / "a.png").write_bytes(good)
    assert run(src, out, workers=1, count=1)[0]["status"] == "ok"
    assert sorted(p.name for p in (out / "a").iterdir()) == ["a.npz", "a.png", "exemplar.png"]


def test_accented_names_keep_their_letters(tmp_path):
    """Accents are dropped, not the letters: "ünï/béans.jpg" is uni__beans (it was __n___b_ans); a
    name of no Latin letter at all is still a safe, unique name."""
    for rel in ("ünï/béans.jpg", "Crème brûlée.png", "石头.png", "砖.png"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_bytes(b"x")
    names = sorted(it["name"] for it in batch.find_work(tmp_path))
    assert names[:2] == ["Creme_brulee", "uni__beans"], names
    assert len(set(names)) == 4 and all(re.fullmatch(r"[A-Za-z0-9._-]+", n) for n in names), names


def test_an_exemplar_deep_in_folders_gets_a_name_its_files_fit(tmp_path):
    # Folders joined by "__" made a name of 264 characters: "File name too long" for a good
    # exemplar. A long path's name is its start and a hash; a long given name is refused.
    src, out = tmp_path / "src", tmp_path / "out"
    deep = src / ("a" * 100) / ("b" * 100)
    deep.mkdir(parents=True)
    save_image(data.bricks(64, rng=3), deep / ("c" * 60 + ".png"))
    save_image(data.cells(64, rng=4), deep / ("c" * 60 + ".jpg"))  # the same name, then its extension
    out.mkdir()  # the line of an earlier version's try, under the name too long (its name is not kept)
    long_name = "__".join(["a" * 100, "b" * 100, "c" * 60, "png"])
    (out / "batch.jsonl").write_text(json.dumps({"name": long_name, "source": str(deep / ("c" * 60 + ".png")),
                                                 "status": "failed", "error": "File name too long"}) + "\n")
    results = run(src, out, workers=1, count=2)
    assert [r["status"] for r in results] == ["ok", "ok"], [r["error"] for r in results]
    names = [r["name"] for r in results]
    assert len(set(names)) == 2 and all(len(n) <= batch.NAME_MAX and n.startswith("a" * 100) for n in names)
    assert all((out / f).is_file() for r in results for f in r["outputs"])
    (tmp_path / "m.csv").write_text(f"path,name\nsrc/x.png,{'n' * 161}\n")
    with pytest.raises(TGHopError, match="m.csv line 2: the name 'nnn.*is 161 characters long"):
        run(tmp_path / "m.csv", out, workers=1, task=_no_work)


def test_no_name_starts_with_a_dash(tmp_path):
    # "-dash/--2.png" was the folder "-dash__--2" and the model "-dash__--2.npz": options to
    # `tghop synth`, `ls` and `rm`. Names start with a letter or digit, as a map's do.
    for rel in ("-dash/--2.png", "-lead.png", "lead.png", "_x/.-y/z.png"):
        (tmp_path / "src" / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / "src" / rel).write_bytes(b"x")
    names = sorted(it["name"] for it in batch.find_work(tmp_path / "src"))
    assert len(set(names)) == 3 and names[0] == "dash__--2" and all(n.startswith("lead_png_") for n in names[1:])
    (tmp_path / "m.csv").write_text("path,name\nsrc/lead.png,-given\n")
    assert [it["name"] for it in batch.find_work(tmp_path / "m.csv")] == ["given"]


def test_no_name_is_one_windows_keeps_for_a_device(tmp_path):
    # "con.png" was the folder "con" and the model "con/con.npz": an OUTDIR copied to Windows (or
    # made on a share it serves) cannot hold them. Such a name gets "_" after its device's name;
    # every other name is as before, so resumed runs find their work.
    from tghop.batch_plan import keep_ledger_names, windows_reserved

    src = tmp_path / "src"
    rels = ("con.png", "Nul.jpg", "aux.v2.png", "com1.png", "LPT9.png", "prn.png", "lpt0.png",  # devices
            "com10.png", "console.png", "x.con.png", "sub/con.png", "comx.png", "a.nul.png")  # ordinary
    for rel in rels:
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        (src / rel).write_bytes(b"x")
    names = {str(it["rel"]): it["name"] for it in batch.find_work(src)}
    assert names == {"con.png": "con_", "Nul.jpg": "Nul_", "aux.v2.png": "aux_.v2", "com1.png": "com1_",
                     "LPT9.png": "LPT9_", "prn.png": "prn_", "lpt0.png": "lpt0_", "com10.png": "com10",
                     "console.png": "console", "x.con.png": "x.con", "sub/con.png": "sub__con", "comx.png": "comx",
                     "a.nul.png": "a.nul"}, names
    assert not any(windows_reserved(n) for n in names.values())
    (src / "con_.png").write_bytes(b"x")  # "con_" is "con" too (no name ends in "_"): still two names
    names = [it["name"] for it in batch.find_work(src)]
    assert len({n.lower() for n in names}) == len(names) and not any(windows_reserved(n) for n in names)
    (tmp_path / "m.csv").write_text("path,name\nsrc/con.png,AUX\nsrc/Nul.jpg,nul.tex\nsrc/prn.png,prn tex\n")
    assert [it["name"] for it in batch.find_work(tmp_path / "m.csv")] == ["AUX_", "nul_.tex", "prn_tex"]
    # An earlier run's folder "con" (before names avoided devices) is not kept; an ordinary one is.
    items = batch.find_work(src)
    previous = {"con": {"source": str(src / "con.png")}, "old_console": {"source": str(src / "console.png")}}
    keep_ledger_names(items, previous)
    by = {str(it["rel"]): it["name"] for it in items}
    assert by["console.png"] == "old_console" and not windows_reserved(by["con.png"])
    assert [windows_reserved(n) for n in ("con", "CON.txt", "nul .x", "a.", "a ", "com0", "comx", "aa")] == \
        [True, True, True, True, True, True, False, False]


def test_a_file_added_beside_an_exemplar_does_not_rename_it(tmp_path):
    src, out = tmp_path / "src", tmp_path / "out"
    (src / "sub").mkdir(parents=True)
    save_image(data.bricks(64, rng=3), src / "sub" / "tex.png")
    (first,) = run(src, out, workers=1)
    assert first["name"] == "sub__tex" and first["status"] == "ok"
    save_image(data.cells(64, rng=4), src / "sub__tex.png")  # would take the name sub__tex too
    again = {r["source"]: r for r in run(src, out, workers=1)}
    kept, new = again[str(src / "sub" / "tex.png")], again[str(src / "sub__tex.png")]
    assert kept["name"] == "sub__tex" and kept["skipped"]  # not fitted again under a new name
    assert new["name"] != "sub__tex" and new["status"] == "ok" and not new["skipped"]
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == sorted(["sub__tex", new["name"]])
    # a name a manifest row gives wins over the ledger's
    (tmp_path / "m.csv").write_text(f"path,name\n{src / 'sub' / 'tex.png'},mine\n")
    with pytest.warns(UserWarning, match=r"1 folder of exemplars no longer in SOURCE: sub__tex_png_"):
        (named,) = run(tmp_path / "m.csv", out, workers=1)  # the folder-named ones are no exemplars of it
    assert named["name"] == "mine" and named["status"] == "ok"
    assert named["renamed_from"] == "sub__tex"  # 0.62: the same input and settings, its files moved to the new name


def test_a_csv_manifest_refuses_cells_its_header_does_not_name(tmp_path):
    bad = tmp_path / "m.csv"
    for text, words in (("path,size\na.png,32\nb.png,32,64\n", "m.csv line 3 has 3 cells, the header 2; remove"),
                        ("path,,size\na.png,big,32\n", "m.csv line 2: 'big' is in a column the header does not name"),
                        ("path,size,size\na.png,32,64\n", "m.csv: the header names the column 'size' twice"),
                        ("path,size\n\na.png,big\n", "m.csv line 3: size 'big'")):  # blank lines count
        bad.write_text(text)
        with pytest.raises(TGHopError, match=re.escape(words)):
            batch.find_work(bad)
    bad.write_text("path,size,\na.png,32,,\n")  # empty trailing cells, as spreadsheets write them, are no cells
    assert [it["settings"] for it in batch.find_work(bad)] == [{"size": [32, 32]}]


def test_a_manifest_separated_by_semicolons_is_told_so(tmp_path):
    # It said "needs a header line with a 'path' column" of a header that has one, between ';'.
    for sep, shown in ((";", "';'"), ("\t", "'\\t'")):
        bad = tmp_path / "m.csv"
        bad.write_text(f"path{sep}size\na.png{sep}32\n")
        with pytest.raises(TGHopError, match=re.escape(f"m.csv: the header line is separated by {shown}, not commas; "
                                                       "a CSV manifest's cells are separated by commas")):
            batch.find_work(bad)
    bad.write_text("file;size\na.png;32\n")  # no path column whatever the separator: the plain message
    with pytest.raises(TGHopError, match="needs a header line with a 'path' column"):
        batch.find_work(bad)


def test_a_manifest_that_lists_one_file_twice_warns_naming_the_lines(tmp_path):
    # It was made twice (NAME and NAME_2) without a word.
    m = tmp_path / "m.csv"
    m.write_text("path,size\na.png,32\nb.png,32\n./a.png,32\na.png,64\nb.png,32\n")
    with pytest.warns(UserWarning) as caught:
        names = [it["name"] for it in batch.find_work(m)]
    assert [str(w.message) for w in caught] == [
        f"{m} line 4 lists a.png as line 2 does, with the same settings: it is made twice; remove the line, or give "
        "count for more results of one exemplar",
        f"{m} line 6 lists b.png as line 3 does, with the same settings: it is made twice; remove the line, or give "
        "count for more results of one exemplar"]
    assert len(set(names)) == 5  # still each its own folder
    m.write_text("path,size,name\na.png,32,one\na.png,32,two\na.png,64\n")  # named, or other settings: meant
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(batch.find_work(m)) == 3


def test_a_json_manifest_takes_path_and_name_only_as_strings(tmp_path):
    bad = tmp_path / "m.jsonl"
    for row, words in (({"path": ["pep.png"]}, "m.jsonl line 2: path ['pep.png'] is not a string; write it in quotes"),
                       ({"path": 7}, "line 2: path 7 is not a string"),
                       ({"path": "a.png", "name": 5}, "line 2: name 5 is not a string"),
                       ({"path": "a.png", "name": False}, "line 2: name False is not a string"),
                       ({"path": "a.png", "name": ["x"]}, "line 2: name ['x'] is not a string"),
                       ({"path": "a.png", "": 3}, "line 2: unknown column ''")):
        bad.write_text(json.dumps({"path": "b.png"}) + "\n" + json.dumps(row) + "\n")
        with pytest.raises(TGHopError, match=re.escape(words)):
            batch.find_work(bad)
    bad.write_text(json.dumps({"path": " a.png ", "name": None}) + "\n")
    (item,) = batch.find_work(bad)
    assert item["rel"] == Path("a.png") and item["name"] == "a" and not item["named"]


def test_one_boolean_rule_names_its_field():
    from tghop.manifest import parse_bool

    for text, want in (("1", True), (" Yes ", True), ("ON", True), ("true", True), (True, True),
                       ("0", False), ("no", False), (" off", False), ("FALSE", False), (False, False)):
        assert parse_bool(text, "tile") is want
    with pytest.raises(TGHopError, match=re.escape("line 3: windows must be true or false, got 'maybe'")):
        parse_bool("maybe", "windows", where="line 3")
    with pytest.raises(TGHopError, match=re.escape("tile must be true or false, got ' '")):
        parse_bool(" ", "tile")  # blank text is refused unless the caller says what it means
    assert parse_bool(" ", "paper", empty=False) is False and parse_bool("", "paper", empty=True) is True


def test_one_size_syntax_for_manifests_and_the_command_line():
    from tghop.manifest import parse_size, split_size

    for text, pair in ((" 3 x 4 ", (3, 4)), ("3X4", (3, 4)), ("3*4", (3, 4)), ("3, 4", (3, 4)), ("7", (7, 7)),
                       (512, (512, 512))):
        assert split_size(text) == pair == split_size(text, signed=True)
    for text in ("3x", "x4", "3x4x5", "3.0x4", "big", ""):
        assert split_size(text) is None and split_size(text, signed=True) is None
    # a minus sign: the command line reads it (check_size then states the range), a manifest does not
    assert split_size("-5") is None and split_size("-5", signed=True) == (-5, -5)
    assert split_size("5x-6", signed=True) == (5, -6)
    with pytest.raises(TGHopError, match=re.escape("line 2: size '-5' is not HEIGHTxWIDTH")):
        parse_size("-5", "line 2")
    assert parse_size("3x4", "line 2") == [3, 4] and parse_size([5], "line 2") == [5, 5]


def test_manifest_numbers_are_integers_not_floats(tmp_path):
    bad = tmp_path / "m.jsonl"
    for key, value, words in (("count", 2.0, "count 2.0 has a decimal point; write 2"),
                              ("seed", 1e3, "seed 1000.0 has a decimal point; write 1000"),
                              ("size", [64.0, 64], "size 64.0 has a decimal point; write 64"),
                              ("count", True, "count must be an integer from 1 to 1,000, got True")):
        bad.write_text(json.dumps({"path": "a.png", key: value}) + "\n")
        with pytest.raises(TGHopError, match="m.jsonl line 1: " + re.escape(words)):
            batch.find_work(bad)
    (tmp_path / "a.png").write_bytes(b"x")
    with pytest.raises(TGHopError, match=re.escape("count 2.0 has a decimal point")):
        batch.run(tmp_path, tmp_path / "out", count=2.0)
    assert not (tmp_path / "out").exists()


def test_manifests_give_per_row_settings(tmp_path):
    make_folder(tmp_path / "img", bad=False)
    csv_file = tmp_path / "list.csv"
    csv_file.write_text("path,size,count,seed,tile\nimg/a.png,40x56,2,5,true\nimg/sub/a.png,,,,\n")
    results = run(csv_file, tmp_path / "out_csv", workers=1)
    a, b = results
    assert (a["name"], b["name"]) == ("img__a", "img__sub__a")
    assert a["settings"]["size"] == [40, 56] and a["settings"]["tile"] and a["seed_used"] == 5
    assert (len(a["outputs"]) == 2
            and np.asarray(Image.open(tmp_path / "out_csv" / a["outputs"][0])).shape[:2] == (40, 56))
    assert b["settings"]["size"] == [48, 48] and len(b["outputs"]) == 1 and b["seed_used"] == 1
    jsonl = tmp_path / "list.jsonl"
    jsonl.write_text(json.dumps({"path": str(tmp_path / "img" / "a.png"), "name": "first", "size": [40, 40]}) + "\n"
                     + json.dumps({"path": "img/missing.png", "count": 3}) + "\n")
    first, missing = run(jsonl, tmp_path / "out_jsonl", workers=1)
    assert first["name"] == "first" and first["status"] == "ok" and first["settings"]["size"] == [40, 40]
    assert missing["status"] == "failed" and "no such file" in missing["error"] and missing["sha256"] is None


def test_a_python_run_over_the_commands_outdir_does_nothing_again(tmp_path):
    # The command recorded every setting and run() only those given: a run() over the
    # command's OUTDIR (the same settings) fitted every exemplar again, and the other way round.
    make_folder(tmp_path / "img", bad=False)
    out = tmp_path / "out"
    code, _, err, _ = invoke("batch", tmp_path / "img", "-o", out, "--size", "32", "--seed", "1", "--clusters", "6",
                             "--codewords", "30", "--stride", "4", "--workers", "1", "-q", cwd=tmp_path)
    assert code == 0, err
    again = batch.run(tmp_path / "img", out, size=32, seed=1, fit=FIT, workers=1)
    assert [r["skipped"] for r in again] == [True, True]
    defaults = batch.run(tmp_path / "img", tmp_path / "out2", size=32, seed=1, workers=1,
                         fit={"n_clusters": 6, "n_codewords": 30, "stride": 4, "rng": 0, "gamma": 0.003})
    assert [r["settings"] for r in defaults] == [r["settings"] for r in again]  # defaults given or not: the same


def test_a_manifest_row_gives_its_own_working_scale(tmp_path):
    from tghop.modelfile import load_model

    make_folder(tmp_path / "img", bad=False)
    csv_file = tmp_path / "list.csv"
    csv_file.write_text("path,scale\nimg/a.png,1.5\nimg/sub/a.png,\n")
    a, b = run(csv_file, tmp_path / "out", workers=1)
    assert a["settings"]["fit"] == {**b["settings"]["fit"], "scale": 1.5} and b["settings"]["fit"]["scale"] == 1.0
    assert load_model(tmp_path / "out" / a["model"]).exemplar_shape_[:2] == (96, 96)
    assert load_model(tmp_path / "out" / b["model"]).exemplar_shape_[:2] == (64, 64)
    csv_file.write_text("path,scale\nimg/a.png,1.25\nimg/sub/a.png,\n")  # a changed scale redoes its row only
    a, b = run(csv_file, tmp_path / "out", workers=1)
    assert not a["skipped"] and b["skipped"]
    assert load_model(tmp_path / "out" / a["model"]).exemplar_shape_[:2] == (80, 80)
    for cell, words in (("0", "scale must be a finite number > 0 and <= 4, got 0.0"),
                        ("big", "scale 'big' is not a number")):
        csv_file.write_text(f"path,scale\nimg/a.png,{cell}\n")
        with pytest.raises(TGHopError, match="list.csv line 2: " + re.escape(words)):
            run(csv_file, tmp_path / "out2", workers=1)
    assert not (tmp_path / "out2").exists()


def test_an_interrupted_exemplar_leaves_no_files_of_its_own(tmp_path, monkeypatch):
    # Ctrl-C in process during the second image: nothing of this try is left, an earlier run's files stay.
    from tghop.synthesis import TGHop

    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    (src / "sub" / "a.png").unlink()
    (first,) = run(src, out, workers=1)
    before = {p.name: p.read_bytes() for p in (out / "a").iterdir()}
    assert sorted(before) == ["a.npz", "a.png", "exemplar.png"]
    original, calls = TGHop.synthesize, []

    def interrupted(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return original(self, *args, **kwargs)

    monkeypatch.setattr(TGHop, "synthesize", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run(src, out, workers=1, count=2)
    assert {p.name: p.read_bytes() for p in (out / "a").iterdir()} == before and not leftovers(out)
    shutil.rmtree(out)
    calls.clear()
    with pytest.raises(KeyboardInterrupt):
        run(src, out, workers=1, count=2)
    assert not (out / "a").exists() and not leftovers(out)
    monkeypatch.setattr(TGHop, "synthesize", original)
    (again,) = run(src, out, workers=1, count=2)
    assert again["status"] == "ok" and sorted(p.name for p in (out / "a").iterdir()) == [
        "a.npz", "a_1.png", "a_2.png", "exemplar.png"]


def finish_then_ctrl_c(job):
    batch.process_exemplar(job)  # its files moved into place, as a worker finishing while its cluster closes
    raise KeyboardInterrupt


def test_an_exemplar_whose_result_never_came_back_is_done_again(tmp_path):
    # Ctrl-C while a task runs: on a local cluster the worker finishes it while the cluster
    # closes and moves seed 2's files into place without a ledger line; the rerun with seed 1
    # must not take them for seed 1's.
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    save_image(data.bricks(64, rng=3), src / "a.png")
    assert run(src, out, workers=1)[0]["status"] == "ok"
    seed_1 = (out / "a" / "a.png").read_bytes()
    with pytest.raises(KeyboardInterrupt):
        batch.run(src, out, size=(48, 48), seed=2, fit=FIT, generate=GEN, workers=1, task=finish_then_ctrl_c)
    assert (out / "a" / "a.png").read_bytes() != seed_1
    last = ledger(out)[-1]
    assert last["status"] == "interrupted" and last["settings"]["seed"] == 2 and "does it again" in last["error"]
    (again,) = run(src, out, workers=1)
    assert again["status"] == "ok" and not again["skipped"] and (out / "a" / "a.png").read_bytes() == seed_1
    assert run(src, out, workers=1)[0]["skipped"]


def test_a_model_file_in_a_manifest_is_named_as_one(tmp_path):
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    (src / "sub" / "a.png").unlink()
    (first,) = run(src, out, workers=1)
    (tmp_path / "m.csv").write_text(f"path\n{out / first['model']}\n")
    (failed,) = run(tmp_path / "m.csv", tmp_path / "out2", workers=1)
    assert failed["error"] == f"{out / first['model']} is a model file, not an image; list the exemplar image"


def test_a_missing_or_misnamed_npz_exemplar_is_worded_for_what_it_is(tmp_path):
    # 0.58 took any exemplar named *.npz for a model file: a missing x.npz failed as Python's FileNotFoundError
    # (cause run), a PNG saved as y.npz was "a model file". The content decides, as tghop fit reads it.
    save_image(data.bricks(64, rng=3), tmp_path / "y.png")
    (tmp_path / "y.png").rename(tmp_path / "y.npz")
    (tmp_path / "m.csv").write_text("path\nx.npz\ny.npz\n")
    missing, image = run(tmp_path / "m.csv", tmp_path / "out", workers=1)
    assert missing["error"] == f"{tmp_path / 'x.npz'}: no such file; check the path" and missing["cause"] == "input"
    assert image["status"] == "ok", image["error"]


def test_names_a_manifest_gives_are_kept_and_clashes_refused(tmp_path):
    m = tmp_path / "m.csv"
    m.write_text("path,name\nx.png,Tom\ny.png,\nz.png,y\nsub/w.png,my tex\n")
    assert [it["name"] for it in batch.find_work(m)] == ["Tom", "y_png", "y", "my_tex"]
    m.write_text("path,name\nx.png,Tom\ny.png,tom\n")
    with pytest.raises(TGHopError, match=re.escape(f"{m} line 3: the name 'tom' and {m} line 2's 'Tom' are one "
                                                   "folder name in OUTDIR")):
        batch.find_work(m)


def test_manifest_errors_name_the_file_alike(tmp_path):
    bad = tmp_path / "m.jsonl"
    for text in ('{"path": "a.png", "colour": 1}\n', "[1]\n", '{"path": "a.png", "size": "big"}\n'):
        bad.write_text(text)
        with pytest.raises(TGHopError, match=re.escape(f"{bad} line 1: ")):
            batch.find_work(bad)


@pytest.mark.parametrize("case", ["huge cell", "nul in path", "nul in a map", "nested JSON", "unclosed quote",
                                  "latin-1", "utf-16", "many columns"])
def test_an_odd_manifest_is_one_line_naming_its_line(tmp_path, case):
    """0.57: a cell over the csv module's 131,072 characters, a NUL in a path and JSON nested thousands deep were
    tracebacks; a quote left open ran the batch on a path of several rows; a file not UTF-8 was the codec's
    words; a header of 100,000 columns was checked for repeats pairwise (minutes)."""
    bad = tmp_path / ("m.jsonl" if case == "nested JSON" else "m.csv")
    data = {"huge cell": b"path,name\na.png," + b"x" * 200_000 + b"\n",
            "nul in path": b"path,size\na.png\x00,32\n",
            "nul in a map": b"path,maps\na.png,normal=n\x00.png\n",
            "nested JSON": b"[" * 100_000 + b"]" * 100_000 + b"\n",
            "unclosed quote": b'path,size\n"a.png,32\nb.png,16\n',
            "latin-1": "path,name\na.png,café\n".encode("latin-1"),
            "utf-16": "path,size\r\na.png,32\r\n".encode("utf-16"),
            "many columns": (b"path," + b",".join(b"c%d" % i for i in range(100_000)) + b"\na.png" + b",1" * 10
                             + b"\n")}[case]
    bad.write_bytes(data)
    words = {"huge cell": f"{bad} line 2: field larger than field limit (131072) (a quote left open?); close the quote",
             "nul in path": f"{bad} line 2: the path 'a.png\\x00' holds a NUL character, which no file name can",
             "nul in a map": f"{bad} line 2: the path 'n\\x00.png' holds a NUL character",
             "nested JSON": f"{bad} line 1: not a JSON object",
             "unclosed quote": f"{bad} line 3: the path 'a.png,32\\nb.png,16' holds a line break (a quote left open?)",
             "latin-1": f"{bad}: cannot read the manifest (not UTF-8 text: byte 0xe9 at 19); save it as UTF-8",
             "utf-16": f"{bad}: cannot read the manifest (UTF-16 text: byte 0xff at 0); save it as UTF-8",
             "many columns": f"{bad} line 2: unknown column c0, c1, c2, c3, c4 and 5 more; a manifest gives path"
             }[case]
    code, _, err, exc = invoke("batch", str(bad), "-o", str(tmp_path / "out"), "--size", "16", cwd=tmp_path)
    assert_one_line(code, err, words, exception=exc)
    assert not (tmp_path / "out").exists()


def test_a_json_string_or_csv_cell_may_hold_what_splitlines_splits_at(tmp_path):
    """0.57 split the file at U+2028, form feeds and other breaks str.splitlines knows: a JSON line holding one
    raw (as json.dumps(ensure_ascii=False) writes it) was "not a JSON object"."""
    good = tmp_path / "m.jsonl"
    good.write_text('{"path": "a.png", "name": "x\u2028y"}\n', encoding="utf-8")
    assert [it["given"] for it in batch.find_work(good)] == ["x\u2028y"]
    good = tmp_path / "m.csv"
    good.write_text('path,name\na.png,"x\fy"\n', encoding="utf-8")
    assert [it["given"] for it in batch.find_work(good)] == ["x\fy"]


# ------------------------------------------------------------------ the command line
def test_cli_end_to_end_in_process(tmp_path):
    src = make_folder(tmp_path / "src")
    code, _, err, exc = invoke("batch", "src", "-o", "out", "--workers", "1", "--size", "48", "--count", "2",
                               "--seed", "3", *CLI_FAST, cwd=tmp_path)
    assert_one_line(code, err, "2 of 4 exemplars failed", "bad", "flat", exception=exc)
    assert code == 1
    assert "failed: bad:" in err and "not a readable image" in err and "2 of 4 exemplars done" in err
    out = tmp_path / "out"
    assert sorted(p.name for p in (out / "a").iterdir()) == ["a.npz", "a_1.png", "a_2.png", "exemplar.png"]
    check_sheet(out, [{"name": n} for n in ("a", "sub__a", "bad", "flat")])
    # all good: exit 0, nothing redone
    (src / "bad.png").unlink()
    (src / "flat.png").unlink()
    code, _, err, _ = invoke("batch", "src", "-o", "out", "--workers", "1", "--size", "48", "--count", "2",
                             "--seed", "3", *CLI_FAST, cwd=tmp_path)
    assert code == 0, err
    assert "2 of 2 exemplars done (2 by an earlier run)" in err
    code, _, err, exc = invoke("batch", "src", "-o", "o2", "--workers", "2", "--scheduler", "tcp://x:1", cwd=tmp_path)
    assert_one_line(code, err, "--workers and --scheduler", exception=exc)
    assert code == 2  # a usage error (it exited 1)
    code, _, err, exc = invoke("batch", "nothere", "-o", "o3", cwd=tmp_path)
    assert_one_line(code, err, "nothere", "no such folder or manifest", exception=exc)


def test_folders_of_exemplars_gone_from_source_are_said_and_pruned_on_request(tmp_path):
    # Exemplars removed from SOURCE between runs left their folders in OUTDIR, and nothing said
    # so. Now each run names them; --prune deletes the files the ledger says tghop made there,
    # and the folder where nothing else is in it; never anything else.
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    save_image(data.cells(64, rng=5), src / "c.png")
    args = ["batch", "src", "-o", "out", "--workers", "1", "--size", "48", "--seed", "1", *CLI_FAST]
    code, _, err, _ = invoke(*args, cwd=tmp_path)
    assert code == 0, err
    (src / "c.png").unlink()
    (src / "sub" / "a.png").unlink()
    (out / "sub__a" / "notes.txt").write_text("mine")  # the user's own file in one of them
    (out / "mine").mkdir()  # a folder no ledger line names
    (out / "mine" / "mine.png").write_bytes(b"x")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "e.png").write_bytes(b"x")
    (out / "link").symlink_to(elsewhere)
    with open(out / "batch.jsonl", "a") as fh:  # hand-edited lines: a link, a path out of OUTDIR
        for name, files in (("link", ["link/e.png"]), ("..", ["../src/a.png"]), ("x/..", ["src/a.png"])):
            fh.write(json.dumps({"name": name, "status": "ok", "outputs": files, "model": files[0]}) + "\n")
    def listing():  # the hash cache is written once its files are 2 s old (STAT_MARGIN): by whichever run comes then
        return sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.name != ".batch-hashes.json")

    every = listing()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (a,) = run(src, out, workers=1)
    assert a["skipped"]
    said = [str(w.message) for w in caught if "no longer in SOURCE" in str(w.message)]
    assert len(said) == 1 and "2 folders of exemplars no longer in SOURCE: c, sub__a; prune=True" in said[0], said
    code, _, err, _ = invoke(*args, cwd=tmp_path)
    assert code == 0, err
    assert "no longer in SOURCE: c: kept\nno longer in SOURCE: sub__a: kept\n" in err, err
    assert "; 2 folders of exemplars no longer in SOURCE kept (--prune removes them)" in err, err
    assert listing() == every  # nothing removed
    code, _, err, _ = invoke(*args, "--prune", cwd=tmp_path)
    assert code == 0, err
    assert "no longer in SOURCE: c: removed\n" in err and "sub__a: its files removed, the folder kept" in err, err
    assert "2 folders of exemplars no longer in SOURCE: 1 removed, 1 kept for files tghop did not make" in err, err
    left = listing()
    assert left == sorted([p for p in every if not p.startswith(("out/c", "out/sub__a/"))] + ["out/sub__a/notes.txt"])
    code, _, err, _ = invoke(*args, "--prune", cwd=tmp_path)  # the user's folder is not tghop's any more
    assert code == 0 and "no longer in SOURCE" not in err, err
    (a,) = run(src, out, workers=1)
    assert a["skipped"] and a["status"] == "ok"


def test_prune_keeps_the_results_of_a_source_folder_missing_or_unreadable(tmp_path, monkeypatch):
    # 0.61 pruned every exemplar of a share that was down (or a folder not mounted): a studio lost finished work.
    from tghop import batch_plan

    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    save_image(data.cells(64, rng=5), src / "sub" / "c.png")
    assert len(run(src, out, workers=1)) == 3
    (src / "sub").rename(tmp_path / "away")  # the share is down
    with pytest.warns(UserWarning, match=r"2 folders of exemplars no longer in SOURCE not pruned \(sub__a, sub__c\): "
                      r".*/src/sub is missing .*mount it and run again, or .*tghop batch --prune --force"):
        run(src, out, workers=1, prune=True)
    assert (out / "sub__a" / "sub__a.npz").is_file() and (out / "sub__c" / "sub__c.npz").is_file()
    code, _, err, _ = invoke("batch", "src", "-o", "out", "--workers", "1", "--size", "48", "--seed", "1", "--prune",
                             *CLI_FAST, cwd=tmp_path)
    assert code == 0 and "sub__a: kept, not pruned" in err and "0 removed, 2 kept, not pruned" in err, err
    (tmp_path / "away").rename(src / "sub")
    (src / "sub" / "a.png").unlink()
    listdir = os.listdir

    def unreadable(path):
        if str(path) == str(src / "sub"):
            raise PermissionError(13, "Permission denied")
        return listdir(path)

    monkeypatch.setattr(batch_plan.os, "listdir", unreadable)
    with pytest.warns(UserWarning, match="src/sub cannot be read .*never pruned"):
        run(src, out, workers=1, prune=True, force=True)  # never, even forced
    assert (out / "sub__a" / "sub__a.npz").is_file()
    monkeypatch.undo()
    (src / "sub").rename(tmp_path / "away")
    run(src, out, workers=1, prune=True, force=True)  # forced: the folder is gone for good
    assert not (out / "sub__a").exists() and not (out / "sub__c").exists()


def test_prune_keeps_everything_where_most_of_the_library_would_go(tmp_path):
    names = [f"x{i}" for i in range(batch.PRUNE_MIN + 2)]
    previous = {n: {"source": str(tmp_path / "gone" / f"{n}.png")} for n in names}
    (tmp_path / "gone").mkdir()  # an empty mount point: the folder is there, its images are not
    held, said = batch.prune_held(names, previous, exemplars=3)
    assert sorted(held) == sorted(names) and len(said) == 1 and "--prune --force" in said[0], said
    assert batch.prune_held(names, previous, exemplars=3, force=True) == ({}, [])
    assert batch.prune_held(names, previous, exemplars=len(names)) == ({}, [])  # half at most: pruned
    code, _, err, _ = invoke("batch", "src", "-o", "out", "--force", cwd=tmp_path)
    assert code == 2 and "--force is for --prune" in err, err


def test_a_warning_names_its_exemplar(tmp_path):
    # Two exemplars a.png in two folders, each with an alpha channel: the command said
    # "Warning: a.png: alpha channel dropped" twice, and which was which the ledger alone told.
    src = make_folder(tmp_path / "src", bad=False)
    for rel, rng in (("a.png", 3), ("sub/a.png", 4)):
        save_image(np.concatenate([data.bricks(64, rng=rng), np.ones((64, 64, 1))], axis=2), src / rel)
    code, _, err, _ = invoke("batch", "src", "-o", "out", "--workers", "1", "--size", "48", *CLI_FAST, cwd=tmp_path)
    assert code == 0, err
    said = sorted(line for line in err.splitlines() if line.startswith("Warning: "))
    assert said == ["Warning: a: a.png: alpha channel dropped", "Warning: sub__a: a.png: alpha channel dropped"], err


def test_a_folder_s_images_of_other_types_are_said_not_left_out_unsaid(tmp_path):
    # A studio's folder of .png and .tga: the .tga were skipped without a word, and a rerun said all done
    # (.tga is read now: an EXR, which tghop does not read, stands for the others).
    src = make_folder(tmp_path / "src", bad=False)
    (src / "sub" / "wall.exr").write_bytes(b"\x76\x2f\x31\x01" + bytes(60))
    with pytest.warns(UserWarning, match=r"1 image file of another type skipped \(sub/wall.exr\).*convert them to PNG"):
        items = batch.find_work(src, tmp_path / "out")
    assert sorted(str(it["rel"]) for it in items) == ["a.png", "sub/a.png"]
    only = tmp_path / "only"
    only.mkdir()
    (only / "wall.exr").write_bytes(b"\x76\x2f\x31\x01" + bytes(60))
    with pytest.raises(TGHopError, match=r"no image files in this folder .*1 image file of another type skipped"):
        batch.find_work(only, tmp_path / "out2")


def test_a_folder_takes_every_image_file_fit_reads_tga_too(tmp_path):
    # A studio's Unreal exemplars and maps as .tga (and .dds, JPEG 2000) were skipped "of another type, convert them
    # to PNG", though tghop fit read them: the batch's extensions are now the one list of what tghop reads.
    from PIL import features

    from tghop._formats import OTHER_IMAGE_SUFFIXES, READ_SUFFIXES
    from tghop.imageio import load_image

    assert batch.IMAGE_SUFFIXES is READ_SUFFIXES
    Image.init()
    opened = {ext for ext, fmt in Image.registered_extensions().items() if fmt in Image.OPEN}
    assert set(READ_SUFFIXES) - opened <= ({".avif"} if not features.check("avif") else set())  # Pillow < 11.2
    assert not set(OTHER_IMAGE_SUFFIXES) & opened  # said skipped: none that fit reads
    src = make_folder(tmp_path / "src", bad=False)
    rgb = (data.bricks(64, rng=5) * 255).round().astype(np.uint8)
    (src / "studio").mkdir()
    for name in ("T_Wall_BC.tga", "T_Wall_N.TGA", "wall.dds", "wall.jp2"):
        Image.fromarray(rgb).save(src / "studio" / name)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        items = batch.find_work(src, tmp_path / "out")
    assert not [w for w in said if "another type" in str(w.message)], [str(w.message) for w in said]
    assert [w for w in said if "a material's maps by their names" in str(w.message)]  # T_Wall_BC and _N: a set
    taken = sorted(str(it["rel"]) for it in items)
    assert taken == ["a.png", "studio/T_Wall_BC.tga", "studio/T_Wall_N.TGA", "studio/wall.dds", "studio/wall.jp2",
                     "sub/a.png"]
    for item in items:  # and fit reads each
        assert load_image(item["path"]).shape == (64, 64, 3)


def test_jpeg_files_by_other_names_and_bilevel_pnm_are_exemplars(tmp_path):
    # A browser saves JPEG photos as .jfif; they, .jpe and .pbm (Pillow reads them all) were skipped
    # as "of another type" and the user told to convert them to PNG.
    src = make_folder(tmp_path / "src", bad=False)
    for name, fmt in (("photo.jfif", "JPEG"), ("old.JPE", "JPEG"), ("bits.pbm", "PPM")):
        Image.new("1" if fmt == "PPM" else "RGB", (64, 64)).save(src / name, format=fmt)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        items = batch.find_work(src, tmp_path / "out")
    assert sorted(str(it["rel"]) for it in items) == ["a.png", "bits.pbm", "old.JPE", "photo.jfif", "sub/a.png"]


def test_progress_into_a_log_is_a_line_per_tenth(tmp_path):
    # Without a terminal (nohup, a job's log) click draws no bar: a run of hours said "exemplars" and
    # nothing more until its end. Now a line at each tenth of the exemplars (here each of the 4).
    make_folder(tmp_path / "src")
    fast = [a for a in CLI_FAST if a != "-q"]
    code, _, err, _ = invoke("batch", "src", "-o", "out", "--workers", "1", "--size", "48", *fast, cwd=tmp_path)
    assert code == 1, err
    said = [line for line in err.splitlines() if line.startswith("exemplars: ")]
    assert [line.split(" (")[0] for line in said] == [f"exemplars: {n} of 4 finished" for n in range(1, 5)], err
    # "4 of 4 done, 2 failed" beside the summary's "2 of 4 exemplars done" read as 4 made
    assert said[-1] == "exemplars: 4 of 4 finished (2 done, 2 failed), 0 running", err
    assert "2 of 4 exemplars done" in err, err
    # click's bar, which draws nothing into a log, wrote its label alone on the first line
    assert [line for line in err.splitlines() if line.strip() == "exemplars"] == [], err


def test_a_rerun_says_what_an_earlier_run_did_before_its_bar(tmp_path):
    # A rerun's bar counted only what was left ("exemplars 0/50" of a batch of 1,250), and each rerun
    # tried and listed every bad exemplar again. Now a line first says what was done before, the
    # bar counts the rest, and the failures of unchanged input are skipped, counted, not listed.
    from tghop.cli.batch import plan_line

    assert plan_line({"exemplars": 1250, "done_before": 1200, "failed_before": 0, "to_do": 50}) == \
        "1,200 of 1,250 exemplars already done; 50 to make"
    make_folder(tmp_path / "src")
    fast = [a for a in CLI_FAST if a != "-q"]
    args = ["batch", "src", "-o", "out", "--workers", "1", "--size", "48", "--seed", "1", *fast]
    code, _, err, _ = invoke(*args, cwd=tmp_path)
    assert code == 1 and "already done" not in err and "failed: bad: " in err, err  # the bar says it all
    save_image(data.bricks(64, rng=7), tmp_path / "src" / "new.png")
    code, _, err, _ = invoke(*args, cwd=tmp_path)
    lines = err.splitlines()
    assert lines[:2] == ["2 of 5 exemplars already done, 2 skipped as failed before (--retry-failed tries them "
                         "again); 1 to make", "exemplars: 1 of 1 finished (1 done, 0 failed), 0 running"], err
    assert "3 of 5 exemplars done (2 by an earlier run); results in out" in err, err
    assert "\n2 skipped as failed before, their input and settings unchanged (bad, flat; their errors are in " \
           "out/batch.jsonl); fix or remove them, or --retry-failed tries them again\n" in err, err
    assert "failed: " not in err and code == 1  # the batch is still incomplete
    assert lines[-1] == "Error: 2 of 5 exemplars failed; 2 of them before: bad, flat (see out/batch.jsonl)", err
    code, _, err, _ = invoke(*args, cwd=tmp_path)
    assert err.splitlines()[0].endswith("; nothing to make") and "exemplars: " not in err, err  # no bar of 0
    code, _, err, _ = invoke(*args, "--retry-failed", cwd=tmp_path)
    assert err.splitlines()[0] == "3 of 5 exemplars already done; 2 to make", err
    assert "failed: bad: " in err and "failed: flat: " in err and "skipped as failed" not in err, err
    code, _, err, _ = invoke(*args, "-q", cwd=tmp_path)
    assert "already done" not in err and "skipped as failed before" in err, err  # -q: the summary alone


def test_ctrl_c_in_a_rerun_says_the_whole_batchs_count_too(tmp_path, monkeypatch):
    # "interrupted after 3 of 50 exemplars" of a rerun read as 3 of the batch done, where an earlier
    # run had done 1,200 of its 1,250: this run's count alone. Now the whole batch's is said too.
    from tghop.cli.batch import stopped_line

    plan = {"exemplars": 1250, "done_before": 1200, "failed_before": 0, "to_do": 50}
    assert stopped_line(plan, {"done": 4, "total": 50}, 1) == \
        " after 3 made and 1 failed in this run (50 to make); 1,203 of 1,250 exemplars done in all"
    assert stopped_line({**plan, "done_before": 0}, {"done": 3, "total": 1250}, 0) == " after 3 of 1,250 exemplars"
    make_folder(tmp_path / "src")
    args = ["batch", "src", "-o", "out", "--workers", "1", "--size", "48", "--seed", "1", *CLI_FAST]
    assert invoke(*args, cwd=tmp_path)[0] == 1  # a and sub__a done, bad and flat failed
    for i in range(3):
        save_image(data.bricks(64, rng=7 + i), tmp_path / "src" / f"c{i}.png")
    calls, task = [], batch.process_exemplar

    def ctrl_c_at_the_second(job):
        calls.append(job["name"])
        if len(calls) == 2:
            raise KeyboardInterrupt
        return task(job)

    monkeypatch.setattr(batch, "process_exemplar", ctrl_c_at_the_second)
    code, _, err, exc = invoke(*args, cwd=tmp_path)
    assert_one_line(code, err, exception=exc)
    assert err.strip().splitlines()[-1] == "Error: interrupted after 1 made in this run (3 to make); 3 of 7 " \
        "exemplars done in all; run the same command again to finish the rest", err


def _run_cli(args, cwd, block_dask=False, block=(), **kw):
    """The command line in a process of its own, where the modules ``block`` names (and with
    ``block_dask`` Dask's), and those inside them, cannot be imported (not installed)."""
    block = (*block, *(("dask", "distributed") if block_dask else ()))
    code = ("import sys\n"
            "class Block:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            f"        if any(name == b or name.startswith(b + '.') for b in {block!r}):\n"
            "            raise ImportError(f'No module named {name!r}')\n"
            f"if {bool(block)}:\n"
            "    sys.meta_path.insert(0, Block())\n"
            "import tghop.batch\n"
            "from tghop.__main__ import run\n"
            "sys.argv[0] = 'tghop'\n"
            "run()\n")
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, **kw)


def test_a_decoder_missing_is_no_fault_of_the_input_and_is_tried_again(tmp_path):
    # A WebP exemplar read by a Pillow built without WebP failed as "not an image format tghop reads",
    # cause "input": every rerun skipped it, also once Pillow could read it, until --retry-failed or a
    # new tghop. Now a library or decoder missing is the run's cause (said as such), tried again.
    src = tmp_path / "src"
    src.mkdir()
    save_image(data.bricks(64, rng=3), src / "a.png")
    Image.fromarray(np.round(data.cells(64, rng=4) * 255).astype(np.uint8)).save(src / "w.webp", lossless=True)
    args = ["batch", "src", "-o", "out", "--workers", "1", "--size", "48", "--seed", "1", *CLI_FAST]
    p = _run_cli(args, tmp_path, block=("PIL._webp",))  # Pillow's WebP library missing: a real failure
    _, err = p.communicate(timeout=300)
    assert p.returncode == 1, err.decode()
    (line,) = [line for line in ledger(tmp_path / "out") if line["name"] == "w"]
    assert line["status"] == "failed" and line["cause"] == "run", line
    assert "a WebP image, and this Pillow was built without WebP support; install a Pillow" in line["error"]
    # the library there again: tried again, not "skipped as failed before" (0.64: in this process, no interpreter
    # started for it)
    code, _, err, _ = invoke(*args, cwd=tmp_path)
    assert code == 0 and "2 of 2 exemplars done (1 by an earlier run)" in err, err


def test_without_dask_one_line_and_workers_1_still_works(tmp_path):
    (tmp_path / "src").mkdir()
    save_image(np.full((64, 64, 3), 0.5), tmp_path / "src" / "flat.png")
    p = _run_cli(["batch", "src", "-o", "out", "--workers", "2"], tmp_path, block_dask=True)
    _, err = p.communicate(timeout=120)
    assert_one_line(p.returncode, err.decode(), "needs dask.distributed", "pip install 'tghop[batch]'")
    assert not (tmp_path / "out" / "batch.jsonl").exists()
    p = _run_cli(["batch", "src", "-o", "out", "--workers", "1", "-q"], tmp_path, block_dask=True)
    _, err = p.communicate(timeout=120)
    assert_one_line(p.returncode, err.decode(), "1 of 1 exemplar failed", "flat")
    # The default (no --workers) on a core install works the first time: in this process, said in a warning.
    save_image(data.bricks(64, rng=3), tmp_path / "src" / "bricks.png")
    p = _run_cli(["batch", "src", "-o", "out", "--size", "48", *CLI_FAST], tmp_path, block_dask=True)
    _, err = p.communicate(timeout=120)
    lines = err.decode().strip().splitlines()
    assert p.returncode == 1 and lines[-1].startswith("Error: 1 of 2 exemplars failed"), err.decode()  # flat.png
    said = [line for line in lines if line.startswith("Warning: Dask is not installed")]
    assert len(said) == (len(os.sched_getaffinity(0)) > 1), err.decode()  # one core: in process anyway
    assert [line["status"] for line in ledger(tmp_path / "out") if line["name"] == "bricks"] == ["ok"]


@pytest.mark.parametrize("workers", ["1", "2"])
def test_ctrl_c_stops_cleanly_and_a_rerun_finishes(tmp_path, workers):
    # Ctrl-C in a terminal reaches the whole process group: Dask's worker processes too.
    if workers != "1":
        pytest.importorskip("distributed")
    src = make_folder(tmp_path / "src", bad=False)
    for i in range(2):
        save_image(data.bricks(64, rng=7 + i), src / f"c{i}.png")
    args = ["batch", "src", "-o", "out", "--size", "48", "--seed", "1", *CLI_FAST]
    p = _run_cli(args + ["--workers", workers], tmp_path, start_new_session=True)
    deadline = time.time() + 60
    ledger_file = tmp_path / "out" / "batch.jsonl"
    while time.time() < deadline and not (ledger_file.exists() and ledger_file.read_text().endswith("\n")):
        time.sleep(0.05)
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err.decode()
    assert_one_line(p.returncode, err.decode(), "interrupted after", "run the same command again")
    lines = ledger(tmp_path / "out")
    done = sum(line["status"] == "ok" for line in lines)  # the others: the exemplars under way, "interrupted"
    assert 1 <= done < 4 and not leftovers(tmp_path / "out")
    assert all(line["status"] in ("ok", "interrupted") for line in lines)
    code, _, err, _ = invoke(*args, "--workers", "1", cwd=tmp_path)  # the rerun in this process (0.64)
    assert code == 0, err
    assert f"4 of 4 exemplars done ({done} by an earlier run)" in err


def test_ctrl_c_writes_the_interrupted_lines_before_the_local_cluster_closes(tmp_path):
    # 0.62 closed its local cluster after Ctrl-C (a busy worker's nanny waits for it, then kills it) and only then
    # wrote the lines "interrupted" of the exemplars under way: a second kill meanwhile lost them. 0.63 writes them
    # first. A real run, a real Ctrl-C to the process group; the ledger is read as the cluster's close begins.
    pytest.importorskip("distributed")
    src = make_folder(tmp_path / "src", bad=False)
    (src / "list.csv").write_text("path,count\na.png,1\nsub/a.png,1000\n")  # sub/a: 1,000 images, long under way
    code = ("import sys, distributed\n"
            "from pathlib import Path\n"
            "close = distributed.LocalCluster.close\n"
            "def spied(self, *args, **kwargs):\n"
            "    ledger = Path('out', 'batch.jsonl')\n"
            "    Path('at-close.jsonl').write_text(ledger.read_text() if ledger.exists() else '')\n"
            "    return close(self, *args, **kwargs)\n"
            "distributed.LocalCluster.close = spied\n"
            "from tghop.__main__ import run\n"
            "sys.argv[0] = 'tghop'\n"
            "run()\n")
    args = ["batch", "src/list.csv", "-o", "out", "--size", "48", "--seed", "1", "--workers", "2", *CLI_FAST]
    p = subprocess.Popen([sys.executable, "-c", code, *args], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, start_new_session=True)
    running = tmp_path / "out" / "sub__a" / batch.RUNNING
    deadline = time.time() + 300
    while time.time() < deadline and p.poll() is None and not running.exists():
        time.sleep(0.05)
    time.sleep(0.5)  # handed out: the worker runs it
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=300)
    assert p.returncode == 130, err.decode()
    at_close = [json.loads(line) for line in (tmp_path / "at-close.jsonl").read_text().splitlines()]
    assert [line["status"] for line in at_close if line["name"] == "sub__a"] == ["interrupted"], at_close
    assert ledger(tmp_path / "out") == at_close  # nothing written after the close
    assert not running.exists()


def test_a_task_past_the_timeout_in_process_is_its_exemplars_failure(tmp_path):
    # 0.62 had no time limit per task: one exemplar that never ends stopped the batch there. 0.63's --task-timeout
    # (in this process: a timer's signal) records it as the exemplar's failure, and the run goes on. A real input made
    # slow: a row of 1,000 images of 256x256, first in the manifest. The timeout is short (the test's
    # own wait); the fast row ends well within it under load (docs/choices.md, "The test suite on CI's two cores").
    src = make_folder(tmp_path / "src", bad=False)
    (src / "list.csv").write_text("path,count,size\na.png,1000,256\nsub/a.png,1,48\n")
    args = ["batch", "src/list.csv", "-o", "out", "--size", "48", "--seed", "1", "--workers", "1", *CLI_FAST]
    code, _, err, _ = invoke(*args, "--task-timeout", "4", cwd=tmp_path)
    assert code == 1 and "failed: a: stopped after the task timeout (4 s, --task-timeout / task_timeout)" in err, err
    slow, fast = ledger(tmp_path / "out")
    assert (slow["name"], slow["cause"], slow["timed_out"], slow["task_timeout"]) == ("a", "input", True, 4)
    assert fast["name"] == "sub__a" and fast["status"] == "ok"
    assert not (tmp_path / "out" / "a").exists() and not leftovers(tmp_path / "out")
    code, _, err, _ = invoke(*args, "--task-timeout", "4", cwd=tmp_path)  # skipped until it changes
    assert code == 1 and "1 skipped as failed before" in err and len(ledger(tmp_path / "out")) == 2, err
    made = []  # a longer timeout, or none, tries it again (each in a copy of OUTDIR); the same one does not
    for timeout in (4, 20, None):
        shutil.copytree(tmp_path / "out", tmp_path / f"out-{timeout}")
        batch.run(src / "list.csv", tmp_path / f"out-{timeout}", size=48, seed=1, fit=FIT, generate=GEN, workers=1,
                  task_timeout=timeout, task=lambda job: made.append((job["name"], timeout)) or {"status": "failed"})
    assert made == [("a", 20), ("a", None)]
    for bad in ("0", "-1", "nan", "inf", "soon"):
        code, _, err, _ = invoke(*args, "--task-timeout", bad, cwd=tmp_path)
        assert code == 2 and "--task-timeout" in err and "Traceback" not in err, err
    with pytest.raises(TGHopError, match=r"^task_timeout must be a number of seconds above 0 \(or None: no limit\), "
                                         r"got True$"):
        batch.run(src, tmp_path / "out", workers=1, task_timeout=True)
    stopped = []
    thread = threading.Thread(target=lambda: stopped.append(pytest.raises(TGHopError, batch.run, src, tmp_path / "o2",
                                                                          workers=1, task_timeout=5)))
    thread.start()
    thread.join()
    assert "needs the main thread" in str(stopped[0].value) and not (tmp_path / "o2").exists()


def test_a_task_timeout_too_short_or_too_long_for_the_timer_is_the_tasks_record():
    # 0.63's timer in this process: a timeout past what setitimer takes (about 9.2e9 s; --task-timeout 1e300) raised
    # OverflowError, a traceback from tghop batch --workers 1 (Dask's path takes it as no limit); one of a nanosecond
    # fired before the task's try, TaskTimeout's traceback instead of the exemplar's record.
    from tghop.batch_task import within

    job = {"name": "a", "seed": 1}
    assert within(lambda job: {"status": "ok"}, job, 1e300) == {"status": "ok"}
    for _ in range(20):
        record = within(lambda job: time.sleep(1) or {"status": "ok"}, job, 1e-9)
        assert (record["status"], record["timed_out"]) == ("failed", True), record
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)

def test_ctrl_c_while_the_cluster_starts_prints_no_traceback(tmp_path):
    # Ctrl-C to the whole process group, again and again from the start: ignored while the
    # workers start (they inherit that), then a clean stop; never a worker's traceback.
    pytest.importorskip("distributed")
    src = make_folder(tmp_path / "src", bad=False)
    for i in range(4):
        save_image(data.bricks(64, rng=20 + i), src / f"c{i}.png")
    p = _run_cli(["batch", "src", "-o", "out", "--size", "48", "--seed", "1", "--workers", "2", *CLI_FAST],
                 tmp_path, start_new_session=True)
    time.sleep(1.0)  # the command's own imports: Python's usual KeyboardInterrupt there
    deadline = time.time() + 90
    while p.poll() is None and time.time() < deadline:
        os.killpg(p.pid, signal.SIGINT)
        time.sleep(0.3)
    _, err = p.communicate(timeout=60)
    err = err.decode()
    assert "Traceback" not in err and "Exception ignored" not in err, err
    if p.returncode == 130 and err.strip() == "Error: interrupted":
        pass  # before the command read its arguments (Python's and tghop's imports: over 1 s on a loaded machine)
    elif p.returncode == 130:  # "after N of M" once the exemplars are counted; before (importing Dask), without
        assert_one_line(p.returncode, err, "run the same command again to finish the rest")
        assert re.search(r"Error: interrupted( after \d+ of \d+ exemplars)?; run", err), err
    else:  # every exemplar was done before a Ctrl-C reached the command after the start
        assert p.returncode == 0, err


def test_a_local_clusters_workers_print_no_tifffile_log_lines(tmp_path):
    # The command keeps tifffile's log of a malformed TIFF (incorrect StripOffsets count) off the terminal in
    # its own process (tghop.cli.common.quiet_tifffile, 0.57), but a local cluster's workers read the
    # exemplars, and with no logging set up there Python's last resort printed each line (0.57). 0.58: the
    # command has each worker it starts do the same (run's worker_setup); the library sets no logging.
    pytest.importorskip("distributed")
    from test_hostile_inputs import tiff_declaring

    src = tmp_path / "src"
    src.mkdir()
    (src / "bad.tif").write_bytes(tiff_declaring(tmp_path, 100))  # 1 pixel, its tags say 100x100
    p = _run_cli(["batch", "src", "-o", "out", "--size", "48", "--seed", "1", "--workers", "2", "-q"], tmp_path)
    _, err = p.communicate(timeout=300)
    err = err.decode()
    assert p.returncode == 1 and "failed: bad: " in err, err
    assert "tifffile" not in err and "StripOffsets" not in err, err


# ------------------------------------------------------------------ on Dask
def _local_cluster():
    """(LocalCluster of 2 worker processes, its Client), closed by the generator's end."""
    dask = pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    import logging

    with dask.config.set({"distributed.scheduler.allowed-failures": 2}):
        cluster = distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                           dashboard_address=":0", silence_logs=logging.CRITICAL)
    client = distributed.Client(cluster)
    # Read as a worker is removed: the tests kill workers, and under load a restart took over the 15 s after
    # which Dask closes its nanny for good (the cluster lost every worker; since 0.60 the run says so)
    with dask.config.set({"distributed.deploy.lost-worker-timeout": "120s"}):
        yield cluster, client
    client.close()
    cluster.close()


@pytest.fixture(scope="module")
def cluster():
    yield from _local_cluster()


def test_local_cluster_run(tmp_path, cluster):
    _, client = cluster
    src, out = make_folder(tmp_path / "src"), tmp_path / "out"
    results = run(src, out, count=2, client=client)
    by = {r["name"]: r for r in results}
    assert [by[n]["status"] for n in ("a", "bad", "flat", "sub__a")] == ["ok", "failed", "failed", "ok"]
    assert all(0 < by[n]["peak_rss_mb"] < 4096 for n in ("a", "sub__a"))  # this worker's own peak
    workers = {by[n]["worker"].split(":")[1] for n in by}
    assert str(os.getpid()) not in workers  # ran in the worker processes
    for name in ("a", "sub__a"):
        assert all((out / f).is_file() for f in by[name]["outputs"])
    assert len(ledger(out)) == 4
    check_sheet(out, results)
    again = run(src, out, count=2, client=client)
    assert [r["skipped"] for r in again] == [True, True, True, True]  # bad and flat: their input failed


def test_cli_to_a_scheduler_address(tmp_path, cluster, monkeypatch):
    local, fixture_client = cluster
    make_folder(tmp_path / "src", bad=False)
    rgba = np.concatenate([data.bricks(64, rng=3), np.ones((64, 64, 1))], axis=2)
    save_image(rgba, tmp_path / "src" / "a.png")
    code, _, err, _ = invoke("batch", "src", "-o", "out", "--scheduler", local.scheduler_address, "--size", "48",
                             "--seed", "2", *CLI_FAST, cwd=tmp_path)
    assert code == 0, err
    assert "2 of 2 exemplars done" in err
    assert {line["worker"].split(":")[1] for line in ledger(tmp_path / "out")} != {str(os.getpid())}
    # A worker's warning is the ledger's and the command's one line (it was the worker's raw
    # Python warning, with its source line).
    assert err.count("Warning: a: a.png: alpha channel dropped\n") == 1 and "UserWarning" not in err
    assert {line["name"]: line["warnings"] for line in ledger(tmp_path / "out")} == {
        "a": ["a.png: alpha channel dropped"], "sub__a": []}
    monkeypatch.setattr(batch_dask, "CONNECT_TIMEOUT", "1s")  # nothing listens there: Dask tries until then
    code, _, err, exc = invoke("batch", "src", "-o", "out2", "--scheduler", "tcp://127.0.0.1:9", *CLI_FAST,
                               cwd=tmp_path)
    assert_one_line(code, err, "cannot reach the Dask scheduler", exception=exc)
    assert not (tmp_path / "out2").exists()  # OUTDIR is made once the scheduler is reached
    # The failed Client was closed then, not left to a later collection (which deadlocked in
    # the next LocalCluster's start): none is left apart from the fixture's.
    import distributed
    assert [c for c in gc.get_objects() if type(c) is distributed.Client] == [fixture_client]
    code, _, err, exc = invoke("batch", "src", "-o", "out3", "--scheduler", "notanaddress", *CLI_FAST, cwd=tmp_path)
    assert_one_line(code, err, "cannot reach the Dask scheduler at notanaddress", exception=exc)
    assert not (tmp_path / "out3" / "index.html").exists()  # nothing finished: no empty contact sheet


def _worker_threads(dask_worker):
    """How many of the worker's threads run a task (``Worker.active_threads``)."""
    return len(dask_worker.active_threads)


def _wait_idle(client, timeout=60):
    """Until the cluster runs nothing: a task already running when its client cancelled it
    goes on to its end on the worker (Dask cannot stop a running thread), and until it ends,
    its files are still staged (``.partial.*.tmp``). The scheduler forgets a task whose client
    left while its worker still runs it, so the workers are asked as well."""
    def busy():
        return any(client.processing().values()) or any(client.run(_worker_threads).values())

    deadline = time.time() + timeout
    while time.time() < deadline and busy():
        time.sleep(0.1)
    assert not busy()


def test_ctrl_c_with_a_scheduler_address_leaves_the_cluster_running(tmp_path, cluster):
    # Ctrl-C to `python -m tghop batch --scheduler ADDRESS` alone (the cluster is not in its
    # process group): it stops with one line, the cluster lives on, and a rerun finishes.
    # Before the tests below that kill the module cluster's workers (its nannies can take minutes to bring
    # one back on a loaded machine): the same two workers are asked for afterwards.
    n_more = 6
    _, client = cluster
    workers = set(client.scheduler_info()["workers"])
    src = make_folder(tmp_path / "src", bad=False)
    for i in range(n_more):  # enough that the batch is still under way when the first line is written
        save_image(data.bricks(64, rng=7 + i), src / f"c{i}.png")
    args = [sys.executable, "-m", "tghop", "batch", "src", "-o", "out", "--scheduler", cluster[0].scheduler_address,
            "--size", "48", "--seed", "1", *CLI_FAST]
    out = tmp_path / "out"
    p = subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.time() + 60
    while (time.time() < deadline and p.poll() is None
           and not ((out / "batch.jsonl").exists() and (out / "batch.jsonl").read_text().endswith("\n"))):
        time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err.decode()
    assert_one_line(p.returncode, err.decode(), "interrupted after", "run the same command again")
    lines = [line for line in ledger(out) if line["status"] != "interrupted"]  # those under way: done again
    done = len(lines)
    assert 1 <= done < n_more + 2 and len({line["name"] for line in lines}) == done
    _wait_idle(client)
    assert not leftovers(out)
    # the scheduler and both workers survive the client's Ctrl-C: the same two (a restarted
    # worker would have another address), given time to answer on a loaded machine
    deadline = time.time() + 60
    while time.time() < deadline and set(client.scheduler_info()["workers"]) != workers:
        time.sleep(0.2)
    assert set(client.scheduler_info()["workers"]) == workers
    assert client.submit(sum, [1, 2], pure=False).result(timeout=30) == 3
    code, _, err, _ = invoke(*args[3:], cwd=tmp_path)  # the rerun: the command in this process
    assert code == 0, err
    assert f"{n_more + 2} of {n_more + 2} exemplars done ({done} by an earlier run)" in err
    lines = [line for line in ledger(out) if line["status"] != "interrupted"]
    names = sorted(line["name"] for line in lines)
    assert names == sorted(["a", "sub__a"] + [f"c{i}" for i in range(n_more)])  # each exactly once
    assert all(line["status"] == "ok" for line in lines)
    for line in lines:
        assert all((out / f).is_file() for f in line["outputs"] + [line["model"]])
    assert not leftovers(out)


def _partial_file(job):
    """What a worker killed in the middle of write_atomic leaves: a temporary file."""
    folder = Path(job["folder"])
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f".{job['name']}.png.abc123.tmp").write_bytes(b"\x89PNG half")


def crash_once(job):
    marker = Path(job["folder"]).parent / f".died-{job['name']}"
    if not marker.exists():
        marker.write_text(str(os.getpid()))
        _partial_file(job)
        os._exit(1)  # the worker process dies mid-task
    return batch.process_exemplar(job)


def crash_always(job):
    _partial_file(job)
    os._exit(1)


def test_a_worker_that_dies_is_retried_then_recorded(tmp_path, cluster):
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    _, client = cluster
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    results = run(src, out, client=client, task=crash_once)
    assert [r["status"] for r in results] == ["ok", "ok"], results
    for r in results:
        died = int((out / f".died-{r['name']}").read_text())
        assert int(r["worker"].split(":")[1]) != died  # the second try ran in another process
        assert (out / r["outputs"][0]).is_file()
    assert not leftovers(out)
    (src / "sub" / "a.png").unlink()
    out2 = tmp_path / "out2"
    (failed,) = run(src, out2, client=client, task=crash_always)
    assert failed["status"] == "failed" and "died on every try" in failed["error"]
    # a given cluster's scheduler (allowed-failures 2 here) sets the tries, not retries: "4 tries on a local cluster"
    assert "tries on a local cluster" not in failed["error"] and "allowed-failures" in failed["error"], failed
    assert not leftovers(out2) and not (out2 / "a").exists()
    assert ledger(out2)[0]["status"] == "failed" and failed["cause"] == "run"
    assert failed["worker_died"] and failed["worker_deaths"] == 1  # counted over runs (0.62)
    (again,) = run(src, out2, client=client)  # a lost worker is no fault of the input: tried again
    assert again["status"] == "ok" and not again["skipped"]


def worker_died(job):
    """The record the driver writes for a task whose worker died on every try (tghop.batch_dask)."""
    return {"status": "failed", "error": "the worker running it died on every try (killed or out of memory; 4 tries)",
            "cause": "run", "outputs": [], "model": None, "thumbnail": None, "seed_used": job.get("seed"),
            "started": None, "seconds": None, "task_lost": True, "worker_died": True}


def test_an_exemplar_whose_worker_dies_in_every_run_becomes_its_own_failure(tmp_path):
    # 0.61 tried it again in every rerun: one file that crashes the decoder killed workers in each, for ever.
    from tghop.batch_plan import LOST_RUNS

    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    (src / "sub" / "a.png").unlink()
    for runs in range(1, LOST_RUNS + 1):
        (rec,) = run(src, out, workers=1, task=worker_died)
        assert not rec["skipped"] and rec["worker_deaths"] == runs
        assert rec["cause"] == ("input" if runs == LOST_RUNS else "run"), rec
    assert "--retry-failed" in rec["error"]
    (rec,) = run(src, out, workers=1, task=worker_died)
    assert rec["skipped"] and rec["status"] == "failed"  # skipped as failed before, its reason and fix in its line
    p = subprocess.run([sys.executable, "-m", "tghop", "batch", str(src), "-o", str(out), "--workers", "1",
                        "--size", "48", "--seed", "1", *CLI_FAST], capture_output=True, text=True)
    assert p.returncode == 1 and "1 skipped as failed before" in p.stderr and "--retry-failed" in p.stderr, p.stderr
    (rec,) = run(src, out, workers=1, retry_failed=True)  # the real task: it was the crash, not the file
    assert rec["status"] == "ok" and not rec["skipped"]


def die_in_the_second_image(job):
    """The worker dies while the second image is made (the first, the model and the thumbnail written)."""
    from tghop.synthesis import TGHop

    original, calls = TGHop.synthesize, []

    def dying(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            os._exit(1)
        return original(self, *args, **kwargs)

    TGHop.synthesize = dying
    return batch.process_exemplar(job)


def test_a_worker_killed_mid_exemplar_leaves_no_files_of_it(tmp_path, cluster):
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    _, client = cluster
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    (src / "sub" / "a.png").unlink()
    (failed,) = run(src, out, client=client, count=2, task=die_in_the_second_image)
    assert failed["status"] == "failed" and "died on every try" in failed["error"]
    assert not (out / "a").exists() and not leftovers(out)


def crash_on_a(job):
    if job["name"] == "a":
        _partial_file(job)
        os._exit(1)
    return batch.process_exemplar(job)


def test_with_no_retries_a_dying_worker_fails_only_its_own_exemplar(tmp_path):
    # A worker is given only the task it runs (Dask alone placed every task on a worker at
    # once, and a worker's death counted against those waiting there: with retries=0 they failed).
    pytest.importorskip("distributed")
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    for i, name in enumerate("abcd"):
        save_image(data.bricks(64, rng=i) if i % 2 else data.cells(64, rng=i), src / f"{name}.png")
    results = run(src, out, workers=2, retries=0, task=crash_on_a)
    assert [r["status"] for r in results] == ["failed", "ok", "ok", "ok"], results
    assert "died on every try" in results[0]["error"] and "; 1 try on" in results[0]["error"]
    assert not leftovers(out)


def test_a_driver_killed_while_its_tasks_run_on_a_scheduler_leaves_them_to_be_redone(tmp_path, cluster):
    # `tghop batch --scheduler` killed (kill -9, out of memory): its tasks run on without it and move
    # seed 2's files into place with no ledger line; a rerun with seed 1 took them for the earlier
    # line's (seed 1) and kept them. The folder's RUNNING file, made at the hand-out, says so now.
    local, client = cluster
    make_folder(tmp_path / "src", bad=False)
    out = tmp_path / "out"
    args = ["batch", "src", "-o", "out", "--scheduler", local.scheduler_address, "--size", "48", "--count", "2",
            *CLI_FAST]
    code, _, err, _ = invoke(*args, "--seed", "1", cwd=tmp_path)
    assert code == 0, err
    seed_1 = {p: p.read_bytes() for p in out.rglob("*.png")}
    p = subprocess.Popen([sys.executable, "-m", "tghop", *args, "--seed", "2"], cwd=tmp_path,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while time.time() < deadline and p.poll() is None and not any(out.glob("*/.partial.*.tmp")):
        time.sleep(0.01)
    p.kill()  # while a task makes its files
    p.wait()
    _wait_idle(client)
    assert any(path.read_bytes() != seed_1[path] for path in seed_1)  # a task ran on: seed 2's files
    code, _, err, _ = invoke(*args, "--seed", "1", cwd=tmp_path)
    assert code == 0, err
    assert {p: p.read_bytes() for p in out.rglob("*.png")} == seed_1
    assert not list(out.rglob(batch.RUNNING)) and not leftovers(out)


def probe_threads(job):
    """The task, noting how many threads tghop and BLAS may use while it fits."""
    from threadpoolctl import threadpool_info

    from tghop import _resources, fit_options

    seen = {}
    original = fit_options.model_for

    def model_for(*args, **kwargs):
        seen["cores"] = _resources.usable_cores()
        seen["blas"] = max([i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"] or [1])
        return original(*args, **kwargs)

    fit_options.model_for = model_for
    try:
        record = batch.process_exemplar(job)
    finally:
        fit_options.model_for = original
    import dask

    return {**record, "seen": seen, "omp_env": os.environ.get("OMP_NUM_THREADS"),
            "reuse_faults": [reuse_faults(1 << 20), reuse_faults(1 << 25)],
            "dask": {key: dask.config.get(key) for key in batch.QUIET_CLUSTER}}


def reuse_faults(n):
    """Page faults of an array of ``n`` float64 made again after one was freed: one per
    page (4 KB; 2 MB with transparent huge pages) when malloc maps fresh memory for each,
    none when it reuses the freed memory. 8 MB: fresh under Dask's MALLOC_TRIM_THRESHOLD_;
    256 MB: fresh under glibc's default thresholds and in a thread's own arena too."""
    import resource

    for _ in range(2):
        a = np.ones(n)
        del a
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    a = np.ones(n)
    del a
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


def test_default_local_cluster_runs_each_exemplar_on_one_thread(tmp_path, monkeypatch):
    # The default layout: one worker process per core (here 2), each task limited to one
    # thread, BLAS's and tghop's own (ICHM's clusters, refinement, ...): no oversubscription;
    # glibc's malloc reuses freed memory, even arrays of hundreds of MB made in the task's
    # thread (Dask's MALLOC_TRIM_THRESHOLD_ is in the workers' environment; the worker preload
    # resets it and maps no arrays; MALLOC_ARENA_MAX keeps the task's thread on the main heap).
    pytest.importorskip("distributed")
    import cloudpickle

    from tghop._resources import limit_cores, usable_cores

    with limit_cores(3):
        with limit_cores(1):
            assert usable_cores() == 1
        assert usable_cores() == min(3, batch.affinity_cores())
    assert usable_cores() == batch.affinity_cores()
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    import socket
    import warnings

    held = socket.socket()  # Dask's default dashboard port taken, as by another cluster
    try:
        held.bind(("", 8787))
        held.listen()
    except OSError:
        pass  # in use already: the same case
    # The workers' environment is theirs: Dask's nanny wrote it into the caller's os.environ, where
    # it stayed after the run (what the caller started next ran on one BLAS thread and one arena).
    for name in ("OMP_NUM_THREADS", "MALLOC_ARENA_MAX"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")  # one set before: kept as it was
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            results = run(src, out, workers=2, task=probe_threads)
    finally:
        held.close()
    assert [os.environ.get(n) for n in ("OMP_NUM_THREADS", "MALLOC_ARENA_MAX", "MKL_NUM_THREADS")] == [None, None, "3"]
    # 0.36 printed Dask's "Port 8787 is already in use. Perhaps you already have a cluster running?"
    assert not [w for w in caught if "8787" in str(w.message)]
    assert [r["status"] for r in results] == ["ok", "ok"]
    for r in results:
        assert r["seen"] == {"cores": 1, "blas": 1} and r["threads"] == 1 and r["omp_env"] == "1"
        # Freed memory reused, small arrays and large (Dask's 64 KB trim threshold: a third
        # slower; glibc's defaults: 10 % slower).
        assert max(r["reuse_faults"]) < 100, r["reuse_faults"]
        assert int(r["worker"].split(":")[1]) != os.getpid()
        # Dask's own periodic work made rarer in the workers: an idle cluster of 2 took 0.09 cores of 2
        assert r["dask"] == {"distributed.worker.profile.enabled": False, "distributed.admin.tick.interval": "1s",
                             "distributed.admin.system-monitor.interval": "5s"}, r["dask"]
    (inline,) = run(src / "sub", tmp_path / "out2", workers=1, task=probe_threads)
    assert inline["seen"]["cores"] == usable_cores() and inline["threads"] is None  # in process: every core


def _threads_now():
    from threadpoolctl import threadpool_info

    from tghop import _resources

    return {"cores": _resources.usable_cores(),
            "blas": max([i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"] or [1])}


def _wait_for(path, timeout=120):
    deadline = time.time() + timeout
    while not path.exists():
        assert time.time() < deadline, f"{path.name} never came"
        time.sleep(0.02)


def two_at_once(job):
    """The task, two at once in one worker process: A enters its thread limits, then B, then A
    ends; B notes the limits it runs under after that (files in OUTDIR's parent order them)."""
    import threading

    from tghop import fit_options
    from tghop._errors import warn as tghop_warn

    sync, me, seen = Path(job["folder"]).parent.parent, job["name"], {}
    if not hasattr(fit_options, "test_hooks"):  # one hook per process (both tasks would patch it)
        fit_options.test_hooks, original = {}, fit_options.model_for

        def model_for(*args, **kwargs):  # called inside the task's thread limits
            fit_options.test_hooks.get(threading.get_ident(), lambda: None)()
            return original(*args, **kwargs)

        fit_options.model_for = model_for

    def hook():
        if me == "a":
            (sync / "a-in").touch()
            _wait_for(sync / "b-in")
        else:
            (sync / "b-in").touch()
            _wait_for(sync / "a-done")
            seen.update(_threads_now())
        tghop_warn(f"{me}'s own warning")  # tghop's own warnings are a ledger line's

    fit_options.test_hooks[threading.get_ident()] = hook
    if me == "b":
        _wait_for(sync / "a-in")  # A is inside its limits first
    try:
        record = batch.process_exemplar(job)
    finally:
        del fit_options.test_hooks[threading.get_ident()]
    if me == "a":
        (sync / "a-done").touch()
    return {**record, "seen": seen}


def test_two_tasks_in_one_worker_keep_one_thread_each(tmp_path, monkeypatch):
    # A worker started by hand with --nthreads 2 runs two tasks in one process, and BLAS's thread
    # limit and tghop's own (usable_cores) are the process's: when the first task ended it put
    # back the limits from before it while the second still ran, which then fitted on every core
    # (and on every BLAS thread where the worker's default is more: dask worker --no-nanny).
    # So are the warnings' filters and showwarning, which each task's catch_warnings replaced.
    dask = pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    import cloudpickle
    import logging

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    src = tmp_path / "src"
    src.mkdir()
    save_image(data.bricks(64, rng=3), src / "a.png")
    save_image(data.cells(64, rng=4), src / "b.png")
    if batch.affinity_cores() < 2:
        pytest.skip("one core: every limit is one thread anyway")
    # A worker's BLAS on 2 threads (Dask's nanny sets OPENBLAS_NUM_THREADS=1, --no-nanny does not;
    # the parent's environment wins, and an earlier cluster left 1 there).
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")
    with dask.config.set({"distributed.nanny.pre-spawn-environ": {"OPENBLAS_NUM_THREADS": "2"}}):
        cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=True,
                                           dashboard_address=":0", silence_logs=logging.CRITICAL)
    client = distributed.Client(cluster)
    try:
        (before,) = client.run(_threads_now).values()
        assert before["blas"] == 2 and before["cores"] >= 2, before
        results = run(src, tmp_path / "out", client=client, task=two_at_once)
        assert [r["status"] for r in results] == ["ok", "ok"], results
        assert results[1]["seen"] == {"cores": 1, "blas": 1}  # it was {"cores": 2, "blas": 2} (2 cores)
        # Each task's warnings in its own ledger line: A's went to B's list, B's to the worker's stderr.
        assert [r["warnings"] for r in results] == [["a's own warning"], ["b's own warning"]]
    finally:
        client.close()
        cluster.close()


def test_an_exemplar_over_the_pixel_limit_is_told_to_downscale_itself(tmp_path):
    # batch has no --downscale (and run no downscale=): it was told "pass downscale=True"
    from test_cli_failures import png_header

    src = make_folder(tmp_path / "src", bad=False)
    (src / "big.png").write_bytes(png_header(9000, 9000))
    records = {r["name"]: r for r in run(src, tmp_path / "out", workers=1)}
    assert records["big"]["status"] == "failed" and "9000x9000" in records["big"]["error"]
    assert records["big"]["error"].endswith("downscale it first (e.g. to 8192x8192)")
    assert all(r["status"] == "ok" for name, r in records.items() if name != "big")


def test_a_script_without_the_main_guard_is_told_to_add_it(tmp_path):
    # Dask's worker processes import the calling script again; unguarded, each started a batch of
    # its own and the run ended in "RuntimeError: Nanny failed to start" under their tracebacks.
    pytest.importorskip("distributed")
    src = make_folder(tmp_path / "src", bad=False)
    script = tmp_path / "script.py"
    script.write_text(f"import tghop.batch\ntghop.batch.run({str(src)!r}, 'out', workers=2)\n")
    p = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    last = p.stderr.strip().splitlines()[-1]
    assert p.returncode == 1 and last.startswith("tghop._errors.TGHopError: the local Dask cluster's workers did not "
                                                 "start"), p.stderr[-2000:]
    assert """'if __name__ == "__main__":' around the call""" in last and last.endswith("or workers=1")
    assert (tmp_path / "out" / "batch.jsonl").read_text() == ""  # opened before the cluster: nothing done


def test_a_scheduler_without_workers_is_said_and_the_run_goes_on_when_one_joins(tmp_path):
    """`--scheduler` of a cluster whose workers have not started: a warning says the run waits
    for one (it waited without a word), and the run ends once a worker joins."""
    pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    import logging

    cluster = distributed.LocalCluster(n_workers=0, processes=True, threads_per_worker=1, dashboard_address=":0",
                                       silence_logs=logging.CRITICAL)
    try:
        src = tmp_path / "src"
        src.mkdir()
        save_image(data.bricks(64, rng=3), src / "a.png")
        joins = threading.Timer(1.0, cluster.scale, args=(1,))
        joins.start()
        with pytest.warns(UserWarning, match=r"has no workers yet: the exemplars wait until one joins \(start one: "
                                             r"dask worker tcp://"):
            results = run(src, tmp_path / "out", scheduler=cluster.scheduler_address)
        joins.join()
        assert [r["status"] for r in results] == ["ok"]
        # The command line says it while it waits (warnings were shown only at the command's end).
        args = [sys.executable, "-m", "tghop", "batch", "src", "-o", "out2", "--size", "48", *CLI_FAST,
                "--scheduler", cluster.scheduler_address]
        cluster.scale(0)
        deadline = time.time() + 60
        while time.time() < deadline and cluster.scheduler_info["workers"]:
            time.sleep(0.1)
        p = subprocess.Popen(args, cwd=tmp_path, stderr=subprocess.PIPE, text=True)
        try:  # the warning, while no worker can finish anything (a minute for a loaded machine's start)
            first = p.stderr.readline() if select.select([p.stderr], [], [], 60)[0] else "(nothing said)"
        finally:
            p.send_signal(signal.SIGINT)
            rest = p.communicate(timeout=60)[1]
        assert first.startswith("Warning: the Dask scheduler at tcp://") and "has no workers yet" in first, first + rest
        assert p.returncode == 130 and rest.rstrip().splitlines()[-1].startswith("Error: interrupted"), rest
    finally:
        cluster.close()


def test_a_model_records_its_exemplars_depth(tmp_path):
    # tghop synth MODEL.npz warns of a 16-bit exemplar's bits written with 8 when the model records its depth:
    # the batch's models did not.
    from tghop.modelfile import load_model

    (tmp_path / "img").mkdir()
    save_image(data.bricks(64, rng=3), tmp_path / "img" / "deep.png", depth=16)
    save_image(data.cells(64, rng=4), tmp_path / "img" / "flat.png")
    by = {r["name"]: r for r in run(tmp_path / "img", tmp_path / "out", workers=1)}
    assert {name: load_model(tmp_path / "out" / r["model"]).exemplar_depth_ for name, r in by.items()} == {
        "deep": 16, "flat": 8}


def test_a_hand_edited_ledger_line_repeating_a_key_or_nested_deep_is_skipped_as_a_torn_one(tmp_path):
    # 0.59 read the ledger with json.loads: a line giving "status" twice counted as its last value (here "ok": the
    # exemplar passed over), and a line of arrays nested thousands deep stopped the run with a RecursionError.
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    assert [r["status"] for r in run(src, out, workers=1)] == ["ok", "ok"]
    lines = (out / "batch.jsonl").read_text().splitlines()
    edited = [line.replace("{", '{"status": "failed", ', 1) if json.loads(line)["name"] == "a" else line
              for line in lines]
    (out / "batch.jsonl").write_text("\n".join(edited + ["[" * 100_000]) + "\n")
    assert {r["name"]: r["skipped"] for r in run(src, out, workers=1)} == {"a": False, "sub__a": True}


def test_a_ledger_line_not_in_utf8_is_skipped_as_a_torn_one(tmp_path):
    # 0.62 read the whole ledger as UTF-8: one line of other bytes (a hand edit in Latin-1, a sector of garbage) made
    # it unreadable, and every rerun fitted every exemplar again without a word.
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    assert [r["status"] for r in run(src, out, workers=1)] == ["ok", "ok"]
    with open(out / "batch.jsonl", "ab") as fh:
        fh.write(b'{"name": "caf\xe9"}\n\xff\xfe\x00garbage\n')
    assert [r["skipped"] for r in run(src, out, workers=1)] == [True, True]


def test_a_hand_edited_ledger_lines_outputs_not_a_list_of_names_is_no_finished_exemplar(tmp_path):
    # 0.63: a line's outputs of 7 ("Value after * must be an iterable") or of [1, 2] ("unsupported operand type(s) for
    # /") stopped the rerun with a traceback; such a line lists no files of its exemplar, which is made again.
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    assert [r["status"] for r in run(src, out, workers=1)] == ["ok", "ok"]
    edited = [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]
    for rec, outputs in zip(edited, (7, [1, 2])):
        rec["outputs"] = outputs
    with open(out / "batch.jsonl", "a") as fh:
        fh.writelines(json.dumps(rec) + "\n" for rec in edited)
    assert [(r["skipped"], r["status"]) for r in run(src, out, workers=1)] == [(False, "ok"), (False, "ok")]

def test_a_folder_named_as_a_claim_is_no_claim(tmp_path):
    # 0.62 took a folder .batch-running in an exemplar's folder (made by hand) for a killed run's claim: the exemplar
    # was made again, the folder could not be removed as the claim's file is, and so in every rerun, without a word.
    src, out = make_folder(tmp_path / "src", bad=False), tmp_path / "out"
    assert [r["status"] for r in run(src, out, workers=1)] == ["ok", "ok"]
    (out / "a" / batch.RUNNING).mkdir()
    assert [r["skipped"] for r in run(src, out, workers=1)] == [True, True]


def test_a_folder_or_file_in_the_way_of_an_exemplars_results_is_named_and_nothing_moved(tmp_path):
    # 0.61 moved the exemplar's files into place one by one: a folder named as its model (a.npz) failed that move
    # after its images had moved (a failed exemplar with files of its own, IsADirectoryError's words in the ledger),
    # and a file named as its folder was "FileExistsError: [Errno 17] File exists". Both are the run's: a rerun does
    # the exemplar once the way is clear.
    src = make_folder(tmp_path / "src", bad=False)
    (src / "sub" / "a.png").unlink()
    out = tmp_path / "out"
    (out / "a" / "a.npz").mkdir(parents=True)
    (failed,) = run(src, out, workers=1)
    assert failed["status"] == "failed" and failed["cause"] == "run", failed
    assert failed["error"] == (f"{out / 'a' / 'a.npz'} is a folder, where a's file of that name goes; move or remove "
                               "that folder, or choose another OUTDIR")
    assert [p.name for p in (out / "a").iterdir()] == ["a.npz"] and not leftovers(out)
    (out / "a" / "a.npz").rmdir()
    (out / "a").rmdir()
    (out / "a").write_text("notes")
    (failed,) = run(src, out, workers=1)
    assert failed["cause"] == "run" and failed["error"] == (
        f"{out / 'a'} is a file, where the folder of a's results goes; move or remove that file, or choose another "
        "OUTDIR"), failed
    (out / "a").unlink()
    (done,) = run(src, out, workers=1)
    assert done["status"] == "ok" and sorted(p.name for p in (out / "a").iterdir()) == ["a.npz", "a.png",
                                                                                           "exemplar.png"]


@pytest.mark.skipif(sys.platform in ("win32", "darwin"), reason="file names there are Unicode")
def test_the_contact_sheet_of_a_name_that_is_not_utf8_links_its_bytes_and_shows_it_as_a_terminal_does(tmp_path):
    # 0.63 failed to write it ("'utf-8' codec can't encode character '\\udce9': surrogates not allowed", a traceback)
    name = os.fsdecode(b"caf\xe9")
    record = {"name": name, "status": "ok", "source": f"in/{name}.png", "outputs": [f"{name}/{name}_1.png"],
              "model": f"{name}/{name}.npz", "thumbnail": f"{name}/thumb.png"}
    page = batch.write_contact_sheet(tmp_path, [record, {**record, "name": "b", "status": "failed",
                                                         "error": f"in/{name}.png: not a readable image"}]).read_text()
    assert 'href="caf%E9/caf%E9_1.png"' in page and 'href="caf%E9/caf%E9.npz"' in page
    assert "<b>caf\ufffd</b>" in page and "in/caf\ufffd.png: not a readable image" in page
