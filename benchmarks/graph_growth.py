"""What a keyframe loop try costs as the graph grows: the whole solve against iSAM2 (issue 22).

    python benchmarks/graph_growth.py [--nodes 6000] [--every 10] [--batch-nodes 1000]

A robot drives laps of a 40 x 20 m block (a node every 1.5 m, as keyframe's 1 Hz nodes at
1.5 m/s; 6,000 nodes is about a 10 km route), its odometry 2 % long and 0.3 deg a node off in
heading. From the second lap on, every `--every`th node tries a loop closure onto the first lap's
node at the same place, and every fifth such try is a wrong one (3 m off), which the graph check
must reject, as `PoseGraph.try_loop` does in keyframe. Printed per tenth of the nodes: the mean
and 90th percentile ms of a try, for `batch_nodes=0` (always whole) and the given `batch_nodes`,
with the two graphs' verdicts compared and their final poses' largest difference.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from longslam.core.geometry import compose_xyyaw, relative_xyyaw
from longslam.slam.graph import PoseGraph

ODOMETRY_SIGMAS = (0.05, 0.01, 0.005)
LOOP_SIGMAS = (0.05, 0.05, 0.02)


def block_lap(step: float = 1.5, width: float = 40.0, height: float = 20.0) -> np.ndarray:
    """Poses every `step` metres round a width x height rectangle, counter-clockwise."""
    poses = []
    for side, (length, yaw) in enumerate(((width, 0.0), (height, np.pi / 2), (width, np.pi), (height, -np.pi / 2))):
        start = [(0.0, 0.0), (width, 0.0), (width, height), (0.0, height)][side]
        for d in np.arange(0.0, length, step):
            poses.append((start[0] + d * np.cos(yaw), start[1] + d * np.sin(yaw), yaw))
    return np.array(poses)


def grow(truth: np.ndarray, lap: int, every: int, batch_nodes: int) -> tuple[list[float], list[bool], PoseGraph]:
    deltas = relative_xyyaw(truth[:-1], truth[1:])
    deltas[:, 0] *= 1.02
    deltas[:, 2] += np.radians(0.3)
    graph = PoseGraph(batch_nodes=batch_nodes)
    graph.add_node(0, truth[0])
    seconds, verdicts = [], []
    for k, delta in enumerate(deltas, start=1):
        graph.add_node(k, compose_xyyaw(graph.estimate(k - 1), delta))
        graph.add_odometry(k - 1, k, delta, ODOMETRY_SIGMAS)
        if k >= lap and k % every == 0:
            target = k % lap
            claim = relative_xyyaw(truth[target], truth[k])
            if (k // every) % 5 == 0:
                claim = claim + (3.0, 0.0, 0.0)
            start = time.perf_counter()
            check = graph.try_loop(target, k, claim, sigmas=LOOP_SIGMAS, max_error=3.0, check="graph")
            seconds.append(time.perf_counter() - start)
            verdicts.append(check.accepted)
    return seconds, verdicts, graph


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, default=6000)
    parser.add_argument("--every", type=int, default=10)
    parser.add_argument("--batch-nodes", type=int, default=1000)
    args = parser.parse_args()
    one = block_lap()
    truth = np.concatenate([one] * (args.nodes // len(one) + 1))[: args.nodes]
    runs = {}
    for batch_nodes in (0, args.batch_nodes):
        start = time.perf_counter()
        runs[batch_nodes] = grow(truth, len(one), args.every, batch_nodes)
        print(f"batch_nodes={batch_nodes}: {len(runs[batch_nodes][0])} tries in {time.perf_counter() - start:.1f} s")
    tries = len(runs[0][0])
    print(f"{args.nodes} nodes, {len(one)} a lap, a try every {args.every} nodes from the second lap")
    print("tenth of tries | whole: mean / p90 ms | batch_nodes=%d: mean / p90 ms" % args.batch_nodes)
    for t in range(10):
        rows = slice(t * tries // 10, (t + 1) * tries // 10)
        cells = []
        for batch_nodes in (0, args.batch_nodes):
            ms = 1000 * np.asarray(runs[batch_nodes][0][rows])
            cells.append(f"{ms.mean():7.1f} / {np.percentile(ms, 90):7.1f}")
        print(f"{t + 1:>14} | {cells[0]:>19} | {cells[1]:>19}")
    same = sum(a == b for a, b in zip(runs[0][1], runs[args.batch_nodes][1]))
    whole, incremental = runs[0][2].optimize(), runs[args.batch_nodes][2].optimize()
    gap = max(np.hypot(whole[n][0] - incremental[n][0], whole[n][1] - incremental[n][1]) for n in whole)
    print(f"the same verdict on {same} of {tries} tries ({sum(runs[0][1])} accepted by the whole solve); "
          f"final poses within {gap * 1000:.2f} mm")


if __name__ == "__main__":
    main()
