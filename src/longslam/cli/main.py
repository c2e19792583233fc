"""The `longslam` command: a thin layer over the library."""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import re
import sys
import traceback
from typing import Any

# One OpenBLAS thread per process unless the user sets it: a run's matrices are small, a study
# runs one method per core, and OpenBLAS's spinning threads take the other cores' CPU for next
# to no wall time. Set before numpy loads OpenBLAS.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from longslam.cli.errors import EXPECTED_FAILURES, describe_failure, quiet_broken_pipe
from longslam.cli.output import configure, note
from longslam.cli.parser import Parser, add_common_options
from longslam.core.errors import InputError, LongslamError, MethodError
from longslam.slam.api import MethodChoice
from longslam.slam.catalog import choose_method

log = logging.getLogger("longslam.cli.main")


CAMERA_HELP = {
    "width": "image width in pixels",
    "height": "image height in pixels",
    "fov": "horizontal field of view in degrees",
    "max_depth": "depth range in metres",
    "camera_height": "camera height above the floor in metres",
}


def _camera_args(parser: argparse.ArgumentParser) -> None:
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


def _camera(args: argparse.Namespace):
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


def _params(pairs: list[str]) -> dict:
    from longslam.core.settings import parse_key_values

    return parse_key_values(pairs)


MESH_OPTIONS = ("floor", "units", "up", "places")


def _world_args(parser: argparse.ArgumentParser, default: str | None) -> None:
    shown = f" (default {default})" if default else " (default: the route's world)"
    parser.add_argument("--world", help=f"world name (see `longslam list`) or a mesh file (PLY, OBJ, GLB/glTF){shown}")
    parser.add_argument(
        "--floor", type=float, help="floor height of a mesh in metres, once turned z-up (default: found)"
    )
    parser.add_argument("--units", choices=("m", "cm", "mm"), help="length unit of a mesh file (default m)")
    parser.add_argument("--up", choices=("z", "y"), help="up axis of a mesh file (default y for GLB/glTF, z otherwise)")
    parser.add_argument("--places", help='places file of a mesh: JSON {"name": [x, y], ...}')


def _world(args: argparse.Namespace, value: str | None) -> str | None:
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


def _describe_world(name: str, mesh_floor_z: float | None) -> str:
    if mesh_floor_z is None:
        return f"world {name}"
    return f"world {name} (floor at z = {mesh_floor_z:.3f} m in the mesh file)"


def _given_files(paths: list[str | None]) -> dict[str, str]:
    """The command's inputs that are files or folders on disk (a route or world may be a name)."""
    return {f"input {p}": p for p in paths if p is not None and os.path.exists(p)}


def _check_out_file(args: argparse.Namespace, out: str, what: str, inputs: list[str | None]) -> None:
    """An output file replaces an existing one only with --overwrite, and never an input."""
    from longslam.io.overwrite_policy import check_not_an_input, check_output_file_free

    check_not_an_input(out, _given_files(inputs), what, inside=False)
    check_output_file_free(out, args.overwrite, what)


def cmd_world(args: argparse.Namespace) -> None:
    from longslam.io.paths import PLOT_SUFFIXES, check_output_file
    from longslam.sim.drive import drive_route
    from longslam.sim.routes import get_route
    from longslam.viz.plots import plot_plan
    from longslam.world import load_world

    check_output_file(args.out, PLOT_SUFFIXES, "--out")
    _check_out_file(args, args.out, "--out", [args.route, args.mesh or args.world, args.places])
    if args.mesh and args.world:
        raise LongslamError("give the world once: --world NAME_OR_FILE (--mesh FILE is the same)")
    ref = _world(args, args.mesh or args.world)
    route = get_route(args.route, ref) if args.route else None
    world = load_world(ref or (route.world if route else "university"))
    paths, waypoints, title = {}, None, f"world {world.name}"
    if route:
        driven = drive_route(world, route)
        paths[f"route {route.name} ({driven.length:.0f} m)"] = driven.xyyaw[:, :2]
        waypoints = route.resolve(world.places)
        title += f", route {route.name}: {len(waypoints)} waypoints, {driven.length:.1f} m"
    plot_plan(world.occupancy, args.out, paths, waypoints=waypoints, title=title)
    print(f"wrote {args.out}: {_describe_world(world.name, None if world.plan else world.source_floor_z)}")


