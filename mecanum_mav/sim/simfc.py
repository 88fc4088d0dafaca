"""The simulated ArduPilot Rover board (:class:`~mecanum_mav.sim.board.SimBoard`) on a real
MAVLink link, in real time: ``mecanum-mav simfc`` and the companion's ``--fc sim``.

The loop blocks in a selector on the link until a message arrives or the board's next physics
tick or telemetry message is due; physics is stepped with the real elapsed time. Telemetry goes
to every peer heard. :meth:`SimFlightController.snapshot` and :meth:`~SimFlightController.wait_for`
give tests and tools the true state from another thread.
"""

from __future__ import annotations

import selectors
import threading
import time
from collections.abc import Callable
from types import TracebackType

from mecanum_mav.config.params import Params
from mecanum_mav.io.links import Link, follow, open_link
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.sim.board import ORIGIN, RcOverrides, SimBoard, SimState
from mecanum_mav.sim.physics import DEFAULT_PHYSICS

__all__ = ["RcOverrides", "SimFlightController", "SimState"]


class SimFlightController:
    """A simulated ArduPilot Rover board on ``url``, obeying RC overrides and sending telemetry.

    Args:
        url: pymavlink connection string to serve on, e.g. ``udpin:127.0.0.1:0``.
        params: the board's parameters (see :class:`~mecanum_mav.sim.board.SimBoard`).
        pose: where the simulated chassis starts (local NED, yaw clockwise from north).
        physics: the chassis model (:data:`~mecanum_mav.sim.physics.PHYSICS`).

    Raises ``OSError``/``ValueError`` when the link cannot be opened. Use :meth:`start` /
    :meth:`stop` (or ``with``, which stops on exit) or run :meth:`run` in your own thread.
    """

    def __init__(self, url: str, params: Params, pose: Pose2d = ORIGIN,
                 physics: str = DEFAULT_PHYSICS) -> None:
        self.board = SimBoard(params, time.monotonic(), pose, physics)
        self._cond = threading.Condition()
        self._state = self.board.state()
        self._stop_event = threading.Event()
        self._thread: threading.Thread | None = None
        self._link: Link = open_link(url, source_system=self.board.sysid,
                                     source_component=self.board.compid, name="simfc")

    # ------------------------------------------------------------------ lifecycle

    @property
    def local_port(self) -> int | None:
        """The bound local UDP/TCP port (after listening on port 0), else None."""
        return self._link.local_port

    def start(self) -> None:
        """Run the loop in a daemon thread; does nothing if it is already running."""
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self.run, args=(self._stop_event,),
                                        name=f"simfc:{self.local_port}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the loop, wait for its thread and close the link; idempotent."""
        self._stop_event.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join()
        self._link.close()

    def __enter__(self) -> SimFlightController:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()

    # ------------------------------------------------------------------ state

    def snapshot(self) -> SimState:
        """The latest consistent state (thread-safe; the channel map is the caller's copy)."""
        with self._cond:
            state = self._state
        return _copy_state(state)

    def wait_for(self, predicate: Callable[[SimState], bool], timeout_s: float) -> SimState | None:
        """Wait until ``predicate(state)`` holds, re-checked at every published state
        (each physics tick and each batch of messages); the state, or None after
        ``timeout_s`` seconds."""
        with self._cond:
            if self._cond.wait_for(lambda: predicate(self._state), timeout_s):
                return _copy_state(self._state)
        return None

    def _publish(self) -> None:
        """Make the current state visible to :meth:`snapshot` and wake :meth:`wait_for`."""
        state = self.board.state()
        with self._cond:
            self._state = state
            self._cond.notify_all()

    # ------------------------------------------------------------------ loop

    def run(self, stop: threading.Event) -> None:
        """Serve until ``stop`` is set or :meth:`stop` is called (noticed within one physics
        period). Never raises on bad input: unparseable bytes are counted by the link and
        dropped."""
        board, link = self.board, self._link
        with selectors.DefaultSelector() as selector:
            fd = follow(selector, link, None)
            while not (stop.is_set() or self._stop_event.is_set()):
                due = min(board.next_due_s(), link.next_send_s)  # (paced writes: follow)
                timeout = max(0.0, due - time.monotonic())
                if selector.select(timeout) and board.receive(link.read(), time.monotonic()):
                    self._publish()
                if board.on_time(time.monotonic(), link.mav):
                    self._publish()
                fd = follow(selector, link, fd)


def _copy_state(state: SimState) -> SimState:
    """``state`` with its own channel map, so a caller cannot change the published one."""
    return SimState(**{**state.__dict__, "channel_pwm": dict(state.channel_pwm)})
