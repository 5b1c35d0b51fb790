"""Property: whatever the input file's bytes and the option values, the CLI either exits 0
with a valid result or exits != 0 with one ``Error:`` line, no traceback and no file left.

Mutated PNG, JPEG and model (.npz) bytes, model files with changed arrays (shapes, types,
values, order; deleted, swapped or unknown arrays) and random option values, in-process
(click's CliRunner); the changed model files also straight through ``load_model`` and
``synthesize`` (a valid image or one ModelFileError line). The suite runs a couple of hundred
cases; ``python scripts/fuzz_cli.py`` runs thousands.
"""

from __future__ import annotations

import io
import os
import tempfile
from functools import lru_cache

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

#: Tiny, fast fits: a 40x40 exemplar, every patch (stride 1), two clusters.
FAST = ["--clusters", "2", "--codewords", "5", "--stride", "1", "--max-patches", "300", "-q"]


@lru_cache(maxsize=None)
def seeds():
    """Valid PNG, JPEG and model bytes to mutate (made in code, once)."""
    from PIL import Image

    from tghop import TGHop, data
    from tghop.modelfile import save_model

    img = data.bricks(40, rng=3)
    pil = Image.fromarray((img * 255).astype(np.uint8))
    png, jpg = io.BytesIO(), io.BytesIO()
    pil.save(png, format="PNG")
    pil.save(jpg, format="JPEG", quality=80)
    with tempfile.TemporaryDirectory() as d:
        model = TGHop(n_clusters=2, n_codewords=5, stride=1, rng=0).fit(img)
        save_model(model, os.path.join(d, "m.npz"))
        with open(os.path.join(d, "m.npz"), "rb") as fh:
            npz = fh.read()
    return {"png": png.getvalue(), "jpg": jpg.getvalue(), "npz": npz}


@lru_cache(maxsize=None)
def seed_arrays():
    """The arrays of a small model with a coarse layout model (layout.*), to mutate."""
    from tghop import TGHop, data

    from tghop.modelfile import save_model

    model = TGHop(n_clusters=2, n_codewords=5, stride=4, max_patches=300, rng=0).fit(data.bricks(96, rng=3))
    assert model.layout_ is not None
    with tempfile.TemporaryDirectory() as d:
        save_model(model, os.path.join(d, "m.npz"))
        with np.load(os.path.join(d, "m.npz")) as f:
            return {k: f[k] for k in f.files}


#: Values written into arrays: specials, extremes and ordinary numbers.
VALUES = [np.nan, np.inf, -np.inf, 0.0, -0.0, -1.0, 1.0, 0.5, 2.0, 1e30, -1e30, 1e300, 7.0, 255.0, -3.0, 1e-300]
DTYPES = ["float16", "float32", "float64", "int64", "int32", "uint8", "uint64", "complex128", "bool", "<U3"]


