"""The shared floor every stage stands on: frames, trajectories, timestamps, the grid map, errors,
settings and the registry, with the small helpers they use (text files, progress, JSON values)."""
