"""The results database of a study: one SQLite file, one row per run, written as each run ends.

Table `runs` has one row per run key (`route/noise/method/seed-N`, or `route/camera/noise/method/
seed-N` in a study with named cameras; its primary key, so a run is there at most once): its
configuration (`camera_name` is the camera's name, "camera" for the one camera of a `[camera]`
study and for every run recorded before cameras had names; `camera` holds its settings; `sensor` is the sensor model,
"ideal" for a study without a
sensors axis and for every run recorded before sensors were one; `perturbation` the perturbations'
text, "none" likewise), status
('ok' or 'error' with the error text), the headline metrics as columns (ate, e_trans, e_rot,
peak_rss_bytes, map_precision, ...), the full metrics, curves against distance travelled and
harness figures as JSON text, and the paths of its files relative to the study folder. Table `study` holds the
study's configuration.

    sqlite3 DIR/results.sqlite "select method, noise, avg(ate) from runs where status='ok' group by 1, 2"
"""

from __future__ import annotations

import datetime as dt
import json
import sqlite3
from pathlib import Path
from typing import Any

from longslam.core.errors import InputError
from longslam.run.folder import RUN_FILES
from longslam.sim.perturbations.parse import NONE
from longslam.sim.sensors.catalog import IDEAL
from longslam.study.record import HEADLINE, JSON_PARTS, RunRecord
from longslam.study.spec import DEFAULT_CAMERA

DB_NAME = "results.sqlite"
SCHEMA_VERSION = 2  # 2: the harness's figures column is `measurements`

# The run's identity and configuration (from its RunSpec), what happened, the headline values of
# its record (study/record.py decides which), whole parts of the record as JSON, and its files.
SPEC_COLUMNS = {
    "key": "TEXT PRIMARY KEY",
    "study": "TEXT",
    "world": "TEXT",
    "route": "TEXT",
    "noise": "TEXT",
    "method": "TEXT",
    "method_name": "TEXT",
    "params": "TEXT",
    "seed": "INTEGER",
    "camera": "TEXT",
    "follower": "TEXT",
    "align": "TEXT",
    "config_hash": "TEXT",
    "spec": "TEXT",
    # `camera` was the settings (JSON) before cameras had names, so the name has a column of its own.
    "camera_name": "TEXT",
    "sensor": "TEXT",
    "perturbation": "TEXT",  # the perturbations' text (drop=0.1, none)
    "repeat": "INTEGER",  # which run of its cell (0 for every run recorded before studies repeated cells)
}
OUTCOME_COLUMNS = {
    "status": "TEXT NOT NULL",
    "error": "TEXT",
    "traceback": "TEXT",
    "finished_at": "TEXT",
    "elapsed_s": "REAL",
    "host": "TEXT",
    "executor": "TEXT",
    # When the study handed the run to its executor and when it came back (UTC, ISO 8601 with
    # microseconds): which runs overlapped in time.
    "started_at": "TEXT",
    "ended_at": "TEXT",
    "cores": "INTEGER",
}
FILE_COLUMNS = {f"{kind}_path": "TEXT" for kind in RUN_FILES} | {"run_dir": "TEXT", "log_path": "TEXT"}
RUN_COLUMNS = {
    **SPEC_COLUMNS,
    **OUTCOME_COLUMNS,
    **{c.name: c.sql_type for c in HEADLINE},
    **{part: "TEXT" for part in JSON_PARTS},
    **FILE_COLUMNS,
}
JSON_COLUMNS = ("params", "camera", "follower", "spec", *JSON_PARTS)


