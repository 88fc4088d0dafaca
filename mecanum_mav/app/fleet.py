"""A fleet on one machine behind a router, driven from one ground-station connection.

:class:`Fleet` starts N ``mecanum-mav sim --instance N`` processes and MAVProxy as the router
(one ``--master`` per rover, one ``--out`` to the ground station; MAVProxy sends what the
ground station addresses to system N to the link it last heard system N's HEARTBEAT on, and
everything the rovers send to the ground station). :func:`drive_fleet` is the drive the CI
test checks and ``tools/fleet_example.py`` draws: sticks to one rover at a time, then one
mission run by two rovers at once, each addressed by its system id.

MAVProxy picks the link by a message's ``target_system`` field; messages without one (the
ground station's HEARTBEAT, MANUAL_CONTROL, whose field is ``target``) go to its first link
only. So behind MAVProxy the rovers drive by RC_CHANNELS_OVERRIDE (MAVProxy's ``rc``, Mission
Planner's joystick), GUIDED setpoints and missions, and the HEARTBEAT that keeps their
ground-station failsafe quiet is MAVProxy's own (system 255, once a second to every link).
"""

from __future__ import annotations

import math
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

from mecanum_mav.app.cli import instance_sysid
from mecanum_mav.app.demo import demo_mission
from mecanum_mav.config.params import SPECS
from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.groundstation import ScriptedGroundStation, fleet_ground_station

__all__ = ["Fleet", "FleetDrive", "drive_fleet", "fleet_figure", "plot_fleet", "router_command"]

Vec = tuple[float, float]
STICK = 0.6
"""Stick deflection of the stick phases (of full scale)."""
StickSender = Callable[[ScriptedGroundStation, float, float], None]
"""Sends one stick message (x forward, y right, [-1, 1]) to a ground station's rover."""
STICK_PERIOD_S = 0.05
"""The ground station sends sticks at 20 Hz, as QGroundControl does."""


def router_command(master_ports: Sequence[int], gcs_url: str) -> list[str]:
    """MAVProxy as a router: one ``--master=udpin:127.0.0.1:PORT`` per rover, ``--out`` to the
    ground station, no console (``--daemon``), routing from the start without waiting for a
    rover's HEARTBEAT (``--nowait``), nothing written to disk (``--no-state``), no
    ground-station modules of its own (``--default-modules=``). The program name is
    ``mavproxy.py`` (first element)."""
    return ["mavproxy.py", *(f"--master=udpin:127.0.0.1:{p}" for p in master_ports),
            f"--out={gcs_url}", "--daemon", "--nowait", "--no-state", "--default-modules="]


def free_udp_ports(count: int) -> list[int]:
    """``count`` distinct UDP ports the OS just handed out on 127.0.0.1 (for programs that
    cannot bind port 0 and say which port they got, like MAVProxy's ``--master``)."""
    with ExitStack() as stack:
        socks = [stack.enter_context(socket.socket(socket.AF_INET, socket.SOCK_DGRAM))
                 for _ in range(count)]
        for sock in socks:
            sock.bind(("127.0.0.1", 0))
        return [int(sock.getsockname()[1]) for sock in socks]


