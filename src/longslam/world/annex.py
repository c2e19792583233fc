"""A second building, `annex`: a corridor ring round a pillared hall, with three rooms.

It exists so that something can be learnt from a building that is not the one evaluated: the
default ORB vocabulary of appearance-based loop closure (`longslam vocabulary build`) is trained
here, never on `university`. Its walls, floor and furniture are textured from another seed than
`university`'s, and its plan shares no stretch with it.
"""

from __future__ import annotations

from longslam.world.layout import Box, FloorPlan, Rect

# Texture seed: any value but university's 0; fixed so that the default vocabulary is reproducible.
TEXTURE_SEED = 11


def _furniture() -> list[Box]:
    pillars = [Box(x, y, x + 0.5, y + 0.5, 3.0, "pillar") for x in (25.0, 34.5) for y in (13.5, 20.0)]
    tables = [Box(x, y, x + 1.2, y + 0.7, 0.75, "table") for x in (9.0, 11.5, 14.0) for y in (10.0, 12.5)]
    shelves = [Box(44.5, 21.0, 45.0, 25.0, 1.8, "shelf")]
    return pillars + tables + shelves


def annex_plan() -> FloorPlan:
    free = [
        Rect(4.0, 4.0, 56.0, 6.5, "corridor", "south"),
        Rect(4.0, 27.5, 56.0, 30.0, "corridor", "north"),
        Rect(4.0, 6.5, 6.5, 27.5, "corridor", "west"),
        Rect(53.5, 6.5, 56.0, 27.5, "corridor", "east"),
        Rect(20.0, 10.0, 40.0, 24.0, "hall", "hall"),
        Rect(29.0, 6.5, 31.0, 10.0, "corridor", "hall_south_way"),
        Rect(29.0, 24.0, 31.0, 27.5, "corridor", "hall_north_way"),
        Rect(6.7, 8.5, 16.0, 14.5, "classroom", "workshop"),
        Rect(6.5, 11.0, 6.7, 12.0, "door", "workshop_door"),
        Rect(44.0, 20.0, 53.3, 25.5, "room", "library"),
        Rect(53.3, 22.0, 53.5, 23.0, "door", "library_door"),
        Rect(8.0, 30.2, 16.0, 35.0, "room", "office"),
        Rect(11.5, 30.0, 12.5, 30.2, "door", "office_door"),
    ]
    places = {
        "sw": (5.25, 5.25),
        "se": (54.75, 5.25),
        "ne": (54.75, 28.75),
        "nw": (5.25, 28.75),
        "south_mid": (30.0, 5.25),
        "north_mid": (30.0, 28.75),
        "hall_center": (30.0, 17.0),
        "hall_w": (22.0, 17.0),
        "hall_e": (38.0, 17.0),
        "workshop": (12.0, 14.0),
        "library": (48.0, 23.0),
        "office": (12.0, 33.5),
    }
    return FloorPlan(
        name="annex",
        bounds=(0.0, 0.0, 60.0, 38.0),
        free=free,
        furniture=_furniture(),
        wall_height=3.0,
        places=places,
    )
