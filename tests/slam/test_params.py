"""Method parameters from the command line: non-finite numbers are refused for every parameter."""

import dataclasses
import typing

import pytest

from longslam.cli.common import parse_params
from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics
from longslam.slam.api import MethodContext
from longslam.slam.keyframe import KeyframeConfig
from longslam.slam.catalog import create_method
from longslam.slam.submap.config import SubmapConfig

CONTEXT = MethodContext(Intrinsics.from_fov(16, 12, 90.0), 8.0)


def _float_fields(cls) -> list[str]:
    hints = typing.get_type_hints(cls)
    return [f.name for f in dataclasses.fields(cls) if float in (hints[f.name], *typing.get_args(hints[f.name]))]


CASES = [("keyframe", key) for key in _float_fields(KeyframeConfig)] + [("submap", key) for key in _float_fields(SubmapConfig)]


@pytest.mark.parametrize("method, key", CASES)
@pytest.mark.parametrize("text", ["nan", "NaN", "inf", "-Infinity"])
def test_non_finite_values_are_refused(method, key, text):
    params = parse_params([f"{key}={text}"])  # as the command line decodes them
    with pytest.raises(InputError, match=rf"{key}.*finite"):
        create_method(method, CONTEXT, params)


def test_every_float_parameter_is_covered():
    assert len(CASES) > 30 and ("keyframe", "loop_threshold") in CASES
