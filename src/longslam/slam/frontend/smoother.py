"""The front end's batch estimator over planar poses (x, y, yaw), run at the end.

`FullSmoother` runs over every frame, as a `slam.graph.FactorGraph`: the wheel factors of the
online filter (`filter.py`; lateral step held tight, the biases as slowly varying states, one per block of frames),
the scan-to-map
factors (information = the registration's Hessian), and the loop closures a method adds. The
final trajectory comes from it, so a loop correction spreads as smooth curvature. On a long route
a method's optimised graph nodes can be held instead, and only the frames between them smoothed
(`FullSmoother.solve_held`): a finish whose memory does not grow with the loops.
"""

from __future__ import annotations

import bisect
from collections.abc import Mapping
from dataclasses import dataclass

import gtsam
import numpy as np

from longslam.core.errors import InputError
from longslam.core.geometry import compose_xyyaw, relative_xyyaw
from longslam.core.parameter import check_declared, param
from longslam.slam.frontend.filter import MotionNoise
from longslam.slam.frontend.frame_store import FrameRecord, FrameStore
from longslam.slam.graph.factors import FactorGraph, WheelStep, X, pose_array
from longslam.slam.graph.parts import levenberg_marquardt_parts
from longslam.slam.graph.solver import Stopping, levenberg_marquardt

# Added to a scan's or loop's information: a registration's Hessian is singular along a corridor.
INFORMATION_RIDGE = 1e-6
# A pose the solve keeps where it is given (the route's first frame, a held graph node): stds of
# x, y (m) and yaw (rad).
HELD_SIGMAS = np.array([1e-4, 1e-4, 1e-5])
HELD_AXES_SIGMA = 1e-5  # rad: the building's axes, held in a solve between held nodes


@dataclass
class SmootherConfig:
    bias_block: int = param(10, "frames sharing one bias state", at_least=1)
    # Held far tighter than online: E_rot scores the direction of each 10 Hz step in the previous
    # pose's frame, and dead reckoning gets that almost exactly right. A correction must come as
    # heading and forward distance, never as a sideways shift of a step.
    lateral_sigma: float = param(1e-5, "std of a wheel step's sideways component in the smoother", above=0, unit="m")
    # The y of its twist is zero on any arc a wheeled base drives.
    nonholonomic_sigma: float = param(
        0.0,
        "without wheel odometry, std of each step's sideways motion; 0: off, as for a hand-held camera",
        at_least=0,
        unit="m",
    )
    iterations: int = param(50, "most optimiser iterations of the full smoother", at_least=1)
    bias_states: bool = param(
        True, "bias states in the smoother, or each wheel step corrected by the online filter's bias estimate"
    )
    optimizer: str = param(
        "lm",
        "lm: Levenberg-Marquardt (Gauss-Newton steps, damped when one fails); gn: stop there instead",
        choices=("lm", "gn"),
    )
    # The last iterations of a tighter tolerance move the trajectory by millimetres at several times the cost.
    relative_tolerance: float = param(3e-4, "stop once a step lowers the error by less than this share", at_least=0)
    # A longer route is solved window by window (`slam.graph.parts`): the same Levenberg-Marquardt
    # steps as one solve, but no more than one window's linear system is held at a time, so the
    # solve's peak does not grow with the route.
    window: int = param(
        500, "most frames in one window of the solve, at least twice bias_block (0: no limit)", at_least=0
    )
    # Faster (each window is built and linearised twice a step), and up to this length the whole
    # solve's peak stays under the one the maps reach after it.
    whole_frames: int = param(
        8000, "a route of up to this many frames is solved whole (0: by window from the start)", at_least=0
    )
    # A method that hands over its graph's optimised nodes (keyframe, submap) then has only the
    # frames between them smoothed, chunk by chunk (`solve_held`): the finish holds one chunk's
    # graph, where the solve over every frame grows with the loops that tie the laps together.
    hold_nodes_beyond: int = param(
        10000,
        "routes longer than this many frames are finished with the graph's nodes held (0: every route)",
        at_least=0,
    )

    @property
    def stopping(self) -> Stopping:
        """When the solver loop stops, from `iterations`, `relative_tolerance` and `optimizer`."""
        return Stopping(self.iterations, self.relative_tolerance, damping=self.optimizer != "gn")

    def __post_init__(self) -> None:
        check_declared(self, "front end", "smoother.")
        if self.window != 0 and self.window < 2 * self.bias_block:
            raise InputError(
                f"front end: smoother.window must be 0 (no limit) or at least twice bias_block "
                f"({2 * self.bias_block} frames), got {self.window}"
            )


