"""``mecanum-mav view`` and ``mecanum-mav log --rerun/--view``: the Rerun view of a drive.

What the view shows, and from which messages: :mod:`~mecanum_mav.app.rerunview` (the one
mapping, for a live stream and a finished tlog alike). This module connects it:

- live (:func:`run_view`): messages from a pymavlink URL (``udpin:127.0.0.1:14551``, the
  default: an extra output of MAVProxy, ``--out=udpout:127.0.0.1:14551``; or the companion's
  ground-station link itself, ``udpin:127.0.0.1:14550`` when no ground station holds that
  port) or a tlog being written (followed as it grows: ``sim --view`` does that), timed by
  their arrival (a tlog's by its records' stamps), flushed to the viewer every
  :data:`FLUSH_PERIOD_S`; from several at once (``--connect`` again: ``twin --view`` follows
  the companion's tlog and the chassis's truth), each poll's messages merged in time order.
  The view only listens: it sends nothing (no heartbeat that could keep a failsafe from
  noticing a lost ground station).
- a finished tlog (:func:`write_rrd`): every message, sent in columns, to an ``.rrd`` file
  that Rerun's viewer opens (``rerun FILE.rrd``, or ``log --view``).
- the viewer (:func:`open_viewer`): the native one where a display exists (``$DISPLAY`` or
  ``$WAYLAND_DISPLAY``), else Rerun's web viewer served on 127.0.0.1 (its address printed;
  the viewer ships inside the ``rerun-sdk`` wheel, so it works offline).
"""

from __future__ import annotations

import contextlib
import heapq
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.parse
from collections.abc import Callable, Generator, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from mecanum_mav.app.logmission import log_origin
from mecanum_mav.app.logsenders import vehicle_of
from mecanum_mav.app.rerunview import APPLICATION_ID, ViewMapping, rerun_module
from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import STAMP_LEN, TlogEntry, parse_tlog
from mecanum_mav.protocol.dialect import mavutil
from mecanum_mav.sim.process import dies_with_this_thread, free_port

__all__ = ["DEFAULT_CONNECT", "DEFAULT_WEB_PORT", "FLUSH_PERIOD_S", "TlogFollower", "Viewer",
           "follow_in_viewer", "gc_paused", "has_display", "merged", "open_viewer", "run_view",
           "serve_rrd", "show_log", "stop_view", "viewer_url", "write_rrd"]

DEFAULT_CONNECT = "udpin:127.0.0.1:14551"
"""Where ``view`` listens by default: MAVProxy's extra output (``--out=udpout:127.0.0.1:14551``
beside the ground station on 14550)."""
DEFAULT_WEB_PORT = 9090
"""The web viewer's port by default (Rerun's)."""
FLUSH_PERIOD_S = 0.2
"""Live rows go to the viewer this often (s)."""
_MAX_TAIL = 1 << 16
"""Bytes of a followed tlog kept unread at most (a record cut short by the writer)."""
_WAIT_S = 0.05
"""How long a live read waits for a message (s)."""
_STOP_WAIT_S = 5.0
"""How long a web viewer asked to stop (SIGTERM) may take before it is killed (s)."""


@contextlib.contextmanager
def gc_paused(*, keep: bool = False) -> Iterator[None]:
    """Python's cyclic garbage collector paused: reading a long tlog makes hundreds of
    thousands of messages and no cycles, and the collector's passes over them took more than
    half the time (a 30-minute tlog: 5.0 s read with it, 2.0 s without).

    With ``keep`` (what was read stays to the process's end: ``log``), everything made so far
    is then left out of the collector's later passes (``gc.freeze``; still freed when no
    longer referenced): each would go over all of it again (a 30-minute tlog's messages:
    870,000 objects, 0.4-0.75 s a pass, and the view's mapping and Rerun's import set off
    two or three)."""
    import gc

    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if keep:
            gc.freeze()
        if was:
            gc.enable()


def has_display() -> bool:
    """Whether a native window can open here ($DISPLAY or $WAYLAND_DISPLAY)."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def viewer_url(web_port: int, grpc_port: int) -> str:
    """The web viewer's address that opens the recording served on ``grpc_port``."""
    source = urllib.parse.quote(f"rerun+http://127.0.0.1:{grpc_port}/proxy", safe="")
    return f"http://127.0.0.1:{web_port}/?url={source}"


