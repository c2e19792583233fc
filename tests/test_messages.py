"""Error messages that say what was wrong: the form a name takes, the option the user typed (not
the library's field), the file that is missing or is a folder. Each message here missed the
point before its fix."""

from __future__ import annotations

from pathlib import Path

import pytest

from helpers.cli_checks import one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main


@pytest.fixture()
def seq(tmp_path) -> Path:
    return write_tiny_sequence(tmp_path / "seq", n=30)[0]


@pytest.mark.parametrize("route, needles", [
    ("tour-1KM", ["'tour-1KM'", "did you mean 'tour-1km'", "tour-<L>km", "NAME-xN"]),
    ("tour--5km", ["'tour--5km'", "tour-<L>km"]),
    ("demo-x-1", ["'demo-x-1'", "NAME-xN", "e.g. paper-1km-x3"]),
    ("myroute-x3.txt", ["route file myroute-x3.txt: no such file", "FILE-xN, e.g. myroute.txt-x3"]),
    ("nofile.txt", ["route file nofile.txt: no such file"]),
])
def test_a_route_that_is_no_route_is_shown_the_forms_a_route_takes(tmp_path, capsys, monkeypatch, route, needles):
    monkeypatch.chdir(tmp_path)
    assert main(["world", "--route", route, "--out", str(tmp_path / "plan.png")]) == 2
    line = one_line_error(capsys, *needles)
    if route.endswith(".txt"):
        assert "unknown route" not in line


def test_an_empty_places_file_is_said_to_have_no_places(tmp_path):
    from longslam.core.errors import InputError
    from longslam.world.reference import read_places

    (tmp_path / "places.json").write_text("{}")
    with pytest.raises(InputError, match="has no places") as err:
        read_places(tmp_path / "places.json")
    assert "expected an object" not in str(err.value)


def test_report_of_a_study_file_asks_for_the_study_folder(tmp_path, capsys):
    study = tmp_path / "study.toml"
    study.write_text('routes = ["demo"]\n')
    assert main(["report", str(study)]) == 2
    line = one_line_error(capsys, "study.toml is a file, not a study folder", "longslam report FOLDER")
    assert "--out study.toml" not in line


