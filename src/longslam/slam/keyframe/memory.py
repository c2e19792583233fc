"""The keyframe method's memory, after RTAB-Map's `Memory`: short-term, working and long-term.

New nodes enter short-term memory (STM), which loop closure does not search; the oldest STM node
moves to working memory (WM), which it does. When WM exceeds its budget, its least recently used
node moves to long-term memory (LTM): its data go to the SQLite database and leave RAM, and it
leaves the visual vocabulary. A loop closure brings a few LTM neighbours of its match back.
"""

from __future__ import annotations

from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from longslam.slam.features import Features
from longslam.slam.keyframe.config import KeyframeConfig
from longslam.slam.keyframe.memory_db import MemoryDatabase
from longslam.slam.occupancy import LocalGrid
from longslam.slam.place_recognition import Vocabulary

# A node id -> its (estimated, odometry) camera poses, as the database stores them.
NodePoses = Callable[[int], tuple[np.ndarray, np.ndarray]]


# A node's stored arrays that make its local grid.
GRID_ARRAYS = ("grid_obstacles", "grid_free")
# Long-term nodes' grids kept after a read (a few KB each).
LTM_GRIDS_CACHED = 256


@dataclass
class Node:
    id: int
    stamp: float
    odom: np.ndarray  # (3,) odometry x, y, yaw (jumps removed)
    features: Features | None  # None while the node is in long-term memory
    grid: LocalGrid | None
    points: np.ndarray | None  # (M, 3) float32 depth points in the robot frame, for the 3D map
    last_access: int = 0  # node count when last created, matched or retrieved (LRU for transfers)

    @property
    def in_ram(self) -> bool:
        return self.features is not None