def _rerun_cli(*args: str) -> list[str]:
    """The Rerun viewer's command line: its binary itself (``python -m rerun`` would run it as
    a child of its own, which stopping the wrapper leaves behind)."""
    import importlib.util

    spec = importlib.util.find_spec("rerun_cli")  # (rerun-sdk's; untyped: not imported)
    if spec is None or spec.origin is None:
        raise RuntimeError("the Rerun viewer (rerun_cli, in rerun-sdk) is not installed")
    binary = os.environ.get("RERUN_CLI_PATH") or str(Path(spec.origin).parent / "rerun")
    return [binary, *args]


def _quiet_env() -> dict[str, str]:
    """The environment for the viewer: warnings and errors only on stderr."""
    return {**os.environ, "RUST_LOG": os.environ.get("RUST_LOG", "warn")}


@dataclass
class Viewer:
    """A viewer started for a recording: the process (native or the web server), where the
    data goes (``grpc_url``) and, for the web viewer, the address to open (``url``)."""

    process: subprocess.Popen[bytes]
    grpc_url: str
    url: str | None

    def close(self) -> None:
        """Stop the viewer's process (the web server, killed if it has not ended
        :data:`_STOP_WAIT_S` after SIGTERM; a native window is left open)."""
        if self.url is not None and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(_STOP_WAIT_S)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


