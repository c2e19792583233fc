"""Study files: what a good one gives, and errors that name the key and the valid values."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import pytest

from longslam.study.config import StudyConfigError, check_method_params, load_study
from longslam.study.spec import plan_runs

ROOT = Path(__file__).resolve().parents[2]
GOOD = """
routes = ["demo", "tiny.txt"]
noise = ["small", "large"]
methods = ["odometry"]
seeds = 2
[camera]
width = 64
height = 48
[variants.odometry-again]
method = "odometry"
"""


def _write(tmp_path: Path, text: str) -> Path:
    (tmp_path / "tiny.txt").write_text("20 31.25\n28 31.25\n")
    path = tmp_path / "study.toml"
    path.write_text(text)
    return path


def test_a_good_study_file_plans_every_run(tmp_path):
    config = load_study(_write(tmp_path, GOOD))
    assert config.name == "study" and config.world == "university"
    assert [r.name for r in config.routes] == ["demo", "tiny"]
    assert config.routes[1].waypoints == ((20.0, 31.25), (28.0, 31.25))
    assert config.seeds == (0, 1) and config.camera.width == 64 and config.align == "none"
    assert [(m.label, m.method) for m in config.methods] == [("odometry", "odometry"), ("odometry-again", "odometry")]
    runs = plan_runs(config)
    assert len(runs) == 2 * 2 * 2 * 2 and len({r.key for r in runs}) == len(runs)
    assert runs[0].key == "demo/small/odometry/seed-0"
    assert len({r.config_hash for r in runs}) == len(runs)


def test_all_means_every_registered_method(tmp_path):
    from longslam.slam.catalog import default_method_names

    # Every method that runs without parameters: not `command`, which needs its program (test_command.py).
    config = load_study(_write(tmp_path, GOOD.replace('["odometry"]', '"all"')))
    assert [m.label for m in config.methods][: len(default_method_names())] == default_method_names()


def test_shipped_study_files_load():
    for name in ("quick", "paper"):
        config = load_study(ROOT / "studies" / f"{name}.toml")
        assert config.name == name and "odometry" in [m.method for m in config.methods]
    paper = load_study(ROOT / "studies" / "paper.toml")
    assert [r.name for r in paper.routes] == ["paper-300m", "paper-1km"]
    assert paper.noise == ("small", "medium", "large", "xlarge") and paper.seeds == (0, 1, 2, 3, 4)
    # Both front ends run: the methods' default (fused) and the paper's wheel-only configuration.
    wheel = {m.label: m for m in paper.methods if m.params.get("frontend.mode") == "wheel"}
    assert {"keyframe-wheel", "submap-wheel"} <= set(wheel)
    assert {wheel["keyframe-wheel"].method, wheel["submap-wheel"].method} == {"keyframe", "submap"}
    hard = load_study(ROOT / "studies" / "hard-end.toml")
    axes = {m.label: m.method for m in hard.methods if m.params.get("frontend.wall_axes.use") is True}
    assert axes == {"keyframe-axes": "keyframe", "submap-axes": "submap"}
    assert hard.noise == ("xlarge",) and hard.seeds == (0, 1, 2, 3, 4)


def _refused(tmp_path, study: str, change: tuple[str, str], expected: list[str]) -> None:
    """`study` with one change is refused, naming the file and every expected part."""
    old, new = change
    assert old in study
    path = _write(tmp_path, study.replace(old, new, 1))
    with pytest.raises(StudyConfigError) as err:
        load_study(path)
    message = str(err.value)
    assert str(path) in message
    for part in expected:
        assert part in message, f"{part!r} not in {message!r}"


@pytest.mark.parametrize(
    "change, expected",
    [
        (("seeds = 2", "seeds = 2\nnosie = 1"), ["nosie", "valid keys", "noise", "routes"]),
        (('"large"]', '"huge"]'), ["noise[1]", "'huge'", "none, small, medium, large, xlarge"]),
        (('["odometry"]', '["orbslam9"]'), ["methods[0]", "'orbslam9'", "odometry"]),
        (('["odometry"]', '"some"'), ["methods[0]", "'some'", "odometry"]),
        (('"demo", "tiny.txt"', '"nowhere"'), ["routes[0]", "'nowhere'", "demo, paper-300m, paper-1km", "waypoint file"]),
        (("seeds = 2", "seeds = -1"), ["seeds", "at least 1"]),
        (("seeds = 2", 'seeds = ["a"]'), ["seeds", "list of integers"]),
        (("width = 64", "widht = 64"), ["camera.widht", "valid keys", "width, height, fov, max_depth"]),
        (("width = 64", "width = 0"), ["camera", "width must be a positive integer"]),
        (("width = 64", 'width = "big"'), ["camera.width", "'big'", "expected a whole number"]),
        (("seeds = 2", 'seeds = 2\nalign = "affine"'), ["align", "'affine'", "none, se3, sim3"]),
        (("seeds = 2", "seeds = 2\nmap_tolerance_cells = -1"), ["map_tolerance_cells", ">= 0"]),
        (('method = "odometry"', 'method = "nope"'), ["variants.odometry-again.method", "'nope'", "odometry"]),
        (("seeds = 2", 'seeds = 2\n[params.submapx]\na = 1'), ["params.submapx", "valid keys: odometry"]),
        (('routes = ["demo", "tiny.txt"]\n', ""), ["routes", "missing"]),
        (("seeds = 2", "seeds = = 2"), ["not valid TOML", "line"]),
    ],
)
def test_errors_name_the_key_and_the_valid_values(tmp_path, change, expected):
    _refused(tmp_path, GOOD, change, expected)


def test_bad_method_parameters_fail_before_any_run(tmp_path):
    config = load_study(_write(tmp_path, GOOD + "\n[params.odometry]\nalpha = 1\n"))
    with pytest.raises(StudyConfigError, match=r"params\.odometry: .*takes no parameters"):
        check_method_params(config)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(StudyConfigError, match="does not exist"):
        load_study(tmp_path / "nope.toml")


CAMERAS = GOOD.replace("[camera]\nwidth = 64\nheight = 48\n", "[cameras.small]\nwidth = 64\nheight = 48\n[cameras.large]\nwidth = 96\nheight = 72\nfov = 80\n")


def test_named_cameras_are_an_axis_of_the_study(tmp_path):
    config = load_study(_write(tmp_path, CAMERAS))
    assert [(c.name, c.settings.width, c.settings.height, c.settings.hfov_deg) for c in config.cameras] == [
        ("small", 64, 48, 90.0), ("large", 96, 72, 80.0)
    ]
    assert config.camera == config.cameras[0].settings
    assert config.to_dict()["cameras"] == {c.name: asdict(c.settings) for c in config.cameras}
    runs = plan_runs(config)
    assert len(runs) == 2 * 2 * 2 * 2 * 2 and len({r.key for r in runs}) == len(runs)
    assert runs[0].key == "demo/small/small/odometry/seed-0"  # route demo, camera small, noise small
    assert {r.key.split("/")[1] for r in runs} == {"small", "large"}
    assert {(r.camera_name, r.camera["width"]) for r in runs} == {("small", 64), ("large", 96)}
    assert len({r.config_hash for r in runs}) == len(runs)
    assert config.grid_text().startswith("2 routes x 2 cameras x 2 noise levels x 2 methods x 2 seeds = ")
    assert load_study(_write(tmp_path, GOOD)).grid_text().startswith("2 routes x 2 noise levels x 2 methods x 2 seeds = ")


# Computed with longslam's code before cameras could be named (commit c517f78): a [camera] study's
# runs must keep these keys and hashes, so an existing study folder resumes without redoing a run.
PINNED = """
routes = ["tiny.txt"]
noise = ["small", "large"]
methods = ["odometry"]
seeds = 2
[camera]
width = 64
height = 48
"""
PINNED_RUNS = {
    "tiny/small/odometry/seed-0": "2c364b570d80e4d2",
    "tiny/large/odometry/seed-0": "627ab6d1b6f8469a",
    "tiny/small/odometry/seed-1": "439e1c0dc0e1f513",
    "tiny/large/odometry/seed-1": "c78588981bc9087e",
}


def test_a_one_camera_study_keeps_its_run_keys_and_hashes(tmp_path):
    config = load_study(_write(tmp_path, PINNED), ["odometry"])
    assert config.cameras == () and "cameras" not in config.to_dict()
    assert {r.key: r.config_hash for r in plan_runs(config)} == PINNED_RUNS
    # The default camera (no [camera] table) too.
    default = load_study(_write(tmp_path, PINNED.replace("[camera]\nwidth = 64\nheight = 48\n", "").replace(
        '["small", "large"]', '["small"]').replace("seeds = 2", "seeds = 1")), ["odometry"])
    assert [(r.key, r.config_hash) for r in plan_runs(default)] == [("tiny/small/odometry/seed-0", "990af2e41902c219")]
    # The same camera under a name is the same runs (same hashes) in folders named after it.
    named = load_study(_write(tmp_path, PINNED.replace("[camera]", "[cameras.tiny64]")), ["odometry"])
    assert {r.key: r.config_hash for r in plan_runs(named)} == {
        key.replace("tiny/", "tiny/tiny64/", 1): value for key, value in PINNED_RUNS.items()
    }


def test_real_systems_study_file_loads():
    from longslam.slam.catalog import method_names

    # orbslam3 is the plugin's (the longslam.methods entry point); without it the file is refused.
    with pytest.raises(StudyConfigError, match=r"methods\[3\]: unknown method 'orbslam3'"):
        load_study(ROOT / "studies" / "real-systems.toml", ["odometry", "keyframe", "submap"])
    config = load_study(ROOT / "studies" / "real-systems.toml", [*method_names(), "orbslam3"])
    assert config.name == "real-systems"
    assert [r.name for r in config.routes] == ["demo", "paper-300m"]
    assert config.noise == ("large",) and config.seeds == (0,) and config.repeats == 5
    assert [m.label for m in config.methods] == ["odometry", "keyframe", "submap", "orbslam3"]
    assert [(c.name, c.settings.width, c.settings.height, c.settings.hfov_deg, c.settings.max_depth)
            for c in config.cameras] == [("qvga", 320, 240, 90.0, 8.0), ("vga", 640, 480, 90.0, 8.0)]
    assert len(plan_runs(config)) == 2 * 2 * 1 * 4 * 5
    longer = load_study(ROOT / "studies" / "real-systems-1km.toml", [*method_names(), "orbslam3"])
    assert [r.name for r in longer.routes] == ["paper-1km"] and longer.repeats == 3
    assert [c.name for c in longer.cameras] == ["vga"] and len(plan_runs(longer)) == 4 * 3


@pytest.mark.parametrize(
    "change, expected",
    [
        (("[cameras.small]", "[camera]\nwidth = 64\n[cameras.small]"), ["camera", "[camera]", "[cameras.NAME]", "not both"]),
        (("[cameras.small]", '[cameras."bad/name"]'), ["cameras.bad/name", "a camera name is a folder", "'bad/name'"]),
        (("[cameras.small]", '[cameras.".hidden"]'), ["cameras..hidden", "starting with a letter or digit"]),
        (("[cameras.small]", '[cameras.""]'), ["a camera name", "got ''"]),
        (("[cameras.large]", "[cameras.SMALL]"), ["cameras.SMALL", "only in case", "cameras.small"]),
        (("width = 96", "widht = 96"), ["cameras.large.widht", "unknown key", "width, height, fov, max_depth, camera_height"]),
        (("width = 96", "width = 0"), ["cameras.large", "width must be a positive integer"]),
        (("fov = 80", 'fov = "wide"'), ["cameras.large.fov", "'wide'", "expected a finite number"]),
        (("width = 96\nheight = 72\nfov = 80", "width = 64\nheight = 48"), ["cameras.large", "same settings as cameras.small"]),
    ],
)
def test_camera_errors_name_the_key_and_the_valid_values(tmp_path, change, expected):
    _refused(tmp_path, CAMERAS, change, expected)


@pytest.mark.parametrize("tables", ["cameras = 1\n", "cameras = {}\n", "[cameras]\nsmall = 5\n"])
def test_cameras_must_be_tables_of_settings(tmp_path, tables):
    text = GOOD.replace("[camera]\nwidth = 64\nheight = 48\n", "").replace("[variants.odometry-again]", tables + "[variants.odometry-again]")
    if tables.startswith("cameras ="):  # a top-level key must come before the first table
        text = tables + text.replace(tables, "")
    path = _write(tmp_path, text)
    with pytest.raises(StudyConfigError, match=r"cameras(\.small)?: expected .*table") as err:
        load_study(path)
    assert str(path) in str(err.value)


def test_repeats_run_each_cell_again_and_one_repeat_keeps_keys_and_hashes(tmp_path):
    once = load_study(_write(tmp_path, GOOD))
    thrice = load_study(_write(tmp_path, GOOD.replace("seeds = 2", "seeds = 2\nrepeats = 3")))
    assert thrice.repeats == 3 and thrice.run_count == 3 * once.run_count
    assert "3 repeats" in thrice.grid_text() and "repeat" not in once.grid_text()
    assert "repeats" not in once.to_dict() and thrice.to_dict()["repeats"] == 3
    first, runs = plan_runs(once), plan_runs(thrice)
    # A cell's first run is the run of a study without repeats: the same key, the same hash.
    by_key = {run.key: run for run in runs if run.repeat == 0}
    assert {run.key: run.config_hash for run in first} == {k: r.config_hash for k, r in by_key.items()}
    again = [run for run in runs if run.repeat == 2]
    assert again and all(run.key.endswith("-repeat-2") for run in again)
    assert len({run.config_hash for run in runs}) == len(runs)


@pytest.mark.parametrize("value", ["0", "-1", "1.5", '"3"', "1001", "true"])
def test_repeats_must_be_a_count(tmp_path, value):
    with pytest.raises(StudyConfigError, match=r"repeats.*whole number of runs per cell, 1 to 1000"):
        load_study(_write(tmp_path, GOOD.replace("seeds = 2", f"seeds = 2\nrepeats = {value}")))
