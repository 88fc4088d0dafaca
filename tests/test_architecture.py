"""The layers import downwards only (docs/architecture.md), and the core never touches sockets."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "mecanum_mav"

LAYERS = {"mecanum": 1, "config": 2, "protocol": 3, "control": 4, "io": 4, "runtime": 5, "sim": 6,
          "app": 7}
"""Rank of each subpackage: a module may import its own layer and lower ones. control and io
share a rank and never import each other."""

FACADES = {"mixing", "kinematics", "geometry", "odometry", "params", "pwm", "cli", "__main__"}
"""The documented import paths at the top of the package: they re-export, nothing imports them."""

IO_MODULES = {"socket", "selectors", "select", "serial", "threading", "subprocess", "signal",
              "os", "pathlib", "io", "tempfile", "shutil", "time"}
"""Standard-library modules that reach the world; the pure layers never import them."""

PURE_LAYERS = ("mecanum", "config", "protocol", "control")

ROOT_RANK = 1
"""The package's ``__init__`` (version, wheel names) may import the conventions of the
mathematics layer (``mecanum.wheels``), which imports nothing from the package."""

ALLOWED = {"protocol/dialect.py": {"os"}}
"""dialect.py sets ``MAVLINK20`` in ``os.environ`` before pymavlink is imported; no I/O."""


def modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def layer_of(path: Path) -> str | None:
    parts = path.relative_to(PACKAGE).parts
    return parts[0] if len(parts) > 1 else None


def package_of(path: Path) -> list[str]:
    """The dotted package ``path`` belongs to, as parts (``mecanum/geometry.py`` ->
    ``["mecanum_mav", "mecanum"]``; a package's ``__init__.py`` is its own package)."""
    parts = ["mecanum_mav", *path.relative_to(PACKAGE).with_suffix("").parts]
    return parts[:-1]


def absolute(path: Path, node: ast.ImportFrom) -> list[str]:
    """The absolute module names a ``from`` import in ``path`` names: a relative one (``from
    ..io.links import Link``, level 2) resolved against the importing module's package, as
    Python resolves it. ``from .. import io`` names the package and, as it may, ``io`` in it."""
    if node.level == 0:
        return [node.module] if node.module else []
    package = package_of(path)
    assert node.level <= len(package), \
        f"{path.name}: relative import beyond the top-level package (level {node.level})"
    base = ".".join(package[:len(package) - node.level + 1])
    if node.module:
        return [f"{base}.{node.module}"]
    return [base] + [f"{base}.{alias.name}" for alias in node.names if alias.name != "*"]


def imports(path: Path) -> list[str]:
    """Every module name ``path`` imports, absolute (relative imports resolved)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            found += absolute(path, node)
    return found


def package_target(name: str) -> str | None:
    """The subpackage (or facade module) a ``mecanum_mav...`` import lands in."""
    parts = name.split(".")
    if parts[0] != "mecanum_mav" or len(parts) == 1:
        return None
    return parts[1]


@pytest.mark.parametrize("path", modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_a_module_imports_only_its_own_layer_and_lower_ones(path):
    layer = layer_of(path)
    rank = LAYERS.get(layer, 0) if layer else (7 if path.stem in FACADES else ROOT_RANK)
    for name in imports(path):
        target = package_target(name)
        if target is None:
            continue
        assert target not in FACADES, f"{path.name} imports the facade {name}; import the layer"
        target_rank = LAYERS.get(target, 0)
        assert target_rank <= rank, f"{path.name} ({layer}) imports {name} (a higher layer)"
        if target_rank == rank and layer in ("control", "io"):
            assert target == layer, f"{path.name} ({layer}) imports {name}: control and io " \
                                    "never import each other"


@pytest.mark.parametrize("path", [p for p in modules() if layer_of(p) in PURE_LAYERS],
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_the_pure_layers_never_import_sockets_files_threads_or_the_clock(path):
    allowed = ALLOWED.get(str(path.relative_to(PACKAGE)), set())
    reached = sorted({n.split(".")[0] for n in imports(path)} & IO_MODULES - allowed)
    assert not reached, f"{path.relative_to(PACKAGE)} imports {reached}"


@pytest.mark.parametrize("path", [p for p in modules() if layer_of(p) in PURE_LAYERS],
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_the_pure_layers_never_open_a_file(path):
    tree = ast.parse(path.read_text())
    calls = [n.func.id for n in ast.walk(tree)
             if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)]
    assert "open" not in calls and "print" not in calls


def test_the_layer_table_covers_every_subpackage():
    subpackages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    assert subpackages == set(LAYERS)


@pytest.mark.parametrize(("module", "statement", "expected"), [
    ("mecanum/geometry.py", "from ..io.links import Link", ["mecanum_mav.io.links"]),
    ("mecanum/geometry.py", "from .wheels import WHEELS", ["mecanum_mav.mecanum.wheels"]),
    ("mecanum/geometry.py", "from .. import io", ["mecanum_mav", "mecanum_mav.io"]),
    ("io/__init__.py", "from ..app import cli", ["mecanum_mav.app"]),
    ("__init__.py", "from .mecanum.wheels import WHEELS", ["mecanum_mav.mecanum.wheels"]),
    ("app/cli.py", "from pymavlink import mavutil", ["pymavlink"]),
])
def test_relative_imports_are_judged_as_the_absolute_module_they_name(module, statement,
                                                                       expected):
    node = ast.parse(statement).body[0]
    assert isinstance(node, ast.ImportFrom)
    assert absolute(PACKAGE / module, node) == expected


MAX_MODULE_LINES = 600
"""The longest a module of the package may grow (issue 24): one concern each, readable whole."""


@pytest.mark.parametrize("path", modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_module_in_the_package_is_over_600_lines(path):
    lines = len(path.read_text().splitlines())
    assert lines <= MAX_MODULE_LINES, (
        f"{path.relative_to(PACKAGE)} has {lines} lines (at most {MAX_MODULE_LINES}): split it "
        f"by concern, re-exporting what moved")
