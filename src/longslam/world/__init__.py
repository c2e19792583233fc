"""longslam.world"""
