"""RC_CHANNELS_OVERRIDE channel rules: the classifier every reader uses, and the writers."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mecanum_mav.protocol.rcoverride import (
    CHANNELS,
    LEAVE,
    RELEASE,
    field_action,
    override_fields,
    release_fields,
)

# The rules as MAVLink common / ArduPilot state them (CONVENTIONS.md), written out here as
# the test's own oracle: (channel, raw) -> action.
SPEC = [
    *((ch, 65535, LEAVE) for ch in (1, 4, 8)),
    *((ch, 0, RELEASE) for ch in (1, 4, 8)),
    *((ch, 65534, 65534) for ch in (1, 8)),  # on 1-8, 65534 is just a (silly) pulse
    *((ch, 65535, LEAVE) for ch in (9, 12, 18)),
    *((ch, 0, LEAVE) for ch in (9, 12, 18)),
    *((ch, 65534, RELEASE) for ch in (9, 12, 18)),
    *((ch, pulse, pulse) for ch in (1, 8, 9, 18) for pulse in (1, 800, 1500, 2200, 65533)),
]


@pytest.mark.parametrize(("channel", "raw", "action"), SPEC)
def test_field_action_follows_the_spec(channel, raw, action):
    assert field_action(channel, raw) == action


def test_actions_are_not_pulses():
    assert LEAVE < 0 and RELEASE < 0 and LEAVE != RELEASE


@given(st.integers(1, CHANNELS), st.integers(0, 65535))
def test_a_pulse_answer_is_the_raw_value_and_never_0(channel, raw):
    action = field_action(channel, raw)
    assert action in (LEAVE, RELEASE) or (action == raw and action > 0)


def test_untouched_fields_read_back_as_leave_on_every_channel():
    fields = override_fields([], [])
    assert len(fields) == CHANNELS == 18
    assert fields == [65535] * 8 + [0] * 10
    assert [field_action(ch, raw) for ch, raw in enumerate(fields, 1)] == [LEAVE] * 18


@given(st.lists(st.integers(1, CHANNELS), min_size=4, max_size=4, unique=True),
       st.lists(st.integers(800, 2200), min_size=4, max_size=4))
def test_what_the_companion_writes_reads_back_as_meant(channels, pulses):
    actions = [field_action(ch, raw) for ch, raw in enumerate(override_fields(channels, pulses), 1)]
    expected = dict(zip(channels, pulses, strict=True))
    assert actions == [expected.get(ch, LEAVE) for ch in range(1, CHANNELS + 1)]
    released = [field_action(ch, raw) for ch, raw in enumerate(release_fields(channels), 1)]
    assert released == [RELEASE if ch in channels else LEAVE for ch in range(1, CHANNELS + 1)]


def test_release_fields_use_0_low_and_65534_high():
    fields = release_fields([2, 11])
    assert fields[1] == 0 and fields[10] == 65534
