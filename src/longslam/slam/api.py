"""The interface every SLAM method implements: frames in, a pose per frame out, then a result.

A method is described by a `MethodSpec`: its name, the dataclass of its parameters and a `build`
function. The catalogue (`slam/catalog.py`) lists the specs; methods never import it, so checking
a study's parameters builds a config, not a method.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Frame, Intrinsics
from longslam.core.gridmap import GridMap
from longslam.core.settings import from_mapping
from longslam.core.trajectory import Trajectory

if TYPE_CHECKING:  # a type only: importing the graph would load GTSAM into every run
    from longslam.slam.graph import PoseGraph


@dataclass(frozen=True)
class Table:
    """Numbers that grow with the route (a row per loop constraint, per keyframe...): the run
    folder gets them as NAME.csv, so that stats.json stays small however long the route."""

    columns: tuple[str, ...]
    rows: np.ndarray  # (N, len(columns))

    def __post_init__(self) -> None:
        rows = np.asarray(self.rows, dtype=np.float64).reshape(-1, len(self.columns))
        object.__setattr__(self, "rows", rows)

    def column(self, name: str) -> np.ndarray:
        return self.rows[:, self.columns.index(name)]


EVENT_KINDS = ("tracking_lost", "new_map", "loop", "merge", "relocalized", "global_ba")


@dataclass(frozen=True)
class Event:
    """Something that explains a run's course, at a frame or over frames: tracking lost (first to
    last untracked frame), a new map started, a loop closed, maps merged, a relocalisation, a
    global bundle adjustment started. The run folder gets them as events.csv and `longslam
    diagnose` names the place of each."""

    kind: str  # one of EVENT_KINDS
    first_frame: int
    last_frame: int  # = first_frame for an event at one frame
    first_t: float
    last_t: float
    detail: str = ""  # a short note (a map id, the console's line)

    def __post_init__(self) -> None:
        if self.kind not in EVENT_KINDS:
            raise ValueError(f"event kind {self.kind!r}: expected one of {', '.join(EVENT_KINDS)}")


@dataclass
class Result:
    trajectory: Trajectory  # final estimate, one pose per frame (after any optimisation)
    online: Trajectory  # what `step` returned at each frame
    grid: GridMap | None = None  # 2D occupancy map in the world frame
    cloud: np.ndarray | None = None  # (N, 3) float points of a 3D map, if the method builds one
    # Counts (nodes, submaps, loop closures accepted/rejected...) and bytes held by each map part.
    stats: dict[str, Any] = field(default_factory=dict)
    # Per-loop, per-node... rows, by file name (see `Table`): "loops" is every constraint the
    # method added to the front end (frame i, frame j, j's base pose in i's: dx, dy m, dyaw rad).
    tables: dict[str, Table] = field(default_factory=dict)
    events: list[Event] = field(default_factory=list)  # in frame order (see `Event`)


@runtime_checkable
class Method(Protocol):
    """A SLAM method. Two more parts are optional, read through the functions below (a method
    without them gets their defaults):

    - `images_every_frame: tuple[str, ...]`, the images ("rgb", "depth") that `step` looks at in
      every frame: the run engine then decodes them for the next frames on a second thread while
      the method works (run/read_ahead.py). Default (): images are read when used.
    - `work_ahead(frame) -> None`: work on a frame that depends on its images alone (a
      measured noise, a grey image, corners tracked from the frame before). When the engine
      reads images ahead it calls this on its own thread, for every frame in order, after the
      frame's images are decoded and before `step(frame)`; the method keeps what it worked out
      for `step` (by frame index) and `step` computes it itself for a frame without it, with
      the same result. It must not touch what `step` changes. Default: none.
    - `graph: PoseGraph | None`, the method's pose graph: the live view draws its loop and
      registration edges. Default None.
    """

    name: str

    def step(self, frame: Frame) -> np.ndarray:
        """Take one frame; return the 4x4 camera-in-world pose estimate for it, online."""
        ...

    def finish(self) -> Result:
        """Final trajectory for every frame, maps and stats."""
        ...


@runtime_checkable
class Closable(Protocol):
    """A method that holds threads or a native system (a wrapped C++ SLAM system) defines `close`:
    the engine calls it when a run stops before `finish` has returned (an error, Ctrl-C), so that
    nothing of the method outlives its run. `finish` itself must release what it holds."""

    def close(self) -> None: ...


def wanted_images(method: Method) -> tuple[str, ...]:
    """The images the method's `step` reads in every frame (see `Method`)."""
    return tuple(getattr(method, "images_every_frame", ()))


def ahead_work(method: Method) -> Callable[[Frame], None] | None:
    """The method's `work_ahead`, or None if it has none (see `Method`)."""
    work = getattr(method, "work_ahead", None)
    return work if callable(work) else None


def pose_graph(method: Method) -> PoseGraph | None:
    """The method's pose graph, or None if it keeps none (see `Method`)."""
    return getattr(method, "graph", None)


