"""The front end shared by the SLAM methods: per-frame planar motion from wheels and depth.

    fe = FrontEnd(intrinsics, FrontEndConfig())
    for frame in sequence:
        x, y, yaw = fe.step(frame)            # online, robot base on the floor
    fe.add_loop(i, j, delta_xyyaw, info)      # frame j in frame i's frame, 3x3 information (body)
    final = fe.final_trajectory()             # (N, 3), a smoother over every frame

Modes:
- "fused" (default): wheel steps with their biases estimated, corrected by scan-to-map
  registration of the depth band 0.2-1.5 m above the floor. Without wheel odometry in the
  frames it runs on the scans alone with a constant-velocity prediction, and says so in `stats`.
- "wheel": the wheel odometry alone, with steps no robot makes in one frame (jumps) replaced by
  no motion; the paper's configuration. It needs odometry in every frame. The final trajectory
  is the online one until a method adds loops; then the smoother spreads their corrections
  over the frames, trusting the wheel steps as given (no bias states).
"""

from __future__ import annotations

import math
import time
from array import array
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Frame, Intrinsics
from longslam.core.geometry import CameraMount, JumpFilteredOdometry, relative_xyyaw, wrap_angle
from longslam.core.memory_release import release_free_memory
from longslam.core.parameter import check_declared, nested, param
from longslam.slam.api import Table
from longslam.slam.depth_trust import (
    DepthTrust,
    measured_noise,
    range_for_noise,
    scan_weight,
    too_noisy_for_scan,
    trusted_depth,
    trusted_range,
)
from longslam.slam.frontend.ahead import AheadWorker, FrameAhead
from longslam.slam.frontend.filter import BiasFilter, MotionNoise
from longslam.slam.frontend.local_map import LocalMap, LocalMapConfig
from longslam.slam.frontend.registration import RegistrationConfig, information_in_body, register
from longslam.slam.frontend.scan import ScanConfig, ScanExtractor
from longslam.slam.frontend.smoother import FullSmoother, SmootherConfig
from longslam.slam.frontend.visual import VisualConfig, VisualOdometry
from longslam.slam.frontend.visual_gates import GateBounds, VisualGates
from longslam.slam.frontend.wall_axes import WallAxes, WallAxesConfig
from longslam.slam.graph import Edge
from longslam.slam.graph.factors import WheelStep
from longslam.slam.rows import Rows

relative = relative_xyyaw

MODES = ("fused", "wheel")
# loops.csv: frame i, frame j, j's base pose in i's frame, and the constraint's information (the
# upper triangle of its 3x3 matrix, in GTSAM's Pose2 tangent: body dx, dy, dyaw).
LOOP_COLUMNS = (
    "frame_i",
    "frame_j",
    "dx_m",
    "dy_m",
    "dyaw_rad",
    "info_xx",
    "info_xy",
    "info_xyaw",
    "info_yy",
    "info_yyaw",
    "info_yawyaw",
)
# frontend.csv: see `FrontEnd.frame_table`.
FRAME_COLUMNS = ("frame", "wheel", "visual", "scan", "scan_shift_m", "scan_turn_deg")
SCAN_REGISTERED, SCAN_REFUSED = 1.0, -1.0
# Below this forward step (m) the robot is turning in place: the wheels' forward bias is not added.
TRANSLATING_STEP = 1e-4
# The focal length `visual_sigma_yaw` is given for: the paper's camera, 320 px across 90 degrees.
REFERENCE_FOCAL_PX = 160.0


