"""The sensor models longslam knows: the built-in ones and third-party ones from entry points.

A package adds its own model in its pyproject.toml, the way methods are added::

    [project.entry-points."longslam.sensors"]
    dusty = "mypackage.sensors:Dusty"

where the target is a `SensorModel` instance, or a class (or any callable) that makes one with no
arguments. The entry point's name is the model's name in `--sensor`, a study's `sensors` and
`meta.json`.
"""

from __future__ import annotations

from typing import Any

from longslam.core.errors import InputError
from longslam.core.registry import Registry, failure
from longslam.sim.sensors.base import SensorModel
from longslam.sim.sensors.kinect import KinectV1
from longslam.sim.sensors.realsense import RealSenseD435

ENTRY_POINT_GROUP = "longslam.sensors"
IDEAL = "ideal"


def _as_model(name: str, loaded: Any) -> SensorModel:
    """A plugin's entry point: a SensorModel, or a class (any callable) making one."""
    entry = SENSORS.plugin(name)
    where = f"sensor {name!r}: entry point {entry.value if entry else name}"
    if not isinstance(loaded, SensorModel) and not callable(loaded):
        raise InputError(
            f"{where} is a {type(loaded).__name__}; "
            "expected a longslam.sim.sensors.SensorModel (or a class making one)"
        )
    try:
        model = loaded if isinstance(loaded, SensorModel) else loaded()
    except (Exception, SystemExit) as err:
        raise InputError(
            f"sensor {name!r}: making the model from entry point "
            f"{entry.value if entry else name} raised {failure(err)}"
        ) from None
    if not isinstance(model, SensorModel):
        raise InputError(
            f"{where} gave a {type(model).__name__}; "
            "expected a longslam.sim.sensors.SensorModel (or a class making one)"
        )
    if model.name != name:
        # The name in meta.json and the study is the entry point's, so the frame draws are keyed by it.
        object.__setattr__(model, "name", name)
    return model


SENSORS: Registry[SensorModel] = Registry("sensor", ENTRY_POINT_GROUP, _as_model)
for _model in (SensorModel(), KinectV1(), RealSenseD435()):
    SENSORS.register(_model.name, _model)
BUILTIN = tuple(SENSORS.builtin_names())


def sensor_names() -> list[str]:
    """Every sensor model by name: the built-in ones, then the plugins'."""
    return SENSORS.names()


def sensor_problem(name: str) -> str | None:
    """Why a plugin's sensor cannot load, found without importing it, or None."""
    return SENSORS.problem(name)


def get_sensor(name: str) -> SensorModel:
    return SENSORS.get(name)
