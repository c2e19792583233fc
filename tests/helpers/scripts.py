"""The project's scripts, benchmarks and examples are files, not modules of the package: a test loads
one by its path, registered under `name` (a dataclass in it looks its module up while it is made)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[2]


def load_script(path: Path, name: str) -> ModuleType:
    """The file at `path` (relative to the checkout, or absolute) run as the module `name`."""
    spec = importlib.util.spec_from_file_location(name, ROOT / path)
    assert spec is not None and spec.loader is not None, f"no Python file at {path}"
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
