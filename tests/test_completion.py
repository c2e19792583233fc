"""Shell completion: command, method, route, noise and sensor names, in-process and through the
installed command."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.cli_checks import complete


def test_sensor_names_are_completed(monkeypatch):
    assert {"kinect-v1"} <= set(complete(monkeypatch, "longslam simulate --route demo --sensor kin"))
    assert {"ideal", "kinect-v1", "realsense-d435"} <= set(complete(monkeypatch, "longslam simulate --route demo --sensor "))


@pytest.mark.parametrize("line, expected", [
    ("longslam run --method k", {"keyframe"}),
    ("longslam ev", {"evaluate"}),
    ("longslam simulate --route paper-", {"paper-300m", "paper-1km"}),
    ("longslam simulate --route demo --noise l", {"large"}),
    ("longslam demo --noise x", {"xlarge"}),
    ("longslam world --world univ", {"university"}),
    ("longslam list --params sub", {"submap"}),
    ("longslam run --method keyframe --param max_f", {"max_features="}),
    ("longslam run --method submap --param frontend.mo", {"frontend.mode="}),
])
def test_completion_offers_the_names(monkeypatch, line, expected):
    assert expected <= set(complete(monkeypatch, line)), complete(monkeypatch, line)


@pytest.mark.slow
def test_completion_through_the_installed_command(tmp_path):
    """The real `longslam` script answers a completion request (what the shell function that
    `register-python-argcomplete longslam` prints does), and runs nothing else."""
    answer = tmp_path / "answer"
    line = "longslam run --method k"
    env = {**os.environ, "_ARGCOMPLETE": "1", "_ARGCOMPLETE_SHELL": "bash", "COMP_LINE": line,
           "COMP_POINT": str(len(line)), "_ARGCOMPLETE_STDOUT_FILENAME": str(answer)}
    script = Path(sys.executable).with_name("longslam")
    done = subprocess.run([str(script)], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert answer.read_text().split("\013") == ["keyframe "]
