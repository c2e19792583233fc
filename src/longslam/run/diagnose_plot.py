"""The picture of `longslam diagnose`: where along the route the error is picked up, and what the
front end ran on there."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

from longslam.core.gridmap import FREE, OCCUPIED  # noqa: E402
from longslam.io.atomic import atomic_path  # noqa: E402
from longslam.run.diagnose import Diagnosis  # noqa: E402

FACTOR_COLOURS = {"loops": "tab:red", "scans": "tab:blue", "visual": "tab:green", "wheels": "tab:gray", "": "white"}


def plot_diagnosis(d: Diagnosis, out: str | Path, title: str = "") -> None:
    """Four panels: the route coloured by position error with the loop constraints (wrong ones
    red); heading error; along- and across-track error; and the stretches' factors (share of
    frames with a registered scan, a visual step; the dominant factor as the strip's colour)."""
    fig = plt.figure(figsize=(13, 11))
    grid = fig.add_gridspec(4, 1, height_ratios=[2.6, 1, 1, 1])
    ax_plan = fig.add_subplot(grid[0])
    axes = [fig.add_subplot(grid[k]) for k in (1, 2, 3)]
    for ax in axes[1:]:
        ax.sharex(axes[0])
    p = d.parts
    if d.world is not None:
        occ = d.world.occupancy
        image = np.full(occ.data.shape, 0.85)
        image[occ.data == FREE] = 1.0
        image[occ.data == OCCUPIED] = 0.0
        ax_plan.imshow(image, origin="lower", extent=occ.extent, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    ax_plan.plot(d.truth_xy[:, 0], d.truth_xy[:, 1], "--", color="black", lw=0.8, label="ground truth")
    segments = np.stack([d.estimate_xy[:-1], d.estimate_xy[1:]], axis=1)
    lines = LineCollection(segments, cmap="viridis", lw=1.6)
    lines.set_array(p.position_m[1:])
    ax_plan.add_collection(lines)
    fig.colorbar(lines, ax=ax_plan, label="position error [m]", fraction=0.03, pad=0.01)
    position_of = {int(f): k for k, f in enumerate(d.frames)}
    for wrong in (False, True):
        pairs = [
            (position_of[lp.frame_i], position_of[lp.frame_j])
            for lp in d.loops
            if lp.wrong == wrong and lp.frame_i in position_of and lp.frame_j in position_of
        ]
        for n, (i, j) in enumerate(pairs):
            ax_plan.plot(
                *zip(d.estimate_xy[i], d.estimate_xy[j]),
                color="tab:red" if wrong else "tab:orange",
                lw=1.4 if wrong else 0.6,
                alpha=0.9 if wrong else 0.5,
                label=(f"{'wrong' if wrong else 'right'} loop constraints ({len(pairs)})" if n == 0 else None),
            )
    ax_plan.plot(*d.truth_xy[0], "o", color="tab:green", ms=7, label="start")
    ax_plan.plot(*d.truth_xy[-1], "s", color="tab:red", ms=7, label="end")
    margin = 3.0
    both = np.concatenate([d.truth_xy, d.estimate_xy])
    ax_plan.set_xlim(both[:, 0].min() - margin, both[:, 0].max() + margin)
    ax_plan.set_ylim(both[:, 1].min() - margin, both[:, 1].max() + margin)
    ax_plan.set_aspect("equal")
    ax_plan.set_xlabel("x [m]")
    ax_plan.set_ylabel("y [m]")
    ax_plan.legend(loc="upper left", fontsize=8)
    ax_plan.set_title(title or f"{Path(d.run).name}: error along the route")

    axes[0].plot(p.distance_m, p.heading_deg, color="tab:purple", lw=1.0)
    axes[0].set_ylabel("heading error [deg]")
    axes[1].plot(p.distance_m, p.along_m, color="tab:blue", lw=1.0, label="along track (+ ahead)")
    axes[1].plot(p.distance_m, p.across_m, color="tab:orange", lw=1.0, label="across track (+ left)")
    axes[1].set_ylabel("position error [m]")
    axes[1].legend(loc="upper left", fontsize=8)
    starts = np.array([s.start_m for s in d.stretches])
    widths = np.array([s.end_m - s.start_m for s in d.stretches])
    if d.has_frontend_table:
        axes[2].bar(
            starts,
            [s.scan_share for s in d.stretches],
            widths,
            align="edge",
            color="tab:blue",
            alpha=0.5,
            label="frames with a registered scan",
        )
        axes[2].step(
            np.append(starts, starts[-1] + widths[-1]),
            np.append([s.visual_share for s in d.stretches], d.stretches[-1].visual_share),
            where="post",
            color="tab:green",
            label="frames with a visual step",
        )
    for s in d.stretches:  # the dominant factor as a strip under the bars
        axes[2].axvspan(s.start_m, s.end_m, ymin=0.0, ymax=0.06, color=FACTOR_COLOURS.get(s.dominant, "white"), lw=0)
    for lp in d.loops:
        if lp.frame_j in position_of:
            axes[2].axvline(
                p.distance_m[position_of[lp.frame_j]],
                color="tab:red" if lp.wrong else "tab:orange",
                lw=1.2 if lp.wrong else 0.4,
                alpha=0.8,
            )
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for k, c in FACTOR_COLOURS.items() if k]
    first = axes[2].legend(loc="upper right", fontsize=7)
    axes[2].add_artist(first)
    axes[2].legend(handles, [f"dominant: {k}" for k in FACTOR_COLOURS if k], loc="lower right", fontsize=7, ncol=4)
    axes[2].set_ylim(0, 1.05)
    axes[2].set_ylabel("share of frames")
    axes[2].set_xlabel("distance travelled [m] (loop constraints as vertical lines, at their later frame)")
    regions = [(s.start_m + (s.end_m - s.start_m) / 2, s.region) for s in d.stretches if s.region]
    for x, name in regions:
        axes[0].annotate(
            name,
            (x, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(0, 2),
            textcoords="offset points",
            ha="center",
            va="bottom",
            fontsize=6,
            rotation=90,
            color="0.35",
        )
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    out = Path(out)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=100, format=out.suffix.lstrip(".") or "png")
    plt.close(fig)
