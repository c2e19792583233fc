"""--overwrite replaces only what the command itself writes, recognised by its content: not the
user's file that happens to carry an image's name, not a text file given as a
vocabulary's --out, and never the run folder holding the --config a run reads."""

from __future__ import annotations

import pytest

from helpers.cli_checks import one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main


@pytest.mark.parametrize("name, needle", [("plan.png", "not a PNG image"), ("plan.pdf", "not a PDF file"),
                                          ("plan.svg", "not an SVG image")])
def test_world_overwrite_replaces_only_an_image(tmp_path, capsys, name, needle):
    mine = tmp_path / name
    mine.write_text("my notes")
    assert main(["world", "--out", str(mine), "--overwrite"]) == 2
    one_line_error(capsys, str(mine), "--overwrite replaces only a file of the kind it writes", needle, "nothing was replaced")
    assert mine.read_text() == "my notes"
    mine.unlink()
    assert main(["world", "--out", str(mine)]) == 0
    assert main(["world", "--out", str(mine), "--overwrite"]) == 0  # its own image: replaced


def test_vocabulary_build_overwrite_replaces_only_a_vocabulary(tmp_path, capsys):
    seq = write_tiny_sequence(tmp_path / "seq", n=5)[0]
    mine = tmp_path / "voc.txt"
    mine.write_text("my thesis\n")
    assert main(["vocabulary", "build", "--sequence", str(seq), "--out", str(mine), "--overwrite"]) == 2
    one_line_error(capsys, str(mine), "not a vocabulary", "nothing was replaced")
    assert mine.read_text() == "my thesis\n"


def test_run_config_never_overwrites_its_own_run_folder(tmp_path, capsys):
    seq = write_tiny_sequence(tmp_path / "seq", n=10)[0]
    run = tmp_path / "run"
    assert main(["run", "--method", "odometry", str(seq), "--out", str(run)]) == 0
    capsys.readouterr()
    before = {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()}
    assert main(["run", "--config", str(run / "config.toml"), "--out", str(run), "--overwrite"]) == 2
    one_line_error(capsys, f"run folder {run} holds the --config {run / 'config.toml'}", "choose another --out")
    assert {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()} == before
    assert main(["run", "--config", str(run / "config.toml"), "--out", str(tmp_path / "again")]) == 0


def test_viz_overwrite_replaces_only_a_recording(tmp_path):
    from longslam.core.errors import InputError
    from longslam.viz.live import check_target

    mine = tmp_path / "run.rrd"
    mine.write_text("my notes")
    with pytest.raises(InputError, match="is not a rerun recording; nothing was replaced"):
        check_target(str(mine), overwrite=True)
    mine.write_bytes(b"RRF2\0)\0\0")  # how rerun's recordings start
    check_target(str(mine), overwrite=True)