class KeyframeMemory:
    def __init__(
        self,
        config: KeyframeConfig,
        db: MemoryDatabase,
        vocabulary: Vocabulary,
        node_poses: NodePoses,
        counts: dict[str, int],
    ):
        self.config = config
        self.db = db
        self.vocabulary = vocabulary
        self.node_poses = node_poses
        self.counts = counts  # the method's counters: nodes_transferred, nodes_retrieved
        self.nodes: dict[int, Node] = {}
        self.stm: deque[int] = deque()
        self.wm: set[int] = set()
        # The local grids of long-term nodes read lately: scan proximity reads the same few back
        # from the database for node after node as the robot drives past them.
        self._ltm_grids: OrderedDict[int, LocalGrid] = OrderedDict()

    def add(self, node: Node) -> None:
        """A new node: known from now on (loop closure may retrieve around it), not yet searchable."""
        self.nodes[node.id] = node

    def admit(self, node_id: int, words: np.ndarray) -> None:
        """A new node, after its own loop query, joins the vocabulary's index and STM. It joins the
        index after the query, so it never matches itself."""
        self.vocabulary.add_words(node_id, words)
        self.stm.append(node_id)
        while len(self.stm) > self.config.stm_size:
            self.wm.add(self.stm.popleft())
        self.enforce_budget()
        if self.config.vocabulary_forget:
            # Here every word handed out is in a bag: the node's own (just indexed) and those of
            # nodes retrieved during its loop search.
            self.vocabulary.forget_unused()

    def searchable(self) -> list[int]:
        """The nodes loop closure may match: working memory, in id order."""
        return sorted(self.wm)

    def enforce_budget(self) -> None:
        budget = self.config.wm_max_nodes
        if budget <= 0:
            return
        while len(self.wm) > budget:
            oldest = min(self.wm, key=lambda i: (self.nodes[i].last_access, i))
            self.transfer(oldest)

    def transfer(self, node_id: int, count: bool = True) -> None:
        """Working memory -> long-term memory: the node's data go to the database and leave RAM."""
        node = self.nodes[node_id]
        assert (
            node.features is not None and node.grid is not None
        )  # in working or short-term memory: its data are in RAM
        arrays = {
            "keypoints": node.features.keypoints,
            "descriptors": node.features.descriptors,
            "points3d": node.features.points,
            "grid_obstacles": node.grid.obstacles,
            "grid_free": node.grid.free,
            "cloud": node.points,
        }
        pose, odom = self.node_poses(node_id)
        self.db.put_node(node_id, node.stamp, pose, odom, arrays, weight=node.last_access)
        self.vocabulary.remove(node_id)
        self.wm.discard(node_id)
        node.features = node.grid = node.points = None
        if count:
            self.counts["nodes_transferred"] += 1

    def load(self, node_id: int) -> tuple[Features, LocalGrid, np.ndarray]:
        """A long-term node's features, local grid and points, read back from the database."""
        stored = self.db.get_node(node_id).arrays
        features = Features(stored["keypoints"], stored["descriptors"], stored["points3d"])
        return features, self._stored_grid(stored), stored["cloud"]

    def _stored_grid(self, stored: dict[str, np.ndarray]) -> LocalGrid:
        """A node's local grid from its stored arrays (`GRID_ARRAYS`)."""
        return LocalGrid(stored["grid_obstacles"], stored["grid_free"], self.config.grid_cell)

    def grid_and_points(self, node_id: int) -> tuple[LocalGrid, np.ndarray]:
        """A node's local grid and points, from RAM or from the database."""
        node = self.nodes[node_id]
        if node.in_ram:
            assert node.grid is not None  # in RAM with its features
            return node.grid, node.points
        # Only the arrays the maps need: decoding a node's features too took half the read.
        stored = self.db.get_arrays(node_id, (*GRID_ARRAYS, "cloud"))
        return self._stored_grid(stored), stored["cloud"]

    def grid(self, node_id: int) -> LocalGrid | None:
        """A node's local grid, from RAM, from the last `LTM_GRIDS_CACHED` read back, or from the database."""
        node = self.nodes[node_id]
        if node.in_ram:
            return node.grid
        grid = self._ltm_grids.get(node_id)
        if grid is None:
            grid = self._stored_grid(self.db.get_arrays(node_id, GRID_ARRAYS))
            self._ltm_grids[node_id] = grid
            if len(self._ltm_grids) > LTM_GRIDS_CACHED:
                self._ltm_grids.popitem(last=False)
        else:
            self._ltm_grids.move_to_end(node_id)
        return grid

    def retrieve_around(self, node_id: int) -> None:
        """Bring back up to max_retrieved long-term nodes next to a loop closure (graph neighbours)."""
        brought = 0
        for offset in (1, -1, 2, -2, 3, -3):
            if brought >= self.config.max_retrieved:
                break
            other = self.nodes.get(node_id + offset)
            if other is None or other.in_ram:
                continue
            other.features, other.grid, other.points = self.load(other.id)
            other.last_access = len(self.nodes)
            self.vocabulary.add(other.id, other.features.descriptors)
            self.wm.add(other.id)
            brought += 1
            self.counts["nodes_retrieved"] += 1
        self.enforce_budget()

    def flush(self) -> None:
        """Every node still in RAM to the database (the end of a run), not counted as transfers."""
        for node_id in sorted(self.wm | set(self.stm)):
            self.transfer(node_id, count=False)

    def release_search(self) -> None:
        """Drop what only loop search needs (the vocabulary and the long-term grids read back), at
        the end of a run: nothing searches any more."""
        self.vocabulary = Vocabulary(self.vocabulary.max_distance, self.vocabulary.max_words_per_image, "bruteforce")
        self._ltm_grids.clear()

    def census(self) -> dict[str, int]:
        return {
            "wm_nodes": len(self.wm),
            "stm_nodes": len(self.stm),
            "ltm_nodes": sum(1 for n in self.nodes.values() if not n.in_ram),
        }

    def memory_bytes(self) -> dict[str, int]:
        in_ram = [n for n in self.nodes.values() if n.in_ram]
        return {
            "features": sum(n.features.nbytes for n in in_ram if n.features is not None),
            "local_grids": sum(n.grid.nbytes for n in in_ram if n.grid is not None),
            "node_points": sum(n.points.nbytes for n in in_ram if n.points is not None),
            "vocabulary": int(self.vocabulary.nbytes),
            "database_on_disk": self.db.size_bytes(),
        }
