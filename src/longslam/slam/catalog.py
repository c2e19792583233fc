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

from typing import Any

from longslam.core.registry import Registry
from longslam.slam.api import Method, MethodChoice, MethodContext, MethodSpec

ENTRY_POINT_GROUP = "longslam.methods"


def _as_spec(name: str, loaded: Any) -> MethodSpec:
    """A plugin's entry point: a MethodSpec, or a factory that becomes the spec of one."""
    return loaded if isinstance(loaded, MethodSpec) else MethodSpec(name, None, loaded)


METHODS: Registry[MethodSpec] = Registry("method", ENTRY_POINT_GROUP, _as_spec)
METHODS.register_lazy("keyframe", "longslam.slam.keyframe.method:SPEC")
METHODS.register_lazy("odometry", "longslam.slam.odometry:SPEC")
METHODS.register_lazy("submap", "longslam.slam.submap.method:SPEC")
# Any program that reads a TUM RGB-D folder and writes a trajectory (slam/command).
METHODS.register_lazy("command", "longslam.slam.command.method:SPEC")
BUILTIN = tuple(METHODS.builtin_names())


def method_names() -> list[str]:
    """Every method by name: the built-in ones, then the plugins'."""
    return METHODS.names()


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
    """ "Every method" where no parameters are given (the demo's default): the methods that run
    with their defaults, so not `command`, which needs the program to run."""
    return [name for name in method_names() if runnable_alone(name)]


def get_spec(name: str) -> MethodSpec:
    return METHODS.get(name)


def choose_method(name: str, params: dict[str, Any] | None = None, typed: bool = False) -> MethodChoice:
    """Method `name` with `params` checked (UnknownNameError for a name no method has)."""
    return get_spec(name).choose(params, typed)


def check_params(name: str, params: dict[str, Any] | None = None, typed: bool = False) -> Any:
    """The method's checked config for `params`, without building the method."""
    return get_spec(name).config(params, typed)


def create_method(name: str, context: MethodContext, params: dict[str, Any] | None = None) -> Method:
    return get_spec(name).create(context, params)
