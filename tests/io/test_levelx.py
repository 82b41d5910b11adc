"""highD-family folders (levelX layout): values against hand-computed ones, the façade, the CLI on
a folder against itself and a shifted copy, and malformed folders (one line, exit 2).

The files are built here from the published column layout (the data are not redistributable).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from fuzz.test_cli_fuzz import run_isolated
from simcred.cli import run
from simcred.errors import OptionError, TraceSetError
from simcred.io import detect, read
from simcred.traces import RUN_INFO, TraceSet


def _header(text: str) -> list[str]:
    return text.split(",")


HIGHD_TRACKS = _header("frame,id,x,y,width,height,xVelocity,yVelocity,xAcceleration,yAcceleration,"
                       "frontSightDistance,backSightDistance,dhw,thw,ttc,precedingXVelocity,precedingId,"
                       "followingId,leftPrecedingId,leftAlongsideId,leftFollowingId,rightPrecedingId,"
                       "rightAlongsideId,rightFollowingId,laneId")
HIGHD_META = _header("id,width,height,initialFrame,finalFrame,numFrames,class,drivingDirection,"
                     "traveledDistance,minXVelocity,maxXVelocity,meanXVelocity,minDHW,minTHW,minTTC,"
                     "numLaneChanges")
HIGHD_RECORDING = _header("id,frameRate,locationId,speedLimit,month,weekDay,startTime,duration,"
                          "totalDrivenDistance,totalDrivenTime,numVehicles,numCars,numTrucks,"
                          "upperLaneMarkings,lowerLaneMarkings")
IND_TRACKS = _header("recordingId,trackId,frame,trackLifetime,xCenter,yCenter,heading,width,length,"
                     "xVelocity,yVelocity,xAcceleration,yAcceleration,lonVelocity,latVelocity,"
                     "lonAcceleration,latAcceleration")
IND_META = _header("recordingId,trackId,initialFrame,finalFrame,numFrames,width,length,"
                   "class")
IND_RECORDING = _header("recordingId,locationId,frameRate,speedLimit,weekday,startTime,duration,"
                        "numTracks,numVehicles,numVRUs,latLocation,lonLocation,xUtmOrigin,yUtmOrigin,"
                        "orthoPxToMeter")


def write_table(path: Path, header: list[str], rows: list[dict]) -> None:
    """A CSV with the published header; cells not given are 0."""
    lines = [",".join(header)] + [",".join(str(row.get(h, 0)) for h in header) for row in rows]
    path.write_text("\n".join(lines) + "\n")


def highd_folder(folder: Path, tracks: dict[int, dict], *, rec: str = "01", rate: int = 25,
                 shift: float = 0.0) -> Path:
    """A highD recording: ``tracks[id] = {frames, x0, v, lane, direction, cls, w, h}``.

    Vehicles move at constant speed ``v`` (+ ``shift``) along their direction of travel.
    """
    folder.mkdir(parents=True, exist_ok=True)
    rows, meta = [], []
    for tid, spec in tracks.items():
        sign = 1 if spec["direction"] == 2 else -1
        v = spec["v"] + shift
        for k, frame in enumerate(spec["frames"]):
            rows.append({"frame": frame, "id": tid, "x": spec["x0"] + sign * v * k / rate,
                         "y": spec.get("y", 20.0), "width": spec["w"], "height": spec["h"],
                         "xVelocity": sign * v, "yVelocity": 0.0, "laneId": spec["lane"]})
        meta.append({"id": tid, "width": spec["w"], "height": spec["h"], "class": spec["cls"],
                     "drivingDirection": spec["direction"], "numFrames": len(spec["frames"])})
    write_table(folder / f"{rec}_tracks.csv", HIGHD_TRACKS, rows)
    write_table(folder / f"{rec}_tracksMeta.csv", HIGHD_META, meta)
    write_table(folder / f"{rec}_recordingMeta.csv", HIGHD_RECORDING,
                [{"id": int(rec), "frameRate": rate, "locationId": 2, "speedLimit": -1,
                  "month": "09.2017", "startTime": "08:38",
                  "upperLaneMarkings": "8.51;12.59;16.43", "lowerLaneMarkings": "21.0;25.0"}])
    return folder


TWO = {1: {"frames": [0, 1, 2], "x0": 100.0, "v": 30.0, "lane": 2, "direction": 1,
           "cls": "Car", "w": 4.5, "h": 1.8},
       7: {"frames": [1, 2, 3, 4], "x0": 10.0, "v": 25.0, "lane": 6, "direction": 2,
           "cls": "Truck", "w": 12.0, "h": 2.5, "y": 24.0}}


def test_highd_tracks_are_runs_with_centres_time_and_normalised_direction(tmp_path):
    ts = read(highd_folder(tmp_path / "h", TWO))
    assert detect(tmp_path / "h").name == "levelx"
    assert ts.run_ids == ("01:1", "01:7")
    assert ts.signals == ("x", "y", "vx", "vy", "ax", "ay", "lane")
    car, truck = ts.run(0), ts.run(1)
    assert car["t"].tolist() == [0.0, 0.04, 0.08]
    assert truck["t"].tolist() == [0.04, 0.08, 0.12, 0.16]
    # track 1 drives left (direction 1): turned by 180°, so x = -(corner + width / 2) grows
    assert car["x"].tolist() == [-(100.0 - 30 * k / 25 + 2.25) for k in range(3)]
    assert car["y"].tolist() == [-(20.0 + 0.9)] * 3
    assert car["vx"].tolist() == [30.0] * 3
    assert truck["x"].tolist() == [10.0 + 25 * k / 25 + 6.0 for k in range(4)]
    assert truck["y"].tolist() == [24.0 + 1.25] * 4 and truck["vx"].tolist() == [25.0] * 4
    assert car["lane"].tolist() == [2.0] * 3 and truck["lane"].tolist() == [6.0] * 4
    info = ts.metadata[RUN_INFO]
    assert info["01:7"] == {"recording": "01", "track": 7, "class": "Truck", "width": 2.5,
                            "length": 12.0, "driving_direction": 2}
    assert ts.units["vx"] == "m/s" and ts.units["lane"] == ""
    assert ts.metadata["recordings"]["01"]["startTime"] == "08:38"
    json.dumps(dict(ts.metadata), allow_nan=False)  # JSON as it is written to files


def test_direction_keep_is_the_file_frame(tmp_path):
    ts = read(highd_folder(tmp_path / "h", TWO), direction="keep")
    assert ts.run(0)["x"][0] == 100.0 + 2.25 and ts.run(0)["vx"][0] == -30.0


def test_recordings_option_selects_and_orders(tmp_path):
    folder = highd_folder(tmp_path / "h", TWO, rec="02")
    highd_folder(folder, {3: TWO[1]}, rec="01")
    assert read(folder).run_ids == ("01:3", "02:1", "02:7")
    assert read(folder, recordings=["02"]).run_ids == ("02:1", "02:7")
    with pytest.raises(OptionError, match="no recording '05' \\(recordings: 01, 02\\)"):
        read(folder, recordings=["05"])


def test_single_frame_tracks_are_counted_not_hidden(tmp_path):
    tracks = {**TWO, 9: {**TWO[1], "frames": [5]}}
    ts = read(highd_folder(tmp_path / "h", tracks))
    assert ts.run_ids == ("01:1", "01:7") and ts.metadata["short_tracks"] == {"01:9": 1}


def test_ind_layout_keeps_centre_and_heading(tmp_path):
    folder = tmp_path / "ind"
    folder.mkdir()
    rows = [{"recordingId": 0, "trackId": 0, "frame": f, "xCenter": 1.0 + f, "yCenter": -2.0,
             "heading": 90.0, "xVelocity": 1.0} for f in range(3)]
    write_table(folder / "00_tracks.csv", IND_TRACKS, rows)
    write_table(folder / "00_tracksMeta.csv", IND_META,
                [{"trackId": 0, "width": 0.8, "length": 1.9, "class": "bicycle"}])
    write_table(folder / "00_recordingMeta.csv", IND_RECORDING, [{"frameRate": 25}])
    ts = TraceSet.read(folder)
    assert ts.metadata["format"] == "inD/rounD/exiD/uniD"
    assert ts.signals == ("x", "y", "vx", "vy", "ax", "ay", "heading")
    assert ts.column("x").tolist() == [1.0, 2.0, 3.0] and ts.column("heading")[0] == 90.0
    assert ts.metadata[RUN_INFO]["00:0"]["class"] == "bicycle"
    assert ts.metadata[RUN_INFO]["00:0"]["length"] == 1.9


def test_a_csv_directory_is_still_a_csv_directory(tmp_path):
    TraceSet.from_runs([{"t": [0, 1], "x": [0, 1]}]).write(tmp_path / "d")
    assert detect(tmp_path / "d").name == "csv-dir"


# -- simcred compare on folders: a known answer ----------------------------------------------------


def traffic(folder: Path, seed: int, shift: float = 0.0) -> Path:
    """40 vehicles per direction with speeds around 30 m/s (both directions alike)."""
    rng = np.random.default_rng(seed)
    tracks = {}
    for tid in range(1, 81):
        direction = 1 if tid <= 40 else 2
        tracks[tid] = {"frames": list(range(tid, tid + 30)), "x0": float(rng.uniform(0, 300)),
                       "v": float(rng.normal(30, 3)), "lane": 2 if direction == 1 else 6,
                       "direction": direction, "cls": "Car", "w": 4.5, "h": 1.8}
    return highd_folder(folder, tracks, shift=shift)


@pytest.mark.parametrize("shift, same", [(0.0, True), (15.0, False)])
def test_cli_compare_on_highd_folders(tmp_path, capsys, shift, same):
    a = traffic(tmp_path / "a", seed=1)
    b = traffic(tmp_path / "b", seed=1, shift=shift)
    code = run(["compare", str(a), str(b), "-f", "vx", "--bins", "4", "--permutations", "99",
                "--seed", "3", "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["chain"]["rejected"] is (not same)  # the verdict the CLI leads with
    if same:
        assert doc["distance"] == 0.0 and not doc["start"]["rejected"]
    else:
        assert doc["start"]["rejected"]  # 15 m/s faster: the start states differ


def test_convert_highd_folder_to_parquet_keeps_metadata(tmp_path, capsys):
    folder = highd_folder(tmp_path / "h", TWO)
    assert run(["convert", str(folder), str(tmp_path / "h.parquet")]) == 0
    back, direct = TraceSet.read(tmp_path / "h.parquet"), read(folder)
    assert back.digest() == direct.digest()  # signals, run ids, offsets, time, values
    assert {k: v for k, v in back.metadata.items() if k != "converted_from"} == direct.metadata
    assert back.metadata[RUN_INFO]["01:1"]["class"] == "Car"
    assert back.metadata["converted_from"]["format"] == "levelx"


# -- malformed folders: one line, exit 2 -----------------------------------------------------------


def _edit(name: str, change):
    def build(folder: Path) -> None:
        path = folder / name
        path.write_text(change(path.read_text()))
    return build


def _cell(text: str, *, row: int, column: int, value: str) -> str:
    """``text`` with the cell at (line ``row``, field ``column``) replaced."""
    lines = text.splitlines()
    fields = lines[row].split(",")
    fields[column] = value
    lines[row] = ",".join(fields)
    return "\n".join(lines) + "\n"


def _drop(name: str):
    return lambda folder: (folder / name).unlink()


MALFORMED = {
    "no tracksMeta": _drop("01_tracksMeta.csv"),
    "no recordingMeta": _drop("01_recordingMeta.csv"),
    "empty tracks": _edit("01_tracks.csv", lambda s: ""),
    "header only tracks": _edit("01_tracks.csv", lambda s: s.splitlines()[0] + "\n"),
    "binary tracks": lambda f: (f / "01_tracks.csv").write_bytes(b"\xff\xfe\x00\x01" * 64),
    "no id column": _edit("01_tracks.csv", lambda s: s.replace("frame,id,", "frame,ident,", 1)),
    "no frame column": _edit("01_tracks.csv", lambda s: s.replace("frame,", "frm,", 1)),
    "no laneId": _edit("01_tracks.csv", lambda s: s.replace(",laneId", ",lane", 1)),
    "text in x": _edit("01_tracks.csv", lambda s: _cell(s, row=2, column=2, value="abc")),
    "fractional frame": _edit("01_tracks.csv", lambda s: s.replace("\n1,1,", "\n1.5,1,", 1)),
    "duplicate frame": _edit("01_tracks.csv", lambda s: s + s.splitlines()[1] + "\n"),
    "track missing in meta": _edit("01_tracksMeta.csv",
                                   lambda s: "\n".join(s.splitlines()[:2]) + "\n"),
    "duplicate meta id": _edit("01_tracksMeta.csv", lambda s: s + s.splitlines()[1] + "\n"),
    "direction 3": _edit("01_tracksMeta.csv", lambda s: s.replace(",Car,1,", ",Car,3,", 1)),
    "no class": _edit("01_tracksMeta.csv", lambda s: s.replace(",class,", ",klass,", 1)),
    "frameRate 0": _edit("01_recordingMeta.csv", lambda s: s.replace("\n1,25,", "\n1,0,", 1)),
    "frameRate text": _edit("01_recordingMeta.csv", lambda s: s.replace("\n1,25,", "\n1,x,", 1)),
    "two recording rows": _edit("01_recordingMeta.csv", lambda s: s + s.splitlines()[1] + "\n"),
    "ragged row": _edit("01_tracks.csv", lambda s: s + "1,2,3\n"),
    "all tracks single frame": lambda f: highd_folder(f, {1: {**TWO[1], "frames": [0]}}),
}


@pytest.mark.parametrize("name", list(MALFORMED))
def test_malformed_highd_folder_is_one_line_exit_2(tmp_path, name):
    folder = highd_folder(tmp_path / "corrupt_h", TWO)
    MALFORMED[name](folder)
    code, out, err, elapsed = run_isolated(["compare", str(folder), str(folder), "-f", "vx"], 10)
    assert code == 2, (code, err[-400:])
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), err[-400:]
    assert "Traceback" not in err + out and "corrupt_h" in lines[0]
    for runs in ("tracks", "recordings"):  # the scene mode reads through the same checks
        with pytest.raises((TraceSetError, OptionError)):
            read(folder, runs=runs)


def test_twenty_malformed_cases():
    assert len(MALFORMED) == 20


def test_highd_folder_copy_reads_the_same(tmp_path):
    folder = highd_folder(tmp_path / "h", TWO)
    shutil.copytree(folder, tmp_path / "copy")
    assert read(tmp_path / "copy").equals(read(folder))


# -- scene mode: every recording a run, its tracks the objects -------------------------------------


def two_recordings(folder: Path) -> Path:
    """Recording 01: TWO plus a single-frame track 9; recording 02: tracks 3 and 7 (another 7)."""
    highd_folder(folder, {**TWO, 9: {**TWO[1], "frames": [6], "x0": 50.0}})
    return highd_folder(folder, {3: {**TWO[7], "frames": [10, 11, 13]},
                                 7: {**TWO[1], "frames": [11, 12], "cls": "Car"}}, rec="02")


def test_scene_mode_holds_every_row_of_track_mode_once(tmp_path):
    folder = two_recordings(tmp_path / "h")
    tracks, scenes = read(folder), read(folder, runs="recordings")
    assert scenes.run_ids == ("01", "02") and scenes.metadata["runs"] == "recordings"
    fields = ("x", "y", "vx", "vy", "ax", "ay", "lane", "present")
    assert scenes.signals == tuple(f"obj{t}.{s}" for t in (1, 3, 7, 9) for s in fields)
    assert scenes.run(0)["t"].tolist() == [f / 25 for f in (0, 1, 2, 3, 4, 6)]
    present = {(r, t): scenes.run(i)[f"obj{t}.present"] == 1 for i, r in enumerate(("01", "02"))
               for t in (1, 3, 7, 9)}
    file_rows = 3 + 4 + 1 + 3 + 2
    assert sum(int(p.sum()) for p in present.values()) == file_rows  # each row once
    for run_id in tracks.run_ids:  # a track-mode run is its object's present frames, bit for bit
        rec, track = run_id.split(":")
        run, scene = tracks.run(tracks.run_ids.index(run_id)), scenes.run(scenes.run_ids.index(rec))
        here = present[(rec, int(track))]
        assert scene["t"][here].tolist() == run["t"].tolist()
        for s in tracks.signals:
            assert scene[f"obj{track}.{s}"][here].tolist() == run[s].tolist()
            assert not scene[f"obj{track}.{s}"][~here].any()  # absent: 0
    single = scenes.run(0)  # track 9, a single frame: left out of track mode, an object here
    assert single["obj9.present"].tolist() == [0, 0, 0, 0, 0, 1]
    assert single["obj9.x"][-1] == -(50.0 + 2.25) and single["obj9.vx"][-1] == 30.0
    assert not present[("01", 3)].any() and not present[("02", 1)].any()  # not in the recording
    only = read(folder, runs="recordings", recordings=["02"])
    assert only.run_ids == ("02",) and only.signals[::8] == ("obj3.x", "obj7.x")
    assert only.run(0)["obj7.x"].tolist() == scenes.run(1)["obj7.x"].tolist()


def test_scene_mode_keeps_metadata_per_object_through_convert(tmp_path):
    folder = two_recordings(tmp_path / "h")
    scenes = read(folder, runs="recordings")
    objects = scenes.metadata[RUN_INFO]["02"]["objects"]
    assert list(objects) == ["obj3", "obj7"]
    assert objects["obj3"] == {"recording": "02", "track": 3, "class": "Truck", "width": 2.5,
                               "length": 12.0, "driving_direction": 2}
    assert scenes.metadata[RUN_INFO]["01"]["objects"]["obj7"]["class"] == "Truck"  # another 7
    assert scenes.units["obj3.vx"] == "m/s" and scenes.units["obj3.present"] == ""
    assert scenes.metadata["recordings"]["02"]["startTime"] == "08:38"
    assert run(["convert", str(folder), str(tmp_path / "s.parquet"), "--runs", "recordings"]) == 0
    back = TraceSet.read(tmp_path / "s.parquet")
    assert back.digest() == scenes.digest()
    assert {k: v for k, v in back.metadata.items() if k != "converted_from"} == scenes.metadata
    assert back.metadata["converted_from"]["options"]["runs"] == "recordings"
    json.dumps(dict(scenes.metadata), allow_nan=False)


def test_scene_mode_direction_keep_and_ind_layout(tmp_path):
    kept = read(highd_folder(tmp_path / "h", TWO), runs="recordings", direction="keep")
    assert kept.run(0)["obj1.x"][0] == 100.0 + 2.25 and kept.run(0)["obj1.vx"][0] == -30.0
    folder = tmp_path / "ind"
    folder.mkdir()
    rows = [{"trackId": k, "frame": f, "xCenter": 1.0 + f, "yCenter": -2.0 * k,
             "heading": 90.0} for k in (0, 1) for f in range(k, 3)]
    write_table(folder / "00_tracks.csv", IND_TRACKS, rows)
    write_table(folder / "00_tracksMeta.csv", IND_META,
                [{"trackId": k, "width": 0.8, "length": 1.9, "class": c}
                 for k, c in ((0, "bicycle"), (1, "pedestrian"))])
    write_table(folder / "00_recordingMeta.csv", IND_RECORDING, [{"frameRate": 25}])
    ts = TraceSet.read(folder, runs="recordings")
    assert ts.run_ids == ("00",) and "obj1.heading" in ts.signals and "obj1.lane" not in ts.signals
    assert ts.column("obj1.present").tolist() == [0, 1, 1]
    assert ts.column("obj1.y").tolist() == [0.0, -2.0, -2.0]
    assert ts.metadata[RUN_INFO]["00"]["objects"]["obj1"]["class"] == "pedestrian"


def test_scene_mode_refuses_a_single_frame_and_too_many_values(tmp_path, monkeypatch):
    folder = highd_folder(tmp_path / "h", {1: {**TWO[1], "frames": [4]}})
    with pytest.raises(TraceSetError, match="01_tracks.csv: a single frame \\(4\\)"):
        read(folder, runs="recordings")
    monkeypatch.setenv("SIMCRED_MAX_SCENE_VALUES", "79")  # 5 frames × 2 objects × 8 signals
    with pytest.raises(OptionError, match="runs='recordings'.* = 80 exceeds the limit of 79"):
        read(highd_folder(tmp_path / "two", TWO), runs="recordings")


def scene_traffic(folder: Path, seed: int, shift: float = 0.0) -> Path:
    """Eight recordings of 12 vehicles coming and going, speeds around 30 m/s."""
    rng = np.random.default_rng(seed)
    for rec in range(1, 9):
        tracks = {tid: {"frames": list(range(3 * tid, 3 * tid + 40)),
                        "x0": float(rng.uniform(0, 300)), "v": float(rng.normal(30, 3)),
                        "lane": 2 if tid % 2 else 6, "direction": 1 if tid % 2 else 2,
                        "cls": "Car", "w": 4.5, "h": 1.8} for tid in range(1, 13)}
        highd_folder(folder, tracks, rec=f"{rec:02d}", shift=shift)
    return folder


@pytest.mark.parametrize("shift, same", [(0.0, True), (15.0, False)])
def test_cli_compare_on_highd_folders_in_scene_mode(tmp_path, capsys, shift, same):
    a = scene_traffic(tmp_path / "a", seed=1)
    b = scene_traffic(tmp_path / "b", seed=1, shift=shift)
    code = run(["compare", str(a), str(b), "--read", "runs=recordings", "-f", "obj4.vx",
                "--bins", "4", "--permutations", "99", "--seed", "3", "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["chain"]["rejected"] is (not same)
    if same:
        assert doc["distance"] == 0.0 and not doc["start"]["rejected"]


@pytest.mark.parametrize("command", [["convert", "{f}", "{f}.parquet", "--runs", "scenes"],
                                     ["compare", "{f}", "{f}", "-f", "vx", "--read",
                                      "runs=scenes"]])
def test_scene_option_bad_value_is_one_line_exit_2(tmp_path, command):
    folder = highd_folder(tmp_path / "h", TWO)
    code, out, err, _ = run_isolated([c.format(f=folder) for c in command], 10)
    assert code == 2, (code, err[-400:])
    lines = [line for line in err.splitlines() if line.strip()]
    assert lines == ["error: runs must be one of tracks, recordings, got 'scenes'"], err[-400:]
    with pytest.raises(OptionError, match="runs must be one of tracks, recordings"):
        read(folder, runs="scenes")
