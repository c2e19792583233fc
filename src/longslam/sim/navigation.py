"""Where the robot can drive, and the shortest paths between waypoints on that grid."""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from skimage.graph import MCP_Geometric

from longslam.core.errors import InputError
from longslam.core.gridmap import FREE, GridMap


class NavigationGrid:
    """Traversable cells for a round robot of `robot_radius` on a coarse grid.

    Paths cost more near walls (up to `clearance` metres away), so the robot keeps to the middle
    of corridors and doors as a person would rather than shaving corners.
    """

    def __init__(
        self,
        occupancy: GridMap,
        robot_radius: float = 0.2,
        resolution: float = 0.1,
        clearance: float = 0.8,
        wall_penalty: float = 4.0,
    ):
        factor = max(1, int(round(resolution / occupancy.resolution)))
        free = occupancy.data == FREE
        clearance_fine = ndimage.distance_transform_edt(free) * occupancy.resolution
        rows, cols = (s // factor * factor for s in free.shape)
        # A coarse cell's clearance is its worst fine cell's, so a coarse path never grazes a wall.
        blocks = clearance_fine[:rows, :cols].reshape(rows // factor, factor, cols // factor, factor)
        self.clearance_m = blocks.min(axis=(1, 3))
        self.resolution = occupancy.resolution * factor
        self.origin = occupancy.origin
        self.robot_radius = robot_radius
        self.traversable = self.clearance_m > robot_radius
        closeness = np.clip((clearance - self.clearance_m) / clearance, 0.0, 1.0)
        self.costs = np.where(self.traversable, 1.0 + wall_penalty * closeness**2, np.inf)
        self._grid = GridMap(np.zeros(self.traversable.shape, np.int8), self.resolution, self.origin)

    def cell(self, xy: tuple[float, float]) -> tuple[int, int]:
        rc = self._grid.world_to_cell(np.asarray(xy))[0]
        return int(rc[0]), int(rc[1])

    def is_traversable(self, xy: tuple[float, float]) -> bool:
        r, c = self.cell(xy)
        rows, cols = self.traversable.shape
        return 0 <= r < rows and 0 <= c < cols and bool(self.traversable[r, c])

    def check_waypoint(self, xy: tuple[float, float], label: str) -> None:
        if not self.is_traversable(xy):
            raise InputError(
                f"{label} ({xy[0]:.2f}, {xy[1]:.2f}) is not on free floor: it is inside a wall or "
                f"furniture, outside the building, or closer than {self.robot_radius} m to an obstacle"
                f"{self._nearest_hint(xy, self.traversable)}"
            )

    def check_reachable(self, waypoints: list[tuple[float, float]], labels: list[str]) -> None:
        """Every waypoint (each already on free floor) can be reached from the first: refuses the
        first one that lies in a part of the floor the robot cannot drive to (8-connected cells,
        as the path search moves)."""
        parts, _ = ndimage.label(self.traversable, structure=np.ones((3, 3), dtype=bool))
        start = parts[self.cell(waypoints[0])]
        for xy, label in zip(waypoints[1:], labels[1:]):
            if parts[self.cell(xy)] != start:
                raise InputError(
                    f"{label} ({xy[0]:.2f}, {xy[1]:.2f}) cannot be reached from {labels[0]} "
                    f"({waypoints[0][0]:.2f}, {waypoints[0][1]:.2f}): no way through for a robot of radius "
                    f"{self.robot_radius} m{self._nearest_hint(xy, parts == start, 'reachable')}"
                )

    def _nearest_hint(self, xy: tuple[float, float], allowed: np.ndarray, what: str = "free") -> str:
        """'; the nearest free point is (x, y)', or nothing if no cell is allowed."""
        if not allowed.any():
            return "; the floor has no free point at all (is the floor height right?)"
        _, (rows, cols) = ndimage.distance_transform_edt(~allowed, return_indices=True)
        r, c = self.cell(xy)
        r = int(np.clip(r, 0, allowed.shape[0] - 1))
        c = int(np.clip(c, 0, allowed.shape[1] - 1))
        x, y = self._grid.cell_to_world(np.array([[rows[r, c], cols[r, c]]]))[0]
        return f"; the nearest {what} point is ({x:.2f}, {y:.2f})"

    def shortest_path(self, start: tuple[float, float], goal: tuple[float, float]) -> np.ndarray:
        """(N, 2) world polyline from start to goal through traversable cells, smoothed."""
        self.check_waypoint(start, "start")
        self.check_waypoint(goal, "goal")
        mcp = MCP_Geometric(self.costs, fully_connected=True)
        g = self.cell(goal)
        cumulative, _ = mcp.find_costs([self.cell(start)], [g])
        if not np.isfinite(cumulative[g]):
            raise InputError(f"no path from ({start[0]:.2f}, {start[1]:.2f}) to ({goal[0]:.2f}, {goal[1]:.2f})")
        return self._polyline(mcp, start, goal)

    def path_lengths(self, start: tuple[float, float], goals: list[tuple[float, float]]) -> np.ndarray:
        """The length in metres of `shortest_path(start, goal)` for every goal (inf where there is
        none), from one search of the grid."""
        self.check_waypoint(start, "start")
        mcp = MCP_Geometric(self.costs, fully_connected=True)
        cumulative, _ = mcp.find_costs([self.cell(start)])
        lengths = np.full(len(goals), np.inf)
        for i, goal in enumerate(goals):
            if self.is_traversable(goal) and np.isfinite(cumulative[self.cell(goal)]):
                lengths[i] = np.linalg.norm(np.diff(self._polyline(mcp, start, goal), axis=0), axis=1).sum()
        return lengths

    def _polyline(self, mcp: MCP_Geometric, start: tuple[float, float], goal: tuple[float, float]) -> np.ndarray:
        cells = np.asarray(mcp.traceback(self.cell(goal)), dtype=np.float64)
        xy = _smooth(self._grid.cell_to_world(cells), window=7)
        xy[0], xy[-1] = start, goal
        return _dedupe(xy)


def _smooth(xy: np.ndarray, window: int) -> np.ndarray:
    """Moving average that keeps the ends: takes the staircase out of 8-connected grid paths."""
    if len(xy) <= window:
        return xy
    pad = window // 2
    padded = np.concatenate([np.repeat(xy[:1], pad, 0), xy, np.repeat(xy[-1:], pad, 0)])
    kernel = np.ones(window) / window
    return np.column_stack([np.convolve(padded[:, i], kernel, mode="valid") for i in range(2)])


def _dedupe(xy: np.ndarray) -> np.ndarray:
    keep = np.concatenate([[True], np.linalg.norm(np.diff(xy, axis=0), axis=1) > 1e-6])
    return xy[keep]
