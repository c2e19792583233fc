"""A run of a sequence on disk in a process of its own, scored against the sequence's ground truth:
what the demo and the benchmarks print."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from longslam.core.errors import InputError
from longslam.io.sequence import SequenceReader
from longslam.io.trajectory_files import read_tum
from longslam.run.engine import run_sequence
from longslam.run.folder import TRAJECTORY
from longslam.run.isolate import run_isolated
from longslam.run.measurements import RunMeasurements
from longslam.run.score import score
from longslam.slam.catalog import choose_method


def run_named(
    method: str, sequence: str | Path, out: str | Path, params: dict[str, Any] | None = None, **kwargs: Any
) -> RunMeasurements:
    """`run_sequence` of method `method` with `params` (command-line text or values), checked here."""
    return run_sequence(choose_method(method, params), sequence, out, **kwargs)


def run_sequence_isolated(
    method: str, sequence: str | Path, out: str | Path, params: dict[str, Any] | None = None, **kwargs: Any
) -> RunMeasurements:
    """`run_named` in a fresh process, so its peak memory is the run's alone."""
    return run_isolated(run_named, method, sequence, out, params, **kwargs)


def run_and_score(
    method: str,
    sequence: str | Path,
    out: str | Path,
    params: dict[str, Any] | None = None,
    progress: bool = False,
    viz: str | None = None,
) -> tuple[dict[str, Any], RunMeasurements]:
    """Run a method over a sequence in its own process, then score its final trajectory against the
    sequence's ground truth. Returns (scores, measurements): what the demo and benchmarks print."""
    measurements = run_sequence_isolated(method, sequence, out, params, overwrite=True, progress=progress, viz=viz)
    truth = SequenceReader(sequence).ground_truth
    if truth is None:
        raise InputError(f"sequence {sequence} has no groundtruth.txt to score against")
    return score(truth, read_tum(Path(out) / TRAJECTORY)), measurements
