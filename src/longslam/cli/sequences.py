"""The commands that make a sequence's world and frames: `world` and `simulate`."""

from __future__ import annotations

import argparse

from longslam.cli.common import (
    add_camera_options,
    add_world_options,
    camera_from_args,
    check_out_file,
    describe_world,
    given_files,
    world_from_args,
)
from longslam.core.errors import LongslamError


def cmd_world(args: argparse.Namespace) -> None:
    from longslam.io.paths import PLOT_SUFFIXES, check_output_file
    from longslam.sim.drive import drive_route
    from longslam.sim.routes import get_route
    from longslam.viz.plots import plot_plan
    from longslam.world import load_world

    check_output_file(args.out, PLOT_SUFFIXES, "--out")
    check_out_file(args, args.out, "--out", [args.route, args.mesh or args.world, args.places])
    if args.mesh and args.world:
        raise LongslamError("give the world once: --world NAME_OR_FILE (--mesh FILE is the same)")
    ref = world_from_args(args, args.mesh or args.world)
    route = get_route(args.route, ref) if args.route else None
    world = load_world(ref or (route.world if route else "university"))
    paths, waypoints, title = {}, None, f"world {world.name}"
    if route:
        driven = drive_route(world, route)
        paths[f"route {route.name} ({driven.length:.0f} m)"] = driven.xyyaw[:, :2]
        waypoints = route.resolve(world.places)
        title += f", route {route.name}: {len(waypoints)} waypoints, {driven.length:.1f} m"
    plot_plan(world.occupancy, args.out, paths, waypoints=waypoints, title=title)
    print(f"wrote {args.out}: {describe_world(world.name, None if world.plan else world.source_floor_z)}")


def cmd_simulate(args: argparse.Namespace) -> None:
    from longslam.core.odometry_noise import get_noise
    from longslam.io.overwrite_policy import check_not_an_input
    from longslam.io.sequence import SequenceReader
    from longslam.sim.routes import get_route
    from longslam.sim.simulate import simulate
    from longslam.world import world_label

    check_not_an_input(args.out, given_files([args.route, args.world, args.places]), "sequence folder")
    route = get_route(args.route, world_from_args(args, args.world))
    from longslam.sim.perturbations import parse_perturbations
    from longslam.sim.sensors import get_sensor

    noise = get_noise(args.noise)
    sensor = get_sensor(args.sensor)  # before any rendering: a typo costs nothing
    perturbations = parse_perturbations(args.perturb)
    out = simulate(
        route,
        noise,
        args.seed,
        args.out,
        camera=camera_from_args(args),
        overwrite=args.overwrite,
        sensor=sensor,
        perturbations=perturbations,
    )
    meta = SequenceReader(out).meta  # renders cached before meta had world_name: the route's world
    name = meta.get("world_name") or world_label(route.world)
    perturbed = (
        f", perturbed by {meta['perturbation']} ({meta['frames_dropped']} frames dropped)" if perturbations else ""
    )
    print(f"wrote sequence {out}: route {route.name} in {describe_world(name, meta.get('mesh_floor_z'))}{perturbed}")


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """`world` and `simulate`."""
    p = sub.add_parser("world", help="draw a world's floor plan, optionally with a route")
    add_world_options(p, "university, or the route file's")
    p.add_argument("--mesh", help="a mesh file: the same as --world FILE")
    p.add_argument("--route", help="a route name or a waypoint file to draw")
    p.add_argument("--out", required=True, help="image file to write (e.g. plan.png)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing image file")
    p.set_defaults(func=cmd_world)

    p = sub.add_parser("simulate", help="render a route with noisy odometry into a TUM RGB-D sequence")
    p.add_argument("--route", required=True, help="route name (see `longslam list`) or a waypoint file")
    add_world_options(p, None)
    p.add_argument("--noise", default="none", help="odometry noise level (none, small, medium, large, xlarge)")
    p.add_argument("--seed", type=int, default=0, help="seed of the odometry noise and of the sensor's")
    p.add_argument(
        "--sensor",
        default="ideal",
        help="sensor model: ideal (perfect colour and depth), kinect-v1, "
        "realsense-d435, or a plugin's (see `longslam list`)",
    )
    p.add_argument(
        "--perturb",
        action="append",
        default=[],
        metavar="NAME[=LEVEL]",
        help="a perturbation after the sensor model: drop, drop-burst, depth-offset, exposure, blur, "
        "depth-dropout, or a plugin's (see `longslam list`); repeatable, applied in order",
    )
    p.add_argument("--out", required=True, help="sequence folder to write")
    p.add_argument("--overwrite", action="store_true", help="replace an existing folder")
    add_camera_options(p)
    p.set_defaults(func=cmd_simulate)
