"""What a finished (or failed) study run reports: one typed record, and the database columns that
come from it.

A record crosses process boundaries (a worker process, a Ray task) as JSON (`to_dict`,
`from_dict`) and lands in one row of the results database; `HEADLINE` names the values that get
a column of their own there, so that SQL can query them directly.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from typing import Any

OK, ERROR = "ok", "error"


@dataclass
class RunRecord:
    status: str  # OK or ERROR
    error: str | None = None  # "Type: message" of a failed run
    traceback: str | None = None
    host: str | None = None
    elapsed_s: float | None = None  # wall time of the run as the study saw it
    log: str | None = None  # the run's output, relative to the study folder
    metrics: dict[str, Any] = field(default_factory=dict)  # run.score.score, plus ate_online
    map_quality: dict[str, Any] | None = None
    measurements: dict[str, Any] = field(default_factory=dict)  # stats.json without the RSS samples
    error_curve: list[list[float]] = field(default_factory=list)  # [distance m, position error m]
    memory_curve: list[list[float]] = field(default_factory=list)  # [distance m, resident bytes]
    files: dict[str, str] = field(default_factory=dict)  # kind -> file name in the run folder

    @property
    def ok(self) -> bool:
        return self.status == OK

    @classmethod
    def failed(cls, error: str, **more: Any) -> "RunRecord":
        return cls(ERROR, error=error, **more)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "RunRecord":
        """A record from its JSON form; unknown keys are ignored, a missing status is an error."""
        known = {f.name for f in fields(cls)}
        values = {k: v for k, v in data.items() if k in known}
        values.setdefault("status", ERROR)
        return cls(**values)


@dataclass(frozen=True)
class Column:
    name: str
    sql_type: str
    value: Callable[[RunRecord], Any]


def _measured(key: str) -> Callable[[RunRecord], Any]:
    return lambda record: record.measurements.get(key)


def _metric(key: str) -> Callable[[RunRecord], Any]:
    return lambda record: record.metrics.get(key)


def _quality(key: str) -> Callable[[RunRecord], Any]:
    return lambda record: (record.map_quality or {}).get(key)


HEADLINE = (
    Column("frames", "INTEGER", _measured("frames")),
    Column("path_length_m", "REAL", _metric("path_length")),
    Column("wall_time_s", "REAL", _measured("wall_time_s")),
    Column("method_time_s", "REAL", _measured("method_time_s")),
    Column("real_time_factor", "REAL", _measured("real_time_factor")),
    Column("peak_rss_bytes", "INTEGER", _measured("peak_rss_bytes")),
    Column("baseline_rss_bytes", "INTEGER", _measured("baseline_rss_bytes")),
    # The CPU the run was denied (run/process_tree.py): its threads' run-queue wait, and that
    # wait's share of wait plus CPU time; a share over 0.10 marks the run as starved.
    Column("cpu_wait_s", "REAL", _measured("cpu_wait_s")),
    Column("cpu_wait_share", "REAL", _measured("cpu_wait_share")),
    *(
        Column(key, "REAL", _metric(key))
        for key in ("ate", "e_trans", "e_rot", "ape_rmse", "rpe_trans", "rpe_rot", "ate_online")
    ),
    *(
        Column(key, "REAL", _quality(key))
        for key in (
            "map_precision",
            "map_recall",
            "map_f1",
            "map_precision_aligned",
            "map_recall_aligned",
            "map_f1_aligned",
            "map_doubled_walls",
        )
    ),
)
# Whole parts of the record, stored as JSON text.
JSON_PARTS = ("metrics", "map_quality", "measurements", "error_curve", "memory_curve")
