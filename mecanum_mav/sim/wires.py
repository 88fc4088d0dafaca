"""Virtual wires, links and poller: what the lockstep harness runs the companion's loop on.

A :class:`Wire` is one direction of a virtual link: bytes queued by a sender (a pymavlink
``MAVLink`` packing with its own ids and sequence numbers), parsed by the receiver as the
companion's links parse them, each write one datagram. A :class:`VirtualLink` is the
companion's end of two wires, the :class:`~mecanum_mav.runtime.loop.LoopLink` the loop reads
and writes, as a ``udpin:`` link is (datagram by datagram, never waiting); a
:class:`VirtualPoller` is the loop's poller, which never sleeps: it returns at once with the
links that have something to read. The clock is the harness's virtual time.
"""

from __future__ import annotations

import itertools
import math
import select
import selectors
from collections.abc import Sequence
from typing import Any, BinaryIO

from mecanum_mav.io.tlog import tlog_record
from mecanum_mav.protocol.codec import encode_rc_override, send_message
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.framing import MessageParser
from mecanum_mav.protocol.signing import TICKS_PER_S, Check, SignatureCheck, ticks_from_unix

__all__ = ["SIGNING_START_TICKS", "TLOG_EPOCH_S", "VirtualLink", "VirtualPoller", "Wire"]

TLOG_EPOCH_S = 1_790_000_000.0
"""The Unix time a recorded tlog gives virtual time 0 (a date in 2026)."""
SIGNING_START_TICKS = ticks_from_unix(TLOG_EPOCH_S)
"""The signing timestamp at virtual time 0 (a date in 2026); it counts on with virtual time."""
_READABLE = select.EPOLLIN
_descriptors = itertools.count(1_000_000)  # virtual descriptors: never a real one's number


class Wire:
    """One direction of a virtual link: bytes queued by a sender, parsed by the receiver.

    With ``signing_key`` the sender signs (as a link with that key does) and the receiver keeps
    only correctly signed, fresh packets (:class:`~mecanum_mav.protocol.signing.SignatureCheck`).
    """

    def __init__(self, sysid: int, compid: int, *, name: str,
                 signing_key: bytes | None = None) -> None:
        self.sender = mavlink.MAVLink(self, srcSystem=sysid, srcComponent=compid)
        self.check = None
        if signing_key is not None:
            signing = self.sender.signing
            signing.secret_key, signing.sign_outgoing = signing_key, True
            signing.link_id, signing.timestamp = 0, SIGNING_START_TICKS
            self.check = SignatureCheck(signing_key, SIGNING_START_TICKS)
        self.parser = MessageParser(mavlink.MAVLink(None), datagrams=True, name=name,
                                    check=self.check)
        self.queue: list[bytes] = []
        self.received = 0
        self.tlog: BinaryIO | None = None
        self.now_s = 0.0

    def follow_clock(self, now_s: float) -> None:
        """Signing timestamps follow virtual time, as a link's follow the wall clock."""
        if self.check is not None:
            now = SIGNING_START_TICKS + int(now_s * TICKS_PER_S)
            self.check.advance(now)
            self.sender.signing.timestamp = max(self.sender.signing.timestamp, now)

    def write(self, data: bytes) -> None:
        """The sender's ``file.write``: one datagram on the wire (recorded with a tlog)."""
        self.queue.append(bytes(data))
        if self.tlog is not None:
            self.tlog.write(tlog_record(round((TLOG_EPOCH_S + self.now_s) * 1e6), data))

    def drop(self) -> list[Any]:
        """Lose everything on the wire (a cut link); returns nothing."""
        self.queue = []
        return []

    def parse(self, data: bytes) -> list[Any]:
        """The messages of one datagram taken off the wire, counted as received."""
        messages: list[Any] = self.parser.parse(data)
        self.received += len(messages)
        return messages

    def deliver(self) -> list[Any]:
        """Everything on the wire, parsed; the wire is empty after."""
        if not self.queue:
            return []
        datagrams, self.queue = self.queue, []
        messages: list[Any] = []
        for data in datagrams:
            messages += self.parse(data)
        return messages


