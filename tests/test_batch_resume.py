"""What a studio's long batch meets and must not lose work to (0.61): a full disk (the tasks' files or the ledger)
stops the run at once with one line, and a driver killed outright (kill -9) leaves the inputs' hashes, so that
the rerun reads no unchanged exemplar again. In process (``workers=1``): the driver's side is the same on Dask.
"""

import errno
import json
import os
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from tghop import batch, batch_plan, data
from tghop._errors import TGHopError
from tghop.imageio import save_image

FIT = dict(n_clusters=6, n_codewords=30, stride=4)
GEN = dict(n_patches=300)


def make_folder(d, n=3):
    d.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        save_image(data.bricks(64, rng=i), d / f"e{i}.png")
    return d


def ledger(out):
    return [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]


def run(src, out, **kw):
    return batch.run(src, out, size=(32, 32), seed=1, fit=FIT, generate=GEN, workers=1, **kw)


def no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_a_full_disk_stops_the_run_at_once_and_the_rerun_does_the_rest(tmp_path, monkeypatch):
    # 0.60 went on after a task's files met a full disk: every exemplar after it was fitted, then failed alike (a
    # studio's thousands, each a fit's time), and the run ended "done" with them all failed. Now the first stops it.
    src, out = make_folder(tmp_path / "src"), tmp_path / "out"
    tried = []
    monkeypatch.setattr(np, "savez", lambda *a, **k: (tried.append(1), no_space()))  # the model's file, as written
    sheet = batch.write_contact_sheet

    def no_space_for_the_sheet(*args, **kwargs):  # the contact sheet's failure hid the stop's line (0.60)
        raise TGHopError("index.html: writing the contact sheet failed (No space left on device); nothing was written")

    monkeypatch.setattr(batch, "write_contact_sheet", no_space_for_the_sheet)
    with pytest.raises(TGHopError, match=r"^the disk of .*out is full \(e\d: .*No space left on device.*\); the run "
                                         r"stopped: the exemplars recorded are in the ledger, .*free some space "
                                         r"first$") as stop:
        run(src, out)
    assert len(tried) == 1
    # the model's file named where it goes (0.60: in the task's hidden folder, out/e0/.partial.x.tmp/e0.npz)
    assert f"{out}/e0/e0.npz: writing the model failed" in str(stop.value) and ".partial" not in str(stop.value)
    lines = ledger(out)
    assert [(line["status"], line["cause"]) for line in lines] == [("failed", "run")], lines  # tried again next run
    assert not list(out.rglob(".batch-running")) and not list(out.rglob("*.tmp"))
    monkeypatch.undo()
    assert batch.write_contact_sheet is sheet
    assert [r["status"] for r in run(src, out)] == ["ok"] * 3
    assert sorted(line["name"] for line in ledger(out) if line["status"] == "ok") == ["e0", "e1", "e2"]


def test_a_full_disk_for_the_ledger_stops_the_run_in_one_line_and_loses_no_exemplar(tmp_path, monkeypatch):
    # 0.60 said "cannot write the output: No space left on device; ...", naming neither the ledger nor the rerun.
    src, out = make_folder(tmp_path / "src"), tmp_path / "out"
    monkeypatch.setattr(batch, "append_ledger", no_space)
    with pytest.raises(TGHopError, match=r"^.*out/batch\.jsonl: cannot add to the ledger \(No space left on device; "
                                         r"free some space\); the run stopped: .* done again by the next run"):
        run(src, out)
    made = [p.parent.name for p in out.rglob(".batch-running")]
    assert len(made) == 1, made  # the exemplar whose line was not written: the rerun does it again
    monkeypatch.undo()
    results = run(src, out)
    assert [r["skipped"] for r in results] == [False] * 3 and [r["status"] for r in results] == ["ok"] * 3


def killing_task(job):
    """The driver killed outright (kill -9) as its first exemplar runs, in process."""
    os.kill(os.getpid(), signal.SIGKILL)


