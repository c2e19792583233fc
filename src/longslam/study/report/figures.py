"""The report's figures: every seed's trajectories over the floor plan, error and memory against
distance travelled, and each method's map beside the ground truth; per route, and per camera in a
study with several (their files then named route-camera-...). Each is a PNG (for report.md); the
trajectories and curves are also plotly figures (for report.html, see `interactive`)."""

from __future__ import annotations

import re
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError
from longslam.io.grid_files import read_grid
from longslam.study.report.results import RowGroup, StudyResults, on_camera

FIGURES_DIR = "report_files"


@dataclass
class Figure:
    path: Path  # relative to the study folder
    caption: str
    interactive: Any = None  # a plotly figure that report.html shows instead of the PNG


def _seed_runs(
    results: StudyResults, route: str, noise: str, camera: RowGroup | str | None = None
) -> dict[str, list[dict]]:
    """method -> its successful runs of (route, noise, camera), by seed."""
    chosen: dict[str, list[dict]] = defaultdict(list)
    for run in sorted(results.ok, key=lambda r: r["seed"]):
        if (run["route"], run["noise"]) == (route, noise) and on_camera(run, camera):
            chosen[run["method"]].append(run)
    return {m: chosen[m] for m in results.methods if m in chosen}


def _first_seed_runs(
    results: StudyResults, route: str, noise: str, camera: RowGroup | str | None = None
) -> dict[str, dict]:
    chosen: dict[str, dict] = {}
    for run in sorted(results.ok, key=lambda r: r["seed"]):
        if (run["route"], run["noise"]) == (route, noise) and on_camera(run, camera) and run["method"] not in chosen:
            chosen[run["method"]] = run
    return {m: chosen[m] for m in results.methods if m in chosen}


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def make_figures(results: StudyResults, left_out: list[str] | None = None) -> list[Figure]:
    """The figures the study folder has the files for; each figure or part of one left out, and
    why, is appended to `left_out` (the report says so rather than dropping it silently)."""
    from longslam.study.prepare import load_world_grid

    left_out = left_out if left_out is not None else []
    out = results.out
    folder = out / FIGURES_DIR
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("*.png"):
        old.unlink()
    figures: list[Figure] = []
    world = results.config.get("world", "university")
    try:
        truth_grid = load_world_grid(out, world)
    except InputError as err:
        left_out.append(f"no figures: the world's ground-truth grid cannot be read ({err})")
        return figures
    for route in results.routes:
        for camera in results.row_cameras:
            figures += _route_figures(results, route, camera, truth_grid, left_out)
    return figures


