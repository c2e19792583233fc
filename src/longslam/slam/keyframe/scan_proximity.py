"""Proximity links by scan matching (RTAB-Map's RGBD/ProximityBySpace with Reg/Strategy 1, ICP).

A visual proximity link needs the two nodes to have looked the same way. A robot that drives a
corridor back the way it came sees the same walls from the other side of their ends, and a
camera sees none of what it saw before. The walls themselves are the same: the new node's
obstacle cells (its local grid, the band the 2D map is made of) are registered point-to-line
against those of older nodes nearby, at their graph estimates, with the front end's scan
registration. The result's Hessian is the link's information: along a straight corridor it has
(next to) nothing, and the link holds only the across-track position and the heading.

Older nodes count only if they shared open space with the new one (one stood where the other's
rays went through): a node in the office behind a corridor wall saw the wall's other face, 0.2 m
from this one, which a registration would happily snap to.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.geometry import relative_xyyaw, wrap_angle
from longslam.slam.frontend.local_map import LocalMap, LocalMapConfig
from longslam.slam.frontend.registration import RegistrationConfig, information_in_body, register
from longslam.slam.keyframe.memory import Node
from longslam.slam.occupancy import LocalGrid


@dataclass(frozen=True)
class ScanLinkSettings:
    radius: float  # m: older nodes whose estimate lies this near are the map
    min_age: float  # s: and are at least this much older (the front end matched the recent ones)
    max_correction: float  # m: a registration moving the node further is a wrong minimum
    max_correction_angle: float  # rad
    min_overlap: float  # share of the node's cells matched
    max_rmse: float  # m, point-to-line
    sigma_floor: tuple[float, float, float]  # m, m, rad added to the registration's covariance
    min_constraining: int = 10  # matched cells whose wall faces a direction, for the link to hold it


@dataclass
class ScanLink:
    anchor: int  # the older node the link is to
    delta: np.ndarray  # (3,) the new node's pose in the anchor's frame
    information: np.ndarray  # (3, 3) in GTSAM's Pose2 tangent of the new node
    correction: float  # m the registration moved the new node's estimate
    matches: int
    held: tuple[int, ...] = (0, 0)  # matched cells facing the weaker and the stronger direction
    freed: int = 0  # directions left free (too few cells face them)


def shares_open_space(a: np.ndarray, b: np.ndarray, a_grid: LocalGrid) -> bool:
    """Whether robot pose `b` (x, y, yaw) stands in, or next to, a cell that node `a`'s rays
    crossed (a's local grid's free cells)."""
    if not len(a_grid.free):
        return False
    p = relative_xyyaw(a, b)[:2]
    cell = np.floor(p / a_grid.cell).astype(np.int64)
    near = np.abs(a_grid.free.astype(np.int64) - cell).max(axis=1) <= 1
    return bool(near.any())


def scan_link(
    node: Node,
    node_pose: np.ndarray,
    candidates: list[tuple[Node, np.ndarray]],
    settings: ScanLinkSettings,
    registration: RegistrationConfig | None = None,
) -> ScanLink | None:
    """Register `node`'s obstacle cells against `candidates` (older nodes with their graph
    estimates) starting from `node_pose`, its own estimate; None when no candidate shares open
    space with it or the registration is refused."""
    if node.grid is None or not len(node.grid.obstacles):
        return None
    near = [
        (c, pose)
        for c, pose in candidates
        if c.grid is not None
        and len(c.grid.obstacles)
        and (shares_open_space(pose, node_pose, c.grid) or shares_open_space(node_pose, pose, node.grid))
    ]
    if not near:
        return None
    local = LocalMap(LocalMapConfig(max_scans=len(near) + 1, radius=2.0 * settings.radius + 8.0))
    for c, pose in near:
        assert c.grid is not None  # `near` holds only nodes with a grid
        local.insert(pose, c.grid.obstacle_points())
    local.rebuild(node_pose[:2])
    scan = node.grid.obstacle_points()
    # A weak pull to the estimate: along a corridor the walls do not hold the node, and it should
    # stay where the odometry put it rather than slide.
    prior = np.diag([settings.max_correction**-2, settings.max_correction**-2, settings.max_correction_angle**-2])
    result = register(scan, node_pose, local, prior, registration)
    if not result.ok or result.matches < settings.min_overlap * len(scan) or result.rmse > settings.max_rmse:
        return None
    correction = float(np.hypot(*(result.pose[:2] - node_pose[:2])))
    if (
        correction > settings.max_correction
        or abs(wrap_angle(result.pose[2] - node_pose[2])) > settings.max_correction_angle
    ):
        return None
    anchor, anchor_pose = min(near, key=lambda item: float(np.hypot(*(item[1][:2] - result.pose[:2]))))
    body = information_in_body(result.hessian, float(result.pose[2]))
    # The registration's Hessian alone is as sure as 500 independent cells; the floor keeps one
    # link from outweighing the nodes' own odometry where the cells agree too well.
    covariance = np.linalg.inv(body + 1e-6 * np.eye(3)) + np.diag(np.square(settings.sigma_floor))
    directions = np.linalg.eigh(result.hessian[:2, :2])[1].T  # world frame, weaker first
    held = facing_cells(scan, result.pose, local, directions)
    c, s = np.cos(result.pose[2]), np.sin(result.pose[2])
    freed = 0
    for direction, count in zip(directions, held):
        if count < settings.min_constraining:
            # Nothing faces this way: the Hessian's share of it comes from tilted normals, and the
            # registration stayed where the estimate put it. Free it.
            v = np.array([c * direction[0] + s * direction[1], -s * direction[0] + c * direction[1], 0.0])
            covariance = covariance + UNHELD_SIGMA**2 * np.outer(v, v)
            freed += 1
    information = np.linalg.inv(covariance)
    return ScanLink(
        anchor.id,
        relative_xyyaw(anchor_pose, result.pose),
        0.5 * (information + information.T),
        correction,
        result.matches,
        held,
        freed,
    )


# m: the std a link gives a direction no wall cell faces (as good as none, but positive definite).
UNHELD_SIGMA = 100.0
# A cell faces a direction when its wall's normal is within 45 degrees of it.
FACING = np.cos(np.pi / 4)


def facing_cells(
    scan_xy: np.ndarray,
    pose: np.ndarray,
    local: LocalMap,
    directions: np.ndarray,
    max_residual: float = 0.1,
    max_distance: float = 0.3,
) -> tuple[int, ...]:
    """How many of the scan's cells, at `pose` against `local`, match a map cell (within
    `max_distance`, point-to-line within `max_residual`) whose normal faces each of `directions`
    (rows of world-frame unit vectors: the eigen directions of the registration's translation
    information).

    Point-to-line registration along a corridor has an along-track Hessian that is not zero: the
    normals, fitted to a few neighbouring cells, tilt by tens of degrees at wall ends, door frames
    and clutter, and a few hundred such cells add up to a covariance of centimetres along it, even
    for a link metres wrong along the corridor (docs/diagnose.md). No cell faces
    along the corridor, though, and the registration has not moved the node along it (after Tuna
    et al.'s localizability in X-ICP, 2023)."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    world = scan_xy @ np.array([[c, s], [-s, c]]) + pose[:2]
    assert local.tree is not None  # built: the registration searched it
    dist, idx = local.tree.query(world, k=1, distance_upper_bound=max_distance)
    hit = np.isfinite(dist)
    n = local.normals[idx[hit]]
    r = np.abs(np.einsum("ij,ij->i", n, world[hit] - local.points[idx[hit]]))
    n = n[r <= max_residual]
    return tuple(int(np.count_nonzero(np.abs(n @ d) >= FACING)) for d in directions)
