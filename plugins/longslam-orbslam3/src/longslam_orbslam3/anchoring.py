"""ORB-SLAM3's maps placed in longslam's world.

ORB-SLAM3's world is the optical frame of the camera at the first frame of a map; after tracking
is lost it starts a new map whose world is the camera at that map's first frame again. longslam's
world is the building's. Each map is placed by an anchor (map-in-world): the first map at the
pose the run starts from (the first odometry pose, as every longslam method starts), and each
later map at the last pose the run had when the new map began, since nothing tells a visual-only
system how far the camera moved while it was lost.

Only frames in state OK count as tracked. In RECENTLY_LOST, ORB-SLAM3 1.0 hands back a pose that
is often the identity with no tracked point (measured on the demo route), so those frames, like
lost ones, hold the last tracked pose.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

TRACKED = ("OK", "OK_KLT")
# States after which the next tracked frame belongs to a new (or a reset) map.
RESTARTS = ("SYSTEM_NOT_READY", "NO_IMAGES_YET", "NOT_INITIALIZED", "LOST")


@dataclass
class MapAnchors:
    """Online bookkeeping: for each frame, its world pose and which map segment it was tracked in."""

    start: np.ndarray  # (4, 4) camera-in-world pose the run starts from
    anchors: list[np.ndarray] = field(default_factory=list)  # map-in-world of each segment
    segment_of_frame: list[int] = field(default_factory=list)  # -1: not tracked (pose held)
    states: dict[str, int] = field(default_factory=dict)
    _held: np.ndarray | None = None
    _restart: bool = True

    def update(self, state: str, pose_wc: np.ndarray | None) -> np.ndarray:
        """One frame's tracking state and ORB-SLAM3 camera-in-map pose -> its world pose."""
        self.states[state] = self.states.get(state, 0) + 1
        held = self.start if self._held is None else self._held
        if state in TRACKED and pose_wc is not None:
            pose_wc = np.asarray(pose_wc, dtype=np.float64)
            if self._restart or not self.anchors:
                self.anchors.append(held @ np.linalg.inv(pose_wc))
                self._restart = False
            self._held = self.anchors[-1] @ pose_wc
            self.segment_of_frame.append(len(self.anchors) - 1)
            return self._held.copy()
        if state in RESTARTS:
            self._restart = True
        self.segment_of_frame.append(-1)
        return held.copy()

    @property
    def frames_untracked(self) -> int:
        return sum(1 for s in self.segment_of_frame if s < 0)


def final_poses(online: np.ndarray, stamps: np.ndarray, anchors: MapAnchors, saved_stamps: np.ndarray,
                saved_poses: np.ndarray, tolerance: float = 1e-4) -> tuple[np.ndarray, int]:
    """Every frame's final world pose: ORB-SLAM3's own saved trajectory (its largest map, after
    loop closure and global BA) where it has the frame, the online pose elsewhere.

    The saved poses are in the frame of that map's first keyframe, the camera at the first frame
    of the segment the earliest saved frame was tracked in. Returns (poses, frames taken from
    the saved trajectory)."""
    poses = np.array(online, dtype=np.float64, copy=True)
    stamps = np.asarray(stamps, dtype=np.float64)
    if not len(saved_stamps):
        return poses, 0
    order = np.argsort(stamps)
    where = np.searchsorted(stamps[order], saved_stamps)
    where = np.clip(where, 0, len(stamps) - 1)
    candidates = np.stack([order[np.clip(where - 1, 0, len(stamps) - 1)], order[where]])
    best = candidates[np.argmin(np.abs(stamps[candidates] - saved_stamps), axis=0), np.arange(len(saved_stamps))]
    matched = np.abs(stamps[best] - saved_stamps) <= tolerance
    if not matched.any():
        return poses, 0
    first = best[matched][np.argmin(saved_stamps[matched])]
    segment = anchors.segment_of_frame[first]
    if segment < 0:  # saved although not tracked online (it was RECENTLY_LOST): its map is the last before it
        earlier = [s for s in anchors.segment_of_frame[:first] if s >= 0]
        segment = earlier[-1] if earlier else 0
    # The map's first keyframe is the segment's first tracked frame, at pose identity in the map.
    start_frame = anchors.segment_of_frame.index(segment)
    anchor = online[start_frame]
    poses[best[matched]] = anchor @ np.asarray(saved_poses, dtype=np.float64)[matched]
    return poses, int(matched.sum())
