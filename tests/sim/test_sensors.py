"""The sensor models against their formulas on rendered flat walls, their holes where each model
puts them (and none under `ideal`), colour noise and motion blur, determinism per (sensor, seed,
frame), and the `longslam.sensors` entry point for a model of one's own."""

from __future__ import annotations

import math

import numpy as np
import pytest

from longslam.cli.main import main
from longslam.core.errors import InputError, UnknownNameError
from longslam.io.sequence import SequenceReader
from longslam.sim.sensors import (
    ColourNoise, FrameMotion, KinectV1, RealSenseD435, SensorModel, frame_rng, get_sensor, sensor_names,
)
from longslam.sim.sensors import catalog
from longslam.sim.sensors.stream import camera_motions, sensed_frame, sensed_frames

from helpers.cli_checks import one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from helpers.flat_walls import K, TEXTURED_HALF, render, square_wall

def sense(model: SensorModel, rgb, depth, seed: int = 0, index: int = 0, motion: FrameMotion | None = None):
    return model.sense(rgb, depth, K, motion or FrameMotion.still(), frame_rng(model.name, seed, index))


@pytest.fixture(scope="module")
def textured():
    """Random grey texels, 1.2 cm each on a `TEXTURED_HALF` wall: contrast in every 7 x 7 window
    from 1 to 4 m."""
    rng = np.random.default_rng(7)
    return rng.integers(30, 225, (1024, 1024), dtype=np.uint8)[:, :, None].repeat(3, axis=2)




# ------------------------------------------------------------------ kinect-v1

@pytest.mark.parametrize("distance", [1.0, 2.0, 4.0])
def test_kinect_axial_noise_matches_its_formula_on_a_flat_wall(distance):
    model = KinectV1()
    rgb, depth = render([square_wall(distance)])
    assert np.allclose(depth, distance, atol=1e-4)  # the clean render is the wall itself
    _, noisy = sense(model, rgb, depth)
    valid = noisy > 0
    assert valid.mean() > 0.99, "a wall facing the camera in range has no holes"
    expected = 0.0012 + 0.0019 * (distance - 0.4) ** 2  # Nguyen et al. 2012, eq. 5
    assert noisy[valid].std() == pytest.approx(expected, rel=0.15)
    assert abs(noisy[valid].mean() - distance) < model.depth_step(distance)


def test_kinect_depth_comes_in_disparity_steps():
    model = KinectV1()
    rgb, depth = render([square_wall(4.0)])
    _, noisy = sense(model, rgb, depth)
    bf = 0.075 * 580.0
    disparity_eighths = 8 * bf / noisy[noisy > 0]
    assert np.allclose(disparity_eighths, np.round(disparity_eighths), atol=1e-3)
    levels = np.unique(np.round(disparity_eighths))
    gaps = np.diff(1 / levels * 8 * bf)
    # The step at 4 m is z^2 / (8 b f) = 4.6 cm (Khoshelham & Elberink 2012).
    assert np.median(np.abs(gaps)) == pytest.approx(16 / (8 * bf), rel=0.1)


@pytest.mark.parametrize("distance", [0.45, 4.8])
def test_kinect_returns_nothing_out_of_its_range(distance):
    rgb, depth = render([square_wall(distance)])
    assert (depth > 0).all()
    _, noisy = sense(KinectV1(), rgb, depth)
    assert (noisy > 0).mean() < 0.01


def test_kinect_projector_shadow_is_a_band_left_of_a_near_edge():
    # A panel 1 m away covering the right half of the view (world y < 0), the wall 2 m away.
    panel = np.array([[1.0, 0.0, -5], [1.0, -5, -5], [1.0, -5, 5], [1.0, 0.0, 5]], float)
    rgb, depth = render([square_wall(2.0), panel])
    edge = int(np.argmax(depth[120] < 1.5))  # first column on the panel
    assert 150 <= edge <= 170
    model = KinectV1(lateral_px=0.0)  # the band's edges exactly where the geometry puts them
    shadow = model.shadow(depth, K)
    width = 0.075 * K.fx * (1 / 1.0 - 1 / 2.0)  # disparity step across the edge: 6 px here
    rows = slice(40, 200)
    counts = shadow[rows].sum(axis=1)
    assert np.all(np.abs(counts - width) <= 1.0)
    assert shadow[rows, edge - int(width) + 1:edge].all()  # on the left of the edge
    assert not shadow[rows, edge:].any()  # none on the panel or right of it
    _, noisy = sense(model, rgb, depth)
    assert (noisy[rows, edge - int(width) + 1:edge] == 0).all()
    assert (noisy[rows, :edge - int(width) - 1] > 0).mean() > 0.99  # the rest of the wall is seen