def _wait_listening(port: int, process: subprocess.Popen[bytes], timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(f"the Rerun viewer exited at once (status {process.returncode})")
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    raise RuntimeError(f"the Rerun viewer did not listen on port {port} in {timeout_s:g} s")


def serve_rrd(rrd: Path | None, web_port: int, *, native: bool,
              timeout_s: float = 20.0) -> Viewer:
    """Start Rerun's viewer, bound to 127.0.0.1: native (``native``) or the web viewer on
    ``web_port`` (0: any free port), showing ``rrd`` (None: what is sent to its
    ``grpc_url``), in a session of its own (a Ctrl-C meant for us leaves it: the native
    window stays open, the web one is stopped by :meth:`Viewer.close` once all is sent).
    The web viewer also ends with the thread that started it
    (:func:`~mecanum_mav.sim.process.dies_with_this_thread`): a view killed before it could
    close it (``kill -9``, :func:`stop_view`'s last resort) leaves no server behind. Raises
    RuntimeError when it does not start."""
    rerun_module()
    grpc_port = free_port(socket.SOCK_STREAM)
    quiet = subprocess.DEVNULL
    if native:
        args = _rerun_cli("--port", str(grpc_port), *([str(rrd)] if rrd else []))
        process = subprocess.Popen(args, stdin=quiet, stdout=quiet, env=_quiet_env(),
                                   start_new_session=True)
        url = None
    else:
        web_port = web_port or free_port(socket.SOCK_STREAM)
        args = _rerun_cli("--serve-web", "--bind", "127.0.0.1", "--port", str(grpc_port),
                          "--web-viewer-port", str(web_port), *([str(rrd)] if rrd else []))
        process = subprocess.Popen(args, stdin=quiet, stdout=quiet, env=_quiet_env(),
                                   start_new_session=True,
                                   preexec_fn=dies_with_this_thread(signal.SIGTERM))
        url = viewer_url(web_port, grpc_port)
    try:
        _wait_listening(grpc_port, process, timeout_s)
    except BaseException:  # (a Ctrl-C too: the viewer is in a session of its own)
        process.kill()
        process.wait()
        raise
    return Viewer(process, f"rerun+http://127.0.0.1:{grpc_port}/proxy", url)


def open_viewer(recording: Any, web_port: int, save: Path | None) -> Viewer:
    """A viewer for the live ``recording`` (:func:`serve_rrd`: native where there is a display)
    and its sinks: the viewer, and ``save`` (an ``.rrd`` file) when given."""
    rr = rerun_module()
    viewer = serve_rrd(None, web_port, native=has_display())
    try:
        sinks: list[Any] = [rr.GrpcSink(viewer.grpc_url)]
        if save is not None:
            sinks.append(rr.FileSink(str(save)))
        recording.set_sinks(*sinks)  # (RuntimeError: ``save`` cannot be created)
    except BaseException:
        viewer.close()
        raise
    return viewer


def write_rrd(entries: list[TlogEntry], params: Params, out: Path) -> int:
    """The view of a finished drive (a tlog's ``entries``) written to ``out`` (``.rrd``):
    every message through :class:`~mecanum_mav.app.rerunview.ViewMapping`, SIM_STATE placed
    about the log's origin, sent in columns. Returns the rows written."""
    rr = rerun_module()
    mapping = ViewMapping(params, log_origin(entries, vehicle_of(entries)))
    recording = rr.RecordingStream(APPLICATION_ID)
    out.parent.mkdir(parents=True, exist_ok=True)
    recording.save(str(out))
    mapping.start(recording)
    with gc_paused():
        mapping.feed_all((e.time_s, e.msg) for e in entries)
        mapping.finish()
        rows = mapping.flush(recording)
    recording.flush()
    recording.disconnect()
    return rows


class TlogFollower:
    """A tlog being written, read as it grows: every complete record since the last
    :meth:`poll` (a record cut short by the writer waits for the rest)."""

    def __init__(self, path: Path) -> None:
        self._file = path.open("rb")
        self._tail = b""

    def poll(self) -> list[tuple[float, Any]]:
        """(Unix time s, message) of the records completed since the last call."""
        data = self._tail + self._file.read()
        if not data:
            return []
        read = parse_tlog(data)  # (only its entries are kept: its name is not needed)
        if read.entries:
            last = read.entries[-1]
            end = last.offset + STAMP_LEN + len(last.msg.get_msgbuf())
            data = data[end:]
        self._tail = data if len(data) <= _MAX_TAIL else b""
        return [(e.time_s, e.msg) for e in read.entries]

    def close(self) -> None:
        self._file.close()


def _messages(connect: str, wait_s: float = _WAIT_S
              ) -> Generator[list[tuple[float, Any]], None, None]:
    """Batches of (time Unix s, message) from ``connect`` (a pymavlink URL, or the path of a
    tlog to follow), forever; an empty batch when nothing came for ``wait_s``."""
    path = Path(connect)
    if path.is_file():
        follower = TlogFollower(path)
        try:
            while True:
                batch = follower.poll()
                if not batch:
                    time.sleep(wait_s)
                yield batch
        finally:
            follower.close()
    conn = mavutil.mavlink_connection(connect)  # (its own ids: never used, it sends nothing)
    try:
        while True:
            msg = conn.recv_match(blocking=True, timeout=wait_s)
            batch = []
            while msg is not None:
                if msg.get_type() != "BAD_DATA":
                    batch.append((time.time(), msg))
                msg = conn.recv_match()  # (what waits, without waiting)
            yield batch
    finally:
        conn.close()


def merged(connects: Sequence[str]) -> Generator[list[tuple[float, Any]], None, None]:
    """:func:`_messages` of each of ``connects`` in turn (each waiting its share of
    :data:`_WAIT_S`), a batch of each round's messages in time order, forever."""
    sources = [_messages(c, _WAIT_S / len(connects)) for c in connects]
    try:
        while True:
            yield list(heapq.merge(*(next(s) for s in sources), key=lambda e: e[0]))
    finally:
        for source in sources:
            source.close()


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def _sigterm_interrupts(stack: contextlib.ExitStack) -> None:
    """SIGTERM ends the view as Ctrl-C does (its web viewer stopped, nothing left behind),
    until ``stack`` closes; in the main thread only (where signals are handled)."""
    import threading

    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _interrupt)
        stack.callback(signal.signal, signal.SIGTERM, previous)


