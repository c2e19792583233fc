"""Figures for the submap method (Voxgraph's design) against dead reckoning (and the `keyframe`
method with --with-keyframe):

    LONGSLAM_CACHE=/tmp/lscache python benchmarks/submap.py                  # everything
    python benchmarks/submap.py --noises large --seeds 1 --skip-1km          # a quick look
    python benchmarks/submap.py --skip-300m                                  # paper-1km only

1. ATE / E_trans / E_rot on paper-300m at small, large, xlarge, mean over seeds, with and without
   loop closure (target: ATE at most a third of odometry's at large and xlarge);
2. paper-1km at large: ATE, submaps, registration constraints accepted and rejected, peak
   resident memory (target < 500 MB) and resident memory at 250, 500, 750, 1000 m;
3. the real-time factor (simulated seconds per second of the method's own processing: frames are
   read from disk, so rendering is excluded; target >= 5).

Each run is a separate process (`run_sequence_isolated`), so peak memory is the run's own.
Sequences are made with `longslam.sim.simulate.simulate` (rendering cached under LONGSLAM_CACHE).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from common import run_and_score, sequence
from longslam.io.sequence import SequenceReader
from longslam.run.measurements import RunMeasurements
from longslam.run.score import score
from longslam.core.settings import parse_key_values
from longslam.slam.catalog import method_names


def run(work: Path, seq: Path, method: str, params: dict, tag: str) -> dict:
    metrics, measurements = run_and_score(method, seq, work / "runs" / f"{seq.name}-{method}-{tag}", params)
    return {"metrics": metrics, "measurements": measurements}


def odometry_metrics(seq: Path) -> dict:
    reader = SequenceReader(seq)
    return score(reader.ground_truth, reader.odometry)


def mean_std(values: list[float]) -> str:
    arr = np.asarray(values, dtype=np.float64)
    return f"{arr.mean():6.3f} +- {arr.std():5.3f}"


def table_300m(work: Path, noises: list[str], seeds: int, params: dict, with_keyframe: bool) -> list[dict]:
    variants = [("submap", "no-loop", {**params, "loop_closure": False}), ("submap", "loop", {**params, "loop_closure": True})]
    if with_keyframe:
        variants.append(("keyframe", "default", {}))
    rows = []
    print("== paper-300m: mean +- std over seeds")
    print(f"{'noise':>7} | {'method':>18} | {'ATE [m]':>15} | {'E_trans':>15} | {'E_rot [deg/m]':>15} | {'RTF':>6} | ATE / odometry")
    for noise in noises:
        seqs = [sequence(work, "paper-300m", noise, s) for s in range(seeds)]
        odo = [odometry_metrics(s) for s in seqs]
        odo_ate = np.mean([m["ate"] for m in odo])
        print(f"{noise:>7} | {'odometry':>18} | {mean_std([m['ate'] for m in odo])} | "
              f"{mean_std([m['e_trans'] for m in odo])} | {mean_std([m['e_rot'] for m in odo])} |        |")
        for method, tag, p in variants:
            runs = [run(work, s, method, p, tag) for s in seqs]
            ates = [r["metrics"]["ate"] for r in runs]
            rtf = np.mean([r["measurements"].real_time_factor for r in runs])
            label = f"{method} {tag}" if method == "submap" else method
            print(f"{noise:>7} | {label:>18} | {mean_std(ates)} | {mean_std([r['metrics']['e_trans'] for r in runs])} | "
                  f"{mean_std([r['metrics']['e_rot'] for r in runs])} | {rtf:6.1f} | {np.mean(ates) / odo_ate:.2f}", flush=True)
            for r in runs:
                stats = r["measurements"].method_stats
                rows.append({"noise": noise, "method": label, "ate": r["metrics"]["ate"], "rtf": r["measurements"].real_time_factor,
                             "peak_rss_mb": r["measurements"]["peak_rss_bytes"] / 1e6,
                             "registrations": (stats.get("registrations_accepted"), stats.get("registrations_rejected")),
                             "loops": (stats.get("loops_accepted"), stats.get("loops_rejected"))})
    return rows


def memory_by_distance(seq: Path, figures: RunMeasurements, marks=(250.0, 500.0, 750.0, 1000.0)) -> dict[float, float]:
    """Resident memory (MB) at the first sample at or after each distance travelled."""
    distances = SequenceReader(seq).ground_truth.distances()
    samples = figures.rss_samples
    out = {}
    for mark in marks:
        frame = int(np.searchsorted(distances, mark))
        after = [rss for i, rss in samples if i >= frame]
        if frame < len(distances) and after:
            out[mark] = after[0] / 1e6
        elif mark <= distances[-1] + 10.0:
            out[mark] = samples[-1][1] / 1e6
    return out


def table_1km(work: Path, params: dict, with_keyframe: bool) -> None:
    seq = sequence(work, "paper-1km", "large", 0)
    odo = odometry_metrics(seq)
    print("\n== paper-1km at large noise, seed 0")
    print(f"odometry ATE {odo['ate']:.2f} m, E_trans {odo['e_trans']:.4f}, E_rot {odo['e_rot']:.3f} deg/m")
    methods = [("submap", {**params, "loop_closure": False})] + ([("keyframe", {})] if with_keyframe else [])
    for method, p in methods:
        r = run(work, seq, method, p, "1km")
        f, stats = r["measurements"], r["measurements"].method_stats
        print(f"{method}: ATE {r['metrics']['ate']:.2f} m, E_trans {r['metrics']['e_trans']:.4f}, "
              f"E_rot {r['metrics']['e_rot']:.3f} deg/m, real-time factor {f['real_time_factor']:.1f}, "
              f"peak RSS {f['peak_rss_bytes'] / 1e6:.0f} MB")
        if method == "submap":
            print(f"  submaps {stats['submaps']}, registrations accepted {stats['registrations_accepted']} / "
                  f"rejected {stats['registrations_rejected']} {stats['registration_rejection_reasons']}, "
                  f"map bytes {json.dumps(stats['map_bytes'])}")
        marks = memory_by_distance(seq, f)
        print("  resident memory by distance: " + ", ".join(f"{d:.0f} m: {mb:.0f} MB" for d, mb in marks.items()))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--noises", nargs="+", default=["small", "large", "xlarge"])
    parser.add_argument("--skip-300m", action="store_true")
    parser.add_argument("--skip-1km", action="store_true")
    parser.add_argument("--param", action="append", default=[], metavar="KEY=VALUE", help="submap parameter")
    parser.add_argument("--with-keyframe", action="store_true", help="also run the keyframe method")
    parser.add_argument("--work", default=None, help="folder for sequences and runs (default: a temporary one)")
    args = parser.parse_args()
    params = parse_key_values(args.param)
    with_keyframe = args.with_keyframe
    if with_keyframe and "keyframe" not in method_names():
        parser.error("the keyframe method is not registered")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.work) if args.work else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        if not args.skip_300m:
            table_300m(work, args.noises, args.seeds, params, with_keyframe)
        if not args.skip_1km:
            table_1km(work, params, with_keyframe)


if __name__ == "__main__":
    main()
