"""Many runs at once: `demo`, `study` and `report`."""

from __future__ import annotations

import argparse

from longslam.cli.common import add_camera_options, camera_from_args
from longslam.cli.output import note
from longslam.core.errors import LongslamError


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
        camera=camera_from_args(args),
        viz=args.viz,
        overwrite=args.overwrite,
        progress=progress.enabled(),
    )
    print(f"\nroute {args.route}, noise {args.noise}, seed {args.seed}\n")
    print(format_table(rows))
    print(f"\ntrajectories over the floor plan: {plot}")
    print(f"position error over time: {plot.with_name('errors.png')}")


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


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """`demo`, `study` and `report`."""
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
    add_camera_options(p)
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
