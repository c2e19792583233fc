"""longslam's floors, from the code's own imports: each package (or top-level module) of
`src/longslam/` stands above every one it imports, imports anywhere in a file counted (inside
functions too). Prints the floors top down and any import that runs back up (an import circle
between two packages); `--draw FILE.png` draws them.

    python scripts/architecture.py [--draw docs/images/architecture/floors.png]

`tests/test_architecture.py` holds the code to what this prints: no import circle between packages,
at most 6 modules at the top of the package.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "src" / "longslam"


def part_of(module: str) -> str | None:
    """The package (or top-level module) of `longslam.X.Y...`: X; None outside longslam."""
    parts = module.split(".")
    if parts[0] != "longslam" or len(parts) < 2:
        return None
    return parts[1]


def module_of(name: str, package: Path = PACKAGE) -> str | None:
    """The module of the tree that an imported name lies in (`longslam.a.b.f` -> `longslam.a.b`, a
    package for its `__init__.py`); None outside longslam."""
    parts = name.split(".")
    if parts[0] != "longslam":
        return None
    for k in range(len(parts), 1, -1):
        path = package.joinpath(*parts[1:k])
        if path.with_suffix(".py").exists() or (path / "__init__.py").exists():
            return ".".join(parts[:k])
    return None


def imports_by_part(
    package: Path = PACKAGE, unit: Callable[[str], str | None] = part_of
) -> dict[str, dict[str, list[str]]]:
    """{part: {imported part: [file:line where it is imported]}} over every .py file, imports
    inside functions too; a part is what `unit` makes of a module's name (its package, or with
    `module_of` the module itself)."""
    found: dict[str, dict[str, list[str]]] = defaultdict(lambda: defaultdict(list))
    for path in sorted(package.rglob("*.py")):
        relative = path.relative_to(package.parent)
        module = ".".join(relative.with_suffix("").parts).removesuffix(".__init__")
        here = unit(module)
        if here is None:
            continue
        found[here]  # a part that imports nothing still stands on the ground
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets: set[str | None] = set()
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                # `from p import m` takes module m of p where there is one, else a name of p.
                targets = {unit(f"{node.module}.{a.name}") or unit(node.module) for a in node.names}
            elif isinstance(node, ast.Import):
                targets = {unit(a.name) for a in node.names}
            for there in targets - {None, here}:
                assert there is not None
                if unit is not part_of or (package / there).exists() or (package / f"{there}.py").exists():
                    found[here][there].append(f"{relative}:{node.lineno}")
    return {part: dict(targets) for part, targets in found.items()}


def floors(graph: dict[str, dict[str, list[str]]]) -> dict[str, int]:
    """Each part's floor: 1 + the highest floor it imports (1: imports no other part). Parts in a
    circle share the floor of the circle."""
    floor: dict[str, int] = {}

    def height(part: str, seen: tuple[str, ...]) -> int:
        if part in floor:
            return floor[part]
        if part in seen:
            return 0
        below = [height(t, seen + (part,)) for t in graph.get(part, {})]
        floor[part] = 1 + max(below, default=0)
        return floor[part]

    for part in graph:
        height(part, ())
    return floor


def circles(graph: dict[str, dict[str, list[str]]]) -> list[tuple[str, str, list[str]]]:
    """Imports that run back up: (part, imported part, where) for each pair that import each
    other through any chain."""
    reach: dict[str, set[str]] = {}

    def reachable(part: str) -> set[str]:
        if part not in reach:
            reach[part] = set()
            todo = list(graph.get(part, {}))
            while todo:
                nxt = todo.pop()
                if nxt not in reach[part]:
                    reach[part].add(nxt)
                    todo.extend(graph.get(nxt, {}))
        return reach[part]

    return [(part, there, where) for part, targets in graph.items() for there, where in targets.items()
            if part in reachable(there)]


def top_modules(package: Path = PACKAGE) -> list[str]:
    return sorted(p.name for p in package.glob("*.py"))


def draw(graph: dict[str, dict[str, list[str]]], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    floor = floors(graph)
    rows: dict[int, list[str]] = defaultdict(list)
    for part in sorted(floor):
        rows[floor[part]].append(part)
    where = {}
    for level, parts in rows.items():
        for i, part in enumerate(parts):
            where[part] = ((i + 1) / (len(parts) + 1), level)
    fig, ax = plt.subplots(figsize=(9, 1.1 * max(rows) + 1))
    for part, targets in graph.items():
        for there in targets:
            (x0, y0), (x1, y1) = where[part], where[there]
            ax.annotate("", xy=(x1, y1 + 0.15), xytext=(x0, y0 - 0.15),
                        arrowprops={"arrowstyle": "->", "color": "0.7", "lw": 0.7})
    for part, (x, y) in where.items():
        lines = sum(len(p.read_text().splitlines()) for p in
                    ((PACKAGE / part).rglob("*.py") if (PACKAGE / part).is_dir() else [PACKAGE / f"{part}.py"]))
        ax.text(x, y, f"{part}/\n{lines:,} lines" if (PACKAGE / part).is_dir() else part, ha="center", va="center",
                fontsize=9, bbox={"boxstyle": "round", "fc": "#e8eef6", "ec": "#4a6a8a"})
    ax.set_ylim(0.4, max(rows) + 0.6)
    ax.set_xlim(0, 1)
    ax.axis("off")
    ax.set_title("longslam's floors: each package stands above what it imports (scripts/architecture.py)", fontsize=10)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110, bbox_inches="tight")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--draw", type=Path, help="draw the floors into this PNG")
    args = parser.parse_args(argv)
    graph = imports_by_part()
    floor = floors(graph)
    for level in sorted(set(floor.values()), reverse=True):
        print(f"floor {level}: {', '.join(sorted(p for p in floor if floor[p] == level))}")
    print(f"top-level modules: {', '.join(top_modules())}")
    back = circles(graph)
    for part, there, where in back:
        print(f"runs back up: {part} -> {there} at {', '.join(where)}")
    print(f"{len(back)} imports run back up")
    if args.draw:
        draw(graph, args.draw)
        print(f"drew {args.draw}")
    return 1 if back else 0


if __name__ == "__main__":
    sys.exit(main())
