"""The A9 importer on the real OSC-Generator files: units, projection, conventions, errors."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pyproj
import pytest

from simcred import data
from simcred.errors import TraceSetError
from simcred.io.a9 import A9Recording, heading_offset, read_a9
from simcred.io.a9_lanes import lane_changer, lane_offset

SUBDIR = Path("data") / "real" / "osc-generator-a9"
CANDIDATES = [data.path("a9"), Path(__file__).resolve().parents[2] / "shared" / SUBDIR,
              Path("/work/shared") / SUBDIR]
DATA = next((p for p in CANDIDATES if (p / "trajectories_file.csv").is_file()), None)
pytestmark = pytest.mark.skipif(
    DATA is None, reason=f"A9 recording not found in {' or '.join(map(str, CANDIDATES))}"
)
TESTFILES = ["testfile_llc.csv", "testfile_rlc.csv", "testfile_straight.csv"]


@pytest.fixture(scope="module")
def rec() -> A9Recording:
    return read_a9(DATA / "trajectories_file.csv")


def _windows(n: int, width: int = 10) -> list[tuple[int, int]]:
    return [(a, a + width) for a in range(0, n - width, width // 2)]


# -- units and projection -------------------------------------------------------------------------


def test_ego_speed_in_metres_per_second(rec):
    v = rec.ego["v"]
    assert v[0] == pytest.approx(99.57388888888887 / 3.6)  # first row: 99.57 km/h
    assert v.min() > 26.4 and v.max() < 27.7


def test_projection_is_local_metric_east_north(rec):
    gx, gy = rec.ego["gnss_x"], rec.ego["gnss_y"]
    assert (gx[0], gy[0]) == pytest.approx((0.0, 0.0), abs=1e-6)
    lat, lon = rec.origin
    proj = pyproj.Proj(rec.crs)
    end_lon, end_lat = proj(gx[-1], gy[-1], inverse=True)
    azimuth, _, distance = pyproj.Geod(ellps="WGS84").inv(lon, lat, end_lon, end_lat)
    assert np.hypot(gx[-1], gy[-1]) == pytest.approx(distance, rel=1e-6)
    assert np.degrees(np.arctan2(gx[-1], gy[-1])) == pytest.approx(azimuth, abs=1e-3)  # x east


def test_gnss_track_length_matches_integrated_speed(rec):
    gnss = np.sum(np.hypot(np.diff(rec.ego["gnss_x"]), np.diff(rec.ego["gnss_y"])))
    speed = np.sum(0.5 * (rec.ego["v"][1:] + rec.ego["v"][:-1]) * np.diff(rec.time))
    assert gnss == pytest.approx(speed, rel=0.01)  # 274.5 m vs 275.1 m


def test_ego_steps_follow_speed_and_heading(rec):
    step = np.diff(rec.ego["x"]) + 1j * np.diff(rec.ego["y"])
    v_dt = 0.5 * (rec.ego["v"][1:] + rec.ego["v"][:-1]) * np.diff(rec.time)
    np.testing.assert_allclose(np.abs(step), v_dt, rtol=1e-3)
    mid = 0.5 * (rec.ego["heading"][1:] + rec.ego["heading"][:-1])
    np.testing.assert_allclose(np.angle(step * np.exp(-1j * mid)), 0.0, atol=1e-9)


# -- conventions ----------------------------------------------------------------------------------


def test_heading_is_compass_and_offset_from_gnss_track(rec):
    """The aligned heading follows the 1-s GNSS course to < 0.5 deg while both turn by ~7 deg."""
    assert np.degrees(rec.heading_offset) == pytest.approx(-7.28, abs=0.05)
    gx, gy, psi = rec.ego["gnss_x"], rec.ego["gnss_y"], rec.ego["heading"]
    moving = slice(2, 101)  # rows 0-2 and 100-102 hold the same fix
    gx, gy, psi = gx[moving], gy[moving], psi[moving]
    errors = []
    for a, b in _windows(len(gx)):
        course = np.arctan2(gy[b] - gy[a], gx[b] - gx[a])
        errors.append(np.degrees(course - np.mean(psi[a:b + 1])))
    assert np.max(np.abs(errors)) < 0.5
    # The road bends left: the CCW heading grows by 7.4 deg (compass 3.4 -> -4.0 deg), and so
    # does the GNSS course; a counter-clockwise compass reading would turn the other way.
    assert np.degrees(psi[-1] - psi[0]) == pytest.approx(7.4, abs=0.3)


def test_ego_position_stays_on_gnss_track(rec):
    e = rec.ego
    dx, dy = e["gnss_x"] - e["x"], e["gnss_y"] - e["y"]
    cross = -np.sin(e["heading"]) * dx + np.cos(e["heading"]) * dy
    assert np.max(np.abs(cross)) < 0.5
    assert rec.gnss_rms < 3.0


def test_recorded_heading_without_offset_drifts(rec):
    recorded = rec.ego["heading"] - rec.heading_offset
    step = np.diff(rec.ego["gnss_x"]) + 1j * np.diff(rec.ego["gnss_y"])
    assert heading_offset(rec.ego["gnss_x"], rec.ego["gnss_y"], recorded) == pytest.approx(
        rec.heading_offset)
    assert np.abs(np.sum(step)) * np.sin(abs(rec.heading_offset)) > 30  # m of lateral drift


def test_object_speeds_are_over_ground(rec):
    """Object 6 drives beside the ego: its track speed matches speed_x/y as absolute values."""
    track = rec.objects[6].track
    t = rec.time[rec.objects[6].rows]
    fd = np.hypot(np.diff(track.x), np.diff(track.y)) / np.diff(t)
    reported = 0.5 * (track.v[1:] + track.v[:-1])
    assert np.mean(fd) == pytest.approx(np.mean(reported), abs=1.0)  # 31.0 vs 30.6 m/s
    ego = rec.ego["v"][rec.objects[6].rows]
    assert np.mean(fd) < np.mean(reported + 0.5 * (ego[1:] + ego[:-1])) - 20  # not relative


def test_oncoming_objects_point_backwards(rec):
    for k in (3, 7):
        relative = rec.objects[k].track.heading - rec.ego["heading"][rec.objects[k].rows]
        assert np.all(np.cos(relative) < -0.9)


# -- objects, segments and the lane changer -------------------------------------------------------


def test_empty_object_cells_are_absence(rec):
    assert list(rec.objects) == [1, 2, 3, 4, 5, 6, 7]
    assert [len(rec.objects[k]) for k in rec.objects] == [103, 1, 16, 4, 20, 40, 7]
    assert rec.objects[6].segments() == [(0, 40)]
    assert rec.objects[5].object_class == 9
    ts = rec.to_traceset(6)
    assert ts.n_rows == 40 and np.all(np.isfinite(ts.values))
    with pytest.raises(TraceSetError, match="object 2 is present in 1 row"):
        rec.to_traceset(2)
    with pytest.raises(TraceSetError, match="no object 9"):
        rec.to_traceset(9)


def test_lane_changer_is_object_one(rec):
    assert lane_changer(rec) == 1
    track = rec.objects[1]
    assert track.rel_x.min() > 38.5 and track.rel_x.max() < 56.1
    offset, width = lane_offset(rec, 1)
    assert np.median(width) == pytest.approx(3.55, abs=0.1)
    assert offset.min() < -width[0] / 2 < offset.max()
    neighbour, _ = lane_offset(rec, 6)
    assert np.all(neighbour > 1.9)  # object 6 stays in the left lane


def test_traceset_for_lane_changer(rec):
    ts = rec.to_traceset(lane_changer(rec))
    assert ts.signals == ("ego.x", "ego.y", "ego.v", "ego.heading",
                          "to.x", "to.y", "to.v", "to.heading")
    assert ts.n_runs == 1 and ts.n_rows == 103 and ts.run_ids == ("trajectories_file:obj1",)
    gap = np.hypot(ts.column("to.x") - ts.column("ego.x"), ts.column("to.y") - ts.column("ego.y"))
    np.testing.assert_allclose(gap, np.hypot(rec.objects[1].rel_x, rec.objects[1].rel_y))
    meta = json.loads(json.dumps(ts.metadata))
    assert meta["object_id"] == 1 and meta["object_class"] == 7 and meta["rows"] == [0, 103]


@pytest.mark.parametrize("name", TESTFILES)
def test_files_without_objects(name):
    rec = read_a9(DATA / name)
    assert rec.objects == {} and rec.ego["v"][0] == 0.0
    ts = rec.to_traceset()
    assert ts.signals == ("ego.x", "ego.y", "ego.v", "ego.heading")
    assert rec.gnss_rms < 1.5
    with pytest.raises(TraceSetError, match="no object crosses"):
        lane_changer(rec)


# -- malformed files ------------------------------------------------------------------------------


def _rows() -> list[list[str]]:
    with (DATA / "trajectories_file.csv").open(newline="") as handle:
        return list(csv.reader(handle))


def _write(tmp_path: Path, rows: list[list[str]], name: str = "bad.csv") -> Path:
    path = tmp_path / name
    with path.open("w", newline="") as handle:
        csv.writer(handle).writerows(rows)
    return path


def _set(rows: list[list[str]], row: int, column: str, value: str) -> list[list[str]]:
    rows[row][rows[0].index(column)] = value
    return rows


def _drop(rows: list[list[str]], column: str) -> list[list[str]]:
    j = rows[0].index(column)
    return [r[:j] + r[j + 1:] for r in rows]


def _decreasing(rows: list[list[str]]) -> list[list[str]]:
    rows[5][0], rows[6][0] = rows[6][0], rows[5][0]
    return rows


def _truncated(rows: list[list[str]]) -> list[list[str]]:
    rows[7] = rows[7][:12]
    return rows


CASES = {
    "missing column": (lambda r: _drop(r, "speed"), "no column 'speed'"),
    "text cell": (lambda r: _set(r, 5, "lat", "abc"), r"column 'lat', row 5 \(line 6\): 'abc'"),
    "time decreases": (_decreasing, "'timestamp' is not strictly increasing at row 6"),
    "truncated row": (_truncated, r"row 7 \(line 8\) has 12 cells, the header has 53"),
    "empty ego cell": (lambda r: _set(r, 3, "heading", ""), "'heading', row 3 .*missing"),
    "nan ego cell": (lambda r: _set(r, 4, "speed", "nan"), "'speed', row 4 .*must be finite"),
    "pos without speed": (
        lambda r: _set(_set(r, 9, "speed_x_1", ""), 9, "speed_y_1", ""),
        r"row 9 \(line 10\): object 1 has 'pos_x_1' but no 'speed_x_1'",
    ),
    "speed without pos": (
        lambda r: _set(r, 2, "speed_y_3", "4.0"),
        r"row 2 \(line 3\): object 3 has 'speed_y_3' but no 'pos_x_3'",
    ),
    "object column missing": (lambda r: _drop(r, "speed_y_4"), "object 4 has no column.*speed_y_4"),
    "header only": (lambda r: r[:1], "0 data row"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_malformed_file_gives_one_line_error(tmp_path, case):
    edit, pattern = CASES[case]
    path = _write(tmp_path, edit(_rows()))
    with pytest.raises(TraceSetError, match=pattern) as info:
        read_a9(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message


def test_empty_and_missing_files(tmp_path):
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    with pytest.raises(TraceSetError, match=f"^{empty}: empty file"):
        read_a9(empty)
    with pytest.raises(TraceSetError, match="no such file"):
        read_a9(tmp_path / "absent.csv")


def test_lane_width_must_be_positive(rec):
    with pytest.raises(TraceSetError, match="lane_width must be a positive number"):
        lane_changer(rec, lane_width=0.0)
    assert lane_changer(rec, lane_width=3.5) == 1
