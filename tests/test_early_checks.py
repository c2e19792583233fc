"""Checks that come before anything is written or started: a study whose config cannot run
creates no study folder, a plugin that cannot load stops a study before its first run. Each
check here came too late, or not at all, before its fix."""

from __future__ import annotations

import pytest

from helpers.cli_checks import one_line_error
from helpers.tiny_vocabulary import TINY_VOCABULARY
from longslam.cli.main import main
from longslam.core.errors import InputError

STUDY = 'name = "s"\nroutes = ["demo"]\nnoise = ["none"]\nmethods = ["odometry"]\nseeds = [0]\n'


@pytest.mark.parametrize("camera", ["[camera]\nmax_depth = 20\n", "[cameras.far]\nmax_depth = 20\n"])
def test_a_study_camera_deeper_than_a_sequence_stores_creates_no_folder(tmp_path, capsys, camera):
    study = tmp_path / "study.toml"
    study.write_text(STUDY + camera)
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, str(study), "max_depth", "at most 13.107", "got 20")
    assert not (tmp_path / "out").exists()


def test_a_damaged_cached_default_vocabulary_is_built_again(vocabulary_cache, caplog):
    from longslam.vocabulary import default

    built = vocabulary_cache
    path = default.default_vocabulary_path()
    path.parent.mkdir(parents=True)
    path.write_text("10 5 0 0\n0 0 garbage\n")  # cut short by a crash or a full disk
    with caplog.at_level("WARNING", logger="longslam"):
        assert default.default_vocabulary(progress=False)[0] == path
    assert built == [path] and path.read_text() == TINY_VOCABULARY
    assert any("the cached default vocabulary" in r.getMessage() and "building it again" in r.getMessage()
               for r in caplog.records)
    assert default.default_vocabulary(progress=False)[0] == path and len(built) == 1  # whole now: used
    path.write_text(TINY_VOCABULARY.replace("7", "8"))  # still a sound tree, but not the one built
    assert default.default_vocabulary(progress=False)[0] == path and len(built) == 2


def test_a_study_sensor_is_suggested_and_a_plugin_that_cannot_load_stops_the_study(tmp_path, capsys, monkeypatch):
    site = tmp_path / "site"
    dist = site / "longslam_broken_sensor-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: longslam-broken-sensor\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[longslam.sensors]\nmissing = longslam_no_such_sensor_module:Model\n")
    monkeypatch.syspath_prepend(str(site))
    study = tmp_path / "study.toml"
    for sensors, needles in (('["kinect-v2"]', ["sensors[0]", "unknown sensor 'kinect-v2' (did you mean 'kinect-v1'?)"]),
                             ('["ideal", "missing"]', ["sensors[1]", "sensor 'missing'", "cannot be loaded",
                                                       "longslam_no_such_sensor_module"])):
        study.write_text(STUDY + f"sensors = {sensors}\n")
        assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
        one_line_error(capsys, str(study), *needles)
        assert not (tmp_path / "out").exists()


def test_a_study_method_variant_is_suggested(tmp_path, capsys):
    study = tmp_path / "study.toml"
    study.write_text(STUDY + '[variants.fast]\nmethod = "keyfram"\n')
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "variants.fast.method", "unknown method 'keyfram' (did you mean 'keyframe'?)")


@pytest.mark.parametrize("ran, failed, code", [(3, 3, 2), (3, 2, 0), (0, 0, 0)])
def test_a_study_all_of_whose_runs_failed_exits_with_an_error(tmp_path, capsys, monkeypatch, ran, failed, code):
    from longslam.study import driver

    summary = driver.StudySummary(3, 3 - ran, ran, failed, 1.0, tmp_path / "out" / "results.sqlite", None)
    monkeypatch.setattr(driver, "run_study", lambda *a, **k: summary)
    study = tmp_path / "study.toml"
    study.write_text(STUDY)
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == code
    err = capsys.readouterr().err
    assert ("error: every run of the study failed (3 of 3)" in err) == (code == 2), err


@pytest.mark.parametrize("method, param, needle", [
    ("submap", "frontend.scan_information_scale=-1", "scan_information_scale must be >= 0, got -1.0"),
    ("keyframe", "frontend.max_correction=-0.5", "max_correction must be >= 0 m, got -0.5"),
    ("submap", "frontend.visual_sigma_yaw=0", "visual_sigma_yaw must be positive, got 0.0"),
    ("keyframe", "frontend.scan_anchor_lag=0", "scan_anchor_lag must be >= 1 frames, got 0"),
])
def test_nonsense_front_end_parameters_are_refused_before_the_run(tmp_path, capsys, method, param, needle):
    from helpers.tiny_sequences import write_tiny_sequence

    seq = write_tiny_sequence(tmp_path / "seq", n=5)[0]
    assert main(["run", "--method", method, str(seq), "--out", str(tmp_path / "run"), "--param", param]) == 2
    one_line_error(capsys, "front end", needle)
    assert not (tmp_path / "run").exists()


def test_export_refuses_a_negative_camera_height_before_writing(tiny_sequence, tmp_path):
    pytest.importorskip("rosbags")
    from longslam.io.rosbag.export import export_sequence

    calls = []
    with pytest.raises(InputError, match="--camera-height must be .* 0 or more.* got -1"):
        export_sequence(tiny_sequence, tmp_path / "bag", camera_height=-1.0, progress=lambda *a: calls.append(a))
    assert calls == [] and not (tmp_path / "bag").exists()


def test_import_checks_max_depth_before_reading_the_bag(tmp_path, monkeypatch):
    pytest.importorskip("rosbags")
    from longslam.io.rosbag import import_

    def no_reading(*_):
        raise AssertionError("the bag was opened before --max-depth was checked")

    monkeypatch.setattr(import_, "_Bag", no_reading)
    with pytest.raises(InputError, match=r"--max-depth 20.0: expected metres in \(0, 13.107\]"):
        import_.import_bag(tmp_path / "bag", tmp_path / "seq", max_depth=20.0)
