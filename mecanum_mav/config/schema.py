"""Every parameter's definition, as data: read it top to bottom.

:data:`SCHEMA` lists every parameter once, grouped by concern under a heading per group
(the groups and their titles are :data:`GROUP_TITLES`, in the same order), as ArduPilot's
``AP_Param`` tables or ros2_controllers' ``generate_parameter_library`` do. Each entry is a
:class:`~mecanum_mav.config.spec.ParamSpec`: name, kind, default, range, units, one sentence,
enumeration labels, and whether a change waits for a restart (``reboot_required``, which the
parameter protocol reports). The order is the order of parameter files, of the reference
table and of the MAVLink parameter index. Names follow ArduPilot: at most 16 characters (the
MAVLink ``param_id`` field), upper case, ``GROUP_NAME``.

Everything else reads this table: the store and its validation
(:mod:`mecanum_mav.config.params`), the cross-parameter rules
(:mod:`mecanum_mav.config.rules`), parameter files (:mod:`mecanum_mav.io.paramfile`), the
reference table and the MAVLink parameter protocol. The table is checked when this module is
imported: a bad entry, a name listed twice or a group without a title raises.
"""

from __future__ import annotations

from collections.abc import Sequence

from mecanum_mav.config.spec import ParamSpec
from mecanum_mav.mecanum.wheels import WHEEL_KEYS as WHEELS
from mecanum_mav.mecanum.wheels import WHEEL_NAMES

__all__ = ["GROUP_TITLES", "RETIRED", "SCHEMA", "SPECS", "WHEELS"]

# WHEELS (exported): the wheel abbreviations in parameter names, FL, FR, RL, RR, defined in
# mecanum_mav.mecanum.wheels as WHEEL_KEYS.
_WHEEL_WORDS = {
    abbreviation: full.replace("_", "-")
    for abbreviation, full in zip(WHEELS, WHEEL_NAMES, strict=True)
}

GROUP_TITLES: dict[str, str] = {
    "MIX": "Stick mixing",
    "INP": "Stick input shaping",
    "GEO": "Geometry (metres)",
    "WHL": "Wheel speed",
    "MOT_DZ": "Motor output, all wheels",
    **{f"MOT_{w}": f"Motor output, {_WHEEL_WORDS[w]} wheel" for w in WHEELS},
    "SYSID": "MAVLink identity",
    "FC": "Flight-controller link",
    "OUT": "Output to the flight controller",
    "FS": "Failsafes",
    "ARMING": "Arming",
    "RCMAP": "Stick channels (RC receiver and ground-station RC_CHANNELS_OVERRIDE)",
    "RCIN": "RC stick input: the receiver through the flight controller, pulse range",
    "MODE": "Mode switch (RC receiver)",
    "MAN": "Manual driving",
    "CTL": "Control loop",
    "GUID": "GUIDED driving",
    "WP": "AUTO missions",
    "ORIGIN": "Global origin of the local frame",
    "ODOM": "Odometry",
    "TLM": "Telemetry to the ground station",
    "SIM": "Built-in simulator (flight controller and chassis)",
}
"""Title of each parameter group, in file order."""


