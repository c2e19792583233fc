"""Wheel odometry's jump filter: a corrupt step is dropped, the motion of frames lost in between is not."""

import numpy as np

from longslam.core.geometry import camera_poses_from_planar
from longslam.core.geometry.planar import CameraMount, JumpFilteredOdometry

MOUNT = CameraMount(1.25)


def _camera(x: float, y: float, yaw: float) -> np.ndarray:
    return camera_poses_from_planar(np.array([[x, y, yaw]]), 1.25)[0]


def test_a_turn_too_big_for_one_frame_is_a_jump():
    wheels = JumpFilteredOdometry(MOUNT, jump_distance=1.0, jump_angle=0.8)
    wheels.update(_camera(0, 0, 0), 0.0)
    wheels.update(_camera(0.1, 0, 0), 0.1)
    pose = wheels.update(_camera(0.2, 0, 1.2), 0.2)  # 1.2 rad in 0.1 s
    assert wheels.jumps == 1
    np.testing.assert_allclose(pose, [0.1, 0.0, 0.0], atol=1e-9)


def test_the_same_turn_after_lost_frames_is_motion():
    wheels = JumpFilteredOdometry(MOUNT, jump_distance=1.0, jump_angle=0.8)
    wheels.update(_camera(0, 0, 0), 0.0)
    wheels.update(_camera(0.1, 0, 0), 0.1)
    pose = wheels.update(_camera(1.8, 0, 1.2), 2.1)  # 2 s of frames lost: 1.7 m and 1.2 rad
    assert wheels.jumps == 0
    np.testing.assert_allclose(pose, [1.8, 0.0, 1.2], atol=1e-9)
    # Without timestamps every step is one frame's.
    untimed = JumpFilteredOdometry(MOUNT, jump_distance=1.0, jump_angle=0.8)
    for camera in (_camera(0, 0, 0), _camera(0.1, 0, 0), _camera(1.8, 0, 1.2)):
        untimed.update(camera)
    assert untimed.jumps == 1


def test_the_period_is_the_shortest_interval_so_a_lost_second_frame_does_not_count_gaps_short():
    wheels = JumpFilteredOdometry(MOUNT, jump_distance=1.0, jump_angle=0.8)
    wheels.update(_camera(0, 0, 0), 0.0)
    wheels.update(_camera(0.2, 0, 0), 0.2)  # the frame at 0.1 s was lost
    wheels.update(_camera(0.3, 0, 0), 0.3)
    pose = wheels.update(_camera(2.8, 0, 0), 0.6)  # two frames lost: three periods, 2.5 m
    assert wheels.jumps == 0
    np.testing.assert_allclose(pose, [2.8, 0.0, 0.0], atol=1e-9)
