"""A study's results as the report reads them: the runs in the database, in the study's order."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from longslam.errors import InputError
from longslam.study.database import DB_NAME, ResultsDB, check_results_tables


@dataclass
class StudyResults:
    out: Path
    config: dict[str, Any]
    runs: list[dict[str, Any]]  # every recorded run
    ok: list[dict[str, Any]]
    routes: list[str]
    noise: list[str]
    methods: list[str]

    @property
    def columns(self) -> list[tuple[str, str]]:
        present = {(r["route"], r["noise"]) for r in self.runs}
        return [(route, noise) for route in self.routes for noise in self.noise if (route, noise) in present]

    def values(self, method: str, route: str, noise: str, column: str) -> list[float]:
        return [r[column] for r in self.ok if (r["method"], r["route"], r["noise"]) == (method, route, noise) and r[column] is not None]


def _ordered(first: list[str], seen: list[str]) -> list[str]:
    out = [x for x in first if x in seen]
    return out + sorted(set(seen) - set(out))


def load_results(out: str | Path) -> StudyResults:
    out = Path(out)
    path = out / DB_NAME
    if not path.is_file():
        raise InputError(f"{out} holds no study results ({DB_NAME} is missing); run `longslam study FILE --out {out}` first")
    check_results_tables(path)
    with ResultsDB(path) as db:
        config = db.study() or {}
        runs = db.runs()
    ok = [r for r in runs if r["status"] == "ok"]
    routes = _ordered([r["name"] for r in config.get("routes", [])], [r["route"] for r in runs])
    noise = _ordered(list(config.get("noise", [])), [r["noise"] for r in runs])
    methods = _ordered([m["label"] for m in config.get("methods", [])], [r["method"] for r in runs])
    return StudyResults(out, config, runs, ok, routes, noise, methods)
