"""benchmarks/compare.py's options, parameter renames and table, without running anything."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from helpers.scripts import load_script

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))  # compare.py imports its neighbour common.py
compare = load_script(BENCHMARKS / "compare.py", "benchmarks_compare")


def test_the_defaults_and_repeated_params():
    args = compare.parse_args(["c517f78"])
    assert (args.rev, args.routes, args.noise, args.seeds, args.repeats, args.params, args.keep) == (
        "c517f78", ["paper-300m"], "large", [0], 2, [], False)
    args = compare.parse_args(["HEAD~1", "--params", "frontend.mode=wheel", "max_features=500", "--params", "a=1",
                               "--seeds", "0", "3", "--methods", "keyframe"])
    assert args.params == ["frontend.mode=wheel", "max_features=500", "a=1"]
    assert args.seeds == [0, 3] and args.methods == ["keyframe"]


@pytest.mark.parametrize("argv", [["REV", "--params", "frontend.mode"], ["REV", "--params", "=wheel"],
                                  ["REV", "--repeats", "0"], []])
def test_bad_options_stop_with_usage(argv, capsys):
    with pytest.raises(SystemExit) as stop:
        compare.parse_args(argv)
    assert stop.value.code == 2


def test_a_renamed_parameter_takes_its_older_name_others_stay():
    assert compare.renamed(["frontend.mode=wheel", "max_features=500"]) == ["frontend=wheel", "max_features=500"]


def test_ratios_are_tree_over_rev():
    assert compare.ratio(5.0, 10.0) == "0.50"
    assert compare.ratio(None, 10.0) == compare.ratio(5.0, None) == compare.ratio(5.0, 0.0) == "-"


def _side(wall, peak, ate, cpu=None):
    return {"wall_s": wall, "cpu_s": [w / 2 for w in wall] if cpu is None else cpu, "peak_mb": peak, "ate_m": ate}


def test_the_table_shows_medians_ratios_failures_and_unsteady_ate():
    rows = [
        {"sequence": "paper-300m-large-0", "method": "keyframe", "params": "frontend.mode=wheel",
         "tree": _side([10.0, 12.0, 30.0], [300.0, 310.0, 305.0], [0.5, 0.5, 0.5]),
         "rev": _side([20.0, 24.0, 22.0], [400.0, 400.0, 400.0], [0.7, 0.8, 0.9])},
        {"sequence": "paper-300m-large-0", "method": "submap", "params": "",
         "tree": _side([], [], []), "rev": _side([5.0], [100.0], [0.1])},
    ]
    lines = compare.format_table(rows, "c517f78")
    assert lines[0].split() == ["sequence", "method", "params", "wall", "s", "tree", "wall", "s", "c517f78", "tree",
                                "/", "c517f78", "CPU", "s", "tree", "CPU", "s", "c517f78", "tree", "/", "c517f78", "peak", "MB", "tree", "peak", "MB", "c517f78", "tree", "/", "c517f78",
                                "ATE", "m", "tree", "ATE", "m", "c517f78"]
    assert lines[2].split() == ["paper-300m-large-0", "keyframe", "frontend.mode=wheel", "12.0", "22.0", "0.55",
                                "6.0", "11.0", "0.55", "305", "400", "0.76", "0.5000", "0.8000*"]
    assert lines[3].split() == ["paper-300m-large-0", "submap", "-", "failed", "5.0", "-", "failed", "2.5", "-", "failed", "100", "-",
                                "failed", "0.1000"]
    assert "tree / c517f78: below 1 the working tree is faster" in lines[4]
    assert lines[5].startswith("* the repeats' ATE differ")
    assert len({len(line) for line in lines[:2]}) == 1  # the rule is as wide as the header


def test_a_method_over_several_sequences_gets_a_line_of_sums_and_mean_ate():
    rows = [
        {"sequence": f"paper-300m-large-{seed}", "method": "keyframe", "params": "frontend.mode=wheel",
         "tree": _side([wall, wall + 2.0], [300.0, 310.0], [ate, ate]),
         "rev": _side([2 * wall, 2 * wall], [400.0, 420.0], [ate + 0.1, ate + 0.1])}
        for seed, wall, ate in ((0, 8.0, 0.5), (10, 10.0, 0.7))
    ] + [
        {"sequence": "paper-300m-large-20", "method": "keyframe", "params": "frontend.mode=wheel",
         "tree": _side([], [], []), "rev": _side([5.0], [100.0], [0.1])},
        {"sequence": "paper-300m-large-0", "method": "submap", "params": "",
         "tree": _side([30.0], [500.0], [0.2]), "rev": _side([20.0], [450.0], [0.3])},
    ]
    lines = compare.format_table(rows, "c517f78")
    summary = [line.split() for line in lines if line.startswith("all ") and "keyframe" in line]
    # Medians 9 + 11 against 16 + 20; CPU half of wall; the larger peak; mean ATE; the failed seed left out.
    assert summary == [["all", "2", "of", "3", "keyframe", "frontend.mode=wheel", "20.0", "36.0", "0.56",
                        "10.0", "18.0", "0.56", "305", "410", "0.74", "0.6000", "0.7000"]]
    assert any(line.startswith("all N: per method, sums") for line in lines)


def test_a_side_runs_its_own_src_first(tmp_path, monkeypatch):
    other = tmp_path / "other-checkout" / "src"
    (other / "longslam").mkdir(parents=True)
    monkeypatch.setenv("PYTHONPATH", f"{other}:{tmp_path / 'lib'}")
    env = compare.side_env(tmp_path / "rev" / "src")
    assert env["PYTHONPATH"].split(":") == [str(tmp_path / "rev" / "src"), str(tmp_path / "lib")]
