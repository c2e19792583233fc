"""What several test files share, named by what it makes or checks (fixtures stay in conftest.py):

- `tiny_sequences`: tiny synthetic sequences written in a moment (`write_tiny_sequence`);
- (the generated building with a wing at 30 degrees is `longslam.world.wing_building`, which the benchmarks use too);
- `flat_walls`: flat walls rendered by the paper's camera;
- `pose_graphs`: a square route and a drifting odometry for pose-graph tests;
- `tiny_vocabulary`: the smallest sound ORB vocabulary file;
- `cli_checks`: the CLI's failure was one line; what shell completion answers;
- `sequence_checks`: two sequences the same, as a round trip must give them;
- `recordings`: reading a rerun recording back;
- `scripts`: a script, benchmark or example of the checkout loaded as a module (`load_script`).

`tests/` is on the path (pyproject's `pythonpath`), so a test imports `from helpers.x import y`.
"""
