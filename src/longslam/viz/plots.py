"""Figures: trajectories over the floor plan."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; no display on servers
import matplotlib.pyplot as plt
import numpy as np

from longslam.gridmap import FREE, OCCUPIED, GridMap
from longslam.io.atomic import atomic_path


def _plan_image(grid: GridMap) -> np.ndarray:
    image = np.full(grid.data.shape, 0.8)
    image[grid.data == FREE] = 1.0
    image[grid.data == OCCUPIED] = 0.0
    return image


def plot_plan(
    grid: GridMap,
    out: str | Path,
    trajectories: dict[str, np.ndarray] | None = None,
    waypoints: np.ndarray | None = None,
    title: str = "",
    zoom_margin: float | None = None,
) -> None:
    """Floor plan (ground-truth occupancy) with (N, 2) xy paths drawn over it, saved as an image.

    With `zoom_margin`, the view is cropped to the paths plus that many metres around them.
    """
    xmin, xmax, ymin, ymax = grid.extent
    if zoom_margin is not None and trajectories:
        points = np.concatenate([np.asarray(xy)[:, :2] for xy in trajectories.values()])
        xmin, ymin = np.maximum(points.min(axis=0) - zoom_margin, (xmin, ymin))
        xmax, ymax = np.minimum(points.max(axis=0) + zoom_margin, (xmax, ymax))
    fig, ax = plt.subplots(figsize=(12, 12 * (ymax - ymin) / (xmax - xmin) + 1.0))
    ax.imshow(_plan_image(grid), origin="lower", extent=grid.extent, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    for i, (label, xy) in enumerate((trajectories or {}).items()):
        xy = np.asarray(xy)
        style = {"color": "black", "lw": 2.0, "ls": "--"} if label == "ground truth" else {"lw": 1.2}
        ax.plot(xy[:, 0], xy[:, 1], label=label, **style)
    if waypoints is not None and len(waypoints):
        wp = np.asarray(waypoints)
        ax.plot(wp[:, 0], wp[:, 1], "o", color="tab:red", ms=6, label="waypoints")
        for k, (x, y) in enumerate(wp):
            ax.annotate(str(k), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8, color="tab:red")
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    if title:
        ax.set_title(title)
    if trajectories or waypoints is not None:
        ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    out = Path(out)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=110, format=out.suffix.lstrip(".") or "png")
    plt.close(fig)


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


def _grid_image(grid: GridMap, block: int = 1) -> tuple[np.ndarray, tuple[float, float, float, float]]:
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
    fig, axes = plt.subplots(1, len(panels), figsize=(width * len(panels), width * aspect + 0.9), squeeze=False)
    pixels = 0.8 * width * dpi  # about the width of a panel's drawing area
    for ax, (name, grid) in zip(axes[0], panels.items()):
        block = max(1, round((xmax - xmin) / grid.resolution / pixels))
        image, extent = _grid_image(grid, block)
        ax.imshow(image, origin="lower", extent=extent, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        if name == "ground truth" and path is not None and len(path):
            ax.plot(path[:, 0], path[:, 1], color="tab:green", lw=0.8, alpha=0.8)
        ax.set_xlim(xmin, xmax)
        ax.set_ylim(ymin, ymax)
        ax.set_aspect("equal")
        ax.set_title(name + (f"\n{captions[name]}" if captions and name in captions else ""), fontsize=9)
        ax.tick_params(labelsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
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
    image, extent = _grid_image(grid, block)
    # Three layers: the map's free and unknown space, the true walls (orange), the map's walls
    # (black) on top: a black wall off the orange is a wall where there is none, orange
    # without black a wall the map missed.
    ax.imshow(np.where(image == 0.0, 1.0, image), origin="lower", extent=extent, cmap="gray", vmin=0, vmax=1,
              interpolation="nearest")
    true_block = max(1, round((xmax - xmin) / truth.resolution / pixels))
    true_walls, true_extent = _grid_image(truth, true_block)
    walls = np.zeros(true_walls.shape + (4,))
    walls[true_walls == 0.0] = (1.0, 0.55, 0.0, 1.0)
    ax.imshow(walls, origin="lower", extent=true_extent, interpolation="nearest")
    ink = np.zeros(image.shape + (4,))
    ink[image == 0.0] = (0.0, 0.0, 0.0, 1.0)
    ax.imshow(ink, origin="lower", extent=extent, interpolation="nearest")
    if doubled is not None and len(doubled):
        doubled = np.asarray(doubled, dtype=np.float64).reshape(-1, 2)
        ax.scatter(doubled[:, 0], doubled[:, 1], s=30, facecolors="none", edgecolors="magenta", linewidths=0.8,
                   label="wall shown twice")
        ax.legend(loc="upper right", fontsize=8)
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
