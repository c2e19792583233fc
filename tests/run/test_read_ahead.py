"""Images decoded ahead on a second thread: same frames, same order, same errors."""

import threading

import numpy as np
import pytest

from longslam.core.errors import InputError
from longslam.core.frame import Frame, Intrinsics
from longslam.run.read_ahead import read_ahead

K = Intrinsics(4, 4, 4.0, 4.0, 2.0, 2.0)


def _frames(n, broken=None, loaded_by=None):
    def loader(i, kind):
        def load():
            if loaded_by is not None:
                loaded_by.append((i, kind, threading.current_thread().name))
            if i == broken:
                raise InputError(f"image {i} is corrupt")
            return np.full((4, 4), i, np.float32)
        return load
    return [Frame(i, 0.1 * i, loader(i, "rgb"), loader(i, "depth"), None, K) for i in range(n)]


def test_frames_come_in_order_with_their_images_decoded_on_another_thread():
    loads = []
    out = list(read_ahead(_frames(10, loaded_by=loads), ("depth",), ahead=3))
    assert [f.index for f in out] == list(range(10))
    assert all(float(f.depth[0, 0]) == f.index for f in out)
    assert {kind for _, kind, _ in loads} == {"depth"}  # rgb left to be read when used
    assert all(name.startswith("longslam-read") for _, _, name in loads)
    assert not isinstance(out[0]._rgb, np.ndarray)  # still lazy


def test_a_read_error_comes_with_its_frame_after_the_frames_before_it():
    seen = []
    with pytest.raises(InputError, match="image 5 is corrupt"):
        for frame in read_ahead(_frames(10, broken=5), ahead=2):
            seen.append(frame.index)
    assert seen == [0, 1, 2, 3, 4]


def test_methods_say_which_images_they_read_every_frame(tiny_sequence, tmp_path):
    from longslam.io.sequence import SequenceReader
    from longslam.slam.api import MethodContext
    from longslam.slam.catalog import create_method

    reader = SequenceReader(tiny_sequence)
    context = MethodContext(reader.intrinsics, reader.max_depth, str(tmp_path))
    wanted = {
        (name, frontend): tuple(getattr(create_method(name, context, {"frontend.mode": frontend}), "images_every_frame", ()))
        for name in ("keyframe", "submap") for frontend in ("wheel", "fused")
    }
    assert wanted[("keyframe", "wheel")] == ()  # nodes only: lazy reads
    assert wanted[("keyframe", "fused")] == ("rgb", "depth")
    assert wanted[("submap", "wheel")] == ("depth",)
    assert wanted[("submap", "fused")] == ("rgb", "depth")
