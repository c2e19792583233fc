"""How far a frame's depth can be trusted, measured from the frame itself.

A real depth camera's noise grows with range: as z^2 for a structured-light or stereo camera
(sigma_z = sigma_w z^2 for a constant noise sigma_w in inverse depth, 1/m: a Kinect's disparity
noise, a D435's subpixel matching error). On a smooth surface inverse depth is affine in the
pixel coordinates (a plane's 1/z is), so the second difference of 1/z along a row is zero but
for the noise, whose own share has std sqrt(6) sigma_w. Its median absolute value over a frame
(depth edges are the outliers a median ignores) gives sigma_w with no knowledge of the sensor,
and with it the range where sigma_z stays below what a method can use (`max_sigma`): RTAB-Map's
Grid/RangeMax and Vis/MaxDepth, set per sensor by hand, here set by the frame.

A rendered frame (the ideal sensor) measures below `exact_below`: its only noise is the 16-bit
PNG's rounding (0.2 mm), and it is used as it is, so an ideal run is unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from longslam.core.depth_cut import depth_within
from longslam.core.parameter import check_declared, param

MAD_TO_STD = 1.4826  # a Gaussian's std over its median absolute deviation


@dataclass(frozen=True)
class DepthTrust:
    use: bool = param(True, "measure each frame's depth noise; false: every return is used, however noisy")
    max_sigma: float = param(0.03, "the axial noise a return may have and be used", above=0, unit="m")
    exact_below: float = param(
        1e-4, "inverse-depth noise below this is rounding (1.6 mm at 4 m)", at_least=0, unit="1/m"
    )
    # A shorter trusted range leaves too little of a corridor to register a scan or track corners on
    # (a D435's 1.7 m).
    min_range: float = param(2.5, "trusted range under which a frame's step is the wheels' alone", at_least=0, unit="m")
    min_pixels: int = param(
        500, "fewer valid pixel triples than this: too little to measure, depth used as it is", at_least=0
    )
    stride: int = param(2, "every this many image rows sampled to measure the noise", at_least=1)
    # A Kinect v1 measures 1.7e-3 1/m, a D435 1e-2, rendered depth below 1e-5 (exact: weight 1).
    scan_noise_half: float = param(
        5e-5, "inverse-depth noise at which a scan's information is halved (0: never)", at_least=0, unit="1/m"
    )

    # A loop is verified from a similar viewpoint, where a return's range noise mostly runs along
    # the ray it is seen on again; PnP and the 3D-3D check weigh it by its noise (place_recognition).
    loop_max_sigma: float = param(0.1, "depth under min_range: a loop feature's most range noise", above=0, unit="m")
    # Loop features on depth cut at its trusted range (a Kinect v1's 4.2 m) leave most of a place's
    # corners without a point to match by PnP; the 3D-3D support check (the methods'
    # loop_min_depth_support) and the graph's error check still hold each loop. Depth too noisy for
    # a scan (a D435's) keeps the methods' count: its loop features reach past the trusted range.
    # Chosen on paper-300m Kinect v1 seeds 10-14 (docs/sensors.md).
    loop_inlier_share: float = param(
        0.75, "loops on depth cut at a trusted range: share of the method's PnP inliers they need", above=0, at_most=1
    )

    # A column's returns in the height band measure one range on a wall: averaged, their noise
    # falls with their number, so the scan reaches past the trusted range (ScanExtractor.columns).
    scan_columns: bool = param(
        True, "noisy depth: the scan is one averaged point per image column, weighed by its own noise"
    )
    column_returns: int = param(4, "returns a column's point needs", at_least=1)
    column_max_sigma: float = param(0.05, "a column point with more range noise is left out", above=0, unit="m")
    column_correlation: float = param(
        1.0, "pixels over which a column's depth noise is correlated (1: independent)", at_least=1, unit="px"
    )
    # Under 1: a column's mean keeps what its returns share (a Kinect v1's disparity step is the
    # same for every return of a column on a wall facing it), and the local map is made of the same
    # noisy scans; with the RGB-D heading at visual_sigma_yaw 0.001 the scans' full weight pulled
    # it. Chosen among 0.1, 0.25 and 1 on paper-300m Kinect seeds 10-14 (docs/sensors.md).
    column_information: float = param(
        0.25, "factor on a column scan's registration information (instead of scan_noise_half's)", at_least=0
    )

    def __post_init__(self) -> None:
        check_declared(self, "front end", "depth_trust.")


def inverse_depth_noise(depth: np.ndarray, stride: int = 2) -> tuple[float, int] | None:
    """(sigma_w in 1/m, the number of pixel triples it was measured on) of a depth image
    (metres, 0 = no return), or None if no triple is valid."""
    z = np.asarray(depth, dtype=np.float32)[::stride]
    valid = z > 0
    w = np.divide(1.0, z, out=np.zeros_like(z), where=valid)
    both = valid[:, 2:] & valid[:, 1:-1] & valid[:, :-2]
    second = (w[:, 2:] - 2.0 * w[:, 1:-1] + w[:, :-2])[both]
    if second.size == 0:
        return None
    return float(MAD_TO_STD * np.median(np.abs(second)) / math.sqrt(6.0)), int(second.size)


def measured_noise(depth: np.ndarray, trust: DepthTrust = DepthTrust()) -> float | None:
    """`depth`'s inverse-depth noise sigma_w (1/m); None for depth that is exact (or too sparse
    to measure, or `trust.use` off): use it as it is."""
    if not trust.use:
        return None
    measured = inverse_depth_noise(depth, trust.stride)
    if measured is None:
        return None
    sigma_w, count = measured
    if count < trust.min_pixels or sigma_w < trust.exact_below:
        return None
    return sigma_w


def range_for_noise(sigma_w: float | None, trust: DepthTrust = DepthTrust()) -> float | None:
    """The range (m) up to which axial noise sigma_w z^2 stays within `trust.max_sigma`."""
    return None if sigma_w is None else math.sqrt(trust.max_sigma / sigma_w)


def trusted_range(depth: np.ndarray, trust: DepthTrust = DepthTrust()) -> float | None:
    """The range (m) up to which `depth`'s noise stays within `trust.max_sigma`; None for depth
    that is exact (or too sparse to measure): use it all."""
    return range_for_noise(measured_noise(depth, trust), trust)


def too_noisy_for_scan(limit: float | None, trust: DepthTrust = DepthTrust()) -> bool:
    """Whether depth trusted to `limit` (m; None: exact) is too noisy for a scan: under `min_range`
    too little of a corridor is left to register on. Such depth (a D435's) is used noise-weighed
    instead: the front end's RGB-D steps and the methods' loops take all of it (docs/sensors.md)."""
    return limit is not None and limit < trust.min_range


def scan_weight(sigma_w: float | None, trust: DepthTrust = DepthTrust()) -> float:
    """The factor on a cell scan's registration information (in the online filter and the final
    smoother) for depth of inverse-depth noise sigma_w: 1 / (1 + (sigma_w / scan_noise_half)^2),
    exactly 1 for exact depth. Noisy frames take a column scan instead, each point weighed by its
    own noise (`scan_columns`); this factor serves with `scan_columns` off.

    Far smaller than the scan's own noise would ask for, on purpose: the local map is made of the
    same noisy scans, so consecutive registrations share its errors, and the front end's bias
    states take that slowly varying error for a wheel bias; so a weight that only makes each scan
    consistent with the truth on its own is not enough. Scans are weighted down rather than
    dropped: a weak scan still holds the heading to the local map, which the visual steps' heading
    does not (docs/sensors.md)."""
    if sigma_w is None or not trust.use or trust.scan_noise_half <= 0:
        return 1.0
    return 1.0 / (1.0 + (sigma_w / trust.scan_noise_half) ** 2)


def trusted_depth(depth: np.ndarray, limit: float | None) -> np.ndarray:
    """`depth` with the returns beyond `limit` removed; `depth` itself when there is no limit."""
    return depth if limit is None else depth_within(depth, limit)
