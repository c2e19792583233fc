"""The command line's manners (issue 24): --version, completion, -v/--quiet/--no-progress, help on
every option, "did you mean", bags given to `run`, arguments checked before work, `run --config`,
`list --params`, and one form of the real-time factor."""

from __future__ import annotations

from types import SimpleNamespace

import argparse
import io
import logging
import os
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import pytest

from helpers.cli_checks import complete, one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli import output as cli_output
from longslam.core import progress
from longslam.cli.main import build_parser, main
from longslam.cli.parser import subcommand_parsers
from longslam.core.errors import InputError
from longslam.cli.settings_doc import describe
from longslam.slam.catalog import BUILTIN, get_spec


@pytest.fixture(autouse=True)
def _fresh_output_settings():
    """main() sets process-wide switches (bars, the log level, --quiet): back to the defaults."""
    yield
    progress.set_enabled(None)
    cli_output._quiet = False
    logging.getLogger("longslam").setLevel(logging.NOTSET)


def _main(argv: list[str]) -> int:
    """main()'s status, also when argparse exits (a usage error)."""
    try:
        return main(argv)
    except SystemExit as exit:
        return exit.code


# --- --version ---------------------------------------------------------------------------------
def test_version_is_the_installed_distributions(capsys):
    assert _main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"longslam {version('longslam')}"


# --- completion --------------------------------------------------------------------------------
@pytest.mark.parametrize("line, expected", [
    ("longslam run --method k", {"keyframe"}),
    ("longslam ev", {"evaluate"}),
    ("longslam simulate --route paper-", {"paper-300m", "paper-1km"}),
    ("longslam simulate --route demo --noise l", {"large"}),
    ("longslam demo --noise x", {"xlarge"}),
    ("longslam world --world univ", {"university"}),
    ("longslam list --params sub", {"submap"}),
    ("longslam run --method keyframe --param max_f", {"max_features="}),
    ("longslam run --method submap --param frontend.mo", {"frontend.mode="}),
])
def test_completion_offers_the_names(monkeypatch, line, expected):
    assert expected <= set(complete(monkeypatch, line)), complete(monkeypatch, line)


