"""The working tree against a git revision, run side by side on the same sequences.

    python benchmarks/compare.py REV [--routes paper-300m] [--methods keyframe submap]
                                     [--params KEY=VALUE ...] [--noise large] [--seeds 0]
                                     [--repeats 2] [--work out/bench-compare] [--keep]

REV is checked out into a git worktree of its own under --work (removed at the end unless
--keep). Each sequence (route, noise, seed) is simulated once, by the working tree, into --work,
and both sides read that same folder, so the figures differ only by the method's code. Each run
is its own `longslam run` process with this interpreter and PYTHONPATH set to that side's `src`
(the working tree is the checkout this script is in), alternating tree, REV, tree, REV... for
--repeats rounds (both `src` folders byte-compiled first, so that no run pays for it). Per run:

- wall: wall-clock seconds of the whole process, start to exit (imports, reading, writing);
- CPU: the process's CPU seconds, user and system (`os.wait4`'s rusage): on a machine shared
  with other jobs its wall time grows with their load, its CPU time far less;
- peak: the process's peak resident memory as the kernel counts it (`os.wait4`'s ru_maxrss, what
  `/usr/bin/time -v` prints), in MB (10^6 bytes);
- ATE: the run's trajectory.txt against the sequence's groundtruth.txt, scored by the working
  tree's `longslam.run.score` for both sides (one metric code).

The table gives each side's median and the ratios tree / REV: below 1 the working tree is faster
(or smaller). --params go to the method on both sides; a parameter that REV does not know under
its current name but did under an older one (RENAMED_PARAMS) is passed to REV under that name,
with a note. Every run's figures are written to --work/compare.json.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TREE_SRC = ROOT / "src"
# The working tree's code is the checkout this script is in, whichever longslam the interpreter
# has installed (an editable install may point at another checkout): it simulates and scores here.
sys.path.insert(0, str(TREE_SRC))

from common import run_process_usage, sequence  # noqa: E402
from longslam.core.errors import InputError  # noqa: E402
from longslam.run.score import score_files  # noqa: E402
from longslam.core.settings import parse_key_values  # noqa: E402
from longslam.core.odometry_noise import get_noise  # noqa: E402
from longslam.sim.routes import get_route  # noqa: E402

SIDES = ("tree", "rev")

# A parameter's current name: (its name before, the commit that renamed it).
RENAMED_PARAMS = {
    "frontend.mode": ("frontend", "6bd1c3d"),
}

# Checks a method's parameters in a side's own code, as its `longslam run` would (no frames read);
# `parse_key_values` is in `longslam.core.settings` since the package's restructure, in
# `longslam.settings` before it.
PROBE = ("import sys\n"
         "try:\n    from longslam.core.settings import parse_key_values\n"
         "except ImportError:\n    from longslam.settings import parse_key_values\n"
         "from longslam.slam.catalog import check_params\n"
         "check_params(sys.argv[1], parse_key_values(sys.argv[2:]))")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("rev", metavar="REV", help="git revision to compare the working tree with (a commit, tag, branch)")
    parser.add_argument("--routes", nargs="+", default=["paper-300m"], help="routes (default paper-300m)")
    parser.add_argument("--methods", nargs="+", default=["keyframe", "submap"], help="methods (default keyframe submap)")
    parser.add_argument("--params", nargs="+", action="extend", default=[], metavar="KEY=VALUE",
                        help="method parameters for both sides, e.g. frontend.mode=wheel (the paper's configuration)")
    parser.add_argument("--noise", default="large", help="odometry noise level (default large)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0], help="noise seeds (default 0)")
    parser.add_argument("--repeats", type=int, default=2, help="runs of each side per sequence and method (default 2)")
    parser.add_argument("--work", default="out/bench-compare",
                        help="folder for REV's worktree, the sequences, runs and logs (default out/bench-compare)")
    parser.add_argument("--keep", action="store_true", help="keep REV's worktree (the next run with --work reuses it)")
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error(f"--repeats must be at least 1, got {args.repeats}")
    for pair in args.params:
        if "=" not in pair or pair.startswith("="):
            parser.error(f"--params {pair!r}: expected KEY=VALUE")
    return args


def ratio(tree: float | None, rev: float | None) -> str:
    """tree / rev, two decimals; '-' when either is missing or rev is 0."""
    if tree is None or rev is None or rev == 0:
        return "-"
    return f"{tree / rev:.2f}"


def median(values: list[float]) -> float | None:
    return statistics.median(values) if values else None


def _figure(value: float | None, fmt: str) -> str:
    return "failed" if value is None else format(value, fmt)


def _ate(values: list[float]) -> str:
    """The median ATE; '*' when the repeats disagree (a method that is not deterministic)."""
    if not values:
        return "failed"
    return f"{statistics.median(values):.4f}" + ("*" if max(values) - min(values) > 1e-9 else "")


def _groups(rows: list[dict]) -> list[list[dict]]:
    """The rows of each (method, params), in the order they first come."""
    groups: dict[tuple[str, str], list[dict]] = {}
    for row in rows:
        groups.setdefault((row["method"], row["params"]), []).append(row)
    return list(groups.values())


def _summary(group: list[dict]) -> list[str]:
    """One method's line over its sequences: the sums of each side's median wall and CPU seconds,
    the larger peak and the mean of the median ATEs, over the sequences where neither side failed
    (a speed claim over several seeds is the ratio of the sums, each sequence weighed by its length)."""
    both = [row for row in group if all(row[side]["wall_s"] and row[side]["ate_m"] for side in SIDES)]
    label = f"all {len(both)} of {len(group)}" if len(both) < len(group) else f"all {len(group)}"
    if not both:
        return [label, group[0]["method"], group[0]["params"] or "-"] + ["failed", "failed", "-"] * 3 + ["failed"] * 2

    def total(side: str, key: str) -> float | None:
        values = [median(row[side].get(key, [])) for row in both]
        return None if any(v is None for v in values) else sum(values)

    wall = {side: total(side, "wall_s") for side in SIDES}
    cpu = {side: total(side, "cpu_s") for side in SIDES}
    peak = {side: max(median(row[side]["peak_mb"]) or 0.0 for row in both) for side in SIDES}
    ate = {side: statistics.mean(statistics.median(row[side]["ate_m"]) for row in both) for side in SIDES}
    return [label, group[0]["method"], group[0]["params"] or "-",
            _figure(wall["tree"], ".1f"), _figure(wall["rev"], ".1f"), ratio(wall["tree"], wall["rev"]),
            _figure(cpu["tree"], ".1f"), _figure(cpu["rev"], ".1f"), ratio(cpu["tree"], cpu["rev"]),
            _figure(peak["tree"], ".0f"), _figure(peak["rev"], ".0f"), ratio(peak["tree"], peak["rev"]),
            f"{ate['tree']:.4f}", f"{ate['rev']:.4f}"]


def format_table(rows: list[dict], rev: str) -> list[str]:
    """The comparison table's lines. Each row: sequence, method, params (text) and per side ("tree",
    "rev") lists of the runs' wall_s, cpu_s, peak_mb and ate_m (a failed run adds to none of them)."""
    head = ["sequence", "method", "params", "wall s tree", f"wall s {rev}", f"tree / {rev}",
            "CPU s tree", f"CPU s {rev}", f"tree / {rev}",
            "peak MB tree", f"peak MB {rev}", f"tree / {rev}", "ATE m tree", f"ATE m {rev}"]
    cells = []
    for row in rows:
        wall = {side: median(row[side]["wall_s"]) for side in SIDES}
        cpu = {side: median(row[side].get("cpu_s", [])) for side in SIDES}
        peak = {side: median(row[side]["peak_mb"]) for side in SIDES}
        cells.append([row["sequence"], row["method"], row["params"] or "-",
                      _figure(wall["tree"], ".1f"), _figure(wall["rev"], ".1f"), ratio(wall["tree"], wall["rev"]),
                      _figure(cpu["tree"], ".1f"), _figure(cpu["rev"], ".1f"), ratio(cpu["tree"], cpu["rev"]),
                      _figure(peak["tree"], ".0f"), _figure(peak["rev"], ".0f"), ratio(peak["tree"], peak["rev"]),
                      _ate(row["tree"]["ate_m"]), _ate(row["rev"]["ate_m"])])
    cells += [_summary(group) for group in _groups(rows) if len(group) > 1]
    widths = [max(len(line[i]) for line in [head] + cells) for i in range(len(head))]

    def line(values: list[str]) -> str:
        return "  ".join(v.ljust(w) if i < 3 else v.rjust(w) for i, (v, w) in enumerate(zip(values, widths))).rstrip()

    out = [line(head), line(["-" * w for w in widths])] + [line(c) for c in cells]
    out.append(f"medians of each side's runs; ratios are tree / {rev}: below 1 the working tree is faster (or smaller)")
    if any(c[0].startswith("all ") for c in cells):
        out.append("all N: per method, sums of the sequences' medians (wall, CPU), the larger peak, the mean ATE; "
                   "sequences where a side failed are left out")
    if any(c[-1].endswith("*") or c[-2].endswith("*") for c in cells):
        out.append("* the repeats' ATE differ (the median is shown; compare.json has each)")
    return out


