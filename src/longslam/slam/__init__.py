"""longslam.slam"""
