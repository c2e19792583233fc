"""longslam.sim"""
