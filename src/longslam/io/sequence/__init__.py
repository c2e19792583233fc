"""RGB-D sequences on disk in the TUM RGB-D layout.

A sequence folder holds::

    rgb/<t>.png        8-bit colour images
    depth/<t>.png      16-bit depth, metres x depth_scale (5000), 0 = no return
    rgb.txt            TUM list: '# ...' header lines, then 'timestamp filename' lines
    depth.txt          the same for the depth images
    groundtruth.txt    TUM trajectory, camera-in-world (optional: real TUM test sequences lack it)
    odometry.txt       TUM trajectory of the noisy odometry, camera-in-world (longslam only)
    camera.json        width, height, fx, fy, cx, cy, depth_scale, max_depth (longslam only)
    meta.json          free-form provenance: world, route, noise level, seed, version (longslam only)

Real TUM sequences (no camera.json, no odometry.txt, rgb and depth stamps that differ by a few
milliseconds) read as well: rgb and depth images are associated by nearest timestamp as TUM's
`associate.py` does.

Writing is atomic: `SequenceWriter` and `derive_sequence` build the sequence in a hidden temporary
sibling folder and rename it to its final name only when everything has been written, so an
interrupted run never leaves a folder that a later run would take as a complete sequence.
"""

from longslam.io.sequence.layout import DEFAULT_MAX_DIFF, DEPTH_SCALE
from longslam.io.sequence.reader import SequenceReader
from longslam.io.sequence.writer import SequenceWriter, derive_sequence

__all__ = ["DEFAULT_MAX_DIFF", "DEPTH_SCALE", "SequenceReader", "SequenceWriter", "derive_sequence"]
