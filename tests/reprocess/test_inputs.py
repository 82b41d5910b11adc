"""What reprocess reads (issue 14 part 2): GT/SD at different rates, gaps and dropouts,
long-format tables, CommonRoad scenarios with a chosen TO and its EGO."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from simcred.cli import run
from simcred.errors import SimcredError
from simcred.io import commonroad, longformat
from simcred.io.measurement import Measurement
from simcred.kinematics import LANE_WIDTH, Track
from simcred.reprocess.inputs import (
    LongColumns,
    commonroad_drive,
    long_drive,
    read_measurement,
    road_frame,
)
from simcred.reprocess.pipeline import ReprocessConfig, reprocess
from simcred.reprocess.timebase import Drive, RecordedTracks, align
from simcred.sim.experiments.cutin import CutInConfig, simulate
from simcred.traces import TIME, TraceSet

DATA = Path(__file__).parents[1] / "data" / "commonroad-ngsim"
US101 = DATA / "USA_US101-3_3_T-1.xml"
OBJECTS = ("ego", "to")


@pytest.fixture(scope="module")
def short():
    return simulate(0, CutInConfig(duration=4.0))


def _thinned(traces: TraceSet, step: int, source: str) -> TraceSet:
    run = {k: v[::step] for k, v in traces.run(0).items()}
    return TraceSet.from_runs([run], run_ids=["gt"], source=source)


def _recording(tracks: dict[str, Track], source: str = "rec") -> RecordedTracks:
    return RecordedTracks(source, tracks, "sha256:test")


def _track(t) -> Track:
    t = np.asarray(t, dtype=float)
    return Track(t, 20 * t, np.zeros_like(t), np.full_like(t, 20.0), np.zeros_like(t))


# -- time base -----------------------------------------------------------------------------------


def test_gt_at_a_lower_rate_is_compared_on_its_own_samples(short):
    gt = _thinned(short.gt, 5, "GT at 20 Hz")
    result = reprocess(Measurement(sd=short.sd, gt=gt), ReprocessConfig(scenario_based=False))
    np.testing.assert_array_equal(result.times, gt.run(0)[TIME])  # the coarser recording's
    assert result.input_report["time_base"] == "GT"
    assert result.input_report["steps"]["GT"] == pytest.approx(0.05)
    # typed inside, the report a view of it: the time base without a second copy of the tracks
    assert result.aligned.base == "GT" and result.aligned.times is result.times
    assert not result.aligned.tracks
    assert result.input_report == {"drive": dict(result.drive_metadata),
                                   **result.aligned.to_dict()}
    # SD's samples include GT's, so linear interpolation onto them is exact
    run = short.sd.run(0)
    np.testing.assert_allclose(result.states["SD"]["to"].x, run["to.x"][::5], rtol=0, atol=1e-9)
    np.testing.assert_allclose(result.states["GT"]["to"].x, gt.run(0)["to.x"], rtol=0, atol=0)
    # the sensor offset (1.4 m) is still what the sensor step measures
    assert result.errors["ideal"]["S"]["to"]["d"].median == pytest.approx(1.4, abs=0.1)
    assert result.errors["ideal"]["S"]["to"]["d"].n == len(result.times)


def test_each_recording_is_fitted_on_its_own_samples(short):
    gt = _thinned(short.gt, 5, "GT at 20 Hz")
    result = reprocess(Measurement(sd=short.sd, gt=gt), ReprocessConfig(scenario_based=False))
    assert result.descriptions["fit(SD)"].dt == pytest.approx(0.01)
    assert result.descriptions["fit(GT)"].dt == pytest.approx(0.05)


def test_every_gap_is_reported_and_no_comparison_time_lies_inside_one():
    t = np.round(np.arange(0, 3.01, 0.1), 10)
    holes = (t > 1.05) & (t < 1.35)  # 1.1, 1.2, 1.3 missing: a 0.4 s gap from 1.0 to 1.4
    drive = Drive(_recording({"ego": _track(t), "to": _track(t[~holes])}))
    aligned = align(drive, OBJECTS)
    [gap] = aligned.gaps
    assert (gap.recording, gap.object) == ("SD", "to")
    assert (gap.start, gap.end) == pytest.approx((1.0, 1.4))
    assert gap.missing == 3 and gap.duration == pytest.approx(0.4)
    np.testing.assert_allclose(aligned.times, t[~holes])
    assert aligned.to_dict()["gaps"][0]["missing_samples"] == 3


def test_a_gap_longer_than_the_limit_is_a_one_line_error_or_cut_away():
    t = np.round(np.arange(0, 5.01, 0.1), 10)
    holes = (t > 1.05) & (t < 1.95)  # no sample from 1.0 to 2.0: 1 s > 0.5 s
    drive = Drive(_recording({"ego": _track(t), "to": _track(t[~holes])}, "drive.csv"))
    with pytest.raises(SimcredError) as info:
        align(drive, OBJECTS)
    message = str(info.value)
    assert "\n" not in message
    assert "drive.csv" in message and "'to'" in message and "1.000 s to 2.000 s" in message
    assert len(align(drive, OBJECTS, max_gap=1.5).gaps) == 1  # a higher limit accepts it
    cut = align(drive, OBJECTS, long_gaps="longest")
    assert cut.cut == pytest.approx((2.0, 5.0))  # 3 s after the gap beat 1 s before it
    assert cut.times[0] == pytest.approx(2.0) and cut.times[-1] == pytest.approx(5.0)
    assert cut.tracks["SD"]["ego"].t[0] == pytest.approx(2.0)


def test_recordings_without_a_common_span_are_refused():
    drive = Drive(_recording({"ego": _track([0, 0.1, 0.2]), "to": _track([1.0, 1.1, 1.2])}))
    with pytest.raises(SimcredError, match="share no time span"):
        align(drive, OBJECTS)


def test_a_missing_object_names_the_recording_and_the_objects():
    drive = Drive(_recording({"ego": _track([0, 0.1, 0.2])}, "x.csv"))
    with pytest.raises(SimcredError, match=r"x.csv: SD has no object 'to'.*objects: ego"):
        align(drive, OBJECTS)


# -- long format ---------------------------------------------------------------------------------


def _long_csv(measurement: Measurement, path: Path, blank: dict[tuple[str, int], str]) -> Path:
    """The SD as a long table (t, object, x, y, v, heading); ``blank`` empties cells
    ``(object, row) -> column`` (dropouts)."""
    run = measurement.sd.run(0)
    lines = ["t,object,x,y,v,heading"]
    for k, t in enumerate(run[TIME]):
        for name in OBJECTS:
            cells = [repr(float(run[f"{name}.{s}"][k])) for s in ("x", "y", "v", "heading")]
            column = blank.get((name, k))
            if column is not None:
                cells[("x", "y", "v", "heading").index(column)] = (
                    "" if column != "v" else "nan")
            lines.append(f"{float(t)!r},{name}," + ",".join(cells))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_long_format_dropouts_are_removed_counted_and_their_gaps_reported(short, tmp_path):
    blank = {("to", k): "y" for k in range(150, 160)} | {("to", 300): "v"}
    path = _long_csv(short, tmp_path / "drive.csv", blank)
    drive = long_drive(path, LongColumns(object_column="object"))
    assert drive.sd.dropouts == {"ego": 0, "to": 11}
    assert len(drive.sd.tracks["to"]) == len(drive.sd.tracks["ego"]) - 11
    aligned = align(drive, OBJECTS)
    t = short.sd.run(0)[TIME]
    spans = [(g.start, g.end, g.missing) for g in aligned.gaps]
    assert spans == [(pytest.approx(t[149]), pytest.approx(t[160]), 10),
                     (pytest.approx(t[299]), pytest.approx(t[301]), 1)]
    assert len(aligned.times) == len(t) - 11
    assert aligned.to_dict()["dropouts"] == {"SD": {"to": 11}}


def test_cli_reprocesses_a_long_table_and_prints_every_gap(short, tmp_path, capsys):
    path = _long_csv(short, tmp_path / "drive.csv", {("to", 200): "x"})
    out = tmp_path / "out"
    assert run(["reprocess", str(path), "--object-column", "object", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "1 gap(s)" in printed and "gap: SD object 'to'" in printed
    summary = json.loads((out / "reprocess.json").read_text())
    assert summary["input"]["gaps"][0]["missing_samples"] == 1
    assert summary["input"]["drive"]["format"] == "long"
    assert (out / "figures" / "fig3_fit.png").is_file()


def test_a_long_table_with_gt_at_another_rate(short, tmp_path):
    sd = _long_csv(short, tmp_path / "sd.csv", {})
    gt = _long_csv(Measurement(sd=_thinned(short.gt, 2, "gt")), tmp_path / "gt.csv", {})
    drive = read_measurement(sd, long=LongColumns(object_column="object"), gt=gt)
    assert drive.gt is not None and align(drive, OBJECTS).base == "GT"


@pytest.mark.parametrize("args, message", [
    (["--object-column", "vehicle"], "no column 'vehicle'"),
    (["--object-column", "object", "--object", "12"], "no object 'obj12' in column 'object'"),
    (["--object-column", "object", "--max-gap", "0"], "--max-gap"),
    (["--object-column", "object", "--run", "a"], "--run needs --run-column"),
    (["--object-column", "object", "--ego", "to"], "--ego and --object are both 'to'"),
    (["--run-column", "object"], "no column 'ego.x' (columns are: t, object, x, y"),
])
def test_cli_bad_long_input_is_one_line(short, tmp_path, capsys, args, message):
    path = _long_csv(short, tmp_path / "drive.csv", {})
    assert run(["reprocess", str(path), "--out", str(tmp_path / "o"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1 and "Traceback" not in err


# -- CommonRoad ----------------------------------------------------------------------------------


def _literal_follower(traces: TraceSet, obstacle: str, half_width: float) -> str | None:
    """Per time step, loop over every other obstacle; count who is nearest behind."""
    runs = {r: traces.run(i) for i, r in enumerate(traces.run_ids)}
    to = runs[obstacle]
    counts: dict[str, int] = {}
    for k, t in enumerate(to[TIME]):
        best, best_gap = None, math.inf
        for name, other in runs.items():
            if name == obstacle or t not in other[TIME]:
                continue
            j = int(np.flatnonzero(other[TIME] == t)[0])
            h = to["heading"][k]
            dx, dy = other["x"][j] - to["x"][k], other["y"][j] - to["y"][k]
            lon = dx * math.cos(h) + dy * math.sin(h)
            lat = -dx * math.sin(h) + dy * math.cos(h)
            if (math.cos(other["heading"][j] - h) > math.cos(math.pi / 4) and lon < 0
                    and abs(lat) < half_width and -lon < best_gap):
                best, best_gap = name, -lon
        if best is not None:
            counts[best] = counts.get(best, 0) + 1
    if not counts:
        return None
    top = max(counts.values())
    return next(r for r in runs if counts.get(r) == top)


@pytest.mark.parametrize("path", sorted(DATA.glob("*.xml")), ids=lambda p: p.stem)
def test_the_follower_agrees_with_a_literal_loop(path):
    traces = commonroad.read(path)
    for obstacle in traces.run_ids:
        literal = (_literal_follower(traces, obstacle, LANE_WIDTH / 2)
                   or _literal_follower(traces, obstacle, math.inf))
        chosen = commonroad.follower(traces, obstacle)
        if literal is None:
            assert chosen is None or chosen[1].startswith("nearest vehicle (none")
        else:
            assert chosen is not None and chosen[0] == literal, obstacle


def test_the_us101_lane_changer_gets_the_car_behind_it_in_its_lane():
    drive = commonroad_drive(US101, 394)
    assert drive.metadata["ego"] == 401
    assert drive.metadata["ego_choice"] == "follower in its lane"
    assert drive.gt is None and set(drive.sd.tracks) == {"ego", "to"}


def test_the_road_frame_is_rigid_and_starts_the_ego_at_the_origin():
    traces = commonroad.read(US101)
    raw = {name: Track(*(traces.run(traces.run_ids.index(run))[c]
                         for c in (TIME, "x", "y", "v", "heading")))
           for name, run in (("ego", "obj401"), ("to", "obj394"))}
    moved, frame = road_frame(raw)
    assert (moved["ego"].x[0], moved["ego"].y[0]) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert moved["ego"].y[-1] == pytest.approx(0.0, abs=1e-9)  # x along the EGO's chord
    before = np.hypot(raw["to"].x - raw["ego"].x, raw["to"].y - raw["ego"].y)
    after = np.hypot(moved["to"].x - moved["ego"].x, moved["to"].y - moved["ego"].y)
    np.testing.assert_allclose(after, before, rtol=1e-12)
    np.testing.assert_allclose(moved["to"].heading - moved["ego"].heading,
                               raw["to"].heading - raw["ego"].heading, atol=1e-12)
    assert frame["direction"] == "EGO chord"


@pytest.mark.parametrize("kwargs, message", [
    ({"obstacle": 9999}, r"no obstacle 9999 with a trajectory \(obstacles: 363, 376"),
    ({"obstacle": 394, "ego": 394}, "--ego and --object are both obstacle 394"),
    ({"obstacle": "x"}, "--object must be an integer id"),
])
def test_commonroad_bad_choices_are_one_line_errors(kwargs, message):
    with pytest.raises(SimcredError, match=message):
        commonroad_drive(US101, **kwargs)


def test_cli_reprocesses_a_commonroad_obstacle_end_to_end_with_figures(tmp_path):
    out = tmp_path / "r"
    assert run(["--quiet", "reprocess", str(US101), "--object", "394", "--out", str(out)]) == 0
    summary = json.loads((out / "reprocess.json").read_text())
    assert summary["input"]["drive"]["object"] == 394 and summary["input"]["drive"]["ego"] == 401
    assert summary["input"]["samples"] == 32 and summary["input"]["gaps"] == []
    assert set(summary["reactions"]) == {"SD", "rSD"}
    for name in ("errors.json", "reaction.json", "risk.json", "scenario.xosc",
                 "descriptions/fit_SD.json", "resimulations/rSD.parquet"):
        assert (out / name).is_file(), name
    figures = sorted(p.name for p in (out / "figures").glob("*.png"))
    assert {"fig3_fit.png", "fig7_velocity_risk.png"} <= set(figures)
    assert all((out / "figures" / f).stat().st_size > 10_000 for f in figures)


def test_cli_commonroad_needs_an_object(tmp_path, capsys):
    assert run(["reprocess", str(US101), "--out", str(tmp_path / "o")]) == 2
    assert "needs --object ID" in capsys.readouterr().err


def test_cli_ego_is_refused_for_an_a9_recording(tmp_path, capsys):
    from simcred import data

    path = data.path("a9/trajectories_file.csv")
    assert run(["reprocess", str(path), "--ego", "3", "--out", str(tmp_path / "o")]) == 2
    assert "A9 recording's EGO is the recording car" in capsys.readouterr().err


def _without_states(tmp_path: Path, obstacle: int, steps) -> Path:
    """US-101-3 with the trajectory states ``steps`` of ``obstacle`` deleted (a real gap)."""
    text = US101.read_text()
    start = text.index(f'<obstacle id="{obstacle}">')
    end = text.index("</obstacle>", start)
    block = text[start:end]
    for k in steps:
        pattern = (r"\s*<state>(?:(?!</state>).)*?<time>\s*<exact>" + str(k)
                   + r"</exact>\s*</time>(?:(?!</state>).)*?</state>")
        block, n = re.subn(pattern, "", block, flags=re.S)
        assert n == 1
    path = tmp_path / "gap.xml"
    path.write_text(text[:start] + block + text[end:])
    return path


def test_cli_reports_a_gap_in_a_commonroad_trajectory(tmp_path, capsys):
    path = _without_states(tmp_path, 394, (10, 11, 12))  # no state from 0.9 s to 1.3 s
    out = tmp_path / "r"
    assert run(["reprocess", str(path), "--object", "394", "--out", str(out)]) == 0
    assert "gap: SD object 'to' 0.900-1.300 s (0.400 s, 3 sample(s) missing)" in (
        capsys.readouterr().out)
    report = json.loads((out / "reprocess.json").read_text())["input"]
    assert report["samples"] == 32 - 3 and len(report["gaps"]) == 1


def test_cli_refuses_or_cuts_a_gap_over_the_limit(tmp_path, capsys):
    path = _without_states(tmp_path, 394, range(5, 12))  # 0.4 s to 1.2 s: 0.8 s
    assert run(["reprocess", str(path), "--object", "394", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "gap.xml: SD object 'to': no sample from 0.400 s to 1.200 s (0.800 s) > max_gap" in err
    out = tmp_path / "b"
    assert run(["--quiet", "reprocess", str(path), "--object", "394", "--long-gaps", "longest",
                "--out", str(out)]) == 0
    report = json.loads((out / "reprocess.json").read_text())["input"]
    assert report["cut_to_longest_stretch"] == pytest.approx([1.2, 3.1])
    assert report["span"] == pytest.approx([1.2, 3.1]) and report["samples"] == 20


def test_the_long_reader_drops_and_counts_dropouts_only_when_asked(tmp_path):
    path = tmp_path / "d.csv"
    path.write_text("run,t,x,lane\na,0,1,\na,1,,\na,2,nan,\na,3,4,\nb,0,1,\nb,1,2,\n")
    with pytest.raises(SimcredError, match="column 'x', row 3: value is nan"):
        longformat.read(path, run_column="run", signals=["x"])
    with pytest.raises(SimcredError, match="dropouts='drop' needs signals"):
        longformat.read(path, run_column="run", dropouts="drop")
    traces = longformat.read(path, run_column="run", signals=["x"], dropouts="drop")
    assert traces.metadata["dropouts"] == {"a": 2}
    np.testing.assert_array_equal(traces.run(0)[TIME], [0.0, 3.0])
    np.testing.assert_array_equal(traces.run(0)["x"], [1.0, 4.0])


def test_a_measurement_with_nan_dropouts_is_read_as_long_tables(short, tmp_path):
    """simcred's own Parquet files are long tables too (``run``, ``t``, ``ego.x``, ...): read so,
    NaN samples are dropouts instead of an error."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    short.write(tmp_path / "m")
    sd = pq.read_table(tmp_path / "m" / "sd.parquet")
    x = sd.column("to.x").to_numpy().copy()
    x[100:120] = np.nan  # 0.2 s of the TO lost by the sensor
    sd = sd.set_column(sd.column_names.index("to.x"), "to.x", pa.array(x))
    pq.write_table(sd, tmp_path / "m" / "sd_nan.parquet")
    drive = read_measurement(tmp_path / "m" / "sd_nan.parquet", gt=tmp_path / "m" / "gt.parquet")
    assert drive.sd.dropouts == {"ego": 20, "to": 20}  # a row without an object column
    result = reprocess(drive, ReprocessConfig(scenario_based=False))
    [gap] = [g for g in result.input_report["gaps"] if g["object"] == "to"]
    t = short.sd.run(0)[TIME]
    assert (gap["recording"], gap["start"], gap["end"]) == ("SD", t[99], t[120])
    assert len(result.times) == len(t) - 20
    assert result.errors["ideal"]["S"]["to"]["d"].median == pytest.approx(1.4, abs=0.1)


