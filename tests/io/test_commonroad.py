"""CommonRoad reader on the real NGSIM scenarios: states exactly as commonroad-io and the XML."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from commonroad.common.file_reader import CommonRoadFileReader

from simcred.errors import SimcredError
from simcred.io import read
from simcred.io.commonroad import obstacle_states

DATA = Path(__file__).parent.parent / "data" / "commonroad-ngsim"
FILES = sorted(DATA.glob("*.xml"))
# dynamic obstacles and states per file, counted from the XML with grep (see the README)
SIZES = {"USA_Lanker-1_1_T-1": (24, 938), "USA_Peach-4_8_T-1": (9, 368),
         "USA_US101-3_3_T-1": (12, 384), "USA_US101-4_1_T-1": (22, 1271)}


def raw_obstacles(path: Path) -> dict[str, dict[str, list[float]]]:
    """Independent oracle: the numbers of every dynamic obstacle, straight from the XML text."""
    out = {}
    root = ET.parse(path).getroot()
    # 2018b: <obstacle><role>dynamic</role>...; 2020a: <dynamicObstacle>
    dynamic = [o for o in root.iter("obstacle") if o.findtext("role") == "dynamic"]
    for obstacle in dynamic + list(root.iter("dynamicObstacle")):
        states = [obstacle.find("initialState"), *obstacle.find("trajectory").iter("state")]
        run = {k: [] for k in ("step", "x", "y", "heading", "v", "acceleration")}
        for state in states:
            run["step"].append(float(state.findtext("time/exact")))
            run["x"].append(float(state.findtext("position/point/x")))
            run["y"].append(float(state.findtext("position/point/y")))
            run["heading"].append(float(state.findtext("orientation/exact")))
            run["v"].append(float(state.findtext("velocity/exact")))
            acceleration = state.findtext("acceleration/exact")
            if acceleration is not None:
                run["acceleration"].append(float(acceleration))
        out[f"obj{obstacle.get('id')}"] = run
    return out


def test_the_data_ships_with_its_licence():
    assert len(FILES) == 4
    assert "BSD 3-Clause" in (DATA / "LICENSE.txt").read_text()
    assert "NGSIM" in (DATA / "README.md").read_text()


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_states_equal_commonroad_io_objects(path):
    traces = read(path)
    scenario, _ = CommonRoadFileReader(str(path)).open()
    dt = scenario.dt
    assert (traces.n_runs, traces.n_rows) == SIZES[path.stem]
    assert traces.run_ids == tuple(f"obj{o.obstacle_id}" for o in scenario.dynamic_obstacles)
    for i, obstacle in enumerate(scenario.dynamic_obstacles):
        states = obstacle_states(obstacle)
        run = traces.run(i)
        assert run["t"].tolist() == [s.time_step * dt for s in states]
        assert run["x"].tolist() == [s.position[0] for s in states]
        assert run["y"].tolist() == [s.position[1] for s in states]
        assert run["heading"].tolist() == [s.orientation for s in states]
        assert run["v"].tolist() == [s.velocity for s in states]
        if "acceleration" in traces.signals:
            assert run["acceleration"].tolist() == [s.acceleration for s in states]


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_states_equal_the_numbers_in_the_xml(path):
    traces = read(path)
    raw = raw_obstacles(path)
    assert list(raw) == list(traces.run_ids)
    for i, rid in enumerate(traces.run_ids):
        run, expected = traces.run(i), raw[rid]
        assert run["t"].tolist() == [k * 0.1 for k in expected["step"]]
        for name in ("x", "y", "heading", "v"):
            assert run[name].tolist() == expected[name], (rid, name)
        # acceleration is a signal exactly when the XML gives it in every state
        has = len(expected["acceleration"]) == len(expected["x"])
        assert ("acceleration" in traces.signals) == has
        if has:
            assert run["acceleration"].tolist() == expected["acceleration"]


def test_lane_change_of_obstacle_394_is_visible():
    # the README: obstacle 394 of US101-3_3 changes lanes; its lateral offset to the road's
    # heading moves by about a lane width, the other obstacles' by much less
    traces = read(DATA / "USA_US101-3_3_T-1.xml")
    shifts = {}
    for i, rid in enumerate(traces.run_ids):
        run = traces.run(i)
        heading = np.median(traces.column("heading"))
        normal = np.array([-np.sin(heading), np.cos(heading)])
        lateral = run["x"] * normal[0] + run["y"] * normal[1]
        shifts[rid] = abs(lateral[-1] - lateral[0])
    assert max(shifts, key=shifts.get) == "obj394"
    assert shifts["obj394"] > 2.0


def test_scenario_layout_is_one_run_with_object_signals():
    path = DATA / "USA_US101-3_3_T-1.xml"
    per_obstacle = read(path)
    scenario = read(path, layout="scenario")
    assert scenario.run_ids == ("USA_US101-3_3_T-1",) and scenario.n_rows == 32
    for i, rid in enumerate(per_obstacle.run_ids):
        assert scenario.column(f"{rid}.x").tolist() == per_obstacle.run(i)["x"].tolist()
    # obstacles enter and leave in Lankershim: the documented missing-row rule applies
    lanker = DATA / "USA_Lanker-1_1_T-1.xml"
    with pytest.raises(SimcredError, match="object 'obj1230': no state at t=0.9"):
        read(lanker, layout="scenario")
    kept = read(lanker, layout="scenario", missing="intersect")
    assert kept.n_rows == 9 and kept.metadata["rows_dropped_by_intersect"] == 938 - 24 * 9


def test_bad_files_are_one_line(tmp_path):
    broken = tmp_path / "broken.xml"
    broken.write_text('<commonRoad timeStepSize="0.1"><obstacle id="1"><role>dynamic</role>')
    for path, expected in ((broken, "unreadable CommonRoad scenario"),):
        with pytest.raises(SimcredError) as info:
            read(path)
        assert expected in str(info.value) and "\n" not in str(info.value)
    uncertain = tmp_path / "uncertain.xml"
    text = (DATA / "USA_US101-3_3_T-1.xml").read_text()
    first = text.index("<velocity>", text.index("<trajectory>"))
    end = text.index("</velocity>", first)
    uncertain.write_text(text[:first] + "<velocity><intervalStart>1.0</intervalStart>"
                         "<intervalEnd>2.0</intervalEnd>" + text[end:])
    with pytest.raises(SimcredError, match="obstacle 363, state 1") as info:
        read(uncertain)
    assert "\n" not in str(info.value)
    with pytest.raises(SimcredError, match="layout must be one of"):
        read(DATA / "USA_US101-3_3_T-1.xml", layout="lanes")
