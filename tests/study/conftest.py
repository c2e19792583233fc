"""The study tests' fixtures: a folder with the tiny route and the plugin of test methods on the
path, and one study run in it (module-scoped: each module that asks runs its own)."""

from __future__ import annotations

import os

import pytest

from helpers.studies import PLUGIN, ROUTE, write_study
from longslam.slam import catalog
from longslam.study.config import load_study
from longslam.study.driver import run_study


@pytest.fixture(scope="module")
def env(tmp_path_factory, render_cache):
    """The session's render cache, a tiny route, and a plugin of test methods on the path."""
    root = tmp_path_factory.mktemp("study")
    plugins = root / "plugins"
    (plugins / "longslam_test_plugin-0.1.dist-info").mkdir(parents=True)
    (plugins / "longslam_test_plugin.py").write_text(PLUGIN)
    (plugins / "longslam_test_plugin-0.1.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: longslam-test-plugin\nVersion: 0.1\n"
    )
    (plugins / "longslam_test_plugin-0.1.dist-info" / "entry_points.txt").write_text(
        "[longslam.methods]\ngridded = longslam_test_plugin:Gridded\n"
        "crashy = longslam_test_plugin:Crashy\ndies = longslam_test_plugin:Dies\n"
        "sleepy = longslam_test_plugin:Sleepy\nhog = longslam_test_plugin:HOG\n"
    )
    (root / "tiny.txt").write_text(ROUTE)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("LONGSLAM_CACHE", str(render_cache))
        mp.syspath_prepend(str(plugins))  # spawned children get the parent's sys.path
        mp.setenv("PYTHONPATH", os.pathsep.join([str(plugins), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
        # The catalogue finds the entry points again once the plugin is on the path.
        assert {"gridded", "crashy", "dies"} <= set(catalog.method_names())
        yield root


@pytest.fixture(scope="module")
def study(env):
    """One study: two good methods (one with a grid), one that raises, one whose process dies."""
    config = load_study(write_study(env, "main", ["odometry", "gridded", "crashy", "dies"], ["large"], [0, 1]))
    out = env / "main-out"
    summary = run_study(config, out, jobs=2, progress=False)
    return out, summary
