"""ASAM OSI traces: betterosi-written traces read as expected; TraceSet -> OSI -> TraceSet."""

from __future__ import annotations

import tempfile
import warnings
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simcred.errors import SimcredError
from simcred.io import read, write
from simcred.io.osi import FIELDS
from simcred.traces import TraceSet

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    import betterosi as b

VERSION = b.InterfaceVersion(version_major=3, version_minor=8, version_patch=0)


def readme_trace(path: Path, frames: int = 200) -> None:
    """The trace of betterosi's README: object 42 moves 0.5 m per 10 ms frame, vx = 1."""
    moving = b.MovingObject(id=b.Identifier(value=42), base=b.BaseMoving(
        dimension=b.Dimension3d(length=5, width=2, height=1),
        position=b.Vector3d(x=0, y=0, z=0),
        orientation=b.Orientation3d(roll=0.0, pitch=0.0, yaw=0.0),
        velocity=b.Vector3d(x=1, y=0, z=0)))
    gt = b.GroundTruth(version=VERSION, timestamp=b.Timestamp(seconds=0, nanos=0),
                       moving_object=[moving], host_vehicle_id=b.Identifier(value=42))
    view = b.SensorView(version=VERSION, timestamp=b.Timestamp(seconds=0, nanos=0),
                        global_ground_truth=gt, host_vehicle_id=b.Identifier(value=42))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with b.Writer(str(path)) as writer:
            for i in range(frames):
                total = i * 10_000_000
                gt.timestamp = b.Timestamp(seconds=total // 10**9, nanos=total % 10**9)
                moving.base.position.x += 0.5
                view.timestamp = gt.timestamp
                writer.add(view if "sv" in path.name else gt)


@pytest.mark.parametrize("name", ["trace_gt.osi", "trace.mcap", "trace_sv.osi", "trace_sv.mcap"])
def test_betterosi_written_trace_reads_as_written(tmp_path, name):
    readme_trace(tmp_path / name)
    traces = read(tmp_path / name)
    assert traces.n_runs == 1 and traces.n_rows == 200
    steps = np.arange(200)
    assert traces.time.tolist() == [float(Fraction(int(k) * 10_000_000, 10**9)) for k in steps]
    assert traces.column("obj42.x").tolist() == (0.5 * (steps + 1)).tolist()
    assert traces.column("obj42.vx").tolist() == [1.0] * 200
    assert traces.column("obj42.length").tolist() == [5.0] * 200
    assert set(traces.signals) == {f"obj42.{f}" for f in (
        "x", "y", "z", "roll", "pitch", "yaw", "vx", "vy", "vz", "length", "width", "height")}
    assert list(traces.metadata["host_vehicles"].values()) == ["obj42"]


def test_written_trace_holds_the_numbers_for_betterosi(tmp_path):
    ts = TraceSet.from_runs([{"t": [0.0, 0.25], "ego.x": [1.5, 2.5], "ego.yaw": [0.1, -0.0],
                              "obj3.vy": [7.0, 8.0]}], run_ids=["drive"])
    path = write(ts, tmp_path / "drive.mcap")
    frames = list(b.read(str(path), return_ground_truth=True))
    assert [(f.timestamp.seconds, f.timestamp.nanos) for f in frames] == [(0, 0), (0, 250000000)]
    ego = {o.id.value: o for o in frames[1].moving_object}
    assert frames[1].host_vehicle_id.value == 4  # "ego" gets the first free id after obj3
    assert ego[4].base.position.x == 2.5 and np.signbit(ego[4].base.orientation.yaw)
    assert ego[3].base.velocity.y == 8.0 and not ego[3].base.has_field("position")


FLOATS = st.floats(allow_nan=False, allow_infinity=False, width=64)
TIMES = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)


@st.composite
def osi_tracesets(draw, *, names: bool, runs: int):
    objects = draw(st.lists(st.sampled_from(["obj1", "obj7", "obj300"] + (
        ["ego", "lead"] if names else [])), min_size=1, max_size=3, unique=True))
    signals = [f"{o}.{f}" for o in objects
               for f in draw(st.lists(st.sampled_from(list(FIELDS)), min_size=1, max_size=4,
                                      unique=True))]
    out = []
    for _ in range(runs):
        steps = draw(st.integers(2, 6))
        # at least 1 µs apart: distinct after rounding to whole nanoseconds
        t = sorted(draw(st.lists(st.integers(-10**12, 10**12), min_size=steps, max_size=steps,
                                 unique=True)))
        run = {"t": [k * 1e-6 for k in t]}
        run.update({s: draw(st.lists(FLOATS, min_size=steps, max_size=steps)) for s in signals})
        out.append(run)
    return TraceSet.from_runs(out, run_ids=[f"run{k}" for k in range(runs)],
                              metadata={"model": "hypothesis"})


