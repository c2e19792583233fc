"""Regenerate every published result from its runs: one command, each step resumable.

    python scripts/publish.py [--only STEP[,STEP...]] [--work DIR] [--jobs N] [--without-orbslam3]

The steps, in order (without --only: paper, sensors, scale, maps; real-systems and degradation
only when --only names them, as ORB-SLAM3's condition, a run alone with the CPU it asks for,
cannot be met on 2 cores; --without-orbslam3 leaves ORB-SLAM3 out of sensors and degradation,
plugin or not, and the pages say so). Estimated wall time on this project's 2-core machine, from the last
recorded runs (d78f602's, render cache cold, scale's at 286a7cb):

  paper         studies/paper.toml (200 runs, 5 variants at today's defaults)
                -> docs/results/paper-reproduction.md                              about 1 h 25 min
  sensors       studies/sensors.toml (orbslam3 only if its plugin is installed)
                -> docs/results/sensors.md                                         about 7 min
                (with ORB-SLAM3 about 1 h 10 min)
  scale         benchmarks/scale.py's runs: paper-1km, paper-1km-x3 (3 km), tour-10km at large
                noise, seed 0; odometry, keyframe, submap -> docs/results/scale.md about 1 h
                (and about 20 min more the first time, to render the 10 km tour)
  maps          the paper study's keyframe and submap maps (first seed of every route and noise
                level), scored and drawn -> docs/results/maps.md                   about 1 min
  real-systems  studies/real-systems.toml and real-systems-1km.toml
                -> docs/real-systems.md (scripts/publish_real_systems.py)          about 1 h 55 min
  degradation   studies/degradation.toml, degradation-depth-delay.toml and, with the plugin,
                degradation-orbslam3.toml
                -> docs/results/degradation.md              about 30 min, ORB-SLAM3's 2 h 30 min

All four default steps: about 2 h 50 min with the render cache cold, without ORB-SLAM3. Every step
resumes: a study from its database in WORK/STEP, the scale benchmark from the runs it measured in
WORK/scale; a page is rewritten each time. The command refuses a git tree with uncommitted changes
to tracked files outside docs/results (there, the pages of a step published before at the same
commit may wait to be committed), and a page whose runs were made at more than one commit (it names
them: delete WORK/STEP to run the step again at one commit). Each page begins with a stamp: the
runs' commit, the date, the machine (cores, CPU model, memory), the command and the step's wall
time; its figures go beside it in a folder named by the commit.
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
STEPS = ("paper", "sensors", "scale", "maps", "real-systems", "degradation")
DEFAULT_STEPS = ("paper", "sensors", "scale", "maps")
SCALE_ROUTES = ("paper-1km", "paper-1km-x3", "tour-10km")
SCALE_METHODS = ("odometry", "keyframe", "submap")
SCALE_NOISE, SCALE_SEED = "large", 0
MAP_METHODS = ("keyframe", "submap")
MAP_TARGET = 0.9  # issue 25: aligned precision and recall of every method's map
NOT_EDITED = "<!-- written by scripts/publish.py from the runs; do not edit by hand: run it again -->"


class PublishError(Exception):
    """A step cannot publish: the message says why and what to do."""


@dataclass
class Publication:
    """Where a publication reads and writes, and how it was asked for."""

    root: Path  # the git checkout
    work: Path  # the steps' studies and runs, WORK/STEP
    results: Path  # the generated pages, docs/results
    command: str  # the command line, as the stamps show it
    jobs: int = 2
    # ORB-SLAM3 left out of the sensors and degradation steps even with its plugin installed: its
    # runs need 3 cores to themselves, which a 2-core machine cannot give them (issue 39).
    without_orbslam3: bool = False
    say: Callable[[str], None] = field(default=lambda text: print(f"[publish {time.strftime('%H:%M:%S')}] {text}",
                                                                    flush=True))

    @property
    def docs(self) -> Path:
        return self.results.parent


# ---------------------------------------------------------------------------------------- checks


def git(root: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, check=True).stdout.strip()


def check_clean(root: Path, pages: Path | None = None) -> None:
    """Refuse a checkout whose tracked files differ from its commit (untracked files are allowed),
    but for the folder of the pages this script writes (`pages`): a step published after another at
    the same commit finds the first one's pages there, and committing them would move the commit."""
    status = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                            capture_output=True, text=True, check=True).stdout
    files = [line[3:] for line in status.splitlines() if line.strip()]  # "XY path": the two status columns
    if pages is not None and pages.resolve().is_relative_to(root.resolve()):
        written = pages.resolve().relative_to(root.resolve()).as_posix() + "/"
        files = [f for f in files if not f.startswith(written)]
    if files:
        raise PublishError(f"the git tree at {root} has uncommitted changes ({', '.join(files[:8])}"
                           + (", ..." if len(files) > 8 else "") + "): commit or stash them; a published "
                           "page names the commit its runs were made at")


