"""Shell completion of names beyond the first battery's: sensor models."""

from __future__ import annotations

from helpers.cli_checks import complete


def test_sensor_names_are_completed(monkeypatch):
    assert {"kinect-v1"} <= set(complete(monkeypatch, "longslam simulate --route demo --sensor kin"))
    assert {"ideal", "kinect-v1", "realsense-d435"} <= set(complete(monkeypatch, "longslam simulate --route demo --sensor "))
