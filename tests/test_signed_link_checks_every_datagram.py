"""A link with a signing key checks every datagram it receives: none of them may take the
unchecked way (the stick lane answers datagrams straight from their bytes,
``Link.unchecked`` in io/links/), and an unsigned stick is dropped."""

from __future__ import annotations

import socket

import pytest
from conftest import wait_until

from mecanum_mav.io.links import mavlink, open_link

KEY = bytes(range(32))


@pytest.mark.parametrize("url", ["udpin:127.0.0.1:0", "udpout:127.0.0.1:9"])
def test_a_link_with_a_signing_key_is_never_unchecked(url):
    signed = open_link(url, source_system=1, source_component=1, name="gcs", signing_key=KEY)
    plain = open_link(url, source_system=1, source_component=1, name="gcs")
    try:
        assert not signed.unchecked
        assert plain.unchecked  # (the same link without a key: the lane may answer it)
    finally:
        signed.close()
        plain.close()


def test_an_unsigned_stick_datagram_to_a_signing_link_gives_no_message():
    link = open_link("udpin:127.0.0.1:0", source_system=1, source_component=1, name="gcs",
                     signing_key=KEY)
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    stick = bytes(mav.manual_control_encode(1, 1000, 0, 500, 0, 0).pack(mav))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as pilot:
        pilot.sendto(stick, ("127.0.0.1", link.local_port))
        got = wait_until(link.receive_datagram, 2.0)
        assert got is not None
        assert link.parse_datagram(*got) == []
    link.close()
