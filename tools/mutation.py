#!/usr/bin/env python3
"""Mutation testing of the package with mutmut: every mutant of a package's modules, run
against the tests that reach it, and a report per module.

What
    mutmut (configured in pyproject.toml, ``[tool.mutmut]``) copies the package into
    ``mutants/``, writes every mutant of every function there (an operator swapped, a
    constant changed, an argument dropped, a return value replaced, ...), traces once which
    tests call which function, and then runs each mutant against the tests that reached its
    function, fastest first, stopping at the first failure. A mutant is *killed* when a test
    fails (or it runs past mutmut's time limit), *survived* when they all pass, *no tests*
    when no traced test reaches its function.

    A mutant that changes nothing a caller can observe (equivalent) is listed, with its
    mutated line and a one-line reason, in ``tools/equivalent_mutants.toml``, reviewed like
    code; nothing else is left out. An entry whose mutant no longer exists, makes another
    change, or is killed is stale and fails the run.

    The score of a module is killed / (mutants - equivalent). Goals (issue 36): 90 % in
    mecanum/, config/, protocol/, control/, io/ and runtime/, 80 % in app/ and sim/.

Usage
    python tools/mutation.py mecanum                # run one package's mutants, report
    python tools/mutation.py mecanum config -j 2    # several, two at a time
    python tools/mutation.py app.view io.links.tcp  # some modules
    python tools/mutation.py all                    # every package (hours on 2 cores)
    python tools/mutation.py --report-only all      # the report from the results so far
    python tools/mutation.py mecanum --survivors    # and the survivors' diffs

    The report is printed and written to mutants/report.md (survivors: mutants/survivors.md).
    Results stay in mutants/ between runs: mutmut reruns a mutant only when its function or
    the tests changed, so a second run of the same package after a new test is quick. Every
    run also writes its verdicts to tools/mutation_verdicts.json (kept in the repository) and
    every run starts by taking the verdicts mutants/ lacks from it: a fresh clone goes on
    where the last run stopped (see save_ledger and restore_ledger).

Exit status: 0 when every package reported meets its goal; 1 when one does not, or mutants
were left unchecked; 2 on a stale entry in the equivalents file or when mutmut itself failed.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "mecanum_mav"
MUTANTS = ROOT / "mutants"
EQUIVALENTS = ROOT / "tools" / "equivalent_mutants.toml"
REPORT = MUTANTS / "report.md"
SURVIVORS = MUTANTS / "survivors.md"
LEDGER = ROOT / "tools" / "mutation_verdicts.json"

GOALS: dict[str, float] = {
    "mecanum": 0.90, "config": 0.90, "protocol": 0.90, "control": 0.90, "io": 0.90,
    "runtime": 0.90, "app": 0.80, "sim": 0.80,
}
"""The share of non-equivalent mutants each package's tests must kill."""

KILLED = {"killed", "timeout", "segfault", "caught by type check"}
"""mutmut's verdicts that count as killed: a test failed, the tests ran past the time limit
(the mutant loops), or the process died of the mutant."""
SURVIVED = {"survived", "no tests"}
"""Verdicts that count against the score: no test failed, or no traced test reaches it."""


@dataclass
class ModuleTally:
    """A module's mutants by verdict."""

    module: str
    verdicts: Counter[str] = field(default_factory=Counter)
    equivalent: int = 0

    @property
    def total(self) -> int:
        return sum(self.verdicts.values())

    @property
    def killed(self) -> int:
        return sum(self.verdicts[v] for v in KILLED)

    @property
    def unchecked(self) -> int:
        return self.total - self.killed - sum(self.verdicts[v] for v in SURVIVED)

    @property
    def score(self) -> float | None:
        """killed / (mutants - equivalent); None when nothing is left to kill."""
        counted = self.total - self.equivalent - self.unchecked
        return self.killed / counted if counted > 0 else None


def package_of(module: str) -> str:
    """``mecanum_mav.control.core`` -> ``control``; a module at the package's root -> ``(root)``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 2 else "(root)"


def load_results() -> dict[str, dict[str, int | None]]:
    """mutmut's exit code for each mutant, by module (``mutants/**/*.py.meta``)."""
    results: dict[str, dict[str, int | None]] = {}
    for meta in sorted((MUTANTS / PACKAGE).rglob("*.py.meta")):
        source = meta.relative_to(MUTANTS).with_suffix("")  # mecanum_mav/x/y.py
        module = ".".join(source.with_suffix("").parts)
        data = json.loads(meta.read_text())
        results[module] = data.get("exit_code_by_key", {})
    return results


def verdict(exit_code: int | None) -> str:
    """mutmut's name for a mutant's exit code."""
    from mutmut.stats import status_by_exit_code
    return str(status_by_exit_code[exit_code])


