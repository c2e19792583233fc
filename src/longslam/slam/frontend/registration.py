"""Point-to-line registration of a 2D scan against the local map, with an optional pose prior.

Gauss-Newton over the robot's planar pose (x, y, yaw) with Huber weights. The scan term's
Hessian J^T W J / sigma^2 is returned as the information of the result: along a straight
corridor every line normal points across it, so the Hessian has (near) zero along the corridor
and a smoother fusing it takes that direction from the other factors.

Pose convention: world point = R(yaw) p + (x, y), yaw perturbed about the robot's position.
`information_in_body` converts the Hessian to GTSAM's Pose2 tangent (body-frame translation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.geometry import wrap_angle
from longslam.core.parameter import check_declared, param
from longslam.slam.frontend.local_map import LocalMap


@dataclass(frozen=True)
class RegistrationConfig:
    iterations: int = param(10, "Gauss-Newton iterations of scan-to-map registration", at_least=1)
    max_match_distance: float = param(
        0.3, "distance between a scan point and its nearest map point for a match", above=0, unit="m"
    )
    huber: float = param(0.05, "Huber threshold of a point-to-line residual", above=0, unit="m")
    sigma: float = param(0.03, "point-to-line noise of one scan point", above=0, unit="m")
    # Neighbouring 5 cm cells of one wall are not independent views: a 200-point scan is not 200
    # independent measurements.
    correlation: float = param(10.0, "the registration's Hessian is divided by this in the smoother", above=0)
    min_matches: int = param(
        15, "matched scan points a registration needs", at_least=3, why="a planar pose has three unknowns"
    )
    tolerance: float = param(1e-4, "step norm that ends the iterations", above=0)

    def __post_init__(self) -> None:
        check_declared(self, "front end", "registration.")


@dataclass
class RegistrationResult:
    pose: np.ndarray  # (3,) x, y, yaw
    hessian: np.ndarray  # (3, 3) information of the scan term alone, world x, y and yaw
    matches: int
    rmse: float  # m, point-to-line, matched points
    ok: bool


def register(
    scan_xy: np.ndarray,
    guess: np.ndarray,
    local_map: LocalMap,
    prior_information: np.ndarray | None = None,
    config: RegistrationConfig | None = None,
    weight: float = 1.0,
    point_sigma: np.ndarray | None = None,
) -> RegistrationResult:
    """Align base-frame `scan_xy` (N, 2) to `local_map`, starting at (and pulled towards,
    with `prior_information`) the planar pose `guess`. `weight` scales the scan term's
    information (noisy depth: `depth_trust.scan_weight`). `point_sigma` (N,), each point's own
    range noise (m), weighs each point by sigma^2 / (sigma^2 + its noise^2) and widens its Huber
    threshold by its noise."""
    cfg = config or RegistrationConfig()
    guess = np.asarray(guess, dtype=np.float64)
    pose = guess.copy()
    empty = RegistrationResult(pose, np.zeros((3, 3)), 0, float("nan"), False)
    if local_map.tree is None or len(scan_xy) < cfg.min_matches:
        return empty
    prior = np.zeros((3, 3)) if prior_information is None else np.asarray(prior_information, dtype=np.float64)
    hessian = np.zeros((3, 3))
    weighed: tuple[np.ndarray, np.ndarray] | None = None  # each point's (weight, Huber threshold)
    if point_sigma is not None:
        noise2 = np.asarray(point_sigma, dtype=np.float64) ** 2
        weighed = (cfg.sigma**2 / (cfg.sigma**2 + noise2), np.sqrt(cfg.huber**2 + noise2))
    matches, rmse = 0, float("nan")
    for _ in range(cfg.iterations):
        c, s = np.cos(pose[2]), np.sin(pose[2])
        rotated = scan_xy @ np.array([[c, s], [-s, c]])
        world = rotated + pose[:2]
        dist, idx = local_map.tree.query(world, k=1, distance_upper_bound=cfg.max_match_distance)
        hit = np.isfinite(dist)
        matches = int(hit.sum())
        if matches < cfg.min_matches:
            return empty
        n = local_map.normals[idx[hit]]
        q = local_map.points[idx[hit]]
        rot = rotated[hit]
        r = np.einsum("ij,ij->i", n, world[hit] - q)
        # d(world)/d(yaw) = perpendicular of the rotated point.
        j = np.column_stack([n[:, 0], n[:, 1], n[:, 0] * -rot[:, 1] + n[:, 1] * rot[:, 0]])
        a = np.abs(r)
        if weighed is None:
            w = np.where(a <= cfg.huber, 1.0, cfg.huber / np.maximum(a, 1e-12))
        else:
            limit = weighed[1][hit]
            w = np.where(a <= limit, 1.0, limit / np.maximum(a, 1e-12)) * weighed[0][hit]
        scale = weight / (cfg.sigma**2 * cfg.correlation)
        hessian = (j * w[:, None]).T @ j * scale
        gradient = (j * (w * r)[:, None]).sum(axis=0) * scale
        diff = pose - guess
        diff[2] = wrap_angle(diff[2])
        lhs = hessian + prior
        rhs = -(gradient + prior @ diff)
        try:
            delta = np.linalg.solve(lhs + 1e-9 * np.eye(3), rhs)
        except np.linalg.LinAlgError:
            return empty
        pose = pose + delta
        pose[2] = float(wrap_angle(pose[2]))
        rmse = float(np.sqrt(np.mean(r * r)))
        if np.linalg.norm(delta) < cfg.tolerance:
            break
    return RegistrationResult(pose, hessian, matches, rmse, True)


def information_in_body(hessian_world: np.ndarray, yaw: float) -> np.ndarray:
    """World (x, y, yaw) information -> GTSAM Pose2 tangent (body dx, dy, dyaw) information."""
    c, s = np.cos(yaw), np.sin(yaw)
    a = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return a.T @ hessian_world @ a
