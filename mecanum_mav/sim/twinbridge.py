"""The twin's physics: ArduPilot SITL's JSON backend (:mod:`mecanum_mav.sim.sitljson`) driving
the MuJoCo chassis (:mod:`mecanum_mav.sim.mujocochassis`) in lockstep.

The firmware paces the pair: it sends a servo packet per frame and waits for the answer.
:class:`BridgeCore` (no I/O) takes each packet's bytes and returns the answer:

- a packet with a new ``frame_count``: the four wheels' pulse widths (:class:`WheelMap`: per
  wheel FL, FR, RL, RR a servo channel and a sign) become wheel commands in [-1, 1] as the
  simulated board reads them (:meth:`~mecanum_mav.control.pwm.WheelOutput.command_from_pulse`
  over the wheel's ``MOT_<W>_MIN/TRIM/MAX``; a pulse of 0, no output, is 0 = stop), the
  chassis steps ``1 / frame_rate`` s, and the answer carries the chassis' new state;
- the same ``frame_count`` again (the firmware resends when an answer was late): the same
  answer again, no step (:attr:`BridgeStats.repeated`);
- a count that skips ahead: one step, the gap counted (:attr:`BridgeStats.dropped`); a count
  that goes back (the firmware restarted, e.g. ``setup-fc --reboot``): one step, counted in
  :attr:`BridgeStats.restarts`; the physics goes on (a rebooted board does not move the robot)
  but the time the firmware is told starts again from 0 (a restarted firmware's clock takes
  the first timestamp as its time since boot; setup-fc tells a reboot by that clock);
- anything else (wrong magic, wrong size): ignored, counted, never an answer.

What it tells the firmware (:class:`ChassisSensors`), all in NED/FRD: physics time, the gyro
(body rates from MuJoCo), the specific force in body FRD (the mean acceleration over the
frame minus gravity, rotated into the body: ``(0, 0, -g)`` at rest), position NED from the
start, roll/pitch/yaw, velocity NED. Every frame it records the truth (:class:`TruthSample`),
and every :data:`~mecanum_mav.sim.twinrecord.CONTACTS_PERIOD_S` of physics the wheels'
contacts with the floor (a chassis that has them).

:class:`BridgeProcess` serves the core in a process of its own (what the twin uses),
:class:`TwinBridge` in a thread; the counters and the truth go to a
:class:`~mecanum_mav.sim.twinrecord.TwinRecord` (re-exported here with its types).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import select
import selectors
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from mecanum_mav.control.pwm import PwmMap, WheelOutput
from mecanum_mav.sim.firmware import kill_group
from mecanum_mav.sim.physics import PhysicsUnavailableError, contacts_of, require_mujoco
from mecanum_mav.sim.sitljson import PhysicsState, ServoPacket, decode_servo_packet, encode_state
from mecanum_mav.sim.twinrecord import (
    BUSY_S,
    COMMANDS,
    CONTACTS_PERIOD_S,
    DROPPED,
    FIRST_WALL,
    FRAME_RATE,
    FRAMES,
    LAST_WALL,
    MALFORMED,
    PHYSICS_S,
    PULSES,
    REPEATED,
    RESTARTS,
    TRUTH_CAPACITY,
    BridgeStats,
    TruthSample,
    TwinRecord,
    blank,
    sample_row,
)

if TYPE_CHECKING:  # (mujoco is an optional extra: only the twin imports it)
    from mecanum_mav.sim.mujocochassis import MujocoChassis

__all__ = ["DEFAULT_WHEEL_MAP", "TRUTH_CAPACITY", "BridgeCore", "BridgeProcess", "BridgeStats",
           "ChassisSensors", "TruthSample", "TwinBridge", "TwinRecord", "WheelMap",
           "bridge_main", "bridge_socket", "sample_row", "serve"]

DEFAULT_WHEEL_MAP: tuple[tuple[int, float], ...] = ((1, 1.0), (2, 1.0), (3, 1.0), (4, 1.0))
"""Servo channel (1-based) and sign of FL, FR, RL, RR: SERVO1..4, as the companion's
pass-through board puts them (CONVENTIONS.md)."""
_NWU_TO_NED = np.diag([1.0, -1.0, -1.0])
"""MuJoCo's world is x north, y west, z up and the body x forward, y left, z up: flipping y
and z turns either into NED / FRD."""


class WheelMap:
    """Servo outputs -> the four wheel commands FL, FR, RL, RR, through four ESCs.

    Each ESC reads its pulse as the simulated board does
    (:meth:`~mecanum_mav.control.pwm.WheelOutput.command_from_pulse`) and, as a car ESC does,
    drives only once it has seen neutral: from power-up, and again after a loss of signal
    (pulse 0, no output), it holds the wheel (command 0) until a pulse inside its dead band
    (``|command| < esc_dead_band``) arms it. (This SITL sends 1500 us on SERVO1..4 before the
    firmware runs, which arms them, then 1000 us on SERVO1 alone for about 20 ms at every
    boot and while setup-fc changes SERVO1_FUNCTION: FL turns backwards briefly, and the
    chassis starts the twin turned about 1 degree and 5 mm from where it stood.)

    Args:
        outputs: each wheel's pulse range (``MOT_<W>_MIN/TRIM/MAX``) and reverse
            (``MOT_<W>_REV``), from a :class:`~mecanum_mav.control.pwm.PwmMap`; its channel
            is not used (``channels`` says which servo drives the wheel).
        channels: per wheel FL, FR, RL, RR ``(servo channel 1-based, sign)``; a negative sign
            is a motor wired the other way round.
        esc_dead_band: the ESCs' dead band, a fraction of full command (``SIM_ESC_DZ``).

    Raises:
        ValueError: not four entries, a channel outside 1..32, or a sign of 0.
    """

    def __init__(self, outputs: PwmMap, channels: Sequence[tuple[int, float]] = DEFAULT_WHEEL_MAP,
                 esc_dead_band: float = 0.02) -> None:
        if len(channels) != 4:
            raise ValueError(f"need 4 (channel, sign) pairs FL, FR, RL, RR, got {len(channels)}")
        self._wheels: list[tuple[int, WheelOutput]] = []
        for (channel, sign), out in zip(channels, outputs.wheels, strict=True):
            if not 1 <= int(channel) <= 32 or not (math.isfinite(sign) and sign != 0.0):
                raise ValueError(f"bad wheel map entry ({channel}, {sign})")
            esc = WheelOutput(int(channel), out.minimum, out.trim, out.maximum,
                              out.reversed != (sign < 0.0))
            self._wheels.append((int(channel) - 1, esc))
        self._band = max(float(esc_dead_band), 1e-9)
        self._armed = [False, False, False, False]

    def pulses(self, pwm: Sequence[int]) -> tuple[int, int, int, int]:
        """The pulse widths (us) of the wheels' channels FL, FR, RL, RR (0: none)."""
        fl, fr, rl, rr = (pwm[i] if i < len(pwm) else 0 for i, _ in self._wheels)
        return (fl, fr, rl, rr)

    def commands(self, pwm: Sequence[int]) -> tuple[float, float, float, float]:
        """Wheel commands FL, FR, RL, RR in [-1, 1] from one frame's servo outputs (SERVO1
        first): 0 for a channel that outputs nothing (pulse 0, or not in the packet) and for
        an ESC that has not seen neutral since it last had no signal."""
        out = [0.0, 0.0, 0.0, 0.0]
        for wheel, (i, esc) in enumerate(self._wheels):
            pulse = pwm[i] if i < len(pwm) else 0
            if pulse <= 0:
                self._armed[wheel] = False
                continue
            command = esc.command_from_pulse(pulse)
            if not self._armed[wheel]:
                self._armed[wheel] = abs(command) < self._band
                continue
            out[wheel] = command
        return (out[0], out[1], out[2], out[3])


