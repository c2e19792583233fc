"""What `longslam evaluate` prints: one aligned `name: value unit` line per figure, or one JSON
object with a "units" object beside the figures.

In the text, a statistic's name says which one it is: the fixed RPE figures rpe_trans and rpe_rot
are RMSEs and print as `rpe_trans (rmse)`; the ape_* and rpe_* statistics carry evo's names
(rmse, mean, median, std, min, max) in their keys.
"""

from __future__ import annotations

from typing import Any

from longslam.eval.metrics import DELTA_UNIT_LABELS
from longslam.eval.units import units_of

STATISTIC_LABELS = {"rpe_trans": "rpe_trans (rmse)", "rpe_rot": "rpe_rot (rmse)"}
PLAIN = ("", "count")  # units not printed after a number


def scores_json(scores: dict[str, Any]) -> dict[str, Any]:
    """The scores with a "units" object: {key: unit} for every numeric key (see `eval.units`)."""
    return {**scores, "units": units_of(scores)}


def _undefined(key: str, scores: dict[str, Any], min_step: float) -> str:
    if key.startswith("rpe"):
        unit = DELTA_UNIT_LABELS[scores.get("rpe_delta_unit", "m")]
        return f"undefined: no pair of poses {scores.get('rpe_delta')} {unit} apart (see --delta, --delta-unit)"
    return f"undefined: no ground-truth step of {min_step} m or more (see --min-step)"


def format_text(scores: dict[str, Any], min_step: float = 0.01) -> str:
    """One line per key, names right-aligned to the longest, numbers to 6 significant digits."""
    units = units_of(scores)
    labels = {key: STATISTIC_LABELS.get(key, key) for key in scores}
    width = max(len(label) for label in labels.values())
    lines = []
    for key, value in scores.items():
        if value is None:
            text = _undefined(key, scores, min_step)
        elif isinstance(value, float):
            unit = units.get(key, "")
            text = f"{value:.6g}" + ("" if unit in PLAIN else f" {unit}")
        else:
            unit = units.get(key, "")
            text = f"{value}" + ("" if unit in PLAIN or isinstance(value, (str, bool)) else f" {unit}")
        lines.append(f"{labels[key]:>{width}}: {text}")
    return "\n".join(lines)
