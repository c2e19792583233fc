"""The demo: the `demo` route at `large` noise, every registered method, a table and two figures
(trajectories over the floor plan, position error over time)."""

from __future__ import annotations

from pathlib import Path
from typing import overload

import numpy as np

from longslam.core.odometry_noise import get_noise
from longslam.core.trajectory import Trajectory
from longslam.eval.metrics import ape_errors
from longslam.eval.sync import associate
from longslam.io.paths import check_output_folder
from longslam.io.sequence import SequenceReader
from longslam.io.trajectory_files import read_tum
from longslam.run.folder import TRAJECTORY
from longslam.run.scored_run import run_and_score
from longslam.run.speed import format_real_time_factor
from longslam.sim.camera import CameraSettings
from longslam.sim.routes import get_route
from longslam.sim.simulate import check_seed, simulate
from longslam.slam.catalog import default_method_names, get_spec
from longslam.viz.plots import plot_errors_over_time, plot_plan
from longslam.world import load_world

COLUMNS = ("method", "ATE [m]", "E_trans", "E_rot [deg/m]", "peak RSS [MB]", "real-time factor")


def format_table(rows: list[dict]) -> str:
    cells = [COLUMNS] + [
        (
            r["method"],
            f"{r['ate']:.3f}",
            f"{r['e_trans']:.4f}",
            f"{r['e_rot']:.4f}",
            f"{r['peak_rss_bytes'] / 1e6:.0f}",
            format_real_time_factor(r["real_time_factor"]),
        )
        for r in rows
    ]
    widths = [max(len(row[i]) for row in cells) for i in range(len(COLUMNS))]
    lines = [" | ".join(c.ljust(w) for c, w in zip(row, widths)) for row in cells]
    lines.insert(1, "-+-".join("-" * w for w in widths))
    return "\n".join(lines)


@overload
def _viz_target(viz: str, method: str) -> str: ...
@overload
def _viz_target(viz: str | None, method: str) -> str | None: ...
def _viz_target(viz: str | None, method: str) -> str | None:
    if viz is None or viz == "viewer":
        return viz
    path = Path(viz)
    return str(path.with_name(f"{path.stem}-{method}{path.suffix}"))


def run_demo(
    out: str | Path = "out/demo",
    route_name: str = "demo",
    noise_name: str = "large",
    seed: int = 0,
    methods: list[str] | None = None,
    camera: CameraSettings = CameraSettings(),
    progress: bool = True,
    viz: str | None = None,
    overwrite: bool = False,
) -> tuple[list[dict], Path]:
    """Simulate, run each method in its own process, evaluate. Returns the table rows and the plot path.

    `viz`: "viewer" shows each run live in a rerun viewer; a path FILE.rrd records each method's
    run to FILE-<method>.rrd beside it, replacing an existing one only with `overwrite`."""
    out = check_output_folder(out, "demo folder")
    check_seed(seed, "--seed")
    route, noise = get_route(route_name), get_noise(noise_name)
    methods = methods or default_method_names()  # `command` needs a program: named only
    if viz is not None and viz != "viewer":
        from longslam.viz.live import check_target

        for name in methods:
            check_target(_viz_target(viz, name), overwrite)
    out.mkdir(parents=True, exist_ok=True)
    sequence = out / f"sequence-{route.name}-{noise.name}-{seed}"
    if not sequence.exists():
        simulate(route, noise, seed, sequence, camera=camera, progress=progress)
    truth = SequenceReader(sequence).ground_truth
    assert truth is not None, "a simulated sequence always has ground truth"
    for name in methods:  # once-per-machine work (a vocabulary) outside the runs' figures
        get_spec(name).prepare_for()
    rows, paths, curves, ates = [], {"ground truth": truth.positions[:, :2]}, {}, {}
    for name in methods:
        run_dir = out / "runs" / name
        scores, measurements = run_and_score(name, sequence, run_dir, progress=progress, viz=_viz_target(viz, name))
        estimate = read_tum(run_dir / TRAJECTORY)
        rows.append(
            {
                "method": name,
                **scores,
                "peak_rss_bytes": measurements.peak_rss_bytes,
                "real_time_factor": measurements.real_time_factor,
            }
        )
        paths[name] = estimate.positions[:, :2]
        curves[name] = error_over_time(truth, estimate)
        ates[name] = scores["ate"]
    world = load_world(route.world)
    plot = out / "trajectories.png"
    waypoints = route.resolve(world.places)
    title = f"route {route.name}, noise {noise.name}, seed {seed}"
    plot_plan(world.occupancy, plot, paths, waypoints=waypoints, title=title, zoom_margin=6.0, errors=ates)
    plot_errors_over_time(
        curves, out / ERRORS_FIGURE, title=f"position error over time (no alignment): {title}", errors=ates
    )
    return rows, plot


ERRORS_FIGURE = "errors.png"


def error_over_time(truth: Trajectory, estimate: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Time since the first matched pose (s) and position error (m, no alignment) at each pose: the
    terms whose mean is the ATE."""
    ref, est = associate(truth, estimate)
    return ref.timestamps - ref.timestamps[0], ape_errors(ref, est, "translation")
