"""A study folder belongs to its study: another study written into it is refused unless it only
extends the first."""

from __future__ import annotations

import pytest

from helpers.cli_checks import one_line_error
from helpers.file_trees import file_tree
from helpers.studies import tiny_study_file
from longslam.cli.main import main


@pytest.mark.slow  # renders a route and runs a study on it four times
def test_a_different_study_into_a_study_folder_is_refused_unless_extended(tmp_path, capsys):
    from longslam.study.database import ResultsDB

    a = tiny_study_file(tmp_path, "1", name="a.toml")
    out = tmp_path / "out"
    assert main(["study", str(a), "--out", str(out), "--no-report"]) == 0
    assert main(["study", str(a), "--out", str(out), "--no-report"]) == 0  # the same study: resumed
    b = tiny_study_file(tmp_path, "[1]", name="b.toml")
    capsys.readouterr()
    before = file_tree(out)
    assert main(["study", str(b), "--out", str(out), "--no-report"]) == 2
    line = one_line_error(capsys, str(out), "study 'a'", "study 'b'", "name, seeds", "--extend")
    assert "1 seed)" in line
    assert file_tree(out) == before
    assert main(["study", str(b), "--out", str(out), "--no-report", "--extend"]) == 0
    with ResultsDB(out / "results.sqlite") as db:
        assert db.study()["name"] == "a" and db.study()["seeds"] == [0, 1] and db.count() == 2
