"""Accuracy, memory and speed of SLAM methods against dead reckoning on the paper's routes.

    python benchmarks/slam_methods.py --method keyframe [--seeds 3] [--skip-1km] [--param key=value ...]

Sequences are simulated once per (route, noise, seed) into --work (frames shared through the
render cache); each run is a separate process (clean peak memory). Prints:
- paper-300m at small, large, xlarge: ATE, E_trans, E_rot, mean over the seeds, beside odometry;
- paper-1km at large: ATE, the method's counters, peak RSS, RSS at 250/500/750/1000 m;
- real-time factor (the method's own processing time; reading and rendering frames excluded).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from common import run_and_score, sequence
from longslam.io.sequence import SequenceReader
from longslam.run.measurements import RunMeasurements
from longslam.run.score import score
from longslam.core.settings import parse_key_values

COUNTERS = ("nodes", "submaps", "loops_accepted", "loops_rejected", "appearance_accepted",
            "appearance_rejected_verification", "appearance_rejected_graph",
            "proximity_accepted", "proximity_rejected_verification", "proximity_rejected_graph",
            "registrations_accepted", "registrations_rejected",
            "nodes_transferred", "nodes_retrieved", "vocabulary_words")


def run(work: Path, method: str, seq: Path, params: dict, tag: str) -> tuple[dict, dict]:
    return run_and_score(method, seq, work / "runs" / f"{seq.name}-{method}{tag}", params)


def rss_at_distances(figures: RunMeasurements, truth, marks=(250, 500, 750, 1000)) -> list[str]:
    distance = truth.distances()
    samples = np.array(figures.rss_samples, dtype=np.float64)
    out = []
    for mark in marks:
        frame = int(np.searchsorted(distance, mark))
        label = f"{mark} m"
        if frame >= len(distance):
            if mark > 1.05 * distance[-1]:
                out.append(f"{mark} m: (route shorter)")
                continue
            # A route within 5 % of the mark (paper-1km is 992 m): report its end, before finish().
            frame, label = len(distance) - 1, f"{distance[-1]:.0f} m (end)"
        k = min(int(np.searchsorted(samples[:, 0], frame)), len(samples) - 2)
        out.append(f"{label}: {samples[k, 1] / 1e6:.0f} MB")
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--method", required=True)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--work", default="out/bench")
    parser.add_argument("--skip-300m", action="store_true")
    parser.add_argument("--skip-1km", action="store_true")
    parser.add_argument("--param", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--tag", default="", help="suffix for run folders of a parameter variant")
    args = parser.parse_args()
    params = parse_key_values(args.param)
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    seeds = range(args.seeds)

    if not args.skip_300m:
        print(f"== paper-300m, mean over {args.seeds} seeds: {args.method} {params or ''} vs odometry")
        print(f"{'noise':>7} | {'ATE':>13} | {'E_trans':>15} | {'E_rot deg/m':>15} | ATE ratio | RTF")
        for noise in ("small", "large", "xlarge"):
            rows = {"m": [], "o": []}
            rtf = []
            for seed in seeds:
                seq = sequence(work, "paper-300m", noise, seed)
                scores, figures = run(work, args.method, seq, params, args.tag)
                rows["m"].append(scores)
                rtf.append(figures.real_time_factor)
                rows["o"].append(score(SequenceReader(seq).ground_truth, SequenceReader(seq).odometry))
            mean = lambda who, key: float(np.mean([s[key] for s in rows[who]]))  # noqa: E731
            print(
                f"{noise:>7} | {mean('m', 'ate'):5.2f} / {mean('o', 'ate'):5.2f} | {mean('m', 'e_trans'):.4f}/{mean('o', 'e_trans'):.4f} | "
                f"{mean('m', 'e_rot'):.3f} / {mean('o', 'e_rot'):.3f} | {mean('m', 'ate') / mean('o', 'ate'):9.2f} | {np.mean(rtf):.1f}"
            )

    if not args.skip_1km:
        print(f"\n== paper-1km at large, {args.method} {params or ''}")
        for seed in seeds:
            seq = sequence(work, "paper-1km", "large", seed)
            truth = SequenceReader(seq).ground_truth
            scores, figures = run(work, args.method, seq, params, args.tag)
            odom = score(truth, SequenceReader(seq).odometry)
            stats = figures.method_stats
            counters = ", ".join(f"{k} {stats[k]}" for k in COUNTERS if k in stats)
            print(f"seed {seed}: ATE {scores['ate']:.2f} m (odometry {odom['ate']:.2f}), E_trans {scores['e_trans']:.4f}, "
                  f"E_rot {scores['e_rot']:.3f}; peak RSS {figures.peak_rss_bytes / 1e6:.0f} MB "
                  f"(baseline {figures.baseline_rss_bytes / 1e6:.0f} MB); RTF {figures.real_time_factor:.1f}")
            print(f"   {counters}")
            print(f"   RSS by distance: {'; '.join(rss_at_distances(figures, truth))}")
            print(f"   map bytes: {stats.get('map_bytes')}")


if __name__ == "__main__":
    main()
