"""A real system beside longslam's methods on the same sequences: ATE without alignment and after
SE(3) alignment, frames it could not track, loop closures, CPU per frame and peak memory.

    python benchmarks/real_systems.py SEQ [SEQ ...] --methods odometry keyframe submap orbslam3 \
        --repeats 3 --jobs 2 --work /tmp/real-systems

Each run is `longslam run` in its own process (its peak memory its own). Methods whose threads
make runs differ (orbslam3) are repeated `--repeats` times; longslam's own methods are
deterministic and run once. Prints one Markdown row per (sequence, method): mean and range.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

NONDETERMINISTIC = {"orbslam3"}


def _evaluate(run: Path, seq: Path, align: str) -> dict:
    out = subprocess.run([sys.executable, "-m", "longslam", "evaluate", str(run), str(seq), "--json", "--align", align],
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out)


def one_run(seq: Path, method: str, repeat: int, work: Path, params: list[str]) -> dict:
    run = work / seq.name / f"{method}-{repeat}"
    if not (run / "stats.json").is_file():
        command = [sys.executable, "-m", "longslam", "run", "--method", method, str(seq), "--out", str(run), "--overwrite"]
        for p in params:
            command += ["--param", p]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            return {"seq": seq.name, "method": method, "error": done.stderr.strip().splitlines()[-1:]}
    stats = json.loads((run / "stats.json").read_text())
    plain, aligned = _evaluate(run, seq, "none"), _evaluate(run, seq, "se3")
    m = stats["method_stats"]
    return {
        "seq": seq.name, "method": method, "ate": plain["ate"], "ate_se3": aligned["ape_rmse"], "e_rot": plain["e_rot"],
        "untracked": m.get("frames_untracked", 0), "maps": m.get("maps", 1), "loops": m.get("loops_accepted", 0),
        "cpu_ms": 1000 * stats["process_cpu_time_s"] / stats["frames"], "peak_mib": stats["peak_rss_bytes"] / 2**20,
        "wall_s": stats["wall_time_s"],
    }


def _cell(values: list[float], digits: int = 3) -> str:
    if len(values) == 1:
        return f"{values[0]:.{digits}f}"
    return f"{np.mean(values):.{digits}f} ({min(values):.{digits}f}-{max(values):.{digits}f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("sequences", nargs="+", type=Path)
    parser.add_argument("--methods", nargs="+", default=["odometry", "keyframe", "submap", "orbslam3"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--work", type=Path, default=Path("/tmp/longslam-real-systems"))
    parser.add_argument("--param", action="append", default=[], help="METHOD:key=value, e.g. orbslam3:pace=1")
    args = parser.parse_args()
    jobs = []
    for seq in args.sequences:
        for method in args.methods:
            params = [p.split(":", 1)[1] for p in args.param if p.split(":", 1)[0] == method]
            for r in range(args.repeats if method in NONDETERMINISTIC else 1):
                jobs.append((seq, method, r, args.work, params))
    with ThreadPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(lambda job: one_run(*job), jobs))
    print("| sequence | method | runs | ATE (m), no alignment | ATE (m), SE(3) aligned | E_rot (deg/m) | frames untracked | maps | loops | CPU ms/frame | peak MiB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for seq in args.sequences:
        for method in args.methods:
            mine = [r for r in rows if r["seq"] == seq.name and r["method"] == method]
            failed = [r for r in mine if "error" in r]
            ok = [r for r in mine if "error" not in r]
            if not ok:
                print(f"| {seq.name} | {method} | 0 | failed: {failed[0]['error'] if failed else '-'} |")
                continue
            print(f"| {seq.name} | {method} | {len(ok)}{f' ({len(failed)} failed)' if failed else ''} | "
                  f"{_cell([r['ate'] for r in ok])} | {_cell([r['ate_se3'] for r in ok])} | {_cell([r['e_rot'] for r in ok], 2)} | "
                  f"{_cell([r['untracked'] for r in ok], 0)} | {_cell([r['maps'] for r in ok], 0)} | {_cell([r['loops'] for r in ok], 0)} | "
                  f"{_cell([r['cpu_ms'] for r in ok], 1)} | {_cell([r['peak_mib'] for r in ok], 0)} |")


if __name__ == "__main__":
    main()
