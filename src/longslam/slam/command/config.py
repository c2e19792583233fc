"""The parameters of the `command` method, and the command template they hold.

The template is split like a shell line (`shlex`, no shell runs it) and each word is filled with
`str.format`: `{sequence}`, `{output}`, `{associations}`, `{settings}` (absolute paths), `{fx}`,
`{fy}`, `{cx}`, `{cy}` (pixels), `{width}`, `{height}` (pixels) and `{depth_scale}` (5000, the
TUM PNG scale). A value is filled into its word after the split, so a path with spaces stays one
argument; `{{` and `}}` are literal braces; a format spec works (`{fx:.2f}`).
"""

from __future__ import annotations

import shlex
import string
from dataclasses import dataclass
from pathlib import PurePath
from typing import Any

from longslam.core.errors import InputError
from longslam.core.parameter import check_declared, param

METHOD = "command"
PATHS = ("sequence", "output", "associations", "settings")
NUMBERS = ("fx", "fy", "cx", "cy")
WHOLE = ("width", "height", "depth_scale")
PLACEHOLDERS = PATHS + NUMBERS + WHOLE
FORMATS = ("tum", "euroc", "kitti")
FRAMES = ("optical", "robot")
MAX_TIMEOUT_S = 30 * 86400.0  # a month: beyond it a number is a mistake, not a run


def _check(ok: bool, message: str) -> None:
    if not ok:
        raise InputError(f"method {METHOD!r}: {message}")


def placeholders_of(word: str) -> list[str]:
    """The placeholder names in one word of the template (ValueError for unbalanced braces)."""
    return [field for _, field, _, _ in string.Formatter().parse(word) if field is not None]


def split_template(command: str) -> list[str]:
    """The template's words, each checked: known placeholders only, and each fillable."""
    try:
        words = shlex.split(command)
    except ValueError as err:  # an unclosed quote
        raise InputError(
            f"method {METHOD!r}: parameter command={command!r} cannot be split into words " f"as a shell would: {err}"
        ) from None
    _check(bool(words), f"parameter command={command!r} holds no program to run")
    valid = ", ".join("{" + name + "}" for name in PLACEHOLDERS)
    # Trial values of each placeholder's type: a bad format spec fails here, not after the frames.
    trial: dict[str, Any] = {**{n: "/p" for n in PATHS}, **{n: 1.5 for n in NUMBERS}, **{n: 2 for n in WHOLE}}
    for word in words:
        try:
            names = placeholders_of(word)
        except ValueError as err:
            raise InputError(
                f"method {METHOD!r}: parameter command: {word!r}: {err} (write {{{{ and }}}} for "
                f"literal braces; valid placeholders: {valid})"
            ) from None
        unknown = [n for n in names if n not in PLACEHOLDERS]
        if unknown:
            raise InputError(
                f"method {METHOD!r}: parameter command: unknown placeholder {{{unknown[0]}}} in "
                f"{word!r}; valid placeholders: {valid} ({{{{ and }}}} for literal braces)"
            )
        try:
            word.format_map(trial)
        except (ValueError, TypeError, KeyError, IndexError, AttributeError) as err:
            raise InputError(f"method {METHOD!r}: parameter command: {word!r} cannot be filled: {err}") from None
    return words


@dataclass(frozen=True)
class CommandConfig:
    command: str = param(
        "", "the program and its arguments, with placeholders such as {sequence} and {output} (see the README)"
    )
    trajectory: str = param(
        "CameraTrajectory.txt",
        "the trajectory file the program writes, relative to {output}, which is also its working directory",
    )
    format: str = param(
        "tum",
        "the trajectory file's format: tum, euroc (stamps in ns, as ORB-SLAM3 writes) or kitti (a pose a frame)",
        choices=FORMATS,
    )
    frame: str = param(
        "optical",
        "whose poses the file holds: the camera's optical frame (OpenCV axes) or the robot base (x ahead, z up)",
        choices=FRAMES,
    )
    timeout: float = param(
        3600.0,
        "time the program may run before it (and every process it started) is killed and the run fails",
        above=0,
        at_most=MAX_TIMEOUT_S,
        unit="s",
    )
    camera_height: float | None = param(
        None,
        "camera height above the floor, for robot-frame poses and a start without odometry (none: the odometry's)",
        above=0,
        below=10,
        unit="m",
    )
    keep_sequence: bool = param(
        False, "keep the TUM folder written for the program in the run folder (it is removed once the program ends)"
    )

    def __post_init__(self) -> None:
        check_declared(self, f"method {METHOD!r}")
        if self.command:
            split_template(self.command)
        path = PurePath(self.trajectory)
        _check(
            bool(self.trajectory.strip()) and not path.is_absolute() and ".." not in path.parts,
            f"parameter trajectory={self.trajectory!r}: expected a file name relative to {{output}} "
            "(the program's working directory), inside it",
        )

    def words(self) -> list[str]:
        """The template's words; InputError when no program was given."""
        if not self.command.strip():
            raise InputError(
                f"method {METHOD!r} needs the program to run: --param command='myslam {{sequence}} "
                f"{{output}}' (placeholders: {', '.join('{' + n + '}' for n in PLACEHOLDERS)})"
            )
        return split_template(self.command)

    def uses(self, placeholder: str) -> bool:
        return any(placeholder in placeholders_of(word) for word in self.words())


def fill(words: list[str], values: dict[str, Any]) -> list[str]:
    """The program's argv: each word of the template with the placeholders' values."""
    return [word.format_map(values) for word in words]


def command_line(argv: list[str]) -> str:
    """The argv as one line a shell would split back into it (for stats and messages)."""
    return shlex.join(argv)
