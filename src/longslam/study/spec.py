"""The runs of a study: one per (route, camera, sensor, perturbation, noise level, method, seed), as plain
picklable data."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from itertools import product
from typing import Any

from longslam.sim.camera import CameraSettings
from longslam.sim.follower import FollowerSettings
from longslam.sim.perturbations.parse import NONE
from longslam.sim.routes import Route
from longslam.sim.sensors.catalog import IDEAL
from longslam.study.config import StudyConfig

# The name of the one camera of a [camera] study (and of every run recorded before cameras had names).
DEFAULT_CAMERA = "camera"


@dataclass(frozen=True)
class RunSpec:
    """Everything a worker needs to do one run, on this machine or another."""

    study: str
    world: str  # a world reference: a name, or a mesh file's with its content hash
    route: str
    waypoints: tuple  # the route's waypoints: (x, y) or place names
    noise: str
    method: str  # the label in the study (a method name, or a variant's label)
    method_name: str  # the registered method
    params: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    camera: dict[str, Any] = field(default_factory=dict)  # CameraSettings fields
    follower: dict[str, Any] = field(default_factory=dict)  # FollowerSettings fields
    align: str = "none"
    map_tolerance_cells: float = 2.0
    camera_name: str = ""  # a [cameras.NAME] of the study; "" for the one camera of a [camera] study
    sensor: str = ""  # a sensor of the study's `sensors`; "" for a study without them (the ideal sensor)
    repeat: int = 0  # which run of its cell, 0 to the study's repeats - 1
    # An entry of the study's `perturbations` (canonical: `drop=0.1`, `none`); "" for a study
    # without them (no perturbation).
    perturbation: str = ""
    depth_delay: float | None = None  # the study's `depth_delay`: seconds the depth is moved back in step by

    @property
    def key(self) -> str:
        """Unique name of the run within a study; also its folder under `runs/`."""
        # A [camera] study's runs keep the keys they had before cameras could be named, so an
        # old study folder resumes into the same rows and folders.
        camera = f"{self.camera_name}/" if self.camera_name else ""
        sensor = f"{self.sensor}/" if self.sensor else ""
        sensor += f"{self.perturbation}/" if self.perturbation else ""
        sensor += f"depth-delay={self.depth_delay:g}/" if self.depth_delay is not None else ""
        # A cell's first run keeps the key it had before studies repeated cells.
        repeat = f"-repeat-{self.repeat}" if self.repeat else ""
        return f"{self.route}/{camera}{sensor}{self.noise}/{self.method}/seed-{self.seed}{repeat}"

    @property
    def config_hash(self) -> str:
        """Changes whenever anything that affects the run's result changes."""
        from longslam.world.reference import world_identity

        described = self.describe()
        described.pop("study")  # renaming a study does not change its runs
        # Nor does naming or renaming its camera: the settings are hashed, and the name is in the
        # key. This also keeps every hash of a study from before cameras could be named.
        described.pop("camera_name")
        # The ideal sensor, named or not, is the frames as rendered: the hashes from before sensors.
        if described["sensor"] in ("", IDEAL):
            described.pop("sensor")
        # No perturbation, named or not, is the frames as the sensor delivers them: the hashes from
        # before perturbations.
        if described["perturbation"] in ("", NONE):
            described.pop("perturbation")
        if not described["repeat"]:  # a cell's first run: the hashes from before repeats
            described.pop("repeat")
        if described["depth_delay"] is None:  # depth as read: the hashes from before depth delays
            described.pop("depth_delay")
        described["world"] = world_identity(self.world)  # a mesh by its content: moving the file is no change
        text = json.dumps(described, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def describe(self) -> dict[str, Any]:
        data = asdict(self)
        data["waypoints"] = self.route_object().waypoints_json()
        return data

    def route_object(self) -> Route:
        return Route.from_json(self.route, self.world, list(self.waypoints))

    def camera_settings(self) -> CameraSettings:
        return CameraSettings(**self.camera)

    def follower_settings(self) -> FollowerSettings:
        return FollowerSettings(**self.follower)

    @property
    def sensor_name(self) -> str:
        """The sensor model the run sees its frames through."""
        return self.sensor or IDEAL

    @property
    def perturbation_name(self) -> str:
        """The perturbations the run sees its frames through, as text: `none` for none."""
        return self.perturbation or NONE


def plan_runs(config: StudyConfig) -> list[RunSpec]:
    """Every run of the study, seed by seed (and repeat by repeat): a study stopped early has whole
    seeds done."""
    runs = []
    for seed, repeat in product(config.seeds, range(config.repeats)):
        for route in config.routes:
            for (camera_name, camera), sensor, perturbation, noise in product(
                config.camera_axis(), config.sensor_axis(), config.perturbation_axis(), config.noise
            ):
                for entry in config.methods:
                    runs.append(
                        RunSpec(
                            study=config.name,
                            world=config.world,
                            route=route.name,
                            waypoints=tuple(route.waypoints),
                            noise=noise,
                            method=entry.label,
                            method_name=entry.method,
                            params=dict(entry.params),
                            seed=seed,
                            camera=asdict(camera),
                            follower=asdict(config.follower),
                            align=config.align,
                            map_tolerance_cells=config.map_tolerance_cells,
                            camera_name=camera_name,
                            sensor=sensor,
                            repeat=repeat,
                            perturbation=perturbation,
                            depth_delay=config.depth_delay,
                        )
                    )
    return runs
