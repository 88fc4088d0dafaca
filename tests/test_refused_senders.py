"""A signed ``udpin:`` link tells a sender it refused why, with its heartbeat, and nothing else.

Real UDP sockets on 127.0.0.1 around a :class:`~mecanum_mav.io.links.Link` with a key (the
heartbeat is sent by hand, as the core's housekeeping sends it once a second), and the bounded
table of refused addresses alone, in its own time."""

from __future__ import annotations

import errno
import hashlib
import logging
import os
import socket
import time
import tracemalloc
from typing import Any

import pytest
from support import deliver, mavlink_sender, read_for

from mecanum_mav.io.links import Link, open_link
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.refusedsenders import (
    HINT_MIN_INTERVAL_S,
    MAX_REFUSED_SENDERS,
    REFUSED_TIMEOUT_S,
    RefusedSenders,
)
from mecanum_mav.protocol.signing import REFUSED_TEXTS, Check, SignatureCheck, ticks_from_unix
from mecanum_mav.protocol.statustext import Severity, statustext_messages

KEY = hashlib.sha256(b"rover-on-a-shared-radio").digest()
UNSIGNED_REASON = "Unsigned packet refused: signing required"
BAD_SIGNATURE_REASON = "Bad signature: packet refused (wrong key?)"
EACCES = f"[Errno {errno.EACCES}] {os.strerror(errno.EACCES)}"
"""What a send to the broadcast address without SO_BROADCAST fails with."""

# --------------------------------------------------------------------------- the table alone


def test_a_refused_address_is_due_at_most_once_per_interval_with_its_latest_refusal():
    table = RefusedSenders()
    table.refused("a", Check.UNSIGNED, 0.0)
    assert table.due(0.0) == [("a", Check.UNSIGNED)]
    table.refused("a", Check.BAD_SIGNATURE, 0.1)
    assert table.due(0.1) == []
    assert table.due(HINT_MIN_INTERVAL_S) == [("a", Check.BAD_SIGNATURE)]


def test_a_refused_address_silent_for_the_timeout_is_forgotten_one_still_sending_is_not():
    table = RefusedSenders()
    table.refused("quiet", Check.UNSIGNED, 0.0)
    for t in range(int(REFUSED_TIMEOUT_S) + 2):
        table.refused("chatty", Check.UNSIGNED, float(t))
    assert [a for a, _ in table.due(REFUSED_TIMEOUT_S + 1.0)] == ["chatty"]
    assert "quiet" not in table and len(table) == 1


def test_the_table_keeps_the_most_recently_heard_addresses_and_drops_the_longest_silent():
    table = RefusedSenders()
    table.refused("first", Check.UNSIGNED, 0.0)
    for n in range(MAX_REFUSED_SENDERS - 2):
        table.refused(n, Check.UNSIGNED, 0.1 + n * 0.01)
    table.refused("first", Check.UNSIGNED, 0.5)  # heard again (the table not yet full)
    table.refused("new", Check.UNSIGNED, 0.6)  # the table full
    table.refused("newer", Check.UNSIGNED, 0.7)  # one too many: address 0 goes
    assert len(table) == MAX_REFUSED_SENDERS
    assert "first" in table and "newer" in table and 0 not in table


def test_a_forgotten_address_is_told_nothing_more():
    table = RefusedSenders()
    table.refused("a", Check.UNSIGNED, 0.0)
    table.forget("a")
    table.forget("never heard")
    assert table.due(1.0) == [] and len(table) == 0


def test_a_flood_of_forged_addresses_costs_no_more_memory_than_eight_addresses_do():
    """The module's promise: however many addresses are refused, told, forgotten for being
    silent or for signing, the table holds what eight addresses need."""
    table = RefusedSenders()

    def flood(first: int, count: int) -> None:
        for n in range(first, first + count):
            now_s = n * 0.01
            table.refused(("10.0.0.1", n), Check.UNSIGNED, now_s)
            table.due(now_s)
            if n % 3 == 0:
                table.forget(("10.0.0.1", n - 1))  # (a peer now)
            if n % 1000 == 0:
                table.due(now_s + REFUSED_TIMEOUT_S + 1.0)  # (all silent too long)

    flood(0, 2_000)  # (the dictionaries at their working size)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        flood(2_000, 20_000)
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert len(table) <= MAX_REFUSED_SENDERS
    assert grown < 16_000, f"{grown} bytes more after 20,000 addresses"


# --------------------------------------------------------------------------- the link


def signed_udpin() -> Link:
    return open_link("udpin:127.0.0.1:0", source_system=1, source_component=191, name="gcs",
                     signing_key=KEY, tell_refused=True)


def sender(key: bytes | None = None) -> mavlink.MAVLink:
    """A ground station's packer: unsigned, or signing with ``key`` (as MAVProxy does)."""
    return mavlink_sender(key)


