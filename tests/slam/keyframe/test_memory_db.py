"""The long-term memory database: round trips, reopening, and surviving a killed writer."""

import multiprocessing as mp
import os
import signal

import numpy as np
import pytest

from longslam.core.errors import InputError
from longslam.core.geometry import pose_from_xyyaw
from longslam.slam.keyframe.memory_db import MemoryDatabase


def _arrays(rng):
    return {"descriptors": rng.integers(0, 255, (50, 32), dtype=np.uint8), "points": rng.normal(size=(50, 3)).astype(np.float32)}


def test_nodes_links_and_statistics_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    path = tmp_path / "memory.db"
    stored = {}
    with MemoryDatabase(path) as db:
        for i in range(5):
            stored[i] = _arrays(rng)
            db.put_node(i, 0.1 * i, pose_from_xyyaw((i, 0, 0.1 * i)), pose_from_xyyaw((i, 0.1, 0.1 * i)), stored[i], weight=i)
        db.put_link(0, 1, "odometry", pose_from_xyyaw((1, 0, 0.1)), np.eye(3))
        db.put_link(4, 0, "loop", pose_from_xyyaw((-4, 0, -0.4)), np.eye(3) * 10)
        db.update_poses({2: pose_from_xyyaw((2.5, 0.5, 0.2))})
        db.set_statistics({"loops_accepted": 1})
    with MemoryDatabase(path) as db:  # reopened: everything is there
        assert db.node_ids() == [0, 1, 2, 3, 4]
        node = db.get_node(3)
        np.testing.assert_array_equal(node.arrays["descriptors"], stored[3]["descriptors"])
        np.testing.assert_allclose(node.odometry, pose_from_xyyaw((3, 0.1, 0.3)))
        np.testing.assert_allclose(db.get_node(2).pose, pose_from_xyyaw((2.5, 0.5, 0.2)))
        assert [(a, b) for a, b, _, _ in db.links("loop")] == [(4, 0)]
        assert db.statistics() == {"loops_accepted": 1}
        assert db.size_bytes() > 0
        with pytest.raises(KeyError):
            db.get_node(99)


def _writer(path, ready):
    rng = np.random.default_rng(1)
    db = MemoryDatabase(path)
    i = 0
    while True:
        db.put_node(i, float(i), np.eye(4), np.eye(4), _arrays(rng))
        if i == 20:
            ready.set()
        i += 1


def test_a_killed_writer_leaves_a_database_that_opens(tmp_path):
    path = tmp_path / "memory.db"
    ctx = mp.get_context("fork")
    ready = ctx.Event()
    proc = ctx.Process(target=_writer, args=(path, ready))
    proc.start()
    assert ready.wait(30)
    os.kill(proc.pid, signal.SIGKILL)
    proc.join()
    with MemoryDatabase(path) as db:
        ids = db.node_ids()
        assert len(ids) >= 21 and ids == list(range(len(ids)))
        db.get_node(ids[-1])  # the last committed node is whole


def test_not_a_database_is_a_clear_error(tmp_path):
    bad = tmp_path / "notes.db"
    bad.write_text("this is not sqlite " * 100)
    with pytest.raises(InputError, match="notes.db is not a longslam memory database"):
        MemoryDatabase(bad)
