"""longslam.study"""