@st.composite
def mutated_arrays(draw):
    """A model file with some of its arrays changed: shapes, types, values, order; deleted,
    swapped or unknown arrays. Returns the .npz bytes."""
    arrays = dict(seed_arrays())
    names = sorted(k for k in arrays if k != "__meta__")
    for _ in range(draw(st.integers(1, 3))):
        name = draw(st.sampled_from(names))
        if name not in arrays:
            continue
        a = arrays[name]
        op = draw(st.sampled_from(["shape", "shape", "dtype", "value", "value", "value", "reverse", "permute",
                                   "scale", "delete", "extra", "swap"]))
        axis = draw(st.integers(0, max(a.ndim - 1, 0)))
        if op == "shape":
            how = draw(st.sampled_from(["drop", "add", "newaxis", "ravel", "empty"]))
            if how == "drop" and a.ndim and a.shape[axis]:
                a = np.delete(a, draw(st.integers(0, a.shape[axis] - 1)), axis=axis)
            elif how == "add" and a.ndim and a.shape[axis]:
                a = np.concatenate([a, np.take(a, [0], axis=axis)], axis=axis)
            elif how == "newaxis":
                a = a[None]
            elif how == "ravel":
                a = a.ravel()
            else:
                a = a[:0]
        elif op == "dtype":
            with np.errstate(all="ignore"):
                a = a.astype(draw(st.sampled_from(DTYPES)))
        elif op == "value" and a.size:
            a = a.copy()
            where = draw(st.integers(0, a.size - 1))
            value = draw(st.sampled_from(VALUES + [float(draw(st.floats(-10, 10)))]))
            if a.dtype.kind in "iu":
                value = draw(st.sampled_from([-1, 0, 1, 2, 3, 8, 21, 22, 99, 2**31, -(2**31)]))
                if a.dtype.kind == "u":
                    value = abs(value)
                with np.errstate(all="ignore"):
                    value = np.array(value).astype(a.dtype)
            with np.errstate(all="ignore"):
                a.flat[where] = value
        elif op == "reverse" and a.ndim:
            a = np.flip(a, axis=axis).copy()
        elif op == "permute" and a.ndim and a.shape[axis] > 1:
            order = draw(st.permutations(range(a.shape[axis])))
            a = np.take(a, order, axis=axis)
        elif op == "scale" and a.dtype.kind == "f":
            with np.errstate(all="ignore"):
                a = a * draw(st.sampled_from([-1.0, 0.0, 0.5, 2.0, 1e6]))
        elif op == "delete":
            del arrays[name]
            continue
        elif op == "extra":
            arrays[draw(st.sampled_from(["extra", "hop3.kernels", "layout.layout.sdr.mean"]))] = a
        elif op == "swap":
            other = draw(st.sampled_from(names))
            if other in arrays:
                arrays[name], a = arrays[other], arrays[name]
                name = other
        arrays[name] = a
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def check_model(blob):
    """The library side: a mutated model file loads and synthesizes a valid image, or
    :func:`load_model` raises one ModelFileError line (and nothing else)."""
    from tghop import ModelFileError
    from tghop.modelfile import load_model

    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "m.npz")
        with open(path, "wb") as fh:
            fh.write(blob)
        try:
            model = load_model(path)
        except ModelFileError as exc:
            assert "\n" not in str(exc) and str(exc), str(exc)
            return "refused"
    image = model.synthesize((40, 40), rng=0, n_patches=60)
    assert image.shape == (40, 40, model.exemplar_shape_[2]), image.shape
    assert np.isfinite(image).all() and image.min() >= 0 and image.max() <= 1
    return "loaded"


@st.composite
def mutated_file(draw):
    kind = draw(st.sampled_from(["png", "jpg", "npz"]))
    data = bytearray(seeds()[kind])
    for _ in range(draw(st.integers(0, 4))):
        op = draw(st.sampled_from(["flip", "truncate", "insert", "header", "delete"]))
        if not data:
            break
        at = draw(st.integers(0, len(data) - 1))
        if op == "flip":
            data[at] ^= draw(st.integers(1, 255))
        elif op == "truncate":
            del data[at:]
        elif op == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=16))
        elif op == "delete":
            del data[at: at + draw(st.integers(1, 64))]
        else:  # overwrite bytes near the start: sizes, magic numbers, headers
            at = draw(st.integers(0, min(len(data) - 1, 64)))
            chunk = draw(st.binary(min_size=1, max_size=8))
            data[at: at + len(chunk)] = chunk
    return kind, bytes(data)


