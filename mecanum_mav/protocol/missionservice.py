"""The MAVLink mission protocol, vehicle side, as a pure state machine (no I/O, time passed in).

:class:`MissionService` is fed the mission messages the companion receives (``on_*``), is
ticked with the monotonic time, and returns the messages to send as :class:`Outgoing` values.
It follows the mavlink.io Mission Protocol; where the specification is silent or where
ArduPilot (whose ground-station behaviour the clients expect) differs, the choice is written
here.

Upload (ground station -> vehicle)
    ``MISSION_COUNT(n)`` starts it; the vehicle requests item 0, 1, ... with
    ``MISSION_REQUEST_INT`` and after the last item answers ``MISSION_ACK`` ACCEPTED; only then
    is the stored mission replaced (atomic: any failure leaves the old mission as it was).
    ``n == 0`` clears the mission at once; ``n >``
    :data:`~mecanum_mav.protocol.mission.MAX_ITEMS` gets NO_SPACE. Each item goes
    through :func:`~mecanum_mav.protocol.mission.item_from_fields` and
    :func:`~mecanum_mav.protocol.mission.check_item`; a refused item ends the upload with a
    ``MISSION_ACK`` carrying its MAV_MISSION_RESULT and the reason as an ``"error"`` event.

    Every request has a timeout of :data:`ITEM_TIMEOUT_S` (the spec's value for items). When it
    expires the request is sent again, at most :data:`MAX_RETRIES` times; when it would expire
    once more the upload is cancelled: ``MISSION_ACK`` OPERATION_CANCELLED and the event
    "Mission upload timed out at item N". A duplicate of an item already received (a link
    that duplicates packets, or a ground station resending after a slow request) is dropped
    silently: the request for the next item is already out and has its own timeout, and
    answering every duplicate with another request would multiply the traffic on a
    duplicating link. An item ahead of the one expected (out of sequence) is dropped and the
    expected item requested again at once; such a re-request restarts the timeout and counts
    as a retry, as the timer's do, so a ground station that keeps sending the wrong item
    cannot hold the upload open. Receiving the expected item resets the count.

    A legacy ``MISSION_ITEM`` (float x/y) is accepted, and from then on the transfer requests
    with ``MISSION_REQUEST``; a new transfer starts with ``MISSION_REQUEST_INT`` again.

    A new ``MISSION_COUNT`` from the uploading system/component restarts the upload (as
    ArduPilot does); from anyone else it gets DENIED and the transfer in progress goes on.
    Items from anyone else during an upload get DENIED too (ArduPilot's answer).
    ``MISSION_CLEAR_ALL`` cancels an upload (the uploader, if it is not the one clearing, gets
    OPERATION_CANCELLED). A ``MISSION_ACK`` with an error from the uploader cancels the upload
    (the spec's "Canceling Operations"); the vehicle answers nothing.

    An item received while no upload is in progress is answered with the final ``MISSION_ACK``
    of the last upload if it comes from that upload's ground station: the usual cause is that
    the final ACK was lost and the ground station sent its last item again, and it must learn
    the outcome. From anyone else it gets MAV_MISSION_ERROR ("not accepting items now").

Download (vehicle -> ground station)
    ``MISSION_REQUEST_LIST`` -> ``MISSION_COUNT``; ``MISSION_REQUEST_INT(seq)`` ->
    ``MISSION_ITEM_INT``; ``MISSION_REQUEST(seq)`` -> ``MISSION_ITEM`` with float x/y
    (degrees or metres, :func:`~mecanum_mav.protocol.mission.float_xy`). The spec suggests answering
    ``MISSION_REQUEST`` with ``MISSION_ITEM_INT``; ArduPilot answers ``MISSION_ITEM`` and old
    ground stations that send ``MISSION_REQUEST`` expect it, so this follows ArduPilot. The
    ground station drives the download and its retries, so the vehicle keeps no download
    state: requests are answered in any order, repeated, and without a preceding
    ``MISSION_REQUEST_LIST`` (MAVProxy and QGroundControl do this); a ``seq`` past the end gets
    INVALID_SEQUENCE, and the ground station's closing ``MISSION_ACK`` is consumed. Downloads
    are served from the accepted mission also while an upload is in progress (ArduPilot denies
    them because its upload overwrites in place; here the accepted mission is intact until the
    upload completes).

Mission types
    Only MAV_MISSION_TYPE_MISSION is stored. For FENCE and RALLY, ``MISSION_REQUEST_LIST``
    gets ``MISSION_COUNT`` 0 of that type (QGroundControl and MAVSDK ask for them and would
    otherwise wait for a timeout); every other message of those or of unknown types gets
    ``MISSION_ACK`` UNSUPPORTED of that type, without disturbing an upload in progress. The one
    exception is ``MISSION_CLEAR_ALL`` with MAV_MISSION_TYPE_ALL (the value the spec defines
    for exactly that message): there are no fences or rally points, so it clears the mission
    and is ACCEPTED. Every ``MISSION_ACK``/``MISSION_COUNT``/request/item sent carries the
    mission type it is about and is addressed to the system/component that started the
    operation.

Items are stored as uploaded, ``current`` included (the companion may set ``current`` on the
way out). Events (:meth:`MissionService.take_events`): ``"replaced"`` and ``"cleared"`` when the
stored mission changed (:attr:`MissionService.version` is incremented with each), ``"error"``
with a STATUSTEXT-sized reason (at most :data:`~mecanum_mav.protocol.statustext.STATUSTEXT_LEN`
characters) when an operation failed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import (
    MAX_ITEMS,
    MissionItem,
    MissionItemError,
    check_item,
    float_xy,
    item_from_fields,
)
from mecanum_mav.protocol.statustext import STATUSTEXT_LEN

__all__ = ["ITEM_TIMEOUT_S", "MAX_RETRIES", "STATUSTEXT_LEN", "MissionService", "Outgoing", "Src"]

ITEM_TIMEOUT_S = 0.25
"""Seconds the vehicle waits for a requested item before requesting it again (the spec's
timeout for mission items)."""

MAX_RETRIES = 5
"""How many times a request is sent again before the upload is cancelled (the spec's maximum)."""

Src = tuple[int, int]
"""(system id, component id) of a message's sender or an outgoing message's target."""

_MISSION = mavlink.MAV_MISSION_TYPE_MISSION
_EMPTY_TYPES = frozenset({mavlink.MAV_MISSION_TYPE_FENCE, mavlink.MAV_MISSION_TYPE_RALLY})
_ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
_CANCELLED = mavlink.MAV_MISSION_OPERATION_CANCELLED


@dataclass(frozen=True)
class Outgoing:
    """One message for the companion to send.

    ``kind`` is ``"MISSION_REQUEST_INT"``, ``"MISSION_REQUEST"``, ``"MISSION_ACK"``,
    ``"MISSION_COUNT"``, ``"MISSION_ITEM_INT"`` or ``"MISSION_ITEM"``; ``seq`` is used by the
    requests and items, ``result`` (the MAV_MISSION_RESULT ``type``) by the ACK, ``count`` by
    MISSION_COUNT and ``item`` by the items.
    """

    kind: str
    target: Src
    seq: int = 0
    result: int = 0
    count: int = 0
    item: MissionItem | None = None
    mission_type: int = 0

    @property
    def xy(self) -> tuple[float, float] | tuple[int, int]:
        """The item's x/y as this message carries them: the stored integers for
        MISSION_ITEM_INT, degrees or metres (:func:`~mecanum_mav.protocol.mission.float_xy`) for the
        legacy MISSION_ITEM.

        Raises:
            ValueError: the message carries no item.
        """
        if self.item is None:
            raise ValueError(f"{self.kind} carries no item")
        if self.kind == "MISSION_ITEM":
            return float_xy(self.item)
        return self.item.x, self.item.y


@dataclass
class _Upload:
    """An upload in progress."""

    src: Src
    count: int
    deadline: float
    items: list[MissionItem] = field(default_factory=list)
    legacy: bool = False
    retries: int = 0

    @property
    def expected(self) -> int:
        """The seq of the item being requested."""
        return len(self.items)


def _ack(target: Src, result: int, mission_type: int = _MISSION) -> Outgoing:
    return Outgoing("MISSION_ACK", target, result=result, mission_type=mission_type)


def _item(fields: Mapping[str, float], *, encoded: bool) -> MissionItem:
    return item_from_fields(
        int(fields["seq"]), int(fields["frame"]), int(fields["command"]),
        int(fields["current"]), int(fields["autocontinue"]),
        (fields["param1"], fields["param2"], fields["param3"], fields["param4"]),
        fields["x"], fields["y"], fields["z"], encoded=encoded)


class MissionService:
    """The vehicle's side of the mission protocol (see the module docstring).

    Attributes:
        items: the accepted mission, read by the executor; replaced only as a whole.
        version: incremented every time the mission is replaced or cleared.
    """

    def __init__(self, items: Sequence[MissionItem] = ()) -> None:
        self.items: tuple[MissionItem, ...] = tuple(items)
        self.version = 0
        self._upload: _Upload | None = None
        self._events: list[tuple[str, str]] = []
        self._last_outcome: tuple[Src, int] | None = None  # (uploader, final ACK result)

    # ------------------------------------------------------------------ state

    @property
    def uploading(self) -> bool:
        """True while an upload is in progress."""
        return self._upload is not None

    def next_due_s(self) -> float:
        """The monotonic time at which :meth:`tick` next has work; ``math.inf`` when idle."""
        return self._upload.deadline if self._upload is not None else math.inf

    def take_events(self) -> list[tuple[str, str]]:
        """``(kind, text)`` events since the last call, oldest first.

        ``"replaced"`` / ``"cleared"``: the mission changed (persist it, reset the executor);
        ``"error"``: a failed operation, the text (at most ``STATUSTEXT_LEN`` characters) for a
        STATUSTEXT.
        """
        events, self._events = self._events, []
        return events

    # ------------------------------------------------------------------ upload

    def on_count(self, src: Src, count: int, mission_type: int, now: float) -> list[Outgoing]:
        """MISSION_COUNT: start (or restart) an upload of ``count`` items (uint16 on the wire)
        from ``src``."""
        if mission_type != _MISSION:
            return [_ack(src, mavlink.MAV_MISSION_UNSUPPORTED, mission_type)]
        upload = self._upload
        if upload is not None:
            if upload.src != src:
                self._error("Mission upload denied: another in progress")
                return [_ack(src, mavlink.MAV_MISSION_DENIED)]
            self._upload = None  # the uploader starts again
        if count > MAX_ITEMS:
            self._last_outcome = (src, mavlink.MAV_MISSION_NO_SPACE)
            self._error(f"Only {MAX_ITEMS} mission items are supported")
            return [_ack(src, mavlink.MAV_MISSION_NO_SPACE)]
        if count == 0:
            self._last_outcome = (src, _ACCEPTED)
            self._replace(())
            return [_ack(src, _ACCEPTED)]
        self._last_outcome = None
        self._upload = _Upload(src, count, now + ITEM_TIMEOUT_S)
        return [self._request(self._upload)]

    def on_item(self, src: Src, fields: Mapping[str, float], *, encoded: bool,
                mission_type: int, now: float) -> list[Outgoing]:
        """MISSION_ITEM_INT (``encoded=True``) or the legacy MISSION_ITEM (``encoded=False``).

        Args:
            fields: the message's ``seq``, ``frame``, ``command``, ``current``,
                ``autocontinue``, ``param1`` .. ``param4``, ``x``, ``y`` and ``z``.
        """
        if mission_type != _MISSION:
            return [_ack(src, mavlink.MAV_MISSION_UNSUPPORTED, mission_type)]
        upload = self._upload
        if upload is None:
            if self._last_outcome is not None and self._last_outcome[0] == src:
                return [_ack(src, self._last_outcome[1])]  # its final ACK was lost
            return [_ack(src, mavlink.MAV_MISSION_ERROR)]
        if src != upload.src:
            return [_ack(src, mavlink.MAV_MISSION_DENIED)]
        if not encoded:
            upload.legacy = True
        seq = int(fields["seq"])
        if seq < upload.expected:  # a duplicate: the request for the next one is out already
            return []
        if seq > upload.expected:  # out of sequence: ask for the expected one again
            return self._retry(upload, now, f"Mission upload stalled at item {upload.expected}")
        try:
            item = _item(fields, encoded=encoded)
            check_item(item, upload.count)
        except MissionItemError as exc:
            self._error(str(exc))
            return [self._finish(upload, exc.result)]
        upload.items.append(item)
        if upload.expected == upload.count:
            ack = self._finish(upload, _ACCEPTED)
            self._replace(upload.items)
            return [ack]
        upload.retries = 0
        upload.deadline = now + ITEM_TIMEOUT_S
        return [self._request(upload)]

    def tick(self, now: float) -> list[Outgoing]:
        """Request a late item again, or cancel the upload when the retries are used up."""
        upload = self._upload
        if upload is None or now < upload.deadline:
            return []
        return self._retry(upload, now, f"Mission upload timed out at item {upload.expected}")

    # ------------------------------------------------------------------ download

    def on_request_list(self, src: Src, mission_type: int, now: float) -> list[Outgoing]:
        """MISSION_REQUEST_LIST: the number of stored items (0 for fence and rally)."""
        if mission_type == _MISSION:
            return [Outgoing("MISSION_COUNT", src, count=len(self.items))]
        if mission_type in _EMPTY_TYPES:
            return [Outgoing("MISSION_COUNT", src, count=0, mission_type=mission_type)]
        return [_ack(src, mavlink.MAV_MISSION_UNSUPPORTED, mission_type)]

    def on_request(self, src: Src, seq: int, *, legacy: bool, mission_type: int,
                   now: float) -> list[Outgoing]:
        """MISSION_REQUEST_INT (``legacy=False``) or MISSION_REQUEST (``legacy=True``): the item
        as MISSION_ITEM_INT or MISSION_ITEM, or INVALID_SEQUENCE for a ``seq`` past the end."""
        if mission_type != _MISSION:
            return [_ack(src, mavlink.MAV_MISSION_UNSUPPORTED, mission_type)]
        if not 0 <= seq < len(self.items):
            return [_ack(src, mavlink.MAV_MISSION_INVALID_SEQUENCE)]
        kind = "MISSION_ITEM" if legacy else "MISSION_ITEM_INT"
        return [Outgoing(kind, src, seq=seq, item=self.items[seq])]

    def on_ack(self, src: Src, result: int, mission_type: int, now: float) -> None:
        """MISSION_ACK: the end of a download (consumed), or an error from the uploader, which
        cancels its upload."""
        upload = self._upload
        if (upload is not None and src == upload.src and mission_type == _MISSION
                and result != _ACCEPTED):
            self._error(f"Mission upload cancelled by GCS at item {upload.expected}")
            self._finish(upload, _CANCELLED)

    # ------------------------------------------------------------------ clear

    def on_clear_all(self, src: Src, mission_type: int, now: float) -> list[Outgoing]:
        """MISSION_CLEAR_ALL: empty the mission; an upload in progress is cancelled."""
        if mission_type not in (_MISSION, mavlink.MAV_MISSION_TYPE_ALL):
            return [_ack(src, mavlink.MAV_MISSION_UNSUPPORTED, mission_type)]
        out: list[Outgoing] = []
        upload = self._upload
        if upload is not None:
            self._error("Mission upload cancelled: mission cleared")
            cancel = self._finish(upload, _CANCELLED)
            if upload.src != src:
                out.append(cancel)
        self._replace(())
        out.append(_ack(src, _ACCEPTED, mission_type))
        return out

    # ------------------------------------------------------------------ helpers

    def _request(self, upload: _Upload) -> Outgoing:
        kind = "MISSION_REQUEST" if upload.legacy else "MISSION_REQUEST_INT"
        return Outgoing(kind, upload.src, seq=upload.expected)

    def _retry(self, upload: _Upload, now: float, give_up_text: str) -> list[Outgoing]:
        """Request the expected item again, or cancel when that was done MAX_RETRIES times."""
        if upload.retries >= MAX_RETRIES:
            self._error(give_up_text)
            return [self._finish(upload, _CANCELLED)]
        upload.retries += 1
        upload.deadline = now + ITEM_TIMEOUT_S
        return [self._request(upload)]

    def _finish(self, upload: _Upload, result: int) -> Outgoing:
        """End the upload (the mission is not touched here); its final ACK."""
        self._upload = None
        self._last_outcome = (upload.src, result)
        return _ack(upload.src, result)

    def _replace(self, items: Sequence[MissionItem]) -> None:
        self.items = tuple(items)
        self.version += 1
        if self.items:
            self._events.append(("replaced", f"Mission replaced: {len(self.items)} items"))
        else:
            self._events.append(("cleared", "Mission cleared"))

    def _error(self, text: str) -> None:
        self._events.append(("error", text[:STATUSTEXT_LEN]))
