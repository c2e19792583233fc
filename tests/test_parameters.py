"""Each method parameter declared once (`core.parameter.param`): doc, range, unit and choices, held by
`check_declared` and shown by `longslam list --params`."""

import dataclasses
from dataclasses import dataclass

import pytest

from longslam.core.errors import InputError
from longslam.core.parameter import check_declared, declared, param
from longslam.slam.catalog import check_params, get_spec, method_names


def _config_types():
    """Every typed method config, and every config nested in one, by a dotted path."""
    out = {}

    def walk(cls, path):
        out[path] = cls
        for f in dataclasses.fields(cls):
            if isinstance(f.default_factory, type) and dataclasses.is_dataclass(f.default_factory):
                walk(f.default_factory, f"{path}.{f.name}")

    for name in method_names():
        try:
            config_type = get_spec(name).config_type
        except Exception:  # a plugin that cannot be loaded here
            continue
        if config_type is not None:
            walk(config_type, name)
    return out


CONFIGS = _config_types()


def test_the_method_configs_are_found():
    assert {"keyframe", "submap", "command", "keyframe.frontend", "keyframe.frontend.scan"} <= set(CONFIGS)


@pytest.mark.parametrize("path", sorted(CONFIGS))
def test_every_field_is_declared_with_a_doc_and_its_default_within_its_range(path):
    cls = CONFIGS[path]
    base = cls()
    for f in dataclasses.fields(cls):
        rule = declared(f)
        assert rule is not None, f"{path}.{f.name} is not declared with param()"
        assert rule.doc.strip(), f"{path}.{f.name} has no doc"
        assert rule.accepts(getattr(base, f.name)), f"{path}.{f.name}: the default is outside its range"
    check_declared(base, path)


@pytest.mark.parametrize(
    "method, key, value, needle",
    [
        ("keyframe", "grid_cell", 0.001, "method 'keyframe': grid_cell must be from 0.01 to 10 m (a finer grid"),
        ("keyframe", "vocabulary_index", "exact", "vocabulary_index must be one of bruteforce, flat, hnsw, got 'exact'"),
        ("submap", "voxel_size", 0, "method 'submap': voxel_size must be from 0.02 to 5 m"),
        ("submap", "registration_sampling_ratio", 1.5, "registration_sampling_ratio must be in (0, 1], got 1.5"),
        ("command", "timeout", -1, "method 'command': timeout must be in (0, 2.592e+06] s, got -1"),
        ("keyframe", "frontend.scan_information_scale", -1, "front end: scan_information_scale must be >= 0, got -1"),
        ("keyframe", "frontend.visual_sigmas_no_wheels", [0.1, 0, 0.1], "each of visual_sigmas_no_wheels must be"),
        ("submap", "frontend.scan.cell", -1, "front end: scan.cell must be positive, got -1"),
        ("keyframe", "frontend.visual_tracking.quality", 2, "visual_tracking.quality must be in (0, 1], got 2"),
        ("keyframe", "frontend.local_map.max_scans", 0, "local_map.max_scans must be >= 1, got 0"),
        ("keyframe", "frontend.registration.sigma", 0, "registration.sigma must be positive, got 0"),
        ("keyframe", "frontend.noise.lateral", -0.001, "noise.lateral must be positive, got -0.001"),
        ("keyframe", "frontend.smoother.optimizer", "bfgs", "smoother.optimizer must be one of lm, gn, got 'bfgs'"),
        ("keyframe", "frontend.depth_trust.stride", 0, "depth_trust.stride must be >= 1, got 0"),
        ("keyframe", "frontend.wall_axes.min_share", 1.5, "wall_axes.min_share must be from 0 to 1, got 1.5"),
    ],
)
def test_a_value_outside_its_declaration_is_refused_naming_the_parameter(method, key, value, needle):
    with pytest.raises(InputError) as caught:
        check_params(method, {key: value})
    assert needle in str(caught.value)
    assert "\n" not in str(caught.value)


def test_the_orbslam3_plugin_declares_its_parameters_too():
    pytest.importorskip("longslam_orbslam3", reason="the orbslam3 plugin is not installed")
    with pytest.raises(InputError, match="method 'orbslam3': features must be from 100 to 20000, got 50"):
        check_params("orbslam3", {"features": 50})
    with pytest.raises(InputError, match="min_th_fast .* must be at most ini_th_fast"):
        check_params("orbslam3", {"min_th_fast": 30})


def test_cross_field_checks_stay_by_hand():
    with pytest.raises(InputError, match="obstacle_max_height must exceed obstacle_min_height"):
        check_params("keyframe", {"obstacle_min_height": 2.0})
    with pytest.raises(InputError, match="smoother.window must be 0 .no limit. or at least twice bias_block"):
        check_params("keyframe", {"frontend.smoother.window": 10})
    assert check_params("keyframe", {"frontend.smoother.window": 0}).frontend.smoother.window == 0


def test_a_declaration_is_checked_where_it_is_written():
    with pytest.raises(ValueError, match="outside its own declaration"):
        param(-1.0, "a length", above=0)

    @dataclass(frozen=True)
    class Toy:
        share: float = param(0.5, "a share of something", at_least=0, at_most=1)
        size: float = param(1.0, "a size in metres", above=0, below=10, unit="m", why="it is held in memory")

        def __post_init__(self):
            check_declared(self, "toy")

    with pytest.raises(InputError, match=r"^toy: size must be in \(0, 10\) m \(it is held in memory\), got 12.0$"):
        Toy(size=12.0)
    with pytest.raises(InputError, match="share must be from 0 to 1, got nan"):
        Toy(share=float("nan"))
    rules = {f.name: declared(f) for f in dataclasses.fields(Toy)}
    assert rules["share"].allowed(float) == "[0, 1]"
    assert rules["size"].allowed(float, optional=True) == "(0, 10) m or none"
    assert rules["size"].allowed(int) == "whole number 1 to 9 m"
