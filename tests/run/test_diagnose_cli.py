"""`longslam diagnose RUN SEQ`: the text, the JSON and the picture, from a run folder's files."""

from __future__ import annotations

import json

import numpy as np

from helpers.cli_checks import one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main
from longslam.run.folder import write_table
from longslam.slam.api import Table


def _run(tmp_path):
    seq = write_tiny_sequence(tmp_path / "seq", n=30, step=0.2, odometry_scale=1.1)[0]
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run")]) == 0
    return seq, tmp_path / "run"


def test_diagnose_prints_stretches_and_writes_json_and_a_picture(tmp_path, capsys):
    seq, run = _run(tmp_path)
    # What keyframe or submap would write: a loop constraint (exact, from the truth) and the factors.
    write_table(run / "loops.csv", Table(("frame_i", "frame_j", "dx_m", "dy_m", "dyaw_rad"), np.array([[2, 20, 3.6, 0, 0]])))
    frames = np.column_stack([np.arange(30), np.ones(30), np.zeros(30), np.ones(30), np.full(30, 0.01), np.zeros(30)])
    write_table(run / "frontend.csv", Table(("frame", "wheel", "visual", "scan", "scan_shift_m", "scan_turn_deg"), frames))
    capsys.readouterr()
    args = ["diagnose", str(run), str(seq), "--stretch", "2", "--json", str(tmp_path / "d.json"), "--plot", str(tmp_path / "d.png")]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "58 m" not in out and "30 frames, 6 m" in out
    assert "loop constraints: 1, 0 wrong" in out and "along error picked up most at" in out
    found = json.loads((tmp_path / "d.json").read_text())
    assert found["units"]["along"] == "m" and len(found["stretches"]) == 3
    # The odometry overshoots by 10 %: the error is all along the track, growing stretch by stretch.
    assert found["summary"]["final_along_m"] > 0.5 and abs(found["summary"]["final_across_m"]) < 1e-6
    assert all(s["along_gain_m"] > 0 for s in found["stretches"])
    assert {s["dominant"] for s in found["stretches"]} <= {"scans", "loops"}
    assert (tmp_path / "d.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # Written files are not replaced without --overwrite.
    assert main(args) == 2
    one_line_error(capsys, "d.png", "--overwrite")


def test_a_run_without_tables_is_diagnosed_without_factors(tmp_path, capsys):
    seq, run = _run(tmp_path)
    capsys.readouterr()
    assert main(["diagnose", str(run), str(seq)]) == 0
    out = capsys.readouterr().out
    assert "loop constraints: none" in out and "no frontend.csv" in out


def test_a_folder_that_is_no_run_is_named(tmp_path, capsys):
    seq = write_tiny_sequence(tmp_path / "seq", n=5)[0]
    assert main(["diagnose", str(seq), str(seq)]) == 2
    one_line_error(capsys, str(seq), "trajectory.txt")


def test_a_runs_events_are_read_with_their_frames(tmp_path, capsys):
    from longslam.run.folder import EVENTS, read_events, write_events
    from longslam.slam.api import Event

    seq, run = _run(tmp_path)
    events = [Event("tracking_lost", 4, 9, 0.4, 0.9, "6 frames"), Event("new_map", 10, 10, 1.0, 1.0, "map 2"),
              Event("loop", 20, 20, 2.0, 2.0, "*Loop detected, with a comma")]
    write_events(run / EVENTS, events)
    assert read_events(run / EVENTS) == events
    capsys.readouterr()
    assert main(["diagnose", str(run), str(seq), "--json", str(tmp_path / "d.json")]) == 0
    out = capsys.readouterr().out
    assert "events: 1 loop, 1 new_map, 1 tracking_lost" in out
    assert "frames 4-9" in out and "0.4-0.9 s" in out and "map 2" in out
    found = json.loads((tmp_path / "d.json").read_text())
    assert [e["kind"] for e in found["events"]] == ["tracking_lost", "new_map", "loop"]
    # A damaged events file is named, with its line.
    (run / EVENTS).write_text((run / EVENTS).read_text() + "loop,x,1,0,0,\n")
    assert main(["diagnose", str(run), str(seq)]) == 2
    one_line_error(capsys, "events.csv", "line 5")


def test_a_run_diagnosed_against_another_sequence_is_warned_of_as_evaluate_does(tmp_path, capsys):
    """A sequence of another route gave 71 m and +106 deg, exit 0 and no word; `evaluate` warns."""
    seq, run = _run(tmp_path)
    other = write_tiny_sequence(tmp_path / "other", n=30, step=0.2, turn=1.5, seed=1)[0]
    capsys.readouterr()
    assert main(["diagnose", str(run), str(seq)]) == 0
    assert "warning" not in capsys.readouterr().err
    assert main(["diagnose", str(run), str(other), "--json", str(tmp_path / "d.json")]) == 0
    err = capsys.readouterr().err
    expected = f"warning: {run} ran on the sequence {seq.resolve()} (its stats.json), not on {other}"
    assert expected in err
    assert main(["evaluate", str(run), str(other)]) == 0
    assert expected in capsys.readouterr().err  # the same words
    assert json.loads((tmp_path / "d.json").read_text())["warnings"] == [expected[len("warning: "):]]
