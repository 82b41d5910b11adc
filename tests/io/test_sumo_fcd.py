"""SUMO FCD XML: what the reader gives equals SUMO's own numbers of the same run (libsumo)."""

from __future__ import annotations

import gzip
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from simcred.errors import SimcredError
from simcred.io import read

sumo = pytest.importorskip("sumo")
libsumo = pytest.importorskip("libsumo")
BIN = Path(sumo.SUMO_HOME) / "bin"
STEP, END, PRECISION = 0.1, 8.0, 6

NODES = '<nodes><node id="A" x="0" y="0"/><node id="B" x="400" y="0"/></nodes>'
EDGES = '<edges><edge id="AB" from="A" to="B" numLanes="1" speed="30"/></edges>'
# two vehicles on a straight road; "7" (an integer id) enters later and follows "lead"
ROUTES = """<routes>
  <vType id="car" accel="2.6" decel="4.5" sigma="0.5" length="5" minGap="2.5" maxSpeed="30"/>
  <route id="r" edges="AB"/>
  <vehicle id="lead" type="car" route="r" depart="0" departSpeed="10" departPos="30"/>
  <vehicle id="7" type="car" route="r" depart="0.5" departSpeed="12" departPos="0"/>
</routes>"""


@pytest.fixture(scope="module")
def sumo_run(tmp_path_factory):
    """Run SUMO once: the FCD file it writes, and its own numbers read with libsumo per step."""
    d = tmp_path_factory.mktemp("sumo")
    (d / "n.nod.xml").write_text(NODES)
    (d / "e.edg.xml").write_text(EDGES)
    (d / "r.rou.xml").write_text(ROUTES)
    env = {**os.environ, "SUMO_HOME": sumo.SUMO_HOME}
    subprocess.run([BIN / "netconvert", "-n", d / "n.nod.xml", "-e", d / "e.edg.xml", "-o",
                    d / "net.net.xml", "--no-warnings"], check=True, capture_output=True, env=env)
    fcd = d / "fcd.xml"
    libsumo.start([str(BIN / "sumo"), "-n", str(d / "net.net.xml"), "-r", str(d / "r.rou.xml"),
                   "--fcd-output", str(fcd), "--fcd-output.acceleration", "--precision",
                   str(PRECISION), "--step-length", str(STEP), "--end", str(END), "--seed", "1",
                   "--no-step-log", "--no-warnings"])
    own: dict[str, dict[str, list[float]]] = {}
    try:
        while libsumo.simulation.getTime() < END - STEP / 2:
            t = libsumo.simulation.getTime()  # FCD labels a step with the time it started at
            libsumo.simulationStep()
            for v in libsumo.vehicle.getIDList():
                x, y = libsumo.vehicle.getPosition(v)
                values = {"t": t, "x": x, "y": y, "speed": libsumo.vehicle.getSpeed(v),
                          "angle": libsumo.vehicle.getAngle(v),
                          "acceleration": libsumo.vehicle.getAcceleration(v),
                          "pos": libsumo.vehicle.getLanePosition(v)}
                run = own.setdefault(v, {k: [] for k in values})
                for k, value in values.items():
                    run[k].append(value)
    finally:
        libsumo.close()
    return fcd, own


def test_fcd_read_equals_sumos_own_numbers(sumo_run):
    fcd, own = sumo_run
    traces = read(fcd)
    assert traces.run_ids == ("lead", "obj7")
    assert traces.lengths.tolist() == [80, 75]  # 8 s at 0.1 s; "7" departs at 0.5 s
    assert set(traces.metadata["skipped_attributes"]) == {"type", "lane"}
    tolerance = 0.5 * 10.0**-PRECISION + 1e-12  # SUMO prints PRECISION digits after the point
    for i, vehicle in enumerate(("lead", "7")):
        run, expected = traces.run(i), own[vehicle]
        assert len(run["t"]) == len(expected["t"]) > 20
        np.testing.assert_allclose(run["t"], expected["t"], rtol=0, atol=1e-9)
        for name in ("x", "y", "speed", "angle", "acceleration", "pos"):
            worst = np.max(np.abs(run[name] - np.asarray(expected[name])))
            assert worst <= tolerance, (vehicle, name, worst)


