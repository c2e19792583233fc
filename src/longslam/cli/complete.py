"""Shell completion of the names a `longslam` user types (argcomplete completers).

Each completer is tied to an option by its `dest` in `attach_completers`, over the whole parser
tree, so a subcommand added later with a `--method`, `--route`, `--noise` or `--world` option
completes its names too. Enable in bash or zsh with `eval "$(register-python-argcomplete longslam)"`.
"""

from __future__ import annotations

import argparse
from typing import Any

from argcomplete.completers import FilesCompleter

from longslam.cli.parser import subcommand_parsers


def method_names(**_: Any) -> list[str]:
    from longslam.slam.catalog import method_names as names

    return names()


def route_names(prefix: str = "", **kwargs: Any) -> list[str]:
    from longslam.sim.routes import ROUTES

    return ROUTES.names() + list(FilesCompleter()(prefix, **kwargs))  # or a waypoint file


def noise_levels(**_: Any) -> list[str]:
    from longslam.core.odometry_noise import NOISE_LEVELS

    return list(NOISE_LEVELS)


def sensor_names(**_: Any) -> list[str]:
    from longslam.sim.sensors import sensor_names as names

    return names()  # plugins' too


def world_names(prefix: str = "", **kwargs: Any) -> list[str]:
    from longslam.world import WORLDS

    return WORLDS.names() + list(FilesCompleter()(prefix, **kwargs))  # or a mesh file


def method_params(parsed_args: argparse.Namespace | None = None, **_: Any) -> list[str]:
    """`KEY=` for every parameter of the method given so far with --method (none before it)."""
    from longslam.core.settings import parameter_names
    from longslam.slam.catalog import get_spec

    method = getattr(parsed_args, "method", None)
    if not method:
        return []
    try:
        config_type = get_spec(method).config_type
    except Exception:  # an unknown method: nothing to offer, and completion must never fail loudly
        return []
    return [f"{name}=" for name in parameter_names(config_type)] if config_type is not None else []


COMPLETERS = {
    "method": method_names,
    "route": route_names,
    "noise": noise_levels,
    "odom_noise": noise_levels,
    "world": world_names,
    "param": method_params,
    "params_of": method_names,
    "sensor": sensor_names,
}


def attach_completers(parser: argparse.ArgumentParser) -> None:
    for p in (parser, *subcommand_parsers(parser)):
        for action in p._actions:
            completer = COMPLETERS.get(action.dest)
            if completer is not None and action.choices is None:
                action.completer = completer  # type: ignore[attr-defined]
