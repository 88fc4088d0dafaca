"""Links that drop and come back, on real ptys, sockets and a real process (issue 11.2).

The flight controller is played by the test on the far end of a serial pty (behind a symlink
the test owns, as udev's /dev/serial/by-id names are), a TCP server or a TCP client. Pulling
the cable: close the pty's master and remove the symlink (the companion's end then reads EIO),
or close the socket. Plugging it back: a new pty behind the same symlink, or a new connection.
What the core decides meanwhile is tested in virtual time in test_link_drops.py; when the link
tries to reopen (every half second) on a fake clock in test_link_timing.py. These tests keep
the causal checks, with generous deadlines; what a companion whose device is gone costs in
CPU is tools/bench_link_down.py's figure.
"""

from __future__ import annotations

import contextlib
import errno
import socket
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from sitl import CompanionProcess, free_port
from support import FlightControllerEnd, PtyFlightController, at_most_every, wait_until
from test_end_to_end import ARM, NEUTRAL, STICK_PERIOD_S, WHEELS, channels

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.io.links import PEER_TIMEOUT_S, Link, mavlink, open_link
from mecanum_mav.protocol.rcoverride import override_fields
from mecanum_mav.sim.groundstation import ScriptedGroundStation, udp_ground_station

FORWARD = override_fields(WHEELS, [2000] * 4)
BEAT_PERIOD_S = 0.1
DEADLINE_S = 15.0
"""How long a step of these tests may take before the test gives up (the loaded machine)."""
FC_DOWN = "FC link down"
ANSWER_DEADLINE_S = PEER_TIMEOUT_S / 2
"""A restarted ground station is answered before this: not after its old address was
forgotten (a peer silent for PEER_TIMEOUT_S)."""


class Pilot:
    """The test's loop: the ground station (pumped, sticks at 50 Hz while ``stick`` is set)
    and the flight controller's end (``fc``, pumped when set)."""

    def __init__(self, gcs: ScriptedGroundStation, fc_link: Link | None = None) -> None:
        self.gcs = gcs
        self.fc_link = fc_link
        """The companion's own flight-controller link, when it runs in this process."""
        self.fc: FlightControllerEnd | None = None
        self.stick: tuple[int, int, int] | None = None
        self._send_stick = at_most_every(STICK_PERIOD_S, self._stick)

    def run_until(self, done: Callable[[], Any], timeout_s: float) -> Any:
        return wait_until(done, timeout_s, pump=self._pump, pump_s=0.01)

    def _pump(self, wait_s: float) -> None:
        if self.fc is not None:
            self.fc.pump()
        if self.stick is not None:
            self._send_stick()
        self.gcs.pump(wait_s)

    def _stick(self) -> None:
        assert self.stick is not None
        x, y, r = self.stick
        self.gcs.mav.manual_control_send(1, x, y, 500, r, 0)

    def reopen_tries(self, count: int) -> bool:
        """Wait until the companion's flight-controller link has tried to reopen ``count``
        times (its reopen timer moved on each time); whether it did."""
        link = self.fc_link
        assert link is not None
        tries: list[float] = []

        def tried() -> bool:
            due = link.next_reopen_s
            if not tries or tries[-1] != due:
                tries.append(due)
            return len(tries) > count  # (the first is the timer the break set)

        return bool(self.run_until(tried, DEADLINE_S))

    def said(self, text: str, since: int = 0) -> list[str]:
        return [m.text for m in self.gcs.received("STATUSTEXT", since) if text in m.text]

    def arm(self) -> bool:
        """Arm (the sticks left alone, as a pilot does)."""
        self.stick = None

        def armed() -> bool:
            ack = self.gcs.command(ARM, 1, timeout_s=0.1)
            return ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED

        return bool(self.run_until(armed, DEADLINE_S))

    def drive(self) -> bool:
        """Full stick forward until the flight controller gets full forward."""
        assert self.fc is not None
        self.stick = (1000, 0, 0)
        fc = self.fc
        return bool(self.run_until(lambda: FORWARD in fc.overrides(), DEADLINE_S))




