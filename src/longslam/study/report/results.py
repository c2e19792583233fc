"""A study's results as the report reads them: the runs in the database, in the study's order."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from longslam.core.errors import InputError
from longslam.sim.perturbations.parse import NONE
from longslam.sim.sensors.catalog import IDEAL
from longslam.study.database import DB_NAME, ResultsDB, check_results_tables
from longslam.study.spec import DEFAULT_CAMERA


@dataclass(frozen=True)
class RowGroup:
    """The runs of one camera, sensor and/or perturbation, in a study whose tables are split by
    them (None: that axis is not split)."""

    camera: str | None = None
    sensor: str | None = None
    perturbation: str | None = None

    @property
    def parts(self) -> list[str]:
        return [part for part in (self.camera, self.sensor, self.perturbation) if part is not None]

    def __str__(self) -> str:
        return ", ".join(self.parts)


@dataclass
class StudyResults:
    out: Path
    config: dict[str, Any]
    runs: list[dict[str, Any]]  # every recorded run
    ok: list[dict[str, Any]]
    routes: list[str]
    noise: list[str]
    methods: list[str]
    cameras: list[str] = field(default_factory=lambda: [DEFAULT_CAMERA])
    sensors: list[str] = field(default_factory=lambda: [IDEAL])
    perturbations: list[str] = field(default_factory=lambda: [NONE])

    @property
    def columns(self) -> list[tuple[str, str]]:
        present = {(r["route"], r["noise"]) for r in self.runs}
        return [(route, noise) for route in self.routes for noise in self.noise if (route, noise) in present]

    @property
    def by_camera(self) -> bool:
        """Whether the tables and figures are split by camera: the study has more than one (even
        if only one has runs so far, so the report keeps its shape while a study fills in)."""
        return len(self.cameras) > 1 or len(self.config.get("cameras", {})) > 1

    @property
    def by_sensor(self) -> bool:
        """Whether the tables and figures are split by sensor: the study has more than one."""
        return len(self.sensors) > 1 or len(self.config.get("sensors", [])) > 1

    @property
    def by_perturbation(self) -> bool:
        """Whether the tables and figures are split by perturbation: the study has more than one."""
        return len(self.perturbations) > 1 or len(self.config.get("perturbations", [])) > 1

    @property
    def _split(self) -> bool:
        return self.by_camera or self.by_sensor or self.by_perturbation

    @property
    def row_cameras(self) -> list[RowGroup | None]:
        """The groups a method's rows are split into: each camera, sensor and/or perturbation, or
        [None] for all runs at once."""
        if not self._split:
            return [None]
        cameras: list[str | None] = list(self.cameras) if self.by_camera else [None]
        sensors: list[str | None] = list(self.sensors) if self.by_sensor else [None]
        perturbations: list[str | None] = list(self.perturbations) if self.by_perturbation else [None]
        return [RowGroup(c, s, p) for c in cameras for s in sensors for p in perturbations]

    @property
    def group_title(self) -> str:
        """The heading of the tables' group column: 'camera', 'sensor', 'camera, sensor',
        'perturbation'..."""
        return ", ".join(
            name
            for name, split in (
                ("camera", self.by_camera),
                ("sensor", self.by_sensor),
                ("perturbation", self.by_perturbation),
            )
            if split
        )

    def group_of(self, run: dict[str, Any]) -> RowGroup | None:
        """The row group a run belongs to (see `row_cameras`)."""
        if not self._split:
            return None
        return RowGroup(
            run.get("camera_name", DEFAULT_CAMERA) if self.by_camera else None,
            (run.get("sensor") or IDEAL) if self.by_sensor else None,
            (run.get("perturbation") or NONE) if self.by_perturbation else None,
        )

    def camera_of(self, group: "RowGroup | str | None") -> str:
        """The camera of a row group (the study's first when the group does not split cameras)."""
        camera = group.camera if isinstance(group, RowGroup) else group
        return camera or self.cameras[0]

    def camera_folder(self, camera: str) -> str:
        """The camera's part of the study's folders: its name for named cameras ([cameras.NAME]),
        "" for the one camera of a [camera] study (whose folders have no camera in them)."""
        return camera if self.config.get("cameras") else ""

    def values(
        self, method: str, route: str, noise: str, column: str, camera: "RowGroup | str | None" = None
    ) -> list[float]:
        """A database column of the successful runs of (method, route, noise); of one camera's
        runs if `camera` is given."""
        return [
            r[column]
            for r in self.ok
            if (r["method"], r["route"], r["noise"]) == (method, route, noise)
            and r[column] is not None
            and on_camera(r, camera)
        ]


def on_camera(run: dict[str, Any], camera: "RowGroup | str | None") -> bool:
    """Whether a run is one of `camera`'s: a camera's name, or a row group of a camera, a sensor
    and/or a perturbation (every run is, for None)."""
    if camera is None:
        return True
    if isinstance(camera, RowGroup):
        return (
            (camera.camera is None or run.get("camera_name", DEFAULT_CAMERA) == camera.camera)
            and (camera.sensor is None or (run.get("sensor") or IDEAL) == camera.sensor)
            and (camera.perturbation is None or (run.get("perturbation") or NONE) == camera.perturbation)
        )
    return run.get("camera_name", DEFAULT_CAMERA) == camera


def runs_anchor(route: str, noise: str, method: str, camera: "RowGroup | str | None" = None) -> str:
    """The HTML id of a (route, camera and/or sensor, noise, method) group's first row in the table
    of every run: 'runs/' and the runs' key without the seed (an id may hold anything but white
    space)."""
    group = [p for p in camera.parts if p] if isinstance(camera, RowGroup) else ([camera] if camera else [])
    parts = [route] + group + [noise, method]
    return "runs/" + "/".join(re.sub(r"\s+", "_", p) for p in parts)


def _ordered(first: list[str], seen: list[str]) -> list[str]:
    out = [x for x in first if x in seen]
    return out + sorted(set(seen) - set(out))


def load_results(out: str | Path) -> StudyResults:
    out = Path(out)
    path = out / DB_NAME
    if out.is_file():  # the study file given in place of the folder its study wrote
        raise InputError(
            f"{out} is a file, not a study folder; give the folder a study wrote "
            f"(`longslam study {out} --out FOLDER`, then `longslam report FOLDER`)"
        )
    if not path.is_file():
        raise InputError(
            f"{out} holds no study results ({DB_NAME} is missing); run `longslam study FILE --out {out}` first"
        )
    check_results_tables(path)
    with ResultsDB(path) as db:
        config = db.study() or {}
        runs = db.runs()
    ok = [r for r in runs if r["status"] == "ok"]
    routes = _ordered([r["name"] for r in config.get("routes", [])], [r["route"] for r in runs])
    noise = _ordered(list(config.get("noise", [])), [r["noise"] for r in runs])
    methods = _ordered([m["label"] for m in config.get("methods", [])], [r["method"] for r in runs])
    cameras = _ordered(list(config.get("cameras", {})), [r["camera_name"] for r in runs]) or [DEFAULT_CAMERA]
    sensors = _ordered(list(config.get("sensors", [])), [r.get("sensor") or IDEAL for r in runs]) or [IDEAL]
    perturbations = _ordered(list(config.get("perturbations", [])), [r.get("perturbation") or NONE for r in runs]) or [
        NONE
    ]
    return StudyResults(out, config, runs, ok, routes, noise, methods, cameras, sensors, perturbations)
