"""Shared fixtures: the lockstep harness (the rover core, the simulated board and the scripted
ground station in virtual time). Real-socket tests build their own links on port 0.

Shared helpers that are not fixtures live in support.py (plain code the rigs import too);
:func:`wait_until` is re-exported here for older ``from conftest import wait_until``."""

from __future__ import annotations

import os
import re
import signal
import sys
from collections.abc import Generator, Iterator

import pytest
from hypothesis import settings
from support import wait_until as wait_until

from mecanum_mav.config.params import Params
from mecanum_mav.control.fccheck import FcCheckState
from mecanum_mav.sim.lockstep import Lockstep


def lockstep(params: Params | dict | None = None, **options) -> Lockstep:
    """A :class:`Lockstep` harness (core + simulated board + scripted ground station) whose
    flight-controller link is up (the board's first heartbeat has been heard) and whose
    check of the board's setup has decided (as a pilot arms after "FC setup checked")."""
    if isinstance(params, dict) or params is None:
        values, params = params or {}, Params()
        params.update(values)
    h = Lockstep(params, **options)
    assert h.run_until(lambda: not h.core.vehicle.fc_lost, 3.0), "no flight-controller heartbeat"
    assert h.run_until(lambda: h.core.fc_check.state is not FcCheckState.READING, 3.0), \
        "the flight controller's setup was never read"
    return h


@pytest.fixture
def harness(request) -> Lockstep:
    """A lockstep harness; parametrize indirectly with a dict of parameter values."""
    return lockstep(getattr(request, "param", None))


