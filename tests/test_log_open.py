"""What ``log --view`` spends before its viewer is served: the read tlog is left out of the
garbage collector's later passes, and nothing of the PNG's is imported."""

from __future__ import annotations

import gc
import io
import os
import subprocess
import sys

import pytest

from mecanum_mav.app.logview import run_log
from mecanum_mav.sim.sampledrive import sample_drive


@pytest.fixture(scope="module")
def tlog(tmp_path_factory: pytest.TempPathFactory):
    path = tmp_path_factory.mktemp("drive") / "drive.tlog"
    with path.open("wb") as f:
        sample_drive(f)
    return path


def test_the_log_command_leaves_what_it_read_out_of_the_collectors_later_passes(
        tlog, tmp_path, monkeypatch):
    frozen: list[int] = []
    monkeypatch.setattr(gc, "freeze", lambda: frozen.append(gc.get_count()[0]))
    assert gc.isenabled()
    out = io.StringIO()
    assert run_log(tlog, None, out, io.StringIO(), rerun=tmp_path / "view.rrd") == 0
    assert len(frozen) == 1  # once: after the read, the messages made with the collector paused
    assert gc.isenabled()
    assert "wrote" in out.getvalue()


def test_a_view_of_a_log_imports_no_plotting(tlog, tmp_path):
    probe = (
        "import sys, io\n"
        "from pathlib import Path\n"
        "from mecanum_mav.app.logview import run_log\n"
        f"run_log(Path({str(tlog)!r}), None, io.StringIO(), io.StringIO(),"
        f" rerun=Path({str(tmp_path / 'v.rrd')!r}))\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'matplotlib'"
        " or m == 'mecanum_mav.app.plots'))\n")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=120, env={**os.environ, "DISPLAY": ""}, check=True)
    assert done.stdout.strip().splitlines()[-1] == "[]"
