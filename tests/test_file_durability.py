"""What the rover keeps on disk survives a power cut, and one serial device is one claim
whatever its name.

- An atomic save (``io/atomicfile.write_atomic``: the parameter file, its ``.bak`` and the
  mission beside it, ``io/storage.FileStorage``) writes a temporary file, syncs it, renames
  it over the target and then syncs the directory, "so the rename survives a power cut"
  (its docstring): a rename is a change to the directory, which an ``fsync`` of the file
  does not make durable. The tests watch ``os.open``, ``os.fsync`` and ``os.replace`` and
  check the order: data synced, renamed, then the target's directory opened and synced.
- A ground station on a serial device is claimed per device (``io/claims.
  ground_station_claim``: one rover per system id and ground-station destination): the same
  device reached through a ``/dev/serial/by-id`` symlink, or named with another baud rate,
  is the same destination (docs/hardware.md recommends the by-id names).
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from support import RawPty

from mecanum_mav.config.params import Params
from mecanum_mav.io import atomicfile
from mecanum_mav.io.atomicfile import remove_stale_temporaries, write_atomic
from mecanum_mav.io.claims import InUseError, claim_ground_station, ground_station_claim
from mecanum_mav.io.storage import FileStorage
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import MissionItem


class DiskCalls:
    """The calls that decide durability, in order: ``("sync", path)`` for an ``os.fsync``
    (the path its descriptor was opened with; ``dir:`` before it when opened as a
    directory), ``("rename", source, target)`` for an ``os.replace``."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.calls: list[tuple[str, ...]] = []
        self._paths: dict[int, str] = {}
        real_open: Callable[..., int] = os.open
        real_fsync: Callable[[int], None] = os.fsync
        real_replace: Callable[..., None] = os.replace

        def open_(path: Any, flags: int, *args: Any, **kwargs: Any) -> int:
            fd = real_open(path, flags, *args, **kwargs)
            directory = bool(flags & getattr(os, "O_DIRECTORY", 0))
            self._paths[fd] = ("dir:" if directory else "") + os.fspath(path)
            return fd

        def fsync(fd: Any) -> None:
            real_fsync(fd)
            number = fd if isinstance(fd, int) else fd.fileno()
            self.calls.append(("sync", self._paths.get(number, f"fd {number}")))

        def replace(source: Any, target: Any, *args: Any, **kwargs: Any) -> None:
            real_replace(source, target, *args, **kwargs)
            self.calls.append(("rename", os.fspath(source), os.fspath(target)))

        monkeypatch.setattr(os, "open", open_)
        monkeypatch.setattr(os, "fsync", fsync)
        monkeypatch.setattr(os, "replace", replace)

    def renames(self) -> list[tuple[str, ...]]:
        return [c for c in self.calls if c[0] == "rename"]

    def assert_durable(self, target: Path) -> None:
        """``target`` was renamed into place from a synced temporary file beside it, and its
        directory was synced after that rename."""
        renames = [k for k, c in enumerate(self.calls)
                   if c[0] == "rename" and c[2] == str(target)]
        assert len(renames) == 1, self.calls
        k = renames[0]
        source = self.calls[k][1]
        assert Path(source).parent == target.parent, self.calls  # (a rename within a folder)
        assert ("sync", source) in self.calls[:k], (
            f"data not synced before the rename: {self.calls}")
        assert ("sync", f"dir:{target.parent}") in self.calls[k + 1:], (
            f"directory not synced after the rename: {self.calls}")


