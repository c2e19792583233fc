"""ORB vocabularies of our own for systems that use DBoW2 (ORB-SLAM3): k-means trees over ORB
descriptors of longslam's frames, written in DBoW2's text format. The k-means itself is in
`longslam.vocabulary.kmeans` (not re-exported here: its `kmeans` function would hide the module)."""

from longslam.vocabulary.build import BuildSummary, OrbExtractor, build_vocabulary_file, vocabulary_from_descriptors
from longslam.vocabulary.dbow2 import format_text, read_vocabulary, write_vocabulary
from longslam.vocabulary.default import default_vocabulary, default_vocabulary_path
from longslam.vocabulary.tree import Vocabulary, build_tree

__all__ = [
    "BuildSummary",
    "OrbExtractor",
    "Vocabulary",
    "build_tree",
    "build_vocabulary_file",
    "default_vocabulary",
    "default_vocabulary_path",
    "format_text",
    "read_vocabulary",
    "vocabulary_from_descriptors",
    "write_vocabulary",
]
