"""The methods longslam knows: the built-in specs and third-party ones from entry points.

A third-party package declares, in its pyproject.toml,

    [project.entry-points."longslam.methods"]
    mymethod = "mypackage.module:SPEC"

where SPEC is a `longslam.slam.api.MethodSpec` (its parameters then get the same checking as the
built-in methods') or a factory `make_method(context: MethodContext, params: dict) -> Method`.

Built-in methods are named here by module path and imported only when asked for, so listing the
methods does not import every method; the methods themselves never import this module.
"""

from __future__ import annotations

import importlib
import sys
from functools import lru_cache
from importlib.metadata import entry_points
from typing import Any

from longslam.core.errors import UnknownNameError
from longslam.slam.api import Method, MethodContext, MethodSpec

ENTRY_POINT_GROUP = "longslam.methods"
BUILTIN = {
    "keyframe": "longslam.slam.keyframe.method:SPEC",
    "odometry": "longslam.slam.odometry:SPEC",
    "submap": "longslam.slam.submap.method:SPEC",
    # Any program that reads a TUM RGB-D folder and writes a trajectory (slam/command).
    "command": "longslam.slam.command.method:SPEC",
}


def _load(target: str) -> Any:
    module, _, attribute = target.partition(":")
    return getattr(importlib.import_module(module), attribute)


@lru_cache(maxsize=8)
def _plugins(search_path: tuple[str, ...]) -> dict[str, Any]:
    # Keyed on sys.path: a package made importable later (a test, a notebook) is then found.
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP) if ep.name not in BUILTIN}


def method_names() -> list[str]:
    """Every method by name: the built-in ones, then the plugins'."""
    return list(BUILTIN) + sorted(_plugins(tuple(sys.path)))


def required_params(name: str) -> tuple[str, ...]:
    """The parameters method `name` cannot run without (`MethodSpec.required`); () for a method
    that cannot be loaded here, whose runs then report why."""
    try:
        return tuple(get_spec(name).required)
    except Exception:  # a plugin that fails to import: its runs report it
        return ()


def runnable_alone(name: str, params: dict[str, Any] | None = None) -> bool:
    """Whether method `name` runs with `params` (None: its defaults): every required parameter given."""
    params = params or {}
    return all(params.get(key) not in (None, "") for key in required_params(name))


def default_method_names() -> list[str]:
    """"Every method" where no parameters are given (the demo's default): the methods that run
    with their defaults, so not `command`, which needs the program to run."""
    return [name for name in method_names() if runnable_alone(name)]


def get_spec(name: str) -> MethodSpec:
    if name in BUILTIN:
        return _load(BUILTIN[name])
    plugins = _plugins(tuple(sys.path))
    if name not in plugins:
        raise UnknownNameError("method", name, method_names())
    loaded = plugins[name].load()
    if isinstance(loaded, MethodSpec):
        return loaded
    return MethodSpec(name, None, loaded)


def check_params(name: str, params: dict[str, Any] | None = None, typed: bool = False) -> Any:
    """The method's checked config for `params`, without building the method."""
    return get_spec(name).config(params, typed)


def create_method(name: str, context: MethodContext, params: dict[str, Any] | None = None) -> Method:
    return get_spec(name).create(context, params)