# fmt: off
# (the schema tables keep each entry's numbers on one line)
def _wheel_specs(wheel: str, channel: int) -> tuple[ParamSpec, ...]:
    """The five motor output parameters of one wheel (``FL`` ... ``RR``)."""
    words = _WHEEL_WORDS[wheel]
    prefix = f"MOT_{wheel}"
    return (
        ParamSpec(
            f"{prefix}_CH", int, default=channel, minimum=1, maximum=16, units="",
            description=f"RC channel (1-16, sent in RC_CHANNELS_OVERRIDE; ArduPilot never "
            f"reads 17-18) whose flight controller output drives the {words} wheel's ESC.",
        ),
        ParamSpec(
            f"{prefix}_MIN", int, default=1000, minimum=800, maximum=2200, units="us",
            description=f"ESC pulse width for full output in the {words} motor's negative "
            f"direction (full backward for the robot unless {prefix}_REV = 1).",
        ),
        ParamSpec(
            f"{prefix}_TRIM", int, default=1500, minimum=800, maximum=2200, units="us",
            description=f"ESC pulse width at which the {words} motor stands still; sent as "
            f"neutral when disarmed or in failsafe.",
        ),
        ParamSpec(
            f"{prefix}_MAX", int, default=2000, minimum=800, maximum=2200, units="us",
            description=f"ESC pulse width for full output in the {words} motor's positive "
            f"direction (full forward for the robot unless {prefix}_REV = 1).",
        ),
        ParamSpec(
            f"{prefix}_REV", int, default=0, minimum=0, maximum=1, units="",
            values={0: "normal", 1: "reversed"},
            description=f"Reverse the {words} motor at the PWM edge (set 1 for a mirrored "
            f"motor) so that a positive wheel command rolls the robot forward.",
        ),
    )


