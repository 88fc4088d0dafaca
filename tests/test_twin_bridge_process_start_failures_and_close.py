"""The twin's bridge (mecanum_mav/sim/twinbridge.py) when it does not come up, and closed
twice: a bridge process without the physics says so (``no-physics``) and the caller raises the
install hint; one that does not say its port in time is given up; either way its folder goes.
Closing a bridge (the process or the thread) is idempotent."""

from __future__ import annotations

import socket
import tempfile
from pathlib import Path

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.sim.physics import PhysicsUnavailableError
from mecanum_mav.sim.sitljson import encode_servo_packet
from mecanum_mav.sim.twinbridge import BridgeCore, BridgeProcess, TwinBridge, WheelMap

pytest.importorskip("mujoco", reason="the MuJoCo chassis needs the physics extra")

from mecanum_mav.sim.mujocochassis import MujocoChassis


@pytest.fixture
def bridge_folders(monkeypatch: pytest.MonkeyPatch) -> list[Path]:
    """The folders the bridges of the test make (their record and setup files)."""
    made: list[Path] = []
    mkdtemp = tempfile.mkdtemp

    def spy(*args: object, **kwargs: object) -> str:
        folder = mkdtemp(*args, **kwargs)  # type: ignore[call-overload]
        made.append(Path(folder))
        return str(folder)

    monkeypatch.setattr(tempfile, "mkdtemp", spy)
    return made


def test_a_bridge_process_without_the_physics_raises_the_install_hint_and_leaves_no_folder(
        tmp_path, monkeypatch, bridge_folders):
    # the bridge's own process finds a mujoco that cannot be imported (this one has it)
    (tmp_path / "mujoco").mkdir()
    (tmp_path / "mujoco" / "__init__.py").write_text(
        "raise ImportError('no mujoco in this process')\n")
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    with pytest.raises(PhysicsUnavailableError, match=r"no mujoco in this process.*"
                                                      r"pip install 'mecanum-mav\[physics\]'"):
        BridgeProcess(Params().as_dict())
    assert len(bridge_folders) == 1 and not bridge_folders[0].exists()


def test_a_bridge_process_that_does_not_say_its_port_in_time_is_given_up_and_leaves_no_folder(
        bridge_folders):
    with pytest.raises(RuntimeError, match=r"the bridge process did not start within 0\.01 s "
                                           r"\(no answer; exit code None\)"):
        BridgeProcess(Params().as_dict(), start_timeout_s=0.01)
    assert len(bridge_folders) == 1 and not bridge_folders[0].exists()


def test_closing_a_bridge_process_twice_is_harmless():
    bridge = BridgeProcess(Params().as_dict())
    bridge.close()
    bridge.close()
    assert not bridge.alive()


def test_closing_a_bridge_thread_twice_is_harmless_and_it_answers_no_more():
    params = Params()
    wheels = WheelMap(PwmMap.from_params(params), [(1, 1.0), (2, 1.0), (3, 1.0), (4, 1.0)],
                      params["SIM_ESC_DZ"])
    bridge = TwinBridge(BridgeCore(MujocoChassis.from_params(params), wheels))
    bridge.close()
    bridge.close()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as firmware:
        firmware.bind(("127.0.0.1", 0))
        firmware.settimeout(0.2)
        firmware.sendto(encode_servo_packet(1200, 1, [1500] * 4), ("127.0.0.1", bridge.port))
        with pytest.raises(OSError):  # (no answer: a timeout, or the port refused)
            firmware.recv(4096)
