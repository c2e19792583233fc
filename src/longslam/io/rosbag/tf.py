"""A small TF buffer over a bag's /tf and /tf_static, and pose interpolation in time.

Enough for an import: the pose of one frame in another at a stamp, through any chain of static
and moving links (a moving link interpolated between its two nearest transforms).
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from longslam.core.errors import InputError
from longslam.core.geometry import invert


def interpolate_poses(
    stamps_ns: np.ndarray, poses: np.ndarray, query_ns: np.ndarray, max_gap_ns: int, what: str
) -> np.ndarray:
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
                    f"{stamps[-1] / 1e9:.6f} s); the stream cannot be synchronised with the images"
                )
            out[k] = poses[end]
            continue
        t0, t1 = int(stamps[h - 1]), int(stamps[h])
        if t1 - t0 > max_gap_ns:
            raise InputError(
                f"{what}: a gap of {(t1 - t0) / 1e9:.3f} s around t={t / 1e9:.6f} s (more than "
                f"{max_gap_ns / 1e9:.3f} s); the stream cannot be synchronised with the images"
            )
        w = (int(t) - t0) / (t1 - t0)
        rot = Slerp([0.0, 1.0], Rotation.from_matrix(poses[h - 1 : h + 1, :3, :3]))([w]).as_matrix()[0]
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
        self._moving: dict[str, tuple[str, Any, Any]] = {}  # child: (parent, stamps, poses)
        self._parents: dict[str, set[str]] = defaultdict(set)

    def add(self, parent: str, child: str, pose: np.ndarray, stamp_ns: int, static: bool) -> None:
        parent, child = parent.lstrip("/"), child.lstrip("/")
        self._parents[child].add(parent)
        if len(self._parents[child]) > 1:
            raise InputError(
                f"{self.source}: TF frame {child!r} has more than one parent "
                f"({', '.join(sorted(self._parents[child]))}); a TF tree allows one"
            )
        if static:
            self._static[child] = (parent, pose)
        else:
            _, stamps, poses = self._moving.setdefault(child, (parent, [], []))
            if isinstance(stamps, np.ndarray):
                raise InputError(f"{self.source}: TF {parent} -> {child} added to after it was looked up")
            stamps.append(int(stamp_ns))
            poses.append(pose)

    @property
    def frames(self) -> list[str]:
        return sorted(set(self._parents) | {p for ps in self._parents.values() for p in ps})

    def _parent(self, frame: str) -> str | None:
        if frame in self._static:
            return self._static[frame][0]
        if frame in self._moving:
            return self._moving[frame][0]
        return None

    def _chain(self, frame: str) -> list[str]:
        """`frame` and its ancestors up to the root."""
        chain = [frame]
        while (parent := self._parent(chain[-1])) is not None:
            if parent in chain:
                raise InputError(f"{self.source}: the TF tree has a cycle through {parent!r}")
            chain.append(parent)
        return chain

    def _link(self, frame: str, stamp_ns: int) -> np.ndarray:
        """The pose of `frame` in its parent at the stamp."""
        if frame in self._static:
            return self._static[frame][1]
        parent, stamps, poses = self._moving[frame]
        if not isinstance(stamps, np.ndarray):  # arrays once all messages are in
            stamps, poses = np.array(stamps, dtype=np.int64), np.array(poses)
            self._moving[frame] = (parent, stamps, poses)
        return interpolate_poses(
            stamps, poses, np.array([stamp_ns]), self.max_gap_ns, f"{self.source}: TF {parent} -> {frame}"
        )[0]

    def _up_to(self, chain: list[str], stop: str, stamp_ns: int) -> np.ndarray:
        """The pose of chain[0] in `stop`, one of its ancestors."""
        pose = np.eye(4)
        for frame in chain[: chain.index(stop)]:
            pose = self._link(frame, stamp_ns) @ pose
        return pose

    def lookup(self, target: str, frame: str, stamp_ns: int) -> np.ndarray:
        """The pose of `frame` in `target` at the stamp (4x4), through their lowest common
        ancestor (so a moving link above both, odom -> base_link say, is never looked up)."""
        target, frame = target.lstrip("/"), frame.lstrip("/")
        if target == frame:
            return np.eye(4)
        up_target, up_frame = self._chain(target), self._chain(frame)
        common = next((f for f in up_frame if f in up_target), None)
        if common is None:
            known = ", ".join(self.frames) or "none"
            raise InputError(
                f"{self.source}: no TF path from {target!r} to {frame!r} in /tf and /tf_static "
                f"(frames seen: {known}); the bag needs the transform between the odometry's child frame "
                f"and the camera's frame"
            )
        return invert(self._up_to(up_target, common, stamp_ns)) @ self._up_to(up_frame, common, stamp_ns)
