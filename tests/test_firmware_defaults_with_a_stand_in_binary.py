"""How :class:`~mecanum_mav.sim.firmware.Firmware` starts ``ardurover`` (its defaults files:
``rover.parm`` beside the binary if there, the extra ones, then the given parameters in a file
of its own directory; none at all without any) and ends it (its directory removed, on every
way out, also when it had already ended). The binary is a stand-in script that prints its
arguments: what the real firmware does with them is test_sitl.py's."""

from __future__ import annotations

from pathlib import Path

import pytest
from support import wait_until

from mecanum_mav.sim.firmware import Firmware

STAND_IN = """#!/bin/sh
echo "$@"
"""


def stand_in(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    binary = folder / "ardurover"
    binary.write_text(STAND_IN)
    binary.chmod(0o755)
    return binary


def arguments(firmware: Firmware) -> list[str]:
    """What the stand-in was started with (once it has printed them)."""
    assert wait_until(lambda: firmware.log().endswith("\n"), 10.0), "the stand-in said nothing"
    return firmware.log().split()


def test_the_defaults_are_rover_parm_then_the_extra_files_then_the_given_parameters(
        tmp_path: Path):
    binary = stand_in(tmp_path / "bin")
    rover_parm = binary.with_name("rover.parm")
    rover_parm.write_text("CRUISE_SPEED 2\n")
    extra = tmp_path / "passthrough.parm"
    extra.write_text("SERIAL1_PROTOCOL 2\n")
    with Firmware(binary, 9003, params={"CRUISE_SPEED": 1.5, "FRAME_CLASS": 2},
                  extra_defaults=[extra]) as firmware:
        argv = arguments(firmware)
        assert firmware.workdir is not None
        own = firmware.workdir / "twin.parm"
        assert argv[argv.index("--defaults") + 1] == f"{rover_parm},{extra},{own}"
        assert own.read_text() == "CRUISE_SPEED 1.5\nFRAME_CLASS 2\n"  # these win: last


def test_without_rover_parm_or_parameters_the_firmware_gets_no_defaults_file(tmp_path: Path):
    with Firmware(stand_in(tmp_path / "bin"), 9003) as firmware:
        argv = arguments(firmware)
        assert "--defaults" not in argv
        assert firmware.workdir is not None
        assert not (firmware.workdir / "twin.parm").exists()
        assert argv[argv.index("--sim-port-out") + 1] == "9003"


def test_a_firmware_has_no_log_before_it_starts_and_closing_one_that_ended_removes_its_folder(
        tmp_path: Path):
    firmware = Firmware(stand_in(tmp_path / "bin"), 9003)
    assert firmware.log() == ""
    with pytest.raises(RuntimeError, match="has not started"):
        _ = firmware.log_path
    firmware.start()
    workdir = firmware.workdir
    assert workdir is not None and workdir.is_dir()
    try:
        assert wait_until(lambda: not firmware.alive(), 10.0)  # (the stand-in just exits)
    finally:
        firmware.close()
    assert not workdir.exists()
    assert firmware.proc is not None and firmware.proc.returncode == 0  # ended by itself
    firmware.close()  # idempotent
    assert firmware.workdir is None