def cmd_simulate(args: argparse.Namespace) -> None:
    from longslam.core.odometry_noise import get_noise
    from longslam.io.overwrite_policy import check_not_an_input
    from longslam.io.sequence import SequenceReader
    from longslam.sim.routes import get_route
    from longslam.sim.simulate import simulate
    from longslam.world import world_label

    check_not_an_input(args.out, _given_files([args.route, args.world, args.places]), "sequence folder")
    route = get_route(args.route, _world(args, args.world))
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
        camera=_camera(args),
        overwrite=args.overwrite,
        sensor=sensor,
        perturbations=perturbations,
    )
    meta = SequenceReader(out).meta  # renders cached before meta had world_name: the route's world
    name = meta.get("world_name") or world_label(route.world)
    perturbed = (
        f", perturbed by {meta['perturbation']} ({meta['frames_dropped']} frames dropped)" if perturbations else ""
    )
    print(f"wrote sequence {out}: route {route.name} in {_describe_world(name, meta.get('mesh_floor_z'))}{perturbed}")


def _run_inputs(args: argparse.Namespace) -> tuple[MethodChoice, str]:
    """The method with its parameters checked, and the sequence, of `run`: the options, over a
    --config file's."""
    params = _params(args.param)
    if args.config is None:
        if args.method is None:
            raise LongslamError("give the method: --method NAME (see `longslam list`), or --config RUN/config.toml")
        if args.sequence is None:
            raise LongslamError("give the sequence folder to run on")
        return choose_method(args.method, params), args.sequence
    from longslam.run.repeat import method_of, read_run_config

    config = read_run_config(args.config)
    if args.method is not None and args.method != config.method:
        raise LongslamError(f"--method {args.method}: {args.config} holds the parameters of method {config.method!r}")
    sequence = args.sequence or config.sequence
    if sequence is None:
        raise LongslamError(f"give the sequence folder to run on ({args.config} names none in [run])")
    return method_of(config, args.config).over(params), sequence


def cmd_run(args: argparse.Namespace) -> None:
    from longslam.run.engine import run_sequence

    if args.viz is not None:
        from longslam.viz.live import check_target

        check_target(args.viz, args.overwrite)
    if args.config is not None:  # --overwrite would delete the config it reads: RUN/config.toml --out RUN
        from longslam.io.overwrite_policy import check_not_an_input

        check_not_an_input(args.out, {"--config": args.config}, "run folder")
    method, sequence = _run_inputs(args)
    log.info(
        "run: method %s on %s into %s, parameters %s", method.name, sequence, args.out, method.params or "the defaults"
    )
    measurements = run_sequence(
        method, sequence, args.out, overwrite=args.overwrite, intrinsics=args.intrinsics, viz=args.viz, prepare=True
    )
    from longslam.run.speed import describe_real_time_factor

    print(
        f"wrote {args.out}: {measurements.frames} frames, {describe_real_time_factor(measurements.real_time_factor)}, "
        f"peak RSS {measurements.peak_rss_bytes / 1e6:.0f} MB"
        + (f", live view {measurements.observer_time_s:.1f} s" if measurements.observer_time_s is not None else "")
    )
    for text in measurements.about.get("sequence_notes", []):
        note(f"{args.sequence}: {text}")
    for text in measurements.method_stats.get("notes", []):
        note(f"{method.name}: {text}")


# evaluate's library fields -> its options, for the checks that can only run on the poses
EVALUATE_OPTIONS = {
    "n_to_align": "--n-to-align",
    "max_diff": "--t-max-diff",
    "min_step": "--min-step",
    "rpe_delta": "--delta",
    "delta_tol": "--delta-tol",
}


def _as_options(message: str) -> str:
    message = message.replace("align='none'", "--align none")
    return re.sub(r"\b(" + "|".join(EVALUATE_OPTIONS) + r")\b", lambda m: EVALUATE_OPTIONS[m[1]], message)


def _check_evaluate_options(args: argparse.Namespace) -> list[str]:
    """The evaluate options' values, checked before any file is read and named as options (the
    library's checks name its fields); returns warnings for options that will have no effect."""
    numbers = (
        ("--delta", args.delta, lambda v: v > 0, "a number > 0 (in --delta-unit)"),
        ("--delta-tol", args.delta_tol, lambda v: v >= 0, "a share of --delta >= 0"),
        ("--t-max-diff", args.t_max_diff, lambda v: v >= 0, "a time difference >= 0 s"),
        ("--t-offset", args.t_offset, lambda v: True, "a number of seconds"),
        ("--min-step", args.min_step, lambda v: v > 0, "a length > 0 m"),
    )
    for option, value, ok, expected in numbers:
        if not (math.isfinite(value) and ok(value)):
            raise InputError(f"{option} {value:g}: expected a finite {expected.removeprefix('a ')}")
    if args.n_to_align != -1 and args.n_to_align < 3:
        raise InputError(f"--n-to-align {args.n_to_align}: expected -1 (all poses) or a whole number >= 3")
    same = [p for p in (args.save_results, args.save_rpe_results) if p]
    if len(same) == 2 and os.path.abspath(same[0]) == os.path.abspath(same[1]):
        raise InputError(f"--save-results and --save-rpe-results both name {same[0]}; give each its own file")
    warnings = []
    if args.n_to_align != -1 and args.align == "none" and not args.align_flag and not args.correct_scale:
        # only an alignment is fitted on the first N poses; without one the option changes nothing
        warnings.append(f"--n-to-align {args.n_to_align} has no effect without --align (or -a, -s)")
    return warnings