@dataclass(frozen=True)
class MethodContext:
    """What a method may know before the first frame: nothing about the simulator."""

    intrinsics: Intrinsics
    max_depth: float | None
    output_dir: str | None = None  # where a method may keep files (e.g. a database)
    # The file that receives what native code prints to the process's stdout and stderr during
    # the run (run/console.py), set by the engine when the run has a folder; a method wrapping a
    # C++ system may read it (its log lines are often the only report of what happened inside).
    console_log: str | None = None


def frame_odometry(frame: Frame, method: str) -> np.ndarray:
    """The frame's odometry pose as float64, or a clear error for methods fed by odometry
    (real TUM sequences come without it)."""
    if frame.odometry is None:
        raise InputError(
            f"frame {frame.index} (t={frame.timestamp:.6f}) has no odometry pose; the {method!r} method "
            f"needs a sequence with odometry.txt"
        )
    return np.array(frame.odometry, dtype=np.float64)


@dataclass(frozen=True)
class MethodSpec:
    """A method under its name: its parameters' dataclass and how to build it from a config.

    `config_type` None means the method takes its parameters as a plain dict: `build` gets the
    user's values as they are, unchecked.
    """

    name: str
    config_type: type | None
    build: Callable[[MethodContext, Any], Method]
    summary: str = ""
    # Work a method needs done once per machine before its runs (a download, a vocabulary built
    # into the cache), given its config. The demo and studies call it in their own process before
    # the runs start, so that no run's time or peak memory carries it; `longslam run` lets the
    # first run do it.
    prepare: Callable[[Any], None] | None = None
    # Cores one run keeps busy. A method with threads of its own (ORB-SLAM3's tracking, local
    # mapping and loop closing) declares them: a study's executors schedule by cores, so its run
    # never shares them with another run (`--jobs` counts cores).
    threads: int = 1
    # Whether the method takes frames at the sequence's own rate (a real-time system): starved of
    # CPU, it loses work (frames, keyframes), not only time.
    real_time: bool = False
    # Whether the same frames give the same result. A system whose threads race is a distribution:
    # a study repeats its cells (`repeats`) and the report gives the median, spread and failures.
    deterministic: bool = True
    # Parameters without a usable default (the program the `command` method runs): a run must give
    # them, so "every method" (the demo's, a study's `methods = "all"`) leaves the method out
    # unless its parameters are given there.
    required: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not (isinstance(self.threads, int) and self.threads >= 1):
            raise ValueError(f"method {self.name!r}: threads={self.threads!r}; expected a whole number of cores >= 1")

    def missing(self, params: Mapping[str, Any] | None = None) -> list[str]:
        """The required parameters that `params` leaves unset or empty."""
        params = params or {}
        return [name for name in self.required if params.get(name) in (None, "")]

    def check_required(self, params: Mapping[str, Any] | None = None) -> None:
        """InputError naming each required parameter `params` leaves unset."""
        missing = self.missing(params)
        if missing:
            raise InputError(
                f"method {self.name!r} needs the parameter{'s' if len(missing) > 1 else ''} "
                f"{', '.join(missing)} (`--param {missing[0]}=...`, or [params.{self.name}] in a study "
                f"file; `longslam list --params {self.name}` describes them)"
            )

    def cores(self, available: int) -> int:
        """The cores a run takes on a machine (or executor) of `available` cores: all of them, for
        a method that needs more."""
        return max(1, min(self.threads, available))

    def prepare_for(self, params: Mapping[str, Any] | None = None) -> None:
        """Do the method's once-per-machine work for `params` (nothing for most methods)."""
        if self.prepare is not None:
            self.prepare(self.config(params))

    def config(self, params: Mapping[str, Any] | None = None, typed: bool = False, base: Any = None) -> Any:
        """The checked config for `params` (unknown keys and bad values refused) over the defaults,
        or over the config `base`; no method built. `typed`: the values come from a typed file (a
        study's TOML), where a quoted number is a mistake rather than command-line text to convert."""
        params = dict(params or {})
        if self.config_type is None:
            return {**(base or {}), **params}
        return from_mapping(self.config_type, params, f"method {self.name!r}", base=base, typed=typed)

    def choose(self, params: Mapping[str, Any] | None = None, typed: bool = False) -> MethodChoice:
        """The method with `params` checked once, where they enter (see `MethodChoice`)."""
        return MethodChoice(self, dict(params or {}), self.config(params, typed))

    def create(self, context: MethodContext, params: Mapping[str, Any] | None = None) -> Method:
        return self.build(context, self.config(params))


@dataclass(frozen=True)
class MethodChoice:
    """A method and the parameters a user gave it, checked once where they enter (the command line,
    a run's config.toml, a study file): the spec, the parameters as given (a run folder records
    them) and the typed config the method is built with. The engine takes this, never raw text."""

    spec: MethodSpec
    params: dict[str, Any]
    config: Any

    @property
    def name(self) -> str:
        return self.spec.name

    def over(self, params: Mapping[str, Any], typed: bool = False) -> MethodChoice:
        """These parameters with `params` over them (the command line's over a config file's)."""
        if not params:
            return self
        return MethodChoice(self.spec, {**self.params, **params}, self.spec.config(params, typed, base=self.config))
