"""A method that breaks the API contract is named in a MethodError that keeps its traceback; what a
user gave wrong stays an InputError."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pytest

from longslam.cli.main import main
from longslam.core.errors import InputError, MethodError
from longslam.core.trajectory import Trajectory
from longslam.io.sequence import SequenceReader
from longslam.run.engine import run_frames
from longslam.slam.catalog import choose_method
from longslam.slam.api import MethodContext, MethodSpec, Result


@dataclass(frozen=True)
class BrokenConfig:
    # "step": step() raises; "shape": step() returns a (3,) pose; "finish": finish() raises;
    # "ahead": work_ahead() raises (on the read-ahead thread)
    breaks: str = "step"

    def __post_init__(self) -> None:
        if self.breaks not in ("step", "shape", "finish", "input", "ahead"):
            raise InputError(f"breaks: expected step, shape, finish, input or ahead, got {self.breaks!r}")


class Broken:
    def __init__(self, context: MethodContext, config: BrokenConfig):
        self.config = config
        self.stamps: list[float] = []
        self.images_every_frame = ("depth",) if config.breaks == "ahead" else ()

    def work_ahead(self, frame) -> None:
        if self.config.breaks == "ahead" and frame.index == 2:
            {}["no such key"]

    def step(self, frame) -> np.ndarray:
        self.stamps.append(frame.timestamp)
        if self.config.breaks == "step" and frame.index == 2:
            return {}["no such key"]  # a plugin's bug: KeyError deep in its code
        if self.config.breaks == "shape":
            return np.zeros(3)
        if self.config.breaks == "input":
            raise InputError("frame needs depth the sequence has not")
        return np.eye(4)

    def finish(self) -> Result:
        if self.config.breaks == "finish":
            raise ZeroDivisionError("division by zero in the optimiser")
        poses = np.repeat(np.eye(4)[None], len(self.stamps), axis=0)
        return Result(Trajectory(np.array(self.stamps), poses))


@pytest.fixture
def broken_method(method_catalogue):
    method_catalogue.register("broken", MethodSpec("broken", BrokenConfig, Broken, "a method with bugs, for tests"))
    return "broken"


@pytest.mark.parametrize("breaks, where", [("step", "step() of frame 2 raised KeyError"),
                                            ("finish", "finish() raised ZeroDivisionError"),
                                            ("ahead", "work_ahead() of frame 2 raised KeyError")])
def test_a_method_that_raises_is_a_method_error_naming_it_and_the_call(tiny_sequence, broken_method, breaks, where):
    reader = SequenceReader(tiny_sequence)
    with pytest.raises(MethodError, match=re.escape(f"method 'broken': {where}")) as caught:
        run_frames(choose_method(broken_method, {"breaks": breaks}), reader, MethodContext(reader.intrinsics, reader.max_depth),
                   progress=False)
    assert caught.value.__cause__ is not None  # the method's own error, with its traceback


def test_a_pose_of_the_wrong_shape_is_a_method_error(tiny_sequence, broken_method):
    reader = SequenceReader(tiny_sequence)
    with pytest.raises(MethodError, match=r"returned a pose of shape \(3,\) for frame 0; expected \(4, 4\)"):
        run_frames(choose_method(broken_method, {"breaks": "shape"}), reader, MethodContext(reader.intrinsics, reader.max_depth),
                   progress=False)


def test_an_input_error_from_a_method_stays_an_input_error(tiny_sequence, broken_method):
    reader = SequenceReader(tiny_sequence)
    with pytest.raises(InputError, match="frame needs depth") as caught:
        run_frames(choose_method(broken_method, {"breaks": "input"}), reader, MethodContext(reader.intrinsics, reader.max_depth),
                   progress=False)
    assert not isinstance(caught.value, MethodError)


def test_the_command_prints_the_methods_traceback_and_one_line_naming_it(tiny_sequence, broken_method, tmp_path,
                                                                         capsys):
    code = main(["run", "--method", "broken", str(tiny_sequence), "--out", str(tmp_path / "run"),
                 "--param", "breaks=step", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2
    assert "Traceback" in err and 'return {}["no such key"]' in err  # where the author's bug is
    assert err.strip().splitlines()[-1].startswith("longslam run: error: method 'broken': step() of frame 2 raised KeyError")
    assert not (tmp_path / "run").exists()  # nothing half-written