def test_run_config_that_is_a_run_folder_names_its_config_toml(seq, tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["run", "--method", "odometry", str(seq), "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["run", "--config", str(run), "--out", str(tmp_path / "again")]) == 2
    line = one_line_error(capsys, f"run config {run} is a folder", f"did you mean {run / 'config.toml'}?")
    assert "Errno" not in line


def test_run_config_keys_outside_a_table_are_called_keys(tmp_path, capsys):
    config = tmp_path / "config.toml"
    config.write_text('method = "odometry"\n')
    assert main(["run", "--config", str(config), "--out", str(tmp_path / "run")]) == 2
    line = one_line_error(capsys, "key(s) method outside a table", "[run]")
    assert "table(s)" not in line
    config.write_text("[parms]\n")
    assert main(["run", "--config", str(config), "--out", str(tmp_path / "run")]) == 2
    one_line_error(capsys, "unknown table(s) [parms]", "did you mean 'params'?")


def test_one_zip_for_both_save_options_is_refused_naming_both(seq, tmp_path, capsys):
    zipped = tmp_path / "a.zip"
    assert main(["evaluate", str(seq / "odometry.txt"), str(seq / "groundtruth.txt"), "--save-results", str(zipped),
                 "--save-rpe-results", str(zipped)]) == 2
    line = one_line_error(capsys, "--save-results and --save-rpe-results both name", "a.zip")
    assert "another process" not in line and not zipped.exists()


@pytest.mark.parametrize("option, needle", [
    (["-d", "inf"], "--delta inf: expected a finite number > 0"),
    (["-d", "nan"], "--delta nan"),
    (["--delta-tol", "-1"], "--delta-tol -1"),
    (["--n-to-align", "0", "--align"], "--n-to-align 0: expected -1 (all poses)"),
    (["--n-to-align", "1000", "--align"], "--n-to-align 1000 is more than the 30 associated poses"),
    (["--t-max-diff", "-1"], "--t-max-diff -1: expected a finite time difference"),
    (["--t-offset", "nan"], "--t-offset nan: expected a finite number of seconds"),
    (["--min-step", "-1"], "--min-step -1: expected a finite length > 0 m"),
])
def test_evaluate_errors_name_the_option_not_the_field(seq, capsys, option, needle):
    assert main(["evaluate", str(seq / "odometry.txt"), str(seq / "groundtruth.txt"), *option]) == 2
    line = one_line_error(capsys, needle)
    for field in ("n_to_align", "max_diff", "min_step", "rpe_delta", "the poses hold"):
        assert field not in line


@pytest.mark.parametrize("option, needle", [
    (["--fov", "0"], "--fov must be a number in (0, 180) degrees, got 0"),
    (["--fov", "nan"], "--fov nan: expected a finite number"),
    (["--width", "0"], "--width must be a positive integer, got 0"),
    (["--max-depth", "20"], "--max-depth must be a positive number of metres, at most 13.107"),
])
def test_camera_errors_name_the_option_not_the_field(tmp_path, capsys, option, needle):
    assert main(["simulate", "--route", "demo", "--out", str(tmp_path / "seq"), *option]) == 2
    assert "hfov_deg" not in one_line_error(capsys, needle)
    assert not (tmp_path / "seq").exists()


def test_an_input_named_in_its_label_is_not_named_twice(seq, tmp_path, capsys):
    assert main(["vocabulary", "build", "--sequence", str(seq), "--out", str(seq / "voc.txt")]) == 2
    line = one_line_error(capsys, f"is inside the input {seq};")
    assert f"{seq} {seq}" not in line


def test_a_binary_vocabulary_is_called_binary_not_echoed(tmp_path):
    from longslam.core.errors import InputError
    from longslam.vocabulary.dbow2 import check_vocabulary_file

    path = tmp_path / "voc.txt"
    path.write_bytes(b"\xffJ\x07\xf4" + bytes(range(256)) * 4)
    with pytest.raises(InputError) as refused:
        check_vocabulary_file(path)
    message = str(refused.value)
    assert message.endswith("its first line is b'\\xffJ\\x07\\xf4'... (binary data, not text)"), message
    path.write_bytes(b"10 6 0 0\n\x01\x02\xff\xfe garbage \x1b[31m red\n")
    with pytest.raises(InputError, match=r"voc.txt:2: .*got 4: b'\\x01\\x02\\xff\\xfe'\.\.\. \(binary data, not text\)$"):
        check_vocabulary_file(path)


def test_a_full_disk_inside_a_write_names_the_output(seq, tmp_path, capsys, monkeypatch):
    import errno

    from longslam.eval import evo_results

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")  # as a write() deep in a library: no file

    monkeypatch.setattr(evo_results, "save_ape_result", full)
    zipped = tmp_path / "a.zip"
    assert main(["evaluate", str(seq / "odometry.txt"), str(seq / "groundtruth.txt"), "--save-results", str(zipped)]) == 2
    one_line_error(capsys, f"writing {zipped}: No space left on device", "the disk is full")


@pytest.mark.parametrize("kind", ["ROS 2", "ROS 1"])
def test_run_on_a_bag_points_to_import(tmp_path, capsys, kind):
    if kind == "ROS 2":
        bag = tmp_path / "bag"
        bag.mkdir()
        (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    else:
        bag = tmp_path / "run.bag"
        bag.write_bytes(b"#ROSBAG V2.0\n")
    assert main(["run", "--method", "odometry", str(bag), "--out", str(tmp_path / "r")]) == 2
    one_line_error(capsys, f"{bag} is a {kind} bag, not a sequence folder", f"longslam import {bag} --out SEQUENCE")
    assert not (tmp_path / "r").exists()
