"""Long routes: a route driven N times over, and seeded random tours of a building's places.

Spelled as route names wherever a route is given (`--route`, a study's `routes`):

    paper-1km-x3       the route's waypoints three times over (3 km; a route file works too)
    tour-10km          a random tour of the world's places, at least 10 km long, seed 0
    tour-2500m-seed4   the same with another length and seed

A tour starts at a place drawn from the seed and goes on to places drawn uniformly from the
others (never the one it stands at) until the planned path is at least the length asked for; so
it revisits the corridor, the hall and the rooms many times, which is what long-route loop
closure and memory need. The planned length is the navigation grid's shortest paths; the driven
length is within about 2 % of it (the follower cuts corners).
"""

from __future__ import annotations

import math
import re

import numpy as np

from longslam.core.errors import InputError
from longslam.sim.navigation import NavigationGrid
from longslam.world.model import World

REPEAT = re.compile(r"(?P<base>.+)-x(?P<times>\d+)")
TOUR = re.compile(r"tour-(?P<length>\d+(?:\.\d+)?)(?P<unit>km|m)(?:-seed(?P<seed>\d+))?")
MAX_REPEAT = 1000
# 100 km is about 700,000 frames (some 120 GB of 320 x 240 frames on disk): beyond any study here.
MAX_TOUR_M = 100_000.0
# A leg shorter than this is no step of a tour (two names for one spot): such legs are never
# drawn, so every leg adds at least this much and a tour of L metres has at most L / MIN_LEG_M
# legs. Taking them, two places at one point made a tour that never grew, planned forever.
MIN_LEG_M = 1.0
EXAMPLES = ("paper-1km-x3", "tour-3km", "tour-10km")


def repeated(waypoints: tuple, times: int, name: str) -> tuple:
    """The waypoints `times` times over; a route that ends where it starts is not given the same
    point twice at each join."""
    if not 1 <= times <= MAX_REPEAT:
        raise InputError(f"route {name!r}: a route repeated {times} times; expected 1 to {MAX_REPEAT}")
    joined = list(waypoints)
    for _ in range(times - 1):
        joined += list(waypoints[1:] if waypoints[-1] == waypoints[0] else waypoints)
    return tuple(joined)


def tour_length_m(match: re.Match) -> float:
    """The length a `TOUR` name asks for, in metres (checked)."""
    length = float(match["length"]) * (1000.0 if match["unit"] == "km" else 1.0)
    if not 0 < length <= MAX_TOUR_M:
        raise InputError(
            f"route {match[0]!r}: a tour of {length:g} m; expected more than 0 and at most " f"{MAX_TOUR_M:g} m"
        )
    return length


def tour_waypoints(world: World, length_m: float, seed: int, places: str | None = None) -> tuple[str, ...]:
    """Place names of a random tour of `world`, at least `length_m` long by the planned paths.

    `places` says where the places come from in messages (default: the world)."""
    places = places or f"world {world.name!r}"
    nav = NavigationGrid(world.occupancy)
    names = sorted(p for p, xy in world.places.items() if nav.is_traversable(xy))
    if len(names) < 2:
        raise InputError(f"world {world.name!r} has {len(names)} places the robot can stand on; a tour needs two")
    rng = np.random.default_rng(seed)
    here = names[int(rng.integers(len(names)))]
    legs: dict[str, dict[str, float]] = {}  # one search of the grid per place left from
    tour, total = [here], 0.0
    for _ in range(math.ceil(length_m / MIN_LEG_M)):  # each leg at least MIN_LEG_M: bounded
        if total >= length_m:
            break
        if here not in legs:
            others = [n for n in names if n != here]
            lengths = nav.path_lengths(world.places[here], [world.places[n] for n in others])
            found = {n: float(d) for n, d in zip(others, lengths) if np.isfinite(d)}
            legs[here] = {n: d for n, d in found.items() if d >= MIN_LEG_M}
            if not legs[here] and found:
                near = min(found, key=found.__getitem__)
                pair = " and ".join(repr(n) for n in sorted((here, near)))
                raise InputError(
                    f"{places}: places {pair} are {found[near]:.2f} m apart, and no "
                    f"other place can be reached from {here!r}; a tour goes between places at least "
                    f"{MIN_LEG_M:g} m apart"
                )
        if not legs[here]:
            raise InputError(f"world {world.name!r}: no other place can be reached from place {here!r}")
        reachable = sorted(legs[here])
        step = reachable[int(rng.integers(len(reachable)))]
        total += legs[here][step]
        tour.append(step)
        here = step
    return tuple(tour)
