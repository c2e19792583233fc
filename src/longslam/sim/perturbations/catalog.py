"""The perturbations longslam knows: the built-in ones and third-party ones from entry points.

A package adds its own in its pyproject.toml, the way sensor models are added::

    [project.entry-points."longslam.perturbations"]
    snow = "mypackage.perturbations:Snow"

where the target is a `Perturbation` subclass, made with the level (`Snow(0.01)`). The entry
point's name is the perturbation's name in `--perturb`, a study's `perturbations` and
`meta.json`; it is a folder of a study too, so letters, digits, '_', '.' and '-' only.
"""

from __future__ import annotations

import re
from typing import Any

from longslam.core.errors import InputError
from longslam.core.registry import Registry, failure
from longslam.sim.perturbations.base import Perturbation, level_text
from longslam.sim.perturbations.colour import Blur, Exposure
from longslam.sim.perturbations.depth import DepthDropout, DepthOffset, DepthRange
from longslam.sim.perturbations.frames import Drop, DropBurst

ENTRY_POINT_GROUP = "longslam.perturbations"
# '=' and '+' join a name to its level and perturbations to each other, so a name holds neither.
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


def _as_class(name: str, loaded: Any) -> type[Perturbation]:
    """A plugin's entry point: a Perturbation subclass, whose name is a folder name."""
    entry = PERTURBATIONS.plugin(name)
    where = f"perturbation {name!r}: entry point {entry.value if entry else name}"
    if not NAME.fullmatch(name):
        raise InputError(
            f"perturbation {name!r}: its entry point's name cannot be a folder name; "
            "expected letters, digits, '_', '.' or '-'"
        )
    if not (isinstance(loaded, type) and issubclass(loaded, Perturbation)):
        raise InputError(
            f"{where} is a {type(loaded).__name__}; " "expected a subclass of longslam.sim.perturbations.Perturbation"
        )
    return loaded


PERTURBATIONS: Registry[type[Perturbation]] = Registry("perturbation", ENTRY_POINT_GROUP, _as_class)
for _cls in (Drop, DropBurst, DepthOffset, Exposure, Blur, DepthDropout, DepthRange):
    PERTURBATIONS.register(_cls.name, _cls)
BUILTIN = tuple(PERTURBATIONS.builtin_names())


def perturbation_names() -> list[str]:
    """Every perturbation by name: the built-in ones, then the plugins'."""
    return PERTURBATIONS.names()


def perturbation_problem(name: str) -> str | None:
    """Why a plugin's perturbation cannot load, found without running its code, or None."""
    if PERTURBATIONS.plugin(name) is not None and not NAME.fullmatch(name):
        return "its name cannot be a folder name (letters, digits, '_', '.' or '-')"
    return PERTURBATIONS.problem(name)


def perturbation_class(name: str) -> type[Perturbation]:
    """The class of the perturbation `name`; UnknownNameError (with did-you-mean) if there is none."""
    return PERTURBATIONS.get(name)


def get_perturbation(name: str, level: float | None = None) -> Perturbation:
    """The perturbation `name` at `level` (its default if None); InputError for a bad name or level."""
    cls = perturbation_class(name)
    level = float(cls.default_level if level is None else level)
    problem = cls.level_problem(level)
    if problem is not None:
        raise InputError(f"perturbation {name}={level_text(level)}: {problem}")
    try:
        made = cls(level)
    except (Exception, SystemExit) as err:
        raise InputError(
            f"perturbation {name!r}: making it at level {level_text(level)} raised {failure(err)}"
        ) from None
    if made.name != name:
        # The name in meta.json and the study is the entry point's, so the frame draws are keyed by it.
        made.name = name
    return made


def describe_levels() -> list[str]:
    """Each perturbation with what its level means and its default, for `longslam list`."""
    out = []
    for name in perturbation_names():
        problem = perturbation_problem(name)
        if problem:
            out.append(f"{name} (broken: {problem})")
            continue
        try:
            cls = perturbation_class(name)
        except InputError as err:
            out.append(f"{name} (broken: {err})")
            continue
        out.append(f"{name} ({cls.meaning}; default {level_text(cls.default_level)})")
    return out
