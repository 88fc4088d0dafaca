"""Where the rover keeps what a ground station changed: the parameter file and the mission
beside it, written atomically (the core's :class:`~mecanum_mav.control.core.Storage`)."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator, Sequence
from pathlib import Path

from mecanum_mav.config.params import Params
from mecanum_mav.io.atomicfile import remove_stale_temporaries
from mecanum_mav.io.claims import InUseError, exclusive_lock
from mecanum_mav.io.missionfile import (
    MissionFileError,
    load_mission,
    mission_path_for,
    save_mission,
)
from mecanum_mav.io.paramfile import save_keeping_layout
from mecanum_mav.protocol.mission import MissionItem

log = logging.getLogger(__name__)

__all__ = ["FileInUseError", "FileStorage", "claim_parameter_file"]


class FileStorage:
    """Keeps accepted parameters in the ``--params`` file and the mission beside it
    (``rover.parm`` -> ``rover.waypoints``), both written atomically; temporary files that a
    save cut short (kill -9, power loss) left beside them are removed when it is created."""

    def __init__(self, param_path: Path) -> None:
        self.param_path = param_path
        self.mission_path = mission_path_for(param_path)
        for path in (param_path, self.mission_path):  # a save cut short by kill -9 or power
            for stale in remove_stale_temporaries(path):
                log.warning("removed %s, left by a save that was cut short", stale)

    def save_params(self, params: Params) -> None:
        """Bring the parameter file up to date: only changed values change (comments, order
        and layout stay), the previous file is kept as FILE.bak
        (:func:`~mecanum_mav.io.paramfile.save_keeping_layout`)."""
        save_keeping_layout(params, self.param_path)

    def save_mission(self, items: Sequence[MissionItem]) -> None:
        """Write the mission file."""
        save_mission(items, self.mission_path)

    def load_mission(self) -> tuple[list[MissionItem], str]:
        """The stored mission (empty if none) and, if the file is unreadable, why."""
        if not self.mission_path.exists():
            return [], ""
        try:
            items = load_mission(self.mission_path)
        except (MissionFileError, OSError) as exc:
            log.error("mission not loaded: %s", exc)  # the file is left as it is
            return [], f"Mission file unreadable: {self.mission_path.name}"
        log.info("mission of %d items loaded from %s", len(items), self.mission_path)
        return items, ""


class FileInUseError(InUseError):
    """Another running process keeps its parameters (and mission) in this file."""


@contextlib.contextmanager
def claim_parameter_file(param_path: Path) -> Iterator[None]:
    """Hold the parameter file (and the mission file beside it) for this process.

    Two rovers saving into one file would overwrite each other's changes, and one's saved
    ``SYSID_THISMAV`` would give the other its system id next time: while one process holds
    ``rover.parm``, another one asking for it gets :class:`FileInUseError` instead. The claim
    is an exclusive ``flock`` on ``.rover.parm.lock`` beside the file (the file itself is
    replaced by every atomic save, so it cannot carry the lock); the kernel releases it when
    the process ends, however it ends (:func:`~mecanum_mav.io.claims.exclusive_lock`).

    Raises:
        FileInUseError: another process holds the file.
        OSError: the lock file cannot be created (e.g. a read-only folder).
    """
    lock_path = param_path.with_name(f".{param_path.name}.lock")
    with exclusive_lock(lock_path, f"{param_path} is in use by another running rover{{holder}} "
                        f"(it holds {lock_path}); give each rover its own --params file",
                        FileInUseError):
        yield
