"""Help for every option: each option of each subcommand has help, `demo --help` explains its
choices, the common options work before and after every subcommand, and `list --params` shows each
parameter's default, allowed values and doc, as the configs accept them."""

from __future__ import annotations

import argparse

import pytest

from helpers.cli_checks import exit_status
from longslam.cli.main import build_parser, main
from longslam.cli.parser import subcommand_parsers
from longslam.cli.settings_doc import describe
from longslam.core.errors import InputError
from longslam.slam.catalog import BUILTIN, get_spec


def _all_parsers() -> list[argparse.ArgumentParser]:
    parser = build_parser()
    return [parser, *subcommand_parsers(parser)]


def test_every_option_of_every_subcommand_has_help():
    missing = []
    for parser in _all_parsers():
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                missing += [f"{parser.prog} {c.dest}" for c in action._choices_actions if not c.help]
            elif not action.help or action.help == argparse.SUPPRESS:
                missing.append(f"{parser.prog} {'/'.join(action.option_strings) or action.dest}")
    assert not missing, missing


def test_demo_help_explains_route_noise_and_seed(capsys):
    assert exit_status(["demo", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--route ROUTE route name" in text and "--noise NOISE odometry noise level" in text
    assert "--seed SEED seed of the odometry noise" in text


def test_common_options_before_and_after_every_subcommand():
    for parser in _all_parsers():
        for flag in ("--debug", "-v", "--verbose", "--quiet", "--no-progress"):
            assert flag in parser._option_string_actions, (parser.prog, flag)
    parser = build_parser()
    assert parser.parse_args(["-vv", "list"]).verbose == 2  # the top's value survives the subcommand
    args = parser.parse_args(["list", "-v", "--quiet", "--no-progress"])
    assert (args.verbose, args.quiet, args.no_progress) == (1, True, True)
    assert parser.parse_args(["list"]).verbose is None


def test_list_params_shows_default_allowed_values_and_doc(capsys):
    assert main(["list", "--params", "keyframe"]) == 0
    lines = {line.split()[0]: " ".join(line.split()) for line in capsys.readouterr().out.splitlines()[1:]}
    assert lines["max_features"].startswith("max_features 2000 whole number 1 to 100000 ")
    assert lines["vocabulary_index"].startswith("vocabulary_index hnsw one of bruteforce, flat, hnsw ")
    assert lines["loop_sigma_linear"].startswith("loop_sigma_linear 0.05 (0, inf) ")
    # A bound relative to another field is checked by hand and said in the doc.
    assert lines["obstacle_min_height"].startswith("obstacle_min_height 0.2 [0, inf) m ")
    assert "below obstacle_max_height" in lines["obstacle_min_height"]
    assert lines["grid_cell"].startswith("grid_cell 0.05 [0.01, 10] m ")
    assert lines["frontend.camera_height"].startswith("frontend.camera_height none (0, inf) m or none ")
    assert lines["frontend.scan.cell"].startswith("frontend.scan.cell 0.05 (0, inf) m ")
    assert len(lines) == len(describe(get_spec("keyframe").config_type))


@pytest.mark.parametrize("method", sorted(BUILTIN))
def test_every_parameter_has_a_line_of_doc(method):
    config_type = get_spec(method).config_type
    thin = [(p.name, p.doc) for p in describe(config_type) if len(p.doc.split()) < 3 or len(p.doc) > 160]
    assert not thin, thin


@pytest.mark.parametrize("method", sorted(BUILTIN))
def test_listed_choices_are_what_the_config_accepts(method):
    import dataclasses

    config_type = get_spec(method).config_type
    for param in describe(config_type):
        if not param.allowed.startswith("one of "):
            continue
        for choice in param.allowed[len("one of "):].split(", "):
            get_spec(method).config({param.name: choice})
        with pytest.raises(InputError):
            get_spec(method).config({param.name: "no-such-choice"})
    assert dataclasses.is_dataclass(config_type) or config_type is None
