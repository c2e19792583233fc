"""The CLI turns every expected failure into one line naming the problem, exit code 2, no traceback."""

import json

import pytest

from longslam.cli import main


def _one_line_error(capsys, *needles: str) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "error:" in lines[0], err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def test_evaluate_json_never_prints_nan_or_infinity(tmp_path, capsys):
    (tmp_path / "gt.txt").write_text("0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0 1\n0.2 2 0 0 0 0 0 1\n")
    (tmp_path / "huge.txt").write_text("0 0 0 0 0 0 0 1\n0.1 1e300 0 0 0 0 0 1\n0.2 1e308 0 0 0 0 0 1\n")
    assert main(["evaluate", str(tmp_path / "huge.txt"), str(tmp_path / "gt.txt"), "--json"]) == 2
    assert capsys.readouterr().out == ""
    assert main(["evaluate", str(tmp_path / "huge.txt"), str(tmp_path / "gt.txt"), "--json"]) == 2
    _one_line_error(capsys, "huge.txt", "ate", "infinity")
    assert main(["evaluate", str(tmp_path / "gt.txt"), str(tmp_path / "gt.txt"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["ate"] == 0.0
