"""What the harness measures of one run, typed: the figures behind a run folder's stats.json."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from longslam.io.atomic import name_final_folder


@dataclass
class RunMeasurements:
    """One run's figures. `stats.json` is `to_dict()`: the fields in this order, then what the run was
    given (`about`: the sequence, its intrinsics, a study's route, noise, seed...)."""

    longslam_version: str
    longslam_commit: str | None  # git HEAD of the source, "+dirty" with changes; None outside a checkout
    method: str
    params: dict[str, Any]  # as the user gave them
    config: dict[str, Any]  # every parameter the method ran with
    frames: int
    sequence_duration_s: float
    wall_time_s: float  # first frame to the end of `finish`, observer and reading ahead included
    method_time_s: float  # the method's own time: every step plus finish
    finish_time_s: float
    # CPU time of the whole process, every thread, from the first frame to the end of `finish`: a
    # method with threads of its own (ORB-SLAM3's mapping and loop closing) works beside `step`,
    # which the wall-clock figures do not see. Reading ahead (and an observer) count too.
    process_cpu_time_s: float
    step_time_mean_s: float
    step_time_p95_s: float
    step_time_max_s: float
    # The mean step over each tenth of the frames: whether the per-frame cost grows with the route.
    step_time_mean_s_by_tenth: list[float]
    # Simulated seconds per second of the method's own processing (reading frames excluded).
    real_time_factor: float | None  # None for a sequence that spans no time (one frame)
    # The CPU the run was denied: how long its threads (and any child processes') were ready to run
    # but waited for a core (run/process_tree.py), and that wait's share of wait plus CPU time.
    cpu_wait_s: float
    cpu_wait_share: float
    starved: bool
    tree_cpu_time_s: float
    # Whose threads waited: [CPU s, wait s] by thread name, the 8 that waited longest.
    cpu_wait_by_thread: dict[str, list[float]]
    child_processes: int
    # The process's own peak, or with child processes (a program run as a method) the largest sum
    # of the tree's resident memory seen in one sample; raised again by writing the run's files.
    peak_rss_bytes: int
    baseline_rss_bytes: int
    rss_samples: list[tuple[int, int]]  # (frames done, resident bytes)
    method_stats: dict[str, Any]  # what the method reports of itself (Result.stats)
    observer_time_s: float | None = None  # a live view's time, kept out of the figures above
    about: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON-ready figures, as stats.json holds them."""
        figures = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "about"}
        if self.observer_time_s is None:
            del figures["observer_time_s"]
        return {**figures, **self.about}

    def in_folder(self, tmp: Path, out: Path) -> RunMeasurements:
        """These figures with every path into the temporary run folder `tmp` (a method's database,
        say) named by where it will be once the folder is renamed to `out`."""
        return RunMeasurements(
            **{f.name: name_final_folder(getattr(self, f.name), tmp, out) for f in dataclasses.fields(self)}
        )