def cmd_evaluate(args: argparse.Namespace) -> None:
    from longslam.eval.evaluate_output import format_text, scores_json
    from longslam.run.score import score_files_full

    for warning in _check_evaluate_options(args):
        print(f"warning: {warning}", file=sys.stderr)

    for option, path, suffix in (
        ("--save-plot", args.save_plot, None),
        ("--save-results", args.save_results, ".zip"),
        ("--save-rpe-results", args.save_rpe_results, ".zip"),
    ):
        if path is not None:  # before any work, as every output
            from longslam.io.paths import check_output_file
            from longslam.viz.evaluation_plots import SAVE_SUFFIXES as SAVE_PLOT_SUFFIXES

            check_output_file(path, (suffix,) if suffix else SAVE_PLOT_SUFFIXES, option)
            _check_out_file(args, path, option, [args.estimate, args.groundtruth])
    if args.plot:
        from longslam.viz.evaluation_plots import check_can_show

        check_can_show()
    warnings: list[str] = []
    # -a is --align's se3; --align sim3 beside it asks for more, and wins.
    align = "se3" if args.align_flag and args.align == "none" else args.align
    try:
        evaluation = score_files_full(
            args.estimate,
            args.groundtruth,
            align=align,
            max_diff=args.t_max_diff,
            min_step=args.min_step,
            warnings=warnings,
            offset=args.t_offset,
            estimate_topic=args.est_topic,
            truth_topic=args.ref_topic,
            delta=args.delta,
            delta_unit=args.delta_unit,
            all_pairs=args.all_pairs,
            delta_tol=args.delta_tol,
            pairs_from_reference=args.pairs_from_reference,
            pose_relation=args.pose_relation,
            correct_scale=args.correct_scale,
            align_origin=args.align_origin,
            n_to_align=args.n_to_align,
        )
    except InputError as err:  # the checks that need the poses name the library's fields
        raise InputError(_as_options(str(err))) from None
    for warning in warnings:
        print(f"warning: {warning}", file=sys.stderr)
    names = (str(args.groundtruth), str(args.estimate))
    if args.save_results:
        from longslam.eval.evo_results import save_ape_result

        save_ape_result(evaluation, args.save_results, *names, overwrite=args.overwrite)
    if args.save_rpe_results:
        from longslam.eval.evo_results import save_rpe_result

        save_rpe_result(evaluation, args.save_rpe_results, *names, overwrite=args.overwrite)
    title = f"{args.estimate} against {args.groundtruth}"
    if args.save_plot:
        from longslam.viz.evaluation_plots import save_plot

        save_plot(evaluation, args.save_plot, title, overwrite=args.overwrite)
    if args.json:
        print(json.dumps(scores_json(evaluation.scores), allow_nan=False))
    else:
        print(format_text(evaluation.scores, min_step=args.min_step))
    for option, path in (
        ("--save-results", args.save_results),
        ("--save-rpe-results", args.save_rpe_results),
        ("--save-plot", args.save_plot),
    ):
        if path:
            print(f"wrote {path} ({option})", file=sys.stderr)
    if args.plot:
        from longslam.viz.evaluation_plots import show_plot

        sys.stdout.flush()
        show_plot(evaluation, title)


def cmd_diagnose(args: argparse.Namespace) -> None:
    from longslam.io.atomic import write_text_atomic
    from longslam.io.overwrite_policy import check_output_file_free
    from longslam.run.diagnose import diagnose_run, diagnosis_text

    for out in (args.plot, args.json):
        if out is not None:
            check_output_file_free(out, args.overwrite)
    found = diagnose_run(args.run, args.sequence, stretch_m=args.stretch, with_world=args.plot is not None)
    for warning in found.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(diagnosis_text(found))
    if args.json is not None:
        write_text_atomic(args.json, json.dumps(found.to_json(), indent=1, allow_nan=False) + "\n")
        print(f"wrote {args.json}")
    if args.plot is not None:
        from longslam.run.diagnose_plot import plot_diagnosis

        plot_diagnosis(found, args.plot)
        print(f"wrote {args.plot}")


