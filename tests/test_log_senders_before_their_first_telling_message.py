"""Who sent a message in a tlog where the companion and its flight controller share system 1
component 1 (mecanum_mav.app.logsenders.Senders.role): a sender's messages before its first
telling one (ODOMETRY: the companion) have that one's role, unless another sender of the same
id had that role then; a sender that never sends a telling message has none. So ``mecanum-mav
log`` takes the companion's first HEARTBEAT, sent before its first ODOMETRY, as the vehicle's
mode, and never the flight controller's (mecanum_mav.app.loganalysis)."""

from __future__ import annotations

from typing import Any

from mecanum_mav.app.loganalysis import analyse
from mecanum_mav.app.logsenders import Senders
from mecanum_mav.io.tlog import TlogEntry
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.modes import Mode

START_S = 1_800_000_000.0


class Sender:
    """Messages as one MAVLink sender packs them (its own sequence numbers from ``seq``),
    decoded as received."""

    def __init__(self, sysid: int, compid: int, seq: int) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.mav.seq = seq

    def __call__(self, build: str, *args: Any) -> Any:
        data = getattr(self.mav, f"{build}_encode")(*args).pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        return mavlink.MAVLink(None).decode(bytearray(data))

    def heartbeat(self, mode: Mode, armed: bool) -> Any:
        flags = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
            mavlink.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0)
        return self("heartbeat", mavlink.MAV_TYPE_GROUND_ROVER,
                    mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, flags, int(mode), 4)

    def odometry(self) -> Any:
        return self("odometry", 0, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_FRD,
                    0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                    [float("nan")] + [0.0] * 20, [float("nan")] + [0.0] * 20, 0,
                    mavlink.MAV_ESTIMATOR_TYPE_VIO, 100)


def senders_of(messages: list[Any]) -> Senders:
    senders = Senders()
    for index, msg in enumerate(messages):
        senders.add(index, msg)
    return senders


def test_a_senders_messages_before_its_first_odometry_are_the_companions():
    companion, board = Sender(1, 1, seq=10), Sender(1, 1, seq=200)
    messages = [companion.heartbeat(Mode.AUTO, True), board.heartbeat(Mode.MANUAL, False),
                companion.odometry(), board.heartbeat(Mode.MANUAL, False)]
    senders = senders_of(messages)
    assert [senders.role(i) for i in range(len(messages))] == ["vehicle", None, "vehicle", None]


def test_before_its_first_odometry_a_sender_is_unknown_while_another_of_its_id_is_the_companion():
    """A second sender of 1/1 that sends ODOMETRY (a companion restarted, its sequence
    numbers starting again) is the companion only from then: before, the first one was."""
    first, second = Sender(1, 1, seq=10), Sender(1, 1, seq=150)
    messages = [first.heartbeat(Mode.AUTO, True), first.odometry(),
                second.heartbeat(Mode.MANUAL, False), second.odometry(),
                second.heartbeat(Mode.MANUAL, False)]
    senders = senders_of(messages)
    assert [senders.role(i) for i in range(len(messages))] == [
        "vehicle", "vehicle", None, "vehicle", "vehicle"]


def test_the_log_takes_the_companions_first_heartbeat_as_the_vehicles_mode_not_the_boards():
    companion, board = Sender(1, 1, seq=10), Sender(1, 1, seq=200)
    timed = [(0.0, companion.heartbeat(Mode.AUTO, True)),
             (0.05, board.heartbeat(Mode.MANUAL, False)),
             (0.1, companion.odometry()),
             (1.0, companion.heartbeat(Mode.AUTO, True)),
             (1.05, board.heartbeat(Mode.MANUAL, False)),
             (1.1, companion.odometry())]
    entries = [TlogEntry(START_S + t, k, msg) for k, (t, msg) in enumerate(timed)]
    result = analyse(entries)
    assert [(span.start_s, span.mode, span.armed) for span in result.modes] == [
        (0.0, "AUTO", True)]