def commit_of(runs: list[dict], what: str) -> str:
    """The one clean commit that made every finished run (from each run's stats: `longslam_commit`)."""
    from longslam.run.provenance import single_commit

    try:
        return single_commit([(r.get("measurements") or {}).get("longslam_commit") for r in runs
                              if r.get("status") == "ok"], what)
    except ValueError as err:
        raise PublishError(str(err)) from None


# ----------------------------------------------------------------------------------------- pages


def duration(seconds: float) -> str:
    minutes = round(seconds / 60)
    if seconds < 90:
        return f"{seconds:.0f} s"
    return f"{minutes // 60} h {minutes % 60} min" if minutes >= 60 else f"{minutes} min"


def stamp(pub: Publication, commit: str, wall_s: float, commands: list[str], source: str, note: str = "") -> list[str]:
    """The block every generated page begins with: the runs' commit, the date, the machine, the
    command, what the step ran (`commands`, then the page from `source`) and its wall time."""
    from longslam.run.provenance import machine

    head = git(pub.root, "rev-parse", "--short=7", "HEAD")
    return [
        NOT_EDITED, "",
        f"- **Commit**: every run was made at `{commit}`; the page was written at `{head}`",
        f"- **Date**: {dt.datetime.now(dt.timezone.utc).strftime('%Y-%m-%d %H:%M')} UTC",
        f"- **Machine**: {machine()}",
        f"- **Command**: `{pub.command}`",
        "- **The step ran**: " + ", then ".join(f"`{c}`" for c in commands) + f"; the page is written from {source}",
        f"- **Wall time of the step**: {duration(wall_s)}" + (f" ({note})" if note else ""),
        "",
    ]


def figure_folder(pub: Publication, page: str, commit: str) -> Path:
    """docs/results/PAGE-COMMIT/, emptied; another commit's folder of the same page is removed."""
    stem = Path(page).stem
    for old in pub.results.glob(f"{stem}-*"):
        if old.is_dir() and re.fullmatch(rf"{re.escape(stem)}-[0-9a-f]{{7,40}}", old.name):
            shutil.rmtree(old)
    folder = pub.results / f"{stem}-{commit}"
    folder.mkdir(parents=True)
    return folder


def write_page(pub: Publication, page: str, lines: list[str]) -> Path:
    pub.results.mkdir(parents=True, exist_ok=True)
    path = pub.results / page
    path.write_text("\n".join(lines).rstrip() + "\n", encoding="utf-8")
    pub.say(f"wrote {path.relative_to(pub.root) if path.is_relative_to(pub.root) else path}")
    return path


def _rel(pub: Publication, path: Path) -> str:
    return str(path.relative_to(pub.root)) if path.is_absolute() and path.is_relative_to(pub.root) else str(path)


def _runs(study: Path) -> list[dict]:
    from longslam.study.database import DB_NAME, ResultsDB

    if not (study / DB_NAME).is_file():
        raise PublishError(f"{study / DB_NAME} does not exist: run its step first")
    with ResultsDB(study / DB_NAME) as db:
        return db.runs()


def _span(runs: list[dict]) -> str:
    starts = [dt.datetime.fromisoformat(r["started_at"]) for r in runs if r.get("started_at")]
    ends = [dt.datetime.fromisoformat(r["ended_at"]) for r in runs if r.get("ended_at")]
    return duration((max(ends) - min(starts)).total_seconds()) if starts and ends else "unknown"


# ---------------------------------------------------------------------------------------- studies


@dataclass(frozen=True)
class StudyPage:
    """A step that runs a study and publishes its report as a page."""

    step: str
    study_file: Path
    page: str  # its file name under docs/results
    title: str
    about: tuple[str, ...] = ()  # paragraphs under the stamp: what the study is


