"""The simulated board's RC_CHANNELS (mecanum_mav.sim.board, module docstring), as ArduPilot's
``GCS_MAVLINK::send_rc_channels`` sends it: ``time_boot_ms`` its ``AP_HAL::millis()`` (a
uint32 that wraps), ``chancount`` the receiver's channels, each channel the override in force
or else the receiver's pulse, 0 beyond the receiver's channels (ArduPilot's zeroed array, not
the MAVLink spec's UINT16_MAX), RSSI 255 ("unknown") unless set. The board alone, time passed
in, every message packed and decoded by pymavlink as a ground station receives it."""

from __future__ import annotations

from typing import Any

from mecanum_mav.config.params import Params
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.board import SimBoard

GCS = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
RECEIVER = (1510, 1490, 1000, 1520, 2000, 1800)
UINT32_WRAP_S = 2**32 / 1000
"""A uint32 of milliseconds wraps after this long (some 49.7 days)."""


def received(build: str, *args: Any) -> Any:
    """A message from the ground station's system as the board receives it (packed, parsed)."""
    data = getattr(GCS, f"{build}_encode")(*args).pack(GCS)
    return mavlink.MAVLink(None).decode(bytearray(data))


class Wire:
    """A link's sending side: the board's messages packed, then decoded as received."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.mav = mavlink.MAVLink(self, srcSystem=1, srcComponent=1)

    def write(self, data: bytes) -> None:
        self.data += data

    def rc_channels(self) -> list[Any]:
        msgs = mavlink.MAVLink(None).parse_buffer(bytes(self.data)) or []
        self.data.clear()
        return [m for m in msgs if m.get_type() == "RC_CHANNELS"]


def board_asked_for_rc_channels(boot_s: float) -> tuple[SimBoard, Wire]:
    """A board booted at ``boot_s`` with :data:`RECEIVER`, asked for RC_CHANNELS at 10 Hz."""
    board = SimBoard(Params(), boot_s)
    board.receiver = RECEIVER
    board.receive([received("command_long", 1, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                            mavlink.MAVLINK_MSG_ID_RC_CHANNELS, 100_000, 0, 0, 0, 0, 0)],
                  boot_s)
    return board, Wire()


def test_rc_channels_carry_the_receivers_pulses_under_the_overrides_zero_beyond_it():
    board, wire = board_asked_for_rc_channels(10.0)
    # an override of channel 2 and of channel 8 (beyond the receiver's six); the others left
    board.receive([received("rc_channels_override", 1, 1, 65535, 1700, 65535, 65535,
                            65535, 65535, 65535, 1300)], 12.2)  # (in force: SIM_RC_TMO 0.5 s)
    board.on_time(12.3456, wire.mav)
    (msg,) = wire.rc_channels()
    assert msg.time_boot_ms == 2345  # ms since boot, rounded down
    assert msg.chancount == len(RECEIVER)
    raw = [getattr(msg, f"chan{ch}_raw") for ch in range(1, 19)]
    assert raw == [1510, 1700, 1000, 1520, 2000, 1800, 0, 1300] + [0] * 10
    assert msg.rssi == 255  # UINT8_MAX: unknown


def test_rc_channels_time_since_boot_wraps_as_a_uint32_of_milliseconds():
    board, wire = board_asked_for_rc_channels(0.0)
    board.rssi = 180
    board.on_time(UINT32_WRAP_S + 1.5, wire.mav)
    (msg,) = wire.rc_channels()
    assert msg.time_boot_ms == 1500
    assert msg.rssi == 180
    assert [getattr(msg, f"chan{ch}_raw") for ch in range(1, 7)] == list(RECEIVER)
