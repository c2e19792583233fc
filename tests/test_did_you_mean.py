"""A mistyped name gets the name that was meant ("did you mean"), or the list of valid ones when
none is close: commands, methods, routes, parameters, and keys in a study file."""

from __future__ import annotations


import pytest

from helpers.cli_checks import one_line_error
from helpers.cli_checks import exit_status
from longslam.cli.main import main
from longslam.core.errors import InputError


def _error_line(capsys) -> str:
    lines = [line for line in capsys.readouterr().err.splitlines() if "error:" in line]
    assert len(lines) == 1, lines
    return lines[0]


@pytest.mark.parametrize("argv, needle", [
    (["evalute"], "invalid choice: 'evalute' (did you mean 'evaluate'?)"),
    (["evaluate", "a", "b", "--align", "sse3"], "invalid choice: 'sse3' (did you mean 'se3'?)"),
    (["run", "--methd", "keyframe", "SEQ", "--out", "OUT"], "unrecognized option: --methd (did you mean --method?)"),
    (["run", "--method", "keyframe", "SEQ", "--out", "OUT", "--overwite"], "--overwite (did you mean --overwrite?)"),
    (["run", "--method", "keyfram", "SEQ", "--out", "OUT"], "unknown method 'keyfram' (did you mean 'keyframe'?)"),
    (["run", "--method", "keyframe", "SEQ", "--out", "OUT", "--param", "max_feature=100"],
     "unknown parameter max_feature (did you mean max_features?)"),
    (["run", "--method", "submap", "SEQ", "--out", "OUT", "--param", "camera_height=1.3"],
     "unknown parameter camera_height (did you mean frontend.camera_height?)"),
    (["simulate", "--route", "dem", "--out", "OUT"], "unknown route 'dem' (did you mean 'demo'?)"),
    (["simulate", "--route", "demo", "--noise", "larg", "--out", "OUT"], "unknown noise level 'larg' (did you mean 'large'"),
    (["world", "--world", "universty", "--out", "OUT.png"], "unknown world 'universty' (did you mean 'university'?)"),
    (["list", "--params", "submpa"], "unknown method 'submpa' (did you mean 'submap'?)"),
])
def test_a_typo_gets_the_name_that_was_meant(tiny_sequence, tmp_path, capsys, argv, needle):
    argv = [str(tiny_sequence) if a == "SEQ" else str(tmp_path / a) if a.startswith("OUT") else a for a in argv]
    assert exit_status(argv) == 2
    line = _error_line(capsys)
    assert needle in line, line
    assert "required" not in line and "valid parameters" not in line  # the near miss, not 42 names
    assert not (tmp_path / "OUT").exists()


def test_a_parameter_close_to_none_lists_the_valid_ones(tiny_sequence, tmp_path, capsys):
    assert main(["run", "--method", "submap", str(tiny_sequence), "--out", str(tmp_path / "r"), "--param", "zzz=1"]) == 2
    one_line_error(capsys, "unknown parameter(s) zzz; valid parameters:", "voxel_size")


def test_a_camera_key_typo_in_a_study_file_is_suggested(tmp_path):
    from longslam.study.config import load_study

    study = tmp_path / "s.toml"
    study.write_text('name = "s"\nroutes = ["demo"]\nnoise = ["none"]\nmethods = ["odometry"]\nseeds = [0]\n'
                     "[camera]\nwidht = 320\n")
    with pytest.raises(InputError, match=r"camera.widht: unknown key \(did you mean width\?\); valid keys: width"):
        load_study(study)
