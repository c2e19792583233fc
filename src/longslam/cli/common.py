"""What several commands share: the camera and world options, method parameters, the output-file check."""

from __future__ import annotations

import argparse
import os
import re

from longslam.core.errors import InputError, LongslamError

CAMERA_HELP = {
    "width": "image width in pixels",
    "height": "image height in pixels",
    "fov": "horizontal field of view in degrees",
    "max_depth": "depth range in metres",
    "camera_height": "camera height above the floor in metres",
}


def add_camera_options(parser: argparse.ArgumentParser) -> None:
    # Names and defaults come from CameraSettings, so the CLI cannot drift from the library.
    from longslam.sim.camera import CAMERA_KEYS, CameraSettings

    defaults = CameraSettings()
    for key, field in CAMERA_KEYS.items():
        parser.add_argument(
            f"--{key.replace('_', '-')}",
            dest=f"camera_{key}",
            metavar=key.upper(),
            help=f"{CAMERA_HELP[key]} (default {getattr(defaults, field)})",
        )


def camera_from_args(args: argparse.Namespace):
    from longslam.core.settings import from_mapping
    from longslam.sim.camera import CAMERA_KEYS, CameraSettings

    given = {field: getattr(args, f"camera_{key}") for key, field in CAMERA_KEYS.items()}
    try:
        return from_mapping(CameraSettings, {k: v for k, v in given.items() if v is not None}, "camera")
    except InputError as err:  # named as the user gave it: --fov, not the field hfov_deg
        keys = {**{key: key for key in CAMERA_KEYS}, **{field: key for key, field in CAMERA_KEYS.items()}}
        bad = re.match(r"camera(?: setting |: parameter )(\w+)(?: \(\w+\))?(=\S+:| must be)", str(err))
        if bad is None or bad[1] not in keys:
            raise
        option = "--" + keys[bad[1]].replace("_", "-")
        rest = str(err)[bad.end() :].strip()
        if bad[2] == " must be":
            raise InputError(f"{option} must be {rest}") from None
        raise InputError(f"{option} {getattr(args, 'camera_' + keys[bad[1]])}: {rest}") from None


def parse_params(pairs: list[str]) -> dict:
    from longslam.core.settings import parse_key_values

    return parse_key_values(pairs)


MESH_OPTIONS = ("floor", "units", "up", "places")


def add_world_options(parser: argparse.ArgumentParser, default: str | None) -> None:
    shown = f" (default {default})" if default else " (default: the route's world)"
    parser.add_argument("--world", help=f"world name (see `longslam list`) or a mesh file (PLY, OBJ, GLB/glTF){shown}")
    parser.add_argument(
        "--floor", type=float, help="floor height of a mesh in metres, once turned z-up (default: found)"
    )
    parser.add_argument("--units", choices=("m", "cm", "mm"), help="length unit of a mesh file (default m)")
    parser.add_argument("--up", choices=("z", "y"), help="up axis of a mesh file (default y for GLB/glTF, z otherwise)")
    parser.add_argument("--places", help='places file of a mesh: JSON {"name": [x, y], ...}')


def world_from_args(args: argparse.Namespace, value: str | None) -> str | None:
    """The world reference the options give, or None if they name no world."""
    from longslam.world import WORLDS, world_ref

    options = {k: getattr(args, k) for k in MESH_OPTIONS if getattr(args, k) is not None}
    if value is None:
        if options:
            raise LongslamError(f"--{next(iter(options))} describes a mesh file: give it with --world FILE")
        return None
    if value in WORLDS:
        if options:
            raise LongslamError(f"--{next(iter(options))} describes a mesh file, not the world {value!r}")
        return value
    return world_ref({"mesh": value, **options} if options else value, what="--world")


def describe_world(name: str, mesh_floor_z: float | None) -> str:
    if mesh_floor_z is None:
        return f"world {name}"
    return f"world {name} (floor at z = {mesh_floor_z:.3f} m in the mesh file)"


def given_files(paths: list[str | None]) -> dict[str, str]:
    """The command's inputs that are files or folders on disk (a route or world may be a name)."""
    return {f"input {p}": p for p in paths if p is not None and os.path.exists(p)}


def check_out_file(args: argparse.Namespace, out: str, what: str, inputs: list[str | None]) -> None:
    """An output file replaces an existing one only with --overwrite, and never an input."""
    from longslam.io.overwrite_policy import check_not_an_input, check_output_file_free

    check_not_an_input(out, given_files(inputs), what, inside=False)
    check_output_file_free(out, args.overwrite, what)
