"""Reading a MAVLink signing key file (``--signing-key FILE``, ``--fc-signing-key FILE``)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from mecanum_mav.protocol.signing import SigningKeyError, key_from_text

__all__ = ["KeyFileError", "load_signing_key"]


class KeyFileError(ValueError):
    """The key file cannot be used; the message names the file and says why."""


def load_signing_key(path: str | os.PathLike[str]) -> bytes:
    """The 32-byte secret key in ``path``: 64 hex digits or a passphrase (see
    :func:`~mecanum_mav.protocol.signing.key_from_text`).

    Like ssh with a private key, a file that its group or others may read is refused: the
    key is the rover's whole protection on a shared link.

    Raises:
        KeyFileError: missing, unreadable, readable by group or others, not UTF-8 text, or
            not a key.
    """
    file = Path(path)
    try:
        mode = file.stat().st_mode
        if not stat.S_ISREG(mode):
            raise KeyFileError(f"signing key {file}: not a regular file")
        if mode & (stat.S_IRGRP | stat.S_IROTH):
            raise KeyFileError(
                f"signing key {file}: readable by {'group' if mode & stat.S_IRGRP else 'others'}"
                f" (mode {stat.S_IMODE(mode):04o}); protect it with: chmod 600 {file}")
        data = file.read_bytes()
    except OSError as exc:
        raise KeyFileError(f"signing key {file}: {exc.strerror or exc}") from None
    try:
        return key_from_text(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise KeyFileError(f"signing key {file}: not UTF-8 text") from None
    except SigningKeyError as exc:
        raise KeyFileError(f"signing key {file}: {exc}") from None
