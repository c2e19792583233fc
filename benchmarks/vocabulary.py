"""The keyframe method's per-node cost against distance, for each way of finding a word
(`--param vocabulary_index`): OpenCV brute force (exact), faiss flat (exact), faiss HNSW
(approximate), on one sequence (default paper-1km, large noise, seed 0).

    LONGSLAM_CACHE=/tmp/lscache python benchmarks/vocabulary.py [--route paper-1km] [--indexes hnsw flat]

Prints per index: the mean time to make a node over the first and the last 100 nodes and their
ratio (target <= 1.5), the dictionary's size, loops accepted, and the share of the exact run's
loop closures (node pairs, appearance and proximity) that the run found too; ATE and E_rot; wall
and method time and peak memory. Runs one at a time, each in its own process.
"""

from __future__ import annotations

import argparse
import sqlite3
from pathlib import Path

import numpy as np

from common import run_and_score, sequence

from longslam.run.folder import read_table


def loop_pairs(database: Path, kind: str) -> set[tuple[int, int]]:
    with sqlite3.connect(database) as conn:
        return {(a, b) for a, b, k in conn.execute("SELECT from_id, to_id, type FROM Link") if k == kind}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--route", default="paper-1km")
    parser.add_argument("--noise", default="large")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--indexes", nargs="+", default=["bruteforce", "flat", "hnsw"])
    parser.add_argument("--frontend", default="wheel", help="keyframe's frontend.mode parameter (wheel: the paper's)")
    parser.add_argument("--work", default="out/bench-vocabulary")
    args = parser.parse_args()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    seq = sequence(work, args.route, args.noise, args.seed)
    exact: dict[str, set] | None = None
    for index in args.indexes:
        out = work / "runs" / f"{seq.name}-{index}"
        params = {"vocabulary_index": index}
        if args.frontend:
            params["frontend.mode"] = args.frontend
        scores, measured = run_and_score("keyframe", seq, out, params)
        stats = measured.method_stats
        times = read_table(out / "nodes.csv").column("time_ms")
        pairs = {kind: loop_pairs(out / "memory.db", kind) for kind in ("loop", "proximity")}
        if index in ("bruteforce", "flat") and exact is None:
            exact = pairs
        shared = ""
        if exact is not None:
            shared = ", ".join(f"{kind} {len(pairs[kind] & exact[kind])}/{len(exact[kind])}" for kind in exact)
        print(
            f"{index:10s} {seq.name}: node time first 100 {times[:100].mean():.1f} ms, last 100 "
            f"{times[-100:].mean():.1f} ms (ratio {times[-100:].mean() / times[:100].mean():.2f}); "
            f"{stats['vocabulary_words']} words; loops {stats['loops_accepted']}; exact run's loops found: {shared}; "
            f"ATE {scores['ate']:.3f} m, E_rot {scores['e_rot']:.3f} deg/m; wall {measured.wall_time_s:.1f} s, "
            f"method {measured.method_time_s:.1f} s, peak {measured.peak_rss_bytes / 1e6:.0f} MB",
            flush=True,
        )


if __name__ == "__main__":
    main()
