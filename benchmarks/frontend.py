"""The front end alone against dead reckoning: ATE, E_trans, E_rot and ms per frame.

    python benchmarks/frontend.py [--routes paper-300m] [--noises large xlarge] [--seeds 0 1 2]
                                  [--work /tmp/seqs] [--param key=value ...] [--no-odometry]
                                  [--methods keyframe submap] [--frontends fused wheel]
                                  [--sensor realsense-d435]

Sequences are simulated once per (route, noise, seed) into --work as ROUTE-NOISE-SEED (frames
shared through the render cache). For each, prints dead reckoning (the odometry.txt poses),
the front end's online trajectory and its final (full-rate smoother) trajectory, with the
ratios of ATE and E_trans to dead reckoning. ms/frame is the front end's own time (reading
PNGs excluded); the smoother's one-off time at the end is printed apart.
--no-odometry hides the wheel odometry from the front end (a real sequence's case); ATE is
then also given after SE(3) alignment, since the start pose is unknown to the front end.
--methods also runs those methods (in this process) with each --frontends setting, and prints
their final trajectory's metrics, the loop constraints they fed to the front end and how many of
those are wrong against ground truth (> 0.5 m or > 5 deg), and their real-time factor.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from common import sequence
from longslam.run.score import score
from longslam.core.settings import from_mapping, parse_key_values
from longslam.core.frame import Frame
from longslam.io.sequence import SequenceReader
from longslam.eval.diagnose import loop_errors
from longslam.core.geometry import planar_from_camera_poses
from longslam.slam.api import MethodContext
from longslam.slam.catalog import create_method
from longslam.slam.frontend import FrontEnd, FrontEndConfig
from longslam.core.trajectory import Trajectory


def run(path: Path, config: FrontEndConfig, no_odometry: bool) -> dict:
    reader = SequenceReader(path)
    fe = FrontEnd(reader.intrinsics, config)
    for frame in reader:
        if no_odometry:
            frame = Frame(frame.index, frame.timestamp, frame.rgb, frame.depth, None, frame.intrinsics)
        fe.step(frame)
    t0 = time.perf_counter()
    final = fe.final_trajectory()
    smooth_s = time.perf_counter() - t0
    stamps = reader.timestamps
    gt = reader.ground_truth
    out = {"stats": fe.stats, "smooth_s": smooth_s}
    trajs = {"online": fe.camera_poses(fe.online_trajectory()), "final": fe.camera_poses(final)}
    if not no_odometry:
        trajs = {"dead reckoning": reader.odometry.poses, **trajs}
    for name, poses in trajs.items():
        est = Trajectory(stamps, poses, source=name)
        out[name] = score(gt, est, align="se3" if no_odometry else "none")
    return out


def wrong_loops(reader: SequenceReader, constraints: np.ndarray, camera_height: float) -> tuple[int, float, float]:
    """Constraints off by more than 0.5 m or 5 deg from the ground truth; the worst errors."""
    gt = planar_from_camera_poses(reader.ground_truth.poses, camera_height)
    found = loop_errors(gt, constraints)
    return (sum(lp.wrong for lp in found), max((lp.error_m for lp in found), default=0.0),
            max((lp.error_deg for lp in found), default=0.0))


def run_method(path: Path, method: str, frontend: str) -> dict:
    reader = SequenceReader(path)
    m = create_method(method, MethodContext(reader.intrinsics, reader.max_depth, None), {"frontend.mode": frontend})
    t0 = time.perf_counter()
    for frame in reader:
        m.step(frame)
    result = m.finish()
    seconds = time.perf_counter() - t0
    out = score(reader.ground_truth, result.trajectory)
    stats = result.stats
    out["rtf"] = (reader.timestamps[-1] - reader.timestamps[0]) / seconds
    out["loops"] = stats.get("loops_accepted", 0) + stats.get("registrations_accepted", 0)
    loops = result.tables.get("loops")
    if loops is not None:
        out["fed"] = len(loops.rows)
        out["wrong"], out["worst_m"], out["worst_deg"] = wrong_loops(reader, loops.rows, stats["camera_height"])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--routes", nargs="+", default=["paper-300m"])
    ap.add_argument("--noises", nargs="+", default=["large", "xlarge"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--work", type=Path, default=Path("/tmp/seqs"))
    ap.add_argument("--sensor", default="ideal", help="sensor model the sequences are simulated through")
    ap.add_argument("--param", action="append", default=[], help="front-end parameter key=value (nested: registration.sigma=0.05)")
    ap.add_argument("--no-odometry", action="store_true")
    ap.add_argument("--one-thread", action="store_true", help="OpenCV on one thread (with taskset -c 0: one core)")
    ap.add_argument("--methods", nargs="*", default=[])
    ap.add_argument("--frontends", nargs="+", default=["fused"])
    args = ap.parse_args()
    if args.one_thread:
        import cv2

        cv2.setNumThreads(1)
    config = from_mapping(FrontEndConfig, parse_key_values(args.param), "front end")
    args.work.mkdir(parents=True, exist_ok=True)
    header = f"{'sequence':28s} {'trajectory':15s} {'ATE m':>7s} {'ratio':>6s} {'E_trans':>8s} {'ratio':>6s} {'E_rot':>7s}"
    print(header + ("  ATE(se3)" if args.no_odometry else ""))
    rows: dict[tuple[str, str], list[dict]] = {}
    for route in args.routes:
        for noise in args.noises:
            for seed in args.seeds:
                path = sequence(args.work, route, noise, seed, args.sensor)
                res = run(path, config, args.no_odometry)
                base = res.get("dead reckoning")
                for name in ("dead reckoning", "online", "final"):
                    if name not in res:
                        continue
                    m = res[name]
                    ratio_ate = m["ate"] / base["ate"] if base else float("nan")
                    ratio_tr = m["e_trans"] / base["e_trans"] if base else float("nan")
                    extra = f"  {m['ape_mean']:.3f}" if args.no_odometry else ""
                    print(f"{path.name:28s} {name:15s} {m['ate']:7.3f} {ratio_ate:6.2f} {m['e_trans']:8.4f} {ratio_tr:6.2f} "
                          f"{m['e_rot']:7.3f}{extra}")
                    rows.setdefault((f"{route}-{noise}", name), []).append(m)
                st = res["stats"]
                print(f"{'':28s} front end {st['ms_per_frame']:.1f} ms/frame, smoother {res['smooth_s']:.1f} s; "
                      f"registered {st['scans_registered']}/{st['frames']}, refused {st['scans_refused']}, "
                      f"unmatched {st['scans_unmatched']}; odometry: {st['odometry_source']}", flush=True)
                for method in args.methods:
                    for frontend in args.frontends:
                        m = run_method(path, method, frontend)
                        name = f"{method}-{frontend}"
                        rows.setdefault((f"{route}-{noise}", name), []).append(m)
                        loops = (f"loops {m['loops']}, fed {m['fed']}, wrong {m['wrong']} (worst {m['worst_m']:.2f} m "
                                 f"{m['worst_deg']:.1f} deg)") if "fed" in m else f"loops {m['loops']}"
                        print(f"{path.name:28s} {name:15s} {m['ate']:7.3f} {m['ate'] / base['ate']:6.2f} "
                              f"{m['e_trans']:8.4f} {m['e_trans'] / base['e_trans']:6.2f} {m['e_rot']:7.3f}  "
                              f"rtf {m['rtf']:.1f}; {loops}", flush=True)
    if len(args.seeds) > 1:
        print("\nmean over seeds")
        for (seq, name), ms in rows.items():
            print(f"{seq:28s} {name:15s} " + "  ".join(f"{k} {np.mean([m[k] for m in ms]):.4f}" for k in ("ate", "e_trans", "e_rot")))


if __name__ == "__main__":
    main()
