"""A method's work ahead (`work_ahead`, on the read-ahead thread) gives the numbers its step would
have computed itself: the same poses and trajectory with it and without, at exact depth, at a
Kinect's noise (depth trusted to a range) and at a D435's (tracked with its noise, so not ahead);
and no frame is tracked twice: ahead where the step is behind, else in the step."""

import threading

import numpy as np
import pytest

from longslam.core.frame import Frame
from longslam.io.sequence import SequenceReader
from longslam.run.read_ahead import WORK_THREAD_NAME, read_ahead
from longslam.sim.routes import get_route
from longslam.slam.api import MethodContext, ahead_work
from longslam.slam.catalog import create_method
from longslam.slam.frontend import FrontEndConfig
from longslam.slam.frontend.ahead import AheadWorker
from longslam.slam.frontend.visual import CornerTracker

pytestmark = pytest.mark.slow  # runs both methods on a rendered route

FRAMES = 60
# Inverse-depth noise sigma_w (1/m): none, a Kinect v1's, a D435's (docs/sensors.md).
NOISE = {"exact": 0.0, "kinect": 1.7e-3, "d435": 1e-2}


@pytest.fixture(scope="module")
def demo(rendered):
    return SequenceReader(rendered(get_route("demo"), "large", 0))


def _frames(reader, sigma_w):
    """The route's first frames, with depth noise drawn once (so both runs see the same images)."""
    rng = np.random.default_rng(7)
    frames = []
    for frame in list(reader)[:FRAMES]:
        depth = np.asarray(frame.depth, dtype=np.float64)
        if sigma_w:
            hit = depth > 0
            depth[hit] = 1.0 / np.maximum(1.0 / depth[hit] + sigma_w * rng.standard_normal(hit.sum()), 1e-3)
        frames.append(Frame(frame.index, frame.timestamp, frame.rgb, depth.astype(np.float32), frame.odometry, frame.intrinsics))
    return frames


def _run(name, reader, frames, threaded):
    method = create_method(name, MethodContext(reader.intrinsics, reader.max_depth, None), {})
    fed = read_ahead(frames, method.images_every_frame, work=ahead_work(method)) if threaded else frames
    poses = [method.step(frame) for frame in fed]
    return method, np.array(poses), method.finish()


def _record_threads(monkeypatch, owner, names):
    """The name of the thread of every call of `owner`'s methods `names`, in one list."""
    threads = []
    for name in names:
        real = getattr(owner, name)

        def recorded(self, *args, real=real, **kwargs):
            threads.append(threading.current_thread().name)
            return real(self, *args, **kwargs)

        monkeypatch.setattr(owner, name, recorded)
    return threads


@pytest.fixture()
def corner_threads(monkeypatch):
    """The name of the thread of every corner tracking."""
    return _record_threads(monkeypatch, CornerTracker, ["__call__"])


@pytest.mark.parametrize("name", ["keyframe", "submap"])
@pytest.mark.parametrize("noise", list(NOISE))
def test_work_ahead_gives_the_step_its_own_numbers(demo, name, noise, corner_threads):
    frames = _frames(demo, NOISE[noise])
    _, alone, result_alone = _run(name, demo, frames, threaded=False)
    here = threading.current_thread().name
    assert corner_threads and all(t == here for t in corner_threads)
    corner_threads.clear()
    method, ahead, result_ahead = _run(name, demo, frames, threaded=True)
    assert np.array_equal(alone, ahead)
    assert np.array_equal(result_alone.trajectory.poses, result_ahead.trajectory.poses)
    if name == "submap":
        assert np.array_equal(result_alone.cloud, result_ahead.cloud)
        assert not method._ahead_points  # every frame's points taken by its step
    assert not method.frontend._ahead._done  # every frame's work taken by its step
    worked = [t for t in corner_threads if t.startswith(WORK_THREAD_NAME)]
    if noise == "d435":
        # Tracked with its noise, in the step's own masks: nothing tracked ahead.
        assert not worked
    else:
        # Every frame after the first tracked once: ahead, or by the step where it caught up.
        assert len(corner_threads) == FRAMES - 1


def test_a_frame_without_work_ahead_is_worked_out_by_the_step(demo, corner_threads):
    """Work ahead of one frame in three: the others' steps track themselves, and the tracks ahead of
    a frame whose previous frame was not worked out are not the step's (they start elsewhere)."""
    frames = _frames(demo, 0.0)
    _, alone, _ = _run("submap", demo, frames, threaded=False)
    method = create_method("submap", MethodContext(demo.intrinsics, demo.max_depth, None), {})
    poses = []
    for frame in frames:
        if frame.index % 3 == 0:
            method.work_ahead(frame)
        poses.append(method.step(frame))
    assert np.array_equal(alone, np.array(poses))


def test_work_ahead_without_wheel_odometry(demo, corner_threads):
    """Without odometry the step is fitted from the tracks alone (RANSAC): the same poses."""
    frames = [Frame(f.index, f.timestamp, f.rgb, f.depth, None, f.intrinsics) for f in _frames(demo, NOISE["kinect"])]
    _, alone, _ = _run("submap", demo, frames, threaded=False)
    corner_threads.clear()
    _, ahead, _ = _run("submap", demo, frames, threaded=True)
    assert np.array_equal(alone, ahead)
    assert len(corner_threads) == FRAMES - 1


def test_the_tracking_is_left_to_a_step_that_caught_up(demo):
    """A frame's corners are tracked ahead while the step is behind, and left to the step once it
    has taken the frame before (it then waits for this one): the threads share the tracking."""
    config = FrontEndConfig()
    worker = AheadWorker(demo.intrinsics, config.depth_trust, config.visual_tracking)
    frames = _frames(demo, 0.0)[:4]
    assert not worker.work(frames[0]).visual.tracked  # no frame before it
    second = worker.work(frames[1])  # nothing stepped yet
    assert second.visual.tracked and second.previous == 0 and second.visual.tracks is not None
    # Its tracks start at frame 0: a step whose previous frame was another does not use them.
    assert second.visual_after(0) is second.visual
    assert not second.visual_after(7).tracked and second.visual_after(7).gray is second.visual.gray
    worker.stepped = 0  # the step took frame 0: frame 2 is still two frames ahead of it
    assert worker.work(frames[2]).visual.tracked
    worker.stepped = 2  # the step took frame 2 and waits for frame 3
    fourth = worker.work(frames[3])
    assert not fourth.visual.tracked and fourth.visual.tracks is None and fourth.previous is None
