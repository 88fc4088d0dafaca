"""Parameter files: the text format MAVProxy (``param load``) and Mission Planner read, atomic.

One ``NAME VALUE`` per line, separated by whitespace or a comma (Mission Planner writes
``NAME,VALUE``); ``#`` starts a comment, on its own line or after a value; blank lines are
ignored. Values may be written ``1``, ``1.0`` or ``1e3``; an int parameter needs an integral
value. :func:`load` checks every line and then the cross-parameter rules and reports *all*
problems at once as ``path:line: message`` in a
:class:`~mecanum_mav.config.params.ParamFileError`; nothing is applied unless the whole file
is valid, and the order of lines does not matter. :func:`save` writes only full-line comments
and ``NAME VALUE`` lines, because MAVProxy rejects lines with a trailing comment, atomically
(:func:`~mecanum_mav.io.atomicfile.write_atomic`).

``python -m mecanum_mav.params --table`` prints the parameter reference table and
``python -m mecanum_mav.params --write-defaults params/default.parm`` regenerates the
defaults file from the schema.
"""

from __future__ import annotations

import argparse
import codecs
import logging
import os
import re
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from mecanum_mav.config.params import (
    GROUP_TITLES,
    NAME_MAX_LEN,
    RETIRED,
    SCHEMA,
    SPECS,
    ParamError,
    ParamFileError,
    Params,
    Value,
    consistency_problems,
    markdown_table,
    unknown_name,
)
from mecanum_mav.io.atomicfile import write_atomic

log = logging.getLogger(__name__)

__all__ = [
    "DEFAULTS_FILE_HEADER",
    "DEFAULT_HEADER",
    "format_text",
    "load",
    "main",
    "parse_text",
    "save",
    "save_keeping_layout",
    "update_text",
]


def parse_text(text: str, source: str = "<string>", base: Params | None = None) -> Params:
    """Parse parameter file text (see the module docstring) on top of ``base``.

    Returns a new store: ``base`` (default: the schema defaults) with the file's values
    applied; ``base`` itself is never modified. Raises :class:`ParamFileError` listing every
    problem as ``"{source}:{line}: {message}"`` when any line or cross-parameter rule fails.
    """
    result = base.copy() if base is not None else Params()
    errors: list[str] = []
    first_line: dict[str, int] = {}
    candidate = result.as_dict()
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split("#", 1)[0].replace(",", " ").split()
        if not fields:
            continue
        name, rest = fields[0], fields[1:]
        where = f"{source}:{number}: "
        if name in RETIRED:
            log.warning("%s%s is no longer a parameter (%s); line ignored", where, name,
                        RETIRED[name])
            continue
        if name not in SPECS:
            errors.append(where + unknown_name(name))
            continue
        duplicate = name in first_line
        if duplicate:
            errors.append(where + f"{name}: duplicate, already set on line {first_line[name]}")
        else:
            first_line[name] = number
        if len(rest) > 1:
            errors.append(where + f"{name}: unexpected text after the value: {rest[1:]!r}")
            continue
        try:
            value = SPECS[name].parse(rest[0] if rest else "")
        except ParamError as exc:
            errors.append(where + str(exc))
            continue
        if not duplicate:
            candidate[name] = value
    for message, names in consistency_problems(candidate):
        number = max(first_line.get(n, 0) for n in names)
        errors.append(f"{source}:{number}: {message}")
    if errors:
        raise ParamFileError(errors)
    result.update(candidate)
    return result


def load(path: str | os.PathLike[str], base: Params | None = None) -> Params:
    """Read a parameter file on top of ``base`` (default: the schema defaults).

    See :func:`parse_text`; raises :class:`ParamFileError` (nothing applied) or ``OSError``.
    A UTF-8 byte-order mark and Windows line ends are accepted.
    """
    text = Path(path).read_text(encoding="utf-8-sig", errors="replace")
    return parse_text(text, source=str(path), base=base)


DEFAULT_HEADER = (
    "mecanum-mav parameters: NAME VALUE per line, # starts a comment.\n"
    "Loads with mecanum-mav, MAVProxy (param load) and Mission Planner."
)
"""The comment header :func:`save` writes when given none."""

