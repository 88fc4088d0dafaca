"""The simulated board sends its chassis's wheel contacts (DEBUG_VECT ``CONTACT_FL`` ..
``CONTACT_RR``, 10 Hz) with the MuJoCo chassis, and nothing of the kind with the kinematic
one."""

from __future__ import annotations

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.protocol.outbox import MessageOutbox
from mecanum_mav.sim.board import CONTACT_NAMES, SimBoard

pytest.importorskip("mujoco")


def debug_vects(physics: str, seconds: float = 1.0) -> list:
    board = SimBoard(Params(), physics=physics)
    outbox = MessageOutbox()
    sent = []
    for tick in range(1, round(seconds / 0.01) + 1):
        board.on_time(tick * 0.01, outbox)
        sent += [m for m in outbox.take() if m.get_type() == "DEBUG_VECT"]
    return sent


def test_the_board_on_the_mujoco_chassis_sends_each_wheels_contact_at_10_hz():
    # Kills: the board not adding the contacts to its telemetry; the force or the slip flag
    # swapped between fields.
    sent = debug_vects("mujoco")
    names = [m.name for m in sent]
    assert set(names) == set(CONTACT_NAMES) == {"CONTACT_FL", "CONTACT_FR", "CONTACT_RL",
                                                "CONTACT_RR"}
    assert all(9 <= names.count(n) <= 11 for n in CONTACT_NAMES)
    weight = Params()["SIM_MASS"] * 9.81
    last = sent[-4:]
    assert [m.name for m in last] == list(CONTACT_NAMES)
    for m in last:  # at rest: a quarter of the weight each, no slip
        assert m.x == pytest.approx(weight / 4, rel=0.05)
        assert m.y < 0.05 and m.z == 0.0


def test_the_board_on_the_kinematic_chassis_sends_no_contacts():
    # Kills: contacts sent (zeros) for a chassis that has none.
    assert debug_vects("kinematic") == []