@pytest.mark.slow
def test_an_unplugged_serial_flight_controller_is_reported_once_and_reopened_on_its_path(
        tmp_path: Path) -> None:
    device = tmp_path / "ttyFC"
    cable = PtyFlightController(device)
    gcs, port = udp_ground_station()
    pilot = Pilot(gcs)
    pilot.fc = cable
    try:
        with CompanionProcess(port.url, f"{device},57600", tmp_path) as companion:
            assert pilot.run_until(lambda: pilot.said("Flight controller link up"), 15.0), (
                companion.log())
            assert pilot.arm() and pilot.drive(), companion.log()
            # pull the cable while driving, the pilot still pushing the stick
            since = gcs.mark()
            cable.unplug()
            pilot.fc = None
            assert pilot.run_until(lambda: pilot.said(FC_DOWN, since), DEADLINE_S), (
                companion.log())
            # plug it back in: the same path, a new pty
            cable = PtyFlightController(device)
            pilot.fc = cable
            plugged = time.monotonic()
            fc = cable
            assert pilot.run_until(lambda: fc.messages, DEADLINE_S), companion.log()
            reopened_s = (fc.first_byte_s or plugged) - plugged
            first = fc.messages[0]
            assert first.get_type() == "RC_CHANNELS_OVERRIDE" and channels(first) == NEUTRAL
            assert pilot.run_until(lambda: pilot.said("Flight controller link up", since),
                                   DEADLINE_S)
            assert all(o == NEUTRAL for o in fc.overrides())  # the stick is still pushed
            assert pilot.arm() and pilot.drive(), companion.log()
            said = [m.text for m in gcs.received("STATUSTEXT", since)]
            log = companion.log()
            assert companion.proc.poll() is None, log
    finally:
        cable.unplug()
        port.close()
    print(f"serial: first byte {reopened_s:.3f} s after the device reappeared")
    assert said.count("FC link down: device gone; reconnecting") == 1, said
    assert said.count("FC link reconnected") == 1, said
    assert log.count(FC_DOWN) == 1, log


@contextlib.contextmanager
def companion_with_fc(fc_url: str) -> Iterator[Pilot]:
    """An in-process companion between a UDP ground station and ``fc_url``; the pilot."""
    gcs, port = udp_ground_station()
    companion = Companion(Params(), port.url, fc_url)
    companion.start()
    pilot = Pilot(gcs, companion.fc)
    try:
        yield pilot
    finally:
        companion.close()
        port.close()
        if pilot.fc is not None:
            pilot.fc.close()


@pytest.mark.slow
def test_a_tcp_flight_controller_that_closes_is_reported_once_and_reconnected(
        tmp_path: Path) -> None:
    server = socket.create_server(("127.0.0.1", 0))
    address = server.getsockname()
    servers = [server]
    with contextlib.ExitStack() as cleanup, companion_with_fc(
            f"tcp:{address[0]}:{address[1]}") as pilot:
        cleanup.callback(lambda: [s.close() for s in servers])
        pilot.fc = FlightControllerEnd.on_socket(server.accept()[0])
        assert pilot.run_until(lambda: pilot.said("Flight controller link up"), DEADLINE_S)
        assert pilot.arm() and pilot.drive()
        # the flight controller goes away altogether: its connection and its server
        since = pilot.gcs.mark()
        pilot.fc.close()
        server.close()
        pilot.fc = None
        closed = time.monotonic()
        assert pilot.run_until(lambda: pilot.said(FC_DOWN, since), DEADLINE_S)
        assert pilot.reopen_tries(2)  # connects refused meanwhile
        server = socket.create_server(address)  # back on the same port
        servers.append(server)
        server.setblocking(False)
        back = time.monotonic()

        def accepted() -> socket.socket | None:
            try:
                return server.accept()[0]
            except BlockingIOError:
                return None

        sock = pilot.run_until(accepted, DEADLINE_S)
        assert sock is not None
        reconnect_s = time.monotonic() - back
        pilot.fc = fc = FlightControllerEnd.on_socket(sock)
        assert pilot.run_until(lambda: fc.messages, DEADLINE_S)
        assert fc.overrides()[:1] == [NEUTRAL] and fc.messages[0].get_type() == (
            "RC_CHANNELS_OVERRIDE")
        assert pilot.run_until(lambda: pilot.said("Flight controller link up", since),
                               DEADLINE_S)
        assert pilot.arm() and pilot.drive()
        said = pilot.said("FC link", since)
    print(f"tcp: reconnected {reconnect_s:.3f} s after the server was back "
          f"({back - closed:.1f} s away)")
    assert said == ["FC link down: closed by the peer; reconnecting", "FC link reconnected"]


def test_a_tcpin_flight_controller_client_that_leaves_is_reported_once_and_a_new_one_heard(
        ) -> None:
    tcp_port = free_port(socket.SOCK_STREAM)
    with companion_with_fc(f"tcpin:127.0.0.1:{tcp_port}") as pilot:
        pilot.fc = FlightControllerEnd.on_socket(socket.create_connection(("127.0.0.1", tcp_port)))
        assert pilot.run_until(lambda: pilot.said("Flight controller link up"),
                               DEADLINE_S)
        since = pilot.gcs.mark()
        pilot.fc.close()
        pilot.fc = None
        assert pilot.run_until(lambda: pilot.said(FC_DOWN, since), DEADLINE_S)
        start = time.monotonic()
        pilot.fc = fc = FlightControllerEnd.on_socket(
            socket.create_connection(("127.0.0.1", tcp_port)))
        assert pilot.run_until(lambda: pilot.said("FC link reconnected", since),
                               DEADLINE_S)
        heard_s = time.monotonic() - start
        assert pilot.run_until(lambda: fc.messages, DEADLINE_S)
        assert fc.messages[0].get_type() == "RC_CHANNELS_OVERRIDE"
        assert channels(fc.messages[0]) == NEUTRAL
        assert pilot.run_until(lambda: pilot.said("Flight controller link up", since),
                               DEADLINE_S)
        assert pilot.arm() and pilot.drive()
        said = pilot.said("FC link", since)
    print(f"tcpin: the new client heard after {heard_s:.3f} s")
    assert said == ["FC link down: client left; reconnecting", "FC link reconnected"]


