"""Claims one running rover holds against another on this machine: an exclusive ``flock`` on
a lock file, which the kernel releases when the process ends, however it ends (kill -9
included). The lock files stay (removing one would race with the next claim); each holds
the process id of its last holder, for the message a refused claimant prints.

- :func:`claim_ground_station`: one rover per system id and ground-station destination
  (two rovers sending as system 1 to the same ground station look like one vehicle to it:
  two acks per command, both drive), and one per listening port (two ``udpin`` sockets on
  one port both bind, with SO_REUSEADDR, and each gets part of the traffic). The lock files
  live in a per-user runtime folder (:func:`runtime_dir`).
- :func:`exclusive_lock`: the lock itself (also the ``--params`` file's claim,
  :func:`~mecanum_mav.io.storage.claim_parameter_file`).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import socket
import stat
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import quote

__all__ = ["InUseError", "claim_ground_station", "exclusive_lock", "ground_station_claim",
           "runtime_dir"]

_LISTEN = {"udpin": "UDP", "udp": "UDP", "tcpin": "TCP"}
"""pymavlink URL kinds that listen (``udp:`` listens too), and their protocol."""
_SEND = frozenset({"udpout", "udpbcast", "tcp"})
"""pymavlink URL kinds that send to a host and port."""


class InUseError(OSError):
    """Another running process holds the claim."""


def runtime_dir() -> Path:
    """This user's folder for the claims: ``$XDG_RUNTIME_DIR/mecanum-mav`` when that is set,
    else ``/tmp/mecanum-mav-UID``; created private (0700).

    Raises:
        OSError: it cannot be created, or it is not a folder this user owns (another user's
            folder in /tmp must not decide what this user may run).
    """
    base = os.environ.get("XDG_RUNTIME_DIR")
    path = (Path(base) / "mecanum-mav") if base else Path(f"/tmp/mecanum-mav-{os.getuid()}")
    try:
        path.mkdir(mode=0o700)
    except FileExistsError:
        pass
    except OSError as exc:  # (XDG_RUNTIME_DIR gone, or another user's after su)
        raise OSError(f"cannot keep the rover claims in {path}: {exc.strerror or exc}"
                      f"{' (from XDG_RUNTIME_DIR)' if base else ''}") from None
    info = path.lstat()
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid():
        raise OSError(f"{path} is not a folder of this user's: cannot keep the rover claims "
                      f"there")
    return path


@contextlib.contextmanager
def exclusive_lock(lock_path: Path, refusal: str,
                   error: type[InUseError] = InUseError) -> Iterator[None]:
    """Hold an exclusive ``flock`` on ``lock_path`` (created if missing) while inside, with
    this process id written in it.

    Raises:
        InUseError: (``error``) another process holds it: ``refusal``, its ``{holder}``
            replaced by the holder's process id in words.
        OSError: the lock file cannot be created or opened.
    """
    fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode("ascii", errors="replace").strip()
            who = f" (process {holder})" if holder.isdigit() else ""
            raise error(refusal.replace("{holder}", who)) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        os.close(fd)


def _address(host: str) -> str:
    """``host`` as an IPv4 address where it resolves (``localhost`` is 127.0.0.1)."""
    try:
        return str(socket.getaddrinfo(host, None, socket.AF_INET)[0][4][0])
    except (OSError, UnicodeError, IndexError):
        return host.lower()


def ground_station_claim(sysid: int, gcs_url: str) -> tuple[str, str] | None:
    """(lock file name, refusal message) for a rover of system ``sysid`` on the
    ground-station link ``gcs_url``; None for a link that needs no claim (a listening port 0,
    which the OS picks). Sending links are claimed per system id and destination (host
    resolved, port); listening links per protocol and port, whatever the system id."""
    kind, sep, rest = gcs_url.partition(":")
    host, _, port = rest.rpartition(":")
    if sep and kind in _LISTEN:
        if port == "0":
            return None
        proto = _LISTEN[kind]
        return (f"listen-{proto.lower()}-{quote(port, safe='')}.lock",
                f"--gcs {gcs_url}: another running rover{{holder}} listens on {proto} port "
                f"{port}; give each rover its own --gcs port")
    if sep and kind in _SEND:
        where = f"{kind}-{quote(_address(host), safe='')}-{quote(port, safe='')}"
    else:  # a serial device (DEVICE[,BAUD])
        where = "serial-" + quote(os.path.realpath(gcs_url.split(",")[0]), safe="")
    return (f"system{sysid}-{where}.lock",
            f"system id {sysid} on --gcs {gcs_url} is in use by another running rover"
            f"{{holder}}: a ground station would see the two as one vehicle (two answers to "
            f"each command, both driving); give each rover its own system id (sim --instance "
            f"N, or --set SYSID_THISMAV=K) or its own --gcs")


@contextlib.contextmanager
def claim_ground_station(sysid: int, gcs_url: str) -> Iterator[None]:
    """Hold the claim of :func:`ground_station_claim` while inside (nothing for a link that
    needs none).

    Raises:
        InUseError: another running rover on this machine holds it.
        OSError: the runtime folder cannot be used (:func:`runtime_dir`).
    """
    claim = ground_station_claim(sysid, gcs_url)
    if claim is None:
        yield
        return
    name, refusal = claim
    with exclusive_lock(runtime_dir() / name, refusal):
        yield