class _LazyBar:
    """A tqdm bar that appears at the first progress report, so an error found before any work
    is the only line on stderr."""

    def __init__(self, desc: str):
        self.desc = desc
        self.bar: Any = None  # a tqdm bar once the first report comes

    def update(self, done: int, total: int) -> None:
        if self.bar is None:
            from longslam.core.progress import bar

            self.bar = bar(desc=self.desc, unit="frame", leave=False)
        self.bar.total = total
        self.bar.update(done - self.bar.n)

    def __enter__(self) -> "_LazyBar":
        return self

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()


def _progress_bar(desc: str):
    """A progress bar and the (done, total) callback that moves it."""
    bar = _LazyBar(desc)
    return bar, bar.update


def cmd_export(args: argparse.Namespace) -> None:
    from longslam.io.rosbag.export import export_sequence

    bar, update = _progress_bar("export")
    with bar:
        summary = export_sequence(
            args.sequence,
            args.out,
            fmt=args.format,
            depth_encoding=args.depth_encoding,
            storage=args.storage,
            compress=args.compress,
            odom_noise=args.odom_noise,
            camera_height=args.camera_height,
            overwrite=args.overwrite,
            progress=update,
            distro=args.distro,
            topics=args.topics,
        )
    line = f"wrote {summary.path}: {summary.frames} frames, {summary.messages} messages, {summary.bytes / 1e6:.1f} MB"
    if summary.linear_variance is not None:
        line += (
            f"; odometry covariance per step: forward {summary.linear_variance:.3g} m^2, "
            f"yaw {summary.yaw_variance:.3g} rad^2"
        )
    print(line)
    for text in summary.notes:
        note(f"{args.sequence}: {text}")


def cmd_import(args: argparse.Namespace) -> None:
    from longslam.io.rosbag.import_ import Topics, import_bag

    topics = Topics(args.rgb, args.depth, args.camera_info, args.odom, args.groundtruth)
    bar, update = _progress_bar("import")
    with bar:
        summary = import_bag(
            args.bag,
            args.out,
            topics,
            max_diff=args.max_diff,
            max_depth=args.max_depth,
            groundtruth_frame=args.groundtruth_frame,
            overwrite=args.overwrite,
            progress=update,
            intrinsics=args.intrinsics,
        )
    t = summary.topics
    print(
        f"wrote sequence {summary.path}: {summary.frames} frames from {t.rgb} ({summary.rgb_messages} messages) "
        f"and {t.depth} ({summary.depth_messages}); camera from {t.camera_info or '--intrinsics'}; "
        f"odometry {'from ' + str(t.odom) if summary.odometry else 'none'}; "
        f"ground truth {'from ' + str(t.groundtruth) if summary.groundtruth else 'none'}"
    )
    for text in summary.notes:
        note(text)


def cmd_demo(args: argparse.Namespace) -> None:
    from longslam.cli.demo import format_table, run_demo

    if args.viz is not None:
        from longslam.viz.live import check_target

        check_target(args.viz, args.overwrite)
    from longslam.core import progress

    # bars only where the command draws them: on a terminal, without --quiet or --no-progress
    rows, plot = run_demo(
        args.out,
        args.route,
        args.noise,
        args.seed,
        camera=_camera(args),
        viz=args.viz,
        overwrite=args.overwrite,
        progress=progress.enabled(),
    )
    print(f"\nroute {args.route}, noise {args.noise}, seed {args.seed}\n")
    print(format_table(rows))
    print(f"\ntrajectories over the floor plan: {plot}")
    print(f"position error over time: {plot.with_name('errors.png')}")


def _list_params(method: str) -> None:
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
        _list_params(args.params_of)
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


def cmd_study(args: argparse.Namespace) -> None:
    from longslam.study.config import load_study
    from longslam.study.driver import run_study

    if args.jobs is not None and args.jobs < 1:
        raise LongslamError(f"--jobs must be at least 1, got {args.jobs}")
    config = load_study(args.file)
    summary = run_study(
        config,
        args.out,
        executor=args.executor,
        address=args.address,
        jobs=args.jobs,
        retry_failed=args.retry_failed,
        retry_starved=args.retry_starved,
        report=not args.no_report,
        extend=args.extend,
    )
    print(
        f"study {config.name}: {summary.planned} runs, {summary.skipped} done before, {summary.ran} run now "
        f"({summary.failed} failed) in {summary.wall_time_s:.0f} s; results in {summary.database}"
    )
    if summary.report is not None:
        print(f"report: {summary.report} and {summary.report.with_suffix('.md')}")
    if summary.ran and summary.failed == summary.ran:
        # a study none of whose runs worked is a failure of the command, for a script or CI to see
        raise LongslamError(
            f"every run of the study failed ({summary.failed} of {summary.ran}); why is in the "
            f"report's failures and each run's log under {args.out}"
        )


