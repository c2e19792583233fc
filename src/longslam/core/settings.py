"""One way to turn user-given values into typed dataclass settings, and back.

Method parameters (`--param key=value`, a study file's `[params.M]`), camera options (CLI flags,
a study's `[camera]`) and the follower's settings all come through `from_mapping`: strings from
the command line and TOML/JSON values alike are converted to each field's type, unknown keys and
bad values are refused with the key, the value and what is valid, and non-finite numbers are
refused everywhere. A dataclass checks its own ranges in `__post_init__` (a method's config against
each field's declaration, `core/parameter.py`), so a config that exists is a valid one.
`to_mapping` / `to_toml` write a config back, so each run folder can keep the settings it ran with
(`config.toml`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import types
import typing
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, TypeVar

from longslam.core.errors import InputError

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

C = TypeVar("C", bound="DataclassInstance")

TRUE_WORDS = ("1", "true", "yes", "on")
FALSE_WORDS = ("0", "false", "no", "off")


def _field_type(cls: type, name: str) -> tuple[type, bool]:
    """The field's base type and whether it may be None."""
    kind = typing.get_type_hints(cls)[name]
    if typing.get_origin(kind) in (typing.Union, types.UnionType) and type(None) in typing.get_args(kind):
        base = next(a for a in typing.get_args(kind) if a is not type(None))
        return base, True
    return kind, False


def _finite_number(raw: Any, expected: str) -> float:
    if isinstance(raw, bool):  # True is an int to Python, not a number to a user
        raise ValueError(expected)
    try:
        value = float(raw)
    except (TypeError, ValueError):
        raise ValueError(expected) from None
    if not math.isfinite(value):
        raise ValueError(expected)
    return value


def convert(raw: Any, kind: Any, optional: bool = False) -> Any:
    """`raw` (a string from the command line, or a TOML/JSON value) as a value of type `kind`.

    Raises ValueError with what was expected.
    """
    if raw is None or (optional and isinstance(raw, str) and raw.lower() in ("none", "null")):
        if not optional:
            raise ValueError("may not be empty")
        return None
    if kind is bool:
        if isinstance(raw, bool):
            return raw
        if isinstance(raw, int) and raw in (0, 1):
            return bool(raw)
        if isinstance(raw, str) and raw.lower() in TRUE_WORDS + FALSE_WORDS:
            return raw.lower() in TRUE_WORDS
        raise ValueError("expected true or false")
    if kind is int:
        value = _finite_number(raw, "expected a whole number")
        if not value.is_integer():
            raise ValueError("expected a whole number")
        return int(value)
    if kind is float:
        return _finite_number(raw, "expected a finite number")
    if kind is str:
        if not isinstance(raw, (str, int, float)) or isinstance(raw, bool):
            raise ValueError("expected a string")
        return str(raw)
    if typing.get_origin(kind) is tuple:
        # A fixed-length tuple (tuple[float, float, float]): a list from TOML or JSON.
        items = typing.get_args(kind)
        if not isinstance(raw, (list, tuple)) or len(raw) != len(items):
            raise ValueError(f"expected a list of {len(items)} values")
        return tuple(convert(value, item) for value, item in zip(raw, items))
    raise ValueError(f"fields of type {kind!r} cannot be set from text")


def field_names(cls: type) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


