"""LoopCloser's search order against the keyframe memory's working-memory budget."""

from types import SimpleNamespace

import numpy as np

from longslam.core.frame import Intrinsics
from longslam.slam.features import Features
from longslam.slam.keyframe import KeyframeConfig
from longslam.slam.keyframe.loops import PROXIMITY, LoopCloser, counter_names
from longslam.slam.keyframe.memory import Node


def test_a_proximity_candidate_moved_to_long_term_memory_is_not_tried():
    # A proximity link's retrieval can push the next candidates out of working memory (its
    # budget): their features are gone, and verifying against them failed on len(None).
    nodes = {i: Node(i, float(i), np.zeros(3), Features.empty(), None, np.zeros((0, 3), np.float32)) for i in range(3)}
    memory = SimpleNamespace(nodes=nodes, searchable=lambda: [])
    counts = dict.fromkeys(counter_names(), 0)
    closer = LoopCloser(KeyframeConfig(scan_proximity=False, proximity_candidates=2), Intrinsics(160, 120, 100.0, 100.0, 80.0, 60.0),
                        None, memory, np.eye(4), counts)
    tried = []

    def try_link(node, cand, source):
        tried.append(cand)
        nodes[2].features = nodes[2].grid = nodes[2].points = None  # what `KeyframeMemory.transfer` leaves
        return True

    closer.proximity_candidates = lambda node, exclude: [1, 2]
    closer.try_link = try_link
    closer.detect(nodes[0], np.zeros(0, np.int64))
    assert tried == [1]
    assert counts[f"{PROXIMITY}_hypotheses"] == 1
