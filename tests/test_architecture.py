"""The package's shape: few modules at its top, no import that runs back up a floor (an import
circle between two of its packages, or two of its modules, imports inside functions counted), no
method leaning on a sibling method. `scripts/architecture.py` prints the floors these are measured on."""

from __future__ import annotations

import ast
from functools import partial
from pathlib import Path

from helpers.scripts import load_script

ROOT = Path(__file__).resolve().parent.parent
architecture = load_script(Path("scripts/architecture.py"), "architecture")

METHODS = ("keyframe", "submap", "command")


def test_at_most_six_modules_stand_at_the_top_of_the_package():
    assert len(architecture.top_modules()) <= 6, architecture.top_modules()


def test_no_import_runs_back_up_a_floor():
    assert architecture.circles(architecture.imports_by_part()) == []


def test_a_circle_is_found_where_there_is_one(tmp_path):
    """The check can fail: two packages that import each other, one inside a function."""
    for name, body in (("a", "from longslam.b import x\n"), ("b", "def f():\n    from longslam.a import y\n")):
        (tmp_path / "longslam" / name).mkdir(parents=True)
        (tmp_path / "longslam" / name / "__init__.py").write_text(body)
    found = architecture.circles(architecture.imports_by_part(tmp_path / "longslam"))
    assert {(a, b) for a, b, _ in found} == {("a", "b"), ("b", "a")}


def test_no_two_modules_import_each_other_even_within_a_package():
    by_module = architecture.imports_by_part(unit=partial(architecture.module_of, package=architecture.PACKAGE))
    assert architecture.circles(by_module) == []


def test_a_circle_of_modules_in_one_package_is_found(tmp_path):
    """The check can fail: two modules of one package through a function's import, as
    eval/map_align and eval/map_quality were."""
    package = tmp_path / "longslam"
    (package / "eval").mkdir(parents=True)
    (package / "eval" / "__init__.py").write_text("")
    (package / "eval" / "align.py").write_text("from longslam.eval.quality import points\n")
    (package / "eval" / "quality.py").write_text("def scores():\n    from longslam.eval.align import align\n")
    by_module = architecture.imports_by_part(package, unit=partial(architecture.module_of, package=package))
    found = {(a, b) for a, b, _ in architecture.circles(by_module)}
    assert found == {("longslam.eval.align", "longslam.eval.quality"), ("longslam.eval.quality", "longslam.eval.align")}


def test_no_method_imports_a_sibling_method():
    slam = architecture.PACKAGE / "slam"
    for method in METHODS:
        for path in (slam / method).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ImportFrom) and node.module:
                    others = [m for m in METHODS if m != method and node.module.startswith(f"longslam.slam.{m}")]
                    assert not others, f"{path.relative_to(ROOT)}:{node.lineno} imports {node.module}"
