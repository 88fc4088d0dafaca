"""The lockstep harness's virtual link (mecanum_mav/sim/wires.py's :class:`VirtualLink`) keeps
the loop's link promise (mecanum_mav/runtime/loop.py's ``LoopLink``): with no signature check
:meth:`take_rejections` has nothing; with one, what it refused since the last call, per kind,
once."""

from __future__ import annotations

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.signing import Check
from mecanum_mav.sim.wires import VirtualLink, Wire

KEY = bytes(range(32))


def _unsigned_heartbeat() -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    return bytes(mav.heartbeat_encode(6, 8, 0, 0, 4).pack(mav))


def test_an_unsigned_virtual_link_has_no_rejections_to_take():
    link = VirtualLink("gcs", Wire(255, 190, name="gcs"), Wire(1, 1, name="gcs"))
    assert link.signature_check is None
    link.inbound.queue.append(_unsigned_heartbeat())
    assert len(link.read()) == 1
    assert link.take_rejections() == {}


def test_a_signed_virtual_link_gives_what_it_refused_once():
    inbound = Wire(255, 190, name="gcs", signing_key=KEY)
    link = VirtualLink("gcs", inbound, Wire(1, 1, name="gcs", signing_key=KEY))
    inbound.queue.append(_unsigned_heartbeat())
    assert link.read() == []
    assert link.take_rejections() == {Check.UNSIGNED: 1}
    assert link.take_rejections() == {}
