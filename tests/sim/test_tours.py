"""Long routes spelled as names: a route N times over, and seeded random tours of the places."""

from __future__ import annotations

import pytest

from helpers.cli_checks import one_line_error
from longslam.cli.main import main
from longslam.core.errors import InputError
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


@pytest.mark.slow  # plans two kilometre tours (3.3 s)
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


@pytest.mark.parametrize("apart, route", [(0.0, "tour-1km"), (0.01, "tour-100m")])
def test_a_tour_between_places_at_one_spot_is_refused_at_once(tmp_path, capsys, monkeypatch, apart, route):
    """Two places at one point made every leg 0 m long: the planner went on forever, its memory growing."""
    pytest.importorskip("trimesh")
    import json
    import signal
    import time

    from longslam.world.wing_building import write_building

    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    ply, _ = write_building(tmp_path / "b")
    places = tmp_path / "same.json"
    places.write_text(json.dumps({"a": [1.0, 1.0], "b": [1.0 + apart, 1.0]}))

    def too_long(*_):
        raise TimeoutError("the tour was still being planned after 60 s")

    previous = signal.signal(signal.SIGALRM, too_long)
    signal.alarm(60)
    try:
        t0 = time.monotonic()
        assert main(["world", "--world", str(ply), "--places", str(places), "--route", route,
                     "--out", str(tmp_path / "p.png")]) == 2
        assert time.monotonic() - t0 < 30
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    one_line_error(capsys, str(places), "places 'a' and 'b'", "m apart", "at least 1 m apart")
    assert not (tmp_path / "p.png").exists()


def test_a_place_named_twice_is_left_out_of_legs_but_the_tour_goes_on():
    from longslam.sim.tours import MIN_LEG_M, tour_waypoints
    from longslam.world import get_world

    world = get_world("annex")
    world.places = {**world.places, "sw_again": world.places["sw"]}
    tour = tour_waypoints(world, 300.0, 2)
    same = {"sw", "sw_again"}
    assert not any({a, b} == same for a, b in zip(tour[:-1], tour[1:]))
    assert len(tour) <= 300.0 / MIN_LEG_M + 1