def utc_now() -> str:
    """Now, as the database's started_at and ended_at hold it."""
    return dt.datetime.now(dt.timezone.utc).isoformat(timespec="microseconds")


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
        if not row:
            return None
        try:
            config = json.loads(row[0])
        except (TypeError, ValueError) as err:
            raise InputError(f"results database {self.path}: table study, key config: not valid JSON ({err})") from None
        if not isinstance(config, dict):
            raise InputError(f"results database {self.path}: table study, key config: expected a JSON object")
        return config

    # ------------------------------------------------------------------ runs

    def finished(self) -> dict[str, tuple[str, str]]:
        """run key -> (config hash, status) of every recorded run."""
        return {
            r["key"]: (r["config_hash"], r["status"])
            for r in self._conn.execute("SELECT key, config_hash, status FROM runs")
        }

    def record(
        self,
        spec: Any,
        record: RunRecord,
        run_dir: str | None,
        executor: str = "",
        started_at: str | None = None,
        cores: int | None = None,
    ) -> None:
        """Store one finished run (replacing an older row of the same key), committed at once."""
        row: dict[str, Any] = {
            "key": spec.key,
            "study": spec.study,
            "world": spec.world,
            "route": spec.route,
            "noise": spec.noise,
            "method": spec.method,
            "method_name": spec.method_name,
            "params": spec.params,
            "seed": spec.seed,
            "camera": spec.camera,
            "camera_name": getattr(spec, "camera_name", "") or DEFAULT_CAMERA,
            "sensor": getattr(spec, "sensor", "") or IDEAL,
            "perturbation": getattr(spec, "perturbation", "") or NONE,
            "repeat": getattr(spec, "repeat", 0),
            "follower": spec.follower,
            "align": spec.align,
            "config_hash": spec.config_hash,
            "spec": spec.describe(),
            "status": record.status,
            "error": record.error,
            "traceback": record.traceback,
            "finished_at": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
            "elapsed_s": record.elapsed_s,
            "host": record.host,
            "executor": executor,
            "log_path": record.log,
            "started_at": started_at,
            "ended_at": utc_now(),
            "cores": cores,
        }
        if record.ok:
            row.update({c.name: c.value(record) for c in HEADLINE})
            row.update({part: getattr(record, part) for part in JSON_PARTS})
            row["run_dir"] = run_dir
            row.update({f"{kind}_path": _in(run_dir, record.files.get(kind)) for kind in RUN_FILES})
        values = {
            k: (json.dumps(v, default=str) if k in JSON_COLUMNS and v is not None else _finite(v))
            for k, v in row.items()
        }
        names = ", ".join(values)
        marks = ", ".join(f":{k}" for k in values)
        with self._conn:
            self._conn.execute(f"INSERT OR REPLACE INTO runs ({names}) VALUES ({marks})", values)

    def starved(self, share: float) -> set[str]:
        """Keys of the runs whose threads waited for a CPU for more than `share` of their time."""
        rows = self._conn.execute("SELECT key FROM runs WHERE cpu_wait_share > ?", (share,))
        return {row[0] for row in rows}

    def runs(self, status: str | None = None) -> list[dict[str, Any]]:
        """Every run (or those with `status`) as dicts, JSON columns decoded, in key order."""
        query = (
            "SELECT * FROM runs"
            + (" WHERE status = ?" if status else "")
            + " ORDER BY route, camera_name, sensor, perturbation, noise, method, seed, repeat"
        )
        out = []
        for row in self._conn.execute(query, (status,) if status else ()):
            item = dict(row)
            if item.get("camera_name") is None:  # recorded before cameras had names: the study's one camera
                item["camera_name"] = DEFAULT_CAMERA
            if item.get("sensor") is None:  # recorded before sensors were an axis: the ideal sensor
                item["sensor"] = IDEAL
            if item.get("perturbation") is None:  # recorded before perturbations were an axis: none
                item["perturbation"] = NONE
            if item.get("repeat") is None:  # recorded before studies repeated cells
                item["repeat"] = 0
            for column in JSON_COLUMNS:
                if item.get(column) is not None:
                    try:
                        item[column] = json.loads(item[column])
                    except (TypeError, ValueError) as err:
                        raise InputError(
                            f"results database {self.path}: run {item.get('key')!r}, column {column}: "
                            f"not valid JSON ({err})"
                        ) from None
            out.append(item)
        return out

    def count(self) -> int:
        return int(self._conn.execute("SELECT COUNT(*) FROM runs").fetchone()[0])


def connect_read_only(path: str | Path) -> sqlite3.Connection:
    """A connection that writes nothing beside the database: without a write-ahead log left by a
    process that died, the file is opened immutable (no -shm file); with one, read-only."""
    path = Path(path)
    wal = path.with_name(path.name + "-wal")
    mode = "mode=ro" if wal.exists() else "immutable=1"
    return sqlite3.connect(
        f"{path.absolute().as_uri()}?{mode}", uri=True
    )  # as_uri: a '?' or '#' in the path is escaped


def check_results_tables(path: str | Path) -> None:
    """Refuse a results database without its tables, read-only, before anything would create them:
    a report of such a file would be an empty report over the study's last one."""
    path = Path(path)
    try:
        conn = connect_read_only(path)
        try:
            tables = {row[0] for row in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        finally:
            conn.close()
    except sqlite3.DatabaseError as err:
        raise InputError(f"results database {path} cannot be read: {err}") from None
    missing = [t for t in ("runs", "study") if t not in tables]
    if missing:
        raise InputError(
            f"results database {path} has no table {' and no table '.join(missing)}; it is not a "
            "longslam study's database (or was damaged); nothing was written"
        )


def _in(run_dir: str | None, name: str | None) -> str | None:
    return f"{run_dir}/{name}" if run_dir and name else None
