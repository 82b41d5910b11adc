"""Real input end to end (issue 14 acceptance): every NGSIM obstacle of the shipped CommonRoad
scenarios as the TO (with its follower as the EGO), and the A9 recording's lane changer.

``--object all`` reprocesses every obstacle and reports each one that fails, with the stage and
the reason, instead of aborting. Every obstacle must reprocess, the shortest (3 states, 0.2 s)
included: the robust fit needs 2 samples.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from simcred import data
from simcred.cli import run
from simcred.reprocess.obstacles import reprocess_obstacles
from simcred.reprocess.pipeline import ReprocessConfig
from simcred.scenario.fit import MIN_SAMPLES

DATA = Path(__file__).parents[1] / "data" / "commonroad-ngsim"
SCENARIOS = sorted(DATA.glob("*.xml"))


@pytest.fixture(scope="module")
def outcomes():
    """Every obstacle of every scenario, pipeline only (figures: see the CLI test)."""
    found = {}
    for path in SCENARIOS:
        batch = reprocess_obstacles(path, ReprocessConfig(), "unused", lambda result, out: None)
        found.update({(path.stem, o.obstacle): o for o in batch.outcomes})
    return found


@pytest.mark.slow
def test_every_ngsim_obstacle_gets_an_ego_and_a_reported_outcome(outcomes):
    assert len(outcomes) == 67  # docs/formats.md: 67 obstacles with a trajectory
    for key, outcome in outcomes.items():
        assert outcome.status in ("ok", "failed"), key
        if outcome.status == "ok":
            assert outcome.summary["ego"] != key[1]
            assert outcome.summary["samples"] >= MIN_SAMPLES
        else:  # reported, one line, by a step that raised a SimcredError
            assert outcome.stage == "pipeline", (key, outcome.stage, outcome.reason)
            assert outcome.reason and "\n" not in outcome.reason
            assert not outcome.reason.startswith("internal error"), (key, outcome.reason)


@pytest.mark.slow
def test_every_ngsim_obstacle_reprocesses(outcomes):
    failed = {key: o.reason for key, o in outcomes.items() if o.status != "ok"}
    assert not failed
    assert ("USA_Peach-4_8_T-1", 507) in outcomes  # the shortest: 3 states


@pytest.mark.slow
def test_cli_reprocesses_every_obstacle_of_a_scenario_and_writes_a_summary(tmp_path):
    path = DATA / "USA_US101-3_3_T-1.xml"
    out = tmp_path / "all"
    assert run(["--quiet", "reprocess", str(path), "--object", "all", "--out", str(out)]) == 0
    summary = json.loads((out / "reprocess_all.json").read_text())
    assert summary["obstacles"] == 12 and summary["reprocessed"] == 12
    assert summary["kind"] == "reprocess_all"
    first = summary["outcomes"][0]
    assert (out / first["directory"] / "reprocess.json").is_file()
    assert (out / first["directory"] / "figures" / "fig7_velocity_risk.png").is_file()


def test_cli_reprocesses_the_a9_lane_changer_with_figures(tmp_path):
    out = tmp_path / "a9"
    path = data.path("a9/trajectories_file.csv")
    assert run(["--quiet", "reprocess", str(path), "--threshold", "0.1", "--out", str(out)]) == 0
    summary = json.loads((out / "reprocess.json").read_text())
    assert summary["input"]["drive"]["object"] == 1
    assert summary["input"]["gaps"] == [] and summary["input"]["time_base"] == "SD"
    assert (out / "figures" / "fig3_fit.png").is_file()
