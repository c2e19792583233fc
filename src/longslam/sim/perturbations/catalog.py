"""The perturbations longslam knows: the built-in ones and third-party ones from entry points.

A package adds its own in its pyproject.toml, the way sensor models are added::

    [project.entry-points."longslam.perturbations"]
    snow = "mypackage.perturbations:Snow"

where the target is a `Perturbation` subclass, made with the level (`Snow(0.01)`). The entry
point's name is the perturbation's name in `--perturb`, a study's `perturbations` and
`meta.json`; it is a folder of a study too, so letters, digits, '_', '.' and '-' only.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from functools import lru_cache
from importlib.metadata import entry_points

from longslam.errors import InputError, UnknownNameError
from longslam.sim.perturbations.base import Perturbation, level_text
from longslam.sim.perturbations.colour import Blur, Exposure
from longslam.sim.perturbations.depth import DepthDropout, DepthOffset
from longslam.sim.perturbations.frames import Drop, DropBurst
from longslam.sim.sensors.catalog import failure

ENTRY_POINT_GROUP = "longslam.perturbations"
BUILTIN: dict[str, type[Perturbation]] = {
    cls.name: cls for cls in (Drop, DropBurst, DepthOffset, Exposure, Blur, DepthDropout)
}
# '=' and '+' join a name to its level and perturbations to each other, so a name holds neither.
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


@lru_cache(maxsize=8)
def _plugins(search_path: tuple[str, ...]) -> dict:
    # Keyed on sys.path, as the sensors' catalogue is: a package put on the path later is found.
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP) if ep.name not in BUILTIN}


def perturbation_names() -> list[str]:
    """Every perturbation by name: the built-in ones, then the plugins'."""
    return list(BUILTIN) + sorted(_plugins(tuple(sys.path)))


def perturbation_problem(name: str) -> str | None:
    """Why a plugin's perturbation cannot load, found without running its code, or None."""
    plugins = _plugins(tuple(sys.path))
    if name not in plugins:
        return None
    if not NAME.fullmatch(name):
        return "its name cannot be a folder name (letters, digits, '_', '.' or '-')"
    module = plugins[name].module
    try:
        found = importlib.util.find_spec(module)
    except (ImportError, ValueError):  # a parent package missing, or an empty name
        found = None
    return None if found is not None else f"its module {module} is not installed"


def perturbation_class(name: str) -> type[Perturbation]:
    """The class of the perturbation `name`; UnknownNameError (with did-you-mean) if there is none."""
    if name in BUILTIN:
        return BUILTIN[name]
    plugins = _plugins(tuple(sys.path))
    if name not in plugins:
        raise UnknownNameError("perturbation", name, perturbation_names())
    if not NAME.fullmatch(name):
        raise InputError(f"perturbation {name!r}: its entry point's name cannot be a folder name; "
                         "expected letters, digits, '_', '.' or '-'")
    entry = plugins[name].value
    # A plugin's code runs here: whatever it raises (SystemExit too) is its failure, named.
    try:
        loaded = plugins[name].load()
    except (Exception, SystemExit) as err:
        raise InputError(f"perturbation {name!r}: entry point {entry} cannot be loaded ({failure(err)})") from None
    if not (isinstance(loaded, type) and issubclass(loaded, Perturbation)):
        raise InputError(f"perturbation {name!r}: entry point {entry} is a {type(loaded).__name__}; "
                         "expected a subclass of longslam.sim.perturbations.Perturbation")
    return loaded


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
        raise InputError(f"perturbation {name!r}: making it at level {level_text(level)} raised {failure(err)}") from None
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
