"""What ORB-SLAM3 said on its console: the only report of its loop closures, map merges, new
maps and global bundle adjustments that the bindings give (pyorbslam3 0.1.1 exposes no counters).

The lines are ORB-SLAM3 1.0's own (LoopClosing.cc, Tracking.cc, Atlas.cc); the engine sends the
process's native output to the run's console.log, which is read here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

MARKERS = {
    "loops": "*Loop detected",
    "merges": "*Merge detected",
    "maps_created": "Creation of new map with id",
    "relocalizations": "Relocalized!!",
    "global_ba_started": "Starting Global Bundle Adjustment",
    "global_ba_finished": "Global Bundle Adjustment finished",
    "global_ba_stopped": "Stoping Global Bundle Adjustment",  # sic: ORB-SLAM3's spelling
    "local_map_failures": "Fail to track local map!",
    # Tracking::ResetActiveMap's last line: the active map was cleared of its keyframes (a loss
    # before it had 10 of them); printed whatever the verbosity.
    "map_resets": "Frames set to lost",
}


@dataclass
class ConsoleCounts:
    counts: dict[str, int]

    @property
    def global_ba_running(self) -> bool:
        """A global BA was started and has neither finished nor been stopped (by a newer loop)."""
        c = self.counts
        return c["global_ba_started"] > c["global_ba_finished"] + c["global_ba_stopped"]


def count_markers(text: str) -> ConsoleCounts:
    # "Global Bundle Adjustment finished" is printed twice per BA in some builds' paths; count lines.
    counts = dict.fromkeys(MARKERS, 0)
    for line in text.splitlines():
        for key, marker in MARKERS.items():
            if marker in line:
                counts[key] += 1
    return ConsoleCounts(counts)


def read_counts(path: str | Path | None, start: int = 0) -> ConsoleCounts:
    """Counts over the log from byte `start` (where this run's lines begin); zeros without a log."""
    if path is None or not Path(path).is_file():
        return count_markers("")
    with open(path, "rb") as f:
        f.seek(start)
        return count_markers(f.read().decode("utf-8", errors="replace"))


# Console lines that become a run's events (longslam.slam.api.Event), by event kind.
EVENT_MARKERS = {
    "loop": MARKERS["loops"],
    "merge": MARKERS["merges"],
    "relocalized": MARKERS["relocalizations"],
    "global_ba": MARKERS["global_ba_started"],
}


class ConsoleFollower:
    """Reads what ORB-SLAM3 printed since the last call, so that each line is tied to the frame
    being tracked when it appeared (its threads print when they act, a frame or two late)."""

    def __init__(self, path: str | Path | None, start: int = 0):
        self.path = path
        self.position = start

    def new_events(self) -> list[tuple[str, str]]:
        """(event kind, the console's line) of every marked line printed since the last call."""
        if self.path is None:
            return []
        try:
            with open(self.path, "rb") as f:
                f.seek(self.position)
                data = f.read()
        except OSError:
            return []
        end = data.rfind(b"\n") + 1  # a line still being written is read next time
        self.position += end
        found = []
        for line in data[:end].decode("utf-8", errors="replace").splitlines():
            for kind, marker in EVENT_MARKERS.items():
                if marker in line:
                    found.append((kind, line.strip()[:120]))
        return found
