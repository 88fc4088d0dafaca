"""The generator's own command line, ``python -m mecanum_mav.app.docgen``, as
docs/development.md describes it: it rewrites the generated pages (only those that changed,
saying which), ``--check`` writes nothing and lists the stale ones, ``--docs DIR`` picks the
folder (the repository's docs/ without it), and the pages are UTF-8 files as MkDocs reads them."""

from __future__ import annotations

import argparse
import locale
from collections.abc import Iterator
from pathlib import Path

import pytest

from mecanum_mav.app import docgen

PAGES = [Path("reference") / "parameters.md", Path("reference") / "cli.md"]


def test_writing_creates_the_folder_and_says_each_page_written_and_only_changed_ones(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    docs = tmp_path / "site" / "docs"  # (not there yet)
    assert docgen.main(["--docs", str(docs)]) == 0
    assert capsys.readouterr().out.splitlines() == [f"wrote {docs / p}" for p in PAGES]
    assert docgen.main(["--docs", str(docs)]) == 0  # nothing changed: nothing written
    assert capsys.readouterr().out == ""
    cli = docs / "reference" / "cli.md"
    cli.write_text(cli.read_text(encoding="utf-8") + "edited by hand\n", encoding="utf-8")
    assert docgen.main(["--docs", str(docs)]) == 0
    assert capsys.readouterr().out.splitlines() == [f"wrote {cli}"]
    assert docgen.write_pages(docs) == []


def test_without_docs_it_writes_and_checks_the_repository_docs_folder(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(docgen, "DOCS", tmp_path)  # (the repository's docs/, moved aside)
    assert docgen.main(["--check"]) == 1
    assert docgen.main([]) == 0
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*.md")) == sorted(PAGES)
    assert docgen.main(["--check"]) == 0


def test_help_names_the_command_to_run_and_what_each_option_does(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("COLUMNS", "200")
    with pytest.raises(SystemExit) as exited:
        docgen.main(["--help"])
    assert exited.value.code == 0
    shown = " ".join(capsys.readouterr().out.split())
    assert shown.startswith(f"usage: {docgen.REGENERATE} [-h] [--check] [--docs DIR] ")
    assert " Generate the reference pages of docs/. " in shown
    assert "--check write nothing; exit 1 listing the pages that are stale" in shown
    assert "--docs DIR the documentation folder (default: the repository's docs/)" in shown


def degrees_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="toy")
    sub = parser.add_subparsers(dest="command")
    turn = sub.add_parser("turn", help="turn in place", description="Turn in place.")
    turn.add_argument("--rate", type=float, default=30.0, help="turn rate in °/s")
    return parser


@pytest.fixture
def ascii_locale() -> Iterator[None]:
    """A machine whose locale encoding is ASCII (the C locale)."""
    before = locale.setlocale(locale.LC_CTYPE)
    locale.setlocale(locale.LC_CTYPE, "C")
    try:
        yield
    finally:
        locale.setlocale(locale.LC_CTYPE, before)


def test_pages_are_written_and_checked_as_utf8_whatever_the_locale(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ascii_locale: None) -> None:
    """MkDocs reads pages as UTF-8; a help text with a degree sign must not depend on the
    machine that generates the pages."""
    monkeypatch.setattr(docgen, "build_parser", degrees_parser)
    assert docgen.main(["--docs", str(tmp_path)]) == 0
    assert "turn rate in °/s".encode() in (tmp_path / "reference" / "cli.md").read_bytes()
    assert docgen.main(["--check", "--docs", str(tmp_path)]) == 0
