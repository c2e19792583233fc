"""Where a run's per-frame time goes, tenth by tenth of the route: which part of `step` grows as
the route does (issue 22's "last tenth <= 1.2x the first").

    python benchmarks/step_phases.py SEQ --method submap --out RUN [--param NAME=VALUE ...]

Runs the method in this process through the run engine, with each listed part of `step` wrapped
in a timer; a part's time is charged to the frame whose `step` called it. Prints, per tenth of the
frames, the mean ms per frame of the whole `step` and of each part (inclusive: a part that calls
another counts it too), and how often the part ran. Wall-clock, so run it on a quiet machine.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from longslam.run.scored_run import run_named
from longslam.core.settings import parse_key_values

# (module, owner in the module or "" for a module-level function, attribute, label)
FRONTEND = [
    ("longslam.slam.frontend.motion", "FrontEnd", "step", "frontend.step"),
    ("longslam.slam.frontend.motion", "FrameStep", "depths", "frame_step.depths"),
]
PHASES = {
    "submap": FRONTEND + [
        ("longslam.slam.submap.tsdf", "TSDF", "integrate_depth", "tsdf.integrate_depth"),
        ("longslam.slam.submap.free_space", "SubmapFreeSpace", "add", "free_space.add"),
        ("longslam.slam.submap.method", "SubmapMethod", "_finish_submap", "finish_submap"),
        ("longslam.slam.submap.method", "SubmapMethod", "_register_submap", "  register_submap"),
        ("longslam.slam.submap.method", "", "register", "    register (one pair)"),
        ("longslam.slam.submap.store", "SubmapStore", "get", "    store.get"),
        ("longslam.slam.submap.method", "SubmapMethod", "_loop_closure", "loop_closure"),
        ("longslam.slam.features", "", "extract", "  features.extract"),
        ("longslam.slam.place_recognition", "Vocabulary", "query", "  vocabulary.query"),
        ("longslam.slam.place_recognition", "", "verify", "  verify (PnP)"),
        ("longslam.slam.place_recognition", "", "depth_held_transform", "  depth_held_transform"),
        ("longslam.slam.submap.method", "SubmapMethod", "_add_loop", "  add_loop"),
        ("longslam.slam.submap.method", "SubmapMethod", "_known_place", "  known_place"),
        ("longslam.slam.place_recognition", "Vocabulary", "add", "  vocabulary.add"),
        ("longslam.slam.graph.pose_graph", "PoseGraph", "_solve", "graph solve (any)"),
    ],
    "keyframe": FRONTEND + [
        ("longslam.slam.keyframe.method", "KeyframeMethod", "_add_node", "add_node"),
        ("longslam.slam.keyframe.method", "", "extract", "  features.extract"),
        ("longslam.slam.keyframe.method", "", "local_grid", "  local_grid"),
        ("longslam.slam.keyframe.method", "", "depth_points_in_base", "  depth_points"),
        ("longslam.slam.place_recognition", "Vocabulary", "quantise", "  vocabulary.quantise"),
        ("longslam.slam.keyframe.loops", "LoopCloser", "detect", "  loops.detect"),
        ("longslam.slam.place_recognition", "Vocabulary", "query_words", "    vocabulary.query_words"),
        ("longslam.slam.keyframe.loops", "LoopCloser", "try_link", "    try_link (visual)"),
        ("longslam.slam.keyframe.loops", "", "verify", "      verify (PnP)"),
        ("longslam.slam.keyframe.loops", "", "depth_held_transform", "      depth_held_transform"),
        ("longslam.slam.keyframe.loops", "LoopCloser", "proximity_candidates", "    proximity_candidates"),
        ("longslam.slam.keyframe.loops", "LoopCloser", "try_scan_link", "    try_scan_link"),
        ("longslam.slam.keyframe.loops", "", "scan_link", "      scan_link"),
        ("longslam.slam.keyframe.memory", "KeyframeMemory", "grid", "      memory.grid (read back)"),
        ("longslam.slam.keyframe.loops", "LoopCloser", "_try_loop", "    graph try_loop"),
        ("longslam.slam.graph.pose_graph", "PoseGraph", "optimize_local", "      optimize_local"),
        ("longslam.slam.keyframe.memory", "KeyframeMemory", "retrieve_around", "    memory.retrieve_around"),
        ("longslam.slam.keyframe.memory", "KeyframeMemory", "admit", "  memory.admit"),
        ("longslam.slam.keyframe.memory", "KeyframeMemory", "transfer", "    memory.transfer"),
    ],
}
STEP = {"submap": ("longslam.slam.submap.method", "SubmapMethod"),
        "keyframe": ("longslam.slam.keyframe.method", "KeyframeMethod")}


class Clock:
    """Per-frame sums of each wrapped part's time."""

    def __init__(self) -> None:
        self.frame = -1
        self.times: dict[str, dict[int, float]] = defaultdict(lambda: defaultdict(float))
        self.calls: dict[str, dict[int, int]] = defaultdict(lambda: defaultdict(int))
        self.depth: dict[str, int] = defaultdict(int)  # a recursive part counts its outermost call only

    def wrap(self, owner: object, name: str, label: str, starts_frame: bool = False) -> None:
        inner = getattr(owner, name)
        clock = self

        @functools.wraps(inner)
        def timed(*args, **kwargs):
            if starts_frame:
                clock.frame += 1
            clock.depth[label] += 1
            started = time.perf_counter()
            try:
                return inner(*args, **kwargs)
            finally:
                clock.depth[label] -= 1
                if clock.depth[label] == 0 and clock.frame >= 0:
                    clock.times[label][clock.frame] += time.perf_counter() - started
                    clock.calls[label][clock.frame] += 1

        setattr(owner, name, timed)


