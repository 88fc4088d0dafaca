"""Fleet instances on one machine (``sim --instance N``), as ArduPilot SITL's ``-I N``: the
system id and ground-station port of instance N, and ``sim``'s ground-station URL."""

from __future__ import annotations

import argparse

__all__ = ["DEFAULT_GCS_URL", "INSTANCE_PORT_BASE", "INSTANCE_PORT_STEP", "MAX_INSTANCE",
           "instance_gcs_url", "instance_number", "instance_port", "instance_sysid",
           "sim_gcs_url"]

DEFAULT_GCS_URL = "udpout:127.0.0.1:14550"
"""Where QGroundControl and MAVProxy listen by default."""
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


def instance_number(text: str) -> int:
    """``--instance N``'s argument: a whole number 0 .. :data:`MAX_INSTANCE`.

    Raises:
        argparse.ArgumentTypeError: anything else (argparse reports it as a usage error).
    """
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not 0 <= value <= MAX_INSTANCE:
        raise argparse.ArgumentTypeError(f"must be 0 .. {MAX_INSTANCE}, got {value}")
    return value


def sim_gcs_url(args: argparse.Namespace) -> str:
    """``sim``'s ground-station URL: ``--gcs`` if given, else the instance's port
    (:func:`instance_gcs_url`), else :data:`DEFAULT_GCS_URL`."""
    if args.gcs is not None:
        return str(args.gcs)
    return DEFAULT_GCS_URL if args.instance is None else instance_gcs_url(args.instance)

