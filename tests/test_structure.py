"""The shape of the package: every module imports on its own, no import cycles, no module
reaching for another's private names, no side effects on import, no overlong files or lines.

These read the source (ast) and run fresh interpreters; they need nothing of ../shared/.
"""

from __future__ import annotations

import ast
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import tghop

SRC = Path(tghop.__file__).resolve().parent
PACKAGE = "tghop"

#: Files allowed over MAX_LINES, each one coherent algorithm (why it stays whole).
LONG_FILES = {
    "quilting.py": "image quilting: the plan, the bounded candidate search and the boundary cuts are one "
                   "algorithm whose parts share its tables",
}
MAX_LINES = 850
#: The longest line, in characters, of any Python file (the package, tests, benchmarks and scripts) and of
#: the page's scripts.
MAX_LINE_LENGTH = 120
ROOT = Path(__file__).resolve().parent.parent
#: The JavaScript of tghop serve's page, held to the same limits as the package's modules.
PAGE_SCRIPTS = sorted((SRC / "server" / "static").glob("*.js"))


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


MODULES = {_module_name(p): p for p in sorted(SRC.rglob("*.py"))}


def _is_package(name: str) -> bool:
    return MODULES[name].name == "__init__.py"


def _resolve(module: str, node: ast.ImportFrom) -> str:
    """The absolute name of what ``from ... import`` names (relative imports resolved)."""
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if _is_package(module) else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(module: str):
    """Yield (imported module, names taken from it or None) for every import in ``module``,
    function-level imports included; only tghop's own modules."""
    tree = ast.parse(MODULES[module].read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == PACKAGE:
                    yield alias.name, None
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(module, node)
            if target.split(".")[0] != PACKAGE:
                continue
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                if sub in MODULES:  # `from . import layout`: the module itself
                    yield sub, None
                else:
                    yield target, alias.name


def _graph():
    graph = {m: set() for m in MODULES}
    for module in MODULES:
        for target, _ in _imports(module):
            if target in MODULES and target != module:
                graph[module].add(target)
    return graph


def test_the_package_import_graph_has_no_cycle():
    graph = _graph()
    # A submodule runs its package's __init__ first; that implicit edge is not a cycle of
    # the code's own (the package's face imports its parts), so only explicit imports count.
    state, stack, cycles = {}, [], []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                cycles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node)
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_the_library_does_not_import_the_command_line():
    # Arrows point down: tghop.cli stands on the library (and tghop.server beside it), never
    # the other way; only the entry point (tghop.__main__) starts the command line.
    bad = [f"{module} imports {target}" for module in MODULES
           if not (module == "tghop.cli" or module.startswith("tghop.cli.") or module == "tghop.__main__")
           for target, _ in _imports(module) if target == "tghop.cli" or target.startswith("tghop.cli.")]
    assert not bad, "library modules importing the command line:\n" + "\n".join(bad)


def test_no_module_imports_a_private_name_of_another():
    bad = []
    for module in MODULES:
        for target, name in _imports(module):
            if name and name.startswith("_") and not name.startswith("__") and target != module:
                bad.append(f"{module}: from {target} import {name}")
        # module._name on a module imported as a whole (`from . import layout`, `import tghop.x as y`)
        tree = ast.parse(MODULES[module].read_text())
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and _resolve(module, node).split(".")[0] == PACKAGE:
                for alias in node.names:
                    if f"{_resolve(module, node)}.{alias.name}" in MODULES:
                        aliases[alias.asname or alias.name] = alias.name
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith(PACKAGE + ".") and alias.asname:
                        aliases[alias.asname] = alias.name
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                    and node.attr.startswith("_") and not node.attr.startswith("__")):
                bad.append(f"{module}: {node.value.id}.{node.attr}")
    assert not bad, "private names used across modules:\n" + "\n".join(bad)


#: A fresh interpreter that imports each module named in its arguments in a child of its own (a fork of
#: itself before any of tghop's modules is imported), and prints the failures. Only NumPy and SciPy's linear
#: algebra and images are loaded first (most modules import them, and loading them was most of each fresh
#: interpreter's work): NumPy loads its submodules itself and SciPy's load on first use, so what a module
#: imports finds them as in an interpreter of its own.
IMPORT_EACH = """
import importlib, os, sys, traceback
import numpy, scipy.linalg, scipy.ndimage
failed = []
for name in sys.argv[1:]:
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read)
        try:
            importlib.import_module(name)
            status = 0
        except BaseException as exc:
            os.write(write, traceback.format_exception_only(exc)[-1].strip().encode())
            status = 1
        os._exit(status)
    os.close(write)
    with os.fdopen(read, "rb") as said:
        message = said.read().decode()
    if os.waitpid(pid, 0)[1]:
        failed.append(f"{name}: {message or 'no message'}")
print("\\n".join(failed))
"""


