"""CI knows what ran: where the firmware is, .ci/run sets MECANUM_REQUIRE_SITL=1 and a skipped
real-firmware test fails (conftest.py's hooks), whether it is marked ``sitl`` or only skipped
for a reason that names the firmware. Each case is a pytest run of its own (a subprocess)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parent
UNFINDABLE = {"MECANUM_SITL": "/nonexistent/ardurover"}  # find_sitl: "not an executable file"
REQUIRED = {"MECANUM_REQUIRE_SITL": "1"}


def pytest_run(target: Path, cwd: Path, env: dict[str, str],
               *options: str) -> subprocess.CompletedProcess[str]:
    """``python -m pytest -q -rA OPTIONS TARGET`` in ``cwd``, with ``env`` instead of this
    run's MECANUM_SITL and MECANUM_REQUIRE_SITL."""
    environment = {k: v for k, v in os.environ.items()
                   if k not in ("MECANUM_SITL", "MECANUM_REQUIRE_SITL")}
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-rA", "-p", "no:cacheprovider",
                           *options, str(target)], cwd=cwd, env={**environment, **env},
                          capture_output=True, text=True, timeout=120, check=False)


def test_a_real_firmware_test_skipped_where_ci_found_the_firmware_fails():
    repo = TESTS.parent
    required = pytest_run(TESTS / "test_sitl_receiver.py", repo, {**UNFINDABLE, **REQUIRED})
    assert required.returncode == 1, required.stdout
    assert "a real-firmware test was skipped: Skipped: $MECANUM_SITL=" in required.stdout
    assert "1 error" in required.stdout, required.stdout
    optional = pytest_run(TESTS / "test_sitl_receiver.py", repo, UNFINDABLE)
    assert optional.returncode == 0 and "1 skipped" in optional.stdout, optional.stdout


CASES = {  # test file -> (its source, its outcome with MECANUM_REQUIRE_SITL=1)
    "test_marked.py": ("@pytest.mark.sitl\ndef test_x():\n    pytest.skip('no board today')\n",
                       "FAILED"),
    "test_unmarked.py": ("def test_x():\n    pytest.skip('ArduPilot SITL not found')\n",
                         "FAILED"),
    "test_skipif.py": ("@pytest.mark.skipif(True, reason='no ardurover here')\n"
                       "def test_x():\n    pass\n", "ERROR"),
    "test_module.py": ("pytest.skip('ArduPilot SITL not found', allow_module_level=True)\n\n"
                       "def test_x():\n    pass\n", "ERROR"),
    "test_other.py": ("def test_x():\n    pytest.skip('MAVProxy is not installed')\n",
                      "SKIPPED"),
}


def outcomes(run: subprocess.CompletedProcess[str]) -> dict[str, str]:
    """Test file -> FAILED, ERROR or SKIPPED, from the short summary (``-rA``)."""
    found = {}
    for line in run.stdout.splitlines():
        word, _, rest = line.partition(" ")
        if word in ("FAILED", "ERROR", "SKIPPED"):
            name = rest.split()[1] if word == "SKIPPED" else rest.split()[0]
            found[name.split("::")[0].split(":")[0]] = word
    return found


def test_a_skip_that_names_the_firmware_fails_marked_or_not(tmp_path):
    """A test marked ``sitl`` fails whatever its skip says; an unmarked test, or a whole
    module, fails when its skip reason names the firmware (SITL, ardurover, ArduPilot,
    firmware); other skips stay skips."""
    for shared in ("conftest.py", "support.py"):  # (conftest imports support)
        (tmp_path / shared).write_text((TESTS / shared).read_text())
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers =\n    sitl: real firmware\n")
    for name, (source, _) in CASES.items():
        (tmp_path / name).write_text("import pytest\n\n" + source)
    required = pytest_run(tmp_path, tmp_path, REQUIRED, "--continue-on-collection-errors")
    assert outcomes(required) == {name: outcome for name, (_, outcome) in CASES.items()}, (
        required.stdout)
    assert required.stdout.count("a real-firmware test was skipped") >= 4, required.stdout
    optional = pytest_run(tmp_path, tmp_path, {})
    assert optional.returncode == 0, optional.stdout
    assert set(outcomes(optional).values()) == {"SKIPPED"}, optional.stdout
