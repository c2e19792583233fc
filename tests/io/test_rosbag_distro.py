"""Bags for a ROS 2 distribution (--distro), MCAP chunk compression, topic presets, the camera_link
frame and the ground truth on /tf; each bag read back by rosbags, by `longslam import` and by evo."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("rosbags")

from rosbags.highlevel import AnyReader  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from helpers.tiny_sequences import write_bag_sequence  # noqa: E402
from longslam.cli.main import main  # noqa: E402
from longslam.core.errors import InputError  # noqa: E402
from longslam.core.geometry import base_to_camera, invert  # noqa: E402
from longslam.io.rosbag.conventions import TOPIC_PRESETS  # noqa: E402
from longslam.io.rosbag.export import export_sequence  # noqa: E402
from longslam.io.rosbag.import_ import import_bag  # noqa: E402
from longslam.io.rosbag.messages import pose_matrix  # noqa: E402
from longslam.io.sequence import SequenceReader  # noqa: E402
from helpers.sequence_checks import assert_same_sequence  # noqa: E402

STORES = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY}


@pytest.fixture(scope="module")
def sequence(tmp_path_factory) -> Path:
    return write_bag_sequence(tmp_path_factory.mktemp("distro") / "seq")


def humble_reads(info: dict) -> None:
    """What Humble's rosbag2 (0.15, rosbag2_storage/src/rosbag2_storage/metadata_io.cpp and
    rosbag2_transport/src/rosbag2_transport/qos.cpp) asks of metadata.yaml: for version >= 4 a
    topic's offered_qos_profiles is read `as<std::string>()` and, when not empty, parsed as a
    list of QoS maps whose policies are read `as<int>()`."""
    assert info["version"] >= 5  # files, compression fields
    assert isinstance(info["storage_identifier"], str) and isinstance(info["message_count"], int)
    assert isinstance(info["duration"]["nanoseconds"], int)
    assert isinstance(info["starting_time"]["nanoseconds_since_epoch"], int)
    assert all(isinstance(p, str) for p in info["relative_file_paths"])
    assert isinstance(info["compression_format"], str) and isinstance(info["compression_mode"], str)
    for f in info["files"]:
        assert {"path", "starting_time", "duration", "message_count"} <= set(f)
    for topic in info["topics_with_message_count"]:
        qos = topic["topic_metadata"]["offered_qos_profiles"]
        assert isinstance(qos, str), f"{topic['topic_metadata']['name']}: offered_qos_profiles is not a string"
        for profile in yaml.safe_load(qos) or []:
            for policy in ("history", "reliability", "durability", "liveliness", "depth"):
                assert isinstance(profile[policy], int)
            for duration in ("deadline", "lifespan", "liveliness_lease_duration"):
                assert set(profile[duration]) == {"sec", "nsec"}


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
@pytest.mark.parametrize("distro, version", [("humble", 8), ("jazzy", 9)])
def test_a_bag_for_each_distro(sequence, tmp_path, distro, version, storage):
    bag = tmp_path / "bag"
    export_sequence(sequence, bag, storage=storage, distro=distro)
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == version and info["storage_identifier"] == storage
    if distro == "humble":
        humble_reads(info)
    else:  # version 9: QoS as a list of maps with named policies, which Humble cannot read
        static = next(t["topic_metadata"] for t in info["topics_with_message_count"] if t["topic_metadata"]["name"] == "/tf_static")
        assert static["offered_qos_profiles"][0]["durability"] == "transient_local"
    # the message definitions and hashes are the distro's
    store = get_typestore(STORES[distro])
    with AnyReader([bag]) as reader:
        assert len(reader.connections) == 9
        for c in reader.connections:
            assert c.msgdef.data == store.generate_msgdef(c.msgtype, ros_version=2)[0], c.topic
            assert c.digest == store.hash_rihs01(c.msgtype), c.topic
        meta = json.loads(next(reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages()
                               if c.topic == "/longslam/meta"))
    assert meta["distro"] == distro
    import_bag(bag, tmp_path / "back")  # and it reads back whole
    assert_same_sequence(SequenceReader(sequence), SequenceReader(tmp_path / "back"))


def test_the_default_distro_is_humble(sequence, tmp_path):
    export_sequence(sequence, tmp_path / "bag")
    assert yaml.safe_load((tmp_path / "bag/metadata.yaml").read_text())["rosbag2_bagfile_information"]["version"] == 8


def mcap_chunks(path: Path) -> tuple[list[dict], set[int]]:
    """The chunk records of an MCAP file (its format: magic, then opcode u8, length u64, content),
    and the opcodes of the records outside chunks."""
    data = path.read_bytes()
    assert data[:8] == b"\x89MCAP0\r\n" and data[-8:] == b"\x89MCAP0\r\n"
    chunks, outside, at = [], set(), 8
    while at < len(data) - 8:
        opcode, length = struct.unpack_from("<BQ", data, at)
        body = data[at + 9: at + 9 + length]
        if opcode == 0x06:  # Chunk: start u64, end u64, uncompressed size u64, crc u32, compression str, records
            _, _, size, _ = struct.unpack_from("<QQQI", body, 0)
            (name_len,) = struct.unpack_from("<I", body, 28)
            compression = body[32:32 + name_len].decode()
            (records_len,) = struct.unpack_from("<Q", body, 32 + name_len)
            chunks.append({"compression": compression, "uncompressed": size, "compressed": records_len})
        else:
            outside.add(opcode)
        at += 9 + length
    return chunks, outside


def test_mcap_compression_compresses_the_chunks(sequence, tmp_path):
    export_sequence(sequence, tmp_path / "plain", storage="mcap")
    export_sequence(sequence, tmp_path / "small", storage="mcap", compress=True)
    chunks, outside = mcap_chunks(tmp_path / "small/small.mcap")
    assert chunks and all(c["compression"] == "zstd" and c["compressed"] < c["uncompressed"] for c in chunks)
    assert 0x05 not in outside  # every message inside a (compressed) chunk
    plain, _ = mcap_chunks(tmp_path / "plain/plain.mcap")
    assert all(c["compression"] == "" for c in plain)
    # rosbag2 reads the chunks' compression from the file: none is named per message or per file
    info = yaml.safe_load((tmp_path / "small/metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["compression_mode"] == "" and info["compression_format"] == ""
    assert (tmp_path / "small/small.mcap").stat().st_size < 0.8 * (tmp_path / "plain/plain.mcap").stat().st_size
    import_bag(tmp_path / "small", tmp_path / "back")
    assert_same_sequence(SequenceReader(sequence), SequenceReader(tmp_path / "back"))


def tf_links(bag: Path) -> tuple[dict, dict]:
    """(/tf_static links, /tf links) as {(parent, child): [(stamp, 4x4), ...]}."""
    links: tuple[dict, dict] = ({}, {})
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic in ("/tf", "/tf_static")]
        for c, _, raw in reader.messages(connections=conns):
            for t in reader.deserialize(raw, c.msgtype).transforms:
                stamp = t.header.stamp.sec * 10**9 + t.header.stamp.nanosec
                pose = pose_matrix(t.transform.translation, t.transform.rotation, c.topic)
                links[c.topic == "/tf"].setdefault((t.header.frame_id, t.child_frame_id), []).append((stamp, pose))
    return links


@pytest.mark.parametrize("preset", ["default", "rtabmap", "realsense", "openni"])
def test_topic_presets_and_frames(sequence, tmp_path, preset):
    names = TOPIC_PRESETS[preset]
    bag = tmp_path / "bag"
    export_sequence(sequence, bag, storage="mcap", topics=preset)
    with AnyReader([bag]) as reader:
        topics = {c.topic for c in reader.connections}
        image = next(reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages() if c.topic == names.depth)
    assert {names.rgb, names.depth, names.camera_info, names.depth_info, "/odom", "/groundtruth", "/tf",
            "/tf_static"} <= topics
    assert image.header.frame_id == names.optical_frame
    static, moving = tf_links(bag)
    # base_link -> camera_link: upright, 1.25 m up (REP 103); camera_link -> optical: a rotation
    ((_, link),) = static[("base_link", "camera_link")]
    np.testing.assert_allclose(link, np.r_[np.c_[np.eye(3), [0, 0, 1.25]], [[0, 0, 0, 1]]], atol=1e-12)
    ((_, optical),) = static[("camera_link", names.optical_frame)]
    np.testing.assert_allclose(optical[:3, 3], 0.0, atol=1e-12)
    np.testing.assert_allclose(link @ optical, base_to_camera(1.25), atol=1e-9)
    assert set(moving) == {("odom", "base_link"), ("map", "gt_base_link")}
    # the ground truth on /tf: map -> gt_base_link, the true camera poses carried to base_link
    truth = SequenceReader(sequence).ground_truth
    stamps, poses = zip(*moving[("map", "gt_base_link")])
    np.testing.assert_array_equal(np.array(stamps) - 10**18, np.round(truth.timestamps * 1e9).astype(np.int64))
    np.testing.assert_allclose(np.array(poses), truth.poses @ invert(base_to_camera(1.25)), atol=1e-6)
    import_bag(bag, tmp_path / "back")  # the preset's names read back
    assert_same_sequence(SequenceReader(sequence), SequenceReader(tmp_path / "back"))


@pytest.mark.slow
def test_evo_reads_the_bag(sequence, tmp_path):
    # The venv's own evo (a test dependency): CI runs the tests without the venv on PATH.
    evo_traj = Path(sys.executable).with_name("evo_traj")
    if not evo_traj.is_file():
        pytest.skip("evo is not installed")
    export_sequence(sequence, tmp_path / "bag", topics="rtabmap")
    done = subprocess.run([str(evo_traj), "bag2", str(tmp_path / "bag"), "/odom", "/groundtruth", "--save_as_tum"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    truth = SequenceReader(sequence).ground_truth
    rows = np.loadtxt(tmp_path / "groundtruth.tum")
    assert len(rows) == len(truth)
    np.testing.assert_allclose(rows[:, 0] - 1e9, truth.timestamps, atol=1e-6)
    np.testing.assert_allclose(rows[:, 1:4], (truth.poses @ invert(base_to_camera(1.25)))[:, :3, 3], atol=1e-6)


def test_distro_and_preset_errors(sequence, tmp_path, capsys):
    with pytest.raises(InputError, match="--distro 'iron': expected one of humble, jazzy"):
        export_sequence(sequence, tmp_path / "bag", distro="iron")
    with pytest.raises(InputError, match="--topics 'kinect': expected one of default, rtabmap, realsense, openni"):
        export_sequence(sequence, tmp_path / "bag", topics="kinect")
    with pytest.raises(InputError, match="--distro humble applies to ROS 2 bags only"):
        export_sequence(sequence, tmp_path / "x.bag", fmt="ros1", distro="humble")
    assert main(["export", str(sequence), "--out", str(tmp_path / "bag"), "--distro", "jazzy", "--topics", "realsense",
                 "--storage", "mcap", "--compress"]) == 0
    info = yaml.safe_load((tmp_path / "bag/metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert "/camera/camera/aligned_depth_to_color/image_raw" in {t["topic_metadata"]["name"] for t in info["topics_with_message_count"]}
    assert not list(tmp_path.glob("*partial*"))
