"""``mecanum-mav setup-fc --apply`` and ``--reboot`` (app/setupfc.py) against an ArduPilot
parameter service played by the test on a real socket (127.0.0.1, port 0, a thread of its
own): what ``--apply`` writes and how it makes ArduPilot keep it, the reboot and what it
changes, and each way the board can fail the run (the exit statuses of the module docstring:
0 safe, 1 hazard or not accepted, 2 not reachable or the reboot failed, 3 reboot pending)."""

from __future__ import annotations

import io
import selectors
import socket
import threading
import time
from typing import Any

import pytest
from support import ClosedOnExit, fc_heartbeat

from mecanum_mav.app import setupfc
from mecanum_mav.config.params import Params
from mecanum_mav.protocol import paramread
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.fcsetup import check, safe_settings

SAFE = {**safe_settings(Params(), {"RCMAP_THROTTLE": 3.0}), "RCMAP_THROTTLE": 3.0,
        "RC_PROTOCOLS": 1.0}
"""A board set up as the companion needs (channels 1-4 scaled pass-through, throttle on 3)."""

ALL_WRONG = {
    "MAV_GCS_SYSID": 255, "SERVO_RC_FS_MSK": 0, "RC_OVERRIDE_TIME": 3.0, "ARMING_RUDDER": 2,
    "RCMAP_THROTTLE": 3, "FS_THR_ENABLE": 1, "RC_PROTOCOLS": 1,
    **{f"SERVO{ch}_FUNCTION": 50 + ch for ch in (1, 2, 3, 4)},
    **{f"{kind}{ch}_{part}": value for ch in (1, 2, 3, 4) for kind in ("RC", "SERVO")
       for part, value in (("MIN", 1100), ("TRIM", 1520), ("MAX", 1900))},
    **{f"RC{ch}_DZ": 30 for ch in (1, 2, 3, 4)},
}
"""A board on plain pass-through whose every range, trim, dead zone and timeout differs from
what the companion needs: no value the companion writes is one the board already has."""

BOARD_BOOTED_S = 600.0
"""How long the board has been running when the test starts (its SYSTEM_TIME)."""