def test_a_commonroad_reprocessing_is_byte_identical_when_repeated(tmp_path):
    from simcred.reprocess.output import write

    for name in ("a", "b"):
        write(reprocess(commonroad_drive(US101, 388)), tmp_path / name)
    for file in ("reprocess.json", "errors.json", "risk.json", "descriptions/fit_SD.json"):
        assert (tmp_path / "a" / file).read_bytes() == (tmp_path / "b" / file).read_bytes()
    summary = json.loads((tmp_path / "a" / "reprocess.json").read_text())
    assert summary["inputs"]["SD"].startswith("sha256:")
    assert summary["input"]["drive"]["ego"] == 394  # 388's follower


def test_a_long_table_with_several_runs_needs_a_choice(short, tmp_path):
    one = short.sd.run(0)
    two = TraceSet.from_runs([one, one], run_ids=["a", "b"], source="two")
    path = tmp_path / "two.csv"
    longformat.write(two, path)
    with pytest.raises(SimcredError, match=r"2 runs \(a, b\); choose one with --run"):
        long_drive(path, LongColumns(run_column="run"))
    drive = long_drive(path, LongColumns(run_column="run", run="b"))
    assert drive.metadata["run"] == "b" and len(drive.sd.tracks["to"]) == len(one[TIME])
    with pytest.raises(SimcredError, match=r"no run 'c' \(runs: a, b\)"):
        long_drive(path, LongColumns(run_column="run", run="c"))
