"""Methods by name: the built-in ones and third-party ones from the `longslam.methods` entry points.

A third-party package declares, in its pyproject.toml,

    [project.entry-points."longslam.methods"]
    mymethod = "mypackage.module:make_method"

where `make_method(context: MethodContext, params: dict) -> Method`.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any

from longslam.registry import Registry
from longslam.slam.base import Method, MethodContext

MethodFactory = Callable[[MethodContext, dict[str, Any]], Method]
ENTRY_POINT_GROUP = "longslam.methods"

METHODS: Registry[MethodFactory] = Registry("method")
_plugins_loaded = False


def _load_builtins() -> None:
    # Imported here so that registering does not make every module import every method.
    from longslam.slam import keyframe, odometry  # noqa: F401
    from longslam.slam.submap import method as _submap  # noqa: F401


def _load_plugins() -> None:
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    _load_builtins()
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name not in METHODS:
            METHODS.register(ep.name, ep.load())


def method_names() -> list[str]:
    _load_plugins()
    return METHODS.names()


def create_method(name: str, context: MethodContext, params: dict[str, Any] | None = None) -> Method:
    _load_plugins()
    return METHODS.get(name)(context, dict(params or {}))
