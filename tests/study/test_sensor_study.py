"""Sensors end to end on a short route with a small camera: `simulate --sensor` writes the
model's frames and names it in meta.json, the same frames a study's worker makes on the fly; a
study with a sensors axis runs, records and reports each sensor. Slow: they render a route."""

from __future__ import annotations

import json
import os
import sqlite3

import numpy as np
import pytest
from helpers.studies import ROUTE as TINY_ROUTE, write_study

from longslam.cli.main import main
from longslam.io.sequence import SequenceReader
from longslam.sim.simulate import frames_with_odometry, simulate
from longslam.sim.camera import CameraSettings
from longslam.core.odometry_noise import get_noise
from longslam.sim.routes import Route
from longslam.sim.sensors import get_sensor
from longslam.sim.sensors.stream import camera_motions, sensed_frames
from longslam.study.config import load_study
from longslam.study.database import DB_NAME
from longslam.study.driver import run_study

pytestmark = pytest.mark.slow  # renders routes and runs a study over sensors

SMALL = CameraSettings(width=64, height=48)
ROUTE = Route("short", "university", ((20.0, 31.25), (26.0, 31.25), "junction_a"))


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    root = tmp_path_factory.mktemp("sensor-cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("LONGSLAM_CACHE", str(root / "cache"))
        yield root


def test_simulate_with_a_sensor_writes_its_frames_and_names_it(cache):
    ideal = simulate(ROUTE, get_noise("large"), 1, cache / "ideal", camera=SMALL, progress=False)
    kinect = simulate(ROUTE, get_noise("large"), 1, cache / "kinect", camera=SMALL, progress=False, sensor="kinect-v1")
    meta = json.loads((kinect / "meta.json").read_text())
    assert meta["sensor"] == "kinect-v1" and meta["sensor_model"]["axial_b"] == 0.0019 and meta["seed"] == 1
    assert json.loads((ideal / "meta.json").read_text())["sensor"] == "ideal"
    first = sorted((ideal / "depth").iterdir())[5].name
    rendered = next(p for p in (cache / "cache").iterdir() if p.is_dir())
    # The ideal sequence links the cached frames; the Kinect's are its own.
    assert os.stat(ideal / "depth" / first).st_ino == os.stat(rendered / "depth" / first).st_ino
    assert os.stat(kinect / "depth" / first).st_ino != os.stat(rendered / "depth" / first).st_ino
    a, b = SequenceReader(ideal), SequenceReader(kinect)
    assert len(a) == len(b) and (b.odometry.poses == a.odometry.poses).all()
    holes_ideal = np.mean([(a.frame(i).depth == 0).mean() for i in range(0, len(a), 5)])
    holes_kinect = np.mean([(b.frame(i).depth == 0).mean() for i in range(0, len(b), 5)])
    assert holes_kinect > holes_ideal + 0.02  # range, shadows, grazing walls
    assert not (a.frame(5).rgb == b.frame(5).rgb).all()
    # A study's worker makes the same frames on the fly (to the 0.2 mm of the 16-bit PNGs).
    reader = SequenceReader(rendered)
    live = list(sensed_frames(frames_with_odometry(reader, a.odometry), get_sensor("kinect-v1"), 1,
                              camera_motions(reader.ground_truth)))
    for i in (0, 7, len(b) - 1):
        assert (live[i].rgb == b.frame(i).rgb).all()
        np.testing.assert_allclose(live[i].depth, b.frame(i).depth, atol=1.01 / 5000)


def test_cli_simulate_sensor(cache, capsys):
    (cache / "short.txt").write_text("20 31.25\n26 31.25\n")
    code = main(["simulate", "--route", str(cache / "short.txt"), "--noise", "small", "--sensor", "realsense-d435",
                 "--width", "64", "--height", "48", "--out", str(cache / "cli")])
    assert code == 0
    assert json.loads((cache / "cli" / "meta.json").read_text())["sensor"] == "realsense-d435"


def test_a_study_with_a_sensors_axis_runs_records_and_reports_each_sensor(cache):
    (cache / "tiny.txt").write_text(TINY_ROUTE)
    study = write_study(cache, "sensor-axis", ["odometry", "keyframe"], ["large"], [0],
                        'sensors = ["ideal", "kinect-v1"]')
    out = cache / "study-out"
    summary = run_study(load_study(study), out, jobs=1, progress=False)
    assert summary.failed == 0 and summary.ran == 4
    with sqlite3.connect(out / DB_NAME) as conn:
        rows = {key: (sensor, ate) for key, sensor, ate in conn.execute("SELECT key, sensor, ate FROM runs")}
    assert set(rows) == {f"tiny/{s}/large/{m}/seed-0" for s in ("ideal", "kinect-v1") for m in ("odometry", "keyframe")}
    assert rows["tiny/kinect-v1/large/keyframe/seed-0"][0] == "kinect-v1"
    assert (out / "runs" / "tiny" / "kinect-v1" / "large" / "keyframe" / "seed-0" / "trajectory.txt").is_file()
    # Dead reckoning does not look at the images: the same under both sensors.
    assert rows["tiny/ideal/large/odometry/seed-0"][1] == rows["tiny/kinect-v1/large/odometry/seed-0"][1]
    stats = json.loads((out / "runs" / "tiny" / "kinect-v1" / "large" / "keyframe" / "seed-0" / "stats.json").read_text())
    assert stats["sensor"] == "kinect-v1"
    report = (out / "report.md").read_text()
    assert "| method | sensor | metric |" in report and "| kinect-v1 |" in report
    assert "sensors ideal, kinect-v1" in report
