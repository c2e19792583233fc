"""`longslam run --config FILE` takes the method, sequence and parameters from a run's config.toml,
names the file in its errors, and repeats the run to the same trajectory."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from helpers.cli_checks import one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main
from longslam.slam.catalog import get_spec


def _captured_run(monkeypatch) -> dict:
    import longslam.run.engine as engine

    seen: dict = {}

    def fake(method, sequence, out, **_):
        seen.update(method=method.name, sequence=str(sequence), params=method.params)
        return SimpleNamespace(frames=1, real_time_factor=2.0, peak_rss_bytes=1e6, observer_time_s=None, about={},
                               method_stats={})

    monkeypatch.setattr(engine, "run_sequence", fake)
    return seen


def test_run_config_gives_the_method_sequence_and_params(tmp_path, monkeypatch, capsys):
    config = tmp_path / "config.toml"
    config.write_text('[run]\nmethod = "submap"\nsequence = "/data/seq"\n\n[params]\nvoxel_size = 0.3\n'
                      'truncation = 0.9\nfrontend.mode = "wheel"\n')
    seen = _captured_run(monkeypatch)
    assert main(["run", "--config", str(config), "--out", str(tmp_path / "r"), "--param", "truncation=1.2"]) == 0
    assert seen["method"] == "submap" and seen["sequence"] == "/data/seq"
    assert seen["params"] == {"voxel_size": 0.3, "truncation": 1.2, "frontend": {"mode": "wheel"}}
    assert get_spec("submap").config(seen["params"]).frontend.mode == "wheel"


@pytest.mark.parametrize("text, extra, needle", [
    ('[run]\nmethod = "submap"\n[params]\nvoxel_size = "0.3"\n', [], "config.toml: method 'submap': parameter voxel_size"),
    ('[run]\nmethod = "submap"\n[params]\nvoxel_sise = 0.3\n', [], "voxel_sise (did you mean voxel_size?)"),
    ('[params]\nvoxel_size = 0.3\n', [], 'expected [run] with method = "NAME"'),
    ('[run]\nmethod = "submap"\n', ["--method", "keyframe"], "holds the parameters of method 'submap'"),
    ('[run\n', [], "is not valid TOML"),
])
def test_run_config_errors_name_the_file(tmp_path, monkeypatch, capsys, text, extra, needle):
    config = tmp_path / "config.toml"
    config.write_text(text)
    _captured_run(monkeypatch)
    assert main(["run", "--config", str(config), "SEQ", "--out", str(tmp_path / "r"), *extra]) == 2
    one_line_error(capsys, needle)


@pytest.mark.slow
def test_a_run_repeated_from_its_config_gives_the_same_trajectory(tmp_path, capsys):
    sequence = write_tiny_sequence(tmp_path / "seq", n=30, turn=0.5, odometry_scale=1.05)[0]
    first, again = tmp_path / "first", tmp_path / "again"
    assert main(["run", "--method", "submap", str(sequence), "--out", str(first), "--param", "voxel_size=0.3"]) == 0
    assert main(["run", "--config", str(first / "config.toml"), "--out", str(again)]) == 0
    assert "voxel_size = 0.3" in (again / "config.toml").read_text()
    assert (again / "trajectory.txt").read_text() == (first / "trajectory.txt").read_text()
