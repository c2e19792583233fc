"""A study's results as the report reads them: the runs in the database, in the study's order."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from longslam.errors import InputError
from longslam.study.database import DB_NAME, ResultsDB, check_results_tables
from longslam.study.spec import DEFAULT_CAMERA


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
    def row_cameras(self) -> list[str | None]:
        """The cameras a method's rows are split into: each camera, or [None] for all runs at once."""
        return list(self.cameras) if self.by_camera else [None]

    def camera_folder(self, camera: str) -> str:
        """The camera's part of the study's folders: its name for named cameras ([cameras.NAME]),
        "" for the one camera of a [camera] study (whose folders have no camera in them)."""
        return camera if self.config.get("cameras") else ""

    def values(self, method: str, route: str, noise: str, column: str, camera: str | None = None) -> list[float]:
        """A database column of the successful runs of (method, route, noise); of one camera's
        runs if `camera` is given."""
        return [r[column] for r in self.ok if (r["method"], r["route"], r["noise"]) == (method, route, noise)
                and r[column] is not None and on_camera(r, camera)]


def on_camera(run: dict[str, Any], camera: str | None) -> bool:
    """Whether a run is one of `camera`'s (every run is, for camera None)."""
    return camera is None or run.get("camera_name", DEFAULT_CAMERA) == camera


def runs_anchor(route: str, noise: str, method: str, camera: str | None = None) -> str:
    """The HTML id of a (route, camera, noise, method) group's first row in the table of every run:
    'runs/' and the runs' key without the seed (an id may hold anything but white space)."""
    parts = [route] + ([camera] if camera else []) + [noise, method]
    return "runs/" + "/".join(re.sub(r"\s+", "_", p) for p in parts)


def _ordered(first: list[str], seen: list[str]) -> list[str]:
    out = [x for x in first if x in seen]
    return out + sorted(set(seen) - set(out))


def load_results(out: str | Path) -> StudyResults:
    out = Path(out)
    path = out / DB_NAME
    if not path.is_file():
        raise InputError(f"{out} holds no study results ({DB_NAME} is missing); run `longslam study FILE --out {out}` first")
    check_results_tables(path)
    with ResultsDB(path) as db:
        config = db.study() or {}
        runs = db.runs()
    ok = [r for r in runs if r["status"] == "ok"]
    routes = _ordered([r["name"] for r in config.get("routes", [])], [r["route"] for r in runs])
    noise = _ordered(list(config.get("noise", [])), [r["noise"] for r in runs])
    methods = _ordered([m["label"] for m in config.get("methods", [])], [r["method"] for r in runs])
    cameras = _ordered(list(config.get("cameras", {})), [r["camera_name"] for r in runs]) or [DEFAULT_CAMERA]
    return StudyResults(out, config, runs, ok, routes, noise, methods, cameras)
