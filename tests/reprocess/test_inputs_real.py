"""Real input end to end (issue 14 acceptance): every NGSIM obstacle of the shipped CommonRoad
scenarios as the TO (with its follower as the EGO), and the A9 recording's lane changer.

``--object all`` reprocesses every obstacle and reports each one that fails, with the stage and
the reason, instead of aborting. Every obstacle must reprocess, the shortest (3 states, 0.2 s)
included: the robust fit needs 2 samples.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from asam_qc import assert_accepted, quality_check
from simcred import data
from simcred.cli import run
from simcred.reprocess.ad_function import RECORDED_PARAMETERS
from simcred.reprocess.inputs import NOT_DRIVEN
from simcred.reprocess.obstacles import reprocess_obstacles
from simcred.reprocess.pipeline import ReprocessConfig
from simcred.scenario.fit import MIN_SAMPLES

DATA = Path(__file__).parents[1] / "data" / "commonroad-ngsim"
SCENARIOS = sorted(DATA.glob("*.xml"))


MORE = sorted((DATA.parent / "commonroad-crime-ngsim").glob("*.xml"))  # Lankershim, US-101
MONA = sorted((DATA.parent / "commonroad-mona").glob("*.xml"))  # Munich: trucks, on-ramp merge


RESULTS: dict = {}  # (scenario, obstacle) -> Reprocessed, filled by the outcomes fixture
STATED_DISTANCE = 8.0  # m: the resimulated EGO stays this close to a recorded one not reacting


def _reprocess_every_obstacle(paths, results: dict) -> dict:
    """Every obstacle of every scenario in the lanelet frame, with the AD function's set speed,
    lanes and time gap from the recorded EGO (as the CLI does), pipeline only (figures: see the
    CLI test); the results go into ``results``, the outcomes are returned."""
    found = {}
    config = ReprocessConfig(from_recording=RECORDED_PARAMETERS)
    for path in paths:
        def keep(result, out, stem=path.stem):
            results[(stem, int(Path(out).name[3:]))] = result

        batch = reprocess_obstacles(path, config, "unused", keep, frame="lanelet")
        found.update({(path.stem, o.obstacle): o for o in batch.outcomes})
    return found


def _footprint(shape) -> tuple[float, float]:
    return ((shape.length, shape.width) if hasattr(shape, "length")
            else (2 * shape.radius, 2 * shape.radius))


def _assert_acceptance(results: dict, paths) -> list[float]:
    """Issue 24 acceptance for every reprocessed obstacle: map-based geometry, the recorded
    footprints of TO and EGO in every description, no pedestrian or bicycle driven by the ACC,
    no reaction within 0.5 s of the first sample unless flagged not measurable; returns the
    largest distance of the resimulated EGO from the recorded one, per obstacle whose recorded
    EGO does not react (each asserted below :data:`STATED_DISTANCE`)."""
    from simcred.io.commonroad import _open  # commonroad-io's own obstacles, not our metadata

    shapes = {(path.stem, o.obstacle_id): _footprint(o.obstacle_shape)
              for path in paths for o in _open(path).dynamic_obstacles}
    distances = []
    for (stem, obstacle), result in results.items():
        drive = result.input_report["drive"]
        assert drive["frame"]["lanelets"]  # map-based geometry
        assert drive["objects"]["ego"]["type"] not in NOT_DRIVEN  # the ACC drives a vehicle
        for role, number in (("to", obstacle), ("ego", drive["ego"])):
            for description in result.descriptions.values():
                track = description.objects[role]
                assert (track.length, track.width) == shapes[(stem, number)]
        for reaction in result.reactions.values():  # none at the first samples unless flagged
            t0 = result.descriptions["fit(SD)"].t0
            assert reaction.measurable or reaction.time - t0 < 0.5
            assert not reaction.measurable or not reaction.time - t0 < 0.5
        if result.reactions["SD"].manoeuvre == "none":
            recorded, resimulated = result.states["SD"]["ego"], result.states["rSD"]["ego"]
            distance = np.hypot(resimulated.x - recorded.x, resimulated.y - recorded.y)
            assert distance.max() < STATED_DISTANCE, (stem, obstacle, distance.max())
            distances.append(float(distance.max()))
    return distances


@pytest.fixture(scope="module")
def outcomes():
    return _reprocess_every_obstacle(SCENARIOS, RESULTS)


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
def test_every_ngsim_obstacle_keeps_its_shape_its_egos_speed_and_honest_reactions(outcomes):
    """Issue 24 acceptance on the shipped NGSIM scenarios (all cars)."""
    distances = _assert_acceptance(RESULTS, SCENARIOS)
    assert len(RESULTS) == 67 and len(distances) >= 10  # 13 recorded EGOs do not react


@pytest.mark.slow
def test_more_real_scenarios_reprocess_every_obstacle_with_the_acceptance():
    """Issue 24 acceptance on two further real NGSIM scenes (commonroad-crime): an urban
    intersection tile with merging/splitting and turning lanelets (Lankershim) and freeway
    stop-and-go (US-101). Measured: 61/61 obstacles; 19 recorded EGOs do not react, the
    resimulated EGO within 1.64 m of them (max; median 0.01 m: 9 of them stand at a
    signal, and so does their resimulation; 2.75 m with the ACC's configured 1.5 s)."""
    results: dict = {}
    found = _reprocess_every_obstacle(MORE, results)
    assert {p.stem for p in MORE} == {"USA_Lanker-1_3_T-1", "USA_US101-5_1_T-1"}
    assert len(found) == 61 and not {k: o.reason for k, o in found.items() if o.status != "ok"}
    distances = _assert_acceptance(results, MORE)
    assert len(distances) >= 15 and max(distances) < 2.0


@pytest.mark.slow
def test_mona_scenes_with_trucks_and_a_merge_reprocess_every_obstacle_with_the_acceptance():
    """Issue 24 acceptance on three real MONA scenes (Munich; tests/data/commonroad-mona):
    an on-ramp merge (49 cars, 2 trucks, 0.4-7.2 s each), a 16 s window of an urban arterial
    where 3 vehicles turn by 0.3-0.9 rad (28 cars, 3 trucks, a 13 m bus, 2 motorcycles) and a
    1 s excerpt of another with 10 trucks of 5.8-14.3 m. Measured: 130/130 obstacles reprocess
    in the lanelet frame; every truck and the bus is the TO, and some the EGO, with their
    recorded footprints; these files have no pedestrians or bicycles (a motorcycle can be the ACC's
    EGO: NOT_DRIVEN names pedestrians and bicycles only). 66 recorded EGOs do not react; the
    resimulated EGO stays within 0.82 m of them on the 1 s excerpt, 2.91 m on the 16 s window
    and 3.43 m on the merge. (With the ACC's configured 1.5 s time gap instead of the recorded
    EGO's, two merge EGOs that follow at 0.7-1.2 s centre headway were left 8.8 m and 9.1 m
    behind, beyond the stated 8 m; docs/reprocess.md.)"""
    from simcred.io.commonroad import _open

    results: dict = {}
    found = _reprocess_every_obstacle(MONA, results)
    merge, west, east = ("C-DEU_MONAMerge-2_1_T-299", "C-DEU_MONAWest-2_480_T-559",
                         "DEU_MONAEast-2_4316_T-4341")
    assert {p.stem for p in MONA} == {merge, west, east}
    assert len(found) == 130 and not {k: o.reason for k, o in found.items() if o.status != "ok"}
    types = {(p.stem, o.obstacle_id): o.obstacle_type.value
             for p in MONA for o in _open(p).dynamic_obstacles}
    heavy = {key for key, kind in types.items() if kind in ("truck", "bus")}
    assert len(heavy) == 16 and heavy <= set(results)  # every truck and the bus as the TO
    egos = {key: (key[0], r.input_report["drive"]["ego"]) for key, r in results.items()}
    assert len({ego for ego in egos.values() if ego in heavy}) >= 5  # ... and as the EGO
    assert {types[ego] for ego in egos.values()} <= {"car", "truck", "bus", "motorcycle"}
    distances = _assert_acceptance(results, MONA)
    assert len(distances) >= 60
    per_scene: dict = {}
    for (stem, _), r in results.items():
        if r.reactions["SD"].manoeuvre == "none":
            recorded, resimulated = r.states["SD"]["ego"], r.states["rSD"]["ego"]
            per_scene.setdefault(stem, []).append(float(np.hypot(
                resimulated.x - recorded.x, resimulated.y - recorded.y).max()))
    assert max(per_scene[east]) < 1.0 and max(per_scene[west]) < 3.0
    assert max(per_scene[merge]) < 4.0
    assert all(results[key].ad_function["time_gap"] < 1.0 for key in ((merge, 10044),
                                                                      (merge, 10053)))


LOCAL = os.environ.get("SIMCRED_REAL_COMMONROAD")  # a folder of recorded scenes not shipped


@pytest.mark.slow
@pytest.mark.skipif(not LOCAL, reason="SIMCRED_REAL_COMMONROAD names no folder of scenarios")
def test_local_recorded_scenarios_meet_the_acceptance_or_are_refused_in_one_line():
    """Recorded scenes whose licence keeps them out of the repository (highD, exiD, inD, SinD,
    INTERACTION conversions; docs/reprocess.md): every obstacle either reprocesses and meets the
    acceptance or is refused by an input check in one line, never an internal error."""
    paths = sorted(Path(LOCAL).glob("*.xml"))
    assert paths, f"{LOCAL}: no .xml scenario"
    results: dict = {}
    found = _reprocess_every_obstacle(paths, results)
    for key, outcome in found.items():
        assert outcome.status == "ok" or not outcome.reason.startswith("internal error"), \
            (key, outcome.reason)
    _assert_acceptance(results, paths)


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
    for outcome in summary["outcomes"]:  # a reaction at the start is named as not measurable
        reactions = json.loads((out / outcome["directory"] / "reaction.json").read_text())
        assert sorted(outcome["reactions_not_measurable"]) == sorted(
            k for k, r in reactions["reactions"].items() if r["measurable"] is False)
    assert (out / first["directory"] / "figures" / "fig7_velocity_risk.png").is_file()


def test_cli_reprocesses_the_a9_lane_changer_with_figures(tmp_path):
    out = tmp_path / "a9"
    path = data.path("a9/trajectories_file.csv")
    assert run(["--quiet", "reprocess", str(path), "--threshold", "0.1", "--out", str(out)]) == 0
    summary = json.loads((out / "reprocess.json").read_text())
    assert summary["input"]["drive"]["object"] == 1
    assert summary["input"]["gaps"] == [] and summary["input"]["time_base"] == "SD"
    assert (out / "figures" / "fig3_fit.png").is_file()
    # issue 24: every real scene's .xosc passes the ASAM Quality Checker (no map: no road file)
    assert_accepted(quality_check(out / "scenario.xosc", tmp_path), road=False)
