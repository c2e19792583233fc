"""The front end's batch smoother: our Levenberg-Marquardt loop against GTSAM's own optimizer."""

from dataclasses import replace

import gtsam
import numpy as np
import pytest

from longslam.core.geometry import compose_xyyaw as compose
from longslam.core.geometry import relative_xyyaw as relative
from longslam.slam.frontend.filter import MotionNoise
from longslam.slam.frontend.smoother import FullSmoother, SmootherConfig
from longslam.slam.graph.factors import FactorGraph, WheelStep


def _smoother(frames: int = 80, seed: int = 3) -> tuple[FullSmoother, np.ndarray]:
    """Wheels with a forward and a yaw bias on a curving path, scans tying every fifth frame to
    the truth, and one loop: the problem the front end hands over at the end of a run."""
    rng = np.random.default_rng(seed)
    truth = [np.zeros(3)]
    for k in range(1, frames):
        truth.append(compose(truth[-1], np.array([0.15, 0.0, 0.02 * np.sin(k / 9.0)])))
    truth = np.array(truth)
    noise = MotionNoise()
    smoother = FullSmoother(noise, SmootherConfig(relative_tolerance=1e-9, iterations=100))
    odometry = truth[0].copy()
    bias = np.array([0.004, 0.0008])
    for k in range(frames):
        wheel = sigmas = scan = None
        if k:
            step = relative(truth[k - 1], truth[k])
            measured = step + np.array([bias[0], 0.0, bias[1]]) + rng.normal(0, [0.002, 0.0, 0.0003])
            wheel = WheelStep(float(measured[0]), float(measured[1]), float(measured[2]), True)
            sigmas = np.array([0.0045, 1e-3, 0.0006])
            odometry = compose(odometry, measured)
            if k % 5 == 0:
                scan = (k - 5, relative(truth[k - 5], truth[k]) + rng.normal(0, 0.01, 3), np.diag([400.0, 400.0, 900.0]))
        smoother.add_frame(odometry.copy(), wheel, sigmas, None, scan, np.zeros(2))
    smoother.add_loop(2, frames - 3, relative(truth[2], truth[frames - 3]), np.diag([100.0, 100.0, 400.0]))
    return smoother, truth


def test_our_optimizer_reaches_gtsams_levenberg_marquardt_minimum():
    smoother, truth = _smoother()
    ours = smoother.solve()
    built = smoother.build_graph()
    graph, values = built.graph, built.values
    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(1e-9)
    params.setMaxIterations(100)
    theirs = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    theirs = np.array([[p.x(), p.y(), p.theta()] for p in (theirs.atPose2(gtsam.symbol("x", k)) for k in range(len(truth)))])
    assert np.abs(ours - theirs).max() < 1e-6
    # and the biases were worth estimating: far closer to the truth than the odometry
    odometry = np.array(smoother.initial)
    assert np.linalg.norm(ours[:, :2] - truth[:, :2], axis=1).max() < 0.2 * np.linalg.norm(odometry[:, :2] - truth[:, :2], axis=1).max()


@pytest.mark.slow
def test_a_part_nothing_anchors_is_damped_not_fatal():
    # No wheel step from frame 40 to 41, no scan or loop across: frames 41.. float free, Gauss-
    # Newton's system is singular (GTSAM raises IndeterminateLinearSystemException); damped
    # steps solve it, as GTSAM's Levenberg-Marquardt would.
    smoother, truth = _smoother()
    smoother.records[41] = replace(smoother.records[41], wheel=None)
    smoother.loops.clear()
    for k, rec in enumerate(smoother.records):
        if rec.scan is not None and rec.scan[0] <= 40 < k:
            smoother.records[k] = replace(rec, scan=None)
    built = smoother.build_graph()
    graph, values = built.graph, built.values
    try:
        graph.linearize(values).optimize()
        singular = False
    except RuntimeError:
        singular = True
    assert singular
    out = smoother.solve()
    assert np.isfinite(out).all() and smoother.iterations >= 1
    assert np.linalg.norm(out[:41, :2] - truth[:41, :2], axis=1).max() < 0.1
    # the free part is placed anywhere (only the damping holds it), but its shape is solved:
    # the biases correct it as they correct the anchored part
    last = len(truth) - 1
    shape_error = relative(out[41], out[last]) - relative(truth[41], truth[last])
    initial = np.array(smoother.initial)
    odometry_error = relative(initial[41], initial[last]) - relative(truth[41], truth[last])
    assert np.linalg.norm(shape_error[:2]) < 0.6 * np.linalg.norm(odometry_error[:2])
    # as GTSAM's Levenberg-Marquardt shapes it
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(100)
    theirs = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    a, b = (theirs.atPose2(gtsam.symbol("x", k)) for k in (41, last))
    theirs_shape = relative(np.array([a.x(), a.y(), a.theta()]), np.array([b.x(), b.y(), b.theta()]))
    assert np.linalg.norm(relative(out[41], out[last])[:2] - theirs_shape[:2]) < 0.02


