"""Each parameter of a config dataclass described: its default, what values it takes, one line of doc.

`longslam list --params METHOD` prints this. Two sources, so the description cannot drift from
the code:
- The doc is the field's comment in the dataclass's source: its trailing `# ...` comment, or
  else the comment block right above it (its first sentence).
- The allowed values are found by asking the config itself: a number's bounds by bisection on
  what the dataclass's own `__post_init__` accepts (with every other field at its default), a
  text field's values from the class's `CHOICES` (a `ClassVar`, checked by the tests against
  `__post_init__`). A bound that depends on another field is shown at that field's default.
"""

from __future__ import annotations

import dataclasses
import inspect
import io
import math
import re
import textwrap
import tokenize
from dataclasses import dataclass
from typing import Any

from longslam.core.settings import _field_type

FAR = 1e12  # beyond this a number is taken as unbounded
_STEPS = 80  # bisection steps: a float bound to ~1e-12 of its scale


@dataclass(frozen=True)
class Parameter:
    name: str  # dotted for a nested config's field: frontend.mode
    default: Any
    allowed: str
    doc: str


def describe(cls: type, prefix: str = "") -> list[Parameter]:
    """Every parameter of the dataclass `cls`, a nested config's after its own, in field order."""
    docs = field_docs(cls)
    base = cls()
    out: list[Parameter] = []
    nested: list[Parameter] = []
    for f in dataclasses.fields(cls):
        kind, optional = _field_type(cls, f.name)
        if dataclasses.is_dataclass(kind):
            nested.extend(describe(kind, f"{prefix}{f.name}."))
            continue
        default = getattr(base, f.name)
        out.append(
            Parameter(
                f"{prefix}{f.name}", default, allowed_values(cls, base, f.name, kind, optional), docs.get(f.name, "")
            )
        )
    return out + nested


# --- the doc: comments in the source -----------------------------------------------------------
_FIELD = re.compile(r"^([A-Za-z_]\w*)\s*:")


def field_docs(cls: type) -> dict[str, str]:
    """{field: one line of doc} from the comments of the class's source ({} without a source)."""
    try:
        source = textwrap.dedent(inspect.getsource(cls))
    except (OSError, TypeError):
        return {}
    comments: dict[int, str] = {}
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            comments[token.start[0]] = token.string.lstrip("#").strip()
    names = {f.name for f in dataclasses.fields(cls)}
    docs: dict[str, str] = {}
    block: list[str] = []
    body_indent = None
    in_body = False
    for number, line in enumerate(source.splitlines(), start=1):
        stripped = line.strip()
        indent = len(line) - len(line.lstrip())
        if not in_body:  # decorators, then the class line
            in_body = stripped.startswith("class ")
            continue
        if not stripped:
            block = []
            continue
        if body_indent is None:
            body_indent = indent
        if indent != body_indent:
            continue
        if stripped.startswith("def ") or stripped.startswith("@"):
            break
        if stripped.startswith("#"):
            block.append(comments.get(number, stripped.lstrip("#").strip()))
            continue
        match = _FIELD.match(stripped)
        if match and match.group(1) in names:
            own = comments.get(number)
            docs[match.group(1)] = own if own else _first_sentence(" ".join(block))
        block = []
    return docs


def _first_sentence(text: str) -> str:
    match = re.search(r"(?<=[a-z0-9)\]])[.:;](\s|$)", text)
    return text[: match.start()].strip() if match else text.strip()


# --- the allowed values: asked of the config -------------------------------------------------
def _accepts(base: Any, name: str, value: Any) -> bool:
    try:
        dataclasses.replace(base, **{name: value})
    except Exception:  # whatever __post_init__ raises (InputError, ValueError...) means "refused"
        return False
    return True


def allowed_values(cls: type, base: Any, name: str, kind: Any, optional: bool) -> str:
    none = " or none" if optional else ""
    if kind is bool:
        return "true or false" + none
    if kind is str:
        choices = getattr(cls, "CHOICES", {}).get(name)
        return ("one of " + ", ".join(choices) if choices else "text") + none
    if kind in (int, float):
        start = getattr(base, name)
        if start is None:
            start = 1 if kind is int else 1.0
        if not _accepts(base, name, start):
            return f"{kind.__name__}{none}"
        low, high = _bound(base, name, start, -1, kind), _bound(base, name, start, +1, kind)
        return _interval(base, name, low, high, kind) + none
    if getattr(kind, "__origin__", None) is tuple:
        return f"a list of {len(kind.__args__)} numbers{none}"
    return getattr(kind, "__name__", str(kind)) + none


def _bound(base: Any, name: str, start: float, direction: int, kind: type) -> float | None:
    """The last accepted value going from `start` in `direction` (None: none up to FAR)."""
    inside = start
    step = 1 if kind is int else max(abs(start), 1.0)
    outside = None
    while abs(inside + direction * step) <= FAR:
        probe = inside + direction * step
        if _accepts(base, name, kind(probe)):
            inside = probe
            step *= 2
        else:
            outside = probe
            break
    if outside is None:
        return None
    for _ in range(_STEPS):
        middle = (inside + outside) / 2
        if kind is int:
            middle = math.floor(middle) if direction > 0 else math.ceil(middle)
            if middle in (inside, outside):
                break
        if _accepts(base, name, kind(middle)):
            inside = middle
        else:
            outside = middle
    return kind(inside)


def _round(value: float) -> float:
    return 0.0 if abs(value) < 1e-9 else float(f"{value:.6g}")


def _interval(base: Any, name: str, low: float | None, high: float | None, kind: type) -> str:
    if kind is int:
        if low is None and high is None:
            return "any whole number (unchecked)"
        if high is None:
            return f"whole number >= {low}"
        if low is None:
            return f"whole number <= {high}"
        return f"whole number {low} to {high}"
    parts = []
    for bound, side in ((low, "low"), (high, "high")):
        if bound is None:
            parts.append("-inf" if side == "low" else "inf")
            continue
        shown = _round(bound)
        closed = _accepts(base, name, shown)
        parts.append(f"{'[' if closed else '('}{shown:g}" if side == "low" else f"{shown:g}{']' if closed else ')'}")
    low_text, high_text = parts
    if low is None and high is None:
        return "any number (unchecked)"
    if low_text == "-inf":
        low_text = "(-inf"
    if high_text == "inf":
        high_text = "inf)"
    return f"{low_text}, {high_text}"
