"""What `pip install .` and a published release hold: the wheel (the package alone: every
module and the page's static files, no tests, no caches), the sdist (the package and the whole
test suite; it builds the same wheel), the metadata, and extras that every `pip install
'tghop[...]'` hint names. Built with the project's own backend (setuptools.build_meta) in a
copy of the tree, offline."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src" / "tghop"
IGNORED = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info", ".hypothesis", ".pytest_cache")


def _build(tree: Path, kind: str, out: Path) -> Path:
    """Build ``kind`` ("wheel" or "sdist") of ``tree`` into ``out`` with the backend pyproject.toml names."""
    out.mkdir(exist_ok=True)
    code = f"import setuptools.build_meta as b; print(b.build_{kind}({str(out)!r}))"
    res = subprocess.run([sys.executable, "-c", code], cwd=tree, capture_output=True, text=True, timeout=240)
    assert res.returncode == 0, res.stderr[-3000:]
    return out / res.stdout.strip().splitlines()[-1]


def _package_files() -> set[str]:
    return {p.relative_to(SRC.parent).as_posix() for p in SRC.rglob("*")
            if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc"}


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    setuptools = pytest.importorskip("setuptools")
    if int(setuptools.__version__.split(".")[0]) < 77:
        pytest.skip(f"setuptools {setuptools.__version__}: the build needs 77 or newer (pip install 'tghop[test]')")
    tree = tmp_path_factory.mktemp("tree")
    for name in ("pyproject.toml", "README.md", "MANIFEST.in", "LICENSE"):
        shutil.copy2(ROOT / name, tree / name)
    shutil.copytree(ROOT / "src", tree / "src", ignore=IGNORED)
    shutil.copytree(ROOT / "tests", tree / "tests", ignore=IGNORED)
    wheel = _build(tree, "wheel", tree / "dist")
    sdist = _build(tree, "sdist", tree / "dist")
    unpacked = tmp_path_factory.mktemp("sdist")
    with tarfile.open(sdist) as tar:
        tar.extractall(unpacked, **({"filter": "data"} if hasattr(tarfile, "data_filter") else {}))
    (top,) = unpacked.iterdir()
    return wheel, sdist, _build(top, "wheel", unpacked / "dist"), tree


def test_wheel_holds_the_package_and_nothing_else(built):
    wheel, _, _, _ = built
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        metadata = zf.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
        entry_points = zf.read(next(n for n in names if n.endswith(".dist-info/entry_points.txt"))).decode()
    package = {n for n in names if ".dist-info/" not in n}
    # every module and every static file of the page (index.html, each script, style.css), no test,
    # no __pycache__, nothing from benchmarks/ or docs/
    assert package == _package_files()
    static = {f"tghop/server/static/{p.name}" for p in (SRC / "server" / "static").iterdir()}
    assert {"tghop/server/static/index.html", "tghop/server/static/style.css"} <= static <= package
    assert "tghop = tghop.__main__:run" in entry_points
    assert "Requires-Python: >=3.10" in metadata
    assert "License-Expression: BSD-3-Clause" in metadata and "License-File: LICENSE" in metadata
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)  # the licence's text ships with it
    assert "Description-Content-Type: text/markdown" in metadata


def test_sdist_holds_the_whole_test_suite_and_builds_the_same_wheel(built):
    wheel, sdist, again, _ = built
    with tarfile.open(sdist) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    tests = {p.relative_to(ROOT).as_posix() for p in (ROOT / "tests").glob("*.py")}
    assert tests <= names  # conftest.py and the browser helpers too, not only test_*.py
    assert {"pyproject.toml", "README.md", "LICENSE"} <= names and {f"src/{n}" for n in _package_files()} <= names
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
    with zipfile.ZipFile(wheel) as first, zipfile.ZipFile(again) as second:
        assert sorted(first.namelist()) == sorted(second.namelist())


def test_every_install_hint_names_an_extra_the_package_has(built):
    wheel, _, _, _ = built
    with zipfile.ZipFile(wheel) as zf:
        metadata = zf.read(next(n for n in zf.namelist() if n.endswith(".dist-info/METADATA"))).decode()
    extras = set(re.findall(r"^Provides-Extra: (\S+)$", metadata, re.M))
    assert {"metrics", "web", "batch", "tiff", "test", "web-test"} <= extras
    named = {}
    for path in SRC.rglob("*"):
        if path.suffix in (".py", ".js", ".html"):
            for extra in re.findall(r"tghop\[([\w,-]+)\]", path.read_text(encoding="utf-8")):
                named.setdefault(extra, path.name)
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for extra in re.findall(r"tghop\[([\w,-]+)\]|\.\[([\w,-]+)\]", readme):
        named.setdefault("".join(extra), "README.md")
    assert "metrics" in named and "tiff" in named
    unknown = {extra: where for extra, where in named.items() if not set(extra.split(",")) <= extras}
    assert not unknown, f"install hints naming extras the package lacks: {unknown}"
