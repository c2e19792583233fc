"""The submap method (Voxgraph's design): TSDF submaps in a planar pose graph."""