class FullSmoother:
    """Batch smoother over every frame: a factor graph of slam/graph, solved by its solver loop."""

    def __init__(self, noise: MotionNoise, config: SmootherConfig | None = None, use_bias: bool = True):
        self.noise = noise
        self.config = config or SmootherConfig()
        self.use_bias = use_bias
        # Every frame's online pose (`initial`) and factors (`records`), in flat arrays.
        self.records = FrameStore()
        self.initial = self.records.poses
        self.loops: list[tuple[int, int, np.ndarray, np.ndarray]] = []
        # (frame, wall direction in the robot's frame, std): walls along the building's axes, whose
        # direction is solved with the poses from `axes_initial` (wall_axes.py).
        self.walls: list[tuple[int, float, float]] = []
        self.axes_initial = 0.0
        self.bias_init: dict[int, np.ndarray] = {}
        self.solved_by = ""  # how the last solve went: "every frame" or "held nodes"

    def add_frame(
        self,
        online_pose: np.ndarray,
        wheel: WheelStep | None,
        wheel_sigmas: np.ndarray | None,
        cv_step: np.ndarray | None,
        scan: tuple[int, np.ndarray, np.ndarray] | None,
        bias: np.ndarray | None,
        visual: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        k = len(self.records)
        self.records.append(
            np.asarray(online_pose, dtype=np.float64), FrameRecord(wheel, wheel_sigmas, cv_step, scan, visual, bias)
        )
        block = k // self.config.bias_block
        if bias is not None and block not in self.bias_init:
            self.bias_init[block] = np.asarray(bias, dtype=np.float64).copy()

    def add_wall(self, k: int, direction: float, sigma: float) -> None:
        """Frame k saw a wall at `direction` (rad, robot frame) along the building's axes."""
        self.walls.append((int(k), float(direction), float(sigma)))

    def add_loop(self, i: int, j: int, delta: np.ndarray, information: np.ndarray) -> None:
        self.loops.append(
            (int(i), int(j), np.asarray(delta, dtype=np.float64), np.asarray(information, dtype=np.float64))
        )

    def solve(self, held: Mapping[int, np.ndarray] | None = None, hold: bool = False) -> np.ndarray:
        """Every frame's smoothed base pose (x, y, yaw), (frames, 3). `held`: a method's optimised
        graph nodes ({frame: pose}), held on a route longer than `hold_nodes_beyond` frames, or
        on any route with `hold`."""
        n = len(self.initial)
        if n == 0:
            return np.zeros((0, 3))
        if held is not None and (hold or n > self.config.hold_nodes_beyond):
            self.solved_by = "held nodes"
            return self.solve_held(held)
        self.solved_by = "every frame"
        window = self.config.window
        if window == 0 or n <= max(window, self.config.whole_frames):
            out, self.iterations = self.build_graph().solve(n, self.config.stopping)
            return out
        return self._solve_in_parts(window)

    def _solve_in_parts(self, window: int) -> np.ndarray:
        """The whole solve's result, computed window by window (`slam.graph.parts`): each step of
        Levenberg-Marquardt eliminates one window at a time, so that no more than one window's
        linear system is held. The windows share the frames and bias blocks that factors of two
        windows touch (a window's first frame's step, a scan's anchor, a loop's frames)."""
        n = len(self.initial)
        ranges = [(a, min(a + window, n) - 1) for a in range(0, n, window)]
        bias_range = self._bias_range()
        variables = self._variables(bias_range)

        def part(p: int) -> gtsam.NonlinearFactorGraph:
            graph = FactorGraph()
            self._add_factors(graph, *ranges[p], bias_range)
            return graph.graph

        result, self.iterations = levenberg_marquardt_parts(
            part, len(ranges), variables.values, variables.dims, self.config.stopping
        )
        return pose_array(result, range(n))

    def solve_held(self, held: Mapping[int, np.ndarray]) -> np.ndarray:
        """Every frame's pose, (frames, 3), with the frames in `held` kept at the poses given (a
        method's optimised graph nodes) and the frames between them smoothed by their own factors,
        one chunk of about `window` frames at a time, in order.

        The loops are left out: they join graph nodes, whose poses already carry them. What a
        chunk reaches before its first frame (a scan's anchor, the bias block running on) is held
        at the earlier chunk's result, so no more than one chunk's graph is held, however long
        the route and however many its loops; the price is that nothing flows back from a later
        chunk into an earlier one but through the held nodes."""
        n = len(self.initial)
        out = np.zeros((n, 3))
        if n == 0:
            return out
        held = {int(k): np.asarray(pose, dtype=np.float64) for k, pose in held.items() if 0 <= int(k) < n}
        out[0] = held.get(0, self.initial[0])
        bias_range = self._bias_range()
        solved_bias: dict[int, np.ndarray] = {}
        self.iterations = 0
        # The walls in frame order, so that each chunk's are one slice of them.
        walls = sorted(self.walls)
        wall_frames = [k for k, _, _ in walls]
        for first, last in _held_chunks(sorted(held), n, max(self.config.window, 2 * self.config.bias_block)):
            graph = FactorGraph()
            chunk_walls = walls[bisect.bisect_right(wall_frames, first) : bisect.bisect_right(wall_frames, last)]
            self._add_held_chunk(graph, first, last, held, out, chunk_walls, bias_range, solved_bias)
            result, taken = levenberg_marquardt(graph.graph, graph.values, graph.dims, self.config.stopping)
            self.iterations = max(self.iterations, taken)
            out[first : last + 1] = pose_array(result, range(first, last + 1))
            for key in graph.dims:
                if gtsam.Symbol(key).chr() == ord("b"):
                    solved_bias[gtsam.Symbol(key).index()] = np.asarray(result.atPoint2(key))
        return out

    def _add_held_chunk(
        self,
        graph: FactorGraph,
        first: int,
        last: int,
        held: Mapping[int, np.ndarray],
        out: np.ndarray,
        walls: list[tuple[int, float, float]],
        bias_range: tuple[int, int] | None,
        solved_bias: Mapping[int, np.ndarray],
    ) -> None:
        """Chunk `first`..`last`'s variables and factors for `solve_held`: its frames from the online
        poses, carried along from the last held frame; frame `first` (solved or held) and the held
        frames held; each frame's own factors, a scan's anchor before the chunk held where it was
        solved; its `walls` against the held axes; the chunk's bias blocks, the first one drawn
        toward where the chunk before left it."""
        online = self.records.pose_span(first, last + 1)
        # Each frame's latest held frame at or before it (the chunk's first frame counts as held).
        starts = np.array([first] + [k for k in range(first + 1, last + 1) if k in held])
        reference = starts[np.searchsorted(starts, np.arange(first, last + 1), side="right") - 1]
        anchors = np.array([held.get(int(k), out[first]) for k in starts])[np.searchsorted(starts, reference)]
        start_values = compose_xyyaw(anchors, relative_xyyaw(online[reference - first], online))
        for k in range(first, last + 1):
            graph.add_pose(k, start_values[k - first])
        graph.prior_pose(first, held.get(first, out[first]), HELD_SIGMAS)
        for k in range(first + 1, last + 1):
            if k in held:
                graph.prior_pose(k, held[k], HELD_SIGMAS)
            record = self.records[k]
            if record.scan is not None and record.scan[0] < first and X(record.scan[0]) not in graph.dims:
                graph.add_pose(record.scan[0], out[record.scan[0]])
                graph.prior_pose(record.scan[0], out[record.scan[0]], HELD_SIGMAS)
            self._add_frame_factors(graph, k, record)
        if walls:
            graph.add_axes(self.axes_initial)
            graph.prior_axes(self.axes_initial, HELD_AXES_SIGMA)
            for k, direction, sigma in walls:
                graph.wall(k, direction, sigma)
        if bias_range is None:
            return
        bb = self.config.bias_block
        b0, b1 = bias_range
        lo, hi = max(b0, first // bb), min(b1, (last - 1) // bb)
        if lo > hi:
            return
        start, walk = self._bias_sigmas()
        carried = solved_bias.get(lo, solved_bias.get(lo - 1))  # where the chunk before left the bias
        value = np.zeros(2) if carried is None else carried
        for b in range(lo, hi + 1):
            value = solved_bias[b] if b in solved_bias else self.bias_init.get(b, value)
            graph.add_bias(b, value)
            if b > lo:
                graph.bias_walk(b - 1, b, walk)
        if lo == b0 and first <= bb * b0 + 1 <= last:
            graph.prior_bias(b0, np.zeros(2), start)
        else:  # the block before (or this block's first frames) solved in the chunk before
            graph.prior_bias(lo, value if carried is None else carried, walk)

    def _bias_sigmas(self) -> tuple[np.ndarray, np.ndarray]:
        """The stds of the route's first bias block from zero and of one block's walk from the
        block before it (forward, yaw)."""
        nz = self.noise
        return (
            np.array([nz.bias_forward_init, nz.bias_yaw_init]),
            np.sqrt(self.config.bias_block) * np.array([nz.bias_forward_walk, nz.bias_yaw_walk]),
        )

    def _bias_range(self) -> tuple[int, int] | None:
        """The first and last bias block the whole graph has, or None (no bias states)."""
        if not (self.use_bias and self.config.bias_states):
            return None
        wheel_frames = [k for k in range(1, len(self.initial)) if self.records[k].wheel is not None]
        if not wheel_frames:
            return None
        return (wheel_frames[0] - 1) // self.config.bias_block, (wheel_frames[-1] - 1) // self.config.bias_block

    def _variables(self, bias_range: tuple[int, int] | None) -> FactorGraph:
        """A graph of the variables alone, at their starting values: every frame's online pose,
        each bias block from the online filter's estimate when it began (or the block's before
        it), and the building's axes if walls were seen."""
        graph = FactorGraph()
        for k in range(len(self.initial)):
            graph.add_pose(k, self.initial[k])
        if bias_range is not None:
            value = np.zeros(2)
            for b in range(bias_range[0], bias_range[1] + 1):
                value = self.bias_init.get(b, value)
                graph.add_bias(b, value)
        if self.walls:
            graph.add_axes(self.axes_initial)
        return graph

    def build_graph(self) -> FactorGraph:
        """The factor graph over every frame, from the online poses, held at the first one."""
        bias_range = self._bias_range()
        graph = self._variables(bias_range)
        self._add_factors(graph, 0, len(self.initial) - 1, bias_range)
        return graph

    def _add_factors(self, graph: FactorGraph, first: int, last: int, bias_range: tuple[int, int] | None) -> None:
        """The factors that belong to frames `first`..`last`: each frame's own factors (its step
        from the frame before, its scan to its anchor, its walls), the loops whose later frame it
        is, and the bias factors of the blocks that start there. Over consecutive ranges they are
        the whole graph's, in its order."""
        if first == 0:
            graph.prior_pose(0, self.initial[0], HELD_SIGMAS)
        for k in range(max(first, 1), last + 1):
            self._add_frame_factors(graph, k)
        if bias_range is not None:
            bb = self.config.bias_block
            b0, b1 = bias_range
            start, walk = self._bias_sigmas()
            if first <= bb * b0 + 1 <= last:  # the route's first block starts from no bias
                graph.prior_bias(b0, np.zeros(2), start)
            # Block b+1's walk from block b belongs to b+1's first frame.
            for b in range(max(b0, (first - 2) // bb), min(b1, (last - 1) // bb)):
                if first <= bb * (b + 1) + 1 <= last:
                    graph.bias_walk(b, b + 1, walk)
        for i, j, delta, info in self.loops:
            if first <= max(i, j) <= last:
                graph.between(i, j, delta, information=info, ridge=INFORMATION_RIDGE)
        for k, direction, sigma in self.walls:
            if first <= k <= last:
                graph.wall(k, direction, sigma)

    def _add_frame_factors(self, graph: FactorGraph, k: int, rec: FrameRecord | None = None) -> None:
        """Frame k's own factors: its step from frame k-1 (the wheels, corrected by their bias
        block's state or by the online filter's biases, or a constant-velocity step; the
        nonholonomic hold; the visual step) and its scan to its anchor. `rec`: frame k's record,
        if read already."""
        nz = self.noise
        rec = self.records[k] if rec is None else rec
        if rec.wheel is not None:
            sig = np.array(rec.wheel_sigmas, dtype=np.float64)
            sig[1] = min(sig[1], self.config.lateral_sigma)
            step = rec.wheel
            if self.use_bias and self.config.bias_states:
                graph.wheel(k - 1, k, step, sig, bias=(k - 1) // self.config.bias_block)
            else:
                # The step corrected by the online filter's biases: a plain GTSAM factor.
                b = rec.bias if (self.use_bias and rec.bias is not None) else np.zeros(2)
                corrected = WheelStep(
                    step.forward - (b[0] if step.moving else 0.0), step.lateral, step.yaw - b[1], step.moving
                )
                graph.wheel(k - 1, k, corrected, sig)
        elif rec.cv_step is not None:
            graph.between(k - 1, k, rec.cv_step, sigmas=np.array([nz.cv_forward, nz.cv_lateral, nz.cv_yaw]))
        if rec.wheel is None and self.config.nonholonomic_sigma > 0:
            # The step's twist (Logmap of the relative pose) has no sideways part: forward and
            # turn are left free (a std of 1 km and 1000 rad), only y is held.
            graph.between(k - 1, k, np.zeros(3), sigmas=np.array([1e3, self.config.nonholonomic_sigma, 1e3]))
        if rec.visual is not None:
            step, sigmas = rec.visual
            graph.between(k - 1, k, step, sigmas=sigmas)
        if rec.scan is not None:
            anchor, meas, info = rec.scan
            graph.between(anchor, k, meas, information=info, ridge=INFORMATION_RIDGE)


def _held_chunks(held: list[int], frames: int, length: int) -> list[tuple[int, int]]:
    """Consecutive chunks (first, last) over `frames` frames, each but the last ending at a held
    frame at least `length` frames after its start (the next one starts there), or at the route's
    end."""
    chunks = []
    first = 0
    for k in held:
        if k - first >= length and k < frames - 1:
            chunks.append((first, k))
            first = k
    if first < frames - 1 or not chunks:
        chunks.append((first, frames - 1))
    return chunks
