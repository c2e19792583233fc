"""Checks that come before anything is written or started: a study whose config cannot run
creates no study folder, a plugin that cannot load stops a study before its first run. Each
check here came too late, or not at all, before its fix."""

from __future__ import annotations

import pytest

from conftest import one_line_error
from longslam.cli import main

STUDY = 'name = "s"\nroutes = ["demo"]\nnoise = ["none"]\nmethods = ["odometry"]\nseeds = [0]\n'


@pytest.mark.parametrize("camera", ["[camera]\nmax_depth = 20\n", "[cameras.far]\nmax_depth = 20\n"])
def test_a_study_camera_deeper_than_a_sequence_stores_creates_no_folder(tmp_path, capsys, camera):
    study = tmp_path / "study.toml"
    study.write_text(STUDY + camera)
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, str(study), "max_depth", "at most 13.107", "got 20")
    assert not (tmp_path / "out").exists()
