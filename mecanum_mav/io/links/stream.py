"""Stream links: :class:`StreamLink`, what serial, ``tcp:`` and ``tcpin:`` links share: the
link's own queue paced to the wire, the newest-override-wins rule, breaks and reopening, and
the linger on close. The transports are in :mod:`~mecanum_mav.io.links.serialport` and
:mod:`~mecanum_mav.io.links.tcp`. Times are seconds on the link's clock.

Stream links never block the loop on a write, and keep no standing queue in the kernel. What is
sent waits in the link (:meth:`StreamLink.flush` hands it over); a packet goes to the kernel
only when what the kernel already holds would be on the wire within :data:`PACING_LEAD_S` (how
that is judged is the transport's: the baud rate and the tty's queue, or TCP's unsent bytes).
The kernel's own buffers (4 KB of tty, about 0.7 s at 57600 baud; a pty's 20 KB, ~4 s) would
otherwise be a standing queue. RC_CHANNELS_OVERRIDE is *newest wins*: an override still waiting
in the link is replaced by a newer one (counted in
:attr:`~mecanum_mav.io.links.base.Link.superseded`, never packed, so the sequence numbers the
board sees have no gaps); everything else queues in order, at most the transport's
:attr:`StreamLink.queue_limit` bytes; a packet that does not fit is dropped and counted as a
send error. Overrides and queued packets take turns, so a 1 kHz override stream never starves
the heartbeat. The last words at shutdown (``send_rc_override(..., replace=False)``: neutral,
then the release) go before anything else, in the order given, and none replaces another: what
waits in the link's queue when one of them comes is dropped (counted in
:attr:`~mecanum_mav.io.links.base.Link.unsent`), since it was numbered before it and would
reach the board out of sequence after it. A loop waits for
:attr:`~mecanum_mav.io.links.base.Link.next_send_s` (the pacing timer) and calls
:func:`~mecanum_mav.io.links.base.follow` once per pass, which flushes and watches the
descriptor for writing while the kernel refuses more (``EAGAIN``). :meth:`StreamLink.close`
with a linger hands over what is still waiting, paced, before it closes: the last words
whatever the wire needs for them, the rest for at most the linger.

Stream links that break come back by themselves. A serial device that vanishes (USB
unplugged, board rebooting: reads and writes fail with EIO/ENXIO), a ``tcp:`` connection the
peer closed or reset, and a ``tcpin:`` client that left put the link *down*
(:attr:`~mecanum_mav.io.links.base.Link.down_reason`): its dead descriptor, which would be
readable forever, is no longer waited on (``wait_fd``, ``follow``), what is sent meanwhile is
dropped and counted in :attr:`~mecanum_mav.io.links.base.Link.unsent`, and
:meth:`StreamLink.reopen` opens the same device path or address again every
:data:`~mecanum_mav.io.links.base.REOPEN_PERIOD_S` without ever blocking (a TCP connect is
non-blocking, and completes on a later attempt). A ``tcpin:`` link keeps listening and is up
again as soon as a new client connects. The shell tells the core about both transitions (it
reports them once).
"""

from __future__ import annotations

import array
import contextlib
import errno
import fcntl
import logging
import math
import select
import time
from collections import deque
from collections.abc import Callable
from typing import Any, ClassVar

from mecanum_mav.io.links.base import MAX_READS, REOPEN_PERIOD_S, Link, LinkDownError

log = logging.getLogger("mecanum_mav.io.links")

__all__ = ["LAST_WORDS_MAX_S", "PACING_LEAD_S", "StreamLink"]

PACING_LEAD_S = 0.002
"""A stream link hands the kernel the next packet only when what the kernel holds already
would be on the wire within this time (seconds): its standing queue is at most this plus
one packet."""
LAST_WORDS_MAX_S = 2.0
""":meth:`StreamLink.close` waits at most this long (seconds) for the wire to carry the last
words at shutdown (neutral, then the release: at 2400 baud three overrides are 0.6 s), however
short its linger; a device that takes nothing for that long is given up."""
AGAIN = (BlockingIOError, InterruptedError)
"""The kernel takes or has nothing now: try again later."""


def queued_bytes(fd: int, request: int) -> int:
    """What the kernel holds unsent for ``fd`` (``TIOCOUTQ``, ``SIOCOUTQNSD``), bytes; 0 if
    it cannot say."""
    count = array.array("i", [0])
    try:
        fcntl.ioctl(fd, request, count, True)
    except OSError:
        return 0
    return count[0]


def ready_within(fd: int, events: int, timeout_s: float) -> bool:
    """Whether ``fd`` is ready for ``events`` (``select.POLLIN``, ``POLLOUT``) within
    ``timeout_s`` seconds (0: now). With poll: ``select()`` refuses a descriptor past 1023,
    which a process with many files open has."""
    poll = select.poll()
    poll.register(fd, events)
    return bool(poll.poll(math.ceil(timeout_s * 1000.0)))