@dataclass(frozen=True)
class Equivalent:
    """A reviewed equivalent mutant: its name, the line it writes, and why nothing can tell."""

    name: str
    change: str
    why: str


def load_equivalents(path: Path = EQUIVALENTS) -> list[Equivalent]:
    """The entries of the equivalents file (``[[mutant]]`` tables: name, change, why)."""
    if not path.exists():
        return []
    data = tomllib.loads(path.read_text())
    return [Equivalent(e["name"], e["change"], e["why"]) for e in data.get("mutant", [])]


def mutant_diff(name: str, module: str) -> str:
    """The unified diff mutmut shows for mutant ``name`` of ``module``."""
    from mutmut.mutation.diff_apply import get_diff_for_mutant
    path = Path(*module.split(".")).with_suffix(".py")
    return str(get_diff_for_mutant(name, path=path))


def added_lines(diff: str) -> list[str]:
    """The lines a diff adds, stripped."""
    return [line[1:].strip() for line in diff.splitlines()
            if line.startswith("+") and not line.startswith("+++")]


def stale_equivalents(equivalents: list[Equivalent],
                      results: dict[str, dict[str, int | None]]) -> list[str]:
    """Why each stale entry is stale: gone, another change, or killed (then it was not
    equivalent). Entries whose mutant has not been run yet are not judged."""
    module_of = {name: module for module, codes in results.items() for name in codes}
    stale = []
    for entry in equivalents:
        module = module_of.get(entry.name)
        if module is None:
            stale.append(f"{entry.name}: no such mutant (the function changed?)")
            continue
        code = results[module][entry.name]
        if code is None:
            continue
        if entry.change.strip() not in added_lines(mutant_diff(entry.name, module)):
            stale.append(f"{entry.name}: now makes another change than `{entry.change}`")
        elif verdict(code) in KILLED:
            stale.append(f"{entry.name}: killed, so not equivalent")
    return stale


def selected(module: str, targets: set[str]) -> bool:
    """Whether ``module`` (``mecanum_mav.app.view``) is one of ``targets``: packages
    (``app``) or modules (``app.view``; a subpackage ``io.links`` takes its modules)."""
    name = module.removeprefix(PACKAGE + ".")
    return package_of(module) in targets or any(
        name == t or name.startswith(t + ".") for t in targets)


def tally(results: dict[str, dict[str, int | None]], targets: set[str],
          equivalents: list[Equivalent]) -> list[ModuleTally]:
    """One tally per module of ``targets`` (:func:`selected`)."""
    equivalent_names = {e.name for e in equivalents}
    tallies = []
    for module, codes in results.items():
        if not selected(module, targets) or not codes:
            continue
        t = ModuleTally(module)
        for name, code in codes.items():
            t.verdicts[verdict(code)] += 1
            if name in equivalent_names and verdict(code) in SURVIVED:
                t.equivalent += 1
        tallies.append(t)
    return tallies


def percent(score: float | None) -> str:
    return "-" if score is None else f"{100 * score:.1f} %"


def report(tallies: list[ModuleTally]) -> tuple[str, bool]:
    """The report in Markdown, and whether every package met its goal with nothing unchecked."""
    lines = ["| module | mutants | killed | survived | no tests | timeout | equivalent | "
             "unchecked | score |", "| --- |" + " ---: |" * 8]
    by_package: dict[str, ModuleTally] = {}
    for t in sorted(tallies, key=lambda t: t.module):
        v = t.verdicts
        lines.append(f"| {t.module.removeprefix(PACKAGE + '.')} | {t.total} | {t.killed} | "
                     f"{v['survived']} | {v['no tests']} | {v['timeout']} | {t.equivalent} | "
                     f"{t.unchecked} | {percent(t.score)} |")
        whole = by_package.setdefault(package_of(t.module), ModuleTally(package_of(t.module)))
        whole.verdicts.update(t.verdicts)
        whole.equivalent += t.equivalent
    lines += ["", "| package | mutants | killed | survived | no tests | equivalent | unchecked | "
              "score | goal |", "| --- |" + " ---: |" * 7 + " --- |"]
    all_met = True
    for name, t in sorted(by_package.items()):
        goal = GOALS.get(name)
        met = t.unchecked == 0 and (goal is None or (t.score is not None and t.score >= goal))
        all_met &= met
        mark = "-" if goal is None else f"{100 * goal:.0f} % {'met' if met else 'NOT MET'}"
        if t.unchecked:
            mark += f" ({t.unchecked} unchecked)"
        lines.append(f"| {name}/ | {t.total} | {t.killed} | {t.verdicts['survived']} | "
                     f"{t.verdicts['no tests']} | {t.equivalent} | {t.unchecked} | "
                     f"{percent(t.score)} | {mark} |")
    return "\n".join(lines) + "\n", all_met


