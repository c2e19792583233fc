"""Work in a process of its own (a run, a method's preparation), so that its peak memory is its alone."""

from __future__ import annotations

import logging
import multiprocessing as mp
from collections.abc import Callable
from queue import Empty
from typing import Any

from longslam.core import progress
from longslam.core.errors import InputError, LongslamError


def _child(queue: mp.Queue, function: Callable[..., Any], args: tuple, kwargs: dict, bars: bool | None = None) -> None:
    progress.set_enabled(bars)  # a spawned process starts with tqdm's default: bars into a log file
    try:
        queue.put(("ok", function(*args, **kwargs)))
    except LongslamError as err:  # bad input: the parent raises it as its own one-line error
        queue.put(("input" if isinstance(err, InputError) else "longslam", str(err)))
    except BaseException as err:  # reported to the parent, which re-raises
        queue.put(("error", f"{type(err).__name__}: {err}"))


def prepare_method(spec: Any, config: Any, bars: bool | None = None, log_level: int = logging.WARNING) -> None:
    """A method's once-per-machine work (see `MethodSpec.prepare`), for `run_isolated`. A spawned
    process starts with no settings of its parent's: `bars` and `log_level` carry the command's
    --no-progress / --quiet / -v to it."""
    progress.set_enabled(bars)
    logger = logging.getLogger("longslam")
    logger.setLevel(log_level)
    if not logger.handlers:
        handler = logging.StreamHandler()
        handler.setFormatter(logging.Formatter("%(message)s"))
        logger.addHandler(handler)
    spec.prepare(config)


def run_isolated(function: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """`function(*args, **kwargs)` in a fresh (spawned) process; its return value comes back.
    `function` must be importable by name (a module-level function)."""
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_child, args=(queue, function, args, kwargs, progress.setting()))
    proc.start()
    # Poll rather than block: a child killed outright (out of memory, a signal) never reports.
    while True:
        try:
            status, payload = queue.get(timeout=1.0)
            break
        except Empty:
            if proc.is_alive():
                continue
            try:  # it may have reported just before it ended
                status, payload = queue.get(timeout=1.0)
                break
            except Empty:
                proc.join()
                raise RuntimeError(
                    f"run failed in its process: it died with exit code {proc.exitcode} before reporting"
                ) from None
    proc.join()
    if status == "input":
        raise InputError(payload)
    if status == "longslam":
        raise LongslamError(payload)
    if status != "ok":
        raise RuntimeError(f"run failed in its process: {payload}")
    return payload
