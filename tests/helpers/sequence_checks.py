"""A check shared by the bag tests: two sequences the same, as a round trip must give them."""

from __future__ import annotations

import numpy as np

from longslam.io.sequence import SequenceReader


def assert_same_sequence(a: SequenceReader, b: SequenceReader) -> None:
    """Two sequences with the same stamps, camera, images and poses (to 1e-6 m): a round trip's test."""
    np.testing.assert_array_equal(a.timestamps, b.timestamps)
    assert a.intrinsics == b.intrinsics and a.max_depth == b.max_depth
    for i in range(len(a)):
        np.testing.assert_array_equal(a.read_rgb(i), b.read_rgb(i))
        np.testing.assert_array_equal(a.read_depth(i), b.read_depth(i))
    for x, y in ((a.odometry, b.odometry), (a.ground_truth, b.ground_truth)):
        np.testing.assert_array_equal(x.timestamps, y.timestamps)
        np.testing.assert_allclose(x.poses, y.poses, atol=1e-6, rtol=0)
