"""A Ray cluster that is missing, refuses or never answers is a clear error, given up in time,
and creates nothing."""

from __future__ import annotations


import pytest

from helpers.cli_checks import one_line_error
from helpers.studies import tiny_study_file
from longslam.cli.main import main


def test_address_without_ray_is_refused_before_anything(tmp_path, capsys):
    study = tiny_study_file(tmp_path, "1")
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--address", "127.0.0.1:6379"]) == 2
    one_line_error(capsys, "--address 127.0.0.1:6379 is for --executor ray")
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_ray_address_that_refuses_is_a_clear_error_and_creates_nothing(tmp_path, capsys):
    pytest.importorskip("ray")
    import socket
    import time

    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    study = tiny_study_file(tmp_path, "1")
    t0 = time.monotonic()
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--executor", "ray",
                 "--address", f"127.0.0.1:{port}"]) == 2
    assert time.monotonic() - t0 < 30
    one_line_error(capsys, f"127.0.0.1:{port}", "no Ray cluster answered")
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_ray_init_that_hangs_is_given_up(tmp_path, capsys, monkeypatch):
    ray = pytest.importorskip("ray")
    import threading
    import socket

    from longslam.study import backends

    monkeypatch.setattr(backends, "RAY_CONNECT_TIMEOUT_S", 0.5)
    release = threading.Event()
    monkeypatch.setattr(ray, "init", lambda **kw: release.wait(30))  # as ray.init retrying an address
    listener = socket.socket()  # answers TCP, never Ray
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    try:
        study = tiny_study_file(tmp_path, "1")
        address = f"127.0.0.1:{listener.getsockname()[1]}"
        assert main(["study", str(study), "--out", str(tmp_path / "out"), "--executor", "ray", "--address", address]) == 2
        one_line_error(capsys, address, "did not start or answer")
        assert not (tmp_path / "out").exists()
    finally:
        release.set()
        listener.close()


def test_a_ray_client_address_without_ray_client_is_a_clear_error(tmp_path, capsys):
    pytest.importorskip("ray")
    import importlib.util

    if importlib.util.find_spec("grpc") is not None:
        pytest.skip("Ray Client is installed here")
    study = tiny_study_file(tmp_path, "1")
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--executor", "ray", "--address", "ray://head:10001"]) == 2
    one_line_error(capsys, "ray://head:10001", "ray[client]")
    assert not (tmp_path / "out").exists()
