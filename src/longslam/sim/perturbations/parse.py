"""Perturbations as text: NAME[=LEVEL] for one, joined by '+' for several at once
(`drop=0.1+blur=0.02`), and `none` for none; as `simulate --perturb` takes them and a study's
`perturbations` lists them. The canonical text names every level, defaults included, so a run key
or meta.json says what was applied even if a default changes."""

from __future__ import annotations

import math
import re
from collections.abc import Iterable

from longslam.core.errors import InputError
from longslam.sim.perturbations.base import Perturbation
from longslam.sim.perturbations.catalog import get_perturbation, perturbation_class

NONE = "none"
# '+' followed by a letter or digit starts the next perturbation; a '+' in a level's exponent
# (1e+3) does not.
_JOIN = re.compile(r"\+(?=[A-Za-z])")


def parse_one(text: str) -> Perturbation:
    """NAME or NAME=LEVEL as a perturbation; InputError naming the text and what was expected."""
    name, has_level, level_part = str(text).strip().partition("=")
    name = name.strip()
    if not name:
        raise InputError(f"perturbation {text!r}: expected NAME or NAME=LEVEL (see `longslam list`)")
    cls = perturbation_class(name)  # an unknown name first: its error lists the valid ones
    if not has_level:
        return get_perturbation(name)
    try:
        level = float(level_part)
    except ValueError:
        level = math.nan
    if not level_part.strip() or not math.isfinite(level):
        raise InputError(f"perturbation {text!r}: level {level_part.strip()!r} is not a number; expected {cls.meaning}")
    return get_perturbation(name, level)


def parse_perturbations(texts: Iterable[str]) -> tuple[Perturbation, ...]:
    """Several texts (each NAME[=LEVEL], or several joined by '+') as one list of perturbations,
    applied in that order; a perturbation given twice is refused."""
    out: list[Perturbation] = []
    for text in texts:
        for part in _JOIN.split(str(text)):
            made = parse_one(part)
            if any(p.name == made.name for p in out):
                raise InputError(
                    f"perturbation {made.name!r} is given twice; give each perturbation once, at one level"
                )
            out.append(made)
    return tuple(out)


def parse_entry(text: str) -> tuple[Perturbation, ...]:
    """One entry of a study's `perturbations`: `none`, or perturbations joined by '+'."""
    return () if str(text).strip() == NONE else parse_perturbations([text])


def canonical(perturbations: Iterable[Perturbation]) -> str:
    """The perturbations' text, every level named: `drop=0.1+blur=0.02`, or `none`."""
    return "+".join(p.text for p in perturbations) or NONE