SCHEMA: tuple[ParamSpec, ...] = (
    # ---- MIX: Stick mixing
    ParamSpec(
        "MIX_ALGO", int, default=0, minimum=0, maximum=3, units="",
        values={0: "cartesian", 1: "polar_2011", 2: "max_speed_scaled", 3: "holonomic_2010"},
        description="Stick mixing algorithm that turns the (x forward, y right, r clockwise) "
        "drive command into four wheel commands.",
    ),
    ParamSpec(
        "MIX_DESAT", int, default=0, minimum=0, maximum=2, units="",
        values={0: "proportional", 1: "rotation_priority", 2: "translation_priority"},
        description="How wheel commands beyond [-1, 1] are brought back: proportional scales "
        "all four wheels together (WPILib), rotation_priority keeps the yaw command and "
        "shrinks translation along its direction (PX4), translation_priority keeps "
        "translation and shrinks rotation.",
    ),

    # ---- INP: Stick input shaping
    ParamSpec(
        "INP_DEADBAND", float, default=0.05, minimum=0.0, maximum=0.5, units="",
        description="Stick deadband as a fraction of full stick on each axis: inputs inside "
        "it read 0 and the rest is rescaled to reach 1 at full stick (WPILib applyDeadband).",
    ),
    ParamSpec(
        "INP_EXPO", float, default=0.0, minimum=0.0, maximum=1.0, units="",
        description="Cubic expo on each stick axis, out = (1 - e) * in + e * in^3 (PX4 "
        "style): 0 is linear, 1 fully cubic.",
    ),
    ParamSpec(
        "INP_CIRCLE", int, default=1, minimum=0, maximum=1, units="",
        values={0: "off", 1: "on"},
        description="Map the square stick range onto the unit circle by clamping the "
        "(x forward, y right) magnitude to 1, so a diagonal is not faster than a straight line.",
    ),

    # ---- GEO: Geometry (metres)
    ParamSpec(
        "GEO_HALF_LEN", float, default=0.15, minimum=0.02, maximum=5.0, units="m",
        reboot_required=True,
        description="Distance along body x (forward) from the robot centre to each wheel "
        "centre, half the wheelbase.",
    ),
    ParamSpec(
        "GEO_HALF_WID", float, default=0.15, minimum=0.02, maximum=5.0, units="m",
        reboot_required=True,
        description="Distance along body y (right) from the robot centre to each wheel "
        "centre, half the track width.",
    ),

    # ---- WHL: Wheel speed
    ParamSpec(
        "WHL_MAX_SPD", float, default=1.0, minimum=0.01, maximum=20.0, units="m/s",
        description="Wheel surface speed at full PWM (MOT_x_MIN or MOT_x_MAX), which maps a "
        "wheel command of 1 to m/s and back.",
    ),
    ParamSpec(
        "WHL_STRAFE_EFF", float, default=1.0, minimum=0.5, maximum=1.2, units="",
        reboot_required=True,
        description="Strafe efficiency: the fraction of the kinematic sideways speed the "
        "chassis achieves (its rollers slip). GUIDED and AUTO ask the wheels for the lateral "
        "speed divided by it and the wheel odometry counts the wheels' lateral part times it. "
        "Measure it: strafe a known distance (several metres, steady speed, WHL_STRAFE_EFF 1) "
        "and divide the true distance by the one the odometry reports.",
    ),

    # ---- MOT_DZ: Motor output, all wheels
    ParamSpec(
        "MOT_DZ", float, default=0.0, minimum=0.0, maximum=0.3, units="",
        description="ESC dead band compensation, a fraction of full command (0 = off): a "
        "wheel command c beyond a tiny threshold (0.002) is sent past the band in which the "
        "ESCs do not drive (as MOT_DZ_TYPE says), so the slowest commanded speeds turn the "
        "wheels; 0 and the smallest commands stay neutral (the wheels stop and brake). "
        "Set it to the largest command at which a wheel on the floor does not yet turn (or a "
        "little above). One value for all wheels: MOT_x_TRIM centres each ESC's band. "
        "MOT_DZ_TYPE says how the ESCs drive past the band.",
    ),
    ParamSpec(
        "MOT_DZ_TYPE", int, default=0, minimum=0, maximum=1, units="",
        values={0: "offset", 1: "jump"},
        description="How the ESCs drive past their dead band (MOT_DZ): offset = the wheel "
        "speed starts from zero at the band's edge (most ESCs with a motor's friction; "
        "ArduPilot's MOT_THR_MIN), a command c is sent as sign(c) * (MOT_DZ + (1 - MOT_DZ) * "
        "|c|); jump = past the edge the wheel turns at the command's own speed at once, c is "
        "sent as sign(c) * max(|c|, MOT_DZ). Tell them apart: a command a little past the "
        "band turns a wheel at (c - MOT_DZ) / (1 - MOT_DZ) * WHL_MAX_SPD (offset) or at c * "
        "WHL_MAX_SPD (jump).",
    ),

    # ---- MOT_x: Motor output, a group per wheel (FL, FR, RL, RR), entries from _wheel_specs above
    *(spec for i, w in enumerate(WHEELS) for spec in _wheel_specs(w, channel=i + 1)),

    # ---- SYSID: MAVLink identity
    ParamSpec(
        "SYSID_THISMAV", int, default=1, minimum=1, maximum=255, units="",
        reboot_required=True,
        description="MAVLink system id of the vehicle (this companion) on the ground-station "
        "link; component id is always 1.",
    ),
    ParamSpec(
        "SYSID_MYGCS", int, default=0, minimum=0, maximum=255, units="",
        description="Only the ground station with this system id may drive and command the "
        "rover (0 = any ground station).",
    ),

    # ---- FC: Flight-controller link
    ParamSpec(
        "FC_SYSID", int, default=1, minimum=1, maximum=255, units="",
        description="System id of the flight controller that RC_CHANNELS_OVERRIDE is "
        "addressed to.",
    ),
    ParamSpec(
        "FC_COMPID", int, default=1, minimum=0, maximum=255, units="",
        description="Component id of the flight controller that RC_CHANNELS_OVERRIDE is "
        "addressed to.",
    ),
    ParamSpec(
        "FC_GCS_SYSID", int, default=255, minimum=1, maximum=255, units="",
        description="System id the companion sends as on the flight-controller link; it must "
        "equal the flight controller's SYSID_MYGCS (MAV_GCS_SYSID), or ArduPilot silently "
        "drops the overrides.",
    ),

    # ---- OUT: Output to the flight controller
    ParamSpec(
        "OUT_RATE", float, default=20.0, minimum=2.0, maximum=200.0, units="Hz",
        description="Rate at which RC_CHANNELS_OVERRIDE is re-sent between input-driven "
        "updates, keeping the flight controller's override timeout from lapsing.",
    ),

    # ---- FS: Failsafes
    ParamSpec(
        "FS_INPUT_TMO", float, default=0.5, minimum=0.1, maximum=10.0, units="s",
        description="Stick input (MANUAL_CONTROL or ground-station RC override) older than "
        "this while driving by hand brings the wheels to neutral until new input arrives.",
    ),
    ParamSpec(
        "FS_GCS_TMO", float, default=3.0, minimum=0.5, maximum=60.0, units="s",
        description="No ground-station HEARTBEAT for this long triggers the ground-station "
        "failsafe action.",
    ),
    ParamSpec(
        "FS_GCS_ACTION", int, default=0, minimum=0, maximum=1, units="",
        values={0: "hold", 1: "disarm"},
        description="Ground-station failsafe action: switch to HOLD (neutral, stay armed) or "
        "disarm.",
    ),
    ParamSpec(
        "FS_FC_TMO", float, default=3.0, minimum=0.5, maximum=60.0, units="s",
        description="No flight-controller HEARTBEAT for this long reports the link lost, "
        "disarms and refuses to arm until it is back.",
    ),
    ParamSpec(
        "FS_THR_ENABLE", int, default=1, minimum=0, maximum=1, units="",
        values={0: "off", 1: "on"},
        description="Receiver failsafe (RCIN_ENABLE 1): no RC_CHANNELS for FS_INPUT_TMO, "
        "channel count 0, RSSI 0 or the throttle channel below FS_THR_VALUE takes the "
        "FS_RC_ACTION and refuses arming (ArduPilot's throttle failsafe); the wheels stop on "
        "such input either way.",
    ),
    ParamSpec(
        "FS_THR_VALUE", int, default=910, minimum=800, maximum=1100, units="us",
        description="Receiver failsafe: a throttle channel (RCMAP_THROTTLE) pulse below this "
        "is the receiver's failsafe (program the receiver to send it when the link is lost).",
    ),
    ParamSpec(
        "FS_RC_ACTION", int, default=0, minimum=0, maximum=1, units="",
        values={0: "hold", 1: "disarm"},
        description="Receiver failsafe action: switch to HOLD (neutral, stay armed) or "
        "disarm.",
    ),

    # ---- ARMING: Arming
    ParamSpec(
        "ARMING_CHECK", int, default=1, minimum=0, maximum=1, units="",
        values={0: "off", 1: "on"},
        description="Pre-arm checks before arming (sticks centred, the flight controller's "
        "setup safe), as ArduPilot's ARMING_CHECK; arming with param2 21196 skips them too "
        "(the flight-controller link is always required).",
    ),

    # ---- RCMAP: Stick channels (RC receiver and ground-station RC_CHANNELS_OVERRIDE)
    ParamSpec(
        "RCMAP_STEER", int, default=1, minimum=1, maximum=18, units="",
        description="RC channel read as the rotation (steering) stick, clockwise for pulses "
        "above trim, from the receiver or a ground station's override (ArduPilot Rover: "
        "RCMAP_ROLL, channel 1).",
    ),
    ParamSpec(
        "RCMAP_THROTTLE", int, default=3, minimum=1, maximum=18, units="",
        description="RC channel read as the forward (throttle) stick, forward for pulses "
        "above trim, from the receiver or a ground station's override (ArduPilot Rover: "
        "RCMAP_THROTTLE, channel 3).",
    ),
    ParamSpec(
        "RCMAP_LATERAL", int, default=4, minimum=1, maximum=18, units="",
        description="RC channel read as the lateral stick, right for pulses above trim, from "
        "the receiver or a ground station's override (ArduPilot Rover: RCMAP_YAW, channel 4).",
    ),

    # ---- RCIN: RC stick input: the receiver through the flight controller, pulse range
    ParamSpec(
        "RCIN_MIN", int, default=1000, minimum=800, maximum=2200, units="us",
        description="Stick pulse width for full negative deflection (receiver and "
        "ground-station overrides).",
    ),
    ParamSpec(
        "RCIN_TRIM", int, default=1500, minimum=800, maximum=2200, units="us",
        description="Stick pulse width at centre (receiver and ground-station overrides).",
    ),
    ParamSpec(
        "RCIN_MAX", int, default=2000, minimum=800, maximum=2200, units="us",
        description="Stick pulse width for full positive deflection (receiver and "
        "ground-station overrides).",
    ),
    ParamSpec(
        "RCIN_ENABLE", int, default=0, minimum=0, maximum=1, units="",
        values={0: "off", 1: "on"},
        description="Read the RC receiver on the flight controller (RC_CHANNELS, asked for "
        "at 25 Hz): its sticks drive unless a ground station's sticks are fresh, its mode and "
        "arm switches act; the wheels need channels the receiver does not use (MOT_x_CH).",
    ),
    ParamSpec(
        "RCIN_ARM_CH", int, default=0, minimum=0, maximum=16, units="",
        description="Receiver channel of an arm/disarm switch, 0 = none: high (above 1800 "
        "us) arms, low (below 1200 us) disarms, on a change held 0.2 s (ArduPilot "
        "RCn_OPTION 153).",
    ),

    # ---- MODE: Mode switch (RC receiver)
    ParamSpec(
        "MODE_CH", int, default=8, minimum=0, maximum=16, units="",
        description="Receiver channel of the six-position mode switch, 0 = none; a new "
        "position held 0.2 s selects MODE1..MODE6 (ArduPilot Rover MODE_CH).",
    ),
    *(ParamSpec(
        f"MODE{i}", int, default=0, minimum=0, maximum=15, units="",
        description=f"Mode of switch position {i} ({band} us): 0 MANUAL, 4 HOLD, 10 AUTO or "
        f"15 GUIDED (ArduPilot Rover MODE{i}).",
    ) for i, band in enumerate(("up to 1230", "1231-1360", "1361-1490", "1491-1620",
                                "1621-1749", "1750 and above"), start=1)),

    # ---- MAN: Manual driving
    ParamSpec(
        "MAN_Z_SCALE", int, default=0, minimum=0, maximum=1, units="",
        values={0: "off", 1: "on"},
        description="Use MANUAL_CONTROL z (0..1000) as a speed scale on the translation and "
        "rotation sticks; off ignores z.",
    ),

    # ---- CTL: Control loop
    ParamSpec(
        "CTL_RATE", float, default=50.0, minimum=10.0, maximum=200.0, units="Hz",
        description="Rate of the GUIDED control loop (position, velocity and heading "
        "controllers and the wheel output).",
    ),

    # ---- GUID: GUIDED driving
    ParamSpec(
        "GUID_SPD_MAX", float, default=0.7, minimum=0.05, maximum=10.0, units="m/s",
        description="GUIDED: largest translation speed, whatever the setpoint asks.",
    ),
    ParamSpec(
        "GUID_ACC_MAX", float, default=1.0, minimum=0.05, maximum=10.0, units="m/s/s",
        description="GUIDED: largest change of the commanded velocity per second; also sets "
        "the braking distance before a position target.",
    ),
    ParamSpec(
        "GUID_YAW_RATE", float, default=90.0, minimum=1.0, maximum=720.0, units="deg/s",
        description="GUIDED: largest yaw rate, whatever the setpoint asks.",
    ),
    ParamSpec(
        "GUID_POS_P", float, default=1.5, minimum=0.1, maximum=10.0, units="1/s",
        description="GUIDED: position gain, commanded speed per metre of position error.",
    ),
    ParamSpec(
        "GUID_YAW_P", float, default=2.5, minimum=0.1, maximum=20.0, units="1/s",
        description="GUIDED: heading gain, commanded yaw rate per radian of heading error.",
    ),
    ParamSpec(
        "GUID_YAW_LEAD", float, default=0.09, minimum=0.0, maximum=1.0, units="s",
        description="GUIDED and AUTO: the body-frame velocity is computed for the heading the "
        "rover will have this long from now (the motors' lag and half a control period: the "
        "pose is already carried forward to now), so turning does not bend the path.",
    ),
    ParamSpec(
        "GUID_TIMEOUT", float, default=3.0, minimum=0.1, maximum=60.0, units="s",
        description="GUIDED: velocity and yaw-rate setpoints older than this lapse and the "
        "rover stops (position and yaw targets persist).",
    ),

    # ---- WP: AUTO missions
    ParamSpec(
        "WP_SPEED", float, default=0.5, minimum=0.05, maximum=10.0, units="m/s",
        description="AUTO: speed along the mission's legs until a DO_CHANGE_SPEED (limited "
        "to GUID_SPD_MAX).",
    ),
    ParamSpec(
        "WP_ACCEL", float, default=0.5, minimum=0.05, maximum=10.0, units="m/s/s",
        description="AUTO: acceleration and braking along a leg (at most GUID_ACC_MAX is "
        "used).",
    ),
    ParamSpec(
        "WP_RADIUS", float, default=0.03, minimum=0.01, maximum=100.0, units="m",
        description="AUTO: a waypoint is reached within this distance unless its item gives "
        "an acceptance radius.",
    ),
    ParamSpec(
        "WP_POS_P", float, default=3.0, minimum=0.1, maximum=10.0, units="1/s",
        description="AUTO: gain of the pull back onto the leg and of the final approach to a "
        "stop waypoint (critically damped with 0.08 s of motor lag; GUIDED uses GUID_POS_P).",
    ),
    ParamSpec(
        "WP_OVERSHOOT", float, default=0.02, minimum=0.0, maximum=10.0, units="m",
        description="AUTO: how far the rover may swing past the next leg's line when it "
        "passes a waypoint without stopping; sets the speed through shallow corners.",
    ),
    ParamSpec(
        "WP_YAW_BEHAVIOR", int, default=0, minimum=0, maximum=1, units="",
        values={0: "hold heading", 1: "face along each leg"},
        description="AUTO: heading between CONDITION_YAW or waypoint yaw commands; a mecanum "
        "rover follows the same path either way.",
    ),

    # ---- ORIGIN: Global origin of the local frame
    ParamSpec(
        "ORIGIN_LAT", float, default=0.0, minimum=-90.0, maximum=90.0, units="deg",
        description="Latitude of the local origin for missions in global frames (0 with "
        "ORIGIN_LON 0 = none; SET_GPS_GLOBAL_ORIGIN overrides it).",
    ),
    ParamSpec(
        "ORIGIN_LON", float, default=0.0, minimum=-180.0, maximum=180.0, units="deg",
        description="Longitude of the local origin (float32 carries it to about 1 m; send "
        "SET_GPS_GLOBAL_ORIGIN for 1 cm).",
    ),

    # ---- ODOM: Odometry
    ParamSpec(
        "ODOM_SRC", int, default=0, minimum=0, maximum=2, units="",
        values={0: "auto", 1: "wheel_distance", 2: "commanded"},
        description="Odometry source: auto uses the flight controller's WHEEL_DISTANCE while "
        "it keeps coming and the commanded wheel speeds otherwise; or only one of them.",
    ),
    ParamSpec(
        "ODOM_CMD_TAU", float, default=0.0, minimum=0.0, maximum=2.0, units="s",
        description="Lag of the commanded wheel speeds in the odometry (when it uses them: "
        "ODOM_SRC commanded, or auto without WHEEL_DISTANCE): each passes a first-order lag "
        "of this time constant before it counts as rolled, as the flight controller, ESCs and "
        "motors delay it (0 = none). Set it to the time the wheels take to reach 63 % of a "
        "step in command.",
    ),
    ParamSpec(
        "ODOM_CMD_GAIN", float, default=1.0, minimum=0.8, maximum=1.2, units="",
        description="Commanded-speed odometry: the fraction of its commanded speed a wheel "
        "really rolls (motors under load run below it; 1 = exactly). Measure the distance "
        "truly driven over the odometry's on a long straight run at mission speed.",
    ),
    ParamSpec(
        "ODOM_YAW_SRC", int, default=0, minimum=0, maximum=1, units="",
        values={0: "auto", 1: "wheels"},
        description="Odometry heading: auto uses the flight controller's ATTITUDE yaw while "
        "fresh (a gyro beats wheel-derived yaw on a slipping mecanum base), wheels uses the "
        "wheels' own turn.",
    ),
    ParamSpec(
        "ODOM_YAW_BIAS", int, default=2, minimum=0, maximum=2, units="",
        values={0: "off", 1: "ekf", 2: "gps"},
        description="Flight controller heading bias: compares its position track (gps: its "
        "GPS_RAW_INT fixes; ekf: its LOCAL_POSITION_NED) with the odometry's over straight, "
        "steady stretches of at least 0.5 m and takes the offset (up to 10 deg) off the "
        "ATTITUDE yaw the odometry and the heading controller use; nothing without a fix.",
    ),
    ParamSpec(
        "ODOM_POS_TAU", float, default=0.0, minimum=0.0, maximum=60.0, units="s",
        description="Position fusion: time constant with which the odometry's position is "
        "pulled toward the flight controller's LOCAL_POSITION_NED (its GPS-fused track, moved "
        "to the odometry's origin); the wheels count within it, the flight controller beyond "
        "it (0 = off: wheels only).",
    ),

    # ---- TLM: Telemetry to the ground station
    ParamSpec(
        "TLM_POS_RATE", float, default=10.0, minimum=0.0, maximum=50.0, units="Hz",
        description="Rate of ODOMETRY, LOCAL_POSITION_NED, ATTITUDE and, once a global origin "
        "is known, GLOBAL_POSITION_INT to the ground station (0 = off).",
    ),
    ParamSpec(
        "TLM_EXT_RATE", float, default=2.0, minimum=0.0, maximum=50.0, units="Hz",
        description="Rate of SYS_STATUS, SERVO_OUTPUT_RAW and WHEEL_DISTANCE to the ground "
        "station (0 = off).",
    ),

    # ---- SIM: Built-in simulator (flight controller and chassis)
    ParamSpec(
        "SIM_MOTOR_TAU", float, default=0.08, minimum=0.001, maximum=5.0, units="s",
        reboot_required=True,
        description="Simulator: first-order time constant of each motor's speed response.",
    ),
    ParamSpec(
        "SIM_SLIP", float, default=0.0, minimum=0.0, maximum=0.5, units="",
        reboot_required=True,
        description="Simulator: standard deviation of each wheel's traction error as a "
        "fraction of its speed (0 = no slip).",
    ),
    ParamSpec(
        "SIM_RC_TMO", float, default=0.5, minimum=0.1, maximum=60.0, units="s",
        reboot_required=True,
        description="Simulator: override timeout after which an un-refreshed RC override "
        "lapses to neutral (ArduPilot RC_OVERRIDE_TIME, as setup-fc --apply sets it; over "
        "1 s the companion's check calls the board unsafe).",
    ),
    ParamSpec(
        "SIM_GCS_SYSID", int, default=255, minimum=1, maximum=255, units="",
        reboot_required=True,
        description="Simulator: the only sender system id whose RC overrides it obeys "
        "(ArduPilot SYSID_MYGCS).",
    ),
    ParamSpec(
        "SIM_RATE", float, default=100.0, minimum=10.0, maximum=1000.0, units="Hz",
        reboot_required=True,
        description="Simulator: physics update rate.",
    ),
    ParamSpec(
        "SIM_SEED", int, default=0, minimum=0, maximum=1000000, units="",
        reboot_required=True,
        description="Simulator: random seed of the slip noise, for repeatable runs.",
    ),
    ParamSpec(
        "SIM_FRICTION", float, default=0.8, minimum=0.05, maximum=2.0, units="",
        reboot_required=True,
        description="Simulator, MuJoCo chassis (sim --physics mujoco): Coulomb friction "
        "coefficient between the rollers and the floor (0.8 a grippy floor, 0.4 a slippery "
        "one).",
    ),
    ParamSpec(
        "SIM_MASS", float, default=4.0, minimum=0.2, maximum=200.0, units="kg",
        reboot_required=True,
        description="Simulator, MuJoCo chassis: mass of the whole robot, wheels included.",
    ),
    ParamSpec(
        "SIM_WHL_RAD", float, default=0.04, minimum=0.01, maximum=0.5, units="m",
        reboot_required=True,
        description="Simulator, MuJoCo chassis: wheel radius to the rollers' outer surface "
        "(the companion itself needs none: WHL_MAX_SPD is a surface speed).",
    ),
    ParamSpec(
        "SIM_MOT_TORQUE", float, default=0.6, minimum=0.01, maximum=100.0, units="N.m",
        reboot_required=True,
        description="Simulator, MuJoCo chassis: the most torque each wheel's motor gives "
        "(its ESC's current limit).",
    ),
    ParamSpec(
        "SIM_ESC_DZ", float, default=0.02, minimum=0.0, maximum=0.3, units="",
        reboot_required=True,
        description="Simulator, MuJoCo chassis: each ESC's dead band around neutral, as a "
        "fraction of full command; a smaller command leaves the motor unpowered, its windings "
        "shorted (the usual brake neutral: the wheel is braked to a stop, within "
        "SIM_MOT_TORQUE).",
    ),
    ParamSpec(
        "SIM_YAW_BIAS", float, default=0.0, minimum=-30.0, maximum=30.0, units="deg",
        reboot_required=True,
        description="Simulator: added to the yaw the board reports in ATTITUDE (clockwise), "
        "as a compass or an EKF heading a few degrees off (0 = the true yaw).",
    ),
    ParamSpec(
        "SIM_POS_RATE", float, default=0.0, minimum=0.0, maximum=50.0, units="Hz",
        reboot_required=True,
        description="Simulator: rate of the board's own LOCAL_POSITION_NED (the true "
        "position, as a GPS-fused EKF's; 0 = none, a board without GPS).",
    ),
)
"""Every parameter, in file, table and MAVLink index order."""
# fmt: on


RETIRED: dict[str, str] = {
    "GEO_WHEEL_RAD": "wheel speeds are WHL_MAX_SPD in m/s and odometry reads WHEEL_DISTANCE in "
    "metres, so no wheel radius is needed",
}
"""Parameters earlier versions had and nothing reads any more: name -> why. A parameter file
that still sets one loads, with a warning naming the line (:mod:`mecanum_mav.io.paramfile`)."""


def _index(schema: Sequence[ParamSpec]) -> dict[str, ParamSpec]:
    """Map names to specs, raising on a duplicate name or a group without a title."""
    specs: dict[str, ParamSpec] = {}
    for spec in schema:
        if spec.name in specs:
            raise ValueError(f"parameter schema: {spec.name} is listed twice")
        if spec.group not in GROUP_TITLES:
            raise ValueError(f"parameter schema: {spec.name}: group {spec.group} has no title")
        specs[spec.name] = spec
    return specs


SPECS: dict[str, ParamSpec] = _index(SCHEMA)
"""Name -> spec, in schema order."""