class ParamBoard(ClosedOnExit):
    """ArduPilot's parameter service, as far as setup-fc uses it, on UDP (setup-fc reaches it
    with ``udpout:``) or TCP (it listens; ``tcp:``), in a thread:

    - HEARTBEAT at 5 Hz once it has a peer (as system ``sysid``);
    - PARAM_REQUEST_READ answered with PARAM_VALUE (names it lacks are not answered);
    - PARAM_SET taken and echoed with PARAM_VALUE (``drop_sets``: so many of a name ignored
      first; ``keeps``: the value a name keeps whatever is set), stored only if the name is
      stored already or the value differs from its default (``AP_Param::save_sync``); every
      value starts as its default, unstored;
    - MAV_CMD_REQUEST_MESSAGE for SYSTEM_TIME answered, then acknowledged;
    - MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN acknowledged with ``reboot_result`` (None: not
      answered), then a reboot: deaf and silent for ``down_s``, every setting not stored
      back at its default (``boot_defaults``: the defaults from that boot on), its time since
      boot starting from 0 again; ``reboots=False``: it acknowledges and runs on;
    - ``power_cycled_at_read``: it reboots by itself on that PARAM_REQUEST_READ (counted
      from 1), unanswered. A TCP board closes the connection when it reboots, as a rebooting
      board's port goes away.

    What it received is kept: :attr:`sets` (each PARAM_SET's value, per name) and
    :attr:`boots`."""

    def __init__(self, values: dict[str, float], *, kind: str = "udp", sysid: int = 1,
                 boot_defaults: dict[str, float] | None = None,
                 drop_sets: dict[str, int] | None = None,
                 keeps: dict[str, float] | None = None,
                 reboot_result: int | None = mavlink.MAV_RESULT_ACCEPTED,
                 reboots: bool = True, down_s: float = 0.0,
                 power_cycled_at_read: int | None = None) -> None:
        self.params = {k: float(v) for k, v in values.items()}
        self.defaults = dict(self.params)
        self.stored: set[str] = set()
        self.boot_defaults = dict(boot_defaults or {})
        self.drop_sets = dict(drop_sets or {})
        self.keeps = dict(keeps or {})
        self.reboot_result, self.reboots, self.down_s = reboot_result, reboots, down_s
        self.power_cycled_at_read = power_cycled_at_read
        self.reads = 0
        self.sets: dict[str, list[float]] = {}
        self.boots = 0
        self.sysid = sysid
        self.tcp = kind == "tcp"
        self.mav: Any = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=1)
        self._booted_s = time.monotonic() - BOARD_BOOTED_S
        self._down_until = -1.0
        self._lock = threading.Lock()
        self.sock = socket.socket(socket.AF_INET,
                                  socket.SOCK_STREAM if self.tcp else socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        if self.tcp:
            self.sock.listen(1)
        port = self.sock.getsockname()[1]
        self.url = f"{'tcp' if self.tcp else 'udpout'}:127.0.0.1:{port}"
        self._conn: socket.socket | None = None
        self._peer: Any = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ the wire

    def _send(self, msg: Any) -> None:
        data = msg.pack(self.mav)
        try:
            if self._conn is not None:
                self._conn.sendall(data)
            elif not self.tcp and self._peer is not None:
                self.sock.sendto(data, self._peer)
        except OSError:
            pass

    def _serve(self) -> None:
        parser: Any = mavlink.MAVLink(None)
        next_beat = 0.0
        with selectors.DefaultSelector() as selector:
            selector.register(self.sock, selectors.EVENT_READ)
            while not self._stop.is_set():
                now = time.monotonic()
                up = now >= self._down_until
                if up and now >= next_beat and (self._peer is not None or self._conn):
                    self._send(fc_heartbeat(self.mav))
                    next_beat = now + 0.2
                for key, _ in selector.select(0.02):
                    sock: Any = key.fileobj
                    if self.tcp and sock is self.sock:
                        if not up:
                            continue  # (booting: the connection waits in the backlog)
                        self._conn, self._peer = self.sock.accept()
                        selector.register(self._conn, selectors.EVENT_READ)
                        parser = mavlink.MAVLink(None)
                        continue
                    try:
                        data, peer = (sock.recv(65536), None) if self.tcp else \
                            sock.recvfrom(65536)
                    except OSError:
                        data, peer = b"", None
                    if self.tcp and not data:
                        selector.unregister(sock)
                        sock.close()
                        self._conn = None
                        continue
                    if time.monotonic() < self._down_until:
                        continue  # rebooting: deaf
                    if peer is not None:
                        self._peer = peer
                    for msg in parser.parse_buffer(data) or []:
                        if self._handle(msg):  # rebooted: what came with it is lost
                            if self._conn is not None:
                                selector.unregister(self._conn)
                                self._conn.close()
                                self._conn = None
                            break

    # ------------------------------------------------------------------ the service

    def _value(self, name: str) -> Any:
        return self.mav.param_value_encode(name.encode(), self.params[name],
                                           mavlink.MAV_PARAM_TYPE_REAL32, len(self.params),
                                           list(self.params).index(name))

    def _handle(self, msg: Any) -> bool:
        """Answer one message; whether the board rebooted."""
        kind = msg.get_type()
        if getattr(msg, "target_system", self.sysid) != self.sysid:
            return False
        if kind == "PARAM_REQUEST_READ":
            self.reads += 1
            if self.reads == self.power_cycled_at_read:
                self._reboot()
                return True
            if msg.param_id in self.params:
                self._send(self._value(msg.param_id))
        elif kind == "PARAM_SET" and msg.param_id in self.params:
            name = msg.param_id
            with self._lock:
                self.sets.setdefault(name, []).append(float(msg.param_value))
                if self.drop_sets.get(name, 0) > 0:
                    self.drop_sets[name] -= 1
                    return False
                value = self.keeps.get(name, float(msg.param_value))
                if name in self.stored or value != self.defaults[name]:
                    self.stored.add(name)
                self.params[name] = value
            self._send(self._value(name))
        elif kind == "COMMAND_LONG" and msg.command == mavlink.MAV_CMD_REQUEST_MESSAGE:
            if int(msg.param1) == mavlink.MAVLINK_MSG_ID_SYSTEM_TIME:
                boot_ms = int((time.monotonic() - self._booted_s) * 1000)
                self._send(self.mav.system_time_encode(int(time.time() * 1e6), boot_ms))
            self._send(self.mav.command_ack_encode(msg.command, mavlink.MAV_RESULT_ACCEPTED))
        elif kind == "COMMAND_LONG" and msg.command == mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
            if self.reboot_result is None:
                return False
            self._send(self.mav.command_ack_encode(msg.command, self.reboot_result))
            if self.reboot_result == mavlink.MAV_RESULT_ACCEPTED and self.reboots:
                self._reboot()
                return True
        return False

    def _reboot(self) -> None:
        with self._lock:
            self.boots += 1
            self.defaults.update(self.boot_defaults)
            for name in self.params:
                if name not in self.stored:
                    self.params[name] = self.defaults[name]
        now = time.monotonic()
        self._down_until = now + self.down_s
        self._booted_s = now

    @property
    def heard(self) -> bool:
        """Whether anyone has reached the board."""
        return self._peer is not None

    def hazards(self) -> set[str]:
        """The settings of the board now that are hazards for the default companion."""
        with self._lock:
            return {f.name for f in check(Params(), self.params) if f.hazard}

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        if self._conn is not None:
            self._conn.close()
        self.sock.close()


def setup_fc(board: ParamBoard, *, apply: bool = False,
             reboot: bool = False) -> tuple[int, str]:
    """setup-fc against ``board``: (exit status, what it printed on stdout)."""
    out = io.StringIO()
    status = setupfc.run_setup(board.url, Params(), apply=apply, reboot=reboot, out=out)
    return status, out.getvalue()


def rows(text: str, name: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith(name + " ")]


# --------------------------------------------------------------------------- --apply


def test_apply_writes_every_needed_setting_of_an_unsafe_board_once_and_calls_it_safe():
    with ParamBoard(ALL_WRONG) as board:
        assert board.hazards()
        status, text = setup_fc(board, apply=True)
        assert status == 0, text
        assert board.hazards() == set()
        wanted = safe_settings(Params(), ALL_WRONG)
        changed = {n for n, v in wanted.items() if ALL_WRONG.get(n) != v}
        assert board.sets == {n: [float(wanted[n])] for n in changed}  # no neighbour first
        assert f"wrote {len(changed)} of {len(changed)} settings ({len(changed)} changed, 0 " \
            "stored by writing a neighbour first)" in text
        assert "after --apply:" in text and text.rstrip().endswith(
            "the flight controller is set up safely for the companion")


def test_a_value_the_board_has_is_written_as_a_neighbour_first_so_a_reboot_keeps_it():
    """ArduPilot does not store a value equal to its default, and Rover sets its dead zones'
    defaults at boot: RC1_DZ 0, unstored, would come back as 30 after the reboot."""
    with ParamBoard(SAFE, boot_defaults={"RC1_DZ": 30.0}) as board:
        status, text = setup_fc(board, apply=True, reboot=True)
        assert status == 0, text
        assert board.sets["RC1_DZ"] == [1.0, 0.0]  # the neighbour, then the value
        assert board.boots == 1 and board.params["RC1_DZ"] == 0.0
        assert "0 changed" in text and "after the reboot:" in text
        assert "after --apply again" not in text  # nothing to write again


def test_apply_with_reboot_writes_again_what_the_reboot_changed_and_ends_safe():
    """FS_THR_ENABLE has no harmless neighbour: equal to its default it is not stored, and a
    boot that changes the default changes it; setup-fc sees it after the reboot and writes
    it again."""
    with ParamBoard(SAFE, boot_defaults={"FS_THR_ENABLE": 0.0}) as board:
        status, text = setup_fc(board, apply=True, reboot=True)
        assert status == 0, text
        assert "HAZARD" in rows(text.split("after the reboot:")[1], "FS_THR_ENABLE")[0]
        assert "after --apply again:" in text
        assert board.sets["FS_THR_ENABLE"] == [1.0] and board.params["FS_THR_ENABLE"] == 1.0
        assert board.boots == 1


def test_a_setting_the_board_did_not_echo_is_sent_again_until_it_is_echoed():
    with ParamBoard(ALL_WRONG, drop_sets={"ARMING_RUDDER": 1}) as board:
        status, text = setup_fc(board, apply=True)
        assert status == 0, text
        assert board.sets["ARMING_RUDDER"] == [0.0, 0.0]
        assert board.params["ARMING_RUDDER"] == 0.0


def test_a_value_the_board_will_not_take_is_not_accepted_and_remains_a_hazard(monkeypatch):
    monkeypatch.setattr(setupfc, "WRITE_DEADLINE_S", 0.6)
    with ParamBoard(ALL_WRONG, keeps={"ARMING_RUDDER": 2.0}) as board:
        status, text = setup_fc(board, apply=True)
    assert status == 1, text
    assert "; not accepted: ARMING_RUDDER" in text
    assert "HAZARD" in rows(text.split("after --apply:")[1], "ARMING_RUDDER")[0]
    assert "1 hazard(s)" in text


def test_a_new_throttle_channel_leaves_a_reboot_pending_with_exit_status_3():
    """ArduPilot reads RCMAP_THROTTLE only at boot: written, it is not in force yet."""
    with ParamBoard({**SAFE, "RCMAP_THROTTLE": 7.0}) as board:
        status, text = setup_fc(board, apply=True)
        assert status == setupfc.EXIT_REBOOT_PENDING == 3, text
        assert board.params["RCMAP_THROTTLE"] == 1.0 and board.boots == 0
    assert "REBOOT PENDING: the flight controller reads RCMAP_THROTTLE only at boot" in text
    assert "set up safely" not in text


def test_reboot_after_a_new_throttle_channel_reads_the_rebooted_board_and_calls_it_safe():
    with ParamBoard({**SAFE, "RCMAP_THROTTLE": 7.0}) as board:
        status, text = setup_fc(board, apply=True, reboot=True)
        assert status == 0, text
        assert board.boots == 1
    assert "rebooting the flight controller" in text and "REBOOT PENDING" not in text
    assert text.rstrip().endswith("the flight controller is set up safely for the companion")


def test_a_board_power_cycled_during_the_read_over_tcp_is_read_to_the_end_once_it_is_back(
        monkeypatch):
    """Its connection ends mid-read: the requests that fall due while the link is down are
    lost, not fatal, and asked again once setup-fc has connected again."""
    monkeypatch.setattr(paramread, "REPEAT_S", 0.2)  # (due twice before the link reconnects)
    with ParamBoard(SAFE, kind="tcp", down_s=0.1, power_cycled_at_read=5) as board:
        status, text = setup_fc(board)
        assert board.boots == 1
    assert status == 0, text
    assert "UNKNOWN" not in text


# --------------------------------------------------------------------------- exit status 2


def test_a_reboot_the_board_refuses_ends_with_exit_status_2_and_says_disarm_first(capsys):
    """ArduPilot refuses to reboot while armed (MAV_RESULT_DENIED)."""
    with ParamBoard(SAFE, reboot_result=mavlink.MAV_RESULT_DENIED) as board:
        status, text = setup_fc(board, reboot=True)
        assert board.boots == 0
    assert status == 2, text
    assert capsys.readouterr().err == (
        "mecanum-mav setup-fc: reboot: MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN refused (result "
        f"{mavlink.MAV_RESULT_DENIED}); disarm first\n")


def test_a_reboot_command_never_answered_ends_with_exit_status_2(monkeypatch, capsys):
    monkeypatch.setattr(setupfc, "ACK_TIMEOUT_S", 0.15)
    with ParamBoard(SAFE, reboot_result=None) as board:
        status, text = setup_fc(board, reboot=True)
    assert status == 2, text
    assert capsys.readouterr().err == (
        "mecanum-mav setup-fc: reboot: no answer to MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN\n")


@pytest.mark.parametrize("board_after_the_ack", [
    {"reboots": False},             # runs on: its time since boot never starts again
    {"down_s": 60.0},               # never heard again
], ids=["runs-on", "silent"])
def test_a_board_not_back_from_its_reboot_in_time_ends_with_exit_status_2(
        monkeypatch, capsys, board_after_the_ack: dict[str, Any]):
    monkeypatch.setattr(setupfc, "REBOOT_TIMEOUT_S", 0.4)
    with ParamBoard(SAFE, **board_after_the_ack) as board:
        status, text = setup_fc(board, reboot=True)
    assert status == 2, text
    assert capsys.readouterr().err == (
        "mecanum-mav setup-fc: reboot: the board was not back within 0.4 s\n")
    assert "after the reboot" not in text


def test_a_board_of_another_system_id_is_not_reached_exit_status_2(monkeypatch, capsys):
    """Only FC_SYSID's HEARTBEAT counts: a board that is system 2 is not the one configured."""
    monkeypatch.setattr(setupfc, "HEARTBEAT_TIMEOUT_S", 0.4)
    with ParamBoard(SAFE, sysid=2) as board:
        status, text = setup_fc(board)
        assert board.heard  # it was reached, and beat back
    assert status == 2
    assert capsys.readouterr().err == (
        f"mecanum-mav setup-fc: no HEARTBEAT from system 1 on {board.url}\n")
    assert "setting" not in text  # no table


def test_a_link_that_cannot_be_opened_ends_with_exit_status_2(tmp_path, capsys):
    device = tmp_path / "no-such-board"
    status = setupfc.run_setup(f"{device},57600", Params(), apply=False, out=io.StringIO())
    assert status == 2
    err = capsys.readouterr().err
    assert err.startswith("mecanum-mav setup-fc: cannot open fc link ") and str(device) in err
