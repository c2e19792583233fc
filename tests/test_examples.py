"""The examples in examples/ run as a user runs them, and give what they say."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers.scripts import load_script

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
pytestmark = pytest.mark.slow


def _load(name: str):
    return load_script(EXAMPLES / f"{name}.py", f"example_{name}")


def test_evaluate_own_trajectory(tmp_path, render_cache, monkeypatch):
    monkeypatch.setenv("LONGSLAM_CACHE", str(render_cache))
    scores = _load("evaluate_own_trajectory").main(tmp_path)
    assert 0.05 < scores["ate"] < 1.0 and scores["e_trans"] > 0


def test_own_method(tmp_path, render_cache, monkeypatch, method_catalogue):
    monkeypatch.setenv("LONGSLAM_CACHE", str(render_cache))
    scores = _load("own_method").main(tmp_path)
    assert scores["ate"] < 1.0


def test_small_study(tmp_path, render_cache, monkeypatch):
    monkeypatch.setenv("LONGSLAM_CACHE", str(render_cache))
    ate = _load("small_study").main(tmp_path)
    assert set(ate) == {(m, n) for m in ("keyframe", "odometry") for n in ("small", "large")}
    assert (tmp_path / "ate.png").read_bytes()[:4] == b"\x89PNG"
