"""The perturbations on small synthetic frames: each one's effect (frames dropped by share and in
bursts, depth out of step with colour, the lights dimmed, motion blur, depth lost in bursts, depth cut short),
determinism per (perturbation, seed, frame), the text NAME[=LEVEL] and its one-line errors, the
`longslam.perturbations` entry point, and `simulate --perturb` on a route of a few metres."""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from longslam.cli.main import main
from longslam.core.errors import InputError, UnknownNameError
from longslam.core.frame import Frame, Intrinsics
from longslam.io.sequence import SequenceReader
from longslam.sim.perturbations import (
    FrameContext, Perturbation, canonical, get_perturbation, parse_entry, parse_perturbations, perturbation_names,
)
from longslam.sim.perturbations.stream import perturbed_frames
from longslam.sim.sensors import FrameMotion

from helpers.cli_checks import one_line_error

K = Intrinsics.from_fov(32, 24, 90.0)  # fx = 16 px
RATE = 10.0  # frames per second, as the follower's


def _frames(n: int, depth: float = 2.0, seed: int = 0) -> tuple[list[Frame], np.ndarray]:
    """n frames at 10 Hz of random texture and flat depth, and their timestamps."""
    rng = np.random.default_rng(seed)
    stamps = np.arange(n) / RATE
    rgb = rng.integers(30, 225, (24, 32, 3), dtype=np.uint8)
    frames = [Frame(i, float(t), rgb, np.full((24, 32), depth, np.float32), None, K) for i, t in enumerate(stamps)]
    return frames, stamps


def _run(perturbations, n: int = 100, seed: int = 0, motion: FrameMotion | None = None, depth: float = 2.0):
    frames, stamps = _frames(n, depth)
    motions = [motion or FrameMotion.still(t) for t in stamps]
    return list(perturbed_frames(frames, perturbations, seed, stamps, motions))


def _context(t: float = 1.0, motion: FrameMotion | None = None, index: int = 10) -> FrameContext:
    return FrameContext(index, t, 0.0, 10.0, K, motion or FrameMotion.still(t), 0)


# ------------------------------------------------------------------ frames dropped

def test_drop_share_drops_about_that_share_and_keeps_the_first_frame():
    kept = _run(parse_perturbations(["drop=0.2"]), n=3000)
    dropped = 3000 - len(kept)
    assert abs(dropped - 600) < 4 * math.sqrt(3000 * 0.2 * 0.8)
    assert kept[0].timestamp == 0.0
    # Numbered anew from 0, as the written sequence reads back; the gaps are in the timestamps.
    assert [f.index for f in kept] == list(range(len(kept)))
    assert max(np.diff([f.timestamp for f in kept])) > 1.5 / RATE


def test_a_higher_drop_share_drops_the_frames_of_a_lower_one_and_more():
    low = {f.timestamp for f in _run(parse_perturbations(["drop=0.1"]), n=500)}
    high = {f.timestamp for f in _run(parse_perturbations(["drop=0.3"]), n=500)}
    assert high < low


