"""The simulator: the chassis, a simulated ArduPilot Rover board (in virtual time, or on a
socket as ``mecanum-mav simfc``), and the lockstep harness with its scripted ground station.

``from mecanum_mav.sim import Lockstep``: the rover core, the board and a ground station
stepped together in virtual time (see :mod:`mecanum_mav.sim.lockstep`).
"""

from mecanum_mav.sim.board import SimBoard, SimState
from mecanum_mav.sim.groundstation import ScriptedGroundStation, UdpPort, udp_ground_station
from mecanum_mav.sim.lockstep import Lockstep, OverrideSeen

__all__ = ["Lockstep", "OverrideSeen", "ScriptedGroundStation", "SimBoard", "SimState",
           "UdpPort", "udp_ground_station"]
