"""Run a small study and plot from its database.

    python examples/small_study.py [WORK_DIR]

Two methods (dead reckoning and keyframe) on 8 m of the `university` corridor at two noise
levels, two seeds, 64 x 48 pixels: a few minutes on 2 cores. Then the ATE per method and noise
level, straight from `results.sqlite` with SQL, as a bar chart (`ate.png`).
"""

from __future__ import annotations

import sqlite3
import sys
import tempfile
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from longslam.study.config import load_study  # noqa: E402
from longslam.study.driver import run_study  # noqa: E402


def main(work: Path) -> dict:
    (work / "corridor.txt").write_text("20 31.25\n28 31.25\n")
    study = work / "small.toml"
    study.write_text(textwrap.dedent("""
        name = "small"
        routes = ["corridor.txt"]
        noise = ["small", "large"]
        methods = ["odometry", "keyframe"]
        seeds = 2
        [camera]
        width = 64
        height = 48
    """))
    summary = run_study(load_study(study), work / "out", jobs=2, progress=False)
    print(f"{summary.ran} runs ({summary.failed} failed) in {summary.wall_time_s:.0f} s; report {summary.report}")

    with sqlite3.connect(summary.database) as db:
        rows = db.execute("SELECT method, noise, avg(ate), count(*) FROM runs WHERE status = 'ok' "
                          "GROUP BY method, noise ORDER BY method, noise").fetchall()
    ate = {(method, noise): value for method, noise, value, _ in rows}
    fig, ax = plt.subplots(figsize=(5, 3))
    for k, noise in enumerate(("small", "large")):
        ax.bar([m + 0.4 * k for m in range(2)], [ate[(method, noise)] for method in ("keyframe", "odometry")],
               width=0.4, label=noise)
    ax.set_xticks([0.2, 1.2], ["keyframe", "odometry"])
    ax.set_ylabel("ATE [m], mean of 2 seeds")
    ax.legend(title="noise")
    fig.tight_layout()
    fig.savefig(work / "ate.png")
    print(f"ATE by method and noise: {ate}; plot {work / 'ate.png'}")
    return ate


if __name__ == "__main__":
    if len(sys.argv) > 1:
        main(Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            main(Path(tmp))
