"""The board's chassis is chosen by name (``sim --physics``): the kinematic one by default."""

from __future__ import annotations

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.sim.board import SimBoard
from mecanum_mav.sim.chassis import SimChassis
from mecanum_mav.sim.physics import PHYSICS, make_chassis


def test_the_board_drives_the_kinematic_chassis_unless_told_otherwise():
    assert isinstance(SimBoard(Params()).chassis, SimChassis)


def test_a_chassis_starts_where_it_is_told():
    pose = Pose2d(1.0, -2.0, 0.5)
    assert make_chassis(Params(), pose, "kinematic").pose == pose


def test_an_unknown_physics_is_refused_naming_the_choices():
    with pytest.raises(ValueError, match="kinematic, mujoco"):
        make_chassis(Params(), physics="bullet")
    assert PHYSICS == ("kinematic", "mujoco")