def test_every_module_imports_on_its_own_in_a_fresh_interpreter():
    # 0.63: each module in a fork of one interpreter; 0.62 started an interpreter for each (over a hundred).
    names = [m for m in MODULES if not m.endswith("__main__")]
    p = subprocess.run([sys.executable, "-c", IMPORT_EACH, *names], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert not p.stdout.strip(), p.stdout


def test_importing_tghop_changes_no_signal_handler_environment_or_collector():
    # A program that imports tghop (every module of it) keeps its own signal handling,
    # environment and garbage collector: what the command does to its process is done in
    # tghop.__main__.run only.
    modules = [m for m in MODULES if not m.endswith("__main__")]
    code = (
        "import gc, json, os, signal, sys\n"
        "def state():\n"
        "    handlers = {s.name: repr(signal.getsignal(s)) for s in signal.valid_signals()\n"
        "                if isinstance(s, signal.Signals)}\n"
        "    return {'signals': handlers, 'env': dict(os.environ), 'frozen': gc.get_freeze_count(),\n"
        "            'argv': list(sys.argv)}\n"
        "before = state()\n"
        f"for name in {modules!r}:\n"
        "    __import__(name)\n"
        "print(json.dumps([before, state()]))\n"
    )
    p = subprocess.run([sys.executable, "-c", code, "tghop"], capture_output=True, text=True, timeout=300,
                       env={k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"})
    assert p.returncode == 0, p.stderr
    before, after = json.loads(p.stdout)
    assert after["signals"] == before["signals"]
    assert after["env"] == before["env"]
    assert after["frozen"] == before["frozen"] and after["argv"] == before["argv"]


def test_the_command_sets_its_process_up():
    # ... and run() does: the start-up Ctrl-C handler and OPENBLAS_THREAD_TIMEOUT (the
    # latter only while NumPy is not loaded and the user has not chosen), then the command
    # line as the command.
    code = (
        "import os, signal, sys\n"
        "import tghop.cli.group as g\n"
        "seen = {}\n"
        "def fake_main(self, **kw):\n"
        "    seen['handler'] = signal.getsignal(signal.SIGINT).__name__\n"
        "    seen['timeout'] = os.environ.get('OPENBLAS_THREAD_TIMEOUT')\n"
        "    seen['as_command'] = kw.get('as_command')\n"
        "g.OneLineGroup.main = fake_main\n"
        "from tghop.__main__ import run\n"
        "run()\n"
        "print(seen)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert p.returncode == 0, p.stderr
    seen = eval(p.stdout)  # noqa: S307 - our own print of a small dict
    assert seen["handler"] == "_interrupted_while_starting" and seen["as_command"] is True
    assert seen["timeout"] == "4"


@pytest.mark.parametrize("user_value", [None, "7"])
def test_the_command_sets_openblas_timeout_only_when_unset(user_value, tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
    if user_value is not None:
        env["OPENBLAS_THREAD_TIMEOUT"] = user_value
    code = ("import os, sys\nimport tghop.__main__ as m\n"
            "sys.argv = ['tghop', '--version']\n"
            "try:\n    m.run()\nexcept SystemExit:\n    pass\n"
            "print('TIMEOUT', os.environ.get('OPENBLAS_THREAD_TIMEOUT'))\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert p.returncode == 0, p.stderr
    assert f"TIMEOUT {user_value or '4'}" in p.stdout


def test_no_file_is_overlong():
    assert PAGE_SCRIPTS, "the page's scripts are not where PAGE_SCRIPTS looks"
    long = {p.relative_to(SRC).as_posix(): len(p.read_text().splitlines())
            for p in [*MODULES.values(), *PAGE_SCRIPTS]}
    over = {name: n for name, n in long.items() if n > MAX_LINES and name not in LONG_FILES}
    assert not over, f"files over {MAX_LINES} lines (split them, or say in LONG_FILES why one stays whole): {over}"


def test_no_line_is_overlong():
    files = {p.resolve() for p in [*MODULES.values(), *PAGE_SCRIPTS]}
    files |= {p.resolve() for d in ("tests", "benchmarks", "scripts") for p in (ROOT / d).rglob("*.py")}
    over = [f"{p.relative_to(ROOT).as_posix() if p.is_relative_to(ROOT) else p}:{i}: {len(line)} characters"
            for p in sorted(files) for i, line in enumerate(p.read_text().splitlines(), 1)
            if len(line) > MAX_LINE_LENGTH]
    assert not over, f"lines over {MAX_LINE_LENGTH} characters (wrap them):\n" + "\n".join(over)


def test_docstring_examples_run_as_pasted():
    # Each module's `>>>` examples in a fresh namespace, as a reader pastes them (a doctest run in
    # the module's own globals found `np` there; inpaint's example used it without importing it).
    # Lines marked `# doctest: +SKIP` (fits, large images) are left out.
    import doctest
    import importlib

    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    failures, attempted = [], 0
    for name in MODULES:
        if name.endswith("__main__"):
            continue
        for test in finder.find(importlib.import_module(name), name, globs={}):
            test.globs = {}
            result = runner.run(test, out=failures.append)
            attempted += result.attempted
    assert attempted >= 5 and not failures, "".join(failures)[:2000]


def test_docstring_examples_define_every_name_they_use():
    # The lines marked `# doctest: +SKIP` are not run, but a reader pastes them too: tghop.material's
    # example fitted `albedo`, `normal` and `height`, which no line of it made.
    import builtins
    import doctest
    import importlib

    finder = doctest.DocTestFinder(exclude_empty=True)
    undefined = []
    for name in MODULES:
        if name.endswith("__main__"):
            continue
        for test in finder.find(importlib.import_module(name), name, globs={}):
            tree = ast.parse("".join(example.source for example in test.examples))
            made = set(dir(builtins))
            for node in ast.walk(tree):
                if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                    made.add(node.id)
                elif isinstance(node, (ast.Import, ast.ImportFrom)):
                    made.update((a.asname or a.name).split(".")[0] for a in node.names)
            used = {node.id for node in ast.walk(tree) if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load)}
            undefined += [f"{test.name}: {n}" for n in sorted(used - made)]
    assert not undefined, undefined


def _readme_table():
    """The rows of the README's "How it works" table: {first cell: whole line}, in order."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    return {line.split("|")[1]: line for line in readme.splitlines() if line.startswith("| `tghop.")}


def test_the_readme_names_every_module():
    # "How it works (one module per stage)" listed tghop.server's modules but for `safety`, and the command
    # line's modules, server's routes and the batch's manifest not at all (or without a purpose).
    table = _readme_table()
    missing = [f"tghop.{p.stem}" for p in SRC.glob("*.py")
               if not p.stem.startswith("__") and not any(f"`tghop.{p.stem}`" in key for key in table)]
    for package in ("server", "cooc", "metrics", "cli", "server/routes"):
        top = package.split("/")[0]
        row = next(line for key, line in table.items() if f"`tghop.{top}`" in key)
        prefix = "routes." if package == "server/routes" else ""
        missing += [f"tghop.{package.replace('/', '.')}.{p.stem}" for p in (SRC / package).glob("*.py")
                    if not p.stem.startswith("__") and f"`{prefix}{p.stem}`" not in row]
    assert not missing, missing


def test_each_package_docstring_maps_every_module():
    # A package's docstring is its module map: tghop.cli's left out inpaint, batch and serve, tghop.server's materials.
    missing = []
    for package in ("tghop.cli", "tghop.server", "tghop.server.routes", "tghop.cooc"):
        doc = ast.get_docstring(ast.parse(MODULES[package].read_text())) or ""
        missing += [module for module in MODULES if module.rpartition(".")[0] == package
                    and f"{module}`" not in doc and module != f"{PACKAGE}.__main__"]
    assert not missing, "modules their package's docstring does not name: " + ", ".join(missing)


def test_the_readme_table_is_in_import_order():
    # The README promises that a module imports only modules of its own row or above it: the table is the
    # order to read the code in. tghop._common sat above tghop._arrays, which it imports; tghop.fit_options
    # (which makes a TGHop) near the top; tghop.cli above tghop.server and tghop.baselines above tghop.cooc,
    # which they run. Imports inside functions count too: they load a later stage all the same.
    rows = {}
    for index, key in enumerate(_readme_table()):
        for name in re.findall(r"`(tghop[\w.]*)`", key):
            rows[name] = index

    def row(module):
        parts = module.split(".")
        return next((rows[".".join(parts[:i])] for i in range(len(parts), 1, -1) if ".".join(parts[:i]) in rows),
                    None)

    assert all(row(m) is not None for m in MODULES if m not in (PACKAGE, f"{PACKAGE}.__main__"))
    later = sorted({f"{module} imports {target}" for module in MODULES for target, _ in _imports(module)
                    if target != PACKAGE and row(module) is not None and row(target) is not None
                    and row(target) > row(module)})
    assert not later, "modules importing a module of a later row of the README's table:\n" + "\n".join(later)


def test_choices_contents_lists_every_section():
    # docs/choices.md's contents table is the newcomer's way in: a section added or renamed without it is lost.
    import re

    text = (ROOT / "docs" / "choices.md").read_text(encoding="utf-8")
    heads = [line[3:] for line in text.splitlines() if line.startswith("## ")][2:]  # after Contents, How to read
    anchors = [re.sub(r"[^\w\- ]", "", head.lower()).replace(" ", "-") for head in heads]
    contents = text.split("## Contents", 1)[1].split("\n## ", 1)[0]
    listed = re.findall(r"^\| \[[^]]+\]\(#([^)]+)\) \|", contents, re.M)
    assert listed == anchors
    assert len([head for head in heads if head.startswith("Where tghop stands")]) == 1  # the older ones: history.md

def _documented_parameters(doc: str):
    """The names a numpydoc ``Parameters`` section gives (``a, b : int`` gives both), or None."""
    import re

    found = re.search(r"\n( *)Parameters\n *-+\n(.*?)(?=\n *\n *[A-Z][A-Za-z ]+\n *-+\n|\Z)", doc, re.S)
    if not found:
        return None
    lines = [line for line in found.group(2).split("\n") if line.strip()]
    indent = min(len(line) - len(line.lstrip()) for line in lines)
    heads = [line.split(" : ")[0] for line in lines if len(line) - len(line.lstrip()) == indent]
    return {name.strip().lstrip("*") for head in heads for name in head.split(",")}


def test_every_documented_signature_lists_all_its_parameters():
    # tghop.batch.run's Parameters had no `scheduler` (named in passing under `client`), patches.space_to_depth
    # no `block`: a parameter the reader cannot find in the section is one the docs forgot (and one the
    # section names but the signature lacks, one they kept).
    import importlib
    import inspect

    forgotten = []
    for name in MODULES:
        module = importlib.import_module(name)
        for attr, obj in vars(module).items():
            if attr.startswith("_") or getattr(obj, "__module__", None) != name:
                continue
            found = [(attr, obj)] if inspect.isfunction(obj) else []
            if inspect.isclass(obj):
                found = [(attr, obj)] + [(f"{attr}.{m}", f) for m, f in vars(obj).items()
                                         if inspect.isfunction(f) and not m.startswith("_")]
            for qualname, func in found:
                documented = _documented_parameters(func.__doc__ or "")
                if not documented:
                    continue
                target = func.__init__ if inspect.isclass(func) else func
                try:
                    params = inspect.signature(target).parameters
                except (TypeError, ValueError):
                    continue
                missing = [p for p in params if p not in ("self", "cls", "y", "args", "kwargs") and p not in documented]
                stale = [p for p in documented if p not in params and p not in ("args", "kwargs")]
                forgotten += [f"{name}.{qualname}: {p}" for p in missing + [f"no {q}" for q in stale]]
    assert not forgotten, forgotten


def test_the_error_modules_docstring_names_every_module_it_imports():
    # tghop._errors is all that --help and --version load, and its docstring lists what it imports: it said "No
    # imports but os, sys, contextvars and warnings" while it imported contextlib and inspect too.
    tree = ast.parse(MODULES[f"{PACKAGE}._errors"].read_text())
    imported = {alias.name.split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.Import)
                for alias in node.names}
    imported |= {node.module.split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
                 and node.level == 0 and node.module != "__future__"}
    doc = ast.get_docstring(tree)
    assert imported and not [m for m in sorted(imported) if f"``{m}``" not in doc], sorted(imported)