def test_fcd_as_one_run_with_vehicle_signals(sumo_run):
    fcd, own = sumo_run
    with pytest.raises(SimcredError, match="object 'obj7': no record at t=0.0"):
        read(fcd, objects_as="signals")
    both = read(fcd, objects_as="signals", missing="intersect")
    assert both.run_ids == ("fcd",)
    assert both.time[0] == pytest.approx(0.5)  # "7" departs at 0.5 s
    per_vehicle = read(fcd)
    assert both.column("obj7.x").tolist() == per_vehicle.run(1)["x"].tolist()
    gap = both.column("lead.pos") - both.column("obj7.pos")
    assert np.all(gap > 5.0)  # the follower never reaches the leader's rear (length 5 m)


def test_gzipped_fcd_and_the_facade_dispatch(sumo_run, tmp_path):
    fcd, _ = sumo_run
    packed = tmp_path / "fcd.xml.gz"
    packed.write_bytes(gzip.compress(fcd.read_bytes()))
    assert read(packed).equals(read(fcd))


def test_hostile_and_malformed_fcd_are_one_line(tmp_path):
    bomb = tmp_path / "bomb.xml"
    bomb.write_text('<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol">'
                    '<!ENTITY lol2 "&lol;&lol;&lol;&lol;">]><fcd-export><timestep time="0">'
                    '<vehicle id="a" x="&lol2;"/></timestep></fcd-export>')
    cut = tmp_path / "cut.xml"
    cut.write_text('<fcd-export><timestep time="0"><vehicle id="a" x="1"/></timestep>'
                   '<timestep time="0.1"><vehicle id="a" x="2"')
    clock = tmp_path / "clock.xml"
    clock.write_text('<fcd-export><timestep time="00:00:01"><vehicle id="a" x="1"/>'
                     '</timestep></fcd-export>')
    nan = tmp_path / "nan.xml"
    nan.write_text('<fcd-export><timestep time="0"><vehicle id="a" x="1"/></timestep>'
                   '<timestep time="0.1"><vehicle id="a" x="nan"/></timestep></fcd-export>')
    once = tmp_path / "once.xml"
    once.write_text('<fcd-export><timestep time="0"><vehicle id="a" x="1"/></timestep>'
                    '</fcd-export>')
    for path, expected in ((bomb, "unreadable XML"), (cut, "unreadable XML"),
                           (clock, "human-readable-time"), (nan, "record 2"),
                           (once, "no run has two time steps")):
        with pytest.raises(SimcredError) as info:
            read(path)
        assert expected in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_a_vehicle_seen_once_is_listed_not_a_run(tmp_path):
    path = tmp_path / "f.xml"
    path.write_text('<fcd-export><timestep time="0"><vehicle id="a" x="1" lane="L"/>'
                    '<vehicle id="b" x="9"/></timestep><timestep time="0.1">'
                    '<vehicle id="a" x="2" lane="L"/></timestep></fcd-export>')
    traces = read(path)
    assert traces.run_ids == ("a",) and traces.column("x").tolist() == [1.0, 2.0]
    assert traces.metadata["runs_too_short"] == ["b"]


def test_fcd_exported_to_csv_by_sumos_xml2csv_reads_the_same(sumo_run, tmp_path):
    # SUMO's own converter (tools/xml/xml2csv.py) writes the long format the CSV reader takes
    fcd, _ = sumo_run
    csv = tmp_path / "fcd.csv"
    tool = Path(sumo.SUMO_HOME) / "tools" / "xml" / "xml2csv.py"
    subprocess.run([sys.executable, tool, fcd, "-s", ",", "-o", csv], check=True,
                   capture_output=True, env={**os.environ, "SUMO_HOME": sumo.SUMO_HOME})
    long = read(csv, time_column="timestep_time", object_column="vehicle_id", objects_as="runs")
    xml = read(fcd)
    assert long.run_ids == xml.run_ids
    assert set(long.metadata["skipped_columns"]) == {"vehicle_lane", "vehicle_type"}
    assert long.time.tolist() == xml.time.tolist()
    for name in xml.signals:
        assert long.column(f"vehicle_{name}").tolist() == xml.column(name).tolist()
