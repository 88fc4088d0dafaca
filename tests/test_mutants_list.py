"""The mutation list (tools/mutants.py) stays applicable to the tree: CI runs only its fast
subset, so a refactor that moves the code of another entry must be caught here, not when
someone runs the whole list."""

from __future__ import annotations

import sys
from pathlib import Path

TOOLS = Path(__file__).resolve().parent.parent / "tools"
sys.path.insert(0, str(TOOLS))

import mutants  # noqa: E402


def test_every_mutation_in_the_list_finds_its_snippet_exactly_once():
    stale = {m.id: reason for m in mutants.MUTATIONS
             if (reason := mutants.stale_reason(m)) is not None}
    assert not stale


def test_mutation_ids_are_unique():
    ids = [m.id for m in mutants.MUTATIONS]
    assert len(ids) == len(set(ids))
