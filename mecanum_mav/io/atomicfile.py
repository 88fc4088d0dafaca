"""Replacing a file atomically: the parameter file and the mission file beside it.

A write goes to a temporary file beside the target (``.NAME.XXXXXXXX.tmp``) that is renamed
over it, so a reader, a power cut or ``kill -9`` sees the old file or the new one, never half.
A process killed in the middle of a write (while the temporary file is written and synced, a
few milliseconds) leaves that temporary file behind: :func:`remove_stale_temporaries`, called
when the files are opened again, removes it.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from pathlib import Path

__all__ = ["remove_stale_temporaries", "write_atomic"]


def write_atomic(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` so that readers see the old file or the new one, never half.

    A temporary file beside ``path`` is written, flushed to disk, given the permissions of the
    file it replaces (0644 for a new one) and renamed over it; the directory is then synced so
    the rename survives a power cut. On any exception the temporary file is removed and
    ``path`` is untouched.
    """
    target = Path(path)
    try:
        mode = stat.S_IMODE(target.stat().st_mode)
    except FileNotFoundError:
        mode = 0o644
    fd, tmp_name = tempfile.mkstemp(prefix=_temporary_prefix(target), suffix=_TEMPORARY_SUFFIX,
                                    dir=target.parent)
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as stream:
            stream.write(data)
            stream.flush()
            os.fsync(stream.fileno())
        tmp.chmod(mode)
        tmp.replace(target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise
    _fsync_directory(target.parent)


_TEMPORARY_SUFFIX = ".tmp"


def _temporary_prefix(target: Path) -> str:
    return f".{target.name}."


def remove_stale_temporaries(path: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporary files an interrupted :func:`write_atomic` of ``path`` (or of
    ``path.bak``) left behind; the removed paths. Only one process may write ``path``: call
    this before it starts."""
    target = Path(path)
    pattern = f"{_temporary_prefix(target)}*{_TEMPORARY_SUFFIX}"
    removed = []
    for stale in target.parent.glob(pattern):
        with contextlib.suppress(FileNotFoundError):
            stale.unlink()
            removed.append(stale)
    return removed


def _fsync_directory(directory: Path) -> None:
    """Make a rename durable (POSIX); a no-op where directories cannot be opened."""
    if not hasattr(os, "O_DIRECTORY"):
        return
    fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
