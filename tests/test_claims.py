"""One rover per system id and ground station on a machine (:mod:`mecanum_mav.io.claims`):
a second ``sim`` or ``run`` that would send as the same system to the same ground station,
or listen on the same port, is refused with exit status 2; the claim dies with its holder,
kill -9 included."""

from __future__ import annotations

import os
import signal
import socket
import stat
from pathlib import Path

import pytest
from support import wait_until

from mecanum_mav.io.claims import (
    InUseError,
    claim_ground_station,
    ground_station_claim,
    runtime_dir,
)
from mecanum_mav.sim.process import CliProcess, free_port


@pytest.fixture(autouse=True)
def _runtime(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))


def test_the_same_system_id_to_the_same_ground_station_is_refused_while_held() -> None:
    with claim_ground_station(1, "udpout:127.0.0.1:14550"):
        with pytest.raises(InUseError) as refused, claim_ground_station(
                1, "udpout:localhost:14550"):
            pass
        assert str(refused.value).startswith(
            f"system id 1 on --gcs udpout:localhost:14550 is in use by another running rover "
            f"(process {os.getpid()})")
        with claim_ground_station(2, "udpout:127.0.0.1:14550"):  # another system id
            pass
        with claim_ground_station(1, "udpout:127.0.0.1:14560"):  # another ground station
            pass
    with claim_ground_station(1, "udpout:127.0.0.1:14550"):  # released by its holder
        pass


def test_a_listening_port_is_one_rovers_whatever_its_system_id() -> None:
    with claim_ground_station(1, "udpin:0.0.0.0:14550"):
        with pytest.raises(InUseError, match="listens on UDP port 14550"), \
                claim_ground_station(7, "udpin:127.0.0.1:14550"):
            pass
        with claim_ground_station(1, "tcpin:0.0.0.0:14550"):  # TCP is another port
            pass
    with claim_ground_station(1, "udpin:127.0.0.1:0"), claim_ground_station(
            1, "udpin:127.0.0.1:0"):  # port 0: the OS gives each its own
        pass


def started(rover: CliProcess) -> bool:
    return "mecanum-mav: rover system" in rover.log()


def test_a_second_rover_with_the_same_id_and_ground_station_exits_2_until_the_first_is_killed(
        tmp_path: Path) -> None:
    gcs = f"udpout:127.0.0.1:{free_port()}"
    with CliProcess(["sim", "--gcs", gcs], tmp_path / "first") as first:
        assert wait_until(lambda: started(first), 20.0), first.log()
        with CliProcess(["run", "--fc", "sim", "--gcs", gcs], tmp_path / "second") as second:
            assert second.wait(20.0) == 2, second.log()
            assert (f"mecanum-mav: system id 1 on --gcs {gcs} is in use by another running "
                    f"rover (process {first.pid})") in second.log()
        os.killpg(first.pid, signal.SIGKILL)  # no clean-up: the kernel frees the claim
        first.wait(10.0)
        with CliProcess(["run", "--fc", "sim", "--gcs", gcs], tmp_path / "third") as third:
            assert wait_until(lambda: started(third), 20.0), third.log()
            assert third.stop(10.0) == 0, third.log()


def test_a_claims_folder_that_is_a_link_or_a_file_is_refused_not_followed(tmp_path: Path):
    """(In /tmp another user could plant ``mecanum-mav-UID`` as a link to a folder of theirs,
    and so decide which rovers this user may start.)"""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    planted = tmp_path / "mecanum-mav"
    planted.symlink_to(elsewhere)
    with pytest.raises(OSError, match=f"{planted} is not a folder of this user's"):
        runtime_dir()
    planted.unlink()
    planted.write_text("")
    with pytest.raises(OSError, match="not a folder of this user's"):
        runtime_dir()


def test_without_xdg_runtime_dir_the_claims_are_in_this_users_folder_in_tmp(
        monkeypatch: pytest.MonkeyPatch):
    for unset in (None, ""):  # (an empty XDG_RUNTIME_DIR is no folder: the XDG spec's "unset")
        if unset is None:
            monkeypatch.delenv("XDG_RUNTIME_DIR")
        else:
            monkeypatch.setenv("XDG_RUNTIME_DIR", unset)
        assert runtime_dir() == Path(f"/tmp/mecanum-mav-{os.getuid()}")


def test_the_claims_folder_is_made_private_to_its_user():
    assert stat.S_IMODE(runtime_dir().stat().st_mode) == 0o700


