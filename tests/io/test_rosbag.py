"""ROS bags: export and import round trips (ROS 1 and ROS 2), a bag written by hand with rosbags'
own writer as a robot would record it, the odometry covariance, and the errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.typesys import Stores, get_types_from_msg, get_typestore  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from helpers.sequence_checks import assert_same_sequence  # noqa: E402
from helpers.tiny_sequences import write_bag_sequence, write_tiny_sequence  # noqa: E402
from longslam.cli.main import main  # noqa: E402
from longslam.core.errors import InputError  # noqa: E402
from longslam.core.geometry import base_to_camera, planar_poses  # noqa: E402
from longslam.io.rosbag.conventions import ODOM_TOPIC  # noqa: E402
from longslam.io.rosbag.export import export_sequence  # noqa: E402
from longslam.io.rosbag.import_ import Topics, import_bag  # noqa: E402
from longslam.io.rosbag.messages import typestore_for  # noqa: E402
from longslam.io.sequence import SequenceReader  # noqa: E402
from longslam.io.trajectory_files import read_tum  # noqa: E402
from longslam.run.scored_run import run_named  # noqa: E402
from longslam.run.folder import TRAJECTORY  # noqa: E402
from longslam.run.score import score  # noqa: E402
from longslam.core.odometry_noise import get_noise  # noqa: E402
from longslam.sim.noise import apply_noise  # noqa: E402


@pytest.fixture(scope="module")
def sequence(tmp_path_factory) -> Path:
    """A tiny sequence that turns, with noise level 'large' in its meta.json."""
    return write_bag_sequence(tmp_path_factory.mktemp("bags") / "seq")


@pytest.mark.parametrize("fmt, name, storage", [("ros2", "bag", "sqlite3"), ("ros2", "bag", "mcap"), ("ros1", "seq.bag", "sqlite3")])
def test_round_trip_gives_the_same_sequence(sequence, tmp_path, fmt, name, storage):
    bag = tmp_path / name
    summary = export_sequence(sequence, bag, fmt=fmt, storage=storage)
    assert summary.frames == 24 and summary.bytes > 0
    assert [p.name for p in tmp_path.iterdir()] == [name]  # no partial left behind
    imported = import_bag(bag, tmp_path / "back")
    assert imported.frames == 24 and imported.notes == []
    a, b = SequenceReader(sequence), SequenceReader(tmp_path / "back")
    assert_same_sequence(a, b)
    assert b.meta["noise"] == "large" and b.meta["imported_from"] == str(bag.resolve())


def test_a_method_gives_the_same_metrics_after_the_round_trip(sequence, tmp_path):
    export_sequence(sequence, tmp_path / "bag")
    import_bag(tmp_path / "bag", tmp_path / "back")
    scores = []
    for seq in (sequence, tmp_path / "back"):
        run_named("keyframe", seq, tmp_path / f"run-{seq.name}", {"frontend.mode": "wheel"}, progress=False)
        truth = SequenceReader(seq).ground_truth
        scores.append(score(truth, read_tum(tmp_path / f"run-{seq.name}" / TRAJECTORY)))
    assert scores[0] == scores[1]
    assert scores[0]["ate"] > 0.001  # the odometry's 5 % scale error shows: the comparison means something


def test_16_bit_millimetre_depth_and_compression(sequence, tmp_path):
    export_sequence(sequence, tmp_path / "mm.bag", fmt="ros1", depth_encoding="16UC1", compress=True)
    import_bag(tmp_path / "mm.bag", tmp_path / "back")
    a, b = SequenceReader(sequence), SequenceReader(tmp_path / "back")
    for i in range(len(a)):
        np.testing.assert_allclose(a.read_depth(i), b.read_depth(i), atol=0.0005 + 1e-6)  # whole millimetres
        np.testing.assert_array_equal(a.read_rgb(i), b.read_rgb(i))


def test_odometry_covariance_is_the_noise_models_per_step_variance(sequence, tmp_path):
    from rosbags.highlevel import AnyReader

    export_sequence(sequence, tmp_path / "bag")
    linear, yaw = get_noise("large").step_variances()
    assert linear == pytest.approx(0.0075**2) and yaw == pytest.approx(np.radians(0.015) ** 2)
    with AnyReader([tmp_path / "bag"]) as reader:
        conns = [c for c in reader.connections if c.topic == ODOM_TOPIC]
        messages = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    assert len(messages) == 24
    cov = messages[5].pose.covariance.reshape(6, 6)
    assert cov[0, 0] == pytest.approx(linear) and cov[5, 5] == pytest.approx(yaw)
    assert np.all(np.diag(cov)[1:5] > 0) and np.all(np.diag(cov)[1:5] < 1e-8)
    # twist: the velocity's variance, per step / dt^2 (frames 0.1 s apart)
    twist = messages[5].twist.covariance.reshape(6, 6)
    assert twist[0, 0] == pytest.approx(linear / 0.01) and twist[5, 5] == pytest.approx(yaw / 0.01)
    assert messages[5].child_frame_id == "base_link" and messages[5].header.frame_id == "odom"
    # base_link sits on the floor under the camera: z = 0 while the odometry camera is at 1.25 m
    assert messages[5].pose.pose.position.z == pytest.approx(0.0, abs=1e-9)


def test_the_noise_models_step_error_has_the_stated_variance():
    # One step's forward error is the bias in force; over many redraw periods its variance is
    # the model's. 0.15 m steps at 10 Hz, 2000 periods of 10 s.
    noise = get_noise("xlarge")
    n = 200_001
    stamps = 0.1 * np.arange(n)
    xyyaw = np.column_stack([0.15 * np.arange(n), np.zeros(n), np.zeros(n)])
    noisy = apply_noise(noise, stamps, xyyaw, np.random.default_rng(7))
    steps = np.diff(noisy[:, :2], axis=0)
    heading = noisy[:-1, 2]
    forward = np.cos(heading) * steps[:, 0] + np.sin(heading) * steps[:, 1]
    forward_error = forward - 0.15
    yaw_error = np.diff(np.unwrap(noisy[:, 2]))
    linear, yaw = noise.step_variances()
    assert np.var(forward_error) == pytest.approx(linear, rel=0.1)
    assert np.var(yaw_error) == pytest.approx(yaw, rel=0.1)
    # 1 s (10 steps) inside one 10 s period: the bias adds up coherently, 10^2 times a step's
    # variance (what the twist covariance gives a 1 Hz link), not 10 times
    one_second = forward_error[: (n - 1) // 100 * 100].reshape(-1, 10, 10)[:, 3, :].sum(axis=1)
    assert np.var(one_second) == pytest.approx(100 * linear, rel=0.1)


# --- a bag as a robot records it, written with rosbags' own writer ----------------------------

FX, FY, CX, CY = 20.0, 21.0, 15.5, 11.5
W, H = 32, 24


def _header(ts, t_ns, frame):
    T = ts.types
    return T["std_msgs/msg/Header"](seq=0, stamp=T["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id=frame)


def _tf(ts, parent, child, pose, t_ns):
    T = ts.types
    q = Rotation.from_matrix(pose[:3, :3]).as_quat()
    return T["geometry_msgs/msg/TransformStamped"](
        header=_header(ts, t_ns, parent), child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=pose[0, 3], y=pose[1, 3], z=pose[2, 3]),
            rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])))


def _pose(ts, pose):
    T = ts.types
    q = Rotation.from_matrix(pose[:3, :3]).as_quat()
    return T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=pose[0, 3], y=pose[1, 3], z=pose[2, 3]),
                                       orientation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]))


def write_robot_bag(path: Path, depth_shift_s: float = 0.004, with_static_tf: bool = True, with_camera_info: bool = True):
    """A ROS 1 bag as a wheeled robot with a Kinect-like camera records it: bgr8 colour at 10 Hz,
    16UC1 depth 4 ms later, CameraInfo, wheel odometry at 50 Hz (odom -> base_footprint), the
    camera two static links up (base_footprint -> camera_link -> camera_rgb_optical_frame), and
    a PoseStamped ground truth of base_footprint. Returns what the import should give."""
    ts = get_typestore(Stores.ROS1_NOETIC)
    ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms\n", "tf2_msgs/msg/TFMessage"))
    T = ts.types
    rng = np.random.default_rng(3)
    t0 = 1_700_000_000 * 10**9
    n, rate = 12, 10
    frame_ns = [t0 + k * 10**9 // rate for k in range(n)]

    def robot(t_ns):  # drives forward 0.5 m/s while turning 0.3 rad/s
        s = (t_ns - t0) / 1e9
        return np.array([0.5 * s, 0.1 * s * s, 0.3 * s])

    link = np.eye(4)
    link[:3, 3] = (0.2, 0.0, 0.9)  # camera_link in base_footprint
    optical = np.eye(4)
    optical[:3, :3] = base_to_camera(0.0)[:3, :3]  # optical frame in camera_link: z forward, x right
    rgbs, depths = [], []
    with Writer1(path) as bag:
        c_rgb = bag.add_connection("/camera/rgb/image_color", "sensor_msgs/msg/Image", typestore=ts)
        c_depth = bag.add_connection("/camera/depth_registered/image_raw", "sensor_msgs/msg/Image", typestore=ts)
        c_info = (bag.add_connection("/camera/rgb/camera_info", "sensor_msgs/msg/CameraInfo", typestore=ts)
                  if with_camera_info else None)
        c_odom = bag.add_connection("/wheel_odom", "nav_msgs/msg/Odometry", typestore=ts)
        c_gt = bag.add_connection("/mocap/pose", "geometry_msgs/msg/PoseStamped", typestore=ts)
        c_static = bag.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=ts, latching=1)
        if with_static_tf:
            msg = T["tf2_msgs/msg/TFMessage"](transforms=[_tf(ts, "base_footprint", "camera_link", link, t0),
                                                          _tf(ts, "camera_link", "camera_rgb_optical_frame", optical, t0)])
            bag.write(c_static, t0, ts.serialize_ros1(msg, "tf2_msgs/msg/TFMessage"))
        for k in range(5 * n):  # odometry at 50 Hz from t0
            t_ns = t0 + k * 10**9 // 50
            pose = planar_poses(robot(t_ns)[None])[0]
            zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
            msg = T["nav_msgs/msg/Odometry"](
                header=_header(ts, t_ns, "odom"), child_frame_id="base_footprint",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=_pose(ts, pose), covariance=np.zeros(36)),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)))
            bag.write(c_odom, t_ns, ts.serialize_ros1(msg, "nav_msgs/msg/Odometry"))
        for t_ns in frame_ns:
            rgb = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
            depth_mm = rng.integers(400, 6000, (H, W)).astype(np.uint16)
            depth_mm[0, :5] = 0
            rgbs.append(rgb)
            depths.append(depth_mm)
            bgr = np.ascontiguousarray(rgb[..., ::-1])
            img = T["sensor_msgs/msg/Image"](header=_header(ts, t_ns, "camera_rgb_optical_frame"), height=H, width=W,
                                             encoding="bgr8", is_bigendian=0, step=3 * W, data=bgr.reshape(-1))
            bag.write(c_rgb, t_ns, ts.serialize_ros1(img, "sensor_msgs/msg/Image"))
            d_ns = t_ns + int(depth_shift_s * 1e9)
            dimg = T["sensor_msgs/msg/Image"](header=_header(ts, d_ns, "camera_rgb_optical_frame"), height=H, width=W,
                                              encoding="16UC1", is_bigendian=0, step=2 * W, data=depth_mm.reshape(-1).view(np.uint8))
            bag.write(c_depth, d_ns, ts.serialize_ros1(dimg, "sensor_msgs/msg/Image"))
            roi = T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
            info = T["sensor_msgs/msg/CameraInfo"](
                header=_header(ts, t_ns, "camera_rgb_optical_frame"), height=H, width=W, distortion_model="plumb_bob",
                D=np.zeros(5), K=np.array([FX, 0, CX, 0, FY, CY, 0, 0, 1.0]), R=np.eye(3).reshape(-1),
                P=np.array([FX, 0, CX, 0, 0, FY, CY, 0, 0, 0, 1.0, 0]), binning_x=0, binning_y=0, roi=roi)
            if c_info is not None:
                bag.write(c_info, t_ns, ts.serialize_ros1(info, "sensor_msgs/msg/CameraInfo"))
            gt = T["geometry_msgs/msg/PoseStamped"](header=_header(ts, t_ns + 1_000_000, "world"),
                                                    pose=_pose(ts, planar_poses(robot(t_ns + 1_000_000)[None])[0]))
            bag.write(c_gt, t_ns + 1_000_000, ts.serialize_ros1(gt, "geometry_msgs/msg/PoseStamped"))
    camera_in_base = link @ optical
    expected_odometry = np.array([planar_poses(robot(t)[None])[0] @ camera_in_base for t in frame_ns])
    return np.array(frame_ns) / 1e9, rgbs, depths, expected_odometry


def test_import_a_bag_written_by_hand(tmp_path):
    stamps, rgbs, depths, odometry = write_robot_bag(tmp_path / "robot.bag")
    summary = import_bag(tmp_path / "robot.bag", tmp_path / "seq", Topics(groundtruth="/mocap/pose"))
    assert summary.topics == Topics("/camera/rgb/image_color", "/camera/depth_registered/image_raw",
                                    "/camera/rgb/camera_info", "/wheel_odom", "/mocap/pose")
    seq = SequenceReader(tmp_path / "seq")
    assert len(seq) == 12 and seq.intrinsics.fx == FX and seq.intrinsics.cy == CY and seq.intrinsics.width == W
    np.testing.assert_allclose(seq.timestamps, stamps, atol=1e-6)
    for i in range(12):
        np.testing.assert_array_equal(seq.read_rgb(i), rgbs[i])  # bgr8 turned into RGB
        np.testing.assert_allclose(seq.read_depth(i), depths[i] / 1000.0, atol=1e-6)  # mm -> m, 0 kept
    # odometry interpolated from 50 Hz to the frames, in the camera's optical frame via two static links
    np.testing.assert_allclose(seq.odometry.poses, odometry, atol=1e-6)
    assert seq.odometry.poses[0][2, 3] == pytest.approx(0.9)
    # ground truth of base_footprint at its own stamps, carried to the camera the same way
    assert len(seq.ground_truth) == 12
    np.testing.assert_allclose(seq.ground_truth.timestamps, stamps + 0.001, atol=1e-6)
    np.testing.assert_allclose(seq.ground_truth.poses[0][:3, 3], odometry[0][:3, 3] + [0.0005, 0, 0], atol=1e-4)
    # and a method runs on it
    measurements = run_named("odometry", tmp_path / "seq", tmp_path / "run", progress=False)
    assert measurements.frames == 12


def test_import_errors_are_clear(tmp_path):
    write_robot_bag(tmp_path / "robot.bag")
    with pytest.raises(InputError, match=r"--odom /nope: no such topic in .*robot.bag; its topics: .*/wheel_odom \(nav_msgs/msg/Odometry\)"):
        import_bag(tmp_path / "robot.bag", tmp_path / "a", Topics(odom="/nope"))
    with pytest.raises(InputError, match=r"--rgb /wheel_odom holds nav_msgs/msg/Odometry; expected sensor_msgs/msg/Image"):
        import_bag(tmp_path / "robot.bag", tmp_path / "a", Topics(rgb="/wheel_odom"))
    write_robot_bag(tmp_path / "late.bag", depth_shift_s=0.05)  # half a frame: nothing pairs
    with pytest.raises(InputError, match=r"no colour image on /camera/rgb/image_color has a depth image .* within 0.02 s.*cannot be synchronised"):
        import_bag(tmp_path / "late.bag", tmp_path / "a")
    write_robot_bag(tmp_path / "notf.bag", with_static_tf=False)
    with pytest.raises(InputError, match=r"no TF path from 'base_footprint' to 'camera_rgb_optical_frame'"):
        import_bag(tmp_path / "notf.bag", tmp_path / "a")
    with pytest.raises(InputError, match="does not exist"):
        import_bag(tmp_path / "nowhere.bag", tmp_path / "a")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["late.bag", "notf.bag", "robot.bag"]


def test_export_errors_are_clear(sequence, tmp_path):
    with pytest.raises(InputError, match="ROS 1 bag is one file ending in .bag"):
        export_sequence(sequence, tmp_path / "x", fmt="ros1")
    with pytest.raises(InputError, match="--format 'ros3'"):
        export_sequence(sequence, tmp_path / "x", fmt="ros3")
    (tmp_path / "x").mkdir()
    with pytest.raises(InputError, match="exists already"):
        export_sequence(sequence, tmp_path / "x")
    bare = write_tiny_sequence(tmp_path / "bare", n=3)[0]  # odometry, but no noise level in meta.json
    with pytest.raises(InputError, match=r"names no noise level.*--odom-noise"):
        export_sequence(bare, tmp_path / "y")
    export_sequence(bare, tmp_path / "y", odom_noise="small")


def test_cli_export_and_import(sequence, tmp_path, capsys):
    assert main(["export", str(sequence), "--format", "ros1", "--out", str(tmp_path / "s.bag")]) == 0
    out = capsys.readouterr().out
    assert "24 frames" in out and f"forward {0.0075**2:.3g} m^2" in out
    assert main(["import", str(tmp_path / "s.bag"), "--out", str(tmp_path / "back")]) == 0
    assert "24 frames" in capsys.readouterr().out
    assert main(["import", str(tmp_path / "s.bag"), "--out", str(tmp_path / "back2"), "--depth", "/none"]) == 2
    assert "--depth /none: no such topic" in capsys.readouterr().err
    assert typestore_for("ros1").types["tf2_msgs/msg/TFMessage"]  # the ROS 1 store gets tf2_msgs
    np.testing.assert_allclose(SequenceReader(tmp_path / "back").odometry.poses, SequenceReader(sequence).odometry.poses, atol=1e-6)


def test_tf_buffer_chains_and_interpolates():
    from longslam.io.rosbag.tf import TfBuffer

    tf = TfBuffer("test", max_gap_ns=10**9)
    mount = base_to_camera(1.0)
    tf.add("base", "camera", mount, 0, static=True)
    for k, x in enumerate((0.0, 1.0)):  # odom -> base moves 1 m and turns 90 degrees in 0.5 s
        pose = planar_poses(np.array([[x, 0.0, k * np.pi / 2]]))[0]
        tf.add("odom", "base", pose, k * 500_000_000, static=False)
    np.testing.assert_allclose(tf.lookup("base", "camera", 123), mount)  # static only: any stamp
    mid = tf.lookup("odom", "camera", 250_000_000)
    np.testing.assert_allclose(mid, planar_poses(np.array([[0.5, 0.0, np.pi / 4]]))[0] @ mount, atol=1e-12)
    np.testing.assert_allclose(tf.lookup("camera", "odom", 250_000_000), np.linalg.inv(mid), atol=1e-12)
    with pytest.raises(InputError, match=r"no TF path from 'odom' to 'map'.*frames seen: base, camera, odom"):
        tf.lookup("odom", "map", 0)
    with pytest.raises(InputError, match=r"TF odom -> base.*gap|no pose near t=5"):
        tf.lookup("odom", "camera", 5 * 10**9)
    with pytest.raises(InputError, match="more than one parent"):
        tf.add("map", "base", mount, 0, static=True)


def test_import_of_a_bag_without_camera_info_takes_the_intrinsics_given(tmp_path, capsys):
    write_robot_bag(tmp_path / "robot.bag", with_camera_info=False)
    out = tmp_path / "seq"
    assert main(["import", str(tmp_path / "robot.bag"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "no sensor_msgs/CameraInfo topic" in err and "--intrinsics fx,fy,cx,cy" in err and not out.exists()
    assert main(["import", str(tmp_path / "robot.bag"), "--out", str(out), "--intrinsics", f"{FX},{FY},{CX},{CY}"]) == 0
    assert "camera from --intrinsics" in capsys.readouterr().out
    seq = SequenceReader(out)
    assert (seq.intrinsics.width, seq.intrinsics.height, seq.intrinsics.fx, seq.intrinsics.cy) == (W, H, FX, CY)
    for bad, needle in (("1,2,3", "expected fx,fy,cx,cy"), ("-1,2,3,4", "fx and fy positive")):
        assert main(["import", str(tmp_path / "robot.bag"), "--out", str(tmp_path / "bad"), "--intrinsics", bad]) == 2
        assert needle in capsys.readouterr().err and not (tmp_path / "bad").exists()
