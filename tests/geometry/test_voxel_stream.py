"""The streaming voxel filter against the batch one it replaces (geometry/voxel_stream.py)."""

from __future__ import annotations

import numpy as np
import pytest

from longslam.core.geometry.cells import average_3d
from longslam.core.geometry.voxel_stream import VoxelStream


def batch(parts: list[np.ndarray], voxel: float) -> np.ndarray:
    """What the keyframe method's finish did before: every batch at once, then the filter."""
    return average_3d(np.concatenate(parts).astype(np.float64), voxel).astype(np.float32)


def batches(rng: np.random.Generator, n: int, low: float, high: float) -> list[np.ndarray]:
    """Batches of float32 points of varying size; neighbouring batches overlap in space, as a
    route's nodes do, so that many voxels get points from several batches."""
    sizes = rng.integers(0, 3000, n)
    sizes[3] = 0  # an empty batch (a node whose depth had no returns)
    return [rng.uniform(low, high, (size, 3)).astype(np.float32) for size in sizes]


@pytest.mark.parametrize("slab_voxels, buffer_points", [(64, 1 << 18), (3, 500), (1, 1)])
def test_streamed_cloud_equals_the_batch_filter_to_the_bit(tmp_path, slab_voxels, buffer_points):
    rng = np.random.default_rng(4)
    # Negative and positive x across many slabs; a coarse voxel puts ~20 points in each.
    parts = batches(rng, 40, -7.3, 5.1)
    voxel = 0.4
    with VoxelStream(voxel, tmp_path, slab_voxels=slab_voxels, buffer_points=buffer_points) as stream:
        for part in parts:
            stream.add(part)
        streamed = stream.result()
    expected = batch(parts, voxel)
    assert streamed.dtype == np.float32 and streamed.shape == expected.shape
    assert streamed.tobytes() == expected.tobytes()
    assert stream.points_added == sum(len(p) for p in parts)
    assert not list(tmp_path.iterdir()), "the scratch folder outlived the stream"


def test_no_points_give_an_empty_float32_cloud(tmp_path):
    with VoxelStream(0.05, tmp_path) as stream:
        stream.add(np.zeros((0, 3), np.float32))
        cloud = stream.result()
    assert cloud.shape == (0, 3) and cloud.dtype == np.float32


def test_the_stream_is_filtered_once(tmp_path):
    with VoxelStream(0.05, tmp_path) as stream:
        stream.add(np.ones((2, 3), np.float32))
        stream.result()
        with pytest.raises(RuntimeError, match="twice"):
            stream.result()
        with pytest.raises(RuntimeError, match="after result"):
            stream.add(np.ones((2, 3), np.float32))


@pytest.mark.parametrize("kwargs, words", [({"voxel": 0.0}, "voxel must be > 0"), ({"voxel": 0.1, "slab_voxels": 0}, "slab_voxels")])
def test_bad_settings_are_named(tmp_path, kwargs, words):
    with pytest.raises(ValueError, match=words):
        VoxelStream(scratch_dir=tmp_path, **kwargs)