class Fleet:
    """N simulated rovers (``mecanum-mav sim --instance 0 .. N-1``, real processes) behind
    MAVProxy, and one ground station on one UDP socket (:attr:`stations`, by system id).

    The rovers' ports come from the OS (``--gcs`` given explicitly: instance N's own port,
    14560 + 10 N, may be taken on a shared machine); their system ids come from
    ``--instance``. Each process's output goes to ``workdir/instanceN.log``, MAVProxy's to
    ``workdir/router.log``; each runs in ``workdir`` (what it writes by a relative path stays
    there) and reads nothing from the terminal. MAVProxy is the ``mavproxy.py`` installed
    beside this Python, else the one on ``PATH``; it runs on this Python, as the rovers do
    (:attr:`processes`, the router first). Use as a context manager: everything is stopped on
    exit (a process that ignores SIGTERM is killed).

    Raises:
        FileNotFoundError: MAVProxy is not installed (``pip install '.[test]'``).
    """

    def __init__(self, count: int, workdir: Path) -> None:
        exe = shutil.which("mavproxy.py", path=str(Path(sys.executable).parent)) or \
            shutil.which("mavproxy.py")
        if exe is None:
            raise FileNotFoundError("mavproxy.py not found (pip install MAVProxy)")
        self.sysids = [instance_sysid(i) for i in range(count)]
        self.workdir = workdir
        self._stack = ExitStack()
        self.processes: list[subprocess.Popen[bytes]] = []
        try:
            self.stations, self.port = fleet_ground_station(self.sysids)
            self._stack.callback(self.port.close)
            ports = free_udp_ports(count)
            self._start([exe, *router_command(ports, self.port.url)[1:]], "router.log")
            for i, port in enumerate(ports):
                self._start(["-m", "mecanum_mav", "sim", "--instance", str(i),
                             "--gcs", f"udpout:127.0.0.1:{port}"], f"instance{i}.log")
        except BaseException:
            self._stack.close()
            raise

    def _start(self, args: list[str], log_name: str) -> None:
        log = self._stack.enter_context((self.workdir / log_name).open("wb"))
        proc = subprocess.Popen([sys.executable, *args], stdout=log, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, cwd=self.workdir)
        self.processes.append(proc)
        self._stack.callback(_stop, proc)

    def log(self, name: str) -> str:
        """The text a process wrote so far (``router.log``, ``instance0.log`` ...; bytes that
        are not UTF-8 read as U+FFFD)."""
        return (self.workdir / name).read_text(errors="replace")

    def __enter__(self) -> Fleet:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._stack.close()


def _stop(proc: subprocess.Popen[bytes]) -> None:
    proc.terminate()  # SIGTERM: the companion sends neutral and releases its channels
    try:
        proc.wait(10.0)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


@dataclass
class FleetDrive:
    """What :func:`drive_fleet` did and saw, per rover (by system id); positions are each
    rover's own LOCAL_POSITION_NED (north, east, metres from where it started)."""

    paths: dict[int, list[tuple[float, float, float]]] = field(default_factory=dict)
    """(time s from the start of the drive, north m, east m) of every LOCAL_POSITION_NED."""
    moved: dict[str, dict[int, Vec]] = field(default_factory=dict)
    """Per phase (``sticks to N``, ``mission``): each rover's displacement (north, east)."""
    phases: list[tuple[str, float, float]] = field(default_factory=list)
    """(name, start s, end s) of each phase."""
    planned: dict[int, list[Vec]] = field(default_factory=dict)
    """The mission's waypoints of each rover that ran it (its local frame)."""
    auto: dict[int, tuple[float, float]] = field(default_factory=dict)
    """(AUTO accepted s, last waypoint reached s) of each rover that ran the mission."""


