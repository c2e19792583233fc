"""An output path that exists and is not a regular file (a FIFO, a device node) is never
replaced, `--overwrite` or not: as root, replacing /dev/null left a regular file in its place."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from helpers.cli_checks import one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main


@pytest.fixture()
def seq(tmp_path) -> Path:
    return write_tiny_sequence(tmp_path / "seq", n=12)[0]


def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def _still_a_fifo(path: Path) -> None:
    assert stat.S_ISFIFO(os.lstat(path).st_mode), f"{path} was replaced"
    assert not [p for p in path.parent.iterdir() if ".partial-" in p.name]


def test_vocabulary_build_refuses_a_fifo_overwrite_or_not(seq, tmp_path, capsys):
    fifo = _fifo(tmp_path / "voc.txt")
    for extra in ([], ["--overwrite"]):
        assert main(["vocabulary", "build", "--sequence", str(seq), "--out", str(fifo), *extra]) == 2
        one_line_error(capsys, str(fifo), "named pipe (FIFO)", "not a regular file")
        _still_a_fifo(fifo)


def test_file_outputs_of_every_command_refuse_a_fifo(seq, tmp_path, capsys):
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run")]) == 0
    capsys.readouterr()
    commands = {
        "plan.png": lambda f: ["world", "--out", f, "--overwrite"],
        "ape.zip": lambda f: ["evaluate", str(tmp_path / "run"), str(seq), "--save-results", f, "--overwrite"],
        "rpe.zip": lambda f: ["evaluate", str(tmp_path / "run"), str(seq), "--save-rpe-results", f, "--overwrite"],
        "ape.png": lambda f: ["evaluate", str(tmp_path / "run"), str(seq), "--save-plot", f, "--overwrite"],
        "d.json": lambda f: ["diagnose", str(tmp_path / "run"), str(seq), "--json", f, "--overwrite"],
        "d.png": lambda f: ["diagnose", str(tmp_path / "run"), str(seq), "--plot", f, "--overwrite"],
        "rec.rrd": lambda f: ["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "r2"), "--viz", f,
                              "--overwrite"],
    }
    for name, command in commands.items():
        fifo = _fifo(tmp_path / name)
        assert main(command(str(fifo))) == 2, name
        one_line_error(capsys, str(fifo), "named pipe (FIFO)")
        _still_a_fifo(fifo)
    assert not (tmp_path / "r2").exists()


@pytest.mark.parametrize("command", ["run", "simulate"])
def test_folder_outputs_name_a_fifo_for_what_it_is(seq, tmp_path, capsys, monkeypatch, command):
    from longslam.sim import simulate as recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered before --out was checked"))
    fifo = _fifo(tmp_path / "out")
    args = (["run", "--method", "odometry", str(seq)] if command == "run" else ["simulate", "--route", "demo"])
    assert main([*args, "--out", str(fifo), "--overwrite"]) == 2
    one_line_error(capsys, str(fifo), "is a named pipe (FIFO)")
    _still_a_fifo(fifo)


def test_report_refuses_a_fifo_for_its_files(tmp_path, capsys):
    from longslam.study.database import DB_NAME, ResultsDB

    out = tmp_path / "study"
    out.mkdir()
    with ResultsDB(out / DB_NAME) as db:
        db.set_study({"name": "s", "routes": [], "noise": [], "methods": [], "seeds": [0]})
    fifo = _fifo(out / "report.md")
    assert main(["report", str(out), "--overwrite"]) == 2
    one_line_error(capsys, str(fifo), "named pipe (FIFO)")
    _still_a_fifo(fifo)


def test_an_atomic_write_never_replaces_a_fifo_that_appeared_meanwhile(tmp_path):
    """The last line of defence: whatever checked the path before, the final rename keeps a FIFO."""
    from longslam.core.errors import InputError
    from longslam.io.atomic import atomic_path, write_text_atomic

    fifo = tmp_path / "x.txt"
    with pytest.raises(InputError, match="named pipe"):
        with atomic_path(fifo) as tmp:
            Path(tmp).write_text("new")
            _fifo(fifo)
    _still_a_fifo(fifo)
    with pytest.raises(InputError, match="named pipe"):
        write_text_atomic(fifo, "new")
    _still_a_fifo(fifo)
    folder = tmp_path / "folder"  # a file never replaces a folder either
    folder.mkdir()
    (folder / "mine.txt").write_text("mine")
    with pytest.raises(InputError, match="is a folder"):
        write_text_atomic(folder, "new")
    assert (folder / "mine.txt").read_text() == "mine"


def test_a_device_node_is_refused_before_anything_is_opened(seq, tmp_path, capsys, nothing_under_dev):
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    from longslam.io.overwrite_policy import check_output_file_free

    assert main(["vocabulary", "build", "--sequence", str(seq), "--out", "/dev/null", "--overwrite"]) == 2
    one_line_error(capsys, "/dev/null", "is a character device, not a regular file")
    from longslam.core.errors import InputError

    with pytest.raises(InputError, match="character device"):
        check_output_file_free("/dev/null", True, "--json")
    with pytest.raises(InputError, match="character device"):
        check_output_file_free("/dev/null", False, "--json")
