"""The generated command-line reference (app/docgen.py) spells every usage as argparse's own
``--help`` does, for every form of option the parsers may take (the shipped command line uses
only some of them): optional and repeated arguments, fixed counts, hidden options, options
without help, a parser without a description."""

from __future__ import annotations

import argparse
import re

import pytest

from mecanum_mav.app import docgen


def toy_parser() -> argparse.ArgumentParser:
    """A command line (no description) with one sub-command using each form of argument."""
    parser = argparse.ArgumentParser(prog="toy")
    parser.add_argument("--verbose", action="store_true", help="say more")
    sub = parser.add_subparsers(dest="command")
    files = sub.add_parser("files", help="the files command", description="Handle files.")
    files.add_argument("--must", required=True)  # (no help)
    files.add_argument("--many", nargs="*", help="zero or more")
    files.add_argument("--some", nargs="+", metavar="F", help="one or more")
    files.add_argument("--point", nargs=2, type=float, metavar=("X", "Y"), help="two numbers")
    files.add_argument("--pair", nargs=2, help="two of the same")
    files.add_argument("--once", nargs=1, help="a list of one")
    files.add_argument("--named", metavar=("NAME",), help="a one-name tuple metavar")
    files.add_argument("--chain", nargs="+", metavar=("FIRST", "NEXT"), help="first, then more")
    files.add_argument("--extra", nargs="*", metavar=("A", "B"), help="perhaps A, then Bs")
    files.add_argument("--hidden", help=argparse.SUPPRESS)
    files.add_argument("first", help="one file")
    files.add_argument("maybe", nargs="?", help="perhaps another")
    files.add_argument("rest", nargs=argparse.REMAINDER, help="the rest, as given")
    sub.add_parser("reset", help="start again", description=LONG_DESCRIPTION)
    sub.add_parser("quiet")  # (no one-line help)
    sub.add_parser("blank", help=None)
    return parser


LONG_DESCRIPTION = (  # (--params-reset straddles the wrap column; the address is longer than it)
    "Check each parameter file this command reads as a whole; when one is wrong, start with "
    "--params-reset and a fresh file. See https://example.com/" + "rover/" * 16
    + "reset.html for more.")


@pytest.fixture
def page(monkeypatch: pytest.MonkeyPatch) -> str:
    monkeypatch.setattr(docgen, "build_parser", toy_parser)
    return docgen.cli_page()


def sections(page: str) -> dict[str, str]:
    parts = re.split(r"^## ", page, flags=re.MULTILINE)
    return {p.split("\n", 1)[0]: p for p in parts[1:]}


def usage(section: str) -> str:
    """The usage block of a section, on one line."""
    return " ".join(section.split("```text")[1].split("```")[0].split())


def argparse_usage(parser: argparse.ArgumentParser) -> str:
    return " ".join(parser.format_usage().split()).removeprefix("usage: ")


def test_each_usage_is_spelled_as_argparse_spells_it(page: str):
    parser = toy_parser()
    files = next(a for a in parser._actions
                 if isinstance(a, argparse._SubParsersAction)).choices["files"]
    assert usage(sections(page)["toy files"]) == argparse_usage(files)


def test_an_option_hidden_from_help_is_in_neither_the_usage_nor_the_table(page: str):
    section = sections(page)["toy files"]
    assert "--hidden" not in section and "HIDDEN" not in section


def test_a_required_option_without_help_is_described_as_required(page: str):
    assert "| `--must MUST` |  | required |" in sections(page)["toy files"]


def test_a_command_line_without_a_description_goes_straight_to_its_command_table(
        page: str):
    intro_end = page.index(docgen.CLI_INTRO) + len(docgen.CLI_INTRO)
    assert page[intro_end:].startswith("\n| command | what it does |\n")
    assert "| [`files`](#toy-files) | the files command |" in page


def test_a_sub_command_without_a_one_line_help_has_an_empty_summary(page: str):
    assert "| [`quiet`](#toy-quiet) |  |" in page
    assert "| [`blank`](#toy-blank) |  |" in page


def test_a_description_is_wrapped_between_words_only(page: str):
    """The docstring of docgen._paragraph: wrapped at USAGE_WIDTH between words, never at a
    hyphen inside an option name, and a word longer than the width (an address) kept whole."""
    paragraph = sections(page)["toy reset"].split("\n\n")[1]
    assert paragraph.split() == LONG_DESCRIPTION.split()
    assert all(len(line) <= docgen.USAGE_WIDTH for line in paragraph.splitlines()
               if " " in line)
