"""Run a study: every (route, camera, sensor, perturbation, noise level, method, seed), in parallel, resumable.

    DIR/results.sqlite    one row per finished run (see `longslam.study.database`)
    DIR/runs/<route>/<noise>/<method>/seed-<n>/   trajectory.txt, online.txt, stats.json, grid.npz...
    DIR/runs/<route>/<camera>/<noise>/<method>/seed-<n>/   the same, in a study with named cameras
    DIR/runs/<route>/[<camera>/]<sensor>/<noise>/<method>/seed-<n>/   in a study with a sensors axis
    DIR/runs/<route>/[<camera>/][<sensor>/]<perturbation>/<noise>/<method>/seed-<n>/   with a perturbations axis
    DIR/logs/...          each local run's stdout and stderr
    DIR/report.md, DIR/report.html

Runs already in the database with the same configuration are skipped, so a study that was
stopped (or killed) continues where it was; a run whose configuration changed is done again.
"""

from __future__ import annotations

import json
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from longslam.core.progress import bar as progress_bar
from longslam.run.process_tree import STARVED_SHARE
from longslam.study.backends import Executor, Task, check_executor_options, make_executor
from longslam.study.config import StudyConfig, check_method_params
from longslam.study.database import DB_NAME, ResultsDB, utc_now
from longslam.study.identity import check_same_study
from longslam.study.lock import study_lock
from longslam.study.prepare import (
    check_out_folder,
    check_routes,
    clean_partials,
    prepare_route,
    render_once,
    route_dir,
    world_grid_path,
)
from longslam.study.spec import RunSpec, plan_runs


@dataclass
class StudySummary:
    planned: int  # runs in the study
    skipped: int  # already in the database
    ran: int  # done by this call
    failed: int  # of those, recorded with an error
    wall_time_s: float
    database: Path
    report: Path | None


def _task(out: Path, spec: RunSpec, cores: int = 1) -> Task:
    return Task(
        spec=spec,
        run_dir=out / "runs" / spec.key,
        log_path=out / "logs" / f"{spec.key}.log",
        grid_path=world_grid_path(out, spec.world),
        observed_path=route_dir(out, spec.route, spec.camera_name) / "observed.npy",
        cores=cores,
    )


def runs_to_do(
    specs: list[RunSpec],
    finished: dict[str, tuple[str, str]],
    retry_failed: bool = False,
    again: set[str] | frozenset[str] = frozenset(),
) -> list[RunSpec]:
    """The planned runs that are not yet in the database with the same configuration (or whose
    keys are in `again`)."""
    todo = []
    for spec in specs:
        done = finished.get(spec.key)
        if done is None or done[0] != spec.config_hash or (retry_failed and done[1] != "ok") or spec.key in again:
            todo.append(spec)
    return todo


def run_study(
    config: StudyConfig,
    out: str | Path,
    executor: str = "local",
    address: str | None = None,
    jobs: int | None = None,
    retry_failed: bool = False,
    retry_starved: bool = False,
    report: bool = True,
    progress: bool = True,
    extend: bool = False,
) -> StudySummary:
    """Run every run of `config` not yet in `out`'s database, then write the report.

    A folder holding another study (another name or grid) is refused unless `extend`: then the
    folder's study is widened by this one's routes, noise levels, methods and seeds.
    `retry_starved` runs again the recorded runs whose threads were starved of CPU (a
    `cpu_wait_share` over STARVED_SHARE)."""
    start = time.perf_counter()
    out = Path(out)
    # The grid and its run count first, before anything is planned or allocated.
    if progress:
        tqdm.write(f"study {config.name}: {config.grid_text()}")
    # Everything that can be wrong with the study is found before its folder is touched.
    check_executor_options(executor, address)
    check_method_params(config)
    specs = plan_runs(config)
    check_routes(config)
    check_out_folder(out)
    recorded = check_same_study(out, config.to_dict(), extend)
    if report:
        from longslam.study.report.render import check_report_files

        check_report_files(out)
    # The executor comes up first: a cluster that does not answer leaves no folder, lock or database.
    pool = make_executor(executor, address, jobs)
    try:
        out.mkdir(parents=True, exist_ok=True)
        with study_lock(out):
            return _run_locked(
                config, out, specs, start, executor, pool, retry_failed, report, progress, recorded, retry_starved
            )
    finally:
        pool.close()