@dataclass(frozen=True)
class FrontEndConfig:
    mode: str = param(
        "fused", "fused: wheels, scans and RGB-D steps; wheel: the wheel odometry alone (the paper's)", choices=MODES
    )
    camera_height: float | None = param(
        None,
        "camera height above the floor; none: the first odometry pose's z, or default_camera_height without odometry",
        above=0,
        unit="m",
    )
    default_camera_height: float = param(
        1.25, "camera height above the floor when neither camera_height nor odometry gives it", above=0, unit="m"
    )
    jump_distance: float = param(1.0, "a bigger odometry step in one frame is a jump, not motion", above=0, unit="m")
    jump_angle: float = param(0.8, "a bigger odometry turn in one frame is a jump, not motion", above=0, unit="rad")
    use_bias: bool = param(True, "estimate the wheels' forward and heading biases")
    scan_anchor_lag: int = param(
        20, "a scan factor links a frame to the one this many before", at_least=1, unit="frames"
    )
    # A negative scale turns scan factors into repulsion.
    scan_information_scale: float = param(1.0, "scale of the registration's Hessian, in the full smoother", at_least=0)
    max_correction: float = param(0.5, "a registration moving the prediction further is refused", at_least=0, unit="m")
    max_correction_angle: float = param(
        0.1, "a registration turning the prediction further is refused", at_least=0, unit="rad"
    )
    insert_distance: float = param(
        0.05, "distance moved (or insert_angle turned) before a scan joins the map", at_least=0, unit="m"
    )
    insert_angle: float = param(
        0.03, "angle turned (or insert_distance moved) before a scan joins the map", at_least=0, unit="rad"
    )
    # They give forward distance in corridors, where the scan has nothing along the way.
    visual: bool = param(
        True, "gated RGB-D steps (tracked corners with depth), accepted within the gates of the predicted step"
    )
    visual_gate_distance: float = param(
        0.04, "an RGB-D step is accepted within this of the wheel step", at_least=0, unit="m"
    )
    visual_gate_angle: float = param(
        0.01, "an RGB-D step is accepted within this of the wheel step's heading change", at_least=0, unit="rad"
    )
    visual_gate_sigmas: float = param(4.0, "forward gate in stds of the forward-bias innovation", above=0)
    visual_max_bias: float = param(
        0.1, "an RGB-D step further than this from the raw wheel step is wrong", at_least=0, unit="m per step"
    )
    visual_bias_reset_after: int = param(5, "consecutive forward refusals that widen the bias's variance", at_least=0)
    visual_gate_distance_no_wheels: float = param(
        0.3, "the gate around the constant-velocity prediction without wheels", at_least=0, unit="m"
    )
    visual_gate_angle_no_wheels: float = param(
        0.2, "the heading gate around the constant-velocity prediction without wheels", at_least=0, unit="rad"
    )
    visual_sigma_forward: float = param(0.004, "std of an RGB-D step's forward component", above=0, unit="m per step")
    visual_sigma_lateral: float = param(
        0.05, "std of an RGB-D step's lateral component (the wheels hold it)", above=0, unit="m per step"
    )
    # About twice the refitted step's scatter (0.0004-0.0005 rad a step on paper-300m, ideal and
    # Kinect v1 frames): with the corners that lock onto a floor tile's next grout line left out
    # (`visual_tracking.arc_max_residual`), its bias is small enough to outvote the wheels', and a
    # looser sigma leaves a wheel bias unseen where no scan registers.
    visual_sigma_yaw: float = param(
        0.001,
        "std of an RGB-D step's heading change at a focal length of 160 px (320 px across 90 deg); "
        "it scales as 160 / fx, a pixel's angle",
        above=0,
        unit="rad per step",
    )
    # A D435's depth, trusted to 1.7 m, gives no scan; its corners still fix each step's heading.
    visual_noisy: bool = param(True, "depth under depth_trust.min_range: RGB-D steps on all of it, noise-weighed")
    visual_noisy_sigma_scale: float = param(2.0, "noisy depth: factor on an RGB-D step's fitted stds", above=0)
    visual_sigmas_no_wheels: tuple[float, float, float] = param(
        (0.004, 0.005, 0.002),
        "stds of an RGB-D step without wheels (forward m, lateral m, yaw rad): its measured scatter",
        above=0,
    )
    scan: ScanConfig = nested(ScanConfig, "the 2D scan cut from each depth image")
    visual_tracking: VisualConfig = nested(VisualConfig, "the corners tracked for RGB-D steps")
    local_map: LocalMapConfig = nested(LocalMapConfig, "the recent scans a scan is registered to")
    registration: RegistrationConfig = nested(RegistrationConfig, "scan-to-map registration")
    noise: MotionNoise = nested(MotionNoise, "per-frame noise of the wheel step and of its biases")
    smoother: SmootherConfig = nested(SmootherConfig, "the batch smoother over every frame, run at the end")
    depth_trust: DepthTrust = nested(DepthTrust, "how far a frame's depth is trusted, measured from the frame")
    wall_axes: WallAxesConfig = nested(WallAxesConfig, "the building's wall directions as a heading reference")

    def __post_init__(self) -> None:
        check_declared(self, "front end")


