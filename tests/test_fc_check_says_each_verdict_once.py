"""The companion's check of the flight controller's setup says each verdict once per change
(mecanum_mav.control.fccheck's module docstring): a board that never answers a setting is
"not confirmed", read again at each arm attempt, and the same verdict is not said again; the
verdict that differs is. The companion and the simulated board in the lockstep harness."""

from __future__ import annotations

from mecanum_mav.config.params import Params
from mecanum_mav.control.fccheck import FcCheckState, FcSetupCheck
from mecanum_mav.io.links import mavlink
from mecanum_mav.sim.lockstep import Lockstep

UNCONFIRMED = "FC setup not confirmed: no answer for RC4_DZ; asked again when arming"
SAFE = "FC setup checked: safe for the companion"


def decided(h: Lockstep) -> bool:
    return h.core.fc_check.state not in (FcCheckState.IDLE, FcCheckState.READING)


def test_a_verdict_that_does_not_change_is_not_said_again_after_a_new_read():
    h = Lockstep(Params())
    missing = h.board.parameters.pop("RC4_DZ")  # a setting this board does not answer
    assert h.run_until(lambda: decided(h), 15.0)
    assert h.gcs.texts().count(UNCONFIRMED) == 1
    for _ in range(2):  # each arm attempt reads the board again, to the same verdict
        ack = h.gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        assert ack is not None and ack.result != mavlink.MAV_RESULT_ACCEPTED
        assert h.core.fc_check.state is FcCheckState.READING
        assert h.run_until(lambda: decided(h), 15.0)
        assert h.core.fc_check.state is FcCheckState.UNCONFIRMED
    h.gcs.mark()
    assert h.gcs.texts().count(UNCONFIRMED) == 1
    h.board.parameters["RC4_DZ"] = missing  # answered now: a new verdict, said
    h.gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert h.run_until(lambda: decided(h), 15.0)
    h.gcs.mark()
    assert h.core.fc_check.state is FcCheckState.SAFE and h.gcs.texts().count(SAFE) == 1


def test_a_check_that_reads_nothing_has_nothing_due_and_its_tick_does_nothing():
    """Before the board is read (or after a read decided) nothing is due: ``next_due_s`` is
    infinite and a tick asks for nothing and says nothing."""
    check = FcSetupCheck()
    assert check.next_due_s == float("inf")
    assert check.tick(Params(), 5.0) == ((), None)
    assert check.state is FcCheckState.IDLE