def _route_figures(
    results: StudyResults, route: str, camera: RowGroup | str | None, truth_grid, left_out: list[str]
) -> list[Figure]:
    """The figures of one route: of one row group's runs (a camera, a sensor and/or a
    perturbation), or of all (camera None: one of each)."""
    from longslam.eval.map_quality import map_scores
    from longslam.io.trajectory_files import read_tum
    from longslam.study.prepare import load_route_data
    from longslam.study.report.interactive import curves_figure, trajectories_figure
    from longslam.viz.plots import plan_view, plot_curves_by_distance, plot_map_over_truth, plot_maps, plot_plans

    out = results.out
    figures: list[Figure] = []
    # Names and titles have the camera only when there are several: a one-camera study's
    # figures keep their names.
    tag = f"{_safe(route)}-{_safe(str(camera).replace(', ', '-'))}" if camera else _safe(route)
    where = f"route {route}, {results.group_title} {camera}" if camera else f"route {route}"
    try:
        data = load_route_data(out, route, results.camera_folder(results.camera_of(camera)))
    except (OSError, InputError, ValueError, KeyError) as err:
        left_out.append(f"no figures of {where}: its ground truth in the study folder's routes/ cannot be read ({err})")
        return figures
    truth_xy = data.truth.positions[:, :2]
    mine = [r for r in results.ok if r["route"] == route and on_camera(r, camera)]
    noises = [n for n in results.noise if any(r["noise"] == n for r in mine)]
    for noise in noises:
        panels: dict[str, dict[str, np.ndarray]] = {}
        errors: dict[str, dict[str, float]] = {}
        estimates: dict[str, dict[int, np.ndarray]] = defaultdict(dict)
        ates: dict[tuple[str, int], float] = {}
        for method, runs in _seed_runs(results, route, noise, camera).items():
            for run in runs:
                try:
                    xy = read_tum(out / run["trajectory_path"]).positions[:, :2]
                except (OSError, InputError, TypeError) as err:
                    left_out.append(f"trajectory of {run['key']} left out of the trajectory figure ({err})")
                    continue
                panel = f"seed {run['seed']}"
                panels.setdefault(panel, {"ground truth": truth_xy})[method] = xy
                estimates[method][run["seed"]] = xy
                if run.get("ate") is not None:
                    errors.setdefault(panel, {})[method] = run["ate"]
                    ates[(method, run["seed"])] = run["ate"]
        if not panels:
            continue
        panels = dict(sorted(panels.items(), key=lambda item: int(item[0].split()[1])))
        name = Path(FIGURES_DIR) / f"trajectories-{tag}-{_safe(noise)}.png"
        seed_text = ", ".join(p.split()[1] for p in panels)
        shown = f"route {route} ({data.length_m:.0f} m)" + (f", {results.group_title} {camera}" if camera else "")
        plot_plans(
            truth_grid,
            out / name,
            panels,
            waypoints=data.waypoints,
            zoom_margin=6.0,
            errors=errors,
            title=f"{shown}, noise {noise}, seed{'s' if len(panels) > 1 else ''} {seed_text}",
        )
        view = plan_view(truth_grid, {k: v for p in panels.values() for k, v in p.items()}, 6.0)
        interactive = trajectories_figure(
            truth_grid,
            view,
            truth_xy,
            dict(estimates),
            ates,
            data.waypoints,
            title=f"{shown}, noise {noise}: every seed (menu: one seed)",
        )
        figures.append(
            Figure(
                name,
                f"Estimated trajectories over the floor plan with the ground truth: {where}, noise {noise}, "
                f"one panel per seed ({seed_text}); ATE of each in its legend.",
                interactive,
            )
        )

    for column, ylabel, scale, what in (
        ("error_curve", "position error [m]", 1.0, "ATE (position error, no alignment)"),
        ("memory_curve", "resident memory [MB]", 1e-6, "Resident memory of the run's process"),
    ):
        curve_panels: dict[str, dict[str, list[np.ndarray]]] = {}
        by_seed: dict[str, dict[str, dict[int, np.ndarray]]] = {}
        for noise in noises:
            curves: dict[str, list[np.ndarray]] = defaultdict(list)
            seeded: dict[str, dict[int, np.ndarray]] = defaultdict(dict)
            for run in mine:
                if run["noise"] == noise and run[column]:
                    curve = np.asarray(run[column], dtype=np.float64)
                    curve[:, 1] *= scale
                    curves[run["method"]].append(curve)
                    seeded[run["method"]][run["seed"]] = curve
            curve_panels[f"noise {noise}"] = {m: curves[m] for m in results.methods if m in curves}
            by_seed[f"noise {noise}"] = {m: seeded[m] for m in results.methods if m in seeded}
        if any(curve_panels.values()):
            kind = "ate" if column == "error_curve" else "memory"
            name = Path(FIGURES_DIR) / f"{kind}-{tag}.png"
            plot_curves_by_distance(curve_panels, out / name, ylabel, title=where)
            interactive = curves_figure(by_seed, ylabel, title=f"{what}, {where}: each run")
            figures.append(
                Figure(
                    name,
                    f"{what} against distance travelled, {where}: mean over the seeds, band from the "
                    "lowest to the highest run (on the page: each run's own line).",
                    interactive,
                )
            )

    # The maps are shown over the walls the camera could see from the route, and the route.
    seen = (
        truth_grid.cell_to_world(np.argwhere(data.observed))
        if data.observed.shape == truth_grid.data.shape
        else np.zeros((0, 2))
    )
    extent = np.vstack([truth_xy, seen])
    lo, hi = extent.min(axis=0) - 1.0, extent.max(axis=0) + 1.0
    view = (lo[0], hi[0], lo[1], hi[1])
    for noise in noises:
        maps, captions = {}, {}
        first = _first_seed_runs(results, route, noise, camera)
        for method, run in first.items():
            if not run.get("grid_path"):
                continue
            try:
                maps[method] = read_grid(out / run["grid_path"])
            except InputError as err:
                left_out.append(f"map of {run['key']} left out of the map figures ({err})")
                continue
            p, r = run.get("map_precision"), run.get("map_recall")
            captions[method] = f"precision {p:.2f}, recall {r:.2f}" if p is not None and r is not None else ""
        if maps:
            name = Path(FIGURES_DIR) / f"maps-{tag}-{_safe(noise)}.png"
            plot_maps(
                truth_grid,
                maps,
                out / name,
                view=view,
                path=truth_xy,
                captions=captions,
                title=f"occupancy maps, {where}, noise {noise}, first seed",
            )
            figures.append(
                Figure(
                    name, f"Each method's occupancy grid beside the ground truth: {where}, noise {noise} (first seed)."
                )
            )
        # Each map again, large enough to read, with the true walls over it and its doubled walls.
        for method, grid in maps.items():
            run = first[method]
            quality = run.get("map_quality") or {}
            if "map_doubled_places" not in quality:
                # Recorded before the doubled-wall measure: measure it here, on the map as it is.
                tolerance = results.config.get("map_tolerance_cells", 2)
                quality = map_scores(grid, truth_grid, tolerance, data.observed, with_places=True)
            name = Path(FIGURES_DIR) / f"map-{tag}-{_safe(noise)}-{_safe(method)}.png"
            share = quality.get("map_doubled_walls")
            more = f", walls shown twice {100 * share:.1f}%" if share is not None else ""
            plot_map_over_truth(
                grid,
                truth_grid,
                out / name,
                view=view,
                doubled=quality.get("map_doubled_places"),
                title=f"{method}: {where}, noise {noise}, seed {run['seed']} ({captions[method]}{more})",
            )
            figures.append(
                Figure(
                    name,
                    f"{method}'s occupancy grid as it is (black), the true walls over it "
                    f"(orange), the walls it shows twice ringed (magenta): {where}, noise {noise}.",
                )
            )
    return figures
