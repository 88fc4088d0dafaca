"""Mission files: the QGC WPL 110 text format (MAVProxy's ``wp load``, Mission Planner), atomic.

Every item read is checked as an upload would be (:func:`~mecanum_mav.protocol.mission.check_item`).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from mecanum_mav.io.atomicfile import write_atomic
from mecanum_mav.protocol.mission import (
    GLOBAL_XY_SCALE,
    MissionItem,
    check_item,
    item_from_fields,
    xy_scale,
)

__all__ = ["MissionFileError", "load_mission", "mission_path_for", "save_mission"]


class MissionFileError(ValueError):
    """A mission file that cannot be read; the text names the file and line."""


_HEADER = "QGC WPL 110"


def mission_path_for(param_path: str | os.PathLike[str]) -> Path:
    """Where the mission of a parameter file lives: beside it, ``rover.parm`` ->
    ``rover.waypoints``."""
    return Path(param_path).with_suffix(".waypoints")


def _format_xy(value: int, frame: int) -> str:
    scale = xy_scale(frame)
    if scale == 1.0:
        return str(value)
    digits = 7 if scale == GLOBAL_XY_SCALE else 4
    return f"{value / scale:.{digits}f}"


def save_mission(items: Iterable[MissionItem], path: str | os.PathLike[str]) -> None:
    """Write ``items`` to ``path`` atomically (:func:`~mecanum_mav.io.atomicfile.write_atomic`)."""
    lines = [_HEADER]
    for it in items:
        fields = [str(it.seq), str(it.current), str(it.frame), str(it.command),
                  *(repr(p) for p in it.params), _format_xy(it.x, it.frame),
                  _format_xy(it.y, it.frame), repr(it.z), str(it.autocontinue)]
        lines.append("\t".join(fields))
    write_atomic(path, ("\n".join(lines) + "\n").encode("utf-8"))


def load_mission(path: str | os.PathLike[str]) -> list[MissionItem]:
    """Read a QGC WPL 110 file; every item is checked as an upload would be.

    Raises:
        MissionFileError: ``file:line: what is wrong`` for the first problem found (bytes
            that are not UTF-8 text included).
        OSError: the file cannot be read.
    """
    source = Path(path)
    data = source.read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:  # a damaged file, or one a tool wrote in another code
        line = data.count(b"\n", 0, exc.start) + 1
        raise MissionFileError(f"{source}:{line}: not UTF-8 text (byte "
                               f"0x{data[exc.start]:02x})") from None
    lines = text.splitlines()
    if not lines or lines[0].strip() != _HEADER:
        raise MissionFileError(f"{source}:1: not a mission file (first line must be {_HEADER})")
    items: list[MissionItem] = []
    rows = [(n, line.split()) for n, line in enumerate(lines[1:], start=2) if line.strip()]
    for n, fields in rows:
        try:
            if len(fields) != 12:
                raise ValueError(f"expected 12 fields, found {len(fields)}")
            seq, current, frame, command = (int(f) for f in fields[:4])
            p1, p2, p3, p4, x, y, z = (float(f) for f in fields[4:11])
            if seq != len(items):
                raise ValueError(f"item {seq} where item {len(items)} was expected")
            item = item_from_fields(seq, frame, command, current, int(fields[11]),
                                    (p1, p2, p3, p4), x, y, z, encoded=False)
            check_item(item, len(rows))
        except ValueError as exc:  # MissionItemError is a ValueError too
            raise MissionFileError(f"{source}:{n}: {exc}") from None
        items.append(item)
    return items
