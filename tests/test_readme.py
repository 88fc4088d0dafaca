"""The README and docs/ stay true: the parameter table, the test command, links and paths."""

from __future__ import annotations

import importlib
import importlib.util
import re
from pathlib import Path
from types import ModuleType

from mecanum_mav.config.params import SCHEMA, markdown_table
from mecanum_mav.config.rules import RULES

ROOT = Path(__file__).resolve().parent.parent


def test_the_parameter_reference_table_is_the_schema():
    """The table between the markers of docs/reference/parameters.md (the README links it)."""
    text = (ROOT / "docs" / "reference" / "parameters.md").read_text()
    table = text.split("<!-- params:begin -->\n", 1)[1].split("<!-- params:end -->", 1)[0]
    assert table.strip() == markdown_table().strip(), (
        "parameter reference table is stale: run `python -m mecanum_mav.app.docgen`")
    names = [row.split("`")[1] for row in table.splitlines() if row.startswith("| `")]
    assert names == [spec.name for spec in SCHEMA]
    assert "docs/reference/parameters.md" in (ROOT / "README.md").read_text()


def fresh_module(name: str) -> ModuleType:
    """Module ``name`` executed anew (its import-time code run now), apart from the one
    imported."""
    spec = importlib.util.find_spec(name)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_schema_its_module_builds_at_import_is_the_reference_table():
    """The schema is built when its module is imported (each wheel's entries by a function,
    every entry checked then): built again, as a fresh module, it is the table users read.
    (Code that runs at import is otherwise invisible to mutmut: its workers import the
    package before a test starts.)"""
    fresh = fresh_module("mecanum_mav.config.schema")
    text = (ROOT / "docs" / "reference" / "parameters.md").read_text()
    table = text.split("<!-- params:begin -->\n", 1)[1].split("<!-- params:end -->", 1)[0]
    assert markdown_table(fresh.SCHEMA).strip() == table.strip()
    assert {s.name: s for s in fresh.SCHEMA} == fresh.SPECS
    assert list(fresh.SPECS) == [s.name for s in SCHEMA]
    rules = fresh_module("mecanum_mav.config.rules")  # its rules checked against the schema
    assert [type(rule).__name__ for rule in rules.RULES] == [
        type(rule).__name__ for rule in RULES]
    assert [(s.name, s.kind, s.reboot_required, s.values) for s in fresh.SCHEMA] == [
        (s.name, s.kind, s.reboot_required, s.values) for s in SCHEMA]


def test_ci_runs_exactly_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    command = "python -m pytest -q"
    assert f"pip install -e '.[test]' && {command}" in readme
    assert f"\n{command}\n" in ci


# --------------------------------------------------------------------------- links and paths

DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
PACKAGE = ROOT / "mecanum_mav"  # `control/guided.py` may name a file from the package root
FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.MULTILINE | re.DOTALL)
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
CODE_SPAN = re.compile(r"`([^`\n]+)`")
FILE_SUFFIXES = (".py", ".md", ".parm", ".toml", ".txt", ".waypoints", ".cfg", ".json", ".png")
MODULE = re.compile(r"mecanum_mav(?:\.[A-Za-z_]\w*)+")


def _top_level_names() -> set[str]:
    return {p.name for p in ROOT.iterdir() if p.name not in {".git", ".venv"}}


def _inside_repo(path: Path) -> bool:
    try:
        path.resolve().relative_to(ROOT)
    except ValueError:
        return False
    return True


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*]|<[^>]*>", "", heading).strip().lower()
    return re.sub(r"\s", "-", re.sub(r"[^\w\- ]", "", text))


def _anchors(path: Path) -> set[str]:
    text = FENCE.sub("", path.read_text())
    return {_slug(m) for m in re.findall(r"^#{1,6}\s+(.+?)\s*#*\s*$", text, re.MULTILINE)}


def _looks_like_repo_path(span: str) -> bool:
    """A code span naming a file of the repository: `tools/x.py`, `docs/api.md`, `.ci/run`."""
    if any(c.isspace() for c in span) or ":" in span or span.startswith(("/", "~", "-")):
        return False
    if "/" not in span or "<" in span or "*" in span:
        return False
    first = span.split("/", 1)[0]
    return span.endswith(FILE_SUFFIXES) or first in _top_level_names() or first == ".."


def _path_candidates(raw: str) -> set[str]:
    """Repository paths named in code: whole code spans, and words of spans and code blocks."""
    prose = FENCE.sub("", raw)
    spans = CODE_SPAN.findall(prose)
    words = [w for chunk in [*spans, *(m.group(0) for m in FENCE.finditer(raw))]
             for w in chunk.split()]
    candidates = {*spans, *(w.lstrip("(['\"").rstrip(".,;:)]'\"") for w in words)}
    return {c for c in candidates if _looks_like_repo_path(c)}


def _problems(doc: Path) -> list[str]:
    name = doc.relative_to(ROOT)
    text = FENCE.sub("", doc.read_text())
    problems = []
    for target in LINK.findall(text):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto: ...
            continue
        file_part, _, anchor = target.partition("#")
        linked = (doc.parent / file_part) if file_part else doc
        if not _inside_repo(linked):
            problems.append(f"{name}: link to {target} leaves the repository")
        elif not linked.exists():
            problems.append(f"{name}: link to {target}: no such file")
        elif anchor and linked.suffix == ".md" and anchor not in _anchors(linked):
            problems.append(f"{name}: link to {target}: no such heading")
    for span in _path_candidates(doc.read_text()):
        path = ROOT / span.rstrip("/")
        if not _inside_repo(path):
            problems.append(f"{name}: `{span}` is outside the repository")
        elif not (path.exists() or (PACKAGE / span).exists()):
            problems.append(f"{name}: `{span}`: no such file in the repository")
    return problems


def test_documentation_points_only_at_files_in_the_repository():
    """Every relative link and every `path/like.py` in README.md and docs/**/*.md exists here.

    Links are relative to the Markdown file; code-span paths to the repository root (or to
    the package, `mecanum_mav/`). Nothing may point outside the repository: a reader of the
    repository has nothing else.
    """
    assert (ROOT / "docs" / "architecture.md") in DOCS, "docs/architecture.md is missing"
    problems = [problem for doc in DOCS for problem in _problems(doc)]
    assert not problems, "\n".join(problems)


def test_documented_modules_exist():
    """Every `mecanum_mav.x.y` the documentation names is a module (or a name in one)."""
    missing = []
    for doc in DOCS:
        for span in CODE_SPAN.findall(FENCE.sub("", doc.read_text())):
            match = MODULE.fullmatch(span.removesuffix("()"))
            if match is None:
                continue
            parts = match.group(0).split(".")
            for cut in range(len(parts), 0, -1):
                try:
                    obj = importlib.import_module(".".join(parts[:cut]))
                except ModuleNotFoundError:
                    continue
                try:
                    for attr in parts[cut:]:
                        obj = getattr(obj, attr)
                except AttributeError:
                    missing.append(f"{doc.relative_to(ROOT)}: `{span}`")
                break
    assert not missing, "documented modules or names that do not exist:\n" + "\n".join(missing)
