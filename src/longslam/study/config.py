"""Study files: a TOML file naming the world, routes, noise levels, methods, seeds and camera.

    name = "quick"                  # optional; default the file's stem
    world = "university"            # optional; default university; or a mesh file relative to this
                                    # file, or { mesh = "b.glb", floor = 0.0, units = "mm", up = "y",
                                    # places = "places.json" }
    routes = ["demo"]               # route names, or waypoint files relative to this file
    noise = ["small", "large"]      # odometry noise levels
    methods = "all"                 # every registered method (`command` only with its [params.command]),
                                    # or a list: ["odometry", "keyframe"]
    seeds = 2                       # a count (seeds 0..n-1) or a list: [0, 1]
    align = "none"                  # alignment for APE/RPE and map quality: none, se3, sim3
    map_tolerance_cells = 2         # map quality: occupied cells count as matched within this

    sensors = ["ideal", "kinect-v1"] # optional: sensor models, an axis of the study (default: ideal
                                    # alone, with no sensor in the run keys and folders)
    perturbations = ["none", "drop=0.1", "drop=0.3", "blur=0.02+exposure=2"]
                                    # optional: perturbations after the sensor model, NAME[=LEVEL],
                                    # several joined by '+', or none; an axis of the study (default:
                                    # none, with no perturbation in the run keys and folders)
    depth_delay = 0.1               # optional: seconds the depth lags the colour (negative: leads),
                                    # as `longslam run --depth-delay`: every run's depth is moved
                                    # back in step by the odometry (default: none; the delay is in
                                    # the run keys and folders)

    [camera]                        # optional: width, height, fov, max_depth, camera_height
    width = 320

    [cameras.qvga]                  # or instead of [camera]: several named cameras, an axis of
    width = 320                     # the study (each route rendered once per camera)
    [cameras.vga]
    width = 640
    height = 480

    [follower]                      # optional: the path follower's settings
    linear_speed = 1.5

    [params.keyframe]               # parameter overrides of a method in the list
    max_features = 500

    [variants.keyframe-small]       # an extra entry: a method under its own label and parameters
    method = "keyframe"
    params = { max_features = 200 }

Every mistake is a `StudyConfigError` naming the file, the key and the valid values.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from longslam.core.errors import InputError, UnknownNameError
from longslam.core.odometry_noise import NOISE_LEVELS
from longslam.core.settings import from_mapping
from longslam.core.suggest import did_you_mean
from longslam.core.textfile import read_text
from longslam.eval.align import ALIGN_MODES
from longslam.sim.camera import CAMERA_KEYS, CameraSettings
from longslam.sim.follower import FollowerSettings
from longslam.sim.routes import ROUTES, Route, get_route, is_route_name, load_route_file
from longslam.world.reference import same_world, world_label, world_ref

TOP_KEYS = (
    "name",
    "world",
    "routes",
    "noise",
    "methods",
    "seeds",
    "align",
    "map_tolerance_cells",
    "camera",
    "cameras",
    "follower",
    "params",
    "variants",
    "sensors",
    "repeats",
    "perturbations",
    "depth_delay",
)
REQUIRED_KEYS = ("routes", "noise", "methods", "seeds")
FOLLOWER_KEYS = tuple(f.name for f in fields(FollowerSettings))
VARIANT_KEYS = ("method", "params")
# A study planning more runs than this is a typo (seeds = 1000000000), not an experiment: at a few
# seconds a run on the smallest route it would take days, and its plan alone fills the memory.
MAX_RUNS = 100_000
# A camera's name is a folder of the study (runs/<route>/<camera>/...) and a column of the report.
CAMERA_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


class StudyConfigError(InputError):
    """A study file that cannot be used; the message names the file, the key and what is valid."""


@dataclass(frozen=True)
class MethodEntry:
    """One column of the study: a registered method under a label, with its parameters."""

    label: str
    method: str
    params: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class CameraEntry:
    """One named camera of a study's `[cameras.NAME]` axis."""

    name: str
    settings: CameraSettings


