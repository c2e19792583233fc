"""Where runs execute: local processes (one fresh process per run), or a Ray cluster.

An executor takes `Task`s and hands back `(task, record)` pairs as runs finish. Each run has a
process of its own, so the peak memory measured in it is that run's alone, and a run that crashes
(an exception, or its process killed or segfaulting) becomes an error record; the others go on.
"""

from __future__ import annotations

import ctypes
import json
import multiprocessing as mp
import os
import shutil
import signal
import sys
from dataclasses import dataclass
from multiprocessing.connection import wait as wait_for
from pathlib import Path
from typing import Any, Protocol, cast

from longslam.core.errors import LongslamError
from longslam.io.grid_files import read_grid
from longslam.study.record import RunRecord

EXECUTORS = ("local", "ray")


@dataclass(frozen=True)
class Task:
    spec: Any  # RunSpec
    run_dir: Path  # the run's folder in the study folder
    log_path: Path  # where a local run's stdout and stderr go
    grid_path: Path  # the world's ground-truth occupancy grid (.npz)
    observed_path: Path  # the route's mask of observed walls (.npy)
    cores: int = 1  # cores the run keeps busy (its method's `threads`, at most the executor's capacity)


class Executor(Protocol):
    capacity: int  # cores the executor may keep busy at once (`--jobs`, or the machine's or cluster's)

    @property
    def running(self) -> int: ...  # runs going

    @property
    def busy_cores(self) -> int: ...  # the cores those runs hold

    def submit(self, task: Task) -> None: ...

    def wait(self, timeout: float) -> list[tuple[Task, RunRecord]]: ...

    def close(self) -> None: ...


# ----------------------------------------------------------------------------- local processes


def _die_with_parent(parent_pid: int) -> None:
    """Ask Linux to kill this process when the study process dies (even by SIGKILL)."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL("libc.so.6", use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except OSError:
            pass
    if os.getppid() != parent_pid:  # the parent died before the request took effect
        os._exit(1)


def _local_child(task: Task, result_path: str, parent_pid: int) -> None:
    _die_with_parent(parent_pid)
    task.log_path.parent.mkdir(parents=True, exist_ok=True)
    log = os.open(task.log_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    os.dup2(log, 1)
    os.dup2(log, 2)
    import time

    from longslam.study.run_log import closing_line, opening_line
    from longslam.study.worker import error_record, execute_run, to_json

    # Without these lines a run that printed nothing left an empty log.
    start = time.perf_counter()
    print(opening_line(task.spec), flush=True)

    def load_truth():
        import numpy as np

        return read_grid(task.grid_path), np.load(task.observed_path)

    try:
        record = execute_run(task.spec, task.run_dir, load_truth)
    except BaseException as err:  # recorded; the study goes on
        record = error_record(err)
        print(record.traceback, file=sys.stderr, flush=True)
    print(closing_line(record, time.perf_counter() - start), flush=True)
    tmp = f"{result_path}.tmp"
    with open(tmp, "w") as handle:
        handle.write(to_json(record))
    os.replace(tmp, result_path)


def _death_message(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        return f"the run's process was killed by {name}"
    return f"the run's process exited with code {exitcode} without a result"


def _keep_console(partial: Path, log_path: Path) -> Path | None:
    """A dead run's console.log, moved beside its log as NAME.console.log; None if it had none."""
    from longslam.run.console import CONSOLE_LOG

    console = partial / CONSOLE_LOG
    if not console.is_file() or console.stat().st_size == 0:
        return None
    kept = log_path.with_name(log_path.stem + ".console.log")
    try:
        shutil.move(str(console), kept)
    except OSError:
        return None
    return kept