PAPER = StudyPage(
    "paper", ROOT / "studies" / "paper.toml", "paper-reproduction.md", "The paper's experiment, reproduced",
    ("Every variant of `studies/paper.toml` at today's defaults on the paper's two routes, four noise levels and "
     "five seeds, beside the paper's own Tables 1 and 2 (rows marked (paper): A. Muravyev and K. Yakovlev, "
     "\"Evaluation of RGB-D SLAM in Large Indoor Environments\", ICR 2022). `keyframe` (RTAB-Map's design) and "
     "`submap` (Voxgraph's) run with the fused front end (wheels, depth scans and gated RGB-D steps); "
     "`keyframe-wheel` and `submap-wheel` take their motion from the wheel odometry alone, as in the paper; "
     "`odometry` is dead reckoning. The paper's systems ran in its own building (Habitat, a scan of the "
     "authors' university), so its rows are a reference, not a target. Runs ran two at a time on the 2 cores: "
     "a run alone is faster.",),
)
SENSORS = StudyPage(
    "sensors", ROOT / "studies" / "sensors.toml", "sensors.md", "Real sensors, not ideal ones",
    ("Every method under the ideal sensor, a Kinect v1 model and a RealSense D435 model (`studies/sensors.toml`): "
     "paper-300m at large wheel noise, 3 seeds. Each sensor's noise is drawn on the fly from the one cached "
     "rendering of the route, per (sensor, seed); the sensor is a column of the tables.",),
)


def run_study_step(pub: Publication, page: StudyPage, study_file: Path | None = None) -> Path:
    """Run (or resume) the step's study in WORK/STEP; returns the study folder."""
    from longslam.study.config import load_study
    from longslam.study.driver import run_study

    out = pub.work / page.step
    file = study_file or page.study_file
    config = load_study(Path(_rel(pub, file)) if Path.cwd() == pub.root else file)  # the page shows its path
    pub.say(f"{page.step}: {config.grid_text()} in {_rel(pub, out)} (resumes from its database)")
    summary = run_study(config, out, jobs=pub.jobs, report=False, progress=True)
    pub.say(f"{page.step}: {summary.planned} runs, {summary.skipped} recorded before, {summary.ran} run now "
            f"({summary.failed} failed) in {duration(summary.wall_time_s)}")
    return out


def study_command(pub: Publication, study_file: Path, out: Path) -> str:
    return f"longslam study {_rel(pub, study_file)} --out {_rel(pub, out)} --jobs {pub.jobs}"


def publish_study(pub: Publication, page: StudyPage, out: Path, wall_s: float, study_file: Path | None = None,
                  notes: tuple[str, ...] = ()) -> Path:
    """The step's page from the study's database: the stamp, what the study is, then its report
    (tables beside the paper's numbers, every run, figures), the figures copied beside the page."""
    from longslam.study.report import build_report, render_markdown

    runs = _runs(out)
    commit = commit_of(runs, f"step {page.step} ({_rel(pub, out)})")
    report = build_report(out, figures=True)
    folder = figure_folder(pub, page.page, commit)
    for figure in report.figures:
        shutil.copyfile(out / figure.path, folder / figure.path.name)
        figure.path = Path(folder.name) / figure.path.name
    body = render_markdown(report).splitlines()[1:]  # its own title gives way to the page's
    lines = [f"# {page.title}", "",
             *stamp(pub, commit, wall_s, [study_command(pub, study_file or page.study_file, out)],
                    f"its database, `{_rel(pub, out)}/results.sqlite`",
                    f"the study's runs span {_span(runs)} from the first start to the last end"),
             *[p + "\n" for p in page.about], *[n + "\n" for n in notes], *body]
    return write_page(pub, page.page, lines)


def study_step(pub: Publication, page: StudyPage, study_file: Path | None = None,
               notes: tuple[str, ...] = ()) -> Path:
    start = time.perf_counter()
    out = run_study_step(pub, page, study_file)
    return publish_study(pub, page, out, time.perf_counter() - start, study_file, notes)


def orbslam3_left_out(pub: Publication, ran: str) -> str | None:
    """Why ORB-SLAM3's runs are not on a page (`ran`: what ran instead), or None when they run."""
    from longslam.slam.catalog import method_names

    if pub.without_orbslam3:
        return (f"**ORB-SLAM3 is not on this page**: it was made with `--without-orbslam3`, on a machine where "
                f"ORB-SLAM3's runs cannot have the 3 cores they need to themselves, so {ran}.")
    if "orbslam3" not in method_names():
        return (f"**ORB-SLAM3 is not on this page**: its plugin (`plugins/longslam-orbslam3`) was not installed "
                f"where the page was made, so {ran}.")
    return None