def side_env(src: Path) -> dict[str, str]:
    """This environment with PYTHONPATH led by `src`, any other longslam checkout's src left out."""
    env = dict(os.environ)
    others = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p and not (Path(p) / "longslam").is_dir()]
    env["PYTHONPATH"] = os.pathsep.join([str(src)] + others)
    return env


def git(*args: str, cwd: Path = ROOT) -> str:
    done = subprocess.run(["git", "-C", str(cwd), *args], capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"compare.py: git {' '.join(args)}: {done.stderr.strip()}")
    return done.stdout.strip()


def make_worktree(sha: str, work: Path) -> tuple[Path, bool]:
    """A detached worktree of `sha` under `work` (reused if one is there already); (path, made now)."""
    path = work / f"rev-{sha[:12]}"
    if path.exists():
        if (path / ".git").exists() and git("rev-parse", "HEAD", cwd=path) == sha:
            return path, False
        raise SystemExit(f"compare.py: {path} exists and is not a worktree of {sha[:12]}; remove it or choose another --work")
    git("worktree", "add", "--detach", str(path), sha)
    return path, True


def check_params(src: Path, method: str, pairs: list[str]) -> str | None:
    """None if the code under `src` takes `pairs` for `method`, else its error's last line."""
    done = subprocess.run([sys.executable, "-c", PROBE, method, *pairs], env=side_env(src),
                          capture_output=True, text=True)
    if done.returncode == 0:
        return None
    lines = done.stderr.strip().splitlines()
    return re.sub(r"^[\w.]*(Error|Exception): ", "", lines[-1]) if lines else f"exit {done.returncode}"


