"""A small TF buffer over a bag's /tf and /tf_static, and pose interpolation in time.

Enough for an import: the pose of one frame in another at a stamp, through any chain of static
and moving links (a moving link interpolated between its two nearest transforms).
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from longslam.errors import InputError
from longslam.geometry import invert


def interpolate_poses(stamps_ns: np.ndarray, poses: np.ndarray, query_ns: np.ndarray, max_gap_ns: int,
                      what: str) -> np.ndarray:
    """Poses at `query_ns`: linear in translation and spherical in rotation between the two
    neighbouring stamps, which must be at most `max_gap_ns` apart; a query outside the stamps'
    span takes the end pose if it is within `max_gap_ns / 2` of it. InputError naming `what` and
    the first query that cannot be served."""
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    query = np.asarray(query_ns, dtype=np.int64)
    if len(stamps) == 0:
        raise InputError(f"{what}: no messages")
    order = np.argsort(stamps, kind="stable")
    stamps, poses = stamps[order], np.asarray(poses, dtype=np.float64)[order]
    keep = np.r_[True, np.diff(stamps) > 0]  # repeated stamps: the first one counts
    stamps, poses = stamps[keep], poses[keep]
    hi = np.searchsorted(stamps, query, side="left")
    out = np.empty((len(query), 4, 4))
    for k, (t, h) in enumerate(zip(query, hi)):
        if h < len(stamps) and stamps[h] == t:
            out[k] = poses[h]
            continue
        if h == 0 or h == len(stamps):
            end = 0 if h == 0 else len(stamps) - 1
            if abs(int(stamps[end]) - int(t)) * 2 > max_gap_ns:
                raise InputError(
                    f"{what}: no pose near t={t / 1e9:.6f} s (its messages span {stamps[0] / 1e9:.6f} to "
                    f"{stamps[-1] / 1e9:.6f} s); the stream cannot be synchronised with the images")
            out[k] = poses[end]
            continue
        t0, t1 = int(stamps[h - 1]), int(stamps[h])
        if t1 - t0 > max_gap_ns:
            raise InputError(
                f"{what}: a gap of {(t1 - t0) / 1e9:.3f} s around t={t / 1e9:.6f} s (more than "
                f"{max_gap_ns / 1e9:.3f} s); the stream cannot be synchronised with the images")
        w = (int(t) - t0) / (t1 - t0)
        rot = Slerp([0.0, 1.0], Rotation.from_matrix(poses[h - 1:h + 1, :3, :3]))([w]).as_matrix()[0]
        out[k] = np.eye(4)
        out[k][:3, :3] = rot
        out[k][:3, 3] = (1 - w) * poses[h - 1, :3, 3] + w * poses[h, :3, 3]
    return out


class TfBuffer:
    """Transforms parent -> child from /tf_static (fixed) and /tf (in time)."""

    def __init__(self, source: str, max_gap_ns: int):
        self.source = source
        self.max_gap_ns = max_gap_ns
        self._static: dict[str, tuple[str, np.ndarray]] = {}
        self._moving: dict[str, tuple[str, list[int], list[np.ndarray]]] = {}
        self._parents: dict[str, set[str]] = defaultdict(set)

    def add(self, parent: str, child: str, pose: np.ndarray, stamp_ns: int, static: bool) -> None:
        parent, child = parent.lstrip("/"), child.lstrip("/")
        self._parents[child].add(parent)
        if len(self._parents[child]) > 1:
            raise InputError(f"{self.source}: TF frame {child!r} has more than one parent "
                             f"({', '.join(sorted(self._parents[child]))}); a TF tree allows one")
        if static:
            self._static[child] = (parent, pose)
        else:
            self._moving.setdefault(child, (parent, [], []))
            self._moving[child][1].append(int(stamp_ns))
            self._moving[child][2].append(pose)

    @property
    def frames(self) -> list[str]:
        return sorted(set(self._parents) | {p for ps in self._parents.values() for p in ps})

    def _to_root(self, frame: str, stamp_ns: int) -> tuple[str, np.ndarray]:
        """(root frame, pose of `frame` in it) at the stamp."""
        pose = np.eye(4)
        seen = {frame}
        while True:
            if frame in self._static:
                parent, link = self._static[frame]
            elif frame in self._moving:
                parent, stamps, poses = self._moving[frame]
                link = interpolate_poses(np.array(stamps), np.array(poses), np.array([stamp_ns]), self.max_gap_ns,
                                         f"{self.source}: TF {parent} -> {frame}")[0]
            else:
                return frame, pose
            pose = link @ pose
            frame = parent
            if frame in seen:
                raise InputError(f"{self.source}: the TF tree has a cycle through {frame!r}")
            seen.add(frame)

    def lookup(self, target: str, frame: str, stamp_ns: int) -> np.ndarray:
        """The pose of `frame` in `target` at the stamp (4x4)."""
        target, frame = target.lstrip("/"), frame.lstrip("/")
        if target == frame:
            return np.eye(4)
        root_a, a = self._to_root(target, stamp_ns)
        root_b, b = self._to_root(frame, stamp_ns)
        if root_a != root_b:
            known = ", ".join(self.frames) or "none"
            raise InputError(
                f"{self.source}: no TF path from {target!r} to {frame!r} in /tf and /tf_static "
                f"(frames seen: {known}); the bag needs the transform between the odometry's child frame "
                f"and the camera's frame")
        return invert(a) @ b
