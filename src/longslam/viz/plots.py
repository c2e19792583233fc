"""Figures: trajectories over the floor plan, error over time, curves against distance, maps."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; no display on servers
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from longslam.core.gridmap import FREE, OCCUPIED, GridMap
from longslam.io.atomic import atomic_path


def _plan_image(grid: GridMap) -> np.ndarray:
    image = np.full(grid.data.shape, 0.8)
    image[grid.data == FREE] = 1.0
    image[grid.data == OCCUPIED] = 0.0
    return image


GROUND_TRUTH = "ground truth"
# Each method's line: its own colour, dash and width. The first is the widest and lowest, each
# later one narrower and over it, so two estimates that nearly coincide both show (the lower
# one as a border around the upper).
DASHES = ("-", (0, (6, 2)), (0, (2, 1.2)), "-.", (0, (8, 2, 2, 2)))
PLACE_TOLERANCE_M = 0.5  # waypoints closer than this are one place, labelled once


def method_styles(labels: list[str]) -> dict[str, dict]:
    """Line style of each estimate (everything but the ground truth), the same in every figure."""
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    methods = [label for label in labels if label != GROUND_TRUTH]
    styles = {}
    for i, label in enumerate(methods):
        styles[label] = {
            "color": colours[i % len(colours)],
            "ls": DASHES[i % len(DASHES)],
            "lw": 1.3 + 0.7 * (len(methods) - 1 - i),
            "alpha": 0.9,
            "zorder": 4 + i,
        }
    return styles


def place_labels(waypoints: np.ndarray, tolerance: float = PLACE_TOLERANCE_M) -> list[tuple[np.ndarray, str]]:
    """One label per place of the route: a place the route visits again gets every visit's number
    ('1, 6') once, not two labels drawn over each other."""
    places: list[tuple[np.ndarray, list[int]]] = []
    for k, xy in enumerate(np.asarray(waypoints, dtype=np.float64).reshape(-1, 2)):
        for where, visits in places:
            if np.linalg.norm(where - xy) < tolerance:
                visits.append(k)
                break
        else:
            places.append((xy, [k]))
    return [(where, ", ".join(map(str, visits))) for where, visits in places]


def draw_plan(
    ax,
    grid: GridMap,
    trajectories: dict[str, np.ndarray] | None = None,
    waypoints: np.ndarray | None = None,
    view: tuple[float, float, float, float] | None = None,
    errors: dict[str, float] | None = None,
    legend: bool = True,
    order: list[str] | None = None,
) -> None:
    """The floor plan with paths over it on `ax`: the ground truth dashed black, each estimate in
    its style (`method_styles`), a start marker, each path's end marked in its colour, each place
    of the route labelled once with its visit numbers. `errors[label]` (ATE, m) goes in the legend;
    `order` (every label of a set of figures) keeps a method's style when some panel lacks another."""
    trajectories = trajectories or {}
    ax.imshow(
        _plan_image(grid), origin="lower", extent=grid.extent, cmap="gray", vmin=0, vmax=1, interpolation="nearest"
    )
    styles = method_styles(order or list(trajectories))
    for label, xy in trajectories.items():
        xy = np.asarray(xy)
        if label == GROUND_TRUTH:
            style = {"color": "black", "lw": 2.0, "ls": "--", "zorder": 3}
        else:
            style = styles[label]
        shown = label if not errors or label not in errors else f"{label} (ATE {errors[label]:.3f} m)"
        ax.plot(xy[:, 0], xy[:, 1], label=shown, **style)
        if len(xy):
            ax.plot(*xy[-1, :2], marker="s", ms=7, color=style["color"], mec="white", mew=0.8, ls="none", zorder=20)
    if trajectories:
        first = np.asarray(next(iter(trajectories.values())))
        if len(first):
            ax.plot(
                *first[0, :2], marker="o", ms=10, color="tab:green", mec="black", ls="none", zorder=21, label="start"
            )
            ax.plot([], [], marker="s", ms=7, color="grey", mec="white", ls="none", label="end (each path's colour)")
    if waypoints is not None and len(waypoints):
        wp = np.asarray(waypoints)
        ax.plot(wp[:, 0], wp[:, 1], "o", color="tab:red", ms=5, label="waypoints", zorder=15)
        for where, text in place_labels(wp):
            ax.annotate(
                text,
                where,
                textcoords="offset points",
                xytext=(5, 5),
                fontsize=8,
                color="tab:red",
                zorder=22,
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7},
            )
    xmin, xmax, ymin, ymax = view or grid.extent
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    if legend and (trajectories or waypoints is not None):
        ax.legend(loc="upper left", fontsize=8)


