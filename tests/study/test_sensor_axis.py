"""Sensors as an axis of a study: the study file's `sensors`, the run keys and hashes, the
database's sensor column, and the report's sensor column (without running a method)."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers.studies import axis_study_file

from longslam.study.config import StudyConfigError, load_study
from longslam.study.database import ResultsDB
from longslam.study.record import OK, RunRecord
from longslam.study.report import StudyResults, accuracy_table, map_table
from longslam.study.report.render import table_html, table_markdown
from longslam.study.report.results import RowGroup, on_camera
from longslam.study.spec import plan_runs

def test_sensors_are_an_axis_with_their_own_run_folders(tmp_path):
    config = load_study(axis_study_file(tmp_path, 'sensors = ["ideal", "kinect-v1", "realsense-d435"]'), ["odometry"])
    assert config.sensors == ("ideal", "kinect-v1", "realsense-d435")
    assert config.grid_text() == "1 route x 3 sensors x 1 noise level x 1 method x 2 seeds = 6 runs"
    assert config.to_dict()["sensors"] == ["ideal", "kinect-v1", "realsense-d435"]
    runs = plan_runs(config)
    assert [r.key for r in runs[:3]] == [
        "tiny/ideal/large/odometry/seed-0", "tiny/kinect-v1/large/odometry/seed-0", "tiny/realsense-d435/large/odometry/seed-0",
    ]
    assert [r.sensor_name for r in runs[:3]] == ["ideal", "kinect-v1", "realsense-d435"]
    assert len({r.config_hash for r in runs}) == 6


def test_the_ideal_sensor_is_the_runs_of_a_study_without_sensors(tmp_path):
    plain = load_study(axis_study_file(tmp_path), ["odometry"])
    assert plain.sensors == () and "sensors" not in plain.to_dict()
    assert [r.key for r in plan_runs(plain)] == ["tiny/large/odometry/seed-0", "tiny/large/odometry/seed-1"]
    assert plan_runs(plain)[0].sensor_name == "ideal"
    named = load_study(axis_study_file(tmp_path, 'sensors = ["ideal", "kinect-v1"]'), ["odometry"])
    ideal = {r.seed: r.config_hash for r in plan_runs(named) if r.sensor == "ideal"}
    kinect = {r.seed: r.config_hash for r in plan_runs(named) if r.sensor == "kinect-v1"}
    # The same frames, so the same hashes as before sensors were an axis; another sensor differs.
    assert ideal == {r.seed: r.config_hash for r in plan_runs(plain)}
    assert not set(kinect.values()) & set(ideal.values())


@pytest.mark.parametrize("sensors, key, needle", [
    ('sensors = ["ideal", "kinect"]', "sensors[1]", "unknown sensor 'kinect' (did you mean 'kinect-v1'?); valid values: ideal, kinect-v1, realsense-d435"),
    ('sensors = ["kinect-v1", "kinect-v1"]', "sensors[1]", "'kinect-v1' is listed twice"),
    ("sensors = []", "sensors", "expected a non-empty list of sensor"),
    ("sensors = [1]", "sensors[0]", "expected a sensor (a string)"),
])
def test_a_bad_sensors_list_names_the_key_and_the_valid_values(tmp_path, sensors, key, needle):
    path = axis_study_file(tmp_path, sensors)
    with pytest.raises(StudyConfigError) as err:
        load_study(path, ["odometry"])
    message = str(err.value)
    assert message.startswith(f"study file {path}: {key}: ") and needle in message and "\n" not in message


def test_the_database_has_a_sensor_column(tmp_path):
    config = load_study(axis_study_file(tmp_path, 'sensors = ["ideal", "kinect-v1"]'), ["odometry"])
    plain = load_study(axis_study_file(tmp_path), ["odometry"])
    with ResultsDB(tmp_path / "results.sqlite") as db:
        db.record(plan_runs(config)[1], RunRecord(OK, metrics={"ate": 0.3}), "runs/x")
        db.record(plan_runs(plain)[0], RunRecord(OK, metrics={"ate": 0.2}), "runs/y")
        rows = {r["key"]: r["sensor"] for r in db.runs()}
        db._conn.execute("UPDATE runs SET sensor = NULL WHERE key = 'tiny/large/odometry/seed-0'")  # as an old row
        old = {r["key"]: r["sensor"] for r in db.runs()}
    assert rows == {"tiny/kinect-v1/large/odometry/seed-0": "kinect-v1", "tiny/large/odometry/seed-0": "ideal"}
    assert old["tiny/large/odometry/seed-0"] == "ideal"


def _runs():
    return [
        {"key": f"paper-300m/{sensor}/large/odometry/seed-{s}", "method": "odometry", "route": "paper-300m",
         "noise": "large", "seed": s, "status": "ok", "camera_name": "camera", "sensor": sensor,
         "ate": ate + 0.01 * s, "e_trans": 0.01, "e_rot": 0.02, "peak_rss_bytes": 2e8,
         "map_precision": precision, "map_recall": 0.5}
        for s in range(2) for sensor, ate, precision in (("ideal", 0.2, 0.9), ("kinect-v1", 0.5, 0.6))
    ]


def test_the_report_has_a_sensor_column():
    runs = _runs()
    config = {"sensors": ["ideal", "kinect-v1"]}
    results = StudyResults(Path("."), config, runs, runs, ["paper-300m"], ["large"], ["odometry"], ["camera"],
                           ["ideal", "kinect-v1"])
    assert results.row_cameras == [RowGroup(None, "ideal"), RowGroup(None, "kinect-v1")]
    table = accuracy_table(results)
    assert table.group_title == "sensor"
    assert table.row_cameras[:6] == ["ideal"] * 3 + ["kinect-v1"] * 3
    ate = {g: row[0].text for g, (_, metric), row in zip(table.row_cameras, table.row_labels, table.rows) if metric == "ATE [m]"}
    assert ate["ideal"] == "0.205 ± 0.007 (n=2)" and ate["kinect-v1"] == "0.505 ± 0.007 (n=2)"
    markdown = table_markdown(table)
    assert "| method | sensor | metric | paper-300m: large |" in markdown
    assert "|  | kinect-v1 | E_trans |" in markdown
    assert "<th>sensor</th>" in table_html(table)
    quality = map_table(results)
    precision = {g: row[0].text for g, (_, metric), row in zip(quality.row_cameras, quality.row_labels, quality.rows)
                 if metric == "precision"}
    assert precision == {"ideal": "0.900 ± 0.000 (n=2)", "kinect-v1": "0.600 ± 0.000 (n=2)"}


def test_cameras_and_sensors_together_split_the_rows_by_both():
    runs = [dict(r, camera_name=camera) for r in _runs() for camera in ("qvga", "vga")]
    config = {"sensors": ["ideal", "kinect-v1"], "cameras": {"qvga": {}, "vga": {}}}
    results = StudyResults(Path("."), config, runs, runs, ["paper-300m"], ["large"], ["odometry"], ["qvga", "vga"],
                           ["ideal", "kinect-v1"])
    table = accuracy_table(results)
    assert table.group_title == "camera, sensor"
    assert table.row_cameras[:12:3] == ["qvga, ideal", "qvga, kinect-v1", "vga, ideal", "vga, kinect-v1"]
    assert on_camera(runs[0], RowGroup("qvga", "ideal")) and not on_camera(runs[0], RowGroup("vga", "ideal"))


def test_one_sensor_has_no_sensor_column():
    runs = [r for r in _runs() if r["sensor"] == "ideal"]
    results = StudyResults(Path("."), {}, runs, runs, ["paper-300m"], ["large"], ["odometry"])
    assert accuracy_table(results).row_cameras == []
    assert "| method | metric |" in table_markdown(accuracy_table(results))


def test_the_shipped_sensors_study_loads():
    root = Path(__file__).resolve().parents[2]
    config = load_study(root / "studies" / "sensors.toml", ["odometry", "keyframe", "submap", "orbslam3"])
    assert config.sensors == ("ideal", "kinect-v1", "realsense-d435") and config.seeds == (0, 1, 2)
    assert config.grid_text() == "1 route x 3 sensors x 1 noise level x 4 methods x 3 seeds = 36 runs"
