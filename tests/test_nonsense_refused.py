"""Inputs that cannot make sense are refused with a clear error, not accepted silently: intrinsics
outside the image or negative, a route that goes nowhere, a camera above the ceiling, strings where a
study wants numbers, a variant listed as a method, a ROS 2 folder without metadata or with one topic
in two roles, and images ORB-SLAM3 would crash on."""

from __future__ import annotations

from pathlib import Path

import pytest

from helpers.cli_checks import one_line_error
from helpers.studies import tiny_study_file
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main


@pytest.fixture()
def seq(tmp_path) -> Path:
    return write_tiny_sequence(tmp_path / "seq", n=12)[0]


def test_a_principal_point_outside_the_image_is_refused(seq, tmp_path, capsys):
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "r"), "--intrinsics", "10,10,800,6"]) == 2
    one_line_error(capsys, "--intrinsics", "principal point", "(800, 6)", "16 x 12")
    import json

    camera = json.loads((seq / "camera.json").read_text())
    (seq / "camera.json").write_text(json.dumps({**camera, "cy": -50}))
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "r")]) == 2
    one_line_error(capsys, "camera.json", "principal point")


def test_a_negative_intrinsic_gets_the_intrinsics_message_not_argparses(seq, tmp_path, capsys):
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "r"), "--intrinsics", "-40,40,8,6"]) == 2
    one_line_error(capsys, "--intrinsics '-40,40,8,6'", "fx and fy positive")


@pytest.mark.parametrize("text, needle", [
    ("20 31.25\n20 31.25\n", "all the same point"),
    ("20 31.25\nnan 31.25\n", "waypoint 1 (nan, 31.25) is not a point"),
])
def test_a_route_that_goes_nowhere_is_refused(tmp_path, capsys, monkeypatch, text, needle):
    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    route = tmp_path / "r.txt"
    route.write_text(text)
    assert main(["simulate", "--route", str(route), "--out", str(tmp_path / "s")]) == 2
    one_line_error(capsys, needle)
    assert not (tmp_path / "s").exists()


def test_a_camera_above_the_ceiling_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    assert main(["simulate", "--route", "demo", "--camera-height", "5", "--width", "16", "--height", "12",
                 "--out", str(tmp_path / "s")]) == 2
    one_line_error(capsys, "camera height 5 m", "over the ceiling")
    assert not (tmp_path / "s").exists() and not (tmp_path / "cache").exists()
    study = tiny_study_file(tmp_path, "1", "camera_height = 5\n")
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "camera.camera_height", "over the ceiling")
    assert not (tmp_path / "out").exists()
    named = study.read_text().replace("[camera]", "[cameras.tall]")
    (tmp_path / "named.toml").write_text(named)
    assert main(["study", str(tmp_path / "named.toml"), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "cameras.tall.camera_height", "over the ceiling")  # the table the height is in


def test_a_study_camera_string_is_not_coerced_to_a_number(tmp_path, capsys):
    study = tiny_study_file(tmp_path, "1").read_text().replace("width = 16", 'width = "16"')
    (tmp_path / "s.toml").write_text(study)
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "camera.width: '16'", "expected a whole number, got a string")


def test_a_study_method_parameter_string_is_not_coerced_to_a_number(tmp_path, capsys):
    """As for [camera]: in a TOML file a quoted number is a mistake, where --param text is converted."""
    study = tiny_study_file(tmp_path, "1").read_text().replace('methods = ["odometry"]', 'methods = ["keyframe"]')
    (tmp_path / "s.toml").write_text(study + '[params.keyframe]\nmax_features = "500"\n')
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "params.keyframe", "max_features='500'", "expected a whole number, got a string")
    assert not (tmp_path / "out").exists()


def test_a_variant_listed_in_methods_is_named_a_variant(tmp_path, capsys):
    study = tiny_study_file(tmp_path, "1").read_text().replace('methods = ["odometry"]', 'methods = ["odometry", "odo2"]')
    (tmp_path / "s.toml").write_text(study + '[variants.odo2]\nmethod = "odometry"\n')
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "methods[1]", "'odo2' is a variant", "remove it from methods")


def test_ros2_folder_without_metadata_and_one_topic_in_two_roles(seq, tmp_path, capsys):
    pytest.importorskip("rosbags")
    bag = tmp_path / "bag"
    assert main(["export", str(seq), "--odom-noise", "large", "--out", str(bag)]) == 0
    capsys.readouterr()
    assert main(["import", str(bag), "--out", str(tmp_path / "x"), "--odom", "/groundtruth", "--groundtruth", "/groundtruth"]) == 2
    one_line_error(capsys, "--groundtruth /groundtruth is also the --odom topic")
    (bag / "metadata.yaml").unlink()
    assert main(["import", str(bag), "--out", str(tmp_path / "x")]) == 2
    one_line_error(capsys, f"bag folder {bag} has no metadata.yaml")


def test_orbslam3_refuses_images_it_would_crash_on(seq, tmp_path, capsys):
    pytest.importorskip("longslam_orbslam3", reason="the orbslam3 plugin is not installed")
    # 16 x 12: ORB-SLAM3 itself stopped with "vector::_M_default_append" (or a segfault) on such images
    assert main(["run", "--method", "orbslam3", str(seq), "--out", str(tmp_path / "run")]) == 2
    one_line_error(capsys, "16 x 12 images are too small for ORB-SLAM3", "at least 120 pixels")
    assert not (tmp_path / "run").exists()
