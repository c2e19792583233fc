"""The navigation grid, the path follower, the routes and the odometry noise model."""

import json

import numpy as np
import pytest

from longslam.core.errors import InputError, UnknownNameError
from longslam.core.geometry import wrap_angle
from longslam.core.gridmap import OCCUPIED
from longslam.sim.follower import follow_paths
from longslam.sim.navigation import NavigationGrid
from longslam.core.odometry_noise import NOISE_LEVELS, BiasNoise, get_noise
from longslam.sim.routes import get_route, load_route_file
from longslam.world.university import university_plan
from longslam.sim.noise import apply_noise


@pytest.fixture(scope="module")
def plan():
    return university_plan()


@pytest.fixture(scope="module")
def nav(plan):
    return NavigationGrid(plan.occupancy())


def _drive(nav, plan, route_name):
    waypoints = get_route(route_name).resolve(plan.places)
    return follow_paths([nav.shortest_path(a, b) for a, b in zip(waypoints[:-1], waypoints[1:])]), waypoints


def test_paths_keep_clear_of_walls_and_furniture(nav, plan):
    occupancy = plan.occupancy()
    # Through the classroom door, between the tables, into the hall.
    path = nav.shortest_path(plan.places["classroom_front"], plan.places["hall_center"])
    fine = occupancy.world_to_cell(path)
    assert not np.any(occupancy.data[fine[:, 0], fine[:, 1]] == OCCUPIED)
    dense = np.concatenate([np.linspace(a, b, 10) for a, b in zip(path[:-1], path[1:])])
    clearance = nav.clearance_m[tuple(np.array([nav.cell(p) for p in dense]).T)]
    assert clearance.min() > 0.2


def test_waypoint_inside_a_wall_is_refused(nav):
    with pytest.raises(InputError, match=r"\(50.00, 29.90\) is not on free floor"):
        nav.shortest_path((50.0, 29.9), (60.0, 31.25))


@pytest.mark.slow
@pytest.mark.parametrize(
    "name,count,length,tolerance",
    [("demo", 7, 60.0, 0.1), ("paper-300m", 12, 300.0, 0.05), ("paper-1km", 25, 1000.0, 0.05)],
)
def test_named_routes_have_the_papers_lengths(nav, plan, name, count, length, tolerance):
    driven, waypoints = _drive(nav, plan, name)
    assert len(waypoints) == count
    assert abs(driven.length - length) <= tolerance * length
    # Every waypoint is reached, within the follower's tolerance.
    reached = driven.xyyaw[driven.waypoint_frames, :2]
    assert np.linalg.norm(reached - np.array(waypoints), axis=1).max() < 0.15


def test_long_route_revisits_hall_and_corridor(plan):
    names = [w for w in get_route("paper-1km").waypoints if isinstance(w, str)]
    assert sum(n.startswith("hall") for n in names) >= 5
    assert sum(n.startswith(("spine", "junction")) for n in names) >= 5


def test_follower_respects_speed_limits_and_turns_in_place(nav, plan):
    driven, _ = _drive(nav, plan, "demo")
    dt = np.diff(driven.timestamps)
    np.testing.assert_allclose(dt, 0.1)
    speed = np.linalg.norm(np.diff(driven.xyyaw[:, :2], axis=0), axis=1) / dt
    turn = np.abs(np.diff(np.unwrap(driven.xyyaw[:, 2]))) / dt
    assert speed.max() <= 1.5 + 1e-9
    assert np.degrees(turn.max()) <= 90.0 + 1e-6
    assert speed.max() > 1.45  # it does reach full speed on straight stretches
    in_place = (speed < 1e-9) & (turn > 0.5)
    assert in_place.sum() > 5  # turns on the spot at the hall's corners


def test_route_files_text_and_json(tmp_path, plan):
    text = tmp_path / "r.txt"
    text.write_text("# my route\n10 31.25\nhall_center  # a place\n")
    route = load_route_file(text)
    assert route.resolve(plan.places) == [(10.0, 31.25), plan.places["hall_center"]]
    js = tmp_path / "r.json"
    js.write_text(json.dumps({"world": "university", "waypoints": [[10, 31.25], [20, 31.25]]}))
    assert get_route(str(js)).resolve(plan.places) == [(10.0, 31.25), (20.0, 31.25)]


