"""A run folder: the names of its files, and writing a method's result into it.

trajectory.txt  final trajectory (TUM), one pose per frame
online.txt      what the method returned frame by frame (TUM)
stats.json      the harness's measurements (times, memory) and the method's own stats
config.toml     the method and the parameters it ran with (every field, defaults included)
grid.npz        2D occupancy grid, if the method builds one
grid.pgm        the same grid as ROS map_server opens it, with grid.yaml (io/map_server.py)
map.ply         3D map points, if the method builds them
NAME.csv        rows that grow with the route, one file per table of the result
                (loops.csv: every loop constraint; nodes.csv: keyframe's time per node)
events.csv      what explains the run's course (tracking lost, new maps, loops), if the method
                reports events: kind, first and last frame and stamp, a note
record.json     a study run's scores (study runs only)
"""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError
from longslam.core.jsonable import json_default
from longslam.core.settings import to_toml
from longslam.io.atomic import write_text
from longslam.io.grid_files import write_grid
from longslam.io.map_server import write_map_server
from longslam.io.ply import vertex_rows, write_ply
from longslam.io.trajectory_files import write_tum
from longslam.run.measurements import RunMeasurements
from longslam.run.resources import peak_rss_bytes
from longslam.slam.api import Event, Result, Table

TRAJECTORY = "trajectory.txt"
ONLINE = "online.txt"
STATS = "stats.json"
CONFIG = "config.toml"
GRID = "grid.npz"
GRID_YAML = "grid.yaml"  # and grid.pgm beside it: map_server's format
GRID_PGM = "grid.pgm"
MAP = "map.ply"
RECORD = "record.json"
EVENTS = "events.csv"
EVENT_COLUMNS = ("kind", "first_frame", "last_frame", "first_t", "last_t", "detail")
TABLE_NAME = re.compile(r"[A-Za-z0-9_-]+")
# The files a study's database points at, by kind.
RUN_FILES = {"trajectory": TRAJECTORY, "online": ONLINE, "grid": GRID, "map": MAP, "stats": STATS}


CLOUD_CHUNK = 1 << 18  # points packed into PLY rows at a time (3 MB)


def write_point_cloud(path: Path, points: np.ndarray) -> None:
    """A binary PLY of (N, 3) points (float32), see io/ply.py. Packed a chunk at a time: a
    float64 copy, the rows and their bytes of a whole cloud at once come to 48 bytes a point,
    held beside the cloud itself."""
    points = np.asarray(points).reshape(-1, 3)
    chunks = ((vertex_rows(points[start : start + CLOUD_CHUNK]), None) for start in range(0, len(points), CLOUD_CHUNK))
    write_ply(path, chunks, comment="made by longslam")


def write_config(out: Path, method: str, config: dict[str, Any], sequence: str | None = None) -> None:
    """config.toml: the method and every parameter it ran with, as KISS-ICP keeps its config
    beside its results, so a run can be repeated from its folder alone."""
    run = {"method": method}
    if sequence is not None:
        run["sequence"] = sequence
    text = "# written by longslam: the method and the parameters this run used\n" + to_toml(
        {"run": run, "params": config or {}}
    )
    write_text(out / CONFIG, text)


def write_table(path: Path, table: Table) -> None:
    """A CSV with a header line; integers stay integers, other numbers in full precision."""
    whole = np.all(np.mod(table.rows, 1.0) == 0.0, axis=0) if len(table.rows) else np.ones(len(table.columns), bool)
    lines = [",".join(table.columns)]
    lines += [",".join(str(int(v)) if whole[c] else repr(float(v)) for c, v in enumerate(row)) for row in table.rows]
    write_text(path, "\n".join(lines) + "\n")


def write_events(path: Path, events: list[Event]) -> None:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(EVENT_COLUMNS)
    for e in events:
        writer.writerow([e.kind, e.first_frame, e.last_frame, f"{e.first_t:.6f}", f"{e.last_t:.6f}", e.detail])
    write_text(path, buffer.getvalue())


def read_events(path: Path) -> list[Event]:
    """The events `write_events` wrote; a damaged file is an error naming its line."""
    try:
        rows = list(csv.reader(path.read_text(encoding="utf-8").splitlines()))
    except (OSError, UnicodeDecodeError, csv.Error) as err:
        raise InputError(f"events file {path} cannot be read: {err}") from None
    if not rows or tuple(rows[0]) != EVENT_COLUMNS:
        raise InputError(f"events file {path}: expected the header line {','.join(EVENT_COLUMNS)}")
    events = []
    for number, row in enumerate(rows[1:], start=2):
        try:
            events.append(Event(row[0], int(row[1]), int(row[2]), float(row[3]), float(row[4]), row[5]))
        except (IndexError, ValueError) as err:
            raise InputError(f"events file {path}, line {number}: {err}") from None
    return events


def read_table(path: Path) -> Table:
    """A table that `write_table` wrote."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise InputError(f"table {path} does not exist") from None
    if not lines:
        raise InputError(f"table {path} is empty: expected a header line of column names")
    columns = tuple(lines[0].split(","))
    try:
        rows = np.array([[float(v) for v in line.split(",")] for line in lines[1:] if line], dtype=np.float64)
    except ValueError as err:
        raise InputError(f"table {path}: {err}") from None
    return Table(columns, rows.reshape(-1, len(columns)))


def write_result(out: Path, result: Result, measurements: RunMeasurements) -> None:
    """Write a result's files into an existing folder; stats.json last, with the peak memory of
    the whole run (this writing included)."""
    write_tum(out / TRAJECTORY, result.trajectory)
    write_tum(out / ONLINE, result.online)
    write_config(out, measurements.method, measurements.config, measurements.about.get("sequence"))
    if result.grid is not None:
        write_grid(result.grid, out / GRID)
        write_map_server(result.grid, out / GRID_YAML)
    if result.cloud is not None and len(result.cloud):
        write_point_cloud(out / MAP, result.cloud)  # float32 rows whatever the method's dtype
    for name, table in result.tables.items():
        if not TABLE_NAME.fullmatch(name):
            raise InputError(f"result table {name!r}: expected a file name of letters, digits, '_' or '-'")
        write_table(out / f"{name}.csv", table)
    if result.events:
        write_events(out / EVENTS, result.events)
    # The peak so far covers writing every other file (Open3D's import and the map included):
    # stats.json, written last, is tiny. A run with child processes (a program run as a method)
    # keeps the larger peak the engine measured over its process tree.
    measurements.peak_rss_bytes = max(measurements.peak_rss_bytes, peak_rss_bytes())
    write_text(out / STATS, json.dumps(measurements.to_dict(), indent=2, default=json_default) + "\n")
