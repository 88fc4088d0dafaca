"""The ends of the paths ``tools/bench_latency.py`` times (``tools/bench_ends.py``): the floor
relay's serial and listening ends, the pty board, and the pinning that keeps the harness and the
systems under test on separate cores."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from support import wait_until

TOOLS = Path(__file__).resolve().parent.parent / "tools"
sys.path.insert(0, str(TOOLS))

from bench_ends import (  # noqa: E402
    NOT_PINNED,
    PtyBoard,
    core_split,
    open_floor_fc,
    open_floor_gcs,
)


def test_the_floor_writes_its_packets_byte_for_byte_to_the_serial_line_the_board_reads() -> None:
    board = PtyBoard()
    send, close = open_floor_fc(board.url)
    packet = bytes(range(256))  # every byte, CR and LF among them: a raw line changes none
    try:
        send(packet)
        got = bytearray()

        def whole() -> bool:
            got.extend(board.read(4096))
            return len(got) >= len(packet)

        assert wait_until(whole, 2.0)
        assert bytes(got) == packet
    finally:
        close()
        board.close()


def test_the_board_hears_nothing_echoed_back_of_what_it_wrote() -> None:
    board = PtyBoard()
    send, close = open_floor_fc(board.url)
    try:
        board.write(b"\xfd\x09\x00\x00\x00\x01\x01\x00\x00\x00\r\n")
        send(b"mark")
        got = bytearray()
        assert wait_until(lambda: got.extend(board.read(4096)) or b"mark" in got, 2.0)
        assert bytes(got) == b"mark"
    finally:
        close()
        board.close()


def test_a_listening_floor_end_receives_what_a_ground_station_sends_to_its_port() -> None:
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))  # a port the OS hands out, free again once closed
    port = probe.getsockname()[1]
    probe.close()
    gcs, listening = open_floor_gcs(f"udpin:127.0.0.1:{port}")
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        assert listening
        assert gcs.getsockname() == ("127.0.0.1", port)
        with pytest.raises(OSError):  # bound, not connected: any ground station may send
            gcs.getpeername()
        sender.sendto(b"stick", ("127.0.0.1", port))
        got = wait_until(lambda: _recv(gcs), 2.0)
        assert got is not None
        assert got[0] == b"stick"
    finally:
        sender.close()
        gcs.close()


def _recv(sock: socket.socket) -> tuple[bytes, object] | None:
    try:
        return sock.recvfrom(2048)
    except BlockingIOError:
        return None


def test_a_sending_floor_end_reads_only_what_comes_from_its_destination() -> None:
    peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    peer.bind(("127.0.0.1", 0))
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs, listening = open_floor_gcs(f"udpout:127.0.0.1:{peer.getsockname()[1]}")
    try:
        assert not listening
        gcs.send(b"hello")
        _, address = peer.recvfrom(2048)
        stranger.sendto(b"stranger", address)
        peer.sendto(b"peer", address)
        got = wait_until(lambda: _recv(gcs), 2.0)
        assert got is not None
        assert got[0] == b"peer"
    finally:
        for sock in (peer, stranger, gcs):
            sock.close()


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two cores")
def test_the_harness_and_the_systems_under_test_get_different_cores() -> None:
    split = core_split(True)
    assert split.harness and split.sut
    assert not split.harness & split.sut
    assert core_split(False) == NOT_PINNED


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two cores")
def test_pinning_a_process_pins_the_threads_it_already_had() -> None:
    core = min(os.sched_getaffinity(0))
    script = f"""
import os, sys, threading
sys.path.insert(0, {str(TOOLS)!r})
from bench_ends import pin_self
started, done = threading.Event(), threading.Event()
seen = []
def early():
    started.set()
    done.wait()
    seen.append(os.sched_getaffinity(0))
thread = threading.Thread(target=early)
thread.start()
started.wait()
pin_self(frozenset({{{core}}}))
done.set()
thread.join()
print(sorted(seen[0]))
"""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=60, check=True).stdout
    assert out.strip() == f"[{core}]"
