"""PoseGraph: loop closures correct drift; wrong closures are muted, visible and removable."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.pose_graphs import LOOP_SIGMAS, ODO_SIGMAS, as_array, drifting_odometry, square_route
from longslam.core.errors import InputError
from longslam.core.geometry import compose_xyyaw, planar_poses, pose_from_xyyaw, relative_xyyaw, xyyaw_from_pose
from longslam.slam.graph import PoseGraph


def build_graph(truth: np.ndarray) -> tuple[PoseGraph, np.ndarray]:
    deltas, odo = drifting_odometry(truth)
    graph = PoseGraph()
    for i, pose in enumerate(odo):
        graph.add_node(i, pose)
    for i, d in enumerate(deltas):
        graph.add_odometry(i, i + 1, d, ODO_SIGMAS)
    return graph, odo


def test_planar_helpers_round_trip():
    a, b = np.array([1.0, -2.0, 0.7]), np.array([3.0, 0.5, -2.9])
    delta = relative_xyyaw(a, b)
    np.testing.assert_allclose(compose_xyyaw(a, delta), b, atol=1e-12)
    expected = np.linalg.inv(pose_from_xyyaw(a)) @ pose_from_xyyaw(b)
    np.testing.assert_allclose(xyyaw_from_pose(expected), delta, atol=1e-12)
    many = np.array([a, b])
    np.testing.assert_allclose(xyyaw_from_pose(planar_poses(many)), many, atol=1e-12)


def test_correct_loop_closure_removes_drift():
    truth = square_route()
    graph, odo = build_graph(truth)
    last = len(truth) - 1
    graph.add_loop(last, 0, relative_xyyaw(truth[last], truth[0]), LOOP_SIGMAS, robust=False)
    est = as_array(graph.optimize(), len(truth))

    odo_err = np.linalg.norm(odo[last, :2] - truth[last, :2])
    est_err = np.linalg.norm(est[last, :2] - truth[last, :2])
    assert odo_err > 4.0
    assert est_err < 0.05 * odo_err
    # The whole trajectory improves, not only the closing node.
    assert np.linalg.norm(est[:, :2] - truth[:, :2], axis=1).mean() < 0.5 * np.linalg.norm(
        odo[:, :2] - truth[:, :2], axis=1
    ).mean()
    np.testing.assert_allclose(est[0], truth[0], atol=1e-6)  # first node held by the prior
    (err,) = graph.edge_errors()
    assert err.error < 3.0  # a consistent closure passes RTAB-Map's OptimizeMaxError test
    assert graph.counts() == {"nodes": 41, "odometry_edges": 40, "loop_edges": 1}


def test_wrong_robust_loop_barely_bends_graph_and_is_flagged():
    truth = square_route()
    graph, odo = build_graph(truth)
    base = as_array(graph.optimize(), len(truth))
    np.testing.assert_allclose(base, odo, atol=1e-6)  # odometry alone is already consistent

    # Claims the far corner (10, 10) is the start: a 14 m lie.
    wrong = graph.add_loop(20, 0, (0.0, 0.0, 0.0), LOOP_SIGMAS, robust=True)
    bent = as_array(graph.optimize(), len(truth))
    assert np.abs(bent[:, :2] - base[:, :2]).max() < 0.2
    worst = graph.max_edge_error()
    assert worst.edge_id == wrong and worst.error > 100.0

    graph.remove_edge(wrong)
    restored = as_array(graph.optimize(), len(truth))
    np.testing.assert_allclose(restored, base, atol=1e-6)
    assert graph.num_loops == 0 and graph.edge_errors() == []


def test_wrong_plain_loop_rejected_by_max_error_then_restored():
    truth = square_route()
    graph, _ = build_graph(truth)
    last = len(truth) - 1
    graph.add_loop(last, 0, relative_xyyaw(truth[last], truth[0]), LOOP_SIGMAS, robust=False)
    good = as_array(graph.optimize(), len(truth))

    wrong = graph.add_loop(20, 0, (0.0, 0.0, 0.0), LOOP_SIGMAS, robust=False)
    graph.optimize()
    rejected = [e.edge_id for e in graph.edge_errors() if max(e.translation_error, e.rotation_error) > 3.0]
    assert wrong in rejected
    graph.remove_edge(wrong)
    np.testing.assert_allclose(as_array(graph.optimize(), len(truth)), good, atol=1e-6)


def test_optimize_is_deterministic():
    truth = square_route()
    results = []
    for _ in range(2):
        graph, _ = build_graph(truth)
        graph.add_loop(40, 0, (0.0, 0.0, 0.0), LOOP_SIGMAS, robust=False)
        graph.add_loop(20, 0, (0.0, 0.0, 0.0), LOOP_SIGMAS, robust=True)
        results.append(as_array(graph.optimize(), len(truth)))
    np.testing.assert_array_equal(results[0], results[1])


def test_bad_input_is_named():
    graph = PoseGraph()
    graph.add_node(0, (0, 0, 0))
    with pytest.raises(InputError, match="node 1"):
        graph.add_odometry(0, 1, (1, 0, 0), ODO_SIGMAS)
    graph.add_node(1, (1, 0, 0))
    with pytest.raises(InputError, match="sigmas"):
        graph.add_loop(0, 1, (1, 0, 0), (0.1, 0.0, 0.1))
    graph.add_node(2, (2, 0, 0))
    graph.add_odometry(0, 1, (1, 0, 0), ODO_SIGMAS)
    with pytest.raises(InputError, match="not connected"):
        graph.optimize()
    with pytest.raises(InputError):
        graph.remove_edge(99)
    assert PoseGraph().optimize() == {}


def test_a_loop_tried_in_working_memory_moves_only_the_free_nodes_and_is_judged_there():
    """A loop try solved over the whole graph would cost time in proportion to the route.
    Tried with `free` nodes (RTAB-Map's working memory), only they move; the held nodes are the
    other ends of their edges."""
    truth = square_route()
    graph, odo = build_graph(truth)
    last = len(truth) - 1
    free = set(range(25, last + 1))  # the last side and a half: node 24 is held
    check = graph.try_loop(last, 0, relative_xyyaw(truth[last], truth[0]), sigmas=LOOP_SIGMAS, max_error=3.0,
                           free=free)
    assert not check.accepted  # 40 steps of drift pushed into 15 edges: not what the graph says
    np.testing.assert_array_equal(np.array([graph.estimate(i) for i in range(len(truth))]), odo)  # as before the try
    assert graph.num_loops == 0
    # A closure the free nodes can absorb: the truth's relative pose between 30 and 36 (6 steps
    # of drift) is kept, and the nodes before 25 stay exactly where they were.
    check = graph.try_loop(30, last, relative_xyyaw(truth[30], truth[last]), sigmas=(0.5, 0.5, 0.2), max_error=3.0,
                           free=free)
    assert check.accepted and graph.num_loops == 1
    est = np.array([graph.estimate(i) for i in range(len(truth))])
    np.testing.assert_array_equal(est[:25], odo[:25])
    assert np.abs(est[26:] - odo[26:]).max() > 1e-3
    # Every node free: the warm whole solve's answer, anchored at the first node's estimate.
    whole, _ = build_graph(truth)
    whole.add_loop(30, last, relative_xyyaw(truth[30], truth[last]), (0.5, 0.5, 0.2), robust=False)
    everywhere, _ = build_graph(truth)
    everywhere.add_loop(30, last, relative_xyyaw(truth[30], truth[last]), (0.5, 0.5, 0.2), robust=False)
    everywhere.optimize_local(range(len(truth)))
    np.testing.assert_allclose(np.array([everywhere.estimate(i) for i in range(len(truth))]),
                               as_array(whole.optimize(), len(truth)), atol=1e-6)


def test_kept_factors_and_connectivity_follow_the_edges_added_and_removed():
    """Each edge's factor is made once and the graph's connectivity kept as edges come, so a
    solve does not rebuild them. A removed edge's factor must leave the solve, and an edge
    whose removal splits the graph must make the next solve name the island."""
    truth = square_route()
    graph, _ = build_graph(truth)
    last = len(truth) - 1
    graph.optimize()
    wrong = graph.add_loop(last, 0, (3.0, 0.0, 0.5), LOOP_SIGMAS, robust=False)
    right = graph.add_loop(last, 0, (0.0, 0.0, 0.0), LOOP_SIGMAS, robust=False)
    with_wrong = as_array(graph.optimize(), len(truth))
    graph.remove_edge(wrong)
    without = as_array(graph.optimize(), len(truth))
    fresh, _ = build_graph(truth)
    fresh.add_loop(last, 0, (0.0, 0.0, 0.0), LOOP_SIGMAS, robust=False)
    np.testing.assert_array_equal(without, as_array(fresh.optimize(), len(truth)))
    assert np.abs(with_wrong - without).max() > 0.1  # the removed edge did pull the solve
    np.testing.assert_array_equal(graph.estimates([5, 0, last]), [graph.estimate(5), graph.estimate(0), graph.estimate(last)])
    # A node held by one edge, then that edge removed: an island.
    graph.add_node(100, (0.0, 5.0, 0.0))
    bridge = graph.add_odometry(0, 100, (0.0, 5.0, 0.0), ODO_SIGMAS)
    graph.optimize()
    graph.remove_edge(bridge)
    with pytest.raises(InputError, match=r"not connected.*\[100\]"):
        graph.optimize()
    graph.add_odometry(3, 100, (0.0, 5.0, 0.0), ODO_SIGMAS)
    graph.remove_edge(right)
    graph.optimize()  # connected again


def test_a_local_try_is_judged_on_the_edges_at_its_free_nodes_as_edge_errors_judges_them():
    """A local solve finds its edges through each node's edges and judges them in one
    numpy pass. Its verdict must be `edge_errors`' largest split error over exactly the edges at
    the free nodes, a removed edge left out."""
    truth = square_route()
    graph, _ = build_graph(truth)
    last = len(truth) - 1
    free = set(range(25, last + 1))
    removed = graph.add_loop(26, 38, relative_xyyaw(truth[26], truth[38]) + (0.3, 0.0, 0.0), LOOP_SIGMAS, robust=False)
    graph.remove_edge(removed)  # it would be the worst edge by far, were it still looked at
    check = graph.try_loop(30, last, relative_xyyaw(truth[30], truth[last]), sigmas=(0.5, 0.5, 0.2), max_error=3.0,
                           free=free)
    assert check.accepted
    at_free = [e for e in graph.edge_errors(None) if e.a in free or e.b in free]
    assert removed not in {e.edge_id for e in at_free} and len(at_free) == 17  # 16 steps and the loop
    expected = max(max(e.translation_error, e.rotation_error) for e in at_free)
    assert expected > 0.1
    assert check.error == pytest.approx(expected, rel=1e-9)
