"""The registered worlds: `WORLDS` by name (`university`, `annex`), each built once per process."""

from __future__ import annotations

import functools
from collections.abc import Callable

from longslam.core.registry import Registry
from longslam.world.annex import TEXTURE_SEED as _ANNEX_SEED
from longslam.world.annex import annex_plan
from longslam.world.builder import build_mesh
from longslam.world.layout import FloorPlan
from longslam.world.model import World
from longslam.world.university import university_plan

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