def gcs_heartbeat(mav: mavlink.MAVLink) -> bytes:
    return bytes(mavlink.MAVLink_heartbeat_message(
        mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3).pack(mav))


def rover_heartbeat() -> Any:
    return mavlink.MAVLink_heartbeat_message(mavlink.MAV_TYPE_GROUND_ROVER,
                                             mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3, 3)


def said(text: str) -> Any:
    """A STATUSTEXT of one chunk: its own ``id`` field is 0, HEARTBEAT's message id."""
    return mavlink.MAVLink_statustext_message(6, text.encode(), 0, 0)


def telemetry() -> Any:
    return mavlink.MAVLink_attitude_message(1000, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)


def peer() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    return sock


def received(sock: socket.socket, timeout_s: float = 0.3) -> list[Any]:
    """Every message reaching ``sock`` within ``timeout_s``, parsed (signed or not)."""
    parser = mavlink.MAVLink(None)
    return read_for(sock.fileno(), lambda: parser.parse_buffer(sock.recv(65536)) or [],
                    timeout_s)


def kinds(messages: list[Any]) -> list[str]:
    return [m.get_type() for m in messages]


@pytest.fixture
def link():
    opened = signed_udpin()
    yield opened
    opened.close()


@pytest.fixture
def sockets():
    made: list[socket.socket] = []

    def make() -> socket.socket:
        made.append(peer())
        return made[-1]
    yield make
    for sock in made:
        sock.close()


@pytest.mark.parametrize(("key", "reason"), [(None, UNSIGNED_REASON),
                                             (b"\x07" * 32, BAD_SIGNATURE_REASON)],
                         ids=["unsigned", "wrong key"])
def test_a_refused_sender_gets_the_signed_heartbeat_and_the_reason_and_nothing_else(
        link, sockets, key, reason):
    stranger, pilot = sockets(), sockets()
    assert deliver(link, pilot, gcs_heartbeat(sender(KEY))) != []  # a peer, signing
    assert deliver(link, stranger, gcs_heartbeat(sender(key))) == []  # refused
    link.send_all([said("Arming checks passed"), rover_heartbeat(), telemetry()])
    got = received(stranger)
    assert kinds(got) == ["HEARTBEAT", "STATUSTEXT"] and got[1].text == reason
    check = SignatureCheck(KEY, ticks_from_unix(time.time()) - 10**6)
    assert all(check.check(m.get_msgbuf()) is Check.ACCEPTED for m in got)  # signed with KEY
    assert [m.get_seq() for m in received(pilot)] == [0, 1, 2]  # the pilot's, no gap
    assert [m.get_seq() for m in got] == [0, 1]  # the hints' own numbers, from 0
    assert link.hints_sent == 1


def test_each_refusal_reason_is_one_statustext():
    """``REFUSED_TEXTS``: each under 50 characters, one STATUSTEXT (a hint is the heartbeat
    and one STATUSTEXT, whatever the kind)."""
    assert [len(statustext_messages(Severity.WARNING, text)) for text in REFUSED_TEXTS.values()
            ] == [1] * len(REFUSED_TEXTS)


def test_a_refused_sender_is_told_at_most_once_per_interval_however_often_the_link_beats(
        link, sockets):
    stranger = sockets()
    deliver(link, stranger, gcs_heartbeat(sender()))
    for _ in range(5):
        deliver(link, stranger, gcs_heartbeat(sender()))
        link.send(rover_heartbeat())
    assert kinds(received(stranger)) == ["HEARTBEAT", "STATUSTEXT"]
    assert link.hints_sent == 1


def test_garbage_or_a_truncated_packet_gets_nothing(link, sockets):
    stranger, noise = sockets(), sockets()
    deliver(link, stranger, gcs_heartbeat(sender()))  # a refusal just before
    for data in (b"hello rover", b"\xfd\x09\x00\x00\x00\xff\xbe\x00\x00\x00",
                 gcs_heartbeat(sender())[:-3]):
        assert deliver(link, noise, data) == []
    link.send(rover_heartbeat())
    assert received(noise) == []
    assert kinds(received(stranger)) == ["HEARTBEAT", "STATUSTEXT"]


def test_a_flood_of_refused_addresses_keeps_the_newest_eight_told(link, sockets):
    strangers = [sockets() for _ in range(MAX_REFUSED_SENDERS + 4)]
    for sock in strangers:
        deliver(link, sock, gcs_heartbeat(sender()))
    link.send(rover_heartbeat())
    told = [bool(received(sock, 0.1)) for sock in strangers]
    assert told == [False] * 4 + [True] * MAX_REFUSED_SENDERS
    assert link.hints_sent == MAX_REFUSED_SENDERS  # one each
    assert link.refused_senders is not None and len(link.refused_senders) == MAX_REFUSED_SENDERS


