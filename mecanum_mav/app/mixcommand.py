"""``mecanum-mav mix``: the four wheel outputs (normalized and PWM) for one drive command, or
one output line per line of a batch (CSV or JSON lines).

A command is Cartesian (``x`` forward, ``y`` right) or polar (``magnitude``, ``direction_deg``
clockwise from the nose), with ``rotation`` clockwise and ``heading_deg`` (clockwise from
north, for field-oriented driving); all normalized to [-1, 1] except the angles (degrees). A
command that cannot be mixed raises :class:`CommandError` (one line of a batch: answered with
its error, never with wheel values).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from collections.abc import Iterable, Sequence
from typing import TextIO

from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.mecanum.mixing import ALGORITHM_NAMES, Desaturation, mix_stick
from mecanum_mav.mecanum.wheels import WHEEL_KEYS

__all__ = ["CSV_COLUMNS", "DESAT_NAMES", "OUTPUT_HEADER", "POLAR_KEYS", "CommandError",
           "cmd_mix", "mix_fields", "run_batch", "stick_from_fields"]

DESAT_NAMES = {d.name.lower(): d for d in Desaturation}
"""The values of ``--desat``: :class:`~mecanum_mav.mecanum.mixing.Desaturation` by lower-case
name."""
CSV_COLUMNS = ("x", "y", "rotation", "heading_deg", "magnitude", "direction_deg", "algo")
"""The fields a command may have (a batch's CSV header names some of them)."""
POLAR_KEYS = ("magnitude", "direction_deg")
OUTPUT_HEADER = [f"w_{k.lower()}" for k in WHEEL_KEYS] + [
    f"pwm_{k.lower()}" for k in WHEEL_KEYS
] + ["error"]
"""A batch's CSV answer columns: the normalized wheels, their pulses (us), the error."""


class CommandError(ValueError):
    """A command (one line of a batch, or the flags of ``mix``) that cannot be mixed."""


# --------------------------------------------------------------------------- mixing a command


def _number(fields: dict[str, object], key: str) -> float:
    """Field ``key`` as a finite number; 0 when it is missing or empty."""
    raw = fields.get(key)
    if raw is None or raw == "":
        return 0.0
    try:
        value = float(raw)  # type: ignore[arg-type]  # any object: TypeError is caught
    except (TypeError, ValueError):
        raise CommandError(f"{key}: not a number: {raw!r}") from None
    if not math.isfinite(value):
        raise CommandError(f"{key}: must be finite, got {raw!r}")
    return value


def stick_from_fields(fields: dict[str, object]) -> tuple[float, float, float, float]:
    """``(x, y, rotation, heading_deg)`` from a command given in Cartesian or polar form.

    Polar fields (``magnitude``, ``direction_deg``) become ``x = m cos d``, ``y = m sin d``;
    missing fields are 0. Mixing both forms in one command is an error.
    """
    unknown = sorted(set(fields) - set(CSV_COLUMNS))
    if unknown:
        known = ", ".join(CSV_COLUMNS)
        raise CommandError(f"unknown field(s) {', '.join(unknown)}; known: {known}")
    polar = any(fields.get(k) not in (None, "") for k in POLAR_KEYS)
    cartesian = any(fields.get(k) not in (None, "") for k in ("x", "y"))
    if polar and cartesian:
        raise CommandError("give x/y or magnitude/direction_deg, not both")
    if polar:
        m, d = _number(fields, "magnitude"), math.radians(_number(fields, "direction_deg"))
        x, y = m * math.cos(d), m * math.sin(d)
    else:
        x, y = _number(fields, "x"), _number(fields, "y")
    return x, y, _number(fields, "rotation"), _number(fields, "heading_deg")


def mix_fields(
    fields: dict[str, object], params: Params, default_algo: str, priority: Desaturation
) -> tuple[str, list[float], tuple[int, int, int, int]]:
    """Mix one command; returns (algorithm, four normalized wheels, four PWM values in us)."""
    algo = str(fields.pop("algo", None) or default_algo)
    if algo not in ALGORITHM_NAMES:
        raise CommandError(f"unknown algorithm {algo!r}; known: {', '.join(ALGORITHM_NAMES)}")
    x, y, rotation, heading = stick_from_fields(fields)
    wheels = [round(float(w), 6) + 0.0 for w in mix_stick(
        x, y, rotation, algo, heading_deg=heading, priority=priority)]
    return algo, wheels, PwmMap.from_params(params).pulses_us(wheels)


# --------------------------------------------------------------------------- batch


def _parse_line(
    line: str, header: list[str] | None, default_keys: Sequence[str]
) -> dict[str, object]:
    if line.startswith("{"):  # (the batch strips each line)
        try:
            fields: dict[str, object] = json.loads(line)  # ("{" begins an object or fails)
        except json.JSONDecodeError as exc:
            raise CommandError(f"bad JSON: {exc.msg} at column {exc.colno}") from None
        return fields
    values = _cells(line)
    keys = header or list(default_keys)
    if len(values) > len(keys):
        raise CommandError(
            f"expected at most {len(keys)} values ({','.join(keys)}), got {len(values)}"
        )
    return {k: v.strip() for k, v in zip(keys, values, strict=False)}


def _cells(line: str) -> list[str]:
    try:
        return next(csv.reader([line]))
    except csv.Error as exc:  # (a cell over the csv module's field size limit, 128 KiB)
        raise CommandError(f"bad CSV: {exc}") from None


def _is_header(line: str) -> bool:
    try:
        first = _cells(line)[0].strip()  # (a line that is not blank: a row)
    except CommandError:
        return False  # (a row, answered with its error)
    return first in CSV_COLUMNS


def run_batch(
    lines: Iterable[str], out: TextIO, err: TextIO, params: Params, algo: str,
    priority: Desaturation,
) -> int:
    """Mix one command per input line (CSV or JSON lines); write one output line each.

    Blank lines and ``#`` comments are skipped. A CSV header line (naming columns from
    :data:`CSV_COLUMNS`) sets the column order and is answered by an output header; without a
    header the columns are ``x,y,rotation,heading_deg`` for ``cartesian`` and
    ``magnitude,direction_deg,rotation,heading_deg`` for the polar algorithms. CSV lines get
    CSV answers (``w_fl..w_rr,pwm_fl..pwm_rr,error``), JSON lines JSON answers. A bad line is
    answered with its error (and reported on ``err``), never with wheel values.

    Returns:
        0 if every line mixed, 1 otherwise.
    """
    default_keys = ("x", "y", "rotation", "heading_deg") if algo == "cartesian" else (
        "magnitude", "direction_deg", "rotation", "heading_deg")
    header: list[str] | None = None
    writer = csv.writer(out, lineterminator="\n")
    failed = False
    for number, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if header is None and not line.startswith("{") and _is_header(line):
            header = [h.strip() for h in next(csv.reader([line]))]
            bad = [h for h in header if h not in CSV_COLUMNS]
            if bad:
                err.write(f"line {number}: unknown column(s) {', '.join(bad)}\n")
                return 1
            writer.writerow(OUTPUT_HEADER)
            continue
        as_json = line.startswith("{")
        try:
            used, wheels, pwm = mix_fields(_parse_line(line, header, default_keys), params, algo,
                                           priority)
        except CommandError as exc:
            failed = True
            err.write(f"line {number}: {exc}\n")
            if as_json:
                out.write(json.dumps({"line": number, "error": str(exc)}) + "\n")
            else:
                writer.writerow([""] * 8 + [str(exc)])
            continue
        if as_json:
            out.write(json.dumps({"algorithm": used, "wheels": wheels, "pwm": list(pwm)}) + "\n")
        else:
            writer.writerow([*wheels, *pwm, ""])
    return 1 if failed else 0


# --------------------------------------------------------------------------- the command


def cmd_mix(args: argparse.Namespace, params: Params) -> int:
    """``mecanum-mav mix``: one command from the flags (a table, or ``--json``), or a batch
    from stdin (``--batch``); 2 for a command that cannot be mixed, 1 for a batch with bad
    lines."""
    algo = args.algo or ALGORITHM_NAMES[int(params["MIX_ALGO"])]
    priority = DESAT_NAMES[args.desat] if args.desat else Desaturation(int(params["MIX_DESAT"]))
    if args.batch:
        return run_batch(sys.stdin, sys.stdout, sys.stderr, params, algo, priority)
    fields: dict[str, object] = {
        "x": args.x, "y": args.y, "magnitude": args.magnitude,
        "direction_deg": args.direction, "rotation": args.rotation, "heading_deg": args.heading,
    }
    try:
        used, wheels, pwm = mix_fields({k: v for k, v in fields.items() if v is not None},
                                       params, algo, priority)
    except CommandError as exc:
        print(f"mecanum-mav mix: {exc}", file=sys.stderr)
        return 2
    channels = PwmMap.from_params(params).channels
    if args.json:
        print(json.dumps({"algorithm": used, "desaturation": priority.name.lower(),
                          "wheels": wheels, "pwm": list(pwm), "channels": list(channels)}))
        return 0
    print(f"algorithm {used}, desaturation {priority.name.lower()}")
    print("wheel  command    PWM us  channel")
    for key, w, p, ch in zip(WHEEL_KEYS, wheels, pwm, channels, strict=True):
        print(f"{key:<5}  {w:+.4f}   {p:>6}  {ch:>7}")
    return 0

