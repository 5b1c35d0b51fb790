"""Each command's ``--help`` ends with examples (0.59; ``tghop --help`` promised them, and 0.58's commands
had none but ``cooc``'s), and those are commands a newcomer can paste: the shell reads them, their options
exist, and those whose inputs are built in (builtin:bricks, or a file an example before them writes) run as
written."""

import re
import shlex
import subprocess
from pathlib import Path

import numpy as np
import pytest

from conftest import cli

README = Path(__file__).resolve().parents[1] / "README.md"
#: The commands as ``tghop --help`` lists them, in the order their examples make each other's inputs.
ORDER = ["fit", "synth", "info", "patches", "clusters", "inpaint", "extend", "morph", "evaluate", "baseline", "batch",
         "serve", "cooc"]
OPTION = re.compile(r"(?<![\w-])(--[a-z][\w-]*)")
#: Options whose value is a file the command writes, not one it reads.
WRITES = {"-o", "--output", "--save-model", "--cache"}
#: An argument that names a file to read.
FILE = re.compile(r"[^\s:]+\.(png|jpg|jpeg|tif|tiff|npz|pt|csv)|[\w./-]+/")


def _help(*command):
    result = cli(*command, "--help")
    assert result.returncode == 0, result.stderr
    return result.stdout.decode()


def _examples(command):
    """The example lines of ``tghop COMMAND --help`` (comments left out)."""
    text = _help(command)
    assert "\nExamples:\n" in text or "\n  Examples:\n" in text, f"tghop {command} --help has no examples"
    block = re.split(r"^ *Examples:\n", text, flags=re.M)[1]
    lines = []
    for line in block.splitlines():
        if not line.startswith("    ") or not line.strip():
            break
        lines.append(line)
    return lines


def test_every_command_is_listed_with_examples():
    listed = re.findall(r"^  ([a-z]+)  ", _help().split("Commands:")[1], re.M)
    assert sorted(listed) == sorted(ORDER)
    assert "tghop COMMAND --help" in _help()


@pytest.mark.parametrize("command", ORDER)
def test_every_example_is_a_line_the_shell_reads_with_options_its_command_takes(command):
    lines = _examples(command)
    commands = [line.strip() for line in lines if not line.strip().startswith("#")]
    assert commands, f"tghop {command} --help: no example command"
    for line in lines:
        assert len(line) <= 80, f"wider than a terminal: {line!r}"
    for line in commands:
        # 0.58's cooc train example ended "(small config: about 15 min ...)": pasted, bash stops on the "(".
        checked = subprocess.run(["bash", "-n", "-c", line], capture_output=True, text=True)
        assert checked.returncode == 0, f"{line!r}: {checked.stderr}"
        words = shlex.split(line.split(" #")[0])
        assert words[0] == "tghop", line
        named = words[1:3] if words[1] == "cooc" else words[1:2]
        assert words[1] == command or (command == "cooc" and words[1] == "baseline"), line
        known = set(OPTION.findall(_help(*named)))
        assert not set(OPTION.findall(line)) - known, f"{line!r}: {sorted(set(OPTION.findall(line)) - known)}"


def _inputs(words):
    """The files an example reads (its arguments that name a file, but the outputs)."""
    return [word for before, word in zip([""] + words, words)
            if before not in WRITES and not word.startswith("-") and FILE.fullmatch(word)]


def _fits_once(monkeypatch):
    """``TGHop.fit`` of one exemplar with one model's settings done once (the commands run in this process): a
    second fit of the same call is a copy of the first's model, as it would have fitted it again (a fit of given
    settings and fit seed is the same bit for bit). ``synth builtin:bricks`` fits the model ``fit builtin:bricks``
    fitted (both with fit seed 0): its fit is skipped, its synthesis runs. Returns the list of the calls served
    from a copy."""
    import copy

    from tghop.synthesis import TGHop

    fit, done, copied = TGHop.fit, {}, []

    def once(self, image, y=None, *, exclude=None, depth=None, progress=None, stacked=False):
        image = np.asarray(image)
        key = (type(self), repr(sorted(self.get_params(deep=False).items())), image.dtype.str, image.shape,
               image.tobytes(), None if exclude is None else np.asarray(exclude).tobytes(), depth, stacked)
        if key in done:
            copied.append(type(self).__name__)
            self.__dict__.update(copy.deepcopy(done[key]))
            return self
        fit(self, image, y, exclude=exclude, depth=depth, progress=progress, stacked=stacked)
        done[key] = copy.deepcopy(self.__dict__)
        return self

    monkeypatch.setattr(TGHop, "fit", once)
    return copied


