"""``mecanum-mav setup-fc``'s verdict on a board (app/setupfc.py), against the simulated
ArduPilot board on a real socket (127.0.0.1, port 0): safe is exit 0; a hazard is exit 1 with
its row marked HAZARD; a setting the board never answers is exit 1, "not confirmed"."""

from __future__ import annotations

import functools
import io

import pytest

from mecanum_mav.app import setupfc
from mecanum_mav.config.params import Params
from mecanum_mav.protocol.paramread import ParamReader
from mecanum_mav.sim.simfc import SimFlightController


def setup_fc(monkeypatch, change: dict[str, float | None]) -> tuple[int, str]:
    """setup-fc (no --apply) against a simulated board whose parameters get ``change``
    (None: the board does not answer that name); (exit status, what it printed)."""
    # a board that never answers a name: give up after 1.5 s, not ParamReader's 10 s
    monkeypatch.setattr(setupfc, "ParamReader", functools.partial(ParamReader, deadline_s=1.5))
    with SimFlightController("udpin:127.0.0.1:0", Params()) as sim:
        for name, value in change.items():
            if value is None:
                del sim.board.parameters[name]
            else:
                sim.board.parameters[name] = value
        sim.start()
        out = io.StringIO()
        status = setupfc.run_setup(f"udpout:127.0.0.1:{sim.local_port}", Params(), apply=False,
                                   out=out)
    return status, out.getvalue()


def rows(text: str, name: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith(name + " ")]


def test_a_board_set_up_safely_is_called_safe_with_exit_status_0(monkeypatch):
    status, text = setup_fc(monkeypatch, {})
    assert status == 0, text
    assert "the flight controller is set up safely for the companion" in text
    assert "HAZARD" not in text and "UNKNOWN" not in text


@pytest.mark.parametrize(("name", "value"), [("ARMING_RUDDER", 1), ("SERVO1_FUNCTION", 51),
                                             ("RC_OVERRIDE_TIME", 3.0)])
def test_a_hazard_is_marked_in_its_row_and_gives_exit_status_1(monkeypatch, name, value):
    status, text = setup_fc(monkeypatch, {name: value})
    assert status == 1, text
    assert "HAZARD" in rows(text, name)[0]
    assert "1 hazard(s)" in text and "set up safely" not in text


def test_a_setting_the_board_never_answers_is_not_confirmed_with_exit_status_1(monkeypatch):
    status, text = setup_fc(monkeypatch, {"FS_THR_ENABLE": None})
    assert status == 1, text
    assert "UNKNOWN" in rows(text, "FS_THR_ENABLE")[0]
    assert "not confirmed: no answer for FS_THR_ENABLE" in text
    assert "set up safely" not in text
