"""The cli's promise (``mecanum_mav.app.cli``): ``run`` and ``sim`` exit 0 when stopped by
Ctrl-C or SIGTERM once running, and the line ``mecanum-mav: rover system ...`` is how a
person or a script knows it runs. A signal that comes the moment that line is read (a
supervisor, a test, a user quick on Ctrl-C) stops the rover in order, never as a start-up
cut short (status 130). In process, the signal sent at the first thing after the line."""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from pathlib import Path

import pytest

from mecanum_mav.app import progress
from mecanum_mav.app.foreground import serve
from mecanum_mav.config.params import Params
from mecanum_mav.sim.process import free_port


@pytest.fixture(autouse=True)
def _handlers_back(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """serve() leaves SIGINT and SIGTERM ignored once one came (the process is on its way
    out); this test's process is not: the handlers come back after."""
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))  # the claim of this test alone
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    yield
    for sig, handler in saved.items():
        signal.signal(sig, handler)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_right_after_the_running_line_is_a_stop_exit_0_not_an_aborted_start_up(
        sig: signal.Signals, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    def signalled_at_once(self: progress.Progress) -> None:
        os.kill(os.getpid(), sig)

    monkeypatch.setattr(progress.Progress, "started", signalled_at_once)
    code = serve(Params(), f"udpout:127.0.0.1:{free_port()}", "sim", None, None)
    out, err = capsys.readouterr()
    assert "mecanum-mav: rover system 1 on" in out
    assert code == 0, err