def cmd_report(args: argparse.Namespace) -> None:
    from longslam.study.report import write_report

    left_out: list[str] = []
    page = write_report(args.dir, overwrite=args.overwrite, left_out=left_out)
    for what in left_out:
        note(what)
    print(f"wrote {page} and {page.with_suffix('.md')}")


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
    check_not_an_input(args.out, _given_files([args.sequence, args.route, args.world, args.places]), "--out")
    check_output(args.out, args.overwrite)
    from longslam.sim.simulate import check_seed

    check_seed(args.seed, "--seed")  # the same range wherever a seed enters
    world = _world(args, args.world)
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
        sequence, source = rendered_route(route, _camera(args)), f"route {route.name}"
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


def _evaluate_args(p: argparse.ArgumentParser) -> None:
    from longslam.eval.metrics import DELTA_UNITS
    from longslam.eval.relations import RPE_RELATIONS

    p.add_argument(
        "estimate",
        help="estimated trajectory: a TUM or KITTI file, a run folder, a ROS bag "
        "(see --est-topic), or - for TUM text on stdin",
    )
    p.add_argument(
        "groundtruth",
        help="ground truth: a TUM or KITTI file, a sequence folder, a ROS bag " "(see --ref-topic), or - for stdin",
    )
    p.add_argument(
        "--est-topic",
        metavar="TOPIC",
        help="the estimate's topic when it is a bag (PoseStamped, "
        "PoseWithCovarianceStamped, TransformStamped or Odometry; "
        "default: the bag's only pose topic)",
    )
    p.add_argument("--ref-topic", metavar="TOPIC", help="the ground truth's topic when it is a bag (as --est-topic)")
    align = p.add_argument_group("alignment (evo's -a, -s, --align_origin, --n_to_align)")
    align.add_argument(
        "--align",
        nargs="?",
        const="se3",
        default="none",
        choices=("none", "se3", "sim3"),
        metavar="none|se3|sim3",
        help="Umeyama alignment of the estimate for APE and RPE: --align alone is se3 (evo's -a); "
        "sim3 also scales (evo's -as); default none",
    )
    align.add_argument("-a", dest="align_flag", action="store_true", help="the same as --align (se3), as evo's -a")
    align.add_argument(
        "-s",
        "--correct-scale",
        action="store_true",
        help="correct the scale: with --align a Sim(3) fit, alone the scale only (evo's -s)",
    )
    align.add_argument(
        "--align-origin",
        action="store_true",
        help="move the estimate's first pose onto the reference's (evo's --align_origin)",
    )
    align.add_argument(
        "--n-to-align",
        type=int,
        default=-1,
        metavar="N",
        help="fit the alignment on the first N poses only (default -1: all)",
    )
    rel = p.add_argument_group("pose relation and RPE pairs (evo's -r, -d, -u, -t, --all_pairs)")
    rel.add_argument(
        "-r",
        "--pose-relation",
        default="trans_part",
        choices=RPE_RELATIONS,
        metavar="RELATION",
        help=f"what APE and RPE measure: {', '.join(RPE_RELATIONS)} (default trans_part, metres; "
        "angle_deg: degrees; point_distance_error_ratio is RPE only, APE then uses trans_part)",
    )
    rel.add_argument(
        "-d",
        "--delta",
        type=float,
        default=1.0,
        help="RPE distance between the poses of a pair, " "in --delta-unit (default 1)",
    )
    rel.add_argument(
        "-u",
        "--delta-unit",
        default="m",
        choices=DELTA_UNITS,
        help="unit of --delta: f frames, m metres of path (default; evo's default is f), "
        "d degrees, r radians of rotation",
    )
    rel.add_argument(
        "-t",
        "--delta-tol",
        type=float,
        default=0.1,
        help="with --all-pairs, the share of delta a pair may be off (default 0.1)",
    )
    rel.add_argument("--all-pairs", action="store_true", help="every pair delta apart instead of consecutive ones")
    rel.add_argument(
        "--pairs-from-reference",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="choose RPE pairs on the reference (default; evo's default is the estimate)",
    )
    sync = p.add_argument_group("timestamp matching (evo's --t_max_diff, --t_offset)")
    sync.add_argument(
        "--t-max-diff",
        "--max-diff",
        dest="t_max_diff",
        type=float,
        default=0.01,
        metavar="SECONDS",
        help="largest stamp difference of a matched pair (default 0.01 s)",
    )
    sync.add_argument(
        "--t-offset",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="added to the estimate's stamps for matching (default 0 s)",
    )
    p.add_argument(
        "--min-step",
        type=float,
        default=0.01,
        help="E_trans and E_rot leave out ground-truth steps shorter than this, in metres (default 0.01)",
    )
    out = p.add_argument_group("output (evo's -p, --save_plot, --save_results)")
    out.add_argument("--json", action="store_true", help='print one JSON object, with a "units" object')
    out.add_argument("-p", "--plot", action="store_true", help="show the APE figures in a window (needs a display)")
    out.add_argument("--save-plot", metavar="FILE", help="save the APE figures to FILE (.png or .pdf)")
    out.add_argument("--save-results", metavar="FILE.zip", help="save the APE result as evo_res reads it")
    out.add_argument("--save-rpe-results", metavar="FILE.zip", help="save the RPE result as evo_res reads it")
    out.add_argument("--overwrite", action="store_true", help="replace existing --save-* files")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="longslam", description="RGB-D SLAM on long routes through large indoor buildings")
    parser.add_argument(
        "--version", action="version", version=f"%(prog)s {_version()}", help="print longslam's version and exit"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("world", help="draw a world's floor plan, optionally with a route")
    _world_args(p, "university, or the route file's")
    p.add_argument("--mesh", help="a mesh file: the same as --world FILE")
    p.add_argument("--route", help="a route name or a waypoint file to draw")
    p.add_argument("--out", required=True, help="image file to write (e.g. plan.png)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing image file")
    p.set_defaults(func=cmd_world)

    p = sub.add_parser("simulate", help="render a route with noisy odometry into a TUM RGB-D sequence")
    p.add_argument("--route", required=True, help="route name (see `longslam list`) or a waypoint file")
    _world_args(p, None)
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
    _camera_args(p)
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("run", help="run a SLAM method over a sequence")
    p.add_argument("--method", help="method name (see `longslam list`); required without --config")
    p.add_argument(
        "sequence", nargs="?", help="sequence folder (TUM RGB-D layout); default with --config: its [run] sequence"
    )
    p.add_argument(
        "--config",
        metavar="CONFIG.toml",
        help="a run folder's config.toml: run its method with its parameters again (--param overrides them)",
    )
    p.add_argument("--out", required=True, help="run folder to write")
    p.add_argument("--param", action="append", default=[], metavar="KEY=VALUE", help="method parameter (repeatable)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing run folder (and --viz file)")
    p.add_argument(
        "--intrinsics",
        metavar="FX,FY,CX,CY",
        help="camera intrinsics in pixels, for a sequence without camera.json (or to replace it)",
    )
    p.add_argument(
        "--viz",
        nargs="?",
        const="viewer",
        metavar="FILE.rrd",
        help="show the run live in a rerun viewer, or record it to FILE.rrd (needs longslam[viz])",
    )
    p.set_defaults(func=cmd_run)

    p = sub.add_parser(
        "evaluate",
        help="score a trajectory against ground truth (evo's APE / RPE and the paper's metrics)",
        description="Score an estimated trajectory against the ground truth: the paper's ATE, "
        "E_trans, E_rot and evo's APE and RPE. Options carry evo_ape's / evo_rpe's names "
        "(with dashes: --pose-relation is evo's --pose_relation).",
    )
    _evaluate_args(p)
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser(
        "diagnose",
        help="where along the route a run's error comes from: heading, along and across "
        "track, per stretch, with its loop constraints and front-end factors",
    )
    p.add_argument("run", help="a run folder (trajectory.txt; loops.csv and frontend.csv where the method wrote them)")
    p.add_argument("sequence", help="the sequence folder the run ran on (groundtruth.txt)")
    p.add_argument("--stretch", type=float, default=50.0, help="length of a stretch of route, in metres (default 50)")
    p.add_argument(
        "--plot",
        metavar="FILE.png",
        help="save the picture: the route coloured by error, the error " "parts and the factors against distance",
    )
    p.add_argument("--json", metavar="FILE.json", help="save the diagnosis as JSON (units in its 'units' key)")
    p.add_argument("--overwrite", action="store_true", help="replace --plot and --json files that exist")
    p.set_defaults(func=cmd_diagnose)

    p = sub.add_parser("export", help="write a sequence as a ROS 1 or ROS 2 bag (needs longslam[ros])")
    p.add_argument("sequence", help="sequence folder (TUM RGB-D layout)")
    p.add_argument(
        "--format", default="ros2", choices=("ros1", "ros2"), help="ros2: a bag folder (default); ros1: a .bag file"
    )
    p.add_argument("--out", required=True, help="bag to write: a folder for ros2, a file ending in .bag for ros1")
    p.add_argument(
        "--depth-encoding",
        default="32FC1",
        choices=("32FC1", "16UC1"),
        help="32FC1: metres, lossless (default); 16UC1: millimetres, half the size",
    )
    p.add_argument("--storage", default="sqlite3", choices=("sqlite3", "mcap"), help="ROS 2 storage (default sqlite3)")
    p.add_argument(
        "--compress",
        action="store_true",
        help="compress: zstd chunks (ros2 mcap), zstd per message (ros2 sqlite3), lz4 chunks (ros1)",
    )
    p.add_argument(
        "--distro",
        choices=("humble", "jazzy"),
        help="the ROS 2 distribution whose rosbag2 plays the bag (default humble: Jazzy plays it too)",
    )
    p.add_argument(
        "--topics",
        default="default",
        choices=("default", "rtabmap", "realsense", "openni"),
        help="camera topic names and optical frame as that driver or SLAM system names them (default: longslam's)",
    )
    p.add_argument(
        "--odom-noise",
        metavar="LEVEL",
        help="noise level for the odometry covariance (default: the sequence's meta.json)",
    )
    p.add_argument("--camera-height", type=float, help="camera above base_link in metres (default: the sequence's)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing bag")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser("import", help="turn a ROS 1 or ROS 2 bag into a sequence folder (needs longslam[ros])")
    p.add_argument("bag", help="a .bag file (ROS 1) or a bag folder (ROS 2)")
    p.add_argument("--out", required=True, help="sequence folder to write")
    p.add_argument("--rgb", metavar="TOPIC", help="colour images (sensor_msgs/Image or CompressedImage)")
    p.add_argument(
        "--depth", metavar="TOPIC", help="depth images registered to the colour camera (32FC1 m or 16UC1 mm)"
    )
    p.add_argument("--camera-info", metavar="TOPIC", help="the colour camera's sensor_msgs/CameraInfo")
    p.add_argument("--odom", metavar="TOPIC", help="wheel odometry (nav_msgs/Odometry)")
    p.add_argument(
        "--groundtruth", metavar="TOPIC", help="ground truth (nav_msgs/Odometry or geometry_msgs/PoseStamped)"
    )
    p.add_argument(
        "--groundtruth-frame",
        metavar="FRAME",
        help="the frame a PoseStamped ground truth is the pose of (default: the odometry's child frame)",
    )
    p.add_argument(
        "--max-diff", type=float, default=0.02, help="colour-depth pairing tolerance in seconds (default 0.02)"
    )
    p.add_argument(
        "--max-depth",
        type=float,
        help="depth range in metres; farther is 'no return' (default 13.107, the 16-bit limit)",
    )
    p.add_argument(
        "--intrinsics",
        metavar="FX,FY,CX,CY",
        help="the colour camera's intrinsics in pixels, for a bag without CameraInfo (instead of --camera-info)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing folder")
    p.set_defaults(func=cmd_import)

    p = sub.add_parser("demo", help="the demo route at large noise with every method: a table and a plot")
    p.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    p.add_argument("--route", default="demo", help="route name (see `longslam list`) or a waypoint file (default demo)")
    p.add_argument(
        "--noise", default="large", help="odometry noise level: none, small, medium, large, xlarge (default large)"
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the odometry noise (default 0)")
    p.add_argument(
        "--viz",
        nargs="?",
        const="viewer",
        metavar="FILE.rrd",
        help="show each method's run live in a rerun viewer, or record FILE-<method>.rrd (needs longslam[viz])",
    )
    p.add_argument("--overwrite", action="store_true", help="replace existing FILE-<method>.rrd recordings")
    _camera_args(p)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("study", help="run a study file (routes x noise levels x methods x seeds) and write its report")
    p.add_argument("file", help="study file (TOML), e.g. studies/quick.toml")
    p.add_argument("--out", required=True, help="study folder: results database, runs, report (resumes if it exists)")
    p.add_argument(
        "--executor", default="local", choices=("local", "ray"), help="local processes (default) or a Ray cluster"
    )
    p.add_argument(
        "--address", help="Ray cluster address (e.g. ray://head:10001 or head:6379); default: start Ray locally"
    )
    p.add_argument(
        "--jobs",
        type=int,
        help="cores the study's runs may keep busy at once (default: this machine's cores, or the Ray "
        "cluster's CPUs); a run takes its method's cores (1 for keyframe, submap and odometry; "
        "3, capped at --jobs, for orbslam3), so nothing runs beside a run that needs them all",
    )
    p.add_argument("--retry-failed", action="store_true", help="run again the runs recorded with an error")
    p.add_argument(
        "--retry-starved",
        action="store_true",
        help="run again the runs whose threads waited for a CPU for more than 10%% of their time "
        "(cpu_wait_share over 0.10: the report marks them starved)",
    )
    p.add_argument("--no-report", action="store_true", help="do not write the report at the end")
    p.add_argument(
        "--extend",
        action="store_true",
        help="add this study's runs to a folder that holds another study (another name, routes, noise "
        "levels, methods or seeds); without it such a folder is refused",
    )
    p.set_defaults(func=cmd_study)

    p = sub.add_parser("report", help="write report.md and report.html of a study folder")
    p.add_argument("dir", help="study folder (holds results.sqlite)")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a report.md or report.html that longslam did not write (its own are always rewritten)",
    )
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("vocabulary", help="ORB vocabularies (DBoW2 text format) for ORB-SLAM3")
    vocabulary = p.add_subparsers(dest="vocabulary_command", required=True, metavar="build")
    p = vocabulary.add_parser("build", help="build a DBoW2 ORB vocabulary from a route's or a sequence's frames")
    given = p.add_mutually_exclusive_group(required=True)
    given.add_argument("--route", help="route name (see `longslam list`) or a waypoint file; rendered if not cached")
    given.add_argument("--sequence", metavar="DIR", help="sequence folder (TUM RGB-D layout) to take the frames of")
    _world_args(p, None)
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
    _camera_args(p)
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
    add_common_options(parser)  # last, so that every subcommand has them (also after the command)
    from longslam.cli.complete import attach_completers

    attach_completers(parser)
    return parser


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("longslam")  # the installed distribution's, as pip shows it
    except PackageNotFoundError:  # run from a source tree that is not installed
        import longslam

        return f"{longslam.__version__} (not installed)"


def _tolerant_output() -> None:
    """Under a C locale without UTF-8 mode stdout is ASCII, and a path that is not valid UTF-8 is
    not text anywhere: print such characters escaped rather than fail with UnicodeEncodeError."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if reconfigure is not None:
            try:
                reconfigure(errors="backslashreplace")
            except (ValueError, OSError):
                pass


def _value_options(parser: argparse.ArgumentParser) -> set[str]:
    """Every option string (of the commands too) that takes one value."""
    found: set[str] = set()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                found |= _value_options(sub)
        elif (
            action.option_strings
            and action.nargs is None
            and not isinstance(
                action, (argparse._StoreTrueAction, argparse._StoreFalseAction, argparse._StoreConstAction)
            )
        ):
            found.update(action.option_strings)
    return found


def _glue_negative_values(argv: list[str], options: set[str]) -> list[str]:
    """`--intrinsics -40,40,8,6` as `--intrinsics=-40,40,8,6`: argparse takes a value that starts
    with '-' (and is not a plain negative number) for an option and says 'expected one argument'."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        token = argv[i]
        if (
            token in options
            and i + 1 < len(argv)
            and len(argv[i + 1]) > 1
            and argv[i + 1][0] == "-"
            and (argv[i + 1][1].isdigit() or argv[i + 1][1] == ".")
        ):
            out.append(f"{token}={argv[i + 1]}")
            i += 2
            continue
        out.append(token)
        i += 1
    return out


# The options that name what a command writes: a failure with no file of its own (a full disk
# met inside a library's write) is said to be writing these.
OUTPUT_OPTIONS = ("out", "save_plot", "save_results", "save_rpe_results")


def _outputs(args: argparse.Namespace) -> str | None:
    given = [str(getattr(args, name)) for name in OUTPUT_OPTIONS if getattr(args, name, None) not in (None, False, "")]
    return " or ".join(given) or None


def main(argv: list[str] | None = None) -> int:
    _tolerant_output()
    parser = build_parser()
    import argcomplete

    argcomplete.autocomplete(parser)  # answers a shell's completion request and exits; else nothing
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(_glue_negative_values(argv, _value_options(parser)))
    configure(args)
    try:
        args.func(args)
        sys.stdout.flush()  # a closed pipe shows here, inside the handlers below
    except BrokenPipeError:
        return quiet_broken_pipe()
    except EXPECTED_FAILURES as err:
        if getattr(args, "debug", False):
            raise
        if isinstance(err, MethodError) and err.__cause__ is not None:
            # A method's bug: its author needs the traceback; the line below says whose it is.
            traceback.print_exception(err.__cause__, file=sys.stderr)
        print(f"longslam {args.command}: error: {describe_failure(err, _outputs(args))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"longslam {args.command}: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
