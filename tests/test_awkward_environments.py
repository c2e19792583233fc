"""Environments that used to end in a traceback: no rerun viewer or display for --viz, a C locale
with non-ASCII paths, paths that are not UTF-8, and a LONGSLAM_CACHE that is a file or empty."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from helpers.cli_checks import one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main


@pytest.fixture()
def seq(tmp_path) -> Path:
    return write_tiny_sequence(tmp_path / "seq", n=12)[0]


def test_viz_live_without_a_viewer_or_a_display_is_a_clear_error(seq, tmp_path, capsys, monkeypatch):
    pytest.importorskip("rerun")
    import shutil as shutil_module

    from longslam.viz import live

    monkeypatch.setattr(live, "_viewer_listening", lambda port=9876: False)
    monkeypatch.setattr(shutil_module, "which", lambda *a, **k: None)
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run"), "--viz"]) == 2
    one_line_error(capsys, "rerun viewer", "not on PATH", "--viz run.rrd")
    monkeypatch.undo()
    monkeypatch.setattr(live, "_viewer_listening", lambda port=9876: False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run"), "--viz"]) == 2
    one_line_error(capsys, "no display", "--viz run.rrd")
    assert not (tmp_path / "run").exists()


def _longslam(*args: str, env: dict | None = None, cwd: Path | None = None):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "longslam", *args], capture_output=True, cwd=cwd,
                          env={**os.environ, **(env or {})}, timeout=120)


@pytest.mark.slow
def test_non_ascii_paths_under_a_c_locale_and_paths_that_are_not_utf8(tmp_path):
    seq = write_tiny_sequence(tmp_path / "séquence", n=8)[0]
    c_locale = {"LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    done = _longslam("run", "--method", "odometry", str(seq), "--out", str(tmp_path / "exécution"), env=c_locale)
    assert done.returncode == 0, done.stderr.decode(errors="replace")
    assert b"Traceback" not in done.stderr
    assert (tmp_path / "exécution" / "config.toml").is_file()
    raw = os.fsencode(tmp_path) + b"/run\xff"  # not valid UTF-8
    done = _longslam("run", "--method", "odometry", str(seq), "--out", os.fsdecode(raw))
    assert done.returncode == 0, done.stderr.decode(errors="replace")
    assert os.path.isfile(raw + b"/stats.json")


@pytest.mark.parametrize("value, needle", [("file", "is a file; expected a folder"), ("", None)])
def test_longslam_cache_that_is_a_file_or_empty(tmp_path, capsys, monkeypatch, value, needle):
    from longslam.sim.simulate import cache_root

    monkeypatch.chdir(tmp_path)
    if value == "file":
        (tmp_path / "file").write_text("x")
        monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "file"))
        assert main(["simulate", "--route", "demo", "--out", str(tmp_path / "s")]) == 2
        one_line_error(capsys, "LONGSLAM_CACHE=", needle)
    else:
        monkeypatch.setenv("LONGSLAM_CACHE", "")
        monkeypatch.setenv("HOME", str(tmp_path / "home"))
        assert cache_root() == tmp_path / "home" / ".cache" / "longslam"  # not the current folder
