"""Named waypoint routes through a world, and routes read from a file.

A waypoint is an (x, y) on the floor or the name of one of the world's places. The named
routes follow the paper: `paper-300m` has 12 waypoints, `paper-1km` 25, and both revisit the
corridor and the hall several times, which gives the loop closures the paper depends on.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

from longslam.core.errors import InputError, UnknownNameError
from longslam.core.registry import Registry
from longslam.core.textfile import read_text
from longslam.sim.tours import MAX_REPEAT, REPEAT, TOUR, repeated, tour_length_m, tour_waypoints
from longslam.world.reference import (
    is_mesh_ref,
    load_world,
    places_label,
    same_world,
    world_key,
    world_label,
    world_ref,
)

Waypoint = tuple[float, float] | str


@dataclass(frozen=True)
class Route:
    name: str
    world: str
    waypoints: tuple[Waypoint, ...]

    def waypoints_json(self) -> list:
        """The waypoints as JSON values: place names as they are, coordinates as [x, y]."""
        return [w if isinstance(w, str) else list(w) for w in self.waypoints]

    def to_dict(self) -> dict:
        return {"name": self.name, "world": self.world, "waypoints": self.waypoints_json()}

    @classmethod
    def from_json(cls, name: str, world: str, waypoints: list) -> "Route":
        """The inverse of `waypoints_json`: [x, y] lists become tuples again."""
        return cls(name, world, tuple(w if isinstance(w, str) else tuple(w) for w in waypoints))

    def resolve(self, places: dict[str, tuple[float, float]]) -> list[tuple[float, float]]:
        """Waypoints as (x, y), place names looked up in the world's places."""
        out: list[tuple[float, float]] = []
        for i, wp in enumerate(self.waypoints):
            if isinstance(wp, str):
                if wp not in places:
                    hint = "" if places or not is_mesh_ref(self.world) else " (give a places file: --places FILE)"
                    raise InputError(
                        f"route {self.name!r}: waypoint {i} names place {wp!r}, which world "
                        f"{world_label(self.world)!r} "
                        f"does not have; places: {', '.join(sorted(places)) or '(none)'}{hint}"
                    )
                out.append((float(places[wp][0]), float(places[wp][1])))
            else:
                x, y = float(wp[0]), float(wp[1])
                if not (math.isfinite(x) and math.isfinite(y)):
                    raise InputError(
                        f"route {self.name!r}: waypoint {i} ({x}, {y}) is not a point: expected finite "
                        "x and y in metres"
                    )
                out.append((x, y))
        if len(out) < 2:
            raise InputError(f"route {self.name!r} needs at least two waypoints, has {len(out)}")
        if all(p == out[0] for p in out):  # would drive nowhere: a sequence of one frame
            raise InputError(
                f"route {self.name!r}: its {len(out)} waypoints are all the same point {out[0]}; "
                "a route needs at least two different points"
            )
        return out


ROUTES: Registry[Route] = Registry("route")


def _named(name: str, *waypoints: Waypoint, world: str = "university") -> None:
    ROUTES.register(name, Route(name, world, tuple(waypoints)))


# A loop of about 60 m round the hall's inner pillars, whose first side is driven twice in the
# same direction: enough for a SLAM method to close a loop in a minute of simulated time.
_named("demo", "hall_entry", (114.0, 24.5), (114.0, 38.0), (120.5, 38.0), (120.5, 24.5), (114.0, 24.5), (114.0, 38.0))

# The paper's routes: waypoint sequences picked once (a seeded search over the world's places for
# the target length, visiting the classroom, a side branch and the hall more than once).
_named(
    "paper-300m",
    "hall_sw",
    "hall_center",
    "hall_entry",
    "hall_nw",
    "office_3",
    "junction_c",
    "classroom",
    "office_3",
    "junction_b",
    "office_2",
    "office_4",
    "hall_se",
)

_named(
    "paper-1km",
    "hall_center",
    "branch_c_end",
    "hall_entry",
    "lobby",
    "seminar",
    "office_2",
    "classroom_front",
    "spine_w",
    "junction_a",
    "junction_c",
    "spine_e",
    "office_4",
    "branch_b_end",
    "spine_e",
    "junction_b",
    "hall_nw",
    "branch_a_end",
    "spine_mid",
    "classroom_front",
    "office_3",
    "spine_e",
    "hall_center",
    "hall_entry",
    "hall_sw",
    "spine_e",
)