class VirtualLink:
    """The companion's end of a virtual link: reads ``inbound``, sends on ``outbound`` (a
    :class:`~mecanum_mav.runtime.loop.LoopLink`).

    It reads datagram by datagram, as a ``udpin:`` link does, and never waits: a datagram
    link. It can also break and come back (:meth:`break_off`, :meth:`come_back`), as a stream
    link does; the loop then finds it as it finds a ``tcpin`` link's: its descriptor turns
    readable, the read finds it down (or up again), and the loop tells the core. A link that
    has broken once is no longer steady (the loop looks at it after every read). What crosses
    the wires is the harness's business (it cuts the flight controller's while it is down).
    """

    next_reopen_s = math.inf
    next_send_s = math.inf
    wants_write = False
    pending = False
    send_errors = 0

    def __init__(self, name: str, inbound: Wire, outbound: Wire) -> None:
        self.name = name
        self.inbound, self.outbound = inbound, outbound
        self.mav = outbound.sender
        self.signature_check = inbound.check
        self.unchecked = inbound.check is None and outbound.check is None
        self.steady = True
        self.down_reason: str | None = None
        self.lane_answers = 0
        """Datagrams the loop answered in the stick lane, unparsed (:meth:`answered`)."""
        self._changed = False  # it broke or came back since the loop last read it
        self._fd = next(_descriptors)

    @property
    def up(self) -> bool:
        return self.down_reason is None

    @property
    def received(self) -> int:
        return self.inbound.received

    @property
    def bad(self) -> int:
        return self.inbound.parser.bad

    def readable(self) -> bool:
        """Whether the loop's poller finds something to read: a datagram, or the break or
        return not yet read."""
        return bool(self.inbound.queue) or self._changed

    def break_off(self, reason: str) -> None:
        """The link broke (device gone, connection closed): the loop finds it down."""
        self.down_reason, self.steady, self._changed = reason, False, True

    def come_back(self) -> None:
        """The link is open again: the loop finds it up."""
        self.down_reason, self._changed = None, True

    # ------------------------------------------------------------------ reading

    def receive_datagram(self) -> tuple[bytes, Any] | None:
        queue = self.inbound.queue
        return (queue.pop(0), self.name) if queue else None

    def parse_datagram(self, data: bytes, address: Any) -> list[Any]:
        return self.inbound.parse(data)

    def answered(self, data: bytes, address: Any) -> None:
        self.inbound.received += 1
        self.lane_answers += 1

    def read(self) -> list[Any]:
        """Every datagram waiting, parsed (the real link takes at most 64 per wake and is
        woken again at once; here that is the same instant)."""
        self._changed = False
        return self.inbound.deliver()

    def take_rejections(self) -> dict[Check, int]:
        check = self.signature_check
        return {} if check is None or not check.new_rejections else check.take_rejections()

    def reopen(self, now_s: float) -> bool:
        return self.up

    # ------------------------------------------------------------------ sending

    def takes_packet(self) -> bool:
        """A datagram link's answer: a packet goes at once."""
        return True

    def send_packet(self, packet: bytes) -> None:
        mav = self.mav
        mav.seq = (mav.seq + 1) & 0xFF
        self.outbound.write(packet)

    def send_all(self, messages: Sequence[Any]) -> None:
        mav = self.mav
        for msg in messages:
            send_message(mav, msg)  # the companion's fast codec

    def send_rc_override(self, target_system: int, target_component: int,
                         channels: list[int], *, replace: bool = True) -> None:
        self.outbound.write(encode_rc_override(self.mav, target_system, target_component,
                                               channels))

    def flush(self) -> None:
        """Nothing waits in a virtual link."""

    def wait_fd(self) -> int | None:
        return self._fd


class VirtualPoller:
    """The loop's poller in virtual time: :meth:`wait` never sleeps; it returns at once each
    registered :class:`VirtualLink` that has something to read, in the order registered."""

    def __init__(self) -> None:
        self._keys: dict[Any, selectors.SelectorKey] = {}

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        key = self._keys[fileobj] = selectors.SelectorKey(fileobj, fileobj, events, data)
        return key

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        return self._keys.pop(fileobj)

    def modify(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        self.unregister(fileobj)
        return self.register(fileobj, events, data)

    def get_key(self, fileobj: Any) -> selectors.SelectorKey:
        return self._keys[fileobj]

    def wait(self, timeout_s: float) -> list[tuple[Any, int]]:
        return [(key.data, _READABLE) for key in self._keys.values() if key.data.readable()]

    def yield_cpu(self) -> None:
        """Nothing: virtual time has no other CPU user."""