def run_view(connect: str | Sequence[str], params: Params, *, save: Path | None = None,
             web_port: int = DEFAULT_WEB_PORT, out: TextIO | None = None,
             stop_when: Callable[[ViewMapping], bool] | None = None) -> int:
    """The ``view`` command: the live view of ``connect`` (one source, or several merged)
    until Ctrl-C (or ``stop_when`` the mapping says so).
    Returns the exit status (0; 2 when a link or the viewer cannot be opened)."""
    out = out or sys.stdout
    connects = [connect] if isinstance(connect, str) else list(connect)
    connect = ", ".join(connects)
    try:
        rr = rerun_module()
    except RuntimeError as exc:
        print(f"mecanum-mav view: {exc}", file=sys.stderr)
        return 2
    mapping = ViewMapping(params)
    recording = rr.RecordingStream(APPLICATION_ID)
    with contextlib.ExitStack() as stack:
        _sigterm_interrupts(stack)  # (from the start: a viewer being started is stopped too)
        try:
            viewer = open_viewer(recording, web_port, save)
        except (RuntimeError, OSError) as exc:
            print(f"mecanum-mav view: {exc}", file=sys.stderr)
            return 2
        stack.callback(viewer.close)
        mapping.start(recording)
        where = viewer.url or "the native viewer"
        print(f"mecanum-mav view: {connect} -> {where}"
              + (f"; recording to {save}" if save else ""), file=out, flush=True)
        try:
            batches = merged(connects)
            stack.callback(batches.close)
            next_flush = time.monotonic()
            while True:  # (the batches never end)
                mapping.feed_all(next(batches))
                now = time.monotonic()
                if now >= next_flush:
                    mapping.flush(recording)
                    next_flush = now + FLUSH_PERIOD_S
                if stop_when is not None and stop_when(mapping):
                    break
        except KeyboardInterrupt:
            pass
        except (OSError, ValueError) as exc:
            print(f"mecanum-mav view: {connect}: {exc}", file=sys.stderr)
            return 2
        finally:
            # (the web viewer is in a session of its own: a Ctrl-C has not stopped it yet)
            # (the viewer gone: the file still gets it; a second Ctrl-C: as it is)
            with contextlib.suppress(RuntimeError, KeyboardInterrupt):
                mapping.flush(recording)
                recording.flush()
            recording.disconnect()  # (before the web viewer stops: nothing left to send)
        print(f"mecanum-mav view: {mapping.messages} messages", file=out, flush=True)
    return 0


def show_log(entries: list[TlogEntry], params: Params, rrd: Path | None, view: bool,
             web_port: int, out: TextIO, err: TextIO,
             then: Callable[[], None] | None = None) -> int:
    """``log --rerun OUT.rrd`` and ``log --view``: the drive's view written to ``rrd`` (a
    temporary file for ``view`` alone) and, with ``view``, opened until the viewer closes or
    Ctrl-C; ``then`` is called once the view is written (and served). Returns the exit status
    (0; 2 without the ``view`` extra or a viewer)."""
    import tempfile

    with contextlib.ExitStack() as stack:
        if rrd is None:
            rrd = Path(stack.enter_context(tempfile.TemporaryDirectory())) / "view.rrd"
        try:
            started = time.perf_counter()
            rows = write_rrd(entries, params, rrd)
            print(f"wrote {rrd} ({rows} rows in {time.perf_counter() - started:.2f} s)",
                  file=out, flush=True)
            if not view:
                if then is not None:
                    then()
                return 0
            viewer = serve_rrd(rrd, web_port, native=has_display())
        except (RuntimeError, OSError) as exc:
            print(f"mecanum-mav log: {exc}", file=err)
            return 2
        stack.callback(viewer.close)
        print(f"mecanum-mav log: the view: {viewer.url or 'the native viewer'} (Ctrl-C ends)",
              file=out, flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            if then is not None:
                then()
            viewer.process.wait()
    return 0


def follow_in_viewer(tlog: Path | None, params_path: Path | None, assignments: list[str],
                     web_port: int, also: Sequence[str] = ()
                     ) -> tuple[Path, subprocess.Popen[bytes]]:
    """``sim --view``: ``mecanum-mav view`` in its own process (the companion's loop is not
    slowed), following ``tlog`` (created now; a temporary file when None), which the companion
    records both of its links to: the simulator's SIM_STATE (the true path and speed) and the
    companion's every override reach the view; and the URLs ``also`` (``twin --view``: the
    chassis's truth). Returns the tlog and the process."""
    import tempfile

    if tlog is None:
        tlog = Path(tempfile.gettempdir()) / f"mecanum-mav-sim-{os.getpid()}.tlog"
    tlog.touch()
    args = [sys.executable, "-m", "mecanum_mav", "view", "--connect", str(tlog),
            *(a for url in also for a in ("--connect", url)), "--web-port", str(web_port)]
    if params_path is not None and params_path.exists():
        args += ["--params", str(params_path)]
    for assignment in assignments:
        args += ["--set", assignment]
    return tlog, subprocess.Popen(args, stdin=subprocess.DEVNULL)


def stop_view(process: subprocess.Popen[bytes], timeout_s: float = 10.0) -> None:
    """Stop a ``view`` process as Ctrl-C does (it sends what it has and stops its web
    viewer), killed if it has not ended after ``timeout_s`` (its web viewer then ends with
    it, :func:`serve_rrd`)."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