def test_a_driver_killed_outright_leaves_the_inputs_hashes_for_the_rerun(tmp_path, monkeypatch):
    # 0.60 wrote .batch-hashes.json at the run's end only: after a kill -9 (or the out-of-memory killer, a lost
    # machine) the rerun read every byte of every exemplar again, hours of a studio's library. Now it is written
    # as soon as the plan is made, before any exemplar runs.
    src, out = make_folder(tmp_path / "src"), tmp_path / "out"
    monkeypatch.setattr(batch_plan, "STAT_MARGIN", 0.0)  # the files were written a moment ago (in the child too)
    code = ("import sys; from tghop import batch, batch_plan; import test_batch_resume as t; "
            "batch_plan.STAT_MARGIN = 0.0; batch.run(sys.argv[1], sys.argv[2], workers=1, task=t.killing_task)")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(Path(__file__).parent),
                                                                   os.environ.get("PYTHONPATH")) if p)}
    p = subprocess.run([sys.executable, "-c", code, str(src), str(out)], env=env, capture_output=True, timeout=300)
    assert p.returncode == -signal.SIGKILL, p.stderr[-2000:]
    hashes = json.loads((out / batch_plan.HASHES).read_text())
    assert sorted(Path(k).name for k in hashes) == ["e0.png", "e1.png", "e2.png"]
    reads = []
    monkeypatch.setattr(batch_plan, "file_sha256", lambda path: reads.append(path))
    plan = []
    run(src, out, task=lambda job: {"status": "failed", "error": "a stand-in", "cause": "run", "outputs": [],
                                    "model": None, "thumbnail": None}, on_plan=plan.append)
    assert reads == [] and plan[0]["to_do"] == 3  # none read again; the killed one too is done again


def full_disk_task(job):
    """A stand-in task whose files met a full disk, as process_exemplar records it."""
    return {"status": "failed", "error": f"{job['folder']}/x.npz: writing the model failed (No space left on device)",
            "cause": "run", "disk_full": True, "outputs": [], "model": None, "thumbnail": None}


def test_a_full_disk_on_a_dask_worker_stops_the_run_too(tmp_path):
    # The driver's side of it on Dask: the run stops at the first such record, the exemplars handed out meanwhile
    # recorded "interrupted" (their tasks may still finish), the rest not started.
    distributed = pytest.importorskip("distributed")
    src, out = make_folder(tmp_path / "src", 6), tmp_path / "out"
    local = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0",
                                     silence_logs=50)
    client = distributed.Client(local)
    try:
        with pytest.raises(TGHopError, match=r"^the disk of .*out is full \(e\d: .*No space left on device\)\); "
                                             r"the run stopped: "):
            batch.run(src, out, size=(32, 32), seed=1, client=client, task=full_disk_task)
    finally:
        client.close()
        local.close()
    lines = ledger(out)
    assert [line["status"] for line in lines][0] == "failed" and len(lines) <= 2, lines
    assert len({line["name"] for line in lines}) == len(lines) and not list(out.rglob(".batch-running"))


def test_a_task_whose_exemplar_another_run_claimed_meanwhile_moves_no_file(tmp_path, monkeypatch):
    # 0.61: a task moved its files into place whatever happened meanwhile, so a killed --scheduler run's task that ran
    # on replaced a rerun's files after the rerun's line said them. 0.62: the RUNNING file holds the claim of the run
    # that handed the exemplar out, and a task moves its files only while it is its own (a stand-in rerun claims the
    # exemplar here while the task fits).
    from tghop import batch_task

    src, out = make_folder(tmp_path / "src", 1), tmp_path / "out"
    thumbnail = batch_task._thumbnail

    def claimed_by_another(image, path):
        batch_task.write_claim(out / "e0", "another run")
        thumbnail(image, path)

    monkeypatch.setattr(batch_task, "_thumbnail", claimed_by_another)
    [result] = run(src, out)
    assert result["status"] == "failed" and result["superseded"] and result["error"] == batch_task.SUPERSEDED
    assert not list((out / "e0").glob("*.png")) and not list((out / "e0").glob("*.npz"))
    monkeypatch.undo()  # a task of a stopped run that starts late: not even fitted
    batch_task.write_claim(out / "e0", "another run")
    record = batch.process_exemplar({"name": "e0", "source": str(src / "e0.png"), "folder": str(out / "e0"),
                                     "claim": "a stopped run", "size": [32, 32], "count": 1, "seed": 1, "fit": FIT,
                                     "generate": GEN})
    assert record["superseded"] and record["fit_seconds"] is None and not list((out / "e0").glob("*.png"))
    [result] = run(src, out)  # the next run claims it anew and makes it
    assert result["status"] == "ok" and not result["skipped"] and not (out / "e0" / batch.RUNNING).exists()


