"""One run of a study, as a worker does it: frames in, method run, outputs written, scores made.

The worker reuses the route's rendered frames and draws the odometry for (noise level, seed), the
sensor's noise for (sensor, seed) and the perturbations for (perturbation, seed) on the fly,
exactly as `longslam simulate` would write them, so a run matches `simulate` + `run`.
It returns a JSON-ready record that the parent stores in the results database.
"""

from __future__ import annotations

import json
import shutil
import socket
import traceback
from pathlib import Path
from typing import Any

from longslam.core.jsonable import json_default
from longslam.core.odometry_noise import get_noise
from longslam.io.sequence import SequenceReader
from longslam.run.depth_delay import run_frames_in_step
from longslam.run.engine import run_into_folder
from longslam.run.folder import RECORD, RUN_FILES
from longslam.run.measurements import RunMeasurements
from longslam.sim.perturbations import parse_entry
from longslam.sim.perturbations.stream import perturbed_frames
from longslam.sim.sensors import get_sensor
from longslam.sim.sensors.stream import camera_motions, sensed_frames
from longslam.sim.simulate import frames_with_odometry, noisy_odometry
from longslam.slam.api import Result
from longslam.slam.catalog import choose_method
from longslam.study.prepare import render_once
from longslam.study.record import OK, RunRecord
from longslam.study.run_scores import TruthLoader, score_run
from longslam.study.spec import RunSpec


def _json_default(value: Any) -> Any:
    # A record must always be written, so anything else is kept as its repr.
    try:
        return json_default(value)
    except TypeError:
        return repr(value)


def to_json(record: RunRecord) -> str:
    """JSON text of a record; numpy values become numbers, anything else unknown its repr."""
    return json.dumps(record.to_dict(), default=_json_default)


def from_json(text: str) -> RunRecord:
    return RunRecord.from_dict(json.loads(text))


def error_record(err: BaseException) -> RunRecord:
    """The record of a run that raised."""
    return RunRecord.failed(
        f"{type(err).__name__}: {err}",
        traceback="".join(traceback.format_exception(err)),
        host=socket.gethostname(),
    )


def execute_run(
    spec: RunSpec, run_dir: str | Path, load_truth: TruthLoader | None = None, progress: bool = False
) -> RunRecord:
    """Do the run and write its folder `run_dir` (replacing an unfinished one). Returns its record.

    `load_truth` gives the world's ground-truth occupancy grid and the mask of observed walls;
    it is called only for a method that builds a grid, after the run (so not in its memory).
    """
    camera = spec.camera_settings()
    rendered = render_once(spec.route_object(), camera, spec.follower_settings())
    reader = SequenceReader(rendered)
    truth = reader.ground_truth
    assert truth is not None, "a rendered sequence always has ground truth"
    odometry = noisy_odometry(truth, get_noise(spec.noise), spec.seed, camera.camera_height)
    sensor = get_sensor(spec.sensor_name)
    perturbations = parse_entry(spec.perturbation_name)

    run_dir = Path(run_dir)
    if run_dir.exists():  # from a run whose record never reached the database
        shutil.rmtree(run_dir)
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    frames = frames_with_odometry(reader, odometry)
    motions = camera_motions(truth) if not sensor.is_ideal or perturbations else []
    if not sensor.is_ideal:
        frames = sensed_frames(frames, sensor, spec.seed, motions)
    if perturbations:
        frames = perturbed_frames(frames, perturbations, spec.seed, truth.timestamps, motions)
    about: dict[str, Any] = {
        "sequence": str(rendered),
        "route": spec.route,
        "noise": spec.noise,
        "seed": spec.seed,
        "label": spec.method,
    }
    if spec.camera_name:
        about["camera"] = spec.camera_name
    if spec.sensor:
        about["sensor"] = spec.sensor
    if spec.perturbation:
        about["perturbation"] = spec.perturbation
    if spec.depth_delay is not None:  # after the perturbations: it undoes a known depth-offset
        frames = run_frames_in_step(frames, spec.depth_delay, f"study {spec.study}", about)
    records: list[RunRecord] = []

    def score_and_record(tmp: Path, result: Result, measurements: RunMeasurements) -> None:
        scores = score_run(result, measurements, truth, spec.align, load_truth, spec.map_tolerance_cells)
        figures = measurements.to_dict()
        del figures["rss_samples"]
        record = RunRecord(
            OK,
            **scores,
            measurements=figures,
            host=socket.gethostname(),
            files={kind: name for kind, name in RUN_FILES.items() if (tmp / name).is_file()},
        )
        (tmp / RECORD).write_text(to_json(record) + "\n", encoding="utf-8", errors="surrogateescape")
        records.append(record)

    # The study file's values are typed (TOML): checked as such, once, here in the run's process.
    method = choose_method(spec.method_name, spec.params, typed=True)
    run_into_folder(run_dir, method, frames, reader, about, progress=progress, before_rename=score_and_record)
    return records[0]
