"""longslam.eval"""
