"""The results database of a study: one SQLite file, one row per run, written as each run ends.

Table `runs` has one row per run key (`route/noise/method/seed-N`, its primary key, so a run is
there at most once): its configuration, status ('ok' or 'error' with the error text), the
headline metrics as columns (ate, e_trans, e_rot, peak_rss_bytes, map_precision, ...), the full
metrics, curves against distance travelled and harness figures as JSON text, and the paths of its
files relative to the study folder. Table `study` holds the study's configuration.

    sqlite3 DIR/results.sqlite "select method, noise, avg(ate) from runs where status='ok' group by 1, 2"
"""

from __future__ import annotations

import datetime as dt
import json
import sqlite3
from pathlib import Path
from typing import Any

from longslam.errors import InputError

DB_NAME = "results.sqlite"
SCHEMA_VERSION = 1

RUN_COLUMNS = {
    "key": "TEXT PRIMARY KEY",
    "study": "TEXT", "world": "TEXT", "route": "TEXT", "noise": "TEXT", "method": "TEXT",
    "method_name": "TEXT", "params": "TEXT", "seed": "INTEGER", "camera": "TEXT", "follower": "TEXT",
    "align": "TEXT", "config_hash": "TEXT", "spec": "TEXT",
    "status": "TEXT NOT NULL", "error": "TEXT", "traceback": "TEXT",
    "finished_at": "TEXT", "elapsed_s": "REAL", "host": "TEXT", "executor": "TEXT",
    "frames": "INTEGER", "path_length_m": "REAL", "wall_time_s": "REAL", "method_time_s": "REAL",
    "real_time_factor": "REAL", "peak_rss_bytes": "INTEGER", "baseline_rss_bytes": "INTEGER",
    "ate": "REAL", "e_trans": "REAL", "e_rot": "REAL", "ape_rmse": "REAL", "rpe_trans": "REAL",
    "rpe_rot": "REAL", "ate_online": "REAL",
    "map_precision": "REAL", "map_recall": "REAL", "map_f1": "REAL",
    "metrics": "TEXT", "map_quality": "TEXT", "figures": "TEXT", "error_curve": "TEXT", "memory_curve": "TEXT",
    "run_dir": "TEXT", "trajectory_path": "TEXT", "online_path": "TEXT", "grid_path": "TEXT",
    "map_path": "TEXT", "stats_path": "TEXT", "log_path": "TEXT",
}
JSON_COLUMNS = ("params", "camera", "follower", "spec", "metrics", "map_quality", "figures", "error_curve", "memory_curve")


def _finite(value: Any) -> Any:
    """None for NaN/inf (SQLite REAL has no NaN), else the value."""
    if isinstance(value, float) and (value != value or value in (float("inf"), float("-inf"))):
        return None
    return value