def _run_locked(
    config: StudyConfig,
    out: Path,
    specs: list[RunSpec],
    start: float,
    executor: str,
    pool: Executor,
    retry_failed: bool,
    report: bool,
    progress: bool,
    recorded: dict | None = None,
    retry_starved: bool = False,
) -> StudySummary:
    say = tqdm.write if progress else (lambda *a, **k: None)

    with ResultsDB(out / DB_NAME) as db:
        db.set_study(recorded or config.to_dict())
        again = db.starved(STARVED_SHARE) if retry_starved else set()
        todo = runs_to_do(specs, db.finished(), retry_failed, again)
        skipped = len(specs) - len(todo)
        if skipped:
            say(f"{skipped} of {len(specs)} runs are in {out / DB_NAME} already; {len(todo)} to do")

        needed = {(spec.route, spec.camera_name) for spec in todo}
        for route in config.routes:
            for camera_name, camera in config.camera_axis():
                prepare_route(out, route, camera, config.follower, camera_name)
                # The local processes share this machine's rendering cache: render each route
                # (per camera) here, once, before they start. Ray workers render on their own
                # nodes, under a lock.
                if executor == "local" and (route.name, camera_name) in needed:
                    render_once(route, camera, config.follower, progress=progress)
        clean_partials(out / "runs")
        from longslam.slam.catalog import get_spec

        if executor == "local":  # once-per-machine work of the methods (a vocabulary), before the runs
            for entry in {(spec.method_name, json.dumps(spec.params, sort_keys=True)) for spec in todo}:
                get_spec(entry[0]).prepare_for(json.loads(entry[1]))

        failed = ran = 0
        if todo:
            pending = deque(todo)
            # Runs start in plan order while their cores are free: a run that needs every core
            # (ORB-SLAM3) waits for the runs before it to end, and nothing starts beside it.
            cores = {name: get_spec(name).cores(pool.capacity) for name in {spec.method_name for spec in todo}}
            started: dict[str, tuple[float, str]] = {}
            bar = progress_bar(
                total=len(specs),
                initial=skipped,
                unit="run",
                desc=f"study {config.name}",
                disable=not progress,
                dynamic_ncols=True,
                smoothing=0.0,
            )
            try:
                while pending or pool.running:
                    while pending and pool.busy_cores + cores[pending[0].method_name] <= pool.capacity:
                        spec = pending.popleft()
                        started[spec.key] = (time.perf_counter(), utc_now())
                        pool.submit(_task(out, spec, cores[spec.method_name]))
                    for task, record in pool.wait(timeout=0.5):
                        began, started_at = started.pop(task.spec.key)
                        record.elapsed_s = time.perf_counter() - began
                        run_dir = str(task.run_dir.relative_to(out)) if record.ok else None
                        db.record(task.spec, record, run_dir, executor, started_at=started_at, cores=task.cores)
                        ran += 1
                        if not record.ok:
                            failed += 1
                            say(f"run {task.spec.key} failed: {record.error}")
                        bar.update(1)
                    bar.set_postfix_str(f"running {pool.running}, left {len(pending)}, failed {failed}", refresh=True)
            finally:
                pool.close()  # runs still going when the loop stopped (an interrupt) are ended here
                bar.close()

    report_path = None
    if report:
        from longslam.study.report import write_report

        report_path = write_report(out)
    return StudySummary(len(specs), skipped, ran, failed, time.perf_counter() - start, out / DB_NAME, report_path)