NUMBERS = st.one_of(
    st.integers(-3, 300).map(str),
    st.sampled_from(["nan", "inf", "-inf", "1e309", "0", "-0", "1e-320", "10000000000000", "0x10", "", " ", "1.5",
                     "knee", "none", "3x", "x3", "7x9", "64x48", "2,3", "\x00", "é"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(max_size=6),
)

OPTIONS = ["--size", "--pool", "--tolerance", "--overlap", "--seed", "--gamma", "--reject-threshold",
           "--clusters", "--codewords", "--cluster-energy", "--k1", "--k2", "--count", "--bins", "--fit-seed",
           "--max-cluster-components", "--ica-iterations", "--patch-size", "--gamma-mode"]


@st.composite
def command(draw):
    if draw(st.integers(0, 3)) == 0:  # a model file with changed arrays
        kind, blob = "npz", draw(mutated_arrays())
    else:
        kind, blob = draw(mutated_file())
    name = {"png": "in.png", "jpg": "in.jpg", "npz": "in.npz"}[kind]
    verb = draw(st.sampled_from(["synth", "synth", "info", "patches", "evaluate", "fit"]))
    if verb == "synth":
        args = ["synth", name, "-o", draw(st.sampled_from(["out.png", "out.jpg"])), "--size", "40", "--pool", "60"]
        if kind != "npz":
            args += FAST
        else:
            args += ["-q"]
    elif verb == "info":
        args = ["info", name] + draw(st.sampled_from([[], ["--json"]]))
    elif verb == "patches":
        args = ["patches", name, "-n", "4", "-o", "grid.png"]
    elif verb == "evaluate":
        args = ["evaluate", name, name, "--metrics", "swd,cooccurrence"]
    else:
        args = ["fit", name, "-o", "model.npz"] + FAST
    for _ in range(draw(st.integers(0, 3))):
        args += [draw(st.sampled_from(OPTIONS)), draw(NUMBERS)]
    return blob, name, args


def invoke_in(folder, args):
    """The command line run in-process (click's CliRunner) in ``folder``: its result, once the property's first
    part holds (no exception but SystemExit, no traceback)."""
    from click.testing import CliRunner

    from tghop.cli import main

    old = os.getcwd()
    os.chdir(folder)
    try:
        result = CliRunner().invoke(main, args, catch_exceptions=True)
    finally:
        os.chdir(old)
    assert result.exception is None or isinstance(result.exception, SystemExit), (args, repr(result.exception))
    assert "Traceback" not in result.stderr, (args, result.stderr)
    return result


def check(blob, name, args):
    """Run one command in a fresh folder and assert the property."""
    from PIL import Image

    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, name)
        with open(path, "wb") as fh:
            fh.write(blob)
        result = invoke_in(folder, args)
        err = result.stderr
        left = sorted(set(os.listdir(folder)) - {name})
        if result.exit_code == 0:
            for f in left:
                assert not f.startswith("."), (args, left)  # no temporary file
                if f.endswith((".png", ".jpg")):
                    with Image.open(os.path.join(folder, f)) as im:
                        im.load()
                        assert im.size[0] >= 1 and im.size[1] >= 1
            if args[0] in ("synth", "patches", "fit"):
                assert left, (args, err)
        else:
            errors = [line for line in err.splitlines() if line.startswith("Error: ")]
            assert len(errors) == 1, (args, err)
            assert left == [], (args, left, err)


@settings(max_examples=150, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much])
@given(command())
def test_cli_fuzz(case):
    check(*case)


@settings(max_examples=120, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much])
@given(mutated_arrays())
def test_model_array_fuzz(blob):
    check_model(blob)


#: Outputs for :func:`stages_command`: odd names, formats tghop does not write, stdout, a folder, a missing folder.
STAGE_OUTPUTS = ["out.png", "out.jpg", "out.tif", "o u.png", "ü ñ.tif", "-", "out.webp", "out.exr", "sub/out.png",
                 "dir", "dir/", "out", ".png", "OUT.PNG", "a..png", "in.png", "out_quilt.png"]
#: Folders made before the command, named as a file it may write (a step's, a map's, a numbered one).
STAGE_OBSTACLES = ["dir", "out_quilt.png", "out_seams.tif", "out_join.png", "out_maps_height.png", "out_2.png",
                   "out_1_refine.png", "out_height.jpg", "out_regions.png", "out_stages.png"]


