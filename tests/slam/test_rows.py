"""Per-frame rows in flat chunks (slam/rows.py)."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from longslam.slam.rows import Rows


def test_rows_come_back_as_appended_across_chunks():
    rng = np.random.default_rng(0)
    poses = rng.normal(size=(23, 4, 4))
    rows = Rows((4, 4), chunk=5)
    assert len(rows) == 0 and not rows and rows.array().shape == (0, 4, 4)
    for pose in poses:
        rows.append(pose)
    assert len(rows) == 23
    assert rows.array().tobytes() == poses.tobytes()
    stamps = Rows(chunk=4)
    for t in (0.1, 0.2, 1e9 + 0.05):
        stamps.append(t)
    assert stamps.array().tolist() == [0.1, 0.2, 1e9 + 0.05]


def test_a_pose_a_frame_costs_its_128_bytes_not_a_list_of_arrays():
    tracemalloc.start()
    try:
        rows = Rows((4, 4))
        for _ in range(20_000):
            rows.append(np.eye(4))
        held = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    # A list of (4, 4) arrays held about 320 bytes a frame (header, allocation, pointer).
    assert held < 20_000 * 150, f"{held / 20_000:.0f} bytes a pose"


def test_a_row_is_a_view_by_index_and_out_of_range_is_refused():
    rows = Rows((3,), chunk=2)
    for k in range(5):
        rows.append([k, k, k])
    assert rows.row(3).tolist() == [3, 3, 3] and rows.row(-1).tolist() == [4, 4, 4]
    rows.row(2)[1] = 9.0  # written through, as the frame store writes records back
    assert rows.array()[2].tolist() == [2, 9, 2]
    assert rows.nbytes == 3 * 2 * 3 * 8  # three whole chunks of two rows
    for k in (5, -6):
        with pytest.raises(IndexError, match="of 5"):
            rows.row(k)
