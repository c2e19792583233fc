"""Rows that grow with the route (loops, nodes) go to NAME.csv in the run folder, not stats.json."""

from __future__ import annotations

import dataclasses

import json

import numpy as np
import pytest

from longslam.core.errors import InputError
from longslam.run.folder import STATS, read_table, write_result, write_table
from longslam.slam.api import Result, Table
from longslam.core.trajectory import Trajectory
from longslam.run.measurements import RunMeasurements


def _result(tables: dict[str, Table]) -> Result:
    poses = np.repeat(np.eye(4)[None], 3, axis=0)
    trajectory = Trajectory(np.arange(3.0), poses)
    return Result(trajectory=trajectory, online=trajectory, stats={"frames": 3}, tables=tables)


def test_a_table_round_trips_with_integers_kept_whole(tmp_path):
    table = Table(("frame_i", "frame_j", "dx_m"), np.array([[3, 17, 0.1 + 0.2], [4, 1200, -1e-9]]))
    write_table(tmp_path / "loops.csv", table)
    text = (tmp_path / "loops.csv").read_text()
    assert text.splitlines()[:2] == ["frame_i,frame_j,dx_m", "3,17,0.30000000000000004"]
    back = read_table(tmp_path / "loops.csv")
    assert back.columns == table.columns and np.array_equal(back.rows, table.rows)


def test_an_empty_table_is_a_header_alone(tmp_path):
    write_table(tmp_path / "loops.csv", Table(("frame_i", "frame_j"), np.zeros((0, 2))))
    assert (tmp_path / "loops.csv").read_text() == "frame_i,frame_j\n"
    assert read_table(tmp_path / "loops.csv").rows.shape == (0, 2)


def test_the_run_folder_gets_each_table_as_csv_and_stats_stay_small(tmp_path):
    many = Table(("frame_i", "frame_j"), np.column_stack([np.arange(5000), np.arange(5000) + 7]))
    write_result(tmp_path, _result({"loops": many}), _measurements("x"))
    assert len(read_table(tmp_path / "loops.csv").rows) == 5000
    assert (tmp_path / STATS).stat().st_size < 2000
    assert "loops" not in json.loads((tmp_path / STATS).read_text())


@pytest.mark.parametrize("name", ["../escape", "a b", ""])
def test_a_table_name_that_is_no_file_name_is_refused(tmp_path, name):
    with pytest.raises(InputError, match="result table"):
        write_result(tmp_path, _result({name: Table(("a",), np.zeros((1, 1)))}), _measurements("x"))


def test_a_table_file_that_is_not_numbers_names_the_file(tmp_path):
    (tmp_path / "t.csv").write_text("a,b\n1,x\n")
    with pytest.raises(InputError, match="t.csv"):
        read_table(tmp_path / "t.csv")


def _measurements(method: str) -> RunMeasurements:
    """Figures of a run that never ran: what write_result needs beside a result."""
    fields = {f.name: 0 for f in dataclasses.fields(RunMeasurements) if f.name not in ("observer_time_s", "about")}
    return RunMeasurements(**{**fields, "method": method, "params": {}, "config": {}, "method_stats": {},
                              "step_time_mean_s_by_tenth": [], "cpu_wait_by_thread": {}, "rss_samples": []})
