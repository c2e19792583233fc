"""How a run's speed is shown: the real-time factor, in one form for `run`, the demo and the report.

The figure is simulated seconds per second of the method's own processing (run/engine.py). A
method that does almost nothing per frame (dead reckoning) gets a figure that is only the timer's
noise: 47382 one run, 80323 the next. Above `CEILING` it is shown as "> 1000": faster than any
camera needs, and all that such a figure can honestly say.
"""

from __future__ import annotations

import math

CEILING = 1000.0


def format_real_time_factor(value: float | None) -> str:
    """ "12.3", "0.85", "> 1000", or "–" when there is no figure."""
    if value is None or math.isnan(value):
        return "–"
    if value >= CEILING:
        return f"> {CEILING:.0f}"
    return f"{value:.3g}" if value < 100 else f"{value:.0f}"


def describe_real_time_factor(value: float | None) -> str:
    """The figure and what it means, for a line of text."""
    shown = format_real_time_factor(value)
    if shown == "–":
        return "real-time factor unknown (the sequence spans no time)" if value is None else "real-time factor unknown"
    assert value is not None  # "–" is shown for None
    if value >= CEILING:
        return f"real-time factor {shown} (the method's own work per frame is negligible)"
    pace = "faster than" if value >= 1 else "slower than"
    return f"real-time factor {shown} ({shown} s of sequence per second of processing: {pace} real time)"