def assert_round_trip(back: TraceSet, original: TraceSet, *, metadata: bool) -> None:
    assert back.run_ids == original.run_ids
    assert set(back.signals) == set(original.signals)
    assert back.features(original.signals).tobytes() == original.values.tobytes()  # doubles
    # times: whole nanoseconds, so within 0.5 ns (plus the float's own rounding)
    slack = 0.5e-9 + np.spacing(np.abs(original.time)) * 2
    assert np.all(np.abs(back.time - original.time) <= slack)
    if metadata:
        extra = {"format", "host_vehicles"}
        assert {k: v for k, v in back.metadata.items() if k not in extra} == \
            dict(original.metadata)


@settings(max_examples=25, deadline=None)
@given(osi_tracesets(names=True, runs=2))
def test_mcap_round_trip(original):
    with tempfile.TemporaryDirectory() as tmp:
        back = read(write(original, Path(tmp) / "set.mcap"))
    assert_round_trip(back, original, metadata=True)


@settings(max_examples=25, deadline=None)
@given(osi_tracesets(names=False, runs=1))
def test_osi_round_trip(original):
    with tempfile.TemporaryDirectory() as tmp:
        back = read(write(original, Path(tmp) / "run0.osi"))  # an .osi run is named by its file
    assert_round_trip(back, original, metadata=False)


def test_same_trace_set_gives_byte_identical_files(tmp_path):
    ts = TraceSet.from_runs([{"t": [0, 1], "ego.x": [0, 1]}])
    for suffix in (".mcap", ".osi"):
        if suffix == ".osi":
            ts = TraceSet.from_runs([{"t": [0, 1], "obj1.x": [0, 1]}])
        a, c = write(ts, tmp_path / f"a{suffix}"), write(ts, tmp_path / f"c{suffix}")
        assert a.read_bytes() == c.read_bytes()


def test_bad_traces_and_sets_are_one_line(tmp_path):
    readme_trace(tmp_path / "good_gt.osi", frames=3)
    data = (tmp_path / "good_gt.osi").read_bytes()
    (tmp_path / "cut_gt.osi").write_bytes(data[:-5])
    (tmp_path / "junk.mcap").write_bytes(b"\x89MCAP0\r\n" + b"junk" * 10)
    two = TraceSet.from_runs([{"t": [0, 1], "obj1.x": [0, 1]}] * 2, run_ids=["a", "b"])
    cases = [
        (lambda: read(tmp_path / "cut_gt.osi"), "unreadable OSI trace"),
        (lambda: read(tmp_path / "junk.mcap"), "unreadable OSI trace"),
        (lambda: write(two, tmp_path / "two.osi"), "holds one run"),
        (lambda: write(TraceSet.from_runs([{"t": [0, 1], "ego.v": [0, 1]}]),
                       tmp_path / "v.mcap"), "no field 'v'"),
        (lambda: write(TraceSet.from_runs([{"t": [0, 1e-10], "obj1.x": [0, 1]}]),
                       tmp_path / "ns.osi"), "within 1 ns"),
        (lambda: write(TraceSet.from_runs([{"t": [0, 1], "obj1.x": [0, 1]}]),
                       tmp_path / "h.mcap", host="ego"), "no object named 'ego'"),
    ]
    for call, expected in cases:
        with pytest.raises(SimcredError) as info:
            call()
        assert expected in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_real_ngsim_traffic_through_osi(tmp_path):
    # real NGSIM positions and headings (CommonRoad scenario) as OSI objects: back bit for bit
    scenario = Path(__file__).parent.parent / "data" / "commonroad-ngsim" / "USA_US101-3_3_T-1.xml"
    real = read(scenario, layout="scenario")
    keep = [s for s in real.signals if s.endswith((".x", ".y", ".heading"))]
    osi_names = [s.replace(".heading", ".yaw") for s in keep]
    run = {"t": real.time, **{n: real.column(s) for n, s in zip(osi_names, keep, strict=True)}}
    traces = TraceSet.from_runs([run], run_ids=["us101"])
    back = read(write(traces, tmp_path / "us101.osi"))
    assert back.n_rows == 32 and set(back.signals) == set(osi_names)
    assert back.features(traces.signals).tobytes() == traces.values.tobytes()
    assert np.all(np.abs(back.time - traces.time) <= 0.5e-9)