def test_a_ground_station_restarting_on_a_new_port_is_heard_and_answered_at_once() -> None:
    companion = Companion(Params(), "udpin:127.0.0.1:0", "udpin:127.0.0.1:0")
    companion.start()
    target = f"udpout:127.0.0.1:{companion.gcs.local_port}"
    stations = []
    try:
        for _ in range(2):  # the ground station, then the same after a restart
            gcs, gcs_port = udp_ground_station(target)
            stations.append(gcs_port)
            gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            gcs.mav.param_request_read_send(1, 1, b"SYSID_THISMAV", -1)
            # answered before the old address could have been forgotten (PEER_TIMEOUT_S)
            value = gcs.wait("PARAM_VALUE", timeout_s=ANSWER_DEADLINE_S, since=0)
            assert value is not None and value.param_id == "SYSID_THISMAV"
            assert gcs.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1, ANSWER_DEADLINE_S,
                            since=0)
            assert gcs_port.link.local_port not in {s.link.local_port for s in stations[:-1]}
            gcs_port.close()
    finally:
        companion.close()
        for gcs_port in stations:
            gcs_port.close()


class _UnresolvableConnect(socket.socket):
    """A socket whose connect finds its host name no longer resolves (an mDNS name after the
    network dropped): ``connect_ex`` raises instead of returning an error code."""

    def connect_ex(self, address: object) -> int:
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")


class _NoRouteConnect(socket.socket):
    """A socket whose non-blocking connect fails at once (the kernel has no route to the
    address: ENETUNREACH comes back from connect itself, not later)."""

    def connect_ex(self, address: object) -> int:
        return errno.ENETUNREACH


class _ImmediateConnect(socket.socket):
    """A socket whose non-blocking connect completes at once (return code 0, which a kernel
    may give for a local address)."""

    def connect_ex(self, address: object) -> int:
        self.settimeout(1.0)  # (blocking, but never for ever)
        try:
            return super().connect_ex(address)
        finally:
            self.setblocking(False)


@contextlib.contextmanager
def _broken_tcp_link() -> Iterator[Link]:
    """A ``tcp:`` link whose board accepted it and went away: down, its server still
    listening on 127.0.0.1 (closed after, with the link)."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        link = open_link(f"tcp:127.0.0.1:{server.getsockname()[1]}", source_system=255,
                         source_component=190, name="fc")
        try:
            board, _ = server.accept()
            board.close()  # the board goes away: the link breaks on its next read
            assert wait_until(lambda: link.read() == [] and not link.up, 2.0)
            yield link
        finally:
            link.close()


def test_a_tcp_reconnect_that_completes_at_once_brings_the_link_up(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A non-blocking connect may complete at once (code 0): that try connected, the link is
    up on it."""
    from mecanum_mav.io.links import tcp

    with _broken_tcp_link() as link:
        monkeypatch.setattr(tcp.socket, "socket", _ImmediateConnect)
        assert wait_until(lambda: link.reopen(link.next_reopen_s), 2.0)
        assert link.up


@pytest.mark.parametrize("failure", ["name", "files", "no route"])
def test_a_tcp_link_whose_reconnect_cannot_resolve_or_open_a_socket_stays_down_and_tries_again(
        failure: str, monkeypatch: pytest.MonkeyPatch,
        caplog: pytest.LogCaptureFixture) -> None:
    """Reconnecting never raises into the loop: a name that does not resolve, a process out
    of descriptors, or no route, is a failed attempt like a refused one, and the debug log says
    which."""
    from mecanum_mav.io.links import tcp

    with _broken_tcp_link() as link:
        if failure == "name":
            monkeypatch.setattr(tcp.socket, "socket", _UnresolvableConnect)
        elif failure == "no route":
            monkeypatch.setattr(tcp.socket, "socket", _NoRouteConnect)
        else:
            def out_of_files(*args: object) -> socket.socket:
                raise OSError(errno.EMFILE, "Too many open files")
            monkeypatch.setattr(tcp.socket, "socket", out_of_files)
        with caplog.at_level("DEBUG", logger="mecanum_mav"):
            assert link.reopen(link.next_reopen_s) is False
        assert not link.up
        why = {"name": f"[Errno {socket.EAI_NONAME}] Name or service not known",
               "files": f"[Errno {errno.EMFILE}] Too many open files",
               "no route": f"[Errno {errno.ENETUNREACH}] Network is unreachable"}[failure]
        assert [r.getMessage() for r in caplog.records if r.levelname == "DEBUG"] == [
            f"fc: reconnecting failed: {why}"]
        monkeypatch.undo()
        assert wait_until(lambda: link.reopen(link.next_reopen_s), 2.0)  # (and it can)
        assert link.up
