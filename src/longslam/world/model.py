"""A world: the mesh the camera sees, the ground-truth occupancy grid, and named places."""

from __future__ import annotations

from dataclasses import dataclass, field

from longslam.core.gridmap import GridMap
from longslam.world.layout import FloorPlan
from longslam.world.world_mesh import WorldMesh


@dataclass
class World:
    name: str
    mesh: WorldMesh
    occupancy: GridMap  # ground truth at 5 cm: 0 free, 100 occupied, -1 unknown
    floor_z: float = 0.0  # height of the floor the robot drives on
    places: dict[str, tuple[float, float]] = field(default_factory=dict)  # named (x, y) spots on the floor
    plan: FloorPlan | None = None  # the floor plan, for worlds built from one
    # For a mesh file: the height (metres, z up) in the file at which its floor was found or
    # given; the world's mesh is moved down by it, so its floor is z = 0.
    source_floor_z: float = 0.0