def _long_smoother(window: int, frames: int = 400) -> tuple[FullSmoother, np.ndarray]:
    """`_smoother`'s problem over more frames, with loops that cross windows, solved in windows
    of at most `window` frames (0: whole)."""
    smoother, truth = _smoother(frames)
    smoother.config = SmootherConfig(relative_tolerance=1e-9, iterations=100, window=window, whole_frames=0)
    for i, j in ((frames // 4, 3 * frames // 4), (3 * frames // 8, 19 * frames // 20), (20, 60)):
        smoother.add_loop(i, j, relative(truth[i], truth[j]), np.diag([100.0, 100.0, 400.0]))
    return smoother, truth


@pytest.mark.slow  # solves a 230- or 400-frame route's smoother several times over (10-30 s)
def test_a_route_longer_than_the_window_is_solved_window_by_window_to_the_whole_solve():
    # A hard case for windows: the online poses are the raw biased wheels (the front end's are
    # already corrected by its filter), and only the loops across windows show the heading bias.
    whole, truth = _long_smoother(window=0)
    windowed, _ = _long_smoother(window=100)
    linearised = []
    add_factors = windowed._add_factors

    def counted(graph, *args):
        add_factors(graph, *args)
        linearised.append(len(graph.graph.keyVector()))

    windowed._add_factors = counted
    full, parts = whole.solve(), windowed.solve()
    # No part's graph holds much more than one window's poses and bias blocks (plus the frames
    # and blocks it shares with the others).
    assert max(linearised) <= 100 + 100 // 10 + 12, max(linearised)
    # The same steps as the whole graph's: the same result but for rounding.
    assert windowed.iterations == whole.iterations
    assert np.abs(parts - full).max() < 1e-6, np.abs(parts - full).max()
    error = lambda xy: np.linalg.norm(xy[:, :2] - truth[:, :2], axis=1)  # noqa: E731
    assert error(full).mean() < 0.02 * error(np.array(whole.initial)).mean()


def test_the_windows_parts_are_the_whole_graph():
    smoother, _ = _long_smoother(window=100, frames=230)
    smoother.add_wall(150, 0.1, 0.01)
    smoother.axes_initial = 0.05
    whole = smoother.build_graph()
    bias_range = smoother._bias_range()
    values = smoother._variables(bias_range).values
    parts = []
    for a in (0, 100, 200):
        part = FactorGraph()
        smoother._add_factors(part, a, min(a + 100, 230) - 1, bias_range)
        parts.append(part.graph)
    assert sum(part.size() for part in parts) == whole.graph.size()
    assert values.keys() == whole.values.keys()
    assert np.isclose(sum(part.error(whole.values) for part in parts), whole.graph.error(whole.values), rtol=1e-12)


def test_a_route_within_the_window_is_solved_whole():
    within, _ = _long_smoother(window=120, frames=120)
    whole, _ = _long_smoother(window=0, frames=120)
    assert np.array_equal(within.solve(), whole.solve())


@pytest.mark.slow  # solves a 230- or 400-frame route's smoother several times over (10-30 s)
def test_a_route_of_up_to_whole_frames_is_solved_whole_and_a_longer_one_in_windows():
    import dataclasses

    short, _ = _long_smoother(window=100, frames=230)
    short.config = dataclasses.replace(short.config, whole_frames=230)
    whole, _ = _long_smoother(window=0, frames=230)
    assert np.array_equal(short.solve(), whole.solve())
    longer, _ = _long_smoother(window=100, frames=230)
    longer.config = dataclasses.replace(longer.config, whole_frames=229)
    windowed = longer.solve()
    assert not np.array_equal(windowed, whole.solve())  # another sum order: the windows' steps
    assert np.abs(windowed - whole.solve()).max() < 1e-6


def test_a_window_too_small_for_the_bias_blocks_is_refused():
    import pytest

    from longslam.core.errors import InputError

    with pytest.raises(InputError, match="smoother.window"):
        SmootherConfig(window=5)


def test_the_frame_store_gives_back_what_it_was_given_in_a_fraction_of_the_objects_memory():
    from longslam.slam.frontend.frame_store import CHUNK, FrameRecord, FrameStore

    store = FrameStore()
    rng = np.random.default_rng(0)
    given = []
    for k in range(CHUNK + 5):  # across a chunk's end
        record = FrameRecord(
            WheelStep(*rng.normal(size=3), bool(k % 2)) if k % 3 else None,
            rng.normal(size=3) if k % 3 else None, rng.normal(size=3) if k % 3 == 0 else None,
            (k - 1, rng.normal(size=3), rng.normal(size=(3, 3))) if k % 4 else None,
            (rng.normal(size=3), rng.normal(size=3)) if k % 5 else None, rng.normal(size=2) if k % 2 else None)
        store.append(rng.normal(size=3), record)
        given.append(record)
    for k in (0, 1, 2, 3, CHUNK - 1, CHUNK, CHUNK + 4):
        back, record = store[k], given[k]
        assert back.wheel == record.wheel
        for name in ("wheel_sigmas", "cv_step", "bias"):
            a, b = getattr(back, name), getattr(record, name)
            assert (a is None) == (b is None) and (a is None or np.array_equal(a, b))
        assert (back.scan is None) == (record.scan is None)
        if record.scan is not None:
            assert back.scan[0] == record.scan[0] and all(np.array_equal(x, y) for x, y in zip(back.scan[1:], record.scan[1:]))
        assert (back.visual is None) == (record.visual is None)
    assert np.asarray(store.poses).shape == (CHUNK + 5, 3)
    assert store.nbytes <= 2 * CHUNK * 40 * 8  # 320 bytes a frame, in whole chunks


def test_without_wheels_a_nonholonomic_hold_takes_the_sideways_scatter_out_of_the_steps():
    # Visual steps only (no wheels), their sideways part scattered by 1 cm a frame, as tracked
    # corners give; the truth drives arcs (as the simulator's follower does), whose twists have no
    # sideways part.
    rng = np.random.default_rng(5)
    frames = 120
    truth = [np.zeros(3)]
    for k in range(1, frames):
        arc = gtsam.Pose2.Expmap(np.array([0.15, 0.0, 0.03 * np.sin(k / 15.0)]))
        truth.append(compose(truth[-1], np.array([arc.x(), arc.y(), arc.theta()])))
    truth = np.array(truth)

    def solved(hold: float) -> np.ndarray:
        smoother = FullSmoother(MotionNoise(), SmootherConfig(nonholonomic_sigma=hold, relative_tolerance=1e-9), use_bias=False)
        online = truth[0].copy()
        for k in range(frames):
            visual = None
            if k:
                step = relative(truth[k - 1], truth[k]) + rng.normal(0, [0.002, 0.01, 0.0005])
                online = compose(online, step)
                visual = (step, np.array([0.01, 0.02, 0.002]))
            smoother.add_frame(online.copy(), None, None, None, None, None, visual)
        return smoother.solve()

    def sideways(poses: np.ndarray) -> np.ndarray:  # each step's twist, y part (m)
        return np.array([gtsam.Pose2.Logmap(gtsam.Pose2(*relative(a, b)))[1] for a, b in zip(poses[:-1], poses[1:])])

    free, held = solved(0.0), solved(1e-3)
    assert np.abs(sideways(truth)).max() < 1e-9
    assert np.abs(sideways(free)).mean() > 0.003  # the scatter stays without the hold
    assert np.abs(sideways(held)).mean() < 0.1 * np.abs(sideways(free)).mean()


@pytest.fixture(scope="module")
def whole_and_nodes() -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """`_long_smoother`'s problem solved whole, and the "graph nodes" a method would hand over:
    every tenth frame and the loops' frames at the whole solve's poses."""
    whole, _ = _long_smoother(window=0)
    full = whole.solve()
    nodes = set(range(0, len(full), 10)) | {f for i, j, _, _ in whole.loops for f in (i, j)}
    return full, {k: full[k] for k in sorted(nodes)}


@pytest.mark.slow  # solves a long route's smoother whole for its fixture (4 s)
def test_with_the_nodes_held_the_frames_between_come_out_where_the_whole_solve_puts_them(whole_and_nodes):
    full, held = whole_and_nodes
    smoother, _ = _long_smoother(window=100)
    smoother.config = replace(smoother.config, hold_nodes_beyond=0)
    built = []
    add_chunk = smoother._add_held_chunk

    def counted(graph, first, last, *args):
        add_chunk(graph, first, last, *args)
        built.append(len(graph.dims))

    smoother._add_held_chunk = counted
    out = smoother.solve(held)
    assert smoother.solved_by == "held nodes"
    # Chunk by chunk: no graph much larger than one window's poses and bias blocks.
    assert len(built) >= 3 and max(built) <= 100 + 10 + 100 // 10 + 4, built
    nodes = sorted(held)
    assert np.abs(out[nodes] - full[nodes]).max() < 1e-6  # held where given
    # Between the nodes each frame's own factors put it where the whole solve did; only the
    # biases carried from chunk to chunk differ (measured: 26 um, 0.0004 deg).
    assert np.abs(out[:, :2] - full[:, :2]).max() < 1e-4, np.abs(out[:, :2] - full[:, :2]).max()
    assert np.abs(out[:, 2] - full[:, 2]).max() < 3e-5, np.abs(out[:, 2] - full[:, 2]).max()


def test_the_frames_between_held_nodes_follow_the_nodes_not_the_online_poses():
    # Nodes held at the truth (a perfect graph): the frames between come out near the truth
    # though the online poses are the raw biased wheels, metres off by the end.
    smoother, truth = _long_smoother(window=100)
    smoother.config = replace(smoother.config, hold_nodes_beyond=0)
    out = smoother.solve({k: truth[k] for k in range(0, len(truth), 10)})
    online = np.linalg.norm(np.array(smoother.initial)[:, :2] - truth[:, :2], axis=1)
    error = np.linalg.norm(out[:, :2] - truth[:, :2], axis=1)
    assert online.max() > 1.0, online.max()
    assert error.max() < 0.01, error.max()


@pytest.mark.slow  # solves a 230- or 400-frame route's smoother several times over (10-30 s)
def test_a_route_up_to_hold_nodes_beyond_is_solved_over_every_frame_though_nodes_are_given():
    smoother, truth = _long_smoother(window=100, frames=230)
    held = {k: truth[k] for k in range(0, 230, 10)}
    smoother.config = replace(smoother.config, hold_nodes_beyond=230)
    assert np.array_equal(smoother.solve(held), _long_smoother(window=100, frames=230)[0].solve())
    assert smoother.solved_by == "every frame"
    smoother.config = replace(smoother.config, hold_nodes_beyond=229)
    smoother.solve(held)
    assert smoother.solved_by == "held nodes"


def test_walls_between_held_nodes_hold_headings_against_the_held_axes():
    # Walls at every frame of the second half, along axes at 0.05 rad: each chunk takes its own.
    smoother, truth = _long_smoother(window=100)
    smoother.config = replace(smoother.config, hold_nodes_beyond=0)
    held = {k: truth[k] for k in range(0, len(truth), 50)}
    plain = smoother.solve(held)
    smoother.axes_initial = 0.05
    for k in range(len(truth) - 1, len(truth) // 2, -1):  # out of order: the solve sorts them
        smoother.add_wall(k, 0.05 - truth[k, 2], 0.001)
    walled = smoother.solve(held)
    second = slice(len(truth) // 2 + 1, None)
    assert np.abs(walled[second, 2] - truth[second, 2]).max() < 0.5 * np.abs(plain[second, 2] - truth[second, 2]).max()
    assert np.array_equal(walled[: len(truth) // 2 - 50], plain[: len(truth) // 2 - 50])  # chunks before the walls as they were
