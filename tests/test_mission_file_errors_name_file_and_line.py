"""A mission file that cannot be read (io/missionfile.py) is refused as a whole with
``file:line: what is wrong`` for the first problem found, line numbers counting every line of
the file (blank ones too)."""

from __future__ import annotations

from pathlib import Path

import pytest

from mecanum_mav.io.missionfile import MissionFileError, load_mission
from mecanum_mav.io.storage import FileStorage

HEADER = "QGC WPL 110"
ITEM_0 = "0\t1\t3\t16\t0\t0\t0\t0\t47.3977000\t8.5456000\t0\t1"
ITEM_1 = "1\t0\t3\t16\t0\t0\t0\t0\t47.3977180\t8.5456000\t0\t1"
ITEM_2 = "2\t0\t3\t16\t0\t0\t0\t0\t47.3977180\t8.5456265\t0\t1"


def refusal(tmp_path: Path, text: str) -> str:
    path = tmp_path / "rover.waypoints"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(MissionFileError) as caught:
        load_mission(path)
    return str(caught.value).removeprefix(f"{path}:")


def test_a_good_file_loads_every_item_in_order(tmp_path: Path):
    path = tmp_path / "rover.waypoints"
    path.write_text("\n".join([HEADER, ITEM_0, "", ITEM_1, ITEM_2]) + "\n", encoding="utf-8")
    assert [item.seq for item in load_mission(path)] == [0, 1, 2]


@pytest.mark.parametrize("text", ["", "\n", "QGC WPL 120\n" + ITEM_0 + "\n",
                                  ITEM_0 + "\n"], ids=["empty", "blank", "v120", "no-header"])
def test_a_file_without_the_qgc_wpl_110_header_is_not_a_mission_file(tmp_path: Path,
                                                                         text: str):
    assert refusal(tmp_path, text) == "1: not a mission file (first line must be QGC WPL 110)"


@pytest.mark.parametrize(("bad_line", "problem"), [
    (ITEM_1.rsplit("\t", 1)[0], "expected 12 fields, found 11"),
    (ITEM_2, "item 2 where item 1 was expected"),
    (ITEM_1.replace("\t16\t", "\twaypoint\t"), "invalid literal for int() with base 10: "
                                                "'waypoint'"),
    (ITEM_1.replace("47.3977180", "95.0"), "item 1: latitude off the earth"),
], ids=["fields", "order", "number", "upload-check"])
def test_the_first_bad_item_is_named_by_its_line_and_what_is_wrong(tmp_path: Path,
                                                                  bad_line: str, problem: str):
    text = "\n".join([HEADER, ITEM_0, "", bad_line, "garbage after it"]) + "\n"
    assert refusal(tmp_path, text) == f"4: {problem}"


@pytest.mark.parametrize(("before", "line"), [
    ("\n".join([HEADER, ITEM_0, ITEM_1]) + "\n", 4),
    ("\n\n", 3),  # blank lines count, the first one too
], ids=["item-4", "after-blank-lines"])
def test_bytes_that_are_not_utf8_text_are_refused_naming_their_line(tmp_path: Path,
                                                                    before: str, line: int):
    """A damaged file (or one a tool wrote in another encoding) is a MissionFileError with
    its line like any other problem, not an exception the companion does not expect."""
    path = tmp_path / "rover.waypoints"
    bad = b"2\t0\t3\t16\t0\t0\t0\t0\t47.39\xff\t8.54\t0\t1\n"
    path.write_bytes(before.encode("utf-8") + bad)
    with pytest.raises(MissionFileError) as caught:
        load_mission(path)
    assert str(caught.value) == f"{path}:{line}: not UTF-8 text (byte 0xff)"


def test_a_mission_file_that_is_not_utf8_leaves_the_rover_without_a_mission_and_says_so(
        tmp_path: Path):
    """The rover's stored mission (io/storage.py): an unreadable file is logged and said,
    and the rover starts without a mission instead of failing."""
    storage = FileStorage(tmp_path / "rover.parm")
    storage.mission_path.write_bytes(HEADER.encode() + b"\n\xc3\x28\n")
    assert storage.load_mission() == ([], "Mission file unreadable: rover.waypoints")