def test_a_renamed_exemplar_keeps_its_files_under_the_new_name(tmp_path, monkeypatch):
    # 0.61: a manifest row given a new name (the same file and settings) was fitted again under it, and its old folder
    # kept and said "no longer in SOURCE". 0.62: the finished result, found by its input's SHA-256 and settings, is
    # moved to the new name, its files renamed as a run names them (a material's maps too), and the ledger says so.
    from test_cli_failures import invoke

    src = make_folder(tmp_path / "src", 2)
    save_image(np.linspace(0, 1, 64 * 64).reshape(64, 64), src / "e1_r.png")
    args = ["batch", "src/list.csv", "-o", "out", "--size", "32", "--seed", "1", "--count", "2", "--clusters", "6",
            "--codewords", "30", "--stride", "4", "--workers", "1", "-q"]
    (src / "list.csv").write_text("path,name,maps\ne0.png,rock,\ne1.png,stone,rough=e1_r.png\n")
    code, _, err, _ = invoke(*args, cwd=tmp_path)
    assert code == 0, err
    out = tmp_path / "out"
    made = {p.relative_to(out).as_posix(): p.read_bytes() for p in out.glob("*/*") if p.is_file()}
    assert "stone/stone_1_rough.png" in made and "rock/rock_2.png" in made, sorted(made)
    (src / "list.csv").write_text("path,name,maps\ne0.png,granite,\ne1.png,Slate,rough=e1_r.png\n")
    monkeypatch.setattr(batch, "process_exemplar", lambda job: pytest.fail(f"{job['name']} made again"))
    code, _, err, _ = invoke(*args, cwd=tmp_path)
    assert code == 0, err
    assert "renamed: rock is now granite: its files moved, not made again" in err and "no longer in SOURCE" not in err
    moved = {p.relative_to(out).as_posix(): p.read_bytes() for p in out.glob("*/*") if p.is_file()}
    renamed = {k.replace("rock", "granite").replace("stone", "Slate"): v for k, v in made.items()}
    assert moved == renamed and not (out / "rock").exists() and not (out / "stone").exists()
    last = {line["name"]: line for line in ledger(out)}
    assert last["granite"]["renamed_from"] == "rock" and last["rock"]["status"] == "renamed"
    assert last["rock"]["renamed_to"] == "granite" and last["Slate"]["outputs"][1] == "Slate/Slate_1_rough.png"
    results = batch.run(src / "list.csv", out, size=32, seed=1, count=2, fit=FIT, workers=1)  # nothing to move now
    assert [(r["skipped"], r.get("renamed")) for r in results] == [(True, None), (True, None)]


def test_a_rename_of_case_only_is_a_rename_and_its_old_folder_is_said(tmp_path):
    # Rock.png to rock.png: 0.61 compared the names without case, so it neither moved its files (it made it again, and
    # the folder Rock stayed on a case-sensitive file system) nor said that folder "no longer in SOURCE".
    src, out = make_folder(tmp_path / "src", 1), tmp_path / "out"
    (src / "e0.png").rename(src / "Rock.png")
    run(src, out)
    made = {p.name: p.read_bytes() for p in (out / "Rock").iterdir()}
    (src / "Rock.png").rename(src / "rock.png")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no folder said "no longer in SOURCE"
        (again,) = run(src, out, task=lambda job: pytest.fail(f"{job['name']} made again"))
    assert again["renamed"] and again["renamed_from"] == "Rock"
    assert {p.name: p.read_bytes() for p in (out / "rock").iterdir()} == {
        k.replace("Rock", "rock"): v for k, v in made.items()}
    assert [p.name for p in out.iterdir() if p.is_dir()] == ["rock"]  # the folder's name too, on any file system
    (src / "rock.png").rename(src / "Rock.png")  # back, with other settings: made again, the old folder said
    if not (out / "ROCK").exists():  # a case-sensitive file system: two folders
        with pytest.warns(UserWarning, match="1 folder of exemplars no longer in SOURCE: rock; prune=True"):
            run(src, out, count=2)
        run(src, out, count=2, prune=True)
        assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ["Rock"]