class ChassisSensors:
    """Reads a :class:`~mecanum_mav.sim.mujocochassis.MujocoChassis` as the firmware's JSON
    sensors (:class:`~mecanum_mav.sim.sitljson.PhysicsState`), in NED/FRD.

    The specific force is the mean acceleration since the last reading (the velocity change
    over the physics time between them, as an IMU's delta-velocity) minus gravity, in the
    body frame; gyro rates are MuJoCo's body angular velocity now.
    """

    def __init__(self, chassis: MujocoChassis) -> None:
        self._chassis = chassis
        self._gravity_ned = _NWU_TO_NED @ np.asarray(chassis.model.opt.gravity, dtype=float)
        self._z0 = float(chassis.data.qpos[2])
        self._velocity = self._velocity_ned()
        self._mujoco_time = float(chassis.data.time)
        self._accel_ned = np.zeros(3)

    def _velocity_ned(self) -> np.ndarray:
        velocity: np.ndarray = _NWU_TO_NED @ np.asarray(self._chassis.data.qvel[0:3], dtype=float)
        return velocity

    def _rotation_ned_frd(self) -> np.ndarray:
        """Body FRD -> NED rotation matrix, from MuJoCo's state quaternion (w, x, y, z)."""
        w, x, y, z = (float(v) for v in self._chassis.data.qpos[3:7])
        flu_to_nwu = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        rotation: np.ndarray = _NWU_TO_NED @ flu_to_nwu @ _NWU_TO_NED
        return rotation

    def read(self, epoch_s: float = 0.0) -> PhysicsState:
        """The state now (call once per frame, after the step), its time counted from the
        physics time ``epoch_s`` (where the firmware last started)."""
        c = self._chassis
        data = c.data
        velocity = self._velocity_ned()
        mujoco_time = float(data.time)
        elapsed = mujoco_time - self._mujoco_time
        if elapsed > 0.0:  # (a frame shorter than MuJoCo's step may not have moved it)
            self._accel_ned = (velocity - self._velocity) / elapsed
            self._velocity, self._mujoco_time = velocity, mujoco_time
        rotation = self._rotation_ned_frd()
        accel_body = rotation.T @ (self._accel_ned - self._gravity_ned)
        gyro = _NWU_TO_NED @ np.asarray(data.qvel[3:6], dtype=float)
        pose = c.pose
        roll, pitch = c.roll_pitch
        down = -(float(data.qpos[2]) - self._z0)
        return PhysicsState(
            time_s=c.time_s - epoch_s,
            gyro=(float(gyro[0]), float(gyro[1]), float(gyro[2])),
            accel_body=(float(accel_body[0]), float(accel_body[1]), float(accel_body[2])),
            position_ned=(float(pose.x_m), float(pose.y_m), down),
            attitude=(roll, pitch, float(pose.yaw_rad)),
            velocity_ned=(float(velocity[0]), float(velocity[1]), float(velocity[2])),
        )


