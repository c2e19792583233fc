"""A sensor plugin that fails (at loading, at making its model, in `sense()`) is a one-line
error naming the sensor, the frame and what it did, exit 2, and no sequence folder left; before,
each ended in a traceback, and a `sense()` raising SystemExit(0) made `simulate` exit 0 having
written nothing."""

from __future__ import annotations

from pathlib import Path

import pytest

from helpers.cli_checks import one_line_error
from longslam.cli.main import main

PLUGIN = '''
import numpy as np
from longslam.sim.sensors import SensorModel

class Returns(SensorModel):
    def __init__(self, what):
        self.what = what
    def sense(self, rgb, depth, intrinsics, motion, rng):
        return None if self.what is None else (rgb, depth, depth)

class Raises(SensorModel):
    def __init__(self, error):
        self.error = error
    def sense(self, rgb, depth, intrinsics, motion, rng):
        raise self.error

class NoCalibration(SensorModel):
    def __init__(self):
        raise ValueError("calibration file not found")

none_out = Returns(None)
three_out = Returns(3)
runtime = Raises(RuntimeError("lens cap on"))
memory = Raises(MemoryError())
exits = Raises(SystemExit(0))
NUMBER = 7
'''

ENTRY_POINTS = {
    "none-out": "longslam_failing_sensors:none_out", "three-out": "longslam_failing_sensors:three_out",
    "runtime": "longslam_failing_sensors:runtime", "memory": "longslam_failing_sensors:memory",
    "exits": "longslam_failing_sensors:exits", "no-calibration": "longslam_failing_sensors:NoCalibration",
    "number": "longslam_failing_sensors:NUMBER", "missing": "longslam_no_such_sensor_module:Model",
}


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    """The failing models above, each under its own `longslam.sensors` entry point."""
    site = tmp_path / "site"
    dist = site / "longslam_failing_sensors-0.1.dist-info"
    dist.mkdir(parents=True)
    (site / "longslam_failing_sensors.py").write_text(PLUGIN)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: longslam-failing-sensors\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[longslam.sensors]\n" + "".join(f"{k} = {v}\n" for k, v in ENTRY_POINTS.items()))
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    route = tmp_path / "r.txt"
    route.write_text("20 31.25\n21 31.25\n")
    return route


def _simulate(route: Path, sensor: str, out: Path) -> int:
    return main(["simulate", "--route", str(route), "--width", "16", "--height", "12", "--sensor", sensor,
                 "--out", str(out)])


@pytest.mark.parametrize("sensor, needles", [
    ("none-out", ["sensor 'none-out', frame 0", "sense() returned a NoneType; expected (rgb, depth)"]),
    ("three-out", ["sensor 'three-out', frame 0", "sense() returned 3 values; expected (rgb, depth)"]),
    ("runtime", ["sensor 'runtime', frame 0", "sense() raised RuntimeError: lens cap on"]),
    ("memory", ["sensor 'memory', frame 0", "sense() raised MemoryError"]),
    ("exits", ["sensor 'exits', frame 0", "sense() raised SystemExit: 0"]),
])
def test_a_failing_sense_is_one_line_naming_sensor_and_frame_and_leaves_no_folder(plugins, tmp_path, capsys,
                                                                                    sensor, needles):
    out = tmp_path / "seq"
    assert _simulate(plugins, sensor, out) == 2
    one_line_error(capsys, *needles)
    assert not out.exists() and not [p for p in tmp_path.iterdir() if ".partial-" in p.name]


@pytest.mark.parametrize("sensor, needles", [
    ("number", ["sensor 'number'", "longslam_failing_sensors:NUMBER is a int; expected a longslam.sim.sensors.SensorModel"]),
    ("no-calibration", ["sensor 'no-calibration'", "raised ValueError: calibration file not found"]),
    ("missing", ["sensor 'missing'", "cannot be loaded (ModuleNotFoundError", "longslam_no_such_sensor_module"]),
])
def test_a_sensor_that_cannot_be_made_is_refused_before_rendering(plugins, tmp_path, capsys, monkeypatch,
                                                                    sensor, needles):
    from longslam.sim import simulate as recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered for a broken sensor"))
    assert _simulate(plugins, sensor, tmp_path / "seq") == 2
    one_line_error(capsys, *needles)
    assert not (tmp_path / "seq").exists()


def test_list_says_which_plugin_sensor_has_no_module(plugins, capsys):
    assert main(["list"]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("sensors:"))
    assert "missing (broken: its module longslam_no_such_sensor_module is not installed)" in line
    assert "runtime," in line or line.endswith("runtime")  # the others are listed as they are