def _owner(module: str, owner: str) -> object:
    mod = importlib.import_module(module)
    return getattr(mod, owner) if owner else mod


def report(clock: Clock, frames: int, labels: list[str]) -> None:
    edges = np.linspace(0, frames, 11).astype(int)
    print(f"{'part':28s}" + "".join(f"{f'{k + 1}/10':>9s}" for k in range(10)) + "   last/first")
    for label in labels:
        per_frame = np.zeros(frames)
        calls = np.zeros(frames)
        for f, t in clock.times[label].items():
            if f < frames:
                per_frame[f] = t
        for f, n in clock.calls[label].items():
            if f < frames:
                calls[f] = n
        means = [1000 * per_frame[a:b].mean() for a, b in zip(edges[:-1], edges[1:])]
        ratio = means[-1] / means[0] if means[0] > 0 else float("inf")
        print(f"{label:28s}" + "".join(f"{m:9.2f}" for m in means) + f"   {ratio:6.2f}")
        if label != "step":
            counts = [calls[a:b].sum() for a, b in zip(edges[:-1], edges[1:])]
            print(f"{'    calls':28s}" + "".join(f"{int(c):9d}" for c in counts))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("sequence", type=Path)
    parser.add_argument("--method", choices=sorted(PHASES), default="submap")
    parser.add_argument("--out", type=Path, required=True, help="run folder (replaced)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE")
    args = parser.parse_args()
    clock = Clock()
    module, owner = STEP[args.method]
    clock.wrap(_owner(module, owner), "step", "step", starts_frame=True)
    labels = ["step"]
    for module, owner, name, label in PHASES[args.method]:
        clock.wrap(_owner(module, owner), name, label)
        labels.append(label)
    measurements = run_named(args.method, args.sequence, args.out, parse_key_values(args.param), overwrite=True,
                                progress=False)
    frames = measurements.frames
    print(f"{args.method} on {args.sequence}: {frames} frames, finish {measurements.finish_time_s:.1f} s")
    report(clock, frames, labels)


if __name__ == "__main__":
    main()
