"""The fleet (mecanum_mav.app.fleet) when something goes wrong, and its picture: the fleet
drive fails naming the rover at fault (its docstring's Raises), a fleet that cannot start
leaves nothing running, and each rover's panel shows its own path.

The drive's faults are played by scripted rovers (no processes): what each answers is the
only thing that matters to the drive's checks. tests/test_fleet.py drives real ones.
"""

from __future__ import annotations

import io
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from support import child_processes

from mecanum_mav.app.fleet import Fleet, FleetDrive, drive_fleet, plot_fleet
from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.modes import Mode

_MESSAGES = mavlink.MAVLink(io.BytesIO(), srcSystem=1, srcComponent=1)
"""Builds the messages the scripted rovers answer with."""


class ScriptedRover:
    """A ground station's view of one rover that answers the drive's requests at once, or
    fails at ``fault``: ``silent`` (no HEARTBEAT), ``arming``, ``position`` (no
    LOCAL_POSITION_NED), ``mission`` (the upload refused), ``auto`` (AUTO refused), ``slow``
    (never reaches the mission's last item)."""

    def __init__(self, sysid: int, fault: str | None = None) -> None:
        self.target = (sysid, 1)
        self.fault = fault
        self.mav = mavlink.MAVLink(io.BytesIO(), srcSystem=255, srcComponent=190)
        self.messages: list[Any] = []
        self.arrived_s: list[float] = []
        self._last_item: int | None = None
        self._auto = False

    def wait(self, kind: str, predicate: Any = None, timeout_s: float = 3.0,
             since: int | None = None) -> Any | None:
        if kind == "HEARTBEAT" and self.fault != "silent":
            return _MESSAGES.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                              mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3)
        if kind == "LOCAL_POSITION_NED" and self.fault != "position":
            return _MESSAGES.local_position_ned_encode(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        return None

    def arm(self, timeout_s: float = 5.0) -> None:
        if self.fault == "arming":
            raise RuntimeError("the vehicle never accepted arming")

    def sticks(self, x: int = 0, y: int = 0, r: int = 0, z: int = 500,
               target: int | None = None) -> int:
        return len(self.messages)

    def upload(self, items: list[Any]) -> Any:
        self._last_item = len(items) - 1
        refused = self.fault == "mission"
        return _MESSAGES.mission_ack_encode(
            255, 190, mavlink.MAV_MISSION_NO_SPACE if refused else mavlink.MAV_MISSION_ACCEPTED)

    def set_mode(self, mode: Mode, timeout_s: float = 1.0) -> int:
        if mode != Mode.AUTO or self.fault == "auto":
            return int(mavlink.MAV_RESULT_DENIED)
        self._auto = True
        return int(mavlink.MAV_RESULT_ACCEPTED)

    def pump(self, timeout_s: float) -> list[Any]:
        threading.Event().wait(timeout_s)  # the time a real link's wait would take
        if self._auto and self.fault != "slow" and self._last_item is not None:
            self._auto = False
            self.messages.append(_MESSAGES.mission_item_reached_encode(self._last_item))
            self.arrived_s.append(0.0)
            return self.messages[-1:]
        return []

    def mark(self) -> int:
        return len(self.messages)

    def received(self, kind: str, since: int = 0) -> list[Any]:
        return [m for m in self.messages[since:] if m.get_type() == kind]


@pytest.mark.parametrize(("fault", "sysid", "error"), [
    ("silent", 2, "rover 2 never showed up"),
    ("arming", 3, "rover 3 refused arming"),
    ("position", 1, "no position from rover 1"),
    ("mission", 2, f"rover 2 refused the mission ({mavlink.MAV_MISSION_NO_SPACE})"),
    ("auto", 1, "rover 1 refused AUTO"),
    ("slow", 2, "rovers [2] did not finish the mission in time"),
])
def test_the_fleet_drive_fails_naming_the_rover_at_fault(fault: str, sysid: int,
                                                         error: str) -> None:
    stations = {s: ScriptedRover(s, fault if s == sysid else None) for s in (1, 2, 3)}
    with pytest.raises(RuntimeError) as raised:
        drive_fleet(stations, stick_s=0.0, timeout_s=0.1)  # type: ignore[arg-type]
    assert str(raised.value) == error


def test_without_mavproxy_a_fleet_says_how_to_install_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "bin").mkdir()
    monkeypatch.setattr(sys, "executable", str(tmp_path / "bin" / "python"))
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    with pytest.raises(FileNotFoundError, match=r"pip install MAVProxy"):
        Fleet(1, tmp_path)


def test_a_fleet_that_fails_to_start_stops_what_it_had_started(tmp_path: Path) -> None:
    # The router starts first; the first rover's log cannot be opened (a folder is in the
    # way): the error comes out and the router is stopped, nothing is left running.
    (tmp_path / "instance0.log").mkdir()
    before = child_processes()
    try:
        with pytest.raises(IsADirectoryError):
            Fleet(1, tmp_path)
    except FileNotFoundError:
        pytest.skip("MAVProxy is not installed (pip install '.[test]')")
    assert (tmp_path / "router.log").exists()  # it had started
    assert child_processes() == before


# --------------------------------------------------------------------------- the picture

_RED, _ORANGE, _GREEN = (0.839, 0.153, 0.157), (1.0, 0.498, 0.055), (0.173, 0.627, 0.173)
"""tab:red, tab:orange, tab:green: the colours of the first three phases."""


def _columns_of(image: np.ndarray, rgb: tuple[float, float, float]) -> np.ndarray:
    """The x of every pixel of colour ``rgb``."""
    close = np.all(np.abs(image[:, :, :3] - np.asarray(rgb)) < 0.02, axis=2)
    return np.nonzero(close)[1]


def test_each_rovers_panel_draws_a_phases_path_only_where_that_rover_moved(
        tmp_path: Path) -> None:
    # Rover 1 drives north in "one", rover 2 east in "two"; in "three" nobody moves, and
    # "four" has no positions at all. Panels: rover 1 left, rover 2 right.
    matplotlib_image = pytest.importorskip("matplotlib.image")
    drive = FleetDrive(
        paths={1: [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (1.0, 1.0, 0.0), (2.5, 1.0, 0.0)],
               2: [(0.0, 0.0, 0.0), (1.5, 0.0, 0.5), (2.0, 0.0, 1.0), (2.5, 0.0, 1.0)]},
        moved={"one": {1: (1.0, 0.0), 2: (0.0, 0.0)}, "two": {1: (0.0, 0.0), 2: (0.0, 1.0)},
               "three": {1: (0.0, 0.0), 2: (0.0, 0.0)}, "four": {1: (0.0, 0.0), 2: (0.0, 0.0)}},
        phases=[("one", 0.0, 1.0), ("two", 1.0, 2.0), ("three", 2.0, 3.0), ("four", 5.0, 6.0)],
        planned={1: [(0.0, 0.0), (1.0, 0.0)]})
    png = plot_fleet(drive, tmp_path / "fleet.png")
    image = matplotlib_image.imread(png)
    middle = image.shape[1] / 2
    red, orange = _columns_of(image, _RED), _columns_of(image, _ORANGE)
    assert red.size and (red < middle).all()
    assert orange.size and (orange > middle).all()
    assert _columns_of(image, _GREEN).size == 0
