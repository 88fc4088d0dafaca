"""Building MAVLink messages without a link: a pymavlink ``MAVLink`` whose sends are collected.

Every ``mav.xxx_send(...)`` of pymavlink's generated API encodes the message and hands it to
``send``; :class:`MessageOutbox` keeps the message object instead of writing it anywhere. Code
that decides what to say (the rover core, telemetry, the mission protocol) writes to an outbox
and stays free of sockets; whoever owns a link packs the collected messages with that link's
own sequence number, source ids and signing (``link.mav.send(msg)``).
"""

from __future__ import annotations

from typing import Any

from mecanum_mav.protocol.dialect import mavlink

__all__ = ["MessageOutbox"]


class MessageOutbox(mavlink.MAVLink):
    """A pymavlink ``MAVLink`` that collects the messages its ``*_send`` methods produce.

    ``outbox.heartbeat_send(...)`` appends the encoded HEARTBEAT object to
    :attr:`messages`; :meth:`take` returns them, oldest first, and starts a new list.
    """

    def __init__(self) -> None:
        super().__init__(None)
        self.messages: list[Any] = []

    def send(self, mavmsg: Any, force_mavlink1: bool = False) -> None:
        """Collect ``mavmsg`` (an encoded pymavlink message object); nothing is written."""
        self.messages.append(mavmsg)

    def take(self) -> list[Any]:
        """The messages collected since the last call, oldest first."""
        messages, self.messages = self.messages, []
        return messages
