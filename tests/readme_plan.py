"""The README as a test plan: its sections, code blocks and commands, made runnable here.

:func:`blocks` reads README.md's fenced code blocks with the headings above them; the
walkthrough (tests/test_readme_walkthrough.py) runs the commands of each user path exactly
as written, changing only what a test on a shared machine must (:func:`localize`): the
ground station's UDP port 14550 becomes a free one, the flight controller's device
``/dev/ttyACM0,115200`` the real firmware's link, and paths into the repository absolute ones
(the commands run in an empty directory, as a user's would, from a clone).
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
README_GCS_PORT = 14550
README_FC_DEVICE = "/dev/ttyACM0,115200"
README_SITL = "ardupilot/build/sitl/bin/ardurover"
"""Where the README's ``twin`` finds ArduPilot's SITL (an ArduPilot clone's build output)."""
_FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)
_HEADING = re.compile(r"^(#{1,6})\s+(.+?)\s*$", re.MULTILINE)


@dataclass(frozen=True)
class Block:
    """A fenced code block: the headings above it (outermost first), its language, its text."""

    headings: tuple[str, ...]
    lang: str
    text: str

    def under(self, heading: str) -> bool:
        """Whether it sits under a heading that starts with ``heading``."""
        return any(h.startswith(heading) for h in self.headings)


def blocks(text: str | None = None) -> list[Block]:
    """Every fenced code block of the README (or of ``text``), in order."""
    text = README.read_text() if text is None else text
    out = []
    for match in _FENCE.finditer(text):
        path: dict[int, str] = {}
        for h in _HEADING.finditer(_without_fences(text[:match.start()])):
            level = len(h.group(1))
            path = {k: v for k, v in path.items() if k < level}
            path[level] = h.group(2)
        out.append(Block(tuple(path[k] for k in sorted(path)), match.group(1), match.group(2)))
    return out


def _without_fences(text: str) -> str:
    """``text`` without its fenced blocks (a ``#`` comment in one is not a heading)."""
    return _FENCE.sub("", text)


def section(heading: str, lang: str | None = None) -> list[Block]:
    """The blocks under a heading starting with ``heading`` (of language ``lang``)."""
    return [b for b in blocks() if b.under(heading) and (lang is None or b.lang == lang)]


def shell_commands(text: str) -> list[str]:
    """The commands of a shell block: continuation lines joined, comments and blank lines
    dropped, ``&&`` chains split into their commands."""
    joined = re.sub(r"\\\n\s*", " ", text)
    out = []
    for line in joined.splitlines():
        line = _strip_comment(line).strip()
        if line:
            out += [part.strip() for part in line.split("&&") if part.strip()]
    return out


def prompt_commands(text: str) -> list[str]:
    """The commands of a block typed at a program's prompt (MAVProxy's): one a line,
    ``#`` comments dropped."""
    return [c for line in text.splitlines() if (c := _strip_comment(line).strip())]


def _strip_comment(line: str) -> str:
    """``line`` without a ``#`` comment (not one inside quotes)."""
    quote = None
    for i, ch in enumerate(line):
        if ch in "'\"" and quote in (None, ch):
            quote = None if quote else ch
        elif ch == "#" and quote is None and (i == 0 or line[i - 1].isspace()):
            return line[:i]
    return line


def localize(command: str, *, gcs_port: int, fc_url: str | None = None,
             sitl: str | None = None) -> str:
    """``command`` for this machine: 14550 -> ``gcs_port``, the README's serial device ->
    ``fc_url``, its ArduPilot SITL -> ``sitl``, repository paths absolute; a ``mecanum-mav
    sim``, ``run`` or ``twin`` that relies on the default ground-station address gets it with
    the free port."""
    out = command.replace(str(README_GCS_PORT), str(gcs_port))
    if fc_url is not None:
        out = out.replace(README_FC_DEVICE, fc_url)
    if sitl is not None:
        out = out.replace(README_SITL, sitl)
    words = shlex.split(out)
    for i, word in enumerate(words):
        first = word.split("/", 1)[0]
        if "/" in word and first in ("params", "docs", "tools") and (ROOT / word).exists():
            words[i] = str(ROOT / word)
    if words[:2] in (["mecanum-mav", "sim"], ["mecanum-mav", "run"], ["mecanum-mav", "twin"]) \
            and "--gcs" not in words \
            and "--instance" not in words:
        words += ["--gcs", f"udpout:127.0.0.1:{gcs_port}"]
    return shlex.join(words)
