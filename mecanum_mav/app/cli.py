"""The ``mecanum-mav`` command line.

Sub-commands:
    sim     the companion and the built-in simulated flight controller (the quick start)
    run     the companion between a ground station (--gcs) and a flight controller (--fc)
    setup-fc  check (and with --apply fix) an ArduPilot flight controller for the companion
    simfc   the simulated flight controller alone, as its own process
    log     summarize and plot a tlog (a recorded drive); --rerun/--view: its Rerun view
    view    watch the rover live in Rerun's viewer, from any MAVLink stream or a tlog
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

This module is the command line itself: the parsers (what docs/reference/cli.md is generated
from), the entry point, and each sub-command's handler, which turns its flags into a call.
What the commands do lives beside it: :mod:`~mecanum_mav.app.foreground` (``run``, ``sim``,
``simfc``), :mod:`~mecanum_mav.app.mixcommand` (``mix``), :mod:`~mecanum_mav.app.instances`
(``--instance``), :mod:`~mecanum_mav.app.setupfc`, :mod:`~mecanum_mav.app.logview`,
:mod:`~mecanum_mav.app.demo`, :mod:`~mecanum_mav.app.plots`. Their public names are
importable from here too.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import logging
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from mecanum_mav import __version__
from mecanum_mav.app.foreground import serve, serve_simfc
from mecanum_mav.app.instances import (
    DEFAULT_GCS_URL,
    INSTANCE_PORT_BASE,
    INSTANCE_PORT_STEP,
    MAX_INSTANCE,
    instance_gcs_url,
    instance_number,
    instance_port,
    instance_sysid,
    sim_gcs_url,
)
from mecanum_mav.app.mixcommand import (
    CSV_COLUMNS,
    DESAT_NAMES,
    OUTPUT_HEADER,
    POLAR_KEYS,
    CommandError,
    cmd_mix,
    mix_fields,
    run_batch,
    stick_from_fields,
)
from mecanum_mav.app.view import DEFAULT_CONNECT, DEFAULT_WEB_PORT
from mecanum_mav.config.params import (
    ParamError,
    ParamFileError,
    Params,
    markdown_table,
    parse_assignment,
)
from mecanum_mav.io.keyfile import KeyFileError, load_signing_key
from mecanum_mav.io.paramfile import load, save
from mecanum_mav.mecanum.mixing import ALGORITHM_NAMES
from mecanum_mav.sim.physics import (
    DEFAULT_PHYSICS,
    MIN_REAL_TIME_FACTOR,
    PHYSICS,
    PhysicsUnavailableError,
    mujoco_real_time_factor,
)

__all__ = [  # the command line, and what it re-exports from the modules that do the work
    "CSV_COLUMNS", "DEFAULT_GCS_URL", "DESAT_NAMES", "INSTANCE_PORT_BASE", "INSTANCE_PORT_STEP",
    "INTERRUPTED", "LOG_LEVELS", "MAX_INSTANCE", "OUTPUT_HEADER", "POLAR_KEYS", "CommandError",
    "build_parser", "configure_logging", "instance_gcs_url", "instance_port", "instance_sysid",
    "load_params", "main", "mix_fields", "run_batch", "serve", "serve_simfc", "signing_keys",
    "sim_gcs_url", "stick_from_fields",
]

LOG_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR")
"""The values of ``--log-level``."""
PARAMS_RESET_HELP = ("start on the parameter defaults (and --set) instead of the --params "
                     "file, which is left untouched: for a file that no longer loads")
QUIET_HELP = ("no status line every 5 s (printed only when stdout is a terminal); what "
              "happens and errors are still said")
SIGNING_KEY_HELP = ("MAVLink 2 signing on the ground-station link: FILE holds 64 hex digits "
                    "(the key) or a passphrase (key = SHA-256, as MAVProxy's 'signing key'); "
                    "it must not be readable by group or others. Only correctly signed "
                    "packets are obeyed; everything sent is signed")
FC_SIGNING_KEY_HELP = ("MAVLink 2 signing on the flight-controller link, for a board that "
                       "requires it (same FILE format as --signing-key)")


# --------------------------------------------------------------------------- common flags


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


def signing_keys(args: argparse.Namespace) -> tuple[bytes | None, bytes | None]:
    """The ground-station and flight-controller links' signing keys from ``--signing-key``
    and ``--fc-signing-key`` (None where not given).

    Raises:
        KeyFileError: a key file is missing, not private, or holds no key.
    """
    gcs, fc = getattr(args, "signing_key", None), getattr(args, "fc_signing_key", None)
    return (None if gcs is None else load_signing_key(gcs),
            None if fc is None else load_signing_key(fc))


# --------------------------------------------------------------------------- the handlers
# One per sub-command: its flags to a call of the module that does the work.


def cmd_run(args: argparse.Namespace, params: Params) -> int:
    return serve(params, args.gcs, args.fc, args.params, args.tlog, args.keys,
                 quiet=args.quiet)


def cmd_sim(args: argparse.Namespace, params: Params) -> int:
    gcs = sim_gcs_url(args)
    scheme, _, host_port = gcs.partition(":")
    # A ground station (or the router) takes the other end of a UDP link: it listens where
    # the rover sends (udpout), it sends where the rover listens (udpin, pymavlink's udp).
    master = {"udpout": "udpin", "udpin": "udpout", "udp": "udpout"}.get(scheme)
    rover = ("" if args.instance is None else
             f"instance {args.instance}, system id {params['SYSID_THISMAV']}, ")
    if master is None:  # (a TCP link or a serial device: its URL says it all)
        print(f"mecanum-mav sim: {rover}ground-station link {gcs}", flush=True)
    elif args.instance is not None:
        print(f"mecanum-mav sim: {rover}{'sending to' if scheme == 'udpout' else 'listening on'}"
              f" UDP {host_port}: one --master={master}:{host_port} of the router (see "
              f"docs/fleet.md)", flush=True)
    elif scheme == "udpout":
        print(f"mecanum-mav sim: point a ground station at UDP {host_port} "
              f"(QGroundControl and Mission Planner listen on 14550; "
              f"MAVProxy: mavproxy.py --master=udpin:{host_port})", flush=True)
    else:
        print(f"mecanum-mav sim: listening for a ground station on UDP {host_port} "
              f"(MAVProxy: mavproxy.py --master=udpout:{host_port})", flush=True)
    if args.physics == "mujoco":
        try:
            factor = mujoco_real_time_factor(params)
        except PhysicsUnavailableError as exc:
            print(f"mecanum-mav sim: {exc}", file=sys.stderr)
            return 2
        print(f"MuJoCo chassis: {factor:.1f}x real time", flush=True)
        if factor < MIN_REAL_TIME_FACTOR:
            print(f"mecanum-mav sim: warning: the MuJoCo chassis runs only {factor:.1f}x real "
                  f"time (under {MIN_REAL_TIME_FACTOR:g}x): a busy machine may make it fall "
                  "behind", file=sys.stderr, flush=True)
    return with_view(args, args.tlog, lambda tlog: serve(
        params, gcs, "sim", args.params, tlog, args.keys, quiet=args.quiet,
        physics=args.physics))


def with_view(args: argparse.Namespace, tlog: Path | None,
              run: Callable[[Path | None], int], also: Sequence[str] = ()) -> int:
    """``run(tlog)``; with ``--view`` a ``view`` process follows that tlog (a temporary one
    when None) and the URLs ``also`` while it runs, and is stopped after (``sim --view``,
    ``twin --view``)."""
    if not args.view:
        return run(tlog)
    from mecanum_mav.app.view import follow_in_viewer, stop_view

    tlog, viewer = follow_in_viewer(tlog, args.params, args.set, args.web_port, also)
    try:
        return run(tlog)
    finally:
        stop_view(viewer)


def cmd_twin(args: argparse.Namespace, params: Params) -> int:
    import socket

    from mecanum_mav.app.twin import run_twin
    from mecanum_mav.sim.firmware import sitl_from_env
    from mecanum_mav.sim.process import free_port
    from mecanum_mav.sim.truthsender import view_url

    sitl = args.sitl or sitl_from_env()
    if sitl is None:
        print("mecanum-mav twin: give --sitl PATH (ArduPilot's ardurover) or set "
              "$MECANUM_SITL", file=sys.stderr)
        return 2
    truth = args.truth or f"udpout:127.0.0.1:{free_port(socket.SOCK_DGRAM)}"
    try:
        watch = view_url(truth)
    except ValueError as exc:
        print(f"mecanum-mav twin: {exc}", file=sys.stderr)
        return 2
    return with_view(args, None, lambda tlog: run_twin(
        params, sitl, friction=args.friction, gcs=args.gcs, tlog=tlog, truth=truth),
        also=[watch])


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

    return run_log(args.tlog, args.png, rerun=args.rerun, view=args.view, params=params,
                   web_port=args.web_port)


def cmd_view(args: argparse.Namespace, params: Params) -> int:
    from mecanum_mav.app.view import run_view

    return run_view(args.connect or [DEFAULT_CONNECT], params, save=args.save,
                    web_port=args.web_port)


def cmd_setup_fc(args: argparse.Namespace, params: Params) -> int:
    from mecanum_mav.app.setupfc import run_setup

    return run_setup(args.fc, params, apply=args.apply, reboot=args.reboot,
                     signing_key=args.keys[1])


def cmd_simfc(args: argparse.Namespace, params: Params) -> int:
    return serve_simfc(args.listen, params)


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


# --------------------------------------------------------------------------- parser


def add_web_port(parser: argparse.ArgumentParser, when: str) -> None:
    """``--web-port P``: where the Rerun web viewer is served (``when``: in which case)."""
    parser.add_argument("--web-port", type=int, default=DEFAULT_WEB_PORT, metavar="P",
                        help=f"{when}the Rerun web viewer's port on 127.0.0.1 (default "
                        f"{DEFAULT_WEB_PORT})")


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
    sim.add_argument("--instance", type=instance_number, metavar="N",
                     help=f"rover N of a fleet on one machine (0 .. {MAX_INSTANCE}), as "
                     f"ArduPilot SITL's -I N: system id N+1 (SYSID_THISMAV; --set wins, the "
                     f"--params file does not) and the ground-station link to UDP port "
                     f"{INSTANCE_PORT_BASE}+{INSTANCE_PORT_STEP}N (--gcs wins), for a router "
                     f"such as MAVProxy. Give each rover its own --params and --tlog file")
    sim.add_argument("--tlog", type=Path, metavar="FILE", help="record all traffic (tlog)")
    sim.add_argument("--physics", choices=PHYSICS, default=DEFAULT_PHYSICS,
                     help="the chassis model: kinematic (default; exact wheel kinematics, "
                     "no inertia) or mujoco (a rigid body on rollers in MuJoCo; needs "
                     "pip install 'mecanum-mav[physics]')")
    sim.add_argument("--params-reset", action="store_true", help=PARAMS_RESET_HELP)
    sim.add_argument("--signing-key", type=Path, metavar="FILE", help=SIGNING_KEY_HELP)
    sim.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    sim.add_argument("--view", action="store_true",
                     help="watch it in Rerun's viewer, the true pose and the companion's "
                     "output to the flight controller included: 'view' follows the --tlog "
                     "(a temporary one without it); needs pip install 'mecanum-mav[view]'")
    add_web_port(sim, "with --view and no display, ")
    sim.set_defaults(handler=cmd_sim, default_log_level="INFO", creates_params=True)

    twin = sub.add_parser("twin", parents=[common],
                          help="real ArduPilot firmware (SITL) + MuJoCo chassis + companion",
                          description="Run the digital twin: ArduPilot Rover's own firmware "
                          "(SITL, JSON physics backend) drives the MuJoCo chassis, set up by "
                          "setup-fc --apply --reboot, with the companion in the loop; a ground "
                          "station drives the companion. Needs the physics extra.")
    twin.add_argument("--sitl", type=Path, metavar="PATH",
                      help="the ardurover binary (default: $MECANUM_SITL)")
    twin.add_argument("--friction", type=float, default=0.8, metavar="F",
                      help="the floor's friction coefficient (SIM_FRICTION; default 0.8)")
    twin.add_argument("--gcs", default=DEFAULT_GCS_URL, metavar="URL",
                      help=f"the companion's ground-station link (default {DEFAULT_GCS_URL})")
    twin.add_argument("--view", action="store_true",
                      help="watch it in Rerun's viewer: 'view' follows the companion's tlog "
                      "(both links: its overrides, the firmware's outputs) and the chassis's "
                      "truth (--truth: its true path and wheel contacts); needs pip install "
                      "'mecanum-mav[view]'")
    twin.add_argument("--truth", metavar="udpout:HOST:PORT",
                      help="where the chassis's truth goes (SIM_STATE 20 Hz, wheel contacts "
                      "10 Hz, as system 1 component 25; default: a free port on 127.0.0.1, "
                      "printed; --view shows it; 'view --connect udpin:HOST:PORT' too)")
    add_web_port(twin, "with --view and no display, ")
    twin.set_defaults(handler=cmd_twin)

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
    log.add_argument("--rerun", type=Path, metavar="OUT.rrd",
                     help="also write the Rerun view of the drive (as 'view' shows it live; "
                     "open it with 'rerun OUT.rrd'; needs pip install 'mecanum-mav[view]')")
    log.add_argument("--view", action="store_true",
                     help="open the Rerun view of the drive (native viewer with a display, "
                     "else the web viewer on 127.0.0.1, its address printed; Ctrl-C ends)")
    add_web_port(log, "with --view and no display, ")
    log.add_argument("--png", type=Path, metavar="OUT",
                     help="where to write the figure (default: FILE.png beside the tlog; "
                     "with --rerun or --view only when given)")
    log.set_defaults(handler=cmd_log)

    view = sub.add_parser(
        "view", parents=[common], help="watch the rover live in Rerun's viewer",
        description="A live view of any MAVLink stream in Rerun's viewer: the map (mission "
        "plan, estimated path, the true path where SIM_STATE is on the stream), the chassis "
        "to scale with each wheel's command, time series of the sticks, wheel commands, PWM, "
        "speed and cross-track, and modes, arming and failsafes on the timeline. It only "
        "listens. The native viewer opens where a display exists, else the web viewer is "
        "served on 127.0.0.1 and its address printed. Ctrl-C ends. Needs pip install "
        "'mecanum-mav[view]'. --params/--set give the PWM map and chassis size (PARAM_VALUE "
        "on the stream updates them).")
    view.add_argument("--connect", action="append", metavar="URL",
                      help=f"a pymavlink URL or a tlog being written (followed); again for "
                      f"more sources, merged in time order (e.g. a running twin's printed "
                      f"truth URL beside the ground station's stream). Default "
                      f"{DEFAULT_CONNECT}: an extra output of MAVProxy (mavproxy.py "
                      f"--master=udpin:127.0.0.1:14550 --out=udpout:127.0.0.1:14551), beside "
                      f"the ground station. Without a ground station on 14550: "
                      f"udpin:127.0.0.1:14550 (the companion's own link)")
    view.add_argument("--save", type=Path, metavar="OUT.rrd",
                      help="also record the view to OUT.rrd (open it later with 'rerun')")
    add_web_port(view, "without a display, ")
    view.set_defaults(handler=cmd_view)

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
