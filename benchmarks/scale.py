"""How the methods hold up as the route grows: memory, per-frame cost, finish and accuracy (issue 22).

    python benchmarks/scale.py [--routes paper-1km paper-1km-x3 tour-10km] [--noise large] [--seed 0]
                               [--methods odometry keyframe submap orbslam3] [--work out/bench-scale]
                               [--plot-dir docs/images/scale]

For each route: `longslam simulate` as its own process (wall time and frames per second: the
render when the route is not yet in the render cache), then each method as its own `longslam run`
process (an installed plugin's too; a method that is not installed is left out). Per run: peak
RSS of the whole process (`os.wait4`, what `/usr/bin/time -v` prints), the run's own RSS samples
every 1,000 frames, the mean ms per frame over the first and the last tenth of the frames, the
`finish` time, ATE and its ratio to dead reckoning's on the same sequence, and the loop
constraints further than 0.5 m (in the directions each holds) or 5 degrees from the truth (loops.csv). With --plot-dir: RSS
against distance and ATE against route length, one line per method.

It resumes: a sequence already in --work is not simulated again, and a run already measured there
(its row beside its folder, runs/SEQ-METHOD.json) is read back; delete --work to measure afresh.
A sequence counts as simulated once SEQ.done stands beside it.

Targets printed beside the figures: keyframe and submap peak <= 450 MB on a 10 km route, and on a
3 km route <= 1.15x their 1 km peak; last tenth's ms per frame <= 1.2x the first's; finish <= 60 s
at 10 km; keyframe ATE <= 0.1x dead reckoning's at 10 km with no wrong loop constraint.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from common import run_process
from longslam.eval.diagnose import loop_errors
from longslam.core.geometry import planar_from_camera_poses
from longslam.io.sequence import SequenceReader
from longslam.run.folder import read_table
from longslam.run.score import score_files
from longslam.slam.catalog import method_names

PEAK_10KM_MB = 450
PEAK_3KM_RATIO = 1.15
TIME_GROWTH = 1.2
FINISH_10KM_S = 60.0
ATE_RATIO_10KM = 0.1


def simulate(route: str, noise: str, seed: int, work: Path) -> tuple[Path, float]:
    """The sequence in `work`, simulated unless a finished one is there (SEQ.done beside it; a
    folder without it was interrupted and is simulated again)."""
    out = work / f"{route}-{noise}-{seed}"
    done = out.with_name(out.name + ".done")
    if out.exists() and done.exists():
        return out, 0.0
    command = [sys.executable, "-m", "longslam", "--no-progress", "simulate", "--route", route, "--noise", noise,
               "--seed", str(seed), "--out", str(out), "--overwrite"]
    wall, _, status = run_process(command, work / f"simulate-{route}.log")
    if status:
        raise SystemExit(f"simulate {route} failed (exit {status}); see {work / f'simulate-{route}.log'}")
    done.write_text(f"{wall:.1f}\n")
    return out, wall


def measure(method: str, seq: Path, work: Path, dead_reckoning_ate: float, truth_xyyaw: np.ndarray) -> dict:
    """One method's run on `seq`, measured; a run measured before in `work` (its row beside its
    folder, RUN.json) is read back, not run again, so an interrupted benchmark resumes."""
    run = work / "runs" / f"{seq.name}-{method}"
    done = run.with_name(run.name + ".json")
    if done.is_file() and (run / "stats.json").is_file():
        return {**json.loads(done.read_text()), "reused": True}
    command = [sys.executable, "-m", "longslam", "--no-progress", "run", str(seq), "--method", method,
               "--out", str(run), "--overwrite"]
    wall, peak_mib, status = run_process(command, work / f"{seq.name}-{method}.log")
    if status:
        return {"method": method, "failed": status}
    stats = json.loads((run / "stats.json").read_text())
    tenths = stats["step_time_mean_s_by_tenth"]
    rss = np.array(stats["rss_samples"], dtype=np.float64)
    every_1000 = [[int(f), b / 1e6] for f, b in rss if int(f) % 1000 == 0]
    ate = score_files(run, seq)["ate"]
    wrong = None
    if (run / "loops.csv").is_file():
        wrong = sum(lp.wrong for lp in loop_errors(truth_xyyaw, read_table(run / "loops.csv").rows))
    row = {
        "method": method, "wall_s": wall, "peak_mb": peak_mib * 2**20 / 1e6, "rss_every_1000_frames_mb": every_1000,
        "ms_per_frame_first_tenth": 1000 * tenths[0], "ms_per_frame_last_tenth": 1000 * tenths[-1],
        "finish_s": stats["finish_time_s"], "ate_m": ate, "ate_ratio_to_dead_reckoning": ate / dead_reckoning_ate,
        "wrong_loops": wrong, "frames": stats["frames"], "longslam_commit": stats.get("longslam_commit"),
    }
    done.write_text(json.dumps(row) + "\n")
    return row


def targets(route_m: float, row: dict, one_km_peak: dict[str, float]) -> list[str]:
    out = []
    method = row["method"]
    if method in ("keyframe", "submap"):
        growth = row["ms_per_frame_last_tenth"] / row["ms_per_frame_first_tenth"]
        out.append(f"ms/frame last/first {growth:.2f} <= {TIME_GROWTH}: {'met' if growth <= TIME_GROWTH else 'MISSED'}")
        if route_m >= 9000:
            out.append(f"peak <= {PEAK_10KM_MB} MB: {'met' if row['peak_mb'] <= PEAK_10KM_MB else 'MISSED'}")
            out.append(f"finish <= {FINISH_10KM_S:.0f} s: {'met' if row['finish_s'] <= FINISH_10KM_S else 'MISSED'}")
        if 2500 <= route_m < 9000 and method in one_km_peak:
            ratio = row["peak_mb"] / one_km_peak[method]
            out.append(f"peak / 1 km peak {ratio:.2f} <= {PEAK_3KM_RATIO}: {'met' if ratio <= PEAK_3KM_RATIO else 'MISSED'}")
    if method == "keyframe" and route_m >= 9000:
        ok = row["ate_ratio_to_dead_reckoning"] <= ATE_RATIO_10KM and row["wrong_loops"] == 0
        out.append(f"ATE <= {ATE_RATIO_10KM}x dead reckoning, no wrong loop: {'met' if ok else 'MISSED'}")
    return out


def plot(results: list[dict], out_dir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    fig, (ax_mem, ax_ate) = plt.subplots(1, 2, figsize=(12, 4.2))
    methods = sorted({r["method"] for entry in results for r in entry["runs"] if "failed" not in r})
    for method in methods:
        lengths, ates = [], []
        for entry in results:
            for r in entry["runs"]:
                if r["method"] == method and "failed" not in r:
                    frames_per_m = r["frames"] / entry["route_m"]
                    xy = np.array(r["rss_every_1000_frames_mb"], dtype=np.float64).reshape(-1, 2)
                    ax_mem.plot(xy[:, 0] / frames_per_m, xy[:, 1], label=f"{method}, {entry['route']}", lw=1.2)
                    lengths.append(entry["route_m"] / 1000)
                    ates.append(r["ate_m"])
        ax_ate.plot(lengths, ates, "o-", label=method)
    ax_mem.set_xlabel("distance travelled [m]")
    ax_mem.set_ylabel("resident memory [MB]")
    ax_mem.legend(fontsize=7)
    ax_ate.set_xlabel("route length [km]")
    ax_ate.set_ylabel("ATE [m]")
    ax_ate.legend(fontsize=8)
    for ax in (ax_mem, ax_ate):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out_dir / "scale.png", dpi=100)
    print(f"wrote {out_dir / 'scale.png'}")


def run_scale(routes: list[str], noise: str, seed: int, methods: list[str], work: Path) -> list[dict]:
    """Simulate each route (once: a sequence already in `work` is kept) and run each installed
    method on it (once: a run already measured in `work` is read back); prints a table per route
    and writes work/scale.json. Returns its entries, one per route."""
    work.mkdir(parents=True, exist_ok=True)
    installed = set(method_names())
    methods = [m for m in methods if m in installed]
    results: list[dict] = []
    one_km_peak: dict[str, float] = {}
    for route in routes:
        seq, simulate_s = simulate(route, noise, seed, work)
        reader = SequenceReader(seq)
        route_m = float(reader.ground_truth.distances()[-1])
        height = json.loads((seq / "meta.json").read_text())["camera"]["camera_height"]
        truth = planar_from_camera_poses(reader.ground_truth.poses, height)
        dead_reckoning = score_files(seq / "odometry.txt", seq)["ate"]
        render = f"simulate {simulate_s:.0f} s ({len(reader) / simulate_s:.1f} frames/s)" if simulate_s else "simulated before"
        print(f"\n{seq.name}: {len(reader)} frames, {route_m:.0f} m; {render}; dead reckoning ATE {dead_reckoning:.3f} m",
              flush=True)
        print(f"  {'method':10s} {'peak MB':>8s} {'ms/frame first':>14s} {'last':>6s} {'finish s':>8s} {'ATE m':>7s} "
              f"{'x DR':>6s} {'wrong loops':>11s}  targets", flush=True)
        rows = []
        for method in methods:
            row = measure(method, seq, work, dead_reckoning, truth)
            rows.append(row)
            if "failed" in row:
                print(f"  {method:10s} failed (exit {row['failed']})", flush=True)
                continue
            if abs(route_m - 1000) < 100:
                one_km_peak[method] = row["peak_mb"]
            wrong = "-" if row["wrong_loops"] is None else str(row["wrong_loops"])
            print(f"  {method:10s} {row['peak_mb']:8.0f} {row['ms_per_frame_first_tenth']:14.1f} "
                  f"{row['ms_per_frame_last_tenth']:6.1f} {row['finish_s']:8.1f} {row['ate_m']:7.3f} "
                  f"{row['ate_ratio_to_dead_reckoning']:6.3f} {wrong:>11s}  " + "; ".join(targets(route_m, row, one_km_peak))
                  + ("  (measured before)" if row.get("reused") else ""), flush=True)
        results.append({"route": route, "route_m": route_m, "frames": len(reader), "simulate_s": simulate_s,
                        "noise": noise, "seed": seed, "dead_reckoning_ate_m": dead_reckoning, "runs": rows})
    (work / "scale.json").write_text(json.dumps(results, indent=1) + "\n")
    print(f"\nwrote {work / 'scale.json'}", flush=True)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--routes", nargs="+", default=["paper-1km", "paper-1km-x3", "tour-10km"])
    parser.add_argument("--noise", default="large")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--methods", nargs="+", default=["odometry", "keyframe", "submap", "orbslam3"])
    parser.add_argument("--work", default="out/bench-scale")
    parser.add_argument("--plot-dir")
    args = parser.parse_args()
    results = run_scale(args.routes, args.noise, args.seed, args.methods, Path(args.work))
    if args.plot_dir:
        plot(results, Path(args.plot_dir))


if __name__ == "__main__":
    main()