def plan_view(
    grid: GridMap, trajectories: dict[str, np.ndarray] | None, zoom_margin: float | None
) -> tuple[float, float, float, float]:
    """The floor plan's extent, or with `zoom_margin` the paths plus that many metres around them."""
    xmin, xmax, ymin, ymax = grid.extent
    if zoom_margin is not None and trajectories:
        points = np.concatenate([np.asarray(xy)[:, :2] for xy in trajectories.values() if len(xy)])
        xmin, ymin = np.maximum(points.min(axis=0) - zoom_margin, (xmin, ymin))
        xmax, ymax = np.minimum(points.max(axis=0) + zoom_margin, (xmax, ymax))
    return float(xmin), float(xmax), float(ymin), float(ymax)


def plot_plan(
    grid: GridMap,
    out: str | Path,
    trajectories: dict[str, np.ndarray] | None = None,
    waypoints: np.ndarray | None = None,
    title: str = "",
    zoom_margin: float | None = None,
    errors: dict[str, float] | None = None,
) -> None:
    """Floor plan (ground-truth occupancy) with (N, 2) xy paths drawn over it, saved as an image
    (see `draw_plan`). With `zoom_margin`, the view is cropped to the paths plus that many metres."""
    view = plan_view(grid, trajectories, zoom_margin)
    xmin, xmax, ymin, ymax = view
    fig, ax = plt.subplots(figsize=(12, 12 * (ymax - ymin) / (xmax - xmin) + 1.0))
    draw_plan(ax, grid, trajectories, waypoints, view, errors)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    out = Path(out)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=110, format=out.suffix.lstrip(".") or "png")
    plt.close(fig)


def plot_plans(
    grid: GridMap,
    out: str | Path,
    panels: dict[str, dict[str, np.ndarray]],
    waypoints: np.ndarray | None = None,
    title: str = "",
    zoom_margin: float | None = None,
    errors: dict[str, dict[str, float]] | None = None,
    columns: int = 3,
) -> None:
    """Small multiples: one floor plan per panel (e.g. a seed), all over the same view, each with its
    paths (`panels[panel][label]`) and its own legend (`errors[panel][label]`: ATE, m)."""
    names = list(panels)
    every = {f"{name}/{label}": xy for name in names for label, xy in panels[name].items()}
    view = plan_view(grid, every, zoom_margin)
    xmin, xmax, ymin, ymax = view
    cols = max(1, min(columns, len(names)))
    rows = -(-len(names) // cols)
    width = 16.0 if cols > 1 else 12.0
    panel_w = width / cols
    fig, axes = plt.subplots(
        rows, cols, figsize=(width, rows * (panel_w * (ymax - ymin) / (xmax - xmin) + 0.8)), squeeze=False
    )
    order = list(dict.fromkeys(label for name in names for label in panels[name]))
    for ax, name in zip(axes.flat, names):
        draw_plan(ax, grid, panels[name], waypoints, view, (errors or {}).get(name), order=order)
        ax.set_title(name, fontsize=10)
    for ax in list(axes.flat)[len(names) :]:
        ax.axis("off")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    _save(fig, out, dpi=90)


def plot_errors_over_time(
    curves: dict[str, tuple[np.ndarray, np.ndarray]],
    out: str | Path,
    title: str = "",
    errors: dict[str, float] | None = None,
) -> None:
    """Position error (m, no alignment: the ATE's per-pose term) against time (s) of each method,
    in the line styles of its trajectory figure; `errors[label]` (ATE, m) in the legend and drawn
    as a dotted level."""
    styles = method_styles(list(curves))
    fig, ax = plt.subplots(figsize=(10, 4.2))
    for label, (t, e) in curves.items():
        style = styles[label]
        shown = label if not errors or label not in errors else f"{label} (ATE {errors[label]:.3f} m)"
        ax.plot(t, e, label=shown, **style)
        if errors and label in errors:
            ax.axhline(errors[label], color=style["color"], ls=":", lw=0.9, alpha=0.8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("position error [m]")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    _save(fig, out, dpi=110)


# ----------------------------------------------------------------------------- study report figures


def _save(fig, out: str | Path, dpi: int = 90) -> None:
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=dpi, format=out.suffix.lstrip(".") or "png")
    plt.close(fig)


def plot_curves_by_distance(
    panels: dict[str, dict[str, list[np.ndarray]]],
    out: str | Path,
    ylabel: str,
    title: str = "",
    points: int = 200,
) -> None:
    """One panel per key of `panels` (e.g. a noise level), one line per method: the mean over
    its runs of y against distance travelled, with the band from the lowest to the highest run.

    panels[panel][method] is a list of (M, 2) arrays of (distance [m], y), one per run.
    """
    names = list(panels)
    fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names) + 0.6, 3.6), squeeze=False, sharey=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    methods = sorted({m for curves in panels.values() for m in curves})
    for ax, name in zip(axes[0], names):
        for k, method in enumerate(methods):
            runs = [np.asarray(c, dtype=np.float64).reshape(-1, 2) for c in panels[name].get(method, []) if len(c)]
            if not runs:
                continue
            end = min(r[-1, 0] for r in runs)
            grid = np.linspace(0.0, end, points) if end > 0 else np.zeros(1)
            ys = np.array([np.interp(grid, r[:, 0], r[:, 1]) for r in runs])
            colour = colours[k % len(colours)]
            ax.plot(grid, ys.mean(axis=0), color=colour, lw=1.5, label=f"{method} ({len(runs)} runs)")
            if len(runs) > 1:
                ax.fill_between(grid, ys.min(axis=0), ys.max(axis=0), color=colour, alpha=0.2, lw=0)
        ax.set_title(name)
        ax.set_xlabel("distance travelled [m]")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(ylabel)
    axes[0][-1].legend(fontsize=8, loc="upper left")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    _save(fig, out)


