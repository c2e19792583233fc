"""Your own SLAM method in longslam, in about 40 lines: frames in, a pose per frame, a result.

    python examples/own_method.py [WORK_DIR]

`Smoothed` is dead reckoning with each step's heading change damped: a toy, but a method as
longslam runs one. To put it in a study, register its spec in your package's pyproject.toml:

    [project.entry-points."longslam.methods"]
    smoothed = "mypackage.module:SPEC"
"""

from __future__ import annotations

import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from longslam.run.engine import run_frames
from longslam.slam.api import MethodContext, MethodSpec, Result
from longslam.core.trajectory import Trajectory


@dataclass(frozen=True)
class SmoothedConfig:
    damping: float = 0.5  # share of each step's rotation kept (1: plain dead reckoning)

    def __post_init__(self) -> None:
        if not 0.0 < self.damping <= 1.0:
            raise ValueError(f"damping={self.damping}: expected (0, 1]")


class Smoothed:
    name = "smoothed"

    def __init__(self, context: MethodContext, config: SmoothedConfig):
        self.config, self.stamps, self.poses, self.previous = config, [], [], None

    def step(self, frame) -> np.ndarray:
        odometry = np.asarray(frame.odometry, dtype=np.float64)
        if self.previous is None:
            pose = odometry
        else:  # the odometry's step, its rotation damped, applied to the last estimate
            step = np.linalg.inv(self.previous[0]) @ odometry
            angle = np.arctan2(step[0, 2], step[0, 0]) * self.config.damping
            c, s = np.cos(angle), np.sin(angle)
            step[:3, :3] = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # about the camera's y (down)
            pose = self.previous[1] @ step
        self.previous = (odometry, pose)
        self.stamps.append(frame.timestamp)
        self.poses.append(pose)
        return pose

    def finish(self) -> Result:
        trajectory = Trajectory(np.array(self.stamps), np.array(self.poses))
        return Result(trajectory, trajectory, stats={"frames": len(self.poses)})


SPEC = MethodSpec("smoothed", SmoothedConfig, Smoothed, "dead reckoning with damped turns (an example)")


def main(work: Path) -> dict:
    from longslam.io.sequence import SequenceReader
    from longslam.run.score import score
    from longslam.sim.camera import CameraSettings
    from longslam.core.odometry_noise import get_noise
    from longslam.sim.routes import Route
    from longslam.sim.simulate import simulate
    from longslam.slam import catalog

    route = Route("corner", "university", ((20.0, 31.25), (28.0, 31.25)))
    sequence = simulate(route, get_noise("large"), seed=0, out=work / "seq", camera=CameraSettings(width=64, height=48),
                        overwrite=True, progress=False)
    reader = SequenceReader(sequence)
    # The harness finds methods by name: here the spec goes in by hand, as an entry point would put it.
    if "smoothed" not in catalog.METHODS:
        catalog.METHODS.register("smoothed", SPEC)
    context = MethodContext(reader.intrinsics, reader.max_depth)
    result, measurements = run_frames(catalog.choose_method("smoothed", {"damping": 0.8}), reader, context, progress=False)
    scores = score(reader.ground_truth, result.trajectory)
    print(f"smoothed: ATE {scores['ate']:.3f} m over {measurements.frames} frames, "
          f"peak {measurements.peak_rss_bytes / 1e6:.0f} MB, CPU wait share {measurements.cpu_wait_share:.2f}")
    return scores


if __name__ == "__main__":
    if len(sys.argv) > 1:
        main(Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            main(Path(tmp))
