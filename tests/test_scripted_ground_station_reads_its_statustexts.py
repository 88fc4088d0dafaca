"""The scripted ground station's texts (``ScriptedGroundStation.texts``,
mecanum_mav/sim/groundstation.py): the STATUSTEXTs it received from an index on (by default
all, the very first message included), a long text's chunks joined as each completed, a text
whose last chunk has not come yet last."""

from __future__ import annotations

from typing import Any

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.statustext import Severity, statustext_messages
from mecanum_mav.sim.groundstation import ScriptedGroundStation

VEHICLE = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
LONG = "Mission item 3 is too far from home: " + "x" * 40 + " (the end)"


def as_received(*messages: Any) -> list[Any]:
    """``messages`` from the vehicle as the ground station decodes them off the wire."""
    return [mavlink.MAVLink(None).decode(bytearray(m.pack(VEHICLE))) for m in messages]


def said(text: str, chunk_id: int = 7) -> list[Any]:
    return as_received(*statustext_messages(Severity.INFO, text, chunk_id=chunk_id))


def test_texts_are_every_statustext_received_the_first_message_included_chunks_joined():
    gcs = ScriptedGroundStation(port=None)  # type: ignore[arg-type]  # (never asked)
    first, *rest = said(LONG)
    heartbeat = as_received(VEHICLE.heartbeat_encode(
        mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 0))
    gcs.receive([*said("Flight controller link up"), first, *heartbeat], 0.0)
    gcs.receive([*said("Arming", chunk_id=0), *rest, *said("Mission complete")], 1.0)
    assert len(statustext_messages(Severity.INFO, LONG, chunk_id=7)) > 1
    assert gcs.texts() == ["Flight controller link up", "Arming", LONG, "Mission complete"]
    assert gcs.texts(since=1) == ["Arming", LONG, "Mission complete"]  # (its first chunk on)
    # from the heartbeat on: the long text's chunks from there only
    assert gcs.texts(since=3) == ["Arming", LONG[50:], "Mission complete"]


def test_a_long_text_whose_last_chunk_has_not_come_yet_comes_last_as_far_as_it_went():
    gcs = ScriptedGroundStation(port=None)  # type: ignore[arg-type]
    *head, _ = said(LONG)
    gcs.receive([*head, *said("Arming")], 0.0)
    assert gcs.texts() == ["Arming", LONG[:len(head) * 50]]
