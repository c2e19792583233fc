"""longslam: RGB-D SLAM on long routes through large indoor buildings."""

__version__ = "0.1.0"
