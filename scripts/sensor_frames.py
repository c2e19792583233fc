"""One frame of a rendered route as each sensor model delivers it, colour above depth, for the docs.

    python scripts/sensor_frames.py SEQUENCE OUT.png [--frame N] [--seed 0]
        [--sensors ideal kinect-v1 realsense-d435]

SEQUENCE is an ideal-sensor sequence (e.g. from `longslam simulate`); without --frame the frame
with the most depth edges among every 10th is shown. Holes (no return) are black in the depth row.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from longslam.io.atomic import atomic_path  # noqa: E402
from longslam.io.sequence import SequenceReader  # noqa: E402
from longslam.sim.sensors import frame_rng, get_sensor  # noqa: E402
from longslam.sim.sensors.stream import camera_motions  # noqa: E402


def edgiest_frame(reader: SequenceReader) -> int:
    """The frame (of every 10th) whose depth jumps by more than 0.3 m at the most pixels."""
    def edges(i: int) -> int:
        depth = reader.read_depth(i)
        return int(np.count_nonzero(np.abs(np.diff(depth, axis=1)) > 0.3))
    return max(range(0, len(reader), 10), key=edges)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sequence", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--frame", type=int)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sensors", nargs="+", default=["ideal", "kinect-v1", "realsense-d435"])
    args = parser.parse_args()

    reader = SequenceReader(args.sequence)
    index = edgiest_frame(reader) if args.frame is None else args.frame
    rgb, depth = reader.read_rgb(index), reader.read_depth(index)
    motion = camera_motions(reader.ground_truth)[index]
    fig, axes = plt.subplots(2, len(args.sensors), figsize=(4.2 * len(args.sensors), 6.6), squeeze=False)
    cmap = plt.get_cmap("turbo").copy()
    cmap.set_bad("black")
    top = float(reader.max_depth or depth.max())
    for column, name in enumerate(args.sensors):
        model = get_sensor(name)
        colour, sensed = model.sense(rgb, depth, reader.intrinsics, motion, frame_rng(name, args.seed, index))
        holes = 100.0 * np.count_nonzero(sensed == 0) / sensed.size
        axes[0, column].imshow(colour)
        axes[0, column].set_title(name)
        shown = axes[1, column].imshow(np.ma.masked_equal(sensed, 0.0), cmap=cmap, vmin=0.0, vmax=top)
        axes[1, column].set_title(f"depth, {holes:.0f}% no return")
        for ax in axes[:, column]:
            ax.set_xticks([])
            ax.set_yticks([])
    fig.colorbar(shown, ax=axes[1, :].tolist(), shrink=0.8, label="depth [m]")
    turn = np.degrees(np.linalg.norm(motion.angular_velocity))
    fig.suptitle(f"{reader.meta.get('route', reader.path.name)}, frame {index} (turning at {turn:.0f} deg/s), seed {args.seed}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(args.out) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    print(f"wrote {args.out}: frame {index}")


if __name__ == "__main__":
    main()