class LocalExecutor:
    """Runs on up to `jobs` cores at once (a run takes its method's cores), each in a new process
    (spawned, so nothing is inherited)."""

    def __init__(self, jobs: int | None = None):
        self.capacity = max(1, int(jobs or os.cpu_count() or 1))
        self._ctx = mp.get_context("spawn")
        self._running: dict[int, tuple[Task, Any, str]] = {}

    @property
    def running(self) -> int:
        return len(self._running)

    @property
    def busy_cores(self) -> int:
        return sum(task.cores for task, _, _ in self._running.values())

    def submit(self, task: Task) -> None:
        task.run_dir.parent.mkdir(parents=True, exist_ok=True)
        result_path = str(task.run_dir.parent / f".{task.run_dir.name}.result.json")
        if os.path.exists(result_path):
            os.unlink(result_path)
        process = self._ctx.Process(target=_local_child, args=(task, result_path, os.getpid()), daemon=False)
        process.start()
        self._running[process.sentinel] = (task, process, result_path)

    def wait(self, timeout: float) -> list[tuple[Task, RunRecord]]:
        if not self._running:
            return []
        done = []
        for sentinel in cast("list[int]", wait_for(list(self._running), timeout=timeout)):  # the sentinels given
            task, process, result_path = self._running.pop(sentinel)
            process.join()
            try:
                with open(result_path) as handle:
                    record = RunRecord.from_dict(json.load(handle))
                os.unlink(result_path)
            except (OSError, ValueError):
                # The unfinished run folder of the dead process (see longslam.io.atomic): its
                # console.log (what native code printed, often the only word of why it died:
                # an abort's message, an assertion) is kept beside the run's log first.
                from longslam.io.partials import partial_path

                partial = partial_path(task.run_dir, process.pid)
                kept = _keep_console(partial, task.log_path)
                where = f"{task.log_path}" + (f" and {kept}" if kept else "")
                record = RunRecord.failed(f"{_death_message(process.exitcode)}; see {where}")
                if partial.exists():
                    shutil.rmtree(partial, ignore_errors=True)
            record.log = record.log or str(task.log_path)
            done.append((task, record))
        return done

    def close(self) -> None:
        for _task, process, result_path in self._running.values():
            if process.is_alive():
                process.kill()
            process.join()
            if os.path.exists(result_path):
                os.unlink(result_path)
        self._running.clear()


# ----------------------------------------------------------------------------- Ray


def _ray_run(spec: Any, truth_refs: list) -> tuple[dict, dict[str, bytes]]:
    # The record travels as its JSON form: Ray then needs no longslam class to unpickle it.
    """A run on a Ray worker: in a temporary folder of that node; the files come back as bytes,
    so the cluster needs no file system shared with the study folder."""
    import tempfile

    import ray

    from longslam.study.worker import error_record, execute_run, to_json

    def load_truth():
        return ray.get(truth_refs[0]), ray.get(truth_refs[1])

    with tempfile.TemporaryDirectory(prefix="longslam-run-") as tmp:
        run_dir = Path(tmp) / "run"
        try:
            record = execute_run(spec, run_dir, load_truth)
            files = {str(p.relative_to(run_dir)): p.read_bytes() for p in run_dir.rglob("*") if p.is_file()}
        except BaseException as err:
            record, files = error_record(err), {}
    return json.loads(to_json(record)), files


# An address that never answers made ray.init retry for minutes: how long it may take instead.
RAY_CONNECT_TIMEOUT_S = 20.0


def check_executor_options(kind: str, address: str | None) -> None:
    """Refuse executor options that cannot work, before anything is created."""
    if kind not in EXECUTORS:
        from longslam.core.errors import UnknownNameError

        raise UnknownNameError("executor", kind, EXECUTORS)
    if address is not None and kind != "ray":
        raise LongslamError(f"--address {address} is for --executor ray; the {kind} executor runs on this machine")
    if address is not None and not address.strip():
        raise LongslamError("--address is empty; give the Ray cluster's address (e.g. head:6379), or leave it out")
    if kind == "ray" and address and address.startswith("ray://"):
        import importlib.util

        if importlib.util.find_spec("grpc") is None:
            raise LongslamError(
                f"--address {address}: a ray:// address goes through Ray Client, which needs pip install "
                "'ray[client]'; "
                "or give the cluster's own address (head:6379) from a machine in the cluster"
            )


def _probe(address: str, timeout: float) -> None:
    """A TCP connection to a host:port address, so a cluster that is down is an error at once."""
    import socket

    host, sep, port = address.rpartition(":")
    if not sep or not port.isdigit():
        return  # "auto", or a form Ray resolves itself
    try:
        with socket.create_connection((host.strip("[]") or "127.0.0.1", int(port)), timeout=timeout):
            pass
    except OSError as err:
        reason = "no answer" if isinstance(err, TimeoutError) else (err.strerror or str(err))
        raise LongslamError(
            f"--address {address}: no Ray cluster answered within {timeout:.0f} s ({reason}); "
            "check the address and that the cluster is up (`ray status` on its head node)"
        ) from None