@dataclass(frozen=True)
class FrameStep:
    """What the front end made of one frame, for the method that stepped it: the robot base's
    planar pose (online), and the range to which the frame's depth can be trusted, measured from the
    frame's own noise when the step looked at its depth (fused), else measured on first ask."""

    index: int
    xyyaw: np.ndarray  # (3,) x, y, yaw of the robot base
    depth_trust: DepthTrust
    depth_measured: bool  # whether `depth_limit` is the step's measurement
    depth_limit: float | None  # metres; None: every return trusted

    def depths(self, depth: np.ndarray) -> MethodDepths:
        """`depth` (the frame's depth image as the method holds it) without the returns beyond what
        the frame's own noise lets be trusted (depth_trust), and the depth for loop features with
        the noise they are verified and weighed at, the trusted range measured once. Depth too noisy
        for a scan (trusted to less than `min_range`, a D435's) gives loops the returns within
        `depth_trust.loop_max_sigma` of noise and its sigma_w; other depth gives them the trusted
        depth, verified as exact; where that depth was cut at a trusted range (a Kinect's), fewer of
        the loop features have a point to match, so a loop needs `depth_trust.loop_inlier_share` of
        the method's PnP inliers."""
        trust = self.depth_trust
        limit = self._limit(depth)
        trusted = trusted_depth(depth, limit)
        if not too_noisy_for_scan(limit, trust):
            return MethodDepths(trusted, trusted, None, 1.0 if limit is None else trust.loop_inlier_share)
        assert limit is not None  # depth too noisy for a scan was measured
        loops = trusted_depth(depth, limit * math.sqrt(trust.loop_max_sigma / trust.max_sigma))
        return MethodDepths(trusted, loops, trust.max_sigma / (limit * limit))

    def _limit(self, depth: np.ndarray) -> float | None:
        return self.depth_limit if self.depth_measured else trusted_range(depth, self.depth_trust)


class MethodDepths(NamedTuple):
    """A frame's depth as a method uses it (`FrameStep.depths`)."""

    trusted: np.ndarray  # for the maps: the returns within the trusted range
    loops: np.ndarray  # for loop and proximity features
    loop_noise: float | None  # inverse-depth noise sigma_w (1/m) the loops are verified at; None: exact
    loop_inlier_share: float = 1.0  # of the method's PnP inliers a loop from this frame needs

    def loop_min_inliers(self, method_min_inliers: int) -> int:
        """The PnP inliers a loop from this frame needs, for a method that asks `method_min_inliers`."""
        return max(1, round(method_min_inliers * self.loop_inlier_share))


