"""Typed method configs built from `--param key=value` dictionaries, with errors that list keys."""

from __future__ import annotations

import dataclasses
import math
import typing
from typing import Any, TypeVar

from longslam.errors import InputError

C = TypeVar("C")


def config_from_params(cls: type[C], params: dict[str, Any], method: str) -> C:
    """An instance of the dataclass `cls` with `params` overriding its defaults.

    Values are converted to each field's type (so "0.5" from the command line becomes 0.5);
    unknown keys and unconvertible values raise InputError naming the key and what is valid.
    """
    fields = {f.name: f for f in dataclasses.fields(cls)}
    hints = typing.get_type_hints(cls)
    unknown = sorted(set(params) - set(fields))
    if unknown:
        raise InputError(
            f"method {method!r}: unknown parameter(s) {', '.join(unknown)}; valid parameters: {', '.join(sorted(fields))}"
        )
    values = {}
    for key, raw in params.items():
        kind = hints[key]
        optional = typing.get_origin(kind) in (typing.Union, getattr(__import__("types"), "UnionType", None)) and type(None) in typing.get_args(kind)
        base = next((a for a in typing.get_args(kind) if a is not type(None)), kind) if optional else kind
        try:
            if raw is None or (optional and str(raw).lower() in ("none", "null")):
                if not optional:
                    raise ValueError("may not be empty")
                values[key] = None
            elif base is bool:
                if isinstance(raw, bool):
                    values[key] = raw
                elif str(raw).lower() in ("1", "true", "yes", "on"):
                    values[key] = True
                elif str(raw).lower() in ("0", "false", "no", "off"):
                    values[key] = False
                else:
                    raise ValueError("expected true or false")
            elif base is int:
                if isinstance(raw, float) and not raw.is_integer():
                    raise ValueError("expected a whole number")
                values[key] = int(raw)
            else:
                values[key] = base(raw)
        except (TypeError, ValueError) as err:
            raise InputError(f"method {method!r}: parameter {key}={raw!r}: {err} (expected {getattr(base, '__name__', base)})") from None
    _refuse_non_finite(values, method)
    config = cls(**values)
    check = getattr(config, "validate", None)
    if check is not None:
        check()
    return config


def _refuse_non_finite(values: dict[str, Any], method: str) -> None:
    """NaN or an infinity passes float() but would silently disable every comparison it enters."""
    for key, value in values.items():
        if isinstance(value, float) and not math.isfinite(value):
            raise InputError(f"method {method!r}: parameter {key}={value!r}: expected a finite number")
