"""A run folder says which code made it and what CPU the run was denied."""

from __future__ import annotations

import json
import subprocess

from helpers.tiny_sequences import write_tiny_sequence
from longslam.run.scored_run import run_named
from longslam.run.provenance import SOURCE_ROOT, source_commit


def test_a_run_names_its_commit_and_its_cpu_wait(tmp_path):
    seq = write_tiny_sequence(tmp_path / "seq", n=20)[0]
    run_named("odometry", seq, tmp_path / "run", progress=False)
    stats = json.loads((tmp_path / "run" / "stats.json").read_text())
    head = subprocess.run(["git", "-C", str(SOURCE_ROOT), "rev-parse", "--short=7", "HEAD"], capture_output=True, text=True)
    if head.returncode == 0:
        assert stats["longslam_commit"].split("+")[0] == head.stdout.strip() == source_commit().split("+")[0]
    else:
        assert stats["longslam_commit"] is None
    assert 0.0 <= stats["cpu_wait_share"] <= 1.0 and stats["cpu_wait_s"] >= 0.0
    assert stats["tree_cpu_time_s"] > 0.0 and stats["child_processes"] == 0
