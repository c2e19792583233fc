"""One settings layer: user values to typed configs and back, for methods, camera and follower."""

import tomllib

import pytest

from longslam.core.errors import InputError
from longslam.core.settings import from_mapping, parse_key_values, to_mapping, to_toml
from longslam.sim.camera import CameraSettings
from longslam.sim.follower import FollowerSettings
from longslam.slam.frontend import FrontEndConfig
from longslam.slam.keyframe import KeyframeConfig
from longslam.slam.submap.config import SubmapConfig


def test_values_from_the_command_line_and_toml_get_the_fields_types():
    config = from_mapping(KeyframeConfig, parse_key_values(["max_features=500", "proximity=off", "frontend.camera_height=1.3"]), "keyframe")
    assert (config.max_features, config.proximity, config.frontend.camera_height) == (500, False, 1.3)
    assert from_mapping(KeyframeConfig, {"frontend.camera_height": "none"}, "keyframe").frontend.camera_height is None
    assert from_mapping(CameraSettings, {"width": 64.0, "hfov_deg": "60"}, "camera") == CameraSettings(width=64, hfov_deg=60.0)


@pytest.mark.parametrize("cls, key, value, expected", [
    (KeyframeConfig, "max_features", 2.5, "whole number"),
    (KeyframeConfig, "loop_threshold", float("nan"), "finite"),
    (SubmapConfig, "voxel_size", "-inf", "finite"),
    (SubmapConfig, "loop_closure", "maybe", "true or false"),
    (CameraSettings, "width", "wide", "whole number"),
    (FollowerSettings, "linear_speed", "Infinity", "finite"),
])
def test_bad_values_name_the_key_the_value_and_what_is_expected(cls, key, value, expected):
    with pytest.raises(InputError, match=rf"owner: parameter {key}=.*{expected}"):
        from_mapping(cls, {key: value}, "owner")


def test_unknown_keys_list_the_valid_ones_and_ranges_are_the_configs_own():
    with pytest.raises(InputError, match=r"unknown parameter voxel \(did you mean voxel_size\?\)"):
        from_mapping(SubmapConfig, {"voxel": 0.1}, "method 'submap'")
    with pytest.raises(InputError, match="must be positive"):
        from_mapping(SubmapConfig, {"submap_interval": 0}, "method 'submap'")
    with pytest.raises(InputError, match="expected KEY=VALUE"):
        parse_key_values(["voxel_size"])


@pytest.mark.parametrize("config", [
    KeyframeConfig(max_features=300, frontend=FrontEndConfig(mode="wheel", camera_height=1.3)),
    SubmapConfig(loop_closure=True, frontend_registrations=False),
])
def test_a_config_written_as_toml_reads_back_the_same(config):
    text = to_toml({"params": to_mapping(config)})
    back = from_mapping(type(config), tomllib.loads(text)["params"], "back")
    assert back == config
