"""Each parameter of a config dataclass declared once, with its default, doc and valid values.

After RTAB-Map's `Parameters.h`: a field is declared as

    grid_cell: float = param(0.05, "cell size of a node's local grid", at_least=0.01, at_most=10.0, unit="m")

and that one declaration is what `longslam list --params` shows, what the parameter reference
page prints, and what `check_declared` (called by the config's `__post_init__`) holds a value
to. A check that relates one field to another stays hand-written in the `__post_init__`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, TypeVar

from longslam.core.errors import InputError

T = TypeVar("T")
KEY = "longslam.parameter"  # the key of a field's metadata that holds its `Declared`


@dataclass(frozen=True)
class Declared:
    """What a field's declaration says: one line of doc, its bounds (each optional; `at_least` and
    `at_most` inclusive, `above` and `below` exclusive), its unit, the text values it takes, and
    why a bound is there (shown with a refusal)."""

    doc: str
    at_least: float | None = None
    at_most: float | None = None
    above: float | None = None
    below: float | None = None
    unit: str = ""
    choices: tuple[str, ...] | None = None
    why: str = ""

    @property
    def low(self) -> tuple[float, bool] | None:
        """The lower bound and whether it is allowed itself (None: unbounded)."""
        if self.at_least is not None:
            return self.at_least, True
        return None if self.above is None else (self.above, False)

    @property
    def high(self) -> tuple[float, bool] | None:
        if self.at_most is not None:
            return self.at_most, True
        return None if self.below is None else (self.below, False)

    def accepts(self, value: Any) -> bool:
        if value is None:
            return True  # a field that may be None says so in its type
        if isinstance(value, tuple):
            return all(self.accepts(item) for item in value)
        if self.choices is not None:
            return value in self.choices
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return True
        if not math.isfinite(value):
            return False
        low, high = self.low, self.high
        if low is not None and not (value >= low[0] if low[1] else value > low[0]):
            return False
        return high is None or (value <= high[0] if high[1] else value < high[0])

    def bounds_text(self) -> str:
        """The range as a refusal says it: "positive", ">= 0", "from 1 to 1000", "in (0, 1]"."""
        low, high = self.low, self.high
        if low is None and high is None:
            return "a finite number"
        if high is None:
            assert low is not None
            return "positive" if low == (0, False) else f"{'>=' if low[1] else '>'} {low[0]:g}"
        if low is None:
            return f"{'<=' if high[1] else '<'} {high[0]:g}"
        if low[1] and high[1]:
            return f"from {low[0]:g} to {high[0]:g}"
        return f"in {_interval(low, high)}"

    def allowed(self, kind: Any, optional: bool = False) -> str:
        """What values the field takes, as `longslam list --params` shows them."""
        none = " or none" if optional else ""
        unit = f" {self.unit}" if self.unit else ""
        if kind is bool:
            return "true or false" + none
        if kind is str:
            return ("one of " + ", ".join(self.choices) if self.choices else "text") + none
        if getattr(kind, "__origin__", None) is tuple:
            numbers = f"a list of {len(kind.__args__)} numbers"
            if self.low is None and self.high is None:
                return numbers + unit + none
            return f"{numbers}, each {_interval(self.low, self.high)}{unit}{none}"
        if kind is int:
            return _whole_numbers(self.low, self.high) + unit + none
        if kind is float:
            if self.low is None and self.high is None:
                return "any number" + unit + none
            return _interval(self.low, self.high) + unit + none
        return getattr(kind, "__name__", str(kind)) + none


def _interval(low: tuple[float, bool] | None, high: tuple[float, bool] | None) -> str:
    left = "(-inf" if low is None else f"{'[' if low[1] else '('}{low[0]:g}"
    right = "inf)" if high is None else f"{high[0]:g}{']' if high[1] else ')'}"
    return f"{left}, {right}"


def _whole_numbers(low: tuple[float, bool] | None, high: tuple[float, bool] | None) -> str:
    least = None if low is None else (math.ceil(low[0]) if low[1] else math.floor(low[0]) + 1)
    most = None if high is None else (math.floor(high[0]) if high[1] else math.ceil(high[0]) - 1)
    if least is None and most is None:
        return "any whole number"
    if most is None:
        return f"whole number >= {least}"
    if least is None:
        return f"whole number <= {most}"
    return f"whole number {least} to {most}"


def param(
    default: T,
    doc: str,
    *,
    at_least: float | None = None,
    at_most: float | None = None,
    above: float | None = None,
    below: float | None = None,
    unit: str = "",
    choices: tuple[str, ...] | None = None,
    why: str = "",
) -> T:
    """A dataclass field with `default` that declares its doc, range, unit and choices."""
    declared = Declared(doc, at_least, at_most, above, below, unit, None if choices is None else tuple(choices), why)
    if not declared.accepts(default):
        raise ValueError(f"the default {default!r} is outside its own declaration {declared}")
    field: T = dataclasses.field(default=default, metadata={KEY: declared})
    return field


def nested(factory: type[T], doc: str) -> T:
    """A field holding a nested config (its own fields are its parameters, `head.field`)."""
    field: T = dataclasses.field(default_factory=factory, metadata={KEY: Declared(doc)})
    return field


def declared(field: dataclasses.Field[Any]) -> Declared | None:
    """The field's declaration (None for a field declared without `param`)."""
    found = field.metadata.get(KEY)
    return found if isinstance(found, Declared) else None


def check_declared(config: Any, what: str, prefix: str = "") -> None:
    """Each field of the dataclass `config` within its declared range or choices; else InputError
    naming `what` (the owner: "method 'keyframe'", "front end"), the parameter (`prefix` + its
    name), what it may be (with the unit, and why where the declaration says) and what it is."""
    for field in dataclasses.fields(config):
        rule = declared(field)
        value = getattr(config, field.name)
        if rule is None or rule.accepts(value):
            continue
        name = f"{prefix}{field.name}"
        if rule.choices is not None:
            raise InputError(f"{what}: {name} must be one of {', '.join(rule.choices)}, got {value!r}")
        unit = f" {rule.unit}" if rule.unit and rule.bounds_text() != "positive" else ""
        why = f" ({rule.why})" if rule.why else ""
        each = "each of " if isinstance(value, tuple) else ""
        raise InputError(f"{what}: {each}{name} must be {rule.bounds_text()}{unit}{why}, got {value!r}")