def _ray_init(ray: Any, address: str | None, timeout: float) -> None:
    """ray.init, given up after `timeout` seconds (it retries an unanswering address for minutes)."""
    import threading

    outcome: list[BaseException | None] = []

    def connect() -> None:
        try:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
            outcome.append(None)
        except BaseException as err:  # handed to the caller
            outcome.append(err)

    thread = threading.Thread(target=connect, daemon=True, name="ray-init")
    thread.start()
    thread.join(timeout)
    if not outcome:
        raise LongslamError(
            f"Ray at {address or 'a local cluster'} did not start or answer within {timeout:.0f} s; "
            "check the address and that the cluster is up (`ray status` on its head node)"
        )
    err = outcome[0]
    if err is not None:
        if isinstance(err, (ConnectionError, ValueError, RuntimeError, TimeoutError)):
            raise LongslamError(f"Ray at {address or 'a local cluster'} could not be joined: {err}") from None
        raise err


class RayExecutor:
    """Runs as Ray tasks on an existing cluster (`address`), or on Ray already started in this
    process (`ray.init()`), or on a local Ray that it starts. Each task runs in a new worker
    process (max_calls=1) and is not retried: a crash is recorded like any failed run."""

    def __init__(self, address: str | None = None, jobs: int | None = None):
        try:
            import ray
        except ImportError:
            raise LongslamError("the ray executor needs Ray: pip install 'longslam[ray]'") from None
        self._ray = ray
        self._started = False
        if not ray.is_initialized():
            if address is not None:
                _probe(address, RAY_CONNECT_TIMEOUT_S)
            _ray_init(ray, address, RAY_CONNECT_TIMEOUT_S * 3 if address is None else RAY_CONNECT_TIMEOUT_S)
            self._started = address is None
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.capacity = max(1, int(jobs or cpus))
        # Each task asks Ray for its run's cores (num_cpus), so Ray never packs a multi-threaded
        # system beside other runs on a node that lacks the cores.
        self._remote = ray.remote(num_cpus=1, max_calls=1, max_retries=0)(_ray_run)
        self._truth_refs: dict[tuple[str, str], list] = {}
        self._running: dict[Any, Task] = {}

    @property
    def running(self) -> int:
        return len(self._running)

    @property
    def busy_cores(self) -> int:
        return sum(task.cores for task in self._running.values())

    def _truth(self, task: Task) -> list:
        key = (str(task.grid_path), str(task.observed_path))
        if key not in self._truth_refs:
            import numpy as np

            self._truth_refs[key] = [
                self._ray.put(read_grid(task.grid_path)),
                self._ray.put(np.load(task.observed_path)),
            ]
        return self._truth_refs[key]

    def submit(self, task: Task) -> None:
        ref = self._remote.options(num_cpus=task.cores).remote(task.spec, self._truth(task))
        self._running[ref] = task

    def wait(self, timeout: float) -> list[tuple[Task, RunRecord]]:
        if not self._running:
            return []
        ready, _ = self._ray.wait(list(self._running), num_returns=1, timeout=timeout)
        if ready:
            more, _ = self._ray.wait(
                [r for r in self._running if r not in ready], num_returns=len(self._running) - len(ready), timeout=0
            )
            ready += more
        done = []
        for ref in ready:
            task = self._running.pop(ref)
            try:
                data, files = self._ray.get(ref)
                record = RunRecord.from_dict(data)
            except Exception as err:  # the worker died, or Ray could not run the task
                record, files = RunRecord.failed(f"Ray task failed: {type(err).__name__}: {err}"), {}
            if record.ok:
                _write_files(task.run_dir, files)
            done.append((task, record))
        return done

    def close(self) -> None:
        for ref in list(self._running):
            try:
                self._ray.cancel(ref, force=True)
            except Exception:
                pass
        self._running.clear()
        if self._started:
            self._ray.shutdown()
            self._started = False  # closed twice (the loop's and the study's finally): shut down once


def _write_files(run_dir: Path, files: dict[str, bytes]) -> None:
    from longslam.io.atomic import atomic_path

    if run_dir.exists():
        shutil.rmtree(run_dir)
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(run_dir) as tmp:
        tmp.mkdir()
        for name, data in files.items():
            path = tmp / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)


def make_executor(kind: str, address: str | None = None, jobs: int | None = None) -> Executor:
    check_executor_options(kind, address)
    if kind == "local":
        return LocalExecutor(jobs)
    if kind == "ray":
        return RayExecutor(address, jobs)
    from longslam.core.errors import UnknownNameError

    raise UnknownNameError("executor", kind, EXECUTORS)
