"""The live view's end (mecanum_mav.app.view.run_view): its last rows are sent as it stops, and
a viewer already gone or a second Ctrl-C while they are sent still ends it as a stop (status
0, the count of messages said), not with a traceback.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")

from mecanum_mav.app import view
from mecanum_mav.app.rerunview import ViewMapping
from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import tlog_record
from mecanum_mav.protocol.dialect import mavlink


class _Ended:
    returncode = 0

    def poll(self) -> int:
        return 0


@pytest.mark.parametrize("trouble", [RuntimeError("the viewer is gone"), KeyboardInterrupt()],
                         ids=["viewer-gone", "second-ctrl-c"])
def test_trouble_sending_the_last_rows_still_ends_the_view_as_a_stop(
        trouble: BaseException, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    source = tmp_path / "live.tlog"
    source.write_bytes(tlog_record(1_800_000_000_000_000, mav.heartbeat_encode(
        mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3).pack(mav)))
    monkeypatch.setattr(view, "open_viewer", lambda recording, web_port, save: view.Viewer(
        _Ended(), "rerun+http://127.0.0.1:9/proxy", "http://127.0.0.1:9/"))  # type: ignore[arg-type]
    stopping: list[bool] = []

    class Troubled(ViewMapping):
        def flush(self, recording: Any) -> int:
            if stopping:
                raise trouble
            return super().flush(recording)

    monkeypatch.setattr(view, "ViewMapping", Troubled)

    def stop(mapping: ViewMapping) -> bool:
        stopping.append(True)
        return True

    out = io.StringIO()
    assert view.run_view(str(source), Params(), web_port=0, out=out, stop_when=stop) == 0
    assert out.getvalue().endswith("mecanum-mav view: 1 messages\n")
