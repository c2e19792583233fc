"""A study run's record: typed, through JSON and back, and into the database's columns."""

from types import SimpleNamespace

from longslam.study.record import HEADLINE, RunRecord
from longslam.study.database import ResultsDB


def _spec(key: str) -> SimpleNamespace:
    return SimpleNamespace(
        key=key, study="s", world="university", route="demo", noise="large", method="m", method_name="odometry",
        params={}, seed=0, camera={}, follower={}, align="none", config_hash="h", describe=lambda: {"key": key},
    )


def test_a_record_survives_its_json_form_and_old_keys_are_ignored():
    record = RunRecord("ok", metrics={"ate": 0.5}, measurements={"frames": 10}, files={"trajectory": "trajectory.txt"})
    assert RunRecord.from_dict(record.to_dict()) == record
    assert RunRecord.from_dict({"error": "boom", "unknown": 1}) == RunRecord("error", error="boom")


def test_the_database_has_a_column_per_headline_value_filled_from_the_record(tmp_path):
    record = RunRecord(
        "ok", metrics={"ate": 0.5, "e_rot": 0.1, "path_length": 12.0}, map_quality={"map_recall": 0.9},
        measurements={"frames": 10, "peak_rss_bytes": 123, "real_time_factor": float("inf")},
        files={"trajectory": "trajectory.txt"},
    )
    with ResultsDB(tmp_path / "results.sqlite") as db:
        db.record(_spec("a"), record, "runs/a")
        db.record(_spec("b"), RunRecord.failed("ValueError: no"), None)
        rows = {r["key"]: r for r in db.runs()}
    assert {c.name for c in HEADLINE} <= set(rows["a"])
    a = rows["a"]
    assert (a["ate"], a["e_rot"], a["path_length_m"], a["map_recall"], a["frames"], a["peak_rss_bytes"]) == (0.5, 0.1, 12.0, 0.9, 10, 123)
    assert a["real_time_factor"] is None  # SQLite holds no infinity
    assert a["trajectory_path"] == "runs/a/trajectory.txt" and a["measurements"]["frames"] == 10
    assert rows["b"]["status"] == "error" and rows["b"]["ate"] is None and rows["b"]["error"] == "ValueError: no"
