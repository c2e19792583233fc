"""Map quality of run folders, scored as the study's Table 3 is (docs/paper-reproduction.md).

    python benchmarks/maps.py RUN SEQUENCE [RUN SEQUENCE ...] [--plot-dir DIR] [--view X0 X1 Y0 Y1]

For each run folder (its grid.npz and trajectory.txt) and the sequence it ran on: precision and
recall of its occupied cells within 2 cells, as the map is and after its best planar alignment,
and the share of observed walls it shows twice (`eval.map_quality.map_scores`, with the walls the
camera could see from the sequence's ground truth, `observed_walls`, as `study.prepare` finds
them). With --plot-dir, each run's map over the true walls (`viz.plots.plot_map_over_truth`),
as RUN-NAME.png, over --view (x0 x1 y0 y1, metres; default the whole map).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from longslam.eval.map_quality import map_scores, observed_walls
from longslam.core.geometry.planar import planar_from_camera_poses
from longslam.core.gridmap import GridMap
from longslam.io.trajectory_files import read_tum
from longslam.world import load_world
from longslam.io.grid_files import read_grid

KEYS = ("map_precision", "map_recall", "map_precision_aligned", "map_recall_aligned", "map_doubled_walls")


def score_run(run: Path, sequence: Path) -> tuple[dict, GridMap, GridMap]:
    """(scores, the run's grid, the world's grid) of one run folder against its sequence."""
    meta = json.loads((sequence / "meta.json").read_text(encoding="utf-8"))
    camera = meta["camera"]
    world = load_world(meta["world"])
    truth = read_tum(sequence / "groundtruth.txt")
    observed = observed_walls(world.occupancy, planar_from_camera_poses(truth.poses, camera["camera_height"]),
                              camera["hfov_deg"], camera["max_depth"])
    grid = read_grid(run / "grid.npz")
    estimate = read_tum(run / "trajectory.txt")
    # As study.run_scores does for align 'none': the map as it is, at the trajectory's height.
    scores = map_scores(grid, world.occupancy, 2.0, observed, height=float(np.mean(estimate.positions[:, 2])),
                        with_places=True)
    return scores, grid, world.occupancy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pairs", nargs="+", type=Path, help="RUN SEQUENCE pairs")
    parser.add_argument("--plot-dir", type=Path)
    parser.add_argument("--view", type=float, nargs=4, metavar=("X0", "X1", "Y0", "Y1"))
    args = parser.parse_args()
    if len(args.pairs) % 2:
        parser.error("give RUN SEQUENCE pairs")
    print("| run | " + " | ".join(KEYS) + " |")
    print("|---" * (len(KEYS) + 1) + "|")
    for run, sequence in zip(args.pairs[::2], args.pairs[1::2]):
        scores, grid, truth = score_run(run, sequence)
        print(f"| {run} | " + " | ".join(f"{scores[k]:.4f}" for k in KEYS) + " |")
        if args.plot_dir:
            from longslam.viz.plots import plot_map_over_truth

            args.plot_dir.mkdir(parents=True, exist_ok=True)
            title = (f"{run.name}: precision {scores['map_precision']:.3f}, recall {scores['map_recall']:.3f} "
                     f"(aligned {scores['map_precision_aligned']:.3f}, {scores['map_recall_aligned']:.3f})")
            plot_map_over_truth(grid, truth, args.plot_dir / f"{run.name}.png", view=tuple(args.view) if args.view else None,
                                doubled=scores["map_doubled_places"], title=title, width=8.0, dpi=80)


if __name__ == "__main__":
    main()
