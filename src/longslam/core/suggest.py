""" "Did you mean" for a name a user typed: the closest valid names, by difflib's ratio."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

# difflib's own default cutoff: `max_feature` -> `max_features`, `keyfram` -> `keyframe`, while
# an unrelated word suggests nothing rather than a random name.
CUTOFF = 0.6


def close_names(name: str, valid: Iterable[str], n: int = 3) -> list[str]:
    """The valid names closest to `name`, best first (none if nothing is close)."""
    return difflib.get_close_matches(str(name), [str(v) for v in valid], n=n, cutoff=CUTOFF)


def did_you_mean(name: str, valid: Iterable[str], quote: bool = True) -> str:
    """ " (did you mean 'x'?)" (or "'x' or 'y'"), or "" when no valid name is close."""
    close = close_names(name, valid)
    if not close:
        return ""
    shown = [repr(c) if quote else c for c in close]
    return " (did you mean " + (shown[0] if len(shown) == 1 else ", ".join(shown[:-1]) + " or " + shown[-1]) + "?)"