def renamed(pairs: list[str]) -> list[str]:
    """`pairs` with each key that was renamed under its older name."""
    out = []
    for pair in pairs:
        key, _, value = pair.partition("=")
        out.append(f"{RENAMED_PARAMS[key][0]}={value}" if key in RENAMED_PARAMS else pair)
    return out


def side_params(src: Path, label: str, method: str, pairs: list[str]) -> list[str]:
    """The --param pairs that give `method` at `src` the parameters `pairs` (older names where it
    knew them so); stops with the side's error when neither spelling is taken."""
    error = check_params(src, method, pairs)
    if error is None:
        return pairs
    older = renamed(pairs)
    if older != pairs and check_params(src, method, older) is None:
        commits = sorted({RENAMED_PARAMS[p.partition("=")[0]][1] for p in pairs if p.partition("=")[0] in RENAMED_PARAMS})
        print(f"note: {label} does not take {' '.join(pairs)} for {method}; passing {' '.join(older)} "
              f"(the names before {', '.join(commits)})", flush=True)
        return older
    raise SystemExit(f"compare.py: {label}: method {method} with {' '.join(pairs) or 'no parameters'}: {error}")


def measure(src: Path, seq: Path, method: str, pairs: list[str], out: Path) -> dict:
    """One `longslam run` of the code under `src`: wall_s, peak_mb, ate_m (and the run's own
    stats.json peak), or failed (its exit status)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    # `-m longslam.cli` runs the command in every revision (`-m longslam` only since the restructure).
    command = [sys.executable, "-m", "longslam.cli", "run", str(seq), "--method", method, "--out", str(out), "--overwrite"]
    for pair in pairs:
        command += ["--param", pair]
    wall, peak_mib, cpu, status = run_process_usage(command, out.with_name(out.name + ".log"), env=side_env(src))
    if status:
        return {"failed": status, "log": str(out.with_name(out.name + ".log"))}
    stats = json.loads((out / "stats.json").read_text())
    return {"wall_s": wall, "cpu_s": cpu, "peak_mb": peak_mib * 2**20 / 1e6, "ate_m": score_files(out / "trajectory.txt", seq)["ate"],
            "stats_peak_rss_mb": stats.get("peak_rss_bytes", 0) / 1e6, "command": shlex.join(command)}


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    work = Path(args.work).resolve()
    work.mkdir(parents=True, exist_ok=True)
    try:  # an unknown name stops here, before anything is made
        parse_key_values(args.params)
        for route in args.routes:
            get_route(route)
        get_noise(args.noise)
    except InputError as err:
        raise SystemExit(f"compare.py: {err}") from None
    sha = git("rev-parse", "--verify", f"{args.rev}^{{commit}}")
    head = git("rev-parse", "--short=7", "HEAD")
    changed = git("status", "--porcelain", "--", "src").splitlines()
    rev_src_root, made = make_worktree(sha, work)
    srcs = {"tree": TREE_SRC, "rev": rev_src_root / "src"}
    labels = {"tree": "the working tree", "rev": args.rev}
    print(f"tree: {ROOT} (HEAD {head}{f', {len(changed)} changed files under src/' if changed else ''})")
    print(f"{args.rev}: {sha[:12]}, worktree {rev_src_root}{' (made now)' if made else ' (reused)'}")
    print(f"interpreter {sys.executable}; {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}", flush=True)
    try:
        for src in srcs.values():  # bytecode up front: a fresh worktree's first run would compile its modules
            subprocess.run([sys.executable, "-m", "compileall", "-q", str(src)], check=True, stdout=subprocess.DEVNULL)
        pairs = {(side, m): side_params(srcs[side], labels[side], m, args.params) for side in SIDES for m in args.methods}
        seqs = []
        for route in args.routes:
            for seed in args.seeds:
                print(f"sequence {route} {args.noise} seed {seed} (simulated by the working tree once) ...", flush=True)
                seqs.append(sequence(work, route, args.noise, seed))
        rows, runs = [], []
        total = len(seqs) * len(args.methods) * args.repeats * len(SIDES)
        done = 0
        tag = "-".join(re.sub(r"[^A-Za-z0-9._=-]", "_", p) for p in args.params)
        for seq in seqs:
            for method in args.methods:
                row = {"sequence": seq.name, "method": method, "params": " ".join(args.params),
                       **{side: {"wall_s": [], "cpu_s": [], "peak_mb": [], "ate_m": []} for side in SIDES}}
                for repeat in range(args.repeats):
                    for side in SIDES:
                        done += 1
                        out = work / "runs" / seq.name / (method + (f"-{tag}" if tag else "")) / f"{side}-{repeat}"
                        figures = measure(srcs[side], seq, method, pairs[side, method], out)
                        runs.append({"sequence": seq.name, "method": method, "params": pairs[side, method],
                                     "side": side, "src": str(srcs[side]), "repeat": repeat, **figures})
                        name = "tree" if side == "tree" else args.rev
                        if "failed" in figures:
                            print(f"[{done}/{total}] {seq.name} {method} {name}: failed (exit {figures['failed']}), "
                                  f"see {figures['log']}", flush=True)
                            continue
                        for key in ("wall_s", "cpu_s", "peak_mb", "ate_m"):
                            row[side][key].append(figures[key])
                        print(f"[{done}/{total}] {seq.name} {method} {name} (run {repeat + 1}/{args.repeats}): "
                              f"{figures['wall_s']:.1f} s (CPU {figures['cpu_s']:.1f} s), {figures['peak_mb']:.0f} MB, ATE {figures['ate_m']:.4f} m",
                              flush=True)
                rows.append(row)
        print(f"\nload average at the end {os.getloadavg()[0]:.2f}\n")
        print("\n".join(format_table(rows, args.rev)))
        (work / "compare.json").write_text(json.dumps({"rev": args.rev, "rev_sha": sha, "tree_head": head,
                                                       "tree_changed_src_files": changed, "runs": runs}, indent=1) + "\n")
        print(f"\nwrote {work / 'compare.json'}")
    finally:
        if args.keep:
            print(f"kept {rev_src_root}")
        else:
            git("worktree", "remove", "--force", str(rev_src_root))


if __name__ == "__main__":
    main()