def from_mapping(cls: type[C], values: Mapping[str, Any], what: str, base: C | None = None, typed: bool = False) -> C:
    """An instance of the dataclass `cls` with `values` over its defaults (or over `base`).

    `what` names the owner in errors, e.g. "method 'keyframe'" or "camera". A field that is itself
    a dataclass takes a table (`registration = {sigma = 0.05}`) or dotted keys
    (`registration.sigma=0.05`). Unknown keys and unconvertible values raise InputError naming the
    key, the value and what is valid; the dataclass's own `__post_init__` then checks ranges.
    `typed`: the values come from a typed file (TOML), so a string for a number or a boolean is
    refused (`width = "320"` is a mistake there), where from the command line it is converted.
    """
    if not isinstance(values, Mapping):
        raise InputError(f"{what}: expected a table of key = value, got {values!r}")
    names = field_names(cls)
    flat: dict[str, Any] = {}
    nested: dict[str, dict[str, Any]] = {}
    for key, raw in values.items():
        head, dot, tail = str(key).partition(".")
        if head in names and (dot or isinstance(raw, Mapping)) and dataclasses.is_dataclass(_field_type(cls, head)[0]):
            nested.setdefault(head, {}).update({tail: raw} if dot else dict(raw))
        else:
            flat[key] = raw
    unknown = sorted(set(flat) - set(names), key=str)
    if unknown:
        raise InputError(_unknown_keys(cls, unknown, what))
    converted = {}
    for key, raw in flat.items():
        kind, optional = _field_type(cls, key)
        if typed and isinstance(raw, str) and kind in (int, float, bool):
            expected = {bool: "true or false", int: "a whole number"}.get(kind, "a finite number")
            raise InputError(
                f"{what}: parameter {key}={raw!r}: expected {expected}, got a string (write it without quotes)"
            )
        try:
            converted[key] = convert(raw, kind, optional)
        except ValueError as err:
            raise InputError(f"{what}: parameter {key}={raw!r}: {err}") from None
    if nested:
        start = base if base is not None else cls()
        for head, sub in nested.items():
            converted[head] = from_mapping(
                type(getattr(start, head)), sub, f"{what}: {head}", getattr(start, head), typed
            )
    if base is not None:
        return dataclasses.replace(base, **converted)
    return cls(**converted)


def parameter_names(cls: type, prefix: str = "") -> list[str]:
    """Every settable key of the dataclass `cls`, a nested config's fields as `head.field`."""
    out = []
    for name in field_names(cls):
        kind = _field_type(cls, name)[0]
        out.extend(parameter_names(kind, f"{prefix}{name}.") if dataclasses.is_dataclass(kind) else [f"{prefix}{name}"])
    return out


def _unknown_keys(cls: type, unknown: list[Any], what: str) -> str:
    """The error for keys `cls` does not have: "did you mean" for a near miss (a typo), the list of
    valid keys only when nothing is close, since a list of 42 names hides the one that was meant."""
    from longslam.core.suggest import close_names

    names = field_names(cls)
    candidates = names + [n for n in parameter_names(cls) if n not in names]
    guesses = {key: close_names(str(key), candidates, n=1) for key in unknown}
    if all(guesses.values()):
        shown = ", ".join(f"{key} (did you mean {guesses[key][0]}?)" for key in unknown)
        return f"{what}: unknown parameter {shown}"
    valid = ", ".join(sorted(names)) if names else "none (it takes no parameters)"
    return f"{what}: unknown parameter(s) {', '.join(map(str, unknown))}; valid parameters: {valid}"


def to_mapping(config: Any) -> dict[str, Any]:
    """The dataclass's fields and values (None values kept; nested dataclasses as dicts)."""
    out = {}
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        out[f.name] = to_mapping(value) if dataclasses.is_dataclass(value) else value
    return out


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {value!r}")


def _toml_lines(table: Mapping[str, Any], prefix: str = "") -> list[str]:
    lines = []
    for key, value in table.items():
        if isinstance(value, Mapping):  # a nested config: dotted keys, as `--param` spells them
            lines.extend(_toml_lines(value, f"{prefix}{key}."))
        elif value is None:
            lines.append(f"# {prefix}{key}: not set (default)")
        else:
            lines.append(f"{prefix}{key} = {_toml_value(value)}")
    return lines


def to_toml(tables: Mapping[str, Mapping[str, Any]]) -> str:
    """TOML text of named tables of plain values, a nested table as dotted keys; None values are
    left out (TOML has no null), and a comment says so, so reading the file back gives the
    default for them."""
    lines: list[str] = []
    for name, table in tables.items():
        lines.append(f"[{name}]")
        lines.extend(_toml_lines(table))
        lines.append("")
    return "\n".join(lines)


def parse_key_values(pairs: list[str], option: str = "--param") -> dict[str, Any]:
    """`KEY=VALUE` strings (repeatable command-line options) as a dict; a value is JSON when it
    parses as JSON (numbers, true/false, lists), else the string itself, converted later by
    `from_mapping` to the field's type."""
    params: dict[str, Any] = {}
    for pair in pairs:
        if "=" not in pair:
            raise InputError(f"{option} {pair!r}: expected KEY=VALUE")
        key, value = pair.split("=", 1)
        try:
            params[key] = json.loads(value)
        except json.JSONDecodeError:
            params[key] = value
    return params
