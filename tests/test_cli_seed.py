"""A run without --seed says the seed it drew, so that its image can be made again (0.59, an artist's
audit: 0.58 drew from the system's entropy and said nothing, so a result liked could not be made again)."""

import re

import numpy as np
import pytest

from tghop import TGHop, data
from tghop.modelfile import save_model

from conftest import cli

FAST = dict(n_clusters=8, n_codewords=40, max_patches=1200, stride=4, layout_factor=None)
GEN = ["--pool", "300", "--refine", "1", "-q"]
TOLD = re.compile(r"^seed (\d+) drawn \(no --seed given\): --seed \1 makes the same (\w+) again$", re.M)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("seed")
    save_model(TGHop(rng=0, **FAST).fit(data.bricks(96, rng=1)), folder / "a.npz")
    save_model(TGHop(rng=0, **FAST).fit(data.cells(96, rng=3)), folder / "b.npz")
    hole = np.zeros((64, 64), dtype=np.uint8)
    hole[20:40, 20:44] = 255
    from PIL import Image

    Image.fromarray(hole).save(folder / "hole.png")
    Image.fromarray((data.bricks(64, rng=2) * 255).round().astype(np.uint8)).save(folder / "photo.png")
    return folder


@pytest.mark.parametrize("args, what", [
    (["synth", "a.npz", "--size", "48x64", "-o", "{}.png", *GEN[:-1]], "image"),
    (["synth", "a.npz", "--size", "48", "--count", "2", "-o", "{}.png", *GEN[:-1]], "images"),
    (["synth", "a.npz", "b.npz", "--size", "48x64", "-o", "{}.png", *GEN[:-1]], "image"),
    (["inpaint", "photo.png", "hole.png", "--source", "a.npz", "-o", "{}.png"], "fill"),
    (["extend", "photo.png", "--size", "64x96", "--source", "a.npz", "-o", "{}.png"], "fill"),
    (["morph", "a.npz", "b.npz", "--size", "32x96", "-o", "{}.png"], "strip"),
])
def test_a_run_without_seed_tells_the_seed_that_makes_it_again(folder, args, what):
    def run(name, *more):
        r = cli(*[a.format(name) for a in args], *more, "-q", cwd=folder)
        assert r.returncode == 0, r.stderr.decode()
        return r.stderr.decode()

    first = TOLD.search(run("first"))
    assert first is not None and first.group(2) == what
    assert TOLD.search(run("again", "--seed", first.group(1))) is None  # given: nothing to tell
    made = sorted(folder.glob("first*.png"))
    assert made
    for made in made:
        assert made.read_bytes() == (folder / made.name.replace("first", "again")).read_bytes(), made.name


def test_count_draws_its_images_one_after_another_from_the_seed(folder):
    # What --count's help says (0.59): image k of --count N --seed S is image k of any --count >= k.
    for count in (1, 2):
        r = cli("synth", "a.npz", "--size", "48", "--count", str(count), "-o", f"c{count}.png", "--seed", "5",
                *GEN, cwd=folder)
        assert r.returncode == 0, r.stderr.decode()
    assert (folder / "c1.png").read_bytes() == (folder / "c2_1.png").read_bytes()


@pytest.mark.parametrize("args", [
    ["inpaint", "photo.png", "hole.png", "--source", "a.npz"],
    ["inpaint", "big.png", "bighole.png"],  # fitted on the photo once: fills 2 and 3 are drawn after fill 1
    ["extend", "photo.png", "--size", "64x96", "--source", "a.npz"],
])
def test_fill_count_numbers_its_files_as_synth_and_fill_k_is_any_counts(folder, args):
    from PIL import Image

    if not (folder / "big.png").exists():
        hole = np.zeros((128, 128), dtype=np.uint8)
        hole[50:74, 40:80] = 255
        Image.fromarray(hole).save(folder / "bighole.png")
        Image.fromarray((data.bricks(128, rng=2) * 255).round().astype(np.uint8)).save(folder / "big.png")
    # 0.58 had no --count on inpaint or extend (the README's way round: fit once with --exclude, then a run per
    # --seed); 0.59's fills one after another from one fit, image k the same in any --count of k or more.
    for count in (1, 3):
        r = cli(*args, "--count", str(count), "-o", f"f{count}.png", "--seed", "4", "-q", cwd=folder)
        assert r.returncode == 0, r.stderr.decode()
    r = cli(*args, "--count", "2", "-o", "f2.png", "--seed", "4", cwd=folder)
    assert r.returncode == 0 and "f2_1.png ... f2_2.png" in r.stderr.decode(), r.stderr.decode()
    assert sorted(p.name for p in folder.glob("f3*.png")) == ["f3_1.png", "f3_2.png", "f3_3.png"]
    assert (folder / "f1.png").read_bytes() == (folder / "f3_1.png").read_bytes()
    assert (folder / "f2_2.png").read_bytes() == (folder / "f3_2.png").read_bytes()
    assert len({(folder / f"f3_{k}.png").read_bytes() for k in (1, 2, 3)}) == 3  # three fills to pick from
    for p in folder.glob("f*.png"):
        p.unlink()


def test_fill_count_to_stdout_or_over_an_input_is_refused_before_any_work(folder):
    r = cli("inpaint", "photo.png", "hole.png", "--source", "a.npz", "--count", "2", "-o", "-", cwd=folder)
    assert r.returncode == 2 and "--count > 1 cannot write to stdout" in r.stderr.decode(), r.stderr.decode()
    (folder / "g").mkdir(exist_ok=True)
    (folder / "g" / "x_2.png").write_bytes((folder / "photo.png").read_bytes())
    r = cli("inpaint", "g/x_2.png", "hole.png", "--source", "a.npz", "--count", "2", "-o", "g/x.png", cwd=folder)
    assert r.returncode == 1 and "would overwrite IMAGE" in r.stderr.decode(), r.stderr.decode()
    assert sorted(p.name for p in (folder / "g").iterdir()) == ["x_2.png"]
