"""The opening and closing lines a local study run writes to its log (DIR/logs/KEY.log), around
whatever else its process prints (Python warnings, a native library's console output, a
traceback): so every log says what ran, where, and how it ended."""

from __future__ import annotations

import datetime as dt
import os
import socket
from typing import Any

from longslam.study.record import RunRecord


def opening_line(spec: Any) -> str:
    params = " ".join(f"{k}={v}" for k, v in sorted(spec.params.items())) or "default parameters"
    started = dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")
    return (
        f"longslam study run {spec.key}: method {spec.method_name} ({params}), route {spec.route}, "
        f"noise {spec.noise}, seed {spec.seed}; process {os.getpid()} on {socket.gethostname()}, started {started}"
    )


def closing_line(record: RunRecord, seconds: float) -> str:
    if not record.ok:
        return f"failed after {seconds:.1f} s: {record.error}"
    measured, metrics = record.measurements, record.metrics
    parts = [f"{measured.get('frames', '?')} frames"]
    if metrics.get("ate") is not None:
        parts.append(f"ATE {metrics['ate']:.4f} m")
    if measured.get("peak_rss_bytes"):
        parts.append(f"peak RSS {measured['peak_rss_bytes'] / 1e6:.0f} MB")
    if measured.get("method_time_s") is not None:
        parts.append(f"method time {measured['method_time_s']:.1f} s")
    return f"finished ok after {seconds:.1f} s: " + ", ".join(parts)
