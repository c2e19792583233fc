"""longslam's factor graphs over planar poses (x, y, yaw), the one place that builds GTSAM graphs.

- `pose_graph.py`: `PoseGraph`, the methods' graph (keyframe nodes, submap origins): edges with
  sigmas or a full information, robust kernels, `try_loop` with rollback.
- `factors.py`: `FactorGraph`, poses and wheel-bias states with priors, between factors and the
  wheel-bias factor, for the front end's full-rate smoother.
- `noise.py`: diagonal, full-information and robust noise models.
- `solver.py`: the Levenberg-Marquardt loop (and GTSAM's own, for graphs of GTSAM factors only).
"""

from longslam.slam.graph.noise import ROBUST_KERNELS
from longslam.slam.graph.pose_graph import (
    ANCHOR_SIGMAS,
    LOOP,
    ODOMETRY,
    REGISTRATION,
    Edge,
    EdgeError,
    LoopCheck,
    PoseGraph,
)

__all__ = [
    "ANCHOR_SIGMAS",
    "LOOP",
    "ODOMETRY",
    "REGISTRATION",
    "ROBUST_KERNELS",
    "Edge",
    "EdgeError",
    "LoopCheck",
    "PoseGraph",
]