@pytest.mark.slow
def test_completion_through_the_installed_command(tmp_path):
    """The real `longslam` script answers a completion request (what the shell function that
    `register-python-argcomplete longslam` prints does), and runs nothing else."""
    answer = tmp_path / "answer"
    line = "longslam run --method k"
    env = {**os.environ, "_ARGCOMPLETE": "1", "_ARGCOMPLETE_SHELL": "bash", "COMP_LINE": line,
           "COMP_POINT": str(len(line)), "_ARGCOMPLETE_STDOUT_FILENAME": str(answer)}
    script = Path(sys.executable).with_name("longslam")
    done = subprocess.run([str(script)], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert answer.read_text().split("\013") == ["keyframe "]


# --- help and common options -------------------------------------------------------------------
def _all_parsers() -> list[argparse.ArgumentParser]:
    parser = build_parser()
    return [parser, *subcommand_parsers(parser)]


def test_every_option_of_every_subcommand_has_help():
    missing = []
    for parser in _all_parsers():
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                missing += [f"{parser.prog} {c.dest}" for c in action._choices_actions if not c.help]
            elif not action.help or action.help == argparse.SUPPRESS:
                missing.append(f"{parser.prog} {'/'.join(action.option_strings) or action.dest}")
    assert not missing, missing


def test_demo_help_explains_route_noise_and_seed(capsys):
    assert _main(["demo", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--route ROUTE route name" in text and "--noise NOISE odometry noise level" in text
    assert "--seed SEED seed of the odometry noise" in text


def test_common_options_before_and_after_every_subcommand():
    for parser in _all_parsers():
        for flag in ("--debug", "-v", "--verbose", "--quiet", "--no-progress"):
            assert flag in parser._option_string_actions, (parser.prog, flag)
    parser = build_parser()
    assert parser.parse_args(["-vv", "list"]).verbose == 2  # the top's value survives the subcommand
    args = parser.parse_args(["list", "-v", "--quiet", "--no-progress"])
    assert (args.verbose, args.quiet, args.no_progress) == (1, True, True)
    assert parser.parse_args(["list"]).verbose is None


# --- -v / --quiet / --no-progress ---------------------------------------------------------------
class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("argv, level", [([], logging.WARNING), (["-v"], logging.INFO), (["-vv"], logging.DEBUG),
                                         (["--quiet"], logging.ERROR)])
def test_log_level_follows_verbose_and_quiet(argv, level):
    cli_output.configure(build_parser().parse_args([*argv, "list"]))
    assert logging.getLogger("longslam").getEffectiveLevel() == level


@pytest.mark.parametrize("argv, terminal, drawn", [
    ([], True, True), ([], False, False), (["--no-progress"], True, False), (["--quiet"], True, False),
])
def test_bars_only_on_a_terminal_and_when_wanted(monkeypatch, argv, terminal, drawn):
    stderr = _Terminal() if terminal else io.StringIO()
    monkeypatch.setattr(sys, "stderr", stderr)
    cli_output.configure(build_parser().parse_args(["list", *argv]))
    for _ in progress.bar(range(3), desc="work"):
        pass
    assert progress.enabled() is drawn
    assert ("\r" in stderr.getvalue()) is drawn


def test_a_run_writes_no_carriage_returns_into_a_redirected_stderr(tiny_sequence, tmp_path, capsys):
    assert main(["run", "--method", "odometry", str(tiny_sequence), "--out", str(tmp_path / "run")]) == 0
    captured = capsys.readouterr()
    assert "\r" not in captured.err and "\r" not in captured.out
    assert "real-time factor" in captured.out


def test_quiet_hides_notes_not_results(capsys):
    cli_output.configure(build_parser().parse_args(["--quiet", "list"]))
    cli_output.note("a note")
    assert capsys.readouterr().err == ""
    cli_output.configure(build_parser().parse_args(["list"]))
    cli_output.note("a note")
    assert capsys.readouterr().err == "note: a note\n"


# --- "did you mean" ------------------------------------------------------------------------------
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
    assert _main(argv) == 2
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


# --- a bag where a sequence is expected ---------------------------------------------------------
@pytest.mark.parametrize("kind", ["ROS 2", "ROS 1"])
def test_run_on_a_bag_points_to_import(tmp_path, capsys, kind):
    if kind == "ROS 2":
        bag = tmp_path / "bag"
        bag.mkdir()
        (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    else:
        bag = tmp_path / "run.bag"
        bag.write_bytes(b"#ROSBAG V2.0\n")
    assert main(["run", "--method", "odometry", str(bag), "--out", str(tmp_path / "r")]) == 2
    one_line_error(capsys, f"{bag} is a {kind} bag, not a sequence folder", f"longslam import {bag} --out SEQUENCE")
    assert not (tmp_path / "r").exists()


# --- export / import check their arguments first --------------------------------------------------
def test_export_refuses_a_negative_camera_height_before_writing(tiny_sequence, tmp_path):
    pytest.importorskip("rosbags")
    from longslam.io.rosbag.export import export_sequence

    calls = []
    with pytest.raises(InputError, match="--camera-height must be .* 0 or more.* got -1"):
        export_sequence(tiny_sequence, tmp_path / "bag", camera_height=-1.0, progress=lambda *a: calls.append(a))
    assert calls == [] and not (tmp_path / "bag").exists()


def test_import_checks_max_depth_before_reading_the_bag(tmp_path, monkeypatch):
    pytest.importorskip("rosbags")
    from longslam.io.rosbag import import_

    def no_reading(*_):
        raise AssertionError("the bag was opened before --max-depth was checked")

    monkeypatch.setattr(import_, "_Bag", no_reading)
    with pytest.raises(InputError, match=r"--max-depth 20.0: expected metres in \(0, 13.107\]"):
        import_.import_bag(tmp_path / "bag", tmp_path / "seq", max_depth=20.0)


# --- run --config ------------------------------------------------------------------------------------
def _captured_run(monkeypatch) -> dict:
    import longslam.run.engine as engine

    seen: dict = {}

    def fake(method, sequence, out, params, **_):
        seen.update(method=method, sequence=str(sequence), params=params)
        return SimpleNamespace(frames=1, real_time_factor=2.0, peak_rss_bytes=1e6, observer_time_s=None, about={},
                               method_stats={})

    monkeypatch.setattr(engine, "run_sequence", fake)
    return seen


def test_run_config_gives_the_method_sequence_and_params(tmp_path, monkeypatch, capsys):
    config = tmp_path / "config.toml"
    config.write_text('[run]\nmethod = "submap"\nsequence = "/data/seq"\n\n[params]\nvoxel_size = 0.3\n'
                      'truncation = 0.9\nfrontend.mode = "wheel"\n')
    seen = _captured_run(monkeypatch)
    assert main(["run", "--config", str(config), "--out", str(tmp_path / "r"), "--param", "truncation=1.2"]) == 0
    assert seen["method"] == "submap" and seen["sequence"] == "/data/seq"
    assert seen["params"] == {"voxel_size": 0.3, "truncation": 1.2, "frontend": {"mode": "wheel"}}
    assert get_spec("submap").config(seen["params"]).frontend.mode == "wheel"


@pytest.mark.parametrize("text, extra, needle", [
    ('[run]\nmethod = "submap"\n[params]\nvoxel_size = "0.3"\n', [], "config.toml: method 'submap': parameter voxel_size"),
    ('[run]\nmethod = "submap"\n[params]\nvoxel_sise = 0.3\n', [], "voxel_sise (did you mean voxel_size?)"),
    ('[params]\nvoxel_size = 0.3\n', [], 'expected [run] with method = "NAME"'),
    ('[run]\nmethod = "submap"\n', ["--method", "keyframe"], "holds the parameters of method 'submap'"),
    ('[run\n', [], "is not valid TOML"),
])
def test_run_config_errors_name_the_file(tmp_path, monkeypatch, capsys, text, extra, needle):
    config = tmp_path / "config.toml"
    config.write_text(text)
    _captured_run(monkeypatch)
    assert main(["run", "--config", str(config), "SEQ", "--out", str(tmp_path / "r"), *extra]) == 2
    one_line_error(capsys, needle)


@pytest.mark.slow
def test_a_run_repeated_from_its_config_gives_the_same_trajectory(tmp_path, capsys):
    sequence = write_tiny_sequence(tmp_path / "seq", n=30, turn=0.5, odometry_scale=1.05)[0]
    first, again = tmp_path / "first", tmp_path / "again"
    assert main(["run", "--method", "submap", str(sequence), "--out", str(first), "--param", "voxel_size=0.3"]) == 0
    assert main(["run", "--config", str(first / "config.toml"), "--out", str(again)]) == 0
    assert "voxel_size = 0.3" in (again / "config.toml").read_text()
    assert (again / "trajectory.txt").read_text() == (first / "trajectory.txt").read_text()


# --- list --params ----------------------------------------------------------------------------------
def test_list_params_shows_default_allowed_values_and_doc(capsys):
    assert main(["list", "--params", "keyframe"]) == 0
    lines = {line.split()[0]: " ".join(line.split()) for line in capsys.readouterr().out.splitlines()[1:]}
    assert lines["max_features"].startswith("max_features 2000 whole number 1 to 100000 ")
    assert lines["vocabulary_index"].startswith("vocabulary_index hnsw one of bruteforce, flat, hnsw ")
    assert lines["loop_sigma_linear"].startswith("loop_sigma_linear 0.05 (0, inf) ")
    assert lines["obstacle_min_height"].startswith("obstacle_min_height 0.2 [0, 1.5) ")  # below the max's default
    assert lines["frontend.camera_height"].startswith("frontend.camera_height none (0, inf) or none ")
    assert len(lines) == len(describe(get_spec("keyframe").config_type))


@pytest.mark.parametrize("method", sorted(BUILTIN))
def test_every_parameter_has_a_line_of_doc(method):
    config_type = get_spec(method).config_type
    thin = [(p.name, p.doc) for p in describe(config_type) if len(p.doc.split()) < 3 or len(p.doc) > 160]
    assert not thin, thin


@pytest.mark.parametrize("method", sorted(BUILTIN))
def test_listed_choices_are_what_the_config_accepts(method):
    import dataclasses

    config_type = get_spec(method).config_type
    for param in describe(config_type):
        if not param.allowed.startswith("one of "):
            continue
        for choice in param.allowed[len("one of "):].split(", "):
            get_spec(method).config({param.name: choice})
        with pytest.raises(InputError):
            get_spec(method).config({param.name: "no-such-choice"})
    assert dataclasses.is_dataclass(config_type) or config_type is None


# --- the real-time factor ----------------------------------------------------------------------------
def test_the_real_time_factor_of_a_method_that_does_nothing_reads_as_such():
    from longslam.cli.demo import format_table
    from longslam.run.speed import describe_real_time_factor, format_real_time_factor
    from longslam.study.report.results import StudyResults
    from longslam.study.report.tables import runs_table

    assert [format_real_time_factor(v) for v in (47382.0, 80323.0, 999.4, 12.345, 0.8512, None)] == \
        ["> 1000", "> 1000", "999", "12.3", "0.851", "–"]
    assert "negligible" in describe_real_time_factor(80323.0)
    assert "slower than real time" in describe_real_time_factor(0.5)
    row = {"method": "odometry", "ate": 1.0, "e_trans": 0.1, "e_rot": 0.1, "peak_rss_bytes": 2e8,
           "real_time_factor": 80323.0}
    assert format_table([row]).splitlines()[-1].split(" | ")[-1].strip() == "> 1000"
    run = {"method": "odometry", "route": "demo", "noise": "large", "status": "ok", "elapsed_s": 3.0,
           "method_time_s": 0.01, "real_time_factor": 47382.0, "frames": 463}
    results = StudyResults(Path("."), {}, [run], [run], ["demo"], ["large"], ["odometry"])
    assert runs_table(results).rows[0][3].text == "> 1000"
