"""benchmarks/step_phases.py wraps parts of the methods by name: every part it lists still exists,
so a rename in the methods fails here instead of in the middle of a profile."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers.scripts import load_script

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
step_phases = load_script(BENCHMARKS / "step_phases.py", "benchmarks_step_phases")

PARTS = [(method, part) for method, parts in step_phases.PHASES.items() for part in parts]


@pytest.mark.parametrize(("method", "part"), PARTS, ids=[f"{m}:{p[3].strip()}" for m, p in PARTS])
def test_every_timed_part_names_a_function_that_exists(method, part):
    module, owner, name, _label = part
    assert callable(getattr(step_phases._owner(module, owner), name))


@pytest.mark.parametrize("method", sorted(step_phases.STEP))
def test_every_method_step_exists(method):
    module, owner = step_phases.STEP[method]
    assert callable(getattr(step_phases._owner(module, owner), "step"))