def test_kinect_lateral_noise_reads_each_pixel_from_a_neighbour_offset_by_its_sigma():
    # A panel 1 m away on the right half, the wall 2 m away; no axial noise or quantisation, so a
    # panel pixel reads anything but 1 m only when its offset crosses the edge. Ten times the
    # model's 0.8 px makes the share large enough to measure; the scaling is the model's.
    panel = np.array([[1.0, 0.0, -5], [1.0, -5, -5], [1.0, -5, 5], [1.0, 0.0, 5]], float)
    rgb, depth = render([square_wall(2.0), panel])
    edge = int(np.argmax(depth[120] < 1.5))
    model = KinectV1(lateral_px=8.0, axial_a=0.0, axial_b=0.0, disparity_step=1e-6, max_incidence_deg=90.0)
    sigma = 8.0 * K.fx / 580.0  # device pixels in the render's: 2.2 px
    crossed = []
    for seed in range(4):
        _, noisy = sense(model, rgb, depth, seed=seed)
        crossed.append(np.abs(noisy[20:220, edge:edge + 12] - 1.0) > 1e-3)
    # Column d right of the edge reads across it when the offset is below -(d + 1/2).
    expected = sum(0.5 * math.erfc((d + 0.5) / (sigma * math.sqrt(2))) for d in range(12)) / 12
    assert np.mean(crossed) == pytest.approx(expected, rel=0.15)
    assert KinectV1().lateral_px == 0.8  # Nguyen et al. 2012


def test_kinect_drops_grazing_returns():
    # A wall seen at 80 deg from its normal at the image centre, and one at 60 deg.
    def slanted(angle_deg: float) -> np.ndarray:
        a = math.radians(angle_deg)
        along = np.array([math.sin(a), -math.cos(a), 0.0])  # the wall's direction in the floor plane
        centre = np.array([3.0, 0.0, 0.0])
        up = np.array([0.0, 0.0, 1.0])
        return np.array([centre - 30 * along - 30 * up, centre + 30 * along - 30 * up,
                         centre + 30 * along + 30 * up, centre - 30 * along + 30 * up])
    centre = (slice(110, 130), slice(150, 170))
    for angle, holes in ((80.0, True), (60.0, False)):
        rgb, depth = render([slanted(angle)])
        assert (depth[centre] > 0).all()
        _, noisy = sense(KinectV1(), rgb, depth)
        assert ((noisy[centre] == 0).mean() > 0.99) == holes, angle


# ------------------------------------------------------------------ realsense-d435

@pytest.mark.parametrize("distance", [1.0, 2.0, 4.0])
def test_realsense_rms_error_matches_its_formula_on_a_flat_wall(distance, textured):
    rgb, depth = render([square_wall(distance, TEXTURED_HALF)], textured)
    _, noisy = sense(RealSenseD435(), rgb, depth)
    valid = noisy > 0
    expected = 0.02 * 2.0 * (distance / 2.0) ** 2  # 2 % at 2 m, growing as z^2
    assert noisy[valid].std() == pytest.approx(expected, rel=0.15)
    band = int(math.ceil(0.05 * K.fx / distance))
    assert valid[:, band + 1:].mean() > 0.99, "a textured wall has no speckle holes"


@pytest.mark.parametrize("distance", [1.0, 2.0])
def test_realsense_invalid_band_on_the_left_edge(distance, textured):
    rgb, depth = render([square_wall(distance, TEXTURED_HALF)], textured)
    _, noisy = sense(RealSenseD435(), rgb, depth)
    width = 0.050 * K.fx / distance  # b f / Z: 8 px at 1 m, 4 px at 2 m
    assert (noisy[:, :int(math.floor(width - 0.5))] == 0).all()
    assert (noisy[:, int(math.ceil(width + 0.5)):] > 0).mean() > 0.99