def test_route_file_errors_name_file_and_line(tmp_path, plan):
    bad = tmp_path / "bad.txt"
    bad.write_text("10 31.25\n1 2 3\n")
    with pytest.raises(InputError, match=r"bad.txt:2"):
        load_route_file(bad)
    missing_place = tmp_path / "p.txt"
    missing_place.write_text("10 31.25\nkitchen\n")
    with pytest.raises(InputError, match="kitchen.*places: "):
        load_route_file(missing_place).resolve(plan.places)
    with pytest.raises(InputError, match="does not exist"):
        load_route_file(tmp_path / "nope.txt")


def test_unknown_route_and_noise_list_valid_names():
    with pytest.raises(UnknownNameError, match="paper-300m") as err:
        get_route("paper-3km")
    assert "demo" in str(err.value)
    with pytest.raises(UnknownNameError, match="valid noise level names: large, medium, none, small, xlarge"):
        get_noise("huge")


def _straight_then_turn(seconds=35.0, dt=0.1):
    n = int(seconds / dt)
    t = np.arange(n) * dt
    xyyaw = np.zeros((n, 3))
    xyyaw[:, 0] = 0.15 * np.arange(n)  # 1.5 m/s
    # The last 20 frames turn in place.
    xyyaw[-20:, 0] = xyyaw[-21, 0]
    xyyaw[-20:, 2] = np.radians(9.0) * np.arange(1, 21)
    return t, xyyaw


def test_noise_none_is_exact_and_levels_match_the_paper():
    t, xyyaw = _straight_then_turn()
    out = apply_noise(get_noise("none"), t, xyyaw, np.random.default_rng(0))
    np.testing.assert_allclose(out[:, :2], xyyaw[:, :2], atol=1e-12)
    np.testing.assert_allclose(wrap_angle(out[:, 2] - xyyaw[:, 2]), 0.0, atol=1e-12)
    assert [(n, NOISE_LEVELS.get(n).linear_std, NOISE_LEVELS.get(n).angular_std_deg) for n in ("small", "medium", "large", "xlarge")] == [
        ("small", 0.0015, 0.003), ("medium", 0.003, 0.0075), ("large", 0.0075, 0.015), ("xlarge", 0.015, 0.025)
    ]


def test_noise_biases_are_piecewise_constant_and_seeded():
    t, xyyaw = _straight_then_turn()
    noise = BiasNoise("test", linear_std=0.01, angular_std_deg=0.0)
    a = apply_noise(noise, t, xyyaw, np.random.default_rng(3))
    b = apply_noise(noise, t, xyyaw, np.random.default_rng(3))
    c = apply_noise(noise, t, xyyaw, np.random.default_rng(4))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    np.testing.assert_allclose(a[0], xyyaw[0])  # starts at the true first pose
    step_error = np.diff(a[:, 0]) - np.diff(xyyaw[:, 0])
    epochs = (t[:-1] // 10.0).astype(int)
    moving = np.diff(xyyaw[:, 0]) > 0
    for e in range(3):
        values = step_error[(epochs == e) & moving]
        assert np.ptp(values) < 1e-12 and abs(values[0]) > 0  # one bias per 10 s
    assert len({round(step_error[(epochs == e) & moving][0], 12) for e in range(3)}) == 3  # redrawn
    assert np.all(step_error[~moving] == 0)  # no linear bias when turning in place


def test_angular_bias_applies_on_every_frame_in_degrees():
    t, xyyaw = _straight_then_turn()
    noise = BiasNoise("test", linear_std=0.0, angular_std_deg=0.5)
    out = apply_noise(noise, t, xyyaw, np.random.default_rng(1))
    yaw_error = np.degrees(np.diff(np.unwrap(out[:, 2])) - np.diff(np.unwrap(xyyaw[:, 2])))
    epochs = (t[:-1] // 10.0).astype(int)
    for e in range(4):
        assert np.ptp(yaw_error[epochs == e]) < 1e-9
    assert 0.01 < np.abs(yaw_error).max() < 2.5  # degrees, not radians
    assert np.all(np.abs(yaw_error[-19:]) > 0)  # also while turning in place