class FrontEnd:
    """Per-frame planar motion for a SLAM method (see the module's docstring). Not thread-safe;
    one instance per sequence."""

    def __init__(self, intrinsics: Intrinsics, config: FrontEndConfig | None = None):
        self.config = config or FrontEndConfig()
        self.intrinsics = intrinsics
        # The step's heading is read from where its corners are seen: it scatters by a share of a
        # pixel, so a coarser image's steps count for less (an 80 px wide one's at 4x the std).
        self._visual_sigma_yaw = self.config.visual_sigma_yaw * (REFERENCE_FOCAL_PX / intrinsics.fx)
        self.mount: CameraMount | None = None  # known at the first frame
        self._extract: ScanExtractor | None = None
        self._gates: VisualGates | None = None
        self._filter: BiasFilter | None = None
        self._map = LocalMap(self.config.local_map)
        # In "wheel" mode the smoother (used only when loops are added) trusts the wheels as given.
        self._smoother = FullSmoother(
            self.config.noise, self.config.smoother, use_bias=self.config.use_bias and self.config.mode == "fused"
        )
        self._wheels: JumpFilteredOdometry | None = None
        self._odom: np.ndarray | None = None  # jump-corrected wheel odometry of the latest frame
        self._has_wheels: bool | None = None
        self._online = Rows((3,))  # every frame's online pose
        self._last_insert: np.ndarray | None = None
        self._time = 0.0
        # A row per frame (FRAME_COLUMNS) for `frame_table`: which factors the frame had, and how
        # far the scan moved the prediction. Flat doubles: 48 bytes a frame however long the route.
        self._frame_rows = array("d")
        self._frame_scan = (0.0, 0.0, 0.0)  # (state, shift m, turn deg) of the latest fused frame
        self._visual_used = False
        self.counts = {
            "frames": 0,
            "odometry_jumps": 0,
            "visual_accepted": 0,
            "visual_refused": 0,
            "visual_failed": 0,
            "forward_bias_resets": 0,
            "scans_registered": 0,
            "scans_refused": 0,
            "scans_unmatched": 0,
            "scan_points": 0,
            "loops": 0,
            "depth_limited": 0,
            "depth_too_noisy": 0,
            "scans_weighted": 0,
            "column_scans": 0,
            "wall_headings": 0,
        }
        self._axes = WallAxes(self.config.wall_axes) if self.config.wall_axes.use else None
        self._range_sum = 0.0  # of the trusted ranges of the frames whose depth was limited
        self._depth_limit: float | None = None  # the latest fused frame's trusted range
        self._depth: np.ndarray | None = None
        self._ahead = AheadWorker(
            intrinsics, self.config.depth_trust, self.config.visual_tracking if self.config.visual else None
        )

    # --- per frame ---------------------------------------------------------------------------
    def step(self, frame: Frame) -> FrameStep:
        """What the front end made of this frame: its planar (x, y, yaw) of the robot base, online,
        and the depth's trusted range (see `FrameStep`)."""
        t0 = time.perf_counter()
        k = len(self._online)
        if self._has_wheels is None:
            self._has_wheels = frame.odometry is not None
            self._start(frame)
        elif (frame.odometry is not None) != self._has_wheels:
            raise InputError(f"frame {frame.index}: odometry present in some frames and not in others")
        wheel = self._wheel_step(frame) if self._has_wheels else None
        if self.config.mode == "wheel":
            assert self._odom is not None  # mode "wheel" has odometry in every frame: `_wheel_step` set it
            pose = self._odom.copy()
            self._visual_used = False
            self._smoother.add_frame(pose, wheel, self._wheel_sigmas(wheel), None, None, None)
        else:
            self._frame_scan = (0.0, 0.0, 0.0)
            pose = self._fused_step(k, frame, wheel)
        self._frame_rows.extend((k, wheel is not None, self._visual_used, *self._frame_scan))
        self._online.append(pose)
        self._ahead.stepped = frame.index  # the frame stepped last
        self.counts["frames"] += 1
        self._time += time.perf_counter() - t0
        # A fused step measured this frame's trusted range; on wheels alone the method measures it.
        fused = self.config.mode == "fused"
        limit = self._depth_limit if fused else None
        return FrameStep(frame.index, pose.copy(), self.config.depth_trust, fused, limit)

    def work_ahead(self, frame: Frame) -> FrameAhead | None:
        """Work out ahead, on the engine's read-ahead thread, what the fused step computes from
        this frame's images alone (`ahead.py`); `step` takes it. Frames come in order, each before
        its step. Nothing on wheels alone, which does not look at the images."""
        if self.config.mode != "fused":
            return None
        return self._ahead.work(frame)

    @property
    def images_every_frame(self) -> tuple[str, ...]:
        """The images `step` reads on every frame: none on wheels alone (a method may read them
        lazily for its own keyframes), colour and depth when fused."""
        return ("rgb", "depth") if self.config.mode == "fused" else ()

    def _start(self, frame: Frame) -> None:
        cfg = self.config
        if frame.odometry is None and cfg.mode == "wheel":
            raise InputError(
                f"frame {frame.index} (t={frame.timestamp:.6f}) has no odometry pose; the front end's "
                f"mode 'wheel' needs a sequence with odometry.txt (mode 'fused' runs without)"
            )
        if frame.odometry is not None:
            self.mount = CameraMount.from_first_pose(np.asarray(frame.odometry, dtype=np.float64), cfg.camera_height)
            self._wheels = JumpFilteredOdometry(self.mount, cfg.jump_distance, cfg.jump_angle)
        else:
            self.mount = CameraMount(cfg.default_camera_height if cfg.camera_height is None else cfg.camera_height, 0.0)
            self._odom = np.zeros(3)  # a sequence without odometry starts at the origin
        self._extract = ScanExtractor(self.intrinsics, self.mount.camera_in_base, cfg.scan)
        tracker = None
        if cfg.visual and cfg.mode == "fused":
            tracker = VisualOdometry(
                self.intrinsics,
                self.mount.camera_in_base,
                cfg.visual_tracking,
                correlated=cfg.depth_trust.column_correlation,
            )
        self._gates = VisualGates(
            tracker,
            GateBounds(
                cfg.visual_gate_distance,
                cfg.visual_gate_angle,
                cfg.visual_gate_sigmas,
                cfg.visual_max_bias,
                cfg.visual_bias_reset_after,
                cfg.noise.bias_forward_reset,
                cfg.use_bias,
            ),
            self.counts,
        )
        self._filter = BiasFilter(np.zeros(3), cfg.noise, use_bias=cfg.use_bias and bool(self._has_wheels))

    @property
    def camera_height(self) -> float | None:
        return None if self.mount is None else self.mount.camera_height

    @property
    def floor_z(self) -> float:
        return 0.0 if self.mount is None else self.mount.floor_z

    def _wheel_step(self, frame: Frame) -> WheelStep | None:
        previous = self._odom
        assert self._wheels is not None and self._filter is not None  # `_start` made them: the frames have odometry
        self._odom = self._wheels.update(np.asarray(frame.odometry, dtype=np.float64), frame.timestamp)
        self.counts["odometry_jumps"] = self._wheels.jumps
        if previous is None:
            self._filter.place(self._odom)
            return None
        delta = relative(previous, self._odom)
        return WheelStep(float(delta[0]), float(delta[1]), float(delta[2]), abs(delta[0]) > TRANSLATING_STEP)

    def _wheel_sigmas(self, wheel: WheelStep | None) -> np.ndarray | None:
        if wheel is None:
            return None
        n = self.config.noise
        return np.array(
            [n.forward_min + n.forward_rel * abs(wheel.forward), n.lateral, n.yaw_min + n.yaw_rel * abs(wheel.yaw)]
        )

    def _fused_step(self, k: int, frame: Frame, wheel: WheelStep | None) -> np.ndarray:
        cfg = self.config
        ahead = self._ahead.take(frame.index)
        visual_ahead = None if ahead is None else ahead.visual_after(self._ahead.stepped)
        # Scans and tracked corners only where the frame's own depth noise allows (depth_trust).
        sigma_w = ahead.sigma_w if ahead is not None else measured_noise(frame.depth, cfg.depth_trust)
        limit = range_for_noise(sigma_w, cfg.depth_trust)
        self._depth_limit = limit
        trust = cfg.depth_trust
        no_scan = too_noisy_for_scan(limit, trust)
        # Depth too noisy for a scan (a D435's) makes no column scan either: alone, without RGB-D
        # steps, it moved the heading by as much as the wheels' drift.
        columns = limit is not None and not no_scan and trust.scan_columns
        weight = trust.column_information if columns else scan_weight(sigma_w, trust)
        if weight < 1.0:
            self.counts["scans_weighted"] += 1
        if columns:
            self.counts["column_scans"] += 1
        full_depth = frame.depth
        # Depth too noisy for a scan reaches the corner tracker whole, with its noise; depth that
        # gives a scan (a Kinect's) is tracked within its trusted range, where the scan holds the
        # heading (tracked on all of it, the corners' heading pulled against the scan's).
        noisy_tracking = cfg.visual_noisy and no_scan
        whole = frame
        self._depth = ahead.trusted if ahead is not None else trusted_depth(frame.depth, limit)
        if limit is not None:
            self.counts["depth_limited"] += 1
            self._range_sum += limit
            if no_scan:  # nothing to register on
                self.counts["depth_too_noisy"] += 1
                self._depth = np.zeros_like(self._depth)
            clean = frame
            frame = Frame(
                clean.index, clean.timestamp, lambda: clean.rgb, self._depth, clean.odometry, clean.intrinsics
            )
        tracked, tracked_noise = (whole, sigma_w) if noisy_tracking else (frame, None)
        flt = self._filter
        assert flt is not None and self._gates is not None and self._extract is not None  # `_start` made them
        cv_step = None
        visual = None
        vis_sigmas = np.array([cfg.visual_sigma_forward, cfg.visual_sigma_lateral, self._visual_sigma_yaw])
        if wheel is not None:
            bias = flt.bias if cfg.use_bias else np.zeros(2)
            expected = np.array(
                [wheel.forward - (bias[0] if wheel.moving else 0.0), wheel.lateral, wheel.yaw - bias[1]]
            )
            bias_var = flt.forward_bias_variance if cfg.use_bias else 0.0
            flt.predict_wheel(wheel)
            accepted = self._gates.against_wheels(
                tracked,
                wheel,
                expected,
                bias_var,
                self._wheel_variances(wheel)[0],
                vis_sigmas[0],
                flt,
                tracked_noise,
                visual_ahead,
            )
            visual = None if accepted is None else accepted.step
            if accepted is not None and accepted.covariance is not None:
                fitted = cfg.visual_noisy_sigma_scale * np.sqrt(np.diag(accepted.covariance))
                vis_sigmas = np.maximum(vis_sigmas, fitted)
            if visual is not None and cfg.use_bias:
                raw = np.array([wheel.forward, wheel.yaw])
                flt.update_bias(
                    raw - visual[[0, 2]], self._wheel_variances(wheel) + vis_sigmas[[0, 2]] ** 2, wheel.moving
                )
        elif k > 0:
            # No wheels: the visual step where it tracks, else the last step again (constant
            # velocity), loosely.
            cv = relative(self._online.row(-2), self._online.row(-1)) if k > 1 else np.zeros(3)
            accepted = self._gates.against_prediction(
                frame, cv, cfg.visual_gate_distance_no_wheels, cfg.visual_gate_angle_no_wheels, visual_ahead
            )
            visual = None if accepted is None else accepted.step
            vis_sigmas = np.asarray(cfg.visual_sigmas_no_wheels, dtype=np.float64)
            if visual is not None:
                flt.predict_step(visual, vis_sigmas)
            else:
                cv_step = cv
                flt.predict_constant_velocity(cv_step)
        else:
            self._gates.first(tracked, tracked_noise, visual_ahead)
        predicted = flt.pose
        scan_sigma = None
        if columns:
            assert sigma_w is not None  # `columns` needs measured noise
            scan, scan_sigma = self._extract.columns(
                full_depth, sigma_w, trust.column_returns, trust.column_max_sigma, trust.column_correlation
            )
        else:
            scan = self._extract(self._depth)
        self.counts["scan_points"] += len(scan)
        scan_factor = None
        if self._map.tree is not None:
            reg = register(scan, predicted, self._map, flt.pose_information(), cfg.registration, weight, scan_sigma)
            if not reg.ok:
                self.counts["scans_unmatched"] += 1
            else:
                d = reg.pose - predicted
                shift, turn = float(np.hypot(d[0], d[1])), float(np.degrees(abs(wrap_angle(d[2]))))
                if np.hypot(d[0], d[1]) > cfg.max_correction or abs(wrap_angle(d[2])) > cfg.max_correction_angle:
                    self.counts["scans_refused"] += 1
                    self._frame_scan = (SCAN_REFUSED, shift, turn)
                else:
                    self.counts["scans_registered"] += 1
                    self._frame_scan = (SCAN_REGISTERED, shift, turn)
                    flt.update_pose(reg.pose, reg.hessian)
                    anchor = max(0, k - cfg.scan_anchor_lag)
                    if anchor < k:
                        scan_factor = (
                            anchor,
                            relative(self._online.row(anchor), reg.pose),
                            cfg.scan_information_scale * information_in_body(reg.hessian, reg.pose[2]),
                        )
        pose = flt.pose
        if self._axes is not None and len(scan):
            sigma = float(np.radians(cfg.wall_axes.sigma_deg))
            for frame_k, heading, direction in self._axes.measure(
                k, float(pose[2]), scan, float(np.sqrt(flt.cov[2, 2]))
            ):
                self.counts["wall_headings"] += 1
                assert self._axes.axes is not None  # measurements come once the axes have settled
                self._smoother.axes_initial = float(self._axes.axes)
                self._smoother.add_wall(frame_k, direction, sigma)
                if frame_k == k:  # online too, so the next measurement is gated against a held heading
                    flt.update_heading(heading, sigma)
                    pose = flt.pose
        last = self._last_insert
        if len(scan) and (
            last is None
            or np.hypot(*(pose[:2] - last[:2])) >= cfg.insert_distance
            or abs(wrap_angle(pose[2] - last[2])) >= cfg.insert_angle
        ):
            self._map.insert(pose, scan)
            self._last_insert = pose
        self._visual_used = visual is not None
        self._smoother.add_frame(
            pose,
            wheel,
            self._wheel_sigmas(wheel),
            cv_step,
            scan_factor,
            flt.bias if wheel is not None else None,
            None if visual is None else (visual, vis_sigmas),
        )
        return pose

    def _wheel_variances(self, wheel: WheelStep) -> np.ndarray:
        n = self.config.noise
        return np.array(
            [(n.forward_min + n.forward_rel * abs(wheel.forward)) ** 2, (n.yaw_min + n.yaw_rel * abs(wheel.yaw)) ** 2]
        )

    # --- loops and the end ---------------------------------------------------------------------
    def add_loop(self, frame_i: int, frame_j: int, delta_xyyaw: np.ndarray, information: np.ndarray) -> None:
        """A constraint: frame j's base pose in frame i's base frame, with 3x3 information in
        GTSAM's Pose2 tangent (body dx, dy, dyaw)."""
        n = len(self._online)
        if not (0 <= frame_i < n and 0 <= frame_j < n):
            raise InputError(f"front end: loop between frames {frame_i} and {frame_j}, but {n} frames seen")
        self._smoother.add_loop(frame_i, frame_j, delta_xyyaw, information)
        self.counts["loops"] += 1

    def add_graph_edges(self, edges: Iterable[Edge], frame_of: Mapping[int, int] | Sequence[int]) -> None:
        """A method's graph edges (between keyframes, submap origins...) as constraints between the
        frames its nodes were made at: `frame_of[node]` is that frame's index."""
        for edge in edges:
            self.add_loop(frame_of[edge.a], frame_of[edge.b], np.array(edge.delta), edge.information)

    def online_trajectory(self) -> np.ndarray:
        return self._online.array()

    def final_trajectory(self, held: Mapping[int, np.ndarray] | None = None) -> np.ndarray:
        """(N, 3) planar poses of every frame from the smoother over all frames. In wheel mode
        without loops this is the online trajectory itself. `held`: a method's optimised graph
        nodes ({frame: pose}); in wheel mode, or on a route longer than `smoother.hold_nodes_beyond`
        frames, they are held and the frames between smoothed chunk by chunk
        (`FullSmoother.solve_held`).

        Wheel mode holds them on any route: its frames have nothing but the wheel steps, taken as
        given (the lateral step all but fixed), and a solve over every frame has to bend those
        steps to meet each loop, where the method's graph, whose node links allow for the wheels'
        drift, already placed its nodes with the loops it checked. Held, the frames between two
        nodes only follow the wheels from one to the next, at a fraction of the cost."""
        if self.config.mode == "wheel" and not self._smoother.loops:
            return self.online_trajectory()
        poses = self._smoother.solve(held, hold=self.config.mode == "wheel")
        # The solve's graphs are gone; what comes next (a method's map) should not start on top
        # of their freed heap.
        release_free_memory()
        return poses

    def camera_poses(self, xyyaw: np.ndarray) -> np.ndarray:
        """(N, 3) planar poses -> (N, 4, 4) camera-in-world poses (after the first frame)."""
        assert self.mount is not None  # placed at the first frame
        return self.mount.to_camera(np.asarray(xyyaw).reshape(-1, 3))

    def frame_table(self) -> Table:
        """A row per frame: whether it had a wheel step and an accepted visual step, its scan's
        fate (1 registered, -1 refused as too large a correction, 0 none or unmatched) and how far
        the scan moved the predicted pose (m, deg): the run folder's frontend.csv, which
        `longslam diagnose` reads."""
        return Table(
            FRAME_COLUMNS, np.frombuffer(self._frame_rows, dtype=np.float64).reshape(-1, len(FRAME_COLUMNS)).copy()
        )

    def loop_table(self) -> Table:
        """Every constraint a method added (`add_loop`), so that a benchmark can check each
        against ground truth: the run folder's loops.csv."""
        upper = np.triu_indices(3)
        rows = [
            [i, j, *map(float, delta), *np.asarray(info, dtype=np.float64)[upper]]
            for i, j, delta, info in self._smoother.loops
        ]
        return Table(LOOP_COLUMNS, np.array(rows, dtype=np.float64).reshape(-1, len(LOOP_COLUMNS)))

    @property
    def stats(self) -> dict[str, Any]:
        out: dict[str, Any] = dict(self.counts)
        out["mode"] = self.config.mode
        out["odometry_source"] = (
            "wheels"
            if self._has_wheels
            else "none: visual steps and scan registration (constant velocity where tracking fails)"
        )
        out["ms_per_frame"] = 1000.0 * self._time / max(self.counts["frames"], 1)
        if self._smoother.solved_by:
            out["final_solve"] = self._smoother.solved_by
        if self.counts["depth_limited"]:
            out["trusted_range_mean_m"] = self._range_sum / self.counts["depth_limited"]
        if self._axes is not None:
            # Measured wall directions: the first `settle` set the axes, `gated` were off them (a wing).
            out["wall_directions"] = {
                "measured": self._axes.measured,
                "gated": self._axes.gated,
                "axes_deg": None if self._axes.axes is None else float(np.degrees(self._axes.axes)),
            }
        if self._filter is not None and self._has_wheels and self.config.mode == "fused":
            out["bias_final"] = [float(b) for b in self._filter.bias]
        return out