def test_a_claims_folder_in_tmp_that_cannot_be_made_is_refused_without_naming_xdg(
        monkeypatch: pytest.MonkeyPatch):
    """The refusal names XDG_RUNTIME_DIR only where that variable chose the folder (a name
    too long for the file system stands for any reason /tmp refuses it)."""
    monkeypatch.delenv("XDG_RUNTIME_DIR")
    monkeypatch.setattr(os, "getuid", lambda: int("9" * 300))
    with pytest.raises(OSError) as refused:
        runtime_dir()
    assert str(refused.value) == (f"cannot keep the rover claims in /tmp/mecanum-mav-{'9' * 300}:"
                                  " File name too long")


def lock_name(url: str) -> str:
    claim = ground_station_claim(1, url)
    assert claim is not None
    return claim[0]


@pytest.mark.parametrize(("url", "same"), [
    ("udpout:localhost:14550", "udpout:127.0.0.1:14550"),
    ("udpout:LOCALHOST:14550", "udpout:localhost:14550"),
    ("udpout:A..B:14550", "udpout:a..b:14550"),  # (no address: IDNA refuses an empty label)
])
def test_one_destination_named_two_ways_is_one_claim(url: str, same: str):
    """A sending link's claim is its destination's address where the name resolves, the name
    (case aside) where it does not; another port is another claim."""
    assert lock_name(url) == lock_name(same)
    assert lock_name(url) != lock_name(url.replace("14550", "14551"))


def test_two_destinations_are_two_claims_named_by_their_addresses():
    """Rovers sending to two ground stations (two hosts) may share a system id: each claim
    names its own destination's address."""
    assert lock_name("udpout:127.0.0.1:14550") == "system1-udpout-127.0.0.1-14550.lock"
    assert lock_name("udpout:127.0.0.2:14550") == "system1-udpout-127.0.0.2-14550.lock"


@pytest.mark.parametrize("url", ["udpout:../../elsewhere:14550", "udpout:127.0.0.1:../x",
                                 "tcpin:0.0.0.0:../../x"])
def test_no_url_names_a_claim_outside_the_claims_folder(url: str):
    """Whatever the --gcs text holds, its claim is one file in the claims folder: a slash in
    it is quoted, not a way into another folder."""
    assert "/" not in lock_name(url)
    with claim_ground_station(1, url):
        assert [p.name for p in runtime_dir().iterdir()] == [lock_name(url)]


def test_a_serial_device_named_by_a_path_with_colons_is_the_device_it_links_to(tmp_path: Path):
    """/dev/serial/by-path names hold colons (``pci-0000:00:14.0-usb-0:2:1.0-port0``): such
    a name is still a serial device, one claim with the device it links to, not a network
    destination."""
    device = tmp_path / "ttyUSB0"
    device.touch()
    by_path = tmp_path / "pci-0000:00:14.0-usb-0:2:1.0-port0"
    by_path.symlink_to(device)
    assert lock_name(f"{by_path},57600") == lock_name(str(device))


def _dual_stack_resolver(host: str, port: object, family: int = 0, *_: object,
                         **__: object) -> list[tuple[object, ...]]:
    """getaddrinfo of a machine whose hosts file lists ``::1 localhost`` before
    ``127.0.0.1 localhost``, one entry per address (as some resolvers answer when no socket
    type is asked for)."""
    addresses = {"localhost": [(socket.AF_INET6, ("::1", 0, 0, 0)),
                               (socket.AF_INET, ("127.0.0.1", 0))],
                 "127.0.0.1": [(socket.AF_INET, ("127.0.0.1", 0))]}
    found = [(fam, socket.SOCK_DGRAM, 17, "", address)
             for fam, address in addresses.get(host, []) if family in (0, fam)]
    if not found:
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")
    return found


def test_localhost_is_127_0_0_1_even_where_the_resolver_lists_ipv6_first(
        monkeypatch: pytest.MonkeyPatch):
    """MAVLink's UDP links (pymavlink's udpout) send over IPv4, so the destination a claim
    names is the IPv4 address, whatever the resolver lists first."""
    monkeypatch.setattr(socket, "getaddrinfo", _dual_stack_resolver)
    assert lock_name("udpout:localhost:14550") == lock_name("udpout:127.0.0.1:14550") == (
        "system1-udpout-127.0.0.1-14550.lock")


def test_a_claims_folder_that_cannot_be_made_is_refused_saying_where_and_why(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """(XDG_RUNTIME_DIR of a session that has ended, or of another user after ``su``.)"""
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path / "gone"))
    with pytest.raises(OSError) as refused:
        runtime_dir()
    assert str(refused.value) == (f"cannot keep the rover claims in {tmp_path}/gone/mecanum-mav:"
                                  " No such file or directory (from XDG_RUNTIME_DIR)")
