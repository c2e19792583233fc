"""ORB-SLAM3 (RGB-D) as a longslam method, through the `pyorbslam3` bindings.

Registered as `orbslam3` through the `longslam.methods` entry point; longslam never imports this
package. GPL-3.0-only, because it imports `pyorbslam3` (ORB-SLAM3 is GPLv3).
"""

__version__ = "0.1.0"
