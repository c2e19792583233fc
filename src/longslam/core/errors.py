"""Errors raised for bad input: each names the file, field or value and what was expected."""

from __future__ import annotations

from collections.abc import Iterable


class LongslamError(Exception):
    """Base class of every error longslam raises on purpose."""


class InputError(LongslamError, ValueError):
    """Input that longslam cannot use (a file, a field or a value)."""


class UnknownNameError(InputError, KeyError):
    """A name (route, noise level, method, world...) that is not registered."""

    def __init__(self, kind: str, name: str, valid: Iterable[str], hint: str = "", close: Iterable[str] = ()):
        """`hint` is appended (how other spellings work); `close` are more names to suggest from
        (spellings that are valid but not registered, such as a long route's)."""
        self.kind = kind
        self.name = name
        self.valid = sorted(valid)
        from longslam.core.suggest import did_you_mean

        super().__init__(
            f"unknown {kind} {name!r}{did_you_mean(name, [*self.valid, *close])}; "
            f"valid {kind} names: {', '.join(self.valid)}" + (f"; {hint}" if hint else "")
        )

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return self.args[0]


class TrajectoryError(InputError):
    """A trajectory that is malformed, not rigid, contains NaNs, or cannot be associated."""


class MethodError(LongslamError):
    """A method, or the program it runs, that broke its contract: a program that exited non-zero,
    crashed, ran out of time or wrote no trajectory; a method whose code raised, or returned other
    than the API says. The run failed; the input may be fine. Raised from the method's own error,
    whose traceback (`__cause__`) the command prints for the method's author."""
