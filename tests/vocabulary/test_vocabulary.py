"""The ORB vocabulary builder: k-means on binary descriptors, the DBoW2 tree and its IDF weights,
DBoW2's text format as ORB-SLAM3 reads it, and the `longslam vocabulary build` command."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from longslam.cli.main import main
from longslam.core.errors import InputError
from longslam.sim.simulate import rendered_sequence
from longslam.sim.routes import Route
import longslam.vocabulary.kmeans as kmeans_module
from longslam.vocabulary import Vocabulary, build_tree, format_text, read_vocabulary, write_vocabulary
from longslam.vocabulary.build import OrbExtractor, chosen_frames, sequence_descriptors
from longslam.vocabulary.kmeans import hamming, kmeans, majority, seed_centres

# A few metres along the hall of the university world, past its pillars: ~45 frames with texture.
ROUTE = Route("voc-check", "university", ((114.0, 24.5), (114.0, 29.0)))


def naive_hamming(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.array([[bin(int.from_bytes(x.tobytes(), "big") ^ int.from_bytes(y.tobytes(), "big")).count("1")
                      for y in b] for x in a])


def flip_bits(rng: np.random.Generator, centre: np.ndarray, n: int, bits: int) -> np.ndarray:
    """n copies of `centre` with `bits` random bits flipped in each."""
    out = np.unpackbits(np.repeat(centre[None, :], n, axis=0), axis=1)
    for row in out:
        row[rng.choice(out.shape[1], bits, replace=False)] ^= 1
    return np.packbits(out, axis=1)


def random_images(seed: int, images: int = 12, per_image: int = 80) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (per_image, 32), dtype=np.uint8) for _ in range(images)]


# k-means ------------------------------------------------------------------------------------

def test_hamming_matches_a_bit_count():
    rng = np.random.default_rng(0)
    a, b = rng.integers(0, 256, (7, 32), dtype=np.uint8), rng.integers(0, 256, (5, 32), dtype=np.uint8)
    assert np.array_equal(hamming(a, b), naive_hamming(a, b))
    assert np.all(np.diag(hamming(a, a)) == 0)


def test_majority_sets_a_bit_held_by_at_least_half_the_rows():
    rows = np.array([[0b10000000] + [0] * 31, [0b11000000] + [0] * 31, [0b11100000] + [0] * 31], dtype=np.uint8)
    assert majority(rows)[0] == 0b11000000  # bit 7 in 3 of 3, bit 6 in 2 of 3, bit 5 in 1 of 3
    # FORB::meanValue: with an even count a bit held by exactly half is set.
    assert majority(rows[1:])[0] == 0b11100000  # bit 5 in 1 of 2


def test_hamming_without_numpys_bitwise_count(monkeypatch):
    rng = np.random.default_rng(5)
    a, b = rng.integers(0, 256, (6, 32), dtype=np.uint8), rng.integers(0, 256, (4, 32), dtype=np.uint8)
    monkeypatch.setattr(kmeans_module, "_HAS_BITWISE_COUNT", False)  # numpy < 2: the byte table
    assert np.array_equal(hamming(a, b), naive_hamming(a, b))


def test_kmeans_finds_known_clusters():
    rng = np.random.default_rng(3)
    centres = rng.integers(0, 256, (4, 32), dtype=np.uint8)
    assert hamming(centres, centres)[~np.eye(4, dtype=bool)].min() > 60  # far apart
    data = np.concatenate([flip_bits(rng, c, 50, 6) for c in centres])
    truth = np.repeat(np.arange(4), 50)
    order = rng.permutation(len(data))
    found, labels = kmeans(data[order], 4, np.random.default_rng(0))
    assert len(found) == 4
    # Each found cluster is exactly one true cluster, and its majority centre is the true centre.
    for c in range(4):
        members = truth[order][labels == c]
        assert len(set(members)) == 1
        assert np.array_equal(found[c], centres[members[0]])


def test_kmeans_with_few_or_identical_descriptors():
    rng = np.random.default_rng(1)
    few = rng.integers(0, 256, (3, 32), dtype=np.uint8)
    centres, labels = kmeans(few, 10, rng)  # n <= k: each descriptor is its own cluster (DBoW2)
    assert np.array_equal(centres, few) and list(labels) == [0, 1, 2]
    same = np.repeat(few[:1], 20, axis=0)
    assert len(seed_centres(same, 5, rng)) == 1  # seeding stops once every distance is 0
    centres, labels = kmeans(same, 5, rng)
    assert len(centres) == 1 and np.all(labels == 0)


# the tree -------------------------------------------------------------------------------------

def test_tree_shape_words_and_idf_weights():
    images = random_images(0)
    k, levels = 3, 3
    voc = build_tree(images, k, levels, np.random.default_rng(0))
    assert voc.parents[0] == -1 and np.all(voc.parents[1:] < np.arange(1, voc.nodes))
    depth = np.zeros(voc.nodes, dtype=int)
    for node in range(1, voc.nodes):
        depth[node] = depth[voc.parents[node]] + 1
    assert depth.max() <= levels
    assert np.bincount(voc.parents[1:]).max() <= k
    assert 1 < len(voc.words) <= k ** levels
    # Children get consecutive ids when their parent's k-means runs (DBoW2's numbering).
    for parent in np.unique(voc.parents[1:]):
        kids = np.flatnonzero(voc.parents == parent)
        assert np.array_equal(kids, np.arange(kids[0], kids[0] + len(kids)))
    # Weights: ln(N / N_i) over the images holding word i; inner nodes 0.
    words = [set(voc.transform(image)) for image in images]
    for word, node in enumerate(voc.words):
        holding = sum(word in w for w in words)
        expected = np.log(len(images) / holding) if holding else 0.0
        assert voc.weights[node] == pytest.approx(expected, abs=1e-12)
    assert np.all(voc.weights[~voc.is_leaf] == 0)


def test_transform_descends_to_the_nearest_child():
    images = random_images(1, images=4)
    voc = build_tree(images, 4, 2, np.random.default_rng(2))
    query = images[0][:10]
    for descriptor, word in zip(query, voc.transform(query)):
        node = 0
        while not voc.is_leaf[node]:
            kids = np.flatnonzero(voc.parents == node)
            node = kids[np.argmin(naive_hamming(descriptor[None, :], voc.descriptors[kids])[0])]
        assert voc.words[word] == node


def test_same_seed_same_vocabulary_other_seed_another():
    images = random_images(2)
    a = format_text(build_tree(images, 4, 3, np.random.default_rng(7)))
    b = format_text(build_tree(images, 4, 3, np.random.default_rng(7)))
    c = format_text(build_tree(images, 4, 3, np.random.default_rng(8)))
    assert a == b and a != c


# the text format ----------------------------------------------------------------------------

def test_text_file_round_trips_without_a_final_newline(tmp_path):
    voc = build_tree(random_images(3), 5, 3, np.random.default_rng(0))
    path = write_vocabulary(voc, tmp_path / "voc.txt")
    raw = path.read_bytes()
    assert not raw.endswith(b"\n")
    lines = raw.decode().split("\n")
    assert lines[0] == "5 3 0 0"  # k L scoring (L1_NORM) weighting (TF_IDF), as ORBvoc.txt's "10 6 0 0"
    assert len(lines) == voc.nodes  # the header, then every node but the root
    first = lines[1].split()
    assert len(first) == 2 + 32 + 1 and first[0] == "0"  # parent, isLeaf, 32 bytes, weight
    back = read_vocabulary(path)
    assert (back.k, back.levels, back.scoring, back.weighting) == (5, 3, 0, 0)
    assert np.array_equal(back.parents, voc.parents)
    assert np.array_equal(back.descriptors[1:], voc.descriptors[1:])
    assert np.array_equal(back.weights, voc.weights)  # exact: weights are written with repr
    assert np.array_equal(back.is_leaf, voc.is_leaf)
    assert format_text(back) == raw.decode()


def test_writing_never_replaces_a_file_unasked(tmp_path):
    voc = build_tree(random_images(5, images=2), 3, 1, np.random.default_rng(0))
    path = tmp_path / "voc.txt"
    path.write_text("someone else's")
    with pytest.raises(InputError, match="was written by another process"):
        write_vocabulary(voc, path, overwrite=False)
    assert path.read_text() == "someone else's"
    assert [p.name for p in tmp_path.iterdir()] == ["voc.txt"]  # no partial file left


def test_reader_refuses_what_orbslam3_would_misread(tmp_path):
    voc = build_tree(random_images(4, images=3), 3, 2, np.random.default_rng(0))
    good = format_text(voc)
    cases = {
        "newline": (good + "\n", "ends with a newline"),
        "header": ("30 2 0 0" + good[good.index("\n"):], "k = 30 is outside 0..20"),
        "fields": (good.replace("\n0 0 ", "\n0 ", 1), "expected 35 fields"),
        "parent": (good.replace("\n0 ", "\n9 ", 1), "parent id 9 must be a node before this one"),
    }
    for name, (text, message) in cases.items():
        path = tmp_path / f"{name}.txt"
        path.write_text(text)
        with pytest.raises(InputError, match=message):
            read_vocabulary(path)
    # As ORB-SLAM3's saveToTextFile writes it: "k L  scoring weighting", "... byte  weight", a final newline.
    saved = "\n".join(line.rsplit(" ", 1)[0] + "  " + line.rsplit(" ", 1)[1] for line in good.split("\n")[1:])
    (tmp_path / "saved.txt").write_text("3 2  0 0\n" + saved + "\n")
    assert format_text(read_vocabulary(tmp_path / "saved.txt", final_newline=True)) == good
    leaf = voc.words[0]
    lines = good.split("\n")
    fields = lines[leaf].split()
    fields[1] = "0"  # a word marked as an inner node
    lines[leaf] = " ".join(fields)
    (tmp_path / "flag.txt").write_text("\n".join(lines))
    with pytest.raises(InputError, match=rf"flag.txt:{leaf + 1}: isLeaf is 0 but the node has no children"):
        read_vocabulary(tmp_path / "flag.txt")


def test_vocabulary_checks_its_arrays():
    with pytest.raises(ValueError, match="parent must come before it"):
        Vocabulary(2, 1, np.array([-1, 2, 0]), np.zeros((3, 32), np.uint8), np.zeros(3))


# frames to descriptors --------------------------------------------------------------------------

def test_chosen_frames():
    assert list(chosen_frames(10, 3)) == [0, 3, 6, 9]
    assert list(chosen_frames(100, 1, 5)) == [0, 25, 50, 74, 99]
    with pytest.raises(InputError, match="--frames-every"):
        chosen_frames(10, 0)


def test_orb_extractor_gives_32_byte_descriptors_and_none_on_a_blank_image():
    rng = np.random.default_rng(0)
    blocks = rng.integers(0, 256, (24, 32), dtype=np.uint8).repeat(10, axis=0).repeat(10, axis=1)
    extractor = OrbExtractor(500)
    d = extractor.descriptors(blocks)
    assert d.dtype == np.uint8 and d.shape[1] == 32 and 100 < len(d) <= 500
    assert extractor.descriptors(np.full((240, 320), 128, np.uint8)).shape == (0, 32)


@pytest.fixture(scope="module")
def hall_sequence(render_cache) -> Path:
    """A short rendered walk through the hall, in the session's render cache."""
    return rendered_sequence(ROUTE, root=render_cache, progress=False)


