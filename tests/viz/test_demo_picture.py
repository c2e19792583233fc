"""The demo's pictures and the report's floor-plan figures: every estimate visible even where two
coincide, each place labelled once, start and end marked, the ATE in the legend, a figure of error
over time, and maps with axis labels and a legend of their cells."""

from __future__ import annotations

import matplotlib.image as mpimg
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.colors import to_rgb

from longslam.core.gridmap import FREE, OCCUPIED, GridMap
from longslam.core.trajectory import Trajectory
from longslam.viz import plots
from longslam.viz.plots import draw_plan, method_styles, place_labels, plot_errors_over_time, plot_maps, plot_plan


def _room() -> GridMap:
    data = np.full((80, 120), FREE, dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = OCCUPIED
    return GridMap(data, 0.1, (0.0, 0.0))


def _path() -> np.ndarray:
    t = np.linspace(0, 1, 200)
    return np.column_stack([1 + 9 * t, 1 + 5 * t ** 2])


def _share_of(image: np.ndarray, colour: str) -> float:
    rgb = np.asarray(to_rgb(colour))
    return float(np.mean(np.linalg.norm(image[..., :3] - rgb, axis=-1) < 0.12))


def test_an_estimate_under_another_still_shows(tmp_path):
    """keyframe and submap on the same line: keyframe's colour must still be on the picture."""
    out = tmp_path / "plan.png"
    paths = {"ground truth": _path(), "keyframe": _path(), "submap": _path()}
    plot_plan(_room(), out, paths)
    styles = method_styles(list(paths))
    image = mpimg.imread(out)
    lower, upper = _share_of(image, styles["keyframe"]["color"]), _share_of(image, styles["submap"]["color"])
    assert upper > 0 and lower > 0.4 * upper, (lower, upper)  # on main keyframe was all under submap
    # Each later line is drawn over the earlier ones and narrower than them.
    assert styles["submap"]["zorder"] > styles["keyframe"]["zorder"]
    assert styles["submap"]["lw"] < styles["keyframe"]["lw"] and styles["submap"]["ls"] != styles["keyframe"]["ls"]


def test_a_place_visited_twice_is_labelled_once_with_both_visits():
    waypoints = np.array([[0, 0], [5, 0], [5, 5], [0, 5], [5, 5.2], [5.1, 0], [0, 0.1]])
    labels = place_labels(waypoints)
    assert [text for _, text in labels] == ["0, 6", "1, 5", "2, 4", "3"]


def test_the_plan_marks_start_and_ends_and_puts_the_ate_in_the_legend():
    fig, ax = plt.subplots()
    paths = {"ground truth": _path(), "keyframe": _path() + 0.3, "odometry": _path() * 1.1}
    waypoints = np.array([[1, 1], [10, 6], [1.1, 1.0]])
    draw_plan(ax, _room(), paths, waypoints, errors={"keyframe": 0.0412, "odometry": 0.357})
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "keyframe (ATE 0.041 m)" in legend and "odometry (ATE 0.357 m)" in legend and "ground truth" in legend
    assert "start" in legend and any(t.startswith("end") for t in legend)
    lines = ax.get_lines()
    start = [line for line in lines if line.get_label() == "start"]
    assert len(start) == 1 and np.allclose(start[0].get_xydata()[0], paths["ground truth"][0])
    ends = [line for line in lines if line.get_marker() == "s" and len(line.get_xydata())]
    assert sorted(tuple(np.round(e.get_xydata()[0], 6)) for e in ends) == sorted(
        tuple(np.round(xy[-1], 6)) for xy in paths.values())
    texts = [t.get_text() for t in ax.texts]
    assert texts == ["0, 2", "1"]  # waypoint 2 is back at the start: one label
    plt.close(fig)


def test_error_over_time_is_drawn_per_method_and_its_mean_is_the_ate(tmp_path):
    from longslam.cli.demo import ERRORS_FIGURE, error_over_time
    from longslam.eval.metrics import ate

    stamps = np.arange(50) * 0.1
    poses = np.tile(np.eye(4), (50, 1, 1))
    poses[:, 0, 3] = np.linspace(0, 5, 50)
    drifted = poses.copy()
    drifted[:, 1, 3] = np.linspace(0, 0.5, 50)
    truth, estimate = Trajectory(stamps, poses), Trajectory(stamps, drifted)
    t, e = error_over_time(truth, estimate)
    assert t[0] == 0 and t[-1] == pytest.approx(4.9) and e[-1] == pytest.approx(0.5)
    assert float(np.mean(e)) == pytest.approx(ate(truth, estimate))
    out = tmp_path / ERRORS_FIGURE
    plot_errors_over_time({"keyframe": (t, e), "odometry": (t, 2 * e)}, out, errors={"keyframe": float(np.mean(e))})
    image = mpimg.imread(out)
    styles = method_styles(["keyframe", "odometry"])
    assert _share_of(image, styles["keyframe"]["color"]) > 0 and _share_of(image, styles["odometry"]["color"]) > 0


def test_map_figures_have_axis_labels_and_a_legend_of_free_unknown_occupied(tmp_path, monkeypatch):
    saved = []
    monkeypatch.setattr(plots, "_save", lambda fig, out, dpi=90: saved.append(fig))
    room = _room()
    plot_maps(room, {"keyframe": room}, tmp_path / "maps.png", path=_path())
    fig = saved[-1]
    for ax in fig.axes:
        assert ax.get_xlabel() == "x [m]" and ax.get_ylabel() == "y [m]"
    legend = [t.get_text() for legend in fig.legends for t in legend.get_texts()]
    assert legend[:3] == ["free", "unknown", "occupied"] and "true path" in legend
    plots.plot_map_over_truth(room, room, tmp_path / "map.png", doubled=np.array([[2.0, 2.0]]))
    ax = saved[-1].axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["free", "unknown", "occupied (map)", "true wall", "wall shown twice"]
    for fig in saved:
        plt.close(fig)
