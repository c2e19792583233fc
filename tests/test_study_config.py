"""Study files: what a good one gives, and errors that name the key and the valid values."""

from __future__ import annotations

from pathlib import Path

import pytest

from longslam.study.config import StudyConfigError, check_method_params, load_study
from longslam.study.spec import plan_runs

ROOT = Path(__file__).resolve().parents[1]
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
    from longslam.slam.catalog import method_names

    config = load_study(_write(tmp_path, GOOD.replace('["odometry"]', '"all"')))
    assert [m.label for m in config.methods][: len(method_names())] == method_names()


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
        (("seeds = 2", 'seeds = 2\nalign = "affine"'), ["align", "'affine'", "none, se3, sim3"]),
        (("seeds = 2", "seeds = 2\nmap_tolerance_cells = -1"), ["map_tolerance_cells", ">= 0"]),
        (('method = "odometry"', 'method = "nope"'), ["variants.odometry-again.method", "'nope'", "odometry"]),
        (("seeds = 2", 'seeds = 2\n[params.submapx]\na = 1'), ["params.submapx", "valid keys: odometry"]),
        (('routes = ["demo", "tiny.txt"]\n', ""), ["routes", "missing"]),
        (("seeds = 2", "seeds = = 2"), ["not valid TOML", "line"]),
    ],
)
def test_errors_name_the_key_and_the_valid_values(tmp_path, change, expected):
    old, new = change
    assert old in GOOD
    path = _write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(StudyConfigError) as err:
        load_study(path)
    message = str(err.value)
    assert str(path) in message
    for part in expected:
        assert part in message, f"{part!r} not in {message!r}"


def test_bad_method_parameters_fail_before_any_run(tmp_path):
    config = load_study(_write(tmp_path, GOOD + "\n[params.odometry]\nalpha = 1\n"))
    with pytest.raises(StudyConfigError, match=r"params\.odometry: .*takes no parameters"):
        check_method_params(config)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(StudyConfigError, match="does not exist"):
        load_study(tmp_path / "nope.toml")