def test_realsense_speckle_holes_on_a_low_texture_wall():
    model = RealSenseD435()
    rgb, depth = render([square_wall(2.0)])  # one flat colour: nothing to match
    _, noisy = sense(model, rgb, depth)
    share = (noisy[:, 10:] == 0).mean()
    assert share == pytest.approx(model.expected_speckle_share(), rel=0.15)
    assert 0.2 < share < 0.4


def test_realsense_range_is_0_3_to_10_m():
    rgb, depth = render([square_wall(0.25)])
    assert ((sense(RealSenseD435(speckle_seed=0.0), rgb, depth)[1]) > 0).mean() < 0.01


# ------------------------------------------------------------------ ideal and colour

def test_ideal_changes_nothing(textured):
    rgb, depth = render([square_wall(2.0, TEXTURED_HALF)], textured)
    ideal = get_sensor("ideal")
    assert ideal.is_ideal and not KinectV1().is_ideal
    out_rgb, out_depth = sense(ideal, rgb, depth)
    assert out_rgb is rgb and out_depth is depth
    assert (out_depth > 0).all()  # no holes


def test_shot_and_read_noise_match_their_formula():
    colour = ColourNoise()
    for level in (20, 128, 230):
        rgb = np.full((240, 320, 3), level, np.uint8)
        noisy = colour.apply(rgb, K, FrameMotion.still(), np.random.default_rng(level)).astype(np.float64)
        expected = math.sqrt(colour.shot_gain * level + colour.read_noise**2)
        assert noisy.std() == pytest.approx(expected, rel=0.15)
        assert abs(noisy.mean() - level) < 0.2


def test_motion_blur_smears_an_edge_by_the_turn_during_the_exposure():
    colour = ColourNoise(shot_gain=0.0, read_noise=0.0)
    rgb = np.zeros((240, 320, 3), np.uint8)
    rgb[:, 160:] = 200
    turning = FrameMotion(0.0, np.array([0.0, math.radians(90.0), 0.0]), np.zeros(3))
    still = colour.apply(rgb, K, FrameMotion.still(), np.random.default_rng(0))
    assert (still == rgb).all()
    blurred = colour.apply(rgb, K, turning, np.random.default_rng(0))
    smear = K.fx * math.radians(90.0) * colour.exposure_s  # 4.2 px at 90 deg/s over 1/60 s
    ramp = np.count_nonzero((blurred[120, :, 0] > 10) & (blurred[120, :, 0] < 190))
    assert abs(ramp - smear) <= 1.5
    assert (blurred[:, :150] == 0).all() and (blurred[:, 170:] == 200).all()


def test_gain_steps_hold_for_a_period_and_change_between():
    colour = ColourNoise(shot_gain=0.0, read_noise=0.0, gain_period_s=2.0)
    rgb = np.full((24, 32, 3), 100, np.uint8)
    level = {t: int(colour.apply(rgb, K, FrameMotion.still(t), np.random.default_rng(0), "s", 0).mean()) for t in (0.1, 1.9, 2.1, 4.5, 6.5)}
    assert level[0.1] == level[1.9]
    assert len(set(level.values())) > 1
    assert all(85 <= v <= 115 for v in level.values())  # 1 +- 0.15


# ------------------------------------------------------------------ determinism

def test_a_frame_is_the_same_for_a_seed_whatever_came_before(tmp_path):
    path, truth, _ = write_tiny_sequence(tmp_path / "seq", n=12, turn=1.0)
    reader = SequenceReader(path)
    motions = camera_motions(truth)
    model = get_sensor("kinect-v1")
    every = [(f.rgb, f.depth) for f in sensed_frames(reader, model, 3, motions)]
    late = [(f.rgb, f.depth) for f in sensed_frames((reader.frame(i) for i in range(7, 12)), model, 3, motions)]
    for (rgb_a, depth_a), (rgb_b, depth_b) in zip(every[7:], late):
        assert (rgb_a == rgb_b).all() and (depth_a == depth_b).all()
    again = [f.depth for f in sensed_frames(reader, model, 3, motions)]
    other = [f.depth for f in sensed_frames(reader, model, 4, motions)]
    assert all((a == b).all() for (_, a), b in zip(every, again))
    assert not all((a == b).all() for (_, a), b in zip(every, other))
    rs = [f.depth for f in sensed_frames(reader, get_sensor("realsense-d435"), 3, motions)]
    assert not all((a == b).all() for (_, a), b in zip(every, rs))