def sensors_step(pub: Publication) -> Path:
    """studies/sensors.toml; without ORB-SLAM3 (`orbslam3_left_out`) a copy of it without orbslam3 (the page says so)."""
    text = SENSORS.study_file.read_text(encoding="utf-8")
    note = orbslam3_left_out(pub, "the study ran `studies/sensors.toml` without `orbslam3`")
    if note is None:
        return study_step(pub, SENSORS)
    trimmed = pub.work / "sensors-without-orbslam3.toml"
    pub.work.mkdir(parents=True, exist_ok=True)
    trimmed.write_text(re.sub(r'^methods\s*=\s*\[([^\]]*)\]',
                              lambda m: "methods = [" + ", ".join(
                                  x for x in (s.strip() for s in m.group(1).split(",")) if x != '"orbslam3"') + "]",
                              text, count=1, flags=re.M), encoding="utf-8")
    pub.say("sensors: the study runs without orbslam3")
    return study_step(pub, SENSORS, trimmed, (note,))


# ------------------------------------------------------------------------------------------ scale


def _bench(name: str) -> Any:
    """A module of benchmarks/ (they import each other as top-level modules)."""
    import importlib

    bench = str(ROOT / "benchmarks")
    if bench not in sys.path:
        sys.path.insert(0, bench)
    return importlib.import_module(name)


def scale_step(pub: Publication) -> Path:
    scale = _bench("scale")
    start = time.perf_counter()
    work = pub.work / "scale"
    pub.say(f"scale: {', '.join(SCALE_ROUTES)} at {SCALE_NOISE} noise, seed {SCALE_SEED}, "
            f"{', '.join(SCALE_METHODS)} in {_rel(pub, work)} (runs measured before are read back)")
    results = scale.run_scale(list(SCALE_ROUTES), SCALE_NOISE, SCALE_SEED, list(SCALE_METHODS), work)
    return publish_scale(pub, results, work, time.perf_counter() - start)


