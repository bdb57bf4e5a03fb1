"""What the README and the docs tell a user to type is what the commands take: every flag they
name for a `wrapbench` command is one of its flags, every command they show in full parses, and
every benchmark the README names is in `benchmarks/`. A renamed flag breaks this, not a user."""

from __future__ import annotations

import argparse
import functools
import re
import shlex
from pathlib import Path

import pytest

from recommender.cli import build_parser

REPO = Path(__file__).resolve().parents[1]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
COMMANDS = ("simulate", "recommend", "train", "synth", "track", "calibrate")
#: A command and what follows it on its line, up to the end of a code span.
MENTION = re.compile(rf"wrapbench ({'|'.join(COMMANDS)})\b([^`\n]*)")
FLAG = re.compile(r"(?<![\w-])(--[a-z][a-z0-9-]*)")


@functools.cache
def _flags(command: str) -> frozenset[str]:
    """The command's flags (its parser built once, not once a flag mentioned)."""
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return frozenset(flag for action in sub.choices[command]._actions
                     for flag in action.option_strings)


def _shown_in_full(doc: Path) -> list[list[str]]:
    """The commands an indented block shows with every argument given (no `[...]`, `|` or
    shell variable), continuation lines joined and comments dropped."""
    out, lines = [], doc.read_text().splitlines()
    for i, line in enumerate(lines):
        if not re.match(r"^ {4,}wrapbench ", line) or (i and lines[i - 1].rstrip().endswith("\\")):
            continue
        text, k = line.split("#")[0], i
        while text.rstrip().endswith("\\"):
            k += 1
            text = text.rstrip()[:-1] + " " + lines[k].split("#")[0]
        if not re.search(r"[\[|$&]", text):
            out.append(shlex.split(text)[1:])
    return out


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_flag_the_docs_name_for_a_command_is_one_it_takes(doc):
    unknown = [(m.group(1), flag) for m in MENTION.finditer(doc.read_text())
               for flag in FLAG.findall(m.group(2)) if flag not in _flags(m.group(1))]
    assert unknown == []


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_command_the_docs_show_in_full_parses(doc, capsys):
    for argv in _shown_in_full(doc):
        try:
            build_parser().parse_args(argv)
        except SystemExit:
            pytest.fail(f"{doc.name}: wrapbench {shlex.join(argv)}: {capsys.readouterr().err}")


def test_the_readme_shows_its_commands_in_full_and_they_name_real_flags():
    """The checks above would pass on a README that showed nothing."""
    shown = _shown_in_full(REPO / "README.md")
    assert {argv[0] for argv in shown} >= {"simulate", "recommend", "calibrate"}
    assert _flags("simulate") >= {"--wrap", "--report", "--json"}
    assert FLAG.findall("wrapbench simulate X --wrap W --no-such-flag") == ["--wrap",
                                                                             "--no-such-flag"]


def test_every_benchmark_the_readme_names_is_in_benchmarks():
    """(`benchmarks.X`, capitalised, is the README's stand-in for any of them.)"""
    named = set(re.findall(r"python -m benchmarks\.([a-z]\w*)", (REPO / "README.md").read_text()))
    assert named, "the README names no benchmark"
    assert {n for n in named if not (REPO / "benchmarks" / f"{n}.py").is_file()} == set()
