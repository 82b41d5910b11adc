"""The OpenACC reader: shipped Parquet equals the original CSV, episode rules, signals, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simcred import data
from simcred.errors import OptionError, TraceSetError
from simcred.io.openacc import (
    EpisodeRules,
    OpenACCRecording,
    episodes,
    read_openacc,
    read_recording,
    recording_files,
    to_parquet,
)
from simcred.traces import RUN_INFO, TraceSet, take

#: Excerpts of original CSVs (the first 200 rows, unchanged; tests/data/openacc/README.md),
#: committed, so these checks run on every clone.
ORIGINAL = Path(__file__).resolve().parents[1] / "data" / "openacc"
SHIPPED = data.path("openacc")


@pytest.fixture(scope="module")
def human():
    return read_openacc(follower="human")


# -- shipped data --------------------------------------------------------------------------------


def test_shipped_data_has_licence_and_attribution():
    for folder in ("openacc", "a9"):
        assert (data.path(folder) / "LICENSE.txt").stat().st_size > 5000
    assert "CC BY 4.0" in (SHIPPED / "ATTRIBUTION.md").read_text()
    assert "Apache License 2.0" in data.path("a9/ATTRIBUTION.md").read_text()
    assert len(recording_files(SHIPPED)) == 38
    size = sum(p.stat().st_size for p in SHIPPED.rglob("*.parquet"))
    assert size < 4e6  # a few MB


def test_data_path_rejects_names_outside_the_package():
    with pytest.raises(TraceSetError, match="not a name inside"):
        data.path("../traces.py")
    with pytest.raises(TraceSetError, match="no such shipped data"):
        data.path("a9/nope.csv")
    assert "a9/trajectories_file.csv" in data.names()


@pytest.mark.parametrize("name", ["no_ACC/handling_part22", "short_setting/dynamic_part22",
                                  "long_setting/handling_part23"])
def test_shipped_parquet_equals_original_csv(name):
    """The shipped file's first rows are the original's (an excerpt: its first 200 rows)."""
    original = read_recording(ORIGINAL / f"{name}.csv")
    shipped = read_recording(SHIPPED / f"{name}.parquet")
    rows = len(original.time)
    assert rows == 200 and len(shipped.time) > rows
    assert original.header() == shipped.header()
    assert np.array_equal(original.time, shipped.time[:rows])
    assert original.speed.keys() == shipped.speed.keys()
    assert original.gap.keys() == shipped.gap.keys()
    for i in original.speed:
        assert np.array_equal(original.speed[i], shipped.speed[i][:rows], equal_nan=True)
    for i in original.gap:
        assert np.array_equal(original.gap[i], shipped.gap[i][:rows], equal_nan=True)


def test_ivs_is_the_gap_to_the_vehicle_behind():
    """Antenna distance of (i, i+1) minus IVS<i> is a car length; of (i-1, i) it is not."""
    import pyarrow.csv as pacsv

    table = pacsv.read_csv(ORIGINAL / "short_setting/dynamic_part1.csv",
                           read_options=pacsv.ReadOptions(skip_rows=5))
    col = {n: table.column(n).to_numpy(zero_copy_only=False).astype(float)
           for n in table.column_names}
    for i in (1, 4):  # IVS1 and IVS4 have both neighbours recorded
        behind = np.hypot(col[f"E{i}"] - col[f"E{i + 1}"], col[f"N{i}"] - col[f"N{i + 1}"])
        length = np.nanmedian(behind - col[f"IVS{i}"])
        assert 2.5 < length < 6.0


def test_to_parquet_round_trip_is_exact(tmp_path):
    csv = tmp_path / "x" / "rec.csv"
    csv.parent.mkdir()
    csv.write_text("Date,9,10,2019\nVehicle_order,A,B,\nNumber_of_vehicles,2\nACC,1\n"
                   "Distance_setting,L\nTime,Speed1,E1,N1,Speed2,E2,N2,IVS1\n"
                   "0.1,10.07,1.0,2.0,9.99,0,0,12.34\n0.2,10.1,1.0,2.0,,0,0,12.3\n")
    out = to_parquet(csv, tmp_path / "x" / "rec.parquet")
    a, b = read_recording(csv), read_recording(out)
    assert a.header() == b.header() == {"date": "2019-10-09", "vehicles": ["A", "B"], "acc": True,
                                        "setting": "long"}
    assert np.array_equal(a.speed[2], b.speed[2], equal_nan=True)
    assert b.speed[1].tolist() == [10.07, 10.1] and b.gap[1].tolist() == [12.34, 12.3]
    with pytest.raises(TraceSetError, match="overwrite"):
        to_parquet(csv, csv)


# -- episode rules on a constructed recording (the oracle is the construction) -------------------


def _recording(n=505, **changes) -> OpenACCRecording:
    time = np.round(np.arange(n) * 0.1 + 100.0, 1)
    vl = np.full(n, 15.0)
    vf = 14.0 + 0.01 * np.arange(n)
    gap = np.full(n, 20.0)
    for key, (rows, value) in changes.items():
        {"vl": vl, "vf": vf, "gap": gap}[key][rows] = value
    return OpenACCRecording("test/rec", "2019-10-09", ("L", "F"), False, None, time,
                     {1: vl, 2: vf}, {1: gap})


def test_rules_count_what_they_remove():
    # 505 rows = 5 possible episodes of 101 samples. Missing follower speed at row 150 breaks
    # segment [0, 505) into [0, 150) + [151, 505): 1 + 3 = 4 complete episodes.
    # Leader stopped over [151, 252) -> removed; a gap of 130 m in the last episode -> removed.
    rec = _recording(vf=(150, np.nan), vl=(slice(151, 252), 0.5), gap=(400, 130.0))
    ts = episodes([rec])
    cut = ts.metadata["cut"]
    assert (cut["possible"], cut["removed_incomplete"], cut["removed_leader_stopped"],
            cut["removed_gap"], cut["kept"]) == (5, 1, 1, 1, 2)
    assert cut["possible"] == sum(cut[k] for k in ("removed_incomplete", "removed_leader_stopped",
                                                   "removed_gap", "kept"))
    starts = [info["t0"] for info in ts.metadata[RUN_INFO].values()]
    assert starts == [100.0, 100.0 + 25.2]  # rows 0 and 252


def test_irregular_time_breaks_a_segment():
    rec = _recording(n=202)
    time = rec.time.copy()
    time[101:] += 0.5  # a 0.6 s step between rows 100 and 101
    broken = OpenACCRecording(rec.name, rec.date, rec.vehicles, rec.acc, rec.setting, time,
                              rec.speed, rec.gap)
    assert episodes([broken]).n_runs == 2
    time[100:] += 0.5  # now between rows 99 and 100: only [0, 100) and [100, 202)
    broken = OpenACCRecording(rec.name, rec.date, rec.vehicles, rec.acc, rec.setting, time,
                              rec.speed, rec.gap)
    assert episodes([broken]).n_runs == 1


def test_episode_signals():
    rec = _recording(n=202)
    ts = episodes([rec], EpisodeRules(duration=5.0))
    assert ts.n_runs == 3 and set(ts.lengths) == {51}  # 202 rows // 51
    run = ts.run(1)
    rows = slice(51, 102)
    assert np.array_equal(run["v"], rec.speed[2][rows])
    assert np.array_equal(run["dv"], rec.speed[1][rows] - rec.speed[2][rows])
    assert np.allclose(run["a"], 0.1)  # v grows by 0.01 m/s per 0.1 s
    assert np.array_equal(run["gap"], rec.gap[1][rows])
    assert ts.metadata["units"]["a"] == "m/s²"


def test_no_episode_is_an_error():
    with pytest.raises(TraceSetError, match="no episode passes"):
        episodes([_recording(n=50)])


@pytest.mark.parametrize("kwargs", [{"duration": 0.0}, {"gap_range": (5.0, 1.0)},
                                    {"step": float("nan")}, {"min_leader_speed": float("inf")}])
def test_bad_rules(kwargs):
    with pytest.raises(OptionError):
        EpisodeRules(**kwargs)


# -- the shipped human files ------------------------------------------------------------------


def test_human_episodes_follow_the_rules(human):
    rules = EpisodeRules()
    assert human.n_runs == 609 and set(human.lengths) == {rules.samples}
    info = human.metadata[RUN_INFO]
    assert {i["follower"] for i in info.values()} == {"human"}
    assert {i["file"].split("/")[0] for i in info.values()} == {"no_ACC"}
    for k in range(0, human.n_runs, 37):
        run = human.run(k)
        assert run["v_leader"].mean() > rules.min_leader_speed
        assert run["gap"].min() >= 0.5 and run["gap"].max() <= 120
        assert np.allclose(np.diff(run["t"]), 0.1)
        one = info[human.run_ids[k]]
        assert one["follower_position"] == one["leader_position"] + 1
        assert one["follower_vehicle"] != "unknown"


def test_files_filter_and_acc(human):
    acc = read_openacc(follower="acc", files=["short_setting/dynamic_part22"])
    info = acc.metadata[RUN_INFO]
    assert {i["follower"] for i in info.values()} == {"acc"}
    assert {i["setting"] for i in info.values()} == {"short"}
    with pytest.raises(OptionError, match="no OpenACC recording"):
        read_openacc(files=["no_ACC/nope"])
    with pytest.raises(OptionError, match="follower"):
        read_openacc(follower="robot")


def test_take_keeps_the_runs_and_their_info(human):
    part = take(human, [5, 2])
    assert part.run_ids == (human.run_ids[5], human.run_ids[2])
    assert np.array_equal(part.run(0)["gap"], human.run(5)["gap"])
    assert list(part.metadata[RUN_INFO]) == list(part.run_ids)
    with pytest.raises(TraceSetError):
        take(human, [1, 1])


# -- bad files -------------------------------------------------------------------------------


GOOD_HEAD = "Date,9,10,2019\nVehicle_order,A,B,\nNumber_of_vehicles,2\nACC,0\nDistance_setting,\n"


@pytest.mark.parametrize(("text", "message"), [
    ("Date,9,10,2019\nVehicle_order,A\nNumber,2\n",
     "line 3 should start with 'Number_of_vehicles'"),
    (GOOD_HEAD.replace("ACC,0", "ACC,2") + "Time,Speed1\n0.1,1\n", "'ACC' must be 0 or 1"),
    (GOOD_HEAD + "Time,Speed1\n0.2,1\n0.1,1\n", "not strictly increasing at data row 2"),
    (GOOD_HEAD + "Time,Speed1\n0.1,fast\n", "column 'Speed1' is not numeric"),
    (GOOD_HEAD + "Time,Foo1\n0.1,1\n", "unexpected column 'Foo1'"),
])
def test_bad_file_one_line_error(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(TraceSetError, match=message) as info:
        read_recording(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_data_openacc_records_its_provenance(tmp_path):
    from simcred._json import file_digest
    from simcred.cli import run

    out = tmp_path / "human.parquet"
    assert run(["--quiet", "data", "openacc", "--out", str(out), "--follower", "human"]) == 0
    provenance = TraceSet.read(out).metadata["provenance"]
    assert provenance["options"]["follower"] == "human"
    root = data.path("openacc")
    assert provenance["inputs"] == {p.relative_to(root).as_posix(): file_digest(p)
                                    for p in recording_files(root)}
