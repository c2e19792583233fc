"""Sequences on disk in the TUM RGB-D layout: write, read back, derive, and read real TUM folders."""

from __future__ import annotations

import json
import os

import cv2
import numpy as np
import pytest

import longslam
from longslam.core.errors import InputError
from longslam.core.frame import Frame, Intrinsics
from longslam.core.geometry import camera_poses_from_planar
from longslam.io.sequence import SequenceReader, SequenceWriter, derive_sequence
from longslam.core.timestamps import associate_lists
from longslam.core.trajectory import Trajectory

W, H, N = 32, 24, 20
INTR = Intrinsics.from_fov(W, H, 90.0)
META = {"world": "test", "route": "loop", "noise_level": "small", "seed": 3}


def make_data(seed: int = 0):
    rng = np.random.default_rng(seed)
    stamps = 1000.0 + 0.1 * np.arange(N)
    rgbs = rng.integers(0, 256, size=(N, H, W, 3), dtype=np.uint8)
    depths = rng.uniform(0.3, 8.0, size=(N, H, W)).astype(np.float32)
    depths[rng.random(size=depths.shape) < 0.2] = 0.0
    xyyaw = np.column_stack([np.linspace(0, 2, N), np.linspace(0, 1, N), np.linspace(0, 1.5, N)])
    gt = Trajectory(stamps, camera_poses_from_planar(xyyaw, 1.25))
    noisy = xyyaw + rng.normal(0, 0.05, size=xyyaw.shape)
    odom = Trajectory(stamps, camera_poses_from_planar(noisy, 1.25))
    return stamps, rgbs, depths, gt, odom


def write_sequence(path, data, **kwargs):
    stamps, rgbs, depths, gt, odom = data
    with SequenceWriter(path, INTR, max_depth=8.0, meta=META, **kwargs) as writer:
        for t, rgb, depth in zip(stamps, rgbs, depths):
            writer.add(t, rgb, depth)
        writer.set_ground_truth(gt)
        writer.set_odometry(odom)


def leftovers(folder):
    return sorted(p.name for p in folder.iterdir())


