"""A run repeated from its folder: the config.toml a run writes, read back (`run --config`).

The file holds `[run]` (the method, the sequence) and `[params]` (every parameter the method ran
with, defaults included; see run/folder.py). Parameters given on the command line override the
file's, so `--config RUN/config.toml --param voxel_size=0.1` is the same run but for one value.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from longslam.core.errors import InputError
from longslam.core.suggest import did_you_mean
from longslam.core.textfile import read_text
from longslam.slam.api import MethodChoice
from longslam.slam.catalog import choose_method

TABLES = ("run", "params")


@dataclass(frozen=True)
class RunConfig:
    method: str
    sequence: str | None = None
    params: dict[str, Any] = field(default_factory=dict)


def read_run_config(path: str | Path) -> RunConfig:
    """The method, sequence and parameters of a run's config.toml; errors name the file."""
    path = Path(path)
    if path.is_dir():  # a run folder given for its config.toml
        inside = f"; did you mean {path / 'config.toml'}?" if (path / "config.toml").is_file() else ""
        raise InputError(f"run config {path} is a folder; expected a run folder's config.toml{inside}")
    text = read_text(path, "run config", hint="a run folder's config.toml")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"run config {path} is not valid TOML: {err}") from None
    unknown = sorted(set(data) - set(TABLES))
    keys = [k for k in unknown if not isinstance(data[k], dict)]
    if keys:  # a key outside any table: method = ... above [run], say
        raise InputError(
            f"run config {path}: key(s) {', '.join(keys)} outside a table; expected them under "
            "[run] (method, sequence) or [params]"
        )
    if unknown:
        raise InputError(
            f"run config {path}: unknown table(s) {', '.join(f'[{k}]' for k in unknown)}"
            f"{did_you_mean(unknown[0], TABLES)}; expected [run] and [params]"
        )
    run, params = data.get("run", {}), data.get("params", {})
    if not isinstance(run, dict) or not isinstance(run.get("method"), str) or not run["method"]:
        raise InputError(f'run config {path}: expected [run] with method = "NAME"')
    sequence = run.get("sequence")
    if sequence is not None and not isinstance(sequence, str):
        raise InputError(f"run config {path}: [run] sequence must be a folder path, got {sequence!r}")
    if not isinstance(params, dict):
        raise InputError(f"run config {path}: [params] must be a table of parameters")
    return RunConfig(run["method"], sequence, params)


def method_of(config: RunConfig, path: str | Path) -> MethodChoice:
    """The file's method with its parameters checked as a typed file's ("320" is not a number in
    TOML); errors name the file. The command line's parameters go over it with `.over`."""
    try:
        return choose_method(config.method, config.params, typed=True)
    except InputError as err:
        raise InputError(f"run config {path}: {err}") from None
