"""evo_ape's two figures of one evaluation, side by side: the estimate over the floor plane
coloured by its absolute pose error, with the reference dashed; and that error over time with
its rmse, median and mean as lines and mean +- std as a band.

Figures are built on matplotlib's object API, not pyplot, so saving needs no display and does not
change the process's backend; `show` alone goes through pyplot.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from longslam.core.errors import InputError
from longslam.eval.evaluation import Evaluation
from longslam.eval.relations import EVO_NAMES
from longslam.eval.units import units_of
from longslam.io.atomic import atomic_path

SAVE_SUFFIXES = (".png", ".pdf")


ALIGNED = {
    "none": "not aligned",
    "se3": "SE(3) Umeyama alignment",
    "sim3": "Sim(3) Umeyama alignment",
    "scale": "scale corrected",
    "origin": "origin alignment",
}


def _unit(evaluation: Evaluation) -> str:
    return units_of(evaluation.scores)["ape_rmse"]


def _label(evaluation: Evaluation) -> str:
    unit = _unit(evaluation)
    return f"APE, {EVO_NAMES[evaluation.scores['ape_pose_relation']]}" + (f" [{unit}]" if unit else " (unit-less)")


def draw(fig: Figure, evaluation: Evaluation, title: str = "") -> Figure:
    """Draw both panels into `fig`."""
    errors = evaluation.ape_errors
    ref, est = evaluation.reference, evaluation.aligned
    label = _label(evaluation)
    left, right = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.15, 1.0]})

    # The trajectory coloured by error (evo's plot.traj_colormap), the reference dashed (evo's style).
    # Drawn over the estimate: under a thick coloured line a close reference would vanish.
    left.plot(
        ref.positions[:, 0], ref.positions[:, 1], ls="--", color="black", lw=0.9, alpha=0.8, label="reference", zorder=3
    )
    xy = est.positions[:, :2]
    segments = np.stack([xy[:-1], xy[1:]], axis=1)
    lines = LineCollection(segments, cmap="jet", linewidths=2.5, zorder=2)
    lines.set_array((errors[:-1] + errors[1:]) / 2)
    lines.set_clim(float(errors.min()), float(errors.max()))
    left.add_collection(lines)
    left.plot(*xy[0], "o", color="black", ms=6, label="start", zorder=4)
    left.plot(*xy[-1], "s", color="black", ms=6, label="end", zorder=4)
    fig.colorbar(lines, ax=left, label=label, shrink=0.85)
    left.set_aspect("equal", adjustable="datalim")
    left.autoscale_view()
    left.set_xlabel("x [m]")
    left.set_ylabel("y [m]")
    left.set_title(f"estimate coloured by APE ({ALIGNED[evaluation.scores['align']]})")
    left.legend(loc="best", fontsize=8)
    left.grid(alpha=0.3)

    # The error over time with its statistics (evo's plot.error_array with statistics).
    seconds = est.timestamps - est.timestamps[0]
    stats = {k: evaluation.scores[f"ape_{k}"] for k in ("rmse", "median", "mean", "std")}
    unit = f" {_unit(evaluation)}" if _unit(evaluation) else ""
    right.plot(seconds, errors, color="tab:grey", lw=1.0, label="APE")
    # evo's colours: rmse blue, median green, mean red, mean +- std an olive band.
    right.axhline(stats["rmse"], color="tab:blue", lw=1.5, label=f"rmse {stats['rmse']:.4g}{unit}")
    right.axhline(stats["median"], color="tab:green", lw=1.5, label=f"median {stats['median']:.4g}{unit}")
    right.axhline(stats["mean"], color="tab:red", lw=1.5, label=f"mean {stats['mean']:.4g}{unit}")
    right.axhspan(
        stats["mean"] - stats["std"],
        stats["mean"] + stats["std"],
        color="tab:olive",
        alpha=0.3,
        label=f"mean +- std ({stats['std']:.4g}{unit})",
    )
    right.set_xlabel("time from start [s]")
    right.set_ylabel(label)
    right.set_title("error over time")
    right.legend(loc="best", fontsize=8, framealpha=0.85)
    right.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def save_plot(evaluation: Evaluation, out: str | Path, title: str = "", overwrite: bool = False) -> Path:
    """Both panels in one PNG or PDF file (written under a temporary name, then renamed)."""
    out = Path(out)
    if out.suffix.lower() not in SAVE_SUFFIXES:
        raise InputError(f"--save-plot {out}: expected a file ending in {', '.join(SAVE_SUFFIXES)}")
    fig = draw(Figure(figsize=(13, 5.2)), evaluation, title)
    with atomic_path(out, overwrite=overwrite) as tmp:
        fig.savefig(tmp, dpi=110, format=out.suffix.lower().lstrip("."))
    return out


NON_INTERACTIVE = ("agg", "pdf", "svg", "ps", "cairo", "template", "pgf")


def check_can_show() -> None:
    """Refuse --plot where no window can open: matplotlib falls back to a file-only backend
    (Agg) when there is no display, and `show` would then return at once, showing nothing."""
    import matplotlib

    backend = matplotlib.get_backend()
    if backend.lower() in NON_INTERACTIVE:
        raise InputError(
            f"--plot needs a display, and matplotlib's backend is {backend!r} (no display found); "
            "use --save-plot FILE.png instead"
        )


def show_plot(evaluation: Evaluation, title: str = "") -> None:
    """Both panels in a window (needs a display and an interactive matplotlib backend)."""
    import matplotlib.pyplot as plt

    check_can_show()
    draw(plt.figure(figsize=(13, 5.2)), evaluation, title)
    plt.show()
