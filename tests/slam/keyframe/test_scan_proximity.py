"""Proximity by scan matching: nodes that drove a corridor the other way, on synthetic walls."""

from dataclasses import replace

import numpy as np

from longslam.core.geometry import compose_xyyaw, relative_xyyaw, wrap_angle
from longslam.slam.features import Features
from longslam.slam.keyframe.memory import Node
from longslam.slam.occupancy import LocalGrid
from longslam.slam.keyframe.scan_proximity import ScanLinkSettings, scan_link, shares_open_space

CELL = 0.05
SETTINGS = ScanLinkSettings(radius=8.0, min_age=0.0, max_correction=0.5, max_correction_angle=0.05, min_overlap=0.5,
                            max_rmse=0.04, sigma_floor=(0.05, 0.05, 0.02))
# A straight corridor along x, 2.5 m wide, between walls 0.2 m thick; a room behind its left wall.
WALLS = [((0.0, -1.25), (30.0, -1.25)), ((0.0, 1.25), (30.0, 1.25)), ((0.0, 1.45), (30.0, 1.45))]


def _inside_corridor(xy):
    return np.abs(xy[:, 1]) < 1.2


def _inside_room(xy):
    return (xy[:, 1] > 1.5) & (xy[:, 1] < 4.0)


def _node(node_id: int, pose: np.ndarray, walls, open_space, fov=np.pi / 2, reach=8.0) -> Node:
    """A node at true `pose` whose grid holds the wall cells in its field of view and the open
    cells its rays crossed (no occlusion: the walls seen are the open space's own)."""
    c, s = np.cos(pose[2]), np.sin(pose[2])

    def to_robot(xy):
        d = xy - pose[:2]
        return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])

    def seen(p):
        return (np.hypot(p[:, 0], p[:, 1]) <= reach) & (np.abs(np.arctan2(p[:, 1], p[:, 0])) <= fov / 2)

    wall_points = np.vstack([np.linspace(a, b, 3001) for a, b in walls])
    # Only the faces that open onto this node's space: a wall cell within 0.1 m of it.
    facing = np.zeros(len(wall_points), dtype=bool)
    for offset in ([0.0, 0.1], [0.1, 0.0]):
        facing |= open_space(wall_points + offset) | open_space(wall_points - offset)
    local = to_robot(wall_points)
    obstacles = np.unique(np.floor(local[seen(local) & facing] / CELL).astype(np.int16), axis=0)
    gx, gy = np.meshgrid(np.arange(0.0, reach, CELL), np.arange(-reach, reach, CELL))
    robot = np.column_stack([gx.ravel(), gy.ravel()])
    world = robot @ np.array([[c, s], [-s, c]]) + pose[:2]
    free = np.unique(np.floor(robot[seen(robot) & open_space(world)] / CELL).astype(np.int16), axis=0)
    return Node(node_id, float(node_id), pose, Features.empty(), LocalGrid(obstacles, free, CELL), None)


def test_open_space_is_shared_along_a_corridor_and_not_through_its_wall():
    east = np.array([10.0, 0.0, 0.0])
    old = _node(0, east, WALLS, _inside_corridor)
    assert shares_open_space(east, np.array([16.0, 0.0, np.pi]), old.grid)  # ahead, in its rays
    assert not shares_open_space(east, np.array([6.0, 0.0, np.pi]), old.grid)  # behind it
    assert not shares_open_space(east, np.array([14.0, 2.5, np.pi]), old.grid)  # in the room behind the wall


def test_a_node_driving_back_is_held_across_the_corridor_and_in_heading():
    truth = np.array([16.0, 0.0, np.pi])
    old = [_node(0, np.array([10.0, 0.0, 0.0]), WALLS, _inside_corridor),
           _node(1, np.array([8.5, 0.0, 0.0]), WALLS, _inside_corridor)]
    new = _node(2, truth, WALLS, _inside_corridor)
    estimate = compose_xyyaw(truth, np.array([0.3, 0.12, 0.025]))  # drifted along, across and in heading
    link = scan_link(new, estimate, [(n, n.odom) for n in old], SETTINGS)
    assert link is not None and link.anchor == 0
    placed = compose_xyyaw(old[0].odom, link.delta)
    # Across the corridor the walls hold it, to the grid's cell: these walls lie on cell
    # boundaries, where views from opposite sides round them a whole cell apart (the worst case).
    assert abs(placed[1] - truth[1]) < CELL + 0.01 < 0.12
    assert abs(wrap_angle(placed[2] - truth[2])) < 0.005
    assert abs(placed[0] - estimate[0]) < 0.1  # along it nothing does: it stays where the estimate was
    # ...and the link says so: next to no information along the corridor (the node's forward axis).
    information = link.information
    assert information[0, 0] < 0.01 * information[1, 1]
    # Without the older node's view of these walls, no link.
    assert scan_link(new, estimate, [], SETTINGS) is None