def cell_legend_handles(occupied: str = "occupied") -> list:
    """Legend entries for a grid drawn by `grid_image`: free white, unknown grey, occupied black."""
    return [
        Patch(facecolor="white", edgecolor="#888", label="free"),
        Patch(facecolor=(0.75, 0.75, 0.75), edgecolor="#888", label="unknown"),
        Patch(facecolor="black", edgecolor="#888", label=occupied),
    ]


def grid_image(grid: GridMap, block: int = 1) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """Grey image of a grid (black occupied, white free, grey unknown) and its extent.

    With `block` > 1, each block x block of cells becomes one pixel, occupied if any cell is (then
    free if any is): thin walls stay visible when a large map is drawn small.
    """
    data = grid.data
    if block > 1:
        rows, cols = data.shape
        pad = ((0, -rows % block), (0, -cols % block))
        tiles = np.pad(data, pad, constant_values=-1)
        tiles = tiles.reshape(tiles.shape[0] // block, block, tiles.shape[1] // block, block)
        occupied = (tiles == OCCUPIED).any(axis=(1, 3))
        free = (tiles == FREE).any(axis=(1, 3))
        data = np.where(occupied, OCCUPIED, np.where(free, FREE, -1))
    image = np.full(data.shape, 0.75)
    image[data == FREE] = 1.0
    image[data == OCCUPIED] = 0.0
    ox, oy = grid.origin
    size = grid.resolution * block
    return image, (ox, ox + data.shape[1] * size, oy, oy + data.shape[0] * size)


def plot_maps(
    truth: GridMap,
    maps: dict[str, GridMap],
    out: str | Path,
    view: tuple[float, float, float, float] | None = None,
    path: np.ndarray | None = None,
    captions: dict[str, str] | None = None,
    title: str = "",
) -> None:
    """The ground-truth grid and each method's grid side by side, over the same view
    (xmin, xmax, ymin, ymax); the true path is drawn on the ground truth."""
    panels = {"ground truth": truth, **maps}
    xmin, xmax, ymin, ymax = view or truth.extent
    aspect = (ymax - ymin) / max(xmax - xmin, 1e-6)
    width, dpi = 5.0, 90
    legend_h = 0.45  # inches under the panels for the legend of the cells
    fig, axes = plt.subplots(
        1, len(panels), figsize=(width * len(panels), width * aspect + 0.9 + legend_h), squeeze=False
    )
    pixels = 0.8 * width * dpi  # about the width of a panel's drawing area
    for ax, (name, grid) in zip(axes[0], panels.items()):
        block = max(1, round((xmax - xmin) / grid.resolution / pixels))
        image, extent = grid_image(grid, block)
        ax.imshow(image, origin="lower", extent=extent, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        if name == "ground truth" and path is not None and len(path):
            ax.plot(path[:, 0], path[:, 1], color="tab:green", lw=0.8, alpha=0.8)
        ax.set_xlim(xmin, xmax)
        ax.set_ylim(ymin, ymax)
        ax.set_aspect("equal")
        ax.set_title(name + (f"\n{captions[name]}" if captions and name in captions else ""), fontsize=9)
        ax.set_xlabel("x [m]", fontsize=8)
        ax.set_ylabel("y [m]", fontsize=8)
        ax.tick_params(labelsize=7)
    handles = cell_legend_handles()
    if path is not None and len(path):
        handles.append(Line2D([], [], color="tab:green", lw=0.8, label="true path"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    if title:
        fig.suptitle(title)
    fig.tight_layout(rect=(0, legend_h / fig.get_figheight(), 1, 1))
    _save(fig, out, dpi=dpi)


def plot_map_over_truth(
    grid: GridMap,
    truth: GridMap,
    out: str | Path,
    view: tuple[float, float, float, float] | None = None,
    doubled: np.ndarray | None = None,
    title: str = "",
    width: float = 11.0,
    dpi: int = 80,
) -> None:
    """One method's grid, large (black walls, white free, grey unknown), with the ground truth's
    walls under its walls in orange and the places where the map shows a wall twice ringed in magenta,
    over the view (xmin, xmax, ymin, ymax). The map is drawn as it is (not aligned), so a map
    that drifted shows its walls beside the orange ones."""
    xmin, xmax, ymin, ymax = view or grid.extent
    aspect = (ymax - ymin) / max(xmax - xmin, 1e-6)
    fig, ax = plt.subplots(figsize=(width, width * aspect + 0.6))
    pixels = 0.9 * width * dpi
    block = max(1, round((xmax - xmin) / grid.resolution / pixels))
    image, extent = grid_image(grid, block)
    # Three layers: the map's free and unknown space, the true walls (orange), the map's walls
    # (black) on top: a black wall off the orange is a wall where there is none, orange
    # without black a wall the map missed.
    ax.imshow(
        np.where(image == 0.0, 1.0, image),
        origin="lower",
        extent=extent,
        cmap="gray",
        vmin=0,
        vmax=1,
        interpolation="nearest",
    )
    true_block = max(1, round((xmax - xmin) / truth.resolution / pixels))
    true_walls, true_extent = grid_image(truth, true_block)
    walls = np.zeros(true_walls.shape + (4,))
    walls[true_walls == 0.0] = (1.0, 0.55, 0.0, 1.0)
    ax.imshow(walls, origin="lower", extent=true_extent, interpolation="nearest")
    ink = np.zeros(image.shape + (4,))
    ink[image == 0.0] = (0.0, 0.0, 0.0, 1.0)
    ax.imshow(ink, origin="lower", extent=extent, interpolation="nearest")
    if doubled is not None and len(doubled):
        doubled = np.asarray(doubled, dtype=np.float64).reshape(-1, 2)
        ax.scatter(
            doubled[:, 0],
            doubled[:, 1],
            s=30,
            facecolors="none",
            edgecolors="magenta",
            linewidths=0.8,
            label="wall shown twice",
        )
    handles = cell_legend_handles("occupied (map)") + [
        Patch(facecolor=(1.0, 0.55, 0.0), edgecolor="#888", label="true wall")
    ]
    if doubled is not None and len(doubled):
        handles.append(Line2D([], [], marker="o", ls="none", mfc="none", mec="magenta", label="wall shown twice"))
    ax.legend(handles=handles, loc="upper right", fontsize=8, framealpha=0.9)
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]", fontsize=8)
    ax.set_ylabel("y [m]", fontsize=8)
    ax.tick_params(labelsize=7)
    if title:
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    _save(fig, out, dpi=dpi)
