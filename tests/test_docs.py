"""The documentation site stays true: generated pages are current, the README stays short and
its links lead somewhere, every page is in the site's navigation, the example mission is what
the README says it is."""

from __future__ import annotations

import argparse
import itertools
import math
import re
from pathlib import Path

import pytest

from mecanum_mav.app import docgen
from mecanum_mav.app.cli import build_parser
from mecanum_mav.io.missionfile import load_mission
from mecanum_mav.mecanum.geo import GlobalOrigin

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
README_LIMIT_BYTES = 20 * 1024
FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.MULTILINE | re.DOTALL)
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")


# --------------------------------------------------------------------------- generated pages


def test_the_committed_generated_pages_are_what_the_generator_makes_now():
    stale = docgen.stale_pages()
    assert not stale, (
        "stale generated documentation: " + ", ".join(str(p.relative_to(ROOT)) for p in stale)
        + f"; run `{docgen.REGENERATE}` and commit the pages")


def test_check_mode_lists_a_stale_page_and_exits_1_and_writing_makes_it_current(
        tmp_path, capsys):
    assert docgen.main(["--check", "--docs", str(tmp_path)]) == 1  # nothing there yet
    assert docgen.main(["--docs", str(tmp_path)]) == 0
    assert docgen.main(["--check", "--docs", str(tmp_path)]) == 0
    page = tmp_path / "reference" / "cli.md"
    page.write_text(page.read_text().replace("--fc-signing-key", "--fc-key"))
    capsys.readouterr()
    assert docgen.main(["--check", "--docs", str(tmp_path)]) == 1
    assert str(page) in capsys.readouterr().err
    assert docgen.stale_pages(tmp_path) == [page]


def _option_actions(parser: argparse.ArgumentParser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from ((name, a) for a in sub._actions)
        else:
            yield "", action


def test_the_command_line_page_has_every_sub_command_and_every_option_with_its_help():
    page = docgen.cli_page()
    sections = re.split(r"^## ", page, flags=re.MULTILINE)
    by_title = {s.split("\n", 1)[0]: s for s in sections[1:]}
    for command, action in _option_actions(build_parser()):
        title = f"mecanum-mav {command}".strip()
        assert title in by_title, f"no section for {title}"
        section = by_title[title]
        for option in action.option_strings:
            assert re.search(rf"`[^`]*(?<![\w-]){re.escape(option)}(?![\w-])", section), (
                f"{title}: {option} missing")
        if not action.option_strings:
            assert f"`{action.metavar}`" in section, f"{title}: {action.metavar} missing"
        help_text = " ".join((action.help or "").split())
        if help_text and "%(" not in help_text:
            words = docgen._cell(help_text)
            assert words in section, f"{title}: help of {action.dest} missing"


def test_the_command_line_page_shows_each_usage_with_required_options_unbracketed():
    page = docgen.cli_page()
    assert ("mecanum-mav run [-h] [--params FILE] [--set NAME=VALUE] [--log-level LEVEL] "
            "[--gcs URL] --fc URL") in page
    assert "[-x X]" in page
    assert re.search(r"\[--png OUT\]\s+FILE\.tlog", page)  # (the positional last)
    assert all(len(line) <= docgen.USAGE_WIDTH for line in page.split("```text")[1].split("```")[0]
               .splitlines())


# --------------------------------------------------------------------------- README and site


def test_the_readme_is_at_most_20_kib():
    size = len((ROOT / "README.md").read_bytes())
    assert size <= README_LIMIT_BYTES, (
        f"README.md is {size} bytes; move reference material to docs/ (limit "
        f"{README_LIMIT_BYTES})")


def test_every_relative_link_in_the_readme_points_at_an_existing_file():
    text = FENCE.sub("", (ROOT / "README.md").read_text())
    targets = [t for t in LINK.findall(text) if not re.match(r"[a-z][a-z0-9+.-]*:", t)]
    files = [t.partition("#")[0] for t in targets if t.partition("#")[0]]
    assert files, "the README links to no documentation page"
    missing = [f for f in files if not (ROOT / f).is_file()]
    assert not missing, f"README links to missing files: {missing}"


def _nav_pages() -> set[str]:
    config = (ROOT / "mkdocs.yml").read_text()
    nav = config.split("\nnav:\n", 1)[1]
    return set(re.findall(r":\s*([\w./-]+\.md)\s*$", nav, re.MULTILINE)) | set(
        re.findall(r"^\s*-\s*([\w./-]+\.md)\s*$", nav, re.MULTILINE))


def test_every_documentation_page_is_in_the_site_navigation_and_every_nav_entry_exists():
    pages = {str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md")}
    nav = _nav_pages()
    assert pages - nav == set(), f"pages missing from mkdocs.yml nav: {sorted(pages - nav)}"
    assert nav - pages == set(), f"nav entries with no page: {sorted(nav - pages)}"


def test_the_readme_links_every_documentation_page():
    text = (ROOT / "README.md").read_text()
    linked = {t.partition("#")[0] for t in LINK.findall(text)}
    pages = {f"docs/{p.relative_to(DOCS)}" for p in DOCS.rglob("*.md")}
    assert pages - linked == set(), f"README does not link {sorted(pages - linked)}"


# --------------------------------------------------------------------------- example mission


ORIGIN = GlobalOrigin.from_degrees(47.3977, 8.5456)


def test_the_example_mission_is_a_2_m_square_about_the_readme_origin():
    items = load_mission(DOCS / "examples" / "square.waypoints")
    assert [it.command for it in items] == [16] * 5  # NAV_WAYPOINT; item 0 is home
    assert {it.frame for it in items} == {3}  # MAV_FRAME_GLOBAL_RELATIVE_ALT
    points = [ORIGIN.to_local(it.x, it.y) for it in items]
    expected = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0), (0.0, 0.0)]
    for (north, east), (want_n, want_e) in zip(points, expected, strict=True):
        assert math.hypot(north - want_n, east - want_e) < 0.02, points
    for a, b in itertools.pairwise(points):  # the four sides
        assert math.dist(a, b) == pytest.approx(2.0, abs=0.02)