def load_route_file(path: str | Path, world: str | None = None) -> Route:
    """A route from a file: JSON {"world": ..., "waypoints": [[x, y] or "place", ...]}, or
    text with one waypoint a line (`x y`, or a place name); '#' starts a comment.

    A JSON file's "world" is a world name, a mesh file relative to the route file, or a table
    {"mesh": ..., "floor": ...} (see `longslam.world.world_ref`). `world` (a world reference) is
    the world of a file that names none, default university; a file that names another is refused.
    """
    path = Path(path)
    text = read_text(path, "route file")
    waypoints: list[Waypoint] = []
    given = world
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise InputError(f"route file {path}: not valid JSON ({err})") from None
        if not isinstance(data, dict) or not isinstance(data.get("waypoints"), list):
            raise InputError(f"route file {path}: expected an object with a list field 'waypoints'")
        if "world" in data:
            named = world_ref(data["world"], base=path.parent, what=f"route file {path}: world")
            if given is not None and not same_world(named, given):
                raise InputError(
                    f"route file {path}: world {world_label(named)!r} is not the world given ({world_label(given)!r})"
                )
            world = named
        for i, wp in enumerate(data["waypoints"]):
            if isinstance(wp, str):
                waypoints.append(wp)
            elif isinstance(wp, list) and len(wp) == 2 and all(isinstance(v, (int, float)) for v in wp):
                waypoints.append((float(wp[0]), float(wp[1])))
            else:
                raise InputError(f"route file {path}: waypoints[{i}] = {wp!r}; expected [x, y] or a place name")
    else:
        for number, line in enumerate(text.splitlines(), start=1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            fields = line.replace(",", " ").split()
            if len(fields) == 1:
                waypoints.append(fields[0])
            elif len(fields) == 2:
                try:
                    waypoints.append((float(fields[0]), float(fields[1])))
                except ValueError:
                    raise InputError(
                        f"{path}:{number}: expected 'x y' in metres or a place name, got {line!r}"
                    ) from None
            else:
                raise InputError(f"{path}:{number}: expected 'x y' in metres or a place name, got {line!r}")
    if len(waypoints) < 2:
        raise InputError(f"route file {path} has {len(waypoints)} waypoints; a route needs at least two")
    return Route(path.stem, world or "university", tuple(waypoints))


def is_route_name(name: str) -> bool:
    """A registered route's name, or a long route spelled from one (see `longslam.sim.tours`)."""
    if name in ROUTES or TOUR.fullmatch(name):
        return True
    repeat = REPEAT.fullmatch(name)
    return repeat is not None and is_route_name(repeat["base"])


LONG_FORMS = (
    "a long route is NAME-xN (a route N times over, N from 1 to "
    f"{MAX_REPEAT}, e.g. paper-1km-x3) or tour-<L>km / tour-<L>m[-seed<S>] (e.g. tour-3km)"
)


def _unknown_route(name: str) -> InputError:
    """Why `name` is no route: a route file that does not exist is said to be missing, and a
    misspelt long route is shown its forms (`tour-1KM`, `demo-x-1`)."""
    path = Path(name)
    if path.suffix and not TOUR.fullmatch(name.lower()) or os.sep in name:
        repeat = re.fullmatch(r"(?P<stem>.+)-x(?P<times>\d+)", path.stem)
        how = (
            f"; a route file driven N times over is FILE-xN, e.g. {repeat['stem']}{path.suffix}-x{repeat['times']}"
            if repeat
            else ""
        )
        return InputError(f"route file {name}: no such file (a route is a route name or an existing route file){how}")
    close = [name.lower()] if TOUR.fullmatch(name.lower()) else []
    return UnknownNameError("route", name, ROUTES.names(), hint=LONG_FORMS, close=close)


def get_route(name_or_path: str, world: str | None = None) -> Route:
    """A registered route by name, a long route spelled from one (`paper-1km-x3`, `tour-10km`,
    `tour-2500m-seed4`: see `longslam.sim.tours`), or a route file if the argument is an
    existing path (`r.txt-x3` repeats a file's route).

    `world` (a world reference), if given, is the world the route must be in: the world of a
    route file that names none, and a registered route of another world is refused."""
    repeat = REPEAT.fullmatch(name_or_path)
    if repeat and name_or_path not in ROUTES:
        base = get_route(repeat["base"], world)
        return Route(
            f"{base.name}-x{repeat['times']}", base.world, repeated(base.waypoints, int(repeat["times"]), name_or_path)
        )
    tour = TOUR.fullmatch(name_or_path)
    if tour and name_or_path not in ROUTES:
        ref = world or "university"
        return Route(name_or_path, ref, _tour(ref, tour_length_m(tour), int(tour["seed"] or 0)))
    if name_or_path not in ROUTES and Path(name_or_path).suffix and Path(name_or_path).exists():
        return load_route_file(name_or_path, world)
    if name_or_path not in ROUTES:
        raise _unknown_route(name_or_path)
    route = ROUTES.get(name_or_path)
    if world is not None and not same_world(route.world, world):
        raise InputError(
            f"route {route.name!r} is a route of world {route.world!r}, not of {world_label(world)!r}; "
            "give a route file (waypoints as 'x y' lines, or JSON) for that world"
        )
    return route


_TOURS: dict[tuple[str, float, int], tuple[str, ...]] = {}


def _tour(ref: str, length_m: float, seed: int) -> tuple[str, ...]:
    """A tour's waypoints, planned once per process (a search of the grid per place)."""
    key = (world_key(ref), length_m, seed)
    if key not in _TOURS:
        _TOURS[key] = tour_waypoints(load_world(ref), length_m, seed, places_label(ref))
    return _TOURS[key]


# A tour of the `annex` building (the ring both ways, the hall, every room): the default route an
# ORB vocabulary is trained on, so that appearance-based loop closure is not tuned to `university`.
_named(
    "annex-tour",
    "sw",
    "south_mid",
    "hall_center",
    "hall_w",
    "hall_e",
    "north_mid",
    "ne",
    "library",
    "se",
    "sw",
    "workshop",
    "nw",
    "office",
    "north_mid",
    "hall_center",
    "south_mid",
    "se",
    "ne",
    "nw",
    "sw",
    world="annex",
)