class ResultsDB:
    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._conn = sqlite3.connect(self.path, timeout=30.0)
            self._conn.row_factory = sqlite3.Row
            self._conn.execute("PRAGMA journal_mode=WAL")
            self._conn.execute("PRAGMA synchronous=FULL")  # a recorded run survives a crash of the machine
            with self._conn:
                self._conn.execute("CREATE TABLE IF NOT EXISTS study (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
                columns = ", ".join(f"{name} {kind}" for name, kind in RUN_COLUMNS.items())
                self._conn.execute(f"CREATE TABLE IF NOT EXISTS runs ({columns})")
                # A database from an older longslam gets the columns added since (empty in old rows).
                present = {row[1] for row in self._conn.execute("PRAGMA table_info(runs)")}
                for name, kind in RUN_COLUMNS.items():
                    if name not in present:
                        self._conn.execute(f"ALTER TABLE runs ADD COLUMN {name} {kind.replace(' NOT NULL', '')}")
                self._conn.execute(
                    "INSERT OR IGNORE INTO study (key, value) VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),)
                )
        except sqlite3.DatabaseError as err:
            raise InputError(f"results database {self.path} cannot be opened: {err}") from None

    def __enter__(self) -> "ResultsDB":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._conn.close()

    # ------------------------------------------------------------------ the study

    def set_study(self, config: dict[str, Any]) -> None:
        with self._conn:
            self._conn.execute("INSERT OR REPLACE INTO study (key, value) VALUES ('config', ?)", (json.dumps(config),))

    def study(self) -> dict[str, Any] | None:
        row = self._conn.execute("SELECT value FROM study WHERE key = 'config'").fetchone()
        return json.loads(row[0]) if row else None

    # ------------------------------------------------------------------ runs

    def finished(self) -> dict[str, tuple[str, str]]:
        """run key -> (config hash, status) of every recorded run."""
        return {r["key"]: (r["config_hash"], r["status"]) for r in self._conn.execute("SELECT key, config_hash, status FROM runs")}

    def record(self, spec: Any, record: dict[str, Any], run_dir: str | None, executor: str = "") -> None:
        """Store one finished run (replacing an older row of the same key), committed at once."""
        row: dict[str, Any] = {
            "key": spec.key, "study": spec.study, "world": spec.world, "route": spec.route, "noise": spec.noise,
            "method": spec.method, "method_name": spec.method_name, "params": spec.params, "seed": spec.seed,
            "camera": spec.camera, "follower": spec.follower, "align": spec.align,
            "config_hash": spec.config_hash, "spec": spec.describe(),
            "status": record.get("status", "error"), "error": record.get("error"),
            "traceback": record.get("traceback"),
            "finished_at": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
            "elapsed_s": record.get("elapsed_s"), "host": record.get("host"), "executor": executor, "log_path": record.get("log"),
        }
        if row["status"] == "ok":
            metrics, figures = record.get("metrics", {}), record.get("figures", {})
            quality = record.get("map_quality") or {}
            files = record.get("files", {})
            row.update(
                frames=figures.get("frames"), path_length_m=metrics.get("path_length"),
                wall_time_s=figures.get("wall_time_s"), method_time_s=figures.get("method_time_s"),
                real_time_factor=figures.get("real_time_factor"), peak_rss_bytes=figures.get("peak_rss_bytes"),
                baseline_rss_bytes=figures.get("baseline_rss_bytes"),
                ate=metrics.get("ate"), e_trans=metrics.get("e_trans"), e_rot=metrics.get("e_rot"),
                ape_rmse=metrics.get("ape_rmse"), rpe_trans=metrics.get("rpe_trans"), rpe_rot=metrics.get("rpe_rot"),
                ate_online=metrics.get("ate_online"),
                map_precision=quality.get("map_precision"), map_recall=quality.get("map_recall"),
                map_f1=quality.get("map_f1"),
                metrics=metrics, map_quality=record.get("map_quality"), figures=figures,
                error_curve=record.get("error_curve"), memory_curve=record.get("memory_curve"),
                run_dir=run_dir,
                trajectory_path=_in(run_dir, files.get("trajectory")), online_path=_in(run_dir, files.get("online")),
                grid_path=_in(run_dir, files.get("grid")), map_path=_in(run_dir, files.get("map")),
                stats_path=_in(run_dir, files.get("stats")),
            )
        values = {k: (json.dumps(v, default=str) if k in JSON_COLUMNS and v is not None else _finite(v)) for k, v in row.items()}
        names = ", ".join(values)
        marks = ", ".join(f":{k}" for k in values)
        with self._conn:
            self._conn.execute(f"INSERT OR REPLACE INTO runs ({names}) VALUES ({marks})", values)

    def runs(self, status: str | None = None) -> list[dict[str, Any]]:
        """Every run (or those with `status`) as dicts, JSON columns decoded, in key order."""
        query = "SELECT * FROM runs" + (" WHERE status = ?" if status else "") + " ORDER BY route, noise, method, seed"
        out = []
        for row in self._conn.execute(query, (status,) if status else ()):
            item = dict(row)
            for column in JSON_COLUMNS:
                if item.get(column) is not None:
                    item[column] = json.loads(item[column])
            out.append(item)
        return out

    def count(self) -> int:
        return int(self._conn.execute("SELECT COUNT(*) FROM runs").fetchone()[0])


def _in(run_dir: str | None, name: str | None) -> str | None:
    return f"{run_dir}/{name}" if run_dir and name else None
