"""Visual features of one RGB-D frame: keypoints, binary descriptors and their 3D points.

Shared by the keyframe method and the submap method (place recognition and loop-closure
verification). Points are in the OpenCV camera frame (x right, y down, z forward), metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics

DESCRIPTOR_BYTES = 32  # ORB: 256-bit descriptors


@dataclass
class Features:
    """Keypoints, ORB descriptors and back-projected 3D points, strongest keypoint first.

    `points` is NaN where the depth under a keypoint is missing; such keypoints still count for
    appearance (bag of words) but cannot anchor a PnP solution.
    """

    keypoints: np.ndarray  # (N, 2) float32 pixel coordinates (u, v)
    descriptors: np.ndarray  # (N, 32) uint8
    points: np.ndarray  # (N, 3) float32 camera-frame metres, NaN where depth is invalid

    @classmethod
    def empty(cls) -> "Features":
        return cls(
            np.zeros((0, 2), np.float32),
            np.zeros((0, DESCRIPTOR_BYTES), np.uint8),
            np.zeros((0, 3), np.float32),
        )

    def __len__(self) -> int:
        return len(self.keypoints)

    @property
    def valid(self) -> np.ndarray:
        """(N,) bool: keypoints with a 3D point."""
        return np.isfinite(self.points).all(axis=1)

    @property
    def nbytes(self) -> int:
        return int(self.keypoints.nbytes + self.descriptors.nbytes + self.points.nbytes)


def _gray(rgb: np.ndarray) -> np.ndarray:
    rgb = np.asarray(rgb)
    if rgb.ndim == 2:
        return np.ascontiguousarray(rgb, dtype=np.uint8)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise InputError(f"rgb must be (H, W, 3) or (H, W), got shape {rgb.shape}")
    return cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.uint8), cv2.COLOR_RGB2GRAY)


def backproject(keypoints: np.ndarray, depth: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """(N, 2) pixels + depth image -> (N, 3) float32 camera-frame points, NaN without depth.

    Depth is read at the nearest pixel rather than interpolated: interpolating across a depth
    edge would invent points floating between foreground and background.
    """
    keypoints = np.asarray(keypoints, dtype=np.float64).reshape(-1, 2)
    h, w = depth.shape
    col = np.clip(np.rint(keypoints[:, 0]).astype(np.int64), 0, w - 1)
    row = np.clip(np.rint(keypoints[:, 1]).astype(np.int64), 0, h - 1)
    z = depth[row, col].astype(np.float64)
    ok = np.isfinite(z) & (z > 0.0)
    z = np.where(ok, z, np.nan)
    x = (keypoints[:, 0] - intrinsics.cx) / intrinsics.fx * z
    y = (keypoints[:, 1] - intrinsics.cy) / intrinsics.fy * z
    return np.column_stack([x, y, z]).astype(np.float32)


def extract(
    rgb: np.ndarray,
    depth: np.ndarray,
    intrinsics: Intrinsics,
    max_features: int = 2000,
    detector: str = "orb",
) -> Features:
    """Detect ORB keypoints, describe them, and back-project them with the depth image.

    Returns an empty `Features` (no error) for a frame without texture or without any valid
    depth: such frames happen on a real route (a blank wall, a sensor dropout) and the caller
    simply gets nothing to match.
    """
    if detector.lower() != "orb":
        raise InputError(f"unknown feature detector {detector!r}; valid detectors: orb")
    if max_features <= 0:
        raise InputError(f"max_features must be positive, got {max_features}")
    depth = np.asarray(depth)
    gray = _gray(rgb)
    if depth.shape != gray.shape:
        raise InputError(f"depth shape {depth.shape} does not match image shape {gray.shape}")
    if not np.any(np.isfinite(depth) & (depth > 0)):
        return Features.empty()

    orb = cv2.ORB_create(nfeatures=int(max_features))
    kps, desc = orb.detectAndCompute(gray, None)
    if desc is None or len(kps) == 0:
        return Features.empty()
    # Strongest first, so that callers that cap the count (the vocabulary's words per image)
    # keep the most repeatable keypoints.
    order = np.argsort([-kp.response for kp in kps], kind="stable")
    keypoints = np.array([kps[i].pt for i in order], dtype=np.float32).reshape(-1, 2)
    descriptors = np.ascontiguousarray(desc[order], dtype=np.uint8)
    points = backproject(keypoints, depth, intrinsics)
    return Features(keypoints, descriptors, points)