def survivors(results: dict[str, dict[str, int | None]], targets: set[str],
              equivalents: list[Equivalent]) -> str:
    """Each survivor's diff, by module (Markdown)."""
    equivalent_names = {e.name for e in equivalents}
    out = []
    for module, codes in sorted(results.items()):
        if not selected(module, targets):
            continue
        for name, code in codes.items():
            if verdict(code) in SURVIVED and name not in equivalent_names:
                out.append(f"## {name} ({verdict(code)})\n\n```diff\n"
                           f"{mutant_diff(name, module).strip()}\n```\n")
    return "\n".join(out)


STATS_NAME = "mutmut-stats.json"
"""mutmut's trace in mutants/: which tests reach which function, how long each test takes."""


def recheck_survivors(targets: set[str], equivalents: list[Equivalent]) -> int:
    """Forget the targets' survivors (survived, no tests) so this run tries them again.

    mutmut keeps a verdict until the mutant's function changes; a survivor of an earlier run
    would stay one after the test that kills it was written. A killed mutant stays killed
    (tests are added, not weakened: a weakened test shows in review), and so does a reviewed
    equivalent (mutmut runs it again when its function changes). Returns how many.

    mutmut also keeps its trace, and traces only tests that are new: a function moved to
    another module since (a new name to mutmut) is reached by no traced test, so its mutants
    read "no tests" whatever the tests do. A "no tests" verdict that is not a reviewed
    equivalent therefore deletes the trace: this run traces every test again first."""
    count = 0
    stale_trace = False
    equivalent = {e.name for e in equivalents}
    for meta in sorted((MUTANTS / PACKAGE).rglob("*.py.meta")):
        module = ".".join(meta.relative_to(MUTANTS).with_suffix("").with_suffix("").parts)
        if not selected(module, targets):
            continue
        data = json.loads(meta.read_text())
        codes = data.get("exit_code_by_key", {})
        again = [name for name, code in codes.items() if code is not None
                 and verdict(code) in SURVIVED and name not in equivalent]
        for name in again:
            stale_trace |= verdict(codes[name]) == "no tests"
            codes[name] = None
        if again:
            meta.write_text(json.dumps(data, indent=4))
            count += len(again)
    if stale_trace:
        (MUTANTS / STATS_NAME).unlink(missing_ok=True)
    return count


def _function_and_number(key: str) -> tuple[str, str]:
    """``mecanum_mav.io.tlog.xǁTlogǁwrite__mutmut_12`` -> (``xǁTlogǁwrite``, ``12``)."""
    mangled, _, number = key.partition("__mutmut_")
    return mangled.rpartition(".")[2], number


def save_ledger(path: Path | None = None) -> int:
    """Write every decided verdict in mutants/ to the ledger (:data:`LEDGER`); returns how many.

    mutants/ is a scratch folder that a fresh clone does not have, and judging every mutant
    takes hours: the ledger, kept in the repository, carries the verdicts from one working
    copy to the next. Per source file, per function: the function's hash as mutmut computed
    it and its decided verdicts as ``number:exit-code`` (``"1:1 2:0 5:36"``)."""
    path = LEDGER if path is None else path
    ledger: dict[str, dict[str, list[str]]] = {}
    count = 0
    for meta in sorted((MUTANTS / PACKAGE).rglob("*.py.meta")):
        data = json.loads(meta.read_text())
        codes: dict[str, list[str]] = {}
        for key, code in data.get("exit_code_by_key", {}).items():
            if code is not None:
                function, number = _function_and_number(key)
                codes.setdefault(function, []).append(f"{number}:{code}")
                count += 1
        hashes = data.get("hash_by_function_name", {})
        functions = {f: [hashes[f], " ".join(sorted(c, key=lambda v: int(v.split(":")[0])))]
                     for f, c in sorted(codes.items()) if f in hashes}
        if functions:
            ledger[meta.relative_to(MUTANTS).with_suffix("").as_posix()] = functions
    path.write_text(json.dumps(ledger, indent=1, ensure_ascii=False, sort_keys=True) + "\n")
    return count