def test_sensed_frames_stay_lazy(tmp_path):
    path, truth, _ = write_tiny_sequence(tmp_path / "seq", n=5)
    reader = SequenceReader(path)
    calls = []

    class Counting(SensorModel):
        name = "counting"

        def sense(self, rgb, depth, intrinsics, motion, rng):
            calls.append(1)
            return rgb, depth

    frames = list(sensed_frames(reader, Counting(), 0, camera_motions(truth)))
    assert calls == []
    frames[2].depth, frames[2].rgb
    assert calls == [1]  # both images from one call, and only for the frame looked at


def test_camera_motion_of_a_turn_in_place():
    from longslam.core.geometry import camera_poses_from_planar
    from longslam.core.trajectory import Trajectory

    stamps = 0.1 * np.arange(5)
    xyyaw = np.column_stack([np.zeros(5), np.zeros(5), math.radians(9.0) * np.arange(5)])  # 90 deg/s
    motions = camera_motions(Trajectory(stamps, camera_poses_from_planar(xyyaw, 1.25)))
    # Turning left (yaw up) about world z is turning about the camera's -y axis.
    assert motions[0].angular_velocity == pytest.approx([0.0, -math.radians(90.0), 0.0], abs=1e-9)
    assert np.allclose(motions[0].linear_velocity, 0.0)


# ------------------------------------------------------------------ one's own model

PLUGIN = '''
import numpy as np
from longslam.sim.sensors import SensorModel

class Dusty(SensorModel):
    """5 % of the returns lost, at random."""
    name = "dusty"
    def sense(self, rgb, depth, intrinsics, motion, rng):
        depth = depth.copy()
        depth[rng.random(depth.shape) < 0.05] = 0.0
        return rgb, depth

class Broken(SensorModel):
    name = "broken"
    def sense(self, rgb, depth, intrinsics, motion, rng):
        return rgb, depth[:2]
'''


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    dist = tmp_path / "longslam_test_sensors-0.1.dist-info"
    dist.mkdir()
    (tmp_path / "longslam_test_sensors.py").write_text(PLUGIN)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: longslam-test-sensors\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(
        "[longslam.sensors]\ndusty = longslam_test_sensors:Dusty\nbroken = longslam_test_sensors:Broken\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def test_a_model_of_ones_own_through_the_entry_point(plugin, tmp_path, capsys):
    assert {"dusty", "broken"} <= set(sensor_names())
    model = get_sensor("dusty")
    assert not model.is_ideal
    path, truth, _ = write_tiny_sequence(tmp_path / "seq", n=4)
    reader = SequenceReader(path)
    frames = list(sensed_frames(reader, model, 0, camera_motions(truth)))
    assert any((f.depth == 0).any() for f in frames)
    with pytest.raises(InputError, match="sensor 'broken', frame 0: sense\\(\\) returned depth"):
        sensed_frame(reader.frame(0), get_sensor("broken"), 0, FrameMotion.still()).depth
    capsys.readouterr()
    main(["list"])
    assert "dusty" in capsys.readouterr().out


def test_an_unknown_sensor_names_the_valid_ones():
    with pytest.raises(UnknownNameError, match=r"unknown sensor 'kinect' \(did you mean 'kinect-v1'\?\); "
                                               "valid sensor names: ideal, kinect-v1, realsense-d435"):
        get_sensor("kinect")


def test_cli_simulate_refuses_an_unknown_sensor_before_rendering(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    code = main(["simulate", "--route", "demo", "--sensor", "kinect", "--out", str(tmp_path / "seq")])
    assert code != 0
    one_line_error(capsys, "unknown sensor 'kinect'", "kinect-v1")
    assert not (tmp_path / "cache").exists() and not (tmp_path / "seq").exists()


def test_longslam_list_names_the_sensors(capsys):
    main(["list"])
    assert "sensors:      ideal, kinect-v1, realsense-d435" in capsys.readouterr().out


def test_the_builtin_models_describe_their_constants():
    described = catalog.get_sensor("kinect-v1").describe()
    assert described["name"] == "kinect-v1" and described["baseline"] == 0.075 and described["focal_px"] == 580.0
    assert get_sensor("ideal").describe() == {"name": "ideal"}
