"""Where a keyframe run's memory peaks: the resident memory before, at the peak of, and after each
step of `finish` and of writing the run folder (issue 22).

    python benchmarks/finish_phases.py SEQ --out RUN [--param NAME=VALUE ...]

Runs keyframe in this process and wraps each step (the front end's smoother, the maps, the
database's updates, each file written): before a step the kernel's peak counter (VmHWM) is reset
through /proc/self/clear_refs, so the peak printed is that step's own, not the run's so far.
Linux only. The run's RSS every 1,000 frames is printed at the end.
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from pathlib import Path

from longslam.core.gridmap import GridMap
from longslam.run import folder
from longslam.run.scored_run import run_named
from longslam.core.settings import parse_key_values
from longslam.slam.frontend import FrontEnd
from longslam.slam.keyframe import memory, memory_db, method

CLEAR_REFS = Path("/proc/self/clear_refs")


def _mib() -> dict[str, float]:
    fields = {}
    for line in Path("/proc/self/status").read_text().splitlines():
        key, _, value = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            fields[key] = int(value.split()[0]) / 1024
    return fields


def _wrap(owner: object, name: str, label: str) -> None:
    inner = getattr(owner, name)

    @functools.wraps(inner)
    def measured(*args, **kwargs):
        before = _mib()["VmRSS"]
        CLEAR_REFS.write_text("5")  # VmHWM := VmRSS
        started = time.perf_counter()
        out = inner(*args, **kwargs)
        now = _mib()
        print(f"{label:28s} before {before:7.1f}  peak {now['VmHWM']:7.1f}  after {now['VmRSS']:7.1f} MiB"
              f"  {time.perf_counter() - started:6.1f} s", flush=True)
        return out

    setattr(owner, name, measured)


STEPS = [
    (FrontEnd, "final_trajectory", "front end: smoother"),
    (method, "assemble_maps", "maps (grid and cloud)"),
    (memory.KeyframeMemory, "flush", "memory: flush to database"),
    (memory_db.MemoryDatabase, "update_poses", "database: final poses"),
    (folder, "write_tum", "write trajectory"),
    (GridMap, "save", "write grid.npz"),
    (folder, "write_map_server", "write grid.pgm"),
    (folder, "write_point_cloud", "write map.ply"),
    (folder, "write_table", "write a table"),
]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sequence")
    parser.add_argument("--out", required=True, help="run folder (replaced)")
    parser.add_argument("--param", action="append", default=[], help="NAME=VALUE, as `longslam run --param`")
    args = parser.parse_args(argv)
    if not CLEAR_REFS.exists():
        raise SystemExit("finish_phases.py needs Linux's /proc/self/clear_refs")
    for owner, name, label in STEPS:
        _wrap(owner, name, label)
    params = parse_key_values(args.param)
    measurements = run_named("keyframe", args.sequence, args.out, params=params or None, overwrite=True, progress=False)
    print(f"finish {measurements.finish_time_s:.1f} s; RSS (MiB) every 1,000 frames:",
          [(f, round(b / 2**20)) for f, b in measurements.rss_samples if f % 1000 == 0 or f == measurements.frames])


if __name__ == "__main__":
    sys.exit(main())
