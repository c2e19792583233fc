"""Each parameter of a config dataclass described: its default, what values it takes, one line of doc.

`longslam list --params METHOD` prints this, and the parameter reference page is built from it.
All of it is read from each field's declaration (`longslam.core.parameter.param`): the doc, the
range with its unit, the choices; the same declaration the config's `__post_init__` checks a
value against, so the description cannot drift from the code. A bound relative to another field
is checked by hand in `__post_init__` and said in the doc. A field declared without `param` (a
plugin's plain dataclass) is shown by its type alone, with no doc.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from longslam.core.parameter import Declared, declared
from longslam.core.settings import _field_type


@dataclass(frozen=True)
class Parameter:
    name: str  # dotted for a nested config's field: frontend.mode
    default: Any
    allowed: str
    doc: str


def describe(cls: type, prefix: str = "") -> list[Parameter]:
    """Every parameter of the dataclass `cls`, a nested config's after its own, in field order."""
    base = cls()
    out: list[Parameter] = []
    nested: list[Parameter] = []
    for f in dataclasses.fields(cls):
        kind, optional = _field_type(cls, f.name)
        if dataclasses.is_dataclass(kind):
            nested.extend(describe(kind, f"{prefix}{f.name}."))
            continue
        rule = declared(f) or Declared("")
        out.append(Parameter(f"{prefix}{f.name}", getattr(base, f.name), rule.allowed(kind, optional), rule.doc))
    return out + nested
