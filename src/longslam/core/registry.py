"""The one way longslam names things a user picks: methods, sensors, worlds, routes, noise levels.

A `Registry` holds the built-in items by name, optionally as "module:attribute" targets imported
only when asked for (so listing the methods imports none of them), and, when it has an entry-point
group, the items third-party packages declare in theirs::

    [project.entry-points."longslam.sensors"]
    dusty = "mypackage.sensors:Dusty"

A plugin's item passes through the registry's `accept` function, which checks it (and may make the
item from a class or factory); whatever a plugin's code raises there is its failure, reported as
one line naming the entry point. A name that is neither built in nor a plugin's raises
`UnknownNameError`, which lists the valid names with a did-you-mean.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Callable, Iterator
from importlib.metadata import EntryPoint, entry_points
from typing import Any, Generic, TypeVar

from longslam.core.errors import InputError, UnknownNameError

T = TypeVar("T")


class _Lazy:
    """A built-in item named by "module:attribute", imported on first use."""

    def __init__(self, target: str):
        self.target = target

    def load(self) -> Any:
        module, _, attribute = self.target.partition(":")
        return getattr(importlib.import_module(module), attribute)


def failure(err: BaseException) -> str:
    """What a plugin's code raised, in one short line."""
    text = " ".join(str(err).split())[:200]
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


class Registry(Generic[T]):
    def __init__(self, kind: str, entry_point_group: str | None = None, accept: Callable[[str, Any], T] | None = None):
        """`kind` names an item in messages ("method", "sensor"); `entry_point_group` is where
        plugins declare theirs (None: built-ins only); `accept(name, loaded)` turns what a
        plugin's entry point loads into an item, raising for what it cannot use."""
        self.kind = kind
        self.entry_point_group = entry_point_group
        self._accept = accept
        self._items: dict[str, T | _Lazy] = {}
        self._plugins_seen: tuple[tuple[str, ...], dict[str, EntryPoint]] | None = None  # (sys.path, plugins)

    def register(self, name: str, item: T) -> T:
        if name in self._items:
            raise ValueError(f"{self.kind} {name!r} is registered twice")
        self._items[name] = item
        return item

    def register_lazy(self, name: str, target: str) -> None:
        """A built-in item named by "module:attribute", imported when first asked for."""
        if name in self._items:
            raise ValueError(f"{self.kind} {name!r} is registered twice")
        self._items[name] = _Lazy(target)

    def decorator(self, name: str) -> Callable[[T], T]:
        def wrap(item: T) -> T:
            return self.register(name, item)

        return wrap

    def _plugins(self) -> dict[str, EntryPoint]:
        if self.entry_point_group is None:
            return {}
        # Read again when sys.path changes: a package made importable later (a test, a notebook) is
        # then found; one entry, as the path changes and never changes back for good.
        key = tuple(sys.path)
        if self._plugins_seen is None or self._plugins_seen[0] != key:
            found = {ep.name: ep for ep in entry_points(group=self.entry_point_group) if ep.name not in self._items}
            self._plugins_seen = (key, found)
        return self._plugins_seen[1]

    def builtin_names(self) -> list[str]:
        return list(self._items)

    def plugin(self, name: str) -> EntryPoint | None:
        """The entry point that declares `name`, or None for a built-in or unknown name."""
        return self._plugins().get(name)

    def names(self) -> list[str]:
        """Every name: the built-in ones in their order, then the plugins' sorted."""
        return list(self._items) + sorted(self._plugins())

    def problem(self, name: str) -> str | None:
        """Why a plugin's item cannot load, found without running its code (its module is looked
        for, not imported), or None; so a listing does not offer a plugin whose module is missing."""
        entry = self.plugin(name)
        if entry is None:
            return None
        try:
            found = importlib.util.find_spec(entry.module)
        except (ImportError, ValueError):  # a parent package missing, or an empty name
            found = None
        return None if found is not None else f"its module {entry.module} is not installed"

    def get(self, name: str) -> T:
        if name in self._items:
            item = self._items[name]
            if isinstance(item, _Lazy):
                item = self._items[name] = item.load()
            return item  # type: ignore[return-value]
        entry = self.plugin(name)
        if entry is None:
            raise UnknownNameError(self.kind, name, self.names())
        # A plugin's code runs here: whatever it raises (SystemExit too) is its failure, named.
        try:
            loaded = entry.load()
        except (Exception, SystemExit) as err:
            raise InputError(
                f"{self.kind} {name!r}: entry point {entry.value} cannot be loaded " f"({failure(err)})"
            ) from None
        if self._accept is None:
            return loaded  # type: ignore[no-any-return]
        return self._accept(name, loaded)

    def __contains__(self, name: object) -> bool:
        return name in self._items or (isinstance(name, str) and name in self._plugins())

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())