class StreamLink(Link):
    """What every stream link has (module description). A transport says how it reads and
    writes its port (:meth:`_read_port`, :meth:`_write_port`), how long the kernel's backlog
    is (:meth:`_backlog_s`), why it breaks (:attr:`gone_reason`) and how it opens again
    (:meth:`_reopen`)."""

    gone_reason: ClassVar[str] = "connection lost"
    """Why it broke when a read or write failed, in a few words (a STATUSTEXT has 50
    characters)."""

    def __init__(self, conn: Any, *, url: str, name: str, signing_key: bytes | None,
                 clock: Callable[[], float], queue_limit: int) -> None:
        super().__init__(conn, url=url, name=name, signing_key=signing_key, clock=clock)
        self.queue_limit = queue_limit
        """Bytes queued at most besides the newest override; more is dropped."""
        self._head = b""  # the rest of a packet the kernel took part of: goes on first
        self._override: tuple[int, int, list[int]] | None = None  # newest, not yet packed
        self._last_words: deque[tuple[int, int, list[int]]] = deque()  # go first, in order
        self._queue: deque[bytes] = deque()  # everything else, in order
        self._queued = 0  # bytes in _queue
        self._override_turn = True  # overrides and queued packets take turns
        self._blocked = False  # the kernel refused more: wait until writable
        self._port_fd = self._current_port_fd()  # the descriptor written to

    # ----------------------------------------------------------------- the transport's

    def _read_port(self) -> bytes:
        """What the port has (b"" if nothing); raises ``OSError`` when it failed, and
        :class:`LinkDownError` when the peer ended the stream (after :meth:`_went_down`)."""
        raise NotImplementedError

    def _write_port(self, data: bytes) -> int:
        """Write ``data`` to the port without blocking; bytes taken."""
        raise NotImplementedError

    def _backlog_s(self, now: float) -> float:
        """How long (s) before the kernel may take the next packet: > 0 waits."""
        raise NotImplementedError

    def _free_in_s(self, now: float) -> float:
        """:meth:`_backlog_s` from what the link already knows, if the transport can say
        without asking the kernel (the stick lane's question, before its write)."""
        return self._backlog_s(now)

    def _sent_now(self, now: float) -> None:
        """A packet went to the kernel at once (:meth:`send_packet`): learn what the kernel
        holds, if :meth:`_free_in_s` did not ask."""

    def _handed(self, n: int, now: float) -> None:
        """The kernel took ``n`` bytes at ``now``."""

    def _reopen(self, now_s: float) -> bool:
        """One attempt to open the device or address again; whether it is open."""
        return False

    def _current_port_fd(self) -> int:
        port = getattr(self.conn, "port", None)
        return -1 if port is None else int(port.fileno())

    # ----------------------------------------------------------------- reading

    def read(self, max_reads: int = MAX_READS) -> list[Any]:
        """Every complete message waiting, oldest first, from at most ``max_reads`` chunks;
        never raises (a break puts the link down)."""
        conn, parse, recorder = self.conn, self.parser.parse, self.recorder
        messages: list[Any] = []
        for _ in range(max_reads):
            try:
                data = self._receive()
            except LinkDownError:  # (the only failure _receive raises)
                break
            if not data:
                break
            if conn.first_byte:
                conn.auto_mavlink_version(data)
            parsed = parse(data)
            if recorder is not None:
                recorder.messages(parsed)
            messages += parsed
        signing = self.signing
        if signing is not None:
            signing.catch_up()
        self.received += len(messages)
        return messages

    def _receive(self) -> bytes:
        """What is waiting (b"" if nothing); raises :class:`LinkDownError` when the link
        broke (it is then down), other ``OSError`` for a passing failure."""
        if self.down_reason is not None:
            raise LinkDownError(self.down_reason)
        try:
            data = self._read_port()
        except AGAIN:
            return b""
        except LinkDownError:
            raise
        except OSError as exc:  # pyserial's SerialException is one
            self._went_down(self.gone_reason, f"read: {exc}")
            raise LinkDownError(self.down_reason) from exc
        return bytes(data)

    # ----------------------------------------------------------------- sending

    def write(self, buf: bytes) -> None:
        """Queue one packet in order; it goes when :meth:`flush` can hand it over (the
        pymavlink ``MAVLink`` object writes through here too).

        Raises:
            LinkDownError: the link is down: the packet is lost.
            BlockingIOError: the queue is full: the packet is dropped.
        """
        self._check_open()
        if self._queued + len(buf) > self.queue_limit:
            raise BlockingIOError(errno.ENOBUFS, f"outgoing queue full ({self._queued} bytes)")
        self._queue.append(buf)
        self._queued += len(buf)
        self.flush()

    def _check_open(self) -> None:
        if self.down_reason is not None:
            raise LinkDownError(self.down_reason)

    def send_rc_override(self, target_system: int, target_component: int,
                         channels: list[int], *, replace: bool = True) -> None:
        """RC_CHANNELS_OVERRIDE with the 18 ``chanN_raw`` fields, packed by the fast codec
        when handed over; never raises.

        *Newest wins* (``replace``): an override still waiting in the link (not yet handed to
        the kernel) is replaced by this one, unpacked. With ``replace=False`` (the last
        words at shutdown: neutral, then release) it supersedes the waiting one, drops what
        else waits in the queue (module description) and goes after the last words sent
        before it; a later override does not replace it, and :meth:`close` waits for the
        wire to carry it."""
        try:
            self._check_open()
        except LinkDownError:
            self.unsent += 1
            return
        if self._override is not None:
            self.superseded += 1
            self._override = None
        if replace:
            self._override = (target_system, target_component, channels)
        else:
            self._drop_queue()
            self._last_words.append((target_system, target_component, channels))
            self.sent += 1
        self.flush()

    def takes_packet(self) -> bool:
        """Whether a packet given to :meth:`send_packet` now goes to the kernel at once: the
        link is open, nothing waits in it (an override waiting is newer than nothing; the
        lane must not pass it) and pacing lets it go (:meth:`_free_in_s`, from what is known
        without asking the kernel)."""
        return self._idle_and_open() and self._free_in_s(self.clock()) <= 0.0

    def _idle_and_open(self) -> bool:
        """Nothing waits in the link and it can write now."""
        if self.pending:
            return False
        try:
            self._check_open()
        except LinkDownError:
            return False
        return True

    def send_packet(self, packet: bytes) -> None:
        """Send a packet packed elsewhere with this link's next sequence number, which then
        advances; never raises. Asked right after :meth:`takes_packet` said yes (the stick
        lane), it goes to the kernel at once (the pacing was judged there, not again), and
        the transport then looks at what the kernel holds (:meth:`_sent_now`), after the
        latency-critical write. If something waits in the link or it cannot write, it is
        queued, and, being the lane's override, supersedes the override waiting (newest wins:
        the board never gets an older command after it)."""
        mav = self.conn.mav
        mav.seq = (mav.seq + 1) & 0xFF
        if self._idle_and_open():
            now = self.clock()
            self._head = packet  # (what the kernel does not take stays: follow() hands it)
            self._hand_over(packet, now)
            if self.down_reason is None:  # (a break now counted it unsent)
                self.sent += 1
                self._sent_now(now)
        else:
            if self._override is not None:
                self.superseded += 1
                self._override = None
            self._send_queued(packet)
        recorder = self.recorder
        if recorder is not None:
            recorder.packet(packet)

    def _send_queued(self, packet: bytes) -> None:
        try:
            self.write(packet)
        except LinkDownError:
            self.unsent += 1
        except Exception as exc:  # the queue is full
            self._send_failed(exc)
        else:
            self.sent += 1

    # ----------------------------------------------------------------- pacing

    @property
    def wants_write(self) -> bool:
        """Whether the kernel refused more and something still waits: watch the descriptor
        for writing (:func:`~mecanum_mav.io.links.base.follow` does)."""
        return self._blocked and self.pending

    @property
    def pending(self) -> bool:
        """Whether anything waits in the link to be handed to the kernel."""
        return (bool(self._head) or bool(self._last_words) or self._override is not None
                or bool(self._queue))

    def flush(self) -> None:
        """Hand the kernel what waits, as pacing lets it (module description): the rest
        of a packet first, then the last words, then overrides and queued packets taking
        turns; sets :attr:`next_send_s`. Never blocks or raises (a break puts the link
        down). (Every override sent comes through here: :attr:`pending` is spelled out.)"""
        if not (self._head or self._last_words or self._override is not None or self._queue):
            self.next_send_s = math.inf  # (a link that is down has nothing waiting)
            return
        now = self.clock()
        while True:
            if self._head and not self._hand_over(self._head, now):
                self.next_send_s = math.inf  # writable, or reopened, wakes it
                return
            if not (self._last_words or self._override is not None or self._queue):
                self.next_send_s = math.inf  # (the head is out)
                return
            wait_s = self._backlog_s(now)
            if wait_s > 0.0:
                self.next_send_s = now + wait_s
                return
            self._head = self._next_packet()

    def _next_packet(self) -> bytes:
        if self._last_words:  # packed now: the board sees the sequence numbers in order
            return self._pack_override(*self._last_words.popleft())
        override = self._override
        if override is not None and (self._override_turn or not self._queue):
            self._override = None
            self._override_turn = False
            self.sent += 1
            return self._pack_override(*override)
        packet = self._queue.popleft()
        self._queued -= len(packet)
        self._override_turn = True
        return packet

    def _hand_over(self, data: bytes, now: float) -> bool:
        """Write ``data`` to the kernel; whether it took all of it (the rest stays in
        ``_head``)."""
        try:
            n = self._write_port(data)
        except AGAIN:
            self._blocked = True
            return False
        except OSError as exc:
            self._went_down(self.gone_reason, f"write: {exc}")
            return False
        self._handed(n, now)
        self._head = data[n:]
        self._blocked = bool(self._head)  # the kernel took only part: it is full
        return not self._blocked

    def _drop_queue(self) -> None:
        """A last word passes what waits in the queue: that is dropped (counted in
        :attr:`unsent`). It was numbered when it was queued; after the last word, packed when
        handed over, it would reach the board out of sequence (and a board that checks
        signatures refuses a packet whose timestamp is older than the last one's)."""
        self.unsent += len(self._queue)
        self._queue.clear()
        self._queued = 0

    def _drop_pending(self) -> None:
        """The link broke: what waits in it is lost (counted in :attr:`unsent`)."""
        self._drop_queue()
        self.unsent += len(self._last_words) + (self._override is not None) + bool(self._head)
        self._last_words.clear()
        self._override, self._head, self._blocked = None, b"", False
        self.next_send_s = math.inf

    # ----------------------------------------------------------------- breaks and reopening

    def _went_down(self, reason: str, detail: object = "") -> None:
        """The link broke: mark it down (the shell reports it once) and stop using it; its
        port is closed now (a USB serial node still held open keeps its name from the next
        plug) and opened again from :attr:`next_reopen_s` on. Called only while it is up (a
        read or write that failed; neither is tried while it is down)."""
        self._mark_down(reason, detail)
        with contextlib.suppress(OSError):
            self.conn.port.close()
        self.next_reopen_s = self.clock() + REOPEN_PERIOD_S

    def _mark_down(self, reason: str, detail: object) -> None:
        self.down_reason = reason
        log.info("%s: %s: %s", self.name, reason, detail)
        self._drop_pending()
        self._port_fd = -1

    def _came_up(self) -> None:
        log.debug("%s: up again (was down: %s)", self.name, self.down_reason)
        self.down_reason = None
        self.next_reopen_s = math.inf
        self._port_fd = self._current_port_fd()
        self.parser.reset()  # a partial packet from before the break is not completed now

    def reopen(self, now_s: float) -> bool:
        """While the link is down, once :attr:`next_reopen_s` has come, try to open the same
        device path or TCP address again (never blocking); whether the link is up now."""
        if self.down_reason is None:
            return True
        if now_s < self.next_reopen_s:
            return False
        self.next_reopen_s = now_s + REOPEN_PERIOD_S
        opened = self._reopen(now_s)
        if opened:
            self._came_up()
        return opened

    # ----------------------------------------------------------------- closing

    def close(self, *, linger_s: float = 0.0) -> None:
        """Close the connection; idempotent.

        With ``linger_s`` what was written last reaches the peer and is read before the link
        goes: what still waits in the link is handed over first, paced as always, for at most
        ``linger_s`` (the last words, whatever the wire needs, at most
        :data:`LAST_WORDS_MAX_S`); then the transport makes sure its output is out
        (:meth:`_flush_out`).
        A peer that sees the connection end while the last bytes are still in its buffers may
        drop them: measured with ArduPilot SITL, the companion's channel release sent right
        before ``close()`` never took effect.
        """
        with contextlib.suppress(OSError, ValueError):
            if linger_s > 0.0:
                self._hand_over_rest(linger_s)
                self._flush_out(linger_s)
        self._drop_pending()
        super().close()

    def _hand_over_rest(self, linger_s: float) -> None:
        """Before closing: flush until nothing waits or the link broke; the last words (and
        a packet begun) for as long as the wire needs, at most :data:`LAST_WORDS_MAX_S`, the
        rest for at most ``linger_s``; on the link's clock (which paces) or in real time
        (which the waits take), whichever passes first."""
        start, real_start = self.clock(), time.monotonic()
        while self.pending and self.down_reason is None:
            self.flush()
            now = self.clock()
            if not self.pending:
                return
            limit = LAST_WORDS_MAX_S if (self._head or self._last_words) else linger_s
            deadline = start + limit
            if now >= deadline or time.monotonic() - real_start >= limit:
                return
            if self.wants_write:
                ready_within(self._port_fd, select.POLLOUT, deadline - now)
            else:
                time.sleep(max(0.0, min(self.next_send_s, deadline) - now))

    def _flush_out(self, linger_s: float) -> None:
        """After the last packet was handed over: wait (at most ``linger_s``) until it is
        out."""

