"""One vocabulary of the counters a method reports in `Result.stats`.

The report, the results database and the benchmarks read these names whatever the method, so a
method uses them for what they mean here and adds its own keys only for what it alone has.
"""

FRAMES = "frames"  # frames stepped
FRAMES_WITHOUT_DEPTH = "frames_without_depth"  # frames whose depth image held no valid return
ODOMETRY_JUMPS = "odometry_jumps"  # odometry steps too large for one frame, replaced by no motion
NODES = "nodes"  # graph nodes (keyframes)
SUBMAPS = "submaps"
LOOP_HYPOTHESES = "loop_hypotheses"  # loop-closure candidates put to verification, every source
LOOPS_ACCEPTED = "loops_accepted"  # loop closures in the final graph, every source
LOOPS_REJECTED = "loops_rejected"  # loop closures refused by verification or by the graph
OPTIMIZATIONS = "optimizations"  # pose-graph optimisations run
MAP_BYTES = "map_bytes"  # {part of the map: bytes held in RAM (and on disk where said)}
CAMERA_HEIGHT = "camera_height"  # metres above the floor, as used
NOTES = "notes"  # sentences on what the run could not do, which `longslam run` shows as note: lines

SHARED = (
    FRAMES,
    FRAMES_WITHOUT_DEPTH,
    ODOMETRY_JUMPS,
    NODES,
    SUBMAPS,
    LOOP_HYPOTHESES,
    LOOPS_ACCEPTED,
    LOOPS_REJECTED,
    OPTIMIZATIONS,
    MAP_BYTES,
    CAMERA_HEIGHT,
    NOTES,
)