@pytest.mark.timeout(900)  # two fits and eight commands: half a minute on 2 idle cores, minutes on busy ones
def test_the_examples_whose_inputs_are_built_in_run_as_written(tmp_path, monkeypatch):
    # What a newcomer pastes from the help after `pip install .`: the built-in exemplar's model, images of it,
    # its summary, patches, clusters and a baseline. Left out: an example of their own files (texture.jpg), the
    # server, a batch, the cGAN's and the scores (SIFID's network alone takes minutes on a busy machine).
    copied = _fits_once(monkeypatch)  # `synth builtin:bricks` fits `fit builtin:bricks`'s model: fitted once
    ran = []
    for command in ORDER:
        for line in _examples(command):
            line = line.strip()
            if line.startswith("#"):
                continue
            words = shlex.split(line)
            if (">" in line or "*" in line or command in ("serve", "cooc", "batch", "evaluate")
                    or not all((tmp_path / name).exists() for name in _inputs(words))):
                continue
            result = cli(*words[1:], cwd=tmp_path)
            assert result.returncode == 0, f"{line}: {result.stderr.decode()[-600:]}"
            ran.append(line)
    # The README's set-up line is one of them: it runs here as it does after its `pip install .`.
    first = re.search(r"^```sh\npip install \. && (tghop .*)$", README.read_text(encoding="utf-8"), re.M).group(1)
    assert {first, "tghop fit builtin:bricks -o bricks.npz", "tghop info bricks.npz",
            "tghop clusters bricks.npz builtin:bricks -o clusters.png"} <= set(ran), ran
    assert {command for command in ORDER if any(line.split()[1] == command for line in ran)} >= {
        "fit", "synth", "info", "patches", "clusters", "morph", "baseline"}, ran
    assert copied, "no fit was the same as one before: _fits_once saves nothing (drop it, or fit alike again)"


@pytest.mark.parametrize("command, lines_before", [("synth", 356), ("fit", 170), ("batch", 333)])
def test_help_leads_with_the_common_options_names_every_other_and_help_all_says_each(command, lines_before):
    # 0.63's synth --help was 356 lines, -o, --size and --seed among 60 options in the pipeline's order (0.64)
    import click
    from click.testing import CliRunner

    from tghop.cli import main
    from tghop.cli.help_sections import COMMON

    short = CliRunner().invoke(main, [command, "--help"]).stdout
    every = CliRunner().invoke(main, [command, "--help-all"]).stdout
    assert len(short.splitlines()) < lines_before / 3 < len(every.splitlines()) / 2, short
    first = short.split("\nOptions:\n", 1)[1].split("\n\n", 1)[0]  # the first section: the common options
    options = [p for p in main.get_command(None, command).params if isinstance(p, click.Option) and not p.hidden]
    by_name = {p.name: p for p in options}
    assert [by_name[n].opts[-1] for n in COMMON[command]] == [
        w for w in re.findall(r"^  (?:-\w, )?(--[\w-]+)", first, re.M) if w not in ("--help-all", "--help")]
    for p in options:  # each named in --help, its help in --help-all
        assert all(re.search(rf"(?<![\w-]){name}(?![\w-])", short) for name in p.opts), p.opts
        record = "".join(p.get_help_record(click.Context(main.get_command(None, command)))[1].split())
        assert record in "".join(every.split()), record  # spaces left out: click wraps at hyphens
    assert f"tghop {command} --help-all" in short.replace("main ", "tghop ")  # said where each one's help is
    assert "Other options:" not in short  # a new option gets its heading in help_sections.SECTIONS
