"""The sensor models longslam knows: the built-in ones and third-party ones from entry points.

A package adds its own model in its pyproject.toml, the way methods are added::

    [project.entry-points."longslam.sensors"]
    dusty = "mypackage.sensors:Dusty"

where the target is a `SensorModel` instance, or a class (or any callable) that makes one with no
arguments. The entry point's name is the model's name in `--sensor`, a study's `sensors` and
`meta.json`.
"""

from __future__ import annotations

import importlib.util
import sys
from functools import lru_cache
from importlib.metadata import entry_points

from longslam.core.errors import InputError, UnknownNameError
from longslam.sim.sensors.base import SensorModel
from longslam.sim.sensors.kinect import KinectV1
from longslam.sim.sensors.realsense import RealSenseD435

ENTRY_POINT_GROUP = "longslam.sensors"
IDEAL = "ideal"
BUILTIN: dict[str, SensorModel] = {IDEAL: SensorModel(), "kinect-v1": KinectV1(), "realsense-d435": RealSenseD435()}


@lru_cache(maxsize=8)
def _plugins(search_path: tuple[str, ...]) -> dict:
    # Keyed on sys.path, as the methods' catalogue is: a package put on the path later is found.
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP) if ep.name not in BUILTIN}


def sensor_names() -> list[str]:
    """Every sensor model by name: the built-in ones, then the plugins'."""
    return list(BUILTIN) + sorted(_plugins(tuple(sys.path)))


def failure(err: BaseException) -> str:
    """What a plugin's code raised, in one short line."""
    text = " ".join(str(err).split())[:200]
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def sensor_problem(name: str) -> str | None:
    """Why a plugin's sensor cannot load, found without running its code (its module is looked
    for, not imported), or None; so `longslam list` does not list a missing module as a sensor."""
    plugins = _plugins(tuple(sys.path))
    if name not in plugins:
        return None
    module = plugins[name].module
    try:
        found = importlib.util.find_spec(module)
    except (ImportError, ValueError):  # a parent package missing, or an empty name
        found = None
    return None if found is not None else f"its module {module} is not installed"


def get_sensor(name: str) -> SensorModel:
    if name in BUILTIN:
        return BUILTIN[name]
    plugins = _plugins(tuple(sys.path))
    if name not in plugins:
        raise UnknownNameError("sensor", name, sensor_names())
    entry = plugins[name].value
    # A plugin's code runs here: whatever it raises (SystemExit too) is its failure, named.
    try:
        loaded = plugins[name].load()
    except (Exception, SystemExit) as err:
        raise InputError(f"sensor {name!r}: entry point {entry} cannot be loaded ({failure(err)})") from None
    if not isinstance(loaded, SensorModel) and not callable(loaded):
        raise InputError(f"sensor {name!r}: entry point {entry} is a {type(loaded).__name__}; "
                         "expected a longslam.sim.sensors.SensorModel (or a class making one)")
    try:
        model = loaded if isinstance(loaded, SensorModel) else loaded()
    except (Exception, SystemExit) as err:
        raise InputError(f"sensor {name!r}: making the model from entry point {entry} raised {failure(err)}") from None
    if not isinstance(model, SensorModel):
        raise InputError(f"sensor {name!r}: entry point {entry} gave a {type(model).__name__}; "
                         "expected a longslam.sim.sensors.SensorModel (or a class making one)")
    if model.name != name:
        # The name in meta.json and the study is the entry point's, so the frame draws are keyed by it.
        object.__setattr__(model, "name", name)
    return model