def test_drop_burst_drops_one_burst_of_that_length_a_minute():
    kept = {f.timestamp for f in _run(parse_perturbations(["drop-burst=2"]), n=3000)}  # 300 s: 5 minutes
    dropped = np.array([i for i in range(3000) if i / RATE not in kept])
    bursts = np.split(dropped, np.nonzero(np.diff(dropped) > 1)[0] + 1)
    assert len(bursts) == 5
    assert all(19 <= len(b) <= 21 for b in bursts)  # 2 s at 10 Hz
    assert len({int(b[0] // 600) for b in bursts}) == 5  # one in each minute


def test_a_short_route_still_gets_its_burst():
    kept = _run(parse_perturbations(["drop-burst=1"]), n=100)  # 10 s
    assert 89 <= len(kept) <= 91


# ------------------------------------------------------------------ depth

def test_depth_dropout_zeroes_whole_frames_of_depth_in_bursts_and_leaves_colour():
    frames = _run(parse_perturbations(["depth-dropout=1.5"]), n=1800)  # 180 s: 3 bursts
    empty = np.array([i for i, f in enumerate(frames) if not f.depth.any()])
    assert all(f.depth.all() for f in frames if f.index not in set(empty))  # whole frames or nothing
    bursts = np.split(empty, np.nonzero(np.diff(empty) > 1)[0] + 1)
    assert len(bursts) == 3 and all(14 <= len(b) <= 16 for b in bursts)
    original, _ = _frames(1)
    assert all((f.rgb == original[0].rgb).all() for f in frames)


def test_depth_range_leaves_no_return_beyond_its_level_and_the_rest_exact():
    rng = np.random.default_rng(3)
    depth = rng.uniform(0.3, 8.0, (24, 32)).astype(np.float32)
    depth[0, :4] = 0.0  # no return already
    rgb = rng.integers(30, 225, (24, 32, 3), dtype=np.uint8)
    cut_rgb, cut = get_perturbation("depth-range", 4.5).perturb(rgb, depth, _context(), np.random.default_rng(0))
    near = depth <= 4.5
    assert near.any() and (~near).any()
    assert (cut[near] == depth[near]).all() and not cut[~near].any()
    assert cut.dtype == np.float32 and cut_rgb is rgb
    assert get_perturbation("depth-range", None).level == 4.5  # a Kinect v1's reach


def test_depth_offset_shows_the_depth_from_where_the_camera_was():
    forward = FrameMotion(1.0, np.zeros(3), np.array([0.0, 0.0, 1.0]))  # 1 m/s along the optical axis
    offset = get_perturbation("depth-offset", 0.1)
    rgb = np.zeros((24, 32, 3), np.uint8)
    wall = np.full((24, 32), 2.0, np.float32)
    _, lagging = offset.perturb(rgb, wall, _context(motion=forward), np.random.default_rng(0))
    # 0.1 s earlier the camera was 0.1 m further from the wall.
    assert np.median(lagging[lagging > 0]) == pytest.approx(2.1, abs=1e-4)
    _, leading = get_perturbation("depth-offset", -0.1).perturb(rgb, wall, _context(motion=forward), np.random.default_rng(0))
    assert np.median(leading[leading > 0]) == pytest.approx(1.9, abs=1e-4)


def test_depth_offset_moves_by_the_step_on_its_side_of_the_stamp():
    # Stopped at this frame after driving 1 m/s: a lag sees the depth from where the camera was on
    # the way in; a lead, from where it will be (nowhere else: it stays).
    forward = FrameMotion(0.9, np.zeros(3), np.array([0.0, 0.0, 1.0]))
    stopped = FrameContext(10, 1.0, 0.0, 10.0, K, FrameMotion.still(1.0), 0, forward)
    rgb, wall = np.zeros((24, 32, 3), np.uint8), np.full((24, 32), 2.0, np.float32)
    _, lagging = get_perturbation("depth-offset", 0.1).perturb(rgb, wall, stopped, np.random.default_rng(0))
    assert np.median(lagging[lagging > 0]) == pytest.approx(2.1, abs=1e-4)
    _, leading = get_perturbation("depth-offset", -0.1).perturb(rgb, wall, stopped, np.random.default_rng(0))
    assert np.array_equal(leading, wall)


def test_depth_offset_moves_an_edge_by_the_turn_over_the_offset():
    turn = FrameMotion(1.0, np.array([0.0, -math.radians(90.0), 0.0]), np.zeros(3))  # turning left at 90 deg/s
    depth = np.full((24, 32), 3.0, np.float32)
    depth[:, 16:] = 1.5  # a near box on the right half
    _, shifted = get_perturbation("depth-offset", 0.05).perturb(np.zeros((24, 32, 3), np.uint8), depth,
                                                               _context(motion=turn), np.random.default_rng(0))
    row = shifted[12]
    edge = int(np.argmax((row > 0) & (row < 2.0)))
    # 4.5 deg earlier the camera looked further right, so the box edge was left of column 16 by
    # about fx tan(4.5 deg) = 1.3 px; the column the turn uncovers on the right has no return.
    assert edge in (14, 15)
    assert (row[:edge] > 2.5).all() and (row[edge:-2] < 2.0).all() and row[-1] == 0
    assert shifted.dtype == np.float32 and shifted.shape == depth.shape


# ------------------------------------------------------------------ colour

def test_exposure_dims_the_colour_for_a_stretch_a_minute():
    frames = _run(parse_perturbations(["exposure=2"]), n=1200)  # 120 s: 2 stretches of 10 s
    original, _ = _frames(1)
    bright = original[0].rgb.astype(float).mean()
    means = np.array([f.rgb.astype(float).mean() for f in frames])
    dim = means < 0.5 * bright
    assert dim.sum() in (199, 200, 201)
    assert np.allclose(means[dim], bright / 4, atol=1.0)
    assert np.allclose(means[~dim], bright)
    assert all((f.depth == 2.0).all() for f in frames)  # depth is the camera's own infrared


def _sharpness(rgb: np.ndarray) -> float:
    return float(cv2.Laplacian(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), cv2.CV_64F).var())


def test_blur_lowers_the_sharpness_of_a_turning_frame_more_with_a_longer_exposure():
    turn = FrameMotion(1.0, np.array([0.0, -math.radians(90.0), 0.0]), np.zeros(3))
    rgb = np.random.default_rng(1).integers(0, 255, (24, 32, 3), dtype=np.uint8)
    depth = np.full((24, 32), 2.0, np.float32)
    sharp = _sharpness(rgb)
    blurred = [_sharpness(get_perturbation("blur", level).perturb(rgb, depth, _context(motion=turn), None)[0])
               for level in (0.05, 0.2)]
    assert blurred[0] < 0.5 * sharp and blurred[1] < blurred[0]
    still, _ = get_perturbation("blur", 0.2).perturb(rgb, depth, _context(), None)
    assert (still == rgb).all()  # no motion, no blur


# ------------------------------------------------------------------ determinism

def test_a_frame_is_perturbed_the_same_for_a_seed_whatever_came_before():
    every = parse_perturbations(["drop=0.3+depth-dropout=1"])
    frames, stamps = _frames(600)
    motions = [FrameMotion.still(t) for t in stamps]
    whole = {f.timestamp: f.depth for f in perturbed_frames(frames, every, 5, stamps, motions)}
    late = {f.timestamp: f.depth for f in perturbed_frames(frames[300:], every, 5, stamps, motions)}
    assert set(late) - {frames[300].timestamp} <= set(whole)  # the first frame of a run is never dropped
    assert all((late[t] == whole[t]).all() for t in late if t in whole)
    again = {f.timestamp for f in perturbed_frames(frames, every, 5, stamps, motions)}
    other = {f.timestamp for f in perturbed_frames(frames, every, 6, stamps, motions)}
    assert again == set(whole) and other != set(whole)


# ------------------------------------------------------------------ text and errors

def test_names_levels_and_their_canonical_text():
    assert perturbation_names()[:6] == ["drop", "drop-burst", "depth-offset", "exposure", "blur", "depth-dropout"]
    assert canonical(parse_perturbations(["drop", "blur=0.050"])) == "drop=0.1+blur=0.05"
    assert canonical(parse_entry("exposure=1e+0+depth-offset=-0.03")) == "exposure=1+depth-offset=-0.03"
    assert parse_entry("none") == () and canonical(()) == "none"
    assert get_perturbation("drop", 0.25).describe() == {"name": "drop", "level": 0.25,
                                                         "meaning": "a share of frames dropped, > 0 and <= 0.95"}


@pytest.mark.parametrize("text, error, needles", [
    ("dorp", UnknownNameError, ["unknown perturbation 'dorp' (did you mean 'drop'?)", "valid perturbation names: blur"]),
    ("drop=lots", InputError, ["perturbation 'drop=lots': level 'lots' is not a number; expected a share of frames"]),
    ("drop=", InputError, ["level '' is not a number"]),
    ("drop=nan", InputError, ["level 'nan' is not a number"]),
    ("drop=1.5", InputError, ["perturbation drop=1.5: level 1.5 is out of range; expected a share of frames dropped, > 0 and <= 0.95"]),
    ("blur=0", InputError, ["level 0 is out of range; expected seconds of extra exposure"]),
    ("depth-offset=0", InputError, ["level 0 changes nothing"]),
    ("depth-range=-1", InputError, ["level -1 is out of range; expected metres beyond which depth has no return, > 0"]),
    ("drop=0.1+drop=0.2", InputError, ["perturbation 'drop' is given twice"]),
    ("=0.1", InputError, ["expected NAME or NAME=LEVEL"]),
])
def test_a_bad_perturbation_is_a_one_line_error_naming_it(text, error, needles):
    with pytest.raises(error) as err:
        parse_perturbations([text])
    assert all(n in str(err.value) for n in needles) and "\n" not in str(err.value)


def test_cli_simulate_refuses_a_bad_perturbation_before_rendering(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    for bad, needles in (("dorp", ["unknown perturbation 'dorp'", "did you mean 'drop'"]),
                         ("exposure=20", ["exposure=20", "expected stops darker"])):
        code = main(["simulate", "--route", "demo", "--perturb", bad, "--out", str(tmp_path / "seq")])
        assert code == 2
        one_line_error(capsys, *needles)
    assert not (tmp_path / "cache").exists() and not (tmp_path / "seq").exists()


def test_longslam_list_names_the_perturbations_and_their_levels(capsys):
    main(["list"])
    out = capsys.readouterr().out
    assert "perturbations: drop (a share of frames dropped, > 0 and <= 0.95; default 0.1); drop-burst" in out


# ------------------------------------------------------------------ one's own perturbation

PLUGIN = '''
import numpy as np
from longslam.sim.perturbations import Perturbation


class Snow(Perturbation):
    name = "whatever"  # the entry point's name wins
    default_level = 0.5
    high = 1.0
    meaning = "a share of colour pixels turned white, > 0 and <= 1"

    def perturb(self, rgb, depth, frame, rng):
        rgb = rgb.copy()
        rgb[rng.random(depth.shape) < self.level] = 255
        return rgb, depth


class Broken(Perturbation):
    def perturb(self, rgb, depth, frame, rng):
        return rgb


NotAClass = 3
'''


@pytest.fixture()
def plugin(tmp_path, monkeypatch):
    dist = tmp_path / "longslam_test_perturbations-0.1.dist-info"
    dist.mkdir()
    (tmp_path / "longslam_test_perturbations.py").write_text(PLUGIN)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: longslam-test-perturbations\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(
        "[longslam.perturbations]\nsnow = longslam_test_perturbations:Snow\n"
        "broken = longslam_test_perturbations:Broken\nodd = longslam_test_perturbations:NotAClass\n"
        "gone = longslam_test_perturbations_missing:Gone\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def test_a_perturbation_of_ones_own_through_the_entry_point(plugin, capsys):
    assert {"snow", "broken", "odd", "gone"} <= set(perturbation_names())
    snow = parse_perturbations(["snow=0.25"])
    assert snow[0].name == "snow" and snow[0].text == "snow=0.25"
    frames = _run(snow, n=20)
    white = np.mean([(f.rgb == 255).all(axis=2).mean() for f in frames])
    assert 0.2 < white < 0.3
    assert [(f.rgb == g.rgb).all() for f, g in zip(frames, _run(snow, n=20))] == [True] * 20  # seeded per frame
    with pytest.raises(InputError, match="perturbation 'broken=1', frame 0: perturb\\(\\) raised or returned"):
        _run(parse_perturbations(["broken"]), n=2)[0].rgb
    with pytest.raises(InputError, match="perturbation 'odd': entry point .* is a int; expected a subclass"):
        parse_perturbations(["odd"])
    with pytest.raises(InputError, match="perturbation snow=2: level 2 is out of range; expected a share of colour"):
        parse_perturbations(["snow=2"])
    main(["list"])
    out = capsys.readouterr().out
    assert "snow (a share of colour pixels turned white, > 0 and <= 1; default 0.5)" in out
    assert "gone (broken: its module longslam_test_perturbations_missing is not installed)" in out


# ------------------------------------------------------------------ simulate --perturb

@pytest.fixture(scope="module")
def tiny_route(tmp_path_factory):
    """A 3 m route rendered at 32 x 24 once for this module's tests, in a render cache of their own."""
    root = tmp_path_factory.mktemp("perturb-simulate")
    (root / "tiny.txt").write_text("20 31.25\n23 31.25\n")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("LONGSLAM_CACHE", str(root / "cache"))
        yield root / "tiny.txt"


def _simulate_args(route, *more: str) -> list[str]:
    return ["simulate", "--route", str(route), "--width", "32", "--height", "24", "--seed", "3", *more]


def test_cli_simulate_perturb_writes_the_frames_that_get_through_and_names_them(tiny_route, tmp_path, capsys):
    common = _simulate_args(tiny_route)
    assert main(common + ["--out", str(tmp_path / "plain")]) == 0
    assert main(common + ["--perturb", "drop=0.4", "--perturb", "exposure=1", "--out", str(tmp_path / "perturbed")]) == 0
    assert "perturbed by drop=0.4+exposure=1 (" in capsys.readouterr().out
    plain, perturbed = SequenceReader(tmp_path / "plain"), SequenceReader(tmp_path / "perturbed")
    meta = json.loads((tmp_path / "perturbed" / "meta.json").read_text())
    assert meta["perturbation"] == "drop=0.4+exposure=1"
    assert [p["name"] for p in meta["perturbations"]] == ["drop", "exposure"] and meta["perturbations"][0]["level"] == 0.4
    assert meta["frames_dropped"] == len(plain) - len(perturbed) > 0
    assert "perturbation" not in json.loads((tmp_path / "plain" / "meta.json").read_text())
    # The dropped frames are absent; the ground truth and odometry keep every pose.
    assert set(perturbed.timestamps) < set(plain.timestamps) and perturbed.timestamps[0] == plain.timestamps[0]
    assert len(perturbed.ground_truth) == len(plain.ground_truth) and len(perturbed.odometry) == len(plain.odometry)
    # The same frames as the stream a study's worker makes on the fly.
    again = list(perturbed_frames(plain, parse_perturbations(["drop=0.4", "exposure=1"]), 3, plain.ground_truth.timestamps,
                                  [FrameMotion.still(t) for t in plain.timestamps]))
    assert [f.timestamp for f in again] == list(perturbed.timestamps)
    assert all((f.rgb == perturbed.frame(i).rgb).all() for i, f in enumerate(again))


def test_a_perturbation_that_fails_midway_leaves_no_sequence(tiny_route, plugin, tmp_path, capsys):
    code = main(_simulate_args(tiny_route, "--perturb", "drop=0.2", "--perturb", "broken", "--out", str(tmp_path / "seq")))
    assert code == 2
    one_line_error(capsys, "perturbation 'broken=1', frame 0: perturb() raised or returned other than (rgb, depth)")
    # Neither the sequence nor its temporary folder: only the plugin's own files are there.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["longslam_test_perturbations-0.1.dist-info",
                                                          "longslam_test_perturbations.py"]