@dataclass(frozen=True)
class StudyConfig:
    name: str
    world: str  # a world reference: a registered name, or a mesh file's (longslam.world.reference)
    routes: tuple[Route, ...]
    noise: tuple[str, ...]
    methods: tuple[MethodEntry, ...]
    seeds: tuple[int, ...]
    camera: CameraSettings = CameraSettings()  # the study's one camera, or the first of `cameras`
    follower: FollowerSettings = FollowerSettings()
    align: str = "none"
    map_tolerance_cells: float = 2.0
    source: str = ""  # the study file
    # The [cameras.*] axis; empty for a study with one (unnamed) [camera], whose runs keep the
    # keys and folders they had before cameras could be named.
    cameras: tuple[CameraEntry, ...] = ()
    # The `sensors` axis; empty for a study without one (the ideal sensor), whose runs keep the
    # keys and folders they had before sensors were an axis.
    sensors: tuple[str, ...] = ()
    # The `perturbations` axis, each entry's canonical text (`drop=0.1`, `none`); empty for a study
    # without one, whose runs keep the keys, folders and hashes they had before perturbations.
    perturbations: tuple[str, ...] = ()
    # Seconds each run's depth is moved back in step by (`longslam run --depth-delay`); None: as read.
    depth_delay: float | None = None
    # Runs of each cell: a non-deterministic system (threads that race) gives a distribution, and
    # the report gives its median, spread and failure rate. 1 keeps a study's keys and hashes.
    repeats: int = 1

    def camera_axis(self) -> list[tuple[str, CameraSettings]]:
        """(name, settings) of each camera of the study; the name is "" for a `[camera]` study."""
        if self.cameras:
            return [(c.name, c.settings) for c in self.cameras]
        return [("", self.camera)]

    def sensor_axis(self) -> list[str]:
        """The sensor of each run: the study's sensors, or [""] (the ideal sensor) without them."""
        return list(self.sensors) or [""]

    def perturbation_axis(self) -> list[str]:
        """The perturbation of each run: the study's entries, or [""] (none) without them."""
        return list(self.perturbations) or [""]

    @property
    def run_count(self) -> int:
        """How many runs the study plans: one per route, camera, noise level, method and seed."""
        return (
            len(self.routes)
            * len(self.camera_axis())
            * len(self.sensor_axis())
            * len(self.perturbation_axis())
            * len(self.noise)
            * len(self.methods)
            * len(self.seeds)
            * self.repeats
        )

    def grid_text(self) -> str:
        """The grid and its run count, counted without planning a run: '2 routes x 4 noise levels x
        3 methods x 5 seeds = 120 runs' (a camera axis shown when the study names cameras)."""
        parts = [(len(self.routes), "route")] + ([(len(self.cameras), "camera")] if self.cameras else [])
        parts += [(len(self.sensors), "sensor")] if self.sensors else []
        parts += [(len(self.perturbations), "perturbation")] if self.perturbations else []
        parts += [(len(self.noise), "noise level"), (len(self.methods), "method"), (len(self.seeds), "seed")]
        parts += [(self.repeats, "repeat")] if self.repeats > 1 else []
        return " x ".join(f"{n} {w}{'' if n == 1 else 's'}" for n, w in parts) + f" = {self.run_count} runs"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (stored in the results database)."""
        described = {
            "name": self.name,
            "world": self.world,
            "routes": [r.to_dict() for r in self.routes],
            "noise": list(self.noise),
            "methods": [asdict(m) for m in self.methods],
            "seeds": list(self.seeds),
            "camera": asdict(self.camera),
            "follower": asdict(self.follower),
            "align": self.align,
            "map_tolerance_cells": self.map_tolerance_cells,
            "source": self.source,
        }
        if self.cameras:  # absent for one [camera], so such a study's stored description is unchanged
            described["cameras"] = {c.name: asdict(c.settings) for c in self.cameras}
        if self.sensors:  # absent without the axis, as cameras are
            described["sensors"] = list(self.sensors)
        if self.perturbations:  # absent without the axis, as sensors are
            described["perturbations"] = list(self.perturbations)
        if self.repeats != 1:  # absent for one run per cell, as cameras are
            described["repeats"] = self.repeats
        if self.depth_delay is not None:  # absent without one, as repeats are
            described["depth_delay"] = self.depth_delay
        return described


def _valid(values) -> str:
    return ", ".join(str(v) for v in values)


def _unknown_key(name: str, valid) -> str:
    from longslam.core.suggest import did_you_mean

    return f"unknown key{did_you_mean(name, [str(v) for v in valid], quote=False)}; valid keys: {_valid(valid)}"


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)) and math.isfinite(value)


class _Reader:
    def __init__(self, path: Path):
        self.path = path

    def error(self, key: str, message: str) -> StudyConfigError:
        return StudyConfigError(f"study file {self.path}: {key}: {message}")

    def strings(self, data: dict, key: str, what: str, hint: str = "", valid: str = "") -> Iterator[tuple[str, str]]:
        """(item key, item) of `data[key]`, a non-empty list of strings (one string is a list of one);
        `hint` says what each string is, `valid` lists the valid ones."""
        value = data[key]
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, list) or not value:
            raise self.error(key, f"expected a non-empty list of {what}s{hint}; got {value!r}{valid}")
        for i, item in enumerate(value):
            if not isinstance(item, str):
                raise self.error(f"{key}[{i}]", f"expected a {what} (a string{hint}), got {item!r}")
            yield f"{key}[{i}]", item

    def string_list(self, data: dict, key: str, valid: list[str] | None, what: str) -> list[str]:
        out: list[str] = []
        listed = f"; valid values: {_valid(valid)}" if valid else ""
        for i, (_, item) in enumerate(self.strings(data, key, what, valid=listed)):
            if valid is not None and item not in valid:
                raise self.error(
                    f"{key}[{i}]",
                    f"unknown {what} {item!r}{did_you_mean(item, valid)}; " f"valid values: {_valid(valid)}",
                )
            if item in out:
                raise self.error(f"{key}[{i}]", f"{item!r} is listed twice")
            out.append(item)
        return out

    def table(self, data: dict, key: str, valid_keys) -> dict:
        value = data.get(key, {})
        if not isinstance(value, dict):
            raise self.error(key, f"expected a table ([{key}]), got {value!r}")
        for sub in value:
            if sub not in valid_keys:
                raise self.error(f"{key}.{sub}", _unknown_key(sub, valid_keys))
        return value


def load_study(path: str | Path, methods_available: list[str] | None = None) -> StudyConfig:
    """Read and check a study file. `methods_available` defaults to the registered methods."""
    path = Path(path)
    text = read_text(path, "study file", error=StudyConfigError)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise StudyConfigError(f"study file {path} is not valid TOML: {err}") from None
    if methods_available is None:
        from longslam.slam.catalog import method_names

        methods_available = method_names()
    return parse_study(data, path, methods_available)


def parse_study(data: dict, path: Path, methods_available: list[str]) -> StudyConfig:
    r = _Reader(path)
    for key in data:
        if key not in TOP_KEYS:
            raise r.error(key, _unknown_key(key, TOP_KEYS))
    for key in REQUIRED_KEYS:
        if key not in data:
            raise r.error(key, f"missing; a study file needs {_valid(REQUIRED_KEYS)}")

    name = data.get("name", path.stem)
    if not isinstance(name, str) or not name.strip():
        raise r.error("name", f"expected a non-empty string, got {name!r}")

    try:
        world = world_ref(data.get("world", "university"), base=path.parent, what=f"study file {path}: world")
    except InputError as err:
        raise StudyConfigError(str(err)) from None

    routes = _routes(r, data, world, path)
    noise = r.string_list(data, "noise", NOISE_LEVELS.names(), "noise level")
    methods = _methods(r, data, methods_available)
    seeds = _seeds(r, data["seeds"])

    align = data.get("align", "none")
    if align not in ALIGN_MODES:
        raise r.error("align", f"unknown alignment {align!r}; valid values: {_valid(ALIGN_MODES)}")
    tolerance = data.get("map_tolerance_cells", 2)
    if not _is_number(tolerance) or tolerance < 0:
        raise r.error("map_tolerance_cells", f"expected a number of cells >= 0, got {tolerance!r}")

    if "camera" in data and "cameras" in data:
        raise r.error(
            "camera",
            "a study has either one [camera] or named [cameras.NAME] tables, not both; "
            "move [camera] into a [cameras.NAME] table, or drop [cameras]",
        )
    cameras = _cameras(r, data) if "cameras" in data else []
    camera = cameras[0].settings if cameras else _camera(r, r.table(data, "camera", CAMERA_KEYS), "camera")
    follower_table = r.table(data, "follower", FOLLOWER_KEYS)
    try:
        follower = from_mapping(FollowerSettings, follower_table, "follower", typed=True)
    except InputError as err:
        raise r.error("follower", str(err)) from None

    sensors = _sensors(r, data) if "sensors" in data else []
    perturbations = _perturbations(r, data) if "perturbations" in data else []
    repeats = _repeats(r, data.get("repeats", 1))
    depth_delay = _depth_delay(r, data["depth_delay"]) if "depth_delay" in data else None
    config = StudyConfig(
        name=name,
        world=world,
        routes=tuple(routes),
        noise=tuple(noise),
        methods=tuple(methods),
        seeds=tuple(seeds),
        camera=camera,
        follower=follower,
        align=align,
        map_tolerance_cells=float(tolerance),
        source=str(path),
        cameras=tuple(cameras),
        sensors=tuple(sensors),
        repeats=repeats,
        perturbations=tuple(perturbations),
        depth_delay=depth_delay,
    )
    if config.run_count > MAX_RUNS:
        raise StudyConfigError(
            f"study file {path}: {config.grid_text()}, more than a study may plan ({MAX_RUNS}); "
            "fewer seeds, routes, noise levels or methods"
        )
    return config


def _camera(r: _Reader, table: dict, key: str) -> CameraSettings:
    try:
        return from_mapping(CameraSettings, {CAMERA_KEYS[k]: v for k, v in table.items()}, "camera setting", typed=True)
    except InputError as err:
        # The settings layer names the field (hfov_deg); the file has the user's key (fov).
        bad = re.match(r"camera setting: parameter (\w+)=", str(err))
        if bad:
            fields = {field: name for name, field in CAMERA_KEYS.items()}
            raise r.error(f"{key}.{fields.get(bad.group(1), bad.group(1))}", str(err)[bad.end() :]) from None
        raise r.error(key, str(err)) from None


def _cameras(r: _Reader, data: dict) -> list[CameraEntry]:
    value = data["cameras"]
    example = "e.g. [cameras.qvga] with width = 320, height = 240"
    if not isinstance(value, dict) or not value:
        raise r.error("cameras", f"expected one table per camera ({example}), got {value!r}")
    entries: list[CameraEntry] = []
    for name, table in value.items():
        key = f"cameras.{name}"
        if not CAMERA_NAME.fullmatch(name):
            raise r.error(
                key,
                f"a camera name is a folder of the study: 1 to 64 letters, digits, '_', '.' or '-', "
                f"starting with a letter or digit; got {name!r}",
            )
        if not isinstance(table, dict):
            raise r.error(key, f"expected a table of camera settings ({_valid(CAMERA_KEYS)}), got {table!r}")
        for sub in table:
            if sub not in CAMERA_KEYS:
                raise r.error(f"{key}.{sub}", _unknown_key(sub, CAMERA_KEYS))
        settings = _camera(r, table, key)
        for other in entries:
            if other.name.lower() == name.lower():  # one folder on a case-insensitive file system
                raise r.error(key, f"differs from cameras.{other.name} only in case; choose another name")
            if other.settings == settings:  # the same runs twice under two names
                raise r.error(key, f"has the same settings as cameras.{other.name}; give each camera its own")
        entries.append(CameraEntry(name, settings))
    return entries


def _sensors(r: _Reader, data: dict) -> list[str]:
    from longslam.sim.sensors import get_sensor, sensor_names

    names = sensor_names()
    sensors = r.string_list(data, "sensors", names, "sensor")
    for i, name in enumerate(sensors):
        try:  # a plugin whose module is missing or whose model cannot be made: before the study starts
            get_sensor(name)
        except InputError as err:
            raise r.error(f"sensors[{i}]", str(err)) from None
        if not CAMERA_NAME.fullmatch(name):  # a sensor's name is a folder of the study too
            raise r.error(
                f"sensors[{i}]",
                f"sensor {name!r} cannot be a folder name: 1 to 64 letters, digits, '_', '.' "
                "or '-', starting with a letter or digit",
            )
    return sensors


def _perturbations(r: _Reader, data: dict) -> list[str]:
    from longslam.sim.perturbations import canonical, parse_entry

    expected = ": none, or NAME[=LEVEL] joined by '+' (see `longslam list`)"
    entries: list[str] = []
    for key, item in r.strings(data, "perturbations", "perturbation", expected):
        try:
            text = canonical(parse_entry(item))  # every level named: drop and drop=0.1 are one folder
        except InputError as err:
            raise r.error(key, str(err)) from None
        if text in entries:
            raise r.error(key, f"{item!r} is listed twice (as {text!r})")
        entries.append(text)
    return entries


def _routes(r: _Reader, data: dict, world: str, path: Path) -> list[Route]:
    valid = (
        f"a route name ({_valid(ROUTES.names())}), a long route (NAME-xN, tour-<L>km[-seed<S>]) or a "
        "waypoint file relative to the study file"
    )
    routes: list[Route] = []
    for key, item in r.strings(data, "routes", "route", f": {valid}"):
        if is_route_name(item):
            try:
                # A registered route keeps its own world (refused below if not the study's); a tour
                # is planned in the study's.
                route = get_route(item, None if item in ROUTES else world)
            except InputError as err:
                raise r.error(key, str(err)) from None
        else:
            file = Path(item) if Path(item).is_absolute() else path.parent / item
            if not file.is_file():
                raise r.error(key, f"{item!r} is neither a route nor a file; valid values: {valid}")
            try:
                route = load_route_file(file, world)
            except InputError as err:
                raise r.error(key, str(err)) from None
        if not same_world(route.world, world):
            raise r.error(
                key,
                f"route {route.name!r} is in world {world_label(route.world)!r}, the study in {world_label(world)!r}",
            )
        if any(route.name == other.name for other in routes):
            raise r.error(key, f"a route named {route.name!r} is listed twice (route files are named by their stem)")
        routes.append(route)
    return routes


MAX_REPEATS = 1000


def _repeats(r: _Reader, value: Any) -> int:
    if not _is_int(value) or not 1 <= value <= MAX_REPEATS:
        raise r.error("repeats", f"expected a whole number of runs per cell, 1 to {MAX_REPEATS}, got {value!r}")
    return int(value)


def _depth_delay(r: _Reader, value: Any) -> float:
    from longslam.run.depth_delay import check_depth_delay

    if not _is_number(value):
        raise r.error("depth_delay", f"expected the seconds the depth lags the colour, a number, got {value!r}")
    try:
        return check_depth_delay(float(value), "depth_delay")
    except InputError as err:
        raise r.error("depth_delay", str(err).removeprefix("depth_delay: ")) from None


def _seeds(r: _Reader, value: Any) -> list[int]:
    from longslam.sim.simulate import MAX_SEED, seed_problem

    if _is_int(value):
        if value < 1:
            raise r.error("seeds", f"a count of seeds must be at least 1, got {value}")
        if value > MAX_RUNS:  # before range(): a huge count is refused, not allocated
            raise r.error("seeds", f"a count of {value} seeds is more runs than a study may plan ({MAX_RUNS})")
        return list(range(value))
    if not isinstance(value, list) or not value or not all(_is_int(s) and s >= 0 for s in value):
        raise r.error(
            "seeds", f"expected a count (e.g. 5) or a non-empty list of integers >= 0 (e.g. [0, 1]), got {value!r}"
        )
    for i, seed in enumerate(value):
        if seed > MAX_SEED:
            raise r.error(f"seeds[{i}]", f"seed {seed}: {seed_problem(seed)}")
    if len(set(value)) != len(value):
        raise r.error("seeds", f"a seed is listed twice in {value!r}")
    return list(value)


def _methods(r: _Reader, data: dict, available: list[str]) -> list[MethodEntry]:
    value = data["methods"]
    if value == "all":
        names = list(available)
    else:
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, list):
            raise r.error("methods", f'expected "all" or a list of method names; valid values: {_valid(available)}')
        data = dict(data, methods=value)
        variant_labels = data.get("variants", {}) if isinstance(data.get("variants"), dict) else {}
        for i, item in enumerate(value):
            if isinstance(item, str) and item not in available and item in variant_labels:
                raise r.error(
                    f"methods[{i}]",
                    f"{item!r} is a variant ([variants.{item}]); a variant runs beside the "
                    "methods listed without being listed itself: remove it from methods",
                )
        names = r.string_list(data, "methods", available, "method") if value else []
    params = r.table(data, "params", names)
    if value == "all":  # not a method that needs parameters the file does not give (`command`'s program)
        from longslam.slam.catalog import runnable_alone

        names = [
            name
            for name in names
            if runnable_alone(name, params.get(name) if isinstance(params.get(name), dict) else None)
        ]
    entries = []
    for name in names:
        overrides = params.get(name, {})
        if not isinstance(overrides, dict):
            raise r.error(f"params.{name}", f"expected a table of parameters, got {overrides!r}")
        entries.append(MethodEntry(name, name, dict(overrides)))
    variants = r.table(data, "variants", _AnyKey())
    for label, variant in variants.items():
        key = f"variants.{label}"
        if not isinstance(variant, dict):
            raise r.error(key, f"expected a table with keys {_valid(VARIANT_KEYS)}")
        for sub in variant:
            if sub not in VARIANT_KEYS:
                raise r.error(f"{key}.{sub}", _unknown_key(sub, VARIANT_KEYS))
        method = variant.get("method")
        if method not in available:
            raise r.error(
                f"{key}.method",
                f"unknown method {method!r}{did_you_mean(str(method), available)}; "
                f"valid values: {_valid(available)}",
            )
        if label in names or any(e.label == label for e in entries):
            raise r.error(key, f"label {label!r} is already a method of this study; choose another label")
        overrides = variant.get("params", {})
        if not isinstance(overrides, dict):
            raise r.error(f"{key}.params", f"expected a table of parameters, got {overrides!r}")
        entries.append(MethodEntry(label, method, dict(overrides)))
    if not entries:
        raise r.error("methods", f'no method to run; valid values: "all" or a list of {_valid(available)}')
    return entries


class _AnyKey:
    def __contains__(self, item: object) -> bool:
        return True


def check_method_params(config: StudyConfig) -> None:
    """Check each method's parameters against its config, so a bad parameter fails before any run.

    Only the configs are built, not the methods (nothing is opened or allocated). A third-party
    method without a config type takes its parameters as they are, and checks them at its runs.
    """
    from longslam.slam.catalog import check_params, get_spec

    for entry in config.methods:
        key = f"variants.{entry.label}.params" if entry.label != entry.method else f"params.{entry.method}"
        try:
            check_params(entry.method, entry.params, typed=True)
            get_spec(entry.method).check_required(entry.params)
        except UnknownNameError as err:
            raise StudyConfigError(f"study file {config.source}: methods: {err}") from None
        except InputError as err:
            raise StudyConfigError(f"study file {config.source}: {key}: {err}") from None
