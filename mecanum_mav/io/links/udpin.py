"""``udpin:`` links: :class:`UdpinLink` answers the peers it earned, and
:class:`SignedUdpinLink` also tells refused senders why.

A ``udpin:`` link answers the peers it has heard a valid message from (with a signing key: a
correctly signed one), so a ground station that restarts on a new port is answered from its
first packet on, while garbage or unsigned datagrams from other addresses make no one a peer
(they get nothing back, and cannot make the rover send everything many times over). A peer
silent for :data:`PEER_TIMEOUT_S` (seconds on the link's clock) is forgotten once another
peer is heard; at most :data:`MAX_PEERS` are kept (the longest silent goes first). The peers
are pymavlink's ``conn.clients``, which the link keeps.

With a signing key (and told to: the ground station's link, not the flight controller's),
an address whose well-formed MAVLink packets were all refused (unsigned, badly signed: a
ground station without the key) is no peer either, but is told why: with each of the rover's
heartbeats it gets that HEARTBEAT, signed, and a STATUSTEXT with the reason, and nothing
else, at most once per heartbeat; such addresses are few and forgotten when silent
(:mod:`~mecanum_mav.protocol.refusedsenders`), and garbage makes no one one.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from mecanum_mav.io.links.datagram import DatagramLink
from mecanum_mav.protocol.codec import send_message
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.refusedsenders import RefusedSenders
from mecanum_mav.protocol.signing import REFUSED_TEXTS, Check
from mecanum_mav.protocol.statustext import Severity, statustext_messages

__all__ = ["MAX_PEERS", "PEER_TIMEOUT_S", "SignedUdpinLink", "UdpinLink"]

PEER_TIMEOUT_S = 10.0
"""A ``udpin:`` peer not heard from for this long is no longer sent to, once another is heard."""
MAX_PEERS = 8
"""A ``udpin:`` link sends to at most this many peers."""
_HEARTBEAT = mavlink.MAVLink_heartbeat_message
"""(By class: ``msg.id`` is no message id on STATUSTEXT, whose chunk ``id`` field shadows it.)"""


class UdpinLink(DatagramLink):
    """A ``udpin:`` link: listens, and sends to every peer it earned (module description)."""

    def __init__(self, conn: Any, *, url: str, name: str, signing_key: bytes | None,
                 clock: Callable[[], float]) -> None:
        super().__init__(conn, url=url, name=name, signing_key=signing_key, clock=clock)
        self._peers_s: dict[Any, float] = {}  # peers -> when last heard (clock s)
        self.peer_timeout_s = PEER_TIMEOUT_S
        self._next_prune_s = -math.inf

    def answered(self, data: bytes, address: Any) -> None:
        """A datagram answered without parsing (the stick lane): its sender is heard too."""
        super().answered(data, address)
        self._heard(address)

    def _parse_one(self, data: bytes, address: Any) -> list[Any]:
        parsed = super()._parse_one(data, address)
        if parsed:
            self._heard(address)
        return parsed

    def _heard(self, address: Any) -> None:
        """A valid message came from ``address``: it is a peer (sent to); peers silent for
        :attr:`peer_timeout_s` are dropped, at most :data:`MAX_PEERS` kept."""
        now = self.clock()
        peers = self._peers_s
        known = address in peers
        peers[address] = now
        if known and now < self._next_prune_s:  # the common case: a peer already sent to
            return
        if not known:
            self._new_peer(address)
        self._next_prune_s = now + 1.0
        clients = self.conn.clients
        clients.add(address)
        for old in [a for a, seen in peers.items() if now - seen > self.peer_timeout_s]:
            del peers[old]
        while len(peers) > MAX_PEERS:
            del peers[min(peers, key=peers.__getitem__)]
        clients.intersection_update(peers)

    def _new_peer(self, address: Any) -> None:
        """``address`` has just become a peer."""

    def _put_datagram(self, data: bytes) -> None:
        """To each peer; raises what the socket raised, after trying every peer."""
        failed = None
        for address in self.conn.clients:
            try:
                self._sendto(data, address)
            except OSError as exc:
                failed = exc
        if failed is not None:
            raise failed


class SignedUdpinLink(UdpinLink):
    """A signed ``udpin:`` link that tells the addresses it refused why, with each heartbeat
    (module description; :attr:`refused_senders`, :attr:`hints_sent`)."""

    def __init__(self, conn: Any, *, url: str, name: str, signing_key: bytes,
                 clock: Callable[[], float]) -> None:
        super().__init__(conn, url=url, name=name, signing_key=signing_key, clock=clock)
        self.refused_senders: RefusedSenders = RefusedSenders()
        self.hints_sent = 0
        self._hint_seq = 0  # the hints' own sequence numbers (the peers' have no gaps)

    def send(self, msg: Any) -> bool:
        """:meth:`~mecanum_mav.io.links.base.Link.send`; after a HEARTBEAT went to the peers,
        the refused addresses that are due get it too, with the reason (the heartbeat, 1 Hz,
        paces the hints)."""
        if not super().send(msg):
            return False
        if type(msg) is _HEARTBEAT and self.refused_senders:
            self._tell_refused(msg)
        return True

    def _new_peer(self, address: Any) -> None:
        self.refused_senders.forget(address)  # signed now: a peer, told no more

    def _parse_one(self, data: bytes, address: Any) -> list[Any]:
        """A sender that is not a peer and whose datagram held only refused MAVLink packets
        is kept (bounded) to be told why; garbage (no packet the signature check saw) is
        not."""
        check = self.signature_check
        assert check is not None
        before = check.new_rejections
        parsed = super()._parse_one(data, address)
        kind = check.last_rejection
        if (not parsed and check.new_rejections != before and kind is not None
                and address not in self._peers_s):
            self.refused_senders.refused(address, kind, self.clock())
        return parsed

    def _tell_refused(self, heartbeat: Any) -> None:
        """Each refused address that is due
        (:meth:`~mecanum_mav.protocol.refusedsenders.RefusedSenders.due`) gets one datagram,
        the same HEARTBEAT (signed) and the STATUSTEXT saying why its packets are refused, and
        nothing else. Never raises."""
        due = self.refused_senders.due(self.clock())
        if not due:
            return
        mav = self.conn.mav
        peers_seq, outer_batch = mav.seq, self._batch
        captured: list[bytes] = []
        self._batch, mav.seq = captured, self._hint_seq
        reasons: dict[Check, bytes] = {}
        try:
            send_message(mav, heartbeat)
            beat = captured.pop()
            for kind in {kind for _, kind in due}:
                for msg in statustext_messages(Severity.WARNING, REFUSED_TEXTS[kind]):
                    send_message(mav, msg)
                reasons[kind] = b"".join(captured)
                captured.clear()
        except Exception as exc:  # a send must never take the control loop down
            self._send_failed(exc)
            return
        finally:
            self._hint_seq, mav.seq, self._batch = mav.seq, peers_seq, outer_batch
        for address, kind in due:
            try:
                self._sendto(beat + reasons[kind], address)
            except OSError as exc:
                self._send_failed(exc)
            else:
                self.hints_sent += 1
