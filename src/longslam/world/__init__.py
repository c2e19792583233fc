"""longslam.world: buildings as textured meshes, their ground-truth occupancy, named places.

`get_world(name)` returns a registered world (`catalog.py`), built once per process;
`load_mesh_world(path)` makes a world of a user's own building mesh; `world_ref(name or file)`
and `load_world(ref)` take either (`reference.py`).
"""

from __future__ import annotations

from longslam.world.annex import annex_plan
from longslam.world.builder import build_mesh
from longslam.world.catalog import WORLDS, get_world, world_from_plan
from longslam.world.layout import Box, FloorPlan, Rect
from longslam.world.model import World
from longslam.world.own_building import load_mesh_world
from longslam.world.reference import load_world, world_key, world_label, world_ref
from longslam.world.university import university_plan
from longslam.world.world_mesh import WorldMesh

__all__ = [
    "WORLDS",
    "Box",
    "FloorPlan",
    "Rect",
    "World",
    "WorldMesh",
    "annex_plan",
    "build_mesh",
    "get_world",
    "load_mesh_world",
    "load_world",
    "university_plan",
    "world_from_plan",
    "world_key",
    "world_label",
    "world_ref",
]
