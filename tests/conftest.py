"""Shared test helpers: tiny synthetic sequences, written in a moment, for tests of the run
machinery (the engine, run folders, the CLI) that need frames but not a rendered building; and
rendered sequences, each simulated once per session into the session's own render cache."""

from __future__ import annotations

import builtins
import io
import json
import os
import stat
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from longslam.core.frame import Intrinsics
from longslam.core.geometry import camera_poses_from_planar
from longslam.io.sequence import SequenceWriter
from longslam.sim.simulate import simulate
from longslam.sim.camera import CameraSettings
from longslam.core.odometry_noise import get_noise
from longslam.sim.routes import Route
from longslam.core.trajectory import Trajectory

TINY_INTRINSICS = Intrinsics.from_fov(16, 12, 90.0)


def write_tiny_sequence(
    path: Path, n: int = 30, step: float = 0.15, turn: float = 0.0, odometry_scale: float = 1.0, seed: int = 0,
) -> tuple[Path, Trajectory, Trajectory]:
    """A 16 x 12 sequence of `n` frames at 10 Hz driving `step` m per frame (turning `turn` rad in
    all), with random images and depth, ground truth, and an odometry whose forward steps are
    scaled by `odometry_scale`. Returns (path, ground truth, odometry)."""
    rng = np.random.default_rng(seed)
    stamps = 0.1 * np.arange(n)
    xyyaw = np.column_stack([step * np.arange(n), np.zeros(n), np.linspace(0.0, turn, n)])
    truth = Trajectory(stamps, camera_poses_from_planar(xyyaw, 1.25))
    noisy = xyyaw.copy()
    noisy[:, 0] *= odometry_scale
    odometry = Trajectory(stamps, camera_poses_from_planar(noisy, 1.25))
    with SequenceWriter(path, TINY_INTRINSICS, 8.0, {"route": "tiny"}) as writer:
        for t in stamps:
            writer.add(t, rng.integers(0, 255, (12, 16, 3), dtype=np.uint8), rng.uniform(0.5, 4, (12, 16)).astype(np.float32))
        writer.set_ground_truth(truth)
        writer.set_odometry(odometry)
    return path, truth, odometry


def write_bag_sequence(path: Path) -> Path:
    """A tiny sequence that turns (24 frames), with noise level 'large' and the camera's height
    in its meta.json: what a bag's export needs to carry."""
    write_tiny_sequence(path, n=24, turn=1.0, odometry_scale=1.05)
    meta = json.loads((path / "meta.json").read_text())
    (path / "meta.json").write_text(json.dumps({**meta, "noise": "large", "camera": {"camera_height": 1.25}}))
    return path


@pytest.fixture(scope="module")
def tiny_sequence(tmp_path_factory) -> Path:
    """20 frames straight ahead, odometry exact."""
    return write_tiny_sequence(tmp_path_factory.mktemp("tiny") / "seq", n=20)[0]


@pytest.fixture(scope="session")
def render_cache(tmp_path_factory) -> Path:
    """The test session's own render cache: a test neither reads nor fills the user's, and a route
    rendered for one file is not rendered again for another (another noise level or seed only
    draws new odometry)."""
    return tmp_path_factory.mktemp("render-cache")


RenderedSequence = Callable[..., Path]


@pytest.fixture(scope="session")
def rendered(render_cache: Path, tmp_path_factory) -> RenderedSequence:
    """`rendered(route, noise, seed, camera=CameraSettings())`: the simulated sequence folder for
    (route, noise level, seed, camera), made once per session in the session's render cache. The
    folder is shared: a test that changes it must copy it first."""
    made: dict[tuple, Path] = {}

    def sequence(route: Route, noise: str, seed: int, camera: CameraSettings = CameraSettings()) -> Path:
        key = (route, noise, seed, camera)
        if key not in made:
            out = tmp_path_factory.mktemp(f"{route.name}-{noise}-{seed}") / "seq"
            with pytest.MonkeyPatch.context() as mp:
                mp.setenv("LONGSLAM_CACHE", str(render_cache))
                made[key] = simulate(route, get_noise(noise), seed, out, camera=camera, progress=False)
        return made[key]

    return sequence


@pytest.fixture()
def nothing_under_dev(monkeypatch):
    """Any open, rename or removal of a path under /dev fails the test, before it happens: for tests
    that a device node (/dev/null, /dev/zero) is refused before it is touched, which as root
    could otherwise replace /dev/null, or read /dev/zero until memory runs out."""

    def guard(real):
        def checked(*args, **kwargs):
            for arg in args[:2]:
                if isinstance(arg, (str, bytes, os.PathLike)) and os.fsdecode(arg).startswith("/dev/"):
                    pytest.fail(f"{real.__name__} on {os.fsdecode(arg)}")
            return real(*args, **kwargs)
        return checked

    for module, name in ((builtins, "open"), (io, "open"), (os, "open"), (os, "replace"), (os, "rename"),
                         (os, "unlink"), (os, "remove")):
        monkeypatch.setattr(module, name, guard(getattr(module, name)))
    yield
    monkeypatch.undo()
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def one_line_error(capsys, *needles: str) -> str:
    """The command's stderr was one line, an error naming every needle, and no traceback."""
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "error:" in lines[0], err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


TINY_VOCABULARY = "2 1 0 0\n" + ("0 1 " + " ".join(["7"] * 32) + " 1.0\n") * 2  # k 2, L 1: a root and 2 words


@pytest.fixture()
def vocabulary_cache(tmp_path, monkeypatch):
    """A cache of its own whose default vocabulary 'build' writes TINY_VOCABULARY at once; the
    list of builds it made."""
    from longslam.vocabulary import build

    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    built: list[Path] = []

    def fake_build(sequence, out, **kwargs):
        Path(out).write_text(TINY_VOCABULARY)
        built.append(Path(out))

    monkeypatch.setattr(build, "rendered_route", lambda *a, **k: tmp_path)
    monkeypatch.setattr(build, "build_vocabulary_file", fake_build)
    return built