def test_the_other_face_of_a_wall_is_not_a_link():
    # A node in the room behind the corridor's left wall saw that wall's other face, 0.2 m off.
    room = _node(0, np.array([12.0, 2.5, np.pi]), WALLS, _inside_room)
    new = _node(1, np.array([16.0, 0.0, np.pi]), WALLS, _inside_corridor)
    assert len(room.grid.obstacles) > 50
    assert scan_link(new, new.odom, [(room, room.odom)], SETTINGS) is None


def test_a_link_is_refused_past_its_correction():
    old = [_node(0, np.array([10.0, 0.0, 0.0]), WALLS, _inside_corridor)]
    truth = np.array([16.0, 0.0, np.pi])
    new = _node(1, truth, WALLS, _inside_corridor)
    turned = compose_xyyaw(truth, np.array([0.0, 0.0, 0.2]))  # 11 degrees: beyond max_correction_angle
    assert scan_link(new, turned, [(n, n.odom) for n in old], SETTINGS) is None
    assert relative_xyyaw(truth, turned)[2] > SETTINGS.max_correction_angle


# The same corridor with, in its right wall at x = 11..13, either a side corridor (its two walls
# face along the main one) or a shallow recess (two faces at 30 degrees to the main corridor).
SIDE_WALLS = [((0.0, -1.25), (11.0, -1.25)), ((13.0, -1.25), (30.0, -1.25)), ((0.0, 1.25), (30.0, 1.25)),
              ((11.0, -1.25), (11.0, -6.0)), ((13.0, -1.25), (13.0, -6.0))]
RECESS_DEPTH = np.tan(np.radians(30.0))
RECESS_WALLS = [((0.0, -1.25), (11.0, -1.25)), ((13.0, -1.25), (30.0, -1.25)), ((0.0, 1.25), (30.0, 1.25)),
                ((11.0, -1.25), (12.0, -1.25 - RECESS_DEPTH)), ((12.0, -1.25 - RECESS_DEPTH), (13.0, -1.25))]


def _inside_corridor_or_side(xy):
    return _inside_corridor(xy) | ((xy[:, 0] > 11.05) & (xy[:, 0] < 12.95) & (xy[:, 1] > -6.0) & (xy[:, 1] < -1.2))


def _inside_corridor_or_recess(xy):
    floor = -1.25 - RECESS_DEPTH * (1.0 - np.abs(xy[:, 0] - 12.0)) + 0.05
    return _inside_corridor(xy) | ((np.abs(xy[:, 0] - 12.0) < 1.0) & (xy[:, 1] > floor) & (xy[:, 1] < -1.2))


def _drive_back(walls, open_space, settings=SETTINGS):
    truth = np.array([16.0, 0.0, np.pi])
    old = [_node(0, np.array([10.0, 0.0, 0.0]), walls, open_space), _node(1, np.array([8.5, 0.0, 0.0]), walls, open_space)]
    new = _node(2, truth, walls, open_space)
    estimate = compose_xyyaw(truth, np.array([0.3, 0.12, 0.025]))  # 0.3 m off along the corridor
    link = scan_link(new, estimate, [(n, n.odom) for n in old], settings)
    assert link is not None
    return truth, compose_xyyaw(old[0].odom, link.delta), link


def test_faces_at_a_slant_do_not_hold_a_node_along_the_corridor():
    # The recess's faces give the registration's Hessian some information along the corridor
    # (on the paper's routes, cells at wall ends, door frames and clutter do the same, and links
    # that trusted it were up to 1.3 m wrong along the corridor). No cell faces along it, so the
    # link leaves that direction free.
    _, _, link = _drive_back(RECESS_WALLS, _inside_corridor_or_recess)
    assert link.held[0] < SETTINGS.min_constraining <= link.held[1] and link.freed == 1
    assert link.information[0, 0] < 1e-3 * link.information[1, 1]
    # Counted as the Hessian has it, the link would hold the node along the corridor too.
    _, _, trusting = _drive_back(RECESS_WALLS, _inside_corridor_or_recess, replace(SETTINGS, min_constraining=0))
    assert trusting.information[0, 0] > 0.02 * trusting.information[1, 1]


def test_a_side_corridor_holds_the_node_along_the_main_one():
    truth, placed, link = _drive_back(SIDE_WALLS, _inside_corridor_or_side)
    assert link.held[0] >= SETTINGS.min_constraining and link.freed == 0
    assert abs(placed[0] - truth[0]) < 0.1  # pulled back the 0.3 m its estimate was off
    assert link.information[0, 0] > 0.1 * link.information[1, 1]
