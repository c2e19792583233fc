"""Running a method over a sequence on disk, its outputs and the harness's figures; the CLI."""

import json

import numpy as np
import pytest

from longslam.cli.main import main
from longslam.core.errors import InputError, UnknownNameError
from longslam.core.frame import Frame, Intrinsics
from longslam.io.trajectory_files import read_tum, write_kitti, write_tum
from longslam.run.scored_run import run_named
from longslam.run.scored_run import run_sequence_isolated
from longslam.slam.api import Method, MethodContext
from longslam.slam.catalog import create_method, method_names
from helpers.tiny_sequences import write_tiny_sequence

N = 30


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    return write_tiny_sequence(tmp_path_factory.mktemp("seq") / "seq", n=N, turn=0.3, odometry_scale=1.05)


def test_odometry_method_returns_the_odometry(sequence, tmp_path):
    path, truth, odometry = sequence
    figures = run_named("odometry", path, tmp_path / "run", progress=False)
    estimate = read_tum(tmp_path / "run" / "trajectory.txt")
    online = read_tum(tmp_path / "run" / "online.txt")
    np.testing.assert_allclose(estimate.poses, odometry.poses, atol=1e-7)
    np.testing.assert_allclose(online.poses, odometry.poses, atol=1e-7)
    stats = json.loads((tmp_path / "run" / "stats.json").read_text())
    for key in ("wall_time_s", "real_time_factor", "peak_rss_bytes", "method_stats", "frames"):
        assert key in stats
    assert stats["frames"] == N
    assert stats["peak_rss_bytes"] >= stats["baseline_rss_bytes"] > 10_000_000
    assert abs(stats["sequence_duration_s"] - N * 0.1) < 1e-6
    assert figures.real_time_factor > 1.0
    tenths = stats["step_time_mean_s_by_tenth"]  # the per-frame cost along the route, in ten parts
    assert len(tenths) == 10 and np.mean(tenths) == pytest.approx(stats["step_time_mean_s"], rel=0.2)
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no temporary folder left


def test_the_run_folder_keeps_the_config_it_ran_with(sequence, tmp_path):
    import tomllib

    from longslam.core.settings import from_mapping
    from longslam.slam.submap.config import SubmapConfig

    path, _, _ = sequence
    run_named("submap", path, tmp_path / "run", {"submap_interval": "1.5", "registration": False}, progress=False)
    written = tomllib.loads((tmp_path / "run" / "config.toml").read_text())
    assert written["run"]["method"] == "submap" and written["run"]["sequence"] == str(path.resolve())
    # Every field, defaults included, so the run can be repeated from its folder alone.
    assert from_mapping(SubmapConfig, written["params"], "config.toml") == SubmapConfig(submap_interval=1.5, registration=False)


def test_existing_run_folder_is_refused(sequence, tmp_path):
    (tmp_path / "run").mkdir()
    with pytest.raises(InputError, match="exists already"):
        run_named("odometry", sequence[0], tmp_path / "run", progress=False)


@pytest.mark.slow
def test_isolated_run_measures_its_own_process(sequence, tmp_path):
    figures = run_sequence_isolated("odometry", sequence[0], tmp_path / "run", progress=False)
    assert figures.frames == N and figures.peak_rss_bytes > 0
    # Bad input in the run's process is the same one-line error in this one.
    with pytest.raises(InputError, match="unknown method 'no-such-method'"):
        run_sequence_isolated("no-such-method", sequence[0], tmp_path / "run2", progress=False)


def test_registry_lists_methods_and_rejects_unknown_names():
    assert "odometry" in method_names()
    context = MethodContext(Intrinsics.from_fov(16, 12, 90.0), 8.0)
    assert isinstance(create_method("odometry", context), Method)
    with pytest.raises(UnknownNameError, match="valid method names: .*odometry"):
        create_method("orbslam9", context)
    with pytest.raises(InputError, match="takes no parameters"):
        create_method("odometry", context, {"alpha": 1})


def test_cli_evaluate_json_on_tum_and_kitti(sequence, tmp_path, capsys):
    path, truth, odometry = sequence
    write_tum(tmp_path / "est.txt", odometry)
    assert main(["evaluate", str(tmp_path / "est.txt"), str(path), "--json"]) == 0
    scores = json.loads(capsys.readouterr().out)
    for key in ("ate", "e_trans", "e_rot", "ape_rmse", "rpe_trans", "rpe_rot", "skipped_steps"):
        assert key in scores
    # The odometry overestimates every forward step by 5%.
    assert scores["e_trans"] == pytest.approx(0.05, rel=0.05)
    write_kitti(tmp_path / "est.kitti", odometry)
    write_kitti(tmp_path / "gt.kitti", truth)
    assert main(["evaluate", str(tmp_path / "est.kitti"), str(tmp_path / "gt.kitti"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["ate"] == pytest.approx(scores["ate"], abs=1e-6)


def test_cli_reports_bad_names_and_files(tmp_path, capsys):
    assert main(["simulate", "--route", "nowhere", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert "unknown route 'nowhere'" in err and "paper-1km" in err
    assert main(["evaluate", str(tmp_path / "missing.txt"), str(tmp_path / "gt.txt")]) == 2
    assert "missing.txt does not exist" in capsys.readouterr().err
    bad = tmp_path / "nan.txt"
    bad.write_text("0 nan 0 0 0 0 0 1\n0.1 0 0 0 0 0 0 1\n")
    assert main(["evaluate", str(bad), str(bad)]) == 2
    assert "NaN" in capsys.readouterr().err


@pytest.mark.parametrize("name, params, who", [
    ("odometry", {}, "the 'odometry' method"),
    ("keyframe", {"frontend.mode": "wheel"}, "the front end's mode 'wheel'"),
    ("submap", {"frontend.mode": "wheel"}, "the front end's mode 'wheel'"),
])
def test_methods_fed_by_odometry_refuse_frames_without_it(name, params, who):
    intrinsics = Intrinsics.from_fov(16, 12, 90.0)
    method = create_method(name, MethodContext(intrinsics, 8.0), params)
    frame = Frame(7, 0.7, np.zeros((12, 16, 3), np.uint8), np.ones((12, 16), np.float32), None, intrinsics)
    with pytest.raises(InputError, match=rf"frame 7 \(t=0.700000\) has no odometry pose; {who} needs a sequence with odometry.txt"):
        method.step(frame)


@pytest.mark.parametrize("name", ["keyframe", "submap"])
def test_methods_on_the_fused_front_end_run_without_odometry_and_say_so(name):
    intrinsics = Intrinsics.from_fov(16, 12, 90.0)
    method = create_method(name, MethodContext(intrinsics, 8.0))
    for i in range(3):
        frame = Frame(i, 0.1 * i, np.zeros((12, 16, 3), np.uint8), np.full((12, 16), 2.0, np.float32), None, intrinsics)
        assert np.all(np.isfinite(method.step(frame)))
    result = method.finish()
    assert len(result.trajectory) == 3
    assert result.stats["frontend"]["odometry_source"].startswith("none")
