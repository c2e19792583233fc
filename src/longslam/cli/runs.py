"""The commands that run a method and read its result: `run`, `evaluate` and `diagnose`."""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import re
import sys

from longslam.cli.common import check_out_file, parse_params
from longslam.cli.output import note
from longslam.core.errors import InputError, LongslamError
from longslam.slam.api import MethodChoice
from longslam.slam.catalog import choose_method

log = logging.getLogger("longslam.cli.runs")


def _run_inputs(args: argparse.Namespace) -> tuple[MethodChoice, str]:
    """The method with its parameters checked, and the sequence, of `run`: the options, over a
    --config file's."""
    params = parse_params(args.param)
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
        method,
        sequence,
        args.out,
        overwrite=args.overwrite,
        intrinsics=args.intrinsics,
        viz=args.viz,
        prepare=True,
        depth_delay=args.depth_delay,
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
            check_out_file(args, path, option, [args.estimate, args.groundtruth])
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


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """`run`, `evaluate` and `diagnose`."""
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
        "--depth-delay",
        type=float,
        metavar="SECONDS",
        help="the depth lags the colour by this much (negative: leads), both stamped alike: each depth image "
        "is moved back in step by the odometry before the method sees it",
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
