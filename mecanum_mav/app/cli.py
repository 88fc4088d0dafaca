"""The ``mecanum-mav`` command line.

Sub-commands:
    sim     the companion and the built-in simulated flight controller (the quick start)
    run     the companion between a ground station (--gcs) and a flight controller (--fc)
    setup-fc  check (and with --apply fix) an ArduPilot flight controller for the companion
    simfc   the simulated flight controller alone, as its own process
    log     summarize and plot a tlog (a recorded drive)
    mix     wheel outputs (normalized and PWM) for one command, or a batch from stdin
    plot    the speed-envelope figures of seed 000 (and of our mixers) as PNGs
    params  validate a parameter file, print the parameters, or the schema as Markdown

Every sub-command takes ``--params FILE``, ``--set NAME=VALUE`` and ``--log-level LEVEL``.

Exit status: 0 on success (``run`` and ``sim`` also when stopped by Ctrl-C or SIGTERM once
running), 1 when a batch had bad lines (each reported), 2 for usage errors, parameter files
that do not validate (or do not exist, except for ``run`` and ``sim``, which start from the
defaults and create them) and a rover refused because another holds its parameter file or
its system id and ground station; 130 when Ctrl-C cut a command short (one line, no
traceback).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import logging
import math
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TextIO

from mecanum_mav import __version__
from mecanum_mav.config.params import (
    ParamError,
    ParamFileError,
    Params,
    markdown_table,
    parse_assignment,
)
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.io.keyfile import KeyFileError, load_signing_key
from mecanum_mav.io.paramfile import load, save
from mecanum_mav.mecanum.mixing import ALGORITHM_NAMES, Desaturation, mix_stick
from mecanum_mav.mecanum.wheels import WHEEL_KEYS

DESAT_NAMES = {d.name.lower(): d for d in Desaturation}
LOG_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR")
"""The values of ``--log-level``."""
CSV_COLUMNS = ("x", "y", "rotation", "heading_deg", "magnitude", "direction_deg", "algo")
POLAR_KEYS = ("magnitude", "direction_deg")
OUTPUT_HEADER = [f"w_{k.lower()}" for k in WHEEL_KEYS] + [
    f"pwm_{k.lower()}" for k in WHEEL_KEYS
] + ["error"]


class CommandError(ValueError):
    """A command (one line of a batch, or the flags of ``mix``) that cannot be mixed."""


# --------------------------------------------------------------------------- parameters


def load_params(path: Path | None, assignments: Sequence[str],
                instance: int | None = None) -> Params:
    """Parameters from defaults, then ``path`` (if any), then the system id of ``--instance``
    (:func:`instance_sysid`), then ``--set NAME=VALUE`` overrides.

    The instance's system id wins over the file (which may hold one an earlier run saved),
    ``--set SYSID_THISMAV=K`` over both.

    Raises:
        ParamFileError: the file does not validate (every bad line is listed).
        ParamError: an override is unknown, malformed or out of range.
    """
    params = load(path) if path is not None else Params()
    values: dict[str, float] = {} if instance is None else {
        "SYSID_THISMAV": instance_sysid(instance)}
    # All overrides at once: consistency (e.g. two wheels swapping channels) is checked on the
    # result, not after each one.
    values.update(dict(parse_assignment(text) for text in assignments))
    params.update(values)
    return params


# --------------------------------------------------------------------------- fleet instances

INSTANCE_PORT_BASE = 14560
"""UDP port instance 0 sends to; instance N sends to ``INSTANCE_PORT_BASE + 10 N``."""
INSTANCE_PORT_STEP = 10
"""Ports per instance, as ArduPilot SITL's ``-I N`` (5760 + 10 N ...)."""
MAX_INSTANCE = 254
"""The last instance whose system id (N + 1) is a valid vehicle id (SYSID_THISMAV <= 255)."""


def instance_sysid(instance: int) -> int:
    """The vehicle system id of fleet instance ``instance``: N + 1 (sim_vehicle.py's
    ``--auto-sysid``)."""
    return instance + 1


