"""What the view's mapping is given (mecanum_mav.app.view: write_rrd, show_log, run_view):
the rover's parameters from ``--params``/``--set`` (its size, its PWM map), the log's own
origin and vehicle, and, live, the rows sent to the viewer every ``FLUSH_PERIOD_S``.
"""

from __future__ import annotations

import io
from pathlib import Path
from types import SimpleNamespace
from typing import Any, ClassVar

import pytest

pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")

from mecanum_mav.app import view
from mecanum_mav.app.rerunview import ViewMapping
from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import parse_tlog, tlog_record
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink

BASE_US = 1_800_000_000_000_000


class SpyMapping(ViewMapping):
    """The view's mapping, remembering what it was made with and each flush."""

    made: ClassVar[list[SpyMapping]] = []

    def __init__(self, params: Params | None = None, origin: GlobalOrigin | None = None) -> None:
        super().__init__(params, origin)
        self.given = (params, origin)
        self.flushes = 0
        SpyMapping.made.append(self)

    def flush(self, recording: Any) -> int:
        self.flushes += 1
        return super().flush(recording)


@pytest.fixture
def spy(monkeypatch: pytest.MonkeyPatch) -> type[SpyMapping]:
    SpyMapping.made = []
    monkeypatch.setattr(view, "ViewMapping", SpyMapping)
    return SpyMapping


def _rover_params() -> Params:
    params = Params()
    params.update({"GEO_HALF_LEN": 0.4, "GEO_HALF_WID": 0.3})
    return params


def _drive() -> bytes:
    """A ground station's stream: the rover (system 1) and another vehicle's position
    (system 2) first."""
    rover = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    other = mavlink.MAVLink(None, srcSystem=2, srcComponent=1)
    msgs = [
        (rover, rover.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                       mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3)),
        (other, other.global_position_int_encode(0, 480_000_000, 110_000_000, 0, 0, 0, 0, 0, 0)),
        (rover, rover.global_position_int_encode(0, 470_000_000, 80_000_000, 0, 0, 0, 0, 0, 0)),
        (rover, rover.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                       mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3)),
    ]
    return b"".join(tlog_record(BASE_US + k * 100_000, msg.pack(mav))
                    for k, (mav, msg) in enumerate(msgs))


def test_a_logs_view_maps_the_rover_of_params_about_the_rovers_own_first_position(
        tmp_path: Path, spy: type[SpyMapping]) -> None:
    params = _rover_params()
    entries = parse_tlog(_drive()).entries
    assert view.show_log(entries, params, tmp_path / "v.rrd", False, 0, io.StringIO(),
                         io.StringIO()) == 0
    (mapping,) = spy.made
    assert mapping.given == (params, GlobalOrigin(470_000_000, 80_000_000))


class _Ended:
    returncode = 0

    def poll(self) -> int:
        return 0


def test_the_live_view_maps_the_rover_of_params_and_sends_rows_every_flush_period(
        tmp_path: Path, spy: type[SpyMapping], monkeypatch: pytest.MonkeyPatch) -> None:
    source = tmp_path / "live.tlog"
    source.write_bytes(_drive())
    monkeypatch.setattr(view, "open_viewer", lambda recording, web_port, save: view.Viewer(
        _Ended(), "rerun+http://127.0.0.1:9/proxy", "http://127.0.0.1:9/"))  # type: ignore[arg-type]
    clock = [1000.0]

    def sleep(s: float) -> None:  # (the idle tlog's wait, 10 ms late: the only time passing)
        clock[0] = round(clock[0] + s + 0.01, 6)

    monkeypatch.setattr(view, "time", SimpleNamespace(monotonic=lambda: clock[0], sleep=sleep,
                                                      time=lambda: clock[0]))
    params = _rover_params()
    batches: list[float] = []

    def after(mapping: ViewMapping) -> bool:
        batches.append(clock[0])
        return len(batches) == 9  # the records, then 8 idle waits of 0.06 s: 0.48 s

    assert view.run_view(str(source), params, web_port=0, out=io.StringIO(),
                         stop_when=after) == 0
    (mapping,) = spy.made
    assert mapping.given == (params, None)  # (live: no origin but the stream's)
    assert view.FLUSH_PERIOD_S == 0.2
    # flushed with the first batch, then at 0.24 s (0.2 s on) and 0.48 s, and at the end
    assert mapping.flushes == 3 + 1