def test_round_trip(tmp_path):
    data = make_data()
    stamps, rgbs, depths, gt, odom = data
    seq = tmp_path / "seq"
    write_sequence(seq, data)
    assert leftovers(tmp_path) == ["seq"]
    for name in ("rgb.txt", "depth.txt", "groundtruth.txt", "odometry.txt", "camera.json", "meta.json"):
        assert (seq / name).is_file()
    assert (seq / "rgb" / "1000.000000.png").is_file()
    assert (seq / "depth" / "1000.100000.png").is_file()
    raw = cv2.imread(str(seq / "depth" / "1000.000000.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16

    reader = SequenceReader(seq)
    assert len(reader) == N
    assert reader.intrinsics == INTR
    assert reader.depth_scale == 5000.0
    assert reader.max_depth == 8.0
    assert reader.meta == {**META, "longslam_version": longslam.__version__}
    np.testing.assert_allclose(reader.timestamps, stamps, atol=1e-6)
    np.testing.assert_allclose(reader.ground_truth.timestamps, gt.timestamps, atol=1e-9)
    np.testing.assert_allclose(reader.ground_truth.poses, gt.poses, atol=1e-8)
    np.testing.assert_allclose(reader.odometry.poses, odom.poses, atol=1e-8)

    frames = list(reader)
    assert len(frames) == N
    for i, frame in enumerate(frames):
        assert isinstance(frame, Frame)
        assert frame.index == i
        assert frame.timestamp == pytest.approx(stamps[i], abs=1e-6)
        assert frame.rgb.dtype == np.uint8 and frame.rgb.shape == (H, W, 3)
        np.testing.assert_array_equal(frame.rgb, rgbs[i])
        assert frame.depth.dtype == np.float32 and frame.depth.shape == (H, W)
        assert np.abs(frame.depth - depths[i]).max() <= 1.0 / 5000
        np.testing.assert_array_equal(frame.depth == 0, depths[i] == 0)
        np.testing.assert_allclose(frame.odometry, odom.poses[i], atol=1e-8)
        assert frame.intrinsics == INTR
    assert reader.frame(-1).index == N - 1
    with pytest.raises(IndexError):
        reader.frame(N)


def test_camera_json_fields(tmp_path):
    write_sequence(tmp_path / "seq", make_data())
    camera = json.loads((tmp_path / "seq" / "camera.json").read_text())
    assert set(camera) == {"width", "height", "fx", "fy", "cx", "cy", "depth_scale", "max_depth"}
    assert camera["depth_scale"] == 5000 and camera["max_depth"] == 8.0
    lines = (tmp_path / "seq" / "rgb.txt").read_text().splitlines()
    assert lines[0].startswith("#")
    assert "1000.100000 rgb/1000.100000.png" in lines


@pytest.mark.parametrize("interrupt", [RuntimeError, KeyboardInterrupt])
def test_exception_leaves_nothing(tmp_path, interrupt):
    stamps, rgbs, depths, _, _ = make_data()
    with pytest.raises(interrupt):
        with SequenceWriter(tmp_path / "seq", INTR, 8.0, META) as writer:
            writer.add(stamps[0], rgbs[0], depths[0])
            assert writer.temp_path.is_dir()
            raise interrupt("stop")
    assert leftovers(tmp_path) == []


def test_existing_path_refused_and_overwrite(tmp_path):
    seq = tmp_path / "seq"
    write_sequence(seq, make_data(0))
    with pytest.raises(InputError, match="exists already"):
        SequenceWriter(seq, INTR, 8.0, META)
    # overwrite: the old sequence stays whole until the new one is complete
    data = make_data(1)
    with pytest.raises(RuntimeError):
        with SequenceWriter(seq, INTR, 8.0, META, overwrite=True) as writer:
            writer.add(data[0][0], data[1][0], data[2][0])
            raise RuntimeError("stop")
    np.testing.assert_array_equal(SequenceReader(seq).frame(0).rgb, make_data(0)[1][0])
    write_sequence(seq, data, overwrite=True)
    np.testing.assert_array_equal(SequenceReader(seq).frame(0).rgb, data[1][0])
    assert leftovers(tmp_path) == ["seq"]


def test_writer_validates_frames(tmp_path):
    stamps, rgbs, depths, _, odom = make_data()
    with pytest.raises(InputError):
        with SequenceWriter(tmp_path / "seq", INTR, 8.0, META) as writer:
            with pytest.raises(InputError, match="rgb must have shape"):
                writer.add(0.0, rgbs[0][:, :-1], depths[0])
            with pytest.raises(InputError, match="rgb must be uint8"):
                writer.add(0.0, rgbs[0].astype(np.float32), depths[0])
            with pytest.raises(InputError, match="depth must be float32"):
                writer.add(0.0, rgbs[0], (depths[0] * 5000).astype(np.uint16))
            with pytest.raises(InputError, match="depth must have shape"):
                writer.add(0.0, rgbs[0], depths[0].T)
            with pytest.raises(InputError, match="NaN"):
                writer.add(0.0, rgbs[0], np.full((H, W), np.nan, np.float32))
            writer.add(1.0, rgbs[0], depths[0])
            with pytest.raises(InputError, match="strictly increasing"):
                writer.add(1.0000001, rgbs[1], depths[1])
            writer.set_odometry(odom)  # stamps far from 1.0: refused when the block ends
    assert leftovers(tmp_path) == []


def test_derive_sequence(tmp_path):
    data = make_data()
    stamps = data[0]
    source = tmp_path / "source"
    write_sequence(source, data)
    rng = np.random.default_rng(7)
    xyyaw = rng.normal(size=(N, 3))
    new_odom = Trajectory(stamps, camera_poses_from_planar(xyyaw, 1.25))
    meta = {**META, "noise_level": "large", "seed": 9}
    derived = tmp_path / "derived"
    derive_sequence(source, derived, new_odom, meta)
    assert leftovers(tmp_path) == ["derived", "source"]

    a, b = SequenceReader(source), SequenceReader(derived)
    assert b.meta["noise_level"] == "large" and b.meta["seed"] == 9
    assert a.meta["noise_level"] == "small"
    np.testing.assert_allclose(b.odometry.poses, new_odom.poses, atol=1e-8)
    np.testing.assert_allclose(b.ground_truth.poses, a.ground_truth.poses)
    assert b.intrinsics == a.intrinsics and b.max_depth == a.max_depth
    for i in range(N):
        fa, fb = a.frame(i), b.frame(i)
        np.testing.assert_array_equal(fa.rgb, fb.rgb)
        np.testing.assert_array_equal(fa.depth, fb.depth)
    try:
        os.link(source / "rgb.txt", tmp_path / "link_probe")
        links_work = True
        os.unlink(tmp_path / "link_probe")
    except OSError:
        links_work = False
    if links_work:
        for i in range(N):
            assert os.stat(a.rgb_path(i)).st_ino == os.stat(b.rgb_path(i)).st_ino
            assert os.stat(a.depth_path(i)).st_ino == os.stat(b.depth_path(i)).st_ino

    with pytest.raises(InputError, match="exists already"):
        derive_sequence(source, derived, new_odom, meta)
    derive_sequence(source, derived, new_odom, {"seed": 10}, overwrite=True)
    assert SequenceReader(derived).meta["seed"] == 10

    bad_odom = Trajectory(stamps[:5], new_odom.poses[:5])
    with pytest.raises(InputError, match="no pose within"):
        derive_sequence(source, tmp_path / "bad", bad_odom, meta)
    assert leftovers(tmp_path) == ["derived", "source"]


def make_tum_folder(folder, n=10, offset=0.01):
    """A real-TUM-style folder: 640-less small images, depth stamps offset, no extras."""
    rng = np.random.default_rng(1)
    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    rgb_stamps = 1305031102.175304 + 1 / 30 * np.arange(n)
    depth_stamps = rgb_stamps + offset
    rgb_lines = ["# color images", "# file: 'rgbd_dataset_freiburg1_xyz.bag'", "# timestamp filename"]
    depth_lines = ["# depth maps", "# file: 'rgbd_dataset_freiburg1_xyz.bag'", "# timestamp filename"]
    rgbs, depths = [], []
    for tr, td in zip(rgb_stamps, depth_stamps):
        rgb = rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8)
        raw = rng.integers(0, 40000, size=(H, W), dtype=np.uint16)
        raw[0, :] = 0
        cv2.imwrite(str(folder / "rgb" / f"{tr:.6f}.png"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        cv2.imwrite(str(folder / "depth" / f"{td:.6f}.png"), raw)
        rgb_lines.append(f"{tr:.6f} rgb/{tr:.6f}.png")
        depth_lines.append(f"{td:.6f} depth/{td:.6f}.png")
        rgbs.append(rgb)
        depths.append(raw.astype(np.float32) / 5000)
    # one extra depth image with no rgb partner, listed out of order
    extra = depth_stamps[-1] + 1.0
    cv2.imwrite(str(folder / "depth" / f"{extra:.6f}.png"), np.zeros((H, W), np.uint16))
    depth_lines.insert(3, f"{extra:.6f} depth/{extra:.6f}.png")
    (folder / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    (folder / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    return rgb_stamps, rgbs, depths


def test_read_real_tum_folder(tmp_path):
    folder = tmp_path / "rgbd_dataset_freiburg1_xyz"
    rgb_stamps, rgbs, depths = make_tum_folder(folder)
    # Freiburg 1's calibration is for 640 x 480 images: on these it is not guessed.
    with pytest.raises(InputError, match=r"freiburg1.*640 x 480.*32 x 24.*--intrinsics fx,fy,cx,cy"):
        SequenceReader(folder)
    reader = SequenceReader(folder, intrinsics="16,16,15.5,11.5")
    assert reader.intrinsics_source == "given (--intrinsics)"
    assert len(reader) == len(rgb_stamps)
    np.testing.assert_allclose(reader.timestamps, rgb_stamps, atol=1e-6)
    assert reader.ground_truth is None and reader.odometry is None
    assert reader.meta == {} and reader.max_depth is None and reader.depth_scale == 5000.0
    assert reader.intrinsics == Intrinsics(W, H, 16.0, 16.0, 15.5, 11.5)
    for i, frame in enumerate(reader):
        assert frame.odometry is None
        np.testing.assert_array_equal(frame.rgb, rgbs[i])
        np.testing.assert_allclose(frame.depth, depths[i], atol=1e-6)
        assert reader.depth_path(i).name == f"{rgb_stamps[i] + 0.01:.6f}.png"


def test_association_is_one_to_one():
    # two rgb stamps near one depth stamp: only the closer one gets it
    pairs = associate_lists([1.000, 1.015, 2.0], [1.012, 2.005, 5.0], max_diff=0.02)
    assert pairs == [(1, 0), (2, 1)]
    assert associate_lists([1.0], [1.5], max_diff=0.02) == []


def _associate_by_candidates(first, second, max_diff):
    """TUM's associate.py as written: every candidate a tuple, taken closest first."""
    candidates = sorted((abs(a - b), i, j) for i, a in enumerate(first) for j, b in enumerate(second)
                        if abs(a - b) <= max_diff)
    used_first, used_second, pairs = set(), set(), []
    for _, i, j in candidates:
        if i not in used_first and j not in used_second:
            used_first.add(i)
            used_second.add(j)
            pairs.append((i, j))
    return sorted(pairs, key=lambda p: (first[p[0]], p[0]))


def test_association_matches_associate_py_on_crowded_stamps():
    # Stamps on a coarse grid, so that many tie and many have several candidates.
    rng = np.random.default_rng(7)
    for _ in range(200):
        first = (rng.integers(0, 30, rng.integers(0, 25)) * 0.01).tolist()
        second = (rng.integers(0, 30, rng.integers(0, 25)) * 0.01).tolist()
        max_diff = float(rng.choice([0.0, 0.01, 0.025, 0.1]))
        assert associate_lists(first, second, max_diff) == _associate_by_candidates(first, second, max_diff)


def test_a_folder_without_camera_json_is_never_guessed(tmp_path):
    folder = tmp_path / "my_sequence"
    make_tum_folder(folder, n=2)
    with pytest.raises(InputError, match=r"my_sequence has no camera.json.*--intrinsics fx,fy,cx,cy.*camera.json"):
        SequenceReader(folder)
    for bad in ("1,2,3", "0,1,2,3", "nan,1,2,3", "a,b,c,d"):
        with pytest.raises(InputError, match="expected fx,fy,cx,cy"):
            SequenceReader(folder, intrinsics=bad)


@pytest.mark.parametrize("camera, expected", [(1, (517.3, 516.5, 318.6, 255.3)), (3, (535.4, 539.2, 320.1, 247.6))])
def test_a_freiburg_folder_gets_its_cameras_calibration(tmp_path, camera, expected):
    folder = tmp_path / f"rgbd_dataset_freiburg{camera}_desk"
    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    cv2.imwrite(str(folder / "rgb" / "1.0.png"), np.zeros((480, 640, 3), np.uint8))
    cv2.imwrite(str(folder / "depth" / "1.0.png"), np.zeros((480, 640), np.uint16))
    (folder / "rgb.txt").write_text("1.0 rgb/1.0.png\n")
    (folder / "depth.txt").write_text("1.0 depth/1.0.png\n")
    reader = SequenceReader(folder)
    assert reader.intrinsics == Intrinsics(640, 480, *expected)
    assert f"freiburg{camera}" in reader.intrinsics_source


def test_odometry_nearest_match_and_missing(tmp_path):
    folder = tmp_path / "tum"
    rgb_stamps, _, _ = make_tum_folder(folder, n=5)
    (folder / "camera.json").write_text(json.dumps({"width": W, "height": H, "fx": 16, "fy": 16, "cx": 16, "cy": 12}))
    poses = camera_poses_from_planar(np.zeros((5, 3)), 1.25)
    odom = Trajectory(rgb_stamps + 0.005, poses)
    from longslam.io.trajectory_files import write_tum

    write_tum(folder / "odometry.txt", odom)
    assert SequenceReader(folder).frame(2).odometry.shape == (4, 4)
    write_tum(folder / "odometry.txt", odom.subset(np.arange(4)))
    with pytest.raises(InputError, match=rf"odometry.txt.*t={rgb_stamps[4]:.6f}"):
        SequenceReader(folder)


def test_errors_name_the_file(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        SequenceReader(tmp_path / "nowhere")

    folder = tmp_path / "tum"
    rgb_stamps, _, _ = make_tum_folder(folder, n=5)
    (folder / "camera.json").write_text(json.dumps({"width": W, "height": H, "fx": 16, "fy": 16, "cx": 16, "cy": 12}))

    # missing image file
    missing = folder / "rgb" / f"{rgb_stamps[2]:.6f}.png"
    missing.rename(tmp_path / "aside.png")
    with pytest.raises(InputError, match=rf"{missing.name}.*does not exist"):
        SequenceReader(folder)
    (tmp_path / "aside.png").rename(missing)

    # unreadable image file
    original = missing.read_bytes()
    missing.write_bytes(b"not a png")
    with pytest.raises(InputError, match=rf"{missing.name}.*cannot be decoded"):
        SequenceReader(folder).frame(2).rgb  # images are read when first looked at
    missing.write_bytes(original)

    # malformed line, named file:line
    text = (folder / "depth.txt").read_text()
    (folder / "depth.txt").write_text(text + "12.5 depth/a.png extra\n")
    with pytest.raises(InputError, match=r"depth\.txt:10:"):
        SequenceReader(folder)
    (folder / "depth.txt").write_text(text + "abc depth/a.png\n")
    with pytest.raises(InputError, match=r"depth\.txt:10: timestamp 'abc'"):
        SequenceReader(folder)
    (folder / "depth.txt").write_text(text)

    # missing list
    (folder / "rgb.txt").rename(tmp_path / "rgb.txt")
    with pytest.raises(InputError, match=r"rgb\.txt does not exist"):
        SequenceReader(folder)
    (tmp_path / "rgb.txt").rename(folder / "rgb.txt")

    # bad camera.json field, and images that do not match camera.json
    camera = {"width": W, "height": H, "fx": "wide", "fy": 20, "cx": 16, "cy": 12}
    (folder / "camera.json").write_text(json.dumps(camera))
    with pytest.raises(InputError, match="camera.json"):
        SequenceReader(folder)
    camera.update(fx=20, depth_scale=-1)
    (folder / "camera.json").write_text(json.dumps(camera))
    with pytest.raises(InputError, match="camera.json: field depth_scale"):
        SequenceReader(folder)
    camera.update(depth_scale=5000, width=W * 2)
    (folder / "camera.json").write_text(json.dumps(camera))
    reader = SequenceReader(folder)
    with pytest.raises(InputError, match=rf"{rgb_stamps[0]:.6f}\.png is {W} x {H}.*camera\.json"):
        reader.frame(0).rgb
