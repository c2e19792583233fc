"""Evaluate your own trajectory against a longslam sequence.

    python examples/evaluate_own_trajectory.py [WORK_DIR]

Simulates a short sequence (12 m round the corner of junction_a at 64 x 48 pixels, so it takes
seconds), writes a "trajectory of yours" (the noisy odometry with a drift added, in TUM format),
and scores it as `longslam evaluate TRAJ SEQ` would: the paper's ATE, E_trans and E_rot and the
field's APE and RPE, with and without an SE(3) alignment.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from longslam.io.sequence import SequenceReader
from longslam.io.trajectory_files import read_tum, write_tum
from longslam.run.score import score
from longslam.sim.camera import CameraSettings
from longslam.core.odometry_noise import get_noise
from longslam.sim.routes import Route
from longslam.sim.simulate import simulate
from longslam.core.trajectory import Trajectory


def main(work: Path) -> dict:
    route = Route("corner", "university", ((22.0, 31.25), (29.25, 31.25), (29.25, 36.0)))  # a turn: SE(3) alignment needs one
    sequence = simulate(route, get_noise("large"), seed=0, out=work / "seq", camera=CameraSettings(width=64, height=48),
                        overwrite=True, progress=False)

    # Your SLAM system's output would go here: a TUM file of camera-in-world poses.
    odometry = read_tum(sequence / "odometry.txt")
    poses = odometry.poses.copy()
    poses[:, 1, 3] += np.linspace(0.0, 0.3, len(poses))  # a drift of 30 cm sideways
    write_tum(work / "mine.txt", Trajectory(odometry.timestamps, poses))

    truth = SequenceReader(sequence).ground_truth
    plain = score(truth, read_tum(work / "mine.txt"))
    aligned = score(truth, read_tum(work / "mine.txt"), align="se3")
    print(f"ATE {plain['ate']:.3f} m, E_trans {plain['e_trans']:.4f}, E_rot {plain['e_rot']:.4f} deg/m; "
          f"APE RMSE after SE(3) alignment {aligned['ape_rmse']:.3f} m")
    return plain


if __name__ == "__main__":
    if len(sys.argv) > 1:
        main(Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            main(Path(tmp))
