"""What longslam has: `vocabulary build` and `list`."""

from __future__ import annotations

import argparse

from longslam.cli.common import add_camera_options, add_world_options, camera_from_args, given_files, world_from_args
from longslam.core.errors import LongslamError


def list_params(method: str) -> None:
    from longslam.cli.settings_doc import describe
    from longslam.slam.catalog import get_spec

    spec = get_spec(method)
    if spec.config_type is None:
        print(f"{method}: takes its parameters as given (no typed config to describe)")
        return
    rows = [(p.name, _toml_text(p.default), p.allowed, p.doc) for p in describe(spec.config_type)]
    print(
        f"{method}: {len(rows)} parameters (--param NAME=VALUE, or [params.{method}] in a study file)"
        if rows
        else f"{method}: no parameters"
    )
    if rows:
        widths = [max(len(row[i]) for row in rows) for i in range(3)]
        for row in rows:
            print("  " + "  ".join(cell.ljust(w) for cell, w in zip(row[:3], widths)) + "  " + row[3])


def _toml_text(value: object) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, tuple):
        return "[" + ", ".join(map(str, value)) + "]"
    return str(value)


def cmd_list(args: argparse.Namespace) -> None:
    if args.params_of is not None:
        list_params(args.params_of)
        return
    from longslam.core.odometry_noise import NOISE_LEVELS
    from longslam.sim.routes import ROUTES
    from longslam.sim.sensors import sensor_names
    from longslam.sim.tours import EXAMPLES as TOUR_EXAMPLES
    from longslam.slam.catalog import method_names
    from longslam.world import WORLDS

    print("worlds:      ", ", ".join(WORLDS.names()), "(or a mesh file: --world FILE)")
    print("routes:      ", ", ".join(ROUTES.names()))
    print(
        "long routes:  NAME-xN (a route N times over), tour-<L>km or tour-<L>m[-seed<S>] (a seeded random tour "
        "of the world's places), e.g. " + ", ".join(TOUR_EXAMPLES)
    )
    print(
        "noise levels:",
        ", ".join(
            f"{n} ({NOISE_LEVELS.get(n).linear_std} m, {NOISE_LEVELS.get(n).angular_std_deg} deg per frame)"
            for n in NOISE_LEVELS
        ),
    )
    print("methods:     ", ", ".join(method_names()), "(parameters: longslam list --params METHOD)")
    from longslam.sim.sensors.catalog import sensor_problem

    problems = {name: sensor_problem(name) for name in sensor_names()}
    print(
        "sensors:     ",
        ", ".join(name + (f" (broken: {problems[name]})" if problems[name] else "") for name in sensor_names()),
    )
    from longslam.sim.perturbations.catalog import describe_levels

    print("perturbations:", "; ".join(describe_levels()), "(--perturb NAME[=LEVEL])")


def cmd_vocabulary_build(args: argparse.Namespace) -> None:
    from longslam.sim.routes import get_route
    from longslam.vocabulary.build import (
        build_vocabulary_file,
        check_features,
        check_output,
        check_tree_size,
        rendered_route,
    )

    check_tree_size(args.k, args.levels)  # all before a route is rendered
    check_features(args.features)
    from longslam.io.overwrite_policy import check_not_an_input

    # an input first: that is the better reason to refuse a file of the input sequence
    check_not_an_input(args.out, given_files([args.sequence, args.route, args.world, args.places]), "--out")
    check_output(args.out, args.overwrite)
    from longslam.sim.simulate import check_seed

    check_seed(args.seed, "--seed")  # the same range wherever a seed enters
    world = world_from_args(args, args.world)
    if args.sequence is not None:
        camera = [
            f"--{k[len('camera_'):].replace('_', '-')}"
            for k, v in vars(args).items()
            if k.startswith("camera_") and v is not None
        ]
        if world is not None or camera:
            raise LongslamError(
                f"{(camera or ['--world'])[0]} describes the route to render; a --sequence has its frames already"
            )
        sequence, source = args.sequence, f"sequence {args.sequence}"
    else:
        route = get_route(args.route, world)
        sequence, source = rendered_route(route, camera_from_args(args)), f"route {route.name}"
    summary = build_vocabulary_file(
        sequence,
        args.out,
        k=args.k,
        levels=args.levels,
        seed=args.seed,
        features=args.features,
        every=args.frames_every,
        max_frames=args.max_frames,
        overwrite=args.overwrite,
    )
    print(
        f"wrote {summary.path}: {summary.words} words ({summary.nodes - 1} nodes, k={args.k}, L={args.levels}) "
        f"from {summary.descriptors} ORB descriptors of {summary.frames} frames of {source}, "
        f"{summary.bytes / 1e6:.1f} MB in {summary.seconds:.0f} s"
    )


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """`vocabulary build` and `list`."""
    p = sub.add_parser("vocabulary", help="ORB vocabularies (DBoW2 text format) for ORB-SLAM3")
    vocabulary = p.add_subparsers(dest="vocabulary_command", required=True, metavar="build")
    p = vocabulary.add_parser("build", help="build a DBoW2 ORB vocabulary from a route's or a sequence's frames")
    given = p.add_mutually_exclusive_group(required=True)
    given.add_argument("--route", help="route name (see `longslam list`) or a waypoint file; rendered if not cached")
    given.add_argument("--sequence", metavar="DIR", help="sequence folder (TUM RGB-D layout) to take the frames of")
    add_world_options(p, None)
    p.add_argument("--out", required=True, help="vocabulary file to write (e.g. voc.txt)")
    p.add_argument("--k", type=int, default=10, help="branching factor (default 10)")
    p.add_argument("--levels", type=int, default=5, help="depth levels L (default 5: up to k^L = 100000 words)")
    p.add_argument("--seed", type=int, default=0, help="seed of the k-means++ draws (default 0)")
    p.add_argument(
        "--features", type=int, default=1000, help="ORB features per frame (default 1000, as ORB-SLAM3's TUM settings)"
    )
    p.add_argument("--frames-every", type=int, default=1, metavar="N", help="take every N-th frame (default 1)")
    p.add_argument(
        "--max-frames",
        type=int,
        default=1000,
        help="at most this many frames, spread evenly over the sequence (default 1000)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing file")
    add_camera_options(p)
    p.set_defaults(func=cmd_vocabulary_build)

    p = sub.add_parser(
        "list", help="list worlds, routes, noise levels, methods, sensors and perturbations, or a method's parameters"
    )
    p.add_argument(
        "--params",
        dest="params_of",
        metavar="METHOD",
        help="list the method's parameters: default, allowed values and what each does",
    )
    p.set_defaults(func=cmd_list)