class BridgeCore:
    """The lockstep itself, bytes in, bytes out (see the module's docstring).

    Args:
        chassis: the MuJoCo chassis, at rest where the twin starts.
        wheels: servo outputs -> wheel commands.
        clock: the wall clock of :attr:`TruthSample.wall_s` (monotonic seconds).
        record: where the counters and the truth go (default: a :meth:`TwinRecord.local`).
    """

    def __init__(self, chassis: MujocoChassis, wheels: WheelMap,
                 clock: Callable[[], float] = time.monotonic,
                 record: TwinRecord | None = None) -> None:
        self.chassis = chassis
        self.record = record if record is not None else TwinRecord.local()
        self._a = self.record.array
        self._wheels = wheels
        self._sensors = ChassisSensors(chassis)
        self._clock = clock
        self._last_count: int | None = None
        self._epoch_s = 0.0
        self._answer = b""
        self._contacts = contacts_of(chassis)
        self._contacts_due_s = 0.0
        self.record.add(self._sample(clock()))

    def answer(self, data: bytes) -> bytes | None:
        """The answer to one datagram from the firmware, or None for one to ignore."""
        started = time.perf_counter()
        a = self._a
        packet = decode_servo_packet(data)
        if packet is None:
            a[MALFORMED] += 1
            return None
        if packet.frame_count == self._last_count:
            a[REPEATED] += 1
            return self._answer
        dt = self._step(packet)
        self._answer = encode_state(self._sensors.read(self._epoch_s))
        now = self._clock()
        self.record.add(self._sample(now))
        if self._contacts is not None and self.chassis.time_s >= self._contacts_due_s:
            self.record.set_contacts(self.chassis.time_s, self._contacts())
            self._contacts_due_s = self.chassis.time_s + CONTACTS_PERIOD_S
        if math.isnan(a[FIRST_WALL]):
            a[FIRST_WALL] = now
        else:
            a[PHYSICS_S] += dt
        a[LAST_WALL] = now
        a[BUSY_S] += time.perf_counter() - started
        return self._answer

    def _step(self, packet: ServoPacket) -> float:
        """Count the frame and step the chassis one frame period (returned, seconds)."""
        a, last = self._a, self._last_count
        if last is not None and packet.frame_count < last:
            a[RESTARTS] += 1
            self._epoch_s = self.chassis.time_s
        elif last is not None and packet.frame_count > last + 1:
            a[DROPPED] += packet.frame_count - last - 1
        a[FRAMES] += 1
        a[FRAME_RATE] = packet.frame_rate
        self._last_count = packet.frame_count
        commands = self._wheels.commands(packet.pwm)
        dt = 1.0 / packet.frame_rate
        self.chassis.step(dt, commands)
        a[COMMANDS:COMMANDS + 4] = commands
        a[PULSES:PULSES + 4] = self._wheels.pulses(packet.pwm)
        return dt

    def _sample(self, wall_s: float) -> TruthSample:
        c = self.chassis
        pose = c.pose
        forward, right = c.velocity_body
        return TruthSample(wall_s, c.time_s, float(pose.x_m), float(pose.y_m),
                           float(pose.yaw_rad), forward, right)

    def truth(self) -> list[TruthSample]:
        """Every frame's truth so far, oldest first (a copy; the first is the start)."""
        return self.record.truth()

    def truth_now(self) -> TruthSample:
        """The latest truth."""
        return self.record.truth_now()

    def stats(self) -> BridgeStats:
        return self.record.stats()


