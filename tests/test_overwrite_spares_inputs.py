"""--overwrite never deletes what a command reads: a run, simulate, export, import or vocabulary
build given --overwrite replaces only a folder of the kind it writes, never its input, and the final
rename keeps a folder that became the user's in the meantime."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from helpers.cli_checks import one_line_error
from helpers.file_trees import file_tree
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main


@pytest.fixture()
def seq(tmp_path) -> Path:
    return write_tiny_sequence(tmp_path / "seq", n=12)[0]


def test_run_overwrite_never_deletes_its_input_sequence(seq, tmp_path, capsys):
    before = file_tree(tmp_path)
    for out in (seq, tmp_path, seq / "run"):  # the input, a folder holding it, a folder inside it
        assert main(["run", "--method", "odometry", str(seq), "--out", str(out), "--overwrite"]) == 2
        one_line_error(capsys, str(out), "input sequence")
        assert file_tree(tmp_path) == before
    # through a symbolic link too: the real paths are compared
    link = tmp_path.parent / f"{tmp_path.name}-link"
    link.symlink_to(tmp_path)
    assert main(["run", "--method", "odometry", str(seq), "--out", str(link / "seq"), "--overwrite"]) == 2
    one_line_error(capsys, "input sequence")
    assert file_tree(tmp_path) == before


def test_run_overwrite_replaces_only_a_run_folder(seq, tmp_path, capsys):
    other = write_tiny_sequence(tmp_path / "other", n=5)[0]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    holding = tmp_path / "holding"
    assert main(["run", "--method", "odometry", str(seq), "--out", str(holding / "inner")]) == 0
    (holding / "stats.json").write_text("{}")  # looks like a run, but holds one
    (holding / "config.toml").write_text("")
    capsys.readouterr()
    for out, why in ((other, "no stats.json"), (mine, "no stats.json"), (holding, "holds a run")):
        before = file_tree(out)
        assert main(["run", "--method", "odometry", str(seq), "--out", str(out), "--overwrite"]) == 2
        one_line_error(capsys, str(out), "replaces only a run folder", why, "nothing was deleted")
        assert file_tree(out) == before
    run = tmp_path / "run"
    assert main(["run", "--method", "odometry", str(seq), "--out", str(run)]) == 0
    assert main(["run", "--method", "odometry", str(seq), "--out", str(run), "--overwrite"]) == 0  # a run: replaced


def test_simulate_overwrite_replaces_only_a_sequence(tmp_path, capsys, monkeypatch):
    from longslam.sim import simulate as recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered before --out was checked"))
    seq = write_tiny_sequence(tmp_path / "seq", n=5)[0]
    (seq / "notes.txt").write_text("mine")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "a.txt").write_text("mine")
    route = tmp_path / "r.txt"
    route.write_text("20 31.25\n22 31.25\n")
    for out, why in ((seq, "not a sequence's: notes.txt"), (mine, "no meta.json"), (tmp_path, "holds the input")):
        before = file_tree(tmp_path)
        assert main(["simulate", "--route", str(route), "--out", str(out), "--overwrite"]) == 2
        one_line_error(capsys, str(out), why)
        assert file_tree(tmp_path) == before


@pytest.mark.parametrize("fmt", ["ros2", "ros1"])
def test_export_and_import_overwrite_never_delete_their_input(seq, tmp_path, capsys, fmt):
    pytest.importorskip("rosbags")
    bag = tmp_path / ("bag" if fmt == "ros2" else "seq.bag")
    assert main(["export", str(seq), "--odom-noise", "large", "--format", fmt, "--out", str(bag)]) == 0
    capsys.readouterr()
    before = file_tree(tmp_path)
    if fmt == "ros2":  # a sequence is not a bag: refused, whether it is the input or not
        assert main(["export", str(seq), "--odom-noise", "large", "--out", str(seq), "--overwrite"]) == 2
        one_line_error(capsys, "input sequence")
        assert main(["export", str(seq), "--odom-noise", "large", "--out", str(tmp_path), "--overwrite"]) == 2
        one_line_error(capsys, "holds the input sequence")
    else:
        (tmp_path / "notes.bag").write_text("not a bag")
        before = file_tree(tmp_path)
        assert main(["export", str(seq), "--odom-noise", "large", "--format", "ros1", "--out", str(tmp_path / "notes.bag"), "--overwrite"]) == 2
        one_line_error(capsys, "not a ROS 1 bag")
    assert main(["import", str(bag), "--out", str(bag), "--overwrite"]) == 2
    one_line_error(capsys, "input bag" if fmt == "ros2" else "is a file")
    assert file_tree(tmp_path) == before
    assert main(["import", str(bag), "--out", str(seq), "--overwrite"]) == 0  # a sequence: replaced
    capsys.readouterr()
    assert main(["export", str(seq), "--odom-noise", "large", "--format", fmt, "--out", str(bag), "--overwrite"]) == 0  # a bag: replaced


def test_the_final_rename_keeps_a_folder_that_became_the_users(seq, tmp_path, monkeypatch):
    """A run checks --out again when it renames its output: a folder someone put there meanwhile stays."""
    from longslam.core.errors import InputError
    from longslam.run import engine
    from longslam.run.scored_run import run_named

    out = tmp_path / "run"
    run_named("odometry", seq, out, progress=False)
    real = engine.run_frames

    def meanwhile(*args, **kwargs):
        shutil.rmtree(out)
        out.mkdir()
        (out / "mine.txt").write_text("mine")
        return real(*args, **kwargs)

    monkeypatch.setattr(engine, "run_frames", meanwhile)
    with pytest.raises(InputError, match="replaces only a run folder"):
        run_named("odometry", seq, out, overwrite=True, progress=False)
    assert sorted(os.listdir(out)) == ["mine.txt"]
    assert not [p for p in tmp_path.iterdir() if ".partial-" in p.name]


def test_vocabulary_build_never_writes_into_its_input_sequence(seq, tmp_path, capsys):
    before = file_tree(seq)
    for out in (seq / "rgb.txt", seq / "voc.txt"):
        assert main(["vocabulary", "build", "--sequence", str(seq), "--out", str(out), "--overwrite"]) == 2
        one_line_error(capsys, str(out), "inside the input")
        assert file_tree(seq) == before
    assert main(["vocabulary", "build", "--sequence", str(seq), "--out", str(tmp_path / "v.txt"),
                 "--seed", str(2**64)]) == 2
    one_line_error(capsys, "--seed", "2**63 - 1")
