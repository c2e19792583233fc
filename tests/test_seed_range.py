"""Seeds are the ones SQLite can store: one out of range is refused in a study and on the command
line before anything runs, and the largest one is drawn and recorded as given."""

from __future__ import annotations


import pytest

from helpers.cli_checks import one_line_error
from helpers.studies import tiny_study_file
from longslam.cli.main import main


@pytest.mark.parametrize("seeds, needle", [
    ("[1180591620717411303424]", "seeds[0]: seed 1180591620717411303424"),
    ("[0, 9223372036854775808]", "seeds[1]: seed 9223372036854775808"),
])
def test_a_seed_sqlite_cannot_store_is_refused_in_a_study(tmp_path, capsys, seeds, needle):
    study = tiny_study_file(tmp_path, seeds)
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, str(study), needle, "2**63 - 1")
    assert not (tmp_path / "out").exists()


def test_the_largest_seed_is_drawn_and_recorded(tmp_path):
    from longslam.study.database import ResultsDB
    from longslam.study.config import load_study
    from longslam.study.spec import plan_runs
    from longslam.study.record import RunRecord

    config = load_study(tiny_study_file(tmp_path, "[9223372036854775807]"))
    (spec,) = plan_runs(config)
    with ResultsDB(tmp_path / "db.sqlite") as db:  # an OverflowError came from here before seeds were checked
        db.record(spec, RunRecord.failed("x"), None)
        assert db.runs()[0]["seed"] == 2**63 - 1


@pytest.mark.parametrize("command", ["simulate", "demo"])
def test_a_seed_out_of_range_on_the_command_line(tmp_path, capsys, monkeypatch, command):
    from longslam.sim import simulate as recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered before the seed was checked"))
    args = ["--route", "demo"] if command == "simulate" else []
    assert main([command, *args, "--seed", str(2**64), "--out", str(tmp_path / "x")]) == 2
    one_line_error(capsys, str(2**64), "2**63 - 1")
    assert not (tmp_path / "x").exists()
