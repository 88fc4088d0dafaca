"""What ``mecanum-mav setup-fc`` prints (mecanum_mav.app.setupfc): the table of the hardware
page (docs/hardware.md: a row per setting, its value, what the companion needs, ok / HAZARD /
UNKNOWN, why), and each verdict's line as the page quotes it. Against the in-process board of
``fcsim``.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from fcsim import REAL32, Board, run_setup_on, use_clock

from mecanum_mav.config.params import Params
from mecanum_mav.protocol.fcsetup import safe_settings

ROOT = Path(__file__).resolve().parent.parent
SAFE = {**safe_settings(Params(), {"RCMAP_THROTTLE": 3.0}), "RCMAP_THROTTLE": 3.0,
        "RC_PROTOCOLS": 0.0}
"""A board set up as the companion needs, the throttle on channel 3, no receiver."""


def board(monkeypatch: pytest.MonkeyPatch, values: dict[str, float]) -> Board:
    return Board(use_clock(monkeypatch),
                 params={n: (float(v), REAL32) for n, v in values.items()})


def _documented_safe_board_ending() -> list[str]:
    page = (ROOT / "docs" / "hardware.md").read_text()
    intro = page.index("A board that the companion can drive safely ends with:")
    block = re.search(r"```text\n(.*?)```", page[intro:], re.S)
    assert block
    return block.group(1).rstrip("\n").split("\n")


def _table(text: str) -> list[str]:
    return text.split("\n\n")[0].splitlines()[1:]  # (after the line that waits for the board)


def test_a_safe_board_ends_as_the_hardware_page_shows_with_exit_status_0(
        monkeypatch: pytest.MonkeyPatch) -> None:
    status, text = run_setup_on(board(monkeypatch, SAFE), monkeypatch, Params())
    assert status == 0, text
    ending = _documented_safe_board_ending()
    assert text.rstrip("\n").split("\n")[-len(ending):] == ending
    header, *rows = _table(text)
    assert header.split() == ["setting", "value", "needs", "why"]
    assert header.index("value") + len("value") == rows[0].index(" 255  ") + len(" 255")
    assert all(" ok " in row for row in rows)


def test_each_row_shows_the_value_as_the_board_has_it_and_marks_hazards_and_unknowns(
        monkeypatch: pytest.MonkeyPatch) -> None:
    values = {**SAFE, "ARMING_RUDDER": 1.0, "RC1_MIN": 2_000_000.0, "RC_OVERRIDE_TIME": 0.25}
    del values["FS_THR_ENABLE"], values["RC_PROTOCOLS"]  # (not answered)
    status, text = run_setup_on(board(monkeypatch, values), monkeypatch, Params())
    assert status == 1, text
    rows = {row.split()[0]: row.split()[1:5] for row in _table(text)[1:]}
    assert rows["ARMING_RUDDER"][:3] == ["1", "0", "HAZARD"]
    assert rows["RC1_MIN"][:3] == ["2000000", "1000", "HAZARD"]
    assert rows["RC_OVERRIDE_TIME"][:3] == ["0.25", "0.5", "ok"]
    assert rows["FS_THR_ENABLE"][:3] == ["(none)", "1", "UNKNOWN"]
    assert rows["RC_PROTOCOLS"][:3] == ["(none)", "any", "ok"]  # only read for the table
    assert text.endswith("\n\n2 hazard(s): the rover may drive on after the companion stops, "
                         "or ignore it; fix with --apply\n")


def test_settings_not_answered_are_named_with_the_question_to_ask_exit_status_1(
        monkeypatch: pytest.MonkeyPatch) -> None:
    values = dict(SAFE)
    del values["FS_THR_ENABLE"], values["ARMING_RUDDER"], values["RC_PROTOCOLS"]
    status, text = run_setup_on(board(monkeypatch, values), monkeypatch, Params())
    assert status == 1, text
    assert text.endswith("\n\nnot confirmed: no answer for ARMING_RUDDER, FS_THR_ENABLE (is "
                         "this ArduPilot Rover, and the link's FC_SYSID right?)\n")


def test_a_new_throttle_channel_ends_with_the_reboot_pending_line_of_the_hardware_page(
        monkeypatch: pytest.MonkeyPatch) -> None:
    status, text = run_setup_on(board(monkeypatch, {**SAFE, "RCMAP_THROTTLE": 7.0}),
                                monkeypatch, Params(), apply=True)
    assert status == 3, text
    page = " ".join((ROOT / "docs" / "hardware.md").read_text().split())
    last = text.rstrip("\n").split("\n")[-1]
    assert last == ("REBOOT PENDING: the flight controller reads RCMAP_THROTTLE only at boot: "
                    "run again with --reboot (or power-cycle it) before driving")
    assert f"`{last}`" in page