def bridge_socket(host: str = "127.0.0.1") -> socket.socket:
    """The bridge's UDP socket: bound to a port from the OS, non-blocking."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((host, 0))
    sock.setblocking(False)
    return sock


def serve(sock: socket.socket, core: BridgeCore, stop_fd: int) -> None:
    """Answer the firmware's datagrams on ``sock`` until ``stop_fd`` is readable (a byte, or
    its other end closed)."""
    with selectors.DefaultSelector() as sel:
        sel.register(sock, selectors.EVENT_READ)
        sel.register(stop_fd, selectors.EVENT_READ)
        while True:
            events = sel.select()
            if any(key.fd == stop_fd for key, _ in events):
                return
            _drain(sock, core)


def _drain(sock: socket.socket, core: BridgeCore) -> None:
    """Answer every datagram waiting, in order."""
    while True:
        try:
            data, peer = sock.recvfrom(512)
        except OSError:  # (BlockingIOError: nothing more waiting)
            return
        reply = core.answer(data)
        if reply is not None:
            with contextlib.suppress(OSError):
                sock.sendto(reply, peer)


class TwinBridge:
    """:class:`BridgeCore` on a UDP socket of its own (127.0.0.1, a port from the OS: give
    :attr:`port` to the firmware's ``--sim-port-out``), served by a thread of this process
    until :meth:`close`.

    A thread shares the interpreter: any CPU-bound Python thread of the same process holds
    the lock the bridge needs for up to 5 ms at a time, against the firmware's 0.83 ms frames
    (measured: a busy thread beside it brought the twin to 0.17x real time). The twin runs
    its bridge in a process of its own (:class:`BridgeProcess`)."""

    def __init__(self, core: BridgeCore) -> None:
        self.core = core
        self._sock = bridge_socket()
        self.port: int = self._sock.getsockname()[1]
        self._stop_r, self._stop_w = socket.socketpair()
        self._thread = threading.Thread(target=serve,
                                        args=(self._sock, core, self._stop_r.fileno()),
                                        name="twin-bridge", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop the thread and close the socket; idempotent."""
        if self._thread.is_alive():
            with contextlib.suppress(OSError):
                self._stop_w.send(b"x")
            self._thread.join(timeout=5)
        for s in (self._sock, self._stop_r, self._stop_w):
            s.close()


class BridgeProcess:
    """The bridge in a process of its own (``python -m mecanum_mav.sim.twinbridge``), so that
    nothing in this process can slow the lockstep; its :class:`TwinRecord` is a file both
    map (in ``/dev/shm`` where there is one), read here through :attr:`record`.

    The process ends when told (:meth:`close`) or when this process is gone (it watches a
    pipe whose other end only this process holds). It is a child, not a
    ``multiprocessing`` one: that would import the caller's main script again.

    Args:
        params: the chassis' parameters (``SIM_*``, geometry) and the ESCs' pulse ranges
            (``MOT_<W>_MIN/TRIM/MAX/REV``), as a plain mapping.
        wheel_map: per wheel FL, FR, RL, RR ``(servo channel, sign)``.
        capacity: frames of truth kept (:data:`TRUTH_CAPACITY`).
        start_timeout_s: how long the process may take to build the chassis and bind.

    Raises:
        PhysicsUnavailableError: the process could not import mujoco (the install hint).
        RuntimeError: it did not come up.
    """

    def __init__(self, params: Mapping[str, float],
                 wheel_map: Sequence[tuple[int, float]] = DEFAULT_WHEEL_MAP,
                 capacity: int = TRUTH_CAPACITY, start_timeout_s: float = 30.0) -> None:
        require_mujoco()  # (here, at once, rather than from the process)
        shm = Path("/dev/shm")
        self._dir = Path(tempfile.mkdtemp(prefix="mecanum-bridge-",
                                          dir=shm if shm.is_dir() else None))
        self._proc: subprocess.Popen[bytes] | None = None
        self._keep_w: int | None = None
        try:
            self._start(params, wheel_map, capacity, start_timeout_s)
        except BaseException:
            self.close()
            raise

    def _start(self, params: Mapping[str, float], wheel_map: Sequence[tuple[int, float]],
               capacity: int, timeout_s: float) -> None:
        record_path = self._dir / "record.f64"
        array = np.lib.format.open_memmap(record_path, mode="w+", dtype=np.float64,
                                          shape=(TwinRecord.size(capacity),))
        blank(array)
        array.flush()
        self.record: TwinRecord = TwinRecord(array)
        setup = self._dir / "bridge.json"
        setup.write_text(json.dumps({"params": dict(params), "wheel_map": list(wheel_map),
                                     "record": str(record_path)}))
        watch_r, self._keep_w = os.pipe()
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "mecanum_mav.sim.twinbridge", str(setup), str(watch_r)],
                stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=None,
                pass_fds=(watch_r,), start_new_session=True)
        finally:
            os.close(watch_r)
        assert self._proc.stdout is not None
        ready = select.select([self._proc.stdout], [], [], timeout_s)[0]
        line = self._proc.stdout.readline().decode(errors="replace").strip() if ready else ""
        kind, _, value = line.partition(" ")
        if kind == "no-physics":
            raise PhysicsUnavailableError(value)
        if kind != "port":
            raise RuntimeError(f"the bridge process did not start within {timeout_s:g} s "
                               f"({line or 'no answer'}; exit code {self._proc.poll()})")
        self.port = int(value)

    @property
    def pid(self) -> int | None:
        return self._proc.pid if self._proc is not None else None

    def alive(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    def close(self) -> None:
        """Stop the process and remove its files; idempotent (:attr:`record` stays readable:
        the file's memory goes with the last mapping)."""
        if self._keep_w is not None:
            os.close(self._keep_w)  # (the process sees the pipe's end and stops)
            self._keep_w = None
        if self._proc is not None:
            try:
                self._proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                kill_group(self._proc)
            assert self._proc.stdout is not None  # (stdout=PIPE)
            self._proc.stdout.close()
        shutil.rmtree(self._dir, ignore_errors=True)  # (the record stays mapped here)


def bridge_main(argv: Sequence[str]) -> int:
    """The bridge process (``python -m mecanum_mav.sim.twinbridge SETUP.json WATCH_FD``):
    build the chassis, say ``port N`` on stdout, serve until ``WATCH_FD`` (a pipe's reading
    end) ends, then remove SETUP.json's folder (the record file too: its memory goes with
    the last mapping). ``no-physics MESSAGE`` and exit 2 without mujoco."""
    from mecanum_mav.config.params import Params
    from mecanum_mav.sim.physics import make_chassis

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # (the parent ends it)
    setup = json.loads(Path(argv[0]).read_text())
    watch = int(argv[1])
    values = Params(setup["params"])
    try:
        chassis = cast("MujocoChassis", make_chassis(values, physics="mujoco"))
    except PhysicsUnavailableError as exc:
        print(f"no-physics {exc}", flush=True)
        return 2
    array = np.load(setup["record"], mmap_mode="r+")
    wheels = WheelMap(PwmMap.from_params(values), [tuple(e) for e in setup["wheel_map"]],
                      float(values["SIM_ESC_DZ"]))
    core = BridgeCore(chassis, wheels, record=TwinRecord(array))
    with bridge_socket() as sock:
        print(f"port {sock.getsockname()[1]}", flush=True)
        serve(sock, core, watch)
    shutil.rmtree(Path(argv[0]).parent, ignore_errors=True)  # (its starter may be gone)
    return 0


if __name__ == "__main__":  # pragma: no cover (the bridge process)
    sys.exit(bridge_main(sys.argv[1:]))
