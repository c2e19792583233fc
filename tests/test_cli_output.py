"""What the command line prints and how: --version, the log level from -v/--quiet, progress bars
only on a terminal and when wanted, no carriage returns in a redirected stderr, --quiet hiding notes
but not results, and one form of the real-time factor in every table."""

from __future__ import annotations

import io
import logging
import sys
from importlib.metadata import version
from pathlib import Path

import pytest

from helpers.cli_checks import exit_status
from longslam.cli import output as cli_output
from longslam.cli.main import build_parser, main
from longslam.core import progress


@pytest.fixture(autouse=True)
def _fresh_output_settings():
    """main() sets process-wide switches (bars, the log level, --quiet): back to the defaults."""
    yield
    progress.set_enabled(None)
    cli_output._quiet = False
    logging.getLogger("longslam").setLevel(logging.NOTSET)


def test_version_is_the_installed_distributions(capsys):
    assert exit_status(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"longslam {version('longslam')}"


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
