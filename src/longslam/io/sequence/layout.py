"""The TUM RGB-D layout of a sequence folder: file names and conventions shared by the writer and
the reader."""

DEPTH_SCALE = 5000.0  # TUM: a 16-bit depth value of 5000 is one metre
DEFAULT_MAX_DIFF = 0.02  # seconds; TUM associate.py's default
STAMP_DECIMALS = 6

RGB_DIR, DEPTH_DIR = "rgb", "depth"
RGB_LIST, DEPTH_LIST = "rgb.txt", "depth.txt"
GROUND_TRUTH, ODOMETRY = "groundtruth.txt", "odometry.txt"
CAMERA, META = "camera.json", "meta.json"
