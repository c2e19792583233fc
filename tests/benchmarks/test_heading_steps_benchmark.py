"""benchmarks/heading_steps.py measures each heading source's per-step error against the truth: on
the demo route its wheels carry the simulator's bias and its RGB-D steps on exact depth stay near
the truth, so a sign, frame or pairing slip in the script shows here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers.scripts import load_script

from longslam.core.odometry_noise import get_noise
from longslam.sim.routes import get_route

pytestmark = pytest.mark.slow  # renders the demo route

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
heading_steps = load_script(BENCHMARKS / "heading_steps.py", "benchmarks_heading_steps")

FRAMES = 60  # 6 s: inside the first period of the simulator's wheel bias


def test_the_wheels_error_is_the_simulators_bias_and_the_rgbd_steps_stay_near_the_truth(rendered):
    noise = get_noise("large")
    assert FRAMES * 0.1 < noise.redraw_period  # one bias for every step measured
    errors = heading_steps.heading_errors(rendered(get_route("demo"), "large", 0), 0, FRAMES)
    assert len(errors["true"]) == FRAMES - 1
    wheels = errors["wheels"]
    # One bias a period, added to every step: the same error on each step, some draw of the level's std.
    assert np.ptp(wheels) < 1e-6, np.ptp(wheels)
    assert 1e-7 < abs(wheels[0]) < 4.0 * np.radians(noise.angular_std_deg), wheels[0]
    fitted = np.isfinite(errors["rgbd"])
    assert fitted.mean() > 0.9
    assert abs(errors["rgbd"][fitted].mean()) < 1e-3
    assert errors["rgbd"][fitted].std() < 3e-3
    # The front end's step refits the heading to the corners' bearings: it scatters less than the
    # planar fit of their 3D positions on the same corners.
    fitted_3d = np.isfinite(errors["rgbd_3d"])
    assert fitted_3d.mean() > 0.9
    assert errors["rgbd"][fitted].std() < errors["rgbd_3d"][fitted_3d].std()
    assert errors["scan_points"].min() >= 0


def test_exact_wheels_have_no_heading_error(rendered):
    errors = heading_steps.heading_errors(rendered(get_route("demo"), "none", 0), 0, 20)
    assert np.abs(errors["wheels"]).max() < 1e-9