def test_a_refused_sender_that_signs_becomes_a_peer_and_is_told_no_more(link, sockets):
    station = sockets()
    deliver(link, station, gcs_heartbeat(sender()))
    link.send(rover_heartbeat())
    assert kinds(received(station)) == ["HEARTBEAT", "STATUSTEXT"]
    assert kinds(deliver(link, station, gcs_heartbeat(sender(KEY)))) == ["HEARTBEAT"]
    assert link.refused_senders is not None
    assert station.getsockname() not in link.refused_senders
    link.send_all([rover_heartbeat(), telemetry()])
    assert kinds(received(station)) == ["HEARTBEAT", "ATTITUDE"]


def test_only_a_signed_udpin_link_told_to_keeps_refused_senders():
    """Not an unsigned one, not a udpout one, and not the flight controller's."""
    made = [open_link(url, source_system=1, source_component=191, name="gcs",
                      signing_key=key, tell_refused=tell)
            for url, key, tell in (("udpin:127.0.0.1:0", None, True),
                                   ("udpout:127.0.0.1:9", KEY, True),
                                   ("udpin:127.0.0.1:0", KEY, False))]
    try:
        assert [link.refused_senders for link in made] == [None, None, None]
    finally:
        for link in made:
            link.close()



def test_a_peer_that_sends_an_unsigned_packet_gets_its_heartbeat_once_not_a_hint_too(
        link, sockets):
    """A peer already gets the heartbeat and the core's own refusal text (at most once a
    second): the link does not send it a second heartbeat of its own."""
    pilot = sockets()
    deliver(link, pilot, gcs_heartbeat(sender(KEY)))
    assert deliver(link, pilot, gcs_heartbeat(sender())) == []  # refused, from a peer
    link.send(rover_heartbeat())
    assert kinds(received(pilot)) == ["HEARTBEAT"]
    assert link.refused_senders is not None and len(link.refused_senders) == 0


def test_a_hint_the_kernel_refuses_to_send_is_counted_and_the_heartbeat_still_goes_out(
        caplog: pytest.LogCaptureFixture):
    """(A refused sender at an address the kernel will not send to, here the broadcast
    address without SO_BROADCAST: EACCES. The hint is a failed send, counted, never raised,
    and the warning says why; the peers' heartbeat went out before it.)"""
    link = signed_udpin()
    try:
        link.refused_senders.refused(("255.255.255.255", 9), Check.UNSIGNED, link.clock())
        with caplog.at_level(logging.WARNING, logger="mecanum_mav.io.links"):
            assert link.send(rover_heartbeat())  # (no peer yet: nothing to send it to)
        assert (link.hints_sent, link.send_errors) == (0, 1)
        assert caplog.messages == [f"gcs: send failed (1 so far): {EACCES}"]
    finally:
        link.close()


def test_a_hint_that_cannot_be_made_is_counted_and_said_why_and_never_raises(
        caplog: pytest.LogCaptureFixture):
    """(A refusal of a kind that has no text to tell, the table's ``refused`` being the
    link's own to call: no hint goes out, the failure is a failed send with its reason in
    the warning, and the heartbeat to the peers was sent.)"""
    link = signed_udpin()
    try:
        link.refused_senders.refused(("127.0.0.1", 9), Check.ACCEPTED, link.clock())
        with caplog.at_level(logging.WARNING, logger="mecanum_mav.io.links"):
            assert link.send(rover_heartbeat())
        assert (link.hints_sent, link.send_errors) == (0, 1)
        assert len(caplog.messages) == 1
        assert caplog.messages[0].startswith("gcs: send failed (1 so far): ")
        assert "accepted" in caplog.messages[0]  # the kind it found no text for
    finally:
        link.close()


def test_a_heartbeat_the_signed_link_could_not_send_is_reported_failed_and_tells_no_one(
        caplog: pytest.LogCaptureFixture):
    """``Link.send`` returns False on a failure (counted, warned about under the link's
    name): here the one peer, signing, is at an address the kernel refuses (EACCES). A
    refused sender waiting is not told with a heartbeat that went nowhere."""
    url = "udpin:127.0.0.1:0"
    link = open_link(url, source_system=1, source_component=191, name="gcs",
                     signing_key=KEY, tell_refused=True)
    try:
        assert (link.url, link.name) == (url, "gcs")
        assert link.parse_datagram(gcs_heartbeat(sender(KEY)), ("255.255.255.255", 9))
        link.refused_senders.refused(("127.0.0.1", 9), Check.UNSIGNED, link.clock())
        with caplog.at_level(logging.WARNING, logger="mecanum_mav.io.links"):
            assert link.send(rover_heartbeat()) is False
        assert (link.send_errors, link.hints_sent) == (1, 0)
        assert caplog.messages == [f"gcs: send failed (1 so far): {EACCES}"]
    finally:
        link.close()
