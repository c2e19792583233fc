"""The fixtures several folders share: a tiny sequence, the session's render cache and its rendered
sequences, a guard against touching /dev, a vocabulary cache of its own, and the methods' catalogue
for a test to register its own methods on. Helper functions
(tiny sequences, a generated building, flat walls, CLI checks, ...) are in the `helpers` package."""

from __future__ import annotations

import builtins
import io
import os
import stat
from collections.abc import Callable
from pathlib import Path

import pytest

from helpers.tiny_sequences import write_tiny_sequence
from helpers.tiny_vocabulary import TINY_VOCABULARY
from longslam.core.odometry_noise import get_noise
from longslam.sim.camera import CameraSettings
from longslam.sim.routes import Route
from longslam.sim.simulate import simulate


@pytest.fixture(scope="module")
def tiny_sequence(tmp_path_factory) -> Path:
    """20 frames straight ahead, odometry exact."""
    return write_tiny_sequence(tmp_path_factory.mktemp("tiny") / "seq", n=20)[0]


@pytest.fixture(scope="session")
def render_cache(tmp_path_factory) -> Path:
    """The test session's own render cache: a test neither reads nor fills the user's, and a route
    rendered for one file is not rendered again for another (another noise level or seed only
    draws new odometry). Under pytest-xdist each worker is a session of its own with its own
    temporary folders, so each has its own cache: no two processes write one cache folder."""
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


@pytest.fixture()
def method_catalogue(monkeypatch):
    """The methods' catalogue (`longslam.slam.catalog.METHODS`), put back as it was after the test:
    the methods a test registers on it are its own."""
    from longslam.slam import catalog

    monkeypatch.setattr(catalog.METHODS, "_items", dict(catalog.METHODS._items))
    return catalog.METHODS
