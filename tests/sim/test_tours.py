"""Long routes spelled as names: a route N times over, and seeded random tours of the places."""

from __future__ import annotations

import pytest

from longslam.cli import main
from longslam.errors import InputError
from longslam.sim.drive import drive_route
from longslam.sim.navigation import NavigationGrid
from longslam.sim.routes import get_route, is_route_name
from longslam.world import get_world


def test_a_route_n_times_over_repeats_its_waypoints():
    demo = get_route("demo")
    assert get_route("demo-x3").waypoints == demo.waypoints * 3  # demo does not end where it starts
    assert get_route("demo-x3").name == "demo-x3" and is_route_name("demo-x3")
    closed = get_route("annex-tour")  # ends where it starts: the joins are not doubled
    twice = get_route("annex-tour-x2").waypoints
    assert len(twice) == 2 * len(closed.waypoints) - 1 and twice[len(closed.waypoints) - 1] == closed.waypoints[-1]


def test_a_route_file_can_be_repeated(tmp_path):
    path = tmp_path / "r.txt"
    path.write_text("20 31.25\n26 31.25\n")
    route = get_route(f"{path}-x2")
    assert route.name == "r-x2" and route.waypoints == ((20.0, 31.25), (26.0, 31.25)) * 2


def test_a_tour_is_as_long_as_asked_and_the_same_for_its_seed():
    world = get_world("university")
    tour = get_route("tour-200m-seed3")
    assert tour == get_route("tour-200m-seed3") and tour.world == "university"
    assert tour.waypoints != get_route("tour-200m-seed4").waypoints
    assert all(isinstance(w, str) and w in world.places for w in tour.waypoints)
    assert all(a != b for a, b in zip(tour.waypoints[:-1], tour.waypoints[1:]))
    nav = NavigationGrid(world.occupancy)
    legs = [nav.path_lengths(world.places[a], [world.places[b]])[0] for a, b in zip(tour.waypoints[:-1], tour.waypoints[1:])]
    assert sum(legs) >= 200.0 > sum(legs[:-1])  # it stops at the first place past the length
    driven = drive_route(world, tour).length
    assert 0.97 * sum(legs) < driven < 1.03 * sum(legs), (driven, sum(legs))


@pytest.mark.parametrize("name, needle", [
    ("tour-0km", "more than 0"), ("tour-200km", "at most 100000 m"), ("demo-x0", "1 to 1000"),
    ("demo-x5000", "1 to 1000"), ("nosuch-x3", "nosuch"),
])
def test_a_long_route_out_of_range_is_refused_by_name(name, needle):
    with pytest.raises(InputError, match=needle):
        get_route(name)


def test_list_names_the_long_route_spellings(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "tour-10km" in out and "NAME-xN" in out


def test_a_study_takes_a_tour_as_a_route(tmp_path):
    from longslam.study.config import load_study

    study = tmp_path / "s.toml"
    study.write_text('name = "s"\nroutes = ["tour-150m-seed1", "demo-x2"]\nnoise = ["large"]\n'
                     'methods = ["odometry"]\nseeds = [0]\n')
    config = load_study(study)
    assert [r.name for r in config.routes] == ["tour-150m-seed1", "demo-x2"]
    assert config.routes[0] == get_route("tour-150m-seed1")
    assert config.routes[1].waypoints == get_route("demo").waypoints * 2
