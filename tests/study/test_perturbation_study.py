"""Perturbations end to end on a short route with a small camera: a study with a perturbations
axis runs each perturbation on the fly from one render, records it in the database and the run's
stats, and reports it; its runs see the frames `simulate --perturb` writes. Slow: it renders a
route and runs a study."""

from __future__ import annotations

import json
import sqlite3

import pytest
from helpers.studies import ROUTE, write_study

from longslam.io.sequence import SequenceReader
from longslam.sim.simulate import simulate
from longslam.sim.camera import CameraSettings
from longslam.core.odometry_noise import get_noise
from longslam.sim.perturbations import parse_perturbations
from longslam.sim.routes import Route
from longslam.study.config import load_study
from longslam.study.database import DB_NAME
from longslam.study.driver import run_study

pytestmark = pytest.mark.slow  # renders routes and runs a study over perturbations


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    root = tmp_path_factory.mktemp("perturbation-cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("LONGSLAM_CACHE", str(root / "cache"))
        yield root


def test_a_study_with_a_perturbations_axis_runs_records_and_reports_each(cache):
    (cache / "tiny.txt").write_text(ROUTE)
    study = write_study(cache, "perturbation-axis", ["odometry", "keyframe"], ["large"], [0],
                        'perturbations = ["none", "drop=0.5", "depth-dropout=1+blur=0.05"]')
    out = cache / "study-out"
    summary = run_study(load_study(study), out, jobs=1, progress=False)
    assert summary.failed == 0 and summary.ran == 6
    with sqlite3.connect(out / DB_NAME) as conn:
        rows = {key: (p, frames) for key, p, frames in conn.execute("SELECT key, perturbation, frames FROM runs")}
    entries = ("none", "drop=0.5", "depth-dropout=1+blur=0.05")
    assert set(rows) == {f"tiny/{p}/large/{m}/seed-0" for p in entries for m in ("odometry", "keyframe")}
    assert rows["tiny/drop=0.5/large/keyframe/seed-0"][0] == "drop=0.5"
    # Half the frames reach the method; the images' perturbations drop none.
    none, dropped = rows["tiny/none/large/odometry/seed-0"][1], rows["tiny/drop=0.5/large/odometry/seed-0"][1]
    assert 0.3 * none < dropped < 0.7 * none
    assert rows["tiny/depth-dropout=1+blur=0.05/large/odometry/seed-0"][1] == none
    run = out / "runs" / "tiny" / "drop=0.5" / "large" / "keyframe" / "seed-0"
    assert json.loads((run / "stats.json").read_text())["perturbation"] == "drop=0.5"
    # The study's run saw the frames `simulate --perturb` writes: the same timestamps.
    written = simulate(Route("tiny", "university", ((20.0, 31.25), (28.0, 31.25))), get_noise("large"), 0,
                       cache / "simulated", camera=CameraSettings(width=64, height=48), progress=False,
                       perturbations=parse_perturbations(["drop=0.5"]))
    assert len(SequenceReader(written)) == dropped
    report = (out / "report.md").read_text()
    assert "| method | perturbation | metric |" in report and "| drop=0.5 |" in report
    assert "perturbations none, drop=0.5, depth-dropout=1+blur=0.05" in report
