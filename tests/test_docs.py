"""The README and docs/ name only what exists: tghop's modules and attributes, the commands'
options, the repository's files (docs/history.md, the record of past versions, aside)."""

import importlib
import re
from pathlib import Path

import pytest

from conftest import cli

ROOT = Path(__file__).resolve().parents[1]
# history.md keeps each version's text as written then, names since renamed included.
CURRENT = [ROOT / "README.md"] + [p for p in sorted((ROOT / "docs").glob("*.md")) if p.name != "history.md"]
OPTION = re.compile(r"(?<![\w-])(--[a-z][\w-]*)")


def _resolves(dotted):
    """Whether ``tghop.a.b`` is a module or an attribute of one (None: it needs a missing extra)."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError as error:
            if not (error.name or "").startswith("tghop"):
                return None
            continue
        for part in parts[i:]:
            if not hasattr(obj, part):
                return False
            obj = getattr(obj, part)
        return True
    return False


def test_every_tghop_name_in_the_docs_exists():
    # A module split or renamed (0.53 split core, refine, synthesis, inpaint and the server) leaves its old names here.
    missing = []
    for path in CURRENT:
        for name in sorted(set(re.findall(r"\btghop(?:\.[A-Za-z_]\w*)+", path.read_text(encoding="utf-8")))):
            if _resolves(name) is False:
                missing.append(f"{path.name}: {name}")
    assert not missing, missing


def test_every_file_the_docs_name_exists():
    missing = []
    for path in CURRENT:
        text = path.read_text(encoding="utf-8")
        for name in sorted(set(re.findall(r"(?<![\w/.])((?:benchmarks|scripts|src|tests|docs)/[\w/-]+\.(?:py|md|png))",
                                          text))):
            if name.startswith("benchmarks/results/"):
                continue  # a git-ignored folder: the benchmarks remake what is not committed
            if not (ROOT / name).exists():
                missing.append(f"{path.name}: {name}")
    assert not missing, missing


def _help(command, cache={}):
    """The --help text of ``tghop COMMAND`` (None: no such command)."""
    if command not in cache:
        result = cli(*command, "--help")
        cache[command] = result.stdout.decode() if result.returncode == 0 else None
    return cache[command]


def _command(words):
    """The command a line ``tghop ...`` runs: one word, or a group's two (``cooc train``)."""
    if not re.fullmatch(r"[a-z]+", words[1]) or _help(tuple(words[1:2])) is None:
        return None
    group = "\nCommands:" in _help(tuple(words[1:2]))
    if group and len(words) > 2 and re.fullmatch(r"[a-z]+", words[2]) and _help(tuple(words[1:3])) is not None:
        return tuple(words[1:3])
    return tuple(words[1:2])


@pytest.mark.parametrize("path", CURRENT, ids=lambda p: p.name)
def test_every_command_line_in_the_docs_takes_its_options(path):
    # Each line `tghop CMD [SUB] ... --option` of a code block or a `...` span: the option is in its --help.
    lines = [line.split("#")[0] for line in re.findall(r"^\s*(tghop [a-z].*)$", path.read_text(encoding="utf-8"), re.M)]
    lines += re.findall(r"`(tghop [a-z][^`]*)`", path.read_text(encoding="utf-8"))
    wrong = []
    for line in lines:
        command = _command(line.split())
        if command is None:
            if "--" in line:  # prose that starts with "tghop" has no options
                wrong.append(f"no command: {line.strip()}")
            continue
        known = set(OPTION.findall(_help(command)))
        wrong += [f"{' '.join(command)} has no {option}: {line.strip()}" for option in OPTION.findall(line)
                  if option not in known]
    assert not wrong, wrong


#: A time or memory figure: ``2.3 s``, ``~12 min``, ``0.6 GB``.
FIGURE = re.compile(r"\b\d[\d.,]*\s?(?:ms|s|min|minutes|MB|GB)\b")
#: A version label: ``(0.51)``, ``(2 cores, 0.51)``, ``0.13;``.
VERSION = re.compile(r"(?<![\w.=-])0\.\d{1,2}(?:\.\d)?(?=[;),])")


def test_every_figure_in_the_readmes_command_comments_names_its_version():
    # The README's `--quality best` said "2.3 s at 256x256 (2 cores)" and the cooc and GPDM lines "about 15 min",
    # "~12 min", with no word of the version that took them: a newcomer cannot tell a 0.1 figure from a 0.56 one.
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    unlabelled = []
    for block in re.findall(r"^```sh\n(.*?)^```", text, re.S | re.M):
        commands = re.split(r"\n(?=\S)", block)  # a command and the comment lines that continue it
        for command in commands:
            comment = " ".join(line.split("#", 1)[1] for line in command.splitlines() if "#" in line)
            if FIGURE.search(comment) and not VERSION.search(comment):
                unlabelled.append(command.splitlines()[0].strip())
    assert not unlabelled, unlabelled


def _anchors(path):
    """The anchors GitHub gives the headings of ``path``: lower case, punctuation but ``-`` and ``_`` dropped, spaces
    as ``-``, a repeated one numbered."""
    anchors, seen, fenced = set(), {}, False
    for line in path.read_text(encoding="utf-8").splitlines():
        fenced ^= line.startswith("```")
        heading = None if fenced else re.match(r"#{1,6}\s+(.*)", line)
        if heading:
            slug = re.sub(r"[^\w\- ]", "", heading.group(1).strip().lower()).replace(" ", "-")
            anchors.add(f"{slug}-{seen[slug]}" if slug in seen else slug)
            seen[slug] = seen.get(slug, 0) + 1
    return anchors


def test_every_link_in_the_docs_leads_somewhere():
    # docs/history.md quotes the README of 0.49, whose links were the README's own (docs/history.md, from docs/
    # itself docs/docs/history.md): clicked there, they led nowhere. History's links are checked too.
    broken = []
    for path in [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md")):
        for link in re.findall(r"\]\(([^)\s]+)\)", path.read_text(encoding="utf-8")):
            if re.match(r"[a-z]+:", link):
                continue  # https:, mailto:
            name, _, anchor = link.partition("#")
            target = (path.parent / name) if name else path
            if not target.exists() or (anchor and target.suffix == ".md" and anchor not in _anchors(target)):
                broken.append(f"{path.name}: {link}")
    assert not broken, broken
