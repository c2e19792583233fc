"""Output files are not replaced silently: an existing world file or recording is refused without
--overwrite, a read-only folder is a clear error, and a report.md longslam did not write is kept."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from helpers.cli_checks import one_line_error
from helpers.studies import empty_study_folder
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main


@pytest.fixture()
def seq(tmp_path) -> Path:
    return write_tiny_sequence(tmp_path / "seq", n=12)[0]


def test_world_out_refuses_an_existing_file_without_overwrite(tmp_path, capsys):
    plan = tmp_path / "plan.png"
    keep = b"\x89PNG\r\n\x1a\nkeep"  # an image: --overwrite replaces only one (test_overwrite_kinds.py)
    plan.write_bytes(keep)
    assert main(["world", "--out", str(plan)]) == 2
    one_line_error(capsys, str(plan), "exists already", "--overwrite")
    assert plan.read_bytes() == keep
    assert main(["world", "--out", str(plan), "--overwrite"]) == 0
    assert plan.read_bytes() != keep


def test_viz_file_refused_without_overwrite(seq, tmp_path, capsys):
    keep = tmp_path / "keep.rrd"
    keep.write_bytes(b"keep")
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run"), "--viz", str(keep)]) == 2
    one_line_error(capsys, "keep.rrd", "exists already", "--overwrite")
    assert keep.read_bytes() == b"keep" and not (tmp_path / "run").exists()
    (tmp_path / "rec-odometry.rrd").write_bytes(b"keep")
    assert main(["demo", "--out", str(tmp_path / "demo"), "--viz", str(tmp_path / "rec.rrd")]) == 2
    one_line_error(capsys, "rec-odometry.rrd", "exists already")
    assert not (tmp_path / "demo").exists()


def test_viz_into_a_read_only_folder_is_a_clear_error(seq, tmp_path, capsys):
    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run"), "--viz", str(ro / "x.rrd")]) == 2
        one_line_error(capsys, "not writable")
    finally:
        ro.chmod(0o755)


def test_report_keeps_a_report_md_longslam_did_not_write(tmp_path, capsys):
    out = empty_study_folder(tmp_path / "study")
    (out / "report.md").write_text("my notes on the study\n")
    assert main(["report", str(out)]) == 2
    one_line_error(capsys, "report.md", "not a report longslam wrote", "--overwrite")
    assert (out / "report.md").read_text() == "my notes on the study\n"
    assert main(["report", str(out), "--overwrite"]) == 0
    assert main(["report", str(out)]) == 0  # its own report is rewritten without asking
