"""Reading and writing sequences, trajectories and maps on disk."""
