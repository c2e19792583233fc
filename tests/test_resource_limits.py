"""Values that would exhaust the machine are refused before the work starts: size-like method
parameters, a huge camera, an absurd study grid (with its count); a study shows its run count first."""

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


@pytest.mark.parametrize("method, param, needle", [
    ("keyframe", "grid_cell=0.000001", "grid_cell must be from 0.01 to 10 m"),
    ("keyframe", "max_features=1000000000", "max_features must be from 1 to 100000"),
    ("keyframe", "cloud_voxel=1e-5", "cloud_voxel"),
    ("submap", "voxel_size=0.001", "voxel_size must be from 0.02 to 5 m"),
    ("submap", "grid_resolution=0.0001", "grid_resolution"),
    ("submap", "truncation=100", "truncation (100) may be at most 40 x voxel_size (8 m)"),
])
def test_size_like_parameters_are_refused_before_the_run(seq, tmp_path, capsys, method, param, needle):
    assert main(["run", "--method", method, str(seq), "--out", str(tmp_path / "run"), "--param", param]) == 2
    one_line_error(capsys, needle, "100" if "truncation" in param else "got")
    assert not (tmp_path / "run").exists()


def test_a_huge_camera_is_a_clear_error_not_a_memory_error(tmp_path, capsys, monkeypatch):
    from longslam.sim import simulate as recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered a huge camera"))
    assert main(["simulate", "--route", "demo", "--width", "100000", "--height", "100000", "--out", str(tmp_path / "s")]) == 2
    one_line_error(capsys, "width must be at most 7680 pixels", "100000")
    assert main(["simulate", "--route", "demo", "--width", "7680", "--height", "7680", "--out", str(tmp_path / "s")]) == 2
    one_line_error(capsys, "7680 x 7680 = 58982400 pixels", "GB")
    assert not (tmp_path / "s").exists()


def test_an_absurd_study_grid_is_refused_with_its_count_before_anything(tmp_path, capsys):
    study = tiny_study_file(tmp_path, "1000000000")
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "seeds", "1000000000", "100000")
    study = tiny_study_file(tmp_path, "30000")
    text = study.read_text().replace('noise = ["none"]', 'noise = ["none", "small", "large", "xlarge"]')
    study.write_text(text)
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "1 route x 4 noise levels x 1 method x 30000 seeds = 120000 runs", "100000")
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_study_shows_its_run_count_first(tmp_path, capsys):
    study = tiny_study_file(tmp_path, "2")
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--no-report"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0] == "study s: 1 route x 1 noise level x 1 method x 2 seeds = 2 runs"