def test_an_atomic_write_syncs_the_data_renames_then_syncs_the_directory(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "rover.parm"
    target.write_text("OLD 1\n")
    disk = DiskCalls(monkeypatch)
    write_atomic(target, b"NEW 2\n")
    assert target.read_bytes() == b"NEW 2\n"
    disk.assert_durable(target)


def test_a_new_file_written_atomically_has_its_directory_synced_after_the_rename(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "rover"
    folder.mkdir()
    disk = DiskCalls(monkeypatch)
    write_atomic(folder / "rover.waypoints", b"QGC WPL 110\n")
    disk.assert_durable(folder / "rover.waypoints")


def test_saved_parameters_their_backup_and_the_mission_are_each_durable(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    param_path = tmp_path / "rover.parm"
    param_path.write_text("WP_SPEED 0.5\n")
    storage = FileStorage(param_path)
    params = Params()
    params.update({"WP_SPEED": 0.7})
    disk = DiskCalls(monkeypatch)
    storage.save_params(params)
    storage.save_mission([MissionItem(0, mavlink.MAV_FRAME_LOCAL_NED,
                                      mavlink.MAV_CMD_NAV_WAYPOINT, x=10000, y=20000)])
    assert {c[2] for c in disk.renames()} == {
        str(param_path), str(param_path) + ".bak", str(storage.mission_path)}
    for target in (param_path, Path(str(param_path) + ".bak"), storage.mission_path):
        disk.assert_durable(target)


# --------------------------------------------------------------------------- claims


@pytest.fixture
def runtime(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))


def lock_name(gcs_url: str) -> str:
    """The lock file system 1 on ``gcs_url`` is claimed by."""
    claim = ground_station_claim(1, gcs_url)
    assert claim is not None
    return claim[0]


def test_one_serial_device_by_its_by_id_symlink_and_its_node_is_one_claim(
        tmp_path: Path, runtime: None) -> None:
    by_id = tmp_path / "usb-Radio_Telemetry_0001-if00"
    radio = RawPty(by_id)  # by_id -> /dev/pts/N, as udev's /dev/serial/by-id names are
    other = RawPty()
    try:
        assert lock_name(f"{by_id},57600") == lock_name(f"{radio.device},57600")
        with claim_ground_station(1, f"{by_id},57600"):
            with pytest.raises(InUseError, match="is in use by another running rover"), \
                    claim_ground_station(1, f"{radio.device},57600"):
                pass
            with claim_ground_station(1, f"{other.device},57600"):  # another device
                pass
            with claim_ground_station(2, radio.device):  # another system id
                pass
    finally:
        radio.close()
        other.close()


def test_one_serial_device_at_another_baud_rate_is_the_same_claim(
        tmp_path: Path, runtime: None) -> None:
    radio = RawPty()
    try:
        assert lock_name(f"{radio.device},57600") == lock_name(f"{radio.device},115200") == (
            lock_name(radio.device))
        with claim_ground_station(1, f"{radio.device},57600"), \
                pytest.raises(InUseError), claim_ground_station(1, f"{radio.device},115200"):
            pass
    finally:
        radio.close()


def test_a_write_goes_to_a_hidden_temporary_file_beside_the_target_that_a_restart_removes(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """atomicfile's docstring: the temporary file is ``.NAME.XXXXXXXX.tmp`` beside the target
    (so a write cut short leaves it where :func:`remove_stale_temporaries` looks); only a
    target's own temporaries are removed, and each one removed is named."""
    target = tmp_path / "rover.parm"
    target.write_bytes(b"old")
    seen: list[str] = []
    real_fsync = os.fsync

    def looking(fd: int) -> None:  # (while the data is synced: the temporary file exists)
        seen.extend(p.name for p in tmp_path.iterdir() if p != target)
        real_fsync(fd)

    monkeypatch.setattr(atomicfile.os, "fsync", looking)
    write_atomic(target, b"new")
    [temporary, *_] = seen
    assert re.fullmatch(r"\.rover\.parm\.[A-Za-z0-9_]{8}\.tmp", temporary), seen
    left = tmp_path / temporary
    left.write_bytes(b"half")  # (what a kill -9 in the write would leave)
    other = tmp_path / ".rover.waypoints.abcdefgh.tmp"
    other.write_bytes(b"")
    assert remove_stale_temporaries(target) == [left]
    assert not left.exists() and other.exists() and target.read_bytes() == b"new"


def test_a_restart_after_a_cut_save_removes_its_leftovers_saying_which(
        tmp_path: Path, caplog: pytest.LogCaptureFixture):
    param_path = tmp_path / "rover.parm"
    left = tmp_path / ".rover.waypoints.k3j4h5g6.tmp"
    left.write_bytes(b"QGC WPL 110\n")
    with caplog.at_level(logging.WARNING, logger="mecanum_mav.io.storage"):
        FileStorage(param_path)
    assert not left.exists()
    assert [r.getMessage() for r in caplog.records] == [
        f"removed {left}, left by a save that was cut short"]


def test_the_stored_mission_loads_saying_how_many_items_and_none_is_no_complaint(
        tmp_path: Path, caplog: pytest.LogCaptureFixture):
    storage = FileStorage(tmp_path / "rover.parm")
    assert storage.load_mission() == ([], "")  # (no file yet: nothing to say)
    items = [MissionItem(seq, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_CMD_NAV_WAYPOINT,
                         x=seq * 10_000) for seq in range(3)]
    storage.save_mission(items)
    with caplog.at_level(logging.INFO, logger="mecanum_mav.io.storage"):
        loaded, why = storage.load_mission()
    assert (len(loaded), why) == (3, "")
    assert [r.getMessage() for r in caplog.records] == [
        f"mission of 3 items loaded from {storage.mission_path}"]


def test_an_unreadable_mission_file_is_left_as_it_is_and_said_why(
        tmp_path: Path, caplog: pytest.LogCaptureFixture):
    storage = FileStorage(tmp_path / "rover.parm")
    storage.mission_path.write_text("not a mission\n")
    with caplog.at_level(logging.ERROR, logger="mecanum_mav.io.storage"):
        assert storage.load_mission() == ([], "Mission file unreadable: rover.waypoints")
    [record] = caplog.records
    assert record.getMessage().startswith("mission not loaded: ")
    assert str(storage.mission_path) in record.getMessage()
    assert storage.mission_path.read_text() == "not a mission\n"
