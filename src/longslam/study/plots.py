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
