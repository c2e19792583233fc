"""benchmarks/held_out.py's comparison with its record (the 20 % flag, the cell means, reading and
writing the record), on a tiny fake record: nothing is simulated or run."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from helpers.scripts import load_script

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
held_out = load_script(BENCHMARKS / "held_out.py", "benchmarks_held_out")

# Two seeds of one cell: keyframe 0.100 -> 0.125 (+25 %, flagged) and 0.200 -> 0.215 (+7.5 %).
FAKE = {
    "commit": "abc1234", "date": "2027-01-01 00:00 UTC",
    "rows": [
        {"route": "paper-300m", "noise": "large", "seed": 40, "method": "keyframe", "ate": 0.100, "commit": "abc1234"},
        {"route": "paper-300m", "noise": "large", "seed": 41, "method": "keyframe", "ate": 0.200, "commit": "abc1234"},
        {"route": "paper-300m", "noise": "large", "seed": 40, "method": "odometry", "ate": 2.0, "commit": "abc1234"},
        {"route": "paper-300m", "noise": "large", "seed": 41, "method": "odometry", "ate": 3.0, "commit": "abc1234"},
        {"route": "paper-1km", "noise": "xlarge", "seed": 40, "method": "submap", "ate": 0.300, "commit": "0ld0ld0"},
    ],
}
NOW = {
    ("paper-300m", "large", 40, "keyframe"): 0.125,
    ("paper-300m", "large", 41, "keyframe"): 0.215,
    ("paper-300m", "large", 40, "odometry"): 2.0,
    ("paper-300m", "large", 41, "odometry"): 3.0,
}


@pytest.fixture
def record(tmp_path):
    path = tmp_path / "held_out.json"
    path.write_text(json.dumps(FAKE))
    return held_out.read_record(path)


def test_the_record_reads_each_row_and_its_commit(record):
    assert record.commit == "abc1234"
    assert record.ates[("paper-300m", "large", 41, "keyframe")] == 0.200
    assert record.commits[("paper-1km", "xlarge", 40, "submap")] == "0ld0ld0"


def test_a_missing_record_is_empty(tmp_path):
    assert held_out.read_record(tmp_path / "none.json").ates == {}


def test_more_than_20_percent_either_way_is_flagged():
    assert held_out.change(0.125, 0.100) == pytest.approx(0.25)
    assert held_out.moved(held_out.change(0.125, 0.100))
    assert held_out.moved(held_out.change(0.07, 0.100))
    assert not held_out.moved(held_out.change(0.119, 0.100))
    assert not held_out.moved(held_out.change(0.081, 0.100))
    assert held_out.change(None, 0.1) is None and held_out.change(0.1, None) is None
    assert not held_out.moved(None)
    assert held_out._percent(-1e-7) == "0.0 %" and held_out._percent(0.25) == "+25.0 %"


def test_the_row_table_flags_the_row_that_moved(record):
    lines = held_out.row_table({**NOW, ("paper-300m", "large", 42, "submap"): None}, record)
    seed40 = next(line for line in lines if " 40 " in line and "keyframe" in line)
    seed41 = next(line for line in lines if " 41 " in line and "keyframe" in line)
    assert "0.125" in seed40 and "2.000" in seed40 and "0.100" in seed40 and "+25.0 %" in seed40
    assert seed40.endswith("<<")
    assert "+7.5 %" in seed41 and not seed41.endswith("<<")
    assert any("failed" in line for line in lines)


def test_cell_means_per_method_and_beside_the_record(record):
    means = held_out.cell_means({**NOW, ("paper-300m", "large", 42, "submap"): None})
    assert means[("paper-300m", "large")]["keyframe"] == (pytest.approx(0.17), [40, 41])
    assert means[("paper-300m", "large")]["odometry"] == (pytest.approx(2.5), [40, 41])
    assert "submap" not in means[("paper-300m", "large")]  # a failed run is in no mean
    lines = held_out.mean_table(NOW, record)
    keyframe = next(line for line in lines if "keyframe" in line)
    assert "0.170" in keyframe and "0.150" in keyframe and "+13.3 %" in keyframe and not keyframe.endswith("<<")
    # A seed the record does not have: no recorded mean (it would be of other sequences).
    lines = held_out.mean_table({**NOW, ("paper-300m", "large", 43, "keyframe"): 0.1}, record)
    keyframe = next(line for line in lines if "keyframe" in line)
    assert "40 41 43" in keyframe and keyframe.rstrip().endswith("-")


def test_recording_replaces_the_rows_run_and_keeps_the_others(record, tmp_path):
    new = held_out.updated_record(record, {**NOW, ("paper-300m", "large", 42, "submap"): None}, "def5678", "2027-02-02")
    path = tmp_path / "again.json"
    held_out.write_record(path, new)
    again = held_out.read_record(path)
    assert (again.commit, again.date) == ("def5678", "2027-02-02")
    assert again.ates[("paper-300m", "large", 40, "keyframe")] == 0.125
    assert again.commits[("paper-300m", "large", 40, "keyframe")] == "def5678"
    assert again.ates[("paper-1km", "xlarge", 40, "submap")] == 0.300  # not run now: kept, with its commit
    assert again.commits[("paper-1km", "xlarge", 40, "submap")] == "0ld0ld0"
    assert ("paper-300m", "large", 42, "submap") not in again.ates  # a failed run is not recorded
    rows = json.loads(path.read_text())["rows"]
    assert [r["route"] for r in rows] == ["paper-300m"] * 4 + ["paper-1km"]  # ROUTES' order


def test_the_options():
    args = held_out.parse_args([])
    assert (args.routes, args.noises, args.seeds, args.methods, args.jobs, args.record, args.resume) == (
        list(held_out.ROUTES), None, [40, 41, 42, 43, 44], ["keyframe", "submap"], 1, False, False)
    assert held_out.parse_args(["--methods", "keyframe", "odometry"]).methods == ["keyframe"]  # it always runs
    with pytest.raises(SystemExit):
        held_out.parse_args(["--jobs", "0"])
    with pytest.raises(SystemExit):
        held_out.parse_args(["--routes", "demo"])


def test_the_short_routes_run_at_small_noise_too_unless_the_levels_are_named():
    cells = held_out.route_noises(list(held_out.ROUTES), None)
    assert [n for r, n in cells if r == "paper-300m"] == ["small", "large", "xlarge"]
    assert [n for r, n in cells if r == "wing-loop"] == ["small", "large", "xlarge"]
    assert [n for r, n in cells if r == "paper-1km"] == ["large", "xlarge"]
    assert held_out.route_noises(["paper-1km", "wing-loop"], ["small"]) == [("paper-1km", "small"), ("wing-loop", "small")]
    with pytest.raises(SystemExit):
        held_out.parse_args(["--noises", "huge"])


def test_no_published_seed_is_held_out():
    assert not set(held_out.SEEDS) & {0, 1, 2, 3, 4, 7, 8, 31, 32}


def test_resume_reuses_only_runs_of_the_same_code():
    assert held_out.same_code("abc1234", "abc1234")
    assert not held_out.same_code("abc1234+dirty", "abc1234")
    assert not held_out.same_code("abc1234", "abc1234+dirty")
    assert not held_out.same_code(None, "abc1234")


def _copy(sequence: Path, path: Path) -> Path:
    shutil.copytree(sequence, path)
    return path


def test_a_sequence_whose_frames_changed_has_another_fingerprint_though_its_odometry_is_the_same(
    tiny_sequence, tmp_path
):
    first = held_out.sequence_fingerprint(_copy(tiny_sequence, tmp_path / "a"), every=1)
    assert held_out.sequence_fingerprint(_copy(tiny_sequence, tmp_path / "b"), every=1) == first
    changed = _copy(tiny_sequence, tmp_path / "c")
    depth = sorted((changed / "depth").iterdir())[3]
    depth.write_bytes(depth.read_bytes() + b"\0")
    assert held_out.sequence_fingerprint(changed, every=1) != first
    again = _copy(tiny_sequence, tmp_path / "d")
    (again / "meta.json").write_text('{"longslam_commit": "def"}')  # who simulated it is not what it holds
    assert held_out.sequence_fingerprint(again, every=1) == first


def test_rows_on_a_changed_sequence_say_so_and_the_record_keeps_the_fingerprints(record, tmp_path):
    cell = ("paper-300m", "large", 40)
    new = held_out.updated_record(record, NOW, "def5678", "2027-02-02", {cell: "aaaa", ("paper-300m", "large", 41): "bbbb"})
    path = tmp_path / "again.json"
    held_out.write_record(path, new)
    again = held_out.read_record(path)
    assert again.sequences == {cell: "aaaa", ("paper-300m", "large", 41): "bbbb"}
    lines = held_out.row_table(NOW, again, {cell: "cccc", ("paper-300m", "large", 41): "bbbb"})
    seed40 = next(line for line in lines if " 40 " in line and "keyframe" in line)
    seed41 = next(line for line in lines if " 41 " in line and "keyframe" in line)
    assert "changed" in seed40 and "same" in seed41
    assert " - " in next(line for line in held_out.row_table(NOW, record, {cell: "cccc"}) if " 40 " in line)  # no record
    keyframe = next(line for line in held_out.mean_table(NOW, again, {cell: "cccc", ("paper-300m", "large", 41): "bbbb"})
                    if "keyframe" in line)
    assert "1 changed" in keyframe


def test_the_summary_says_what_moved_and_which_sequences_changed(record):
    cell = ("paper-300m", "large", 40)
    marked = held_out.updated_record(record, {}, "abc1234", "2027-01-01", None)
    marked.sequences[cell] = "aaaa"
    lines = held_out.summary(NOW, marked, {cell: "cccc"})
    assert lines[0].startswith("<< 1 rows moved more than 20%")
    assert lines[1].startswith("1 sequences differ") and "paper-300m large seed 40" in lines[1]
    still = {**NOW, ("paper-300m", "large", 40, "keyframe"): 0.100}
    assert held_out.summary(still, marked, {cell: "aaaa"}) == ["none of the 4 rows the record has moved more than 20%"]


def test_the_header_names_each_commit_the_rows_were_run_at(record):
    header = held_out.record_header("held_out.json", record)
    assert "last written at abc1234 on 2027-01-01 00:00 UTC" in header
    assert "rows run at abc1234 (4 rows), 0ld0ld0 (1 rows)" in header
    assert held_out.record_header("held_out.json", held_out.Record("", "", {}, {}, {})) == "record: held_out.json, none yet"