@st.composite
def stages_command(draw):
    """A command with ``--stages`` (0.61's additions) and odd outputs, depths, counts and folders in the way:
    ``(args, obstacles)``, run by :func:`check_stages` in a folder holding ``tex.npz``, ``mat.npz``, ``in.png``
    (64x64), ``hole.png`` and ``height.png``."""
    verb = draw(st.sampled_from(["synth", "synth mat", "paint", "paint mat", "morph", "morph mat", "inpaint",
                                 "inpaint maps", "extend", "extend maps", "patches"]))
    model = "mat.npz" if verb.endswith(("mat", "maps")) else "tex.npz"
    args = {"synth": ["synth", model, "--size", "40"], "paint": ["synth", model, model, "--size", "40"],
            "morph": ["morph", model, model, "--size", "40x80"],
            "inpaint": ["inpaint", "in.png", "hole.png"] + (["height.png", "--maps"] if "maps" in verb else []),
            "extend": ["extend", "in.png"] + (["height.png", "--maps"] if "maps" in verb else []) + ["--size", "72x80"],
            "patches": ["patches", model, "-n", "4"]}[verb.split()[0]]
    if verb.startswith(("inpaint", "extend")):
        args += ["--source", model]
    args += ["-o", draw(st.sampled_from(STAGE_OUTPUTS)), "--stages", "-q"]
    if verb != "patches":
        args += ["--seed", "1"]
        depth = draw(st.sampled_from([None, "8", "16", "32"]))
        args += [] if depth is None else ["--depth", depth]
        count = draw(st.sampled_from([None, "1", "2"]))
        args += [] if count is None or verb.startswith("morph") else ["--count", count]
    return args, draw(st.lists(st.sampled_from(STAGE_OBSTACLES), max_size=2, unique=True))


@lru_cache(maxsize=None)
def stage_inputs():
    """The bytes of :func:`stages_command`'s input files, made once."""
    from conftest import png, save_material, save_texture

    from tghop import data
    from tghop.material import example_maps

    with tempfile.TemporaryDirectory() as folder:
        save_texture(os.path.join(folder, "tex.npz"))
        save_material(os.path.join(folder, "mat.npz"))
        files = {name: open(os.path.join(folder, name), "rb").read() for name in ("tex.npz", "mat.npz")}
    picture = data.bricks(64, rng=2)
    hole = np.zeros((64, 64))
    hole[20:40, 24:44] = 1
    as_png = lambda a: png(np.round(np.asarray(a) * 255).astype(np.uint8))  # noqa: E731
    return {**files, "in.png": as_png(picture), "hole.png": as_png(hole),
            "height.png": as_png(example_maps(picture)["height"])}


def check_stages(args, obstacles):
    """:func:`check`'s property for a command of :func:`stages_command`: exit 0 with every file whole and no
    temporary one, or one ``Error:`` line, no traceback and the folder as it was."""
    from PIL import Image

    with tempfile.TemporaryDirectory() as folder:
        for name, content in stage_inputs().items():
            with open(os.path.join(folder, name), "wb") as fh:
                fh.write(content)
        for name in obstacles:
            os.makedirs(os.path.join(folder, name), exist_ok=True)
        before = {p: os.path.getsize(os.path.join(folder, p)) for p in os.listdir(folder)}
        result = invoke_in(folder, args)
        err = result.stderr
        left = {p: os.path.getsize(os.path.join(folder, p)) for p in os.listdir(folder)}
        if result.exit_code == 0:
            new = sorted(set(left) - set(before))
            assert new and not any(f.startswith(".") for f in new), (args, new)
            for f in new:
                if f.endswith((".png", ".jpg", ".PNG")):
                    with Image.open(os.path.join(folder, f)) as im:
                        im.load()
        else:
            errors = [line for line in err.splitlines() if line.startswith("Error: ")]
            assert len(errors) == 1, (args, err)
            assert left == before, (args, sorted(set(left) ^ set(before)), err)