DEFAULTS_FILE_HEADER = (
    "mecanum-mav: every parameter at its default.\n"
    "Generated from the schema in mecanum_mav/config/params.py; do not edit by hand,\n"
    "regenerate with: python -m mecanum_mav.params --write-defaults params/default.parm"
)
"""The header of ``params/default.parm``."""


def format_text(params: Mapping[str, Value], *, header: str | None = None) -> str:
    """The text :func:`save` writes: a comment header, then every parameter in schema order,
    grouped under comment lines, as ``NAME VALUE`` (no trailing comments, for MAVProxy)."""
    header = DEFAULT_HEADER if header is None else header
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    group = None
    for s in SCHEMA:
        if s.group != group:
            group = s.group
            lines += [""] * bool(lines) + [f"# {GROUP_TITLES[group]}"]
        lines.append(f"{s.name:<{NAME_MAX_LEN}} {s.format(params[s.name])}")
    return "\n".join(lines) + "\n"


def save(
    params: Mapping[str, Value], path: str | os.PathLike[str], *, header: str | None = None
) -> None:
    """Write every parameter to ``path`` atomically
    (:func:`~mecanum_mav.io.atomicfile.write_atomic`: the permissions of the file it replaces are
    kept; on any exception ``path`` is untouched)."""
    write_atomic(path, format_text(params, header=header).encode("utf-8"))


_LINE_RE = re.compile(r"^(?P<lead>\s*(?P<name>[A-Za-z0-9_]+)[\s,]+)(?P<value>[^\s,#]+)"
                      r"(?P<rest>[^#]*)")


def update_text(text: str, params: Mapping[str, Value]) -> str:
    """``text`` (a parameter file) brought up to date with ``params``, keeping its layout.

    Only the value of a line whose parameter now has another value is rewritten: comments,
    blank lines, order, separators and spacing stay as they were. A parameter that differs
    from its default and has no line in the file is appended at the end, so loading the result
    gives ``params`` again. Lines this cannot read (they would not load either) are kept.
    """
    lines = text.splitlines()
    seen: set[str] = set()
    for i, line in enumerate(lines):
        match = _LINE_RE.match(line)
        if match is None or match["name"] not in SPECS:
            continue
        name = match["name"]
        seen.add(name)
        spec = SPECS[name]
        try:
            same = spec.parse(match["value"]) == params[name]
        except ParamError:
            same = False
        if not same:
            lines[i] = (match["lead"] + spec.format(params[name])
                        + line[match.start("rest"):])
    added = [s for s in SCHEMA if s.name not in seen and params[s.name] != s.default]
    lines += [f"{s.name} {s.format(params[s.name])}" for s in added]
    return "\n".join(lines) + "\n"


def save_keeping_layout(params: Mapping[str, Value], path: str | os.PathLike[str]) -> None:
    """Save ``params`` into the existing file at ``path`` as :func:`update_text` does (only
    changed values change: every other byte stays, a UTF-8 byte order mark and bytes that
    are not UTF-8 included), keeping the previous file as ``path`` + ``.bak``; a file that
    does not exist yet is written whole (:func:`save`). Both writes are atomic."""
    target = Path(path)
    try:
        old = target.read_bytes()
    except FileNotFoundError:
        save(params, target)
        return
    bom = codecs.BOM_UTF8 if old.startswith(codecs.BOM_UTF8) else b""
    text = old[len(bom):].decode("utf-8", errors="surrogateescape")
    new = bom + update_text(text, params).encode("utf-8", errors="surrogateescape")
    if new == old:
        return
    write_atomic(target.with_name(target.name + ".bak"), old)
    write_atomic(target, new)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m mecanum_mav.params", description="Generate files from the schema."
    )
    parser.add_argument("--table", action="store_true", help="print the parameter reference table")
    parser.add_argument("--write-defaults", metavar="PATH", help="write the defaults file")
    args = parser.parse_args(argv)
    if args.table:
        sys.stdout.write(markdown_table())
    if args.write_defaults:
        save(Params(), args.write_defaults, header=DEFAULTS_FILE_HEADER)
    if not (args.table or args.write_defaults):
        parser.print_help()
    return 0
