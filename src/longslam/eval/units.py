"""The unit of every figure `evaluate` returns, for its text output and the "units" object of
`longslam evaluate --json`.

Units are short SI-style strings: "m", "deg", "rad", "s", "%", "m/m" (metres of error per metre
travelled), "deg/m", "frames", "" for a plain number (a scale) or a dimensionless norm (evo's
rot_part and full relations), and "count" for a number of steps, pairs or poses. Keys that hold
a name (align, pose_relation...) have no unit and are left out.
"""

from __future__ import annotations

from typing import Any

from longslam.eval.metrics import DELTA_UNIT_LABELS
from longslam.eval.relations import RELATION_UNITS

STATISTICS = ("rmse", "mean", "median", "std", "min", "max")

FIXED = {
    "ate": "m",
    "e_trans": "m/m",
    "e_rot": "deg/m",
    "rpe_trans": "m",
    "rpe_rot": "deg",
    "used_steps": "count",
    "skipped_steps": "count",
    "zero_estimate_steps": "count",
    "rpe_pairs": "count",
    "matched_poses": "count",
    "path_length": "m",
    "align_scale": "",
    "n_to_align": "count",
    "matched_share_estimate": "",
    "matched_share_groundtruth_span": "",
}


def units_of(scores: dict[str, Any]) -> dict[str, str]:
    """{key: unit} for the numeric keys of an `evaluate` / `score` dict."""
    units = {key: unit for key, unit in FIXED.items() if key in scores}
    ape_unit = RELATION_UNITS[scores.get("ape_pose_relation", "trans_part")]
    rpe_unit = RELATION_UNITS[scores.get("pose_relation", "trans_part")]
    for name in STATISTICS:
        for prefix, unit in (("ape", ape_unit), ("rpe", rpe_unit)):
            if f"{prefix}_{name}" in scores:
                units[f"{prefix}_{name}"] = unit
    if "rpe_delta" in scores:
        units["rpe_delta"] = DELTA_UNIT_LABELS[scores.get("rpe_delta_unit", "m")]
    return units
