"""Each heading source's per-frame error against the ground truth over a stretch of a sequence.

    python benchmarks/heading_steps.py --sensor kinect-v1 --seed 1 --frames 0 200

For every step between consecutive frames: the wheels' heading change and the front end's RGB-D
step's (corners tracked within the depth's trusted range and fitted around the wheel step, as the
fused step does for depth that gives a scan: its heading refitted to the corners' bearings along
the wheels' arc, `visual_tracking.arc_fit`, and, beside it, the planar fit of the corners' 3D
positions alone), each minus the true change; and whether the scan cut
from the frame's trusted depth (the plain scan; the front end cuts a Kinect's by columns, which
reach as far) has enough points to register at all. It prints the mean (a bias, which adds up along the
stretch) and the std (a scatter, which adds up as a random walk) of each source, the heading error
the wheels gather over the stretch, and the share of frames without a scan, where nothing but the
wheels and the RGB-D steps holds the heading (issue 42: the Kinect v1 in a hall wider than its
range). The sequence is simulated under --work the first time it is asked for.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import sequence  # noqa: E402

from longslam.core.geometry import CameraMount, relative_xyyaw, wrap_angle  # noqa: E402
from longslam.io.sequence import SequenceReader  # noqa: E402
from longslam.slam.depth_trust import DepthTrust, trusted_depth, trusted_range  # noqa: E402
from longslam.slam.frontend.registration import RegistrationConfig  # noqa: E402
from longslam.slam.frontend.scan import ScanConfig, ScanExtractor  # noqa: E402
from longslam.slam.frontend.visual import VisualConfig, VisualOdometry  # noqa: E402


def heading_errors(path: Path, first: int, last: int) -> dict[str, np.ndarray]:
    """Per step from frame k-1 to k (first < k < last): the true heading change, the wheels' and
    the RGB-D step's errors (`rgbd`, the front end's; `rgbd_3d`, the planar 3D fit alone; NaN
    where no step was fitted), and the scan's point count at k."""
    reader = SequenceReader(path)
    if reader.ground_truth is None or reader.odometry is None:
        raise SystemExit(f"{path}: heading_steps needs groundtruth.txt and odometry.txt in the sequence")
    truth_poses = reader.ground_truth.poses
    trust = DepthTrust()
    mount = tracker = planar = extract = None
    previous: tuple[np.ndarray, np.ndarray] | None = None  # true and wheel planar poses
    rows = []
    for frame in reader:
        if frame.index >= last:
            break
        if frame.index < first:
            continue
        assert frame.odometry is not None  # the sequence has odometry.txt
        odometry = np.asarray(frame.odometry)
        if mount is None:
            mount = CameraMount.from_first_pose(odometry)
            tracker = VisualOdometry(reader.intrinsics, mount.camera_in_base)
            planar = VisualOdometry(reader.intrinsics, mount.camera_in_base, VisualConfig(arc_fit=False))
            extract = ScanExtractor(reader.intrinsics, mount.camera_in_base, ScanConfig())
        assert tracker is not None and planar is not None and extract is not None
        depth = trusted_depth(frame.depth, trusted_range(frame.depth, trust))
        truth = mount.to_planar(truth_poses[frame.index][None])[0]
        wheels = mount.to_planar(odometry[None])[0]
        predicted = None if previous is None else relative_xyyaw(previous[1], wheels)
        step = tracker(frame.rgb, depth, predicted)
        step_3d = planar(frame.rgb, depth, predicted)
        if previous is not None and predicted is not None:
            true_step = relative_xyyaw(previous[0], truth)
            visual, visual_3d = (
                np.nan if s is None else float(wrap_angle(s.step[2] - true_step[2])) for s in (step, step_3d)
            )
            rows.append(
                (true_step[2], float(wrap_angle(predicted[2] - true_step[2])), visual, visual_3d, len(extract(depth)))
            )
        previous = (truth, wheels)
    table = np.array(rows, dtype=np.float64).reshape(-1, 5)
    return {
        "true": table[:, 0],
        "wheels": table[:, 1],
        "rgbd": table[:, 2],
        "rgbd_3d": table[:, 3],
        "scan_points": table[:, 4],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, default=Path("benchmark-work"))
    parser.add_argument("--route", default="paper-300m")
    parser.add_argument("--noise", default="large")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--sensor", default="kinect-v1")
    parser.add_argument("--frames", type=int, nargs=2, default=(0, 200), metavar=("FIRST", "LAST"))
    args = parser.parse_args()
    first, last = args.frames
    if not 0 <= first < last - 1:
        parser.error(f"--frames {first} {last}: expected 0 <= FIRST < LAST - 1 (at least one step)")
    path = sequence(args.work, args.route, args.noise, args.seed, args.sensor)
    errors = heading_errors(path, first, last)
    if not len(errors["true"]):
        raise SystemExit(f"{path}: no frames in {first}-{last}")
    steps = len(errors["true"])
    no_scan = errors["scan_points"] < RegistrationConfig().min_matches
    print(f"{path.name}, frames {args.frames[0]}-{args.frames[1]}: {steps} steps, "
          f"{no_scan.mean():.0%} of frames without a scan to register")
    for name in ("wheels", "rgbd", "rgbd_3d"):
        values = errors[name][np.isfinite(errors[name])]
        if not len(values):
            print(f"  {name:7s} no step fitted")
            continue
        print(f"  {name:7s} heading error per step: mean {values.mean():+.5f} rad, std {values.std():.5f} rad "
              f"({len(values)} steps)")
    print(f"  the wheels' heading error over the stretch: {np.degrees(errors['wheels'].sum()):+.2f} deg")


if __name__ == "__main__":
    main()
