"""A study folder belongs to one study definition: its name and its grid (world, routes, noise
levels, methods, seeds). Another study into the same folder would be merged into one database
and one report headed by the last study's name; it is refused unless the user asks to extend.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

from longslam.core.errors import InputError
from longslam.study.database import DB_NAME, connect_read_only


def _grid(config: dict[str, Any]) -> dict[str, Any]:
    from longslam.world.reference import world_identity

    world = config.get("world", "")
    return {
        "name": config.get("name"),
        "world": world_identity(world) if isinstance(world, str) and world else world,
        "routes": sorted(json.dumps(r, sort_keys=True) for r in config.get("routes", [])),
        "noise": sorted(config.get("noise", [])),
        "methods": sorted((m.get("label"), m.get("method")) for m in config.get("methods", [])),
        "seeds": sorted(config.get("seeds", [])),
        "sensors": sorted(config.get("sensors", [])),
        "perturbations": sorted(config.get("perturbations", [])),
        "repeats": config.get("repeats", 1),
        "depth_delay": config.get("depth_delay"),
    }


def _summary(config: dict[str, Any]) -> str:
    routes = ", ".join(r.get("name", "?") for r in config.get("routes", []))
    methods = ", ".join(m.get("label", "?") for m in config.get("methods", []))
    seeds = config.get("seeds", [])
    sensors = f"; sensors {', '.join(config['sensors'])}" if config.get("sensors") else ""
    sensors += f"; perturbations {', '.join(config['perturbations'])}" if config.get("perturbations") else ""
    sensors += f"; {config['repeats']} repeats" if config.get("repeats", 1) != 1 else ""
    sensors += f"; depth delay {config['depth_delay']:g} s" if config.get("depth_delay") is not None else ""
    return (
        f"study {config.get('name')!r} (routes {routes}; noise {', '.join(config.get('noise', []))}; "
        f"methods {methods}{sensors}; {len(seeds)} seed{'' if len(seeds) == 1 else 's'})"
    )


def stored_study(out: Path) -> dict[str, Any] | None:
    """The study definition recorded in `out`'s database, read without writing; None if none."""
    path = Path(out) / DB_NAME
    if not path.is_file():
        return None
    try:
        conn = connect_read_only(path)
        try:
            row = conn.execute("SELECT value FROM study WHERE key = 'config'").fetchone()
        finally:
            conn.close()
    except sqlite3.DatabaseError as err:
        if "no such table" in str(err):
            return None
        raise InputError(f"results database {path} cannot be read: {err}") from None
    if row is None:
        return None
    try:
        config = json.loads(row[0])
    except ValueError as err:
        raise InputError(f"results database {path}: table study, key config: not valid JSON ({err})") from None
    return config if isinstance(config, dict) else None


def differences(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    a, b = _grid(old), _grid(new)
    return [key for key in a if a[key] != b[key]]


def check_same_study(out: Path, config: dict[str, Any], extend: bool) -> dict[str, Any]:
    """The study definition to record in `out`: `config` if the folder is new or holds the same
    study; with `extend`, the folder's grid widened by `config`'s. Otherwise InputError."""
    old = stored_study(out)
    if old is None:
        return config
    changed = differences(old, config)
    if not changed:
        return config
    if not extend:
        raise InputError(
            f"study folder {out} holds {_summary(old)}; {config.get('source') or 'this study'} is "
            f"{_summary(config)}, different in {', '.join(changed)}; choose another --out, or pass --extend to add "
            "its runs to this folder (its report then covers both)"
        )
    if old.get("depth_delay") != config.get("depth_delay"):
        # One report describes its runs' depth as moved by one delay (or none).
        raise InputError(
            f"study folder {out} holds runs with depth_delay {old.get('depth_delay')}; "
            f"{config.get('source') or 'this study'} has {config.get('depth_delay')}: a folder holds one depth "
            "delay; choose another --out"
        )
    return merged(old, config)


def merged(old: dict[str, Any], new: dict[str, Any]) -> dict[str, Any]:
    """The folder's study widened by `new`: its name kept, each axis the union (old order first)."""

    def union(key: str, ident) -> list:
        seen, out = set(), []
        for item in list(old.get(key, [])) + list(new.get(key, [])):
            k = ident(item)
            if k not in seen:
                seen.add(k)
                out.append(item)
        return out

    result = dict(new)
    result["name"] = old.get("name", new.get("name"))
    result["routes"] = union("routes", lambda r: r.get("name"))
    result["noise"] = union("noise", lambda n: n)
    result["methods"] = union("methods", lambda m: m.get("label"))
    result["seeds"] = union("seeds", lambda s: s)
    if old.get("sensors") or new.get("sensors"):
        # A folder without the axis holds the ideal sensor's runs under keys without a sensor.
        result["sensors"] = union("sensors", lambda s: s)
    if old.get("perturbations") or new.get("perturbations"):
        # A folder without the axis holds the unperturbed runs under keys without a perturbation.
        result["perturbations"] = union("perturbations", lambda p: p)
    if max(old.get("repeats", 1), new.get("repeats", 1)) != 1:
        result["repeats"] = max(old.get("repeats", 1), new.get("repeats", 1))
    return result
