"""tools/mutation.py's bookkeeping of mutmut's results (docs/testing.md): a new run tries the
earlier survivors of what it targets again, keeps killed mutants killed, and leaves other
modules' results alone; the report scores killed / (mutants - equivalent) per module."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType, SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture
def tool(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    spec = importlib.util.spec_from_file_location("mutation_tool", ROOT / "tools" / "mutation.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "mutation_tool", module)
    spec.loader.exec_module(module)
    monkeypatch.setattr(module, "MUTANTS", tmp_path / "mutants")
    return module


def write_meta(tool: ModuleType, source: str, codes: dict[str, int | None]) -> Path:
    meta = tool.MUTANTS / "mecanum_mav" / f"{source}.meta"
    meta.parent.mkdir(parents=True, exist_ok=True)
    meta.write_text(json.dumps({"exit_code_by_key": codes, "hash_by_function_name": {}}))
    return meta


def codes_in(meta: Path) -> dict[str, int | None]:
    return json.loads(meta.read_text())["exit_code_by_key"]


def trace(tool: ModuleType) -> Path:
    stats = tool.MUTANTS / tool.STATS_NAME
    stats.parent.mkdir(parents=True, exist_ok=True)
    stats.write_text("{}")
    return stats


def test_a_run_tries_its_targets_survivors_again_and_keeps_their_killed_mutants(tool):
    tlog = write_meta(tool, "io/tlog.py", {"a": 0, "b": 1, "c": 36, "d": None})
    other = write_meta(tool, "io/poller.py", {"f": 0, "g": 1})
    stats = trace(tool)
    assert tool.recheck_survivors({"io.tlog"}, []) == 1
    assert codes_in(tlog) == {"a": None, "b": 1, "c": 36, "d": None}
    assert codes_in(other) == {"f": 0, "g": 1}  # not a target: untouched
    assert tool.recheck_survivors({"io"}, []) == 1  # a package takes its modules
    assert codes_in(other) == {"f": None, "g": 1}
    assert stats.exists()  # (the trace is kept: nothing read "no tests")


def test_a_no_tests_verdict_that_is_not_a_reviewed_equivalent_has_every_test_traced_again(
        tool):
    """(A function moved to another module is reached by no test mutmut traced before.)"""
    write_meta(tool, "io/tlog.py", {"mecanum_mav.io.tlog.x_f__mutmut_1": 33})
    stats = trace(tool)
    equivalent = tool.Equivalent("mecanum_mav.io.tlog.x_f__mutmut_1", "x = 1", "why")
    assert tool.recheck_survivors({"io"}, [equivalent]) == 0  # reviewed: kept as it is
    assert stats.exists()  # (no test can reach it, as reviewed)
    write_meta(tool, "io/tlog.py", {"mecanum_mav.io.tlog.x_f__mutmut_1": 33})
    assert tool.recheck_survivors({"io"}, []) == 1
    assert not stats.exists()


def test_the_score_leaves_out_equivalent_mutants_and_counts_timeouts_as_killed(tool):
    write_meta(tool, "io/tlog.py", {f"mecanum_mav.io.tlog.x_f__mutmut_{k}": code
                                    for k, code in enumerate([1, 1, 36, 0, 0, 33, None])})
    equivalent = tool.Equivalent("mecanum_mav.io.tlog.x_f__mutmut_3", "x = 1", "why")
    [tally] = tool.tally(tool.load_results(), {"io"}, [equivalent])
    assert (tally.total, tally.equivalent, tally.killed, tally.unchecked) == (7, 1, 3, 1)
    assert tally.score == pytest.approx(3 / 5)  # the unchecked one is not scored yet


def meta_with_hashes(tool: ModuleType, hashes: dict[str, str],
                     codes: dict[str, int | None]) -> Path:
    """mutants/'s record of io/tlog.py: its functions' hashes and verdicts (by mutant name)."""
    meta = write_meta(tool, "io/tlog.py", codes)
    meta.write_text(json.dumps({"exit_code_by_key": codes, "hash_by_function_name": hashes,
                                "durations_by_key": {}, "estimated_durations_by_key": {}}))
    return meta


TLOG = "mecanum_mav.io.tlog."


def test_the_ledger_carries_every_decided_verdict_to_a_working_copy_without_mutants(
        tool, tmp_path):
    """A fresh clone has no mutants/: the verdicts judged so far come from the ledger, with
    the hashes mutmut compares before it keeps a verdict; unjudged mutants stay unjudged."""
    ledger = tmp_path / "verdicts.json"
    meta_with_hashes(tool, {"x_f": "h1", "xǁTlogǁwrite": "h2"},
                     {TLOG + "x_f__mutmut_1": 1, TLOG + "x_f__mutmut_2": 0,
                      TLOG + "x_f__mutmut_10": 36, TLOG + "xǁTlogǁwrite__mutmut_1": None})
    assert tool.save_ledger(ledger) == 3
    saved = json.loads(ledger.read_text())
    assert saved == {"mecanum_mav/io/tlog.py": {"x_f": ["h1", "1:1 2:0 10:36"]}}
    (tool.MUTANTS / "mecanum_mav" / "io" / "tlog.py.meta").unlink()
    assert tool.restore_ledger(ledger) == 3
    meta = json.loads((tool.MUTANTS / "mecanum_mav" / "io" / "tlog.py.meta").read_text())
    assert meta["exit_code_by_key"] == {TLOG + "x_f__mutmut_1": 1, TLOG + "x_f__mutmut_2": 0,
                                        TLOG + "x_f__mutmut_10": 36}
    assert meta["hash_by_function_name"] == {"x_f": "h1"}


def test_the_ledger_gives_no_verdict_to_a_changed_function_and_never_overrides_a_newer_one(
        tool, tmp_path):
    ledger = tmp_path / "verdicts.json"
    ledger.write_text(json.dumps({"mecanum_mav/io/tlog.py": {
        "x_f": ["h1", "1:1 2:0"], "x_g": ["old", "1:1"], "x_gone": ["h9", "1:1"]}}))
    meta = meta_with_hashes(tool, {"x_f": "h1", "x_g": "new"},
                            {TLOG + "x_f__mutmut_1": None, TLOG + "x_f__mutmut_2": 1,
                             TLOG + "x_g__mutmut_1": None})
    assert tool.restore_ledger(ledger) == 1
    assert codes_in(meta) == {TLOG + "x_f__mutmut_1": 1,  # unjudged here: the ledger's
                              TLOG + "x_f__mutmut_2": 1,  # judged here since: kept
                              TLOG + "x_g__mutmut_1": None}  # the function changed


class _Item:
    """The part of a pytest item the limit reads and writes."""

    def __init__(self, nodeid: str) -> None:
        self.nodeid = nodeid
        self.marks: list[pytest.Mark] = []

    def add_marker(self, mark: pytest.MarkDecorator) -> None:
        self.marks.append(mark.mark)


_MutmutState = SimpleNamespace(  # mutmut.state as a run has it: the trace's time of each test
    state=lambda: SimpleNamespace(duration_by_test={"tests/test_a.py::test_fast": 0.5}))


def test_under_a_mutant_each_test_stops_after_three_times_its_traced_time_and_ten_seconds():
    """A mutant that makes one test hang is killed after that test's limit, not after
    mutmut's limit for all the function's tests (tests/conftest.py); an untimed test gets
    the limit of a 20 s test."""
    from conftest import limit_each_test_under_a_mutant
    items = [_Item("tests/test_a.py::test_fast"), _Item("tests/test_b.py::test_new")]
    limit_each_test_under_a_mutant(items, "mecanum_mav.io.poller.x_f__mutmut_3",  # type: ignore[arg-type]
                                   _MutmutState)
    assert [(m.name, m.args, m.kwargs) for item in items for m in item.marks] == [
        ("timeout", (11.5,), {"method": "signal"}), ("timeout", (70.0,), {"method": "signal"})]


@pytest.mark.parametrize("mutant", ["", "stats", "list_all_tests", "fail"])
def test_without_a_mutant_under_test_no_test_gets_a_limit(mutant: str):
    """The suite itself, mutmut's clean run, its trace and its forced failure: the tests keep
    their own deadlines only."""
    from conftest import limit_each_test_under_a_mutant
    item = _Item("tests/test_a.py::test_fast")
    limit_each_test_under_a_mutant([item], mutant, _MutmutState)  # type: ignore[list-item]
    limit_each_test_under_a_mutant([item], "mecanum_mav.io.poller.x_f__mutmut_3",  # type: ignore[list-item]
                                   None)
    assert item.marks == []