def test_cli_builds_from_a_sequence(hall_sequence, tmp_path, capsys):
    out = tmp_path / "voc.txt"
    args = ["vocabulary", "build", "--sequence", str(hall_sequence), "--out", str(out), "--k", "6", "--levels", "3",
            "--max-frames", "10", "--features", "300"]
    assert main(args) == 0
    assert "words" in capsys.readouterr().out
    voc = read_vocabulary(out)
    assert (voc.k, voc.levels) == (6, 3) and len(voc.words) > 50
    images = sequence_descriptors(hall_sequence, 300, 1, 10, progress=False)
    assert sum(map(len, images)) > 1000
    # The same command again: refused without --overwrite, the same bytes with it.
    first = out.read_bytes()
    assert main(args) == 2
    assert "exists already" in capsys.readouterr().err
    assert main(args + ["--overwrite"]) == 0
    assert out.read_bytes() == first


def test_cli_builds_from_a_route_through_the_render_cache(hall_sequence, tmp_path, monkeypatch):
    # The route again as a file of the same name: its frames are the cached ones, not rendered anew.
    route_file = tmp_path / f"{ROUTE.name}.txt"
    route_file.write_text("".join(f"{x} {y}\n" for x, y in ROUTE.waypoints))
    monkeypatch.setenv("LONGSLAM_CACHE", str(hall_sequence.parent))
    cached = sorted(hall_sequence.parent.iterdir())
    options = ["--k", "5", "--levels", "2", "--max-frames", "4", "--features", "200"]
    assert main(["vocabulary", "build", "--route", str(route_file), "--out", str(tmp_path / "a.txt"), *options]) == 0
    assert sorted(hall_sequence.parent.iterdir()) == cached
    assert main(["vocabulary", "build", "--sequence", str(hall_sequence), "--out", str(tmp_path / "b.txt"), *options]) == 0
    assert (tmp_path / "a.txt").read_bytes() == (tmp_path / "b.txt").read_bytes()