def drive_fleet(stations: dict[int, ScriptedGroundStation], *, mission_side_m: float = 0.6,
                stick_s: float = 1.0, timeout_s: float = 40.0) -> FleetDrive:
    """The fleet drive, each message addressed by system id (``stations`` by system id, at
    least three): every rover armed; MANUAL_CONTROL to the second rover (MAVProxy routes by a
    ``target_system`` field, which MANUAL_CONTROL lacks - its field is ``target`` - so it
    goes to the router's first link, whose rover ignores sticks not addressed to it: no rover
    moves); the same sticks as RC_CHANNELS_OVERRIDE (routed: the second rover drives forward,
    alone); RC override to the third rover (it strafes right, alone); then the same mission (a
    square of ``mission_side_m`` and its diagonal, facing north) uploaded to the first two
    and run in AUTO by both at once.

    Raises:
        RuntimeError: a rover never showed up, refused arming, the upload or AUTO, or did
            not finish the mission within ``timeout_s``.
    """
    ids = sorted(stations)
    out = FleetDrive()
    t0 = time.monotonic()
    for sysid in ids:
        # The router may have come up after a rover's first words (its "Flight controller
        # link up"): wait for a heartbeat, then retry arming until the rover accepts.
        if stations[sysid].wait("HEARTBEAT", timeout_s=20.0, since=0) is None:
            raise RuntimeError(f"rover {sysid} never showed up")
        try:
            stations[sysid].arm(timeout_s=10.0)
        except RuntimeError:
            raise RuntimeError(f"rover {sysid} refused arming") from None
    phases: list[tuple[str, int, StickSender, float, float]] = [
        (f"MANUAL_CONTROL to {ids[1]}", ids[1], _manual_control, STICK, 0.0),
        (f"RC override to {ids[1]}", ids[1], _rc_override, STICK, 0.0),
        (f"RC override to {ids[2]}", ids[2], _rc_override, 0.0, STICK)]
    for name, sysid, send, x, y in phases:
        _phase(out, name, stations,
               lambda s=sysid, f=send, x=x, y=y: _sticks(stations[s], f, x, y, stick_s), t0)
    pair = ids[:2]
    items, points = demo_mission(mission_side_m)
    for sysid in pair:
        ack = stations[sysid].upload(items)
        if ack.type != mavlink.MAV_MISSION_ACCEPTED:
            raise RuntimeError(f"rover {sysid} refused the mission ({ack.type})")
        out.planned[sysid] = [(0.0, 0.0), *points]
    last = len(items) - 1
    _phase(out, "mission", stations, lambda: _run_together(stations, pair, last, out, t0,
                                                           timeout_s), t0)
    for sysid in ids:
        out.paths[sysid] = _path(stations[sysid], t0)
    return out


def _phase(out: FleetDrive, name: str, stations: dict[int, ScriptedGroundStation],
           action: Any, t0: float) -> None:
    before = {s: _position(g) for s, g in stations.items()}
    start = time.monotonic() - t0
    action()
    after = {s: _position(g) for s, g in stations.items()}
    out.phases.append((name, start, time.monotonic() - t0))
    out.moved[name] = {s: (after[s][0] - before[s][0], after[s][1] - before[s][1])
                       for s in stations}


def _position(gcs: ScriptedGroundStation) -> Vec:
    """The rover's next LOCAL_POSITION_NED (north, east)."""
    msg = gcs.wait("LOCAL_POSITION_NED", timeout_s=2.0)
    if msg is None:
        raise RuntimeError(f"no position from rover {gcs.target[0]}")
    return float(msg.x), float(msg.y)


def _rc_override(gcs: ScriptedGroundStation, x: float, y: float) -> None:
    """One RC_CHANNELS_OVERRIDE with the forward (``x``) and right (``y``) sticks in [-1, 1]
    on the default RCMAP channels, rotation centred, every other channel left alone."""
    trim, half = int(SPECS["RCIN_TRIM"].default), 500
    channels = [65535] * 8 + [0] * 10  # 1-8: 65535 leaves a channel, 9-18: 0 does
    for key, value in (("RCMAP_THROTTLE", x), ("RCMAP_LATERAL", y), ("RCMAP_STEER", 0.0)):
        channels[int(SPECS[key].default) - 1] = trim + round(half * value)
    gcs.mav.rc_channels_override_send(*gcs.target, *channels)


def _manual_control(gcs: ScriptedGroundStation, x: float, y: float) -> None:
    gcs.sticks(round(1000 * x), round(1000 * y))


def _sticks(gcs: ScriptedGroundStation, send: StickSender, x: float, y: float,
            duration_s: float) -> None:
    """Sticks (x forward, y right, [-1, 1]) for ``duration_s`` at 20 Hz, then centred until
    the rover stands (half a second)."""
    for stick, seconds in (((x, y), duration_s), ((0.0, 0.0), 0.5)):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            send(gcs, *stick)
            gcs.pump(STICK_PERIOD_S)


