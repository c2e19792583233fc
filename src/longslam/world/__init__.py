"""longslam.world: buildings as textured meshes, their ground-truth occupancy, named places.

`get_world(name)` returns a registered world, built once per process; `load_mesh_world(path)`
makes a world of a user's own building mesh; `world_ref(name or file)` and `load_world(ref)`
take either (see `longslam.world.source`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

from longslam.registry import Registry
from longslam.world.builder import build_mesh
from longslam.world.external import load_mesh_world
from longslam.world.layout import Box, FloorPlan, Rect
from longslam.world.mesh import WorldMesh
from longslam.world.annex import TEXTURE_SEED as _ANNEX_SEED, annex_plan
from longslam.world.university import university_plan
from longslam.world.world import World

WORLDS: Registry[Callable[[], World]] = Registry("world")


def world_from_plan(plan: FloorPlan, seed: int = 0, resolution: float = 0.05) -> World:
    """A world built from a floor plan: its textured mesh, occupancy grid and places."""
    return World(
        name=plan.name,
        mesh=build_mesh(plan, seed=seed),
        occupancy=plan.occupancy(resolution),
        floor_z=0.0,
        places=dict(plan.places),
        plan=plan,
    )


@WORLDS.decorator("university")
def _university() -> World:
    return world_from_plan(university_plan(), seed=0)


@WORLDS.decorator("annex")
def _annex() -> World:
    return world_from_plan(annex_plan(), seed=_ANNEX_SEED)


@functools.lru_cache(maxsize=None)
def get_world(name: str) -> World:
    """The registered world `name`, built on first use and shared afterwards (treat it as
    read-only). Unknown names raise `UnknownNameError` listing the valid ones."""
    return WORLDS.get(name)()


from longslam.world.source import load_world, world_key, world_label, world_ref  # noqa: E402 (needs WORLDS)

__all__ = [
    "WORLDS", "Box", "FloorPlan", "Rect", "World", "WorldMesh", "annex_plan", "build_mesh", "get_world", "load_mesh_world",
    "load_world", "university_plan", "world_from_plan", "world_key", "world_label", "world_ref",
]
