"""Shell completion of names beyond the first battery's: sensor models."""

from __future__ import annotations

from test_cli_manners import _complete


def test_sensor_names_are_completed(monkeypatch):
    assert {"kinect-v1"} <= set(_complete(monkeypatch, "longslam simulate --route demo --sensor kin"))
    assert {"ideal", "kinect-v1", "realsense-d435"} <= set(_complete(monkeypatch, "longslam simulate --route demo --sensor "))