def _run_together(stations: dict[int, ScriptedGroundStation], pair: Sequence[int], last: int,
                  out: FleetDrive, t0: float, timeout_s: float) -> None:
    since = {s: stations[s].mark() for s in pair}
    for sysid in pair:
        if stations[sysid].set_mode(Mode.AUTO) != mavlink.MAV_RESULT_ACCEPTED:
            raise RuntimeError(f"rover {sysid} refused AUTO")
        started = time.monotonic() - t0
        out.auto[sysid] = (started, math.nan)
    deadline = time.monotonic() + timeout_s
    waiting = set(pair)
    while waiting and time.monotonic() < deadline:
        for sysid in sorted(waiting):
            gcs = stations[sysid]
            gcs.pump(0.02)
            if gcs.received("MISSION_ITEM_REACHED", since[sysid]) and any(
                    m.seq == last for m in gcs.received("MISSION_ITEM_REACHED", since[sysid])):
                out.auto[sysid] = (out.auto[sysid][0], time.monotonic() - t0)
                waiting.discard(sysid)
    if waiting:
        raise RuntimeError(f"rovers {sorted(waiting)} did not finish the mission in time")


def _path(gcs: ScriptedGroundStation, t0: float) -> list[tuple[float, float, float]]:
    gcs.pump(0.0)
    return [(at - t0, float(m.x), float(m.y)) for m, at in
            zip(gcs.messages, gcs.arrived_s, strict=True) if m.get_type() == "LOCAL_POSITION_NED"]


def fleet_figure(drive: FleetDrive) -> Any:
    """The matplotlib figure of a fleet drive: each rover's path in its own panel (north up,
    east right; its own local frame, one scale for all panels), a line per phase in which it
    moved (one colour per phase), the planned mission dashed where it ran one, its start
    marked; each panel's legend below it. The title names the phases in which no rover
    moved."""
    from mecanum_mav.app.plots import _pyplot

    plt = _pyplot()
    ids = sorted(drive.paths)
    fig, axes = plt.subplots(1, len(ids), figsize=(4.0 * len(ids), 5.4), sharex=True,
                             sharey=True, squeeze=False)
    palette = ("tab:red", "tab:orange", "tab:green", "tab:blue", "tab:purple")
    colours = {p[0]: palette[i % len(palette)] for i, p in enumerate(drive.phases)}
    for ax, sysid in zip(axes[0], ids, strict=True):
        if sysid in drive.planned:
            pn, pe = zip(*drive.planned[sysid], strict=True)
            ax.plot(pe, pn, "o--", color="0.65", label="mission (planned)")
        points = drive.paths[sysid]
        for name, start, end in drive.phases:
            seg = [(e, n) for t, n, e in points if start <= t <= end]
            if seg and max(math.dist(seg[0], p) for p in seg) > 0.02:
                xs, ys = zip(*seg, strict=True)
                ax.plot(xs, ys, "-", lw=2, color=colours[name], label=name)
        ax.plot([0], [0], "k^", ms=8, label="start")
        ax.set_title(f"system id {sysid} (instance {sysid - 1})")
        ax.set_xlabel("east (m)")
        ax.set_aspect("equal")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=8)
    axes[0][0].set_ylabel("north (m)")
    still = [name for name, moved in drive.moved.items()
             if all(math.hypot(*d) < 0.01 for d in moved.values())]
    note = (f"\n{', '.join(still)}: no rover moved (MAVProxy routes by target_system, "
            f"which MANUAL_CONTROL lacks)") if still else ""
    fig.suptitle(f"{len(ids)} rovers behind one MAVProxy router, one ground-station "
                 "connection: sticks by system id, one mission run by two at once" + note,
                 fontsize=10)
    fig.tight_layout()
    return fig


def plot_fleet(drive: FleetDrive, path: Path) -> Path:
    """Draw each rover's path in its own panel (north up, east right; its own local frame,
    the planned mission dashed where it ran one; :func:`fleet_figure`) to ``path`` (PNG)."""
    from mecanum_mav.app.plots import _pyplot

    plt = _pyplot()
    fig = fleet_figure(drive)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path
