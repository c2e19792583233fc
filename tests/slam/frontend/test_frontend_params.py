"""Every front-end field is a parameter of both methods (`--param frontend.FIELD=VALUE`) and is
written to the run's config.toml."""

import dataclasses
import json
import tomllib
import typing

import pytest

from longslam.cli.common import parse_params
from longslam.core.errors import InputError
from longslam.run.folder import CONFIG, write_config
from longslam.core.settings import to_mapping
from longslam.slam.catalog import check_params
from longslam.slam.frontend import FrontEndConfig

# Another valid value for each text field (the rest are derived from the default below).
OTHER_WORD = {"mode": "wheel", "smoother.optimizer": "gn", "smoother.window": 2000, "depth_trust.loop_inlier_share": 0.5}  # values another than the default


def _leaves(cls: type, default: object, prefix: str = "") -> list[tuple[str, typing.Any, typing.Any]]:
    """(dotted path, type, default) of every field that is not itself a dataclass."""
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        value = getattr(default, f.name)
        if dataclasses.is_dataclass(value):
            out += _leaves(type(value), value, f"{prefix}{f.name}.")
        else:
            out.append((prefix + f.name, hints[f.name], value))
    return out


def _another(path: str, default: typing.Any) -> typing.Any:
    if path in OTHER_WORD:
        return OTHER_WORD[path]
    if default is None:
        return 1.3  # camera_height: given instead of inferred
    if isinstance(default, bool):
        return not default
    if isinstance(default, int):
        return default + 1
    if isinstance(default, float):
        return default * 1.5 if default else 0.001  # a switch that is off at 0 (nonholonomic_sigma)
    if isinstance(default, tuple):
        return tuple(v * 1.5 for v in default)
    raise AssertionError(f"no other value for frontend.{path}={default!r}: add one to OTHER_WORD")


def _text(value: typing.Any) -> str:
    """The value as a user types it after `--param frontend.FIELD=`."""
    return value if isinstance(value, str) else json.dumps(list(value) if isinstance(value, tuple) else value)


def _get(obj: typing.Any, path: str) -> typing.Any:
    for part in path.split("."):
        obj = obj[part] if isinstance(obj, dict) else getattr(obj, part)
    return obj


LEAVES = _leaves(FrontEndConfig, FrontEndConfig())


def test_the_walk_sees_every_nested_front_end_table():
    paths = {path for path, _, _ in LEAVES}
    assert len(paths) > 60
    for table in ("scan", "visual_tracking", "local_map", "registration", "noise", "smoother"):
        assert any(p.startswith(table + ".") for p in paths), table


@pytest.mark.parametrize("method", ["keyframe", "submap"])
@pytest.mark.parametrize("path, kind, default", LEAVES, ids=[p for p, _, _ in LEAVES])
def test_each_front_end_field_is_a_parameter_and_lands_in_config_toml(method, path, kind, default, tmp_path):
    value = _another(path, default)
    assert value != default
    config = check_params(method, parse_params([f"frontend.{path}={_text(value)}"]))
    assert _get(config.frontend, path) == value
    # Only that field moved.
    others = [(p, _get(config.frontend, p)) for p, _, _ in LEAVES if p != path]
    assert others == [(p, d) for p, _, d in LEAVES if p != path]
    write_config(tmp_path, method, to_mapping(config))
    written = tomllib.loads((tmp_path / CONFIG).read_text())["params"]
    assert _get(written["frontend"], path) == (list(value) if isinstance(value, tuple) else value)
    # And the file reads back as the same config.
    assert check_params(method, written) == config


@pytest.mark.parametrize("method", ["keyframe", "submap"])
def test_front_end_values_are_checked_once_for_both_methods(method):
    with pytest.raises(InputError, match="front end: mode must be one of fused, wheel, got 'magic'"):
        check_params(method, parse_params(["frontend.mode=magic"]))
    with pytest.raises(InputError, match="front end: camera_height must be positive"):
        check_params(method, parse_params(["frontend.camera_height=0"]))
    with pytest.raises(InputError, match=r"frontend: parameter visual_sigmas_no_wheels=.*expected a list of 3 values"):
        check_params(method, parse_params(["frontend.visual_sigmas_no_wheels=[0.1, 0.2]"]))
    with pytest.raises(InputError, match=r"unknown parameter camera_height \(did you mean frontend.camera_height\?\)"):
        check_params(method, parse_params(["camera_height=1.3"]))  # the front end's now: frontend.camera_height