def test_cli_errors_name_the_value(hall_sequence, tmp_path, capsys):
    out = str(tmp_path / "voc.txt")
    assert main(["vocabulary", "build", "--sequence", str(hall_sequence), "--out", out, "--k", "30"]) == 2
    assert "--k must be a whole number in 2..20" in capsys.readouterr().err
    assert main(["vocabulary", "build", "--sequence", str(tmp_path / "none"), "--out", out]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["vocabulary", "build", "--sequence", str(hall_sequence), "--out", out, "--width", "640"]) == 2
    assert "--width describes the route to render" in capsys.readouterr().err
    assert main(["vocabulary", "build", "--sequence", str(hall_sequence), "--out", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err


# ORB-SLAM3 itself -------------------------------------------------------------------------------

# ORB-SLAM3 exits the process when it cannot load a vocabulary, so it runs in a child process.
ORBSLAM3_CHECK = textwrap.dedent("""
    import json, sys
    from pathlib import Path
    import cv2, numpy as np, pyorbslam3
    voc, settings, sequence, frames = sys.argv[1], sys.argv[2], Path(sys.argv[3]), int(sys.argv[4])
    def listing(name):
        return [line.split() for line in (sequence / name).read_text().splitlines() if line and not line.startswith("#")]
    slam = pyorbslam3.Slam(vocab_file=voc, settings_file=settings, sensor=pyorbslam3.Sensor.RGBD)
    states = []
    for (t, rgb), (_, depth) in list(zip(listing("rgb.txt"), listing("depth.txt")))[:frames]:
        image = cv2.cvtColor(cv2.imread(str(sequence / rgb)), cv2.COLOR_BGR2RGB)
        raw = cv2.imread(str(sequence / depth), cv2.IMREAD_UNCHANGED).astype(np.float32)
        states.append(bool(slam.track_rgbd(image, raw, float(t)).pose_valid))
    slam.shutdown()
    print("STATES " + json.dumps(states), flush=True)
""")


def orbslam3_settings(sequence: Path) -> str:
    """An ORB-SLAM3 RGB-D settings file (Examples/RGB-D/TUM1.yaml's File.version 1.0 layout) for
    the sequence's pinhole camera, depth in its PNGs' units, every depth within range "close"
    (TUM1.yaml's 40 baselines, 3.1 m, loses tracking in the hall)."""
    camera = json.loads((sequence / "camera.json").read_text())
    return textwrap.dedent(f"""\
        %YAML:1.0
        File.version: "1.0"
        Camera.type: "PinHole"
        Camera1.fx: {camera["fx"]}
        Camera1.fy: {camera["fy"]}
        Camera1.cx: {camera["cx"]}
        Camera1.cy: {camera["cy"]}
        Camera1.k1: 0.0
        Camera1.k2: 0.0
        Camera1.p1: 0.0
        Camera1.p2: 0.0
        Camera.width: {camera["width"]}
        Camera.height: {camera["height"]}
        Camera.fps: 10
        Camera.RGB: 1
        Stereo.ThDepth: {camera["max_depth"] / 0.07732}
        Stereo.b: 0.07732
        RGBD.DepthMapFactor: {float(camera["depth_scale"])}
        ORBextractor.nFeatures: 1000
        ORBextractor.scaleFactor: 1.2
        ORBextractor.nLevels: 8
        ORBextractor.iniThFAST: 20
        ORBextractor.minThFAST: 7
        Viewer.KeyFrameSize: 0.05
        Viewer.KeyFrameLineWidth: 1.0
        Viewer.GraphLineWidth: 0.9
        Viewer.PointSize: 2.0
        Viewer.CameraSize: 0.08
        Viewer.CameraLineWidth: 3.0
        Viewer.ViewpointX: 0.0
        Viewer.ViewpointY: -0.7
        Viewer.ViewpointZ: -1.8
        Viewer.ViewpointF: 500.0
        """)


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("pyorbslam3") is None, reason="pyorbslam3 (GPL, the plugin's) is not installed")
def test_orbslam3_loads_the_vocabulary_and_tracks(hall_sequence, tmp_path):
    voc = tmp_path / "voc.txt"
    assert main(["vocabulary", "build", "--sequence", str(hall_sequence), "--out", str(voc),
                 "--k", "10", "--levels", "3", "--max-frames", "20"]) == 0
    settings = tmp_path / "settings.yaml"
    settings.write_text(orbslam3_settings(hall_sequence))
    done = subprocess.run([sys.executable, "-c", ORBSLAM3_CHECK, str(voc), str(settings), str(hall_sequence), "20"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:] + done.stdout[-2000:]
    assert "Vocabulary loaded!" in done.stdout
    states = json.loads(done.stdout.split("STATES ", 1)[1])
    assert len(states) == 20 and all(states), states