def restore_ledger(path: Path | None = None) -> int:
    """Give mutants/ the ledger's verdicts it does not have (:func:`save_ledger`); returns how
    many. A verdict is taken only where the function's hash in mutants/ is the ledger's (or
    mutants/ has no record of the file yet: mutmut then compares the hashes itself when it
    makes the mutants, and forgets the verdicts of every function that changed since). A
    verdict mutants/ already has is kept: it is as new as the ledger's or newer."""
    from mutmut.utils.format_utils import get_mutant_name
    path = LEDGER if path is None else path
    if not path.exists():
        return 0
    count = 0
    for source, functions in json.loads(path.read_text()).items():
        meta = MUTANTS / f"{source}.meta"
        data = json.loads(meta.read_text()) if meta.exists() else {
            "exit_code_by_key": {}, "hash_by_function_name": {f: h for f, (h, _) in
                                                             functions.items()},
            "durations_by_key": {}, "estimated_durations_by_key": {}}
        codes, hashes = data["exit_code_by_key"], data["hash_by_function_name"]
        taken = 0
        for function, (function_hash, verdicts) in functions.items():
            if hashes.get(function) != function_hash:
                continue
            for entry in verdicts.split():
                number, _, code = entry.partition(":")
                key = get_mutant_name(Path(source), f"{function}__mutmut_{number}")
                if codes.get(key) is None and (key in codes or not meta.exists()):
                    codes[key] = int(code)
                    taken += 1
        if taken:
            meta.parent.mkdir(parents=True, exist_ok=True)
            meta.write_text(json.dumps(data, indent=4))
            count += taken
    return count


GENERATE = """
from mutmut.__main__ import create_mutants, store_lines_covered_by_tests
from mutmut.utils.file_utils import copy_also_copy_files, copy_src_dir, setup_source_paths
copy_src_dir(); copy_also_copy_files(); setup_source_paths(); store_lines_covered_by_tests()
create_mutants({jobs})
"""
"""The first step of ``mutmut run`` alone (mutmut has no command for it): make the mutants of
every function whose source changed, forgetting their verdicts. No test runs."""


def generate_mutants(jobs: int) -> int:
    """Make the mutants as ``mutmut run`` would before it runs any (:data:`GENERATE`)."""
    return subprocess.call([sys.executable, "-c", GENERATE.format(jobs=jobs)], cwd=ROOT)


def run_mutmut(targets: list[str], jobs: int) -> int:
    """``mutmut run`` on the targets' mutants (names ``mecanum_mav.<target>.*``)."""
    globs = [f"{PACKAGE}.{t}.*" for t in targets]
    # (the mutmut of this Python, whether or not its bin/ is on PATH)
    return subprocess.call([sys.executable, "-m", "mutmut", "run", "--max-children", str(jobs),
                            *globs], cwd=ROOT)


def all_packages() -> list[str]:
    return sorted(p.name for p in (ROOT / PACKAGE).iterdir()
                  if p.is_dir() and (p / "__init__.py").exists())


def exists(target: str) -> bool:
    """Whether ``target`` (``app`` or ``app.view``) is a package or module of the package."""
    path = ROOT / PACKAGE / Path(*target.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("packages", nargs="+",
                        help="packages under mecanum_mav/ (mecanum, config, ...), modules "
                        "(app.view, io.links.tcp) or 'all'")
    parser.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 2,
                        help="mutants run at once (default: one per core)")
    parser.add_argument("--report-only", action="store_true",
                        help="no run: the report from the results in mutants/")
    parser.add_argument("--survivors", action="store_true",
                        help="also write each survivor's diff to mutants/survivors.md")
    args = parser.parse_args(argv)

    packages = all_packages() if "all" in args.packages else args.packages
    unknown = sorted(t for t in packages if not exists(t))
    if unknown:
        parser.error(f"no package or module {', '.join(unknown)} in {PACKAGE}/")
    os.chdir(ROOT)  # mutmut reads its configuration and results from here
    restored = restore_ledger()
    if restored:
        print(f"mutation: {restored} verdicts taken from {LEDGER.relative_to(ROOT)}")
    if args.report_only:
        if generate_mutants(args.jobs) != 0:
            print("mutation: mutmut could not make the mutants (its output above)",
                  file=sys.stderr)
            return 2
    else:
        again = recheck_survivors(set(packages), load_equivalents())
        if again:
            print(f"mutation: {again} earlier survivors tried again against today's tests")
        if not (MUTANTS / STATS_NAME).exists():
            print("mutation: tracing every test first (which reaches which function)")
        status = run_mutmut(packages, args.jobs)
        # (stopped by hand or not: what was judged is kept)
        print(f"mutation: {save_ledger()} verdicts in {LEDGER.relative_to(ROOT)}")
        if status != 0:
            print("mutation: mutmut failed or was stopped (its output above)", file=sys.stderr)
            return 2

    results = load_results()
    equivalents = load_equivalents()
    text, met = report(tally(results, set(packages), equivalents))
    MUTANTS.mkdir(exist_ok=True)
    REPORT.write_text(text)
    print(text)
    print(f"(written to {REPORT.relative_to(ROOT)})")
    if args.survivors:
        SURVIVORS.write_text(survivors(results, set(packages), equivalents))
        print(f"survivors' diffs: {SURVIVORS.relative_to(ROOT)}")
    stale = stale_equivalents(equivalents, results)
    for why in stale:
        print(f"stale entry in {EQUIVALENTS.relative_to(ROOT)}: {why}", file=sys.stderr)
    if stale:
        return 2
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
