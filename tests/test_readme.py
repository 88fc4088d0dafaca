"""The README stays true: its parameter table and its test command."""

from __future__ import annotations

from pathlib import Path

from mecanum_mav.config.params import markdown_table

ROOT = Path(__file__).resolve().parent.parent


def test_readme_parameter_table_is_the_schema():
    text = (ROOT / "README.md").read_text()
    table = text.split("<!-- params:begin -->\n", 1)[1].split("<!-- params:end -->", 1)[0]
    assert table.strip() == markdown_table().strip(), (
        "README parameter table is stale: replace it with `mecanum-mav params --markdown`")


def test_ci_runs_exactly_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    command = "python -m pytest -q"
    assert f"pip install -e '.[test]' && {command}" in readme
    assert f"\n{command}\n" in ci
