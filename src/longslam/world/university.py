"""The default building, `university`: one storey after the paper's scene.

A branched corridor (a 100 m spine with three side branches, 168 m in all), a 24 x 24 m hall
with pillars, a 6 x 15 m classroom with tables, offices, a lab and an entrance lobby.
Walls are 0.2 m thick and 3 m high; doors are 1 m openings.
"""

from __future__ import annotations

from longslam.world.layout import Box, FloorPlan, Rect

WALL = 0.2


def _classroom_tables() -> list[Box]:
    tables = []
    for y0 in (34.2, 35.6, 37.0):
        for x0 in (43.0, 45.2, 47.4, 49.6):
            tables.append(Box(x0, y0, x0 + 1.4, y0 + 0.6, 0.75, "table"))
    tables.append(Box(40.6, 35.0, 41.4, 36.6, 0.8, "desk"))  # the lecturer's desk
    return tables


def _hall_pillars() -> list[Box]:
    return [Box(x, y, x + 0.6, y + 0.6, 3.0, "pillar") for x in (111.7, 122.7) for y in (25.7, 35.7)]


def university_plan() -> FloorPlan:
    free = [
        Rect(5.0, 30.0, 105.0, 32.5, "corridor", "spine"),
        Rect(28.0, 32.5, 30.5, 57.0, "corridor", "branch_a"),
        Rect(66.0, 6.0, 68.5, 30.0, "corridor", "branch_b"),
        Rect(92.0, 32.5, 94.5, 52.0, "corridor", "branch_c"),
        Rect(105.0, 19.0, 129.0, 43.0, "hall", "hall"),
        Rect(0.5, 27.0, 5.0, 36.0, "room", "lobby"),
        Rect(40.0, 32.7, 55.0, 38.7, "classroom", "classroom"),
        Rect(41.0, 32.5, 42.0, 32.7, "door", "classroom_door_front"),
        Rect(53.0, 32.5, 54.0, 32.7, "door", "classroom_door_back"),
        Rect(10.0, 32.7, 16.0, 38.7, "room", "office_1"),
        Rect(12.0, 32.5, 13.0, 32.7, "door", "office_1_door"),
        Rect(58.0, 23.8, 64.0, 29.8, "room", "office_2"),
        Rect(60.0, 29.8, 61.0, 30.0, "door", "office_2_door"),
        Rect(78.0, 32.7, 84.0, 38.7, "room", "office_3"),
        Rect(80.0, 32.5, 81.0, 32.7, "door", "office_3_door"),
        Rect(24.0, 57.2, 34.0, 63.0, "room", "seminar"),
        Rect(28.75, 57.0, 29.75, 57.2, "door", "seminar_door"),
        Rect(62.0, 0.5, 72.0, 5.8, "room", "lab"),
        Rect(66.75, 5.8, 67.75, 6.0, "door", "lab_door"),
        Rect(94.7, 44.0, 100.0, 50.0, "room", "office_4"),
        Rect(94.5, 46.0, 94.7, 47.0, "door", "office_4_door"),
    ]
    places = {
        "lobby": (2.75, 31.5),
        "spine_w": (7.0, 31.25),
        "office_1": (13.0, 36.0),
        "junction_a": (29.25, 31.25),
        "branch_a_end": (29.25, 55.5),
        "seminar": (29.0, 60.5),
        "classroom": (53.0, 34.0),
        "classroom_front": (41.8, 37.5),
        "spine_mid": (55.0, 31.25),
        "office_2": (61.0, 26.5),
        "junction_b": (67.25, 31.25),
        "branch_b_end": (67.25, 8.0),
        "lab": (67.0, 3.0),
        "office_3": (81.0, 36.0),
        "junction_c": (93.25, 31.25),
        "branch_c_end": (93.25, 51.0),
        "office_4": (97.5, 47.0),
        "spine_e": (103.0, 31.25),
        "hall_entry": (108.0, 31.25),
        "hall_ne": (126.0, 40.0),
        "hall_se": (126.0, 22.0),
        "hall_nw": (108.0, 40.5),
        "hall_sw": (108.0, 21.5),
        "hall_center": (117.0, 31.0),
    }
    # Two stretches of the spine, and two side branches, that look alike.
    lookalike = [
        (Rect(14.0, 30.0, 26.0, 32.5, "corridor"), Rect(70.0, 30.0, 82.0, 32.5, "corridor")),
        (Rect(28.0, 38.0, 30.5, 50.0, "corridor"), Rect(92.0, 38.0, 94.5, 50.0, "corridor")),
    ]
    return FloorPlan(
        name="university",
        bounds=(0.0, 0.0, 130.0, 64.0),
        free=free,
        furniture=_classroom_tables() + _hall_pillars(),
        wall_height=3.0,
        lookalike_pairs=lookalike,
        places=places,
    )
