"""A study's `depth_delay`: every run's depth moved back in step by the odometry, as `longslam run
--depth-delay` does; checked where the study file is read, in the run keys and hashes (unchanged
without it), in a folder's identity, and end to end (slow)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers.studies import ROUTE, axis_study_file, write_study

from longslam.core.errors import InputError
from longslam.study.config import StudyConfigError, load_study
from longslam.study.database import DB_NAME, ResultsDB
from longslam.study.driver import run_study
from longslam.study.identity import check_same_study, differences
from longslam.study.spec import plan_runs

def test_a_depth_delay_is_in_each_runs_key_and_hash_and_absent_without_one(tmp_path):
    plain = load_study(axis_study_file(tmp_path), ["odometry"])
    assert plain.depth_delay is None and "depth_delay" not in plain.to_dict()
    assert [r.key for r in plan_runs(plain)] == ["tiny/large/odometry/seed-0", "tiny/large/odometry/seed-1"]
    delayed = load_study(axis_study_file(tmp_path, "depth_delay = 0.1"), ["odometry"])
    assert delayed.depth_delay == 0.1 and delayed.to_dict()["depth_delay"] == 0.1
    runs = plan_runs(delayed)
    assert [r.key for r in runs] == ["tiny/depth-delay=0.1/large/odometry/seed-0", "tiny/depth-delay=0.1/large/odometry/seed-1"]
    assert {r.depth_delay for r in runs} == {0.1}
    assert not {r.config_hash for r in runs} & {r.config_hash for r in plan_runs(plain)}
    leading = load_study(axis_study_file(tmp_path, "depth_delay = -0.05"), ["odometry"])
    assert plan_runs(leading)[0].key == "tiny/depth-delay=-0.05/large/odometry/seed-0"


@pytest.mark.parametrize("value", ['"0.1"', "true", "0.7", "nan"])
def test_a_bad_depth_delay_names_the_key_and_what_was_expected(tmp_path, value):
    with pytest.raises(StudyConfigError, match=r"depth_delay.*(seconds the depth lags the colour)") as err:
        load_study(axis_study_file(tmp_path, f"depth_delay = {value}"), ["odometry"])
    assert "study.toml" in str(err.value) and "\n" not in str(err.value)


def test_a_folder_holds_one_depth_delay_even_when_extended(tmp_path):
    plain = load_study(axis_study_file(tmp_path), ["odometry"]).to_dict()
    delayed = load_study(axis_study_file(tmp_path, "depth_delay = 0.1"), ["odometry"]).to_dict()
    assert differences(plain, delayed) == ["depth_delay"]
    out = tmp_path / "out"
    out.mkdir()
    with ResultsDB(out / DB_NAME) as db:
        db.set_study(plain)
    with pytest.raises(InputError, match="a folder holds one depth delay"):
        check_same_study(out, delayed, extend=True)
    with pytest.raises(InputError, match="depth_delay"):
        check_same_study(out, delayed, extend=False)


@pytest.mark.slow  # renders a short route and runs a study
def test_a_study_with_a_depth_delay_moves_each_runs_depth_and_records_it(tmp_path, render_cache, monkeypatch):
    monkeypatch.setenv("LONGSLAM_CACHE", str(render_cache))
    (tmp_path / "tiny.txt").write_text(ROUTE)
    study = write_study(tmp_path, "delayed", ["keyframe"], ["large"], [0],
                        'perturbations = ["depth-offset=0.1"]\ndepth_delay = 0.1')
    out = tmp_path / "out"
    summary = run_study(load_study(study), out, jobs=1, progress=False)
    assert summary.failed == 0 and summary.ran == 1
    run = out / "runs" / "tiny" / "depth-offset=0.1" / "depth-delay=0.1" / "large" / "keyframe" / "seed-0"
    stats = json.loads((run / "stats.json").read_text())
    assert stats["depth_delay_s"] == 0.1 and stats["perturbation"] == "depth-offset=0.1"


def test_the_shipped_depth_delay_study_tells_the_methods_the_perturbations_offset():
    config = load_study(Path(__file__).resolve().parents[2] / "studies" / "degradation-depth-delay.toml")
    assert config.perturbations == ("depth-offset=0.1",) and config.depth_delay == 0.1