def publish_scale(pub: Publication, results: list[dict], work: Path, wall_s: float) -> Path:
    """docs/results/scale.md from the benchmark's entries (work/scale.json)."""
    scale = _bench("scale")
    rows = [r for entry in results for r in entry["runs"]]
    commit = commit_of([{"status": "ok" if "failed" not in r else "failed",
                         "measurements": {"longslam_commit": r.get("longslam_commit")}} for r in rows],
                       f"step scale ({_rel(pub, work)})")
    folder = figure_folder(pub, "scale.md", commit)
    scale.plot(results, folder)
    command = (f"python benchmarks/scale.py --routes {' '.join(SCALE_ROUTES)} --noise {SCALE_NOISE} "
               f"--seed {SCALE_SEED} --methods {' '.join(SCALE_METHODS)} --work {_rel(pub, work)}")
    lines = ["# Scale: 1, 3 and 10 km", "",
             *stamp(pub, commit, wall_s, [command], f"`{_rel(pub, work)}/scale.json`"),
             "Each route simulated once (`longslam simulate`, its own process), then each method as its own "
             "`longslam run` process, one at a time. Per run: peak resident memory of the whole process, the "
             "mean milliseconds a frame over the first and the last tenth of the frames, the `finish` time, "
             "the ATE (no alignment) and its ratio to dead reckoning's on the same sequence, and the loop "
             "constraints further than 0.5 m or 5 degrees from the truth (wrong loops).", "",
             f"Targets (issue 22): keyframe and submap peak <= {scale.PEAK_10KM_MB} MB at 10 km and <= "
             f"{scale.PEAK_3KM_RATIO}x their 1 km peak at 3 km; last tenth's ms a frame <= {scale.TIME_GROWTH}x "
             f"the first's; finish <= {scale.FINISH_10KM_S:.0f} s at 10 km; keyframe's ATE <= "
             f"{scale.ATE_RATIO_10KM}x dead reckoning's at 10 km with no wrong loop.", ""]
    one_km_peak: dict[str, float] = {}
    for entry in results:
        km = entry["route_m"] / 1000
        lines += [f"## {entry['route']}: {km:.2f} km, {entry['frames']:,} frames", "",
                  f"Noise {entry.get('noise', SCALE_NOISE)}, seed {entry.get('seed', SCALE_SEED)}; dead reckoning's "
                  f"ATE {entry['dead_reckoning_ate_m']:.3f} m"
                  + (f"; simulated in {duration(entry['simulate_s'])}" if entry.get("simulate_s") else "") + ".", "",
                  "| method | peak RSS [MB] | ms/frame, first -> last tenth | finish [s] | ATE [m] | x dead reckoning "
                  "| wrong loops | wall [s] | targets |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in entry["runs"]:
            if "failed" in r:
                lines.append(f"| {r['method']} | failed (exit {r['failed']}) | | | | | | | |")
                continue
            if abs(entry["route_m"] - 1000) < 100:
                one_km_peak[r["method"]] = r["peak_mb"]
            met = scale.targets(entry["route_m"], r, one_km_peak)
            lines.append(
                f"| {r['method']} | {r['peak_mb']:.0f} | {r['ms_per_frame_first_tenth']:.1f} -> "
                f"{r['ms_per_frame_last_tenth']:.1f} | {r['finish_s']:.1f} | {r['ate_m']:.3f} | "
                f"{r['ate_ratio_to_dead_reckoning']:.3f} | {'–' if r['wrong_loops'] is None else r['wrong_loops']} | "
                f"{r['wall_s']:.0f} | {'; '.join(met) or '–'} |")
        lines.append("")
    lines += ["![Resident memory against distance travelled, and ATE against route length, one line per "
              "method](" + f"{folder.name}/scale.png)", "",
              "*Left: resident memory of each run's process against distance travelled (a sample every 1,000 "
              "frames). Right: ATE against route length.*", ""]
    return write_page(pub, "scale.md", lines)


# ------------------------------------------------------------------------------------------- maps


def maps_step(pub: Publication) -> Path:
    """docs/results/maps.md from the paper study's run folders: each cell's map scores against the
    target, and the first seed's maps of keyframe and submap drawn over the true walls."""
    maps = _bench("maps")
    from longslam.viz.plots import plot_map_over_truth

    start = time.perf_counter()
    study = pub.work / PAPER.step
    runs = _runs(study)
    commit = commit_of(runs, f"step maps ({_rel(pub, study)}, the paper step's study)")
    ok = [r for r in runs if r["status"] == "ok" and r.get("map_precision_aligned") is not None]
    cells: dict[tuple, list[dict]] = defaultdict(list)
    for r in ok:
        cells[(r["method"], r["route"], r["noise"])].append(r)
    routes = list(dict.fromkeys(r["route"] for r in runs))
    config_noise = _study_noise(study) or list(dict.fromkeys(r["noise"] for r in runs))
    methods = list(dict.fromkeys(m for m, _, _ in cells))
    folder = figure_folder(pub, "maps.md", commit)
    body = [f"Every map of the paper study (`studies/paper.toml`, the [paper page](paper-reproduction.md)) scored as "
            "its Table 3 is: the occupied cells of each method's 2D grid against the true walls the camera "
            "could see, within 2 cells, as the map is and after its best planar alignment; the share of walls "
            f"it shows twice. The target (issue 25) is an aligned precision and recall of {MAP_TARGET} for every "
            "method's map.", "",
            "## Every cell: aligned precision / recall, mean over the seeds", "",
            f"A cell in bold reaches {MAP_TARGET} in both.", "",
            "| method | " + " | ".join(f"{route}: {noise}" for route in routes for noise in config_noise) + " |",
            "|---|" + "---|" * (len(routes) * len(config_noise))]
    for method in methods:
        texts = []
        for route in routes:
            for noise in config_noise:
                mine = cells.get((method, route, noise), [])
                if not mine:
                    texts.append("–")
                    continue
                p = float(np.mean([r["map_precision_aligned"] for r in mine]))
                rc = float(np.mean([r["map_recall_aligned"] for r in mine]))
                text = f"{p:.3f} / {rc:.3f}"
                texts.append(f"**{text}**" if p >= MAP_TARGET and rc >= MAP_TARGET else text)
        body.append(f"| {method} | " + " | ".join(texts) + " |")
    reached = sum(1 for mine in cells.values()
                  if np.mean([r["map_precision_aligned"] for r in mine]) >= MAP_TARGET
                  and np.mean([r["map_recall_aligned"] for r in mine]) >= MAP_TARGET)
    body += ["", f"{reached} of {len(cells)} cells reach the target.", ""]
    drawn = [m for m in MAP_METHODS if m in methods]
    if not drawn:
        body += ["No method of the study that is drawn here (" + ", ".join(MAP_METHODS) + ") made a map.", ""]
    else:
        body += ["## The first seed's maps", "",
                 "Each map as it is (black), the true walls (orange), the walls it shows twice ringed (magenta); "
                 "the scores are `benchmarks/maps.py`'s, recomputed from the run folder.", "",
                 "| route | noise | method | precision | recall | precision, aligned | recall, aligned "
                 "| doubled walls |",
                 "|---|---|---|---|---|---|---|---|"]
        pictures: list[str] = []
        for route in routes:
            for noise in config_noise:
                for method in drawn:
                    mine = sorted(cells.get((method, route, noise), []), key=lambda r: r["seed"])
                    if not mine:
                        continue
                    run = mine[0]
                    sequence = Path((run.get("measurements") or {}).get("sequence") or "")
                    run_dir = study / run["run_dir"]
                    pub.say(f"maps: {route} {noise} {method} seed {run['seed']}")
                    scores, grid, truth = maps.score_run(run_dir, sequence)
                    body.append(f"| {route} | {noise} | {method} (seed {run['seed']}) | "
                                + " | ".join(f"{scores[k]:.3f}" for k in maps.KEYS) + " |")
                    name = f"{route}-{noise}-{method}.png"
                    plot_map_over_truth(grid, truth, folder / name, doubled=scores["map_doubled_places"],
                                        title=f"{method}, {route}, {noise} noise, seed {run['seed']}", width=8.0,
                                        dpi=80)
                    pictures += [f"![{method}'s map, {route}, {noise} noise]({folder.name}/{name})", "",
                                 f"*{method}, {route}, {noise} noise, seed {run['seed']}: aligned precision "
                                 f"{scores['map_precision_aligned']:.3f}, recall {scores['map_recall_aligned']:.3f}.*",
                                 ""]
        body += ["", *pictures]
    lines = ["# Maps: walls where the walls are", "",
             *stamp(pub, commit, time.perf_counter() - start, ["python benchmarks/maps.py RUN SEQUENCE ..."],
                    f"the paper step's study, `{_rel(pub, study)}` (its database and run folders)")]
    return write_page(pub, "maps.md", lines + body)


def _study_noise(study: Path) -> list[str]:
    from longslam.study.database import DB_NAME, ResultsDB

    with ResultsDB(study / DB_NAME) as db:
        return list((db.study() or {}).get("noise", []))


# ----------------------------------------------------------------------------------- real systems


def real_systems_step(pub: Publication) -> Path:
    """The two real-systems studies, then docs/real-systems.md by scripts/publish_real_systems.py."""
    scripts = str(ROOT / "scripts")
    if scripts not in sys.path:
        sys.path.insert(0, scripts)
    import publish_real_systems

    start = time.perf_counter()
    studies, commands = [], []
    for name in ("real-systems", "real-systems-1km"):
        page = StudyPage(name, ROOT / "studies" / f"{name}.toml", "", "")
        studies.append(run_study_step(pub, page))
        commands.append(study_command(pub, page.study_file, studies[-1]))
    out = pub.docs / "real-systems.md"
    commands.append(pub.command)
    publish_real_systems.publish(studies, out, commands, time.perf_counter() - start)
    return out


# ------------------------------------------------------------------------------------ degradation

DEGRADATION = StudyPage(
    "degradation", ROOT / "studies" / "degradation.toml", "degradation.md", "How each method degrades",
    ("keyframe, submap and dead reckoning (`studies/degradation.toml`: 3 seeds) and ORB-SLAM3 "
     "(`studies/degradation-orbslam3.toml`: seed 0 run 3 times, as its threads race) on paper-300m at large "
     "wheel noise, under each perturbation at two levels after the ideal sensor; `none` is the same sequences "
     "unperturbed. A cell gives the median ATE of its runs in m, their range, and how many of them failed by "
     "the rule below the table; a figure per perturbation draws the median against the level (0: none), the "
     "bar spanning the runs. The sensor models are on [their own page](sensors.md).",
     "No method can see a `depth-offset`: the perturbation stamps both images alike. Where the offset is known "
     "from a calibration, `longslam run --depth-delay SECONDS` moves each depth image back in step by the "
     "odometry before the method sees it ([Running a method](../guide/run.md)). The runs of the "
     "perturbation's rows are made without it; the row marked `told` is the same perturbation with the methods "
     "told the delay (`studies/degradation-depth-delay.toml`, its `depth_delay` key), which the figures leave out.",),
)
DEGRADATION_ORBSLAM3 = StudyPage("degradation-orbslam3", ROOT / "studies" / "degradation-orbslam3.toml", "", "")
# The depth-offset runs again with the methods told the delay: what a known offset gives back.
DEGRADATION_TOLD = StudyPage("degradation-depth-delay", ROOT / "studies" / "degradation-depth-delay.toml", "", "")


@dataclass(frozen=True)
class DegradationCell:
    """One method under one perturbation: the ATE of each run that gave one, and the failures."""

    ates: tuple[float, ...]
    failed: int
    runs: int
    starved: int  # a real-time system's runs whose threads waited for a core (the result is then unsure)


def perturbation_level(text: str) -> tuple[str, float] | None:
    """(name, level) of one perturbation row's text (`drop=0.1`); None for `none`, a combination or
    a row whose methods were told a depth delay (`degradation_row`)."""
    if text in ("", "none") or "+" in text or "=" not in text or TOLD in text:
        return None
    name, level = text.split("=", 1)
    return name, float(level)


TOLD = ", told"


def degradation_row(run: dict) -> str:
    """The table row a run belongs to: its perturbation (`none` without one), marked with the
    depth delay its methods were told (a study's `depth_delay`, as `run --depth-delay`)."""
    row = run.get("perturbation") or "none"
    delay = (run.get("spec") or {}).get("depth_delay")
    return row if delay is None else f"{row}{TOLD} depth_delay {float(delay):g} s"


def takes_frames_in_real_time(method_name: str) -> bool:
    """Whether a method's result depends on the CPU it got (its spec's `real_time`): a method that
    is not installed here counts as one, so its starved runs are never hidden."""
    from longslam.core.errors import LongslamError
    from longslam.slam.catalog import get_spec

    try:
        return get_spec(method_name).real_time
    except LongslamError:
        return True


def degradation_cells(runs: list[dict]) -> dict[str, dict[str, DegradationCell]]:
    """{perturbation: {method: cell}} over the runs of the degradation studies, failures by the
    distribution report's rule (dead reckoning's ATE on the same sequence where it ran). Starved
    runs are counted for real-time methods only: an offline method waits for each frame, so a
    core it waited for moves its wall time, not its result."""
    from longslam.run.process_tree import starved
    from longslam.study.report.distribution import dead_reckoning_ates, failure_reasons

    reference = dead_reckoning_ates(runs)
    grouped: dict[str, dict[str, list[dict]]] = defaultdict(lambda: defaultdict(list))
    for run in runs:
        grouped[degradation_row(run)][run["method"]].append(run)
    cells: dict[str, dict[str, DegradationCell]] = {}
    for perturbation, by_method in grouped.items():
        cells[perturbation] = {}
        for method, group in by_method.items():
            ates = tuple(float(r["ate"]) for r in group if r["status"] == "ok" and r.get("ate") is not None)
            failed = len(failure_reasons([r for r in group if r.get("method_name") != "odometry"], reference))
            real_time = takes_frames_in_real_time(group[0].get("method_name") or method)
            hungry = sum(starved(r.get("cpu_wait_share")) for r in group) if real_time else 0
            cells[perturbation][method] = DegradationCell(ates, failed, len(group), hungry)
    return cells


def _perturbation_order(perturbations: list[str]) -> list[str]:
    """`none` first, then by name and level, combinations last."""
    def key(text: str) -> tuple:
        level = perturbation_level(text)
        return (0, "", 0.0) if text == "none" else (1, *level) if level else (2, text, 0.0)
    return sorted(perturbations, key=key)


def degradation_table(cells: dict[str, dict[str, DegradationCell]], methods: list[str]) -> list[str]:
    def text(cell: DegradationCell | None) -> str:
        if cell is None:
            return "not run"
        if not cell.ates:
            return f"no ATE, {cell.failed}/{cell.runs} failed"
        out = f"{np.median(cell.ates):.3f}"
        if len(cell.ates) > 1:
            out += f" [{min(cell.ates):.3f}-{max(cell.ates):.3f}]"
        out += f", {cell.failed}/{cell.runs} failed" if cell.failed else ""
        return out + (f", {cell.starved} starved" if cell.starved else "")

    lines = ["| perturbation | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for perturbation in _perturbation_order(list(cells)):
        lines.append(f"| {perturbation} | " + " | ".join(text(cells[perturbation].get(m)) for m in methods) + " |")
    return lines


def degradation_figures(cells: dict[str, dict[str, DegradationCell]], methods: list[str],
                        folder: Path) -> list[Path]:
    """One PNG per perturbation: each method's median ATE against the level (0: `none`), a bar
    over its runs' range."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    levels: dict[str, list[tuple[float, str]]] = defaultdict(list)
    for perturbation in cells:
        if (parsed := perturbation_level(perturbation)) is not None:
            levels[parsed[0]].append((parsed[1], perturbation))
    paths = []
    for name in sorted(levels):
        points = [(0.0, "none")] * ("none" in cells) + sorted(levels[name])
        fig, ax = plt.subplots(figsize=(5.5, 3.6))
        for method in methods:
            xs, medians, lows, highs = [], [], [], []
            for level, perturbation in points:
                cell = cells[perturbation].get(method)
                if cell is None or not cell.ates:
                    continue
                median = float(np.median(cell.ates))
                xs.append(level)
                medians.append(median)
                lows.append(median - min(cell.ates))
                highs.append(max(cell.ates) - median)
            if xs:
                ax.errorbar(xs, medians, yerr=[lows, highs], marker="o", capsize=3, label=method)
        ax.set_xlabel(f"{name} level (0: none)")
        ax.set_ylabel("ATE [m]")
        ax.set_title(f"ATE under {name}")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        path = folder / f"degradation-{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def publish_degradation(pub: Publication, studies: list[Path], wall_s: float, commands: list[str],
                        notes: tuple[str, ...] = ()) -> Path:
    """The degradation page from the studies' databases: the stamp, the table, the figures."""
    from longslam.study.report.distribution import FAILURE_RULE

    runs = [run for study in studies for run in _runs(study)]
    commit = commit_of(runs, "step degradation (" + ", ".join(_rel(pub, s) for s in studies) + ")")
    cells = degradation_cells(runs)
    methods = list(dict.fromkeys(run["method"] for run in runs))
    folder = figure_folder(pub, DEGRADATION.page, commit)
    figures = degradation_figures(cells, methods, folder)
    lines = [f"# {DEGRADATION.title}", "",
             *stamp(pub, commit, wall_s, commands,
                    "the databases " + ", ".join(f"`{_rel(pub, s)}/results.sqlite`" for s in studies),
                    f"the studies' runs span {_span(runs)} from the first start to the last end"),
             *[p + "\n" for p in DEGRADATION.about], *[n + "\n" for n in notes],
             "## ATE under each perturbation", "", *degradation_table(cells, methods), "",
             FAILURE_RULE + " A run of a real-time system is starved when its threads waited for a core.", ""]
    for path in figures:
        lines += [f"![{path.stem}]({folder.name}/{path.name})", ""]
    return write_page(pub, DEGRADATION.page, lines)


def degradation_step(pub: Publication) -> Path:
    """studies/degradation.toml and studies/degradation-depth-delay.toml, then, unless ORB-SLAM3 is
    left out (`orbslam3_left_out`), studies/degradation-orbslam3.toml."""
    start = time.perf_counter()
    note = orbslam3_left_out(pub, "`studies/degradation-orbslam3.toml` did not run")
    steps = [DEGRADATION, DEGRADATION_TOLD] + ([DEGRADATION_ORBSLAM3] if note is None else [])
    studies = [run_study_step(pub, page) for page in steps]
    commands = [study_command(pub, page.study_file, out) for page, out in zip(steps, studies)]
    notes = () if note is None else (note,)
    return publish_degradation(pub, studies, time.perf_counter() - start, commands, notes)


# ------------------------------------------------------------------------------------------- main

RUNNERS: dict[str, Callable[[Publication], Path]] = {
    "paper": lambda pub: study_step(pub, PAPER),
    "sensors": sensors_step,
    "scale": scale_step,
    "maps": maps_step,
    "real-systems": real_systems_step,
    "degradation": degradation_step,
}


def parse_steps(text: str | None) -> list[str]:
    if not text:
        return list(DEFAULT_STEPS)
    asked = [s.strip() for s in text.split(",") if s.strip()]
    unknown = [s for s in asked if s not in STEPS]
    if unknown:
        raise PublishError(f"unknown step(s) {', '.join(unknown)}; the steps are {', '.join(STEPS)}")
    return [s for s in STEPS if s in asked]  # in the publication's order


def publish(pub: Publication, steps: list[str]) -> list[Path]:
    check_clean(pub.root, pub.results)
    pages = []
    for i, step in enumerate(steps, 1):
        pub.say(f"step {i}/{len(steps)}: {step}")
        start = time.perf_counter()
        pages.append(RUNNERS[step](pub))
        pub.say(f"step {step} done in {duration(time.perf_counter() - start)}")
    return pages


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python scripts/publish.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", metavar="STEP[,STEP]", help=f"run these steps only ({', '.join(STEPS)})")
    parser.add_argument("--work", type=Path, default=Path("out/publish"),
                        help="folder of the steps' studies and runs (default out/publish)")
    parser.add_argument("--jobs", type=int, default=2, help="cores the studies use (default 2)")
    parser.add_argument("--without-orbslam3", action="store_true",
                        help="leave ORB-SLAM3 out of the sensors and degradation steps, plugin or not (the pages "
                        "say so): on a machine that cannot give its runs the 3 cores they need")
    args = parser.parse_args(argv)
    command = "python scripts/publish.py" + "".join(f" {shlex.quote(a)}" for a in (argv if argv is not None
                                                                                  else sys.argv[1:]))
    work = args.work if args.work.is_absolute() else (Path.cwd() / args.work)
    pub = Publication(ROOT, work.resolve(), ROOT / "docs" / "results", command, args.jobs, args.without_orbslam3)
    os.chdir(ROOT)  # the pages name the study files as the checkout has them: studies/paper.toml
    try:
        steps = parse_steps(args.only)
        publish(pub, steps)
    except PublishError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
