"""The long-running commands in the foreground until SIGINT or SIGTERM: the companion
(``run``, ``sim``: :func:`serve`) and the simulated flight controller alone (``simfc``:
:func:`serve_simfc`). Call them from the main thread (they install signal handlers).
"""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path

from mecanum_mav.config.params import Params

__all__ = ["serve", "serve_simfc"]


def serve(params: Params, gcs_url: str, fc_url: str, param_path: Path | None,
          tlog_path: Path | None,
          keys: tuple[bytes | None, bytes | None] = (None, None), *,
          quiet: bool = False, physics: str = "kinematic") -> int:
    """Run the companion in the foreground until SIGINT/SIGTERM; ``fc_url`` may be ``sim``
    (the built-in board, its chassis model ``physics``).

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
                sim = SimFlightController("udpin:127.0.0.1:0", params, physics=physics)
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
        # From here a SIGINT or SIGTERM, however many, ends the loop in order (neutral,
        # release) and waits for the links to linger: none cuts the shutdown short. (Before
        # the line below says it runs: a signal the moment it is read must not exit 130.)
        termination.running(companion.stop)
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

        with on_signals((signal.SIGUSR1,), print_status):
            companion.run()
        print_status()
    return 0


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

