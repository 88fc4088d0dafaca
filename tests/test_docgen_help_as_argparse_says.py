"""The generated command-line reference (app/docgen.py) gives each option's description as
``--help`` shows it (argparse fills in ``%(default)s``, ``%(choices)s``, ``%(type)s`` and
``%(prog)s``), and keeps Markdown from reading anything in it as markup."""

from __future__ import annotations

import argparse

import pytest

from mecanum_mav.app import docgen


def toy_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="toy")
    sub = parser.add_subparsers(dest="command")
    go = sub.add_parser("go", help="go somewhere", description="Go.")
    go.add_argument("--speed", type=float, default=0.5,
                    help="a %(type)s in m/s (default %(default)s) for %(prog)s")
    go.add_argument("--mode", choices=["walk", "run"], default="walk",
                    help="one of %(choices)s")
    go.add_argument("--mark", help=r"a|b *c* <d> [e] f\g")
    return parser


@pytest.fixture
def rows(monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    """The description cell of each option row of the page, by the option's name."""
    monkeypatch.setattr(docgen, "build_parser", toy_parser)
    found = {}
    for line in docgen.cli_page().splitlines():
        if line.startswith("| `--"):
            name = line.split("`")[1].split()[0]
            found[name] = line.rsplit(" | ", 1)[1].removesuffix(" |")
    return found


def test_each_description_is_the_help_text_argparse_shows(rows: dict[str, str]) -> None:
    shown = " ".join(toy_parser()._subparsers._group_actions[0]  # type: ignore[union-attr]
                     .choices["go"].format_help().split())
    for name in ("--speed", "--mode"):
        assert rows[name] in shown, (name, rows[name])
    assert rows["--speed"] == "a float in m/s (default 0.5) for toy go"
    assert rows["--mode"] == "one of walk, run"


def test_markdown_markup_in_a_description_is_escaped(rows: dict[str, str]) -> None:
    assert rows["--mark"] == r"a\|b \*c\* \<d> \[e\] f\\g"  # (no tag without "<")
