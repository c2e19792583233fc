"""The `longslam` command: a thin layer over the library."""

from __future__ import annotations

import argparse
import logging
import os
import sys
import traceback

# One OpenBLAS thread per process unless the user sets it: a run's matrices are small, a study
# runs one method per core, and OpenBLAS's spinning threads take the other cores' CPU for next
# to no wall time. Set before numpy loads OpenBLAS.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from longslam.cli import bags, listing, runs, sequences, studies
from longslam.cli.errors import EXPECTED_FAILURES, describe_failure, quiet_broken_pipe
from longslam.cli.output import configure
from longslam.cli.parser import Parser, add_common_options
from longslam.core.errors import MethodError

log = logging.getLogger("longslam.cli.main")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="longslam", description="RGB-D SLAM on long routes through large indoor buildings")
    parser.add_argument(
        "--version", action="version", version=f"%(prog)s {_version()}", help="print longslam's version and exit"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    sequences.add_parsers(sub)
    runs.add_parsers(sub)
    bags.add_parsers(sub)
    studies.add_parsers(sub)
    listing.add_parsers(sub)
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