@pytest.fixture(autouse=True, scope="session")
def _private_rover_claims(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """The rovers the tests start claim their system id and ground-station port
    (:mod:`mecanum_mav.io.claims`) in a folder of this test session's own: not against rovers
    running on the machine, nor another session's."""
    old = os.environ.get("XDG_RUNTIME_DIR")
    os.environ["XDG_RUNTIME_DIR"] = str(tmp_path_factory.mktemp("runtime"))
    yield
    if old is None:
        del os.environ["XDG_RUNTIME_DIR"]
    else:
        os.environ["XDG_RUNTIME_DIR"] = old


# --------------------------------------------------------------------------- parallel runs

settings.register_profile("suite", deadline=None)
settings.load_profile("suite")
"""Hypothesis's per-example deadline (200 ms) is a wall-clock limit: with the suite's workers
sharing two cores an example of 90 ms took 400 ms. Speed is the benchmarks' (tools/); a
property test checks the property."""

WORKERS_PER_CORE = 2
"""``-n auto`` (pyproject's addopts) starts this many pytest-xdist workers per core: most of the
suite's wall time is spent waiting on real processes (the firmware, the companion, MAVProxy),
so two workers a core keep both cores busy (measured: 1.1 of 2 cores on average with 4
workers, docs/testing.md). ``PYTEST_XDIST_AUTO_NUM_WORKERS`` or ``-n N`` overrides it."""

MAX_WORKERS = 8
"""Each worker may run a firmware, a companion and a ground station at once: no more than this
on a big machine."""


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """Workers for ``-n auto``: :data:`WORKERS_PER_CORE` per core, at most :data:`MAX_WORKERS`."""
    return max(1, min(MAX_WORKERS, WORKERS_PER_CORE * (os.cpu_count() or 1)))


SHARED_FIXTURE_GROUP = "module"
"""A module whose tests share a module-scoped fixture (a twin, three firmwares, a fleet, a
recorded drive) runs on one worker (xdist's ``loadgroup``): split across workers, each would
build the fixture again."""


def _shares_a_module_fixture(item: pytest.Item) -> bool:
    fixturedefs = getattr(item, "_fixtureinfo", None)
    if fixturedefs is None:
        return False
    return any(defs[-1].scope == "module" for defs in fixturedefs.name2fixturedefs.values())


def _runs_long(item: pytest.Item) -> bool:
    return item.get_closest_marker("sitl") is not None or \
        item.get_closest_marker("slow") is not None


@pytest.hookimpl(tryfirst=True)  # before xdist's own, which reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Long tests (marked ``sitl`` or ``slow``) first, so that no worker starts a minute-long
    test as the others finish; a module's tests that share a module fixture in one xdist group
    (:data:`SHARED_FIXTURE_GROUP`). The order within each kind is kept."""
    for item in items:
        if _shares_a_module_fixture(item):
            module = item.nodeid.split("::", 1)[0]
            item.add_marker(pytest.mark.xdist_group(f"{SHARED_FIXTURE_GROUP}:{module}"))
    items.sort(key=lambda item: not _runs_long(item))
    if config.pluginmanager.hasplugin("timeout"):  # (pytest-timeout, a declared dependency)
        limit_each_test_under_a_mutant(items, os.environ.get("MUTANT_UNDER_TEST", ""),
                                       sys.modules.get("mutmut.state"))


@pytest.hookimpl(trylast=True)  # after xdist's own, which marks a grouped test's node id
def pytest_collection_finish(session: pytest.Session) -> None:
    """In an xdist worker: each grouped test's node id carries its group (``...@group``), or the
    groups were lost and each module fixture would be built once per worker."""
    if not session.config.getoption("loadgroup", False):
        return
    lost = [item.nodeid for item in session.items
            if item.get_closest_marker("xdist_group") and "@" not in item.nodeid]
    if lost:
        raise pytest.UsageError(
            f"pytest-xdist put no group in {len(lost)} node ids (first {lost[0]}): this pytest "
            "and pytest-xdist do not work together (pytest-xdist issue 1386); see pyproject.toml")


# --------------------------------------------------------------------------- mutation testing


def pytest_configure(config: pytest.Config) -> None:
    """Under mutmut's tracing pass (tools/mutation.py; ``MUTANT_UNDER_TEST=stats``) the
    processes the tests start run the package as it is: mutmut traces calls in this process
    only, and its trace in a child would look for its configuration in the child's folder.
    The pass itself still traces here (mutmut keeps the mode in-process too). With a mutant
    under test the variable stays, so the companions the tests start run that mutant."""
    global _tracing_for_mutmut
    if os.environ.get("MUTANT_UNDER_TEST") == "stats":
        del os.environ["MUTANT_UNDER_TEST"]
        _tracing_for_mutmut = True
    _ctrl_c_as_a_terminal_gives_it()


def _ctrl_c_as_a_terminal_gives_it() -> None:
    """A suite a shell started in the background without job control (``cmd &`` in a
    script) inherits SIGINT and SIGQUIT ignored, and so would every process it starts: the
    Ctrl-C tests would fail for a reason of the launcher's (a process that starts with SIGINT
    ignored keeps it so, as Python does). Here they get what a terminal gives; a handled
    signal goes back to its default in the processes started after (xdist's workers, the
    companions)."""
    for sig in (signal.SIGINT, signal.SIGQUIT):
        if signal.getsignal(sig) is signal.SIG_IGN:
            signal.signal(sig, signal.default_int_handler if sig == signal.SIGINT
                          else signal.SIG_DFL)


MUTANT_TIME_FACTOR = 3.0
MUTANT_TIME_MARGIN_S = 10.0
MUTANT_UNTRACED_S = 20.0
"""Under a mutant, each test may take MUTANT_TIME_FACTOR x its traced time (mutmut's trace,
already slower than a plain run) + MUTANT_TIME_MARGIN_S; a test the trace has not timed
counts as MUTANT_UNTRACED_S."""


def limit_each_test_under_a_mutant(items: list[pytest.Item], mutant: str,
                                   mutmut_state: object | None) -> None:
    """With a mutant under test (``MUTANT_UNDER_TEST`` names one, in mutmut's process), each
    test fails once it runs past its limit (pytest-timeout, :data:`MUTANT_TIME_FACTOR`), so a
    mutant that makes a test hang (a blocking write that never returns, a wait that never
    ends) is killed in seconds. mutmut's own limit covers the sum of the tests' times, minutes
    for a function most tests reach. Outside mutmut nothing changes: the suite's tests wait
    on their own deadlines. (Without pytest-timeout the caller adds no limit: an unknown
    marker would fail every test, and every mutant would read killed.)"""
    if "__mutmut_" not in mutant or mutmut_state is None:
        return
    traced: dict[str, float] = mutmut_state.state().duration_by_test  # type: ignore[attr-defined]
    for item in items:
        seconds = traced.get(item.nodeid, MUTANT_UNTRACED_S)
        limit = MUTANT_TIME_FACTOR * seconds + MUTANT_TIME_MARGIN_S
        item.add_marker(pytest.mark.timeout(limit, method="signal"))


_tracing_for_mutmut = False
"""True in mutmut's tracing pass: it asks only which functions each test reaches, and its
trace slows every call several times, so a test that keeps wall-clock time (a stick stream
at 1 kHz over a pty) may fail there. Such a failure is not a verdict and must not stop the
pass (mutmut stops at the first): it is reported as passed. Each mutant is then judged by
the tests run normally, on a clean run first (tools/mutation.py)."""


# --------------------------------------------------------------------------- CI knows what ran

REQUIRE_SITL = "MECANUM_REQUIRE_SITL"
"""Set to 1 by .ci/run where the firmware is: a real-firmware test that is skipped fails."""

FIRMWARE_SKIP = re.compile(r"\bSITL\b|ardurover|ardupilot|firmware", re.IGNORECASE)
"""A skip reason that speaks of the firmware: a real-firmware test someone forgot to mark
``sitl`` (or a whole module skipped while it is collected) fails too."""


def _sitl_required() -> bool:
    return os.environ.get(REQUIRE_SITL, "") not in ("", "0")


def _skip_reason(report: pytest.CollectReport | pytest.TestReport) -> str:
    longrepr = report.longrepr
    if isinstance(longrepr, tuple) and len(longrepr) == 3:  # (path, line, "Skipped: why")
        return str(longrepr[2])
    return str(longrepr)


def _fail_the_skip(report: pytest.CollectReport | pytest.TestReport, reason: str) -> None:
    report.outcome = "failed"
    report.longrepr = (f"{REQUIRE_SITL}=1 (the firmware is on this machine) but a real-firmware "
                       f"test was skipped: {reason}")


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(
        item: pytest.Item, call: pytest.CallInfo) -> Generator[None, pytest.TestReport,
                                                                pytest.TestReport]:
    """With $MECANUM_REQUIRE_SITL, a skipped test marked ``sitl``, or one skipped for a reason
    that names the firmware, fails with the skip's reason. In mutmut's tracing pass a failure
    is reported as passed (:data:`_tracing_for_mutmut`)."""
    report = yield
    if _tracing_for_mutmut and report.failed:
        report.outcome = "passed"
        report.longrepr = None
    if report.skipped and _sitl_required() and not hasattr(report, "wasxfail"):
        reason = _skip_reason(report)
        if item.get_closest_marker("sitl") is not None or FIRMWARE_SKIP.search(reason):
            _fail_the_skip(report, reason)
    return report


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(
        collector: pytest.Collector) -> Generator[None, pytest.CollectReport,
                                                  pytest.CollectReport]:
    """With $MECANUM_REQUIRE_SITL, a module skipped while it is collected for a reason that
    names the firmware is a collection error."""
    report = yield
    if report.skipped and _sitl_required():
        reason = _skip_reason(report)
        if FIRMWARE_SKIP.search(reason):
            _fail_the_skip(report, reason)
    return report