def test_a_rename_of_case_only_where_the_two_names_are_one_folder(tmp_path):
    # The path of a case-insensitive file system (macOS's, Windows'): OUTDIR/Rock and OUTDIR/rock are one folder
    # (os.path.samefile). No such mount can be made here without root (ext4's casefold needs mkfs and mount, vfat
    # a mount), so the folder is made to behave so: OUTDIR/rock a link to OUTDIR/Rock. The files are renamed inside
    # it, the folder's own rename fails there (a folder cannot replace a link) and it is kept as it was, and the old
    # name is never a folder "no longer in SOURCE": its thumbnail, exemplar.png, is the new name's, which --prune
    # would have deleted (0.61 compared the names without case and said nothing; a case-sensitive test alone could
    # not see this).
    src, out = make_folder(tmp_path / "src", 1), tmp_path / "out"
    (src / "e0.png").rename(src / "Rock.png")
    run(src, out)
    made = {p.name: p.read_bytes() for p in (out / "Rock").iterdir()}
    (out / "rock").symlink_to("Rock", target_is_directory=True)  # the other case of the name: the same folder
    (src / "Rock.png").rename(src / "rock.png")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no folder said "no longer in SOURCE", in this run or the next
        (again,) = run(src, out, task=lambda job: pytest.fail(f"{job['name']} made again"))
        assert again["renamed"] and again["renamed_from"] == "Rock"
        assert {p.name: p.read_bytes() for p in (out / "rock").iterdir()} == {
            k.replace("Rock", "rock"): v for k, v in made.items()}
        assert sorted(p.name for p in out.iterdir() if p.name not in ("batch.jsonl", "index.html", batch_plan.HASHES)
                      ) == ["Rock", "rock"]  # no temporary name left: the folder kept as it was
        (third,) = run(src, out, prune=True, task=lambda job: pytest.fail(f"{job['name']} made again"))
    assert third["skipped"] and all((out / f).is_file()
                                    for f in [*third["outputs"], third["model"], third["thumbnail"]])
    assert third["thumbnail"] == "rock/exemplar.png" and (out / "Rock" / "exemplar.png").is_file()


def test_a_failed_try_after_a_finished_one_does_not_make_it_again(tmp_path):
    # A share that dropped for a while (its exemplars "no such file"), a worker out of memory: a failed try moves no
    # file, so the folder still holds the finished try's files. 0.61 took the failed line as the exemplar's state and
    # fitted it again once its input was back (a studio's thousands after a NAS blip); 0.62 skips it as done.
    src, out = make_folder(tmp_path / "src", 2), tmp_path / "out"
    (src / "list.csv").write_text("path\ne0.png\ne1.png\n")
    first = run(src / "list.csv", out)
    (src / "e0.png").rename(tmp_path / "away.png")
    assert [r["status"] for r in run(src / "list.csv", out)] == ["failed", "ok"]  # e0: no such file
    (tmp_path / "away.png").rename(src / "e0.png")
    again = run(src / "list.csv", out, task=lambda job: pytest.fail(f"{job['name']} made again"))
    assert [(r["status"], r["skipped"]) for r in again] == [("ok", True), ("ok", True)]
    assert again[0]["outputs"] == first[0]["outputs"] and all((out / f).is_file() for f in first[0]["outputs"])


def kills_on_e0(job):
    """The driver killed outright at e0 (the out-of-memory killer, a decoder's crash, in process); others a
    stand-in's failed line."""
    if job["name"] == "e0":
        os.kill(os.getpid(), signal.SIGKILL)
    return {"status": "failed", "error": "a stand-in", "cause": "run", "outputs": [], "model": None, "thumbnail": None}


