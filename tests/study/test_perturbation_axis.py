"""Perturbations as an axis of a study: the study file's `perturbations`, the run keys, folders
and hashes (unchanged without the axis), the database's perturbation column, the report's
perturbation column, and a folder's study widened by one (without running a method)."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers.studies import axis_study_file

from longslam.study.config import StudyConfigError, load_study
from longslam.study.database import ResultsDB
from longslam.study.identity import differences, merged
from longslam.study.record import OK, RunRecord
from longslam.study.report import StudyResults, accuracy_table
from longslam.study.report.render import table_markdown
from longslam.study.report.results import RowGroup
from longslam.study.report.runs import every_run_table
from longslam.study.spec import plan_runs

def test_perturbations_are_an_axis_with_their_own_run_folders(tmp_path):
    config = load_study(axis_study_file(tmp_path, 'perturbations = ["none", "drop", "drop=0.3", "blur=0.05+exposure=1"]'),
                        ["odometry"])
    assert config.perturbations == ("none", "drop=0.1", "drop=0.3", "blur=0.05+exposure=1")  # every level named
    assert config.grid_text() == "1 route x 4 perturbations x 1 noise level x 1 method x 2 seeds = 8 runs"
    assert config.to_dict()["perturbations"] == list(config.perturbations)
    runs = plan_runs(config)
    assert [r.key for r in runs[:4]] == [
        "tiny/none/large/odometry/seed-0", "tiny/drop=0.1/large/odometry/seed-0", "tiny/drop=0.3/large/odometry/seed-0",
        "tiny/blur=0.05+exposure=1/large/odometry/seed-0",
    ]
    assert len({r.config_hash for r in runs}) == 8


def test_no_perturbation_is_the_runs_of_a_study_without_the_axis(tmp_path):
    plain = load_study(axis_study_file(tmp_path), ["odometry"])
    assert plain.perturbations == () and "perturbations" not in plain.to_dict()
    assert [r.key for r in plan_runs(plain)] == ["tiny/large/odometry/seed-0", "tiny/large/odometry/seed-1"]
    assert plan_runs(plain)[0].perturbation_name == "none"
    named = load_study(axis_study_file(tmp_path, 'perturbations = ["none", "drop=0.2"]'), ["odometry"])
    none = {r.seed: r.config_hash for r in plan_runs(named) if r.perturbation == "none"}
    drop = {r.seed: r.config_hash for r in plan_runs(named) if r.perturbation == "drop=0.2"}
    # The same frames, so the same hashes as before perturbations were an axis; a perturbation differs.
    assert none == {r.seed: r.config_hash for r in plan_runs(plain)}
    assert not set(drop.values()) & set(none.values())


def test_sensors_and_perturbations_together_nest_sensor_then_perturbation(tmp_path):
    config = load_study(axis_study_file(tmp_path, 'sensors = ["ideal", "kinect-v1"]\nperturbations = ["none", "depth-dropout=2"]'),
                        ["odometry"])
    assert [r.key for r in plan_runs(config)[:4]] == [
        "tiny/ideal/none/large/odometry/seed-0", "tiny/ideal/depth-dropout=2/large/odometry/seed-0",
        "tiny/kinect-v1/none/large/odometry/seed-0", "tiny/kinect-v1/depth-dropout=2/large/odometry/seed-0",
    ]


@pytest.mark.parametrize("axis, key, needle", [
    ('perturbations = ["none", "dorp=0.1"]', "perturbations[1]",
     "unknown perturbation 'dorp' (did you mean 'drop'?); valid perturbation names: blur, depth-dropout"),
    ('perturbations = ["drop=2"]', "perturbations[0]",
     "perturbation drop=2: level 2 is out of range; expected a share of frames dropped, > 0 and <= 0.95"),
    ('perturbations = ["drop=x"]', "perturbations[0]", "level 'x' is not a number"),
    ('perturbations = ["drop", "drop=0.1"]', "perturbations[1]", "'drop=0.1' is listed twice (as 'drop=0.1')"),
    ("perturbations = []", "perturbations", "expected a non-empty list of perturbations"),
    ("perturbations = [1]", "perturbations[0]", "expected a perturbation (a string"),
    ('perturbation = ["drop"]', "perturbation", "unknown key (did you mean perturbations?)"),
])
def test_a_bad_perturbations_list_names_the_key_and_what_was_expected(tmp_path, axis, key, needle):
    path = axis_study_file(tmp_path, axis)
    with pytest.raises(StudyConfigError) as err:
        load_study(path, ["odometry"])
    message = str(err.value)
    assert message.startswith(f"study file {path}: {key}: ") and needle in message and "\n" not in message


def test_the_database_has_a_perturbation_column(tmp_path):
    config = load_study(axis_study_file(tmp_path, 'perturbations = ["none", "drop=0.2"]'), ["odometry"])
    plain = load_study(axis_study_file(tmp_path), ["odometry"])
    with ResultsDB(tmp_path / "results.sqlite") as db:
        db.record(plan_runs(config)[1], RunRecord(OK, metrics={"ate": 0.3}), "runs/x")
        db.record(plan_runs(plain)[0], RunRecord(OK, metrics={"ate": 0.2}), "runs/y")
        rows = {r["key"]: r["perturbation"] for r in db.runs()}
        db._conn.execute("UPDATE runs SET perturbation = NULL WHERE key = 'tiny/large/odometry/seed-0'")  # as an old row
        old = {r["key"]: r["perturbation"] for r in db.runs()}
    assert rows == {"tiny/drop=0.2/large/odometry/seed-0": "drop=0.2", "tiny/large/odometry/seed-0": "none"}
    assert old["tiny/large/odometry/seed-0"] == "none"


def test_a_folder_widened_by_perturbations_names_the_difference_and_merges_them(tmp_path):
    old = load_study(axis_study_file(tmp_path, 'perturbations = ["none", "drop=0.1"]'), ["odometry"]).to_dict()
    new = load_study(axis_study_file(tmp_path, 'perturbations = ["drop=0.3"]'), ["odometry"]).to_dict()
    assert differences(old, new) == ["perturbations"]
    assert merged(old, new)["perturbations"] == ["none", "drop=0.1", "drop=0.3"]


def _runs():
    return [
        {"key": f"paper-300m/{p}/large/odometry/seed-{s}", "method": "odometry", "route": "paper-300m",
         "noise": "large", "seed": s, "status": "ok", "camera_name": "camera", "sensor": "ideal", "perturbation": p,
         "ate": ate + 0.01 * s, "e_trans": 0.01, "e_rot": 0.02, "peak_rss_bytes": 2e8, "run_dir": f"runs/{p}/{s}"}
        for s in range(2) for p, ate in (("none", 0.2), ("drop=0.3", 0.6))
    ]


def test_the_report_has_a_perturbation_column():
    runs = _runs()
    config = {"perturbations": ["none", "drop=0.3"]}
    results = StudyResults(Path("."), config, runs, runs, ["paper-300m"], ["large"], ["odometry"], ["camera"],
                           ["ideal"], ["none", "drop=0.3"])
    assert results.row_cameras == [RowGroup(None, None, "none"), RowGroup(None, None, "drop=0.3")]
    table = accuracy_table(results)
    assert table.group_title == "perturbation"
    ate = {g: row[0].text for g, (_, metric), row in zip(table.row_cameras, table.row_labels, table.rows)
           if metric == "ATE [m]" and g}  # "": the paper's published row
    assert ate == {"none": "0.205 ± 0.007 (n=2)", "drop=0.3": "0.605 ± 0.007 (n=2)"}
    assert "| method | perturbation | metric | paper-300m: large |" in table_markdown(table)
    every = every_run_table(results)
    assert every.identity == ["route", "perturbation", "noise", "method", "seed"]
    assert [row.identity[1] for row in every.rows] == ["none", "none", "drop=0.3", "drop=0.3"]
