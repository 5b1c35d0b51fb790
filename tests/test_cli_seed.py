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