def test_an_exemplar_that_kills_the_run_goes_last_in_the_rerun(tmp_path):
    # In process, an exemplar that kills the run (out of memory) came first again in every rerun: nothing after it
    # was ever made (0.61). 0.62 hands out the exemplars a killed run left under way (their RUNNING file) last.
    src, out = make_folder(tmp_path / "src"), tmp_path / "out"
    code = ("import sys; from tghop import batch; import test_batch_resume as t; "
            "batch.run(sys.argv[1], sys.argv[2], workers=1, task=t.kills_on_e0)")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(Path(__file__).parent),
                                                                   os.environ.get("PYTHONPATH")) if p)}
    for _ in range(2):
        p = subprocess.run([sys.executable, "-c", code, str(src), str(out)], env=env, capture_output=True, timeout=300)
        assert p.returncode == -signal.SIGKILL, p.stderr[-2000:]
    assert sorted(line["name"] for line in ledger(out)) == ["e1", "e2"]  # made in the rerun, before e0
    assert (out / "e0" / batch.RUNNING).exists()


def test_ctrl_c_while_the_library_is_hashed_keeps_what_was_read(tmp_path, monkeypatch):
    # A first run over a studio's library reads every file for its SHA-256 before any work (minutes for terabytes);
    # 0.61 kept none of it after a Ctrl-C there, so the next run read them all again. 0.62 writes what it read.
    src, out = make_folder(tmp_path / "src"), tmp_path / "out"
    monkeypatch.setattr(batch_plan, "STAT_MARGIN", 0.0)  # the files were written a moment ago
    sha256, reads = batch_plan.file_sha256, []

    def ctrl_c_at_the_third(path):
        if len(reads) == 2:
            raise KeyboardInterrupt
        reads.append(path)
        return sha256(path)

    monkeypatch.setattr(batch_plan, "file_sha256", ctrl_c_at_the_third)
    with pytest.raises(KeyboardInterrupt):
        run(src, out)
    reads.clear()
    monkeypatch.setattr(batch_plan, "file_sha256", lambda path: reads.append(path) or sha256(path))
    run(src, out, task=lambda job: {"status": "failed", "error": "a stand-in", "cause": "run", "outputs": [],
                                    "model": None, "thumbnail": None})
    assert [Path(path).name for path in reads] == ["e2.png"]  # e0 and e1 were hashed before the Ctrl-C


def test_a_ctrl_c_while_an_exemplar_is_moved_to_its_new_name_loses_nothing(tmp_path, monkeypatch):
    # The files moved and the ledger's lines that say so go together: a Ctrl-C between them would leave the files in
    # the new folder without a line, and the next run would make the exemplar again.
    src, out = make_folder(tmp_path / "src", 1), tmp_path / "out"
    (src / "list.csv").write_text("path,name\ne0.png,rock\n")
    run(src / "list.csv", out)
    (src / "list.csv").write_text("path,name\ne0.png,granite\n")
    move = batch.move_renamed

    def ctrl_c_after_the_move(*args):
        moved = move(*args)
        signal.raise_signal(signal.SIGINT)
        return moved

    monkeypatch.setattr(batch, "move_renamed", ctrl_c_after_the_move)
    with pytest.raises(KeyboardInterrupt):
        run(src / "list.csv", out)
    monkeypatch.undo()
    [again] = run(src / "list.csv", out, task=lambda job: pytest.fail("made again"))
    assert again["skipped"] and again["renamed_from"] == "rock" and (out / "granite" / "granite.png").is_file()


def test_compacting_keeps_the_lines_that_say_a_finished_try_no_longer_stands(tmp_path, monkeypatch):
    # A worker lost on every try after a finished try (it may have moved some files before it died) ends what that
    # try's line says of the folder: compaction dropped such a line (it lists no file), and the exemplar was then
    # taken as done by that earlier line.
    out = tmp_path / "out"
    (out / "x").mkdir(parents=True)
    (out / "x" / "x.png").write_bytes(b"x")
    tried = {"name": "x", "status": "failed", "worker": "host:1", "outputs": []}
    lines = [tried] * 10 + [{"name": "x", "status": "ok", "outputs": ["x/x.png"]},
                            {"name": "x", "status": "failed", "error": "the worker running it died on every try"},
                            tried]
    (out / batch.LEDGER).write_text("".join(json.dumps(line) + "\n" for line in lines))
    before = {}
    batch_plan.read_ledger_files(out, before)
    monkeypatch.setattr(batch_plan, "COMPACT_MIN", 1)
    assert batch_plan.compact_ledger(out) == 10
    after = {}
    batch_plan.read_ledger_files(out, after)
    assert before == after == {}
