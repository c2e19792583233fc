"""The ORB-SLAM3 plugin's events, from its per-frame tracking states and its console (no ORB-SLAM3 run)."""

from __future__ import annotations

import numpy as np
import pytest

from longslam.slam.api import Event

method = pytest.importorskip("longslam_orbslam3.method")
console_log = pytest.importorskip("longslam_orbslam3.console_log")


def test_untracked_stretches_new_maps_and_console_lines_become_events():
    # Starting up (-1 before the first map), lost twice, a second map, lost at the end.
    segments = [-1, 0, 0, -1, -1, 0, -1, -1, 1, 1, -1]
    frames = np.arange(len(segments))
    stamps = 0.1 * frames
    loop = Event("loop", 5, 5, 0.5, 0.5, "*Loop detected")
    events = method.run_events(segments, frames, stamps, [loop])
    assert [(e.kind, e.first_frame, e.last_frame) for e in events] == [
        ("tracking_lost", 3, 4), ("loop", 5, 5), ("tracking_lost", 6, 7), ("new_map", 8, 8), ("tracking_lost", 10, 10)]
    losses = [e for e in events if e.kind == "tracking_lost"]
    # Lost from frame 3 to the first tracked frame after it (5): 0.2 s; at the end, one frame's time.
    assert method._loss_seconds(losses[0], stamps) == pytest.approx(0.2)
    assert method._loss_seconds(losses[-1], stamps) == pytest.approx(0.1)


def test_the_console_is_followed_line_by_line(tmp_path):
    log = tmp_path / "console.log"
    log.write_text("before the run\n")
    follower = console_log.ConsoleFollower(log, log.stat().st_size)
    with log.open("a") as f:
        f.write("*Loop detected\nRelocalized!!\nStarting Global Bundle Adjustment\n*Merge det")
    assert [kind for kind, _ in follower.new_events()] == ["loop", "relocalized", "global_ba"]
    with log.open("a") as f:
        f.write("ected\n")
    assert [kind for kind, _ in follower.new_events()] == ["merge"]
    assert follower.new_events() == []
