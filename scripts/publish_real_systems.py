"""Write docs/real-systems.md from the real-systems studies' databases: every number on the page
comes from them, and the page names the commit, date, machine and commands that made them.

    longslam study studies/real-systems.toml --out out/real-systems --jobs 2
    longslam study studies/real-systems-1km.toml --out out/real-systems-1km --jobs 2
    python scripts/publish_real_systems.py out/real-systems out/real-systems-1km --out docs/real-systems.md

For each ORB-SLAM3 run it reads the run's events (events.csv: tracking lost, new maps, loops) and
places each loss in the building with `longslam diagnose`'s regions; the colour image at the start
of each sequence's first loss is copied beside the page (what the camera saw there).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import shutil
import subprocess
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError
from longslam.run.diagnose import diagnose_run
from longslam.run.provenance import machine, single_commit
from longslam.study.database import DB_NAME, ResultsDB
from longslam.study.report.distribution import FAILURE_RULE, LONGEST_LOSS_S, dead_reckoning_ates, failures_text
from longslam.study.report.render import E_ROT_NOTE
from longslam.study.report.tables import format_number

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("odometry", "keyframe", "submap", "orbslam3")
LOSSES: list = []  # (run, event, region) of every ORB-SLAM3 tracking loss, filled as the runs are read
# Published runs must have had their CPU: a run waiting longer than this share is not published.
UNSTARVED_SHARE = 0.05


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()


def _num(value: Any, digits: int = 3) -> str:
    return "–" if value is None else format_number(float(value), digits)


def _spread(values: list[float]) -> str:
    """median [q1-q3] (min-max) of the values, or the value alone."""
    if not values:
        return "–"
    v = np.asarray(values, dtype=float)
    if len(v) == 1:
        return _num(v[0])
    q1, median, q3 = np.percentile(v, [25, 50, 75])
    return f"{_num(median)} [{_num(q1)}-{_num(q3)}] ({_num(v.min())}-{_num(v.max())})"


def _measured(run: dict, key: str) -> Any:
    return (run.get("measurements") or {}).get(key)


def _method_stat(run: dict, key: str, default: Any = None) -> Any:
    return ((run.get("measurements") or {}).get("method_stats") or {}).get(key, default)


def _cpu_ms_per_frame(run: dict) -> float | None:
    cpu, frames = _measured(run, "tree_cpu_time_s") or _measured(run, "process_cpu_time_s"), run.get("frames")
    return 1000.0 * cpu / frames if cpu and frames else None


def _cell_key(run: dict) -> tuple[str, str]:
    return run["route"], run["camera_name"]


def _commits(runs: list[dict]) -> list[str | None]:
    """The commit each finished run names (a run whose process died records none)."""
    return [_measured(r, "longslam_commit") for r in runs if r["status"] == "ok"]


def summary_table(runs: list[dict], dead: dict) -> list[str]:
    lines = ["| route | camera | method | runs | ATE [m], median [quartiles] (range) | mean +- std | failed "
             "| E_rot [deg/m] | RPE rot [deg] | peak [MB] | CPU [ms/frame] | CPU wait share, max |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    cells: dict[tuple, list[dict]] = defaultdict(list)
    for run in runs:
        cells[(*_cell_key(run), run["method"])].append(run)
    for (route, camera, method), mine in sorted(cells.items(), key=lambda kv: (kv[0][0], kv[0][1], METHODS.index(kv[0][2]) if kv[0][2] in METHODS else 9)):
        ok = [r for r in mine if r["status"] == "ok"]
        ates = [r["ate"] for r in ok if r.get("ate") is not None]
        mean = f"{_num(np.mean(ates))} +- {_num(np.std(ates))}" if ates else "–"
        waits = [r["cpu_wait_share"] for r in mine if r.get("cpu_wait_share") is not None]
        lines.append(
            f"| {route} | {camera} | {method} | {len(mine)} | {_spread(ates)} | {mean} | {failures_text(mine, dead)} "
            f"| {_spread([r['e_rot'] for r in ok if r.get('e_rot') is not None])} "
            f"| {_spread([r['rpe_rot'] for r in ok if r.get('rpe_rot') is not None])} "
            f"| {_num(np.median([r['peak_rss_bytes'] / 1e6 for r in ok]) if ok else None)} "
            f"| {_num(np.median([c for c in map(_cpu_ms_per_frame, ok) if c]) if ok else None)} "
            f"| {_num(max(waits) if waits else None, 2)} |")
    return lines


def orbslam3_runs(study: Path, runs: list[dict], images: Path, page: Path) -> tuple[list[str], list[str]]:
    """A row per ORB-SLAM3 run (its losses placed in the building) and, per sequence, the first
    loss's colour image."""
    lines = ["| route | camera | repeat | ATE [m] | untracked frames | longest loss [s] | maps | loops "
             "| CPU [ms/frame] | CPU wait share | tracking lost (frames, seconds, where) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    pictures: list[str] = []
    shown: set[tuple] = set()
    for run in runs:
        if run["method_name"] != "orbslam3":
            continue
        if run["status"] != "ok":
            lines.append(f"| {run['route']} | {run['camera_name']} | {run.get('repeat') or 0} | failed: "
                         f"{(run.get('error') or '').split(';')[0]} | | | | | | | |")
            continue
        run_dir = study / run["run_dir"]
        sequence = Path(_measured(run, "sequence"))
        try:
            diagnosis = diagnose_run(run_dir, sequence)
        except InputError as err:
            losses_text = f"(not diagnosed: {err})"
            losses = []
        else:
            losses = [(e, region) for e, region in diagnosis.events if e.kind == "tracking_lost"]
            losses_text = "; ".join(f"{e.first_frame}-{e.last_frame}, {e.first_t:.1f}-{e.last_t:.1f} s, "
                                    f"{region or '?'}" for e, region in losses) or "none"
        lines.append(
            f"| {run['route']} | {run['camera_name']} | {run.get('repeat') or 0} | {_num(run.get('ate'))} "
            f"| {_method_stat(run, 'frames_untracked', '–')} | {_num(_method_stat(run, 'tracking_lost_longest_s'), 2)} "
            f"| {_method_stat(run, 'maps_started', _method_stat(run, 'maps', '–'))} | {_method_stat(run, 'loops_accepted', '–')} "
            f"| {_num(_cpu_ms_per_frame(run))} | {_num(run.get('cpu_wait_share'), 2)} | {losses_text} |")
        LOSSES.extend((run, e, region) for e, region in losses)
        key = _cell_key(run)
        if losses and key not in shown:
            shown.add(key)
            event, region = max(losses, key=lambda item: item[0].last_frame - item[0].first_frame)
            rgb = _rgb_of_frame(sequence, event.first_frame)
            if rgb is not None:
                name = f"{run['route']}-{run['camera_name']}-frame-{event.first_frame}.png"
                images.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(rgb, images / name)
                pictures += [f"![{run['route']} {run['camera_name']}, frame {event.first_frame}]"
                             f"({os.path.relpath(images / name, page.parent)})", "",
                             f"*{run['route']}, {run['camera_name']}, repeat {run.get('repeat') or 0}: frame "
                             f"{event.first_frame} ({event.first_t:.1f} s, {region or 'unknown place'}), the first of "
                             f"{event.last_frame - event.first_frame + 1} untracked frames: what the camera saw when "
                             "tracking was lost.*", ""]
    return lines, pictures


def _rgb_of_frame(sequence: Path, frame: int) -> Path | None:
    rows = [line.split() for line in (sequence / "rgb.txt").read_text().splitlines() if line and not line.startswith("#")]
    return sequence / rows[frame][1] if 0 <= frame < len(rows) else None


def why_it_fails(runs: list[dict]) -> list[str]:
    """What the runs' events say about ORB-SLAM3's failures, counted from the events."""
    orb = [r for r in runs if r["method_name"] == "orbslam3"]
    crashed = [r for r in orb if r["status"] != "ok"]
    long_losses = [(run, e, region) for run, e, region in LOSSES if e.last_frame - e.first_frame + 1 >= 20]
    lengths = sorted(e.last_frame - e.first_frame + 1 for _, e, _ in long_losses)
    new_maps = sum(1 for r in orb if (_method_stat(r, "maps_started", 1) or 1) > 1)
    places = sorted({region or "?" for _, _, region in long_losses})
    waits = [r["cpu_wait_share"] for r in orb if r.get("cpu_wait_share") is not None]
    alone = all(not _overlaps(r, runs) for r in orb)
    out = [
        "## Why ORB-SLAM3 fails",
        "",
        f"Of {len(orb)} ORB-SLAM3 runs, {new_maps} started a second map, and every such run lost tracking for "
        f"a stretch first: the long losses (20 frames or more) lasted {', '.join(map(str, lengths)) or 'no'} frames, "
        f"in {', '.join(places) or 'no place'}. {len(crashed)} run(s) died ("
        + (", ".join(sorted({(r.get('error') or '').split(';')[0] for r in crashed})) or "none") + ").",
        "",
        "The length is ORB-SLAM3's own rule. When tracking the local map fails (its console prints `Fail to track "
        "local map!`, once a frame), an RGB-D system without an IMU enters RECENTLY_LOST and tries to relocalise "
        "on every frame; if it has not succeeded once the frame's stamp is more than 3.0 s past the loss "
        "(`Tracking.cc`: `mCurrentFrame.mTimeStamp-mTimeStampLost>3.0f && !bOK`), it is LOST, and the next frame "
        "starts a new map (or resets the map if it holds under 10 keyframes). At 10 frames a second that is "
        "31-32 frames, the stretch the losses above have. The new map begins at the identity; the plugin places "
        "it at the last tracked pose, 3 s behind the robot, so its whole trajectory is off by what the robot did "
        "in those 3 s (a turn taken then rotates the rest of the route), and the final trajectory is ORB-SLAM3's "
        "largest map. Whether tracking the local map fails at all differs from run to run on the same images: "
        "the local mapping thread races tracking, and a frame that arrives before the new keyframe's points are "
        "in the local map finds too few matches. The image below each table is the first frame of the longest "
        "loss: what the camera saw when tracking failed.",
        "",
        "**CPU.** Each ORB-SLAM3 run ran " + ("alone" if alone else "beside other runs (see the tables)") +
        f" on the 2 cores; its threads' CPU wait share was {_num(min(waits), 2) if waits else '–'} to "
        f"{_num(max(waits), 2) if waits else '–'} (median {_num(float(np.median(waits)), 2) if waits else '–'}). "
        "Alone, that wait is ORB-SLAM3's own threads (tracking, local mapping, loop closing and a global bundle "
        "adjustment after a loop) wanting more than 2 cores at once: on this machine it does not get all the CPU "
        f"it asks for even alone, and the runs over {UNSTARVED_SHARE:g} are marked in the tables.",
        "",
    ]
    return out


def _overlaps(run: dict, runs: list[dict]) -> bool:
    if not run.get("started_at") or not run.get("ended_at"):
        return False
    start, end = dt.datetime.fromisoformat(run["started_at"]), dt.datetime.fromisoformat(run["ended_at"])
    return any(other is not run and other.get("started_at") and other.get("ended_at")
               and dt.datetime.fromisoformat(other["started_at"]) < end and start < dt.datetime.fromisoformat(other["ended_at"])
               for other in runs)


def _study_time(runs: list[dict]) -> str:
    starts = [dt.datetime.fromisoformat(r["started_at"]) for r in runs if r.get("started_at")]
    ends = [dt.datetime.fromisoformat(r["ended_at"]) for r in runs if r.get("ended_at")]
    if not starts or not ends:
        return "unknown"
    return f"{(max(ends) - min(starts)).total_seconds() / 60:.0f} min"


def publish(studies: list[Path], out: Path, commands: list[str], wall_s: float | None = None) -> None:
    """Write `out` from the studies' databases; `wall_s`: the wall time of what made them (scripts/publish.py)."""
    images = out.parent / "images" / "real-systems"
    if images.exists():
        shutil.rmtree(images)
    parts: list[str] = []
    all_runs: list[dict] = []
    for study in studies:
        with ResultsDB(study / DB_NAME) as db:
            config, runs = db.study() or {}, db.runs()
        all_runs += runs
        dead = dead_reckoning_ates(runs)
        rows, pictures = orbslam3_runs(study, runs, images, out)
        parts += [f"## Study `{config.get('name')}`: {', '.join(r['name'] for r in config.get('routes', []))}, "
                  f"{config.get('repeats', 1)} runs per cell", "",
                  f"{len(runs)} runs, {sum(r['status'] != 'ok' for r in runs)} ended in an error; the study took "
                  f"{_study_time(runs)} on this machine (an orbslam3 run takes both cores, so it ran alone).", "",
                  *summary_table(runs, dead), "", "### Each ORB-SLAM3 run and where it lost tracking", "", *rows, "",
                  *pictures]
    waits = [r["cpu_wait_share"] for r in all_runs if r.get("cpu_wait_share") is not None]
    starved = [r["key"] for r in all_runs if (r.get("cpu_wait_share") or 0.0) > UNSTARVED_SHARE]
    try:
        commit = single_commit(_commits(all_runs), "the real-systems studies")
    except ValueError as err:
        raise SystemExit(f"error: {err}") from None
    header = [
        "# A real system in the harness: ORB-SLAM3 beside keyframe and submap", "",
        "<!-- written by scripts/publish_real_systems.py from the studies' databases; do not edit by hand -->", "",
        f"Every run was made at commit `{commit}`; the page was written on {dt.date.today().isoformat()} at "
        f"`{_git('rev-parse', '--short=7', 'HEAD')}`, on {machine()}, by:", "",
        "```bash", *commands, "```", "",
        *([f"The studies and this page took {wall_s / 60:.0f} min of wall time this time (runs recorded "
           "before are reused).", ""] if wall_s is not None else []),
        f"Every run's CPU wait share (how long its threads were ready to run but waited for a core, over that wait "
        f"plus their CPU time) is at most {_num(max(waits) if waits else None, 2)}; "
        + (f"{len(starved)} of {len(waits)} runs waited for more than {UNSTARVED_SHARE:g} of their time ("
           + ", ".join(f"{m}: {n}" for m, n in sorted(Counter(k.split('/')[-2] for k in starved).items())) + ")."
           if starved else f"no run waited for more than {UNSTARVED_SHARE:g} of its time."),
        "Nothing else ran on the machine while the studies ran, apart from a load sampler (the load average "
        "once a minute) and short reads of the databases.", "",
        f"`keyframe`, `submap` and `odometry` ran two at a time (one core each): their CPU wait share (median "
        f"{_num(float(np.median([r['cpu_wait_share'] for r in all_runs if r['method_name'] != 'orbslam3' and r.get('cpu_wait_share') is not None] or [0.0])), 2)}) "
        "comes from each run's second thread (it decodes the next frames' images while the method works) and "
        "the other run; they are deterministic, so the wait changes their time, not their trajectories.", "",
        "ORB-SLAM3 (`orbslam3`, the plugin `plugins/longslam-orbslam3`, GPL-3.0, through `pyorbslam3` 0.1.1) sees the "
        "images and depth only; the wheel odometry places its first map at the first odometry pose. It is fed at "
        "the sequence's own rate (10 frames a second) and its tracking, local mapping and loop closing threads "
        "race, so each cell was run several times: the tables give the median, quartiles and range of the ATE "
        "(no alignment) beside the paper's mean +- std. `keyframe`, `submap` and `odometry` (dead reckoning) are "
        "deterministic; their repeats differ only in time.", "",
        f"**Failure rule.** {FAILURE_RULE}", "",
        f"**E_rot.** {E_ROT_NOTE}", "",
        f"Tracking lost means frames in a state other than OK; the longest loss runs from its first untracked frame "
        f"to the next tracked one (a loss over {LONGEST_LOSS_S:g} s fails the run). Where is the region of the "
        "building (from the floor plan) the robot was in at the loss's first frame.", "",
    ]
    out.write_text("\n".join(header + why_it_fails(all_runs) + parts).rstrip() + "\n", encoding="utf-8")
    print(f"wrote {out} ({len(all_runs)} runs, commit {commit}, max CPU wait share {max(waits) if waits else None})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("studies", nargs="+", type=Path, help="study folders (each with results.sqlite)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "real-systems.md")
    parser.add_argument("--command", action="append", default=[],
                        help="a command that made the studies, shown on the page (repeatable)")
    args = parser.parse_args()
    commands = args.command or [f"longslam study studies/{json.loads(json.dumps(s.name))}.toml --out {s} --jobs 2"
                                for s in args.studies]
    commands.append("python scripts/publish_real_systems.py " + " ".join(map(str, args.studies)))
    publish(args.studies, args.out, commands)


if __name__ == "__main__":
    main()
