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


def test_work_is_done_on_each_frame_in_order_after_its_images_on_the_ahead_thread():
    done = []

    def work(frame):
        assert isinstance(frame._depth, np.ndarray)  # its images are decoded first
        done.append((frame.index, threading.current_thread().name))

    out = []
    for frame in read_ahead(_frames(8), ("depth",), ahead=2, work=work):
        assert frame.index in [i for i, _ in done]  # worked out before it is taken
        out.append(frame.index)
    assert out == [i for i, _ in done] == list(range(8))
    assert all(name.startswith("longslam-ahead") for _, name in done)


def test_an_error_of_the_work_comes_with_its_frame():
    def work(frame):
        if frame.index == 3:
            raise ValueError("frame 3 will not do")

    seen = []
    with pytest.raises(ValueError, match="frame 3 will not do"):
        for frame in read_ahead(_frames(8), ("depth",), ahead=2, work=work):
            seen.append(frame.index)
    assert seen == [0, 1, 2]


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


def _os_thread_name() -> str:
    return open(f"/proc/self/task/{threading.get_native_id()}/comm").read().strip()


@pytest.mark.skipif(not __import__("sys").platform.startswith("linux"), reason="thread names in /proc are Linux's")
def test_the_reading_thread_carries_its_name_in_proc_so_its_cpu_wait_is_told_apart():
    names = []
    frames = _frames(3)
    for frame in frames:
        frame._depth = (lambda: (names.append(_os_thread_name()), np.zeros((4, 4), np.float32))[1])
    list(read_ahead(frames, ("depth",), ahead=1))
    assert names == ["longslam-read"] * 3


class _Watcher:
    """A method that looks at every frame's depth and records which OS thread decoded it."""

    images_every_frame = ("depth",)

    def __init__(self, context, config):
        self.stamps = []

    def step(self, frame):
        self.stamps.append(frame.timestamp)
        frame.depth
        return np.eye(4)

    def finish(self):
        from longslam.core.trajectory import Trajectory
        from longslam.slam.api import Result

        trajectory = Trajectory(np.array(self.stamps), np.repeat(np.eye(4)[None], len(self.stamps), axis=0))
        return Result(trajectory, trajectory)


@pytest.mark.parametrize("real_time", [False, True])
def test_a_real_time_system_reads_its_own_frames_and_others_read_ahead(real_time, tiny_sequence, method_catalogue):
    from dataclasses import dataclass

    from longslam.io.sequence import SequenceReader
    from longslam.run.engine import run_frames
    from longslam.slam.api import MethodContext, MethodSpec
    from longslam.slam.catalog import choose_method

    @dataclass(frozen=True)
    class NoConfig:
        pass

    method_catalogue.register("watcher", MethodSpec("watcher", NoConfig, _Watcher, "for tests", real_time=real_time))
    reader = SequenceReader(tiny_sequence)
    readers = []
    frames = list(reader)
    for frame in frames:
        load = frame._depth
        frame._depth = (lambda load=load: (readers.append(threading.current_thread().name), load())[1])
    run_frames(choose_method("watcher", {}), frames, MethodContext(reader.intrinsics, reader.max_depth), progress=False)
    assert len(readers) == len(frames)
    if real_time:
        assert set(readers) == {threading.current_thread().name}
    else:
        assert all(name.startswith("longslam-read") for name in readers)


class _ThreadCounter(_Watcher):
    """A method that records the size of OpenCV's thread pool at each step, in `pools` (the test's list)."""

    pools: list[int] = []

    def step(self, frame):
        import cv2

        self.pools.append(cv2.getNumThreads())
        return super().step(frame)


@pytest.mark.parametrize("threads", [1, 2])
def test_a_runs_opencv_pool_has_the_cores_its_method_declares_and_is_put_back(threads, tiny_sequence, method_catalogue):
    import cv2
    from dataclasses import dataclass

    from longslam.io.sequence import SequenceReader
    from longslam.run.engine import run_frames
    from longslam.slam.api import MethodContext, MethodSpec
    from longslam.slam.catalog import choose_method

    @dataclass(frozen=True)
    class NoConfig:
        pass

    pools = _ThreadCounter.pools = []
    method_catalogue.register("counter", MethodSpec("counter", NoConfig, _ThreadCounter, "for tests", threads=threads))
    reader = SequenceReader(tiny_sequence)
    before = cv2.getNumThreads()
    cv2.setNumThreads(3)
    try:
        run_frames(choose_method("counter", {}), reader, MethodContext(reader.intrinsics, reader.max_depth), progress=False)
        assert pools and set(pools) == {threads}
        assert cv2.getNumThreads() == 3
    finally:
        cv2.setNumThreads(before)