def instance_port(instance: int) -> int:
    """The UDP port fleet instance ``instance`` sends its ground-station link to: 14560 + 10 N,
    a block of ten per instance starting above 14550, so that a router can hand the fleet to
    a ground station listening on its usual 14550."""
    return INSTANCE_PORT_BASE + INSTANCE_PORT_STEP * instance


def instance_gcs_url(instance: int) -> str:
    """The default ``--gcs`` of fleet instance ``instance``: ``udpout:127.0.0.1:14560+10N``."""
    return f"udpout:127.0.0.1:{instance_port(instance)}"


def _instance_number(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not 0 <= value <= MAX_INSTANCE:
        raise argparse.ArgumentTypeError(f"must be 0 .. {MAX_INSTANCE}, got {value}")
    return value


# --------------------------------------------------------------------------- mixing a command


def _number(fields: dict[str, object], key: str, default: float | None = None) -> float | None:
    raw = fields.get(key)
    if raw is None or raw == "":
        return default
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
    missing Cartesian fields are 0. Mixing both forms in one command is an error.
    """
    unknown = sorted(set(fields) - set(CSV_COLUMNS))
    if unknown:
        known = ", ".join(CSV_COLUMNS)
        raise CommandError(f"unknown field(s) {', '.join(unknown)}; known: {known}")
    polar = any(fields.get(k) not in (None, "") for k in POLAR_KEYS)
    cartesian = any(fields.get(k) not in (None, "") for k in ("x", "y"))
    if polar and cartesian:
        raise CommandError("give x/y or magnitude/direction_deg, not both")
    rotation = _number(fields, "rotation", 0.0)
    heading = _number(fields, "heading_deg", 0.0)
    if polar:
        m = _number(fields, "magnitude", 0.0)
        d = math.radians(_number(fields, "direction_deg", 0.0) or 0.0)
        x, y = (m or 0.0) * math.cos(d), (m or 0.0) * math.sin(d)
    else:
        x, y = _number(fields, "x", 0.0) or 0.0, _number(fields, "y", 0.0) or 0.0
    return x, y, rotation or 0.0, heading or 0.0


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
    if line.lstrip().startswith("{"):
        try:
            fields = json.loads(line)
        except json.JSONDecodeError as exc:
            raise CommandError(f"bad JSON: {exc.msg} at column {exc.colno}") from None
        if not isinstance(fields, dict):
            raise CommandError("a JSON line must be an object")
        return dict(fields)
    values = next(csv.reader([line]))
    keys = header or list(default_keys)
    if len(values) > len(keys):
        raise CommandError(
            f"expected at most {len(keys)} values ({','.join(keys)}), got {len(values)}"
        )
    return {k: v.strip() for k, v in zip(keys, values, strict=False)}


def _is_header(line: str) -> bool:
    first = next(csv.reader([line]), [""])[0].strip()
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
    failures = 0
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
            failures += 1
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
    return 1 if failures else 0


# --------------------------------------------------------------------------- sub-commands


def cmd_mix(args: argparse.Namespace, params: Params) -> int:
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


def cmd_plot(args: argparse.Namespace, params: Params) -> int:
    from mecanum_mav.app.plots import render_all

    try:
        paths = render_all(Path(args.out))
    except RuntimeError as exc:
        print(f"mecanum-mav plot: {exc}", file=sys.stderr)
        return 2
    for path in paths:
        print(path)
    return 0


def cmd_params(args: argparse.Namespace, params: Params) -> int:
    if args.markdown:
        print(markdown_table())
        return 0
    if args.save:
        save(params, Path(args.save))
        print(f"saved {len(params.names())} parameters to {args.save}")
        return 0
    buffer = io.StringIO()
    for name in params.names():
        marker = "  # changed" if name in params.changed() else ""
        buffer.write(f"{name} {params[name]}{marker}\n")
    sys.stdout.write(buffer.getvalue())
    return 0


# --------------------------------------------------------------------------- the companion

PARAMS_RESET_HELP = ("start on the parameter defaults (and --set) instead of the --params "
                     "file, which is left untouched: for a file that no longer loads")
QUIET_HELP = ("no status line every 5 s (printed only when stdout is a terminal); what "
              "happens and errors are still said")
DEFAULT_GCS_URL = "udpout:127.0.0.1:14550"
"""Where QGroundControl and MAVProxy listen by default."""


SIGNING_KEY_HELP = ("MAVLink 2 signing on the ground-station link: FILE holds 64 hex digits "
                    "(the key) or a passphrase (key = SHA-256, as MAVProxy's 'signing key'); "
                    "it must not be readable by group or others. Only correctly signed "
                    "packets are obeyed; everything sent is signed")
FC_SIGNING_KEY_HELP = ("MAVLink 2 signing on the flight-controller link, for a board that "
                       "requires it (same FILE format as --signing-key)")


def signing_keys(args: argparse.Namespace) -> tuple[bytes | None, bytes | None]:
    """The ground-station and flight-controller links' signing keys from ``--signing-key``
    and ``--fc-signing-key`` (None where not given).

    Raises:
        KeyFileError: a key file is missing, not private, or holds no key.
    """
    gcs, fc = getattr(args, "signing_key", None), getattr(args, "fc_signing_key", None)
    return (None if gcs is None else load_signing_key(gcs),
            None if fc is None else load_signing_key(fc))


def serve(params: Params, gcs_url: str, fc_url: str, param_path: Path | None,
          tlog_path: Path | None,
          keys: tuple[bytes | None, bytes | None] = (None, None), *,
          quiet: bool = False) -> int:
    """Run the companion in the foreground until SIGINT/SIGTERM; ``fc_url`` may be ``sim``.

    The status line (:meth:`~mecanum_mav.control.core.RoverCore.status_line`: messages
    received, malformed packets, failed sends, refusals per kind) goes to stderr on SIGUSR1
    and at exit. On stdout it says what it does (:class:`~mecanum_mav.app.progress.Progress`:
    waiting for the flight controller, found, lost; on a terminal and without ``quiet`` a
    status line every 5 s). A SIGINT or SIGTERM while it starts abandons the start-up
    (:class:`KeyboardInterrupt`); once it runs, the first one stops it in order and any
    further one is ignored (:class:`~mecanum_mav.app.shutdown.Termination`)."""
    import signal

    from mecanum_mav.app.companion import Companion
    from mecanum_mav.app.progress import Progress
    from mecanum_mav.app.shutdown import on_signals, terminate_in_order
    from mecanum_mav.io.claims import claim_ground_station
    from mecanum_mav.io.storage import claim_parameter_file
    from mecanum_mav.sim.simfc import SimFlightController

    with terminate_in_order() as termination, contextlib.ExitStack() as stack:
        try:
            if param_path is not None:  # one rover per file: a second one is refused
                stack.enter_context(claim_parameter_file(param_path))
            # one rover per system id and ground station (and per listening port)
            stack.enter_context(claim_ground_station(int(params["SYSID_THISMAV"]), gcs_url))
            if fc_url == "sim":
                sim = SimFlightController("udpin:127.0.0.1:0", params)
                sim.start()
                stack.callback(sim.stop)
                fc_url = f"udpout:127.0.0.1:{sim.local_port}"
            tlog = stack.enter_context(tlog_path.open("ab")) if tlog_path else None
            companion = Companion(params, gcs_url, fc_url, param_path=param_path, tlog=tlog,
                                  gcs_signing_key=keys[0], fc_signing_key=keys[1])
        except (OSError, ValueError) as exc:
            print(f"mecanum-mav: {exc}", file=sys.stderr)
            return 2
        stack.callback(companion.close)
        signed = " (signed)" if keys[0] is not None else ""
        fc_signed = " (signed)" if keys[1] is not None else ""
        print(f"mecanum-mav: rover system {params['SYSID_THISMAV']} on {gcs_url}{signed}, "
              f"flight controller on {fc_url}{fc_signed}. Ctrl-C stops (wheels to neutral, "
              f"channels released).", flush=True)

        def print_status() -> None:
            print(f"mecanum-mav: {companion.core.status_line()}", file=sys.stderr, flush=True)

        progress = Progress(companion.core, fc_url, sys.stdout,
                            periodic=not quiet and sys.stdout.isatty())
        progress.started()
        companion.set_timer(progress.tick)

        # From here a SIGINT or SIGTERM, however many, ends the loop in order (neutral,
        # release) and waits for the links to linger: none cuts the shutdown short.
        termination.running(companion.stop)
        with on_signals((signal.SIGUSR1,), print_status):
            companion.run()
        print_status()
    return 0


def cmd_run(args: argparse.Namespace, params: Params) -> int:
    return serve(params, args.gcs, args.fc, args.params, args.tlog, args.keys,
                 quiet=args.quiet)


def cmd_sim(args: argparse.Namespace, params: Params) -> int:
    gcs = sim_gcs_url(args)
    host_port = gcs.split(":", 1)[1] if ":" in gcs else gcs
    if args.instance is None:
        print(f"mecanum-mav sim: point a ground station at UDP {host_port} "
              f"(QGroundControl and Mission Planner listen on 14550; "
              f"MAVProxy: mavproxy.py --master=udpin:{host_port})", flush=True)
    else:
        print(f"mecanum-mav sim: instance {args.instance}, system id "
              f"{params['SYSID_THISMAV']}, sending to UDP {host_port}: one --master="
              f"udpin:{host_port} of the router (see docs/fleet.md)",
              flush=True)
    return serve(params, gcs, "sim", args.params, args.tlog, args.keys, quiet=args.quiet)


def sim_gcs_url(args: argparse.Namespace) -> str:
    """``sim``'s ground-station URL: ``--gcs`` if given, else the instance's port
    (:func:`instance_gcs_url`), else :data:`DEFAULT_GCS_URL`."""
    if args.gcs is not None:
        return str(args.gcs)
    return DEFAULT_GCS_URL if args.instance is None else instance_gcs_url(args.instance)


def cmd_demo(args: argparse.Namespace, params: Params) -> int:
    from mecanum_mav.app.demo import TABLE_HEADER, LegReport, leg_row, plot_demo, run_demo

    print(f"mecanum-mav demo: simulator + companion + scripted ground station on loopback; "
          f"uploading a {args.side:g} m square with a diagonal, facing north, then AUTO ...",
          flush=True)
    print(TABLE_HEADER, flush=True)

    def print_leg(k: int, leg: LegReport) -> None:
        print(leg_row(k, leg), flush=True)  # as the rover drives on

    try:
        result = run_demo(params, side_m=args.side, on_leg=print_leg)
    except (RuntimeError, TimeoutError, OSError) as exc:
        print(f"mecanum-mav demo: {exc}", file=sys.stderr)
        return 1
    print(result.summary())
    try:
        print(f"wrote {plot_demo(result, Path(args.png))}")
    except RuntimeError as exc:  # no matplotlib
        print(f"mecanum-mav demo: no PNG: {exc}", file=sys.stderr)
    return 0


def cmd_log(args: argparse.Namespace, params: Params) -> int:
    from mecanum_mav.app.logview import run_log

    return run_log(args.tlog, args.png)


def serve_simfc(url: str, params: Params) -> int:
    """``mecanum-mav simfc --listen URL``: serve in the foreground until SIGINT or SIGTERM.

    Prints one line saying where it listens; returns 0, or 1 (message on stderr) when the
    link cannot be opened. Call from the main thread (it installs signal handlers).
    """
    import threading

    from mecanum_mav.app.shutdown import on_termination
    from mecanum_mav.sim.simfc import SimFlightController

    try:
        sim = SimFlightController(url, params)
    except (OSError, ValueError) as exc:
        print(f"simfc: {exc}", file=sys.stderr)
        return 1
    stop = threading.Event()
    with sim, on_termination(stop.set):
        port = sim.local_port
        where = f"{url} (port {port})" if port is not None else url
        print(f"simfc: simulated ArduPilot Rover, system {params['FC_SYSID']} component "
              f"{params['FC_COMPID']}, listening on {where}", flush=True)
        sim.run(stop)
    return 0


def cmd_setup_fc(args: argparse.Namespace, params: Params) -> int:
    from mecanum_mav.app.setupfc import run_setup

    return run_setup(args.fc, params, apply=args.apply, reboot=args.reboot,
                     signing_key=args.keys[1])


def cmd_simfc(args: argparse.Namespace, params: Params) -> int:
    return serve_simfc(args.listen, params)


# --------------------------------------------------------------------------- parser


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mecanum-mav",
        description="Drive a mecanum-wheeled rover over MAVLink. Frames: x forward, y right, "
        "rotation clockwise; directions in degrees clockwise from the nose.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--params", type=Path, metavar="FILE",
                        help="parameter file (NAME VALUE per line, # comments); sim and run "
                        "save the ground station's changes to it, and start from the defaults "
                        "when it does not exist yet")
    common.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="override a parameter (repeatable)")
    common.add_argument("--log-level", choices=LOG_LEVELS, type=str.upper, metavar="LEVEL",
                        help=f"what the log shows: {', '.join(LOG_LEVELS)} (default INFO for "
                        f"run and sim, ERROR for demo, WARNING for the others)")

    sim = sub.add_parser("sim", parents=[common],
                         help="companion + simulated flight controller (start here)",
                         description="Run the companion with the built-in simulated flight "
                         "controller and chassis; a ground station drives it over UDP.")
    sim.add_argument("--gcs", metavar="URL",
                     help=f"ground-station link (default {DEFAULT_GCS_URL}; with --instance N "
                     f"udpout:127.0.0.1:{INSTANCE_PORT_BASE}+{INSTANCE_PORT_STEP}N)")
    sim.add_argument("--instance", type=_instance_number, metavar="N",
                     help=f"rover N of a fleet on one machine (0 .. {MAX_INSTANCE}), as "
                     f"ArduPilot SITL's -I N: system id N+1 (SYSID_THISMAV; --set wins, the "
                     f"--params file does not) and the ground-station link to UDP port "
                     f"{INSTANCE_PORT_BASE}+{INSTANCE_PORT_STEP}N (--gcs wins), for a router "
                     f"such as MAVProxy. Give each rover its own --params and --tlog file")
    sim.add_argument("--tlog", type=Path, metavar="FILE", help="record all traffic (tlog)")
    sim.add_argument("--params-reset", action="store_true", help=PARAMS_RESET_HELP)
    sim.add_argument("--signing-key", type=Path, metavar="FILE", help=SIGNING_KEY_HELP)
    sim.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    sim.set_defaults(handler=cmd_sim, default_log_level="INFO", creates_params=True)

    demo = sub.add_parser("demo", parents=[common],
                          help="the whole product in one command: an AUTO mission in the "
                          "simulator",
                          description="Run the simulator, the companion and a scripted ground "
                          "station; upload a square-with-a-diagonal mission facing north, run it "
                          "in AUTO, print time, cross-track and arrival error per leg, and draw "
                          "planned, true and odometry paths.")
    demo.add_argument("--side", type=float, default=2.0, metavar="M",
                      help="side of the square in metres (default 2)")
    demo.add_argument("--png", default="demo.png", metavar="FILE",
                      help="where to write the figure (default demo.png)")
    demo.set_defaults(handler=cmd_demo, default_log_level="ERROR")  # (its companion's noise)

    run = sub.add_parser("run", parents=[common], help="the companion",
                         description="Run the companion: the rover a ground station sees, "
                         "driving the flight controller's outputs by RC_CHANNELS_OVERRIDE.")
    run.add_argument("--gcs", default=DEFAULT_GCS_URL, metavar="URL",
                     help=f"ground-station link, a pymavlink URL (default {DEFAULT_GCS_URL})")
    run.add_argument("--fc", required=True, metavar="URL",
                     help="flight-controller link: a pymavlink URL (e.g. /dev/ttyACM0,115200 or "
                     "udpout:HOST:PORT), or 'sim' for the built-in simulator")
    run.add_argument("--tlog", type=Path, metavar="FILE", help="record all traffic (tlog)")
    run.add_argument("--params-reset", action="store_true", help=PARAMS_RESET_HELP)
    run.add_argument("--signing-key", type=Path, metavar="FILE", help=SIGNING_KEY_HELP)
    run.add_argument("--fc-signing-key", type=Path, metavar="FILE", help=FC_SIGNING_KEY_HELP)
    run.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    run.set_defaults(handler=cmd_run, default_log_level="INFO", creates_params=True)

    setup = sub.add_parser(
        "setup-fc", parents=[common], help="check (and fix) an ArduPilot flight controller",
        description="Connect to the flight controller as the companion would, read the "
        "settings the companion depends on and print each with what it needs and why: the "
        "ground-station id, pass-through of the wheel channels, the fall-back to trim when the "
        "companion dies, the override timeout, matched ranges, rudder arming. Exit status: 0 "
        "when the board is safe, 1 when a hazard remains or a setting was not answered, 2 when "
        "the board cannot be reached, 3 when it will be safe once rebooted.")
    setup.add_argument("--fc", required=True, metavar="URL",
                       help="flight-controller link, as for 'run' (e.g. /dev/ttyACM0,115200)")
    setup.add_argument("--apply", action="store_true",
                       help="write the safe settings (stored even where they equal the "
                       "firmware's default), read them back and check again")
    setup.add_argument("--reboot", action="store_true",
                       help="then reboot the flight controller, wait for it and check again "
                       "(with --apply: write again what the reboot changed)")
    setup.add_argument("--fc-signing-key", type=Path, metavar="FILE", help=FC_SIGNING_KEY_HELP)
    setup.set_defaults(handler=cmd_setup_fc)

    simfc = sub.add_parser("simfc", parents=[common], help="the simulated flight controller",
                           description="Run the simulated ArduPilot Rover flight controller "
                           "and chassis alone, listening on a MAVLink URL.")
    simfc.add_argument("--listen", default="udpin:127.0.0.1:14551", metavar="URL",
                       help="where to listen (default udpin:127.0.0.1:14551)")
    simfc.set_defaults(handler=cmd_simfc)

    mix = sub.add_parser("mix", parents=[common], help="wheel outputs for a drive command",
                         description="Print the four wheel commands (normalized and PWM) for a "
                         "Cartesian (-x/-y) or polar (--magnitude/--direction) command, or mix a "
                         "batch read from stdin (CSV or JSON lines, one output line each).")
    mix.add_argument("--algo", choices=ALGORITHM_NAMES,
                     help="mixing algorithm (default: parameter MIX_ALGO)")
    mix.add_argument("--desat", choices=sorted(DESAT_NAMES),
                     help="desaturation strategy (default: parameter MIX_DESAT)")
    mix.add_argument("-x", type=float, help="forward command, [-1, 1]")
    mix.add_argument("-y", type=float, help="right command, [-1, 1]")
    mix.add_argument("-m", "--magnitude", type=float, help="polar magnitude, [-1, 1]")
    mix.add_argument("-d", "--direction", type=float,
                     help="polar direction, degrees clockwise from the nose")
    mix.add_argument("-r", "--rotation", type=float, default=0.0,
                     help="clockwise rotation, [-1, 1]")
    mix.add_argument("--heading", type=float, default=0.0,
                     help="robot heading (deg clockwise from north) for field-oriented driving")
    mix.add_argument("--json", action="store_true", help="print one JSON object")
    mix.add_argument("--batch", action="store_true",
                     help="read commands from stdin, one per line (CSV or JSON lines)")
    mix.set_defaults(handler=cmd_mix)

    log = sub.add_parser("log", parents=[common], help="summarize and plot a tlog",
                         description="Read a tlog (recorded with --tlog, by MAVProxy or by "
                         "Mission Planner), print distance, time per mode, failsafes and the "
                         "worst cross-track per mission leg, and draw the path, sticks, PWM, "
                         "modes, failsafes and mission progress. Damaged parts are reported "
                         "with their byte ranges and skipped; exit status 2 if nothing could be "
                         "read.")
    log.add_argument("tlog", type=Path, metavar="FILE.tlog", help="the telemetry log")
    log.add_argument("--png", type=Path, metavar="OUT",
                     help="where to write the figure (default: FILE.png beside the tlog)")
    log.set_defaults(handler=cmd_log)

    plot = sub.add_parser("plot", parents=[common], help="speed-envelope figures (PNG)")
    plot.add_argument("--out", default="figures", metavar="DIR", help="output folder")
    plot.set_defaults(handler=cmd_plot)

    par = sub.add_parser("params", parents=[common],
                         help="validate --params FILE and print the parameters")
    par.add_argument("--markdown", action="store_true", help="print the schema as a table")
    par.add_argument("--save", metavar="FILE", help="write the parameters to FILE (atomic)")
    par.set_defaults(handler=cmd_params)
    return parser


INTERRUPTED = 130
"""Exit status of a command cut short by Ctrl-C (128 + SIGINT, as shells report it)."""


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mecanum-mav`` console script: a Ctrl-C anywhere ends with one
    line and status :data:`INTERRUPTED`, never a traceback (``run`` and ``sim`` stop in order
    and exit 0)."""
    try:
        return _main(argv)
    except KeyboardInterrupt:
        with contextlib.suppress(KeyboardInterrupt):  # (a second Ctrl-C while saying so)
            print("mecanum-mav: interrupted", file=sys.stderr, flush=True)
        return INTERRUPTED


def configure_logging(args: argparse.Namespace) -> None:
    """The root logger's level from ``--log-level`` (else the sub-command's default: INFO for
    ``run`` and ``sim``, ERROR for ``demo``, WARNING for the others), and a handler on stderr
    if there is none."""
    level = args.log_level or getattr(args, "default_log_level", "WARNING")
    logging.basicConfig(format="%(asctime)s %(name)s: %(message)s")
    logging.getLogger().setLevel(level)


def _main(argv: Sequence[str] | None) -> int:
    args = build_parser().parse_args(argv)
    configure_logging(args)
    if getattr(args, "params_reset", False) and args.params is not None:
        print(f"mecanum-mav: --params-reset: starting on the defaults; {args.params} is not "
              f"read and left untouched (changes made from the ground station are not saved)",
              file=sys.stderr)
        args.params = None  # neither read nor saved to
    read_from = args.params
    if read_from is not None and not read_from.exists():
        if not getattr(args, "creates_params", False):
            print(f"mecanum-mav: --params {read_from} does not exist (only sim and run start "
                  f"without it, from the defaults, and create it)", file=sys.stderr)
            return 2
        if not read_from.parent.is_dir():
            print(f"mecanum-mav: --params {read_from}: the folder {read_from.parent} does not "
                  f"exist", file=sys.stderr)
            return 2
        print(f"mecanum-mav: {read_from} does not exist: starting from the defaults; changes "
              f"will be saved there", file=sys.stderr)
        read_from = None  # (still saved to)
    try:
        params = load_params(read_from, args.set, getattr(args, "instance", None))
        args.keys = signing_keys(args)
    except (ParamFileError, ParamError, KeyFileError) as exc:
        print(f"mecanum-mav: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"mecanum-mav: cannot read parameters: {exc}", file=sys.stderr)
        return 2
    return int(args.handler(args, params))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
